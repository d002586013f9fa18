"""Consequence analysis in the running controller: the worst-case failure check, its timing and its alarms.

In DP (``auto_position``) the commanded force τ (body axes) is averaged with a first-order filter of time
constant ``averaging_s`` — the slowly varying environmental load the thrusters hold against, without the
wave-frequency part the wave filter already keeps out of τ. Once DP has run that long, every ``period_s``
the average × ``demand_factor`` is checked against each failure group
(:class:`~dpcontrol.allocation.consequence.WorstCaseFailure`). A group whose loss would leave part of the
demand uncovered for ``persist_s`` raises the alarm ``consequence.<group>``; it clears after as long holding.
With ``utilisation_warning`` set, one whose loss would hold but with a remaining thruster at or above that share
of its rating raises the warning ``consequence.<group>.utilisation`` the same way: the margin is going before
the position would be. Outside DP the check rests and its alarms clear (the demand of another mode says nothing
of station keeping). The average and how long it has run survive a restart through the persisted state, so a
resumed controller checks at once instead of after another ``averaging_s``.

The daemon runs it after the cycle's command is published (a few QP solves once a second must not delay a
command); the lockstep simulation after each step. No clock of its own: time comes in with each call.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from dpcontrol.allocation.consequence import FailureGroup, FailureOutcome, WorstCaseFailure
from dpcontrol.models.thrusters import ThrusterSpec
from dpcontrol.runtime.alarms import AlarmRegistry, Severity


@dataclass(frozen=True)
class ConsequenceSettings:
    """The worst-case failure check (consequence analysis) of a redundant (DP class 2/3) thruster layout.

    Off when ``groups`` is empty (the default: a vessel without redundancy, such as CyberShip II with one bow
    tunnel, would alarm whenever DP needs sway). In DP (``auto_position``) the commanded force is averaged
    over ``averaging_s``; every ``period_s`` that average × ``demand_factor`` (an allowance for the waves
    and gusts around it) is allocated to the thrusters left after each group's loss; a group whose loss
    would leave part of it uncovered for ``persist_s`` raises ``consequence.<group>``. With
    ``utilisation_warning`` set, a group whose loss would hold but leave a thruster working at or above that
    share of its rating for ``persist_s`` raises the warning ``consequence.<group>.utilisation`` (the margin
    an operating guideline asks for, before the alarm).
    """

    groups: tuple[FailureGroup, ...] = ()
    period_s: float = 1.0
    averaging_s: float = 30.0
    demand_factor: float = 1.25
    persist_s: float = 10.0
    tolerance: float = 0.002
    utilisation_warning: float | None = None


#: The mode the check runs in (station keeping).
ACTIVE_MODE = "auto_position"


@dataclass(frozen=True, slots=True)
class ConsequenceReport:
    """The last check, for the status and the recorder.

    Attributes
    ----------
    t_s : float
        When it ran [s] (controller clock).
    demand_b : ndarray, shape (3,)
        The demand checked (average × ``demand_factor``) ``[N, N, N·m]``.
    outcomes : tuple of FailureOutcome
        One per failure group, in the configured order.
    """

    t_s: float
    demand_b: np.ndarray
    outcomes: tuple[FailureOutcome, ...]


class ConsequenceMonitor:
    """Averages the demand, runs the worst-case failure check at its rate, raises and clears the alarms.

    Parameters
    ----------
    thrusters : sequence of ThrusterSpec
    settings : ConsequenceSettings
        Must have at least one group.
    alarms : AlarmRegistry
        Where ``consequence.<group>`` (severity alarm) and ``consequence.<group>.utilisation`` (warning) are raised.
    allocation : mapping, optional
        The control loop's allocator settings.
    """

    def __init__(self, thrusters: Sequence[ThrusterSpec], settings: ConsequenceSettings, alarms: AlarmRegistry,
                 allocation: dict[str, object] | None = None) -> None:
        if not settings.groups:
            raise ValueError("consequence analysis without failure groups")
        self.settings = settings
        self.alarms = alarms
        self.check = WorstCaseFailure(thrusters, settings.groups, tolerance=settings.tolerance,
                                      allocation=allocation)
        self._members = {group.name: ", ".join(group.thrusters) for group in settings.groups}
        self._codes = [code for group in settings.groups
                       for code in (f"consequence.{group.name}", f"consequence.{group.name}.utilisation")]
        self._mean_b = np.zeros(3)
        self._engaged_since: float | None = None
        self._last_t: float | None = None
        self._next_check = -math.inf
        # per group: whether its loss would hold at the last check, and since when [s] (None: no check yet)
        self._verdict: dict[str, tuple[bool, float] | None] = dict.fromkeys(self._members)
        # the same for "it holds, with a thruster at or above utilisation_warning"
        self._busy: dict[str, tuple[bool, float] | None] = dict.fromkeys(self._members)
        self.last: ConsequenceReport | None = None

    @property
    def active(self) -> bool:
        """In DP and averaged for ``averaging_s`` (the checks run)."""
        return self.last is not None

    def update(self, t_s: float, mode: str, tau_b: np.ndarray, available: np.ndarray) -> ConsequenceReport | None:
        """One control cycle: ``mode`` and the commanded force ``tau_b`` ``[N, N, N·m]`` of the step at ``t_s`` [s],
        the thrusters ``available`` to the allocation now (bool, (n,)). Returns the check when one ran."""
        if mode != ACTIVE_MODE:
            if self._engaged_since is not None:
                self._rest(t_s)
            return None
        tau = np.asarray(tau_b, dtype=float)
        if not np.all(np.isfinite(tau)):
            return None  # (a step that failed): kept out of the average, which it would poison for good
        if self._engaged_since is None or self._last_t is None:
            self._engaged_since = t_s
            self._mean_b[:] = tau
        else:
            # first-order filter, exact for any step: weight 1 − exp(−Δt/T)
            weight = -math.expm1(-max(t_s - self._last_t, 0.0) / self.settings.averaging_s)
            self._mean_b += weight * (tau - self._mean_b)
        self._last_t = t_s
        if t_s - self._engaged_since < self.settings.averaging_s or t_s < self._next_check:
            return None
        self._next_check = t_s + self.settings.period_s
        demand = self.settings.demand_factor * self._mean_b
        outcomes = self.check.evaluate(demand, np.asarray(available, dtype=bool))
        self.last = ConsequenceReport(t_s, demand, outcomes)
        for outcome in outcomes:
            self._judge(t_s, outcome, demand)
            if self.settings.utilisation_warning is not None:
                self._judge_margin(t_s, outcome, self.settings.utilisation_warning)
        return self.last

    def _settled(self, verdicts: dict[str, tuple[bool, float] | None], group: str, state: bool, t_s: float) -> bool:
        """Record ``group``'s ``state`` at ``t_s`` [s] in ``verdicts``; True once unchanged for ``persist_s``."""
        verdict = verdicts[group]
        if verdict is None or verdict[0] != state:
            verdicts[group] = verdict = (state, t_s)
        return t_s - verdict[1] >= self.settings.persist_s

    def _judge(self, t_s: float, outcome: FailureOutcome, demand_b: np.ndarray) -> None:
        group = outcome.group
        code = f"consequence.{group}"
        if not self._settled(self._verdict, group, outcome.holds, t_s):
            return
        if outcome.holds:
            self.alarms.clear(t_s, code)  # (nothing when not raised)
        else:
            labels = ("kN surge", "kN sway", "kN·m yaw")
            uncovered = ", ".join(f"{abs(value) / 1e3:.1f} {label}" for value, limit, label
                                  in zip(outcome.shortfall_b, self.check.tolerance_b, labels, strict=True)
                                  if abs(value) > limit)
            text = (f"worst-case failure: losing {group} ({self._members[group]}) would leave "
                    f"{uncovered or 'part'} of the demand uncovered "
                    f"({self.settings.demand_factor:g} × the mean force of the last "
                    f"{self.settings.averaging_s:g} s: {demand_b[0] / 1e3:.1f} kN, {demand_b[1] / 1e3:.1f} kN, "
                    f"{demand_b[2] / 1e3:.1f} kN·m)")
            self.alarms.raise_(t_s, code, Severity.ALARM, text)

    def _judge_margin(self, t_s: float, outcome: FailureOutcome, limit: float) -> None:
        """``consequence.<group>.utilisation``: the group's loss would hold, but only with a thruster at or above
        ``limit`` of its rating, for ``persist_s`` (a loss that would not hold is the alarm's, not this)."""
        group = outcome.group
        busy = outcome.holds and outcome.utilisation >= limit
        code = f"consequence.{group}.utilisation"
        if not self._settled(self._busy, group, busy, t_s):
            return
        if not busy:
            self.alarms.clear(t_s, code)
            return
        self.alarms.raise_(t_s, code, Severity.WARNING,
                           f"worst-case failure: losing {group} ({self._members[group]}) would hold, with "
                           f"{outcome.busiest} at {100.0 * outcome.utilisation:.0f} % of its rating "
                           f"(warning from {100.0 * limit:.0f} %)")

    def _rest(self, t_s: float) -> None:
        """Out of DP: the check rests, its alarms clear, the average starts again at the next engagement."""
        for code in self._codes:
            self.alarms.clear(t_s, code)
        self._engaged_since = self._last_t = None
        self._next_check = -math.inf
        self._verdict = dict.fromkeys(self._members)
        self._busy = dict.fromkeys(self._members)
        self.last = None

    # ------------------------------------------------------------------ persistence
    def state_dict(self, t_s: float) -> dict[str, object] | None:
        """The average and how long it has run [s] at ``t_s`` [s] (JSON-able); None outside DP (nothing to keep)."""
        if self._engaged_since is None or self._last_t is None:
            return None
        return {"mean_b": self._mean_b.tolist(), "averaged_s": t_s - self._engaged_since}

    def load_state_dict(self, state: dict[str, object], t_s: float) -> None:
        """Resume the average of :meth:`state_dict` at ``t_s`` [s] (the controller resumed in DP): checks go on
        at once when it had run ``averaging_s``. The alarms' persistence starts again (their registry is new)."""
        mean = np.asarray(state["mean_b"], dtype=float).reshape(3)
        averaged = float(state["averaged_s"])  # type: ignore[arg-type]
        if not (np.all(np.isfinite(mean)) and math.isfinite(averaged) and averaged >= 0.0):
            raise ValueError(f"consequence state: mean_b {mean.tolist()}, averaged_s {averaged}")
        self._mean_b[:] = mean
        self._engaged_since = t_s - averaged
        self._last_t = t_s
