"""Heading dead reckoning on an independent rate-of-turn sensor (docs/fault-handling.md): one GNSS, one gyro and a
rate gyro (``rot1``, its own device: a gyro fault leaves it running), in a sea with current; the gyro frozen 40 s
(4.8 s on CyberShip II, Froude-scaled: see :mod:`sim_plant.bench.failsafe`). Through the fault and after it the
true heading stays within 3° of the set-point and the position within 3 m (43 mm), the mode is auto_position at
the end, and the alarm says the heading is on the rate of turn. The same run without the rate sensor is the
comparison (the model alone carries the heading): on CyberShip II, whose model drifts fastest, the rate of turn
keeps the heading estimate under half the model's error."""

from __future__ import annotations

import numpy as np
import pytest

from sim_plant.bench.failsafe import Case, run_case

START_S = 120.0


def _heading_estimate_error_deg(run, start_s: float, end_s: float) -> float:  # type: ignore[no-untyped-def]
    t = run.t_s
    window = (t >= start_s) & (t <= end_s)
    error = np.angle(np.exp(1j * (run.col("est_heading_rad") - run.col("heading_rad"))))
    return float(np.degrees(np.abs(error[window])).max())


@pytest.mark.parametrize("vessel", ["supply", "cybership2"])
def test_a_frozen_lone_gyro_is_dead_reckoned_on_the_rate_of_turn(vessel: str) -> None:
    case = Case(vessel, "gyro_freeze", START_S, 40.0, rate_of_turn=True)
    run, outcome = run_case(case)
    assert outcome.within(case), outcome  # the vessel's position and heading bounds
    assert outcome.final_mode == "auto_position" and not outcome.left_dp, run.result.mode_changes
    assert {"heading.lost", "heading.dead_reckoning"} <= set(outcome.alarms)
    texts = [e.text for e in run.result.alarm_events if e.code == "heading.dead_reckoning" and e.raised]
    assert texts and "rate of turn (rot1" in texts[0], texts
    assert "estimator.reset" not in outcome.alarms
    end = START_S + case.fault_duration_s
    with_rot = _heading_estimate_error_deg(run, START_S, end + 20.0 * case.fault_duration_s / 40.0)
    # the comparison: the same run without the rate sensor
    base_run, base = run_case(Case(vessel, "gyro_freeze", START_S, 40.0))
    assert base.final_mode == "auto_position"
    texts = [e.text for e in base_run.result.alarm_events if e.code == "heading.dead_reckoning" and e.raised]
    assert texts and "on the model" in texts[0], texts
    without = _heading_estimate_error_deg(base_run, START_S, end + 20.0 * case.fault_duration_s / 40.0)
    if vessel == "cybership2":
        # measured: the estimate within 0.15° on the rate of turn, 0.35° on the model (0.50° while the yaw bias was
        # held through the dead reckoning instead of relaxed to its mean; the returning gyro blended in over the
        # bench's Froude-scaled 2.4 s)
        assert with_rot < 0.3 and with_rot < 0.5 * without, (with_rot, without)
        assert outcome.max_heading_deg < base.max_heading_deg, (outcome, base)
    else:  # the supply vessel's model is good for 40 s already (measured 0.13° on the rate, 0.10° on the model)
        assert with_rot < 0.2 and without < 0.2, (with_rot, without)
