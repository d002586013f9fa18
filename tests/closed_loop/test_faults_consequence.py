"""Consequence analysis in the closed loop (``sim_plant/scenarios/faults/14-consequence.yaml``, lockstep): the
supply vessel in case 10's beam weather with three failure groups. The worst-case failure check warns of the
bow thruster room 70 s before both tunnels actually trip, never of a switchboard while both tunnels run, and of
both switchboards once the tunnels are out."""

from __future__ import annotations

from pathlib import Path

import pytest

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
    # what actually failed at the trip: the capability alarm, as in case 10
    capability = _first_raised(run, "thrusters.capability")
    assert capability is not None and capability >= TRIP_S
