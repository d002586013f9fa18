"""Nonlinear MIMO PID and PD + bias feed-forward DP controllers (vessel-parallel frame).

Control law (Fossen 2021 §12.2 "nonlinear PID"; seed 000 App. A.3 gains; seed 002 eq. (35)):

    e_b   = Rᵀ(ψ̂)(η̂ − η_d)                    (heading component by ssa)
    ė_b   = ν̂ − ν_d,     ν_d = Rᵀ(ψ̂) η̇_d,   ν̇_d ≈ Rᵀ(ψ̂) η̈_d
    τ     = −K_P e_b − K_D ė_b + τ_I + M ν̇_d + D ν_d − τ̂_wind         (integrator)
    τ     = −K_P e_b − K_D ė_b − b̂   + M ν̇_d + D ν_d − τ̂_wind         (PD + bias, seed 003)

``τ_I`` is the integral *force* ``−K_I ∫ e_b dt``, kept in force units so that anti-windup and
gain changes are bumpless. The commercial structure of seed 003 replaces the integrator with the
compensation of the bias ``b̂`` estimated by the wave filter (the force that the low-frequency
environment exerts on the vessel, seed 002 eqs. (16)–(17)): ``τ = −b̂ + PD``.

Anti-windup (integrator mode) uses the force the allocator reports as achieved
(:meth:`PidController.notify_achieved`), and acts only where the low-frequency demand is beyond capability.
The command carries the wave-frequency part of the feedback (with an estimator that filters no waves, all of
it); its peaks are cut by the thrust limits and the drives' rate limits while the low-frequency demand is
well within capability. Anti-windup at every cut peak would bleed the integral (the mean of an
oscillation clipped on one side lies off its centre) and hold the vessel off station (docs/configuration.md, "The PID's
anti-windup"). Per DOF, with the shortfall ``s = τ_achieved − τ_commanded``:

* the saturation side ``sign(s)`` (0 when met) is low-passed with the time constant ``T_t`` into ``d̄``;
  ``|d̄| > 1/2`` — short on one side more than half of the time: the low-frequency demand itself, the
  median of a demand with a symmetric wave-frequency part, is beyond what the thrusters give — marks the
  DOF saturated at low frequency;
* in a step short on that side, and only then, conditional integration (no further integration into the
  saturated side) and back-calculation (Åström & Hägglund): ``τ̇_I = −K_I e_b + s/T_t``; without a
  wave-frequency part (``d̄`` at ±1 within a few ``T_t``) this is the classic scheme;
* the tracking time constant is ``T_t = √(T_i·T_d)`` per DOF by default (Åström & Hägglund's rule,
  ``T_i = K_P/K_I``, ``T_d = K_D/K_P`` from the diagonals).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal, cast

import numpy as np

from dpbase.schema import ConfigError, Section, check_vector
from dpcontrol.control.base import (
    ALL_DOFS,
    ControlOutput,
    check_dt,
    checked_state_inputs,
    kernel_arguments,
    vector3,
)
from dpcontrol.control.kernels import (
    ERROR_INPUT,
    G_DAMPING,
    G_KD,
    G_KI,
    G_KP,
    G_LIMIT,
    G_MASS,
    G_ROWS,
    G_TRACKING,
    P_ACHIEVED,
    P_COMMAND,
    P_DAMPING,
    P_DUTY,
    P_FLAGS,
    P_INTEGRAL,
    P_INTEGRATOR,
    P_LIMIT,
    P_MASS,
    P_ROWS,
    PID_OUT_SIZE,
    pid_step,
)
from dpcontrol.guidance.reference_model import Reference
from dpcontrol.models.vessels import CYBERSHIP2, VesselData

IntegralAction = Literal["integrator", "bias_feedforward"]
INTEGRAL_ACTIONS: tuple[str, ...] = ("integrator", "bias_feedforward")

# seed 000 App. A eq. (A.3): the multivariable PID used on CyberShip II.
SEED000_KP = ((2.7685, 0.0, 0.0), (0.0, 3.212, 0.0445), (0.0, 0.0952, 7.652))
SEED000_KI = ((0.3162, 0.0, 0.0), (0.0, 0.3162, -0.0046), (0.0, 0.0054, 4.4721))
SEED000_KD = ((10.1192, 0.0, 0.0), (0.0, 9.3138, 0.2638), (0.0, 0.3949, 6.0549))

# Closed-loop natural period at L = 100 m for the pole-placement defaults (Froude-scaled with √(L/100)).
_DEFAULT_PERIOD_100M_S = 150.0


def _matrix(name: str, value: Any) -> np.ndarray:
    array = np.array(value, dtype=float)
    if array.shape != (3, 3) or not np.all(np.isfinite(array)):
        raise ValueError(f"{name} must be a finite 3x3 matrix, got {value!r}")
    array.setflags(write=False)
    return array


@dataclass(frozen=True, eq=False)
class PidConfig:
    """Gains and structure of :class:`PidController`.

    Attributes
    ----------
    kp, kd, ki : ndarray, shape (3, 3)
        Proportional [N/m, N/rad; N·m/m, N·m/rad], derivative [N·s/m, ...] and integral
        [N/(m·s), ...] gain matrices acting on body-frame errors.
    integral_action : {"integrator", "bias_feedforward"}
        ``integrator``: PID; ``bias_feedforward``: PD + compensation of the estimated bias ``−b̂``
        (seed 003), ``ki`` unused.
    mass_matrix, damping_matrix : ndarray, shape (3, 3), or None
        Design M and D for the reference feed-forward ``M ν̇_d + D ν_d`` (None: no feed-forward).
    antiwindup_time_constant_s : tuple of 3 float, or None
        Back-calculation tracking time constants ``T_t`` [s], also the time constant over which the
        anti-windup judges whether the low-frequency demand is beyond capability; None: ``√(T_i·T_d)``
        per DOF.
    integral_limit : tuple of 3 float, or None
        Largest magnitude of the integral force per DOF [N, N, N·m]; None: unlimited.
    """

    kp: np.ndarray
    kd: np.ndarray
    ki: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))
    integral_action: IntegralAction = "integrator"
    mass_matrix: np.ndarray | None = None
    damping_matrix: np.ndarray | None = None
    antiwindup_time_constant_s: tuple[float, float, float] | None = None
    integral_limit: tuple[float, float, float] | None = None

    def __post_init__(self) -> None:
        for name in ("kp", "kd", "ki"):
            object.__setattr__(self, name, _matrix(name, getattr(self, name)))
        for name in ("mass_matrix", "damping_matrix"):
            value = getattr(self, name)
            if value is not None:
                object.__setattr__(self, name, _matrix(name, value))
        if self.integral_action not in INTEGRAL_ACTIONS:
            raise ValueError(f"integral_action must be one of {INTEGRAL_ACTIONS}, got {self.integral_action!r}")
        for name in ("antiwindup_time_constant_s", "integral_limit"):
            value = getattr(self, name)
            if value is not None:
                triple = tuple(float(v) for v in value)
                if len(triple) != 3 or not all(math.isfinite(v) and v > 0.0 for v in triple):
                    raise ValueError(f"{name} must be 3 finite numbers > 0, got {value!r}")
                object.__setattr__(self, name, triple)

    def tracking_time_constants_s(self) -> np.ndarray:
        """Back-calculation time constants ``T_t`` [s], shape (3,) (``inf``: DOF without integral)."""
        if self.antiwindup_time_constant_s is not None:
            return np.array(self.antiwindup_time_constant_s)
        kp = np.diag(self.kp)
        ki = np.diag(self.ki)
        kd = np.diag(self.kd)
        out = np.full(3, np.inf)
        for i in range(3):
            if ki[i] > 0.0 and kp[i] > 0.0:
                ti = kp[i] / ki[i]
                td = kd[i] / kp[i]
                out[i] = math.sqrt(ti * td) if td > 0.0 else ti
        return out


def pole_placement_gains(mass_matrix: np.ndarray, damping_matrix: np.ndarray, natural_period_s: Sequence[float],
                         relative_damping: Sequence[float], integral_ratio: float = 0.1
                         ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """DP PID gains by pole placement on ``M ë + (D + K_D) ė + K_P e = 0`` (Fossen 2021 §12.2.5).

    ``K_P = M Ω²``, ``K_D = 2 M Z Ω − D``, ``K_I = integral_ratio · K_P Ω`` with
    ``Ω = diag(2π/T_n)`` and ``Z = diag(ζ)``: the closed loop has natural frequency ``ω_n`` and
    relative damping ``ζ`` per DOF, and the integrator sits a decade below ``ω_n`` (Fossen's
    ``ω_i = ω_n/10`` rule). Negative diagonal ``K_D`` entries (vessels that are already damped more
    than asked) are set to zero.

    Returns
    -------
    kp, kd, ki : ndarray, shape (3, 3)
    """
    M = np.asarray(mass_matrix, dtype=float)
    D = np.asarray(damping_matrix, dtype=float)
    omega = np.diag([2.0 * math.pi / float(t) for t in natural_period_s])
    zeta = np.diag([float(z) for z in relative_damping])
    kp = M @ omega @ omega
    kd = 2.0 * M @ zeta @ omega - D
    for i in range(3):
        kd[i, i] = max(kd[i, i], 0.0)
    ki = integral_ratio * kp @ omega
    return kp, kd, ki


def default_natural_period_s(vessel: VesselData) -> float:
    """Default closed-loop natural period [s]: 150 s × √(L/100 m); 200 s for the shuttle tankers (seed 003)."""
    if vessel.name.startswith("shuttle_tanker"):
        return 200.0
    return _DEFAULT_PERIOD_100M_S * math.sqrt(vessel.length_m / 100.0)


def default_pid_config(vessel: VesselData, integral_action: IntegralAction = "integrator",
                       natural_period_s: float | Sequence[float] | None = None,
                       relative_damping: float | Sequence[float] = 1.0,
                       reference_feedforward: bool = True) -> PidConfig:
    """Default gains: seed 000 (A.3) for CyberShip II, pole placement from M, D otherwise.

    For ``cybership2`` (and no explicit ``natural_period_s``) the gains are exactly seed 000's
    K_P, K_I, K_D. Other vessels get :func:`pole_placement_gains` with natural period
    :func:`default_natural_period_s` (the same Froude scaling as the reference model) and ζ = 1.
    """
    if vessel.name == CYBERSHIP2.name and natural_period_s is None:
        kp, ki, kd = np.array(SEED000_KP), np.array(SEED000_KI), np.array(SEED000_KD)
    else:
        if natural_period_s is None:
            natural_period_s = default_natural_period_s(vessel)
        periods = ([float(natural_period_s)] * 3 if isinstance(natural_period_s, int | float | np.integer | np.floating)
                   else [float(p) for p in natural_period_s])
        zetas = ([float(relative_damping)] * 3 if isinstance(relative_damping, int | float | np.integer | np.floating)
                 else [float(z) for z in relative_damping])
        kp, kd, ki = pole_placement_gains(vessel.mass_matrix, vessel.damping_matrix, periods, zetas)
    return PidConfig(
        kp=kp, kd=kd, ki=ki, integral_action=integral_action,
        mass_matrix=vessel.mass_matrix if reference_feedforward else None,
        damping_matrix=vessel.damping_matrix if reference_feedforward else None,
    )


def pid_config_from_mapping(value: object, vessel: VesselData, path: str = "control") -> PidConfig:
    """Validate a ``control: {kind: pid, ...}`` mapping over the vessel defaults.

    Keys: ``kind`` (``pid``), ``integral_action`` (``integrator`` | ``bias_feedforward``),
    ``natural_period_s`` and ``relative_damping`` (number or 3 numbers: pole placement), or
    explicit ``kp``, ``kd``, ``ki`` (3×3 each, all three together), ``reference_feedforward``
    (bool), ``antiwindup_time_constant_s`` (3), ``integral_limit`` (3: N, N, N·m).
    """
    section = Section.of(value, path)
    section.string("kind", "pid", choices=("pid",))
    action = cast(IntegralAction, section.string("integral_action", "integrator", choices=INTEGRAL_ACTIONS))
    feedforward = section.boolean("reference_feedforward", True)
    explicit = [key for key in ("kp", "kd", "ki") if section.has(key)]
    if explicit and len(explicit) != 3:
        raise ConfigError(f"{section.path}.{explicit[0]}", "kp, kd and ki given together", None, show_got=False)
    periods = section.raw("natural_period_s", None)
    zetas = section.raw("relative_damping", None)
    if explicit:
        kp = section.matrix("kp", (3, 3))
        kd = section.matrix("kd", (3, 3))
        ki = section.matrix("ki", (3, 3))
    else:
        period_values = None if periods is None else _positive_triple(section, "natural_period_s", periods)
        zeta_values = 1.0 if zetas is None else _positive_triple(section, "relative_damping", zetas)
        base = default_pid_config(vessel, action, period_values, zeta_values, feedforward)
        kp, kd, ki = base.kp, base.kd, base.ki
    tracking = section.raw("antiwindup_time_constant_s", None)
    limit = section.raw("integral_limit", None)
    config = PidConfig(
        kp=kp, kd=kd, ki=ki, integral_action=action,
        mass_matrix=vessel.mass_matrix if feedforward else None,
        damping_matrix=vessel.damping_matrix if feedforward else None,
        antiwindup_time_constant_s=None if tracking is None else _positive_triple(
            section, "antiwindup_time_constant_s", tracking),
        integral_limit=None if limit is None else _positive_triple(section, "integral_limit", limit),
    )
    section.finish()
    return config


def _positive_triple(section: Section, key: str, raw: object) -> tuple[float, float, float]:
    if isinstance(raw, (int, float)) and not isinstance(raw, bool):
        raw = [raw, raw, raw]
    vector = check_vector(raw, f"{section.path}.{key}", 3)
    if np.any(vector <= 0.0):
        raise ConfigError(f"{section.path}.{key}", "numbers > 0", raw)
    return (float(vector[0]), float(vector[1]), float(vector[2]))


class PidController:
    """Nonlinear MIMO PID / PD + bias feed-forward in the vessel-parallel frame.

    Implements :class:`dpcontrol.control.base.PositionController`.

    Parameters
    ----------
    config : PidConfig
        Gains and structure.

    Notes
    -----
    One step is one compiled call (:func:`dpcontrol.control.kernels.pid_step`) on the gains and the
    state held here in small arrays; as numpy calls on 3-vectors it cost ≈ 30–50 µs.
    """

    rudder_steering = False  # a DP controller: a force in every DOF (see PositionController)

    def __init__(self, config: PidConfig) -> None:
        self._config = config
        gains = np.zeros((G_ROWS, 3))
        gains[G_KP:G_KP + 3] = config.kp
        gains[G_KD:G_KD + 3] = config.kd
        gains[G_KI:G_KI + 3] = config.ki
        structure = P_INTEGRATOR if config.integral_action == "integrator" else 0
        if config.mass_matrix is not None:
            gains[G_MASS:G_MASS + 3] = config.mass_matrix
            structure |= P_MASS
        if config.damping_matrix is not None:
            gains[G_DAMPING:G_DAMPING + 3] = config.damping_matrix
            structure |= P_DAMPING
        gains[G_TRACKING] = 1.0 / config.tracking_time_constants_s()  # 0 where T_t = inf
        if config.integral_limit is not None:
            gains[G_LIMIT] = config.integral_limit
            structure |= P_LIMIT
        self._gains = gains
        self._structure = structure
        self._state = np.zeros((P_ROWS, 3))  # τ_I, last command, last achieved force, flags, d̄
        self._zero3 = np.zeros(3)  # b̂ and τ̂_wind when not given

    @property
    def config(self) -> PidConfig:
        return self._config

    @property
    def mass_adaptation(self) -> None:
        """None: the gains are fixed (see ``PositionController``)."""
        return None

    @property
    def integral_force_b(self) -> np.ndarray:
        """The integral force ``τ_I`` [N, N, N·m] (copy)."""
        return self._state[P_INTEGRAL].copy()

    def step(self, dt_s: float, eta_hat_ned: np.ndarray, nu_hat_b: np.ndarray, bias_hat_b: np.ndarray | None,
             reference: Reference, *, dof_enabled: Sequence[bool] = ALL_DOFS,
             tau_wind_ff_b: np.ndarray | None = None) -> ControlOutput:
        """One control period.

        Parameters
        ----------
        dt_s : float
            Time since the previous step [s] (> 0).
        eta_hat_ned : array_like, shape (3,)
            LF pose estimate ``[north_m, east_m, psi_rad]``.
        nu_hat_b : array_like, shape (3,)
            LF body velocity estimate ``[m/s, m/s, rad/s]``.
        bias_hat_b : array_like, shape (3,), or None
            Estimated LF environmental force in body axes ``[N, N, N·m]`` (used in
            ``bias_feedforward`` mode; None = zero).
        reference : Reference
            Guidance output (NED).
        dof_enabled : 3 booleans
            Controlled DOFs (surge, sway, yaw); ``(False, False, True)`` is auto-heading. Disabled
            DOFs get zero force and their integrator is cleared.
        tau_wind_ff_b : array_like, shape (3,), or None
            Estimated wind load on the vessel ``τ̂_wind`` (seed 002 eq. (18)); the controller adds
            ``−τ̂_wind`` (seed 002 eq. (35)).

        Returns
        -------
        ControlOutput
        """
        dt = check_dt(dt_s)
        out = np.empty(PID_OUT_SIZE)
        # the runtime's arguments go straight to the kernel, which checks that the vectors are finite: the two
        # DOF masks it passes (valid by construction) and float64 vectors (anything else: TypeError)
        mask, bias, wind = kernel_arguments(dof_enabled, bias_hat_b, tau_wind_ff_b, self._zero3)
        result = ERROR_INPUT
        if mask >= 0:
            try:
                result = pid_step(dt, eta_hat_ned, nu_hat_b, bias, wind, reference.eta_d_ned, reference.eta_dot_d_ned,
                                  reference.eta_ddot_d_ned, mask, self._structure, self._gains, self._state, out)
            except TypeError:
                result = ERROR_INPUT
        if result < 0:  # the arguments checked in order and converted: the first invalid one raises
            eta, nu, mask, bias, wind = checked_state_inputs(
                eta_hat_ned, nu_hat_b, dof_enabled, bias_hat_b=bias_hat_b, tau_wind_ff_b=tau_wind_ff_b,
                zero3=self._zero3)
            vectors = [np.array(v, dtype=float).reshape(-1) for v in
                       (reference.eta_d_ned, reference.eta_dot_d_ned, reference.eta_ddot_d_ned)]
            if any(v.size < 3 for v in vectors):
                raise IndexError("reference vectors must have 3 entries (north, east, heading)")
            eta_d, eta_dot_d, eta_ddot_d = vectors
            pid_step(dt, eta, nu, bias, wind, eta_d, eta_dot_d, eta_ddot_d, mask, self._structure, self._gains,
                     self._state, out)
        return ControlOutput(out[0:3], out[3:6], out[6:9], None)

    def notify_achieved(self, tau_achieved_b: np.ndarray) -> None:
        """The force the allocator could deliver for the last command ``[N, N, N·m]`` (anti-windup)."""
        self._state[P_ACHIEVED] = vector3("tau_achieved_b", tau_achieved_b)
        self._state[P_FLAGS, 0] = 1.0

    def reset(self) -> None:
        """Clear the integrator and the saturation memory (bumpless entry: guidance starts at the estimate)."""
        self._state[:] = 0.0

    @property
    def saturation_duty(self) -> np.ndarray:
        """The low-passed saturation side ``d̄`` per DOF [-] (copy): −1 short of a positive command all the time,
        +1 of a negative one; beyond ±1/2 the DOF counts as saturated at low frequency."""
        return self._state[P_DUTY].copy()

    def state_dict(self) -> dict[str, Any]:
        """JSON-able state: integral force, last command, last achieved force and the saturation duty ``d̄``."""
        state = self._state
        return {
            "integral_force_b": state[P_INTEGRAL].tolist(),
            "last_command_b": state[P_COMMAND].tolist(),
            "last_achieved_b": state[P_ACHIEVED].tolist() if state[P_FLAGS, 0] else None,
            "saturation_duty": state[P_DUTY].tolist(),
        }

    def load_state_dict(self, state: Mapping[str, Any]) -> None:
        """Restore :meth:`state_dict` output (validated first; on error nothing changes). The saturation
        duty starts at zero when absent (a state saved before it existed)."""
        try:
            integral = vector3("integral_force_b", state["integral_force_b"])
            command = vector3("last_command_b", state["last_command_b"])
            achieved_raw = state.get("last_achieved_b")
            achieved = None if achieved_raw is None else vector3("last_achieved_b", achieved_raw)
            duty = vector3("saturation_duty", state.get("saturation_duty", (0.0, 0.0, 0.0)))
            if np.any(np.abs(duty) > 1.0):
                raise ValueError(f"saturation_duty must be within [-1, 1], got {duty.tolist()}")
        except (KeyError, TypeError, ValueError) as error:
            raise ValueError(f"invalid PID state: {error}") from None
        ours = self._state
        ours[P_INTEGRAL] = integral
        ours[P_COMMAND] = command
        ours[P_ACHIEVED] = 0.0 if achieved is None else achieved
        ours[P_FLAGS, 0] = float(achieved is not None)
        ours[P_DUTY] = duty
