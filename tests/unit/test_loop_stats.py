"""``LoopStats``: the daemon's cycle timing summary (``dpcontrol run --stats-out``, the status)."""

from __future__ import annotations

import pytest

from dpcontrol.service.daemon import TIMING_WINDOW, LoopStats


def test_the_summary_splits_the_time_to_the_command_and_the_off_cpu_part_of_the_step() -> None:
    stats = LoopStats(0.1)
    for k in range(100):
        slow = k == 99
        # inputs 100 µs; step 800 µs, of which the thread ran 790 (3000 and 1000 in the slow cycle); command 150
        stats.add_phases(100.0, 3000.0 if slow else 800.0, 150.0, 1000.0 if slow else 790.0)
        stats.add(1200.0, 3250.0 if slow else 1050.0, -20.0 if k % 2 else 30.0)
    summary = stats.summary()
    phases = summary["phases_us"]
    assert summary["cycles"] == 100 and summary["window"] == 100
    assert phases["inputs"]["median"] == 100.0 and phases["command"]["median"] == 150.0
    assert phases["step"]["median"] == 800.0 and phases["step"]["max"] == 3000.0
    assert phases["step_off_cpu"]["median"] == pytest.approx(10.0)
    assert phases["step_off_cpu"]["max"] == pytest.approx(2000.0)  # the slow step waited, it did not compute
    assert summary["start_to_command_published_us"]["max"] == 3250.0
    assert summary["period_jitter_us"]["median"] == pytest.approx(25.0)  # |lateness|


def test_a_cpu_time_above_the_wall_time_counts_as_no_waiting() -> None:
    # the thread CPU clock and the monotonic clock are read a few hundred ns apart
    stats = LoopStats(0.1)
    stats.add_phases(10.0, 500.0, 20.0, 500.4)
    stats.add(600.0, 530.0, 0.0)
    assert stats.summary()["phases_us"]["step_off_cpu"]["max"] == 0.0


def test_the_window_keeps_the_last_cycles_only() -> None:
    stats = LoopStats(0.1)
    for k in range(TIMING_WINDOW + 10):
        stats.add_phases(1.0, 5000.0 if k < 10 else 500.0, 1.0, 500.0)
        stats.add(600.0, 600.0, 0.0)
    summary = stats.summary()
    assert summary["cycles"] == TIMING_WINDOW + 10 and summary["window"] == TIMING_WINDOW
    assert summary["phases_us"]["step"]["max"] == 500.0  # the first ten slow cycles have left the window
    assert summary["phases_us"]["step_off_cpu"]["max"] == 0.0
