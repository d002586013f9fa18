"""The thruster monitor's fail-safe behaviours: the absolute floor of the mismatch limit, feedback judged only when
new, and a drive whose feedback returns after a loss judged afresh (drives or plant restarted) — each fails a test
here when removed. The plant's drive model (``sim_plant.drives.ThrusterDrives``) delivers the thrust."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dpcontrol.models.thrusters import ThrusterSpec
from dpcontrol.runtime.alarms import AlarmRegistry
from dpcontrol.runtime.config import ThrusterMonitorSettings
from dpcontrol.runtime.thruster_monitor import ThrusterFeedback, ThrusterMonitor, mismatch_limit_n
from sim_plant.drives import ThrusterCommand, ThrusterDrives

DT = 0.1
SPEC = ThrusterSpec(name="bow", kind="tunnel", x_m=30.0, y_m=0.0, max_thrust_n=1e5, min_thrust_n=-1e5,
                    angle_rad=math.pi / 2, time_constant_s=1.0, thrust_rate_limit_nps=5e4)


def _run(command_of_t, seconds: float, silent: tuple[float, float] | None = None, restart_at: float | None = None,
         noise_n: float = 0.0, seed: int = 3) -> tuple[ThrusterMonitor, AlarmRegistry, float | None]:
    """The drive (plant model) follows ``command_of_t(t)`` while available; its feedback is silent over
    ``silent`` = (from, to) [s]; at ``restart_at`` the drive is replaced by a new one (a restarted plant: at rest).
    Returns the monitor, its alarms and when the drive was first taken out (None: never)."""
    alarms = AlarmRegistry()
    monitor = ThrusterMonitor([SPEC], ThrusterMonitorSettings(), alarms)
    drives = ThrusterDrives([SPEC])
    rng = np.random.default_rng(seed)
    command = np.zeros(1)
    removed = None
    for k in range(round(seconds / DT)):
        t = k * DT
        if restart_at is not None and abs(t - restart_at) < 1e-9:
            drives = ThrusterDrives([SPEC])
        if silent is None or not silent[0] <= t < silent[1]:
            feedback = drives.feedback()[0]
            delivered = feedback.thrust_n + noise_n * rng.standard_normal()
            monitor.feedback([ThrusterFeedback(SPEC.name, delivered, feedback.azimuth_rad, feedback.ready, t)])
        available = monitor.update(t, DT, command)
        if not available[0] and removed is None:
            removed = t
        command[0] = command_of_t(t) if available[0] else 0.0
        drives.command(t, {SPEC.name: ThrusterCommand(float(command[0]))})
        for j in range(5):
            drives.update(t + j * DT / 5, DT / 5)
    return monitor, alarms, removed


def test_the_limit_has_an_absolute_floor_of_a_share_of_the_rating() -> None:
    assert mismatch_limit_n(1e5, 3.672e-16, 0.25) == pytest.approx(0.05 * 1e5)
    assert mismatch_limit_n(1e5, 3.672e-16, 0.25, 0.1) == pytest.approx(0.1 * 1e5)
    assert mismatch_limit_n(1e5, 8e4, 0.25) == pytest.approx(0.25 * 1e5)  # at high load: mismatch_fraction


def test_a_healthy_drive_asked_for_nothing_is_never_judged_on_its_noise() -> None:
    # Commanded ~0 (a vessel in standby or at rest): the expected thrust is a few 1e-16 N; the drive's feedback
    # carries 1 kN (1 % of its rating) of measurement noise. Relative to the expectation alone it would latch.
    monitor, alarms, removed = _run(lambda t: 1e-15 * math.sin(t), 30.0, noise_n=1e3)
    assert removed is None and not alarms.is_active("thruster.bow.unavailable")
    assert abs(monitor._health[0].expected_n) < 1.0  # [N]: asked for nothing, as in the report (3.7e-16 N)


def test_feedback_lost_while_the_command_falls_does_not_latch_the_drive() -> None:
    # In DP at 50 % load; the drives go silent at 30 s (plant stopped) and the command falls to zero (standby);
    # the plant is restarted and reports again at 45 s, a new drive at rest, delivering 0 N against an expectation
    # of ~0 N. The last sample before the silence is not a measure of what the drive does while silent.
    monitor, alarms, removed = _run(lambda t: 5e4 if t < 30.0 else 0.0, 60.0, silent=(30.0, 45.0), restart_at=40.0)
    assert removed is None, monitor.status()
    assert not monitor.is_latched("bow")
    assert not alarms.is_active("thruster.bow.feedback_lost")


def test_a_drive_restarted_in_dp_is_judged_afresh_and_kept() -> None:
    # The command stays at 50 % load through a 10 s silence and the restart; the new drive ramps up from rest at its
    # rate limit: against the expectation carried over the silence (50 kN) that is a mismatch; judged afresh from
    # what it delivers when it comes back, the expectation ramps with it.
    monitor, _, removed = _run(lambda t: 5e4, 60.0, silent=(20.0, 30.0), restart_at=25.0)
    assert removed is None, monitor.status()


def test_a_repeated_sample_is_not_judged() -> None:
    # The transport repeats the last sample (same receive time) for the timeout while the drive is silent; the
    # command changes meanwhile. Judged every cycle, that stale value would start a mismatch.
    alarms = AlarmRegistry()
    monitor = ThrusterMonitor([SPEC], ThrusterMonitorSettings(feedback_timeout_s=30.0, mismatch_persist_s=2.0),
                              alarms)
    command = np.full(1, 5e4)
    for k in range(100):  # 10 s of a healthy drive at 50 kN
        t = k * DT
        monitor.feedback([ThrusterFeedback("bow", 5e4, 0.0, True, t)])
        monitor.update(t, DT, command)
    last = 99 * DT
    command[0] = -5e4
    for k in range(100, 200):  # the same sample again and again (rx time of 9.9 s): no new information
        monitor.feedback([ThrusterFeedback("bow", 5e4, 0.0, True, last)])
        available = monitor.update(k * DT, DT, command)
    assert available[0] and not monitor.is_latched("bow")


def test_a_dead_drive_that_returns_dead_is_judged_again_from_its_return() -> None:
    # The drive stops delivering at 7 s, goes silent from 10 s to 20 s and returns still dead. The re-check is a
    # judgement, not an amnesty: it is latched — after mismatch_persist_s of its own, not at once on a mismatch
    # that was pending before the loss.
    alarms = AlarmRegistry()
    monitor = ThrusterMonitor([SPEC], ThrusterMonitorSettings(), alarms)
    command = np.full(1, 5e4)
    removed = None
    for k in range(400):
        t = k * DT
        if not 10.0 <= t < 20.0:
            delivered = monitor._health[0].expected_n if t < 7.0 else 0.0
            monitor.feedback([ThrusterFeedback("bow", delivered, 0.0, True, t)])
        if not monitor.update(t, DT, command)[0] and removed is None:
            removed = t
    persist = ThrusterMonitorSettings().mismatch_persist_s
    assert removed is not None and persist <= removed - 20.0 <= persist + 3.0
    assert monitor.is_latched("bow")


def _drive_feedback(delivered_of, ready_of, seconds: float) -> tuple[list[float], list[bool]]:
    """A monitor of one drive commanded 50 kN throughout, fed feedback ``delivered_of(t, expected)`` [N] and
    ``ready_of(t)``: its ``expected_n`` per step and whether the drive was in the allocation."""
    monitor = ThrusterMonitor([SPEC], ThrusterMonitorSettings(), AlarmRegistry())
    command = np.full(1, 5e4)
    expected, available = [], []
    for k in range(round(seconds / DT)):
        t = k * DT
        delivered = delivered_of(t, monitor._health[0].expected_n)
        monitor.feedback([ThrusterFeedback(SPEC.name, delivered, SPEC.angle_rad, ready_of(t), t)])
        available.append(bool(monitor.update(t, DT, command)[0]))
        expected.append(monitor._health[0].expected_n)
    return expected, available


def test_a_mismatch_that_wavers_about_the_limit_is_judged_with_hysteresis() -> None:
    # From 20 s the drive delivers 25 kN (the limit at 50 kN) ± 40 % short of the expectation, swinging every 4 s:
    # the low-passed error crosses the limit in every swing and stays above half of it. With hysteresis the
    # mismatch persists from its first crossing and latches after mismatch_persist_s; judged against the limit
    # alone it restarts with every swing (2 s above, 2 s below) and never latches.
    limit = mismatch_limit_n(SPEC.max_thrust_n, 5e4, ThrusterMonitorSettings().mismatch_fraction)

    def short(t: float, expected: float) -> float:
        return expected - (0.0 if t < 20.0 else limit * (1.0 + 0.4 * math.sin(2.0 * math.pi * t / 4.0)))

    _, available = _drive_feedback(short, lambda t: True, 40.0)
    first_out = available.index(False) * DT if False in available else None
    assert first_out is not None and 20.0 + ThrusterMonitorSettings().mismatch_persist_s <= first_out < 30.0


def test_a_drive_that_reports_ready_again_is_used_after_readmit_s_not_at_once() -> None:
    # not ready from 10 s to 15 s (a drive restarting its converter), then ready: back in the allocation readmit_s
    # (5 s) of ready later, not with its first ready sample
    _, available = _drive_feedback(lambda t, e: e, lambda t: not 10.0 <= t < 15.0, 30.0)
    out = [k * DT for k, a in enumerate(available) if not a]
    assert out[0] == pytest.approx(10.0) and out[-1] == pytest.approx(15.0 + 5.0 - DT)
