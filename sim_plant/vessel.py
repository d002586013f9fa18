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

Both models integrate with classical RK4 at the plant rate in compiled kernels
(:mod:`sim_plant.kernels`: :func:`~sim_plant.kernels.vessel_derivative`,
:func:`~sim_plant.kernels.rk4_step`); a model holds its parameters as one array (``params``, the layout
of :data:`~sim_plant.kernels.DP_PARAMETERS` or :data:`~sim_plant.kernels.MANOEUVRING_PARAMETERS`),
rebuilt when they change.
"""

from __future__ import annotations

import math

import numpy as np

from dpbase.wind_loads import BlendermannCoefficients, blendermann_type
from dpcontrol.models.vessels import VesselData
from sim_plant.environment.rao import HullDimensions
from sim_plant.kernels import (
    DP_MODEL,
    DP_PARAMETERS,
    L_ADDED,
    L_DAMPING,
    L_DRAFT,
    L_IZ,
    L_QUAD,
    LOADING_VALUES,
    MANOEUVRING_MODEL,
    dp_parameters,
    rk4_step,
    vessel_derivative,
)
from sim_plant.vessel_data import ManoeuvringDerivatives, PlantVesselExtras, extras_for


class _ModelBase:
    """Shared RK4 stepping and properties.

    Attributes
    ----------
    kind : int
        :data:`~sim_plant.kernels.DP_MODEL` or :data:`~sim_plant.kernels.MANOEUVRING_MODEL` (the kernels'
        ``model`` argument).
    params : ndarray
        The model's parameters in the kernels' layout (replaced, not modified, when they change).
    """

    vessel: VesselData
    extras: PlantVesselExtras
    mass_factor: float
    kind: int
    params: np.ndarray

    def step(self, x: list[float] | np.ndarray, h_s: float, tau_x_n: float, tau_y_n: float,  # noqa: PLR0917
             tau_n_nm: float, current_north_mps: float, current_east_mps: float, rudder_rad: float = 0.0) -> None:
        """One classical RK4 step of length ``h_s`` with inputs held constant (ZOH), in place
        (:func:`sim_plant.kernels.rk4_step`; the plant calls the kernel with its own state array).

        Parameters
        ----------
        x : list of float or ndarray, length 6
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
        state = np.array(x, dtype=float)
        rk4_step(state, self.kind, self.params, h_s, tau_x_n, tau_y_n, tau_n_nm, current_north_mps,
                 current_east_mps, rudder_rad)
        x[:] = state.tolist()

    def derivative(self, x: list[float], tau_b: tuple[float, float, float] = (0.0, 0.0, 0.0),
                   current_ned: tuple[float, float] = (0.0, 0.0), rudder_rad: float = 0.0
                   ) -> tuple[float, float, float, float, float, float]:
        """ẋ for a state (tests and diagnostics; :func:`sim_plant.kernels.vessel_derivative`)."""
        return vessel_derivative(self.kind, self.params, x[2], x[3], x[4], x[5], tau_b[0], tau_b[1], tau_b[2],
                                 current_ned[0], current_ned[1], rudder_rad)


class DpVesselModel(_ModelBase):
    """Nonlinear 3-DOF low-speed model of a DP vessel (see the module docstring).

    Parameters
    ----------
    vessel : VesselData
    extras : PlantVesselExtras or None
        Plant-only data (default: :func:`sim_plant.vessel_data.extras_for`).
    """

    kind = DP_MODEL

    def __init__(self, vessel: VesselData, extras: PlantVesselExtras | None = None) -> None:
        self.vessel = vessel
        self.extras = extras if extras is not None else extras_for(vessel)
        base = _loading_values(vessel, self.extras.wind_type)
        loaded = self.extras.loaded
        if loaded is not None:
            # ballast values a and full-load differences b − a: a rebuild (every 1e-4 of mass in a 12 h
            # offloading) is one a + s (b − a) and one kernel call
            full = _loading_values(loaded, self.extras.loaded_wind_type or self.extras.wind_type)
            self._ballast_values, self._loading_delta = base, full - base
        else:
            # without a loaded variant the factor scales I_z, the draft and M_A, and nothing else
            self._base_values = base
            self._scaled = np.zeros(len(LOADING_VALUES), dtype=bool)
            self._scaled[[L_IZ, L_DRAFT]] = True
            self._scaled[L_ADDED:L_DAMPING] = True
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
            values = self._ballast_values + s * self._loading_delta
        else:
            values = np.where(self._scaled, factor, 1.0) * self._base_values
        added = np.empty((3, 3))
        mass_matrix = np.empty((3, 3))
        params = np.empty(len(DP_PARAMETERS))
        dp_parameters(values, mass, added, mass_matrix, params)
        iz, xg, draft, frontal, lateral, cdt, bow, stern, delta = values[:L_ADDED].tolist()
        self.mass_matrix = mass_matrix
        self.added_mass_matrix = added
        self.damping_matrix = values[L_DAMPING:L_QUAD].reshape(3, 3)
        self.quadratic_damping = values[L_QUAD:]
        self.mass_kg = mass
        self.iz_kgm2 = iz
        self.xg_m = xg
        self.mass_factor = factor
        self.hull = HullDimensions(base.length_m, max(base.beam_m, 1e-6), max(draft, 1e-6))
        self.wind = BlendermannCoefficients(cdt, bow, stern, delta, frontal, lateral, base.length_m,
                                            self.extras.wind_centroid_frac * base.length_m)
        self.params = params

    @property
    def surge_mass_kg(self) -> float:
        """True surge mass including added mass, M11 = m − X_u̇ [kg] (what MRAC estimates)."""
        return float(self.mass_matrix[0, 0])

    def kinetic_energy(self, x: list[float]) -> float:
        """½ νᵀ M ν [J] (M symmetric)."""
        nu = np.array(x[3:6])
        return float(0.5 * nu @ self.mass_matrix @ nu)


def _loading_values(vessel: VesselData, wind_type: str) -> np.ndarray:
    """What the loading of a DP model sets, as one array (layout :data:`sim_plant.kernels.LOADING_VALUES`)."""
    return np.concatenate(([vessel.iz_kgm2, vessel.xg_m, vessel.draft_m, vessel.frontal_wind_area_m2,
                            vessel.lateral_wind_area_m2], blendermann_type(wind_type),
                           np.ravel(vessel.added_mass_matrix), np.ravel(vessel.damping_matrix),
                           vessel.quadratic_damping))


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

    kind = MANOEUVRING_MODEL

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
        self.wind = BlendermannCoefficients.of_type(self.extras.wind_type, self.vessel.frontal_wind_area_m2,
                                                    self.vessel.lateral_wind_area_m2, length,
                                                    self.extras.wind_centroid_frac * length)
        self.params = _manoeuvring_parameters(dv, length, half_rho, self.surge_speed_mps, (m22, m23, m32, m33))

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


def _manoeuvring_parameters(dv: ManoeuvringDerivatives, length: float, half_rho: float, u0: float,
                            mass: tuple[float, float, float, float]) -> np.ndarray:
    """The manoeuvring model's parameter array (layout :data:`sim_plant.kernels.MANOEUVRING_PARAMETERS`)."""
    m22, m23, m32, m33 = mass
    det = m22 * m33 - m23 * m32
    qy = half_rho * length**2  # × U²: force scale
    qn = half_rho * length**3  # × U²: moment scale
    return np.array([m22, m23, m32, m33, det, dv.y_v, dv.y_r, dv.y_d, dv.n_v, dv.n_r, dv.n_d, qy, qn, length, u0])


def vessel_model(vessel: VesselData, surge_speed_mps: float | None = None) -> DpVesselModel | ManoeuvringVesselModel:
    """The truth model for ``vessel``: the manoeuvring model when plant data has derivatives for it
    (the mariner; surge speed = ``surge_speed_mps`` or the service speed), else the DP model."""
    extras = extras_for(vessel)
    if extras.manoeuvring is not None:
        speed = surge_speed_mps if surge_speed_mps else vessel.service_speed_mps
        return ManoeuvringVesselModel(vessel, extras.manoeuvring, speed, extras)
    return DpVesselModel(vessel, extras)
