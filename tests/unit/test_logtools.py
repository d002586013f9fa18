"""Reading recordings (rotated, unfinished, damaged) and exporting them to CSV."""

from __future__ import annotations

import csv
import math
import re
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from mcap.reader import make_reader

from dpcontrol.logtools import export_csv, flatten, read_config, read_records
from interfaces.recorder import Recorder, RecorderSettings, list_log_files

T0_NS = 1_700_000_000_000_000_000
CONFIG = {"vessel_id": "cs2", "config_sha256": "cd" * 32, "config": {"loop": {"rate_hz": 10.0}}}
NMEA = b"$GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*47\r\n"
CAN = bytes([0x12, 0x00, 0xFF, 0x7F, 0x80, 0x01, 0x02, 0xFE])


class FakeClock:
    def __init__(self) -> None:
        self.ns = T0_NS

    def __call__(self) -> int:
        return self.ns


def _record_session(directory: Path, n: int = 30, rotate_s: float = 1.0, seed: int = 4,
                    sync_every: int = 0) -> list[dict]:
    """Record n cycles at 10 Hz (rotating every rotate_s) and return what was recorded, in order.

    ``sync_every`` cycles the recorder is made to flush, which closes a chunk.
    """
    rng = np.random.default_rng(seed)
    clock = FakeClock()
    rec = Recorder(RecorderSettings(path=str(directory), rotate_s=rotate_s, flush_s=0.2), clock, config=CONFIG)
    assert rec.wait_ready(10.0)
    made = []
    for k in range(n):
        t_s = 0.1 * k
        x = rng.normal(size=3) * 1e3
        estimate = {"eta_n": x.tolist(), "nested": {"a": {"b": float(rng.normal())}, "flag": bool(k % 2)},
                    "missing": None, "label": f"k,{k}"}
        rec.record("estimate", t_s, estimate)
        made.append({"topic": "estimate", "log_time_ns": clock.ns, "t_s": t_s, "payload": estimate})
        clock.ns += 1_000_000
        rec.record_raw("nmea0183", t_s, NMEA, log_time_ns=clock.ns)
        made.append({"topic": "raw/nmea0183", "log_time_ns": clock.ns, "t_s": t_s, "data": NMEA, "rejected": None})
        clock.ns += 1_000_000
        rejected = "not available" if k % 3 == 0 else None
        rec.record_raw("nmea2000", t_s, CAN, rejected=rejected, log_time_ns=clock.ns, can_id=0x09F80102)
        made.append({"topic": "raw/nmea2000", "log_time_ns": clock.ns, "t_s": t_s, "data": CAN,
                     "rejected": rejected, "can_id": 0x09F80102})
        clock.ns += 98_000_000
        if sync_every and k % sync_every == sync_every - 1:
            assert rec.sync(10.0)
    assert rec.close(10.0)
    return made


def test_read_records_across_rotated_files_in_order_with_topic_filter(tmp_path: Path) -> None:
    made = _record_session(tmp_path, n=30, rotate_s=1.0)
    files = list_log_files(tmp_path)
    assert len(files) == 3
    got = [(r.topic, r.log_time_ns, r.t_s) for r in read_records(tmp_path, ["estimate", "raw/nmea2000"])]
    assert got == [(m["topic"], m["log_time_ns"], m["t_s"]) for m in made if m["topic"] != "raw/nmea0183"]
    raw = [r for r in read_records(tmp_path, ["raw/nmea2000"])]
    assert [r.data for r in raw] == [CAN] * 30
    assert [r.payload["rejected"] for r in raw] == [m["rejected"] for m in made if m["topic"] == "raw/nmea2000"]
    assert read_config(tmp_path) == CONFIG
    with pytest.raises(FileNotFoundError):
        list(read_records(tmp_path / "nowhere"))


def _cell(value: object) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    return str(value)


def test_export_csv_flattens_every_topic_and_reads_back_exactly(tmp_path: Path) -> None:
    made = _record_session(tmp_path / "log", n=25, rotate_s=1.0)
    paths = export_csv(tmp_path / "log", tmp_path / "csv")
    assert paths == sorted((tmp_path / "csv").iterdir())
    assert {p.name for p in paths} == {"config.csv", "estimate.csv", "raw_nmea0183.csv", "raw_nmea2000.csv",
                                       "raw.csv", "recorder.csv"}

    with open(tmp_path / "csv" / "estimate.csv", newline="") as handle:
        reader = csv.DictReader(handle)
        rows = list(reader)
    assert reader.fieldnames == ["log_time_ns", "t_s", "eta_n[0]", "eta_n[1]", "eta_n[2]", "nested.a.b",
                                 "nested.flag", "missing", "label"]
    estimates = [m for m in made if m["topic"] == "estimate"]
    assert len(rows) == len(estimates)
    for row, m in zip(rows, estimates, strict=True):
        p = m["payload"]
        assert int(row["log_time_ns"]) == m["log_time_ns"]
        assert float(row["t_s"]) == m["t_s"]
        assert [float(row[f"eta_n[{i}]"]) for i in range(3)] == p["eta_n"]  # exact: floats round-trip
        assert float(row["nested.a.b"]) == p["nested"]["a"]["b"]
        assert row["nested.flag"] == _cell(p["nested"]["flag"])
        assert row["missing"] == "" and row["label"] == p["label"]

    with open(tmp_path / "csv" / "raw.csv", newline="") as handle:
        reader = csv.DictReader(handle)
        raw_rows = list(reader)
    assert reader.fieldnames is not None and reader.fieldnames[:3] == ["log_time_ns", "t_s", "topic"]
    raw_made = [m for m in made if m["topic"].startswith("raw/")]
    assert [(r["topic"], int(r["log_time_ns"])) for r in raw_rows] == [(m["topic"], m["log_time_ns"])
                                                                         for m in raw_made]
    for row, m in zip(raw_rows, raw_made, strict=True):
        assert bytes.fromhex(row["data_hex"]) == m["data"]
        assert row["rejected"] == _cell(m["rejected"])
        assert row["data_text"] == (NMEA.decode().strip() if m["data"] == NMEA else "")
        assert row["can_id"] == _cell(m.get("can_id"))


def _get(value: object, path: str) -> object:
    """Follow a flattened column name ``a.b[0].c`` into a nested value (test oracle)."""
    for key, index in re.findall(r"([^.\[\]]+)|\[(\d+)\]", path):
        value = value[int(index)] if index else value[key]  # type: ignore[index]
    return value


_scalars = st.none() | st.booleans() | st.integers(-10**6, 10**6) | st.floats(allow_nan=False) | st.text(max_size=5)
_keys = st.text(alphabet="abcxyz_", min_size=1, max_size=4)
_json = st.recursive(_scalars, lambda inner: st.lists(inner, max_size=4) | st.dictionaries(_keys, inner, max_size=4),
                     max_leaves=25)


@settings(max_examples=150, deadline=None)
@given(st.dictionaries(_keys, _json, max_size=5))
def test_flatten_keeps_every_leaf_once_at_its_path(value: dict) -> None:
    flat = flatten(value)
    for path, leaf in flat.items():
        assert _get(value, path) == leaf or (isinstance(leaf, float) and math.isnan(leaf))

    def leaves(v: object) -> int:
        if isinstance(v, dict):
            return sum(leaves(x) for x in v.values())
        if isinstance(v, list):
            return sum(leaves(x) for x in v)
        return 1

    assert len(flat) == leaves(value)


def test_truncated_file_at_any_point_reads_a_prefix_and_never_raises(tmp_path: Path) -> None:
    _record_session(tmp_path / "log", n=40, rotate_s=100.0, sync_every=5)
    (path,) = list_log_files(tmp_path / "log")
    data = path.read_bytes()
    full = [(r.topic, r.log_time_ns) for r in read_records(path)]
    cut_file = tmp_path / "cut.mcap"
    rng = np.random.default_rng(5)
    cuts = sorted({*rng.integers(0, len(data), 60).tolist(), 0, 7, 8, 9, len(data) - 1})
    previous = 0
    lengths = []
    for cut in cuts:
        cut_file.write_bytes(data[:cut])
        issues: list[str] = []
        got = [(r.topic, r.log_time_ns) for r in read_records(cut_file, on_issue=lambda p, m, i=issues: i.append(m))]
        assert got == full[:len(got)]
        assert len(got) >= previous
        previous = len(got)
        lengths.append(len(got))
        if len(got) < len(full):
            assert issues  # a shortened file is always reported
    assert lengths[-1] == len(full)  # only the final magic byte missing: everything is there
    assert len({n for n in lengths if 0 < n < len(full)}) >= 3  # cuts landed in several chunks


def test_damaged_chunk_is_skipped_and_reported_the_rest_is_read(tmp_path: Path) -> None:
    _record_session(tmp_path / "log", n=40, rotate_s=100.0, sync_every=5)
    (path,) = list_log_files(tmp_path / "log")
    full = [(r.topic, r.log_time_ns) for r in read_records(path)]
    with open(path, "rb") as stream:
        summary = make_reader(stream).get_summary()
    assert summary is not None and len(summary.chunk_indexes) >= 3
    damaged = summary.chunk_indexes[len(summary.chunk_indexes) // 2]
    data = bytearray(path.read_bytes())
    data[damaged.chunk_start_offset + damaged.chunk_length - 10] ^= 0xFF  # inside the compressed data
    path.write_bytes(bytes(data))
    issues: list[str] = []
    got = [(r.topic, r.log_time_ns) for r in read_records(path, on_issue=lambda p, m: issues.append(m))]
    lost = [m for m in full if damaged.message_start_time <= m[1] <= damaged.message_end_time]
    assert lost
    assert got == [m for m in full if m not in lost]
    assert len(issues) == 1 and "damaged chunk" in issues[0]


def test_a_killed_empty_file_and_a_junk_file_do_not_stop_reading_a_directory(tmp_path: Path) -> None:
    made = _record_session(tmp_path, n=20, rotate_s=1.0)
    files = list_log_files(tmp_path)
    empty = tmp_path / (files[0].name[:-9] + "9998.mcap")  # sorts after the first file
    empty.write_bytes(b"")
    junk = tmp_path / (files[-1].name[:-9] + "9999.mcap")
    junk.write_bytes(b"not an mcap file at all")
    issues: list[tuple[Path, str]] = []
    got = [r.log_time_ns for r in read_records(tmp_path, ["estimate"], on_issue=lambda p, m: issues.append((p, m)))]
    assert got == [m["log_time_ns"] for m in made if m["topic"] == "estimate"]
    assert {p for p, _ in issues} == {empty, junk}
