"""The input stage (``dpcontrol.runtime.ingest``): one class per protocol, chosen by the transport's protocol,
decodes, counts and routes exactly as the lockstep simulation, replay and the benchmark rely on."""

from __future__ import annotations

import math

import pytest

from dpcontrol.runtime.config import parse_config
from dpcontrol.runtime.ingest import INPUTS, MavlinkInput, Nmea0183Input, Nmea2000Input, transport_inputs
from dpcontrol.runtime.inputs import SensorRouter, link_source
from dpcontrol.runtime.transport_health import InputHealth
from interfaces.mavlink.codec import MavlinkEncoder
from interfaces.messages import FixQuality, Heading, LinkStatus, Measurement, PositionFix
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
    inputs = transport_inputs(config.transports, router, health, start_t_s=0.0)
    return inputs, health, None


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


def test_mavlink_heartbeats_are_watched_per_system_and_fixes_go_to_their_sensor(stages) -> None:
    inputs, _, _ = stages
    encoder = MavlinkEncoder(3, 1)
    out: list[Measurement] = []
    links: list[LinkStatus] = []
    inputs["mav"].feed(4.0, encoder.heartbeat(), out)
    inputs["mav"].feed(4.1, encoder.gps_raw_int(FIX, time_usec=1), out)
    inputs["mav"].poll(4.2, links)
    assert [m.source for m in out] == ["gnss3"]
    assert [(link.source, link.connected) for link in links] == [(link_source("mav", 3), True)]
    links.clear()
    inputs["mav"].poll(4.0 + 5.0, links)  # within the default 5 s timeout: nothing
    assert links == []
    inputs["mav"].poll(4.0 + 5.2, links)
    assert [(link.source, link.connected) for link in links] == [(link_source("mav", 3), False)]


def test_a_mavlink_link_where_nothing_is_heard_is_reported_lost_once() -> None:
    config = _config()
    router = SensorRouter(config.routes, config.transports)
    inputs = transport_inputs(config.transports, router, start_t_s=10.0)
    links: list[LinkStatus] = []
    for t in (12.0, 15.5, 20.0):
        inputs["mav"].poll(t, links)
    assert [(link.source, link.connected) for link in links] == [(link_source("mav", None), False)]
    replay = transport_inputs(config.transports, router)  # no start time: heartbeats only counted
    replay["mav"].poll(100.0, links)
    assert len(links) == 1


def test_every_raw_input_is_shown_before_its_measurements_with_the_decoders_verdict() -> None:
    """The daemon numbers and records each raw input through this observer; a measurement belongs to the last
    raw input shown before it was appended."""
    config = _config()
    router = SensorRouter(config.routes, config.transports)
    out: list[Measurement] = []
    seen: list[tuple[str, bytes, str | None, dict, int]] = []
    inputs = transport_inputs(config.transports, router,
                              on_raw=lambda transport, _t, data, rejected, fields: seen.append(
                                  (transport, data, rejected, fields, len(out))))
    good = encode_gga(FIX, "GP", 36000.0)
    inputs["serial"].feed(1.0, good + b"$GPGGA,garbage*00\r\n" + good[:20], out)
    assert [(t, r, f, n) for t, _d, r, f, n in seen] == [
        ("serial", None, {"sentence": "GPGGA"}, 0), ("serial", "checksum", {"sentence": "GPGGA"}, 1)]
    assert seen[0][1] == good.rstrip(b"\r\n")  # as the recorder keeps a sentence: without its terminator
    inputs["serial"].link_changed(2.0, False, out)  # the half sentence of a lost line is given up, and shown
    assert seen[-1][2] == "unterminated" and seen[-1][1] == good[:20]
    seen.clear()
    frame_id, data = N2kEncoder(41).position_rapid(FIX)[0]
    inputs["can"].feed(3.0, data, out, can_id=frame_id)
    inputs["mav"].feed(3.1, b"\xfd garbage", out)
    assert [(t, r, f, n) for t, _d, r, f, n in seen] == [("can", None, {"can_id": frame_id}, 1),
                                                        ("mav", seen[1][2], {}, 2)]
    assert seen[1][2] is not None  # the datagram's rejection reason
    assert [m.source for m in out] == ["gnss1", "gnss2"]


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
