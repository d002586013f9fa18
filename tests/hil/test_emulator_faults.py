"""Protocol-level faults and invalid samples, seen by the real interface readers (a fake controller).

One 5-second run: malformed bursts on every link, a serial unplug, a MAVLink heartbeat loss, and
sensors flagging invalid data on each protocol. This run also checks the other zenoh direction:
the controller configuration only *connects* (to the emulator's endpoint), so the emulator listens.
"""

from __future__ import annotations

import collections
from typing import Any

import pytest

from interfaces.mavlink.transport import MavlinkUdpReader
from interfaces.messages import LinkStatus, Measurement, PositionFix, RejectedInput
from interfaces.nmea0183 import SerialReader
from interfaces.nmea2000.transport import CanBusConfig, N2kCanReader
from interfaces.zenoh import ZenohConfig, ZenohNode
from sim_plant.emulator import HilOptions

DURATION_S = 5.0
UTC_START_S = 36000.0
UNPLUG = (1.5, 1.0)          # start, duration [s]
SILENCE = (1.0, 2.0)
HEARTBEAT_TIMEOUT_S = 1.5    # the reader's; beats are 1 s apart


def _scenario() -> dict[str, Any]:
    burst = {"t_s": 0.5, "kind": "malformed_burst"}
    return {
        "name": "hil-faults", "vessel": "cybership2", "duration_s": DURATION_S, "seed": 2, "utc_start_s": UTC_START_S,
        "sensors": [
            {"name": "gnss1", "kind": "gnss", "protocol": "nmea0183", "rate_hz": 5},
            {"name": "gyro1", "kind": "gyro", "protocol": "nmea0183", "rate_hz": 10},
            {"name": "gnss2", "kind": "gnss", "protocol": "nmea2000", "rate_hz": 5},
            {"name": "gyro2", "kind": "gyro", "protocol": "nmea2000", "rate_hz": 10},
            {"name": "gnss3", "kind": "gnss", "protocol": "mavlink", "rate_hz": 2},
            {"name": "gnss4", "kind": "gnss", "protocol": "nmea0183", "rate_hz": 1},   # wired to CAN by the controller
        ],
        "faults": [
            {**burst, "sensor": "gnss1", "count": 6}, {**burst, "sensor": "gnss2", "count": 6},
            {**burst, "sensor": "gyro2", "count": 4}, {**burst, "sensor": "gnss3", "count": 6},
            {"t_s": SILENCE[0], "kind": "heartbeat_loss", "sensor": "gnss3", "duration_s": SILENCE[1]},
            {"t_s": UNPLUG[0], "kind": "serial_unplug", "sensor": "gyro1", "duration_s": UNPLUG[1]},
            {"t_s": 0.2, "kind": "serial_unplug", "sensor": "gnss4", "duration_s": 0.5},      # not a serial line here
            {"t_s": 3.0, "kind": "gnss_invalid", "sensor": "gnss1", "duration_s": 0.5},
            {"t_s": 3.0, "kind": "gyro_invalid", "sensor": "gyro1", "duration_s": 0.3},
            {"t_s": 3.0, "kind": "gnss_invalid", "sensor": "gnss2", "duration_s": 0.5},
            {"t_s": 3.0, "kind": "gyro_invalid", "sensor": "gyro2", "duration_s": 0.3},
            {"t_s": 3.0, "kind": "gnss_invalid", "sensor": "gnss3", "duration_s": 1.0},
        ],
    }


@pytest.fixture(scope="module")
def run(rig: Any, tmp_path_factory: pytest.TempPathFactory, closing: list[Any]) -> dict[str, Any]:
    folder = tmp_path_factory.mktemp("hil_faults")
    serial_events, serial_links, n2k_events, mav_events = rig.Events(), rig.Events(), rig.Events(), rig.Events()
    mav = MavlinkUdpReader(mav_events, heartbeat_timeout_s=HEARTBEAT_TIMEOUT_S, source_names={(3, 1): "gnss3"})
    closing.append(mav)
    can_port, zenoh_port = rig.free_port(), rig.free_port()
    plant_endpoint = f"tcp/127.0.0.1:{zenoh_port}"
    port = folder / "ttyUSB0"
    controller = rig.write_yaml(folder / "vessel.yaml", {
        "vessel_id": "hil-faults",
        "transports": [
            {"name": "serial0", "protocol": "nmea0183", "port": str(port)},
            {"name": "can0", "protocol": "nmea2000", "interface": "remote", "channel": f"ws://127.0.0.1:{can_port}/"},
            {"name": "mav0", "protocol": "mavlink", "url": f"udp:127.0.0.1:{mav.address[1]}"},
        ],
        "sensors": [
            {"name": "gnss1", "kind": "position", "transport": "serial0"},
            {"name": "gyro1", "kind": "heading", "transport": "serial0"},
            {"name": "gnss2", "kind": "position", "transport": "can0", "source_address": 20},
            {"name": "gyro2", "kind": "heading", "transport": "can0", "source_address": 21},
            {"name": "gnss3", "kind": "position", "transport": "mav0", "system_id": 3},
            {"name": "gnss4", "kind": "position", "transport": "can0", "source_address": 22},
        ],
        "zenoh": {"connect": [plant_endpoint]},     # the daemon connects to the plant: the plant listens
    })
    scenario = rig.write_yaml(folder / "scenario.yaml", _scenario())
    emulator = rig.EmulatorRun(scenario, controller, HilOptions(can_server_mode="thread"))
    closing.append(emulator)
    fake_controller = ZenohNode(ZenohConfig(connect=(plant_endpoint,), lease_s=1.0), "hil-faults")
    closing.append(fake_controller)
    plant_alive = fake_controller.watch_alive("plant")
    serial = SerialReader(str(port), source="serial0", clock=lambda: 0.0, on_measurement=serial_events,
                          on_link=serial_links, reconnect_initial_s=0.01, reconnect_max_s=0.05).start()
    closing.append(serial)
    n2k = N2kCanReader(CanBusConfig("remote", f"ws://127.0.0.1:{can_port}/"), n2k_events,
                       source_names={20: "gnss2", 21: "gyro2", 22: "gnss4"}).start()
    closing.append(n2k)
    mav.start()
    assert serial.wait_connected(rig.WAIT_S) and n2k.wait_connected(rig.WAIT_S)
    emulator.start()
    alive = plant_alive.wait_for(True, rig.WAIT_S)
    summary = emulator.join(DURATION_S + rig.WAIT_S)
    # the truncated fast packets are reported when the reader gives up on them (0.75 s)
    n2k_events.wait_for(lambda items: sum(isinstance(i, RejectedInput)
                                          and i.rejected.reason == "truncated_fast_packet" for i in items) >= 2, 5.0)
    return {"summary": summary, "emulator": emulator, "serial": serial_events, "serial_links": serial_links,
            "serial_counters": serial.counters, "n2k": n2k_events, "mav": mav_events, "plant_alive": alive}


def _rejects(events: Any, source: str | None = None) -> collections.Counter[str]:
    return collections.Counter(i.rejected.reason for i in events.items()
                               if isinstance(i, RejectedInput) and (source is None or i.source == source))


def test_serial_burst_invalid_samples_and_unplug(run: dict[str, Any]) -> None:
    counters = run["serial_counters"]
    assert counters["rejected.checksum"] == 2           # 6 items: 2 bad checksums,
    assert counters["rejected.garbage"] >= 2            # 2 runs of binary garbage,
    assert counters["rejected.no_checksum"] + counters["rejected.malformed"] == 2   # 2 truncated sentences
    assert counters["rejected.invalid_fix"] == 3        # GGA quality 0 at 3.0, 3.2, 3.4 s
    assert counters["rejected.invalid_status"] == 6     # THS V and ROT V at 3.0, 3.1, 3.2 s
    # pulled and plugged back once; the last disconnect is the emulator closing its pty at the end
    assert counters["disconnects"] == 2 and counters["connects"] == 2
    assert [s.connected for s in run["serial_links"].items() if isinstance(s, LinkStatus)] == [True, False, True, False]
    times = [round(m.message.utc_time_s - UTC_START_S, 2) for m in run["serial"].items()
             if isinstance(m, Measurement) and isinstance(m.message, PositionFix)]
    start, length = UNPLUG
    assert not [t for t in times if start <= t < start + length]   # nothing from the pulled cable
    assert [t for t in times if t >= start + length]                # the fixes come back on the new pty
    link = run["summary"]["links"]["serial0"]["counters"]
    assert link["unplugs"] == 1 and link["replugs"] == 1 and link["dropped_unplugged_bytes"] > 0


def test_nmea2000_burst_and_invalid_samples(run: dict[str, Any]) -> None:
    gnss, gyro = _rejects(run["n2k"], "gnss2"), _rejects(run["n2k"], "gyro2")
    assert gnss["truncated_fast_packet"] == 2 and gnss["bad_fast_packet"] == 2 and gnss["truncated"] == 2
    assert gnss["invalid_fix"] == 3                     # 129029 method 0 at 3.0, 3.2, 3.4 s
    assert gyro["truncated"] == 4
    assert gyro["not_available"] == 6                   # 127250 and 127251 "not available" at 3.0, 3.1, 3.2 s
    fixes = [i for i in run["n2k"].items() if isinstance(i, Measurement) and isinstance(i.message, PositionFix)]
    assert {i.source for i in fixes} == {"gnss2", "gnss4"}


def test_mavlink_burst_invalid_fix_and_heartbeat_loss(run: dict[str, Any]) -> None:
    rejects = _rejects(run["mav"])
    assert rejects["checksum"] == 2 and rejects["truncated"] == 2 and rejects["garbage"] >= 2
    assert _rejects(run["mav"], "gnss3")["invalid_fix"] == 2     # GPS_RAW_INT fix_type 0 at 3.0, 3.5 s
    links = [i for i in run["mav"].items() if isinstance(i, LinkStatus) and i.source == "gnss3"]
    assert [s.connected for s in links] == [True, False, True]
    lost, back = (run["emulator"].plant_time(s.t_s) for s in links[1:])  # the reader stamps with time.monotonic
    start, length = SILENCE
    # beats at 0 s, none at 1 s and 2 s, then 3 s: lost one timeout after the beat at 0 s, back with the one at 3 s
    assert HEARTBEAT_TIMEOUT_S - 0.05 <= lost <= HEARTBEAT_TIMEOUT_S + 0.3
    assert start + length - 0.05 <= back <= start + length + 0.3
    heartbeats = run["summary"]["links"]["mav0"]["counters"]
    assert heartbeats["heartbeats_suppressed"] == round(length)   # the beats at 1 s and 2 s


def test_faults_are_reported_and_impossible_ones_skipped(run: dict[str, Any]) -> None:
    faults = run["summary"]["faults"]
    bursts = {f["target"]: f["items"] for f in faults if f["kind"] == "malformed_burst"}
    assert bursts == {"gnss1": 6, "gnss2": 6, "gyro2": 4, "gnss3": 6}
    skipped = [f for f in faults if "skipped" in f]
    assert [(f["target"], f["action"]) for f in skipped] == [("gnss4", "unplug"), ("gnss4", "replug")]
    assert any("gnss4" in note and "nmea2000" in note for note in run["summary"]["notes"])
    assert run["summary"]["sensors"]["gnss1"]["malformed_items"] == 6


def test_the_plant_listens_when_the_controller_connects(run: dict[str, Any]) -> None:
    assert run["plant_alive"]
    assert run["summary"]["zenoh"]["endpoints"]["listen"] and not run["summary"]["zenoh"]["endpoints"]["connect"]
