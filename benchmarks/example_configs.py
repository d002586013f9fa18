"""How far each example configuration lets its vessel stray: ``deploy/config/*.yaml`` in lockstep.

Each example's controller sections (:data:`dpcontrol.runtime.config.CONTROLLER_SECTIONS`: estimator, control,
guidance, allocation, limits — not its sensors and transports, which are the vessel's) drive its vessel's seed
scenario, or another scenario of that vessel, and the deviation monitor's readings (the estimate against the
reference, as the deviation alarms see it) are summed up: the largest and the median position [m] and heading
[deg] deviation, the deviation alarms raised, and the MRAC mass estimates at the end when the controller adapts.
``tests/closed_loop/test_example_configs.py`` runs the same and asserts no deviation warning.

Usage::

    .venv/bin/python benchmarks/example_configs.py                       # every example, its seed scenario
    .venv/bin/python benchmarks/example_configs.py supply --control '{"kind": "mrac"}'   # the old supply example
    .venv/bin/python benchmarks/example_configs.py supply --scenario faults/10-thruster-capability.yaml \\
        --duration 119 --control '{"kind": "pid"}'                         # case 10's weather, before the trip
    .venv/bin/python benchmarks/example_configs.py cybership2 --estimator '{"kind": "mmae"}'   # the default grid

On the 2026-12-03 development VM: supply (PID + bias feed-forward, seed 001 sea) 1.10 m / 1.03° at most; the same
with ``{"kind": "mrac"}`` 22.1 m / 64.4°, median 10.4 m / 52.7°; tanker (MRAC, first 2700 s: its first 20 m
correction) 0.86 m / 0.13°; CyberShip II 0.11 m / 0.57°; Blue Lady 0.27 m / 0.83°; Mariner 3.41°.
"""

from __future__ import annotations

import argparse
import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from dpcontrol.runtime.config import CONTROLLER_SECTIONS
from sim_plant.bench.lockstep import LockstepSimulation
from sim_plant.bench.run import build_simulation
from sim_plant.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[1]
#: example → its vessel's seed scenario and how much of it to run [s] (None: all of it)
EXAMPLES: dict[str, tuple[str, float | None]] = {
    "supply": ("supply-seed001.yaml", None),
    "shuttle_tanker": ("tanker-seed003.yaml", 2700.0),  # (12 h in all: 45 min, through its first 20 m correction)
    "cybership2": ("cs2-seed000.yaml", None),
    "blue_lady": ("bluelady-seed004.yaml", None),
    "mariner": ("mariner-seed002.yaml", None),
}


def deviation_watch(simulation: LockstepSimulation) -> tuple[Callable[[float, object], None], list[float], list[float]]:
    """An observer for ``simulation.run`` collecting the deviation monitor's readings each step, and the two lists it
    fills: position [m] and heading [rad] deviations (the estimate against the reference the controller follows),
    while each is watched."""
    deviation = simulation.controller.deviation
    position: list[float] = []
    heading: list[float] = []

    def watch(_t_s: float, _out: object) -> None:
        if deviation.position_m is not None:
            position.append(deviation.position_m)
        if deviation.heading_rad is not None:
            heading.append(deviation.heading_rad)

    return watch, position, heading


def run_example(example: str, scenario_name: str | None = None, duration_s: float | None = None,
                control: dict[str, Any] | None = None, estimator: dict[str, Any] | None = None) -> dict[str, Any]:
    """One example in lockstep; returns the deviations, the alarms and what the run used."""
    config = yaml.safe_load((ROOT / "deploy" / "config" / f"{example}.yaml").read_text(encoding="utf-8"))
    seed_scenario, seed_duration = EXAMPLES[example]
    scenario = load_scenario(ROOT / "sim_plant" / "scenarios" / (scenario_name or seed_scenario))
    if scenario.vessel.name != config["vessel"]:
        raise ValueError(f"{example} is for {config['vessel']}, the scenario for {scenario.vessel.name}")
    overrides = {key: config[key] for key in CONTROLLER_SECTIONS if key in config}
    if control is not None:
        overrides["control"] = control
    if estimator is not None:
        overrides["estimator"] = estimator
    simulation = build_simulation(scenario, overrides=overrides)
    watch, position, heading = deviation_watch(simulation)
    duration = duration_s if duration_s is not None else (seed_duration if scenario_name is None else None)
    result = simulation.run(duration_s=duration, observer=watch, timeseries=False)
    mass = getattr(simulation.controller.controller, "mass_hat_floats", None)
    return {
        "example": example, "scenario": scenario.name, "control": overrides.get("control"),
        "estimator": overrides.get("estimator"),
        "steps": result.steps, "engaged": bool(result.mode_changes), "watched_steps": len(heading),
        "position_max_m": max(position, default=0.0), "position_median_m": float(np.median(position or [0.0])),
        "heading_max_deg": math.degrees(max(heading, default=0.0)),
        "heading_median_deg": math.degrees(float(np.median(heading or [0.0]))),
        "deviation_alarms": sorted({e.code for e in result.alarm_events if e.raised and ".deviation." in e.code}),
        "alarms": sorted({e.code for e in result.alarm_events if e.raised}),
        "mass_estimates": None if mass is None else list(mass),
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("examples", nargs="*", choices=[*EXAMPLES, []], help="default: all")
    parser.add_argument("--scenario", help="a scenario of sim_plant/scenarios/ (default: the example's seed one)")
    parser.add_argument("--duration", type=float, help="simulated seconds")
    parser.add_argument("--control", type=json.loads, help="a control section replacing the example's (JSON)")
    parser.add_argument("--estimator", type=json.loads, help="an estimator section replacing the example's (JSON)")
    args = parser.parse_args()
    for example in args.examples or list(EXAMPLES):
        r = run_example(example, args.scenario, args.duration, args.control, args.estimator)
        mass = "" if r["mass_estimates"] is None else \
            "; MRAC mass estimates " + ", ".join(f"{m:.3g}" for m in r["mass_estimates"])
        print(f"{r['example']:<15} {r['scenario']:<28} control {json.dumps(r['control'])}"
              + (f" estimator {json.dumps(r['estimator'])}" if args.estimator else "") + ": position "
              f"{r['position_max_m']:.2f} m at most ({r['position_median_m']:.2f} median), heading "
              f"{r['heading_max_deg']:.2f}° ({r['heading_median_deg']:.2f}); deviation alarms "
              f"{', '.join(r['deviation_alarms']) or 'none'}{mass}"
              + ("; MRAC adaptation suspended (control.adaptation)" if "control.adaptation" in r["alarms"] else ""))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
