"""Paired MRAC vs PID campaign over random scenarios, per built-in DP vessel (a loop over seeds until the campaign
engine exists).

Each scenario is the vessel's seed scenario (its sensors, estimator, datum) with random weather and a random
manoeuvre, drawn from the scenario's seed:

* sea: JONSWAP, Hs and peak frequency in the vessel's range (model-scale vessels Froude-scaled), direction within
  ±30° of the bow (a DP vessel heads into the weather); current within ±20° and wind within ±30° of the sea's
  direction (no wind on CyberShip II, whose seed scenario has none: a 1:70 model would be blown away by full-scale
  wind);
* 3–6 set-point moves, each up to 20 % of the ship length in a random direction and/or a turn of up to 30° (the bow
  kept within 30° of the initial heading), one
  every ``3 T + travel time`` (T: the controller's natural period), the first after the MRAC's entry rest;
* the shuttle tanker's mass grows linearly from 1× to 1.2–2.0× its ballast mass over the run.

Every scenario runs once per controller on the identical weather (same seed). The error is the true low-frequency
pose of the plant against the guidance's reference η_d — the pose the operator sees — from the entry into DP to the
end: position rms [m] and heading rms [deg]. The MRAC's masses are checked against its bounds and for suspension
(``control.adaptation``).

Usage::

    nice -n 10 .venv/bin/python benchmarks/mrac_campaign.py --seeds 40 --jobs 2            # 4 vessels × 40
    nice -n 10 .venv/bin/python benchmarks/mrac_campaign.py supply --seeds 5 --json out.json

Acceptance (issue "MRAC-augmented PD that holds every vessel"): per vessel, MRAC rms ≤ 1.1× PID in ≥ 90 % of the
runs and ≤ 1.0× in the median, position and heading; no run suspends the adaptation; no estimate on a bound.
"""

from __future__ import annotations

import argparse
import json
import math
import multiprocessing
import statistics
import time
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from dpcontrol.control.pid import default_natural_period_s
from dpcontrol.guidance.reference_model import default_reference_config
from dpcontrol.models.vessels import BUILTIN_VESSELS
from sim_plant.bench.run import build_simulation
from sim_plant.scenario import builtin_scenario_path, parse_scenario

#: vessel → (seed scenario, Hs range [m], peak frequency range [rad/s], current [m/s], wind [m/s])
VESSELS: dict[str, tuple[str, tuple[float, float], tuple[float, float], float, float]] = {
    "cybership2": ("cs2-seed000", (0.02, 0.08), (0.8, 1.1), 0.05, 0.0),
    "supply": ("supply-seed001", (0.5, 4.0), (0.5, 0.9), 0.8, 15.0),
    "shuttle_tanker": ("tanker-seed003", (1.0, 4.0), (0.45, 0.8), 1.0, 15.0),
    "blue_lady": ("bluelady-seed004", (0.02, 0.08), (2.0, 3.5), 0.1, 3.0),
}
CONTROLLERS: dict[str, dict[str, Any]] = {
    "mrac": {"kind": "mrac"},
    "fixed": {"kind": "mrac", "adapt": False},  # the MRAC frozen at the nominal parameters: seed 003 eq. (25)
    "pd": {"kind": "pid", "integral_action": "bias_feedforward"},  # the PD + bias of seed 003 the MRAC augments
    "pid": {"kind": "pid"},  # the default PID (integrator)
}
RATIO_LIMIT = 1.1
SHARE_REQUIRED = 0.9


def scenario_mapping(vessel: str, seed: int) -> dict[str, Any]:
    """The random scenario ``seed`` of ``vessel`` as a scenario mapping (see the module docstring)."""
    name, hs_range, omega_range, current_max, wind_max = VESSELS[vessel]
    data = yaml.safe_load(builtin_scenario_path(name).read_text(encoding="utf-8"))
    data.pop("faults", None)
    data.pop("mass_schedule", None)
    data.pop("plant", None)
    rng = np.random.default_rng([seed, sum(map(ord, vessel))])
    data_vessel = BUILTIN_VESSELS[vessel]
    length = data_vessel.length_m
    period = default_natural_period_s(data_vessel)
    guidance = default_reference_config(data_vessel)
    direction = float(rng.uniform(-30.0, 30.0))
    data["sea_states"] = [{"t_s": 0, "spectrum": "jonswap", "hs_m": float(rng.uniform(*hs_range)),
                           "omega_peak_rad_s": float(rng.uniform(*omega_range)), "gamma": 3.3,
                           "direction_deg": direction}]
    data["current"] = {"speed_mps": float(rng.uniform(0.0, current_max)),
                       "direction_deg": direction + 180.0 + float(rng.uniform(-20.0, 20.0))}
    data["wind"] = {"speed_mps": float(rng.uniform(0.0, wind_max)),
                    "direction_deg": direction + float(rng.uniform(-30.0, 30.0))}
    travel = 0.2 * length / guidance.max_speed_mps + math.radians(30.0) / guidance.max_yaw_rate_radps
    interval = 3.0 * period + travel
    t = 2.5 * period  # engagement, then the entry rest (one period) and some station keeping
    north = east = heading = 0.0
    setpoints = [{"t_s": 0, "north_m": 0.0, "east_m": 0.0, "heading_deg": 0.0}]
    for _ in range(int(rng.integers(3, 7))):
        kind = rng.uniform()
        if kind < 0.75:  # a move (and a turn with it half of the time)
            distance = float(rng.uniform(0.02, 0.2)) * length
            bearing = float(rng.uniform(0.0, 2.0 * math.pi))
            north += distance * math.cos(bearing)
            east += distance * math.sin(bearing)
        if kind > 0.375:  # a turn of up to 30°, the bow kept within 30° of the weather's mean direction
            heading = min(max(heading + float(rng.uniform(-30.0, 30.0)), -30.0), 30.0)
        setpoints.append({"t_s": round(t, 1), "north_m": north, "east_m": east, "heading_deg": heading})
        t += interval
    data["setpoints"] = setpoints
    data["duration_s"] = round(t, 1)
    data["seed"] = int(seed)
    data["name"] = f"{vessel}-campaign-{seed}"
    if vessel == "shuttle_tanker":
        data["mass_schedule"] = [{"t_s": 0, "factor": 1.0}, {"t_s": data["duration_s"],
                                                              "factor": float(rng.uniform(1.2, 2.0))}]
    return data


def run_one(vessel: str, seed: int, controller: str) -> dict[str, Any]:
    """One scenario under one controller: the error rms against η_d and the MRAC's state at the end."""
    data = scenario_mapping(vessel, seed)
    scenario = parse_scenario(data)
    simulation = build_simulation(scenario, overrides={"control": CONTROLLERS[controller]})
    plant = simulation.plant
    position: list[float] = []
    heading: list[float] = []

    def watch(_t_s: float, out: Any) -> None:
        reference = out.reference
        if reference is None:
            return
        north, east, psi, *_ = plant.state()
        r = reference.eta_d_n
        position.append(math.hypot(north - r[0], east - r[1]))
        heading.append(math.remainder(psi - r[2], 2.0 * math.pi))

    started = time.process_time()
    result = simulation.run(observer=watch, timeseries=False)
    mrac = simulation.controller._mrac
    masses = bound = None
    if mrac is not None:
        masses = [m / n for m, n in zip(mrac.mass_hat_floats, mrac.config.mass_nominal, strict=True)]
        lo, hi = mrac.config.mass_bounds_factor
        bound = any(r <= lo * (1 + 1e-9) or r >= hi * (1 - 1e-9) for r in masses)
    truth = plant.truth
    return {
        "vessel": vessel, "seed": seed, "controller": controller, "steps": result.steps,
        "position_rms_m": math.sqrt(float(np.mean(np.square(position)))) if position else math.nan,
        "heading_rms_deg": math.degrees(math.sqrt(float(np.mean(np.square(heading))))) if heading else math.nan,
        "position_max_m": max(position, default=math.nan),
        "suspended": any(e.code == "control.adaptation" and e.raised for e in result.alarm_events),
        "alarms": sorted({e.code for e in result.alarm_events if e.raised}),
        "mass_ratio": masses, "on_bound": bound, "true_mass_factor": truth.mass_factor,
        "cpu_s": time.process_time() - started,
    }


def _task(args: tuple[str, int, str, dict[str, Any]]) -> dict[str, Any]:
    vessel, seed, controller, section = args
    CONTROLLERS[controller] = section  # (a worker process: the section given on the command line)
    return run_one(vessel, seed, controller)


def summarise(rows: list[dict[str, Any]], baseline: str) -> list[str]:
    """Per vessel: the share of runs with MRAC ≤ 1.1× the baseline and the median ratios."""
    lines = []
    by_key = {(r["vessel"], r["seed"], r["controller"]): r for r in rows}
    for vessel in VESSELS:
        pairs = [(r, by_key.get((vessel, r["seed"], baseline))) for r in rows
                 if r["vessel"] == vessel and r["controller"] == "mrac"]
        pairs = [(a, b) for a, b in pairs if b is not None]
        if not pairs:
            continue
        pos = [a["position_rms_m"] / b["position_rms_m"] for a, b in pairs]
        hdg = [a["heading_rms_deg"] / b["heading_rms_deg"] for a, b in pairs]
        within = sum(p <= RATIO_LIMIT and h <= RATIO_LIMIT for p, h in zip(pos, hdg, strict=True)) / len(pairs)
        suspended = sum(a["suspended"] for a, _ in pairs)
        bound = sum(bool(a["on_bound"]) for a, _ in pairs)
        masses = np.array([a["mass_ratio"] for a, _ in pairs])
        truth = np.array([a["true_mass_factor"] for a, _ in pairs])
        ok = within >= SHARE_REQUIRED and statistics.median(pos) <= 1.0 and statistics.median(hdg) <= 1.0 \
            and suspended == 0 and bound == 0
        lines.append(
            f"{vessel:<15} vs {baseline}: {len(pairs)} runs; both rms <= {RATIO_LIMIT}x in {100 * within:.0f} %; "
            f"median ratio position {statistics.median(pos):.3f} (max {max(pos):.2f}), heading "
            f"{statistics.median(hdg):.3f} (max {max(hdg):.2f}); MRAC rms median "
            f"{statistics.median(a['position_rms_m'] for a, _ in pairs):.3g} m / "
            f"{statistics.median(a['heading_rms_deg'] for a, _ in pairs):.3g} deg, {baseline} "
            f"{statistics.median(b['position_rms_m'] for _, b in pairs):.3g} m / "
            f"{statistics.median(b['heading_rms_deg'] for _, b in pairs):.3g} deg; suspended {suspended}, on a bound "
            f"{bound}; final mass / true (surge, sway, yaw) median "
            f"{', '.join(f'{v:.3f}' for v in np.median(masses / truth[:, None], axis=0))}, range "
            f"{np.min(masses / truth[:, None]):.2f}-{np.max(masses / truth[:, None]):.2f} -> "
            f"{'PASS' if ok else 'FAIL'}")
    return lines


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("vessels", nargs="*", choices=[*VESSELS, []], help="default: all four")
    parser.add_argument("--seeds", type=int, default=40, help="random scenarios per vessel")
    parser.add_argument("--first-seed", type=int, default=1)
    parser.add_argument("--controllers", default="mrac,pd,pid", help="comma-separated: mrac, pd, pid")
    parser.add_argument("--jobs", type=int, default=1, help="worker processes")
    parser.add_argument("--json", type=Path, help="write every run's numbers here")
    parser.add_argument("--mrac", type=json.loads, default=None, help="the MRAC's control section (JSON)")
    parser.add_argument("--summarise", type=Path, help="print the tables of a --json file and exit")
    args = parser.parse_args()
    if args.mrac is not None:
        CONTROLLERS["mrac"] = args.mrac
    controllers = args.controllers.split(",")
    if args.summarise is not None:  # the tables of a finished (or interrupted) run
        rows = json.loads(args.summarise.read_text(encoding="utf-8"))
        for baseline in sorted({r["controller"] for r in rows} - {"mrac"}):
            for line in summarise(rows, baseline):
                print(line)
        return 0
    # seed by seed across the vessels: an interrupted campaign has covered every vessel alike
    tasks = [(v, s, c, CONTROLLERS[c]) for s in range(args.first_seed, args.first_seed + args.seeds)
             for v in (args.vessels or list(VESSELS)) for c in controllers]
    rows = []
    with multiprocessing.get_context("spawn").Pool(args.jobs) as pool:
        for row in pool.imap_unordered(_task, tasks):
            rows.append(row)
            print(f"{row['vessel']:<15} seed {row['seed']:>3} {row['controller']:<5} position rms "
                  f"{row['position_rms_m']:.3g} m, heading rms {row['heading_rms_deg']:.3g} deg"
                  + ("" if row["mass_ratio"] is None else
                     f"; mass/nominal {', '.join(f'{m:.3f}' for m in row['mass_ratio'])} "
                     f"(true {row['true_mass_factor']:.3f})"
                     + ("; SUSPENDED" if row["suspended"] else "") + ("; ON A BOUND" if row["on_bound"] else ""))
                  + f" [{row['cpu_s']:.0f} s CPU]", flush=True)
            if args.json is not None:
                args.json.write_text(json.dumps(rows, indent=1), encoding="utf-8")
    for baseline in (c for c in controllers if c != "mrac"):
        for line in summarise(rows, baseline):
            print(line)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
