"""The machine a benchmark ran on, for its report: a timing means little without the CPU, the cores it had,
how busy the machine was, and the interpreter and numeric libraries that ran it.

Read once, before the timed part (nothing here is on a control path).
"""

from __future__ import annotations

import datetime
import os
import platform
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
            "measured_at": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds")}


def describe(info: dict[str, Any]) -> str:
    """One line of :func:`machine_info` for a text report."""
    load = info.get("load_average_1min")
    return (f"machine: {info['cpu']}, {info['usable_cpus']} of {info['logical_cpus']} CPUs usable, "
            f"load {load if load is not None else 'n/a'}, Python {info['python']}, "
            f"numba {info['libraries'].get('numba')}, {info['measured_at']}")
