"""The emulator's sensor links, read back with the real interface readers (a fake controller).

One 6-second run for the module: two GNSS and two gyros... three of each, one pair per transport —
NMEA 0183 on the pty the controller configuration names, NMEA 2000 through the python-can-remote
server the emulator starts, MAVLink over UDP to the port the controller listens on. The readers are
the ones the daemon uses (:class:`SerialReader`, :class:`N2kCanReader`, :class:`MavlinkUdpReader`);
what they decode is compared with the plant truth the emulator writes (``truth.csv``), and the
arrival pattern with the configured rates.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from dpbase.frames import ssa
from dpbase.geodesy import LocalFrame
from interfaces.mavlink.transport import MavlinkUdpReader
from interfaces.messages import Heading, LinkHeartbeat, Measurement, PositionErrorStats, PositionFix, RateOfTurn
from interfaces.nmea0183 import SerialReader
from interfaces.nmea2000.transport import CanBusConfig, N2kCanReader
from sim_plant.emulator import HilOptions

DATUM = (63.4305, 10.3951)
UTC_START_S = 36000.0
DURATION_S = 6.0
NOISE_M = 0.05
NOISE_RAD = math.radians(0.1)
POSITION_RATES = {"gnss1": (5.0, 0.0), "gnss2": (2.0, 0.0), "gnss3": (2.0, 0.1)}  # rate [Hz], offset [s]
HEADING_RATES = {"gyro1": 10.0, "gyro2": 10.0, "gyro3": 5.0}
# wire resolution on top of the sensor noise: MAVLink lat/lon 1e-7° (≤ 5.6 mm), N2K heading 1e-4 rad
QUANTISATION_M = 0.006
HEADING_QUANTISATION_RAD = 1e-4


def _scenario() -> dict[str, Any]:
    return {
        "name": "hil-links", "vessel": "cybership2", "duration_s": DURATION_S, "seed": 11,
        "datum": {"lat_deg": DATUM[0], "lon_deg": DATUM[1]}, "utc_start_s": UTC_START_S,
        "sea_states": [{"t_s": 0, "spectrum": "jonswap", "hs_m": 0.03, "omega_peak_rad_s": 1.0, "direction_deg": 30}],
        "current": {"speed_mps": 0.02, "direction_deg": 45},
        "setpoints": [{"t_s": 0, "north_m": 0, "east_m": 0, "heading_deg": 0}],
        "sensors": [
            {"name": "gnss1", "kind": "gnss", "protocol": "nmea0183", "rate_hz": 5, "noise_m": NOISE_M},
            {"name": "gyro1", "kind": "gyro", "protocol": "nmea0183", "rate_hz": 10, "noise_deg": 0.1},
            {"name": "gnss2", "kind": "gnss", "protocol": "nmea2000", "rate_hz": 2, "noise_m": NOISE_M},
            {"name": "gyro2", "kind": "gyro", "protocol": "nmea2000", "rate_hz": 10, "noise_deg": 0.1},
            {"name": "gnss3", "kind": "gnss", "protocol": "mavlink", "rate_hz": 2, "noise_m": NOISE_M,
             "offset_s": 0.1},
            {"name": "gyro3", "kind": "gyro", "protocol": "mavlink", "rate_hz": 5, "noise_deg": 0.1},
        ],
    }


@pytest.fixture(scope="module")
def run(rig: Any, tmp_path_factory: pytest.TempPathFactory, closing: list[Any]) -> dict[str, Any]:
    folder = tmp_path_factory.mktemp("hil_links")
    serial_events, n2k_events, mav_events, records = rig.Events(), rig.Events(), rig.Events(), rig.Events()
    mav_reader = MavlinkUdpReader(mav_events, bind=("127.0.0.1", 0), heartbeat_timeout_s=3.0,
                                  source_names={(7, 1): "gnss3", (8, 1): "gyro3"})
    closing.append(mav_reader)
    can_port, zenoh_port = rig.free_port(), rig.free_port()
    port = folder / "ttyNAV"
    controller = rig.write_yaml(folder / "vessel.yaml", {
        "vessel_id": "hil-links",
        "vessel": "cybership2",                      # daemon keys the emulator does not read
        "loop": {"rate_hz": 10},
        "estimator": {"kind": "mmae"},
        "transports": [
            {"name": "serial0", "protocol": "nmea0183", "port": str(port), "baud": 38400},
            {"name": "can0", "protocol": "nmea2000", "interface": "remote", "channel": f"ws://127.0.0.1:{can_port}/"},
            {"name": "mav0", "protocol": "mavlink", "url": f"udpin:127.0.0.1:{mav_reader.address[1]}"},
        ],
        "sensors": [
            {"name": "gnss1", "kind": "position", "transport": "serial0", "talker": "GN", "sentences": ["GGA", "GST"]},
            {"name": "gyro1", "kind": "heading", "transport": "serial0", "rate_hz": 10},
            {"name": "gnss2", "kind": "position", "transport": "can0", "source_address": 40},
            {"name": "gyro2", "kind": "heading", "transport": "can0", "source_address": 41},
            {"name": "gnss3", "kind": "position", "transport": "mav0", "system_id": 7},
            {"name": "gyro3", "kind": "heading", "transport": "mav0", "system_id": 8},
        ],
        "zenoh": {"listen": [f"tcp/127.0.0.1:{zenoh_port}"]},
    })
    scenario = rig.write_yaml(folder / "scenario.yaml", _scenario())
    out = folder / "out"
    emulator = rig.EmulatorRun(scenario, controller, HilOptions(out_dir=out),
                               record=lambda topic, t_s, payload: records((topic, t_s, payload)))
    closing.append(emulator)
    serial = SerialReader(str(port), source="serial0", clock=lambda: 0.0, baudrate=38400,
                          on_measurement=serial_events, reconnect_initial_s=0.01, reconnect_max_s=0.05).start()
    closing.append(serial)
    n2k = N2kCanReader(CanBusConfig("remote", f"ws://127.0.0.1:{can_port}/"), n2k_events,
                       source_names={40: "gnss2", 41: "gyro2"}).start()
    closing.append(n2k)
    mav_reader.start()
    assert serial.wait_connected(rig.WAIT_S) and n2k.wait_connected(rig.WAIT_S)
    emulator.start()
    summary = emulator.join(DURATION_S + rig.WAIT_S)
    # the readers have everything once the last sample of each link has arrived
    for events, source in ((serial_events, "serial0"), (n2k_events, "gyro2"), (mav_events, "gyro3")):
        events.wait_for(lambda items, s=source: sum(isinstance(i, Measurement) and i.source == s
                                                    and isinstance(i.message, Heading) for i in items)
                        >= HEADING_RATES.get(s, 10.0) * DURATION_S + 1, 5.0)
    with open(out / "truth.csv", newline="", encoding="utf-8") as stream:
        rows = list(csv.DictReader(stream))
    truth = {round(float(r["t_s"]) * 10): r for r in rows}
    return {"summary": summary, "out": out, "truth": truth, "rows": rows, "serial": serial_events,
            "n2k": n2k_events, "mav": mav_events, "records": records, "emulator": emulator, "port": port,
            "serial_counters": serial.counters}


def _measurements(events: Any, source: str, kind: type) -> list[tuple[float, Any]]:
    return [(t, item.message) for t, item in events.stamped()
            if isinstance(item, Measurement) and item.source == source and isinstance(item.message, kind)]


def _fixes(run: dict[str, Any], sensor: str) -> list[PositionFix]:
    events = {"gnss1": run["serial"], "gnss2": run["n2k"], "gnss3": run["mav"]}[sensor]
    source = "serial0" if sensor == "gnss1" else sensor
    return [m for _, m in _measurements(events, source, PositionFix)]


def _headings(run: dict[str, Any], sensor: str) -> list[tuple[float, Heading]]:
    events = {"gyro1": run["serial"], "gyro2": run["n2k"], "gyro3": run["mav"]}[sensor]
    source = "serial0" if sensor == "gyro1" else sensor
    return _measurements(events, source, Heading)


@pytest.mark.parametrize("sensor", sorted(POSITION_RATES))
def test_positions_match_the_truth_within_the_sensor_noise(run: dict[str, Any], sensor: str) -> None:
    frame = LocalFrame(*DATUM)
    errors = []
    for fix in _fixes(run, sensor):
        assert fix.utc_time_s is not None, "every protocol here carries the sample time"
        row = run["truth"][round((fix.utc_time_s - UTC_START_S) * 10)]
        assert abs(float(row["t_s"]) - (fix.utc_time_s - UTC_START_S)) < 1e-3
        north, east, _ = frame.to_ned(fix.lat_deg, fix.lon_deg)
        errors += [north - float(row["north_total_m"]), east - float(row["east_total_m"])]
    errors_m = np.array(errors)
    assert errors_m.size >= 2 * 12
    assert np.max(np.abs(errors_m)) < 5.0 * NOISE_M + QUANTISATION_M  # each fix: the noise, no offset or lag
    rms = float(np.sqrt(np.mean(errors_m**2)))
    assert 0.5 * NOISE_M < rms < 1.5 * NOISE_M  # the configured noise is there, and nothing more
    assert abs(float(np.mean(errors_m))) < 3.0 * NOISE_M / math.sqrt(errors_m.size)


@pytest.mark.parametrize("sensor", sorted(POSITION_RATES))
def test_each_gnss_sample_arrives_once_at_its_configured_times(run: dict[str, Any], sensor: str) -> None:
    rate, offset = POSITION_RATES[sensor]
    times = sorted(round(f.utc_time_s - UTC_START_S, 2) for f in _fixes(run, sensor))  # type: ignore[operator]
    count = math.floor((DURATION_S - offset) * rate + 1e-9) + 1
    assert times == [round(offset + k / rate, 2) for k in range(count)]


@pytest.mark.parametrize("sensor", sorted(HEADING_RATES))
def test_headings_match_the_truth_and_arrive_at_the_gyro_rate(run: dict[str, Any], sensor: str) -> None:
    rate = HEADING_RATES[sensor]
    received = _headings(run, sensor)
    assert len(received) == round(DURATION_S * rate) + 1
    emulator = run["emulator"]
    errors = []
    for arrival, heading in received:
        # the sample was taken at the last grid time before its arrival (latency ≪ one period)
        k = math.floor((emulator.plant_time(arrival) + 0.02) * rate)
        row = run["truth"][round(k / rate * 10)]
        errors.append(ssa(heading.heading_rad - float(row["heading_total_rad"])))
    errors_rad = np.array(errors)
    assert np.max(np.abs(errors_rad)) < 5.0 * NOISE_RAD + HEADING_QUANTISATION_RAD
    assert 0.5 * NOISE_RAD < float(np.sqrt(np.mean(errors_rad**2))) < 1.5 * NOISE_RAD
    gaps = np.diff([arrival for arrival, _ in received])
    assert abs(float(np.median(gaps)) - 1.0 / rate) < 0.25 / rate


def test_rate_of_turn_and_gnss_statistics_come_with_their_samples(run: dict[str, Any]) -> None:
    assert len(_measurements(run["serial"], "serial0", RateOfTurn)) == round(DURATION_S * 10) + 1
    assert len(_measurements(run["n2k"], "gyro2", RateOfTurn)) == round(DURATION_S * 10) + 1
    assert len(_measurements(run["mav"], "gyro3", RateOfTurn)) == round(DURATION_S * 5) + 1
    stats = [m for _, m in _measurements(run["serial"], "serial0", PositionErrorStats)]
    assert len(stats) == len(_fixes(run, "gnss1"))
    assert all(abs(s.sigma_north_m - NOISE_M) < 1e-3 and abs(s.sigma_east_m - NOISE_M) < 1e-3 for s in stats)
    assert all(f.quality.name == "DGPS" for name in POSITION_RATES for f in _fixes(run, name))


def test_mavlink_autopilots_beat_at_1_hz_as_surface_boats(run: dict[str, Any]) -> None:
    beats = [m for _, m in _measurements(run["mav"], "gnss3", LinkHeartbeat)] + \
        [m for _, m in _measurements(run["mav"], "gyro3", LinkHeartbeat)]
    per_system = {sid: [b for b in beats if b.system_id == sid] for sid in (7, 8)}
    for sid, found in per_system.items():
        assert DURATION_S <= len(found) <= DURATION_S + 1, sid  # 1 Hz from t = 0 to the end
        assert all(b.vehicle_type == 11 and b.component_id == 1 for b in found)  # MAV_TYPE_SURFACE_BOAT


def test_outputs_summary_and_record_hook(run: dict[str, Any]) -> None:
    summary = run["summary"]
    rows = run["rows"]
    assert [round(float(r["t_s"]), 6) for r in rows] == [round(k / 10, 6) for k in range(round(DURATION_S * 10) + 1)]
    assert summary["stopped_by"] == "duration" and summary["duration_s"] == pytest.approx(DURATION_S)
    for name, (rate, offset) in POSITION_RATES.items():
        assert summary["sensors"][name]["samples"] == math.floor((DURATION_S - offset) * rate + 1e-9) + 1
    for name, rate in HEADING_RATES.items():
        assert summary["sensors"][name]["samples"] == round(DURATION_S * rate) + 1
    assert summary["loop"]["wakeups"] >= round(DURATION_S * 10) + 1
    assert summary["counts"]["feedback_published"] == round(DURATION_S * 10) + 1
    assert summary["links"]["serial0"]["device"] == str(run["port"])
    assert summary["links"]["can0"]["addresses"] == {"gnss2": 40, "gyro2": 41}
    assert (run["out"] / "links.json").exists() and (run["out"] / "hil_summary.json").exists()
    records = run["records"].items()
    serial_sentences = summary["sensors"]["gnss1"]["sentences"] + summary["sensors"]["gyro1"]["sentences"]
    raw_serial = [p for topic, _, p in records if topic == "raw/serial0"]
    assert len(raw_serial) == serial_sentences
    assert all(p["data"].startswith(b"$") and p["source"] in ("gnss1", "gyro1") for p in raw_serial)
    assert any(p["data"].startswith(b"$GNGGA") for p in raw_serial)  # the controller's talker
    can_frames = [p for topic, _, p in records if topic == "raw/can0"]
    assert len(can_frames) == summary["links"]["can0"]["writer"]["frames_sent"]
    assert all(isinstance(p["can_id"], int) and len(p["data"]) <= 8 for p in can_frames)
    feedback = [p for topic, _, p in records if topic == "feedback"]
    assert len(feedback) == summary["counts"]["feedback_published"]
    assert not Path(run["port"]).exists()  # the pty symlink is removed at the end
