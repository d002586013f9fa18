"""MAVLink codec: round trips of what the emulator's autopilot sends, validity rules, signing, heartbeats, tlogs."""

from __future__ import annotations

import json
import math
import struct
from pathlib import Path

import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from pymavlink.dialects.v10 import common as mavlink1
from pymavlink.dialects.v20 import common as mavlink2

from interfaces.mavlink.codec import (
    HeartbeatMonitor,
    MavlinkDecoder,
    MavlinkEncoder,
    parse_signing_key,
)
from interfaces.mavlink.logs import decode_tlog
from interfaces.messages import (
    Attitude,
    CourseOverGround,
    FixQuality,
    Heading,
    LinkHeartbeat,
    PositionFix,
    RateOfTurn,
    Rejected,
)

PROPERTY = settings(max_examples=150, deadline=None)
KEY = bytes(range(32))
NOW_S = 1_750_000_000.0

LATLON_DEG = 0.5e-7 + 1e-12
ALT_M = 0.5e-3 + 1e-9
HDOP = 0.005 + 1e-9
CDEG_RAD = math.radians(0.005) + 1e-12
SPEED_MPS = 0.005 + 1e-9
FLOAT32_RAD = 1e-6
UTC_S = 1e-6


def decode(packet: bytes, decoder: MavlinkDecoder | None = None) -> list:
    return [r.item for r in (decoder or MavlinkDecoder()).decode_datagram(packet)]


def angle_diff(a: float, b: float) -> float:
    return abs(math.remainder(a - b, 2.0 * math.pi))


# --------------------------------------------------------------------------------------------
# round trips
# --------------------------------------------------------------------------------------------

lat = st.floats(-90.0, 90.0)
lon = st.floats(-180.0, 180.0)
heading = st.floats(0.0, 2 * math.pi, exclude_max=True)


@given(lat, lon, st.sampled_from([FixQuality.GPS, FixQuality.DGPS, FixQuality.RTK_FLOAT, FixQuality.RTK_FIXED,
                                  FixQuality.MANUAL]),
       st.floats(-500.0, 5000.0), st.floats(0.0, 50.0), st.integers(0, 99), st.floats(0.0, 86399.999999),
       heading, st.floats(0.0, 100.0), heading)
@PROPERTY
def test_gps_raw_int_round_trip(lat_deg: float, lon_deg: float, quality: FixQuality, alt_m: float, hdop: float,
                                satellites: int, utc_s: float, course_rad: float, speed_mps: float,
                                yaw_rad: float) -> None:
    assume(round(lat_deg * 1e7) != 0 or round(lon_deg * 1e7) != 0)  # (0, 0) is no position (tested below)
    sent = PositionFix(lat_deg, lon_deg, quality, utc_time_s=utc_s, num_satellites=satellites, hdop=hdop,
                       altitude_m=alt_m)
    packet = MavlinkEncoder(3, 1).gps_raw_int(sent, course=CourseOverGround(course_rad, speed_mps),
                                              heading=Heading(yaw_rad))
    fix, cog, yaw = decode(packet)
    assert isinstance(fix, PositionFix) and fix.quality == quality and fix.num_satellites == satellites
    assert abs(fix.lat_deg - lat_deg) <= LATLON_DEG and abs(fix.lon_deg - lon_deg) <= LATLON_DEG
    assert abs(fix.altitude_m - alt_m) <= ALT_M and abs(fix.hdop - hdop) <= HDOP
    assert fix.utc_time_s is not None and abs(fix.utc_time_s - utc_s) <= UTC_S
    assert isinstance(cog, CourseOverGround) and angle_diff(cog.course_rad, course_rad) <= CDEG_RAD
    assert abs(cog.speed_mps - speed_mps) <= SPEED_MPS
    assert isinstance(yaw, Heading) and angle_diff(yaw.heading_rad, yaw_rad) <= CDEG_RAD
    assert 0.0 <= yaw.heading_rad < 2 * math.pi


@given(lat, lon, st.floats(-500.0, 5000.0), heading, st.floats(1.0, 20.0), heading)
@PROPERTY
def test_global_position_int_round_trip(lat_deg: float, lon_deg: float, alt_m: float, hdg_rad: float,
                                        speed_mps: float, course_rad: float) -> None:
    assume(round(lat_deg * 1e7) != 0 or round(lon_deg * 1e7) != 0)  # 0/0 means "no position yet" (tested below)
    velocity = (speed_mps * math.cos(course_rad), speed_mps * math.sin(course_rad), 0.0)
    packet = MavlinkEncoder(3, 1).global_position_int(PositionFix(lat_deg, lon_deg, FixQuality.GPS, altitude_m=alt_m),
                                                      heading=Heading(hdg_rad), velocity_ned_mps=velocity)
    fix, hdg, cog = decode(packet)
    assert isinstance(fix, PositionFix) and abs(fix.lat_deg - lat_deg) <= LATLON_DEG
    assert abs(fix.lon_deg - lon_deg) <= LATLON_DEG and abs(fix.altitude_m - alt_m) <= ALT_M
    assert isinstance(hdg, Heading) and angle_diff(hdg.heading_rad, hdg_rad) <= CDEG_RAD
    # vx, vy are whole cm/s: the course error is at most atan(|δv| / v)
    assert abs(cog.speed_mps - speed_mps) <= SPEED_MPS * math.sqrt(2)
    assert angle_diff(cog.course_rad, course_rad) <= SPEED_MPS * math.sqrt(2) / speed_mps + 1e-9


@given(st.floats(-math.pi, math.pi), st.floats(-math.pi / 2, math.pi / 2), st.floats(-math.pi, math.pi),
       st.floats(-2.0, 2.0))
@PROPERTY
def test_attitude_round_trip(roll_rad: float, pitch_rad: float, yaw_rad: float, rate_radps: float) -> None:
    packet = MavlinkEncoder(3, 1).attitude(Attitude(roll_rad, pitch_rad, yaw_rad), rate=RateOfTurn(rate_radps))
    att, hdg, rot = decode(packet)
    assert abs(att.roll_rad - roll_rad) <= FLOAT32_RAD and abs(att.pitch_rad - pitch_rad) <= FLOAT32_RAD
    assert angle_diff(att.yaw_rad, yaw_rad) <= FLOAT32_RAD and -math.pi < att.yaw_rad <= math.pi
    assert angle_diff(hdg.heading_rad, yaw_rad) <= FLOAT32_RAD and 0.0 <= hdg.heading_rad < 2 * math.pi
    assert isinstance(rot, RateOfTurn) and abs(rot.rate_radps - rate_radps) <= FLOAT32_RAD


@given(st.integers(1, 255), st.integers(0, 255))
@PROPERTY
def test_heartbeat_is_a_surface_boat_with_a_generic_autopilot(system_id: int, component_id: int) -> None:
    packet = MavlinkEncoder(system_id, component_id).heartbeat()
    (beat,) = decode(packet)
    assert beat == LinkHeartbeat(system_id, component_id, mavlink2.MAV_TYPE_SURFACE_BOAT)
    raw = mavlink2.MAVLink(None).parse_buffer(packet)[0]
    assert raw.autopilot == mavlink2.MAV_AUTOPILOT_GENERIC and packet[0] == mavlink2.PROTOCOL_MARKER_V2


def test_encoder_refuses_what_mavlink_cannot_say() -> None:
    with pytest.raises(ValueError, match="SIMULATION"):
        MavlinkEncoder().gps_raw_int(PositionFix(1.0, 1.0, FixQuality.SIMULATION))
    with pytest.raises(ValueError, match="system_id"):
        MavlinkEncoder(0, 1)


# --------------------------------------------------------------------------------------------
# validity
# --------------------------------------------------------------------------------------------

@pytest.mark.parametrize(("fix_type", "quality"), [
    (0, None), (1, None), (2, FixQuality.GPS), (3, FixQuality.GPS), (4, FixQuality.DGPS), (5, FixQuality.RTK_FLOAT),
    (6, FixQuality.RTK_FIXED), (7, FixQuality.MANUAL), (8, FixQuality.DGPS), (9, None),
])
def test_gps_fix_type(fix_type: int, quality: FixQuality | None) -> None:
    packet = MavlinkEncoder().gps_raw_int(PositionFix(10.0, 20.0, FixQuality.GPS), fix_type=fix_type)
    (item,) = decode(packet)
    if quality is None:
        assert isinstance(item, Rejected) and item.reason == "invalid_fix"
    else:
        assert isinstance(item, PositionFix) and item.quality == quality


def test_no_fix_and_unknown_fields() -> None:
    (item,) = decode(MavlinkEncoder().gps_raw_int(None))
    assert isinstance(item, Rejected) and item.reason == "invalid_fix"
    (fix,) = decode(MavlinkEncoder().gps_raw_int(PositionFix(10.0, 20.0, FixQuality.GPS)))
    assert fix.hdop is None and fix.num_satellites is None and fix.utc_time_s is None  # eph 65535, 255, no time


def test_time_since_boot_is_not_a_utc_time() -> None:
    (fix,) = decode(MavlinkEncoder().gps_raw_int(PositionFix(10.0, 20.0, FixQuality.GPS), time_usec=123_456_789))
    assert fix.utc_time_s is None


def test_gps_yaw_not_available() -> None:
    encoder = MavlinkEncoder()
    message = encoder._mav.gps_raw_int_encode(0, 3, 100_000_000, 200_000_000, 0, 65535, 65535, 65535, 65535, 255,
                                              yaw=65535)
    fix, rejected = decode(encoder._pack(message))
    assert isinstance(fix, PositionFix) and rejected.reason == "not_available"


def test_global_position_without_position_or_heading() -> None:
    (item,) = decode(MavlinkEncoder().global_position_int(None))
    assert isinstance(item, Rejected) and item.reason == "not_available"
    items = decode(MavlinkEncoder().global_position_int(PositionFix(10.0, 20.0, FixQuality.GPS)))
    assert [type(i) for i in items] == [PositionFix, CourseOverGround]  # hdg 65535: no heading
    assert items[1].course_rad is None and items[1].speed_mps == 0.0


def test_attitude_nan_is_missing_never_a_number() -> None:
    att, rot = decode(MavlinkEncoder().attitude(Attitude(0.1, None, None), rate=RateOfTurn(0.01)))
    assert att.pitch_rad is None and att.yaw_rad is None and isinstance(rot, RateOfTurn)
    (item,) = decode(MavlinkEncoder().attitude(None))
    assert isinstance(item, Rejected) and item.reason == "not_available"
    packet = MavlinkEncoder()._pack(MavlinkEncoder()._mav.attitude_encode(0, math.inf, 0.0, math.inf, 0, 0, math.nan))
    (att,) = decode(packet)
    assert att.roll_rad is None and att.yaw_rad is None and att.pitch_rad == 0.0


def test_a_fix_at_zero_zero_is_no_position() -> None:
    """Receivers and autopilots send lat = lon = 0 before they have a position, whatever fix_type says."""
    encoder = MavlinkEncoder()
    (item,) = decode(encoder._pack(encoder._mav.gps_raw_int_encode(0, 3, 0, 0, 0, 120, 65535, 65535, 65535, 9)))
    assert isinstance(item, Rejected) and item.reason == "not_available"


@pytest.mark.parametrize(("fields", "what"), [
    ((0.0, 0.0, 4.0, 0.0, 0.0, 0.0), "yaw"),           # 4 rad is no Euler angle: not wrapped into a heading
    ((0.0, 0.0, -100.0, 0.0, 0.0, 0.0), "yaw"),
    ((3.5, 0.0, 1.0, 0.0, 0.0, 0.0), "roll"),
    ((0.0, 1.7, 1.0, 0.0, 0.0, 0.0), "pitch"),
    ((0.0, 0.0, 1.0, 0.0, 0.0, 1e30), "rate"),
])
def test_attitude_out_of_range_is_rejected_whole(fields: tuple[float, ...], what: str) -> None:
    encoder = MavlinkEncoder()
    (item,) = decode(encoder._pack(encoder._mav.attitude_encode(0, *fields)))
    assert isinstance(item, Rejected) and item.reason == "out_of_range", what


@pytest.mark.parametrize(("alt_mm", "eph", "vel", "satellites"), [
    (2**31 - 1, 120, 100, 9),     # altitude 2147 km
    (0, 60000, 100, 9),           # HDOP 600
    (0, 120, 65534, 9),           # 655 m/s
    (0, 120, 100, 200),           # 200 satellites used
])
def test_gps_raw_int_out_of_range_is_rejected(alt_mm: int, eph: int, vel: int, satellites: int) -> None:
    encoder = MavlinkEncoder()
    packet = encoder._pack(encoder._mav.gps_raw_int_encode(0, 3, 100_000_000, 200_000_000, alt_mm, eph, 65535, vel,
                                                           1000, satellites))
    (item,) = decode(packet)
    assert isinstance(item, Rejected) and item.reason == "out_of_range"


def test_datagram_accounting() -> None:
    encoder, decoder = MavlinkEncoder(), MavlinkDecoder()
    good = encoder.heartbeat()
    bad_crc = bytearray(encoder.heartbeat())
    bad_crc[-1] ^= 0xFF
    other = encoder._pack(encoder._mav.system_time_encode(0, 0))
    items = decode(b"\x00\x01" + good + bytes(bad_crc) + other + good[:7], decoder)
    assert [i.reason if isinstance(i, Rejected) else type(i).__name__ for i in items] == [
        "garbage", "LinkHeartbeat", "checksum", "truncated"]
    c = decoder.counters
    # packets = what the parser delimited (garbage stretch included); the cut-off tail is only a reject
    assert (c["messages"], c["rejected"], c["ignored"], c["packets"]) == (1, 3, 1, 4)
    assert decode(good, decoder)[0] == LinkHeartbeat(1, 1, mavlink2.MAV_TYPE_SURFACE_BOAT), "no state leaks"


def test_mavlink1_packets_are_accepted_without_signing() -> None:
    mav1 = mavlink1.MAVLink(None, 4, 1)
    packet = mav1.heartbeat_encode(mavlink1.MAV_TYPE_SURFACE_BOAT, 0, 0, 0, 4).pack(mav1)
    assert decode(packet) == [LinkHeartbeat(4, 1, mavlink1.MAV_TYPE_SURFACE_BOAT)]
    item = decode(packet, MavlinkDecoder(KEY))[0]
    assert isinstance(item, Rejected) and item.reason == "unsigned"


# --------------------------------------------------------------------------------------------
# signing
# --------------------------------------------------------------------------------------------

def signed_encoder(key: bytes = KEY, system_id: int = 1, t_s: float = NOW_S) -> MavlinkEncoder:
    return MavlinkEncoder(system_id, 1, signing_key=key, unix_clock=lambda: t_s)


def test_signed_packets_are_accepted_and_the_rest_rejected_and_counted() -> None:
    decoder = MavlinkDecoder(KEY, signing_time_s=NOW_S)
    packet = signed_encoder().heartbeat()
    assert isinstance(decode(packet, decoder)[0], LinkHeartbeat)
    cases = {
        "unsigned": MavlinkEncoder(2, 1).heartbeat(),
        "wrong key": signed_encoder(bytes(32), system_id=3).heartbeat(),
        "replay": packet,
        "tampered": packet[:-1] + bytes([packet[-1] ^ 1]),
        "old stream": signed_encoder(system_id=5, t_s=NOW_S - 120.0).heartbeat(),
    }
    reasons = {name: decode(p, decoder)[0].reason for name, p in cases.items()}
    assert reasons == {"unsigned": "unsigned", "wrong key": "bad_signature", "replay": "bad_signature",
                       "tampered": "bad_signature", "old stream": "bad_signature"}
    assert decoder.counters["rejected.unsigned"] == 1 and decoder.counters["rejected.bad_signature"] == 4


def test_a_forged_packet_does_not_block_the_genuine_stream() -> None:
    decoder = MavlinkDecoder(KEY, signing_time_s=NOW_S)
    encoder = signed_encoder()
    genuine = encoder.heartbeat()
    forged = bytearray(encoder.heartbeat())  # a later timestamp, signature broken
    forged[-1] ^= 0xFF
    assert decode(bytes(forged), decoder)[0].reason == "bad_signature"
    assert isinstance(decode(genuine, decoder)[0], LinkHeartbeat)


def test_without_a_key_signed_packets_are_read() -> None:
    assert isinstance(decode(signed_encoder().heartbeat())[0], LinkHeartbeat)


@pytest.mark.parametrize("bad", ["00" * 31, "zz" * 32, b"\x00" * 33])
def test_signing_key_must_be_32_bytes(bad: str | bytes) -> None:
    with pytest.raises(ValueError, match="signing key"):
        parse_signing_key(bad)
    assert parse_signing_key(KEY.hex()) == KEY


# --------------------------------------------------------------------------------------------
# heartbeat monitor
# --------------------------------------------------------------------------------------------

def test_heartbeat_loss_after_five_silent_seconds_and_recovery() -> None:
    monitor = HeartbeatMonitor(timeout_s=5.0, start_t_s=0.0)
    peer = (1, 1)
    change = monitor.beat(peer, 1.0)
    assert change is not None and change.connected and monitor.connected(peer)
    for t in (2.0, 3.0, 4.0):
        assert monitor.beat(peer, t) is None
    assert monitor.check(9.0) == [] and monitor.connected(peer)  # exactly 5 s: not yet
    (lost,) = monitor.check(9.01)
    assert lost.key == peer and not lost.connected and not monitor.connected(peer)
    assert monitor.check(20.0) == []  # reported once
    back = monitor.beat(peer, 21.0)
    assert back is not None and back.connected and back.detail == "heartbeat resumed"


def test_silence_from_the_start_is_reported_once() -> None:
    monitor = HeartbeatMonitor(timeout_s=5.0, start_t_s=100.0)
    assert monitor.check(104.0) == []
    (change,) = monitor.check(105.5)
    assert change.key is None and not change.connected
    assert monitor.check(200.0) == []


# --------------------------------------------------------------------------------------------
# tlog
# --------------------------------------------------------------------------------------------

def _tlog(packets: list[bytes], t0_us: int = 1_700_000_000_000_000) -> bytes:
    return b"".join(struct.pack(">Q", t0_us + 100_000 * i) + p for i, p in enumerate(packets))


def test_decode_tlog(tmp_path: Path) -> None:
    encoder = MavlinkEncoder(9, 1)
    fix = PositionFix(59.9, 10.7, FixQuality.RTK_FIXED, utc_time_s=43200.5, num_satellites=20, hdop=0.6,
                      altitude_m=1.0)
    first = _tlog([encoder.heartbeat(), encoder.gps_raw_int(fix)])
    second = _tlog([encoder.attitude(Attitude(0.0, 0.0, 1.0), rate=RateOfTurn(0.0)), encoder.gps_raw_int(None)],
                   t0_us=1_700_000_000_300_000)
    path = tmp_path / "flight.tlog"
    path.write_bytes(first + b"\x55" * 17 + second + struct.pack(">Q", 1_700_000_000_900_000) + b"\xfd\x1e")
    stats: dict[str, int] = {}
    records = list(decode_tlog(path, stats))
    assert stats["records"] == 4 and stats["skipped"] == 2 and stats["messages"] == 5 and stats["rejected"] == 1
    for record in records:
        json.dumps(record)
    summary = [(r.get("kind") or "rejected:" + r["rejected"], r.get("msg")) for r in records]
    assert summary == [("heartbeat", "HEARTBEAT"), ("position", "GPS_RAW_INT"), ("rejected:garbage", None),
                       ("attitude", "ATTITUDE"), ("heading", "ATTITUDE"), ("rate_of_turn", "ATTITUDE"),
                       ("rejected:invalid_fix", "GPS_RAW_INT"), ("rejected:truncated", None)]
    position = records[1]
    assert position["source"] == "mav:9/1" and position["quality"] == "rtk_fixed"
    assert position["sample_time"] == pytest.approx(43200.5, abs=1e-6) and position["t_s"] == pytest.approx(1.7e9 + 0.1)
    assert records[2]["offset"] == len(first) and records[3]["offset"] == len(first) + 17


def test_decode_tlog_with_signing_rejects_unsigned(tmp_path: Path) -> None:
    path = tmp_path / "x.tlog"
    path.write_bytes(_tlog([MavlinkEncoder().heartbeat(), signed_encoder().heartbeat()]))
    records = list(decode_tlog(path.read_bytes(), signing_key=KEY))
    assert [r.get("rejected", r.get("kind")) for r in records] == ["unsigned", "heartbeat"]
