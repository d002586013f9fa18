"""Real NMEA 2000 captures in each format boats log (canboat's samples), decoded by ``dpcontrol decode nmea2000``.

Files (``tests/corpora/data/canboat-n2k/``, Apache-2.0, see ``ORIGIN.md``): Actisense N2K ASCII from a
W2K-1, canboat PLAIN (an Actisense NGT-1 on a 2016 trawler) and FAST (a Furuno SCX-20), Yacht Devices
YDWG-02 raw, Digital Yacht iKonvert, a PEAK PCAN-View trace of a Garmin installation and a SocketCAN
pcap; the larger ones cut to their first lines or packets.

Checked per file: the format is detected (and ``--format`` gives the same), only the rejections a real
bus explains occur (no fix yet, magnetic heading without variation, "not available", a wind reference
we do not use; iKonvert's few damaged lines as garbage), the measurements it must carry are there, and
true headings, yaws and positions move continuously per source (30 °/s and 1 m between updates: a
decoding error — scale, byte order, sign — moves them by far more).

Where canboat ships its own decode of the same bytes (``analyzer`` output: the Actisense file, the
PLAIN test file, the YDWG capture), every measurement we decode equals canboat's value of the same
message within canboat's printed resolution, and every message canboat decodes with usable values
and we do not use is accounted for by one of our rules.
"""

from __future__ import annotations

import json
import math
import re
from collections import Counter
from pathlib import Path
from typing import Any

import pytest

from dpbase.geodesy import geodetic_to_ecef
from interfaces.nmea2000.logformats import detect_format
from interfaces.nmea2000.logs import decode_nmea2000_log

CORPUS = Path(__file__).parents[2] / "tests" / "corpora" / "data" / "canboat-n2k"
pytestmark = pytest.mark.skipif(not CORPUS.is_dir(), reason=f"canboat corpus not found at {CORPUS}")

MAX_RATE_RADPS = math.radians(30.0)
NOMINAL_INTERVAL_S = 0.1
MAX_STEP_M = 1.0
EXPLAINED = {"invalid_fix", "magnetic_heading", "not_available", "unsupported_reference"}

# file, format, kinds it must give (at least that many of each), garbage lines allowed (damaged real lines)
FILES = [
    ("actisense-w2k-n2k.raw", "actisense", {"position": 2, "heading": 1, "rate_of_turn": 3, "attitude": 2}, 0),
    ("dirona-actisense-serial-head.raw", "plain", {"position": 80, "heading": 190, "rate_of_turn": 240,
                                                   "attitude": 190, "wind": 40}, 0),
    ("furuno-130842-head.fast.raw", "plain", {"rate_of_turn": 500, "attitude": 380, "course_over_ground": 60}, 0),
    ("pgn-test.plain.txt", "plain", {"position": 1, "rate_of_turn": 1}, 0),
    ("merrimac-ydwg-2020.raw", "ydwg", {"position": 27, "rate_of_turn": 51, "attitude": 26, "wind": 43}, 0),
    ("ikonvert-head.log", "ikonvert", {"heading": 460, "rate_of_turn": 460}, 3),
    ("sample3_PCAN-View-head.trc", "trc", {"position": 110, "course_over_ground": 40}, 0),
    ("can0-1-head.pcap", "pcap", {"position": 69, "heading": 28, "rate_of_turn": 110, "attitude": 84}, 0),
]

_cache: dict[tuple[str, str | None], list[dict[str, Any]]] = {}


def records(name: str, log_format: str | None = None) -> list[dict[str, Any]]:
    key = (name, log_format)
    if key not in _cache:
        _cache[key] = list(decode_nmea2000_log(CORPUS / name, log_format=log_format))
    return _cache[key]


@pytest.mark.parametrize(("name", "log_format", "kinds", "garbage"), FILES)
def test_each_format_decodes_a_real_capture(name: str, log_format: str, kinds: dict[str, int], garbage: int) -> None:
    assert detect_format((CORPUS / name).read_bytes()) == log_format
    stats: dict[str, Any] = {}
    recs = list(decode_nmea2000_log(CORPUS / name, stats))
    assert stats["format"] == log_format and recs == records(name, log_format)
    reasons = Counter(r["rejected"] for r in recs if "rejected" in r)
    assert reasons["garbage"] <= garbage and set(reasons) - {"garbage"} <= EXPLAINED, reasons
    found = Counter(r["kind"] for r in recs if "kind" in r)
    assert all(found[kind] >= count for kind, count in kinds.items()), found


def distance_m(a: dict[str, Any], b: dict[str, Any]) -> float:
    return math.dist(geodetic_to_ecef(a["lat_deg"], a["lon_deg"]), geodetic_to_ecef(b["lat_deg"], b["lon_deg"]))


# iKonvert's sample is a bench recording: its compass (magnetic, variation 0) jumps by up to 145 °/s while the
# same device's rate of turn says under 11 °/s: the sensor's jumps, not the decoder's (canboat decodes alike)
@pytest.mark.parametrize(("name", "log_format"), [(f[0], f[1]) for f in FILES if f[1] != "ikonvert"])
def test_headings_and_positions_are_continuous(name: str, log_format: str) -> None:
    previous: dict[tuple[str, str], dict[str, Any]] = {}
    for r in records(name, log_format):
        kind = r.get("kind")
        key = {"heading": "heading_rad", "attitude": "yaw_rad"}.get(kind or "")
        if key is not None and r.get(key) is not None:
            before = previous.get((kind, r["source"]))
            if before is not None:
                dt_s = abs(r["t_s"] - before["t_s"]) if "t_s" in r and "t_s" in before else NOMINAL_INTERVAL_S
                step = abs(math.remainder(r[key] - before[key], 2 * math.pi))
                assert step <= MAX_RATE_RADPS * max(dt_s, NOMINAL_INTERVAL_S), (name, r["line"], math.degrees(step))
            previous[(kind, r["source"])] = r
        if kind == "position" and r["pgn"] == 129025:
            before = previous.get(("position", r["source"]))
            if before is not None:
                assert distance_m(before, r) <= MAX_STEP_M, (name, r["line"])
            previous[("position", r["source"])] = r


# ----------------------------------------------------------------------------------------------
# canboat's own decode


def _value(field: object) -> float | None:
    value = field.get("value") if isinstance(field, dict) else field
    return float(value) if isinstance(value, int | float) and not isinstance(value, bool) else None


def _day_ms(text: str) -> int:
    match = re.search(r"(\d{2}):(\d{2}):(\d{2}(?:\.\d+)?)$", text.rstrip("Z"))
    assert match, text
    return round((int(match.group(1)) * 3600 + int(match.group(2)) * 60 + float(match.group(3))) * 1000)


def canboat_json(name: str) -> dict[tuple[int, int, int], dict[str, float | None]]:
    """canboat analyzer JSON lines → {(ms of day, pgn, source): {field: value or None}}."""
    out = {}
    for line in (CORPUS / name).read_text().splitlines():
        item = json.loads(line)
        fields = {key: _value(value) for key, value in item["fields"].items()}
        for key, value in item["fields"].items():  # the reference of 127250, by name
            if isinstance(value, str) or (isinstance(value, dict) and "name" in value):
                fields[key + ".name"] = value["name"] if isinstance(value, dict) else value
        out[(_day_ms(item["timestamp"]), item["pgn"], item["src"])] = fields
    return out


_TEXT_LINE = re.compile(r"^(\S+) +\d+ +(\d+) +\d+ +(\d+) [^:]+:  (.*)$")


def canboat_text(name: str) -> dict[tuple[int, int, int], dict[str, float | None]]:
    """canboat analyzer text output → {(ms of day, pgn, source): {field: value or None}}."""
    out = {}
    for line in (CORPUS / name).read_text().splitlines():
        match = _TEXT_LINE.match(line)
        if match is None:
            continue
        fields: dict[str, Any] = {}
        for part in match.group(4).split("; "):
            key, _, text = part.partition(" = ")
            number = re.match(r"\s*(-?\d+(?:\.\d+)?)", text)
            fields[key.strip()] = float(number.group(1)) if number else None
            fields[key.strip() + ".name"] = text.strip()
        out[(_day_ms(match.group(1)), int(match.group(3)), int(match.group(2)))] = fields
    return out


def _angle_close(ours_rad: float, theirs_deg: float | None, tolerance_deg: float) -> bool:
    return theirs_deg is not None and abs(math.remainder(math.degrees(ours_rad) - theirs_deg, 360.0)) <= tolerance_deg


def agrees(record: dict[str, Any], theirs: dict[str, Any], bus_variation: float | None = None) -> bool:
    """Our measurement equals canboat's fields of the same message, within canboat's printed resolution
    (``bus_variation`` [deg]: the 127258 variation canboat decoded last, for a magnetic heading without one)."""
    kind = record["kind"]
    if kind == "position":
        return (abs(record["lat_deg"] - theirs["Latitude"]) <= 1.5e-7
                and abs(record["lon_deg"] - theirs["Longitude"]) <= 1.5e-7)
    if kind == "heading":  # true; from a magnetic one: sensor + deviation + variation
        heading = theirs["Heading"]
        if theirs.get("Reference.name") == "Magnetic":
            variation = theirs["Variation"] if theirs.get("Variation") is not None else bus_variation
            heading += (theirs.get("Deviation") or 0.0) + variation
        return _angle_close(record["heading_rad"], heading, 0.06 * 3)
    if kind == "rate_of_turn":
        return abs(math.degrees(record["rate_radps"]) - theirs["Rate"]) <= 1e-5
    if kind == "attitude":
        return all((record.get(ours) is None and theirs.get(name) is None)
                   or _angle_close(record[ours], theirs.get(name), 0.06)
                   for ours, name in (("yaw_rad", "Yaw"), ("pitch_rad", "Pitch"), ("roll_rad", "Roll")))
    if kind == "course_over_ground":
        return ((record.get("course_rad") is None or _angle_close(record["course_rad"], theirs["COG"], 0.06))
                and (record.get("speed_mps") is None or abs(record["speed_mps"] - theirs["SOG"]) <= 0.006))
    if kind == "wind":
        return abs(record["speed_mps"] - theirs["Wind Speed"]) <= 0.006 and _angle_close(
            record["angle_rad"], theirs["Wind Angle"], 0.06)
    raise AssertionError(kind)


@pytest.mark.parametrize(("name", "decode", "reader", "minimum"), [
    ("actisense-w2k-n2k.raw", "actisense-w2k-n2k.analyzer.json", canboat_json, 11),
    ("pgn-test.plain.txt", "pgn-test.analyzer.json", canboat_json, 2),
    ("merrimac-ydwg-2020.raw", "merrimac-ydwg-2020.analyzer.txt", canboat_text, 150),
])
def test_measurements_equal_canboats_decode(name: str, decode: str, reader: Any, minimum: int) -> None:
    theirs = reader(decode)
    variations = sorted((k[0], v["Variation"]) for k, v in theirs.items()
                        if k[1] == 127258 and v.get("Variation") is not None)
    compared = 0
    for record in records(name):
        if "kind" not in record:
            continue
        key = (round(record["t_s"] * 1000) % 86_400_000, record["pgn"], int(record["source"].split(":")[1]))
        if key not in theirs:  # a fast packet: canboat stamps it with its first frame, we with its last
            key = min((k for k in theirs if k[1:] == key[1:] and 0 <= key[0] - k[0] <= 200),
                      key=lambda k: key[0] - k[0])
        bus = [variation for ms, variation in variations if ms <= key[0]]
        assert agrees(record, theirs[key], bus[-1] if bus else None), (record, theirs[key])
        compared += 1
    print(f"\n{name}: {compared} measurements equal canboat's decode")
    assert compared >= minimum


def test_every_message_canboat_decodes_and_we_drop_has_a_reason() -> None:
    """YDWG capture: a 127250/129025/127251 with values in canboat's decode is ours too, or rejected for a reason.

    Its compass sends magnetic headings without variation; two other devices send 127258 (-15.1°) from
    the first second on: the headings before the first of them are rejected, the rest are true headings."""
    theirs = canboat_text("merrimac-ydwg-2020.analyzer.txt")
    first_variation_ms = min(k[0] for k in theirs if k[1] == 127258)
    ours = {(round(r["t_s"] * 1000) % 86_400_000, r["pgn"], int(r["source"].split(":")[1])): r
            for r in records("merrimac-ydwg-2020.raw") if r.get("pgn") in (127250, 129025, 127251) and "t_s" in r}
    outcomes: Counter[str] = Counter()
    for key, fields in theirs.items():
        if key[1] not in (127250, 129025, 127251) or not any(v is not None for k, v in fields.items()
                                                           if not k.endswith(".name")):
            continue
        record = ours[key]
        outcomes[record.get("kind") or record["rejected"]] += 1
        if record.get("rejected") == "magnetic_heading":
            assert fields["Reference.name"] == "Magnetic" and fields.get("Variation") is None
            assert key[0] < first_variation_ms
    print(f"\ncanboat's usable 127250/129025/127251, ours: {dict(outcomes)}")
    assert set(outcomes) <= {"heading", "position", "rate_of_turn", "magnetic_heading", "invalid_fix"}
    assert outcomes["rate_of_turn"] == 51 and outcomes["heading"] + outcomes["magnetic_heading"] == 51
    assert outcomes["heading"] >= 40
