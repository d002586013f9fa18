"""Persisted state for a bumpless restart: atomic saves (also under SIGKILL), checked loads, background saver."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import threading
from pathlib import Path

import numpy as np
import orjson
import pytest

from dpcontrol.runtime.config import StateSettings
from dpcontrol.service.persist import BackgroundSaver, LoadStatus, StateStore, StateStoreError

ROOT = Path(__file__).resolve().parents[2]
HASH = "ef" * 32
T = 1_790_000_000.0  # a wall-clock time [s]


def _state(rng: np.random.Generator) -> dict:
    return {"x_hat": rng.normal(size=(8, 15)), "P_diag": np.abs(rng.normal(size=(8, 15))),
            "weights": rng.dirichlet(np.ones(8)), "mrac": {"theta": rng.normal(size=3).tolist()}, "mode": "auto"}


def test_save_then_load_round_trips_numpy_state(tmp_path: Path) -> None:
    rng = np.random.default_rng(6)
    state = _state(rng)
    store = StateStore(tmp_path / "sub" / "state.json", period_s=1.0, max_age_s=30.0, version=3, config_hash=HASH)
    store.save(T, state)
    loaded = store.load(T + 2.5)
    result = store.last_result
    assert result is not None and result.ok and result.status is LoadStatus.OK
    assert result.age_s == pytest.approx(2.5) and result.saved_wall_s == T
    assert loaded is not None
    np.testing.assert_array_equal(np.asarray(loaded["x_hat"]), state["x_hat"])  # floats are exact in JSON
    np.testing.assert_array_equal(np.asarray(loaded["weights"]), state["weights"])
    assert loaded["mrac"] == state["mrac"] and loaded["mode"] == "auto"
    assert [p.name for p in (tmp_path / "sub").iterdir()] == ["state.json"]  # no temporaries left


def _write_doc(path: Path, **fields: object) -> None:
    doc = {"format": "dpcontrol.state", "version": 1, "saved_wall_s": T, "config_sha256": HASH, "state": {"a": 1}}
    doc.update(fields)
    path.write_bytes(orjson.dumps(doc))


@pytest.mark.parametrize(("content", "status"), [
    (None, LoadStatus.MISSING),
    (b"", LoadStatus.CORRUPT),
    (b"\x00\xff garbage", LoadStatus.CORRUPT),
    (b'{"format": "dpcontrol.state", "version": 1, "saved_wall_s": 17', LoadStatus.CORRUPT),  # half a file
    (b"[1, 2, 3]", LoadStatus.CORRUPT),
    ({"format": "something.else"}, LoadStatus.CORRUPT),
    ({"saved_wall_s": "yesterday"}, LoadStatus.CORRUPT),
    ({"saved_wall_s": True}, LoadStatus.CORRUPT),
    ({"state": [1, 2]}, LoadStatus.CORRUPT),
    ({"version": 2}, LoadStatus.WRONG_VERSION),
    ({"version": "1"}, LoadStatus.WRONG_VERSION),
    ({"config_sha256": "00" * 32}, LoadStatus.WRONG_CONFIG),
    ({"config_sha256": None}, LoadStatus.WRONG_CONFIG),
    ({"saved_wall_s": T - 30.001}, LoadStatus.TOO_OLD),
    ({"saved_wall_s": T - 30.0}, LoadStatus.OK),  # exactly the limit is still accepted
    ({"saved_wall_s": T + 5.0}, LoadStatus.OK),  # within the clock tolerance
    ({"saved_wall_s": T + 60.0}, LoadStatus.FUTURE),
    ({}, LoadStatus.OK),
])
def test_load_refuses_with_a_reason(tmp_path: Path, content: object, status: LoadStatus) -> None:
    path = tmp_path / "state.json"
    if isinstance(content, bytes):
        path.write_bytes(content)
    elif isinstance(content, dict):
        _write_doc(path, **content)
    store = StateStore(path, max_age_s=30.0, config_hash=HASH)
    result = store.check(T)
    assert result.status is status
    assert (result.state is not None) == (status is LoadStatus.OK)
    assert str(path) in result.detail
    if status is LoadStatus.OK:
        assert result.state == {"a": 1}


def test_config_hash_check_can_be_skipped(tmp_path: Path) -> None:
    _write_doc(tmp_path / "s.json", config_sha256="00" * 32)
    assert StateStore(tmp_path / "s.json", config_hash=None).load(T) == {"a": 1}


def test_unreadable_state_file_is_reported(tmp_path: Path) -> None:
    (tmp_path / "s.json").mkdir()  # a directory where the file should be: reading fails
    result = StateStore(tmp_path / "s.json").check(T)
    assert result.status is LoadStatus.UNREADABLE


def test_failed_saves_leave_the_old_file_untouched(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / "state.json"
    store = StateStore(path, max_age_s=100.0)
    store.save(T, {"generation": 1})
    before = path.read_bytes()

    with pytest.raises(TypeError):
        store.save(T + 1, {"bad": object()})  # unserialisable: nothing written
    with pytest.raises(ValueError, match="finite"):
        store.save(float("nan"), {"generation": 2})

    def failing_replace(src: str, dst: str) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "replace", failing_replace)
    with pytest.raises(StateStoreError, match="No space left"):
        store.save(T + 2, {"generation": 3})
    monkeypatch.undo()
    assert path.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["state.json"]  # the temporary was removed
    assert store.load(T + 3) == {"generation": 1}

    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(StateStoreError, match=str(blocker)):
        StateStore(blocker / "state.json").save(T, {"a": 1})


def test_due_follows_the_period_and_clock_steps(tmp_path: Path) -> None:
    store = StateStore(tmp_path / "s.json", period_s=1.0)
    assert store.due(T)
    store.save(T, {})
    assert not store.due(T + 0.999)
    assert store.due(T + 1.0)
    assert store.due(T - 10.0)  # the wall clock stepped back: save rather than wait


def test_from_settings() -> None:
    assert StateStore.from_settings(StateSettings(path=None)) is None
    store = StateStore.from_settings(StateSettings(path="/tmp/x/state.json", period_s=2.0, max_age_s=9.0),
                                     version=4, config_hash=HASH)
    assert store is not None
    assert (store.path, store.period_s, store.max_age_s, store.version, store.config_hash) == (
        Path("/tmp/x/state.json"), 2.0, 9.0, 4, HASH)


def test_background_saver_snapshots_at_submit_and_writes_the_newest(tmp_path: Path) -> None:
    store = StateStore(tmp_path / "s.json", max_age_s=100.0)
    gate = threading.Event()
    entered = threading.Event()
    write = store.write

    def slow_write(data: bytes) -> None:
        entered.set()
        gate.wait()
        write(data)

    store.write = slow_write  # type: ignore[method-assign]
    saver = BackgroundSaver(store)
    buffer = np.zeros(3)
    assert saver.submit(T, {"x": buffer, "n": 0})
    assert entered.wait(5.0)  # the helper is writing snapshot 0
    for n in (1, 2, 3):
        buffer[:] = n  # the loop updates its arrays in place right after submitting
        assert saver.submit(T + n, {"x": buffer, "n": n})
        buffer[:] = -1.0
    assert saver.superseded == 2  # 1 and 2 were replaced by 3 while the helper was busy
    gate.set()
    assert saver.flush(5.0)
    assert saver.saved == 2 and saver.failed == 0 and saver.last_error is None
    assert store.load(T + 3) == {"x": [3.0, 3.0, 3.0], "n": 3}
    assert saver.close(5.0)
    assert saver.submit(T + 4, {"n": 4}) is False


def test_background_saver_reports_errors_and_never_raises(tmp_path: Path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("x")
    messages: list[str] = []
    got_error = threading.Event()

    def on_error(message: str) -> None:
        messages.append(message)
        got_error.set()

    saver = BackgroundSaver(StateStore(blocker / "s.json"), on_error=on_error)
    assert saver.submit(T, {"bad": object()}) is False
    assert saver.last_error is not None and "not serialisable" in saver.last_error
    assert saver.submit(T, {"ok": 1})
    assert got_error.wait(5.0)
    assert saver.flush(5.0)
    assert str(blocker) in messages[0] and saver.failed == 2
    calls = []
    assert saver.maybe_submit(T + 10, lambda: calls.append(1) or {"ok": 2})
    assert not saver.maybe_submit(T + 10.5, lambda: calls.append(1) or {"ok": 3})  # not due: not even built
    assert calls == [1]
    assert saver.close(5.0)


KILL_DURING_SAVE = textwrap.dedent("""
    import os, sys, threading
    from dpcontrol.service.persist import StateStore

    store = StateStore(sys.argv[1], max_age_s=1e9)
    store.save(1000.0, {"generation": 1, "blob": [0.5] * 50000})
    print("saved", flush=True)
    stop = threading.Event()
    if sys.argv[2] == "write":
        real_fdopen = os.fdopen
        class HalfWriter:
            def __init__(self, f): self.f = f
            def __enter__(self): return self
            def __exit__(self, *a): self.f.close()
            def write(self, data):
                self.f.write(data[: len(data) // 2]); self.f.flush()
                print("stuck", flush=True); stop.wait()
        os.fdopen = lambda fd, mode: HalfWriter(real_fdopen(fd, mode))
    else:
        def stuck_fsync(fd):
            print("stuck", flush=True); stop.wait()
        os.fsync = stuck_fsync
    store.save(1001.0, {"generation": 2, "blob": [0.25] * 50000})
""")


@pytest.mark.parametrize("phase", ["write", "fsync"])
def test_sigkill_during_a_save_leaves_the_old_complete_file(tmp_path: Path, phase: str) -> None:
    path = tmp_path / "state.json"
    child = subprocess.Popen([sys.executable, "-c", KILL_DURING_SAVE, str(path), phase], cwd=ROOT,
                             stdout=subprocess.PIPE, text=True)
    try:
        assert child.stdout is not None
        assert child.stdout.readline().strip() == "saved"
        assert child.stdout.readline().strip() == "stuck"  # in the middle of the second save
        os.kill(child.pid, signal.SIGKILL)
    finally:
        child.kill()
        child.wait(10.0)
    leftovers = [p for p in tmp_path.iterdir() if p != path]
    assert len(leftovers) == 1 and leftovers[0].name.endswith(".tmp")  # the interrupted new file
    store = StateStore(path, max_age_s=1e9)
    state = store.load(1001.0)
    assert state is not None and state["generation"] == 1 and state["blob"] == [0.5] * 50000
    store.save(1002.0, {"generation": 3})  # the next save removes the stray temporary
    assert [p.name for p in tmp_path.iterdir()] == ["state.json"]


SAVE_FOREVER = textwrap.dedent("""
    import sys
    from dpcontrol.service.persist import StateStore

    store = StateStore(sys.argv[1], max_age_s=1e9)
    n = 0
    while True:
        store.save(float(n), {"n": n, "blob": [n * 0.5] * 40000})
        print(n, flush=True)
        n += 1
""")


@pytest.mark.parametrize("saves_before_kill", [3, 11, 24])
def test_sigkill_at_any_time_leaves_a_complete_state(tmp_path: Path, saves_before_kill: int) -> None:
    path = tmp_path / "state.json"
    child = subprocess.Popen([sys.executable, "-c", SAVE_FOREVER, str(path)], cwd=ROOT, stdout=subprocess.PIPE,
                             text=True)
    try:
        assert child.stdout is not None
        last = -1
        while last < saves_before_kill:
            line = child.stdout.readline()
            assert line, "the saving child died"
            last = int(line)
        os.kill(child.pid, signal.SIGKILL)
    finally:
        child.kill()
        child.wait(10.0)
    result = StateStore(path, max_age_s=1e9).check(1e6)
    assert result.ok, result.detail
    assert result.state is not None
    n = result.state["n"]
    assert n >= last  # never older than a save that had completed
    assert result.state["blob"] == [n * 0.5] * 40000  # and never a mix of two saves
