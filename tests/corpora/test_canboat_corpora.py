"""Real NMEA 2000 traffic (canboat samples): every capture decodes, and what it decodes is continuous.

The three captures (``shared/corpora/canboat-n2k``) are in the three candump formats. Checks:

* every line is a frame or metadata (no ``garbage``), nothing fails to decode;
* **positions**: consecutive 129025 rapid updates of one source never jump more than 1 m, except
  across a position epoch in which the receiver's satellite count changed (sample 1 starts at
  power-up: its 1.47 m and 1.10 m steps come exactly when the Garmin 17X goes from 6 to 7 and from
  7 to 8 satellites — a real change of solution, not a decoding error; at most two are allowed);
  and every 129025 agrees with its source's latest 129029 within 2 cm — two independent
  encodings of the same epoch (int32 × 1e-7° and int64 × 1e-16°; 2 cm is one 1e-7° step in
  each axis, as a sender may truncate instead of rounding);
* **headings**: consecutive true headings (127250) and attitude yaws (127257) of one source
  differ by at most ``30 °/s × Δt`` (modulo 2π), Δt from the capture's timestamps or, where the
  format has none, the 100 ms interval these PGNs are sent at. 30 °/s is faster than any ship
  turns (large vessels turn a few °/s, fast craft ~20 °/s), while a decoding error — wrong
  scale, byte order, sign or offset — moves the value by tens of degrees;
* sample 3's compass sends *magnetic* 127250 without variation: all rejected as
  ``magnetic_heading`` (only a true heading is a heading measurement), never passed on.
"""

from __future__ import annotations

import math
from collections import Counter, defaultdict
from pathlib import Path
from typing import Any

import pytest

from dpbase.geodesy import geodetic_to_ecef
from interfaces.nmea2000.logs import decode_candump_log

CORPUS = Path(__file__).parents[2] / "tests" / "corpora" / "data" / "canboat-n2k"
SAMPLES = ["candumpSample1.txt", "candumpSample2.txt", "candumpSample3.txt"]
MAX_RATE_RADPS = math.radians(30.0)
NOMINAL_INTERVAL_S = 0.1
MAX_STEP_M = 1.0
RAPID_VS_FULL_M = 0.02

pytestmark = pytest.mark.skipif(not CORPUS.is_dir(), reason=f"canboat corpus not found at {CORPUS}")

_cache: dict[str, list[dict[str, Any]]] = {}


def records(name: str) -> list[dict[str, Any]]:
    if name not in _cache:
        _cache[name] = list(decode_candump_log(CORPUS / name))
    return _cache[name]


def distance_m(a: dict[str, Any], b: dict[str, Any]) -> float:
    return math.dist(geodetic_to_ecef(a["lat_deg"], a["lon_deg"]), geodetic_to_ecef(b["lat_deg"], b["lon_deg"]))


@pytest.mark.parametrize("name", SAMPLES)
def test_capture_decodes_cleanly(name: str) -> None:
    recs = records(name)
    reasons = Counter(r["rejected"] for r in recs if "rejected" in r)
    assert reasons.keys() <= {"invalid_fix", "magnetic_heading"}, reasons
    assert sum(1 for r in recs if r.get("kind") == "position") > 40
    assert all(abs(r["lat_deg"]) <= 90 and abs(r["lon_deg"]) <= 180 for r in recs if r.get("kind") == "position")


def test_expected_content() -> None:
    kinds = {name: Counter(r.get("kind") for r in records(name) if "kind" in r) for name in SAMPLES}
    assert kinds["candumpSample1.txt"].keys() == {"position", "course_over_ground"}
    assert kinds["candumpSample2.txt"].keys() == {"position", "course_over_ground", "heading", "rate_of_turn",
                                                  "wind", "attitude"}
    assert kinds["candumpSample3.txt"].keys() == {"position", "course_over_ground", "rate_of_turn", "wind",
                                                  "attitude"}
    # sample 1 begins at power-up: the receiver reports "no GNSS" and its stale rapid updates are refused
    invalid = Counter(r["pgn"] for r in records("candumpSample1.txt") if r.get("rejected") == "invalid_fix")
    assert invalid[129029] == 4 and invalid[129025] > 0
    first_valid = min(r["line"] for r in records("candumpSample1.txt") if r.get("kind") == "position")
    assert all(r["line"] < first_valid for r in records("candumpSample1.txt") if r.get("rejected"))


@pytest.mark.parametrize("name", SAMPLES)
def test_rapid_positions_are_continuous(name: str) -> None:
    previous: dict[str, dict[str, Any]] = {}
    latest_full: dict[str, dict[str, Any]] = {}
    satellites_changed: dict[str, bool] = defaultdict(bool)
    excused = checked = 0
    for r in records(name):
        if r.get("kind") != "position":
            continue
        source = r["source"]
        if r["pgn"] == 129029:
            before = latest_full.get(source)
            satellites_changed[source] = before is not None and before.get("num_satellites") != r.get("num_satellites")
            latest_full[source] = r
            continue
        if source in latest_full:
            assert distance_m(r, latest_full[source]) <= RAPID_VS_FULL_M, (name, r["line"])
        if source in previous:
            step = distance_m(previous[source], r)
            checked += 1
            if step > MAX_STEP_M:
                assert satellites_changed[source], (name, r["line"], step)
                excused += 1
        previous[source] = r
        satellites_changed[source] = False  # the excuse covers the first rapid update of the new epoch only
    assert checked > 40 and excused <= 2


@pytest.mark.parametrize(("name", "kind", "key"), [
    ("candumpSample2.txt", "heading", "heading_rad"),
    ("candumpSample3.txt", "attitude", "yaw_rad"),
])
def test_headings_are_continuous(name: str, kind: str, key: str) -> None:
    previous: dict[str, dict[str, Any]] = {}
    checked = 0
    for r in records(name):
        if r.get("kind") != kind or r.get(key) is None:
            continue
        value = r[key]
        assert (0.0 <= value < 2 * math.pi) if kind == "heading" else (-math.pi < value <= math.pi)
        before = previous.get(r["source"])
        if before is not None:
            dt_s = (r["t_s"] - before["t_s"]) if "t_s" in r else NOMINAL_INTERVAL_S
            step = abs(math.remainder(value - before[key], 2 * math.pi))
            assert step <= MAX_RATE_RADPS * max(dt_s, NOMINAL_INTERVAL_S), (name, r["line"], math.degrees(step))
            checked += 1
        previous[r["source"]] = r
    assert checked >= 4


def test_magnetic_heading_without_variation_is_never_a_heading() -> None:
    recs = records("candumpSample3.txt")
    assert not any(r.get("kind") == "heading" for r in recs)
    assert sum(1 for r in recs if r.get("rejected") == "magnetic_heading" and r["pgn"] == 127250) == 175
