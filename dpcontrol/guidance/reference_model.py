"""Third-order reference model with velocity and acceleration limits (DP set-point guidance).

An operator set-point (north, east, heading) is turned into a smooth reference
``η_d, η̇_d, η̈_d`` in NED. Per degree of freedom the model is Fossen's cascade of a first-order
low-pass filter and a mass–spring–damper (Fossen 2021, *Handbook of Marine Craft Hydrodynamics
and Motion Control*, §12.1.1), the shape seed 003 uses for its reference model (natural period
200 s, ζ = 1):

    ṙ_f  = ω (r − r_f)                                   (low-pass pre-filter)
    η̈_d = ω² (r_f − η_d) − 2ζω η̇_d                     (mass–spring–damper)

which together give ``η_d⁽³⁾ + (2ζ+1)ω η̈_d + (2ζ+1)ω² η̇_d + ω³ η_d = ω³ r``. The
mass–spring–damper is written as a velocity loop,

    v_c  = ω/(2ζ) · (r_f − η_d),        η̈_d = 2ζω (v_c − η̇_d),

which is the same linear model, so that the limits can be applied *inside* it: the commanded
velocity ``v_c`` is saturated at the configured speed (as a horizontal vector, so a diagonal move
goes straight at the configured speed, not √2 faster) and at the braking speed
``√(a_max·|r_f − η_d|)`` (so the acceleration limit can always stop the reference without
overshoot), and ``η̈_d`` is saturated at the acceleration limit. A set-point 1 km away therefore
makes the reference travel at the configured speed — no force spike — while small steps follow
the linear third-order response, which has real poles at ζ = 1 and hence no overshoot. Heading
errors use the smallest signed angle, so a heading change across ±180° takes the short way.

Integration: semi-implicit Euler with sub-steps chosen so that ``2ζω·h ≤ 0.2``; the velocity
update ``v ← v + h·2ζω(v_c − v)`` is then a convex combination of ``v`` and ``v_c``, so the speed
limit holds exactly in discrete time too.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from dpbase.frames import ssa
from dpbase.schema import ConfigError, Section, check_vector
from dpcontrol.guidance.kernels import (
    K_ACCEL,
    K_OMEGA,
    K_RATE,
    K_SIZE,
    K_SPEED,
    K_YAW_ACCEL,
    K_YAW_RATE,
    K_ZETA,
    S_ACCEL,
    S_ETA,
    S_PREFILTER,
    S_ROWS,
    S_VELOCITY,
    reference_step,
)
from dpcontrol.models.vessels import VesselData

# Froude-scaled defaults (see :func:`default_reference_config`), stated for a 100 m vessel.
_REFERENCE_LENGTH_M = 100.0
_DEFAULT_PERIOD_100M_S = 150.0
_DEFAULT_SPEED_100M_MPS = 0.5
_DEFAULT_ACCEL_MPS2 = 0.01
_DEFAULT_YAW_RATE_100M_RADPS = math.radians(1.0)
_DEFAULT_YAW_ACCEL_100M_RADPS2 = math.radians(0.05)
ENTRIES = ("auto", "stop", "glide")  # ReferenceModelConfig.entry


@dataclass(frozen=True)
class ReferenceModelConfig:
    """Parameters of the reference model (SI).

    Attributes
    ----------
    natural_period_s : tuple of 3 float
        Natural period ``2π/ω`` per DOF (north, east, heading) [s] (seed 003: 200 s).
    relative_damping : tuple of 3 float
        Relative damping ratio ζ per DOF (seed 003: 1.0, no overshoot).
    max_speed_mps : float
        Largest horizontal speed of the reference (norm of the north/east velocity) [m/s].
    max_accel_mps2 : float
        Largest horizontal acceleration (norm) [m/s²].
    max_yaw_rate_radps : float
        Largest heading rate [rad/s].
    max_yaw_accel_radps2 : float
        Largest heading acceleration [rad/s²].
    entry : {"auto", "stop", "glide"}
        How an entry into DP from standby starts the reference at the estimated pose: ``stop`` at rest (DP
        holds her where she is and its controller brakes the drift she had, as far as her thrust allows),
        ``glide`` at the estimated velocity, which the model then decelerates over its natural period (no
        braking force at the entry). ``auto``: the runtime chooses per controller (``glide`` for an MRAC, whose
        learning gate is built around the glide, and for a course-keeping autopilot, whose ship is under way;
        ``stop`` otherwise). See docs/fault-handling.md, "Entering DP while drifting".
    """

    natural_period_s: tuple[float, float, float] = (150.0, 150.0, 150.0)
    relative_damping: tuple[float, float, float] = (1.0, 1.0, 1.0)
    max_speed_mps: float = 0.5
    max_accel_mps2: float = 0.01
    max_yaw_rate_radps: float = math.radians(1.0)
    max_yaw_accel_radps2: float = math.radians(0.05)
    entry: str = "auto"

    def __post_init__(self) -> None:
        if self.entry not in ENTRIES:
            raise ValueError(f"entry must be one of {', '.join(ENTRIES)}, got {self.entry!r}")
        periods = tuple(float(p) for p in self.natural_period_s)
        zetas = tuple(float(z) for z in self.relative_damping)
        if len(periods) != 3 or len(zetas) != 3:
            raise ValueError("natural_period_s and relative_damping need 3 values (north, east, heading)")
        if not all(math.isfinite(p) and p > 0.0 for p in periods):
            raise ValueError(f"natural periods must be finite and > 0, got {periods}")
        if not all(math.isfinite(z) and z > 0.0 for z in zetas):
            raise ValueError(f"relative damping must be finite and > 0, got {zetas}")
        for name in ("max_speed_mps", "max_accel_mps2", "max_yaw_rate_radps", "max_yaw_accel_radps2"):
            value = float(getattr(self, name))
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"{name} must be finite and > 0, got {value}")
            object.__setattr__(self, name, value)
        object.__setattr__(self, "natural_period_s", periods)
        object.__setattr__(self, "relative_damping", zetas)


@dataclass(frozen=True, eq=False)
class Reference:
    """Reference state at one sample (NED, heading wrapped to (−π, π]).

    Attributes
    ----------
    eta_d_ned : ndarray, shape (3,)
        Desired pose ``[north_m, east_m, psi_rad]``.
    eta_dot_d_ned : ndarray, shape (3,)
        Desired NED velocity ``[m/s, m/s, rad/s]``.
    eta_ddot_d_ned : ndarray, shape (3,)
        Desired NED acceleration ``[m/s², m/s², rad/s²]``.
    """

    eta_d_ned: np.ndarray
    eta_dot_d_ned: np.ndarray
    eta_ddot_d_ned: np.ndarray

    @staticmethod
    def hold(eta_ned: np.ndarray) -> Reference:
        """A reference at rest at ``eta_ned`` (e.g. for tests or station keeping without guidance)."""
        return Reference(np.array(eta_ned, dtype=float), np.zeros(3), np.zeros(3))


def default_reference_config(vessel: VesselData) -> ReferenceModelConfig:
    """Default reference model for a vessel, Froude-scaled from a 100 m DP vessel.

    At L = 100 m: natural period 150 s (between seed 003's 200 s for the 260 m tanker and the
    ≈ 19 s closed-loop period of seed 000's PID on the 1.255 m CyberShip II, both scaled to
    100 m), speed 0.5 m/s, acceleration 0.01 m/s², heading rate 1 °/s, heading acceleration
    0.05 °/s². Froude scaling with λ = L/100 m: times and speeds × √λ, linear accelerations × 1,
    angular rates × 1/√λ, angular accelerations × 1/λ. The shuttle tankers use seed 003's 200 s.
    """
    scale = vessel.length_m / _REFERENCE_LENGTH_M
    root = math.sqrt(scale)
    period = 200.0 if vessel.name.startswith("shuttle_tanker") else _DEFAULT_PERIOD_100M_S * root
    return ReferenceModelConfig(
        natural_period_s=(period, period, period),
        relative_damping=(1.0, 1.0, 1.0),
        max_speed_mps=_DEFAULT_SPEED_100M_MPS * root,
        max_accel_mps2=_DEFAULT_ACCEL_MPS2,
        max_yaw_rate_radps=_DEFAULT_YAW_RATE_100M_RADPS / root,
        max_yaw_accel_radps2=_DEFAULT_YAW_ACCEL_100M_RADPS2 / scale,
    )


def reference_config_from_mapping(value: object, vessel: VesselData, path: str = "guidance") -> ReferenceModelConfig:
    """Validate a ``guidance:`` config mapping (degrees at the edge) over the vessel defaults.

    Keys (all optional): ``natural_period_s`` (number or list of 3), ``relative_damping`` (number or
    list of 3), ``max_speed_mps``, ``max_accel_mps2``, ``max_yaw_rate_degps``,
    ``max_yaw_accel_degps2``, ``entry`` (``auto``, the default: per controller; ``stop``; ``glide``;
    see :class:`ReferenceModelConfig`).

    Raises
    ------
    ConfigError
        Naming the key path and what was expected.
    """
    base = default_reference_config(vessel)
    section = Section.of(value, path)

    def triple(key: str, default: tuple[float, float, float]) -> tuple[float, float, float]:
        raw = section.raw(key, None)
        if raw is None:
            return default
        if isinstance(raw, (int, float)) and not isinstance(raw, bool):
            raw = [raw, raw, raw]
        vector = check_vector(raw, f"{section.path}.{key}", 3)
        if np.any(vector <= 0.0):
            raise ConfigError(f"{section.path}.{key}", "positive numbers", raw)
        return (float(vector[0]), float(vector[1]), float(vector[2]))

    def positive(key: str, default: float) -> float:
        return section.number(key, default, minimum=0.0, exclusive_minimum=True)

    config = ReferenceModelConfig(
        natural_period_s=triple("natural_period_s", base.natural_period_s),
        relative_damping=triple("relative_damping", base.relative_damping),
        max_speed_mps=positive("max_speed_mps", base.max_speed_mps),
        max_accel_mps2=positive("max_accel_mps2", base.max_accel_mps2),
        max_yaw_rate_radps=math.radians(positive("max_yaw_rate_degps", math.degrees(base.max_yaw_rate_radps))),
        max_yaw_accel_radps2=math.radians(
            positive("max_yaw_accel_degps2", math.degrees(base.max_yaw_accel_radps2))),
        entry=section.string("entry", base.entry, choices=ENTRIES),
    )
    section.finish()
    return config


def _finite3(name: str, value: Any) -> tuple[float, float, float]:
    if type(value) is np.ndarray and value.shape == (3,) and value.dtype == np.float64:
        a, b, c = value.tolist()  # three float checks are cheaper than np.isfinite(...).all()
        if math.isfinite(a) and math.isfinite(b) and math.isfinite(c):
            return a, b, c
        raise ValueError(f"{name} must be 3 finite numbers, got {value!r}")
    array = np.asarray(value, dtype=float)
    if array.shape != (3,) or not np.all(np.isfinite(array)):
        raise ValueError(f"{name} must be 3 finite numbers, got {value!r}")
    return float(array[0]), float(array[1]), float(array[2])


class ReferenceModel:
    """Set-point → smooth ``(η_d, η̇_d, η̈_d)`` in NED with speed/acceleration limits.

    Parameters
    ----------
    config : ReferenceModelConfig
        Natural periods, damping and limits.

    Notes
    -----
    Call :meth:`reset` with the current estimate when DP is engaged (bumpless entry: the
    reference starts where the vessel is, moving as it moves). Until then :meth:`step`
    initialises the model at the first set-point. A step is one compiled call
    (:func:`dpcontrol.guidance.kernels.reference_step`) on the state array held here.
    """

    __slots__ = ("_config", "_const", "_initialised", "_omega", "_state", "_zeta")

    def __init__(self, config: ReferenceModelConfig) -> None:
        self._config = config
        self._omega = tuple(2.0 * math.pi / p for p in config.natural_period_s)
        self._zeta = config.relative_damping
        const = np.zeros(K_SIZE)
        const[K_OMEGA:K_OMEGA + 3] = self._omega
        const[K_ZETA:K_ZETA + 3] = self._zeta
        # fastest rate of the model, max(2ζω, ω) over the DOFs: sets the integration sub-steps
        const[K_RATE] = max(max(2.0 * z * w, w) for z, w in zip(self._zeta, self._omega, strict=True))
        const[K_SPEED] = config.max_speed_mps
        const[K_ACCEL] = config.max_accel_mps2
        const[K_YAW_RATE] = config.max_yaw_rate_radps
        const[K_YAW_ACCEL] = config.max_yaw_accel_radps2
        self._const = const
        self._state = np.zeros((S_ROWS, 3))  # r_f, η_d, η̇_d, η̈_d (layout: dpcontrol.guidance.kernels)
        self._initialised = False

    @property
    def config(self) -> ReferenceModelConfig:
        return self._config

    @property
    def initialised(self) -> bool:
        """Whether the model holds a state (after :meth:`reset`, :meth:`step` or a loaded state)."""
        return self._initialised

    def reset(self, eta_ned: np.ndarray, nu_ned: np.ndarray | None = None) -> None:
        """Start the reference at the current estimate (bumpless entry into DP).

        Parameters
        ----------
        eta_ned : array_like, shape (3,)
            Current pose ``[north_m, east_m, psi_rad]``.
        nu_ned : array_like, shape (3,), optional
            Current velocity **in NED** ``η̇ = R(ψ)ν`` ``[m/s, m/s, rad/s]`` (zero if omitted). The
            pre-filter state is placed so that the commanded velocity equals it: the reference
            then decelerates smoothly instead of jumping to rest.
        """
        north, east, psi = _finite3("eta_ned", eta_ned)
        v = (0.0, 0.0, 0.0) if nu_ned is None else _finite3("nu_ned", nu_ned)
        x = [north, east, ssa(psi)]
        # v_c = ω/(2ζ)(r_f − η_d) = v  ⇒  r_f = η_d + 2ζ/ω · v
        rf = [x[i] + 2.0 * self._zeta[i] / self._omega[i] * v[i] for i in range(3)]
        rf[2] = ssa(rf[2])
        state = self._state
        state[S_PREFILTER] = rf
        state[S_ETA] = x
        state[S_VELOCITY] = v
        state[S_ACCEL] = 0.0
        self._initialised = True

    def current(self) -> Reference:
        """The reference at the last step (new arrays)."""
        state = self._state.copy()  # (one copy, three views of it)
        return Reference(state[S_ETA], state[S_VELOCITY], state[S_ACCEL])

    def step(self, dt_s: float, setpoint_eta_ned: np.ndarray) -> Reference:
        """Advance the model by ``dt_s`` towards ``setpoint_eta_ned``.

        Parameters
        ----------
        dt_s : float
            Sample time [s] (>= 0; 0 returns the current reference).
        setpoint_eta_ned : array_like, shape (3,)
            Operator set-point ``[north_m, east_m, psi_rad]`` (heading any wrap).

        Returns
        -------
        Reference
            ``η_d, η̇_d, η̈_d`` at ``t + dt_s`` (new arrays).

        Raises
        ------
        ValueError
            On a negative or non-finite ``dt_s`` or a non-finite set-point (the state is kept).
        """
        if not (math.isfinite(dt_s) and dt_s >= 0.0):
            raise ValueError(f"dt_s must be finite and >= 0, got {dt_s!r}")
        if self._initialised and dt_s > 0.0:  # the per-cycle case: the kernel checks the set-point
            try:
                if reference_step(dt_s, setpoint_eta_ned, self._const, self._state):
                    return self.current()
            except TypeError:  # not a writable float64 vector: converted below
                pass
        setpoint = np.array(_finite3("setpoint_eta_n", setpoint_eta_ned))  # (a ValueError leaves the state)
        if not self._initialised:
            self.reset(setpoint)
        if dt_s == 0.0:
            return self.current()
        reference_step(float(dt_s), setpoint, self._const, self._state)
        return self.current()

    def state_dict(self) -> dict[str, Any]:
        """JSON-able state (for a bumpless restart)."""
        state = self._state
        return {
            "initialised": self._initialised,
            "prefilter_n": state[S_PREFILTER].tolist(),
            "eta_d_n": state[S_ETA].tolist(),
            "eta_dot_d_n": state[S_VELOCITY].tolist(),
            "eta_ddot_d_n": state[S_ACCEL].tolist(),
        }

    def load_state_dict(self, state: Mapping[str, Any]) -> None:
        """Restore a state from :meth:`state_dict` (validated; on error nothing changes)."""
        try:
            initialised = bool(state["initialised"])
            values = [_finite3(key, state[key]) for key in ("prefilter_n", "eta_d_n", "eta_dot_d_n", "eta_ddot_d_n")]
        except (KeyError, TypeError, ValueError) as error:
            raise ValueError(f"invalid reference model state: {error}") from None
        rf, eta, velocity, accel = values
        ours = self._state
        ours[S_PREFILTER] = (rf[0], rf[1], ssa(rf[2]))
        ours[S_ETA] = (eta[0], eta[1], ssa(eta[2]))
        ours[S_VELOCITY] = velocity
        ours[S_ACCEL] = accel
        self._initialised = initialised
