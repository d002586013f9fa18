"""Position and heading deviation alarms: how far the vessel is from where DP wants her now.

Every DP system warns the operator when the vessel strays from the desired position or heading, at two limits:
a warning (the yellow of an operating guideline) and an alarm (the red). Here the deviation is the estimated
low-frequency pose (the wave filter's η̂, so the first-order wave motion does not trip it) against the pose
the controller makes the vessel follow (the desired pose of the moment: during a move the reference travels,
and following it is no deviation; a vessel that cannot keep up with it is). For the PID that is the guidance's
reference η_d; the MRAC drives its reference model y_M (seed 003 eq. (15)) with η_d and makes the vessel track
y_M, which trails η_d by design (8.7 m in the shuttle tanker's 20 m set-point corrections), so its deviation is
measured from y_M (:meth:`dpcontrol.runtime.step.DpController.step` passes the one in use). Position is
watched in ``auto_position``, heading in ``auto_position`` and ``auto_heading``; in standby, or in a mode that
does not hold the quantity, its alarms clear.

A limit exceeded for ``persist_s`` raises its alarm: ``position.deviation.warning`` (warning),
``position.deviation.alarm`` (alarm), ``heading.deviation.warning``, ``heading.deviation.alarm``; both stay up
together above the alarm limit, so the log shows the escalation. An alarm clears once the deviation has been
below :data:`CLEAR_FRACTION` of its limit for ``persist_s`` (a hysteresis band, so that a vessel riding at the
limit does not flap). Pure: time comes in with each call.

**Drift-off** (``position.drift_off``, ``heading.drift_off``, alarm): the deviation moves away from the reference
at a growing rate and, at that rate, would reach the alarm limit within ``drift_off_horizon_s``
— the drift-off commercial systems warn of before the deviation limit: a vessel that has lost the means (or the
knowledge) to hold position accelerates away under the unbalanced environmental force. The rate and its growth
are judged from the deviation now and :data:`DRIFT_WINDOW_S` and twice that ago (d₀, d₁, d₂): increasing
(d₀ < d₁ < d₂) and accelerating (d₂ − d₁ > d₁ − d₀), with ḋ = (d₂ − d₁)/W, d̈ = (d₂ − 2d₁ + d₀)/W² and
d₂ + ḋ·H ≥ the alarm limit (the acceleration qualifies, it is not extrapolated), for ``drift_off_persist_s``.
A step of the deviation (a set-point change)
is never increasing over both intervals; a steady creep does not accelerate. Cleared once the deviation has
stopped growing (d₂ ≤ d₁) for ``persist_s``.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from typing import Any

import numpy as np

from dpcontrol.runtime.alarms import AlarmRegistry, Severity

#: An alarm clears below this share of its limit (hysteresis).
CLEAR_FRACTION = 0.8
DRIFT_WINDOW_S = 5.0  # the drift-off test's interval W [s]
DRIFT_SAMPLE_S = 0.5  # the deviations it keeps are this far apart (≤ 2W/this of them: a short scan per step) [s]
DRIFT_HORIZON_S = 30.0  # the drift-off horizon of a full-scale vessel [s] (docs/fault-handling.md)
DRIFT_HORIZON_LENGTH_M = 76.2  # ... measured on the supply vessel; shorter vessels' horizons shrink by Froude [m]


def drift_off_horizon_s(length_m: float) -> float:
    """The default drift-off horizon H [s] of a vessel ``length_m`` [m] long: :data:`DRIFT_HORIZON_S` for a
    full-scale vessel, shrunk by the Froude time scale √(L / L_ref) below :data:`DRIFT_HORIZON_LENGTH_M`.

    The horizon extrapolates the deviation's present rate; a model-scale vessel does in seconds what a ship
    does in a minute (its engagement transient, CyberShip II's 1.26 m, lasts ~6 s), so a 30 s horizon turned
    those transients into drift-off alarms on the HIL bench. Longer vessels keep 30 s: it is the operator's
    time to take over, and a longer horizon would make the alarm more sensitive than it was measured.
    """
    return DRIFT_HORIZON_S * min(1.0, math.sqrt(max(length_m, 0.0) / DRIFT_HORIZON_LENGTH_M))



@dataclass(frozen=True)
class DeviationSettings:
    """Position and heading deviation limits: the estimated low-frequency pose against the reference (the
    guidance's desired pose of the moment, so a move along a travelling reference is no deviation). Above a
    limit for ``persist_s``: ``position.deviation.warning`` / ``.alarm`` (in ``auto_position``),
    ``heading.deviation.warning`` / ``.alarm`` (in ``auto_position`` and ``auto_heading``); cleared after
    ``persist_s`` below :data:`CLEAR_FRACTION` of the limit. The defaults are a
    full-scale vessel's (3 / 5 m, 3 / 5°); a model-scale vessel needs its own."""

    position_warning_m: float = 3.0
    position_alarm_m: float = 5.0
    heading_warning_rad: float = math.radians(3.0)
    heading_alarm_rad: float = math.radians(5.0)
    persist_s: float = 1.0
    drift_off_horizon_s: float = DRIFT_HORIZON_S  # drift-off: the alarm limit reached within this at the trend
    drift_off_persist_s: float = 3.0  # ... growing at a growing rate for this long (0 horizon: no drift-off alarm)

class _DriftOff:
    """The drift-off judgement of one quantity (module docstring): the recent deviations and since when growing."""

    __slots__ = ("code", "growing_since", "history", "raised", "still_since", "unit")

    def __init__(self, code: str, unit: str) -> None:
        self.code = code
        self.unit = unit
        self.history: deque[tuple[float, float]] = deque()  # (t_s, deviation), the last 2 W (and one before)
        self.growing_since: float | None = None
        self.still_since: float | None = None
        self.raised = False

    def reset(self) -> None:
        self.history.clear()
        self.growing_since = self.still_since = None

    def at(self, t_s: float) -> float | None:
        """The deviation at the latest sample at or before ``t_s`` (None: none that old)."""
        found = None
        for t, value in self.history:
            if t > t_s + 1e-9:
                break
            found = value
        return found


_POSITION_MODES = frozenset({"auto_position"})
_HEADING_MODES = frozenset({"auto_position", "auto_heading"})


class _Limit:
    """One limit's judgement: since when the deviation has been above it, or below its clearing level."""

    __slots__ = ("clear_below", "code", "limit", "over_since", "raised", "severity", "text", "under_since")

    def __init__(self, code: str, severity: Severity, limit: float, text: str) -> None:
        self.code = code
        self.severity = severity
        self.limit = limit  # [m] or [rad]
        self.clear_below = CLEAR_FRACTION * limit
        self.text = text  # the alarm's text, with {value} for the deviation shown
        self.over_since: float | None = None
        self.under_since: float | None = None
        self.raised = False


class DeviationMonitor:
    """Raises and clears the deviation alarms from each step's estimate and reference.

    Parameters
    ----------
    settings : DeviationSettings
        The limits [m, rad] and the persistence [s].
    alarms : AlarmRegistry
    """

    def __init__(self, settings: DeviationSettings, alarms: AlarmRegistry) -> None:
        self.settings = settings
        self.alarms = alarms
        self._position = tuple(
            _Limit(f"position.deviation.{label}", severity, limit,
                   f"position deviation {{value:.1f}} m from the reference ({label} limit {limit:g} m)")
            for label, severity, limit in (("warning", Severity.WARNING, settings.position_warning_m),
                                           ("alarm", Severity.ALARM, settings.position_alarm_m)))
        self._heading = tuple(
            _Limit(f"heading.deviation.{label}", severity, limit, f"heading deviation {{value:.1f}} deg from the "
                   f"reference ({label} limit {math.degrees(limit):g} deg)")
            for label, severity, limit in (("warning", Severity.WARNING, settings.heading_warning_rad),
                                           ("alarm", Severity.ALARM, settings.heading_alarm_rad)))
        self._any_raised = False
        self._drift = {"position": _DriftOff("position.drift_off", "m"),
                       "heading": _DriftOff("heading.drift_off", "deg")}
        #: the last deviations: horizontal distance [m] and heading, wrapped to [0, π] [rad] (None: not watched)
        self.position_m: float | None = None
        self.heading_rad: float | None = None

    def update(self, t_s: float, mode: str, eta_hat_ned: np.ndarray | None, eta_d_ned: np.ndarray | None) -> None:
        """One step at ``t_s`` [s] in ``mode``: the estimate η̂ and the pose tracked (η_d, or the MRAC's y_M)
        ``[m, m, rad]`` (NED; None when there is none, e.g. in standby)."""
        if eta_hat_ned is None or eta_d_ned is None or mode not in _HEADING_MODES:
            self.position_m = self.heading_rad = None
            if self._any_raised:
                self._rest(t_s)
            for drift in self._drift.values():
                self._drift_release(t_s, drift)
            return
        # Python floats: a handful of scalars per step (numpy scalar arithmetic costs several times more)
        n_hat, e_hat, psi_hat = eta_hat_ned.tolist()
        n_d, e_d, psi_d = eta_d_ned.tolist()
        heading = abs(math.remainder(psi_hat - psi_d, math.tau))
        self.heading_rad = heading
        for limit in self._heading:
            self._judge(t_s, limit, heading, math.degrees(heading))
        settings = self.settings
        if settings.drift_off_horizon_s > 0.0:
            self._drift_off(t_s, self._drift["heading"], heading, settings.heading_alarm_rad, math.degrees)
        if mode in _POSITION_MODES:
            position = math.hypot(n_hat - n_d, e_hat - e_d)
            self.position_m = position
            for limit in self._position:
                self._judge(t_s, limit, position, position)
            if settings.drift_off_horizon_s > 0.0:
                self._drift_off(t_s, self._drift["position"], position, settings.position_alarm_m, float)
        else:
            self.position_m = None
            for limit in self._position:
                self._release(t_s, limit)
            self._drift_release(t_s, self._drift["position"])

    def _drift_off(self, t_s: float, drift: _DriftOff, value: float, alarm_limit: float, shown: Any) -> None:
        """Judge ``drift`` with this step's deviation ``value`` [m or rad] (module docstring)."""
        history = drift.history
        if not history or t_s - history[-1][0] >= DRIFT_SAMPLE_S - 1e-9:
            history.append((t_s, value))
        window = DRIFT_WINDOW_S
        while len(history) > 2 and history[1][0] <= t_s - 2.0 * window + 1e-9:
            history.popleft()  # (keeps one sample at or before t − 2W)
        d0 = drift.at(t_s - 2.0 * window)
        d1 = drift.at(t_s - window)
        if d0 is None or d1 is None:
            return
        s = self.settings
        horizon = s.drift_off_horizon_s
        rate = (value - d1) / window
        accel = (value - 2.0 * d1 + d0) / (window * window)
        # Extrapolated linearly: the acceleration qualifies the trend but is not extrapolated, because its
        # estimate is a second difference of a noisy deviation, and ½·d̈·H² multiplies its error by 450 s² at
        # H = 30 s (the entry transient of the supply vessel's HIL pair, 1.33 m off and decelerating in a few
        # seconds, was predicted past the 5 m limit). A vessel really drifting off under an unbalanced force
        # still reaches the rate (limit − d)/H long before the warning limit.
        growing = d0 < d1 < value and accel > 0.0 and value + rate * horizon >= alarm_limit
        if growing:
            drift.still_since = None
            if drift.growing_since is None:
                drift.growing_since = t_s
            if not drift.raised and t_s - drift.growing_since >= s.drift_off_persist_s:
                kind = drift.code.split(".")[0]
                self.alarms.raise_(t_s, drift.code, Severity.ALARM,
                                   f"{kind} drift-off: {shown(value):.2f} {drift.unit} from the reference, moving away "
                                   f"at {shown(rate):.3g} {drift.unit}/s and accelerating")
                drift.raised = True
        else:
            drift.growing_since = None
            if drift.raised and value <= d1:
                if drift.still_since is None:
                    drift.still_since = t_s
                if t_s - drift.still_since >= s.persist_s:
                    self._drift_release(t_s, drift)
            else:
                drift.still_since = None

    def _drift_release(self, t_s: float, drift: _DriftOff) -> None:
        if drift.raised:
            self.alarms.clear(t_s, drift.code)
            drift.raised = False
        drift.reset()

    def _judge(self, t_s: float, limit: _Limit, value: float, shown: float) -> None:
        persist = self.settings.persist_s
        if value > limit.limit:
            limit.under_since = None
            if limit.over_since is None:
                limit.over_since = t_s
            if not limit.raised and t_s - limit.over_since >= persist:
                self.alarms.raise_(t_s, limit.code, limit.severity, limit.text.format(value=shown))
                limit.raised = self._any_raised = True
        elif value < limit.clear_below:
            limit.over_since = None
            if limit.raised:
                if limit.under_since is None:
                    limit.under_since = t_s
                if t_s - limit.under_since >= persist:
                    self._release(t_s, limit)
        else:  # the hysteresis band: neither over the limit nor clear of it
            limit.over_since = limit.under_since = None

    def _release(self, t_s: float, limit: _Limit) -> None:
        if limit.raised:
            self.alarms.clear(t_s, limit.code)
            limit.raised = False
        limit.over_since = limit.under_since = None

    def _rest(self, t_s: float) -> None:
        for limit in (*self._position, *self._heading):
            self._release(t_s, limit)
        self._any_raised = False
