"""The daemon's controller replica (:mod:`dpcontrol.service.replica`) on lockstep runs.

The primary is the lockstep simulation's controller; the replica is fed what the primary consumed,
one cycle later, exactly as :class:`dpcontrol.service.daemon.Daemon` does — checked "ahead of the
deadline" before the primary's next step, or caught up in :meth:`ControllerReplica.hold` when no check
came in between.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest

from dpcontrol.runtime.alarms import AlarmEvent, AlarmRegistry
from dpcontrol.service.replica import REPLICA_ALARM, ControllerReplica
from interfaces.messages import LinkStatus
from sim_plant.bench.run import build_simulation
from sim_plant.scenario import builtin_scenario_path, load_scenario

LINK_LOSS = Path(__file__).resolve().parents[2] / "sim_plant" / "scenarios" / "faults" / "09-link-loss.yaml"


@dataclass
class ReplicaRun:
    replica: ControllerReplica
    events: list[AlarmEvent]
    steps: int
    links_seen: int
    extra: dict[str, Any] = field(default_factory=dict)


def _run(scenario: str | Path, duration_s: float, *, check_every: int = 1,
         before_step: Callable[[float, Any, ControllerReplica], None] | None = None,
         mark_links: Callable[..., None] | None = None, primary_fails_at_s: float | None = None) -> ReplicaRun:
    path = scenario if isinstance(scenario, Path) else builtin_scenario_path(scenario)
    sim = build_simulation(load_scenario(path))
    primary = sim.controller
    alarms = AlarmRegistry()
    replica = ControllerReplica(sim.config, alarms, mark_links or sim.inputs.health.mark_links)
    health = sim.inputs.health
    apply_links = health.apply_links
    cycle_links: list[LinkStatus] = []
    counts = {"steps": 0, "links": 0, "primary_errors": 0}

    def recording_apply_links(t_s: float, links: Any, hub: Any, registry: Any) -> None:
        cycle_links.extend(links)
        apply_links(t_s, links, hub, registry)

    health.apply_links = recording_apply_links  # type: ignore[method-assign]
    step = primary.step

    def primary_step(t_s: float, measurements: Any, feedback: Any, requests: Any) -> Any:
        k = counts["steps"]
        if replica.pending and k % check_every == 0:
            replica.check(t_s, ahead=True)  # the daemon: just before this deadline
        if before_step is not None:
            before_step(t_s, primary, replica)
        if primary_fails_at_s is not None and abs(t_s - primary_fails_at_s) < 1e-9:
            # as the daemon does when its step raises: the replica gets the inputs and the error, and
            # the loop goes on with the last command (here: the simulation gets the previous output)
            error = FloatingPointError("injected")
            replica.hold(t_s, k, None, measurements=measurements, feedback=feedback, requests=requests,
                         links=cycle_links, error=error)
            counts["primary_errors"] += 1
            out = primary.out
        else:
            out = step(t_s, measurements, feedback, requests)
            replica.hold(t_s, k, out, measurements=measurements, feedback=feedback, requests=requests,
                         links=cycle_links)
        counts["links"] += len(cycle_links)
        cycle_links.clear()
        counts["steps"] += 1
        return out

    primary.step = primary_step  # type: ignore[method-assign]
    sim.run(duration_s=duration_s)
    replica.check(duration_s, ahead=True)  # the last cycle
    return ReplicaRun(replica, alarms.drain_events(), counts["steps"], counts["links"],
                      {"primary_errors": counts["primary_errors"]})


@pytest.fixture(scope="module")
def link_loss() -> ReplicaRun:
    # supply vessel, four sensors over NMEA 0183 / NMEA 2000 / MAVLink; a serial port unplugged from 100 s
    # to 130 s and a MAVLink heartbeat lost from 160 s to 200 s: link changes reach the hub mid-run
    return _run(LINK_LOSS, 215.0)


def test_the_replica_recomputes_every_command_of_a_faulted_run_exactly(link_loss: ReplicaRun) -> None:
    counters = link_loss.replica.counters
    assert link_loss.links_seen >= 4  # unplug, replug, heartbeat lost, heartbeat back
    assert counters.stepped == counters.compared == counters.ahead == link_loss.steps
    assert counters.mismatches == 0 and counters.last_mismatch == ""
    assert link_loss.replica.in_agreement
    assert not link_loss.events


def test_a_replica_that_misses_the_link_changes_disagrees_once_and_stays_in_alarm() -> None:
    # the same run with the link changes kept from the replica's hub: the check must see it
    run = _run(LINK_LOSS, 215.0, mark_links=lambda links, hub: None)
    counters = run.replica.counters
    assert counters.mismatches == 1 and not run.replica.in_agreement
    assert counters.stepped == run.steps  # it goes on stepping (warm caches) ...
    assert counters.compared < run.steps  # ... but compares no more
    (event,) = [e for e in run.events if e.code == REPLICA_ALARM]
    assert event.raised and event.t_s > 100.0  # not before the serial port was unplugged at 100 s
    assert "restart the daemon" in event.text


def test_a_corrupted_primary_state_raises_the_alarm_at_the_next_deadline() -> None:
    def corrupt(t_s: float, primary: Any, replica: ControllerReplica) -> None:
        if abs(t_s - 20.0) < 1e-9:  # the set-point changed behind the controller's back
            primary.setpoint_ned[0] += 2.0

    run = _run("cs2-seed000", 25.0, before_step=corrupt)
    counters = run.replica.counters
    assert counters.mismatches == 1 and counters.compared == 201  # cycles 0 … 200
    assert counters.last_mismatch.startswith("cycle 200: thrust differs by up to ")
    (event,) = [e for e in run.events if e.code == REPLICA_ALARM]
    assert event.raised and event.t_s == pytest.approx(20.1)  # checked before the next deadline
    assert "since cycle 200" in event.text


def test_a_step_that_raises_on_both_sides_agrees_and_on_one_side_only_is_a_mismatch() -> None:
    # the primary and the replica both get a measurement the step cannot take: the same exception
    # on both sides is agreement (their states are left the same); the replica alone failing is not
    def poison(controller: Any, t_target: float) -> None:
        step = controller.step

        def failing(t_s: float, *args: Any) -> Any:
            if abs(t_s - t_target) < 1e-9:
                raise FloatingPointError("injected")
            return step(t_s, *args)

        controller.step = failing

    def both(t_s: float, primary: Any, replica: ControllerReplica) -> None:
        if abs(t_s - 5.0) < 1e-9:
            poison(replica.controller, 10.0)

    run = _run("cs2-seed000", 12.0, before_step=both, primary_fails_at_s=10.0)
    assert run.replica.in_agreement and run.replica.counters.compared == run.steps
    assert run.extra["primary_errors"] == 1

    run = _run("cs2-seed000", 12.0, before_step=both)
    counters = run.replica.counters
    assert counters.mismatches == 1
    assert counters.last_mismatch == ("cycle 100: the primary's step returned, the replica's raised "
                                      "FloatingPointError: injected")


def test_cycles_not_checked_before_the_deadline_are_caught_up_in_order() -> None:
    run = _run("cs2-seed000", 30.0, check_every=3)
    counters = run.replica.counters
    assert counters.stepped == counters.compared == run.steps
    assert 0 < counters.ahead < run.steps
    assert counters.mismatches == 0
