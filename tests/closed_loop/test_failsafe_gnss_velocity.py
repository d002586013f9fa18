"""A lone GNSS whose position drifts slowly, against its own velocity (docs/fault-handling.md, "Velocity check"): one
GNSS (with SOG/COG) and one gyro, in a sea with current. The position drifts 10 m in 120 s (0.083 m/s, the
campaign's slowest; Froude-scaled on CyberShip II: 143 mm in 14.3 s, see :mod:`sim_plant.bench.failsafe`); the
Doppler velocity does not: the receiver is rejected for disagreeing with its own velocity and the position
dead-reckoned on that velocity, so through the fault the true LF position stays within 3 m (43 mm) of the
set-point, the mode auto_position throughout, and the receiver is taken back after the fault. Without the check
(its floor out of reach) the position followed the drift: 20.0 m / 137 mm."""

from __future__ import annotations

import numpy as np
import pytest

from sim_plant.bench.failsafe import VESSELS, Case, run_case

START_S = 120.0
CODE = "position.velocity_disagreement"


@pytest.mark.parametrize("vessel", ["supply", "cybership2"])
def test_a_slowly_drifting_lone_gnss_is_rejected_on_its_own_velocity(vessel: str) -> None:
    case = Case(vessel, "gnss_drift", START_S, 120.0)
    run, outcome = run_case(case)
    bounds = VESSELS[vessel]
    assert outcome.max_position_m <= bounds["position_bound_m"], outcome
    assert outcome.max_heading_deg <= bounds["heading_bound_deg"], outcome
    assert outcome.final_mode == "auto_position" and not outcome.left_dp, run.result.mode_changes
    assert {CODE, "sensor.gnss1.rejected", "position.dead_reckoning"} <= set(outcome.alarms)
    assert "estimator.reset" not in outcome.alarms and "position.reference_rejected" not in outcome.alarms
    raised = [t for t, up in run.events(CODE) if up]
    cleared = [t for t, up in run.events(CODE) if not up]
    scale = bounds["time_scale"]
    # rejected once the disagreement passes the limit: the 1 m floor on the supply vessel, 1 m / 0.083 m/s = 12 s of
    # drift plus the low-pass; on the model the receiver's noise sets it (6σ ≈ 38 mm against the 14 mm floor: the
    # model's 1 cm receiver is 2.3 times noisier than the ship's 0.3 m, for its size), 3.3 s there; taken back once
    # back at its level after the fault
    assert raised and raised[0] - START_S <= (20.0 if vessel == "supply" else 40.0) * scale, raised
    end = START_S + case.fault_duration_s
    assert cleared and end < cleared[-1] <= end + 20.0 * scale, (cleared, end)
    texts = [e.text for e in run.result.alarm_events if e.code == "position.dead_reckoning" and e.raised]
    assert texts and "velocity of gnss1" in texts[0], texts
    texts = [e.text for e in run.result.alarm_events if e.code == CODE and e.raised]
    assert texts and texts[0].startswith("gnss1"), texts
    # from the fault's start on too (before it, the PID settling after DP engages)
    after = run.t_s >= START_S
    position = np.hypot(run.col("north_m"), run.col("east_m"))
    assert float(np.nanmax(position[after])) <= bounds["position_bound_m"]


@pytest.mark.parametrize("vessel", ["supply", "cybership2"])
def test_a_healthy_lone_gnss_is_never_rejected(vessel: str) -> None:
    """The same sea with the receiver healthy (the fault on the gyro's rate-of-turn output only: a gyro freeze of
    10 s, which moves nothing the check sees): never rejected by the velocity check."""
    case = Case(vessel, "gyro_freeze", START_S, 10.0)
    _, outcome = run_case(case)
    assert CODE not in outcome.alarms and "sensor.gnss1.rejected" not in outcome.alarms, outcome.alarms
