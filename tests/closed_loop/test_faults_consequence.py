"""Consequence analysis in the closed loop (``sim_plant/scenarios/faults/14-consequence.yaml``, lockstep): the
supply vessel in case 10's beam weather with three failure groups. The worst-case failure check warns of the
bow thruster room 70 s before both tunnels actually trip, never of a switchboard while both tunnels run (but warns
that losing one would leave the other tunnel above 80 % of its rating), and of both switchboards once the tunnels
are out. A controller restarted from the persisted state goes on checking at once."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from dpcontrol.runtime.alarms import Severity
from dpcontrol.runtime.step import DpController
from sim_plant.bench.lockstep import ProbedRun
from sim_plant.bench.run import build_simulation
from sim_plant.scenario import load_scenario

SCENARIO = Path(__file__).resolve().parents[2] / "sim_plant" / "scenarios" / "faults" / "14-consequence.yaml"
TRIP_S = 120.0  # both bow tunnels trip (the scenario's faults)


@pytest.fixture(scope="module")
def run() -> ProbedRun:
    return ProbedRun.run(build_simulation(load_scenario(SCENARIO)))


def _first_raised(run: ProbedRun, code: str) -> float | None:
    return next((t for t, raised in run.events(code) if raised), None)


def test_the_bow_room_is_the_worst_case_before_it_fails(run: ProbedRun) -> None:
    settings = run.simulation.controller.config.consequence
    engaged = next(t for t, _previous, new, _reason in run.result.mode_changes if new == "auto_position")
    raised = _first_raised(run, "consequence.bow_room")
    # no check before averaging_s of DP, no alarm before persist_s of failing checks (the average starts from the
    # force at engagement, small while the integral builds up: the first checks may still hold)
    assert raised is not None and engaged + settings.averaging_s + settings.persist_s <= raised + 1e-9
    assert raised < TRIP_S - 60.0  # a warning more than a minute before the failure, not after it
    # a switchboard's loss leaves one tunnel and one azimuth: enough while both tunnels run
    for group in ("bus_a", "bus_b"):
        after = _first_raised(run, f"consequence.{group}")
        assert after is not None and TRIP_S + settings.persist_s <= after <= TRIP_S + settings.persist_s + 1.1
    # the margin: a switchboard's loss would hold, but leave the other tunnel above 80 % of its rating (warning)
    margin = run.events("consequence.bus_a.utilisation")
    assert margin and margin[0][1] and engaged + settings.averaging_s + settings.persist_s <= margin[0][0] < TRIP_S
    raised = next(e for e in run.result.alarm_events if e.code == "consequence.bus_a.utilisation")
    assert raised.severity is Severity.WARNING and "would hold, with bow_tunnel_2 at " in raised.text
    # once the loss would not hold, the alarm says so and the warning clears (after persist_s)
    assert margin[1] == (pytest.approx(TRIP_S + settings.persist_s, abs=1.1), False)
    # what actually failed at the trip: the capability alarm, as in case 10
    capability = _first_raised(run, "thrusters.capability")
    assert capability is not None and capability >= TRIP_S


def test_a_restarted_controller_goes_on_checking_at_once(run: ProbedRun) -> None:
    """The persisted state carries the check's average: a controller resumed from it in DP checks at its first
    cycle (no second ``averaging_s`` without a worst-case check), with the demand the old one checked."""
    old = run.simulation.controller
    assert old.mode.value == "auto_position" and old.consequence is not None and old.consequence.last is not None
    t_end = float(old.out.t_s)  # the last step
    state = json.loads(json.dumps(old.state_dict(t_end)))  # (as the state file holds it)
    assert state["consequence"]["averaged_s"] > old.config.consequence.averaging_s
    resumed = DpController(old.config)
    resumed.load_state_dict(state, t_end + 5.0)
    assert resumed.mode.value == "auto_position" and resumed.consequence is not None
    report = resumed.consequence.update(t_end + 5.1, "auto_position", old.out.tau_b, old.monitor.available)
    assert report is not None
    np.testing.assert_allclose(report.demand_b, old.consequence.last.demand_b, rtol=0.05)
