"""The demo gives the daemon's loop thread SCHED_FIFO only where the user may (root or RLIMIT_RTPRIO)."""

from __future__ import annotations

import resource
import shutil
from pathlib import Path

import pytest
import yaml

from sim_plant.bench import demo
from sim_plant.scenario import builtin_scenario_path


@pytest.mark.parametrize(("euid", "rtprio", "expected"), [
    (0, (0, 0), demo.DEMO_REALTIME_PRIORITY),  # root: CAP_SYS_NICE
    (1000, (0, 0), None),  # a desktop user: ulimit -r 0
    (1000, (20, 20), 20),  # limits.conf grants up to 20
    (1000, (resource.RLIM_INFINITY, resource.RLIM_INFINITY), demo.DEMO_REALTIME_PRIORITY),
])
def test_priority_follows_what_the_user_may_set(monkeypatch: pytest.MonkeyPatch, euid: int,
                                                rtprio: tuple[int, int], expected: int | None) -> None:
    monkeypatch.setattr(demo.os, "geteuid", lambda: euid)
    monkeypatch.setattr(demo.resource, "getrlimit", lambda which: rtprio)
    assert demo.realtime_priority_allowed() == expected


@pytest.mark.parametrize("realtime", [False, True])
def test_the_configuration_asks_for_it_only_when_allowed(monkeypatch: pytest.MonkeyPatch, tmp_path: Path,
                                                         realtime: bool) -> None:
    for allowed, expected in ((7, 7 if realtime else None), (None, None)):
        monkeypatch.setattr(demo, "realtime_priority_allowed", lambda allowed=allowed: allowed)
        run_dir = tmp_path / str(allowed)
        run_dir.mkdir()
        _, config_file, wiring = demo.prepare(builtin_scenario_path("demo"), run_dir, realtime=realtime)
        shutil.rmtree(wiring["short_dir"])
        loop = yaml.safe_load(config_file.read_text(encoding="utf-8"))["loop"]
        assert loop.get("realtime_priority") == expected
