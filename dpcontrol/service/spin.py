"""Waiting for a control deadline without giving the CPU away: the last milliseconds before each cycle.

Why spin at all: a loop thread that sleeps until its deadline is woken by a timer and put back on a
CPU by the scheduler — on a virtual machine also by the host, which may have given the virtual CPU to
another guest meanwhile. The cycle then starts late by that wake-up latency. On the 2-core HIL VM
(2026-12-02, the demo configuration, SCHED_FIFO 50, 90 s runs) the period jitter was 93–96 µs median
and 0.84–1.26 ms p99 with a sleep, 10 µs median and 0.02–0.41 ms p99 spinning the last 2 ms. The cost
is the spun time: at most ``loop.deadline_spin_ms`` per period (2 ms of 100 ms: 2 % of one core). On a
single CPU, a SCHED_FIFO loop that spins would keep the (normal-priority) sensor readers off it for that
time: there the daemon sleeps to its deadlines whatever the setting.

Why a compiled kernel and not a Python ``while clock() < deadline: pass``: a Python loop holds the
GIL. The sensor reader threads then queue for it and take it at the control step's first kernel call
(the kernels release the GIL), so the loop thread waited inside its own step: the step's off-CPU time
had a p99 of 0.9–1.9 ms against 0.2–0.7 ms (same runs). :func:`_burn` releases the GIL
(``nogil``, :mod:`dpbase.jit`) for each slice of about :data:`SLICE_S`, so the readers decode and
queue their messages while the loop spins, as they do while it sleeps.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

from dpbase.jit import f8, i8, kernel

SLICE_S = 20e-6  # one spin slice [s]: the cycle starts at most about this late; the readers get the GIL between
CALIBRATION_ITERATIONS = 100_000
MIN_ITERATIONS = 100
MAX_ITERATIONS = 10_000_000


@kernel(f8(i8, f8))
def _burn(iterations: int, x: float) -> float:
    """``iterations`` dependent multiply-adds on ``x`` (the result is returned, so nothing is optimised away),
    with the GIL released: CPU time that other Python threads can share."""
    for _ in range(iterations):
        x = x * 0.999999 + 1.0
    return x


def slice_iterations(slice_s: float = SLICE_S, clock: Callable[[], float] = time.perf_counter) -> int:
    """How many :func:`_burn` iterations take about ``slice_s`` [s] on this CPU (the fastest of three
    timings of :data:`CALIBRATION_ITERATIONS`, bounded to [MIN_ITERATIONS, MAX_ITERATIONS])."""
    if not slice_s > 0.0:
        raise ValueError(f"slice_s must be > 0, got {slice_s!r}")
    best = float("inf")
    for _ in range(3):
        start = clock()
        _burn(CALIBRATION_ITERATIONS, 1.0)
        best = min(best, clock() - start)
    per_iteration = max(best, 1e-9) / CALIBRATION_ITERATIONS
    return int(min(max(slice_s / per_iteration, MIN_ITERATIONS), MAX_ITERATIONS))


class DeadlineSpinner:
    """Spin on ``clock`` until a deadline, in GIL-free slices (see the module docstring).

    Parameters
    ----------
    clock : callable
        The loop's monotonic clock [s] (the deadline is on it).
    slice_s : float
        Length of one slice [s] (calibrated once, here).
    """

    def __init__(self, clock: Callable[[], float], slice_s: float = SLICE_S) -> None:
        self.clock = clock
        self.iterations = slice_iterations(slice_s)
        # total time spent spinning before the deadlines [s] (what the spin costs in CPU). The time from a deadline
        # to the return is not counted: it is the cycle's late start, which the loop reports as its jitter, and
        # when the host stops the virtual CPU in a slice (seen at 4.5 % steal: 2.3 ms a cycle in all, for a 2 ms
        # window) it is no spinning at all
        self.spun_s = 0.0

    def until(self, deadline_s: float, stop: threading.Event | None = None) -> bool:
        """Spin until ``clock() >= deadline_s``; True if ``stop`` was set first (the caller stops)."""
        clock = self.clock
        iterations = self.iterations
        start = now = clock()
        try:
            while now < deadline_s:
                if stop is not None and stop.is_set():
                    return True
                _burn(iterations, 1.0)
                now = clock()
            return False
        finally:
            self.spun_s += max(0.0, min(now, deadline_s) - start)


def loop_spinner(spin_s: float, clock: Callable[[], float], shared_cpus: int) -> DeadlineSpinner | None:
    """The control loop's spinner for ``loop.deadline_spin_ms`` (as ``spin_s`` [s]), or None to sleep to the
    deadlines: when the setting is 0, or when the process has a single CPU (``shared_cpus``, counted before
    the loop thread pins itself) that the sensor readers would be kept off while the loop spins."""
    if spin_s <= 0.0 or shared_cpus < 2:
        return None
    return DeadlineSpinner(clock)
