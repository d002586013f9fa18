"""Fault cases 8 and 9: malformed traffic, a serial port unplugged, a MAVLink heartbeat lost.

In lockstep (``sim_plant/scenarios/faults/08-*.yaml``, ``09-*.yaml``) the protocol faults are carried out on
the bytes and link states the daemon would see (``sim_plant.bench.lockstep._Inputs``), and counted by the
same :class:`~dpcontrol.runtime.transport_health.InputHealth` the daemon's input pump uses. The first
tests check that shared module and the daemon's own path into it (``InputPump`` fed as its reader
threads feed it, no transport); the rest run the scenarios.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from dpcontrol.runtime.alarms import AlarmRegistry
from dpcontrol.runtime.config import parse_config
from dpcontrol.runtime.hub import SensorHub, SensorState
from dpcontrol.runtime.inputs import SensorRouter, link_alarm_code, link_source
from dpcontrol.runtime.transport_health import MIN_BAD_FOR_ALARM, InputHealth, TransportHealth
from dpcontrol.service.daemon import InputPump
from dpcontrol.service.transports import RawInput
from interfaces.mavlink.codec import MavlinkEncoder
from interfaces.messages import Heading, LinkStatus, Measurement
from interfaces.nmea0183 import encode_hdt
from sim_plant.bench.lockstep import ProbedRun
from sim_plant.bench.run import build_simulation
from sim_plant.scenario import load_scenario

FAULTS = Path(__file__).resolve().parents[2] / "sim_plant" / "scenarios" / "faults"
DT = 0.1
SETTLED_S = 60.0

CONFIG = {
    "vessel_id": "health", "vessel": "supply",
    "transports": [{"name": "serial", "protocol": "nmea0183", "port": "/dev/null"},
                   {"name": "autopilot", "protocol": "mavlink", "url": "udpin:127.0.0.1:14550"}],
    "sensors": [{"name": "gnss1", "kind": "position", "transport": "serial"},
                {"name": "gyro1", "kind": "heading", "transport": "serial"},
                {"name": "gnss2", "kind": "position", "transport": "autopilot", "system_id": 1},
                {"name": "gyro2", "kind": "heading", "transport": "autopilot", "system_id": 2}],
}


# ------------------------------------------------------------------------------------------ shared module
def test_error_rate_window_counts_malformed_not_flagged_frames() -> None:
    health = TransportHealth(window_s=10.0, bucket_s=0.5)
    for k in range(100):
        health.add(k * 0.1)  # 10 s of good frames
        health.add(k * 0.1, "invalid_fix")  # a receiver without a fix: well-formed, never an error
    assert health.rate(9.9) == (0.0, 0)
    for _ in range(50):
        health.add(10.0, "checksum")
    rate, bad = health.rate(10.0)
    assert bad == 50 and rate == pytest.approx(50 / (50 + 190), rel=0.05)  # 19.5 s of the window's good frames
    assert health.rate(20.6) == (0.0, 0)  # the burst has left the window
    counters = health.counters()
    assert counters["rejected"] == 50 and counters["flagged_invalid"] == 100 and counters["decoded"] == 100
    assert counters["reason.checksum"] == 50 and counters["reason.invalid_fix"] == 100


def test_error_rate_alarm_needs_the_share_and_a_minimum_count() -> None:
    config = parse_config(CONFIG)
    alarms = AlarmRegistry()
    health = InputHealth(["serial", "autopilot"], SensorRouter(config.routes, config.transports), 0.2)
    health.count("serial", 0.0, "garbage")  # 100 % bad but a single frame: no alarm
    health.update_alarms(0.0, alarms)
    assert not alarms.is_active("transport.serial.error_rate")
    for _ in range(MIN_BAD_FOR_ALARM):
        health.count("serial", 0.1, "checksum")
    health.update_alarms(0.1, alarms)
    assert alarms.is_active("transport.serial.error_rate")
    health.update_alarms(11.0, alarms)
    assert not alarms.is_active("transport.serial.error_rate")


def test_link_change_of_one_mavlink_system_disconnects_only_its_sensors() -> None:
    config = parse_config(CONFIG)
    router = SensorRouter(config.routes, config.transports)
    hub = SensorHub(config.sensors, config.hub, AlarmRegistry())
    alarms = AlarmRegistry()
    health = InputHealth(["serial", "autopilot"], router, 0.2)
    health.apply_links(1.0, [LinkStatus(1.0, link_source("autopilot", 2), False, "no heartbeat")], hub, alarms)
    hub.update(1.0, [], None, None)
    assert hub.state_of("gyro2") is SensorState.DISCONNECTED
    assert hub.state_of("gnss2") is not SensorState.DISCONNECTED  # system 1 still beats
    assert alarms.is_active("transport.autopilot.system2.link")
    health.apply_links(2.0, [LinkStatus(2.0, "serial", False, "EOF")], hub, alarms)
    hub.update(2.0, [], None, None)
    assert hub.state_of("gnss1") is SensorState.DISCONNECTED and hub.state_of("gyro1") is SensorState.DISCONNECTED
    assert link_alarm_code("serial") == "transport.serial.link" and alarms.is_active("transport.serial.link")
    health.apply_links(3.0, [LinkStatus(3.0, link_source("autopilot", 2), True, "heartbeat resumed")], hub, alarms)
    assert not alarms.is_active("transport.autopilot.system2.link")


def test_the_daemon_input_pump_counts_and_links_through_the_shared_module() -> None:
    """InputPump fed as its reader threads feed it (no transport started): decoded and rejected frames are
    counted per transport by InputHealth, and a MAVLink heartbeat loss names its system."""
    config = parse_config(CONFIG)
    pump = InputPump(config, clock=lambda: 0.0)
    assert isinstance(pump.health, InputHealth)
    good = encode_hdt(Heading(0.7), "HE")
    bad_checksum = good[:-4] + (b"00" if good[-4:-2] != b"00" else b"11") + b"\r\n"
    for t, data in ((1.0, good), (1.1, bad_checksum), (1.2, b"\x00\x01garbage\r\n")):
        pump.received("serial", RawInput(t, data))
    pump.received("autopilot", RawInput(1.3, b"\xfd\x09garbage that is no MAVLink packet"))
    encoder = MavlinkEncoder(2, 1)
    pump.received("autopilot", RawInput(1.35, encoder.heartbeat()))
    measurements: list[Measurement] = []
    links: list[LinkStatus] = []
    pump.drain(1.4, measurements, links, [])
    counters = pump.health.counters()
    assert counters["serial"]["decoded"] == 1 and counters["serial"]["rejected"] == 2
    assert counters["autopilot"]["rejected"] >= 1
    assert [m.source for m in measurements] == ["gyro1"]
    assert [(s.source, s.connected) for s in links] == [(link_source("autopilot", 2), True)]
    timeout = next(t.settings for t in config.transports if t.name == "autopilot")["heartbeat_timeout_s"]
    links.clear()
    pump.drain(1.35 + timeout + 0.1, measurements, links, [])  # silence: the system's heartbeat is lost
    assert [(s.source, s.connected) for s in links] == [(link_source("autopilot", 2), False)]
    assert pump.router.sensors_on(links[0].source) == ["gyro2"]


# ------------------------------------------------------------------------------------------ case 8
@pytest.fixture(scope="module")
def bursts() -> ProbedRun:
    return ProbedRun.run(build_simulation(load_scenario(FAULTS / "08-malformed-bursts.yaml")))


def _raised(run: ProbedRun, code: str, after_s: float) -> float | None:
    return next((t for t, raised in run.events(code) if raised and t >= after_s - 1e-9), None)


def _cleared(run: ProbedRun, code: str, after_s: float) -> float | None:
    return next((t for t, raised in run.events(code) if not raised and t >= after_s - 1e-9), None)


@pytest.mark.parametrize(("t0", "transport", "reasons"), [
    (90.0, "lockstep_nmea0183", ("checksum", "garbage", "no_checksum")),
    (130.0, "lockstep_nmea2000", ("truncated_fast_packet", "bad_fast_packet", "truncated")),
    (170.0, "lockstep_mavlink", ("checksum", "truncated", "garbage")),
])
def test_case8_burst_is_rejected_counted_and_raises_the_error_rate_alarm(
        bursts: ProbedRun, t0: float, transport: str, reasons: tuple[str, ...]) -> None:
    run = bursts
    code = f"transport.{transport}.error_rate"
    raised = _raised(run, code, t0)
    assert raised is not None and raised - t0 <= DT + 1.0  # fast packets give up after 0.75 s
    assert code in run.status.active_codes(raised)
    cleared = _cleared(run, code, raised)
    window = run.simulation.config.hub.error_rate_window_s
    assert cleared is not None and window - 1.0 <= cleared - t0 <= window + 1.0
    counters = run.result.counters["transports"][transport]
    assert sum(counters[f"reason.{r}"] for r in reasons) == counters["rejected"]
    assert all(counters[f"reason.{r}"] >= 30 for r in reasons)  # the item kinds take turns


def test_case8_every_item_is_rejected_and_none_reaches_the_hub(bursts: ProbedRun) -> None:
    run = bursts
    transports = run.result.counters["transports"]
    assert transports["lockstep_nmea0183"]["rejected"] == 3 + 100
    assert transports["lockstep_nmea2000"]["rejected"] == 100
    assert transports["lockstep_mavlink"]["rejected"] == 100
    assert [f["items"] for f in run.result.counters["protocol_faults"]] == [3, 100, 100, 100]
    # the 3-item burst is counted but below the alarm's minimum
    assert _raised(run, "transport.lockstep_nmea0183.error_rate", 60.0) == pytest.approx(90.0)
    # no sample rejected by a quality test, every reference ok throughout, DP undisturbed
    assert int(run.sensors.rejected[run.sensors.rows - 1].sum()) == 0
    ok = run.sensors.state[run.between(SETTLED_S, 200.0)] == 1  # SensorState.OK
    assert ok.all()
    assert [(m[1], m[2]) for m in run.result.mode_changes] == [("standby", "auto_position")]
    assert run.thrust_rate_excess_n() <= 1e-6
    window = run.between(SETTLED_S, 200.0)
    assert np.nanmax(run.position_error_m()[window]) <= 2.0
    assert np.degrees(np.nanmax(run.heading_error_rad()[window])) <= 3.0


# ------------------------------------------------------------------------------------------ case 9
@pytest.fixture(scope="module")
def links() -> ProbedRun:
    return ProbedRun.run(build_simulation(load_scenario(FAULTS / "09-link-loss.yaml")))


def test_case9_unplugged_port_marks_its_sensor_disconnected_and_dp_continues(links: ProbedRun) -> None:
    run = links
    disconnected = run.sensors.first_time("gnss1", SensorState.DISCONNECTED, 100.0)
    assert disconnected == pytest.approx(100.0)  # the control step that receives the link change
    for code in ("transport.lockstep_nmea0183.link", "sensor.gnss1.disconnected"):
        assert _raised(run, code, 100.0) == pytest.approx(100.0)
        assert code in run.status.active_codes(100.0)
        assert _cleared(run, code, 100.0) == pytest.approx(130.0)
    gnss2 = run.sensors.weight[run.between(100.0, 130.0), run.sensors.column("gnss2")]
    assert np.all(gnss2 == 1.0)
    readmit = run.simulation.config.hub.readmit_s
    back = run.sensors.weight[run.between(130.0 + readmit + 1.0, 160.0), run.sensors.column("gnss1")]
    assert np.all(back > 0.2)


def test_case9_heartbeat_loss_marks_that_autopilot_disconnected(links: ProbedRun) -> None:
    run = links
    transport = next(t for t in run.simulation.config.transports if t.protocol == "mavlink")
    timeout = float(transport.settings["heartbeat_timeout_s"])
    code = f"transport.{transport.name}.system1.link"
    raised = _raised(run, code, 160.0)
    assert raised is not None and timeout < raised - 160.0 + 1.0 <= timeout + 1.0 + DT
    assert code in run.status.active_codes(raised)
    assert run.status.sensor_state(raised, "gyro2") == "disconnected"
    # its data still arrives (the link has data, no heartbeat) but is not used
    column = run.sensors.column("gyro2")
    k0, k1 = round((raised + DT) / DT), round(199.9 / DT)
    assert run.sensors.accepted[k1, column] > run.sensors.accepted[k0, column]
    assert np.all(run.sensors.weight[k0:k1, column] == 0.0)
    assert np.all(run.sensors.weight[k0:k1, run.sensors.column("gyro1")] == 1.0)
    assert _cleared(run, code, raised) == pytest.approx(200.0)  # the first heartbeat after the loss


def test_case9_no_restart_no_mode_change_no_thrust_jump(links: ProbedRun) -> None:
    run = links
    assert [(m[1], m[2]) for m in run.result.mode_changes] == [("standby", "auto_position")]
    assert run.thrust_rate_excess_n() <= 1e-6
    drives_per_step = run.simulation.controller.force_rate_b * DT
    baseline = run.force_step_n(SETTLED_S, 100.0)
    for t0 in (100.0, 130.0, 160.0, 200.0):
        assert np.all(run.force_step_n(t0, t0 + 10.0) <= baseline + drives_per_step)
    window = run.between(SETTLED_S, 230.0)
    assert np.nanmax(run.position_error_m()[window]) <= 2.0
    assert np.degrees(np.nanmax(run.heading_error_rad()[window])) <= 3.0
