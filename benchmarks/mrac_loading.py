"""Loading test of the MRAC-augmented PD (seed 003): overshoot and settling per correction, MRAC vs the fixed PD.

Seed 003 (Tannuri et al.) loads a DP shuttle tanker from ballast towards full load and relocates her by 20 m every
30 min; its claim (seed 003 Figs. 9, 13 and eqs. (26)–(27)) is that the MRAC keeps the response of its reference
model while the fixed PD tuned at ballast loses damping as the mass grows. Here, per vessel and sea seed, in
lockstep:

* the vessel's rigid-body mass grows linearly by ``--factor`` (default 2.5) over ``--hours`` (default 4 h) and is
  then held for one more interval, the run's last ``--interval`` s (default 1200 s);
* a surge set-point correction of ``--move`` ship lengths (default 0.08 L: 20.8 m for the 260 m tanker, seed 003's
  20 m; the MRAC's design move) every ``--interval`` s from one interval on, alternating forward and back; the last
  one starts when the mass reaches its final factor;
* a moderate sea, current and wind from within ±30° of the bow (a DP shuttle tanker heads into the weather), drawn
  per (vessel, seed) (:func:`moderate_sea`);
* the same scenario runs twice: with the MRAC, and with the **fixed PD** it augments — ``{kind: mrac, adapt:
  false}``: seed 003 eq. (25), ``u = −M̂ β₁ ė − M̂ β₀ e + M̂ ÿ_M`` with M̂ frozen at the nominal (ballast) mass, the
  same reference model, bias compensation and wave filter. That is the PD of seed 003 Fig. 13 ("P and D gains ...
  evaluated by Eq. (25) considering the ballasted mass"), and the only difference between the two runs is the
  adaptation.

Vessels: ``shuttle_tanker`` with seed 003's scenario controller (``sim_plant/scenarios/tanker-seed003.yaml``: RPEM
wave filter, MRAC) and ``supply`` with its example configuration (``deploy/config/supply.yaml``: MMAE bank) and its
``control`` replaced by the MRAC (the example itself runs a PID; the MRAC's behaviour on her is a check that the
property is not the tanker's alone).

Measured for each correction from the true LF position in the time series, along the move:

* overshoot [m]: how far the vessel passes the new set-point (0 if she never does);
* settling time [s]: from the correction to the last time the position is outside ``±band × move`` of the new
  set-point (``--bands``, default 2 % and 5 %); ``None`` when she is still outside at the next correction. In a
  sea the true LF position wanders by a few decimetres while the vessel holds station (``res``: the largest
  deviation in each segment's second half), which for the tanker is the size of the 2 % band (0.42 m): the time
  the disturbance last crosses the band then decides the 2 % settling time, and the 5 % band (1.04 m) measures
  the response.

Printed: a table per (vessel, seed) with both controllers, then per vessel the ratio last/first correction of each
metric and controller over the seeds (median, min–max).

Usage::

    OPENBLAS_NUM_THREADS=1 nice -n 10 .venv/bin/python benchmarks/mrac_loading.py               # tanker, seeds 0-3
    ... benchmarks/mrac_loading.py --vessels shuttle_tanker supply --seeds 0 1 2 3 4 5
    ... benchmarks/mrac_loading.py --hours 2 --factor 2.0 --json out.jsonl
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from dpcontrol.runtime.config import CONTROLLER_SECTIONS
from sim_plant.bench.lockstep import RunResult
from sim_plant.bench.run import build_simulation
from sim_plant.scenario import parse_scenario

ROOT = Path(__file__).resolve().parents[1]
#: vessel → (its seed scenario: sensors, datum and, without an example, the controller; its example configuration
#: under deploy/config, or None to keep the scenario's controller)
VESSELS: dict[str, tuple[str, str | None]] = {
    "shuttle_tanker": ("tanker-seed003.yaml", None),
    "supply": ("supply-seed001.yaml", "supply.yaml"),
}
ENVIRONMENTS: tuple[str, ...] = ("moderate", "calm", "still", "seed003")
CONTROLLERS: dict[str, dict[str, Any]] = {
    "mrac": {"kind": "mrac"},
    "fixed_pd": {"kind": "mrac", "adapt": False},
}


@dataclass(frozen=True)
class Loading:
    """One loading run's schedule.

    Attributes
    ----------
    hours : float
        Duration of the mass ramp [h].
    factor : float
        Mass factor at the end of the ramp (from 1).
    interval_s : float
        Time between corrections [s]; the run lasts ``hours`` plus one interval.
    move_per_length : float
        Correction size over the ship length.
    loop_hz, plant_hz : float or None
        Control-loop and plant rates [Hz] (None: the scenario's / configuration's).
    environment : {"moderate", "calm", "still", "seed003"}
        ``moderate``: :func:`moderate_sea` of the seed; ``calm``: its current only, no waves and no wind (the
        response without the sea's disturbance); ``still``: no waves, wind or current (only the sensors' noise
        and the loop itself); ``seed003``: the vessel's seed scenario's own sea and current (for
        the tanker seed 003 Fig. 8: Hs 2 m, Tp 10 s and 1 m/s from ahead), the seed drawing its realisation.
    """

    hours: float = 4.0
    factor: float = 2.5
    interval_s: float = 1200.0
    move_per_length: float = 0.08
    loop_hz: float | None = None
    plant_hz: float | None = None
    environment: str = "moderate"

    @property
    def ramp_s(self) -> float:
        """Duration of the mass ramp [s]."""
        return self.hours * 3600.0

    @property
    def duration_s(self) -> float:
        """Duration of the run [s]."""
        return self.ramp_s + self.interval_s

    @property
    def corrections(self) -> int:
        """Number of corrections: one per interval, the last at the end of the ramp."""
        return round(self.ramp_s / self.interval_s)


def moderate_sea(vessel: str, seed: int) -> dict[str, Any]:
    """A moderate environment from ahead for (vessel, seed), in scenario-file units (degrees, from / toward).

    JONSWAP Hs uniform 1.5–3 m, Tp 8–12 s, γ 1–5, waves from within ±30° of the bow (heading 0: from the north);
    current 0.3–0.8 m/s setting astern within ±30°; wind 0–10 m/s from within ±30° of the bow. Seed 003's
    environment (Hs 2 m, Tp 10 s, 1 m/s current, all from ahead) is near its upper corner.
    """
    rng = np.random.default_rng([list(VESSELS).index(vessel), seed, 3])
    return {
        "sea_states": [{"t_s": 0, "spectrum": "jonswap", "hs_m": round(float(rng.uniform(1.5, 3.0)), 3),
                        "omega_peak_rad_s": round(2.0 * math.pi / float(rng.uniform(8.0, 12.0)), 4),
                        "gamma": round(float(rng.uniform(1.0, 5.0)), 2),
                        "direction_deg": round(float(rng.uniform(-30.0, 30.0)) % 360.0, 1), "fade_s": 1}],
        "current": {"speed_mps": round(float(rng.uniform(0.3, 0.8)), 3),
                    "direction_deg": round(180.0 + float(rng.uniform(-30.0, 30.0)), 1)},
        "wind": {"speed_mps": round(float(rng.uniform(0.0, 10.0)), 2),
                 "direction_deg": round(float(rng.uniform(-30.0, 30.0)) % 360.0, 1)},
    }


def scenario_mapping(vessel: str, seed: int, loading: Loading = Loading()) -> dict[str, Any]:
    """The scenario mapping of a loading run of ``vessel`` in the sea of ``seed`` (controller not chosen yet)."""
    scenario_file, example = VESSELS[vessel]
    scenario = yaml.safe_load((ROOT / "sim_plant" / "scenarios" / scenario_file).read_text(encoding="utf-8"))
    length = float(parse_scenario(scenario, file=scenario_file).vessel.length_m)
    move = round(loading.move_per_length * length, 3)
    if loading.environment not in ENVIRONMENTS:
        raise ValueError(f"environment must be one of {ENVIRONMENTS}, got {loading.environment!r}")
    if loading.environment != "seed003":
        scenario.update(moderate_sea(vessel, seed))
    if loading.environment in ("calm", "still"):
        scenario["sea_states"] = [{**scenario["sea_states"][0], "hs_m": 0.0}]
        scenario["wind"] = {**scenario["wind"], "speed_mps": 0.0}
    if loading.environment == "still":
        scenario["current"] = {**scenario["current"], "speed_mps": 0.0}
    setpoints: list[dict[str, float]] = [{"t_s": 0.0, "north_m": 0.0, "east_m": 0.0, "heading_deg": 0.0}]
    for k in range(1, loading.corrections + 1):
        setpoints.append({"t_s": round(k * loading.interval_s, 3), "north_m": move if k % 2 else 0.0,
                          "east_m": 0.0, "heading_deg": 0.0})
    scenario.update(name=f"loading-{vessel}-{seed}", duration_s=loading.duration_s, seed=seed, setpoints=setpoints,
                    mass_schedule=[{"t_s": 0, "factor": 1.0}, {"t_s": loading.ramp_s, "factor": loading.factor}])
    scenario.pop("faults", None)
    if loading.plant_hz is not None:
        scenario["plant"] = {**scenario.get("plant", {}), "rate_hz": loading.plant_hz}
    if example is not None:
        config = yaml.safe_load((ROOT / "deploy" / "config" / example).read_text(encoding="utf-8"))
        scenario["controller"] = {key: config[key] for key in CONTROLLER_SECTIONS if key in config}
        scenario["controller"].pop("loop", None)  # standby starts etc. are the installation's: DP at once
    return scenario


def controller_overrides(control: dict[str, Any], loading: Loading) -> dict[str, Any]:
    """The ``overrides`` of :func:`sim_plant.bench.run.build_simulation` for one controller of a loading run."""
    overrides: dict[str, Any] = {"control": dict(control)}
    if loading.loop_hz is not None:
        overrides["loop"] = {"rate_hz": loading.loop_hz}
    return overrides


def settling_key(band: float) -> str:
    """The metric name of the settling time into ``±band × move``: ``settling_2pct_s`` for 0.02."""
    return f"settling_{band * 100.0:g}pct_s"


def correction_metrics(result: RunResult, bands: Sequence[float] = (0.02, 0.05)) -> list[dict[str, Any]]:
    """Per correction (set-point change of position): the mass factor at it, the overshoot [m] of the true LF
    position beyond the new set-point along the move, the settling time [s] into ``±band × move`` per band
    (:func:`settling_key`; None: not
    settled before the next correction or the end), the largest deviation [m] along the move in the segment's
    second half (the station keeping the settling band is up against) and the controller's surge mass over the
    true one at the segment's end (the fixed PD: its nominal mass)."""
    c = result.columns
    data = c.data[: c.rows]
    t = data[:, c.index("t_s")]
    north = data[:, c.index("north_m")]
    east = data[:, c.index("east_m")]
    mass = data[:, c.index("mrac_mass_surge_kg")] / data[:, c.index("true_surge_mass_kg")]
    points = result.scenario.setpoints
    end_s = float(t[-1]) + (float(t[-1] - t[-2]) if t.size > 1 else 0.0)
    out: list[dict[str, Any]] = []
    for i in range(1, len(points)):
        old, new = points[i - 1], points[i]
        if None in (old.north_m, old.east_m, new.north_m, new.east_m):
            continue
        step = (float(new.north_m) - float(old.north_m), float(new.east_m) - float(old.east_m))  # type: ignore[arg-type]
        length = math.hypot(*step)
        if length == 0.0:
            continue
        start = float(new.t_s)
        stop = float(points[i + 1].t_s) if i + 1 < len(points) else end_s
        sel = (t >= start) & (t < stop)
        if not np.any(sel):
            continue
        along = (step[0] * (north[sel] - float(new.north_m)) + step[1] * (east[sel] - float(new.east_m))) / length  # type: ignore[arg-type]
        settling: dict[str, float | None] = {}
        for band in bands:
            outside = np.flatnonzero(np.abs(along) > band * length)
            if outside.size == 0:
                settling[settling_key(band)] = 0.0
            elif outside[-1] == along.size - 1:
                settling[settling_key(band)] = None
            else:
                settling[settling_key(band)] = round(float(t[sel][outside[-1] + 1] - start), 1)
        ratio = mass[sel][np.isfinite(mass[sel])]
        late = t[sel] >= start + 0.5 * (stop - start)
        out.append({"t_s": start, "mass_factor": round(result.scenario.mass_factor_at(start), 3),
                    "move_m": round(length, 3), "overshoot_m": round(max(0.0, float(np.max(along))), 3),
                    **settling,
                    "residual_m": round(float(np.max(np.abs(along[late]))), 3) if np.any(late) else None,
                    "mass_ratio_end": round(float(ratio[-1]), 3) if ratio.size else None})
    return out


def timed_run(mapping: dict[str, Any], overrides: dict[str, Any]) -> tuple[RunResult, float, np.ndarray]:
    """Run the scenario ``mapping`` with the controller ``overrides``; the result, its wall time [s] and its recorded
    columns (``result.columns.data`` up to the rows written)."""
    simulation = build_simulation(parse_scenario(mapping, file=mapping["name"]), overrides=overrides)
    start = time.perf_counter()
    result = simulation.run()
    wall = time.perf_counter() - start
    return result, wall, result.columns.data[: result.columns.rows]


def run(vessel: str, seed: int, controller: str, loading: Loading = Loading(),
        bands: Sequence[float] = (0.02, 0.05), *, control: dict[str, Any] | None = None) -> dict[str, Any]:
    """One run; returns its per-correction metrics, the final MRAC surge-mass error and the wall time. ``control``:
    keys added to both controllers' ``control`` section (e.g. ``{"actuator_time_constant_s": 0}``)."""
    mapping = scenario_mapping(vessel, seed, loading)
    result, wall, data = timed_run(mapping, controller_overrides({**CONTROLLERS[controller], **(control or {})},
                                                                 loading))
    c = result.columns
    mass = data[:, c.index("mrac_mass_surge_kg")]
    true = data[:, c.index("true_surge_mass_kg")]
    ok = np.isfinite(mass) & np.isfinite(true)
    mass_error = float(100.0 * (mass[ok][-1] / true[ok][-1] - 1.0)) if np.any(ok) else math.nan
    return {"vessel": vessel, "seed": seed, "controller": controller, "corrections": correction_metrics(result, bands),
            "mass_error_pct": round(mass_error, 2), "sea": mapping["sea_states"][0], "current": mapping["current"],
            "wind": mapping.get("wind", {"speed_mps": 0.0}), "wall_s": round(wall, 1)}


def metric_names(result: dict[str, Any]) -> list[str]:
    """The per-correction metrics of a run's rows that are compared first to last: the overshoot and the settling
    times."""
    return ["overshoot_m", *(key for key in result["corrections"][0] if key.startswith("settling_"))]


def ratio(values: Sequence[float | None], censor: float | None = None) -> tuple[float | None, bool]:
    """Last over first of ``values`` and whether it is a lower bound: a last value of None (not settled) counts as
    ``censor`` (the segment's length) when given. (None, False) when the first is None or 0."""
    first, last = values[0], values[-1]
    if first is None or first == 0.0:
        return None, False
    if last is None:
        return (None, False) if censor is None else (censor / first, True)
    return last / first, False


def thirds(values: Sequence[float | None], censor: float) -> float | None:
    """Median of the last third of ``values`` over the median of the first third (None counts as ``censor``): the
    trend, less sensitive than last/first to the one correction a gust or a wave group decides."""
    n = max(1, len(values) // 3)
    first = statistics.median(censor if v is None else v for v in values[:n])
    last = statistics.median(censor if v is None else v for v in values[-n:])
    return None if first == 0.0 else last / first


def _fmt(value: float | None, spec: str) -> str:
    return "—" if value is None else format(value, spec)


def _ratio_text(value: tuple[float | None, bool]) -> str:
    return ("≥" if value[1] else "") + _fmt(value[0], ".2f")


def print_table(runs: dict[str, dict[str, Any]], interval_s: float) -> None:
    """One (vessel, seed)'s corrections, the controllers side by side; settling times at the first band."""
    first = next(iter(runs.values()))
    sea, current, wind = first["sea"], first["current"], first["wind"]
    names = list(runs)
    metrics = metric_names(first)
    tp = sea["tp_s"] if "tp_s" in sea else 2.0 * math.pi / sea["omega_peak_rad_s"]
    print(f"\n{first['vessel']} seed {first['seed']}: Hs {sea['hs_m']} m, Tp {tp:.1f} s from {sea['direction_deg']}°, "
          f"current {current['speed_mps']} m/s, wind {wind['speed_mps']} m/s; "
          + ", ".join(f"{name} mass error at the end {r['mass_error_pct']:+.1f} % ({r['wall_s']:.0f} s)"
                      for name, r in runs.items()))
    header = f"{'t [s]':>7} {'mass×':>6}"
    for name in names:
        header += f" | {name:>9} os [m]" + "".join(f" {key.split('_')[1]:>7}" for key in metrics[1:])
        header += f" {'res [m]':>7} {'m̂/m':>6}"
    print(header + "   (settling times [s]; res: largest deviation in the segment's second half)")
    for rows in zip(*(r["corrections"] for r in runs.values()), strict=True):
        line = f"{rows[0]['t_s']:7.0f} {rows[0]['mass_factor']:6.3f}"
        for row in rows:
            line += f" | {_fmt(row['overshoot_m'], '.3f'):>16}"
            line += "".join(f" {_fmt(row[key], '.0f'):>7}" for key in metrics[1:])
            line += f" {_fmt(row['residual_m'], '.2f'):>7} {_fmt(row['mass_ratio_end'], '.3f'):>6}"
        print(line)
    for name, r in runs.items():
        parts = [f"{key} {_ratio_text(ratio([row[key] for row in r['corrections']], interval_s))}" for key in metrics]
        print(f"  {name}: last/first " + ", ".join(parts))


def print_spread(results: list[dict[str, Any]], interval_s: float) -> None:
    """Per vessel and controller over the seeds: last/first and last-third/first-third ratios (median, min–max),
    and the first and last values (median)."""
    print("\nover the seeds: last/first median (min–max) | last third/first third median (min–max) | "
          "first → last value, median")
    keys = sorted({(r["vessel"], r["controller"]) for r in results})
    for vessel, controller in keys:
        rows = [r for r in results if r["vessel"] == vessel and r["controller"] == controller]
        print(f"{vessel} {controller} ({len(rows)} seeds):")
        for metric in metric_names(rows[0]):
            ratios = [ratio([row[metric] for row in r["corrections"]], interval_s) for r in rows]
            finite = [v for v, _ in ratios if v is not None]
            bounds = sum(bound for _, bound in ratios)
            trend = [v for v in (thirds([row[metric] for row in r["corrections"]], interval_s) for r in rows)
                     if v is not None]
            firsts = [r["corrections"][0][metric] for r in rows]
            known = [v for v in firsts if v is not None]  # (none when no run settled at its first correction)
            lasts = [interval_s if r["corrections"][-1][metric] is None else r["corrections"][-1][metric] for r in rows]

            def spread(values: list[float]) -> str:
                return f"{statistics.median(values):.2f} ({min(values):.2f}–{max(values):.2f})" if values else "—"

            print(f"  {metric:20s} {spread(finite)}{f' [{bounds} lower bounds: not settled]' if bounds else ''} | "
                  f"{spread(trend)} | {_fmt(statistics.median(known) if known else None, '.3g')} → "
                  f"{statistics.median(lasts):.3g}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--vessels", nargs="+", choices=list(VESSELS), default=["shuttle_tanker"])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3])
    parser.add_argument("--hours", type=float, default=4.0, help="duration of the mass ramp [h] (default 4)")
    parser.add_argument("--factor", type=float, default=2.5, help="mass factor at the end of the ramp (default 2.5)")
    parser.add_argument("--interval", type=float, default=1200.0, help="time between corrections [s]")
    parser.add_argument("--move", type=float, default=0.08, help="correction over the ship length (default 0.08)")
    parser.add_argument("--bands", type=float, nargs="+", default=[0.02, 0.05],
                        help="settling bands over the move (default 0.02 0.05)")
    parser.add_argument("--loop-hz", type=float, default=None, help="control-loop rate [Hz] (default: the config's)")
    parser.add_argument("--plant-hz", type=float, default=None, help="plant rate [Hz] (default: the scenario's)")
    parser.add_argument("--environment", choices=ENVIRONMENTS, default="moderate",
                        help="moderate (default): a moderate sea per seed; calm: its current only; still: no waves, "
                             "wind or current; seed003: the seed scenario's own sea and current")
    parser.add_argument("--controllers", nargs="+", choices=list(CONTROLLERS), default=list(CONTROLLERS))
    parser.add_argument("--control", default=None,
                        help="JSON object of control keys added to both controllers (kind: mrac)")
    parser.add_argument("--json", type=Path, default=None, help="append one JSON object per run to this file")
    args = parser.parse_args(argv)
    loading = Loading(hours=args.hours, factor=args.factor, interval_s=args.interval, move_per_length=args.move,
                      loop_hz=args.loop_hz, plant_hz=args.plant_hz, environment=args.environment)
    results: list[dict[str, Any]] = []
    for vessel in args.vessels:
        for seed in args.seeds:
            runs = {}
            for controller in args.controllers:
                result = run(vessel, seed, controller, loading, args.bands,
                             control=json.loads(args.control) if args.control else None)
                runs[controller] = result
                results.append(result)
                if args.json is not None:
                    with args.json.open("a", encoding="utf-8") as stream:
                        stream.write(json.dumps(result) + "\n")
            print_table(runs, loading.interval_s)
            sys.stdout.flush()
    print_spread(results, loading.interval_s)
    return 0


if __name__ == "__main__":
    sys.exit(main())
