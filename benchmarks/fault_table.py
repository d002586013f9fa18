"""The README's fault table (docs/fault-handling.md): every fault-injection scenario of ``sim_plant/scenarios/faults/``
run in lockstep, each injected fault with the delay to the alarm that proves its detection, the
configured bound, the response (mode changes, fall-backs) and the station keeping measured.

Detection per fault: :func:`sim_plant.bench.report.fault_detections` (the first raise of one of the
alarm codes that prove that kind of fault on that target, e.g. ``sensor.gnss1.frozen``, within the
fault or twice its bound). Station keeping: the largest distance of the true LF position from the
reference and the largest heading error from 60 s on (DP engages at 20 s); the largest thrust-command
change beyond the drives' rate limits (0: no thrust jump).

Usage::

    .venv/bin/python benchmarks/fault_table.py [--markdown]
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from sim_plant.bench.lockstep import ProbedRun
from sim_plant.bench.report import fault_detections
from sim_plant.bench.run import build_simulation
from sim_plant.scenario import load_scenario

FAULTS = Path(__file__).resolve().parents[1] / "sim_plant" / "scenarios" / "faults"
SETTLED_S = 60.0


def measure(path: Path) -> dict[str, Any]:
    """Run one fault scenario and measure its detections, response and station keeping."""
    wall = time.perf_counter()
    run = ProbedRun.run(build_simulation(load_scenario(path)))
    window = run.between(SETTLED_S, math.inf)
    rows = []
    for detection in fault_detections(run.result):
        fault = detection.fault
        rows.append({"t_s": fault.t_s, "kind": fault.kind, "target": fault.target, "alarm": detection.code,
                     "detected_after_s": detection.detected_s, "bound_s": detection.bound_s,
                     "within_bound": detection.within_bound})
    return {
        "scenario": path.stem, "faults": rows,
        "mode_changes": [(round(t, 1), old, new, why) for t, old, new, why in run.result.mode_changes],
        "position_error_max_m": float(np.nanmax(run.position_error_m()[window])),
        "heading_error_max_deg": float(np.degrees(np.nanmax(run.heading_error_rad()[window]))),
        "thrust_rate_excess_n": run.thrust_rate_excess_n(),
        "wall_s": time.perf_counter() - wall,
    }


def _fmt(value: float | None, digits: int = 2) -> str:
    return "—" if value is None else f"{value:.{digits}f}"


def markdown(results: list[dict[str, Any]]) -> str:
    lines = ["| scenario | fault (t, target) | alarm | detected after [s] | bound [s] | response "
             "| max pos. error [m] | max heading error [°] |",
             "|---|---|---|---|---|---|---|---|"]
    for result in results:
        response = "; ".join(f"{t:g} s {old}→{new} ({why})" for t, old, new, why in result["mode_changes"]
                             if t > 20.5) or "DP stays in auto_position"
        for i, row in enumerate(result["faults"]):
            lines.append(
                f"| {result['scenario'] if i == 0 else ''} | {row['kind']} {row['t_s']:g} s {row['target']} "
                f"| {row['alarm'] or '—'} | {_fmt(row['detected_after_s'])} | {_fmt(row['bound_s'])} "
                f"| {response if i == 0 else ''} "
                f"| {_fmt(result['position_error_max_m']) if i == 0 else ''} "
                f"| {_fmt(result['heading_error_max_deg']) if i == 0 else ''} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--markdown", action="store_true", help="print the README table")
    args = parser.parse_args(argv)
    results = []
    for path in sorted(FAULTS.glob("*.yaml")):
        result = measure(path)
        results.append(result)
        if not args.markdown:
            print(f"{result['scenario']}: {result['wall_s']:.1f} s wall, pos ≤ {result['position_error_max_m']:.2f} m,"
                  f" heading ≤ {result['heading_error_max_deg']:.2f}°, thrust-rate excess "
                  f"{result['thrust_rate_excess_n']:.1f} N")
            for row in result["faults"]:
                print(f"   {row['kind']:<20} {row['target']:<10} t={row['t_s']:>6g}  alarm={row['alarm']}  "
                      f"after={_fmt(row['detected_after_s'])} s  bound={_fmt(row['bound_s'])} s  "
                      f"ok={row['within_bound']}")
            for change in result["mode_changes"]:
                print(f"   mode {change}")
    if args.markdown:
        print(markdown(results))
    missed = [(r["scenario"], f["kind"]) for r in results for f in r["faults"]
              if f["bound_s"] is not None and not f["within_bound"]]
    if missed:
        print(f"not detected within the bound: {missed}", file=sys.stderr)
    return 1 if missed else 0


if __name__ == "__main__":
    sys.exit(main())
