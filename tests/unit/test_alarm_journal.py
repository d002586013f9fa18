"""Alarm transitions in the service's log (``AlarmJournal``): one line per transition, the level from the
severity, and a flapping alarm held to one line per interval that ends on the code's true state."""

from __future__ import annotations

import logging

import pytest

from dpcontrol.runtime.alarms import AlarmJournal, AlarmRegistry, CountAlarm, Severity

LOGGER = "test.alarm_journal"


def _lines(caplog: pytest.LogCaptureFixture) -> list[tuple[int, str]]:
    lines = [(r.levelno, r.getMessage()) for r in caplog.records if r.name == LOGGER]
    caplog.clear()
    return lines


def test_each_transition_is_one_line_at_the_level_of_its_severity(caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.DEBUG, logger=LOGGER)
    alarms = AlarmRegistry()
    journal = AlarmJournal(logging.getLogger(LOGGER))
    alarms.raise_(0.0, "transport.serial0.link", Severity.WARNING, "serial0: link lost (open /dev/ttyS1 failed)")
    alarms.raise_(0.0, "hub.position_lost", Severity.ALARM, "no position reference")
    alarms.raise_(0.0, "controller.internal_error", Severity.CRITICAL, "control step raised")
    alarms.raise_(0.0, "operator.setpoint_rejected", Severity.INFO, "set-point too far")
    journal.write(0.0, alarms.drain_events())
    assert _lines(caplog) == [
        (logging.WARNING, "alarm raised [WARNING] transport.serial0.link: serial0: link lost (open /dev/ttyS1 failed)"),
        (logging.ERROR, "alarm raised [ALARM] hub.position_lost: no position reference"),
        (logging.CRITICAL, "alarm raised [CRITICAL] controller.internal_error: control step raised"),
        (logging.INFO, "alarm raised [INFO] operator.setpoint_rejected: set-point too far"),
    ]
    alarms.raise_(1.0, "hub.position_lost", Severity.ALARM, "no position reference")  # already active: no event
    alarms.clear(30.0, "hub.position_lost")
    journal.write(30.0, alarms.drain_events())
    assert _lines(caplog) == [(logging.INFO, "alarm cleared [ALARM] hub.position_lost: no position reference")]


def test_a_flapping_alarm_is_one_line_per_interval_ending_on_its_true_state(
        caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.DEBUG, logger=LOGGER)
    alarms = AlarmRegistry()
    journal = AlarmJournal(logging.getLogger(LOGGER), min_interval_s=10.0)
    code = "sensor.gnss1.stale"
    lines: list[tuple[float, int, str]] = []
    for cycle in range(251):  # 25 s at 10 Hz: raised on even cycles, cleared on odd ones, until 20 s
        t = cycle * 0.1
        if t < 20.0:
            alarms.set(t, code, cycle % 2 == 0, Severity.WARNING, "gnss1: no fix for 2 s")
        journal.write(t, alarms.drain_events())
        lines += [(t, level, text) for level, text in _lines(caplog)]
    # 200 transitions: the first logged at once, then one line per 10 s interval
    assert [round(t, 1) for t, _, _ in lines] == [0.0, 10.0, 20.0]
    assert lines[0][2] == f"alarm raised [WARNING] {code}: gnss1: no fix for 2 s"
    # at 10.0 s the alarm had just been raised again: the held line says so, with the count
    assert lines[1][2] == f"alarm raised [WARNING] {code}: gnss1: no fix for 2 s (100 transitions of this alarm " \
                          "in the last 10 s)"
    # the last transition (cleared at 19.9 s) is the state the journal ends on
    assert lines[2][1] == logging.INFO and lines[2][2].startswith(f"alarm cleared [WARNING] {code}")
    assert "(99 transitions of this alarm in the last 10 s)" in lines[2][2]
    assert not alarms.is_active(code)


def test_other_codes_are_not_held_by_a_flapping_one(caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.DEBUG, logger=LOGGER)
    alarms = AlarmRegistry()
    journal = AlarmJournal(logging.getLogger(LOGGER), min_interval_s=10.0)
    alarms.raise_(0.0, "a", Severity.WARNING, "first")
    journal.write(0.0, alarms.drain_events())
    alarms.clear(0.5, "a")
    alarms.raise_(0.5, "b", Severity.ALARM, "second")
    journal.write(0.5, alarms.drain_events())
    assert _lines(caplog) == [(logging.WARNING, "alarm raised [WARNING] a: first"),
                              (logging.ERROR, "alarm raised [ALARM] b: second")]
    journal.write(10.0, [])
    assert _lines(caplog) == [(logging.INFO, "alarm cleared [WARNING] a: first (1 transition of this alarm in the "
                                             "last 10 s)")]


def test_a_count_alarm_is_raised_when_its_count_grows_and_cleared_when_quiet() -> None:
    alarms = AlarmRegistry()
    dropped = CountAlarm("inputs.overflow", Severity.WARNING, hold_s=10.0)
    assert not dropped.grew(alarms, 0.0, 0)
    assert dropped.grew(alarms, 1.0, 3)
    alarms.raise_(1.0, dropped.code, dropped.severity, "3 dropped")
    assert not dropped.grew(alarms, 5.0, 3)
    assert dropped.grew(alarms, 6.0, 4)  # a later growth restarts the hold
    assert not dropped.grew(alarms, 15.9, 4) and alarms.is_active("inputs.overflow")
    assert not dropped.grew(alarms, 16.1, 4) and not alarms.is_active("inputs.overflow")
