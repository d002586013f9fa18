"""Heading autopilot for course keeping (seed 002 eqs. (60)–(67), the mariner case).

Design model (first-order Nomoto with a bias, seed 002 eqs. (60)–(63)):

    ψ̇ = r,     ṙ = −r/T + τ_N/m + b,     ḃ = 0,     τ_N = m (K/T) δ = N_δ δ

with ``m = I_z − N_ṙ``. Control law, PID with reference and wind feed-forward (eq. (64)):

    τ_N = −τ̂_wind + m (ṙ_d + r_d/T) − m (K_p ψ̃ + K_d r̃ + K_i ∫ψ̃ dt),   ψ̃ = ssa(ψ − ψ_d), r̃ = r − r_d

(optionally ``− m b̂``, see "Bias compensation" below)

which leaves the third-order error dynamics (eq. (65))
``r̃̇ + (1/T + K_d) r̃ + K_p ψ̃ + K_i ∫ψ̃ = 0`` (a constant bias is removed by the integral). The
gains place its poles at ``(s² + 2ζω_n s + ω_n²)(s + ω_i)`` with ``ω_i = ω_n/10``:

    K_d = 2ζω_n + ω_i − 1/T,   K_p = ω_n² + 2ζω_n ω_i,   K_i = ω_n² ω_i.

The rudder command is ``δ = τ_N / N_δ`` (eq. (67)), limited in angle and rate. Anti-windup:
conditional integration — while the rudder is limited the integrator does not integrate further
in the direction that pushes it deeper into the limit.

Bias compensation: the course-keeping filter estimates the bias ``b`` of eq. (72) (the slowly
varying yaw moment of waves, wind and current per unit inertia). Seed 002 notes that the filter's
bias estimate "can be used in the controller to implement integral action"; with
``bias_feedforward`` the law also subtracts ``m b̂`` (passed as ``tau_bias_n_nm``), as the DP
controllers do with their bias (τ = u − b̂). The integrator stays: it removes what the filter's
model gets wrong (K, T), and in steady state with a consistent filter it settles at zero (the
filter's ψ̂ is stationary only when ``(K/T)δ + b̂ = 0``, which the law reaches at ψ̃ = 0). Without
it, a wave drift moment worth a few degrees of rudder (the seed 002 sea) pushes the ship off
course by ``δ_b/(K_p T/K)`` until the slow integrator (``ω_i = ω_n/10``) has caught up.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from dpbase.frames import ssa
from dpbase.schema import ConfigError, Section, join
from dpcontrol.control.base import HEADING_ONLY, ControlOutput
from dpcontrol.guidance.reference_model import Reference
from dpcontrol.models.vessels import VesselData


@dataclass(frozen=True)
class AutopilotConfig:
    """Heading autopilot parameters (SI).

    Attributes
    ----------
    inertia_kgm2 : float
        ``m = I_z − N_ṙ`` [kg·m²].
    nomoto_gain_per_s, nomoto_time_constant_s : float
        Nomoto ``K`` [1/s] and ``T`` [s] (seed 002 eq. (57)).
    natural_frequency_radps : float
        Closed-loop ``ω_n`` [rad/s].
    relative_damping : float
        Closed-loop ζ.
    integral_ratio : float
        ``ω_i / ω_n`` (default 0.1).
    rudder_max_rad : float
        Rudder angle limit [rad].
    rudder_rate_radps : float or None
        Rudder rate limit [rad/s] (None: unlimited).
    bias_feedforward : bool
        Subtract the estimated bias moment ``tau_bias_n_nm`` given to :meth:`HeadingAutopilot.step`.
    """

    inertia_kgm2: float
    nomoto_gain_per_s: float
    nomoto_time_constant_s: float
    natural_frequency_radps: float = 0.05
    relative_damping: float = 0.8
    integral_ratio: float = 0.1
    rudder_max_rad: float = math.radians(35.0)
    rudder_rate_radps: float | None = None
    bias_feedforward: bool = True

    def __post_init__(self) -> None:
        for name in ("inertia_kgm2", "nomoto_gain_per_s", "nomoto_time_constant_s", "natural_frequency_radps",
                     "relative_damping", "rudder_max_rad"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0.0):
                raise ValueError(f"{name} must be a finite number > 0, got {value!r}")
        if not (math.isfinite(self.integral_ratio) and self.integral_ratio >= 0.0):
            raise ValueError(f"integral_ratio must be >= 0, got {self.integral_ratio!r}")
        if self.rudder_rate_radps is not None and not (math.isfinite(self.rudder_rate_radps)
                                                       and self.rudder_rate_radps > 0.0):
            raise ValueError(f"rudder_rate_radps must be > 0, got {self.rudder_rate_radps!r}")
        if self.gains()[1] < 0.0:
            raise ValueError("natural_frequency_radps too low for this Nomoto time constant (K_d < 0)")

    @property
    def rudder_gain_nm_per_rad(self) -> float:
        """``N_δ = m K / T`` [N·m/rad] (seed 002 eq. (63))."""
        return self.inertia_kgm2 * self.nomoto_gain_per_s / self.nomoto_time_constant_s

    def gains(self) -> tuple[float, float, float]:
        """``(K_p, K_d, K_i)`` [1/s², 1/s, 1/s³] from the pole placement of eq. (65)."""
        w = self.natural_frequency_radps
        z = self.relative_damping
        wi = self.integral_ratio * w
        kd = 2.0 * z * w + wi - 1.0 / self.nomoto_time_constant_s
        kp = w * w + 2.0 * z * w * wi
        ki = w * w * wi
        return kp, kd, ki

    @staticmethod
    def for_vessel(vessel: VesselData, natural_frequency_radps: float = 0.05, relative_damping: float = 0.8,
                   bias_feedforward: bool = True) -> AutopilotConfig:
        """Autopilot for a vessel with Nomoto data and a rudder (the mariner: seed 002).

        ``m`` is the yaw entry of the design mass matrix; the rudder limits come from the first
        ``propeller_rudder`` thruster.
        """
        if vessel.nomoto_gain_per_s is None or vessel.nomoto_time_constant_s is None:
            raise ValueError(f"vessel {vessel.name} has no Nomoto model")
        rudder = next((t for t in vessel.thrusters if t.kind == "propeller_rudder"), None)
        if rudder is None or rudder.rudder_max_angle_rad is None:
            raise ValueError(f"vessel {vessel.name} has no rudder")
        return AutopilotConfig(
            inertia_kgm2=float(vessel.mass_matrix[2, 2]),
            nomoto_gain_per_s=vessel.nomoto_gain_per_s,
            nomoto_time_constant_s=vessel.nomoto_time_constant_s,
            natural_frequency_radps=natural_frequency_radps,
            relative_damping=relative_damping,
            rudder_max_rad=rudder.rudder_max_angle_rad,
            rudder_rate_radps=rudder.azimuth_rate_limit_radps,
            bias_feedforward=bias_feedforward,
        )


@dataclass(frozen=True)
class AutopilotOutput:
    """One autopilot step.

    Attributes
    ----------
    rudder_rad : float
        Rudder command after the angle and rate limits [rad].
    rudder_demand_rad : float
        ``τ_N / N_δ`` before the limits [rad].
    tau_n_nm : float
        Yaw moment the law asks for ``τ_N`` [N·m].
    heading_error_rad : float
        ``ψ̃ = ssa(ψ − ψ_d)`` [rad].
    limited : bool
        The rudder was limited (angle or rate).
    """

    rudder_rad: float
    rudder_demand_rad: float
    tau_n_nm: float
    heading_error_rad: float
    limited: bool


class HeadingAutopilot:
    """PID heading autopilot with reference and wind feed-forward (seed 002 eqs. (64)–(67))."""

    def __init__(self, config: AutopilotConfig) -> None:
        self._config = config
        self._kp, self._kd, self._ki = config.gains()
        self._m = config.inertia_kgm2
        self._inv_t = 1.0 / config.nomoto_time_constant_s
        self._n_delta = config.rudder_gain_nm_per_rad
        self._integral = 0.0
        self._rudder = 0.0

    @property
    def config(self) -> AutopilotConfig:
        return self._config

    def step(self, dt_s: float, psi_hat_rad: float, r_hat_radps: float, psi_d_rad: float, *, r_d_radps: float = 0.0,
             r_dot_d_radps2: float = 0.0, tau_wind_n_nm: float | None = None,
             tau_bias_n_nm: float | None = None) -> AutopilotOutput:
        """One control period.

        Parameters
        ----------
        dt_s : float
            Time since the previous step [s] (> 0).
        psi_hat_rad, r_hat_radps : float
            Estimated heading [rad] and yaw rate [rad/s] (wave filtered, seed 002 eqs. (69)–(79)).
        psi_d_rad, r_d_radps, r_dot_d_radps2 : float
            Reference heading, rate and acceleration (e.g. the heading channel of
            :class:`~dpcontrol.guidance.reference_model.ReferenceModel`).
        tau_wind_n_nm : float, optional
            Estimated wind yaw moment ``τ̂_wind`` (eq. (66)) [N·m].
        tau_bias_n_nm : float, optional
            Estimated bias moment ``m b̂`` (eq. (72)) [N·m]; subtracted when the config's
            ``bias_feedforward`` is on (see the module docstring), ignored otherwise.
        """
        values = (dt_s, psi_hat_rad, r_hat_radps, psi_d_rad, r_d_radps, r_dot_d_radps2)
        if not all(isinstance(v, (int, float)) and math.isfinite(v) for v in values) or dt_s <= 0.0:
            raise ValueError(f"autopilot inputs must be finite numbers with dt_s > 0, got {values!r}")
        if tau_wind_n_nm is not None and not math.isfinite(tau_wind_n_nm):
            raise ValueError("tau_wind_n_nm must be finite")
        if tau_bias_n_nm is not None and not math.isfinite(tau_bias_n_nm):
            raise ValueError("tau_bias_n_nm must be finite")
        cfg = self._config
        psi_err = ssa(psi_hat_rad - psi_d_rad)
        r_err = r_hat_radps - r_d_radps
        feedforward = self._m * (r_dot_d_radps2 + self._inv_t * r_d_radps)
        tau = feedforward - self._m * (self._kp * psi_err + self._kd * r_err + self._ki * self._integral)  # (64)
        if tau_wind_n_nm is not None:
            tau -= tau_wind_n_nm
        if tau_bias_n_nm is not None and cfg.bias_feedforward:
            tau -= tau_bias_n_nm
        demand = tau / self._n_delta  # (67)
        rudder = min(max(demand, -cfg.rudder_max_rad), cfg.rudder_max_rad)
        if cfg.rudder_rate_radps is not None:
            step = cfg.rudder_rate_radps * dt_s
            rudder = min(max(rudder, self._rudder - step), self._rudder + step)
        limited = abs(rudder - demand) > 1e-12 * (1.0 + abs(demand))
        # conditional integration: the integral term −m K_i ∫ψ̃ must not push the rudder deeper into its limit
        if not (limited and psi_err * (demand - rudder) < 0.0):
            self._integral += psi_err * dt_s
        self._rudder = rudder
        return AutopilotOutput(rudder_rad=rudder, rudder_demand_rad=demand, tau_n_nm=tau,
                               heading_error_rad=psi_err, limited=limited)

    @property
    def rudder_rad(self) -> float:
        """The last rudder command [rad] (where the rate limit continues from)."""
        return self._rudder

    def reset(self, rudder_rad: float = 0.0) -> None:
        """Clear the integrator; start the rate limit from ``rudder_rad``."""
        self._integral = 0.0
        self._rudder = float(rudder_rad)

    def state_dict(self) -> dict[str, Any]:
        """JSON-able state."""
        return {"integral_rad_s": self._integral, "rudder_rad": self._rudder}

    def load_state_dict(self, state: Mapping[str, Any]) -> None:
        """Restore :meth:`state_dict` output (validated)."""
        try:
            integral = float(state["integral_rad_s"])
            rudder = float(state["rudder_rad"])
        except (KeyError, TypeError, ValueError) as error:
            raise ValueError(f"invalid autopilot state: {error}") from None
        if not (math.isfinite(integral) and math.isfinite(rudder)):
            raise ValueError("autopilot state must be finite")
        self._integral = integral
        self._rudder = rudder


def autopilot_config_from_mapping(value: object, vessel: VesselData, path: str = "control") -> AutopilotConfig:
    """Validate a ``control: {kind: autopilot, ...}`` mapping for a vessel with a Nomoto model and a rudder.

    Keys: ``kind`` (``autopilot``), ``natural_frequency_radps`` (0.05), ``relative_damping`` (0.8),
    ``bias_feedforward`` (true); see :meth:`AutopilotConfig.for_vessel`.

    Raises
    ------
    ConfigError
        Naming the key path and what was expected (``<path>.kind`` for a vessel without a Nomoto model or a
        rudder).
    """
    section = Section.of(value, path)
    section.string("kind", "autopilot", choices=("autopilot",))
    natural = section.number("natural_frequency_radps", 0.05, minimum=0.0, exclusive_minimum=True)
    zeta = section.number("relative_damping", 0.8, minimum=0.0, exclusive_minimum=True)
    bias = section.boolean("bias_feedforward", True)
    section.finish()
    try:
        return AutopilotConfig.for_vessel(vessel, natural, zeta, bias)
    except ValueError as error:
        raise ConfigError(join(section.path, "kind"), "a vessel with a Nomoto model and a rudder",
                          str(error)) from None


class AutopilotController:
    """The heading autopilot as a controller of the runtime (:class:`~dpcontrol.control.base.PositionController`).

    It holds heading only and steers with the rudder (``rudder_steering``): its output's ``tau_b`` is
    ``[0, 0, τ_N]`` and ``rudder_rad`` the rudder command of eq. (67); the heading channel of the reference
    (``ψ_d, r_d, ṙ_d``) and the estimate's yaw bias moment feed :meth:`HeadingAutopilot.step`.
    """

    rudder_steering = True
    mass_adaptation = None

    def __init__(self, config: AutopilotConfig) -> None:
        self.pilot = HeadingAutopilot(config)
        # tau_b, error_b, velocity_error_b: the views handed out each step (only the yaw entries are ever set)
        self._out = np.zeros(9)

    @property
    def config(self) -> AutopilotConfig:
        return self.pilot.config

    def step(self, dt_s: float, eta_hat_ned: np.ndarray, nu_hat_b: np.ndarray, bias_hat_b: np.ndarray | None,
             reference: Reference, *, dof_enabled: Sequence[bool] = HEADING_ONLY,
             tau_wind_ff_b: np.ndarray | None = None) -> ControlOutput:
        """One control period of eqs. (64)–(67) (``dof_enabled`` is ignored: the autopilot holds heading only)."""
        r_d = float(reference.eta_dot_d_ned[2])
        pilot = self.pilot.step(dt_s, float(eta_hat_ned[2]), float(nu_hat_b[2]), float(reference.eta_d_ned[2]),
                                r_d_radps=r_d, r_dot_d_radps2=float(reference.eta_ddot_d_ned[2]),
                                tau_wind_n_nm=None if tau_wind_ff_b is None else float(tau_wind_ff_b[2]),
                                tau_bias_n_nm=None if bias_hat_b is None else float(bias_hat_b[2]))
        out = self._out
        out[2] = pilot.tau_n_nm
        out[5] = pilot.heading_error_rad
        out[8] = float(nu_hat_b[2]) - r_d
        return ControlOutput(out[0:3], out[3:6], out[6:9], None, rudder_rad=pilot.rudder_rad)

    def notify_achieved(self, tau_achieved_b: np.ndarray) -> None:
        """Nothing to do: the rudder's own limits are the autopilot's anti-windup."""

    def reset(self) -> None:
        """Clear the integrator (a new engagement); the rate limit starts from the last rudder command."""
        self.pilot.reset(self.pilot.rudder_rad)

    def state_dict(self) -> dict[str, Any]:
        return self.pilot.state_dict()

    def load_state_dict(self, state: Mapping[str, Any]) -> None:
        self.pilot.load_state_dict(state)
