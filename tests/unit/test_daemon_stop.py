"""How the daemon's loop is asked to stop.

A signal handler runs on the loop's own thread, between two bytecodes of whatever the loop was doing —
possibly inside ``Event.wait`` while it holds the event's lock. The handler must take no lock there, or
the daemon hangs for ever on SIGTERM/SIGHUP with the thrusters on their last command (seen once in a full
test run before the handler only set flags).
"""

from __future__ import annotations

import logging
import signal
import threading
import time

import pytest
from test_config import BASE

from dpcontrol.runtime.config import parse_config
from dpcontrol.service.daemon import Daemon


def test_the_signal_handler_takes_no_lock_the_interrupted_loop_may_hold() -> None:
    daemon = Daemon(parse_config(BASE))
    returned = threading.Event()

    def signal_inside_the_wait() -> None:
        with daemon._stop._cond:  # where Event.wait holds it (the handler runs on that same thread)
            daemon._on_signal(signal.SIGHUP)
        returned.set()

    thread = threading.Thread(target=signal_inside_the_wait, daemon=True)  # (a hang must not block pytest)
    thread.start()
    thread.join(5.0)
    assert returned.is_set(), "the signal handler blocked on the lock of the wait it interrupted"
    assert daemon.stopped_by == "SIGHUP"


def test_a_signal_stops_the_loop_within_a_period_and_is_named(caplog: pytest.LogCaptureFixture) -> None:
    # (its serial port and CAN bus do not exist here: links down, the loop runs in standby; zenoh: no
    # endpoint, no scouting, so nothing leaves the process)
    daemon = Daemon(parse_config({**BASE, "loop": {"rate_hz": 10}}))
    codes: list[int] = []
    thread = threading.Thread(target=lambda: codes.append(daemon.run(duration_s=60.0, install_signals=False)))
    with caplog.at_level(logging.INFO, logger="dpcontrol.service.daemon"):
        thread.start()
        deadline = time.monotonic() + 60.0
        while daemon.stats.count < 3 and time.monotonic() < deadline:  # the loop is running
            time.sleep(0.05)
        assert daemon.stats.count >= 3
        asked = time.monotonic()
        daemon._on_signal(signal.SIGTERM)  # (from this thread: the loop's wait is not interrupted)
        thread.join(30.0)
        stopped_after_s = time.monotonic() - asked
    assert not thread.is_alive() and codes == [0]
    assert stopped_after_s < 0.1 * 3  # its current wait (≤ one 0.1 s period), the last cycle, the stop
    assert "stopping (SIGTERM): zero thrust commanded, mode standby" in caplog.text
