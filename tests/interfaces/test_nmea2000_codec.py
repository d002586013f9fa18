"""NMEA 2000 codec: identifiers, round trips of every PGN the emulator sends, validity rules, fast packet."""

from __future__ import annotations

import math
import struct

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from nmea2000 import _canboat as canboat
from nmea2000 import backend

from interfaces.messages import (
    Attitude,
    CourseOverGround,
    FixQuality,
    Heading,
    LinkHeartbeat,
    PositionFix,
    RateOfTurn,
    Rejected,
    Wind,
)
from interfaces.nmea2000.codec import (
    FAST_PACKET_PGNS,
    PGN_ATTITUDE,
    PGN_COG_SOG_RAPID,
    PGN_GNSS_POSITION,
    PGN_MAGNETIC_VARIATION,
    PGN_POSITION_RAPID,
    PGN_RATE_OF_TURN,
    PGN_VESSEL_HEADING,
    PGN_WIND,
    FastPacketAssembler,
    N2kDecoder,
    N2kEncoder,
    fast_packet_frame_count,
    make_can_id,
    parse_can_id,
)

PROPERTY = settings(max_examples=150, deadline=None)

# Half a resolution step of each field (the encoder rounds to nearest), plus float noise.
LAT_RAPID_DEG = 0.5e-7 + 1e-12
LAT_FULL_DEG = 1e-12  # 1e-16° steps: float64 representation dominates
ANGLE_RAD = 0.5e-4 + 1e-12
ROT_RADPS = 0.5 * 3.125e-8 + 1e-15
SPEED_MPS = 0.005 + 1e-9
TIME_S = 0.5e-4 + 1e-9
ALT_M = 0.5e-6 + 1e-9
HDOP = 0.005 + 1e-9


def decode_all(decoder: N2kDecoder, frames: list[tuple[int, bytes]], t_s: float = 0.0) -> list:
    out = []
    for can_id, data in frames:
        out.extend(decoder.decode_frame(can_id, data, t_s))
    return out


def only_item(decoder: N2kDecoder, frames: list[tuple[int, bytes]], t_s: float = 0.0):
    results = decode_all(decoder, frames, t_s)
    assert len(results) == 1, results
    return results[0].item


def angle_diff(a: float, b: float) -> float:
    return abs(math.remainder(a - b, 2.0 * math.pi))


# --------------------------------------------------------------------------------------------
# identifiers
# --------------------------------------------------------------------------------------------

@given(priority=st.integers(0, 7), edp=st.integers(0, 1), dp=st.integers(0, 1), pf=st.integers(0, 255),
       ps=st.integers(0, 255), source=st.integers(0, 255))
@PROPERTY
def test_can_id_follows_the_j1939_layout(priority: int, edp: int, dp: int, pf: int, ps: int, source: int) -> None:
    can_id = priority << 26 | edp << 25 | dp << 24 | pf << 16 | ps << 8 | source
    header = parse_can_id(can_id)
    page = edp << 9 | dp << 8 | pf
    if pf < 240:  # PDU1: PS is the destination address
        assert header.pgn == page << 8 and header.destination == ps
    else:  # PDU2: PS is the group extension, broadcast
        assert header.pgn == page << 8 | ps and header.destination == 255
    assert (header.priority, header.source) == (priority, source)
    assert make_can_id(*header) == can_id


@pytest.mark.parametrize("bad", [-1, 1 << 29, "0x1"])
def test_parse_can_id_refuses_what_is_not_29_bits(bad: object) -> None:
    with pytest.raises(ValueError, match="29-bit"):
        parse_can_id(bad)  # type: ignore[arg-type]


def test_make_can_id_refuses_out_of_range_fields() -> None:
    with pytest.raises(ValueError, match="priority=8"):
        make_can_id(8, PGN_POSITION_RAPID, 1)


# --------------------------------------------------------------------------------------------
# round trips (what the emulator sends decodes to the same values within the wire resolution)
# --------------------------------------------------------------------------------------------

lat = st.floats(-90.0, 90.0)
lon = st.floats(-180.0, 180.0)
source = st.integers(0, 251)


@given(lat, lon, source)
@PROPERTY
def test_position_rapid_round_trip(lat_deg: float, lon_deg: float, address: int) -> None:
    frames = N2kEncoder(address).position_rapid(PositionFix(lat_deg, lon_deg, FixQuality.GPS))
    assert len(frames) == 1 and parse_can_id(frames[0][0]).source == address
    fix = only_item(N2kDecoder(), frames)
    assert isinstance(fix, PositionFix)
    assert abs(fix.lat_deg - lat_deg) <= LAT_RAPID_DEG and abs(fix.lon_deg - lon_deg) <= LAT_RAPID_DEG


@given(lat, lon, st.sampled_from([q for q in FixQuality if q != FixQuality.INVALID]),
       st.floats(0.0, 86399.999), st.integers(0, 99), st.floats(0.0, 50.0), st.floats(-1000.0, 10000.0),
       st.integers(0, 30_000))
@PROPERTY
def test_gnss_position_round_trip(lat_deg: float, lon_deg: float, quality: FixQuality, utc_s: float, svs: int,
                                  hdop: float, alt_m: float, date_days: int) -> None:
    sent = PositionFix(lat_deg, lon_deg, quality, utc_time_s=utc_s, num_satellites=svs, hdop=hdop, altitude_m=alt_m)
    frames = N2kEncoder(7).gnss_position(sent, date_days=date_days)
    assert len(frames) == fast_packet_frame_count(43) == 7
    fix = only_item(N2kDecoder(), frames)
    assert isinstance(fix, PositionFix)
    assert abs(fix.lat_deg - lat_deg) <= LAT_FULL_DEG and abs(fix.lon_deg - lon_deg) <= LAT_FULL_DEG
    assert fix.quality == quality and fix.num_satellites == svs
    assert fix.utc_time_s is not None and abs(fix.utc_time_s - utc_s) <= TIME_S
    assert fix.hdop is not None and abs(fix.hdop - hdop) <= HDOP
    assert fix.altitude_m is not None and abs(fix.altitude_m - alt_m) <= ALT_M


@given(st.floats(0.0, 2.0 * math.pi, exclude_max=True), st.floats(0.0, 514.0))
@PROPERTY
def test_cog_sog_round_trip(course_rad: float, speed_mps: float) -> None:
    cog = only_item(N2kDecoder(), N2kEncoder(3).cog_sog(CourseOverGround(course_rad, speed_mps)))
    assert isinstance(cog, CourseOverGround)
    assert cog.course_rad is not None and angle_diff(cog.course_rad, course_rad) <= ANGLE_RAD
    assert 0.0 <= cog.course_rad < 2.0 * math.pi
    assert cog.speed_mps is not None and abs(cog.speed_mps - speed_mps) <= SPEED_MPS


@given(st.floats(0.0, 2.0 * math.pi, exclude_max=True))
@PROPERTY
def test_true_heading_round_trip(heading_rad: float) -> None:
    heading = only_item(N2kDecoder(), N2kEncoder(3).heading(Heading(heading_rad)))
    assert isinstance(heading, Heading)
    assert angle_diff(heading.heading_rad, heading_rad) <= ANGLE_RAD
    assert 0.0 <= heading.heading_rad < 2.0 * math.pi


@given(st.floats(-3.0, 3.0))
@PROPERTY
def test_rate_of_turn_round_trip(rate_radps: float) -> None:
    rot = only_item(N2kDecoder(), N2kEncoder(3).rate_of_turn(RateOfTurn(rate_radps)))
    assert isinstance(rot, RateOfTurn) and abs(rot.rate_radps - rate_radps) <= ROT_RADPS


@given(st.floats(-math.pi, math.pi), st.floats(-math.pi / 2, math.pi / 2), st.floats(-math.pi, math.pi))
@PROPERTY
def test_attitude_round_trip(roll_rad: float, pitch_rad: float, yaw_rad: float) -> None:
    att = only_item(N2kDecoder(), N2kEncoder(3).attitude(Attitude(roll_rad, pitch_rad, yaw_rad)))
    assert isinstance(att, Attitude)
    assert att.roll_rad is not None and abs(att.roll_rad - roll_rad) <= ANGLE_RAD
    assert att.pitch_rad is not None and abs(att.pitch_rad - pitch_rad) <= ANGLE_RAD
    assert att.yaw_rad is not None and angle_diff(att.yaw_rad, yaw_rad) <= ANGLE_RAD


@given(st.floats(0.0, 100.0), st.floats(0.0, 2.0 * math.pi, exclude_max=True), st.sampled_from(["true", "apparent"]))
@PROPERTY
def test_wind_round_trip(speed_mps: float, angle_rad: float, reference: str) -> None:
    wind = only_item(N2kDecoder(), N2kEncoder(3).wind(Wind(speed_mps, angle_rad, reference)))
    assert isinstance(wind, Wind) and wind.reference == reference
    assert abs(wind.speed_mps - speed_mps) <= SPEED_MPS and angle_diff(wind.angle_rad, angle_rad) <= ANGLE_RAD


def test_encode_dispatches_on_message_type() -> None:
    encoder = N2kEncoder(9)
    pgns = {parse_can_id(encoder.encode(m)[0][0]).pgn for m in (
        PositionFix(1.0, 2.0, FixQuality.GPS), CourseOverGround(1.0, 1.0), Heading(1.0), RateOfTurn(0.1),
        Attitude(0.0, 0.0, 0.0), Wind(1.0, 1.0, "true"))}
    assert pgns == {PGN_GNSS_POSITION, PGN_COG_SOG_RAPID, PGN_VESSEL_HEADING, PGN_RATE_OF_TURN, PGN_ATTITUDE, PGN_WIND}
    with pytest.raises(TypeError, match="LinkHeartbeat"):
        encoder.encode(LinkHeartbeat(1, 1))


def test_encoder_refuses_unrepresentable_values() -> None:
    with pytest.raises(ValueError, match="Latitude"):
        N2kEncoder(1).position_rapid(PositionFix(95.0, 0.0, FixQuality.GPS))
    with pytest.raises(ValueError, match="source_address"):
        N2kEncoder(252)
    with pytest.raises(ValueError, match="wind reference"):
        N2kEncoder(1).wind(Wind(1.0, 1.0, "magnetic"))


# --------------------------------------------------------------------------------------------
# validity: not available / error values, references, methods
# --------------------------------------------------------------------------------------------

def single(pgn: int, payload: bytes, address: int = 5) -> tuple[int, bytes]:
    return make_can_id(2, pgn, address), payload


@pytest.mark.parametrize(("lat_raw", "lon_raw"), [
    (0x7FFFFFFF, 0x7FFFFFFF),  # not available
    (0x7FFFFFFE, 0x01000000),  # error
    (0x01000000, 0x7FFFFFFD),  # reserved
])
def test_position_rapid_not_available_is_rejected_not_a_number(lat_raw: int, lon_raw: int) -> None:
    item = only_item(N2kDecoder(), [single(PGN_POSITION_RAPID, struct.pack("<ii", lat_raw, lon_raw))])
    assert isinstance(item, Rejected) and item.reason == "not_available"


def test_position_out_of_range_is_rejected() -> None:
    item = only_item(N2kDecoder(), [single(PGN_POSITION_RAPID, struct.pack("<ii", 950_000_000, 0))])
    assert isinstance(item, Rejected) and item.reason == "out_of_range"


def test_truncated_single_frame_is_rejected_instead_of_half_decoded() -> None:
    # canboat alone decodes these two bytes into latitude 5.13e-05°
    decoder = N2kDecoder()
    item = only_item(decoder, [single(PGN_POSITION_RAPID, b"\x01\x02")])
    assert isinstance(item, Rejected) and item.reason == "truncated"
    assert decoder.counters["rejected.truncated"] == 1


@pytest.mark.parametrize(("method", "integrity", "valid"), [
    (0, 0, False), (1, 0, True), (4, 1, True), (8, 0, True), (9, 0, False), (14, 0, False), (15, 0, False),
    (1, 2, False), (1, 3, False),
])
def test_gnss_method_and_integrity_decide_validity(method: int, integrity: int, valid: bool) -> None:
    fix = PositionFix(10.0, 20.0, FixQuality.GPS, utc_time_s=1.0)
    item = only_item(N2kDecoder(), N2kEncoder(4).gnss_position(fix, method=method, integrity=integrity))
    if valid:
        assert isinstance(item, PositionFix) and item.quality == FixQuality(method)
    else:
        assert isinstance(item, Rejected) and item.reason == "invalid_fix"


def test_no_gnss_fix_is_rejected() -> None:
    item = only_item(N2kDecoder(), N2kEncoder(4).gnss_position(None))
    assert isinstance(item, Rejected) and item.reason == "invalid_fix"


def test_rapid_position_takes_quality_and_validity_from_the_latest_gnss_position() -> None:
    decoder, encoder = N2kDecoder(fix_state_max_age_s=3.0), N2kEncoder(4)
    rapid = encoder.position_rapid(PositionFix(10.0, 20.0, FixQuality.GPS))
    item = only_item(decoder, rapid, t_s=0.0)
    assert isinstance(item, PositionFix) and item.quality == FixQuality.GPS and decoder.counters["assumed_quality"] == 1
    decode_all(decoder, encoder.gnss_position(PositionFix(10.0, 20.0, FixQuality.RTK_FIXED)), t_s=1.0)
    item = only_item(decoder, rapid, t_s=1.1)
    assert isinstance(item, PositionFix) and item.quality == FixQuality.RTK_FIXED
    decode_all(decoder, encoder.gnss_position(None), t_s=2.0)
    item = only_item(decoder, rapid, t_s=2.1)
    assert isinstance(item, Rejected) and item.reason == "invalid_fix"
    item = only_item(decoder, rapid, t_s=5.5)  # the invalid 129029 is older than 3 s: no longer applies
    assert isinstance(item, PositionFix) and item.quality == FixQuality.GPS
    other = only_item(decoder, N2kEncoder(5).position_rapid(PositionFix(1.0, 2.0, FixQuality.GPS)), t_s=2.2)
    assert isinstance(other, PositionFix), "the state is per source"


def test_magnetic_heading_needs_variation() -> None:
    encoder = N2kEncoder(6)
    item = only_item(N2kDecoder(), encoder.vessel_heading(1.0, reference="magnetic"))
    assert isinstance(item, Rejected) and item.reason == "magnetic_heading"
    item = only_item(N2kDecoder(), encoder.vessel_heading(1.0, reference="magnetic", deviation_rad=-0.02,
                                                          variation_rad=0.1))
    assert isinstance(item, Heading) and abs(item.heading_rad - 1.08) <= 3 * ANGLE_RAD
    item = only_item(N2kDecoder(), encoder.vessel_heading(6.2, reference="magnetic", variation_rad=0.2))
    assert isinstance(item, Heading) and angle_diff(item.heading_rad, 6.4) <= 2 * ANGLE_RAD
    assert 0.0 <= item.heading_rad < 2.0 * math.pi


@pytest.mark.parametrize(("heading_raw", "reference", "reason"), [
    (0xFFFF, 0, "not_available"),  # heading not available
    (0xFFFE, 0, "not_available"),  # heading error
    (0xFF00, 0, "out_of_range"),  # 6.528 rad > 2π
    (10000, 2, "not_available"),  # reference "error"
    (10000, 3, "not_available"),  # reference not available
])
def test_vessel_heading_invalid_values(heading_raw: int, reference: int, reason: str) -> None:
    payload = struct.pack("<BHhhB", 0, heading_raw, 0x7FFF, 0x7FFF, 0xFC | reference)
    item = only_item(N2kDecoder(), [single(PGN_VESSEL_HEADING, payload)])
    assert isinstance(item, Rejected) and item.reason == reason


def test_magnetic_course_is_not_a_course() -> None:
    payload = struct.pack("<BBHHH", 0, 0xFC | 1, 10000, 150, 0xFFFF)
    item = only_item(N2kDecoder(), [single(PGN_COG_SOG_RAPID, payload)])
    assert isinstance(item, CourseOverGround) and item.course_rad is None and abs(item.speed_mps - 1.5) < 1e-9
    payload = struct.pack("<BBHHH", 0, 0xFC | 0, 0xFFFF, 0xFFFF, 0xFFFF)
    item = only_item(N2kDecoder(), [single(PGN_COG_SOG_RAPID, payload)])
    assert isinstance(item, Rejected) and item.reason == "not_available"


@pytest.mark.parametrize(("reference", "expected"), [(0, "true"), (2, "apparent"), (1, None), (3, None), (4, None)])
def test_wind_references(reference: int, expected: str | None) -> None:
    payload = struct.pack("<BHHB", 0, 500, 10000, 0xF8 | reference) + b"\xff\xff"
    item = only_item(N2kDecoder(), [single(PGN_WIND, payload)])
    if expected is None:
        assert isinstance(item, Rejected) and item.reason == "unsupported_reference"
    else:
        assert isinstance(item, Wind) and item.reference == expected and abs(item.speed_mps - 5.0) < 1e-9


def test_rate_and_attitude_not_available() -> None:
    encoder = N2kEncoder(8)
    item = only_item(N2kDecoder(), encoder.rate_of_turn(None))
    assert isinstance(item, Rejected) and item.reason == "not_available"
    item = only_item(N2kDecoder(), encoder.attitude(None))
    assert isinstance(item, Rejected) and item.reason == "not_available"
    item = only_item(N2kDecoder(), encoder.attitude(Attitude(0.1, None, None)))
    assert isinstance(item, Attitude) and item.pitch_rad is None and item.yaw_rad is None
    assert abs(item.roll_rad - 0.1) <= ANGLE_RAD


def test_other_pgns_are_ignored_and_counted() -> None:
    decoder = N2kDecoder()
    assert decoder.decode_frame(make_can_id(6, 60928, 1), bytes(8), 0.0) == []  # ISO address claim
    assert decoder.counters["ignored"] == 1 and decoder.counters["rejected"] == 0


# --------------------------------------------------------------------------------------------
# fast packet
# --------------------------------------------------------------------------------------------

FIX_A = PositionFix(63.4305149, 10.3950528, FixQuality.RTK_FIXED, utc_time_s=100.0)
FIX_B = PositionFix(-33.8567844, 151.2152967, FixQuality.DGPS, utc_time_s=200.0)


def test_lost_frame_drops_the_message_and_counts_it() -> None:
    decoder, encoder = N2kDecoder(fast_packet_timeout_s=0.75), N2kEncoder(10)
    frames = encoder.gnss_position(FIX_A)
    assert decode_all(decoder, frames[:2] + frames[3:], t_s=0.0) == []
    assert decoder.assembler.pending == 1
    good = only_item(decoder, encoder.gnss_position(FIX_B), t_s=0.1)  # next message, next sequence id
    assert isinstance(good, PositionFix) and abs(good.lat_deg - FIX_B.lat_deg) < 1e-9
    assert decoder.expire(0.7) == []
    dropped = decoder.expire(0.8)
    assert len(dropped) == 1 and dropped[0].pgn == PGN_GNSS_POSITION and dropped[0].source_address == 10
    assert isinstance(dropped[0].item, Rejected) and dropped[0].item.reason == "truncated_fast_packet"
    assert decoder.counters["rejected.truncated_fast_packet"] == 1 and decoder.assembler.pending == 0


def test_lost_frame_is_found_when_the_sequence_id_comes_round_again() -> None:
    decoder, encoder = N2kDecoder(fast_packet_timeout_s=100.0), N2kEncoder(10)
    frames = encoder.gnss_position(FIX_A)
    decode_all(decoder, frames[:-1])  # last frame lost
    for _ in range(7):  # sequence ids 1..7
        assert isinstance(only_item(decoder, encoder.gnss_position(FIX_B)), PositionFix)
    results = decode_all(decoder, encoder.gnss_position(FIX_A))  # sequence id 0 again
    reasons = [r.item.reason if isinstance(r.item, Rejected) else "ok" for r in results]
    assert reasons == ["truncated_fast_packet", "ok"]


def test_interleaved_sources_both_decode() -> None:
    decoder = N2kDecoder()
    a, b = N2kEncoder(10).gnss_position(FIX_A), N2kEncoder(20).gnss_position(FIX_B)
    results = decode_all(decoder, [frame for pair in zip(a, b, strict=True) for frame in pair])
    by_source = {r.source_address: r.item for r in results}
    assert set(by_source) == {10, 20}
    assert abs(by_source[10].lat_deg - FIX_A.lat_deg) < 1e-9 and abs(by_source[20].lat_deg - FIX_B.lat_deg) < 1e-9


def test_interleaved_sequence_ids_of_one_source_both_decode() -> None:
    decoder, encoder = N2kDecoder(), N2kEncoder(10)
    a, b = encoder.gnss_position(FIX_A), encoder.gnss_position(FIX_B)
    results = decode_all(decoder, [frame for pair in zip(a, b, strict=True) for frame in pair])
    assert sorted(r.item.utc_time_s for r in results) == [100.0, 200.0]


def test_out_of_order_frames_reassemble() -> None:
    rng = np.random.default_rng(7)
    for _ in range(20):
        decoder = N2kDecoder()
        frames = N2kEncoder(10).gnss_position(FIX_A)
        order = rng.permutation(len(frames))
        item = only_item(decoder, [frames[i] for i in order])
        assert isinstance(item, PositionFix) and abs(item.lon_deg - FIX_A.lon_deg) < 1e-9


def test_partial_state_is_bounded() -> None:
    decoder = N2kDecoder(max_partial=16)
    frame0 = N2kEncoder(1).gnss_position(FIX_A)[0][1]
    results = []
    for address in range(100):
        results += decoder.decode_frame(make_can_id(3, PGN_GNSS_POSITION, address), frame0, 0.0)
    assert decoder.assembler.pending == 16
    assert len(results) == 100 - 16 == decoder.counters["rejected.truncated_fast_packet"]


@pytest.mark.parametrize(("data", "why"), [
    (bytes([0x00, 224]) + bytes(6), "length 224"),
    (bytes([0x05]), "1-byte"),
])
def test_bad_fast_packet_frames_are_rejected(data: bytes, why: str) -> None:
    results = N2kDecoder().decode_frame(make_can_id(3, PGN_GNSS_POSITION, 1), data, 0.0)
    assert len(results) == 1 and results[0].item.reason == "bad_fast_packet" and why in results[0].item.detail


def test_frame_index_beyond_the_announced_length_is_rejected() -> None:
    decoder = N2kDecoder()
    can_id = make_can_id(3, PGN_GNSS_POSITION, 1)
    assert decoder.decode_frame(can_id, bytes([0x20, 20]) + bytes(6), 0.0) == []  # seq 1, 20 bytes = 3 frames
    results = decoder.decode_frame(can_id, bytes([0x25]) + bytes(7), 0.0)  # frame 5
    assert [r.item.reason for r in results] == ["bad_fast_packet"]


def test_assembler_alone_joins_payloads_of_any_length() -> None:
    rng = np.random.default_rng(3)
    for length in (1, 6, 7, 13, 14, 100, 223):
        payload = rng.integers(0, 256, length, dtype=np.uint8).tobytes()
        frames = canboat.fast_packet_fragment(5, payload)
        assert len(frames) == fast_packet_frame_count(length)
        assembler = FastPacketAssembler()
        results = [assembler.push(1, PGN_GNSS_POSITION, bytes(f), 0.0) for f in frames]
        assert [r[0] for r in results[:-1]] == [None] * (len(frames) - 1)
        assert results[-1][0] == payload and all(not r[1] for r in results)


def test_only_129029_is_a_fast_packet_here() -> None:
    assert {PGN_GNSS_POSITION} == FAST_PACKET_PGNS


@pytest.mark.parametrize(("pgn", "fields"), [  # wire values (canboat.Raw: the encoder's own range check bypassed)
    (PGN_ATTITUDE, {"yaw": canboat.Raw(32000), "pitch": 0.0, "roll": 0.0}),  # 3.2 rad: not wrapped into a yaw
    (PGN_ATTITUDE, {"yaw": 0.0, "pitch": canboat.Raw(20000), "roll": 0.0}),  # 2 rad
    (PGN_RATE_OF_TURN, {"rate": canboat.Raw(1_920_000_000)}),                # 60 rad/s
    (PGN_COG_SOG_RAPID, {"cogReference": 0, "cog": 1.0, "sog": canboat.Raw(65500)}),  # 655 m/s
    (PGN_WIND, {"windSpeed": canboat.Raw(30000), "windAngle": 1.0, "reference": 2}),  # 300 m/s
    (PGN_GNSS_POSITION, {"latitude": 10.0, "longitude": 20.0, "method": 1, "integrity": 0,
                         "altitude": canboat.Raw(9 * 10**18), "numberOfSvs": 9, "hdop": 1.0}),  # 9e12 m
    (PGN_GNSS_POSITION, {"latitude": 10.0, "longitude": 20.0, "method": 1, "integrity": 0,
                         "hdop": canboat.Raw(-300 & 0xFFFF)}),  # HDOP -3
])
def test_physically_impossible_values_are_out_of_range(pgn: int, fields: dict[str, object]) -> None:
    item = only_item(N2kDecoder(), N2kEncoder(9).frames(pgn, fields))
    assert isinstance(item, Rejected) and item.reason == "out_of_range", item


# --------------------------------------------------------------------------------------------
# magnetic variation (127258, configured) and address claims (60928)


def variation_frame(source: int, variation_rad: float) -> tuple[int, bytes]:
    payload = backend.DATABASE.encode("magneticVariation", {"sid": 1, "source": 0, "variation": variation_rad})
    return (canboat.can_id_compose(7, PGN_MAGNETIC_VARIATION, source, 255), payload)


def magnetic(source: int, heading_rad: float) -> list[tuple[int, bytes]]:
    return N2kEncoder(source).vessel_heading(heading_rad, reference="magnetic")


def test_a_magnetic_heading_takes_the_variation_the_bus_sends_while_it_is_fresh() -> None:
    decoder = N2kDecoder(variation_max_age_s=60.0)
    assert only_item(decoder, magnetic(5, 1.0), t_s=0.0).reason == "magnetic_heading"
    decoder.decode_frame(*variation_frame(30, -0.2), 1.0)
    assert only_item(decoder, magnetic(5, 1.0), t_s=2.0).heading_rad == pytest.approx(0.8, abs=1e-4)
    assert only_item(decoder, magnetic(5, 1.0), t_s=61.5).reason == "magnetic_heading"  # aged out
    assert decoder.counters["variations"] == 1


def test_the_compass_own_variation_first_then_one_sender_kept() -> None:
    decoder = N2kDecoder()
    decoder.decode_frame(*variation_frame(40, 0.10), 0.0)
    decoder.decode_frame(*variation_frame(30, 0.05), 0.1)
    first = only_item(decoder, magnetic(5, 1.0), t_s=0.2).heading_rad
    decoder.decode_frame(*variation_frame(40, 0.10), 0.3)  # the other sender speaks last: no jump
    assert only_item(decoder, magnetic(5, 1.0), t_s=0.4).heading_rad == first == pytest.approx(1.05, abs=1e-4)
    decoder.decode_frame(*variation_frame(5, -0.3), 0.5)  # the compass's own
    assert only_item(decoder, magnetic(5, 1.0), t_s=0.6).heading_rad == pytest.approx(0.7, abs=1e-4)


def test_a_configured_variation_when_the_bus_has_none() -> None:
    decoder = N2kDecoder(variation_rad=0.25)
    assert only_item(decoder, magnetic(5, 1.0)).heading_rad == pytest.approx(1.25, abs=1e-4)
    with pytest.raises(ValueError):
        N2kDecoder(variation_rad=4.0)


def test_address_claims_name_the_source_and_a_new_device_at_an_address_starts_afresh() -> None:
    decoder = N2kDecoder()
    claim = canboat.can_id_compose(6, 60928, 5, 255)
    name_a, name_b = 0xC0320C0029E0F05A, 0xA0000000001E1234
    decoder.decode_frame(claim, name_a.to_bytes(8, "little"), 0.0)
    decoder.decode_frame(*variation_frame(5, 0.3), 0.0)
    assert decoder.name_of(5) == name_a and decoder.address_of(name_a) == 5
    decoder.decode_frame(claim, name_b.to_bytes(8, "little"), 1.0)  # another device now at address 5
    assert decoder.name_of(5) == name_b and decoder.address_of(name_a) is None
    assert decoder.counters["address_changes"] == 1 and decoder.bus_variation(1.0, 5) is None
    decoder.decode_frame(canboat.can_id_compose(6, 60928, 9, 255), name_a.to_bytes(8, "little"), 2.0)
    assert decoder.address_of(name_a) == 9  # the first device came back at another address
    decoder.decode_frame(claim, b"\x00\x01", 3.0)
    assert decoder.counters["bad_address_claim"] == 1 and decoder.name_of(5) == name_b
