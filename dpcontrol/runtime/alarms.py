"""Alarm registry: raise/clear by code, with severity, first-active time and history.

Alarms are what the operator sees on ``dp/<vessel>/status`` and what the recorder keeps. A code
is raised while a condition holds and cleared when it stops; the registry remembers when it
started, counts occurrences and lists every transition since the last call to
:meth:`AlarmRegistry.drain_events` so the recorder logs each change exactly once.
"""

from __future__ import annotations

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

    def history_codes(self) -> set[str]:
        """Codes ever raised and still listed."""
        return set(self._alarms)
