"""Compiled per-step kernels of the position controllers: the MRAC-augmented PD (seed 003 eqs. (15)–(25))
and the nonlinear PID / PD + bias feed-forward.

Why kernels (see :mod:`dpbase.jit`): one MRAC step is three SISO loops of a few dozen floating-point
operations each — the reference model's acceleration, the errors in the vessel-parallel frame, the control
law, the adaptive law with its gating, dead zone, leakage and projection, and the exact advance of the
reference model. As Python floats that was ~700 bytecodes and a list or tuple per intermediate, ≈ 30 µs per
step (≈ 100 µs on the cold caches of a live cycle); the PID's numpy products on 3-vectors cost 30–50 µs.
Here each is one call.

The functions are the code they replaced, written as loops over the DOFs with the same operations in the
same order, with two exceptions, both in the last bits:

* the MRAC reference model's transition matrix is the closed form of ``exp(A dt)`` for this step's ``dt``
  (:func:`reference_transition`) instead of scipy's ``expm`` cached per ``dt``: the cache missed on every
  step of the live loop, whose measured period jitters by more than its 1e-6 tolerance, and three ``expm``
  calls cost ≈ 170 µs;
* the PID's matrix products are sums in index order instead of numpy's ``@`` (BLAS, whose kernels may fuse
  multiply and add, differently on different machines).

MRAC data layout (C-contiguous float64; built by :class:`~dpcontrol.control.mrac.MracController`, the DOFs
surge, sway, yaw along the last axis; the PID's layout is given with its constants, above :func:`pid_step`):

* ``const`` (``C_ROWS``, 3): ``C_BETA0`` β₀ = ω_M² [1/s²], ``C_BETA1`` β₁ = 2ζω_M [1/s], ``C_G12`` g₁₂,
  ``C_G_RATIO`` g₂₂/g₁₂ [s] (eq. (20)), ``C_GAMMA_M``/``C_GAMMA_C`` Γ₁₁, Γ₂₂, ``C_DEAD_ZONE`` d₀
  [m, m, rad], ``C_ACCEL``/``C_VELOCITY`` the gating thresholds, ``C_A2_LO``/``C_A2_HI``/``C_A1_LO``/
  ``C_A1_HI`` the projection bounds, ``C_A2_NOMINAL``/``C_A1_NOMINAL`` the nominal parameters,
  ``C_OMEGA`` ω_M [rad/s] and ``C_ZETA`` ζ of eq. (15), ``C_FLAGS`` = (σ [1/s], adapt,
  reference regressor) (1.0 = true), ``C_MASS`` (3 rows) the nominal M [kg, kg·m, kg·m²],
  ``C_DAMPING`` (3 rows) the nominal D with a zero diagonal [N·s/m, N·s, N·m·s/rad], ``C_COUPLING`` =
  (``COUPLE_*`` bits, κ of the damping bound (0: none), unused), ``C_DRAG`` the quadratic damping
  [N·s²/m², N·s²/m², N·m·s²], ``C_ENTRY_REST`` how long the reference model must have rested
  after an entry into DP before anything is learnt [s] (0: no wait) and ``C_GUIDED`` = (1.0: y_M is the
  guidance's reference itself, 0.0: the second-order model (15) driven by it, unused, unused),
  ``C_NOISE_FACTOR`` k and ``C_NOISE_TIME`` T_n [s] of the measured dead zone (:func:`dead_zone_width`),
  ``C_LEAD`` the actuator time constant T_u [s] of the feed-forward's lead (:func:`mrac_step`; 0: none),
  ``C_INTEGRAL`` κ_I [1/s] of the integral action ``K_I = κ_I â₂β₀`` (:func:`_integral_force`; 0: none) and
  ``C_TRACKING`` its anti-windup's 1/T_t [1/s];
* ``state`` (``S_ROWS``, 3): ``S_Y_M``/``S_YD_M`` the reference model y_M, ẏ_M in NED [m, rad; m/s,
  rad/s], ``S_A2``/``S_A1`` the estimates â₂, â₁, ``S_COMMAND``/``S_ACHIEVED`` the last command and
  the force the allocator achieved for it [N, N, N·m], ``S_FLAGS`` = (reference model initialised,
  achieved force known, ``S_WEATHER`` started) and ``S_REST`` how long the reference model has rested (gate closed,
  unbroken) since the entry, counted up to ``C_ENTRY_REST`` [s], ``S_NOISE`` the mean square of the
  normalised error s̄ while the reference rests [m², m², rad²], ``S_QUIET`` how long it has rested, counted
  up to ``C_NOISE_TIME`` [s], and ``S_WEATHER`` the weather force compensated, ``w = b̂ + τ̂_wind``, low-passed
  over ``C_NOISE_TIME`` [N, N, N·m] (:func:`dead_zone_width`), ``S_INTEGRAL`` the integral force τ_I
  [N, N, N·m] and ``S_DUTY`` its low-passed saturation side d̄ [-];
* ``out`` (``OUT_SIZE``,): ``OUT_TAU`` τ [N, N, N·m], ``OUT_ERROR`` e_b = Rᵀ(ψ̂)(η̂ − y_M) [m, m, rad],
  ``OUT_VELOCITY_ERROR`` ė_b [m/s, m/s, rad/s] and ``OUT_PARAMETERS`` (â₂, â₁ after the adaptation,
  y_M before the advance: the order of ``PARAMETER_NAMES + REFERENCE_MODEL_NAMES``).
"""

from __future__ import annotations

import math

import numpy as np

from dpbase.frames import ssa_compiled as ssa
from dpbase.jit import UniTuple, b1, f8, f8_1d, f8_2d, i8, kernel, void

C_BETA0, C_BETA1, C_G12, C_G_RATIO, C_GAMMA_M, C_GAMMA_C, C_DEAD_ZONE, C_ACCEL, C_VELOCITY = range(9)
C_A2_LO, C_A2_HI, C_A1_LO, C_A1_HI, C_A2_NOMINAL, C_A1_NOMINAL, C_OMEGA, C_ZETA, C_FLAGS = range(9, 18)
C_ENTRY_REST = 18
C_GUIDED = 19
C_MASS = 20  # three rows: the nominal M (3×3) of the known coupling terms
C_DAMPING = 23  # three rows: the nominal D with its diagonal zeroed (the off-diagonal damping)
C_COUPLING = 26  # (COUPLE_* bit mask, κ of the damping bound, unused)
C_DRAG = 27  # the quadratic damping coefficients of the optional drag term [N·s²/m², N·s²/m², N·m·s²]
C_NOISE_FACTOR = 28  # k of the measured dead zone d = max(d₀, k·s̄_rms) (0: the fixed d₀ only) [-]
C_NOISE_TIME = 29  # the averaging time of s̄_rms at rest [s] (> 0)
C_LEAD = 30  # T_u, the time constant of the actuators' first-order lag the feed-forward leads by [s] (0: no lead)
C_INTEGRAL = 31  # κ_I, the integral gain per unit of the PD's stiffness, K_I = κ_I â₂β₀ [1/s] (0: no integrator)
C_TRACKING = 32  # 1/T_t, the integral's back-calculation gain and the saturation side's low-pass rate [1/s]
C_ROWS = 33
#: ``C_COUPLING[0]`` bits: which known terms of the nominal model enter the law (see :func:`_known_coupling`)
COUPLE_INERTIA, COUPLE_ROTATION, COUPLE_CORIOLIS, COUPLE_DAMPING, COUPLE_DRAG = 1, 2, 4, 8, 16
S_Y_M, S_YD_M, S_A2, S_A1, S_COMMAND, S_ACHIEVED, S_FLAGS, S_REST, S_NOISE, S_QUIET, S_WEATHER = range(11)
S_INTEGRAL = 11  # the integral force τ_I [N, N, N·m] (with ``C_INTEGRAL``)
S_DUTY = 12  # the low-passed saturation side d̄ of the integral's anti-windup [-] (as the PID's ``P_DUTY``)
S_ROWS = 13
OUT_TAU, OUT_ERROR, OUT_VELOCITY_ERROR, OUT_PARAMETERS = 0, 3, 6, 9
OUT_REFERENCE_MODEL = OUT_PARAMETERS + 6  # y_M, the last three of the parameters
OUT_SIZE = 18

#: :func:`mrac_step`'s return value for an input that is not 3 finite numbers: ``ERROR_INPUT - k`` for the
#: k-th vector argument (0 η̂, 1 ν̂, 2 b̂, 3 τ̂_wind, 4 η_d, 5 η̇_d, 6 η̈_d); a result >= 0 is the excitation bit mask (bit i:
#: DOF i) plus ``MASS_CHANGED`` when an estimate â₂ changed.
ERROR_INPUT = -1
MASS_CHANGED = 8
SATURATION_TOLERANCE = 1e-6
#: |low-passed saturation side| above which a DOF counts as saturated at low frequency: short on one side more
#: than half of the time, i.e. the low-frequency demand (the median of a demand with a symmetric wave-frequency
#: part) is itself beyond what the thrusters give; below it only wave-frequency peaks are cut
SATURATED_DUTY = 0.5


@kernel(UniTuple(f8, 4)(f8, f8, f8))
def reference_transition(omega: float, zeta: float, dt: float) -> tuple[float, float, float, float]:
    """``Φ = exp(A dt)`` of the reference model (15), ``A = [[0, 1], [−ω², −2ζω]]``, in closed form.

    By Cayley–Hamilton ``exp(A t) = e^{−ζωt} (C(t) I + S(t) (A + ζω I))`` with ``C = cos ω_d t``,
    ``S = sin(ω_d t)/ω_d``, ``ω_d = ω√(1 − ζ²)`` (ζ < 1), ``C = 1, S = t`` (ζ = 1) and
    ``C = cosh κt``, ``S = sinh(κt)/κ``, ``κ = ω√(ζ² − 1)`` (ζ > 1); each form is continuous in ζ.

    Parameters
    ----------
    omega : float
        ω_M [rad/s] (> 0).
    zeta : float
        ζ [-] (> 0).
    dt : float
        Sample time [s].

    Returns
    -------
    φ₁₁, φ₁₂, φ₂₁, φ₂₂ : float
        ``[y, ẏ]ₖ₊₁ − [r, 0] = Φ ([y, ẏ]ₖ − [r, 0])`` for a reference ``r`` held over the sample (the
        model's equilibrium is ``y = r``: the input matrix of the zero-order hold is ``(I − Φ)[1, 0]ᵀ``).
    """
    decay = math.exp(-zeta * omega * dt)
    if zeta < 1.0:
        rate = omega * math.sqrt(1.0 - zeta * zeta)
        c = math.cos(rate * dt)
        s = math.sin(rate * dt) / rate
    elif zeta > 1.0:
        rate = omega * math.sqrt(zeta * zeta - 1.0)
        c = math.cosh(rate * dt)
        s = math.sinh(rate * dt) / rate
    else:
        c = 1.0
        s = dt
    damped = zeta * omega * s
    return decay * (c + damped), decay * s, -omega * omega * decay * s, decay * (c - damped)


@kernel(i8(f8_1d))
def _valid3(v: np.ndarray) -> int:
    """1 if ``v`` holds 3 finite numbers, else 0."""
    if v.size != 3:
        return 0
    return 1 if math.isfinite(v[0]) and math.isfinite(v[1]) and math.isfinite(v[2]) else 0


@kernel(f8(f8, f8, f8, f8, f8))
def _adapted(a: float, nominal: float, rate: float, k: float, dt: float) -> float:
    """One MRAC parameter after ``dt`` of its law (seed 003 eq. (21)) with the rate ``f`` held constant.

    With leakage ``k = σγ > 0`` (σ-modification â̇ = f − σγ(â − â_nom)) the exact solution over ``dt``;
    with ``k = 0`` the plain integral ``â + dt·f``.
    """
    if k > 0.0:
        target = nominal + rate / k
        return target + (a - target) * math.exp(-k * dt)
    return a + dt * rate


@kernel(i8(f8_1d, f8_1d, f8_1d, f8_1d))
def _state_inputs_error(eta: np.ndarray, nu: np.ndarray, bias: np.ndarray, wind: np.ndarray) -> int:
    """0 when the estimate, bias and wind vectors each hold 3 finite numbers, else ``ERROR_INPUT − k`` for
    the first (k-th, from 0) that does not: the check both controller steps start with."""
    if _valid3(eta) == 0:
        return ERROR_INPUT
    if _valid3(nu) == 0:
        return ERROR_INPUT - 1
    if _valid3(bias) == 0:
        return ERROR_INPUT - 2
    if _valid3(wind) == 0:
        return ERROR_INPUT - 3
    return 0


@kernel(UniTuple(f8, 6)(f8_1d, f8_1d, f8_1d, f8_1d, f8_1d, b1, f8_2d, f8_2d))
def _reference_now(eta: np.ndarray, nu: np.ndarray, r: np.ndarray, rd: np.ndarray, rdd: np.ndarray, guided: bool,
                   const: np.ndarray, state: np.ndarray) -> tuple[float, float, float, float, float, float]:
    """The reference at t_k, written into ``state``'s y_M, ẏ_M; returns (r − y_M, ÿ_M) in NED.

    Guided: y_M is the guidance's η_d itself (one reference: bumpless already, with its rates); r − y_M = 0.
    Otherwise model (15) with u_c = k_M r, started at the estimate on its first step (bumpless, moving as the
    vessel moves); the heading difference the short way.
    """
    y_m = state[S_Y_M]
    yd_m = state[S_YD_M]
    if guided:
        for i in range(3):
            y_m[i] = r[i]
            yd_m[i] = rd[i]
        y_m[2] = ssa(r[2])
        state[S_FLAGS, 0] = 1.0
        return 0.0, 0.0, 0.0, rdd[0], rdd[1], rdd[2]
    if state[S_FLAGS, 0] == 0.0:
        c = math.cos(eta[2])
        s = math.sin(eta[2])
        y_m[0] = eta[0]
        y_m[1] = eta[1]
        y_m[2] = ssa(eta[2])
        yd_m[0] = c * nu[0] - s * nu[1]
        yd_m[1] = s * nu[0] + c * nu[1]
        yd_m[2] = nu[2]
        state[S_FLAGS, 0] = 1.0
    beta0 = const[C_BETA0]
    beta1 = const[C_BETA1]
    d0 = r[0] - y_m[0]
    d1 = r[1] - y_m[1]
    d2 = ssa(r[2] - y_m[2])
    return (d0, d1, d2, beta0[0] * d0 - beta1[0] * yd_m[0], beta0[1] * d1 - beta1[1] * yd_m[1],
            beta0[2] * d2 - beta1[2] * yd_m[2])


@kernel(f8(f8, f8, f8))
def _clamp(x: float, lo: float, hi: float) -> float:
    """Python's ``min(max(x, lo), hi)``."""
    y = lo if lo > x else x
    return hi if hi < y else y


@kernel(f8(f8_2d, f8_2d, i8, f8, f8, b1, f8, f8))
def dead_zone_width(const: np.ndarray, state: np.ndarray, i: int, s_bar: float, dt: float, resting: bool,
                    weather: float, stiffness: float) -> float:
    """The dead zone of DOF ``i`` on ``s̄ = e + (g₂₂/g₁₂)ė`` [m, m, rad], sized from the error the weather causes.

    The robust adaptive law's dead zone must exceed the tracking error that the bounded disturbance alone causes
    (Ioannou & Sun, *Robust Adaptive Control*, §8.5.4: inside it the error carries no information about the
    parameters, and adapting on it is what makes them drift). In DP that error — the residual wave-frequency
    motion, the estimator's noise, the weather force the bias estimate has not taken up and its slow wander —
    depends on the sea, not on the vessel alone, so it is measured: once the reference has rested for T_n
    (``C_NOISE_TIME``, one reference-model period; ``resting``: the mass gate of eq. (21) closed and
    ``|ẏ_M| ≤ v_min``) the law's model error no longer acts (it acts only through the reference's acceleration
    and velocity, and the error dynamics (19) have settled within a period) and the error is all disturbance.
    Its mean square is averaged there, ``s̄²_rms ← s̄²_rms + (1 − e^{−dt/T_n})(s̄² − s̄²_rms)``, and held
    otherwise: a Gaussian error exceeds k = 3 of its standard deviations (the RMS about zero, which includes its
    mean) with a probability of 0.3 %.

    What the rest does not show is the weather force that changes during a move: a turn swings a current or wind
    force across the hull (in the body axes the law works in), the drag changes with ν − ν_c, and the bias
    estimate takes the change up only with its lag, the error meanwhile growing to metres. The force compensated,
    ``w = b̂ + τ̂_wind`` (``weather`` [N, N, N·m]), is low-passed over T_n into w̄ (``S_WEATHER``, at every step);
    ``|w − w̄|``, the change of the last reference-model period, over the loop's stiffness ``P = â₂β₀``
    (``stiffness``, seed 003 eq. (25)) is the error such a change causes.

    The dead zone is ``d = max(d₀, k·s̄_rms + |w − w̄|/P)`` (k = ``C_NOISE_FACTOR``; 0: the fixed d₀ alone).

    ``S_QUIET`` counts how long the reference has rested without a break, up to T_n [s].
    """
    factor = const[C_NOISE_FACTOR, i]
    width = const[C_DEAD_ZONE, i]
    if factor <= 0.0:
        return width
    settle = const[C_NOISE_TIME, i]
    quiet = state[S_QUIET, i] + dt if resting else 0.0
    state[S_QUIET, i] = quiet if quiet < settle else settle
    alpha = 1.0 - math.exp(-dt / settle)  # (one low-pass weight for both averages)
    mean_square = state[S_NOISE, i]
    if quiet >= settle:
        mean_square += alpha * (s_bar * s_bar - mean_square)
        state[S_NOISE, i] = mean_square
    if state[S_FLAGS, 2] == 0.0:
        state[S_WEATHER, i] = weather
    mean = state[S_WEATHER, i]
    mean += alpha * (weather - mean)
    state[S_WEATHER, i] = mean
    measured = factor * math.sqrt(mean_square) + abs(weather - mean) / stiffness
    return measured if measured > width else width


@kernel(f8(f8_2d, i8, f8))
def damping_ceiling(const: np.ndarray, i: int, a2: float) -> float:
    """The upper projection bound of â₁ in DOF ``i`` for the mass estimate ``a2`` [N·s/m, N·s/m, N·m·s/rad].

    The frozen loop of seed 003 eq. (23), ``m ÿ + (c + â₂β₁ − â₁) ẏ + â₂β₀ y = (â₂/m_M) u_c``, is stable only
    while ``c + â₂β₁ − â₁ > 0``. Where â₁ adapts (Γ₂₂ > 0) its bound is therefore
    ``min(ĉ_max, ĉ_min + κ β₁ â₂)`` with ``ĉ_min`` the lower projection bound (the least damping the vessel
    is taken to have, c ≥ ĉ_min) and κ = ``C_COUPLING[1]`` < 1: every admissible pair leaves the frozen loop
    the damping ``c + â₂β₁ − â₁ ≥ (1 − κ) β₁ â₂ > 0``. (The static ``max(dhi·c_nom, m_nom β₁)`` alone let
    â₁ reach ``m_nom β₁`` with â₂ at ``0.3 m_nom``: a negative damping ``c − 0.7 m_nom β₁``.) Where â₁ is
    fixed (Γ₂₂ = 0, the default) it stays the model's c_nom and only the static bound applies.
    """
    ceiling = const[C_A1_HI, i]
    kappa = const[C_COUPLING, 1]
    if kappa > 0.0 and const[C_GAMMA_C, i] > 0.0:
        ceiling = min(ceiling, const[C_A1_LO, i] + kappa * const[C_BETA1, i] * a2)
    return ceiling


@kernel(void(i8, f8, f8_1d, f8_1d))
def _rotate_acceleration(couple: int, r_m: float, nu_m: np.ndarray, accel: np.ndarray) -> None:
    """With ``COUPLE_ROTATION``: ``accel`` = Rᵀÿ_M becomes ν̇_M = d/dt(Rᵀ(ψ)ẏ_M) = Rᵀÿ_M − S(r_M)ν_M, the
    body-frame acceleration of the reference, whose rotation term ``[r_M v_M, −r_M u_M, 0]`` [m/s²] the plain
    Rᵀÿ_M leaves out (``r_M`` = ẏ_M,ψ the reference's yaw rate [rad/s], ``nu_m`` = ν_M = Rᵀẏ_M)."""
    if couple & COUPLE_ROTATION:
        accel[0] += r_m * nu_m[1]
        accel[1] -= r_m * nu_m[0]


@kernel(void(i8, i8, f8_1d, f8_1d, f8_1d, f8_2d, f8_1d))
def _known_coupling(couple: int, mask: int, z: np.ndarray, nu_m: np.ndarray, nu: np.ndarray, const: np.ndarray,
                    known: np.ndarray) -> None:
    """The coupling force of the nominal model that the per-DOF law (18) leaves out, into ``known`` [N, N, N·m].

    With the plant ``M ν̇ + C(ν)ν + Dν = τ`` (seed 002 eqs. (1)–(10)) and the law
    ``τ = diag(â₂) z + diag(â₁) ν + h`` the known part is

    * ``COUPLE_INERTIA``: ``Σ_{j≠i} M_ij z_j`` (the supply vessel's M₂₃: sway–yaw), ``z_j`` of eq. (17) of an
      enabled DOF j (a DOF not controlled has no error dynamics to shape);
    * ``COUPLE_CORIOLIS``: ``C(ν_M)ν_M`` of the nominal M at the reference's body velocity ν_M = Rᵀẏ_M, in the
      plant's Kirchhoff form ``[−p₂r, p₁r, p₂u − p₁v]``, p = Mν_M (the (M₁₁ − M₂₂) u v Munk moment, the
      −M₂₂ v r and M₁₁ u r forces);
    * ``COUPLE_DAMPING``: ``Σ_{j≠i} D_ij ν_j`` (the off-diagonal linear damping, on the velocity as â₁ν);
    * ``COUPLE_DRAG`` (optional, not in the default): ``d_i |ν_M,i| ν_M,i``, the quadratic damping at the
      reference's velocity over ground — right in still water; in a current the drag acts on ν − ν_c, which the
      controller does not know (the bias estimate takes up its mean).

    The rotation term of the acceleration (``COUPLE_ROTATION``) is in ``z`` itself (see :func:`mrac_step`).
    With all four the error dynamics are ``M (ë + β₁ė + β₀e) = diag(v) ã`` (+ what the nominal model gets
    wrong): with the same β₀, β₁ in every DOF, ``V = xᵀ(M ⊗ G)x + ãᵀΓ⁻¹ã`` gives ``V̇ = −xᵀ(M ⊗ Q_C)x`` for
    the per-DOF law (21) unchanged — the M of the cross term cancels against M⁻¹ of the error dynamics.
    """
    m = const[C_MASS:C_MASS + 3]
    if couple & COUPLE_INERTIA:
        for i in range(3):
            for j in range(3):
                if j != i and (mask >> j) & 1:
                    known[i] += m[i, j] * z[j]
    if couple & COUPLE_CORIOLIS:
        u = nu_m[0]
        v = nu_m[1]
        r = nu_m[2]
        p1 = m[0, 0] * u + m[0, 1] * v + m[0, 2] * r
        p2 = m[1, 0] * u + m[1, 1] * v + m[1, 2] * r
        known[0] -= p2 * r
        known[1] += p1 * r
        known[2] += p2 * u - p1 * v
    if couple & COUPLE_DRAG:
        drag = const[C_DRAG]
        for i in range(3):
            known[i] += drag[i] * abs(nu_m[i]) * nu_m[i]
    if couple & COUPLE_DAMPING:
        d = const[C_DAMPING:C_DAMPING + 3]
        for i in range(3):
            for j in range(3):
                if j != i:
                    known[i] += d[i, j] * nu[j]


@kernel(void(f8_2d, b1, f8_1d, f8_1d, f8, f8, f8, f8, f8, f8_1d, f8_1d))
def _feedforward(const: np.ndarray, leads: bool, rd: np.ndarray, yd_m: np.ndarray, ydd0: float, ydd1: float,
                 ydd2: float, c: float, s: float, ydd_b: np.ndarray, ff_b: np.ndarray) -> None:
    """The feed-forward acceleration ``ff_b`` of z (17) [m/s², m/s², rad/s²]: the reference's body-frame
    acceleration ``ydd_b``, plus with ``leads`` the actuator lead ``T_u y⃛_M`` (``C_LEAD``).

    ``y⃛_M = β₀(η̇_d − ẏ_M) − β₁ÿ_M`` is model (15), ``ÿ_M = β₀(r − y_M) − β₁ẏ_M``, differentiated (NED:
    ``rd`` = η̇_d, ``yd_m`` = ẏ_M, ``ydd*`` = ÿ_M [m/s², m/s², rad/s²]), rotated into body axes with
    ``c, s = cos ψ̂, sin ψ̂`` [m/s³, m/s³, rad/s³].
    """
    for i in range(3):
        ff_b[i] = ydd_b[i]
    if not leads:
        return
    b0 = const[C_BETA0]
    b1 = const[C_BETA1]
    lead = const[C_LEAD]
    j0 = b0[0] * (rd[0] - yd_m[0]) - b1[0] * ydd0
    j1 = b0[1] * (rd[1] - yd_m[1]) - b1[1] * ydd1
    ff_b[0] += lead[0] * (c * j0 + s * j1)
    ff_b[1] += lead[1] * (-s * j0 + c * j1)
    ff_b[2] += lead[2] * (b0[2] * (rd[2] - yd_m[2]) - b1[2] * ydd2)


@kernel(f8(f8, f8, f8, f8_1d, i8, f8, f8))
def _antiwindup(increment: float, command: float, achieved: float, duty: np.ndarray, i: int, rate: float,
                dt: float) -> float:
    """The integral's increment of DOF i after the anti-windup of the PID and the MRAC's integrator [N, N·m].

    The side on which the allocator fell short of the last ``command`` (``achieved`` above it: +1, below: −1,
    met: 0) is low-passed over T_t into ``duty[i]`` (``rate`` = 1/T_t [1/s]; not filtered in a DOF without T_t,
    i.e. without integral). Where it stays beyond :data:`SATURATED_DUTY` on the side the DOF is short now — the
    low-frequency demand itself beyond capability, not the wave-frequency peaks cut or the allocator's rounding —
    nothing is integrated further into that side (conditional integration) and the integral is pulled back
    towards the force achieved (back-calculation).
    """
    shortfall = achieved - command
    side = 0.0
    if abs(shortfall) > SATURATION_TOLERANCE * (1.0 + abs(command)):
        side = 1.0 if shortfall > 0.0 else -1.0
    alpha = 1.0 - math.exp(-dt * rate) if rate > 0.0 else 1.0
    duty[i] += alpha * (side - duty[i])
    if abs(duty[i]) > SATURATED_DUTY and side * duty[i] > 0.0:
        if increment * duty[i] < 0.0:
            increment = 0.0
        increment += dt * rate * shortfall
    return increment


@kernel(f8(f8_2d, f8_2d, i8, f8, i8, f8))
def _integral_force(const: np.ndarray, state: np.ndarray, i: int, error: float, mask: int, dt: float) -> float:
    """Advance DOF i's integral force ``τ̇_I = −K_I e``, ``K_I = κ_I â₂β₀`` (the PD's stiffness of eq. (25) times
    κ_I = ``integral_ratio`` · ω_M, the rule of :func:`dpcontrol.control.pid.pole_placement_gains`), and return the
    weather force it compensates, ``−τ_I`` [N, N·m] (subtracted in (18) where b̂ would be).

    The integral action of the MRAC where the estimator gives no bias (seed 004's Kalman–Bucy filter): seed 003's
    law compensates the wave filter's bias, whose integral over the LF error is the commercial PD's integral
    action; without it the mean current and wind force leave an offset w/P. Anti-windup as the PID's
    (:func:`_antiwindup`, T_t from ``C_TRACKING``). A DOF not controlled is cleared.
    """
    integral = state[S_INTEGRAL]
    duty = state[S_DUTY]
    if not (mask >> i) & 1:
        integral[i] = 0.0
        duty[i] = 0.0
        return 0.0
    increment = -const[C_INTEGRAL, i] * state[S_A2, i] * const[C_BETA0, i] * error * dt
    if state[S_FLAGS, 1] != 0.0:  # the force achieved for the last command is known
        increment = _antiwindup(increment, state[S_COMMAND, i], state[S_ACHIEVED, i], duty, i,
                                const[C_TRACKING, i], dt)
    integral[i] += increment
    return -integral[i]


@kernel(i8(f8, f8_1d, f8_1d, f8_1d, f8_1d, f8_1d, f8_1d, f8_1d, i8, f8_2d, f8_2d, f8_1d))
def mrac_step(dt: float, eta: np.ndarray, nu: np.ndarray, bias: np.ndarray, wind: np.ndarray, r: np.ndarray,
              rd: np.ndarray, rdd: np.ndarray, mask: int, const: np.ndarray, state: np.ndarray, out: np.ndarray) -> int:
    """One MRAC period: control law (17)–(18), adaptive law (21) and the exact advance of model (15).

    The law per DOF i is ``τ_i = â₂ᵢ z_i + â₁ᵢ ν_i + h_i − b̂_i − τ̂_wind,i`` with z of eq. (17) on the reference's
    body-frame acceleration and ``h`` the known coupling of the nominal model (``C_COUPLING``: the rotation
    term in z, :func:`_rotate_acceleration`; the rest in :func:`_known_coupling`; h = 0 and z on Rᵀÿ_M for
    seed 003's diagonal law). With the actuator lead (``C_LEAD`` T_u > 0, model (15) only) the acceleration in z is
    ``ÿ_M + T_u y⃛_M``, ``y⃛_M = β₀(η̇_d − ẏ_M) − β₁ÿ_M`` the derivative of (15) [m/s³, m/s³, rad/s³] rotated
    into body axes: through the actuators' lag ``1/(1 + T_u s)`` the force delivered is the desired compensation
    ``â₂ÿ_M`` the law's regressor assumes (see :mod:`dpcontrol.control.mrac`, "The actuators' lag"). With the
    integral action (``C_INTEGRAL`` > 0) ``−τ_I`` of :func:`_integral_force` takes the place of b̂.

    Parameters
    ----------
    dt : float
        Sample time [s] (> 0, checked by the caller).
    eta, nu, bias, wind : ndarray, shape (3,)
        η̂ in NED [m, m, rad], ν̂ [m/s, m/s, rad/s], b̂ and τ̂_wind in body axes [N, N, N·m].
    r, rd, rdd : ndarray, shape (3,)
        The guidance's reference η_d [m, m, rad], η̇_d [m/s, m/s, rad/s], η̈_d [m/s², m/s², rad/s²] (NED):
        with ``C_GUIDED`` the reference model's state itself (y_M = η_d), otherwise η_d drives model (15)
        (``u_c = k_M r``) and only η̇_d is used, by the actuator lead.
    mask : int
        Controlled DOFs, bit i for DOF i (surge 1, sway 2, yaw 4).
    const, state, out : ndarray
        See the module docstring; ``state`` is updated, ``out`` written.

    Returns
    -------
    int
        The DOFs whose mass adaptation the reference model excited (bit mask) plus ``MASS_CHANGED`` when
        â₂ changed (>= 0), or ``ERROR_INPUT − k`` when the k-th vector is not 3 finite numbers (nothing
        changed then).
    """
    error = _state_inputs_error(eta, nu, bias, wind)
    if error != 0:
        return error
    if _valid3(r) == 0:
        return ERROR_INPUT - 4
    guided = const[C_GUIDED, 0] != 0.0
    leads = not guided and (const[C_LEAD, 0] > 0.0 or const[C_LEAD, 1] > 0.0 or const[C_LEAD, 2] > 0.0)
    if (guided or leads) and _valid3(rd) == 0:
        return ERROR_INPUT - 5
    if guided and _valid3(rdd) == 0:
        return ERROR_INPUT - 6
    y_m = state[S_Y_M]
    yd_m = state[S_YD_M]
    a2 = state[S_A2]
    a1 = state[S_A1]
    c = math.cos(eta[2])
    s = math.sin(eta[2])
    b0 = const[C_BETA0]
    b1 = const[C_BETA1]
    d0, d1, d2, ydd0, ydd1, ydd2 = _reference_now(eta, nu, r, rd, rdd, guided, const, state)
    # errors and reference in the vessel-parallel frame
    dn = eta[0] - y_m[0]
    de = eta[1] - y_m[1]
    e_b = out[OUT_ERROR:OUT_ERROR + 3]
    e_b[0] = c * dn + s * de
    e_b[1] = -s * dn + c * de
    e_b[2] = ssa(eta[2] - y_m[2])
    yd_b = np.empty(3)
    yd_b[0] = c * yd_m[0] + s * yd_m[1]
    yd_b[1] = -s * yd_m[0] + c * yd_m[1]
    yd_b[2] = yd_m[2]
    ydd_b = np.empty(3)
    ydd_b[0] = c * ydd0 + s * ydd1
    ydd_b[1] = -s * ydd0 + c * ydd1
    ydd_b[2] = ydd2
    couple = int(const[C_COUPLING, 0])
    _rotate_acceleration(couple, yd_m[2], yd_b, ydd_b)
    z = np.empty(3)  # starts as the feed-forward's acceleration: ÿ_M, led by T_u y⃛_M through the actuators' lag
    _feedforward(const, leads, rd, yd_m, ydd0, ydd1, ydd2, c, s, ydd_b, z)
    ed_b = out[OUT_VELOCITY_ERROR:OUT_VELOCITY_ERROR + 3]
    tau = out[OUT_TAU:OUT_TAU + 3]
    for i in range(3):
        ed_b[i] = nu[i] - yd_b[i]
        z[i] = z[i] - b1[i] * ed_b[i] - b0[i] * e_b[i]  # (17)
    known = np.zeros(3)
    _known_coupling(couple, mask, z, yd_b, nu, const, known)
    weather = np.empty(3)  # the weather force compensated: b̂, or −τ_I with the integral action
    for i in range(3):
        weather[i] = _integral_force(const, state, i, e_b[i], mask, dt) if const[C_INTEGRAL, i] > 0.0 else bias[i]
        tau[i] = a2[i] * z[i] + a1[i] * nu[i] + known[i] - weather[i] - wind[i] if (mask >> i) & 1 else 0.0  # (18)

    excited = 0
    mass_changed = False
    flags = const[C_FLAGS]
    if flags[1] != 0.0:  # adapting: eq. (21) with gating, dead zone, optional leakage and projection
        sigma = flags[0]
        command = state[S_COMMAND]
        achieved = state[S_ACHIEVED]
        known = state[S_FLAGS, 1] != 0.0
        for i in range(3):
            if not (mask >> i) & 1:
                continue
            if known and abs(achieved[i] - command[i]) > SATURATION_TOLERANCE * (1.0 + abs(command[i])):
                continue  # the allocator could not deliver the last command: nothing to learn
            mass_before = a2[i]
            # (21), each parameter only while the reference model excites it
            if flags[2] != 0.0:  # desired-compensation law: v_M = [ÿ_M, ẏ_M] instead of v = [z, ẏ]
                v2 = ydd_b[i]
                v1 = yd_b[i]
            else:
                v2 = z[i]
                v1 = nu[i]
            gate = abs(ydd_b[i]) > const[C_ACCEL, i]
            # normalised error signal s̄ = bᵀGx / g₁₂ with a continuous dead zone, then bᵀGx = g₁₂ s̄_dz
            s_bar = e_b[i] + const[C_G_RATIO, i] * ed_b[i]
            resting = not gate and abs(yd_b[i]) <= const[C_VELOCITY, i]
            excess = abs(s_bar) - dead_zone_width(const, state, i, s_bar, dt, resting, weather[i] + wind[i],
                                                  a2[i] * b0[i])
            signal = const[C_G12, i] * math.copysign(excess, s_bar) if excess > 0.0 else 0.0
            rest = state[S_REST, i]
            if rest < const[C_ENTRY_REST, i]:  # since the entry the reference has not rested long enough
                if gate:
                    gate = False  # (the glide that decelerates the drift: nothing to learn from it)
                    state[S_REST, i] = 0.0  # a rest is unbroken: ÿ_M passing through zero is none
                else:
                    state[S_REST, i] = rest + dt
            if gate:
                excited |= 1 << i
            gamma_m = const[C_GAMMA_M, i]
            gamma_c = const[C_GAMMA_C, i]
            rate2 = -gamma_m * v2 * signal if gate else 0.0
            rate1 = -gamma_c * v1 * signal if abs(yd_b[i]) > const[C_VELOCITY, i] else 0.0
            leak = sigma if sigma > 0.0 else 0.0  # no leakage (the default): the plain integral of (21)
            a2[i] = _adapted(a2[i], const[C_A2_NOMINAL, i], rate2, leak * gamma_m, dt)
            a1[i] = _adapted(a1[i], const[C_A1_NOMINAL, i], rate1, leak * gamma_c, dt)
            # projection onto the physical bounds
            a2[i] = _clamp(a2[i], const[C_A2_LO, i], const[C_A2_HI, i])
            a1[i] = _clamp(a1[i], const[C_A1_LO, i], damping_ceiling(const, i, a2[i]))
            if a2[i] != mass_before:
                mass_changed = True
        state[S_FLAGS, 2] = 1.0
    parameters = out[OUT_PARAMETERS:]
    for i in range(3):
        state[S_COMMAND, i] = tau[i]
        parameters[i] = a2[i]
        parameters[3 + i] = a1[i]
        parameters[6 + i] = y_m[i]

    if guided:  # (the guidance advances its own reference)
        return excited | MASS_CHANGED if mass_changed else excited
    # advance the reference model over the sample (exact ZOH discretisation of (15)), about its
    # equilibrium r (the heading unwrapped next to y_M)
    for i in range(3):
        p11, p12, p21, p22 = reference_transition(const[C_OMEGA, i], const[C_ZETA, i], dt)
        d = d0 if i == 0 else (d1 if i == 1 else d2)
        target = y_m[i] + d
        y_new = target + (p12 * yd_m[i] - p11 * d)
        yd_m[i] = p22 * yd_m[i] - p21 * d
        y_m[i] = y_new
    y_m[2] = ssa(y_m[2])
    return excited | MASS_CHANGED if mass_changed else excited


# ---------------------------------------------------------------------- nonlinear PID / PD + bias feed-forward
# PID layouts (built by :class:`~dpcontrol.control.pid.PidController`): ``gains`` (``G_ROWS``, 3) holds the
# matrices K_P, K_D, K_I, M, D (three rows each from ``G_KP``, ``G_KD``, ``G_KI``, ``G_MASS``, ``G_DAMPING``),
# the back-calculation gains 1/T_t [1/s] (``G_TRACKING``) and the integral limits [N, N, N·m] (``G_LIMIT``);
# ``structure`` bits ``P_INTEGRATOR``, ``P_MASS``, ``P_DAMPING``, ``P_LIMIT`` say which are in use;
# ``pid_state`` (``P_ROWS``, 3): ``P_INTEGRAL`` τ_I, ``P_COMMAND`` the last command, ``P_ACHIEVED`` the force the
# allocator achieved for it, ``P_FLAGS`` = (achieved force known, unused, unused) and ``P_DUTY`` the low-passed
# saturation side d̄ (+1 achieved above the command, −1 below, 0 met) [-]; ``pid_out`` (9,): τ, e_b, ė_b.
G_KP, G_KD, G_KI, G_MASS, G_DAMPING, G_TRACKING, G_LIMIT = 0, 3, 6, 9, 12, 15, 16
G_ROWS = 17
P_INTEGRATOR, P_MASS, P_DAMPING, P_LIMIT = 1, 2, 4, 8
P_INTEGRAL, P_COMMAND, P_ACHIEVED, P_FLAGS, P_DUTY = range(5)
P_ROWS = 5
PID_OUT_SIZE = 9


@kernel(f8(f8_2d, i8, i8, f8, f8, f8))
def _row_product(matrix: np.ndarray, first: int, i: int, x0: float, x1: float, x2: float) -> float:
    """Row ``i`` of the 3×3 block at ``matrix[first:first + 3]`` times ``x`` (sum in index order)."""
    row = first + i
    return matrix[row, 0] * x0 + matrix[row, 1] * x1 + matrix[row, 2] * x2


@kernel(i8(f8, f8_1d, f8_1d, f8_1d, f8_1d, f8_1d, f8_1d, f8_1d, i8, i8, f8_2d, f8_2d, f8_1d))
def pid_step(dt: float, eta: np.ndarray, nu: np.ndarray, bias: np.ndarray, wind: np.ndarray, eta_d: np.ndarray,
             eta_dot_d: np.ndarray, eta_ddot_d: np.ndarray, mask: int, structure: int, gains: np.ndarray,
             state: np.ndarray, out: np.ndarray) -> int:
    """One PID period (:mod:`dpcontrol.control.pid`): errors in the vessel-parallel frame, the control law and
    the integral force with conditional integration and back-calculation where the low-frequency demand is
    beyond capability (anti-windup).

    Parameters
    ----------
    dt : float
        Time since the previous step [s] (> 0, checked by the caller).
    eta, nu : ndarray, shape (3,)
        η̂ in NED [m, m, rad] and ν̂ [m/s, m/s, rad/s].
    bias, wind : ndarray, shape (3,)
        b̂ (compensated without the integrator) and τ̂_wind in body axes [N, N, N·m] (zeros when not given:
        subtracting 0.0 leaves every float as it is).
    eta_d, eta_dot_d, eta_ddot_d : ndarray, shape (>= 3,)
        The guidance's reference in NED (its first three entries).
    mask : int
        Controlled DOFs, bit i for DOF i.
    structure : int
        ``P_*`` bits of the configuration.
    gains, state, out : ndarray
        Layouts above; ``state`` is updated, ``out`` written.

    Returns
    -------
    int
        0, or ``ERROR_INPUT − k`` when the k-th of η̂, ν̂, b̂, τ̂_wind is not 3 finite numbers and
        ``ERROR_INPUT − 4`` when a reference vector is shorter than 3 (nothing changed then).

    Notes
    -----
    The matrix products are sums in index order; numpy's ``@`` called BLAS, whose kernels may fuse
    multiply and add, so τ can differ from that code in the last bits.
    """
    error = _state_inputs_error(eta, nu, bias, wind)
    if error != 0:
        return error
    if eta_d.size < 3 or eta_dot_d.size < 3 or eta_ddot_d.size < 3:
        return ERROR_INPUT - 4
    # e_b = Rᵀ(ψ̂)(η̂ − η_d), ν_d = Rᵀ(ψ̂)η̇_d, ν̇_d ≈ Rᵀ(ψ̂)η̈_d, ė_b = ν̂ − ν_d (seed 002 eq. (14); low-speed DP:
    # the S(r)ν_d term of ν̇_d dropped)
    psi = eta[2]
    c = math.cos(psi)
    s = math.sin(psi)
    dn = eta[0] - eta_d[0]
    de = eta[1] - eta_d[1]
    e0 = c * dn + s * de
    e1 = -s * dn + c * de
    e2 = ssa(psi - eta_d[2])
    v0 = c * eta_dot_d[0] + s * eta_dot_d[1]
    v1 = -s * eta_dot_d[0] + c * eta_dot_d[1]
    v2 = eta_dot_d[2]
    w0 = c * eta_ddot_d[0] + s * eta_ddot_d[1]
    w1 = -s * eta_ddot_d[0] + c * eta_ddot_d[1]
    w2 = eta_ddot_d[2]
    ed0 = nu[0] - v0
    ed1 = nu[1] - v1
    ed2 = nu[2] - v2
    integral = state[P_INTEGRAL]
    if structure & P_INTEGRATOR:
        # τ̇_I = −K_I e_b, with conditional integration and back-calculation towards the achieved force
        command = state[P_COMMAND]
        achieved = state[P_ACHIEVED]
        known = state[P_FLAGS, 0] != 0.0
        duty = state[P_DUTY]
        for i in range(3):
            increment = -_row_product(gains, G_KI, i, e0, e1, e2) * dt
            if known:
                increment = _antiwindup(increment, command[i], achieved[i], duty, i, gains[G_TRACKING, i], dt)
            integral[i] += increment
            if structure & P_LIMIT:  # np.clip: NaN propagates
                limit = gains[G_LIMIT, i]
                value = integral[i]
                value = value if (value >= -limit or math.isnan(value)) else -limit
                integral[i] = value if (value <= limit or math.isnan(value)) else limit
    for i in range(3):
        tau = -_row_product(gains, G_KP, i, e0, e1, e2) - _row_product(gains, G_KD, i, ed0, ed1, ed2)
        if structure & P_MASS:
            tau += _row_product(gains, G_MASS, i, w0, w1, w2)
        if structure & P_DAMPING:
            tau += _row_product(gains, G_DAMPING, i, v0, v1, v2)
        if structure & P_INTEGRATOR:
            tau += integral[i]
        else:
            tau -= bias[i]
        tau -= wind[i]
        if not (mask >> i) & 1:
            tau = 0.0
            integral[i] = 0.0
            state[P_DUTY, i] = 0.0
        out[i] = tau
        state[P_COMMAND, i] = tau
    out[3] = e0
    out[4] = e1
    out[5] = e2
    out[6] = ed0
    out[7] = ed1
    out[8] = ed2
    return 0
