"""Property tests of every decode path (hypothesis): no exception escapes, every emitted value is finite
and within physical limits (``physical_range``, this suite's own statement of them).

The paths: the NMEA 0183 stream decoder and its log reader (with capture-time prefixes); NMEA 2000
payloads of every supported PGN, CAN frames (fast packets included) and the log reader of every format;
MAVLink messages with every field drawn over its whole wire type (NaN and ±inf floats included), raw
datagrams and tlogs. Inputs with a *valid* framing (checksum, CRC, length) are drawn as well as random
bytes, so the value checks, not the framing checks, are what is exercised. This is the CI-sized share;
``benchmarks/fuzz_protocols.py`` runs 10⁵ mutated inputs per protocol and prints the counts.
"""

from __future__ import annotations

import base64
import math
import struct

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from nmea2000 import _canboat as canboat
from physical_range import out_of_range

from interfaces.logs import decode_log, decode_nmea0183_log, to_json_line
from interfaces.mavlink.codec import MavlinkDecoder, MavlinkEncoder
from interfaces.messages import Rejected
from interfaces.nmea0183 import Nmea0183Decoder
from interfaces.nmea2000.codec import FAST_PACKET_PGNS, SUPPORTED_PGNS, N2kDecoder
from interfaces.nmea2000.logformats import LOG_FORMATS

FUZZ = settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def assert_clean_messages(items: list[object]) -> None:
    for item in items:
        if not isinstance(item, Rejected):
            assert out_of_range(item) == [], item


def assert_clean_records(records: list[dict[str, object]]) -> None:
    """Log records: finite numbers only, a strict JSON line each, and in-range measurement values."""
    for record in records:
        to_json_line(record)
        for key, value in record.items():
            if isinstance(value, float):
                assert math.isfinite(value), (key, record)
        if "kind" in record:
            assert record.get("lat_deg", 0.0) is None or -90 <= record.get("lat_deg", 0.0) <= 90, record
            for key in ("heading_rad", "course_rad", "angle_rad"):
                assert key not in record or 0.0 <= record[key] <= 2 * math.pi, record
            assert "rate_radps" not in record or abs(record["rate_radps"]) <= math.pi, record
            assert "speed_mps" not in record or 0.0 <= record["speed_mps"] <= 515.0, record


# ----------------------------------------------------------------------------------------------
# NMEA 0183

# numbers as a receiver might write them, and as one gone wrong might: huge, negative, many decimals
NUMBER_TEXT = st.one_of(
    st.floats(allow_nan=False, allow_infinity=False).map(lambda v: f"{v:.{abs(hash(v)) % 9}f}"),
    st.integers(-10**60, 10**60).map(str),
    st.sampled_from(["", "nan", "inf", "-0", ".", "1e5", "A", "V", "N", "S", "M", "T", "R", "E", "W", "K"]),
)
SENTENCE_FIELDS = {"GGA": 14, "RMC": 12, "GNS": 12, "GLL": 7, "GST": 8, "HDT": 2, "THS": 2, "ROT": 2, "MWV": 5}


def nmea(body: str) -> bytes:
    data = body.encode("ascii")
    checksum = 0
    for byte in data:
        checksum ^= byte
    return b"$" + data + b"*%02X\r\n" % checksum


@st.composite
def checksummed_sentences(draw: st.DrawFn) -> bytes:
    """A sentence of a decoded type, every field drawn, with a valid checksum."""
    kind = draw(st.sampled_from(sorted(SENTENCE_FIELDS)))
    fields = draw(st.lists(NUMBER_TEXT, min_size=SENTENCE_FIELDS[kind], max_size=SENTENCE_FIELDS[kind]))
    body = f"GP{kind}," + ",".join(field.replace(",", "").replace("*", "") for field in fields)
    return nmea("".join(ch for ch in body if 32 <= ord(ch) < 127 and ch not in "$!"))


@FUZZ
@given(st.lists(st.one_of(checksummed_sentences(), st.binary(max_size=120)), max_size=8))
def test_nmea0183_stream(chunks: list[bytes]) -> None:
    decoder = Nmea0183Decoder()
    for chunk in chunks:
        assert_clean_messages(decoder.feed(chunk))
    decoder.flush()
    counters = decoder.counters
    assert counters["frames"] == counters["ok"] + counters["ignored"] + counters["rejected"]


@FUZZ
@given(st.lists(st.tuples(st.sampled_from([b"", b"2014-08-01T00:00:00.183000Z ", b"2099-12-31 23:59:60.999,",
                                           b"0000-00-00T99:99:99Z ", b"2014-08-01T00:00:00+99:99 "]),
                          st.one_of(checksummed_sentences(), st.binary(max_size=60))), max_size=6))
def test_nmea0183_log(lines: list[tuple[bytes, bytes]]) -> None:
    assert_clean_records(list(decode_nmea0183_log(b"".join(prefix + line for prefix, line in lines))))


# ----------------------------------------------------------------------------------------------
# NMEA 2000


@FUZZ
@given(st.sampled_from(sorted(SUPPORTED_PGNS)), st.binary(max_size=64), st.integers(0, 255))
def test_nmea2000_payloads(pgn: int, payload: bytes, source: int) -> None:
    assert_clean_messages([N2kDecoder().decode_payload(pgn, payload, source)])


@FUZZ
@given(st.lists(st.tuples(st.sampled_from(sorted(SUPPORTED_PGNS)), st.integers(0, 7), st.integers(0, 3),
                          st.binary(max_size=8)), max_size=30),
       st.floats(0.0, 10.0))
def test_nmea2000_frames(frames: list[tuple[int, int, int, bytes]], dt_s: float) -> None:
    decoder = N2kDecoder()
    for k, (pgn, seq, source, data) in enumerate(frames):
        # few sequence ids, so that frames of one message meet
        frame = bytes([(seq << 5) | (data[0] & 0x1F)]) + data[1:] if pgn in FAST_PACKET_PGNS and data else data
        can_id = canboat.can_id_compose(3, pgn, source, 255)
        assert_clean_messages([r.item for r in decoder.decode_frame(can_id, frame, k * dt_s)])
    assert_clean_messages([r.item for r in decoder.expire(math.inf)])


def candump_line(t: tuple[int, int, int, bytes]) -> str:
    seconds, pgn, source, data = t
    return f"({seconds}.000000) can0 {canboat.can_id_compose(2, pgn, source, 255):08X}#{data.hex()}"


@FUZZ
@given(st.lists(st.one_of(
    st.tuples(st.integers(0, 10**10), st.sampled_from(sorted(SUPPORTED_PGNS)), st.integers(0, 255),
              st.binary(min_size=1, max_size=8)).map(candump_line),
    st.text(max_size=80)), max_size=20))
def test_nmea2000_candump_log(lines: list[str]) -> None:
    assert_clean_records(list(decode_log("nmea2000", "\n".join(lines).encode("utf-8", "replace"))))


def format_line(log_format: str, t: tuple[int, int, int, bytes]) -> str:
    """A line of a text capture format carrying ``data`` for ``pgn`` from ``source`` (values unchecked)."""
    prio, pgn, source, data = t
    can_id = canboat.can_id_compose(prio, pgn, source, 255)
    if log_format == "plain":
        return f"2020-08-22T13:52:36.949Z,{prio},{pgn},{source},255,{len(data)},{','.join(f'{b:02x}' for b in data)}"
    if log_format == "ydwg":
        return f"00:29:58.617 R {can_id:08X} {' '.join(f'{b:02X}' for b in data)}"
    if log_format == "actisense":
        return f"A000057.055 {source:02X}FF{prio:X} {pgn:05X} {data.hex().upper()}"
    if log_format == "ikonvert":
        return f"!PDGY,{pgn},{prio},{source},255,481.706,{base64.b64encode(data).decode()}"
    if log_format == "trc":
        return f"     1)        48.6  Rx     {can_id:08X}  {len(data)}  {' '.join(f'{b:02X}' for b in data)}"
    return f"({t[1]}.000000) can0 {can_id:08X}#{data[:8].hex()}"


@FUZZ
@given(st.sampled_from([f for f in LOG_FORMATS if f != "pcap"]), st.lists(st.one_of(
    st.tuples(st.integers(0, 7), st.sampled_from(sorted(SUPPORTED_PGNS)), st.integers(0, 255),
              st.binary(max_size=48)),
    st.text(max_size=60)), max_size=12))
def test_nmea2000_log_formats(log_format: str, lines: list[tuple[int, int, int, bytes] | str]) -> None:
    text = "\n".join(line if isinstance(line, str) else format_line(log_format, line) for line in lines)
    if log_format == "trc":
        text = ";$FILEVERSION=1.1\n;$STARTTIME=42176.7577227546\n" + text
    data = text.encode("utf-8", "replace")
    assert_clean_records(list(decode_log("nmea2000", data, log_format=log_format)))
    assert_clean_records(list(decode_log("nmea2000", data)))  # detected: whatever it is taken for


@FUZZ
@given(st.binary(max_size=200), st.lists(st.tuples(st.sampled_from(sorted(SUPPORTED_PGNS)), st.binary(max_size=12)),
                                         max_size=10))
def test_nmea2000_pcap(junk: bytes, packets: list[tuple[int, bytes]]) -> None:
    header = struct.pack("<IHHiIII", 0xA1B2C3D4, 2, 4, 0, 0, 65535, 227)
    records_ = b"".join(struct.pack("<IIII", 1_600_000_000, k, 8 + len(p), 8 + len(p))
                        + struct.pack(">IB3x", 0x80000000 | canboat.can_id_compose(2, pgn, 7, 255), len(p)) + p
                        for k, (pgn, p) in enumerate(packets))
    assert_clean_records(list(decode_log("nmea2000", header + records_ + junk)))
    assert_clean_records(list(decode_log("nmea2000", header + junk)))


# ----------------------------------------------------------------------------------------------
# MAVLink

INT32 = st.integers(-(2**31), 2**31 - 1)
UINT16 = st.integers(0, 2**16 - 1)
FLOAT32 = st.floats(width=32)  # NaN and ±inf included


@FUZZ
@given(st.integers(0, 2**64 - 1), st.integers(0, 255), INT32, INT32, INT32, UINT16, UINT16, UINT16, UINT16,
       st.integers(0, 255), UINT16)
def test_mavlink_gps_raw_int(time_usec: int, fix_type: int, lat: int, lon: int, alt: int, eph: int, epv: int, vel: int,
                             cog: int, satellites: int, yaw: int) -> None:
    encoder = MavlinkEncoder()
    packet = encoder._pack(encoder._mav.gps_raw_int_encode(time_usec, fix_type, lat, lon, alt, eph, epv, vel, cog,
                                                           satellites, yaw=yaw))
    assert_clean_messages([r.item for r in MavlinkDecoder().decode_datagram(packet)])


@FUZZ
@given(INT32, INT32, INT32, st.integers(-(2**15), 2**15 - 1), st.integers(-(2**15), 2**15 - 1), UINT16)
def test_mavlink_global_position_int(lat: int, lon: int, alt: int, vx: int, vy: int, hdg: int) -> None:
    encoder = MavlinkEncoder()
    packet = encoder._pack(encoder._mav.global_position_int_encode(0, lat, lon, alt, alt, vx, vy, 0, hdg))
    assert_clean_messages([r.item for r in MavlinkDecoder().decode_datagram(packet)])


@FUZZ
@given(FLOAT32, FLOAT32, FLOAT32, FLOAT32)
def test_mavlink_attitude(roll: float, pitch: float, yaw: float, yawspeed: float) -> None:
    encoder = MavlinkEncoder()
    packet = encoder._pack(encoder._mav.attitude_encode(0, roll, pitch, yaw, 0.0, 0.0, yawspeed))
    assert_clean_messages([r.item for r in MavlinkDecoder().decode_datagram(packet)])


@FUZZ
@given(st.lists(st.binary(max_size=80), max_size=5))
def test_mavlink_datagrams_and_tlog(datagrams: list[bytes]) -> None:
    decoder = MavlinkDecoder()
    for datagram in datagrams:
        assert_clean_messages([r.item for r in decoder.decode_datagram(datagram)])
    tlog = b"".join(struct.pack(">Q", 1_700_000_000_000_000 + k) + d for k, d in enumerate(datagrams))
    assert_clean_records(list(decode_log("mavlink", tlog)))
