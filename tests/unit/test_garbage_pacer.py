"""The loop collects Python's cyclic garbage itself, after each cycle's command (``GarbagePacer``): no automatic
collection inside a control step or in a reader thread holding the GIL the step needs, and the same collections
as the interpreter's otherwise (its thresholds, its choice of generation)."""

from __future__ import annotations

import gc
import threading
import time
import weakref

from test_config import BASE

from dpcontrol.runtime.config import parse_config
from dpcontrol.service.daemon import Daemon, GarbagePacer


class _Node:
    """An object in a reference cycle: only the cyclic collector frees it."""

    def __init__(self) -> None:
        self.me = self


def test_nothing_is_collected_until_the_pacer_says_then_as_the_interpreter_would() -> None:
    was_enabled = gc.isenabled()
    gc.collect()  # every generation's count from zero: the sequence below is then the interpreter's
    pacer = GarbagePacer()
    try:
        assert not gc.isenabled()
        threshold0, threshold1, _ = pacer.thresholds
        cycle = _Node()
        alive = weakref.ref(cycle)
        del cycle
        survivors = [[] for _ in range(20 * threshold0)]  # 20 thresholds' worth of allocations: no collection
        assert alive() is not None and gc.get_count()[0] >= threshold0
        assert pacer.collect() == 0 and alive() is None  # the youngest generation, as the interpreter would
        assert pacer.collect() is None  # below the threshold again: nothing to do
        for _ in range(threshold1 - 1):
            survivors.append([[] for _ in range(threshold0 + 50)])  # (a few deallocations count back)
            assert pacer.collect() == 0
        survivors.append([[] for _ in range(threshold0 + 50)])  # (a few deallocations count back)
        assert pacer.collect() == 1  # the eleventh: the middle generation too
        assert pacer.collections == [threshold1, 1, 0] and pacer.max_us[0] > 0.0
        assert set(pacer.as_dict()) == {"collections", "max_us", "total_ms"}
    finally:
        pacer.close()
        if not was_enabled:
            gc.disable()
    assert gc.isenabled() == was_enabled


def test_the_daemon_collects_after_its_cycles_and_gives_automatic_collection_back() -> None:
    daemon = Daemon(parse_config({**BASE, "loop": {"rate_hz": 10}}))  # (links down: standby, nothing leaves)
    codes: list[int] = []
    thread = threading.Thread(target=lambda: codes.append(daemon.run(duration_s=60.0, install_signals=False)))
    thread.start()
    try:
        deadline = time.monotonic() + 60.0
        while daemon.stats.count < 20 and time.monotonic() < deadline:
            time.sleep(0.05)
        assert daemon.stats.count >= 20
        assert not gc.isenabled()  # automatic collection off while the loop runs (process-wide)
        # garbage made by another thread (as a sensor reader's): the loop collects it after one of its cycles
        cycle = _Node()
        alive = weakref.ref(cycle)
        del cycle
        kept = [[] for _ in range(2 * gc.get_threshold()[0])]
        while alive() is not None and time.monotonic() < deadline:
            time.sleep(0.05)
        assert alive() is None and len(kept) > 0
        assert daemon.garbage is not None and sum(daemon.garbage.collections) >= 1
    finally:
        daemon.request_stop()
        thread.join(30.0)
    assert not thread.is_alive() and codes == [0]
    assert gc.isenabled()
