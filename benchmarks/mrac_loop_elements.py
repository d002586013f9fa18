"""Which element of the closed loop makes the MRAC's surge mass estimate run up in still water.

The supply vessel's surge mass estimate rises from 0.67× to 1.6–1.8× the true mass within two minutes of the first
0.08 L move of :mod:`benchmarks.mrac_loading` in still water (``--environment still``: no waves, wind or current),
where the perfect-state benchmark (:mod:`benchmarks.mrac_estimate_bias`) keeps it at 1.000. This runs that loading
case (the lockstep simulation: sensors, wave filter, guidance, MRAC, allocation, thruster drives, plant; the mass
ramp ×2.5 over ``--hours`` 1 h, a correction every 1200 s, the first at mass ×1.5 — from which on the mass is held,
so that the estimate has one target, unless ``--ramp``) with the loop's elements switched on or off one at a time:

* ``slew``: the azimuths' slew-rate limit (12°/s on the supply vessel), in the allocator and in the plant's drives
  (off: the vessel data without it, so the azimuths turn at once);
* ``rate``: the thrust-rate limits (30–50 kN/s), allocator and drives (off: 10⁶ × the maximum thrust per second);
* ``lag``: the drives' first-order time constant (2 s; off: 1 ms), which the allocator does not model;
* ``noise``: the sensors' noise (GNSS 0.3 m white and 0.3 m Markov, the gyro's 0.05°; off: 1 mm and 0.001°);
* ``tuning``: the controller's sensor configuration (``sigma_m``, ``sigma_deg``, from which the wave filter's
  measurement noise and so its gains follow) for those noisy sensors (off: for the sensors of the case);
* ``filter``: the wave filter of the configuration (the supply vessel's MMAE bank; off: ``raw``, the LF observer
  alone).

Each case is named by the elements it has (``all``: the loop as configured; ``none``: all six off; or a
comma-separated list such as ``slew,lag``), by the one it removes from ``all`` (``no-slew``) or by the one it keeps
(``only-slew``). Printed per case: the surge estimate over the true mass at its peak and at the end of each
correction's interval, each correction's overshoot [m] (:func:`mrac_loading.correction_metrics`), the delay of the
plant's surge force behind the command that lines the two up best after the first move [s], and whether the
supervision suspended the adaptation (an estimate on its bound; it then continues at the nominal mass). With
``--decompose`` also what the law learnt in each correction from the true tracking error and from the estimate's
error (:func:`_decompose`).

Run (6–15 s per case, one process)::

    OPENBLAS_NUM_THREADS=1 nice -n 10 .venv/bin/python benchmarks/mrac_loop_elements.py          # the default cases
    ... benchmarks/mrac_loop_elements.py --cases all no-slew none only-slew --vessel shuttle_tanker
    ... benchmarks/mrac_loop_elements.py --override '{"dead_zone_noise_factor": 3}'
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
from scipy.linalg import solve_continuous_lyapunov

from dpcontrol.control.mrac import default_mrac_config
from dpcontrol.models.vessels import BUILTIN_VESSELS, VesselData
from sim_plant.bench.lockstep import controller_mapping
from sim_plant.scenario import parse_scenario

sys.path.insert(0, str(Path(__file__).resolve().parent))
import mrac_loading  # the loading case: scenario, sea, schedule

ELEMENTS: tuple[str, ...] = ("slew", "rate", "lag", "noise", "tuning", "filter")
DEFAULT_CASES: tuple[str, ...] = ("all", "no-slew", "no-rate", "no-lag", "no-noise", "no-tuning", "no-filter", "none",
                                  "only-slew", "only-rate", "only-lag", "only-noise", "only-tuning", "only-filter")


def elements_of(case: str) -> frozenset[str]:
    """The loop elements a case has (see the module docstring)."""
    if case == "all":
        return frozenset(ELEMENTS)
    if case == "none":
        return frozenset()
    kind, _, element = case.partition("-")
    if kind in ("no", "only") and element in ELEMENTS:
        return frozenset(ELEMENTS) - {element} if kind == "no" else frozenset({element})
    parts = frozenset(case.split(","))
    if not parts <= set(ELEMENTS):
        raise ValueError(f"a case is all, none, ±element or a comma-separated list of {ELEMENTS}, got {case!r}")
    return parts


def vessel_with(vessel: VesselData, elements: frozenset[str]) -> VesselData:
    """The vessel data with the thruster elements not in ``elements`` removed."""
    thrusters = []
    for spec in vessel.thrusters:
        changes: dict[str, Any] = {}
        if "slew" not in elements and spec.azimuth_rate_limit_radps is not None:
            changes["azimuth_rate_limit_radps"] = None
        if "rate" not in elements:
            changes["thrust_rate_limit_nps"] = 1e6 * spec.max_thrust_n
        if "lag" not in elements:
            changes["time_constant_s"] = 1e-3
        thrusters.append(replace(spec, **changes))
    return replace(vessel, thrusters=tuple(thrusters))


def _quiet(sensors: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The scenario's sensors with a little white noise only (the sensor monitoring rejects a signal that never
    changes)."""
    out = []
    for original in sensors:
        sensor = dict(original)
        if sensor.get("kind") == "gnss":
            sensor.update(noise_m=1e-3, markov_m=0.0, velocity_noise_mps=1e-4)
        elif sensor.get("kind") == "gyro":
            sensor.update(noise_deg=1e-3, bias_deg=0.0)
        out.append(sensor)
    return out


def run_case(vessel_name: str, seed: int, case: str, loading: mrac_loading.Loading,
             override: dict[str, Any] | None = None, *, hold_mass: bool = True) -> dict[str, Any]:
    """One case of the still-water loading run; see the module docstring for what is returned."""
    elements = elements_of(case)
    mapping = mrac_loading.scenario_mapping(vessel_name, seed, loading)
    mapping["vessel"] = vessel_with(BUILTIN_VESSELS[vessel_name], elements)
    noisy = mapping["sensors"]
    if "noise" not in elements:
        mapping["sensors"] = _quiet(noisy)
    if hold_mass:  # the mass reaches the first correction's and stays: the estimate's target is one number
        first = float(mapping["setpoints"][1]["t_s"])
        factor = round(1.0 + (loading.factor - 1.0) * first / loading.ramp_s, 6)
        mapping["mass_schedule"] = [{"t_s": 0, "factor": 1.0}, {"t_s": first, "factor": factor}]
    control: dict[str, Any] = {"kind": "mrac", **(override or {})}
    overrides = mrac_loading.controller_overrides(control, loading)
    if ("tuning" in elements) != ("noise" in elements):  # the controller configured for the other sensors
        other = {**mapping, "sensors": noisy if "tuning" in elements else _quiet(noisy)}
        overrides["sensors"] = controller_mapping(parse_scenario(other, file=other["name"]))["sensors"]
    if "filter" not in elements:
        overrides["estimator"] = {"kind": "raw"}
    result, wall, data = mrac_loading.timed_run(mapping, overrides)
    c = result.columns
    t = data[:, c.index("t_s")]
    ratio = data[:, c.index("mrac_mass_surge_kg")] / data[:, c.index("true_surge_mass_kg")]
    tau = data[:, c.index("tau_x_n")]
    points = [float(p.t_s) for p in result.scenario.setpoints[1:]]
    peaks = []
    ends = []
    for k, start_s in enumerate(points):
        stop_s = points[k + 1] if k + 1 < len(points) else float(t[-1]) + 1.0
        sel = (t >= start_s) & (t < stop_s) & np.isfinite(ratio)
        peaks.append(round(float(np.max(ratio[sel])), 3) if np.any(sel) else None)
        ends.append(round(float(ratio[sel][-1]), 3) if np.any(sel) else None)
    metrics = mrac_loading.correction_metrics(result)
    from_true, from_estimate = _decompose(mapping["vessel"], c, data, points)
    # the force the plant got over the command, after the first move: how much of the command arrives
    after = t >= points[0]
    act = data[after, c.index("tau_act_x_n")]
    lag_s = _delay_s(t[after], tau[after], act)
    suspended = any(event.code == "control.adaptation" and event.raised for event in result.alarm_events)
    return {"vessel": vessel_name, "seed": seed, "case": case, "elements": sorted(elements), "peak": peaks,
            "end": ends, "overshoot_m": [row["overshoot_m"] for row in metrics],
            "force_delay_s": lag_s, "suspended": suspended, "from_true_error": from_true,
            "from_estimate_error": from_estimate, "wall_s": round(wall, 1)}


def _decompose(vessel: VesselData, c: Any, data: np.ndarray, points: list[float]) -> tuple[list[float], list[float]]:
    """What the law (21) learnt in each correction's first 300 s (surge, over the true mass), split into the part
    from the true tracking error and the part from the estimate's error: ``−Γ g₁₂ ∫ ÿ_M s̄ dt`` over the steps the
    gate is open, with ``s̄ = e + (g₂₂/g₁₂) ė`` of the true LF state and of the estimate against the recorded y_M
    (its rates by finite differences; heading ≈ 0, so surge is north). An approximation of the law (no dead zone,
    projection or freeze): the two parts show where the learning came from, not its exact amount."""
    config = default_mrac_config(vessel)
    beta0, beta1 = float(config.beta0[0]), float(config.beta1[0])
    g = solve_continuous_lyapunov(np.array([[0.0, -beta0], [1.0, -beta1]]), -np.diag(config.lyapunov_q))  # (20)
    g12 = float(g[0, 1])
    ratio = float(g[1, 1]) / g12
    gamma = config.adaptation_gain_mass[0]
    t = data[:, c.index("t_s")]
    dt = float(np.median(np.diff(t)))
    y_m = data[:, c.index("mrac_ref_model_north_m")]
    yd_m = np.gradient(y_m, dt)
    ydd_m = np.gradient(yd_m, dt)
    s_true = data[:, c.index("north_m")] - y_m + ratio * (data[:, c.index("surge_mps")] - yd_m)
    s_est = data[:, c.index("est_north_m")] - y_m + ratio * (data[:, c.index("est_surge_mps")] - yd_m)
    mass = data[:, c.index("true_surge_mass_kg")]
    from_true, from_estimate = [], []
    for start_s in points:
        sel = (t >= start_s) & (t < start_s + 300.0) & (np.abs(ydd_m) > config.accel_threshold[0]) & np.isfinite(s_est)
        if not np.any(sel):
            from_true.append(math.nan)
            from_estimate.append(math.nan)
            continue
        scale = -gamma * g12 * dt / float(mass[sel][-1])
        from_true.append(round(scale * float(np.sum(ydd_m[sel] * s_true[sel])), 3))
        from_estimate.append(round(scale * float(np.sum(ydd_m[sel] * (s_est[sel] - s_true[sel]))), 3))
    return from_true, from_estimate


def _delay_s(t: np.ndarray, command: np.ndarray, actual: np.ndarray) -> float | None:
    """The delay of the plant's surge force behind the command that best lines them up [s] (cross-correlation)."""
    if t.size < 10:
        return None
    dt = float(np.median(np.diff(t)))
    a = command - command.mean()
    b = actual - actual.mean()
    best, best_lag = -math.inf, 0
    for lag in range(round(30.0 / dt)):
        value = float(np.dot(a[: a.size - lag], b[lag:]))
        if value > best:
            best, best_lag = value, lag
    return round(best_lag * dt, 1)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--vessel", default="supply", choices=list(mrac_loading.VESSELS))
    parser.add_argument("--seeds", type=int, nargs="+", default=[0])
    parser.add_argument("--cases", nargs="+", default=list(DEFAULT_CASES))
    parser.add_argument("--hours", type=float, default=1.0, help="duration of the mass ramp [h] (default 1)")
    parser.add_argument("--factor", type=float, default=2.5, help="mass factor at the end of the ramp (default 2.5)")
    parser.add_argument("--loop-hz", type=float, default=2.0, help="control-loop rate [Hz] (default 2)")
    parser.add_argument("--plant-hz", type=float, default=5.0, help="plant rate [Hz] (default 5)")
    parser.add_argument("--environment", choices=mrac_loading.ENVIRONMENTS, default="still")
    parser.add_argument("--override", default=None, help="JSON object of extra control keys (kind: mrac)")
    parser.add_argument("--ramp", action="store_true",
                        help="the loading ramp to the end (default: the mass held from the first correction on)")
    parser.add_argument("--decompose", action="store_true",
                        help="also print what the law learnt per correction from the true and the estimate's error")
    parser.add_argument("--json", action="store_true", help="one JSON object per line")
    args = parser.parse_args(argv)
    loading = mrac_loading.Loading(hours=args.hours, factor=args.factor, loop_hz=args.loop_hz, plant_hz=args.plant_hz,
                                   environment=args.environment)
    override = json.loads(args.override) if args.override else None
    if not args.json:
        print(f"{'case':10s} {'elements':28s} {'peak m̂/m per correction':>26s} {'end m̂/m per correction':>26s}"
              f" {'overshoot [m]':>20s} {'delay':>6s}")
    for seed in args.seeds:
        for case in args.cases:
            result = run_case(args.vessel, seed, case, loading, override, hold_mass=not args.ramp)
            if args.json:
                print(json.dumps(result), flush=True)
                continue

            def row(values: list[Any], spec: str) -> str:
                return " ".join("—" if v is None else format(v, spec) for v in values)

            print(f"{case:10s} {','.join(result['elements']) or '-':28s} {row(result['peak'], '8.3f'):>26s} "
                  f"{row(result['end'], '8.3f'):>26s} {row(result['overshoot_m'], '6.2f'):>20s} "
                  f"{result['force_delay_s']:5.1f}s{'  SUSPENDED' if result['suspended'] else ''}"
                  f"  (seed {seed}, {result['wall_s']:.0f} s)", flush=True)
            if args.decompose:
                print(f"{'':10s} learnt from the true error {row(result['from_true_error'], '+7.3f')}, "
                      f"from the estimate's error {row(result['from_estimate_error'], '+7.3f')}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
