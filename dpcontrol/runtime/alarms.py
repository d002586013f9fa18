"""Alarm registry: raise/clear by code, with severity, first-active time and history.

Alarms are what the operator sees on ``dp/<vessel>/status`` and what the recorder keeps. A code
is raised while a condition holds and cleared when it stops; the registry remembers when it
started, counts occurrences and lists every transition since the last call to
:meth:`AlarmRegistry.drain_events` so the recorder logs each change exactly once.
:class:`AlarmJournal` writes the same transitions to the service's log (the journal under systemd), where
the engineer who installs the daemon looks first.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from enum import IntEnum


class Severity(IntEnum):
    """Alarm severity, in increasing order."""

    INFO = 0
    WARNING = 1
    ALARM = 2
    CRITICAL = 3


@dataclass
class Alarm:
    """One alarm code and its current state."""

    code: str
    severity: Severity
    text: str
    since_t_s: float
    active: bool = True
    count: int = 1
    cleared_t_s: float | None = None

    def as_dict(self) -> dict[str, object]:
        return {"code": self.code, "severity": self.severity.name.lower(), "text": self.text,
                "since_t_s": self.since_t_s, "active": self.active, "count": self.count}


@dataclass(frozen=True)
class AlarmEvent:
    """A transition of an alarm: raised or cleared at ``t_s``."""

    t_s: float
    code: str
    severity: Severity
    text: str
    raised: bool


@dataclass
class AlarmRegistry:
    """Active and recently cleared alarms, keyed by code.

    Parameters
    ----------
    keep_cleared_s : float
        How long a cleared alarm stays listed (inactive) in the status [s].
    """

    keep_cleared_s: float = 60.0
    _alarms: dict[str, Alarm] = field(default_factory=dict)
    _events: list[AlarmEvent] = field(default_factory=list)

    def raise_(self, t_s: float, code: str, severity: Severity, text: str) -> None:
        """Raise ``code`` (no-op if already active with the same text; the text may be updated)."""
        alarm = self._alarms.get(code)
        if alarm is not None and alarm.active:
            if alarm.text != text or alarm.severity != severity:
                alarm.text = text
                alarm.severity = severity
            return
        if alarm is None:
            self._alarms[code] = Alarm(code, severity, text, t_s)
        else:
            alarm.active = True
            alarm.severity = severity
            alarm.text = text
            alarm.since_t_s = t_s
            alarm.count += 1
            alarm.cleared_t_s = None
        self._events.append(AlarmEvent(t_s, code, severity, text, raised=True))

    def set(self, t_s: float, code: str, active: bool, severity: Severity, text: str) -> None:
        """Raise or clear ``code`` according to ``active``."""
        if active:
            self.raise_(t_s, code, severity, text)
        else:
            self.clear(t_s, code)

    def clear(self, t_s: float, code: str) -> None:
        """Clear ``code`` if it is active."""
        alarm = self._alarms.get(code)
        if alarm is None or not alarm.active:
            return
        alarm.active = False
        alarm.cleared_t_s = t_s
        self._events.append(AlarmEvent(t_s, code, alarm.severity, alarm.text, raised=False))

    def is_active(self, code: str) -> bool:
        alarm = self._alarms.get(code)
        return alarm is not None and alarm.active

    def active(self) -> list[Alarm]:
        return [a for a in self._alarms.values() if a.active]

    def listed(self, t_s: float) -> list[Alarm]:
        """Active alarms plus those cleared less than ``keep_cleared_s`` ago (pruning older ones)."""
        for code in [c for c, a in self._alarms.items()
                     if not a.active and a.cleared_t_s is not None and t_s - a.cleared_t_s > self.keep_cleared_s]:
            del self._alarms[code]
        return sorted(self._alarms.values(), key=lambda a: (not a.active, -a.severity, a.since_t_s))

    def drain_events(self) -> list[AlarmEvent]:
        """Transitions since the last call (for the recorder and logs)."""
        events, self._events = self._events, []
        return events


class CountAlarm:
    """An alarm on a running count of events that have no "back to normal" of their own (dropped inputs,
    rejected requests, foreign commands): raised when the count grows, cleared ``hold_s`` [s] after it
    last grew.

    Use: ``if alarm.grew(registry, t_s, count): registry.raise_(t_s, alarm.code, alarm.severity, text)`` —
    the text is built only when the count grew (this runs every control cycle).
    """

    __slots__ = ("_grew_t", "code", "count", "hold_s", "severity")

    def __init__(self, code: str, severity: Severity, hold_s: float = 10.0) -> None:
        self.code = code
        self.severity = severity
        self.hold_s = hold_s
        self.count = 0
        self._grew_t = -math.inf

    def grew(self, registry: AlarmRegistry, t_s: float, count: int) -> bool:
        """True if ``count`` changed since the last call (the caller raises); clears the alarm once quiet."""
        if count != self.count:
            self.count = count
            self._grew_t = t_s
            return True
        if t_s - self._grew_t > self.hold_s:
            registry.clear(t_s, self.code)
        return False


#: log level of a raised alarm in the journal, by severity (a cleared one is logged at INFO)
LOG_LEVELS = {Severity.INFO: logging.INFO, Severity.WARNING: logging.WARNING, Severity.ALARM: logging.ERROR,
              Severity.CRITICAL: logging.CRITICAL}


@dataclass
class _Held:
    """Transitions of one code not logged yet (it changed again within the interval)."""

    count: int
    last: AlarmEvent


class AlarmJournal:
    """Alarm transitions to a logger, at most one line per code per ``min_interval_s``.

    A sensor at the edge of a threshold can raise and clear an alarm every cycle; its transitions within
    ``min_interval_s`` of the last line logged for that code are counted, and one line at the end of the
    interval gives their number and the code's state then — so the journal always ends with each code's
    true state, and a flapping sensor costs one line per interval instead of 20 a second. The status and
    the recorder keep every transition.

    Parameters
    ----------
    logger : logging.Logger
    min_interval_s : float
        Shortest time between two lines for the same code [s].
    """

    def __init__(self, logger: logging.Logger, min_interval_s: float = 10.0) -> None:
        self.logger = logger
        self.min_interval_s = min_interval_s
        self._last_logged: dict[str, float] = {}
        self._held: dict[str, _Held] = {}

    def write(self, t_s: float, events: Iterable[AlarmEvent]) -> None:
        """Log ``events`` (from :meth:`AlarmRegistry.drain_events`), and what was held and is now due.

        Parameters
        ----------
        t_s : float
            Now, on the clock of the events [s].
        events : iterable of AlarmEvent
        """
        for event in events:
            last = self._last_logged.get(event.code)
            held = self._held.get(event.code)
            if held is not None:
                held.count += 1
                held.last = event
            elif last is not None and event.t_s - last < self.min_interval_s:
                self._held[event.code] = _Held(1, event)
            else:
                self._log(event, "")
        if self._held:
            for code in [c for c, h in self._held.items() if t_s - self._last_logged[c] >= self.min_interval_s]:
                held = self._held.pop(code)
                since = t_s - self._last_logged[code]
                self._log(held.last, f" ({held.count} transition{'s' if held.count > 1 else ''} of this alarm "
                                     f"in the last {since:.0f} s)")

    def _log(self, event: AlarmEvent, note: str) -> None:
        self._last_logged[event.code] = event.t_s
        severity = event.severity.name
        if event.raised:
            self.logger.log(LOG_LEVELS[event.severity], "alarm raised [%s] %s: %s%s", severity, event.code,
                            event.text, note)
        else:
            self.logger.info("alarm cleared [%s] %s: %s%s", severity, event.code, event.text, note)
