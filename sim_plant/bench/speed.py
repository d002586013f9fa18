"""``sim-plant bench``: simulated seconds per wall second of the lockstep closed loop.

Two runs, each the whole loop (plant RK4 + waves + sensors → real codecs → hub → wave filter →
guidance → controller → QP allocation → thruster drives), without writing outputs:

* seed 003: the 12 h shuttle-tanker offloading with the **8-model MMAE bank** and MRAC at 10 Hz (the
  issue's speed target: ≥ 300× real time, under 150 s);
* seed 000: CyberShip II, 300 s, 8-model bank, PID at 10 Hz with its 20 Hz plant.

The wall time of each tenth of a run is reported too, to show that the cost per simulated second
does not grow with the duration (preallocated results, no per-step growth).
"""

from __future__ import annotations

import itertools
import time
from typing import Any

from dpcontrol.platform_info import cpu_times, describe, describe_steal, host_steal, machine_info
from sim_plant.bench.run import build_simulation
from sim_plant.scenario import builtin_scenario_path, load_scenario

BANK_8 = {"kind": "mmae", "omegas_rad_s": [0.3, 0.45, 0.6, 0.75, 0.9, 1.05, 1.2, 1.35]}


def _timed_run(name: str, overrides: dict[str, Any], duration_s: float) -> dict[str, Any]:
    scenario = load_scenario(builtin_scenario_path(name))
    simulation = build_simulation(scenario, overrides=overrides)
    marks: list[tuple[float, float]] = []

    def progress(t: float, total: float) -> None:
        marks.append((t, time.perf_counter()))

    ticks = cpu_times()
    start = time.perf_counter()
    result = simulation.run(progress=progress, duration_s=duration_s)
    wall = time.perf_counter() - start
    steal = host_steal(ticks, cpu_times())
    # cost per simulated second in ten windows of the run
    windows = []
    if len(marks) > 10:
        edges = [marks[round(i * (len(marks) - 1) / 10)] for i in range(11)]
        for (t0, w0), (t1, w1) in itertools.pairwise(edges):
            if t1 > t0:
                windows.append(round((w1 - w0) / (t1 - t0) * 1e3, 3))
    return {"scenario": name, "simulated_s": duration_s, "steps": result.steps, "wall_s": round(wall, 3),
            "speed_x_realtime": round(duration_s / wall, 1),
            "estimator": simulation.config.estimator.kind, "control": simulation.config.control.kind,
            "ms_per_simulated_s_by_tenth": windows,
            "last_to_first_tenth": round(windows[-1] / windows[0], 3) if len(windows) >= 2 and windows[0] else None,
            "host_steal": steal}


def run_speed_bench(tanker_duration_s: float = 43200.0, cs2_duration_s: float = 300.0) -> dict[str, Any]:
    """Both runs (see the module docstring), and the machine they ran on (read before them)."""
    return {"machine": machine_info(), "runs": [
        _timed_run("tanker-seed003", {"estimator": BANK_8, "control": {"kind": "mrac"}}, tanker_duration_s),
        _timed_run("cs2-seed000", {"estimator": BANK_8}, cs2_duration_s),
    ]}


def format_speed(result: dict[str, Any]) -> str:
    """Human-readable summary of :func:`run_speed_bench`."""
    lines = ["sim-plant bench — lockstep closed loop (plant + codecs + controller), no output files"]
    for run in result["runs"]:
        lines.append(f"  {run['scenario']:<16} {run['simulated_s']:>8.0f} s simulated in {run['wall_s']:>7.2f} s: "
                     f"{run['speed_x_realtime']:>7.1f}x real time ({run['estimator']}, {run['control']}); "
                     f"cost last/first tenth {run['last_to_first_tenth']}; {describe_steal(run['host_steal'])}")
    lines.append("  " + describe(result["machine"]))
    return "\n".join(lines)
