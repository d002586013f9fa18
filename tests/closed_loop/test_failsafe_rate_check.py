"""A lone gyro against an independent rate-of-turn sensor (docs/fault-handling.md, "Rate check"): one GNSS, one gyro
and a rate gyro ``rot1``, in a sea with current. The gyro drifts 0.2°/s for 60 s (Froude-scaled on CyberShip II:
the same 12° in 7.2 s, see :mod:`sim_plant.bench.failsafe`): it is rejected for disagreeing with the rate of turn
and the heading dead-reckoned on the rate, so through the fault and after it the true heading stays within 3° of
the set-point and the position within 3 m (43 mm), the mode auto_position throughout, and the gyro is taken back
after the fault. Without the check the heading followed the gyro: 26.6° / 16.1° off. The rate sensor off by the
same 0.2°/s instead: the gyro is never rejected."""

from __future__ import annotations

import pytest

from sim_plant.bench.failsafe import VESSELS, Case, run_case

START_S = 120.0


@pytest.mark.parametrize("vessel", ["supply", "cybership2"])
def test_a_drifting_lone_gyro_is_rejected_on_the_rate_of_turn(vessel: str) -> None:
    case = Case(vessel, "gyro_drift", START_S, 60.0, rate_of_turn=True)
    run, outcome = run_case(case)
    bounds = VESSELS[vessel]
    assert outcome.within(case), outcome  # the vessel's position and heading bounds
    assert outcome.final_mode == "auto_position" and not outcome.left_dp, run.result.mode_changes
    assert {"heading.rate_disagreement", "sensor.gyro1.rejected", "heading.dead_reckoning"} <= set(outcome.alarms)
    assert "estimator.reset" not in outcome.alarms and "heading.reference_rejected" not in outcome.alarms
    raised = [t for t, up in run.events("heading.rate_disagreement") if up]
    cleared = [t for t, up in run.events("heading.rate_disagreement") if not up]
    scale = bounds["time_scale"]
    # rejected within 1° / 0.2°/s = 5 s (0.6 s on the model) of drift, taken back once the window (30 s) and the
    # return time (10 s) agree again after the fault
    assert raised and raised[0] - START_S <= 6.5 * scale, raised
    end = START_S + case.fault_duration_s
    assert cleared and end < cleared[-1] <= end + 45.0 * scale, (cleared, end)
    texts = [e.text for e in run.result.alarm_events if e.code == "heading.dead_reckoning" and e.raised]
    assert texts and "rate of turn (rot1" in texts[0], texts


@pytest.mark.parametrize("vessel", ["supply", "cybership2"])
def test_a_rate_sensor_off_by_as_much_never_rejects_the_gyro(vessel: str) -> None:
    case = Case(vessel, "rot_offset", START_S, 60.0, rate_of_turn=True)
    _, outcome = run_case(case)
    assert outcome.within(case), outcome  # the vessel's position and heading bounds
    assert outcome.final_mode == "auto_position" and not outcome.left_dp
    assert "sensor.gyro1.rejected" not in outcome.alarms and "heading.lost" not in outcome.alarms, outcome.alarms
    assert {"heading.rate_disagreement", "sensor.rot1.rejected"} <= set(outcome.alarms)
