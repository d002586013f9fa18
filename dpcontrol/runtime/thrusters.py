"""Thruster health from drive feedback (issue 8 §10).

A thruster is taken out of the allocation — and commanded to zero — when its drive reports it is
not ready, or when the thrust it delivers disagrees with what a healthy drive would deliver for the
commands it was given (stuck, dead, wrong sign). The expected thrust follows the commands through
the drive's first-order response and rate limit (``ThrusterSpec.time_constant_s``,
``thrust_rate_limit_nps``), so ordinary lag is not a fault. The disagreement must exceed
``mismatch_fraction`` of the drive's rating — or, at low load, half of the expected thrust (at least
5 % of the rating) — for ``mismatch_persist_s``, both low-passed over 1 s.

A "not ready" thruster is re-admitted after it has reported ready for ``readmit_s``; a mismatch
failure latches until an operator resets it (``reset(name)``), because a drive that delivered the
wrong thrust once cannot be trusted again automatically.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from dpcontrol.models.thrusters import ThrusterSpec
from dpcontrol.runtime.alarms import AlarmRegistry, Severity
from dpcontrol.runtime.config import ThrusterMonitorSettings

MISMATCH_FILTER_S = 1.0  # time constant of the low-passed thrust mismatch [s]
RELATIVE_MISMATCH = 0.5  # share of the expected thrust the delivered one may miss at low load [-]
RELATIVE_FLOOR = 0.05  # below this share of the rating a drive's thrust is not judged [-]


def mismatch_limit_n(rating_n: float, expected_n: float, fraction: float) -> float:
    """How far a drive's delivered thrust may be from a healthy drive's ``expected_n`` [N]: ``fraction``
    of its rating ``rating_n``, or at low load :data:`RELATIVE_MISMATCH` of the expected thrust, floored
    at :data:`RELATIVE_FLOOR` of the rating."""
    return min(fraction * rating_n, max(RELATIVE_MISMATCH * abs(expected_n), RELATIVE_FLOOR * rating_n))


@dataclass(frozen=True)
class ThrusterFeedback:
    """What a drive reports: delivered thrust [N], azimuth/rudder angle [rad], readiness."""

    name: str
    thrust_n: float
    azimuth_rad: float
    ready: bool
    t_s: float


@dataclass
class _Health:
    spec: ThrusterSpec
    expected_n: float = 0.0
    error_n: float = 0.0  # |delivered − expected|, low-passed over MISMATCH_FILTER_S [N]
    limit_n: float = math.inf  # the mismatch limit, low-passed likewise [N] (inf until the first feedback)
    last_feedback: ThrusterFeedback | None = None
    ready_since_t_s: float | None = None
    not_ready: bool = False
    mismatch_since_t_s: float | None = None
    failed_mismatch: bool = False
    detail: str = ""


class ThrusterMonitor:
    """Tracks each thruster's availability from commands and feedback.

    Parameters
    ----------
    thrusters : sequence of ThrusterSpec
    settings : ThrusterMonitorSettings
    alarms : AlarmRegistry
    readmit_s : float
        Ready time before a "not ready" thruster is used again [s].
    """

    def __init__(self, thrusters: Sequence[ThrusterSpec], settings: ThrusterMonitorSettings, alarms: AlarmRegistry,
                 readmit_s: float = 5.0) -> None:
        self.settings = settings
        self.alarms = alarms
        self.readmit_s = readmit_s
        self._health = [_Health(spec) for spec in thrusters]
        self._index = {spec.name: i for i, spec in enumerate(thrusters)}
        self.available = np.ones(len(self._health), dtype=bool)
        self.feedback_seen = False
        self.unknown_feedback = 0
        # alarm codes built once (an f-string per thruster and step cost more than the health logic)
        self._codes = [(f"thruster.{spec.name}.feedback_lost", f"thruster.{spec.name}.unavailable")
                       for spec in thrusters]
        # per dt: (per thruster (1 − e^{−dt/T}, Ṫmax·dt), mismatch filter gain), computed once per value
        self._factors: dict[float, tuple[list[tuple[float, float]], float]] = {}
        self._available_list = [True] * len(self._health)
        # the codes this monitor has raised (only it raises them): clear() is called only for these, not for
        # every thruster and step (a registry look-up each, most of the monitor's cost)
        self._raised: set[str] = set()

    def feedback(self, items: Sequence[ThrusterFeedback]) -> None:
        """Store the latest feedback of each drive."""
        for item in items:
            index = self._index.get(item.name)
            if index is None:
                self.unknown_feedback += 1
                continue
            self._health[index].last_feedback = item
            self.feedback_seen = True

    def update(self, t_s: float, dt_s: float, commanded_thrust_n: np.ndarray) -> np.ndarray:
        """Advance the expected drive response by ``dt_s`` and decide availability.

        Parameters
        ----------
        t_s : float
            Now [s].
        dt_s : float
            Time since the previous call [s].
        commanded_thrust_n : ndarray, shape (n,)
            Thrust commanded in the previous cycle (what the drives are following) [N].

        Returns
        -------
        ndarray of bool, shape (n,)
            Availability mask for the allocator (a view, updated in place).
        """
        s = self.settings
        alarms = self.alarms
        if dt_s > 0.0:
            # the measured period takes a handful of values (k·dt differences jitter in the last bits)
            factors = self._factors.get(dt_s)
            if factors is None:
                factors = ([(1.0 - math.exp(-dt_s / h.spec.time_constant_s), h.spec.thrust_rate_limit_nps * dt_s)
                            for h in self._health], -math.expm1(-dt_s / MISMATCH_FILTER_S))
                if len(self._factors) < 64:
                    self._factors[dt_s] = factors
            responses, mismatch_alpha = factors
        targets = commanded_thrust_n.tolist() if type(commanded_thrust_n) is np.ndarray else list(commanded_thrust_n)
        timeout = s.feedback_timeout_s
        fraction = s.mismatch_fraction
        available_all = self._available_list
        raised = self._raised
        for i, health in enumerate(self._health):
            spec = health.spec
            # Expected delivered thrust: first-order lag with the drive's rate limit.
            target = float(targets[i])
            if dt_s > 0.0:
                response, limit = responses[i]
                step = (target - health.expected_n) * response
                # max(−limit, min(limit, step)) written out (same result, NaN included; no builtin calls)
                step = step if step < limit else limit
                health.expected_n += step if step > -limit else -limit
            feedback = health.last_feedback
            name = spec.name
            lost_code, unavailable_code = self._codes[i]
            if feedback is None or t_s - feedback.t_s > timeout:
                # No (recent) feedback: availability keeps its last state; flag only if it was seen before.
                if feedback is not None:
                    alarms.raise_(t_s, lost_code, Severity.WARNING,
                                  f"{name}: no feedback for more than {s.feedback_timeout_s:g} s")
                    raised.add(lost_code)
                elif lost_code in raised:
                    alarms.clear(t_s, lost_code)
                    raised.discard(lost_code)
            else:
                if lost_code in raised:
                    alarms.clear(t_s, lost_code)
                    raised.discard(lost_code)
                if not feedback.ready:
                    health.not_ready = True
                    health.ready_since_t_s = None
                    health.detail = "drive reports not ready"
                elif health.not_ready:
                    if health.ready_since_t_s is None:
                        health.ready_since_t_s = t_s
                    if t_s - health.ready_since_t_s >= self.readmit_s:
                        health.not_ready = False
                        health.expected_n = feedback.thrust_n
                        health.error_n = 0.0
                        health.limit_n = math.inf
                        health.detail = ""
                if feedback.ready and not health.failed_mismatch and not health.not_ready:
                    # The error and the limit are low-passed (the command of a drive in DP fluctuates; a
                    # dead drive's error dips whenever its command does) and judged with hysteresis: the
                    # mismatch persists until the filtered error falls below half the limit. The limit is
                    # mismatch_fraction of the rating, or — when the drive is asked for less — half of
                    # what it should deliver, floored at RELATIVE_FLOOR of the rating: a drive delivering
                    # nothing (or pushing the wrong way) at 5–20 % load is a failure too.
                    error = abs(feedback.thrust_n - health.expected_n)
                    limit_now = mismatch_limit_n(spec.max_thrust_n, health.expected_n, fraction)
                    if not math.isfinite(health.limit_n):
                        health.limit_n = limit_now
                    if dt_s > 0.0:
                        alpha = mismatch_alpha
                        health.error_n += (error - health.error_n) * alpha
                        health.limit_n += (limit_now - health.limit_n) * alpha
                    limit = health.limit_n
                    if health.error_n > limit or (health.mismatch_since_t_s is not None and
                                                  health.error_n > 0.5 * limit):
                        if health.mismatch_since_t_s is None:
                            health.mismatch_since_t_s = t_s
                        if t_s - health.mismatch_since_t_s >= s.mismatch_persist_s:
                            health.failed_mismatch = True
                            health.detail = (f"delivered {feedback.thrust_n:.4g} N, expected "
                                             f"{health.expected_n:.4g} N")
                    else:
                        health.mismatch_since_t_s = None
            available = not (health.not_ready or health.failed_mismatch)
            if not available:
                health.expected_n = 0.0  # it is commanded to zero from now on
            available_all[i] = available
            if not available:
                alarms.raise_(t_s, unavailable_code, Severity.ALARM, f"{name} removed from allocation: {health.detail}")
                raised.add(unavailable_code)
            elif unavailable_code in raised:
                alarms.clear(t_s, unavailable_code)
                raised.discard(unavailable_code)
        self.available[:] = available_all  # one write instead of a numpy item write per thruster
        return self.available

    def reset(self, name: str) -> bool:
        """Operator reset of a latched mismatch failure; returns whether the thruster exists."""
        index = self._index.get(name)
        if index is None:
            return False
        health = self._health[index]
        health.failed_mismatch = False
        health.mismatch_since_t_s = None
        health.error_n = 0.0
        health.limit_n = math.inf
        health.expected_n = health.last_feedback.thrust_n if health.last_feedback else 0.0
        return True

    def delivered(self) -> tuple[np.ndarray, np.ndarray] | None:
        """Latest delivered thrust [N] and azimuth [rad] per thruster, or None without feedback."""
        if not self.feedback_seen:
            return None
        thrust = []
        azimuth = []
        for h in self._health:  # one pass over the drives for both lists
            feedback = h.last_feedback
            if feedback is not None:
                thrust.append(feedback.thrust_n)
                azimuth.append(feedback.azimuth_rad)
            else:
                thrust.append(0.0)
                azimuth.append(h.spec.angle_rad)
        return np.array(thrust), np.array(azimuth)

    def status(self) -> list[dict[str, object]]:
        """Per-thruster availability for the status message."""
        return [{"name": h.spec.name, "available": bool(self.available[i]), "detail": h.detail}
                for i, h in enumerate(self._health)]

    def state_dict(self) -> dict[str, object]:
        return {"latched": [h.spec.name for h in self._health if h.failed_mismatch]}

    def load_state_dict(self, state: dict[str, object]) -> None:
        latched = state.get("latched", [])
        if isinstance(latched, list):
            for name in latched:
                index = self._index.get(str(name))
                if index is not None:
                    self._health[index].failed_mismatch = True
                    self._health[index].detail = "latched failure before restart"
