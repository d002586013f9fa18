"""Health of the sensor transports (docs/fault-handling.md), shared by the daemon and the lockstep simulation.

Two things are watched per transport (serial port, CAN bus, MAVLink link):

* **Error rate** — every frame a decoder hands on is counted as decoded or rejected. Over a sliding
  window of ``window_s`` (default 10 s) the share of *malformed* input (checksum errors, garbage,
  truncated fast packets, bad fields ...) raises ``transport.<name>.error_rate`` when it exceeds
  ``error_rate_alarm`` with at least :data:`MIN_BAD_FOR_ALARM` bad frames (so one bad sentence on a
  quiet line is not an alarm). Input the *sensor* flagged invalid (GGA quality 0, RMC V, THS V, NMEA
  2000 "not available", GPS_RAW_INT without a fix — :data:`SENSOR_FLAGGED_REASONS`) is well-formed
  traffic: it is never used (the codecs do not turn it into measurements) and is counted apart, but
  it is not a transport error — a receiver without a fix is not a broken cable.
* **Link state** — a :class:`~interfaces.messages.LinkStatus` (serial port gone, CAN bus error,
  MAVLink heartbeat lost) marks every sensor on that link *disconnected* in the hub and raises
  ``transport.<link>.link``; the link coming back clears both. A MAVLink link may carry several
  autopilots: a status naming one system (:func:`dpcontrol.runtime.inputs.link_source`) concerns
  only the sensors of that system.

The window is kept as fixed-width time buckets (a ring of counts), so the cost per input and per
cycle is constant whatever the traffic rate, and memory does not grow.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Iterable, Sequence

from dpcontrol.runtime.alarms import AlarmRegistry, Severity
from dpcontrol.runtime.hub import SensorHub
from dpcontrol.runtime.inputs import SensorRouter, link_alarm_code
from interfaces.messages import LinkStatus

ERROR_WINDOW_S = 10.0
BUCKET_S = 0.5
MIN_BAD_FOR_ALARM = 5
SENSOR_FLAGGED_REASONS = frozenset({"invalid_fix", "invalid_status", "not_available", "no_data",
                                    "magnetic_heading", "unsupported_reference"})
"""Reject reasons that are the sensor saying "no valid data" (or data this controller does not use),
carried in a well-formed frame: not transport errors."""


class TransportHealth:
    """Decoded vs malformed inputs of one transport over a sliding window.

    Parameters
    ----------
    window_s : float
        Length of the error-rate window [s].
    bucket_s : float
        Time resolution of the window [s] (the window is ``ceil(window_s / bucket_s)`` buckets).

    Attributes
    ----------
    ok_total, rejected_total, flagged_total : int
        Frames decoded, rejected as malformed, and flagged invalid by the sensor since start.
    reasons : collections.Counter
        Rejected and flagged frames by reason.
    """

    def __init__(self, window_s: float = ERROR_WINDOW_S, bucket_s: float = BUCKET_S) -> None:
        if not window_s > 0.0 or not bucket_s > 0.0:
            raise ValueError("window_s and bucket_s must be > 0")
        self.window_s = window_s
        self.bucket_s = bucket_s
        n = max(1, math.ceil(window_s / bucket_s))
        self._n = n
        self._slot = [-1] * n  # absolute bucket index held by each ring slot (-1: empty)
        self._good = [0] * n
        self._bad = [0] * n
        # newest bucket index that ever counted a malformed frame: older than the window means no malformed
        # frame in it, which rate() answers without its pass over the ring (the usual case, every cycle)
        self._last_bad = -math.inf
        self.ok_total = 0
        self.rejected_total = 0
        self.flagged_total = 0
        self.reasons: Counter[str] = Counter()

    def add(self, t_s: float, reason: str | None = None) -> None:
        """Count one frame received at ``t_s`` [s]: ``reason`` None = decoded, else why it was rejected."""
        bad = False
        if reason is None:
            self.ok_total += 1
        else:
            self.reasons[reason] += 1
            if reason in SENSOR_FLAGGED_REASONS:
                self.flagged_total += 1
            else:
                self.rejected_total += 1
                bad = True
        index = math.floor(t_s / self.bucket_s)
        slot = index % self._n
        if self._slot[slot] != index:
            if self._slot[slot] > index:  # older than what the slot holds now: outside the window
                return
            self._slot[slot] = index
            self._good[slot] = 0
            self._bad[slot] = 0
        if bad:
            self._bad[slot] += 1
            self._last_bad = max(self._last_bad, index)
        else:
            self._good[slot] += 1

    def rate(self, t_s: float) -> tuple[float, int]:
        """``(share of malformed frames, number of malformed frames)`` in the window ending at ``t_s``."""
        newest = math.floor(t_s / self.bucket_s)
        oldest = newest - self._n + 1
        if self._last_bad < oldest:  # no malformed frame in the window: the pass below would give (0.0, 0)
            return 0.0, 0
        good = bad = 0
        # (called every control cycle: one pass over the ring, no attribute look-up per slot)
        for index, good_count, bad_count in zip(self._slot, self._good, self._bad, strict=True):
            if oldest <= index <= newest:
                good += good_count
                bad += bad_count
        total = good + bad
        return (bad / total if total else 0.0), bad

    def counters(self) -> dict[str, int]:
        """Totals since start (and per reason, as ``reason.<name>``)."""
        out = {"decoded": self.ok_total, "rejected": self.rejected_total, "flagged_invalid": self.flagged_total}
        out.update({f"reason.{k}": v for k, v in sorted(self.reasons.items())})
        return out


class InputHealth:
    """Error rate and link state of every transport, turned into hub states and alarms.

    Parameters
    ----------
    transports : sequence of str
        Transport names (from the configuration).
    router : SensorRouter
        Which sensors each link (or MAVLink system) feeds.
    error_rate_alarm : float
        Share of malformed frames above which ``transport.<name>.error_rate`` is raised [-].
    window_s : float
        Error-rate window [s].
    """

    def __init__(self, transports: Sequence[str], router: SensorRouter, error_rate_alarm: float,
                 window_s: float = ERROR_WINDOW_S) -> None:
        self.router = router
        self.error_rate_alarm = error_rate_alarm
        self.window_s = window_s
        self.health = {name: TransportHealth(window_s) for name in transports}
        self._alarm_codes: dict[str, str] = {}  # transport → its error-rate alarm code, built once

    def count(self, transport: str, t_s: float, reason: str | None = None) -> None:
        """One frame of ``transport`` at ``t_s``: decoded (``reason`` None) or rejected for ``reason``."""
        self.of(transport).add(t_s, reason)

    def of(self, transport: str) -> TransportHealth:
        """The counters of ``transport`` (made for one that is not configured: it cannot deliver, but a
        count is kept anyway)."""
        health = self.health.get(transport)
        if health is None:
            health = self.health[transport] = TransportHealth(self.window_s)
        return health

    def apply_links(self, t_s: float, links: Iterable[LinkStatus], hub: SensorHub, alarms: AlarmRegistry) -> None:
        """Mark the sensors of each changed link (dis)connected in the hub; raise/clear the link alarm."""
        for status in links:
            self.mark_links((status,), hub)
            detail = f" ({status.detail})" if status.detail else ""
            alarms.set(t_s, link_alarm_code(status.source), not status.connected, Severity.WARNING,
                       f"{status.source}: link lost{detail}")

    def mark_links(self, links: Iterable[LinkStatus], hub: SensorHub) -> None:
        """Mark the sensors of each changed link (dis)connected in ``hub`` (no alarm: the controller
        replica's hub follows the primary's with this)."""
        for status in links:
            for sensor in self.router.sensors_on(status.source):
                hub.set_disconnected(sensor, not status.connected)

    def update_alarms(self, t_s: float, alarms: AlarmRegistry) -> None:
        """Raise or clear each transport's error-rate alarm for the window ending at ``t_s``."""
        limit = self.error_rate_alarm
        codes = self._alarm_codes
        for name, health in self.health.items():
            rate, bad = health.rate(t_s)
            active = rate > limit and bad >= MIN_BAD_FOR_ALARM
            code = codes.get(name)
            if code is None:
                code = codes[name] = f"transport.{name}.error_rate"
            if active and not alarms.is_active(code):
                alarms.raise_(t_s, code, Severity.WARNING,
                              f"{name}: {100 * rate:.0f} % of the inputs malformed in the last {self.window_s:g} s "
                              f"({bad} frames)")
            elif not active:
                alarms.clear(t_s, code)

    def counters(self) -> dict[str, dict[str, int]]:
        """Per-transport totals (see :meth:`TransportHealth.counters`)."""
        return {name: health.counters() for name, health in self.health.items()}
