"""DeadlineSpinner: on time, the GIL free for other threads while it spins, and stoppable."""

from __future__ import annotations

import threading
import time

import pytest

from dpcontrol.service.spin import (
    MAX_ITERATIONS,
    MIN_ITERATIONS,
    DeadlineSpinner,
    loop_spinner,
    slice_iterations,
)


@pytest.fixture(scope="module")
def spinner() -> DeadlineSpinner:
    return DeadlineSpinner(time.monotonic)


def test_returns_at_the_deadline(spinner: DeadlineSpinner) -> None:
    lateness = []
    for _ in range(20):
        deadline = time.monotonic() + 0.002
        assert spinner.until(deadline) is False
        lateness.append(time.monotonic() - deadline)
    assert min(lateness) >= 0.0  # never early
    # about one slice (20 µs) late; 2 ms of slack for a busy CI machine, still far below a sleep's tail
    assert sorted(lateness)[len(lateness) // 2] < 0.002, lateness


def test_a_past_deadline_returns_at_once(spinner: DeadlineSpinner) -> None:
    before = spinner.spun_s
    start = time.monotonic()
    assert spinner.until(start - 1.0) is False
    assert time.monotonic() - start < 0.001
    assert spinner.spun_s - before < 0.001


def test_spun_time_ends_at_the_deadline_whatever_the_return() -> None:
    """A slice that ends far past the deadline (the host stopped the virtual CPU in it) adds the spin up to the
    deadline, not the stall: the late start is the cycle's jitter, reported as such."""
    readings = iter([0.0, 0.0005, 0.0010, 0.0125])  # start, two slices, then a 10 ms stall in the third
    spinner = DeadlineSpinner(lambda: next(readings))
    assert spinner.until(0.002) is False
    assert spinner.spun_s == 0.002


def test_other_threads_run_while_it_spins(spinner: DeadlineSpinner) -> None:
    """A reader-like thread (short work, short blocking waits) keeps its pace: the spin releases the GIL.
    Against a Python busy loop, which holds it, such a thread got 3 turns in 20 ms (a forced switch every
    5 ms); here it gets dozens."""
    turns = 0
    stop = threading.Event()

    def reader() -> None:
        nonlocal turns
        while not stop.is_set():
            turns += 1
            time.sleep(0.0002)

    thread = threading.Thread(target=reader)
    thread.start()
    try:
        time.sleep(0.005)
        before = turns
        spinner.until(time.monotonic() + 0.05)
        during = turns - before
    finally:
        stop.set()
        thread.join()
    assert during >= 25, during  # a GIL-holding spin: about 10 (one per 5 ms switch interval)


def test_a_stop_request_ends_the_spin(spinner: DeadlineSpinner) -> None:
    stop = threading.Event()
    stop.set()
    start = time.monotonic()
    assert spinner.until(start + 10.0, stop) is True
    stop.clear()
    timer = threading.Timer(0.02, stop.set)
    timer.start()
    assert spinner.until(start + 10.0, stop) is True  # SIGTERM's request_stop, seen within a slice
    assert time.monotonic() - start < 1.0
    timer.join()


def test_the_slice_is_calibrated_and_bounded() -> None:
    assert MIN_ITERATIONS <= slice_iterations() <= MAX_ITERATIONS
    ticks = iter(range(10**6))
    assert slice_iterations(clock=lambda: float(next(ticks))) == MIN_ITERATIONS  # a very slow CPU: 1 s per call
    assert slice_iterations(clock=lambda: 0.0) == MAX_ITERATIONS  # a clock that does not move
    with pytest.raises(ValueError, match="slice_s"):
        slice_iterations(0.0)


def test_the_loop_spins_only_when_set_and_with_a_cpu_to_spare() -> None:
    assert isinstance(loop_spinner(0.002, time.monotonic, 2), DeadlineSpinner)
    assert loop_spinner(0.0, time.monotonic, 2) is None  # loop.deadline_spin_ms: 0
    assert loop_spinner(0.002, time.monotonic, 1) is None  # one CPU: the readers would wait for it
