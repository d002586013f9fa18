"""Black-box recorder: round trip of every topic, the bounded non-blocking queue, rotation, disk bound.

Unwritable paths and crashes are in ``test_recorder_faults.py``.
"""

from __future__ import annotations

import math
import statistics
import threading
import time
from pathlib import Path

import numpy as np
import orjson
import pytest
from mcap.data_stream import ReadDataStream
from mcap.reader import make_reader
from mcap.records import Chunk, Message
from mcap.stream_reader import breakup_chunk

import interfaces.recorder as recorder_module
from dpcontrol.logtools import read_records
from interfaces.recorder import (
    Recorder,
    RecorderSettings,
    TopicSpec,
    default_topics,
    list_log_files,
    log_file_name,
    raw_topic,
)

T0_NS = 1_700_000_000_000_000_000


class FakeClock:
    """A stepped record clock [ns] (the writer thread only reads it)."""

    def __init__(self, start_ns: int = T0_NS) -> None:
        self.ns = start_ns

    def __call__(self) -> int:
        return self.ns

    def advance(self, seconds: float) -> None:
        self.ns += round(seconds * 1e9)


def settings(path: Path, **overrides: float) -> RecorderSettings:
    values = {"max_file_mb": 256.0, "max_total_mb": 4096.0, "rotate_s": 3600.0, "flush_s": 0.2, "queue_size": 10000}
    values.update(overrides)
    return RecorderSettings(path=str(path), **values)  # type: ignore[arg-type]


def summary_of(path: Path):
    with open(path, "rb") as stream:
        return make_reader(stream).get_summary()


def chunk_topics(path: Path, summary, chunk_indexes) -> set[str]:
    """Topics of the messages in the given chunks (read at their indexed offsets)."""
    topics = set()
    with open(path, "rb") as stream:
        for index in chunk_indexes:
            stream.seek(index.chunk_start_offset + 1 + 8)  # opcode and record length
            chunk = Chunk.read(ReadDataStream(stream))
            topics |= {summary.channels[r.channel_id].topic for r in breakup_chunk(chunk) if isinstance(r, Message)}
    return topics


CONFIG = {"vessel_id": "cs2", "config_sha256": "ab" * 32, "config": {"loop": {"rate_hz": 10.0}}, "text": "loop: {}\n"}


def _payload(topic: str, k: int, rng: np.random.Generator) -> dict:
    x = rng.normal(size=3)
    return {
        "estimate": {"eta_n": np.array([x[0], x[1], math.pi * x[2]]), "nu_b": x.tolist(),
                     "P_diag": np.abs(rng.normal(size=15)), "valid": True},
        "mmae": {"omegas_rad_s": [0.3, 0.6, 0.9], "weights": rng.dirichlet(np.ones(3)).tolist(),
                 "omega_hat_rad_s": float(rng.uniform(0.3, 0.9))},
        "reference": {"eta_ref_n": x.tolist(), "setpoint_n": [10.0, 0.0, 0.0]},
        "control": {"tau_b": (1e4 * x).tolist(), "mrac": {"theta": x[:2].tolist(), "gamma": 0.1}},
        "allocation": {"thrust_n": rng.normal(size=4).tolist(), "azimuth_rad": [0.0, None, 1.0, -1.0],
                       "status": "optimal"},
        "command": {"schema": "dpcontrol.thrusters.command/1", "seq": k,
                    "thrusters": [{"name": "t1", "thrust_n": float(x[0])}]},
        "mode": {"mode": "auto_position", "previous": "standby", "reason": "operator"},
        "alarm": {"code": "GNSS1_FROZEN", "severity": "alarm", "text": "gnss1 frozen", "raised": k % 2 == 0},
        "status": {"mode": "auto_position", "cycle_us": {"p50": 120.0}, "sensors": {"gnss1": "ok"}},
        "replay": {"software": "dpcontrol 0.1.0", "seed": 7},
        "config": CONFIG,
    }.get(topic, {"k": k})


def _expected(t_s: float, payload: dict) -> dict:
    """What the JSON message holds: t_s first, arrays as lists, NaN/inf as null."""
    return orjson.loads(orjson.dumps({"t_s": t_s, **payload}, option=orjson.OPT_SERIALIZE_NUMPY))


def test_every_topic_round_trips_with_raw_bytes_and_rejected_inputs(tmp_path: Path) -> None:
    rng = np.random.default_rng(1)
    clock = FakeClock()
    errors: list = []
    rec = Recorder(settings(tmp_path), clock, errors.append, config=CONFIG)
    assert rec.wait_ready(10.0)
    expected: list[tuple[str, int, dict]] = []
    raw_inputs = {
        "nmea0183": (b"$GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*47\r\n", None),
        "nmea2000": (bytes([0x12, 0xFF, 0x00, 0x80, 0x7F, 0x01, 0xFE, 0x0A]), "not available"),
        "mavlink": (bytes.fromhex("fd1c000001010121000000"), "bad CRC"),
    }
    topics = [spec.topic for spec in default_topics() if not spec.topic.startswith("raw/") and spec.topic != "recorder"]
    for k in range(3):
        t_s = 0.1 * k
        for transport, (data, rejected) in raw_inputs.items():
            receive_ns = clock() - 1000  # received just before the loop stamped it
            assert rec.record_raw(transport, t_s, data, rejected=rejected, log_time_ns=receive_ns, source="gnss1")
            expected.append((raw_topic(transport), receive_ns,
                             {"t_s": t_s, "rejected": rejected, "source": "gnss1", "data_hex": data.hex()}))
        for topic in topics:
            payload = _payload(topic, k, rng)
            assert rec.record(topic, t_s, payload)
            expected.append((topic, clock(), _expected(t_s, payload)))
            clock.advance(0.001)
        clock.advance(0.1)
    assert rec.record("estimate", 0.5, {"eta_n": [float("nan"), 1.0, float("inf")]})  # never NaN in a message
    expected.append(("estimate", clock(), {"t_s": 0.5, "eta_n": [None, 1.0, None]}))
    assert rec.record(raw_topic("nmea0183"), 0.5, b"\x00\x01binary")  # a bare bytes payload
    expected.append((raw_topic("nmea0183"), clock(), {"t_s": 0.5, "data_hex": b"\x00\x01binary".hex()}))
    assert rec.close(5.0)
    assert errors == []
    assert rec.health.state == "closed" and rec.dropped == 0

    files = list_log_files(tmp_path)
    assert len(files) == 1
    issues: list = []
    records = list(read_records(tmp_path, on_issue=lambda path, message: issues.append(message)))
    assert issues == []
    assert records[0].topic == "config" and records[0].payload == {"t_s": None, **CONFIG}
    loop_records = [r for r in records[1:] if r.topic != "recorder"]
    assert [(r.topic, r.log_time_ns, r.payload) for r in loop_records] == expected
    rejected = [r for r in loop_records if r.topic == raw_topic("mavlink")]
    assert all(r.data == raw_inputs["mavlink"][0] and r.payload["rejected"] == "bad CRC" for r in rejected)

    summary = summary_of(files[0])  # finished: indexed, with statistics and the declared channels
    assert summary is not None and summary.chunk_indexes
    assert summary.statistics.message_count == len(records)
    declared = {spec.topic for spec in default_topics()}
    channels = {c.topic: c for c in summary.channels.values()}
    assert declared <= set(channels)
    for channel in channels.values():
        assert channel.message_encoding == "json"
        schema = summary.schemas[channel.schema_id]
        assert schema.encoding == "jsonschema"
        assert orjson.loads(schema.data)["properties"]["t_s"]["type"] == ["number", "null"]
    with open(files[0], "rb") as stream:
        metadata = list(make_reader(stream).iter_metadata())
    assert metadata[0].metadata["config_sha256"] == CONFIG["config_sha256"]


class BreakableClock(FakeClock):
    broken = False

    def __call__(self) -> int:
        if self.broken:
            raise RuntimeError("clock failed")
        return self.ns


def test_undeclared_topics_and_bad_records_never_raise_and_are_counted(tmp_path: Path) -> None:
    errors: list = []
    clock = BreakableClock()
    rec = Recorder(settings(tmp_path), clock, errors.append,
                   topics=[TopicSpec("estimate", "dpcontrol.estimate", "estimate")])
    assert rec.wait_ready(10.0)
    assert rec.record("my/new_topic", 1.0, {"x": 1})  # recorded on a channel made on first use
    assert rec.record("estimate", 1.0, {"x": object()})  # unserialisable: dropped in the writer, reported
    assert rec.record("estimate", 1.0, {"x": object()})  # reported once per topic
    assert rec.record("estimate", 1.0, [1, 2, 3])  # type: ignore[arg-type]  # neither a mapping nor bytes
    assert rec.record(42, 1.0, {})  # type: ignore[arg-type]
    assert rec.record("estimate", 1.0, {"x": 2}, log_time_ns=-5)
    assert rec.record("estimate", 2.0, {"ok": True})
    clock.broken = True  # the clock failing must not reach the loop either
    assert rec.record("estimate", 3.0, {"lost": True}) is False
    clock.broken = False
    assert rec.sync(5.0)
    stats = rec.stats()
    assert stats["dropped_by_reason"] == {"invalid": 5, "error": 1}
    assert rec.health.ok
    assert rec.close(5.0)
    kinds = [e.kind for e in errors]
    assert kinds == ["payload", "payload"]  # "estimate" once, the non-string topic once
    got = [(r.topic, r.payload) for r in read_records(tmp_path) if r.topic not in ("config", "recorder")]
    assert got == [("my/new_topic", {"t_s": 1.0, "x": 1}), ("estimate", {"t_s": 2.0, "ok": True})]


class GatedFile:
    """A recorder file whose writes wait for a gate: stands for a hung or very slow disk."""

    def __init__(self, path: Path, gate: threading.Event) -> None:
        self._file = open(path, "xb")  # noqa: SIM115
        self._gate = gate

    def write(self, data: bytes) -> int:
        self._gate.wait()
        return self._file.write(data)

    def tell(self) -> int:
        return self._file.tell()

    def flush(self) -> None:
        self._file.flush()

    def fileno(self) -> int:
        return self._file.fileno()

    def close(self) -> None:
        self._file.close()


def test_full_queue_drops_and_counts_without_blocking_the_producer(tmp_path: Path,
                                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    gate = threading.Event()
    monkeypatch.setattr(recorder_module, "_open_output", lambda path: GatedFile(path, gate))
    capacity, n = 200, 5000
    rec = Recorder(settings(tmp_path, queue_size=capacity), FakeClock())
    # The writer is stuck writing the file header; if record() ever blocked, this thread would
    # never reach gate.set() and the watchdog would have to open the gate.
    watchdog = threading.Timer(30.0, gate.set)
    watchdog.start()
    durations_ns = []
    accepted = 0
    for k in range(n):
        start = time.perf_counter_ns()
        accepted += rec.record("estimate", 0.1 * k, {"k": k})
        durations_ns.append(time.perf_counter_ns() - start)
    opened_by_watchdog = gate.is_set()
    gate.set()
    watchdog.cancel()
    assert not opened_by_watchdog
    assert accepted == capacity
    assert rec.dropped == n - capacity
    assert rec.stats()["dropped_by_reason"] == {"queue_full": n - capacity}
    p50_us = statistics.median(durations_ns) / 1e3
    assert p50_us < 20.0, f"record() median {p50_us:.1f} µs"  # typically well under 1 µs
    assert rec.close(10.0)
    ks = [r.payload["k"] for r in read_records(tmp_path, ["estimate"])]
    assert ks == list(range(capacity))  # the first `capacity` records, in order, nothing else


def test_drop_counts_are_exact_with_concurrent_producers(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    gate = threading.Event()
    monkeypatch.setattr(recorder_module, "_open_output", lambda path: GatedFile(path, gate))
    capacity, n_threads, n_each = 50, 4, 3000
    rec = Recorder(settings(tmp_path, queue_size=capacity), FakeClock())
    accepted = [0] * n_threads

    def produce(index: int) -> None:
        for k in range(n_each):
            accepted[index] += rec.record(f"raw/t{index}", float(k), {"k": k})

    threads = [threading.Thread(target=produce, args=(i,)) for i in range(n_threads)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(30.0)
    gate.set()
    total_accepted = sum(accepted)
    # qsize() is checked before put(): concurrent producers may each pass the check once
    assert capacity <= total_accepted <= capacity + n_threads - 1
    assert rec.dropped == n_threads * n_each - total_accepted
    by_topic = rec.stats()["dropped_by_topic"]
    assert by_topic == {f"raw/t{i}": n_each - accepted[i] for i in range(n_threads) if accepted[i] < n_each}
    assert rec.close(10.0)
    assert sum(1 for r in read_records(tmp_path) if r.topic.startswith("raw/t")) == total_accepted


def test_close_is_bounded_in_time_when_the_disk_hangs(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    gate = threading.Event()
    monkeypatch.setattr(recorder_module, "_open_output", lambda path: GatedFile(path, gate))
    rec = Recorder(settings(tmp_path), FakeClock())
    for k in range(100):
        rec.record("estimate", float(k), {"k": k})
    start = time.monotonic()
    finished = rec.close(0.3)
    elapsed = time.monotonic() - start
    gate.set()  # let the stuck writer go so the thread ends
    assert finished is False
    assert elapsed < 2.0
    assert rec.record("estimate", 1.0, {}) is False  # closed: refused and counted
    assert rec.stats()["dropped_by_reason"].get("closed") == 1


def test_rotation_by_size_keeps_loop_records_within_the_limit(tmp_path: Path) -> None:
    rng = np.random.default_rng(2)
    max_mb = 0.03
    limit = int(max_mb * 1e6)
    rec = Recorder(settings(tmp_path, max_file_mb=max_mb, flush_s=0.05), FakeClock(), config=CONFIG)
    assert rec.wait_ready(10.0)
    n = 1500
    for k in range(n):
        rec.record("estimate", 0.1 * k, {"k": k, "P_diag": rng.normal(size=12)})  # noise: compresses badly
        if k % 100 == 99:
            assert rec.sync(10.0)
    assert rec.close(10.0)
    files = list_log_files(tmp_path)
    assert len(files) >= 3
    for path in files[:-1]:
        assert path.stat().st_size >= limit  # rotated only when full
    for path in files:
        summary = summary_of(path)
        assert summary is not None  # every rotated file is finished (indexed)
        late = [c for c in summary.chunk_indexes if c.chunk_start_offset >= limit]
        assert chunk_topics(path, summary, late) <= {"recorder"}  # no loop record once the file was full
        first = next(read_records(path))
        assert first.topic == "config" and first.payload["config_sha256"] == CONFIG["config_sha256"]
    ks = [r.payload["k"] for r in read_records(tmp_path, ["estimate"])]
    assert ks == list(range(n))


def test_rotation_by_time_from_the_first_record_of_each_file(tmp_path: Path) -> None:
    clock = FakeClock()
    rec = Recorder(settings(tmp_path, rotate_s=10.0), clock, config=CONFIG)
    assert rec.wait_ready(10.0)
    for k in range(35):
        rec.record("estimate", float(k), {"k": k})
        clock.advance(1.0)
    assert rec.close(10.0)
    files = list_log_files(tmp_path)
    assert [[r.payload["k"] for r in read_records(f, ["estimate"])] for f in files] == [
        list(range(0, 10)), list(range(10, 20)), list(range(20, 30)), list(range(30, 35))]
    for path in files:
        assert next(read_records(path)).topic == "config"


def test_max_total_deletes_only_the_oldest_recorder_files(tmp_path: Path) -> None:
    rng = np.random.default_rng(3)
    old = [tmp_path / log_file_name(T0_NS - (10 - i) * 3600 * 10**9, 0) for i in range(3)]
    for path in old:
        path.write_bytes(b"\0" * 20_000)
    other = tmp_path / "notes.txt"
    other.write_bytes(b"\0" * 50_000)
    max_file_mb, max_total_mb = 0.02, 0.07
    rec = Recorder(settings(tmp_path, max_file_mb=max_file_mb, max_total_mb=max_total_mb, flush_s=0.05), FakeClock())
    assert rec.wait_ready(10.0)
    # Old files (60 kB) + a new full file (20 kB) exceed 70 kB: the oldest one goes at once.
    assert not old[0].exists() and old[1].exists() and old[2].exists()
    n = 2000
    for k in range(n):
        rec.record("estimate", 0.1 * k, {"k": k, "noise": rng.normal(size=8)})
        if k % 100 == 99:
            assert rec.sync(10.0)
    assert rec.close(10.0)
    assert other.exists()  # not a recorder file: never deleted
    assert not any(p.exists() for p in old)
    files = list_log_files(tmp_path)
    assert len(files) >= 2
    sizes = [p.stat().st_size for p in files]
    assert sum(sizes[:-1]) + int(max_file_mb * 1e6) <= int(max_total_mb * 1e6)
    assert rec.stats()["files_deleted"] >= 3
    ks = [r.payload["k"] for r in read_records(tmp_path, ["estimate"])]
    assert ks == list(range(ks[0], n))  # what is left is the most recent, contiguous tail
    assert ks[0] > 0


def test_file_names_sort_by_time_even_when_the_wall_clock_steps_back(tmp_path: Path) -> None:
    wall = [T0_NS + 5 * 10**9]
    clock = FakeClock()
    rec = Recorder(settings(tmp_path, rotate_s=1.0), clock, wall_clock=lambda: wall[0])
    assert rec.wait_ready(10.0)
    for k in range(4):
        rec.record("estimate", float(k), {"k": k})
        clock.advance(1.0)
        wall[0] -= 3600 * 10**9  # the wall clock steps back an hour at every rotation
    assert rec.close(10.0)
    names = [p.name for p in list_log_files(tmp_path)]
    assert names == sorted(names) and len(set(names)) == 4
    assert names[0] == log_file_name(T0_NS + 5 * 10**9, 0)
    assert [[r.payload["k"] for r in read_records(tmp_path / name, ["estimate"])] for name in names] == [
        [0], [1], [2], [3]]


def test_disabled_recorder_accepts_nothing_and_counts_nothing() -> None:
    rec = Recorder(RecorderSettings(path=None))
    assert rec.record("estimate", 0.0, {"x": 1}) is False
    assert rec.health.state == "disabled" and rec.health.ok and rec.dropped == 0
    assert rec.close(1.0)


def test_unfinished_file_is_readable_while_recording(tmp_path: Path) -> None:
    rec = Recorder(settings(tmp_path), FakeClock(), config=CONFIG)
    assert rec.wait_ready(10.0)
    for k in range(50):
        rec.record("estimate", float(k), {"k": k})
    assert rec.sync(10.0)  # flushed to the OS, file not finished
    issues: list = []
    ks = [r.payload["k"] for r in read_records(tmp_path, ["estimate"], on_issue=lambda p, m: issues.append(m))]
    assert ks == list(range(50))
    assert len(issues) == 1 and "unfinished" in issues[0]
    with open(rec.current_file, "rb") as stream:  # type: ignore[arg-type]
        assert stream.read()[-8:] != b"\x89MCAP0\r\n"  # really no footer yet
    assert rec.close(5.0)
    assert summary_of(list_log_files(tmp_path)[0]) is not None
