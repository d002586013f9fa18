"""One GNSS and one gyro (DP class 1, or a vessel whose other references failed), one sensor fault, in lockstep:
the supply vessel (full scale) and CyberShip II (1:70 model, the case Froude-scaled: see
:mod:`sim_plant.bench.failsafe`), in a sea with current. Through the fault and after it the true LF position
stays within 3 m (43 mm on the model) of the set-point and the heading within 3°, measured from 60 s on (DP
engages at 20 s) against the operator's set-point; the controller never leaves ``auto_position``; the alarms say
what happened (dead reckoning at once, the lone reference rejected when it jumps)."""

from __future__ import annotations

import pytest

from sim_plant.bench.failsafe import Case, run_case

START_S = 120.0


@pytest.mark.parametrize("vessel", ["supply", "cybership2"])
@pytest.mark.parametrize(("fault", "duration_s", "alarms"), [
    ("gyro_freeze", 40.0, {"heading.dead_reckoning"}),
    ("gnss_freeze", 60.0, {"position.dead_reckoning"}),
])
def test_a_frozen_lone_reference_is_dead_reckoned_through(vessel: str, fault: str, duration_s: float,
                                                          alarms: set[str]) -> None:
    case = Case(vessel, fault, START_S, duration_s)
    run, outcome = run_case(case)
    assert outcome.within(case), outcome  # the vessel's position and heading bounds
    assert not outcome.left_dp and outcome.final_mode == "auto_position", run.result.mode_changes
    assert alarms <= set(outcome.alarms), outcome.alarms
    # raised at once when the freeze is detected (the hub's freeze window + a sample period + a control step),
    # not after the dead-reckoning limit
    code = next(iter(alarms))
    first = min(t for t, raised in run.events(code) if raised and t >= START_S - 1e-9)
    window = run.simulation.config.hub.freeze_window_s
    assert first - START_S <= window + 0.2 + 0.1 + 1e-9
    assert "estimator.reset" not in outcome.alarms


def test_a_lone_gnss_jumping_10_m_for_60_s_is_rejected_and_dead_reckoned_through() -> None:
    case = Case("supply", "gnss_jump", START_S, 60.0)
    run, outcome = run_case(case)
    assert outcome.within(case), outcome  # the vessel's position and heading bounds
    assert not outcome.left_dp and outcome.final_mode == "auto_position"
    # the jump disagrees with the receiver's own velocity (SOG/COG): rejected by the velocity check at the first
    # samples, the position dead-reckoned on that velocity (before the check: by the prediction test, on the model)
    assert {"position.velocity_disagreement", "position.dead_reckoning"} <= set(outcome.alarms)
    assert "estimator.reset" not in outcome.alarms  # never re-initialised on the jumped position
    raised = [t for t, up in run.events("position.velocity_disagreement") if up]
    assert raised and raised[0] - START_S <= 1.0, raised
    # the alarm clears when the receiver is back at its level: the low-pass settling (2 s time constant) and
    # velocity_check_return_s (5 s) after the jump ends
    cleared = [t for t, up in run.events("position.velocity_disagreement") if not up]
    assert cleared and START_S + 60.0 <= cleared[-1] <= START_S + 60.0 + 15.0
    # past the dead-reckoning limit (60 s) the critical alarm says what still carries the position
    texts = [e.text for e in run.result.alarm_events if e.code == "position.dead_reckoning_limit" and e.raised]
    assert texts and all("still holding on the velocity of gnss1" in text for text in texts), texts
