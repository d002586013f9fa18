"""Plant benchmark: what the truth model costs per simulated second, and that it does not grow.

For the CyberShip II (seed 000) and shuttle-tanker (seed 003) scenarios, without the controller:

* ``advance``: ``plant.advance(t)`` alone in 0.1 s steps (RK4 substeps at the plant rate, drives,
  environment, and the sensors sampling internally);
* ``lockstep``: what a lockstep runner calls every 0.1 s control step — ``command``, ``advance``,
  ``truth``, ``feedback``, ``sensor_samples`` — with the vessel kept on station by a trivial PD law
  on the true LF pose and a pseudo-inverse allocation (computed outside the timed region; it only
  exists so that the drives move and the vessel does not drift away).

Each run is split into ten windows of equal simulated length; the median step cost of the last
window over the first (``growth``) shows that the cost does not depend on the duration. The
budget (brief D): the whole closed loop at ≥ 300× real time at 10 Hz, so the plant should cost
≲ 100 µs per 0.1 s step. Timings on a shared, loaded machine are noisy.

Usage::

    .venv/bin/python benchmarks/bench_plant.py [--tanker-duration 7200] [--json]

``run(cs2_duration_s=300, tanker_duration_s=7200) -> dict`` (use 43200 for the full 12 h).
"""

from __future__ import annotations

import argparse
import gc
import json
import math
import time
from typing import Any

import numpy as np

from sim_plant.drives import ThrusterCommand
from sim_plant.plant import Plant
from sim_plant.scenario import builtin_scenario_path, load_scenario

STEP_S = 0.1
WINDOWS = 10


def _holder(plant: Plant) -> Any:
    """A PD station keeper on the true LF pose with a pseudo-inverse allocation (not the controller).

    Returns a function truth -> commands. Gains from the design mass: ω_n = 2π/period, ζ = 0.9.
    """
    vessel = plant.scenario.vessel
    thrusters = vessel.thrusters
    columns = []
    for spec in thrusters:
        angle = spec.angle_rad if spec.kind in ("tunnel", "propeller") else 0.0
        c, s = math.cos(angle), math.sin(angle)
        columns.append([c, s, spec.x_m * s - spec.y_m * c])
    b_pinv = np.linalg.pinv(np.array(columns).T)
    period = 60.0 if vessel.length_m < 10.0 else 150.0
    wn = 2.0 * math.pi / period
    mass = np.diag(vessel.mass_matrix)
    kp = mass * wn * wn
    kd = 2.0 * 0.9 * mass * wn
    names = [t.name for t in thrusters]

    def law(truth: Any) -> dict[str, ThrusterCommand]:
        setpoint = plant.scenario.setpoint_at(truth.t_s)
        north = setpoint.north_m if setpoint and setpoint.north_m is not None else 0.0
        east = setpoint.east_m if setpoint and setpoint.east_m is not None else 0.0
        heading = setpoint.heading_rad if setpoint and setpoint.heading_rad is not None else 0.0
        c, s = math.cos(truth.heading_rad), math.sin(truth.heading_rad)
        # position error clipped to a few metres: a step setpoint must not saturate the drives
        limit = 0.2 * vessel.length_m
        en = min(limit, max(-limit, truth.north_m - north))
        ee = min(limit, max(-limit, truth.east_m - east))
        err = np.array([c * en + s * ee, -s * en + c * ee, math.remainder(truth.heading_rad - heading, 2 * math.pi)])
        nu = np.array([truth.surge_mps, truth.sway_mps, truth.yaw_rate_radps])
        thrust = b_pinv @ (-kp * err - kd * nu)
        return {name: ThrusterCommand(float(f), 0.0) for name, f in zip(names, thrust, strict=True)}

    return law


def _windows(costs: np.ndarray) -> list[float]:
    return [float(np.median(chunk)) * 1e6 for chunk in np.array_split(costs, WINDOWS)]


def _bench(name: str, duration_s: float) -> dict[str, Any]:
    scenario = load_scenario(builtin_scenario_path(name))
    steps = round(duration_s / STEP_S)

    plant = Plant(scenario)
    costs = np.empty(steps)
    clock = time.perf_counter
    gc.disable()
    try:
        for k in range(steps):
            t = (k + 1) * STEP_S
            t0 = clock()
            plant.advance(t)
            costs[k] = clock() - t0
    finally:
        gc.enable()
    advance = _windows(costs)

    plant = Plant(scenario)
    law = _holder(plant)
    commands = law(plant.truth)
    costs = np.empty(steps)
    samples = 0
    gc.disable()
    try:
        for k in range(steps):
            t_prev = k * STEP_S
            t = (k + 1) * STEP_S
            t0 = clock()
            plant.command(t_prev, commands)
            plant.advance(t)
            truth = plant.truth
            plant.feedback()
            samples += len(plant.sensor_samples(t))
            costs[k] = clock() - t0
            commands = law(truth)
    finally:
        gc.enable()
    lockstep = _windows(costs)
    truth = plant.truth
    per_step = float(np.median(costs)) * 1e6
    return {
        "duration_s": duration_s,
        "plant_rate_hz": scenario.plant.rate_hz,
        "advance_us_per_step": float(np.median(advance)),
        "advance_us_per_window": advance,
        "advance_growth": advance[-1] / advance[0],
        "lockstep_us_per_step": per_step,
        "lockstep_p99_us": float(np.percentile(costs, 99)) * 1e6,
        "lockstep_us_per_window": lockstep,
        "lockstep_growth": lockstep[-1] / lockstep[0],
        "lockstep_us_per_simulated_s": per_step / STEP_S,
        "plant_only_realtime_factor": STEP_S / (per_step * 1e-6),
        "sensor_samples": samples,
        # distance from the setpoint at the end under the trivial PD holder (not the controller)
        "holder_offset_m": math.hypot(truth.north_m - (scenario.setpoint_at(truth.t_s).north_m or 0.0),
                                      truth.east_m - (scenario.setpoint_at(truth.t_s).east_m or 0.0)),
        "final_mass_factor": truth.mass_factor,
    }


def run(cs2_duration_s: float = 300.0, tanker_duration_s: float = 7200.0) -> dict[str, Any]:
    """Benchmark both scenarios; returns per scenario the step costs [µs] and growth ratios."""
    return {"cs2-seed000": _bench("cs2-seed000", cs2_duration_s),
            "tanker-seed003": _bench("tanker-seed003", tanker_duration_s)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cs2-duration", type=float, default=300.0, help="simulated seconds (CyberShip II)")
    parser.add_argument("--tanker-duration", type=float, default=7200.0,
                        help="simulated seconds (tanker; 43200 = the full 12 h)")
    parser.add_argument("--json", action="store_true", help="print JSON")
    args = parser.parse_args()
    result = run(args.cs2_duration, args.tanker_duration)
    if args.json:
        print(json.dumps(result, indent=2))
        return
    for name, r in result.items():
        print(f"{name}: {r['duration_s']:.0f} s simulated at {r['plant_rate_hz']:g} Hz")
        print(f"  advance only     median {r['advance_us_per_step']:7.1f} µs per 0.1 s step  "
              f"(growth last/first window {r['advance_growth']:.2f})")
        print(f"  lockstep calls   median {r['lockstep_us_per_step']:7.1f} µs, p99 {r['lockstep_p99_us']:7.1f} µs "
              f"per 0.1 s step = {r['lockstep_us_per_simulated_s']:.0f} µs per simulated s "
              f"({r['plant_only_realtime_factor']:.0f}× real time, plant alone; "
              f"growth {r['lockstep_growth']:.2f})")
        print(f"  windows (µs): {' '.join(f'{w:.0f}' for w in r['lockstep_us_per_window'])}")
        print(f"  {r['sensor_samples']} sensor samples, final mass factor {r['final_mass_factor']:.3f}")


if __name__ == "__main__":
    main()
