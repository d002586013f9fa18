"""Compiled kernels of the plant: vessel derivative and RK4 step, mass matrices, thruster drives, wave sums.

Each kernel is the arithmetic of one part of the plant, written as scalar code and loops (see
:mod:`dpbase.jit` for why: 3-vectors, ≤ 8 drives and a few hundred wave components are too small
for numpy's or the interpreter's per-call cost). The classes keep the configuration, validation and
the decisions made once per step in Python (:class:`~sim_plant.vessel.DpVesselModel`,
:class:`~sim_plant.drives.ThrusterDrives`, :class:`~sim_plant.environment.waves.WaveField`); one
plant substep is one call of :func:`plant_substep`, one wave evaluation one call of :func:`wave_sums`
(gusts and current variation: :func:`cosine_sum`).

The vessel and drive kernels perform the same floating-point operations in the same order as the
plain Python they replaced, so they give the same results bit for bit; the sums over wave and gust
components add their terms in another order than numpy's products and M⁻¹ comes from cofactors
instead of an LU factorisation, which changes the last bits only.

Array layouts (rows of C-contiguous arrays, so that a row is a contiguous view for the Python side):

* vessel state ``x`` (6,): [north_m, east_m, psi_rad, u_mps, v_mps, r_radps];
* vessel parameters ``p``: :data:`DP_PARAMETERS` or :data:`MANOEUVRING_PARAMETERS` (by ``model``);
* drives: ``const`` (len(DRIVE_CONSTANTS), n), ``state`` (len(DRIVE_STATE), n), ``codes``
  (len(DRIVE_CODES), n) and the bank scalars ``bank`` (len(DRIVE_BANK),), n drives;
* wave weights (len(WAVE_WEIGHTS), n) for n components.
"""

from __future__ import annotations

import math

import numpy as np

from dpbase.frames import ssa_compiled as ssa
from dpbase.jit import UniTuple, b1_1d, f8, f8_1d, f8_2d, i8, i8_1d, kernel, void

i8_2d = i8[:, ::1]  # C-contiguous int64 2-D (the drive codes)

# -- vessel ------------------------------------------------------------------------------------------
DP_MODEL = 0           # the ``model`` argument: nonlinear DP model (seed 002 eqs. (1)–(8))
MANOEUVRING_MODEL = 1  # course keeping from manoeuvring derivatives (the mariner)

# DP model parameters: rigid-body mass m and m·x_g, the added mass M_A (symmetrised; the eight
# entries the equations use), linear damping D and M⁻¹ (row-major), quadratic damping d_q.
DP_PARAMETERS = ("m", "mxg", "a11", "a12", "a13", "a21", "a22", "a23", "a31", "a32",
                 "d11", "d12", "d13", "d21", "d22", "d23", "d31", "d32", "d33", "q1", "q2", "q3",
                 "i11", "i12", "i13", "i21", "i22", "i23", "i31", "i32", "i33")
# What a DP model's loading sets (sim_plant.vessel.DpVesselModel.set_mass_factor): I_z, x_g, draft,
# the wind areas A_F, A_L and Blendermann's C_Dt, C_Dl,AF bow and stern, δ, then M_A (not yet
# symmetrised), D (row-major) and d_q.
LOADING_VALUES = ("iz", "xg", "draft", "frontal_area", "lateral_area", "cdt", "cdl_af_bow", "cdl_af_stern",
                  "delta", "a11", "a12", "a13", "a21", "a22", "a23", "a31", "a32", "a33",
                  "d11", "d12", "d13", "d21", "d22", "d23", "d31", "d32", "d33", "q1", "q2", "q3")
L_IZ, L_XG, L_DRAFT = 0, 1, 2
L_ADDED, L_DAMPING, L_QUAD = 9, 18, 27  # first index of M_A, D, d_q
# Manoeuvring model parameters: dimensional sway–yaw mass [[m22, m23], [m32, m33]] and its determinant,
# the derivatives Y'_v, Y'_r, Y'_δ, N'_v, N'_r, N'_δ, the force and moment scales ½ρL², ½ρL³, L, u0.
MANOEUVRING_PARAMETERS = ("m22", "m23", "m32", "m33", "det", "y_v", "y_r", "y_d", "n_v", "n_r", "n_d",
                          "qy", "qn", "length", "u0")

# -- thruster drives ---------------------------------------------------------------------------------
TUNNEL, AZIMUTH, PROPELLER, RUDDER = 0, 1, 2, 3  # drive kinds
NO_FAILURE, STUCK, ZERO, WRONG_SIGN, NOT_READY = 0, 1, 2, 3, 4  # failure codes
NO_DRIVE = -1  # a ``skip`` that leaves no drive out

DRIVE_CONSTANTS = ("x", "y", "cos", "sin", "lift", "time_constant", "rate_limit", "angle_rate_limit")
C_X, C_Y, C_COS, C_SIN, C_LIFT, C_TAU, C_RATE, C_ANGLE_RATE = range(len(DRIVE_CONSTANTS))
DRIVE_STATE = ("thrust", "angle", "target_thrust", "target_angle", "command_time", "alpha")
S_THRUST, S_ANGLE, S_TARGET_THRUST, S_TARGET_ANGLE, S_COMMAND_TIME, S_ALPHA = range(len(DRIVE_STATE))
DRIVE_CODES = ("kind", "failure")
K_KIND, K_FAILURE = range(len(DRIVE_CODES))
DRIVE_LIMITS = ("min_thrust", "max_thrust", "rudder_max")  # command saturation [N, N, rad] (inf: none)
L_MIN_THRUST, L_MAX_THRUST, L_RUDDER_MAX = range(len(DRIVE_LIMITS))
COMMAND_OK = -1  # drives_command applied everything
DRIVE_BANK = ("alpha_h", "lost", "timeout")  # the substep ``alpha`` is for, 1.0 when lost, timeout [s]
B_ALPHA_H, B_LOST, B_TIMEOUT = range(len(DRIVE_BANK))

# -- waves -------------------------------------------------------------------------------------------
# a_i X(ω_i, β), a_i Y(ω_i, β), a_i Ψ(ω_i, β) (adjacent: WaveField interpolates them in β as one block), b_i
WAVE_WEIGHTS = ("x", "y", "psi", "b")
W_X, W_Y, W_PSI, W_B = range(len(WAVE_WEIGHTS))

Derivative = tuple[float, float, float, float, float, float]


@kernel(UniTuple(f8, 6)(f8_1d, f8, f8, f8, f8, f8, f8, f8, f8, f8))
def dp_derivative(p: np.ndarray, psi: float, u: float, v: float, r: float, tx: float, ty: float, tn: float,
                  cn: float, ce: float) -> Derivative:
    """ẋ of the nonlinear DP model (seed 002 eqs. (1)–(8); see :mod:`sim_plant.vessel`)::

        η̇ = R(ψ) ν,   M ν̇ = τ − C_RB(ν)ν − C_A(ν_r)ν_r − Dν_r − d_q(ν_r) + M_A ν̇_c

    Parameters
    ----------
    p : (len(DP_PARAMETERS),) parameters
    psi, u, v, r : heading [rad], body velocity over ground [m/s, m/s, rad/s]
    tx, ty, tn : external force in body axes [N, N, N·m]
    cn, ce : current velocity over ground, NED [m/s]

    Returns
    -------
    tuple of 6 float
        (ṅ, ė, ψ̇, u̇, v̇, ṙ).
    """
    m, mxg = p[0], p[1]
    a11, a12, a13, a21, a22, a23, a31, a32 = p[2], p[3], p[4], p[5], p[6], p[7], p[8], p[9]
    d11, d12, d13, d21, d22, d23, d31, d32, d33 = p[10], p[11], p[12], p[13], p[14], p[15], p[16], p[17], p[18]
    q1, q2, q3 = p[19], p[20], p[21]
    i11, i12, i13, i21, i22, i23, i31, i32, i33 = p[22], p[23], p[24], p[25], p[26], p[27], p[28], p[29], p[30]
    c = math.cos(psi)
    s = math.sin(psi)
    uc = c * cn + s * ce  # current in body axes
    vc = c * ce - s * cn
    ur = u - uc
    vr = v - vc
    # rigid-body Coriolis C_RB(ν)ν with p = M_RB ν (seed 002 eq. (4))
    p2 = m * v + mxg * r
    # added-mass Coriolis C_A(ν_r)ν_r with p_A = M_A ν_r
    pa1 = a11 * ur + a12 * vr + a13 * r
    pa2 = a21 * ur + a22 * vr + a23 * r
    # M_A ν̇_c, ν̇_c = (r v_c, −r u_c, 0)
    dc1 = r * vc
    dc2 = -r * uc
    f1 = (tx + p2 * r + pa2 * r - (d11 * ur + d12 * vr + d13 * r) - q1 * abs(ur) * ur
          + a11 * dc1 + a12 * dc2)
    f2 = (ty - m * u * r - pa1 * r - (d21 * ur + d22 * vr + d23 * r) - q2 * abs(vr) * vr
          + a21 * dc1 + a22 * dc2)
    f3 = (tn - (p2 * u - m * u * v) - (pa2 * ur - pa1 * vr) - (d31 * ur + d32 * vr + d33 * r)
          - q3 * abs(r) * r + a31 * dc1 + a32 * dc2)
    return (c * u - s * v, s * u + c * v, r,
            i11 * f1 + i12 * f2 + i13 * f3,
            i21 * f1 + i22 * f2 + i23 * f3,
            i31 * f1 + i32 * f2 + i33 * f3)


@kernel(void(f8_1d, f8, f8_2d, f8_2d, f8_1d))
def dp_parameters(values: np.ndarray, m: float, added: np.ndarray, mass_matrix: np.ndarray, p: np.ndarray) -> None:
    """Mass matrices and the :data:`DP_PARAMETERS` of a DP model for one loading.

    M_A = ½ (M_A + M_Aᵀ), M = M_RB + M_A with M_RB = [[m, 0, 0], [0, m, m x_g], [0, m x_g, I_z]]
    (seed 002 eq. (4)), and M⁻¹ = adj(M) / det M for the parameters.

    Parameters
    ----------
    values : (len(LOADING_VALUES),) the loading
    m : rigid-body mass [kg]
    added : (3, 3) out — M_A [kg, kg·m, kg·m²]
    mass_matrix : (3, 3) out — M
    p : (len(DP_PARAMETERS),) out — the DP model's parameters
    """
    mxg = m * values[L_XG]
    rigid = ((m, 0.0, 0.0), (0.0, m, mxg), (0.0, mxg, values[L_IZ]))
    for row in range(3):
        for col in range(3):
            added[row, col] = 0.5 * (values[L_ADDED + 3 * row + col] + values[L_ADDED + 3 * col + row])
            mass_matrix[row, col] = rigid[row][col] + added[row, col]
    # M⁻¹ = adj(M) / det M (cofactors of a 3×3: no allocation; equal to an LU inverse up to rounding)
    a, b, c = mass_matrix[0, 0], mass_matrix[0, 1], mass_matrix[0, 2]
    d, e, f = mass_matrix[1, 0], mass_matrix[1, 1], mass_matrix[1, 2]
    g, h, k = mass_matrix[2, 0], mass_matrix[2, 1], mass_matrix[2, 2]
    c00, c01, c02 = e * k - f * h, f * g - d * k, d * h - e * g
    det = a * c00 + b * c01 + c * c02
    inverse = ((c00, c * h - b * k, b * f - c * e),
               (c01, a * k - c * g, c * d - a * f),
               (c02, b * g - a * h, a * e - b * d))
    p[0] = m
    p[1] = mxg
    p[2:5] = added[0]
    p[5:8] = added[1]
    p[8:10] = added[2, :2]
    p[10:22] = values[L_DAMPING:L_QUAD + 3]
    for row in range(3):
        for col in range(3):
            p[22 + 3 * row + col] = inverse[row][col] / det


@kernel(UniTuple(f8, 6)(f8_1d, f8, f8, f8, f8, f8, f8, f8, f8))
def manoeuvring_derivative(p: np.ndarray, psi: float, v: float, r: float, ty: float, tn: float, cn: float,
                           ce: float, rudder: float) -> Derivative:
    """ẋ of the course-keeping model (see :mod:`sim_plant.vessel`): surge through the water held at u0,
    ``M' [v̇_r, ṙ]ᵀ = [Y', N']ᵀ`` with Y' = Y_v v' + Y_r r' + Y_δ δ, N' = N_v v' + N_r r' + N_δ δ
    (prime system, U = |ν_r|), plus the dimensional external sway force and yaw moment.

    Parameters
    ----------
    p : (len(MANOEUVRING_PARAMETERS),) parameters
    psi, v, r : heading [rad], sway velocity over ground [m/s], yaw rate [rad/s]
    ty, tn : external sway force [N] and yaw moment [N·m] (surge force is ignored: u_r = u0)
    cn, ce : current velocity over ground, NED [m/s]
    rudder : rudder angle δ [rad]

    Returns
    -------
    tuple of 6 float
        (ṅ, ė, ψ̇, u̇, v̇, ṙ).
    """
    m22, m23, m32, m33, det = p[0], p[1], p[2], p[3], p[4]
    y_v, y_r, y_d, n_v, n_r, n_d = p[5], p[6], p[7], p[8], p[9], p[10]
    qy, qn, length, u0 = p[11], p[12], p[13], p[14]
    c = math.cos(psi)
    s = math.sin(psi)
    uc = c * cn + s * ce
    vc = c * ce - s * cn
    vr = v - vc
    big_u = math.sqrt(u0 * u0 + vr * vr)
    vp = vr / big_u
    rp = r * length / big_u
    y = (y_v * vp + y_r * rp + y_d * rudder) * qy * big_u * big_u + ty
    n = (n_v * vp + n_r * rp + n_d * rudder) * qn * big_u * big_u + tn
    vr_dot = (m33 * y - m23 * n) / det
    r_dot = (m22 * n - m32 * y) / det
    ug = u0 + uc
    # ν = ν_r + ν_c, ν̇_c = (r v_c, −r u_c, 0)
    return (c * ug - s * v, s * ug + c * v, r, r * vc, vr_dot - r * uc, r_dot)


@kernel(UniTuple(f8, 6)(i8, f8_1d, f8, f8, f8, f8, f8, f8, f8, f8, f8, f8))
def vessel_derivative(model: int, p: np.ndarray, psi: float, u: float, v: float, r: float, tx: float, ty: float,
                      tn: float, cn: float, ce: float, rudder: float) -> Derivative:
    """ẋ of the model ``model`` (:data:`DP_MODEL` or :data:`MANOEUVRING_MODEL`) with parameters ``p``;
    arguments as :func:`dp_derivative`, plus the rudder angle [rad] (manoeuvring model only)."""
    if model == DP_MODEL:
        return dp_derivative(p, psi, u, v, r, tx, ty, tn, cn, ce)
    return manoeuvring_derivative(p, psi, v, r, ty, tn, cn, ce, rudder)


@kernel(void(f8_1d, i8, f8_1d, f8, f8, f8, f8, f8, f8, f8))
def rk4_step(x: np.ndarray, model: int, p: np.ndarray, h: float, tx: float, ty: float, tn: float, cn: float,
             ce: float, rudder: float) -> None:
    """One classical RK4 step of length ``h`` [s] of :func:`vessel_derivative`, inputs held (ZOH), in place.

    Parameters
    ----------
    x : (6,) state [north_m, east_m, psi_rad, u_mps, v_mps, r_radps]; ψ is wrapped with ssa after the step
    model, p : the model and its parameters
    h : step [s]
    tx, ty, tn : external force in body axes [N, N, N·m]; cn, ce : current (NED) [m/s]; rudder : [rad]
    """
    n, e, psi, u, v, r = x[0], x[1], x[2], x[3], x[4], x[5]
    k1 = vessel_derivative(model, p, psi, u, v, r, tx, ty, tn, cn, ce, rudder)
    h2 = 0.5 * h
    k2 = vessel_derivative(model, p, psi + h2 * k1[2], u + h2 * k1[3], v + h2 * k1[4], r + h2 * k1[5],
                           tx, ty, tn, cn, ce, rudder)
    k3 = vessel_derivative(model, p, psi + h2 * k2[2], u + h2 * k2[3], v + h2 * k2[4], r + h2 * k2[5],
                           tx, ty, tn, cn, ce, rudder)
    k4 = vessel_derivative(model, p, psi + h * k3[2], u + h * k3[3], v + h * k3[4], r + h * k3[5],
                           tx, ty, tn, cn, ce, rudder)
    h6 = h / 6.0
    x[0] = n + h6 * (k1[0] + 2.0 * (k2[0] + k3[0]) + k4[0])
    x[1] = e + h6 * (k1[1] + 2.0 * (k2[1] + k3[1]) + k4[1])
    x[2] = ssa(psi + h6 * (k1[2] + 2.0 * (k2[2] + k3[2]) + k4[2]))
    x[3] = u + h6 * (k1[3] + 2.0 * (k2[3] + k3[3]) + k4[3])
    x[4] = v + h6 * (k1[4] + 2.0 * (k2[4] + k3[4]) + k4[4])
    x[5] = r + h6 * (k1[5] + 2.0 * (k2[5] + k3[5]) + k4[5])


@kernel(UniTuple(f8, 3)(f8_2d, f8_2d, i8_2d, i8))
def drives_force(const: np.ndarray, state: np.ndarray, codes: np.ndarray, skip: int) -> tuple[float, float, float]:
    """τ_act_b = Σ forces and moments of the delivered thrusts [N, N, N·m] (see :mod:`sim_plant.drives`).

    F = T (cos α, sin α) with α the fixed angle or the azimuth; a rudder F = (T, T · lift · δ) ahead,
    (T, 0) astern; N = x F_y − y F_x. The delivered thrust is 0 for a ``zero`` failure and −T for
    ``wrong_sign``. Drive ``skip`` is left out (:data:`NO_DRIVE`: none).
    """
    fx_sum = fy_sum = n_sum = 0.0
    for i in range(state.shape[1]):
        if i == skip:
            continue
        t = state[S_THRUST, i]
        failure = codes[K_FAILURE, i]
        if failure == ZERO:
            t = 0.0
        elif failure == WRONG_SIGN:
            t = -t
        if t == 0.0:
            continue
        kind = codes[K_KIND, i]
        if kind == AZIMUTH:
            a = state[S_ANGLE, i]
            fx = t * math.cos(a)
            fy = t * math.sin(a)
        elif kind == RUDDER:
            fx = t
            fy = t * const[C_LIFT, i] * state[S_ANGLE, i] if t > 0.0 else 0.0
        else:
            fx = t * const[C_COS, i]
            fy = t * const[C_SIN, i]
        fx_sum += fx
        fy_sum += fy
        n_sum += const[C_X, i] * fy - const[C_Y, i] * fx
    return fx_sum, fy_sum, n_sum


@kernel(void(f8_2d, f8_2d, i8_2d, f8_1d, f8, f8))
def drives_update(const: np.ndarray, state: np.ndarray, codes: np.ndarray, bank: np.ndarray, t: float,
                  h: float) -> None:
    """Advance every drive over the substep [t, t + h] [s], in place (see :mod:`sim_plant.drives`).

    Thrust: T ← T + clip((T_c − T)(1 − e^{−h/τ}), ±ṫ_max h), toward 0 instead of T_c when the drive is
    ``not_ready``, the controller is lost or the command is older than the timeout (the angle then
    holds); azimuths slew the short way round, rudders straight, both at the angle rate limit; a
    ``stuck`` drive does not move. ``1 − e^{−h/τ}`` is kept for the substep it was computed for while
    substeps differ only by rounding.
    """
    n_drives = state.shape[1]
    if abs(h - bank[B_ALPHA_H]) > 1e-12 * h:
        for i in range(n_drives):
            state[S_ALPHA, i] = -math.expm1(-h / const[C_TAU, i])
        bank[B_ALPHA_H] = h
    lost = bank[B_LOST] != 0.0
    timeout = bank[B_TIMEOUT]
    for i in range(n_drives):
        failure = codes[K_FAILURE, i]
        if failure == STUCK:
            continue
        thrust = state[S_THRUST, i]
        if failure == NOT_READY or lost or t - state[S_COMMAND_TIME, i] > timeout:
            target = 0.0
            hold_angle = True
        else:
            target = state[S_TARGET_THRUST, i]
            hold_angle = False
        delta = (target - thrust) * state[S_ALPHA, i]
        limit = const[C_RATE, i] * h
        if delta > limit:
            delta = limit
        elif delta < -limit:
            delta = -limit
        state[S_THRUST, i] = thrust + delta
        kind = codes[K_KIND, i]
        if hold_angle or kind in (TUNNEL, PROPELLER):
            continue
        angle = state[S_ANGLE, i]
        target_angle = state[S_TARGET_ANGLE, i]
        err = ssa(target_angle - angle) if kind == AZIMUTH else target_angle - angle
        step = const[C_ANGLE_RATE, i] * h
        if err > step:
            err = step
        elif err < -step:
            err = -step
        state[S_ANGLE, i] = ssa(angle + err) if kind == AZIMUTH else angle + err


@kernel(i8(f8_2d, f8_2d, i8_2d, i8_1d, f8_1d, f8_1d, b1_1d, f8))
def drives_command(state: np.ndarray, limits: np.ndarray, codes: np.ndarray, order: np.ndarray, thrust: np.ndarray,
                   azimuth: np.ndarray, enabled: np.ndarray, t: float) -> int:
    """Apply one command per drive, all or nothing (:meth:`sim_plant.drives.ThrusterDrives.command_arrays`).

    Entry ``j`` commands drive ``order[j]``: target thrust ``thrust[j]`` saturated to the drive's limits
    (0 when not ``enabled[j]``), target angle ``azimuth[j]`` (wrapped for an azimuth, limited to ±δ_max for a
    rudder, ignored otherwise), command time ``t``. The comparisons are those of ``min(high, max(low, x))``
    in Python (the first argument wins ties), so the targets are the ones ``ThrusterDrives.command`` sets.

    Parameters
    ----------
    state : drive state (targets and command time written in place)
    limits : (len(DRIVE_LIMITS), n) saturation; codes : drive kinds
    order, thrust, azimuth, enabled : (m,) per command
    t : command time [s]

    Returns
    -------
    int
        :data:`COMMAND_OK`, or the first entry that is not a finite thrust and angle (or ``m`` when the
        arrays differ in length); nothing is written then.
    """
    m = order.size
    if thrust.size != m or azimuth.size != m or enabled.size != m:
        return m
    for j in range(m):
        if not (math.isfinite(thrust[j]) and math.isfinite(azimuth[j])):
            return j
    for j in range(m):
        i = order[j]
        if enabled[j]:
            low = limits[L_MIN_THRUST, i]
            high = limits[L_MAX_THRUST, i]
            value = thrust[j] if thrust[j] > low else low
            state[S_TARGET_THRUST, i] = value if value < high else high
        else:
            state[S_TARGET_THRUST, i] = 0.0
        kind = codes[K_KIND, i]
        if kind == AZIMUTH:
            state[S_TARGET_ANGLE, i] = ssa(azimuth[j])
        elif kind == RUDDER:
            high = limits[L_RUDDER_MAX, i]
            value = azimuth[j] if azimuth[j] > -high else -high
            state[S_TARGET_ANGLE, i] = value if value < high else high
        state[S_COMMAND_TIME, i] = t
    return COMMAND_OK


@kernel(void(f8_2d, i8_2d, f8_2d))
def drives_feedback(state: np.ndarray, codes: np.ndarray, out: np.ndarray) -> None:
    """Delivered thrust [N] (``out[0]``) and actual angle wrapped to (−π, π] [rad] (``out[1]``) per drive."""
    for i in range(state.shape[1]):
        failure = codes[K_FAILURE, i]
        t = state[S_THRUST, i]
        out[0, i] = 0.0 if failure == ZERO else (-t if failure == WRONG_SIGN else t)
        out[1, i] = ssa(state[S_ANGLE, i])


@kernel(void(f8_1d, i8, f8_1d, f8, f8, f8, f8, f8, f8, f8, f8_2d, f8_2d, i8_2d, f8_1d, i8))
def plant_substep(x: np.ndarray, model: int, p: np.ndarray, t: float, h: float, ex: float, ey: float, en: float,
                  cn: float, ce: float, const: np.ndarray, state: np.ndarray, codes: np.ndarray, bank: np.ndarray,
                  rudder: int) -> None:
    """One plant substep [t, t + h]: thruster force, RK4 step of the vessel, drives (see :mod:`sim_plant.plant`).

    Inputs are held over the substep (zero-order hold): the delivered thruster force and rudder angle
    at t, the environment force (``ex, ey, en`` [N, N, N·m], body axes) and the current (``cn, ce``
    [m/s], NED); the drives then move over the substep.

    Parameters
    ----------
    x, model, p : vessel state (in place), model and parameters (:func:`rk4_step`)
    t, h : substep start and length [s]
    const, state, codes, bank : the drives (``state`` and ``bank`` in place; :func:`drives_update`)
    rudder : index of the drive whose angle is the manoeuvring model's rudder and whose force the model
        takes from its derivatives (:data:`NO_DRIVE` for a DP vessel)
    """
    tx, ty, tn = drives_force(const, state, codes, rudder)
    delta = state[S_ANGLE, rudder] if rudder >= 0 else 0.0
    rk4_step(x, model, p, h, tx + ex, ty + ey, tn + en, cn, ce, delta)
    drives_update(const, state, codes, bank, t, h)


@kernel(UniTuple(f8, 6)(f8, f8, f8, f8, f8_1d, f8_1d, f8_1d, f8_2d))
def wave_sums(t: float, d: float, d_rate: float, weight: float, omega: np.ndarray, k: np.ndarray, eps: np.ndarray,
              weights: np.ndarray) -> tuple[float, float, float, float, float, float]:
    """WF motion, its yaw rate and the drift envelope of one wave field (see :mod:`sim_plant.environment.waves`).

    With φ_i = ω_i t − k_i d + ε_i (seed 001 eqs. (8)–(11), (34))::

        x_w = Σ a_i X_i sin φ_i,   y_w = Σ a_i Y_i sin φ_i,   ψ_w = −Σ a_i Ψ_i cos φ_i,
        ψ̇_w = Σ a_i Ψ_i (ω_i − k_i ḋ) sin φ_i,   A = Σ b_i e^{iφ_i}

    Parameters
    ----------
    t : time [s]
    d, d_rate : LF position [m] and speed [m/s] along the propagation direction
    weight : cross-fade weight applied to every output
    omega, k, eps : (n,) frequencies [rad/s], wave numbers [rad/m], phases [rad]
    weights : (len(WAVE_WEIGHTS), n) a_i X_i [m], a_i Y_i [m], a_i Ψ_i [rad], b_i [√(N/m)]

    Returns
    -------
    tuple of 6 float
        (x_w [m], y_w [m], ψ_w [rad], ψ̇_w [rad/s], Re A, Im A), weighted.
    """
    x = y = psi = rate_w = rate_k = re_a = im_a = 0.0
    for i in range(omega.size):
        phi = omega[i] * t - k[i] * d + eps[i]
        s = math.sin(phi)
        c = math.cos(phi)
        a_psi = weights[W_PSI, i]
        b = weights[W_B, i]
        x += weights[W_X, i] * s
        y += weights[W_Y, i] * s
        psi += a_psi * c
        rate_w += a_psi * omega[i] * s
        rate_k += a_psi * k[i] * s
        re_a += b * c
        im_a += b * s
    rate = rate_w - d_rate * rate_k
    return (weight * x, weight * y, -weight * psi, weight * rate, weight * re_a, weight * im_a)


@kernel(f8(f8, f8_1d, f8_1d, f8_1d))
def cosine_sum(t: float, omega: np.ndarray, phase: np.ndarray, amplitude: np.ndarray) -> float:
    """x(t) = Σ c_j cos(ω_j t + θ_j) of a :class:`~sim_plant.environment.spectra.SpectralProcess`.

    Parameters
    ----------
    t : time [s]
    omega, phase, amplitude : (n,) frequencies [rad/s], phases [rad], amplitudes [unit of x]
    """
    x = 0.0
    for j in range(omega.size):
        x += amplitude[j] * math.cos(omega[j] * t + phase[j])
    return x
