"""``loop.realtime_priority`` / ``loop.cpu_affinity``: applied to the loop's own thread only; when the system
refuses, a warning alarm and the loop runs on with the normal scheduler.

Each case runs the daemon's scheduling set-up in a thread of its own, so the test process keeps its
normal scheduler whatever happens.
"""

from __future__ import annotations

import copy
import os
import threading
from typing import Any

from test_config import BASE

from dpcontrol.runtime.config import parse_config
from dpcontrol.service.daemon import Daemon


def _apply_in_thread(loop: dict[str, Any]) -> tuple[Daemon, dict[str, Any]]:
    mapping = copy.deepcopy(BASE)
    mapping["loop"] = loop
    daemon = Daemon(parse_config(mapping))
    seen: dict[str, Any] = {}

    def body() -> None:
        daemon._apply_realtime()
        seen["policy"] = os.sched_getscheduler(0)
        seen["priority"] = os.sched_getparam(0).sched_priority
        seen["cpus"] = os.sched_getaffinity(0)

    thread = threading.Thread(target=body)
    thread.start()
    thread.join(10.0)
    assert not thread.is_alive()
    return daemon, seen


def test_priority_and_affinity_apply_to_the_loop_thread_or_raise_a_warning() -> None:
    cpu = min(os.sched_getaffinity(0))
    daemon, seen = _apply_in_thread({"rate_hz": 10, "realtime_priority": 10, "cpu_affinity": [cpu]})
    assert seen["cpus"] == {cpu}
    if daemon.alarms.is_active("loop.realtime"):    # no privilege for SCHED_FIFO here
        assert "realtime_priority 10" in daemon.alarms.active()[0].text
        assert seen["policy"] == os.SCHED_OTHER
    else:
        assert seen["policy"] == os.SCHED_FIFO and seen["priority"] == 10
        assert daemon.realtime_detail == f"cpus [{cpu}], SCHED_FIFO 10"
    assert os.sched_getscheduler(0) == os.SCHED_OTHER   # the calling (test) thread is untouched


def test_a_cpu_that_does_not_exist_is_a_warning_not_a_failure() -> None:
    daemon, seen = _apply_in_thread({"rate_hz": 10, "cpu_affinity": [4095]})
    assert daemon.alarms.is_active("loop.realtime")
    (alarm,) = daemon.alarms.active()
    assert "cpu_affinity [4095]" in alarm.text and "normal scheduler" in alarm.text
    assert seen["cpus"] == os.sched_getaffinity(0) and seen["policy"] == os.SCHED_OTHER
    assert daemon.realtime_detail == "normal scheduler"


def test_no_settings_change_nothing() -> None:
    daemon, seen = _apply_in_thread({"rate_hz": 10})
    assert not daemon.alarms.is_active("loop.realtime")
    assert seen["policy"] == os.SCHED_OTHER and daemon.realtime_detail == "normal scheduler"
