"""candump parsing (three formats) and ``decode_candump_log`` JSON-line objects."""

from __future__ import annotations

import io
import json
from pathlib import Path

import pytest

from dpcontrol.cli import main
from interfaces.messages import FixQuality, Heading, PositionFix
from interfaces.nmea2000.candump import CandumpFrame, parse_candump_line, read_candump
from interfaces.nmea2000.codec import N2kEncoder
from interfaces.nmea2000.logformats import LINKTYPE_CAN_SOCKETCAN, canonical_format, detect_format
from interfaces.nmea2000.logs import decode_candump_log, decode_nmea2000_log


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
    "(1.0) slcan0 09F112CC#F\u00e9F72",  # canboat's parser panics on a multi-byte character
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


# ----------------------------------------------------------------------------------------------
# the other capture formats (real files of each: tests/corpora/test_canboat_formats.py)

CANBOAT = Path(__file__).parents[2] / "tests" / "corpora" / "data" / "canboat-n2k"


def test_an_unknown_format_is_a_clear_error() -> None:
    with pytest.raises(ValueError, match="ydwg"):
        list(decode_nmea2000_log(b"", log_format="nmea2001"))
    assert canonical_format("FAST") == "plain" and canonical_format("pcapng") == "pcap"


@pytest.mark.skipif(not CANBOAT.is_dir(), reason="canboat corpus absent")
def test_pcapng_reads_as_the_pcap_it_was_converted_from() -> None:
    """The vendored pcap's packets rewritten into a pcapng container (dpkt's writer) decode identically."""
    import dpkt  # noqa: PLC0415

    data = (CANBOAT / "can0-1-head.pcap").read_bytes()
    out = io.BytesIO()
    writer = dpkt.pcapng.Writer(out, snaplen=65535, linktype=LINKTYPE_CAN_SOCKETCAN)
    for t_s, packet in dpkt.pcap.Reader(io.BytesIO(data)):
        writer.writepkt(packet, ts=t_s)
    assert detect_format(out.getvalue()) == "pcap"
    from_pcapng = list(decode_nmea2000_log(out.getvalue()))
    assert from_pcapng == list(decode_nmea2000_log(data)) and len(from_pcapng) > 500


def test_a_pcap_of_another_link_type_is_one_clear_rejection() -> None:
    import dpkt  # noqa: PLC0415

    out = io.BytesIO()
    writer = dpkt.pcap.Writer(out, linktype=1)  # Ethernet
    writer.writepkt(b"\x00" * 60, ts=1.0)
    (record,) = decode_nmea2000_log(out.getvalue())
    assert record["rejected"] == "garbage" and "not SocketCAN" in record["detail"]


@pytest.mark.skipif(not CANBOAT.is_dir(), reason="canboat corpus absent")
def test_the_command_line_detects_or_is_told_the_format(capsys: pytest.CaptureFixture[str]) -> None:
    path = str(CANBOAT / "merrimac-ydwg-2020.raw")
    assert main(["decode", "nmea2000", path, "--stats"]) == 0
    detected = capsys.readouterr()
    assert main(["decode", "nmea2000", path, "--format", "ydwg"]) == 0
    assert capsys.readouterr().out == detected.out and '"format": "ydwg"' in detected.err
    assert main(["decode", "nmea2000", path, "--format", "candump"]) == 0  # told wrong: every line garbage
    assert all(json.loads(line)["rejected"] == "garbage" for line in capsys.readouterr().out.splitlines())
    assert main(["decode", "nmea2000", path, "--format", "seatalk"]) == 2
    assert "known:" in capsys.readouterr().err
    assert main(["decode", "nmea0183", path, "--format", "ydwg"]) == 2


def test_a_trace_line_python_can_skips_is_reported_not_lost(caplog: pytest.LogCaptureFixture) -> None:
    trace = (b";$FILEVERSION=1.1\n;$STARTTIME=42176.7577227546\n"
             b"     1)        48.6  Rx     09F11201  8  FF 50 7A FF 7F FF 7F FD\n  garbage\n"
             b"     2)        49.2  Rx     09F10D01  8  00 F8 FF 7F 5F B8 FF FF\n")
    stats: dict[str, object] = {}
    records = list(decode_nmea2000_log(trace, stats))
    assert stats["format"] == "trc" and stats["frames_read"] == 2 and stats["garbage_lines"] == 1
    assert [r.get("rejected") for r in records] == ["magnetic_heading", "garbage"]
    assert "garbage" in records[1]["detail"] and not caplog.records  # reported here, not as a log warning
