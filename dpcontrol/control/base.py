"""Types shared by the DP position controllers (PID / PD + bias feed-forward, MRAC).

All controllers work in the vessel-parallel frame (seed 002 eq. (14)): the NED pose error is
rotated into body axes with the estimated heading,

    e_b = Rᵀ(ψ̂) (η̂ − η_d),  with the heading component ssa(ψ̂ − ψ_d),

and the commanded generalized force ``tau_b = [X_n, Y_n, N_nm]`` is in body axes (surge, sway,
yaw), the frame of the thrust allocation.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np

from dpcontrol.guidance.reference_model import Reference

DofMask = tuple[bool, bool, bool]
ALL_DOFS: DofMask = (True, True, True)
HEADING_ONLY: DofMask = (False, False, True)

#: What an inertia estimate is doing, per DOF (:meth:`MassAdaptation.adaptation_states`, the ``control`` and
#: ``status`` payloads, the monitor): ``adapting`` — the law moved or could move it lately (the reference model
#: excited it); ``frozen`` — adaptation on but nothing to learn from (no excitation lately): the estimate is held;
#: ``suspended`` — the supervision stopped the adaptation (alarm ``control.adaptation``): nominal parameters until a
#: restart; ``off`` — configured not to adapt (``adapt: false``): nominal parameters.
ADAPTATION_STATES: tuple[str, ...] = ("adapting", "frozen", "suspended", "off")


@dataclass(frozen=True, eq=False)
class ControlOutput:
    """One controller step.

    Attributes
    ----------
    tau_b : ndarray, shape (3,)
        Commanded generalized force in body axes ``[N, N, N·m]`` (zero in disabled DOFs).
    error_b : ndarray, shape (3,)
        Pose error ``e_b = Rᵀ(ψ̂)(η̂ − η_d)`` ``[m, m, rad]`` (for MRAC: against its reference model
        ``y_M``).
    velocity_error_b : ndarray, shape (3,)
        ``ν̂ − Rᵀ(ψ̂) η̇_d`` ``[m/s, m/s, rad/s]``.
    parameters : mapping of str to float, or None
        MRAC parameter estimates (``mass_surge_kg``, ``mass_sway_kg``, ``inertia_yaw_kgm2``,
        ``damping_surge_nspm``, ``damping_sway_nspm``, ``damping_yaw_nmsprad``) and the pose of its
        reference model ``y_M`` at this step in NED (``ref_model_north_m``, ``ref_model_east_m``,
        ``ref_model_heading_rad``); None for PID.
    rudder_rad : float or None
        The rudder command [rad] of a controller that steers with the rudder (``rudder_steering``): the
        allocation sets it directly; None for the DP controllers.
    tracked_ned : ndarray, shape (3,), or None
        The pose the controller makes the vessel follow at this step ``[m, m, rad]`` (NED), when it is not the
        guidance's reference ``η_d``: the MRAC's reference model ``y_M`` (seed 003 eq. (15)), which trails
        ``η_d`` by design. The deviation alarms measure from it. None: the vessel follows ``η_d``.
    """

    tau_b: np.ndarray
    error_b: np.ndarray
    velocity_error_b: np.ndarray
    parameters: Mapping[str, float] | None = None
    rudder_rad: float | None = None
    tracked_ned: np.ndarray | None = None


class MassAdaptation(Protocol):
    """What a controller that estimates the vessel's inertia offers its supervisor (the MRAC, seed 003).

    The runtime reads it through :attr:`PositionController.mass_adaptation` to stop an estimate that ran onto
    its projection bound, to hand the estimate to the wave filter and to show the operator the estimates against
    nominal with what each is doing (:meth:`adaptation_states`), without knowing the controller's kind.
    """

    @property
    def adapting(self) -> bool:
        """Whether the estimates adapt now (False: held at nominal)."""
        ...

    @property
    def excited(self) -> tuple[bool, bool, bool]:
        """Per DOF (surge, sway, yaw): the last step moved the mass estimate."""
        ...

    @property
    def mass_hat_floats(self) -> tuple[float, float, float]:
        """The mass estimate ``â₂`` [kg, kg, kg·m²]."""
        ...

    @property
    def mass_nominal(self) -> tuple[float, float, float]:
        """The nominal masses the estimate starts from [kg, kg, kg·m²]."""
        ...

    def mass_at_bound(self) -> int | None:
        """The first DOF whose estimate sits on its projection bound, or None."""
        ...

    def suspend_adaptation(self) -> None:
        """Return to the nominal parameters and adapt no more (until a restart)."""
        ...

    def adaptation_states(self) -> tuple[str, str, str]:
        """Per DOF (surge, sway, yaw): one of :data:`ADAPTATION_STATES` (for the operator's displays)."""
        ...


@runtime_checkable
class PositionController(Protocol):
    """What the runtime calls every control period (PID and MRAC both implement it).

    ``mass_adaptation`` is the controller's inertia estimation for the runtime to supervise (the MRAC
    itself), or None for a controller with fixed parameters. ``rudder_steering``: the controller holds heading
    only and steers with the rudder (the course-keeping autopilot): its output carries the rudder command, the
    runtime engages it in ``auto_heading`` and feeds the estimator the rudder angle; False for the DP
    controllers, which ask the allocation for a force in every DOF. What pose the controller makes the vessel
    follow, when it is not the guidance's ``η_d``, each step says in :attr:`ControlOutput.tracked_ned`; the runtime
    watches the deviation from it and asks nothing else about the controller's kind.
    """

    @property
    def mass_adaptation(self) -> MassAdaptation | None: ...

    @property
    def rudder_steering(self) -> bool: ...

    def step(self, dt_s: float, eta_hat_ned: np.ndarray, nu_hat_b: np.ndarray, bias_hat_b: np.ndarray | None,
             reference: Reference, *, dof_enabled: Sequence[bool] = ALL_DOFS,
             tau_wind_ff_b: np.ndarray | None = None) -> ControlOutput: ...

    def notify_achieved(self, tau_achieved_b: np.ndarray) -> None: ...

    def reset(self) -> None: ...

    def state_dict(self) -> dict[str, Any]: ...

    def load_state_dict(self, state: Mapping[str, Any]) -> None: ...


def vector3(name: str, value: Any) -> np.ndarray:
    """``value`` as a finite float array of shape (3,), or ValueError naming ``name``.

    A float64 array of shape (3,) is returned as is (not copied): callers must not modify it.
    """
    if type(value) is np.ndarray and value.shape == (3,) and value.dtype == np.float64:
        a, b, c = value.tolist()  # three float checks are cheaper than np.isfinite(...).all()
        if math.isfinite(a) and math.isfinite(b) and math.isfinite(c):
            return value
        raise ValueError(f"{name} must be 3 finite numbers, got {value!r}")
    try:
        array = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be 3 finite numbers, got {value!r}") from None
    if array.shape != (3,) or not np.all(np.isfinite(array)):
        raise ValueError(f"{name} must be 3 finite numbers, got {value!r}")
    return array


def floats3(name: str, value: Any) -> tuple[float, float, float]:
    """``value`` as three finite Python floats, or ValueError naming ``name``."""
    try:
        a, b, c = value.tolist() if type(value) is np.ndarray else value
        a, b, c = float(a), float(b), float(c)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be 3 finite numbers, got {value!r}") from None
    if not (math.isfinite(a) and math.isfinite(b) and math.isfinite(c)):
        raise ValueError(f"{name} must be 3 finite numbers, got {value!r}")
    return a, b, c


def dof_mask(value: Sequence[bool]) -> DofMask:
    """Validate a ``dof_enabled`` argument (three booleans: surge, sway, yaw)."""
    if len(value) != 3:
        raise ValueError(f"dof_enabled must have 3 entries (surge, sway, yaw), got {value!r}")
    return (bool(value[0]), bool(value[1]), bool(value[2]))


def check_dt(dt_s: float) -> float:
    """``dt_s`` as a float > 0, or ValueError."""
    try:
        dt = float(dt_s)
    except (TypeError, ValueError):
        dt = math.nan
    if isinstance(dt_s, bool) or not (math.isfinite(dt) and dt > 0.0):
        raise ValueError(f"dt_s must be a finite number > 0, got {dt_s!r}")
    return dt


def kernel_arguments(dof_enabled: Sequence[bool], bias_hat_b: Any, tau_wind_ff_b: Any, zero3: np.ndarray
                     ) -> tuple[int, Any, Any]:
    """The PID/MRAC kernel's DOF mask and bias/wind vectors for the arguments as given (the fast path).

    The mask is bits (1 surge, 2 sway, 4 yaw) for the two masks the runtime passes (:data:`ALL_DOFS`,
    :data:`HEADING_ONLY`, valid by construction), −1 for anything else (then :func:`checked_state_inputs`
    validates it). An absent bias or wind feed-forward is ``zero3``.
    """
    mask = 7 if dof_enabled is ALL_DOFS else (4 if dof_enabled is HEADING_ONLY else -1)
    return (mask, zero3 if bias_hat_b is None else bias_hat_b, zero3 if tau_wind_ff_b is None else tau_wind_ff_b)


def checked_state_inputs(eta_hat_ned: Any, nu_hat_b: Any, dof_enabled: Sequence[bool], *, bias_hat_b: Any,
                         tau_wind_ff_b: Any, zero3: np.ndarray
                         ) -> tuple[np.ndarray, np.ndarray, int, np.ndarray, np.ndarray]:
    """The state arguments of a controller step checked in their order and converted for its kernel.

    The slow path of the PID and MRAC steps, taken when their kernel refused the arguments as given: the
    first invalid one raises ValueError naming it.

    Returns
    -------
    eta, nu : ndarray, shape (3,)
        η̂ [m, m, rad] (NED) and ν̂ [m/s, m/s, rad/s] (body) as new float64 arrays.
    mask : int
        ``dof_enabled`` as bits: 1 surge, 2 sway, 4 yaw.
    bias, wind : ndarray, shape (3,)
        b̂ and the wind feed-forward [N, N, N·m] (body), ``zero3`` when not given.
    """
    eta = np.array(floats3("eta_hat_ned", eta_hat_ned))
    nu = np.array(floats3("nu_hat_b", nu_hat_b))
    flags = dof_mask(dof_enabled)
    bias = zero3 if bias_hat_b is None else np.array(floats3("bias_hat_b", bias_hat_b))
    wind = zero3 if tau_wind_ff_b is None else np.array(floats3("tau_wind_ff_b", tau_wind_ff_b))
    return eta, nu, flags[0] + 2 * flags[1] + 4 * flags[2], bias, wind
