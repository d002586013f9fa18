"""The input stage (``dpcontrol.runtime.ingest``): one class per protocol, chosen by the transport's protocol,
decodes, counts and routes exactly as the lockstep simulation, replay and the benchmark rely on."""

from __future__ import annotations

import math

import pytest

from dpcontrol.runtime.config import parse_config
from dpcontrol.runtime.ingest import INPUTS, MavlinkInput, Nmea0183Input, Nmea2000Input, transport_inputs
from dpcontrol.runtime.inputs import SensorRouter
from dpcontrol.runtime.transport_health import InputHealth
from interfaces.mavlink.codec import MavlinkEncoder
from interfaces.messages import FixQuality, Heading, Measurement, PositionFix
from interfaces.nmea0183 import encode_gga, encode_ths
from interfaces.nmea2000.codec import N2kEncoder

FIX = PositionFix(60.0, 5.0, FixQuality.DGPS, 36000.0, 12, 0.8, 0.0)


def _config():
    return parse_config({
        "vessel_id": "ingest",
        "vessel": "supply",
        "datum": {"lat_deg": 60.0, "lon_deg": 5.0},
        "transports": [{"name": "serial", "protocol": "nmea0183", "port": "/dev/null"},
                       {"name": "can", "protocol": "nmea2000", "interface": "virtual", "channel": "x"},
                       {"name": "mav", "protocol": "mavlink", "url": "udpin:127.0.0.1:14550"}],
        "sensors": [{"name": "gnss1", "kind": "position", "transport": "serial", "rate_hz": 1, "sigma_m": 0.5},
                    {"name": "gyro1", "kind": "heading", "transport": "serial", "rate_hz": 10, "sigma_deg": 0.1},
                    {"name": "gnss2", "kind": "position", "transport": "can", "source_address": 41,
                     "rate_hz": 1, "sigma_m": 0.5},
                    {"name": "gnss3", "kind": "position", "transport": "mav", "rate_hz": 1, "sigma_m": 0.5}],
    }, file="<test>")


@pytest.fixture()
def stages():
    config = _config()
    router = SensorRouter(config.routes, config.transports)
    health = InputHealth([t.name for t in config.transports], router, 0.2)
    beats: list[tuple[str, int, int, float]] = []
    inputs = transport_inputs(config.transports, router, health, on_heartbeat=lambda *b: beats.append(b))
    return inputs, health, beats


def test_each_protocol_gets_its_own_input_class(stages) -> None:
    inputs, _, _ = stages
    assert {name: type(stage) for name, stage in inputs.items()} == {
        "serial": Nmea0183Input, "can": Nmea2000Input, "mav": MavlinkInput}
    assert set(INPUTS) == {"nmea0183", "nmea2000", "mavlink"}


def test_nmea_sentences_split_across_reads_are_routed_and_garbage_is_counted(stages) -> None:
    inputs, health, _ = stages
    stream = encode_gga(FIX, "GP", 36000.0) + encode_ths(Heading(math.radians(30.0)), "HE") + b"$GPGGA,garbage*00\r\n"
    out: list[Measurement] = []
    for i in range(0, len(stream), 7):
        inputs["serial"].feed(1.0, stream[i:i + 7], out)
    assert [m.source for m in out] == ["gnss1", "gyro1"]
    assert inputs["serial"].rejected == 1
    counters = health.health["serial"].counters()
    assert counters["decoded"] == 2
    assert counters["rejected"] + counters["flagged_invalid"] == 1


def test_nmea2000_frames_need_their_identifier_and_go_to_the_source_address_sensor(stages) -> None:
    inputs, _, _ = stages
    out: list[Measurement] = []
    for can_id, data in N2kEncoder(41).gnss_position(FIX, date_days=20000):
        inputs["can"].feed(2.0, data, out, can_id=can_id)
    assert [m.source for m in out] == ["gnss2"]
    other: list[Measurement] = []
    for can_id, data in N2kEncoder(42).position_rapid(FIX):  # another address: no sensor of this configuration
        inputs["can"].feed(2.0, data, other, can_id=can_id)
    assert other == []
    with pytest.raises(ValueError, match="CAN identifier"):
        inputs["can"].feed(2.0, b"\x00" * 8, out)


def test_an_incomplete_fast_packet_expires_as_a_counted_reject(stages) -> None:
    inputs, _, _ = stages
    frames = N2kEncoder(41).gnss_position(FIX, date_days=20000)
    assert len(frames) > 1
    out: list[Measurement] = []
    inputs["can"].feed(3.0, frames[0][1], out, can_id=frames[0][0])
    assert inputs["can"].rejected == 0
    inputs["can"].expire(30.0)
    assert inputs["can"].rejected == 1 and out == []


def test_mavlink_heartbeats_go_to_the_link_monitor_and_fixes_to_their_sensor(stages) -> None:
    inputs, _, beats = stages
    encoder = MavlinkEncoder(3, 1)
    out: list[Measurement] = []
    inputs["mav"].feed(4.0, encoder.heartbeat(), out)
    inputs["mav"].feed(4.1, encoder.gps_raw_int(FIX, time_usec=1), out)
    assert beats == [("mav", 3, 1, 4.0)]
    assert [m.source for m in out] == ["gnss3"]


def test_a_recorded_input_decodes_as_the_live_one(stages) -> None:
    inputs, _, _ = stages
    live: list[Measurement] = []
    recorded: list[Measurement] = []
    sentence = encode_gga(FIX, "GP", 36000.0)
    inputs["serial"].feed(5.0, sentence, live)
    inputs["serial"].feed_record(5.0, {}, sentence.rstrip(b"\r\n"), recorded)  # the recorder strips the terminator
    frame_id, data = N2kEncoder(41).position_rapid(FIX)[0]
    inputs["can"].feed(5.0, data, live, can_id=frame_id)
    inputs["can"].feed_record(5.0, {"can_id": frame_id}, data, recorded)
    inputs["can"].feed_record(5.0, {}, data, recorded)  # no identifier recorded: nothing to decode
    assert [(m.source, m.message) for m in recorded] == [(m.source, m.message) for m in live]
    assert len(live) == 2
