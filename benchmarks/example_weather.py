"""Each example configuration in random weather with a move and a turn: does she hold, and what does she give up?

For each seed and each built-in DP vessel (CyberShip II, the supply vessel, the Blue Lady, the shuttle tanker), the
vessel's seed scenario (its sensors and datum) gets the random environment of
:func:`wave_filter_campaign.random_sea` (Hs 0.5–4 m, peak 0.35–1.3 rad/s, current 0–0.5 m/s and wind 0–12 m/s,
Froude-scaled below 76.2 m, the peak too since 2026-12-07 — ``--full-scale-periods`` gives the seas of the runs
documented before —; any direction) and three set-points: hold at the origin, at 30 % of the run a move of up to
0.1 L north and east, at 60 % back to the origin with a turn of up to ±20°. The controller is the example's
(``deploy/config``: its estimator, control, guidance, allocation, limits and deviation limits). Printed per run,
from the deviation monitor (the estimate against the reference the controller follows): the largest and the median
position [m] and heading [deg] deviation, and the alarms raised. Nothing is asserted: this prints what it measured.

It found the allocator's missing heading priority (docs/fault-handling.md): with equal slack weights the Blue Lady
fell 95° off heading in a 0.22 m/s current.

Usage::

    OPENBLAS_NUM_THREADS=1 nice -n 10 .venv/bin/python benchmarks/example_weather.py --seeds 0 1 2 3 4 5 6 7
    OPENBLAS_NUM_THREADS=1 nice -n 10 .venv/bin/python benchmarks/example_weather.py --seeds 0 --vessels blue_lady
    ... --allocation '{"slack_weight": 1e4, "slack_penalty": 1e4}'     # without heading priority
    ... --vessels supply --control '{"kind": "pid"}'                 # another controller (here the plain PID)
    ... --shortfall        # when two low-frequency shortfall criteria would have alarmed (see shortfall_onsets)
"""

from __future__ import annotations

import argparse
import json
import math
import time
from typing import Any

import numpy as np
import yaml
from example_configs import deviation_watch
from wave_filter_campaign import ROOT, VESSELS, random_sea

from dpcontrol.runtime.config import CONTROLLER_SECTIONS
from dpcontrol.runtime.step import CAPABILITY_FLOOR
from sim_plant.bench.run import build_simulation
from sim_plant.scenario import parse_scenario

MOVE_FRACTION = 0.1  # the move: up to this share of the ship length, north and east
TURN_DEG = 20.0  # the turn: up to this, either way
DURATION_S = 1200.0  # a full-scale vessel's run; Froude-scaled below 76.2 m [s]
SHORTFALL_WINDOW_S = 60.0  # the low-frequency window of --shortfall [s]


def case(vessel: str, seed: int, allocation: dict[str, Any] | None = None,
         control: dict[str, Any] | None = None, *, full_scale_periods: bool = False) -> tuple[dict[str, Any], float]:
    """The scenario mapping of (vessel, seed) and its duration [s]; ``allocation`` replaces the example's
    ``allocation:`` section (e.g. equal slack weights, to see what heading priority does), ``control`` its
    ``control:`` section; ``full_scale_periods``: the sea's peak not Froude-scaled."""
    scenario = yaml.safe_load((ROOT / "sim_plant" / "scenarios" / VESSELS[vessel][0]).read_text(encoding="utf-8"))
    length = float(parse_scenario(scenario, file=VESSELS[vessel][0]).vessel.length_m)
    rng = np.random.default_rng([list(VESSELS).index(vessel), seed, 1])  # (1: not the sea's own stream)
    duration = DURATION_S * min(1.0, math.sqrt(length / 76.2))
    move = MOVE_FRACTION * length
    scenario.update(random_sea(vessel, seed, length, full_scale_periods=full_scale_periods))
    scenario.update(name=f"weather-{vessel}-{seed}", duration_s=duration, seed=seed, mass_schedule=[], setpoints=[
        {"t_s": 0, "north_m": 0, "east_m": 0, "heading_deg": 0},
        {"t_s": round(0.3 * duration, 1), "north_m": round(float(rng.uniform(-move, move)), 3),
         "east_m": round(float(rng.uniform(-move, move)), 3), "heading_deg": 0},
        {"t_s": round(0.6 * duration, 1), "north_m": 0, "east_m": 0,
         "heading_deg": round(float(rng.uniform(-TURN_DEG, TURN_DEG)), 1)}])
    scenario.pop("faults", None)
    config = yaml.safe_load((ROOT / "deploy" / "config" / VESSELS[vessel][1]).read_text(encoding="utf-8"))
    scenario["controller"] = {key: config[key] for key in (*CONTROLLER_SECTIONS, "deviation") if key in config}
    if allocation is not None:
        scenario["controller"]["allocation"] = allocation
    if control is not None:
        scenario["controller"]["control"] = control
    return scenario, duration


def shortfall_onsets(demand: np.ndarray, achieved: np.ndarray, engaged: np.ndarray, dt_s: float, floor: np.ndarray,
                     *, fraction: float, persist_s: float) -> tuple[float | None, float | None]:
    """When two low-frequency versions of the ``thrusters.capability`` test would first have held for ``persist_s``.

    Parameters
    ----------
    demand, achieved : ndarray, shape (steps, 3)
        The controller's demand and the force the allocator achieved for it per step [N, N, N·m].
    engaged : ndarray of bool, shape (steps,)
        Steps with a reference (in DP).
    dt_s : float
        Control period [s].
    floor : ndarray, shape (3,)
        The alarm's floor of the demand [N, N, N·m] (``CAPABILITY_FLOOR`` × the fleet's capability).
    fraction, persist_s : float
        ``thruster_monitor.shortfall_fraction`` [-] and ``shortfall_persist_s`` [s].

    Returns
    -------
    mean, duty : float or None
        The time [s] from the first step at which, over the last ``SHORTFALL_WINDOW_S`` in DP, (mean) the mean
        shortfall exceeded ``fraction`` of the mean demand (or of the floor) in some DOF, or (duty) the demand was
        short by that much on one side more than half of the time, for ``persist_s``; None: never.
    """
    window = max(1, round(SHORTFALL_WINDOW_S / dt_s))
    kernel = np.ones(window) / window

    def mean(x: np.ndarray) -> np.ndarray:
        return np.column_stack([np.convolve(x[:, i], kernel, "valid") for i in range(3)])

    full = np.convolve(engaged.astype(float), kernel, "valid") > 1.0 - 1e-9
    short = np.abs(demand - achieved) > fraction * np.maximum(np.abs(demand), floor)
    mean_flag = full & np.any(np.abs(mean(demand - achieved)) > fraction * np.maximum(np.abs(mean(demand)), floor),
                              axis=1)
    duty_flag = full & np.any(np.abs(mean(np.where(short, np.sign(achieved - demand), 0.0))) > 0.5, axis=1)

    def onset(flag: np.ndarray) -> float | None:
        count = 0
        for k, on in enumerate(flag.tolist()):
            count = count + 1 if on else 0
            if count * dt_s >= persist_s - 1e-9:
                return (k + window - 1) * dt_s
        return None

    return onset(mean_flag), onset(duty_flag)


def run(vessel: str, seed: int, allocation: dict[str, Any] | None = None,
        control: dict[str, Any] | None = None, shortfall: bool = False, *, full_scale_periods: bool = False) -> str:
    """One run; the line it prints (with ``shortfall``: and :func:`shortfall_onsets`)."""
    scenario, duration = case(vessel, seed, allocation, control, full_scale_periods=full_scale_periods)
    simulation = build_simulation(parse_scenario(scenario, file=scenario["name"]))
    watch, position, heading = deviation_watch(simulation)
    forces: list[tuple[float, ...]] = []

    def observe(t_s: float, out: Any) -> None:
        watch(t_s, out)
        if shortfall:
            forces.append((*out.tau_b.tolist(), *out.tau_achieved_b.tolist(), float(out.reference is not None)))

    start = time.perf_counter()
    result = simulation.run(duration_s=duration, observer=observe, timeseries=False)
    extra = ""
    if shortfall and forces:
        rows = np.array(forces)
        monitor = simulation.config.thruster_monitor
        mean_at, duty_at = shortfall_onsets(rows[:, 0:3], rows[:, 3:6], rows[:, 6] > 0.0,
                                            simulation.config.sample_time_s,
                                            CAPABILITY_FLOOR * simulation.controller.allocator.capability_scale,
                                            fraction=monitor.shortfall_fraction,
                                            persist_s=monitor.shortfall_persist_s)
        extra = "; low-frequency shortfall: mean criterion {}, duty criterion {}".format(
            *("never" if at is None else f"at {at:.0f} s" for at in (mean_at, duty_at)))
    sea = scenario["sea_states"][0]
    alarms = sorted({e.code for e in result.alarm_events if e.raised and not e.code.startswith("consequence.")})
    return (f"{vessel:<15} seed {seed:<3} Hs {sea['hs_m']:.2f} m  ωp {sea['omega_peak_rad_s']:.2f}  current "
            f"{scenario['current']['speed_mps']:.2f} m/s  wind {scenario['wind']['speed_mps']:.1f} m/s: position "
            f"{max(position, default=0.0):.3g} m at most ({float(np.median(position or [0.0])):.3g} median), heading "
            f"{math.degrees(max(heading, default=0.0)):.3g}° ({math.degrees(float(np.median(heading or [0.0]))):.3g}); "
            f"alarms {', '.join(alarms) or 'none'}{extra} ({time.perf_counter() - start:.0f} s)")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3])
    parser.add_argument("--vessels", nargs="+", choices=list(VESSELS), default=list(VESSELS))
    parser.add_argument("--allocation", type=json.loads,
                        help='an allocation section replacing the example\'s (JSON), e.g. equal slack weights: '
                             '\'{"slack_weight": 1e4, "slack_penalty": 1e4}\'')
    parser.add_argument("--control", type=json.loads,
                        help='a control section replacing the example\'s (JSON), e.g. the plain PID: '
                             '\'{"kind": "pid"}\'')
    parser.add_argument("--shortfall", action="store_true",
                        help="also print when two low-frequency shortfall criteria would have alarmed")
    parser.add_argument("--full-scale-periods", action="store_true",
                        help="the sea's peak 0.35-1.3 rad/s for every vessel (the seas of the runs documented before "
                             "2026-12-07's Froude scaling)")
    args = parser.parse_args()
    for seed in args.seeds:
        for vessel in args.vessels:
            print(run(vessel, seed, args.allocation, args.control, args.shortfall,
                      full_scale_periods=args.full_scale_periods), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
