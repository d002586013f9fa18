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
"""

from __future__ import annotations

import math

import numpy as np

from dpcontrol.runtime.alarms import AlarmRegistry, Severity
from dpcontrol.runtime.config import DeviationSettings

#: An alarm clears below this share of its limit (hysteresis).
CLEAR_FRACTION = 0.8

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
        #: the last deviations: horizontal distance [m] and heading, wrapped to [0, π] [rad] (None: not watched)
        self.position_m: float | None = None
        self.heading_rad: float | None = None

    def update(self, t_s: float, mode: str, eta_hat_n: np.ndarray | None, eta_d_n: np.ndarray | None) -> None:
        """One step at ``t_s`` [s] in ``mode``: the estimate η̂ and the pose tracked (η_d, or the MRAC's y_M)
        ``[m, m, rad]`` (NED; None when there is none, e.g. in standby)."""
        if eta_hat_n is None or eta_d_n is None or mode not in _HEADING_MODES:
            self.position_m = self.heading_rad = None
            if self._any_raised:
                self._rest(t_s)
            return
        # Python floats: a handful of scalars per step (numpy scalar arithmetic costs several times more)
        n_hat, e_hat, psi_hat = eta_hat_n.tolist()
        n_d, e_d, psi_d = eta_d_n.tolist()
        heading = abs(math.remainder(psi_hat - psi_d, math.tau))
        self.heading_rad = heading
        for limit in self._heading:
            self._judge(t_s, limit, heading, math.degrees(heading))
        if mode in _POSITION_MODES:
            position = math.hypot(n_hat - n_d, e_hat - e_d)
            self.position_m = position
            for limit in self._position:
                self._judge(t_s, limit, position, position)
        else:
            self.position_m = None
            for limit in self._position:
                self._release(t_s, limit)

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
