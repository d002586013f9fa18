"""The worst-case failure check (consequence analysis): what the thrusters left after a failure group's loss can
hold (``dpcontrol/allocation/consequence.py``), its timing and alarms in the running controller
(``dpcontrol/runtime/consequence.py``), its configuration and its place on the status."""

from __future__ import annotations

import copy
import math
from typing import Any

import numpy as np
import pytest

from dpbase.schema import ConfigError
from dpcontrol.allocation.consequence import FailureGroup, WorstCaseFailure
from dpcontrol.models.vessels import BUILTIN_VESSELS
from dpcontrol.runtime.alarms import AlarmRegistry, Severity
from dpcontrol.runtime.config import ConsequenceSettings, parse_config
from dpcontrol.runtime.consequence import ConsequenceMonitor
from dpcontrol.runtime.step import DpController
from dpcontrol.service.daemon import status_payload
from interfaces.zenoh.schemas import parse_message

SUPPLY = BUILTIN_VESSELS["supply"]  # bow tunnels at x = 30 and 22 m, azimuths at x = -33 m, y = ∓4.5 m
BUS_A = FailureGroup("bus_a", ("bow_tunnel_1", "azimuth_port"))
BUS_B = FailureGroup("bus_b", ("bow_tunnel_2", "azimuth_starboard"))
BOW_ROOM = FailureGroup("bow_room", ("bow_tunnel_1", "bow_tunnel_2"))
ALL = np.ones(4, dtype=bool)


def _outcomes(demand_b: list[float], available: np.ndarray = ALL) -> dict[str, Any]:
    check = WorstCaseFailure(SUPPLY.thrusters, (BUS_A, BUS_B, BOW_ROOM))
    return {o.group: o for o in check.evaluate(np.array(demand_b), available)}


def test_a_beam_load_needs_the_bow_tunnels_a_head_load_does_not() -> None:
    beam = _outcomes([0.0, 150e3, 0.0])  # the stern azimuths alone cannot balance a beam force's yaw moment
    assert beam["bus_a"].holds and beam["bus_b"].holds
    assert not beam["bow_room"].holds
    # with heading priority (the allocator's) the stern azimuths keep the moment balanced and the sway force is
    # what is left over
    assert abs(beam["bow_room"].shortfall_b[1]) > 50e3 and abs(beam["bow_room"].shortfall_b[2]) < 1.0  # [N], [N·m]
    assert beam["bow_room"].utilisation == pytest.approx(1.0)  # (what is left works at its limit)
    head = _outcomes([200e3, 0.0, 0.0])
    assert all(o.holds for o in head.values())
    assert head["bow_room"].utilisation == pytest.approx(200e3 / 700e3, rel=0.05)  # two azimuths share it
    # more than one switchboard's thrusters can give: bus_a's loss leaves 150 + 350 kN
    heavy = _outcomes([0.0, 330e3, 2.0e6])
    assert not heavy["bus_a"].holds and not heavy["bus_b"].holds


def test_a_thruster_already_out_counts_with_the_failure() -> None:
    tunnel_2_out = np.array([True, False, True, True])
    beam = _outcomes([0.0, 150e3, 0.0], tunnel_2_out)
    assert not beam["bus_a"].holds  # bus_a takes tunnel 1: no tunnel left
    assert beam["bus_b"].holds      # bus_b's tunnel is the one already out
    nothing_left = _outcomes([50e3, 0.0, 0.0], np.array([True, True, False, False]))
    assert not nothing_left["bow_room"].holds and math.isinf(nothing_left["bow_room"].utilisation)


def _monitor(**settings: Any) -> tuple[ConsequenceMonitor, AlarmRegistry]:
    alarms = AlarmRegistry()
    values = {"groups": (BUS_A, BOW_ROOM), "period_s": 1.0, "averaging_s": 30.0, "demand_factor": 1.25,
              "persist_s": 10.0, **settings}
    return ConsequenceMonitor(SUPPLY.thrusters, ConsequenceSettings(**values), alarms), alarms


def _drive(monitor: ConsequenceMonitor, t0_s: float, t1_s: float, mode: str, tau_b: list[float]) -> list[float]:
    """10 Hz cycles from t0 to t1 (excluded); the times a check ran."""
    ran = []
    for k in range(round((t1_s - t0_s) * 10)):
        t_s = t0_s + 0.1 * k
        if monitor.update(t_s, mode, np.array(tau_b), ALL) is not None:
            ran.append(round(t_s, 1))
    return ran


def test_timing_averaging_persistence_and_rest() -> None:
    monitor, alarms = _monitor()
    assert _drive(monitor, 0.0, 30.0, "standby", [0.0, 150e3, 0.0]) == []  # outside DP: nothing
    ran = _drive(monitor, 30.0, 100.0, "auto_position", [0.0, 150e3, 0.0])
    assert ran[0] == 60.0 and ran[1] == 61.0 and len(ran) == 40  # after 30 s of DP, once a second
    report = monitor.last
    assert report is not None and report.demand_b == pytest.approx([0.0, 1.25 * 150e3, 0.0])
    # bow_room's loss would not hold from the first check (60 s): raised 10 s later, bus_a never
    assert [(a.code, a.severity, a.since_t_s) for a in alarms.active()] == [
        ("consequence.bow_room", Severity.ALARM, 70.0)]
    text = alarms.active()[0].text
    assert text.startswith("worst-case failure: losing bow_room (bow_tunnel_1, bow_tunnel_2) would leave ")
    assert "kN sway" in text and "1.25 × the mean force of the last 30 s" in text
    # the load goes (the mean decays over 30 s): cleared after 10 s of holding, not at once
    _drive(monitor, 100.0, 400.0, "auto_position", [100e3, 0.0, 0.0])
    assert not alarms.is_active("consequence.bow_room")
    events = [(e.code, e.raised, e.t_s) for e in alarms.drain_events() if e.code == "consequence.bow_room"]
    assert events[0] == ("consequence.bow_room", True, 70.0) and events[1][1] is False
    cleared_at = events[1][2]
    held_since = next(t for t in np.arange(100.0, 400.0, 1.0) if _holds_at(t))
    assert 100.0 < held_since < 150.0
    assert cleared_at == pytest.approx(held_since + 10.0)


def _holds_at(t_s: float) -> bool:
    """Whether the bow room's loss holds the filtered demand at ``t_s`` of test_timing…'s second load (the mean
    decays from the beam load towards the head load with the 30 s time constant)."""
    weight = math.exp(-(t_s - 99.9) / 30.0)
    mean = weight * np.array([0.0, 150e3, 0.0]) + (1.0 - weight) * np.array([100e3, 0.0, 0.0])
    check = WorstCaseFailure(SUPPLY.thrusters, (BOW_ROOM,))
    return check.evaluate(1.25 * mean, ALL)[0].holds


def test_leaving_dp_clears_the_alarms_and_restarts_the_average() -> None:
    monitor, alarms = _monitor(persist_s=0.0)
    _drive(monitor, 0.0, 32.0, "auto_position", [0.0, 150e3, 0.0])
    assert alarms.is_active("consequence.bow_room") and monitor.active
    _drive(monitor, 32.0, 33.0, "auto_heading", [0.0, 150e3, 0.0])
    assert not alarms.is_active("consequence.bow_room") and not monitor.active and monitor.last is None
    assert _drive(monitor, 33.0, 60.0, "auto_position", [0.0, 150e3, 0.0]) == []  # averaging again


def test_a_non_finite_force_is_kept_out_of_the_average() -> None:
    monitor, _alarms = _monitor()
    _drive(monitor, 0.0, 20.0, "auto_position", [100e3, 0.0, 0.0])
    assert monitor.update(20.0, "auto_position", np.array([math.nan, 0.0, 0.0]), ALL) is None
    _drive(monitor, 20.1, 31.0, "auto_position", [100e3, 0.0, 0.0])
    assert monitor.last is not None and np.all(np.isfinite(monitor.last.demand_b))
    assert monitor.last.demand_b == pytest.approx([125e3, 0.0, 0.0])


def test_a_loss_that_holds_with_little_margin_is_a_warning() -> None:
    """``utilisation_warning``: a group whose loss would hold, but with a remaining thruster at or above that share
    of its rating for ``persist_s``, raises ``consequence.<group>.utilisation`` (warning) naming the thruster;
    a loss that would not hold is the alarm's alone."""
    monitor, alarms = _monitor(utilisation_warning=0.5)
    _drive(monitor, 0.0, 80.0, "auto_position", [200e3, 0.0, 0.0])  # demand 250 kN ahead
    outcomes = {o.group: o for o in monitor.last.outcomes}
    assert outcomes["bus_a"].busiest == "azimuth_starboard" and outcomes["bus_a"].utilisation > 0.7
    assert outcomes["bow_room"].utilisation < 0.4  # two azimuths left, each at a third
    assert [(a.code, a.severity, a.since_t_s) for a in alarms.active()] == [
        ("consequence.bus_a.utilisation", Severity.WARNING, 40.0)]  # first check at 30 s, 10 s of it
    assert alarms.active()[0].text == ("worst-case failure: losing bus_a (bow_tunnel_1, azimuth_port) would hold, "
                                       "with azimuth_starboard at 72 % of its rating (warning from 50 %)")
    _drive(monitor, 80.0, 300.0, "auto_position", [100e3, 0.0, 0.0])  # the load halves: 36 % left
    assert not alarms.active()
    # a beam load: the bow room's loss would not hold (the alarm, not also this warning); bus_a's at 75 %
    _drive(monitor, 300.0, 500.0, "auto_position", [0.0, 150e3, 0.0])
    assert sorted(a.code for a in alarms.active()) == ["consequence.bow_room", "consequence.bus_a.utilisation"]
    _drive(monitor, 500.0, 501.0, "standby", [0.0, 0.0, 0.0])  # outside DP every alarm of the check clears
    assert not alarms.active()


def test_a_restart_resumes_the_average() -> None:
    """The persisted state carries the average and how long it ran: a controller resumed in DP checks at its first
    cycle instead of averaging ``averaging_s`` again, with the demand it had (the bumpless restart,
    docs/installation.md)."""
    before, _alarms = _monitor()
    _drive(before, 0.0, 45.0, "auto_position", [0.0, 150e3, 0.0])
    state = before.state_dict(44.9)
    assert state is not None and state["averaged_s"] == pytest.approx(44.9)
    after, _alarms = _monitor()
    after.load_state_dict(state, 1000.0)  # (another process's clock)
    report = after.update(1000.1, "auto_position", np.array([0.0, 150e3, 0.0]), ALL)
    assert report is not None and report.demand_b == pytest.approx(before.last.demand_b, rel=1e-6)
    fresh, _alarms = _monitor()
    assert fresh.state_dict(0.0) is None  # outside DP: nothing to keep
    for broken in ({"mean_b": [math.nan, 0.0, 0.0], "averaged_s": 3.0}, {"mean_b": [0.0, 0.0, 0.0], "averaged_s": -1},
                   {"mean_b": [0.0, 0.0], "averaged_s": 3.0}):
        with pytest.raises(ValueError):
            fresh.load_state_dict(broken, 0.0)  # (the daemon then starts cold)


CONFIG: dict[str, Any] = {
    "vessel_id": "osv1", "vessel": "supply",
    "transports": [{"name": "serial0", "protocol": "nmea0183", "port": "/dev/null"}],
    "sensors": [{"name": "gnss1", "kind": "position", "transport": "serial0"},
                {"name": "gyro1", "kind": "heading", "transport": "serial0"}],
    "consequence": {"groups": {"bus_a": ["bow_tunnel_1", "azimuth_port"], "bow_room": ["bow_tunnel_1", "bow_tunnel_2"]},
                    "averaging_s": 60, "persist_s": 5}}


def test_configuration() -> None:
    settings = parse_config(CONFIG).consequence
    assert settings.groups == (BUS_A, BOW_ROOM)
    assert (settings.averaging_s, settings.persist_s, settings.period_s, settings.demand_factor) == (60, 5, 1.0, 1.25)
    off = copy.deepcopy(CONFIG)
    del off["consequence"]
    assert parse_config(off).consequence.groups == ()  # off unless groups are configured
    assert DpController(parse_config(off)).check_consequences(0.0) is None
    assert settings.utilisation_warning is None  # off unless given
    margin = copy.deepcopy(CONFIG)
    margin["consequence"]["utilisation_warning"] = 0.8
    assert parse_config(margin).consequence.utilisation_warning == 0.8
    for wrong in (0, 1.5, "high"):
        margin["consequence"]["utilisation_warning"] = wrong
        with pytest.raises(ConfigError) as error:
            parse_config(margin)
        assert error.value.path == "consequence.utilisation_warning"


@pytest.mark.parametrize(("groups", "path", "expected"), [
    ({"bus_a": ["bow_tunnel_1", "azimuth_centre"]}, "consequence.groups.bus_a[1]", "one of the vessel's thrusters"),
    ({"bus_a": []}, "consequence.groups.bus_a", "a non-empty list"),
    ({"bus_a": "bow_tunnel_1"}, "consequence.groups.bus_a", "a non-empty list"),
    ({"bus_a": ["bow_tunnel_1", "bow_tunnel_1"]}, "consequence.groups.bus_a", "each thruster once"),
    ({"everything": ["bow_tunnel_1", "bow_tunnel_2", "azimuth_port", "azimuth_starboard"]},
     "consequence.groups.everything", "leaves some thrusters"),
    ({"bus a": ["bow_tunnel_1"]}, "consequence.groups.bus a", "letters, digits"),
    ([["bow_tunnel_1"]], "consequence.groups", "a mapping"),
])
def test_configuration_errors_name_the_key(groups: Any, path: str, expected: str) -> None:
    config = copy.deepcopy(CONFIG)
    config["consequence"]["groups"] = groups
    with pytest.raises(ConfigError) as error:
        parse_config(config)
    assert error.value.path == path and expected in str(error.value)


def test_the_status_carries_the_last_check() -> None:
    config = parse_config(CONFIG)
    alarms = AlarmRegistry()
    controller = DpController(config, alarms)
    status = parse_message("status", status_payload(controller, alarms, 1.0, 1))
    assert isinstance(status, dict) and status.get("consequence") is None  # none ran yet
    assert controller.consequence is not None
    controller.consequence.update(0.0, "auto_position", np.array([0.0, 150e3, 0.0]), ALL)
    controller.consequence.update(60.0, "auto_position", np.array([0.0, 150e3, 0.0]), ALL)
    status = parse_message("status", status_payload(controller, alarms, 60.0, 2))
    assert isinstance(status, dict), status
    assert status["consequence"]["t_s"] == 60.0
    assert status["consequence"]["demand_b"]["y_n"] == pytest.approx(1.25 * 150e3)
    assert [(g["name"], g["holds"]) for g in status["consequence"]["groups"]] == [("bus_a", True), ("bow_room", False)]
    assert status["consequence"]["groups"][0]["busiest"] in ("bow_tunnel_2", "azimuth_starboard")  # what bus_a leaves
