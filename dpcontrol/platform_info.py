"""The machine a benchmark ran on, for its report: a timing means little without the CPU, the cores it had,
how busy the machine was, and the interpreter and numeric libraries that ran it.

Read once, before the timed part (nothing here is on a control path). :func:`cpu_times` is read again after
it: on a virtual machine, :func:`host_steal` then says how much of the CPUs' time the hypervisor gave to other
guests *during* the run — time in which the code measured stood still, whatever it was.
"""

from __future__ import annotations

import datetime
import os
import platform
from collections import deque
from collections.abc import Callable
from importlib import metadata
from pathlib import Path
from typing import Any

_LIBRARIES = ("numpy", "scipy", "numba", "daqp", "pynmea2")


def _cpu_model() -> str:
    """The CPU's model name (``/proc/cpuinfo`` on Linux, else what :mod:`platform` says)."""
    try:
        for line in Path("/proc/cpuinfo").read_text(encoding="utf-8", errors="replace").splitlines():
            key, _, value = line.partition(":")
            if key.strip() in ("model name", "Model", "Processor") and value.strip():
                return value.strip()
    except OSError:
        pass
    return platform.processor() or platform.machine() or "unknown"


def _version(name: str) -> str | None:
    try:
        return metadata.version(name)
    except metadata.PackageNotFoundError:
        return None


def machine_info() -> dict[str, Any]:
    """What a benchmark report says about where it was measured.

    Returns
    -------
    dict
        ``cpu`` (model name), ``logical_cpus`` (of the machine), ``usable_cpus`` (this process's affinity),
        ``load_average_1min`` (runnable tasks, averaged over the last minute, before the run; None where the
        OS has none), ``platform``, ``python``, ``libraries`` (versions, None when not installed) and
        ``measured_at`` (UTC, ISO 8601).
    """
    try:
        usable: int | None = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):  # not Linux
        usable = os.cpu_count()
    try:
        load: float | None = round(os.getloadavg()[0], 2)
    except (AttributeError, OSError):
        load = None
    return {"cpu": _cpu_model(), "logical_cpus": os.cpu_count(), "usable_cpus": usable, "load_average_1min": load,
            "platform": platform.platform(), "python": platform.python_version(),
            "libraries": {name: _version(name) for name in _LIBRARIES},
            "measured_at": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")}


def available_memory_bytes() -> int | None:
    """Memory the kernel estimates a new allocation can get without swapping [bytes].

    Returns
    -------
    int or None
        ``MemAvailable`` of ``/proc/meminfo`` (Linux); None where there is no such line.
    """
    try:
        with open("/proc/meminfo", encoding="ascii") as handle:
            for line in handle:
                if line.startswith("MemAvailable:"):
                    value, unit = line.split()[1:3]
                    return int(value) * (1024 if unit == "kB" else 1)
    except (OSError, ValueError):
        return None
    return None


def cpu_times() -> tuple[int, ...] | None:
    """The machine's CPU time counters since boot, all CPUs together [clock ticks].

    Returns
    -------
    tuple of 8 int or None
        ``user, nice, system, idle, iowait, irq, softirq, steal``: the first line of ``/proc/stat``
        (Linux); None where there is no such file or it reads otherwise.
    """
    try:
        with open("/proc/stat", encoding="ascii") as handle:
            fields = handle.readline().split()
    except (OSError, ValueError):
        return None
    if len(fields) < 9 or fields[0] != "cpu":
        return None
    try:
        return tuple(int(value) for value in fields[1:9])
    except ValueError:
        return None


def host_steal(before: tuple[int, ...] | None, after: tuple[int, ...] | None) -> dict[str, float] | None:
    """The CPU time the hypervisor gave to other guests between two :func:`cpu_times` readings.

    Parameters
    ----------
    before, after : tuple of int or None
        Two readings of :func:`cpu_times`, in that order.

    Returns
    -------
    dict or None
        ``steal_s`` (seconds of CPU time, all CPUs together) and ``steal_percent`` (of all the CPUs' time in
        the interval); None if either reading is missing or no time passed. 0 on dedicated hardware.
    """
    if before is None or after is None:
        return None
    deltas = [new - old for old, new in zip(before, after, strict=True)]
    total = sum(deltas)
    if total <= 0:
        return None
    ticks_per_s = os.sysconf("SC_CLK_TCK")
    return {"steal_s": round(deltas[7] / ticks_per_s, 2), "steal_percent": round(100.0 * deltas[7] / total, 2)}


class HostStealWindow:
    """The hypervisor's share of the CPUs over the last ``window_s`` of a running service [%].

    Parameters
    ----------
    window_s : float
        Length of the window [s] (> 0).
    read : callable
        :func:`cpu_times` (replaceable for tests).

    Notes
    -----
    :meth:`update` reads ``/proc/stat`` (one small file read): call it about once a second, off any
    deadline. The readings older than the window are dropped, so the memory is bounded by the call rate.
    """

    def __init__(self, window_s: float = 10.0, read: Callable[[], tuple[int, ...] | None] = cpu_times) -> None:
        if not window_s > 0.0:
            raise ValueError(f"window_s must be > 0, got {window_s!r}")
        self.window_s = window_s
        self._read = read
        self._readings: deque[tuple[float, tuple[int, ...]]] = deque()

    def update(self, t_s: float) -> float | None:
        """Read the counters at ``t_s`` [s, monotonic]; the steal share since the oldest reading of the window
        [%], None before there are two readings (or where the counters cannot be read)."""
        ticks = self._read()
        if ticks is None:
            return None
        readings = self._readings
        while len(readings) > 1 and t_s - readings[1][0] >= self.window_s:
            readings.popleft()  # the oldest kept is the last one at least window_s old
        oldest = readings[0][1] if readings else None
        readings.append((t_s, ticks))
        steal = host_steal(oldest, ticks)
        return None if steal is None else steal["steal_percent"]


def describe_steal(steal: dict[str, float] | None) -> str:
    """``host steal ...`` of :func:`host_steal` for a text report (``n/a`` when it could not be read)."""
    if steal is None:
        return "host steal n/a"
    return f"host steal {steal['steal_percent']:.2f} % ({steal['steal_s']:.2f} s of CPU time)"


def describe(info: dict[str, Any]) -> str:
    """One line of :func:`machine_info` for a text report."""
    load = info.get("load_average_1min")
    return (f"machine: {info['cpu']}, {info['usable_cpus']} of {info['logical_cpus']} CPUs usable, "
            f"load {load if load is not None else 'n/a'}, Python {info['python']}, "
            f"numba {info['libraries'].get('numba')}, {info['measured_at']}")
