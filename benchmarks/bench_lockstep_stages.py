"""Where a lockstep step's time goes: the cost of each stage of ``sim-plant bench``'s closed loop, per step.

``sim-plant bench`` reports one number (simulated seconds per wall second); this splits a shorter run of
the same loop into its stages, timed *in context* — inside the running loop, where each stage finds the
caches holding the other stages' code and data — which is what matters, and which isolated
micro-benchmarks of the same functions underestimate by 2–3× on the development machines.

Each stage is a method of the simulation's objects, wrapped with ``time.perf_counter`` for this run
only (the wrappers add ~1 µs per call: the total is a little slower than ``sim-plant bench``):

* the loop's parts: ``plant.advance`` (RK4, waves, sensors), ``inputs.measurements`` (NMEA 0183 /
  NMEA 2000 / MAVLink encode → decode → route), ``controller.step`` and ``record`` (the time-series row);
* inside ``controller.step``: the sensor hub, the wave filter's step and predicted measurement, the
  controller, the thruster monitor, the force input and the allocation. Their sum falls short of
  ``controller.step`` by the step's own code (modes, guidance, alarms).

Usage::

    .venv/bin/python benchmarks/bench_lockstep_stages.py [--scenario tanker-seed003] [--duration 600] [--json]

The scenario runs with ``sim-plant bench``'s settings: the 8-model MMAE bank, and MRAC for the tanker.
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from sim_plant.bench.run import build_simulation
from sim_plant.bench.speed import BANK_8
from sim_plant.scenario import builtin_scenario_path, load_scenario

# (label, path of the object from the simulation, method name)
STAGES = (
    ("plant.advance", "plant", "advance"),
    ("inputs.measurements (encode → decode → route)", "inputs", "measurements"),
    ("controller.step", "controller", "step"),
    ("  hub.update", "controller.hub", "update"),
    ("  estimator.step", "controller.estimator", "step"),
    ("  estimator.predicted_measurement", "controller.estimator", "predicted_measurement"),
    ("  force input", "controller", "_update_force_input"),
    ("  control law", "controller.controller", "step"),
    ("  monitor.update", "controller.monitor", "update"),
    ("  allocation", "controller", "_allocate"),
    ("record (time-series row)", "", "_record"),
)


def _resolve(root: Any, path: str) -> Any:
    target = root
    for name in filter(None, path.split(".")):
        target = getattr(target, name)
    return target


def _timed(function: Callable[..., Any], times: list[float]) -> Callable[..., Any]:
    clock = time.perf_counter

    def wrapper(*args: Any, **kwargs: Any) -> Any:
        start = clock()
        try:
            return function(*args, **kwargs)
        finally:
            times.append(clock() - start)
    return wrapper


def run(scenario_name: str = "tanker-seed003", duration_s: float = 600.0) -> dict[str, Any]:
    """One lockstep run of ``duration_s`` simulated seconds with every stage timed.

    Returns
    -------
    dict
        ``steps``, ``wall_s``, ``speed_x_realtime``, ``us_per_step`` and per stage ``us_per_step`` (total time
        over the run's steps), ``calls`` and ``median_us`` (per call).
    """
    scenario = load_scenario(builtin_scenario_path(scenario_name))
    overrides: dict[str, Any] = {"estimator": BANK_8}
    if scenario_name.startswith("tanker"):
        overrides["control"] = {"kind": "mrac"}
    simulation = build_simulation(scenario, overrides=overrides)
    times: dict[str, list[float]] = {}
    for label, path, method in STAGES:
        target = _resolve(simulation, path)
        if target is None or not hasattr(target, method):
            continue  # (a configuration without that stage: no control law in standby-only runs, ...)
        times[label] = []
        setattr(target, method, _timed(getattr(target, method), times[label]))
    start = time.perf_counter()
    result = simulation.run(duration_s=duration_s)
    wall = time.perf_counter() - start
    steps = result.steps
    stages = {}
    for label, values in times.items():
        array = np.array(values) * 1e6
        stages[label.strip()] = {"us_per_step": round(float(array.sum()) / steps, 1), "calls": int(array.size),
                                 "median_us": round(float(np.median(array)), 1) if array.size else None}
    return {"scenario": scenario_name, "simulated_s": duration_s, "steps": steps, "wall_s": round(wall, 2),
            "speed_x_realtime": round(duration_s / wall, 1), "us_per_step": round(wall / steps * 1e6, 1),
            "stages": stages}


def format_table(result: dict[str, Any]) -> str:
    """The stages as a text table, in loop order (indented: inside ``controller.step``)."""
    lines = [f"{result['scenario']}, {result['simulated_s']:g} s simulated in {result['wall_s']} s "
             f"({result['speed_x_realtime']}× real time, {result['us_per_step']} µs per step, timers included)",
             f"{'stage':50s} {'µs/step':>9s} {'median µs/call':>15s} {'calls':>7s}"]
    stages = result["stages"]
    for label, _, _ in STAGES:
        row = stages.get(label.strip())
        if row is not None:
            median = "" if row["median_us"] is None else f"{row['median_us']:.1f}"
            lines.append(f"{label:50s} {row['us_per_step']:9.1f} {median:>15s} {row['calls']:7d}")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", default="tanker-seed003", help="built-in scenario (default tanker-seed003)")
    parser.add_argument("--duration", type=float, default=600.0, help="simulated seconds (default 600)")
    parser.add_argument("--json", action="store_true", help="print JSON instead of the table")
    args = parser.parse_args()
    result = run(args.scenario, args.duration)
    print(json.dumps(result, indent=1) if args.json else format_table(result))


if __name__ == "__main__":
    main()
