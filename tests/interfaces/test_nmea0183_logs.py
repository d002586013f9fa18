"""``interfaces.logs``: the NMEA 0183 part of ``dpcontrol decode`` (JSON-line records)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from interfaces.logs import LOG_DECODERS, decode_log, decode_nmea0183_log, to_json_line
from interfaces.messages import CourseOverGround, FixQuality, Heading, PositionErrorStats, PositionFix, RateOfTurn
from interfaces.nmea0183 import encode_gga, encode_gst, encode_rmc, encode_rot, encode_ths

FIX = PositionFix(-33.8568, 151.2153, FixQuality.RTK_FLOAT, 3723.25, 11, 0.8, 4.5)
LOG = (b"# Name: test receiver\n"
       b"# a comment with a sentence in it: $GPGGA,,,,,,0,,,,M,,M,,*66\n"
       + encode_gga(FIX)
       + encode_rmc(FIX, CourseOverGround(math.pi / 2, 1.0))
       + b"$GPGSV,3,1,11,01,78,221,47,03,09,042,00,04,05,242,00,06,04,149,00*70\r\n"
       + encode_ths(Heading(1.0)) + encode_rot(RateOfTurn(-0.02))
       + encode_gst(PositionErrorStats(0.02, 0.03, 0.05, 0.4, 3723.25))
       + encode_gga(FIX)[:-4] + (b"01\r\n" if encode_gga(FIX)[-4:-2] == b"00" else b"00\r\n")  # bad checksum
       + b"\xb5\x62\x01\x07\x00\r\n"          # binary
       + encode_ths(Heading(1.0))[:-2])       # no terminator at the end of the file


def test_records_for_measurements_and_rejects() -> None:
    stats: dict[str, int] = {}
    records = list(decode_nmea0183_log(LOG, stats))
    kinds = [record.get("kind") or record["rejected"] for record in records]
    assert kinds == ["position", "position", "course_over_ground", "heading", "rate_of_turn", "position_error",
                     "checksum", "garbage", "unterminated"]
    gga = records[0]
    assert gga["source"] == "GP" and gga["sentence"] == "GGA" and gga["line"] == 3
    assert gga["lat_deg"] == pytest.approx(FIX.lat_deg, abs=1e-8)
    assert gga["lon_deg"] == pytest.approx(FIX.lon_deg, abs=1e-8)
    assert gga["quality"] == "rtk_float" and gga["sample_time"] == 3723.25 and gga["num_satellites"] == 11
    heading = records[3]
    assert heading["source"] == "HE" and heading["heading_rad"] == pytest.approx(1.0, abs=1e-5)
    assert "sample_time" not in heading  # THS carries no time: left out, never NaN
    assert records[4]["rate_radps"] == pytest.approx(-0.02, abs=1e-5)
    assert records[5]["sigma_north_m"] == 0.02
    checksum = records[6]
    assert checksum["detail"] and checksum["raw"].startswith("$GPGGA,") and checksum["line"] == 9
    assert records[7]["raw"].startswith("\\xb5b")  # binary shown escaped
    assert stats["comments"] == 2 and stats["lines"] == 11
    assert stats["ignored"] == 1 and stats["ok"] == 5 and stats["messages"] == 6 and stats["rejected"] == 3
    assert stats["frames"] == stats["ok"] + stats["ignored"] + stats["rejected"]


def test_every_record_is_one_strict_json_line(tmp_path: Path) -> None:
    path = tmp_path / "capture.log"
    path.write_bytes(LOG)
    from_path = list(decode_log("nmea0183", path))
    assert from_path == list(decode_log("nmea0183", LOG))  # a path and the bytes give the same records
    for record in from_path:
        line = to_json_line(record)
        assert "\n" not in line and json.loads(line) == record
        assert "NaN" not in line


def test_unknown_protocol_is_a_clear_error() -> None:
    with pytest.raises(ValueError, match="nmea0183"):
        decode_log("nmea0184", b"")
    assert "nmea0183" in LOG_DECODERS


def test_missing_file_raises_oserror(tmp_path: Path) -> None:
    with pytest.raises(OSError):
        list(decode_nmea0183_log(tmp_path / "absent.log"))


def test_high_precision_logs_are_read_by_default_and_the_limit_is_configurable() -> None:
    line = b"$GNGGA,132819.60,4134.49795459,N,09345.03431408,W,2,10,0.9,278.161,M,-31.442,M,6.6,0133*6A\r\n"
    (record,) = decode_nmea0183_log(line)
    assert record["lat_deg"] == pytest.approx(41 + 34.49795459 / 60, abs=1e-12)
    assert [r["rejected"] for r in decode_nmea0183_log(line, max_sentence_chars=82)] == ["too_long"]


@pytest.mark.parametrize(("prefix", "t_s"), [
    (b"2014-08-01T00:00:00.183000Z ", 1406851200.183),   # OpenRVDAS
    (b"2014-08-01 00:00:00.183,", 1406851200.183),
    (b"2014-08-01T02:00:00.183+02:00\t", 1406851200.183),
    (b"2014-08-01T00:00:00Z;", 1406851200.0),
])
def test_a_loggers_capture_time_is_the_records_t_s(prefix: bytes, t_s: float) -> None:
    hdt = encode_ths(Heading(1.0))
    stats: dict[str, int] = {}
    records = list(decode_nmea0183_log(prefix + hdt + b"garbage $\r\n" + hdt, stats))
    assert records[0]["kind"] == "heading" and records[0]["t_s"] == pytest.approx(t_s, abs=1e-6)
    assert [r.get("rejected") for r in records[1:]] == ["garbage", "no_checksum", None]  # no prefix, no capture time
    assert "t_s" not in records[3] and stats["timestamped_lines"] == 1 and stats["rejected.garbage"] == 1


def test_an_impossible_capture_time_is_not_taken_for_one() -> None:
    records = list(decode_nmea0183_log(b"2014-13-01T00:00:00Z " + encode_ths(Heading(1.0))))
    assert records[0]["rejected"] == "garbage" and "t_s" not in records[1]


CORPUS_LOG = Path(__file__).parents[2] / "tests" / "corpora" / "data" / "gpsd-nmea" / "ublox-zed-f9r.log"


@pytest.mark.skipif(not CORPUS_LOG.is_file(), reason=f"gpsd corpus log not found at {CORPUS_LOG.resolve()}")
def test_a_real_log_with_binary_and_comments() -> None:
    stats: dict[str, int] = {}
    records = list(decode_nmea0183_log(CORPUS_LOG, stats))
    positions = [r for r in records if r.get("kind") == "position"]
    assert positions and all(-90 <= r["lat_deg"] <= 90 and r["quality"] != "invalid" for r in positions)
    assert stats["comments"] > 0 and stats["rejected.garbage"] > 0  # UBX binary between the sentences
    assert sum(1 for r in records if "rejected" in r) == stats["rejected"]
    assert len(records) - stats["rejected"] == stats["messages"]


def tag_block(content: str) -> bytes:
    checksum = 0
    for byte in content.encode("ascii"):
        checksum ^= byte
    return b"\\" + content.encode("ascii") + b"*%02X\\" % checksum


def test_an_nmea4_tag_block_gives_the_capture_time() -> None:
    hdt = encode_ths(Heading(1.0))
    log = (tag_block("c:1406851200,s:GYRO1") + hdt + tag_block("c:1406851200183") + hdt
           + tag_block("s:GYRO1") + hdt + b"\\c:1406851200*00\\" + hdt)
    records = list(decode_nmea0183_log(log))
    assert [r.get("t_s") for r in records[:3]] == [1406851200.0, pytest.approx(1406851200.183), None]
    assert [r.get("kind") for r in records[:3]] == ["heading"] * 3
    assert records[3]["rejected"] == "garbage" and records[4]["kind"] == "heading"  # a bad block's checksum
