"""A lone GNSS receiver whose noise grows: the fail-safe cases of ``gnss_noise`` over noise factors × durations ×
vessels × seeds (one GNSS, one gyro; :mod:`sim_plant.bench.failsafe`).

Per run: the largest true LF position / heading distance from the set-point from 60 s on (as the campaign) and from
the noise's start on (what the noise did, without the settling after DP engages), whether within the bounds
(3 m / 3°, 43 mm on CyberShip II) from the noise's start, when ``position.noisy_reference`` was raised after the
noise started and cleared after it ended [s] (``-``: not raised), and the alarms raised. Then per vessel and factor
the median and largest position / heading from the noise's start and the share of runs within the bounds.
``--no-gst``: the receiver sends no GST (the hub sees the noise only in the positions). Nothing is asserted: this
prints what it measured.

Usage::

    OPENBLAS_NUM_THREADS=1 nice -n 10 python benchmarks/noise_sweep.py --seeds 1 2 3
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np

from sim_plant.bench.failsafe import VESSELS, Case, run_case


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--factors", type=float, nargs="+", default=[3.0, 5.0, 10.0, 20.0])
    parser.add_argument("--durations", type=float, nargs="+", default=[10.0, 30.0, 60.0, 120.0],
                        help="full-scale noise durations [s] (Froude-scaled on CyberShip II)")
    parser.add_argument("--vessels", default="supply,cybership2")
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    parser.add_argument("--no-gst", action="store_true", help="receivers without GST")
    args = parser.parse_args(argv)
    if args.no_gst:
        for spec in VESSELS.values():
            spec["gnss"] = {**spec["gnss"], "gst": False}
    rows: dict[tuple[str, float], list[tuple[float, float, bool]]] = {}
    wall = time.perf_counter()
    print(f"{'vessel':10s} {'factor':>6s} {'dur_s':>6s} {'seed':>4s} {'from 60 s':>16s} {'from the noise':>16s} "
          f"{'ok':3s} {'raised':>6s} {'cleared':>7s}  alarms")
    for vessel in args.vessels.split(","):
        scale = 1.0 if vessel == "supply" else 1000.0
        unit = "m" if vessel == "supply" else "mm"
        for factor in args.factors:
            for duration in args.durations:
                for seed in args.seeds:
                    rng = np.random.default_rng(seed)
                    case = Case(vessel=vessel, fault="gnss_noise", start_s=float(np.round(rng.uniform(90, 200), 1)),
                                duration_s=duration, seed=seed, noise_factor=factor,
                                sea_direction_deg=float(np.round(rng.uniform(0, 360))),
                                hs_factor=float(np.round(rng.uniform(0.5, 1.5), 2)),
                                current_direction_deg=float(np.round(rng.uniform(0, 360))))
                    run, outcome = run_case(case)
                    start, end = case.start_s, case.start_s + case.fault_duration_s
                    raised = cleared = "-"
                    for event in run.result.alarm_events:
                        if event.code == "position.noisy_reference":
                            if event.raised and raised == "-":
                                raised = f"{event.t_s - start:.1f}"
                            elif not event.raised and event.t_s >= end - 1e-9:
                                cleared = f"{event.t_s - end:.1f}"
                    after = run.t_s >= start - 1e-9
                    position = float(np.max(np.hypot(run.col("north_m"), run.col("east_m"))[after]))
                    heading = float(np.degrees(np.max(np.abs(np.angle(np.exp(1j * run.col("heading_rad")))[after]))))
                    bounds = VESSELS[vessel]
                    within = position <= bounds["position_bound_m"] and heading <= bounds["heading_bound_deg"]
                    rows.setdefault((vessel, factor), []).append((position, heading, within))
                    codes = " ".join(c for c in outcome.alarms if "deviation" not in c)
                    print(f"{vessel:10s} {factor:6g} {case.fault_duration_s:6.1f} {seed:4d} "
                          f"{outcome.max_position_m * scale:7.3g}{unit:2s} {outcome.max_heading_deg:6.2f}° "
                          f"{position * scale:7.3g}{unit:2s} {heading:6.2f}° "
                          f"{'yes' if within else 'NO':3s} {raised:>6s} {cleared:>7s}  {codes}", flush=True)
    print(f"\n{sum(len(v) for v in rows.values())} runs in {time.perf_counter() - wall:.0f} s")
    print(f"{'vessel':10s} {'factor':>6s} {'median pos':>10s} {'max pos':>9s} {'median hdg':>10s} {'max hdg':>8s} "
          "within")
    for (vessel, factor), values in rows.items():
        scale = 1.0 if vessel == "supply" else 1000.0
        unit = "m" if vessel == "supply" else "mm"
        pos = np.array([v[0] for v in values]) * scale
        hdg = np.array([v[1] for v in values])
        print(f"{vessel:10s} {factor:6g} {np.median(pos):8.3g}{unit:2s} {pos.max():7.3g}{unit:2s} "
              f"{np.median(hdg):9.2f}° {hdg.max():7.2f}° {sum(v[2] for v in values)}/{len(values)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
