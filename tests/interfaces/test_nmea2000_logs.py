"""candump parsing (three formats) and ``decode_candump_log`` JSON-line objects."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from interfaces.messages import FixQuality, Heading, PositionFix
from interfaces.nmea2000.candump import CandumpFrame, parse_candump_line, read_candump
from interfaces.nmea2000.codec import N2kEncoder
from interfaces.nmea2000.logs import decode_candump_log


def fmt1(can_id: int, data: bytes, t_s: float) -> str:
    return f"<0x{can_id:08x}> [{len(data)}] " + " ".join(f"{b:02x}" for b in data) + " "


def fmt2(can_id: int, data: bytes, t_s: float) -> str:
    return f"  can0  {can_id:08X}   [{len(data)}]  " + " ".join(f"{b:02X}" for b in data)


def fmt3(can_id: int, data: bytes, t_s: float) -> str:
    return f"({t_s:.6f}) slcan0 {can_id:08X}#{data.hex().upper()}"


@pytest.mark.parametrize(("line", "expected"), [
    ("<0x18eeff01> [8] 05 a0 be 1c 00 a0 a0 c0 ", CandumpFrame(None, 0x18EEFF01, bytes.fromhex("05a0be1c00a0a0c0"))),
    ("  can0  09F8027F   [8]  00 FC FF FF 00 00 FF FF", CandumpFrame(None, 0x09F8027F,
                                                                    bytes.fromhex("00fcffff0000ffff"))),
    ("(1502984866.421964) slcan0 09F112CC#FF725AFF7FFF7FFD", CandumpFrame(1502984866.421964, 0x09F112CC,
                                                                         bytes.fromhex("ff725aff7fff7ffd"))),
    ("(1.5) slcan0 09F112CC#FF72", CandumpFrame(1.5, 0x09F112CC, b"\xff\x72")),
])
def test_the_three_candump_formats(line: str, expected: CandumpFrame) -> None:
    assert parse_candump_line(line) == expected


@pytest.mark.parametrize("line", ["", "   \n", "# comment", "interface = can0, family = 29, type = 3, proto = 1"])
def test_metadata_lines_are_not_frames(line: str) -> None:
    assert parse_candump_line(line) is None


@pytest.mark.parametrize("line", [
    "<0x18eeff01> [8] 05 a0 be",  # fewer bytes than announced
    "garbage",
    "can0 ZZZZZZZZ [8] 00 00 00 00 00 00 00 00",
    "(1.0) slcan0 09F112CC#FF7",  # odd number of hex digits
    "(x) slcan0 09F112CC#FF72",  # bad timestamp
    "(nan) slcan0 09F112CC#FF72",  # float() takes these; candump never writes them
    "(inf) slcan0 09F112CC#FF72",
    "(-inf) slcan0 09F112CC#FF72",
    "(1e400) slcan0 09F112CC#FF72",
    "(1.0) slcan0 09F112CC#" + "00" * 9,  # nine bytes in a classic frame
    "<0x18eeff01> [8] " + "00 " * 400,
])
def test_malformed_lines_raise_value_error(line: str) -> None:
    with pytest.raises(ValueError):
        parse_candump_line(line)


def _capture(tmp_path: Path, fmt, name: str) -> Path:
    """A capture: rapid positions, a 129029, a heading, a garbage line and a 129029 whose last frame is lost."""
    encoder = N2kEncoder(42)
    fix = PositionFix(52.3702157, 4.8951679, FixQuality.DGPS, utc_time_s=3600.25, num_satellites=8, hdop=1.1,
                      altitude_m=-2.0)
    frames = encoder.position_rapid(fix) + encoder.gnss_position(fix, date_days=19000) + encoder.heading(Heading(0.5))
    lost = encoder.gnss_position(fix)[:-1]
    lines = ["# a comment", *(fmt(can_id, data, 1000.0 + 0.01 * i) for i, (can_id, data) in enumerate(frames)),
             "this is not a frame",
             *(fmt(can_id, data, 1001.0 + 0.01 * i) for i, (can_id, data) in enumerate(lost))]
    path = tmp_path / name
    path.write_text("\n".join(lines) + "\n", encoding="ascii")
    return path


@pytest.mark.parametrize("fmt", [fmt1, fmt2, fmt3])
def test_decode_candump_log_objects(tmp_path: Path, fmt) -> None:
    stats: dict[str, int] = {}
    path = _capture(tmp_path, fmt, "capture.log")
    records = list(decode_candump_log(path, stats))
    assert list(decode_candump_log(path.read_bytes())) == records  # a path or the content
    assert stats["frames_read"] == stats["frames"] == 15 and stats["garbage_lines"] == 1
    assert stats["messages"] == 3 and stats["rejected"] == 1
    for record in records:
        json.dumps(record)  # every object is one JSON line
    kinds = [r.get("kind", "rejected:" + r.get("rejected", "?")) for r in records]
    assert kinds == ["position", "position", "heading", "rejected:garbage", "rejected:truncated_fast_packet"]
    rapid, full, heading, garbage, lost = records
    assert rapid["source"] == "n2k:42" and rapid["pgn"] == 129025 and rapid["quality"] == "gps"
    assert abs(rapid["lat_deg"] - 52.3702157) < 1e-9 and "sample_time" not in rapid
    assert full["pgn"] == 129029 and full["quality"] == "dgps" and full["sample_time"] == pytest.approx(3600.25)
    assert full["num_satellites"] == 8 and abs(full["lon_deg"] - 4.8951679) < 1e-12
    assert heading["heading_rad"] == pytest.approx(0.5, abs=0.5e-4)
    assert garbage["line"] == 11 and garbage["raw"] == "this is not a frame"
    assert lost["pgn"] == 129029 and lost["source"] == "n2k:42"
    if fmt is fmt3:
        assert rapid["t_s"] == pytest.approx(1000.0) and full["line"] == 9
    else:
        assert "t_s" not in rapid


def test_read_candump_reports_bad_lines_with_their_number(tmp_path: Path) -> None:
    path = tmp_path / "x.log"
    path.write_text("(1.0) slcan0 09F112CC#FF72\n\nnonsense\n", encoding="ascii")
    items = list(read_candump(path))
    assert isinstance(items[0], CandumpFrame) and items[0].line_no == 1
    assert items[1][0] == 3 and items[1][2] == "nonsense"
