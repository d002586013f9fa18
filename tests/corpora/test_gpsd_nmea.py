"""Real traffic: the gpsd regression corpora through the NMEA 0183 serial transport, checked against gpsd.

Input. ``gpsd-nmea/*.log`` are captures from ~115 receivers and heading sensors. They are replayed
as the device sent them, the way gpsd's own test harness (gpsfake) does: comment lines (``#``)
are dropped, and the ``Delay-Cookie`` character of ``tcp-torture.log`` is removed and used as a
write boundary. All logs go through ONE pseudo-terminal into ONE running
:class:`~interfaces.nmea0183.SerialReader`, separated by CR LF and a marker sentence
(``$PDPCX,END,<n>``, an unused proprietary address) that the test sees in the raw-line callback.

Reference. Each ``.log.chk`` is the same stream interleaved with the JSON that gpsd produced;
``"class":"TPV"`` objects carry ``mode`` (1 = no fix, 2/3 = fix), ``lat``, ``lon``, ``time``.
gpsd merges all sentences of a cycle into one fix and reports when a cycle ends, so a TPV's
position is that of the last position-carrying sentence before it. Matching rule for a fix we
decoded from sentence S (located in the ``.chk`` by its exact text, in stream order):

* gpsd's reports of S are the TPVs after S up to the next sentence that may change gpsd's
  position — a GGA/RMC/GNS/GLL with *other* latitude/longitude or UTC-time fields, or any
  proprietary sentence (``$P...``: some carry positions). A GGA/RMC/GNS/GLL repeating S's
  position and time (the usual GGA + RMC pair of one epoch) does not end the window. Several
  TPVs may report one epoch (gpsd reports again after a GSA changes the mode): gpsd "had a fix"
  for S if any of them has mode ≥ 2, and every such report must equal our fix;
* when both carry a time, the TPV's time of day must equal S's (else gpsd did not report S's
  epoch, and S is left unmatched);
* fixes with no reference TPV are not compared (counted and printed).

Checked: every matched fix equals gpsd's latitude/longitude within 1e-7°; no fix where gpsd
reported mode < 2 (all gpsd's reports of that epoch); no fix at all from a log where gpsd never
had one; every sentence where our stricter rules reject a position that gpsd reported is in
:data:`STRICTER_THAN_GPSD` with the reason; the binary logs of ``gpsd-binary/`` give no message.

Reproduction: gpsd's fixes are the distinct (time, latitude, longitude) of its TPVs with mode ≥ 2; one
is reproduced when a fix we decoded from the same log has its latitude and longitude within 1e-7° and
the same time of day (within 1 ms; either may lack a time). At least :data:`MIN_REPRODUCED` of them
must be, with the default sentence limit (high-precision receivers write 93 characters; with NMEA's
82 they were lost).
"""

from __future__ import annotations

import contextlib
import json
import math
import re
import threading
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from interfaces.messages import CourseOverGround, PositionFix
from interfaces.nmea0183 import (
    DEFAULT_MAX_SENTENCE_CHARS,
    NMEA_MAX_SENTENCE_CHARS,
    REJECT_REASONS,
    Frame,
    Nmea0183Decoder,
    PtyPair,
    ReceivedLine,
    SerialReader,
)

CORPORA = Path(__file__).parents[2] / "tests" / "corpora" / "data"
NMEA_DIR = CORPORA / "gpsd-nmea"
BINARY_DIR = CORPORA / "gpsd-binary"
pytestmark = pytest.mark.skipif(
    not NMEA_DIR.is_dir(), reason=f"gpsd corpora not found at {CORPORA.resolve()} (expected gpsd-nmea/*.log)")

TOLERANCE_DEG = 1e-7
WAIT_S = 120.0  # bound for the whole replay; it takes a few seconds
MIN_REPRODUCED = 0.98  # share of gpsd's fixes we must reproduce

# Where our stricter validity rules reject a position that gpsd reported (same lat/lon in its TPV).
_ZERO_SATELLITES = ("GGA with a satellite quality (1/2) and 0 satellites used: contradicts itself, rejected; gpsd "
                    "also drops it (mode 1) but a later GSA of the same cycle restores its mode. The same "
                    "receiver's RMC of that epoch still gives the fix.")
STRICTER_THAN_GPSD = {
    ("GPSmap-76S.log", "invalid_fix"): "GGA quality 8: Garmin handheld in simulator mode — not a measurement",
    ("garmin-geko201.log", "invalid_fix"): "GGA quality 8: Garmin handheld in simulator mode — not a measurement",
    ("furuno_gl_ga.log", "invalid_fix"): _ZERO_SATELLITES + " (Furuno sends 00 in every GNGGA; its GNS has 11)",
    ("foretrex-201.log", "invalid_fix"): _ZERO_SATELLITES,
    ("garmin25lp.log", "invalid_fix"): _ZERO_SATELLITES + " (first fix after power-up)",
    ("haicom-305N.log", "invalid_fix"): _ZERO_SATELLITES + " (first fix after power-up)",
    ("mtk-3301.log", "invalid_fix"): "GGA quality 0 with a position: the receiver says no fix (gpsd keeps the "
                                     "position and the mode of the GSA)",
    ("tr737A+.log", "invalid_fix"): "GGA quality 0 with a position (as mtk-3301)",
    ("myguide-3100.log", "no_data"): "GGA with an empty quality field: no validity, no fix",
}
# Receivers whose position sentences exceed NMEA's 82 characters (RTK/high-precision: 7-8 decimals
# of minutes; MTK/SkyTraq: 4-digit time fractions and long altitude fields) while gpsd reported the fix.
LONGER_THAN_NMEA = {"bt-q818.log", "cat-ms352.log", "mt3339.log", "nmea-fuzzy-cases.log", "nmea-rtk.log",
                    "skytraq-PX1172RH_DS.log", "skytraq-dgps.log", "skytraq-fix.log", "skytraq-fixB.log",
                    "ublox-f9p-hpnmea.log"}


def nmea(body: str) -> bytes:
    checksum = 0
    for byte in body.encode("ascii"):
        checksum ^= byte
    return f"${body}*{checksum:02X}\r\n".encode("ascii")


def device_chunks(path: Path) -> list[bytes]:
    """The bytes the device sent, as gpsfake replays them: comments dropped, delay cookies as write boundaries."""
    lines = path.read_bytes().splitlines(keepends=True)
    cookie = None
    for line in lines:
        match = re.match(rb"# Delay-Cookie: (\S) ", line)
        if match:
            cookie = match.group(1)
    stream = b"".join(line for line in lines if not line.startswith(b"#"))
    return stream.split(cookie) if cookie else [stream]


@dataclass
class Replay:
    """What the serial transport delivered, per log."""

    frames: dict[str, list[Frame]] = field(default_factory=dict)
    counters: dict[str, int] = field(default_factory=dict)
    alive_at_end: bool = False
    writer_error: BaseException | None = None


@pytest.fixture(scope="module")
def replay() -> Replay:
    logs = sorted(NMEA_DIR.glob("*.log")) + sorted(BINARY_DIR.glob("*.log"))
    assert len(logs) > 100
    markers = {nmea(f"PDPCX,END,{index}")[:-2]: path.name for index, path in enumerate(logs)}
    result = Replay()
    current: list[Frame] = []
    done = threading.Event()

    def on_line(line: ReceivedLine) -> None:
        nonlocal current
        name = markers.get(line.frame.raw)
        if name is None:
            current.append(line.frame)
            return
        result.frames[name] = current
        current = []
        if len(result.frames) == len(logs):
            done.set()

    with PtyPair() as pty:
        reader = SerialReader(pty.device_path, source="corpus", clock=lambda: 0.0, on_line=on_line, baudrate=115200)
        with reader:
            assert reader.wait_connected(10.0), reader.last_error

            def write_all() -> None:
                try:
                    for index, path in enumerate(logs):
                        for chunk in device_chunks(path):
                            pty.write(chunk)
                        pty.write(b"\r\n" + nmea(f"PDPCX,END,{index}"))
                except BaseException as exc:  # reported by the test, not lost in the thread
                    result.writer_error = exc
                    done.set()

            writer = threading.Thread(target=write_all, name="corpus-writer")
            writer.start()
            assert done.wait(WAIT_S), f"replay incomplete: {len(result.frames)}/{len(logs)} logs"
            writer.join(WAIT_S)
            result.alive_at_end = reader.is_alive
            result.counters = reader.counters
    assert result.writer_error is None, result.writer_error
    return result


def decode_directly(path: Path, max_sentence_chars: int = DEFAULT_MAX_SENTENCE_CHARS) -> list[Frame]:
    decoder = Nmea0183Decoder(max_sentence_chars)
    return decoder.feed_frames(b"".join(device_chunks(path)) + b"\r\n") + decoder.flush()


# ----------------------------------------------------------------------------------------------
# gpsd's answers and the matching rule


@dataclass(frozen=True)
class Chk:
    """A ``.chk`` file: sentence lines and TPV reports in order."""

    items: list[tuple[str, object]]  # ("S", bytes) or ("T", dict)

    @classmethod
    def read(cls, path: Path) -> Chk:
        items: list[tuple[str, object]] = []
        for line in path.read_bytes().splitlines():
            if line.startswith(b"{"):
                if b'"class":"TPV"' in line:
                    items.append(("T", json.loads(line)))
            elif line:
                items.append(("S", line))
        return cls(items)

    @property
    def ever_fixed(self) -> bool:
        return any(kind == "T" and item.get("mode", 0) >= 2 for kind, item in self.items)


# field positions of (time, lat, N/S, lon, E/W) in the sentences that carry a position
_POSITION_FIELDS = {b"GGA": (1, 2, 3, 4, 5), b"GNS": (1, 2, 3, 4, 5), b"RMC": (1, 3, 4, 5, 6),
                    b"GLL": (5, 1, 2, 3, 4)}


def position_key(sentence: bytes) -> tuple[object, ...] | None:
    """(time [s], lat, N/S, lon, E/W) fields of a position sentence, ``None`` for other sentences.

    The time is compared as a number (``130711`` and ``130711.00`` are the same epoch)."""
    indices = _POSITION_FIELDS.get(sentence[3:6])
    if indices is None:
        return None
    fields = sentence.split(b"*")[0].split(b",")
    values = [fields[i] if i < len(fields) else b"" for i in indices]
    with contextlib.suppress(ValueError):
        values[0] = float(values[0]) if values[0] else None
    return tuple(values)


def may_move_gpsd(sentence: bytes, key: tuple[object, ...]) -> bool:
    if sentence.startswith(b"$P"):
        return True
    other = position_key(sentence)
    return other is not None and other != key


def seconds_of_day(iso_time: str) -> float:
    return int(iso_time[11:13]) * 3600 + int(iso_time[14:16]) * 60 + float(iso_time[17:-1])


def reference_tpvs(chk: Chk, index: int, utc_time_s: float | None) -> list[dict]:
    """gpsd's reports of the sentence at ``chk.items[index]``, by the rule of the module docstring."""
    key = position_key(chk.items[index][1])
    reports = []
    for kind, item in chk.items[index + 1:]:
        if kind == "T":
            if "time" in item and utc_time_s is not None:
                difference = abs(seconds_of_day(item["time"]) - utc_time_s) % 86400.0
                if min(difference, 86400.0 - difference) > 1e-3:
                    break
            reports.append(item)
        elif key is None or may_move_gpsd(item, key):
            break
    return reports


def _fixed(reports: list[dict]) -> list[dict]:
    return [report for report in reports if report.get("mode", 0) >= 2 and "lat" in report]


@dataclass
class Comparison:
    compared: int = 0
    unmatched: int = 0
    mismatches: list[str] = field(default_factory=list)
    fix_gpsd_none: dict[tuple[str, str], int] = field(default_factory=dict)
    fixes_in_unfixed_log: list[str] = field(default_factory=list)
    stricter: dict[tuple[str, str], int] = field(default_factory=dict)
    not_in_chk: list[str] = field(default_factory=list)
    compared_per_log: dict[str, int] = field(default_factory=dict)


def _coordinates(sentence: bytes) -> tuple[float, float] | None:
    """lat/lon of a rejected position sentence, read independently of our decoder (plain field arithmetic)."""
    key = position_key(sentence)
    try:
        lat = float(key[1]) // 100 + float(key[1]) % 100 / 60.0
        lon = float(key[3]) // 100 + float(key[3]) % 100 / 60.0
    except (TypeError, ValueError):
        return None
    return (-lat if key[2] == b"S" else lat), (-lon if key[4] == b"W" else lon)


def compare_with_gpsd(frames_per_log: dict[str, list[Frame]]) -> Comparison:
    result = Comparison()
    for name, frames in sorted(frames_per_log.items()):
        chk = Chk.read(NMEA_DIR / (name + ".chk"))
        pointer = 0
        for frame in frames:
            fix = next((m for m in frame.messages if isinstance(m, PositionFix)), None)
            if not frame.sentence:
                continue
            index = pointer
            cut = frame.rejected is not None and frame.rejected.reason == "too_long"  # raw is an excerpt
            while index < len(chk.items) and not (
                    chk.items[index][0] == "S"
                    and (chk.items[index][1].startswith(frame.raw) if cut else chk.items[index][1] == frame.raw)):
                index += 1
            if index == len(chk.items):
                if fix is not None:
                    result.not_in_chk.append(f"{name}: {frame.raw!r}")
                continue
            pointer = index + 1
            if frame.sentence[2:] not in ("GGA", "RMC", "GNS", "GLL"):
                continue
            if fix is None:
                rejected = frame.rejected
                position = _coordinates(chk.items[index][1])
                if rejected is not None and position is not None and any(
                        abs(position[0] - tpv["lat"]) <= TOLERANCE_DEG
                        and abs(position[1] - tpv["lon"]) <= TOLERANCE_DEG
                        for tpv in _fixed(reference_tpvs(chk, index, None))):
                    reason_key = (name, rejected.reason)
                    result.stricter[reason_key] = result.stricter.get(reason_key, 0) + 1
                continue
            if not chk.ever_fixed:
                result.fixes_in_unfixed_log.append(f"{name}: {frame.raw!r}")
            reports = reference_tpvs(chk, index, fix.utc_time_s)
            if not reports:
                result.unmatched += 1
                continue
            fixed = _fixed(reports)
            if not fixed:
                key = (name, frame.sentence)
                result.fix_gpsd_none[key] = result.fix_gpsd_none.get(key, 0) + 1
                continue
            result.compared += 1
            result.compared_per_log[name] = result.compared_per_log.get(name, 0) + 1
            for tpv in fixed:
                if abs(fix.lat_deg - tpv["lat"]) > TOLERANCE_DEG or abs(fix.lon_deg - tpv["lon"]) > TOLERANCE_DEG:
                    result.mismatches.append(f"{name}: {frame.raw!r} → ({fix.lat_deg:.9f}, {fix.lon_deg:.9f}), "
                                             f"gpsd ({tpv['lat']}, {tpv['lon']})")
    return result


@pytest.fixture(scope="module")
def strict_comparison(replay: Replay) -> Comparison:
    nmea_logs = {name: frames for name, frames in replay.frames.items() if (NMEA_DIR / name).is_file()}
    return compare_with_gpsd(nmea_logs)


# ----------------------------------------------------------------------------------------------
# tests


def test_every_log_reads_through_the_serial_transport(replay: Replay) -> None:
    assert replay.alive_at_end
    counters = replay.counters
    assert counters["internal_errors"] == 0 and counters["callback_errors"] == 0 and counters["disconnects"] == 0
    assert counters["frames"] == counters["ok"] + counters["ignored"] + counters["rejected"]
    assert counters["rejected"] == sum(counters[f"rejected.{reason}"] for reason in REJECT_REASONS)
    logs = sorted(NMEA_DIR.glob("*.log"))
    assert {path.name for path in logs} <= set(replay.frames)
    for path in logs:
        # the transport (arbitrary read boundaries, one decoder for the whole session) decodes
        # exactly what the codec decodes from the whole file at once
        assert replay.frames[path.name] == decode_directly(path), path.name
    fixes = sum(isinstance(m, PositionFix) for frames in replay.frames.values() for f in frames for m in f.messages)
    assert fixes > 0


def test_fixes_equal_what_gpsd_reported(strict_comparison: Comparison) -> None:
    result = strict_comparison
    print(f"\n{result.compared} fixes compared with gpsd, {result.unmatched} without a reference TPV, over "
          f"{len(result.compared_per_log)} logs")
    assert result.not_in_chk == []
    assert result.mismatches == []
    assert result.compared > result.unmatched  # the rule finds gpsd's report for most fixes
    compared = {name for name in LONGER_THAN_NMEA if result.compared_per_log.get(name, 0) > 0}
    assert {"nmea-rtk.log", "ublox-f9p-hpnmea.log", "skytraq-dgps.log"} <= compared  # high precision is read


def test_no_fix_where_gpsd_reported_none(strict_comparison: Comparison) -> None:
    assert strict_comparison.fixes_in_unfixed_log == []
    assert strict_comparison.fix_gpsd_none == {}


def test_stricter_validity_rules_are_documented(strict_comparison: Comparison) -> None:
    stricter = dict(strict_comparison.stricter)
    print("\nrejected by us, reported by gpsd: "
          + ", ".join(f"{name} {reason} ×{count}" for (name, reason), count in sorted(stricter.items())))
    assert set(stricter) == set(STRICTER_THAN_GPSD)


@dataclass
class Reproduction:
    fixes: int = 0
    reproduced: int = 0
    missed: dict[str, int] = field(default_factory=dict)


def reproduction(frames_per_log: dict[str, list[Frame]]) -> Reproduction:
    """How many of gpsd's distinct fixes our fixes reproduce (rule of the module docstring)."""
    result = Reproduction()
    for name, frames in sorted(frames_per_log.items()):
        ours: dict[int | None, list[PositionFix]] = {}
        for fix in (m for f in frames for m in f.messages if isinstance(m, PositionFix)):
            ours.setdefault(None if fix.utc_time_s is None else round(fix.utc_time_s * 1000.0) % 86_400_000,
                            []).append(fix)
        untimed = [fix for fixes in ours.values() for fix in fixes]
        chk = Chk.read(NMEA_DIR / (name + ".chk"))
        tpvs = {(item.get("time"), item["lat"], item["lon"]) for kind, item in chk.items
                if kind == "T" and item.get("mode", 0) >= 2 and "lat" in item}
        for time, lat, lon in tpvs:
            result.fixes += 1
            if time is None:
                candidates = untimed
            else:
                candidates = ours.get(None, []) + ours.get(round(seconds_of_day(time) * 1000.0) % 86_400_000, [])
            if any(abs(fix.lat_deg - lat) <= TOLERANCE_DEG and abs(fix.lon_deg - lon) <= TOLERANCE_DEG
                   for fix in candidates):
                result.reproduced += 1
            else:
                result.missed[name] = result.missed.get(name, 0) + 1
    return result


def test_gpsds_fixes_are_reproduced(replay: Replay) -> None:
    nmea_logs = {name: frames for name, frames in replay.frames.items() if (NMEA_DIR / name).is_file()}
    result = reproduction(nmea_logs)
    share = result.reproduced / result.fixes
    print(f"\ngpsd's fixes reproduced: {result.reproduced} of {result.fixes} ({100 * share:.2f} %); missed: "
          + ", ".join(f"{name} ×{count}" for name, count in sorted(result.missed.items())))
    assert result.fixes > 2500
    assert share >= MIN_REPRODUCED
    # NMEA's own 82-character limit loses the high-precision receivers: the default must be above it
    limited = reproduction({name: decode_directly(NMEA_DIR / name, NMEA_MAX_SENTENCE_CHARS) for name in nmea_logs})
    assert limited.reproduced < result.reproduced - 100
    assert all(name in LONGER_THAN_NMEA or limited.missed.get(name, 0) == result.missed.get(name, 0)
               for name in limited.missed)


@pytest.mark.skipif(not BINARY_DIR.is_dir(), reason=f"gpsd binary corpus not found at {BINARY_DIR.resolve()}")
def test_binary_protocols_give_no_fix_and_no_crash(replay: Replay) -> None:
    logs = sorted(BINARY_DIR.glob("*.log"))
    assert logs
    for path in logs:
        frames = replay.frames[path.name]
        assert frames, path.name  # the bytes were seen and accounted for
        assert [m for f in frames for m in f.messages] == [], path.name
        assert all(f.rejected is not None or f.sentence for f in frames)
    assert replay.alive_at_end


# ----------------------------------------------------------------------------------------------
# VTG (course and speed over ground): against gpsd's TPV ``speed`` and ``track``

_VTG_SPEED_TOLERANCE_MPS = 6e-4  # gpsd prints the speed with 3 decimals (m/s)
_VTG_TRACK_TOLERANCE_DEG = 6e-3  # ... the track with 4; VTG has at most 3 decimals
MIN_VTG_COMPARED = 1500  # VTG epochs gpsd reported a speed for (1590 at the time of writing)


def _epoch_of(chk: Chk, index: int) -> float | None:
    """Time of day [s] of the epoch the sentence at ``index`` belongs to: VTG carries no time, so the time of the
    last position sentence before it (GGA, GNS, RMC, GLL: receivers send VTG within the epoch's burst)."""
    for kind, item in reversed(chk.items[:index]):
        if kind == "S" and isinstance(item, bytes):
            key = position_key(item)
            if key is not None:
                if not isinstance(key[0], float):
                    return None
                hhmmss = key[0]  # (the time field as a number: hhmmss.ss)
                return (hhmmss // 10000) * 3600.0 + (hhmmss // 100 % 100) * 60.0 + hhmmss % 100.0
    return None


def test_vtg_course_and_speed_equal_what_gpsd_reported() -> None:
    """Every VTG we decode (course true, speed) equals gpsd's TPV ``track`` and ``speed`` of the same epoch (the first
    TPV with a fix after the VTG whose time is the epoch's — gpsd reports at the end of the cycle — before the next
    VTG); epochs gpsd reported no speed for are not compared. Rejected VTGs are the receivers' own ``N`` (no fix)."""
    compared = 0
    mismatches = []
    rejected: set[str] = set()
    for path in sorted(NMEA_DIR.glob("*.log")):
        frames = [f for f in decode_directly(path) if f.sentence[2:] == "VTG"]
        if not frames:
            continue
        chk = Chk.read(path.with_name(path.name + ".chk"))
        items = chk.items
        start = 0
        for frame in frames:
            if frame.rejected is not None:
                rejected.add(frame.rejected.reason)
                continue
            (course,) = frame.messages
            assert isinstance(course, CourseOverGround)
            index = next((i for i in range(start, len(items)) if items[i] == ("S", frame.raw)), None)
            if index is None:
                continue
            start = index + 1
            epoch = _epoch_of(chk, index)
            if epoch is None:
                continue
            report = None
            for kind, item in items[index + 1:]:
                if kind == "S" and isinstance(item, bytes) and item[3:6] == b"VTG":
                    break
                if kind == "T" and isinstance(item, dict) and item.get("mode", 0) >= 2 and "time" in item and \
                        abs(seconds_of_day(item["time"]) - epoch) < 1e-3:
                    report = item
                    break
            if report is None or "speed" not in report:
                continue
            compared += 1
            speed_error = 0.0 if course.speed_mps is None else abs(report["speed"] - course.speed_mps)
            track_error = 0.0
            if course.course_rad is not None and "track" in report:
                track_error = abs((math.degrees(course.course_rad) - report["track"] + 180.0) % 360.0 - 180.0)
            if speed_error > _VTG_SPEED_TOLERANCE_MPS or track_error > _VTG_TRACK_TOLERANCE_DEG:
                mismatches.append((path.name, frame.raw, report.get("speed"), report.get("track")))
    assert not mismatches, mismatches[:10]
    assert compared >= MIN_VTG_COMPARED
    # a VTG with mode N (no fix) is invalid_fix; a few logs cut a line short (no checksum)
    assert rejected <= {"invalid_fix", "no_checksum"}, rejected
