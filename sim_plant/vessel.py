"""Truth vessel dynamics: nonlinear 3-DOF models integrated with fixed-step RK4.

State (both models): ``[north_m, east_m, psi_rad, u_mps, v_mps, r_radps]`` — LF position and
heading in NED, velocity over ground in body axes.

:class:`DpVesselModel` (DP vessels; seed 002 eqs. (1)–(8)) — with ν_c the current in body axes and
ν_r = ν − ν_c::

    η̇ = R(ψ) ν
    M_RB ν̇ + C_RB(ν) ν + M_A ν̇_r + C_A(ν_r) ν_r + D ν_r + d_q(ν_r) = τ_act + τ_wind + τ_drift

C_RB from M_RB = [[m,0,0],[0,m,m x_g],[0,m x_g,I_z]] (seed 002 eq. (4)); C_A(ν_r) from the added
mass M_A = M − M_RB (symmetrised), both in the skew-symmetric Kirchhoff form C(ν)ν = [−p₂r, p₁r,
p₂u − p₁v] with p = Mν (so νᵀC(ν)ν = 0: the Coriolis terms do no work — tested); linear D and
quadratic d_q = [X|u|u |u_r|u_r, Y|v|v |v_r|v_r, N|r|r |r|r] of the vessel data act on the velocity
relative to the water. The current forces of eq. (8) are represented by this relative-velocity
damping rather than by C_X, C_Y, C_N(γ_rc) tables: no CFD coefficients exist for these vessels, the
quadratic coefficients of :mod:`dpcontrol.models.vessels` are cross-flow drags on the submerged
projected areas (i.e. eq. (8) at 0° and 90°), the Munk moment (a22 − a11)u_r v_r of C_A supplies the
destabilising yaw moment of an oblique current, and every current force vanishes at ν_r = 0, so an
uncontrolled vessel ends up drifting exactly with the current (tested). For a constant current in
NED, ν̇_c = (r v_c, −r u_c, 0), hence M ν̇ = τ − C_RB(ν)ν − C_A(ν_r)ν_r − Dν_r − d_q + M_A ν̇_c
(slow variation of the current itself is neglected in ν̇_c).

The mass may change (offloading, seed 003): :meth:`DpVesselModel.set_mass_factor` rebuilds the
matrices (see :mod:`sim_plant.vessel_data` for the interpolation). The momentum carried by the oil
is neglected: 2.3 t/s at 0.05 m/s is about 100 N against MN-scale forces.

:class:`ManoeuvringVesselModel` (course keeping, the mariner of seed 002): surge speed through the
water held at u0 (engine at constant RPM; the autopilot commands the rudder only), sway and yaw
from the manoeuvring derivatives (prime system, nondimensionalised with U = |ν_r| and L)::

    M' [v̇_r, ṙ]ᵀ = [Y', N']ᵀ,  Y' = Y_v v' + Y_r r' + Y_δ δ,  N' = N_v v' + N_r r' + N_δ δ

— the linear model M ν̇ + N(u0) ν = b δ of Chislett & Strøm-Tejsen (see
:mod:`sim_plant.vessel_data`). Environmental and non-rudder thruster forces are added dimensionally.

Both models integrate with classical RK4 at the plant rate, in plain floats (no numpy, no
allocation except the small tuples of the four stages): the derivative is a closure over the
current parameters, rebuilt when they change.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from dpcontrol.models.frames import ssa
from dpcontrol.models.vessels import VesselData, rigid_body_mass_matrix
from sim_plant.environment.rao import HullDimensions
from sim_plant.environment.wind import BLENDERMANN_TYPES, WindCoefficients
from sim_plant.vessel_data import ManoeuvringDerivatives, PlantVesselExtras, extras_for

Derivative = Callable[..., tuple[float, float, float, float, float, float]]


def _inverse3(m: np.ndarray) -> list[float]:
    inv = np.linalg.inv(m)
    return [float(v) for v in inv.ravel()]


class _ModelBase:
    """Shared RK4 stepping and properties."""

    vessel: VesselData
    extras: PlantVesselExtras
    mass_factor: float
    _f: Derivative

    def step(self, x: list[float], h_s: float, tau_x_n: float, tau_y_n: float, tau_n_nm: float,  # noqa: PLR0917
             current_north_mps: float, current_east_mps: float, rudder_rad: float = 0.0) -> None:
        """One classical RK4 step of length ``h_s`` with inputs held constant (ZOH), in place.

        Plain positional floats on purpose: this runs tens of thousands of times per simulated hour
        and keyword passing or packing costs a measurable share of it.

        Parameters
        ----------
        x : list of float, length 6
            State [north_m, east_m, psi_rad, u_mps, v_mps, r_radps]; ψ is wrapped with ssa after
            the step.
        h_s : float
            Step [s].
        tau_x_n, tau_y_n, tau_n_nm : float
            External generalized force in body axes (thrusters + wind + drift).
        current_north_mps, current_east_mps : float
            Current velocity over ground (NED).
        rudder_rad : float
            Rudder angle for the manoeuvring model (ignored by the DP model).
        """
        f = self._f
        n, e, p, u, v, r = x
        a = (tau_x_n, tau_y_n, tau_n_nm, current_north_mps, current_east_mps, rudder_rad)
        k1 = f(p, u, v, r, *a)
        h2 = 0.5 * h_s
        k2 = f(p + h2 * k1[2], u + h2 * k1[3], v + h2 * k1[4], r + h2 * k1[5], *a)
        k3 = f(p + h2 * k2[2], u + h2 * k2[3], v + h2 * k2[4], r + h2 * k2[5], *a)
        k4 = f(p + h_s * k3[2], u + h_s * k3[3], v + h_s * k3[4], r + h_s * k3[5], *a)
        h6 = h_s / 6.0
        x[0] = n + h6 * (k1[0] + 2.0 * (k2[0] + k3[0]) + k4[0])
        x[1] = e + h6 * (k1[1] + 2.0 * (k2[1] + k3[1]) + k4[1])
        x[2] = ssa(p + h6 * (k1[2] + 2.0 * (k2[2] + k3[2]) + k4[2]))
        x[3] = u + h6 * (k1[3] + 2.0 * (k2[3] + k3[3]) + k4[3])
        x[4] = v + h6 * (k1[4] + 2.0 * (k2[4] + k3[4]) + k4[4])
        x[5] = r + h6 * (k1[5] + 2.0 * (k2[5] + k3[5]) + k4[5])

    def derivative(self, x: list[float], tau_b: tuple[float, float, float] = (0.0, 0.0, 0.0),
                   current_ned: tuple[float, float] = (0.0, 0.0), rudder_rad: float = 0.0
                   ) -> tuple[float, float, float, float, float, float]:
        """ẋ for a state (tests and diagnostics)."""
        return self._f(x[2], x[3], x[4], x[5], tau_b[0], tau_b[1], tau_b[2], current_ned[0], current_ned[1],
                       rudder_rad)


class DpVesselModel(_ModelBase):
    """Nonlinear 3-DOF low-speed model of a DP vessel (see the module docstring).

    Parameters
    ----------
    vessel : VesselData
    extras : PlantVesselExtras or None
        Plant-only data (default: :func:`sim_plant.vessel_data.extras_for`).
    """

    def __init__(self, vessel: VesselData, extras: PlantVesselExtras | None = None) -> None:
        self.vessel = vessel
        self.extras = extras if extras is not None else extras_for(vessel)
        self.mass_factor = math.nan
        self.set_mass_factor(1.0)

    def set_mass_factor(self, factor: float) -> None:
        """Set the loading: rigid-body mass = ``factor`` × the vessel's mass (see vessel_data)."""
        if not factor > 0.0:
            raise ValueError(f"mass factor must be > 0, got {factor}")
        if factor == self.mass_factor:
            return
        base = self.vessel
        loaded = self.extras.loaded
        mass = factor * base.mass_kg
        if loaded is not None:
            s = (factor - 1.0) / (loaded.mass_kg / base.mass_kg - 1.0)

            def lerp(a: float | np.ndarray, b: float | np.ndarray) -> float | np.ndarray:
                return a + s * (b - a)

            iz = float(lerp(base.iz_kgm2, loaded.iz_kgm2))
            xg = float(lerp(base.xg_m, loaded.xg_m))
            m_a = np.asarray(lerp(base.added_mass_matrix, loaded.added_mass_matrix))
            damping = np.asarray(lerp(base.damping_matrix, loaded.damping_matrix))
            quad = np.asarray(lerp(base.quadratic_damping, loaded.quadratic_damping))
            draft = float(lerp(base.draft_m, loaded.draft_m))
            areas = (float(lerp(base.frontal_wind_area_m2, loaded.frontal_wind_area_m2)),
                     float(lerp(base.lateral_wind_area_m2, loaded.lateral_wind_area_m2)))
            ballast = BLENDERMANN_TYPES[self.extras.wind_type]
            full = BLENDERMANN_TYPES[self.extras.loaded_wind_type or self.extras.wind_type]
            blend = tuple(float(lerp(a, b)) for a, b in zip(ballast, full, strict=True))
        else:
            iz = factor * base.iz_kgm2
            xg = base.xg_m
            m_a = factor * base.added_mass_matrix
            damping = np.array(base.damping_matrix)
            quad = np.array(base.quadratic_damping)
            draft = factor * base.draft_m
            areas = (base.frontal_wind_area_m2, base.lateral_wind_area_m2)
            blend = BLENDERMANN_TYPES[self.extras.wind_type]
        m_a = 0.5 * (m_a + m_a.T)
        m_rb = rigid_body_mass_matrix(mass, iz, xg)
        self.mass_matrix = m_rb + m_a
        self.added_mass_matrix = m_a
        self.damping_matrix = damping
        self.quadratic_damping = quad
        self.mass_kg = mass
        self.iz_kgm2 = iz
        self.xg_m = xg
        self.mass_factor = factor
        self.hull = HullDimensions(base.length_m, max(base.beam_m, 1e-6), max(draft, 1e-6))
        cdt, bow, stern, delta = blend
        self.wind = WindCoefficients(cdt, bow, stern, delta, areas[0], areas[1], base.length_m,
                                     self.extras.wind_centroid_frac * base.length_m)
        self._f = _dp_derivative(mass, xg, m_a, damping, quad, minv=_inverse3(self.mass_matrix))

    @property
    def surge_mass_kg(self) -> float:
        """True surge mass including added mass, M11 = m − X_u̇ [kg] (what MRAC estimates)."""
        return float(self.mass_matrix[0, 0])

    def kinetic_energy(self, x: list[float]) -> float:
        """½ νᵀ M ν [J] (M symmetric)."""
        nu = np.array(x[3:6])
        return float(0.5 * nu @ self.mass_matrix @ nu)


def _dp_derivative(m: float, xg: float, m_a: np.ndarray, d: np.ndarray, quad: np.ndarray, *,
                   minv: list[float]) -> Derivative:
    a11, a12, a13 = (float(v) for v in m_a[0])
    a21, a22, a23 = (float(v) for v in m_a[1])
    a31, a32 = float(m_a[2, 0]), float(m_a[2, 1])
    d11, d12, d13, d21, d22, d23, d31, d32, d33 = (float(v) for v in d.ravel())
    q1, q2, q3 = (float(v) for v in quad)
    i11, i12, i13, i21, i22, i23, i31, i32, i33 = minv
    mxg = m * xg
    cos = math.cos
    sin = math.sin

    def f(psi: float, u: float, v: float, r: float, tx: float, ty: float, tn: float, cn: float, ce: float,  # noqa: PLR0917
          rudder: float) -> tuple[float, float, float, float, float, float]:
        c = cos(psi)
        s = sin(psi)
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

    return f


class ManoeuvringVesselModel(_ModelBase):
    """Course-keeping truth model from manoeuvring derivatives (see the module docstring).

    Parameters
    ----------
    vessel : VesselData
        Supplies L, ρ and the dimensions.
    derivatives : ManoeuvringDerivatives
    surge_speed_mps : float
        Speed through the water u0, held constant [m/s] (> 0).
    extras : PlantVesselExtras or None
    """

    def __init__(self, vessel: VesselData, derivatives: ManoeuvringDerivatives, surge_speed_mps: float,
                 extras: PlantVesselExtras | None = None) -> None:
        if not surge_speed_mps > 0.0:
            raise ValueError("the manoeuvring model needs a forward speed > 0")
        self.vessel = vessel
        self.derivatives = derivatives
        self.surge_speed_mps = surge_speed_mps
        self.extras = extras if extras is not None else extras_for(vessel)
        self.mass_factor = math.nan
        self.set_mass_factor(1.0)

    def set_mass_factor(self, factor: float) -> None:
        """Scale the (rigid-body and added) inertia by ``factor``."""
        if not factor > 0.0:
            raise ValueError(f"mass factor must be > 0, got {factor}")
        if factor == self.mass_factor:
            return
        dv = self.derivatives
        length = self.vessel.length_m
        half_rho = 0.5 * self.vessel.water_density_kgpm3
        m22 = factor * (dv.mass - dv.y_vdot) * half_rho * length**3
        m23 = factor * (dv.mass * dv.xg - dv.y_rdot) * half_rho * length**4
        m32 = factor * (dv.mass * dv.xg - dv.n_vdot) * half_rho * length**4
        m33 = factor * (dv.iz - dv.n_rdot) * half_rho * length**5
        self.sway_yaw_mass = np.array([[m22, m23], [m32, m33]])
        self.mass_kg = factor * dv.mass * half_rho * length**3
        self.mass_factor = factor
        self.hull = HullDimensions(length, self.vessel.beam_m, factor * self.vessel.draft_m)
        cdt, bow, stern, delta = BLENDERMANN_TYPES[self.extras.wind_type]
        self.wind = WindCoefficients(cdt, bow, stern, delta, self.vessel.frontal_wind_area_m2,
                                     self.vessel.lateral_wind_area_m2, length,
                                     self.extras.wind_centroid_frac * length)
        self._f = _manoeuvring_derivative(dv, length, half_rho, self.surge_speed_mps, (m22, m23, m32, m33))

    @property
    def surge_mass_kg(self) -> float:
        """Rigid-body plus surge added mass [kg] (reported; surge is not integrated)."""
        dv = self.derivatives
        return self.mass_kg * (1.0 - dv.x_udot / dv.mass)

    def linear_nomoto(self) -> tuple[float, float]:
        """First-order Nomoto approximation (K [1/s], T [s]) of the linear sway–yaw model at u0:
        r/δ = K(1 + T3 s)/((1 + T1 s)(1 + T2 s)) ≈ K/(1 + T s), T = T1 + T2 − T3 (seed 002 eq. (57)).
        K carries the sign of r/δ (negative with this rudder convention)."""
        dv = self.derivatives
        length = self.vessel.length_m
        u0 = self.surge_speed_mps
        half_rho = 0.5 * self.vessel.water_density_kgpm3
        n_mat = -np.array([[dv.y_v * half_rho * length**2 * u0, dv.y_r * half_rho * length**3 * u0],
                           [dv.n_v * half_rho * length**3 * u0, dv.n_r * half_rho * length**4 * u0]])
        b = np.array([dv.y_d * half_rho * length**2 * u0**2, dv.n_d * half_rho * length**3 * u0**2])
        a = -np.linalg.solve(self.sway_yaw_mass, n_mat)
        bb = np.linalg.solve(self.sway_yaw_mass, b)
        # r(s)/δ(s) = (s·bb_r + (a10 bb_v − a00 bb_r)) / (s² − tr(a) s + det(a))
        trace = a[0, 0] + a[1, 1]
        det = a[0, 0] * a[1, 1] - a[0, 1] * a[1, 0]
        num1 = bb[1]
        num0 = a[1, 0] * bb[0] - a[0, 0] * bb[1]
        gain = num0 / det
        t3 = num1 / num0
        t_sum = -trace / det  # T1 + T2
        return float(gain), float(t_sum - t3)


def _manoeuvring_derivative(dv: ManoeuvringDerivatives, length: float, half_rho: float, u0: float,
                            mass: tuple[float, float, float, float]) -> Derivative:
    m22, m23, m32, m33 = mass
    det = m22 * m33 - m23 * m32
    y_v, y_r, y_d, n_v, n_r, n_d = dv.y_v, dv.y_r, dv.y_d, dv.n_v, dv.n_r, dv.n_d
    qy = half_rho * length**2  # × U²: force scale
    qn = half_rho * length**3  # × U²: moment scale
    cos = math.cos
    sin = math.sin
    sqrt = math.sqrt

    def f(psi: float, u: float, v: float, r: float, tx: float, ty: float, tn: float, cn: float, ce: float,  # noqa: PLR0917
          rudder: float) -> tuple[float, float, float, float, float, float]:
        del u, tx  # surge through the water is held at u0
        c = cos(psi)
        s = sin(psi)
        uc = c * cn + s * ce
        vc = c * ce - s * cn
        vr = v - vc
        big_u = sqrt(u0 * u0 + vr * vr)
        vp = vr / big_u
        rp = r * length / big_u
        y = (y_v * vp + y_r * rp + y_d * rudder) * qy * big_u * big_u + ty
        n = (n_v * vp + n_r * rp + n_d * rudder) * qn * big_u * big_u + tn
        vr_dot = (m33 * y - m23 * n) / det
        r_dot = (m22 * n - m32 * y) / det
        ug = u0 + uc
        # ν = ν_r + ν_c, ν̇_c = (r v_c, −r u_c, 0)
        return (c * ug - s * v, s * ug + c * v, r, r * vc, vr_dot - r * uc, r_dot)

    return f


def vessel_model(vessel: VesselData, surge_speed_mps: float | None = None) -> DpVesselModel | ManoeuvringVesselModel:
    """The truth model for ``vessel``: the manoeuvring model when plant data has derivatives for it
    (the mariner; surge speed = ``surge_speed_mps`` or the service speed), else the DP model."""
    extras = extras_for(vessel)
    if extras.manoeuvring is not None:
        speed = surge_speed_mps if surge_speed_mps else vessel.service_speed_mps
        return ManoeuvringVesselModel(vessel, extras.manoeuvring, speed, extras)
    return DpVesselModel(vessel, extras)
