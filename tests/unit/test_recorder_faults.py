"""Recorder under faults: unwritable paths, full/read-only disks, and a SIGKILL of the recording process."""

from __future__ import annotations

import errno
import os
import signal
import statistics
import subprocess
import sys
import textwrap
import threading
import time
from pathlib import Path

import pytest

import interfaces.recorder as recorder_module
from dpcontrol.logtools import read_records
from interfaces.recorder import Recorder, RecorderSettings, list_log_files

ROOT = Path(__file__).resolve().parents[2]


def settings(path: Path, **overrides: float) -> RecorderSettings:
    values = {"max_file_mb": 256.0, "max_total_mb": 4096.0, "rotate_s": 3600.0, "flush_s": 0.2, "queue_size": 1000}
    values.update(overrides)
    return RecorderSettings(path=str(path), **values)  # type: ignore[arg-type]


class Watcher:
    """Collects on_error reports and signals recovery (both called from the writer thread)."""

    def __init__(self) -> None:
        self.errors: list[recorder_module.RecorderError] = []
        self.recovered = threading.Event()

    def on_error(self, error: recorder_module.RecorderError) -> None:
        self.errors.append(error)

    def on_recovered(self) -> None:
        self.recovered.set()


def _record_quickly(rec: Recorder, n: int, start: int) -> float:
    """Record n records (each must be accepted); return the median call time [µs]."""
    durations = []
    for k in range(start, start + n):
        t0 = time.perf_counter_ns()
        assert rec.record("estimate", float(k), {"k": k}) is True
        durations.append(time.perf_counter_ns() - t0)
    return statistics.median(durations) / 1e3


def test_path_under_a_file_reports_counts_drops_and_resumes_when_fixed(tmp_path: Path) -> None:
    blocker = tmp_path / "logs"
    blocker.write_text("a file where the recording directory should be")
    watcher = Watcher()
    rec = Recorder(settings(blocker / "rec"), on_error=watcher.on_error, retry_s=0.05,
                   on_recovered=watcher.on_recovered)
    assert rec.wait_ready(10.0) is False
    health = rec.health
    assert not health.ok and health.state == "unwritable"
    assert health.error is not None and health.error.errno_name == "ENOTDIR"
    assert str(blocker) in health.error.message
    assert [e.kind for e in watcher.errors] == ["open"]  # reported once, not at every retry

    assert _record_quickly(rec, 200, 0) < 20.0  # µs: queued, never waiting for the failing disk
    assert rec.sync(5.0) is False  # processed, but not written
    assert rec.stats()["dropped_by_reason"] == {"unwritable": 200}
    assert len(watcher.errors) == 1

    blocker.unlink()  # the operator fixes the path
    assert watcher.recovered.wait(10.0)
    assert rec.health.ok and rec.health.state == "recording"
    _record_quickly(rec, 10, 200)
    assert rec.close(5.0)
    records = list(read_records(blocker / "rec"))
    assert [r.payload["k"] for r in records if r.topic == "estimate"] == list(range(200, 210))
    first_status = next(r for r in records if r.topic == "recorder")
    assert first_status.payload["dropped_by_reason"] == {"unwritable": 200}  # the gap is explained in the log
    assert "ENOTDIR" in first_status.payload["last_error"]


@pytest.mark.skipif(hasattr(os, "geteuid") and os.geteuid() == 0, reason="root ignores directory permissions")
def test_read_only_directory_reports_eacces_and_resumes(tmp_path: Path) -> None:
    directory = tmp_path / "rec"
    directory.mkdir()
    directory.chmod(0o555)
    watcher = Watcher()
    try:
        rec = Recorder(settings(directory), on_error=watcher.on_error, retry_s=0.05, on_recovered=watcher.on_recovered)
        assert rec.wait_ready(10.0) is False
        assert rec.health.error is not None and rec.health.error.errno_name == "EACCES"
        _record_quickly(rec, 20, 0)
        assert rec.sync(5.0) is False
        assert rec.dropped == 20
    finally:
        directory.chmod(0o755)
    assert watcher.recovered.wait(10.0)
    _record_quickly(rec, 5, 20)
    assert rec.close(5.0)
    assert [r.payload["k"] for r in read_records(directory, ["estimate"])] == list(range(20, 25))


@pytest.mark.parametrize("code", [errno.ENOSPC, errno.EACCES, errno.EROFS])
def test_open_failures_are_reported_by_errno_and_retried(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                         code: int) -> None:
    failing = threading.Event()
    failing.set()
    real_open = recorder_module._open_output

    def open_output(path: Path):
        if failing.is_set():
            raise OSError(code, os.strerror(code), str(path))
        return real_open(path)

    monkeypatch.setattr(recorder_module, "_open_output", open_output)
    watcher = Watcher()
    rec = Recorder(settings(tmp_path), on_error=watcher.on_error, retry_s=0.05, on_recovered=watcher.on_recovered)
    assert rec.wait_ready(10.0) is False
    assert rec.health.error is not None and rec.health.error.errno_name == errno.errorcode[code]
    _record_quickly(rec, 30, 0)
    assert rec.sync(5.0) is False
    assert rec.dropped == 30
    failing.clear()
    assert watcher.recovered.wait(10.0)
    _record_quickly(rec, 5, 30)
    assert rec.close(5.0)
    assert [r.payload["k"] for r in read_records(tmp_path, ["estimate"])] == list(range(30, 35))
    assert list_log_files(tmp_path) and all(p.stat().st_size > 0 for p in list_log_files(tmp_path))


class FaultyFile:
    """A real file whose writes and flushes start failing with ``fault[0]`` (an errno) when set."""

    def __init__(self, path: Path, fault: list[int]) -> None:
        self._file = open(path, "xb")  # noqa: SIM115
        self._fault = fault

    def _check(self) -> None:
        if self._fault[0]:
            raise OSError(self._fault[0], os.strerror(self._fault[0]))

    def write(self, data: bytes) -> int:
        self._check()
        return self._file.write(data)

    def tell(self) -> int:
        return self._file.tell()

    def flush(self) -> None:
        self._check()
        self._file.flush()

    def fileno(self) -> int:
        return self._file.fileno()

    def close(self) -> None:
        self._file.close()


def test_disk_full_mid_file_keeps_what_was_flushed_and_resumes_in_a_new_file(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    fault = [0]
    monkeypatch.setattr(recorder_module, "_open_output", lambda path: FaultyFile(path, fault))
    watcher = Watcher()
    rec = Recorder(settings(tmp_path), on_error=watcher.on_error, retry_s=0.05, on_recovered=watcher.on_recovered)
    assert rec.wait_ready(10.0)
    _record_quickly(rec, 50, 0)
    assert rec.sync(5.0)
    first_file = rec.current_file
    fault[0] = errno.ENOSPC  # the disk fills up
    _record_quickly(rec, 50, 50)
    assert rec.sync(5.0) is False
    health = rec.health
    assert not health.ok and health.error is not None and health.error.errno_name == "ENOSPC"
    assert watcher.errors[0].kind == "flush"
    assert rec.stats()["dropped_by_reason"] == {"unwritable": 50}
    fault[0] = 0  # space freed
    assert watcher.recovered.wait(10.0)
    _record_quickly(rec, 5, 100)
    assert rec.close(5.0)
    files = list_log_files(tmp_path)
    assert files[0] == first_file and len(files) == 2
    issues: list = []
    ks = [r.payload["k"] for r in read_records(first_file, ["estimate"], on_issue=lambda p, m: issues.append(m))]
    assert ks == list(range(50))  # the abandoned file is unfinished but everything flushed is there
    assert issues and "unfinished" in issues[0]
    assert [r.payload["k"] for r in read_records(files[1], ["estimate"])] == list(range(100, 105))


CHILD = textwrap.dedent("""
    import sys, time
    from interfaces.recorder import RecorderSettings
    from interfaces.recorder import Recorder

    rec = Recorder(RecorderSettings(path=sys.argv[1], flush_s=1.0))
    assert rec.wait_ready(30.0)
    print("ready", flush=True)
    k = 0
    next_t = time.monotonic()
    while True:  # a 10 Hz loop until killed
        t = time.monotonic()  # the loop's t_s: CLOCK_MONOTONIC is shared with the parent
        rec.record_raw("nmea0183", t, b"$HEHDT,123.4,T*2B\\r\\n")
        rec.record("estimate", t, {"k": k, "eta_n": [1.0, 2.0, 0.5]})
        rec.record("control", t, {"tau_b": [1.0, 2.0, 3.0]})
        print(k, repr(t), flush=True)
        k += 1
        next_t += 0.1
        time.sleep(max(0.0, next_t - time.monotonic()))
""")


@pytest.mark.parametrize("records_before_kill", [16, 23])
def test_sigkill_loses_at_most_the_last_second(tmp_path: Path, records_before_kill: int) -> None:
    child = subprocess.Popen([sys.executable, "-c", CHILD, str(tmp_path)], cwd=ROOT, stdout=subprocess.PIPE,
                             text=True)
    try:
        assert child.stdout is not None
        assert child.stdout.readline().strip() == "ready"
        printed: dict[int, float] = {}
        while len(printed) < records_before_kill:
            line = child.stdout.readline()
            assert line, "the recording child died"
            k, t = line.split()
            printed[int(k)] = float(t)
        kill_t = time.monotonic()
        os.kill(child.pid, signal.SIGKILL)
    finally:
        child.kill()
        child.wait(10.0)
    issues: list = []
    records = list(read_records(tmp_path, ["estimate"], on_issue=lambda p, m: issues.append(m)))
    assert issues and "unfinished" in issues[0]  # killed: no summary, read by scanning
    ks = [r.payload["k"] for r in records]
    assert ks == list(range(len(ks)))  # a contiguous prefix, nothing damaged
    last_t = records[-1].payload["t_s"]
    assert kill_t - last_t <= 1.0, f"lost {kill_t - last_t:.2f} s of records"
    # and every record made more than a second before the kill is there
    assert all(k in set(ks) for k, t in printed.items() if t <= kill_t - 1.0)
