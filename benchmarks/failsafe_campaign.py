"""Randomized single-reference fault campaign: one GNSS and one gyro, one sensor fault per run.

Each run draws (seeded) a vessel (supply vessel, CyberShip II), a sea (direction, Hs ×0.5–1.5 of the vessel's
moderate sea), a current direction, a sensor fault of every kind the plant injects on a GNSS or a gyro
(``sim_plant.faults.GNSS_FAULTS`` + ``GYRO_FAULTS``; with ``--rate-of-turn`` a rate-of-turn sensor ``rot1`` too,
and its faults ``ROT_FAULTS``), its duration (10–120 s at full scale; Froude-scaled on
CyberShip II, see :mod:`sim_plant.bench.failsafe`) and its start (90–200 s, DP engaged at 20 s), and the plant's
seed. The run is a lockstep simulation through the real codecs, hub, wave filter, PID and allocator; the table
says, per run: the largest true LF position / heading distance from the set-point from 60 s on, whether that is
within 3 m / 3° (43 mm on the model), the time back in ``auto_position`` after the fault (``-``: never left it),
and the alarms raised. Nothing is asserted: this prints what it measured.

Every case is a plain mapping (``--cases-out FILE`` writes them as JSON lines): a campaign engine
(``sim-plant campaign``) can take them as its spec, and ``--cases-in FILE`` runs such a file again.

Usage::

    OPENBLAS_NUM_THREADS=1 nice -n 10 python benchmarks/failsafe_campaign.py --runs 40 --seed 1
    OPENBLAS_NUM_THREADS=1 nice -n 10 python benchmarks/failsafe_campaign.py --runs 20 --seed 1 --rate-of-turn
    OPENBLAS_NUM_THREADS=1 nice -n 10 python benchmarks/failsafe_campaign.py --runs 30 --seed 1 --phases
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

from sim_plant.bench.failsafe import VESSELS, Case, Outcome, run_case, true_distances
from sim_plant.bench.lockstep import ProbedRun
from sim_plant.faults import GNSS_FAULTS, GYRO_FAULTS, ROT_FAULTS

NOTED = ("dead_reckoning", "reference_rejected", "frozen", "stale", "rejected", "noisy", "fallback", "restored",
         "reset", "deviation.alarm", "drift_off", "rate_disagreement",
         "velocity_disagreement")  # the alarm codes listed in the table


def draw_cases(runs: int, seed: int, vessels: list[str], rate_of_turn: bool = False) -> list[Case]:
    """``runs`` cases drawn from ``seed`` (see the module docstring); with ``rate_of_turn`` each case has the
    rate-of-turn sensor ``rot1`` and its faults are drawn too."""
    rng = np.random.default_rng(seed)
    kinds = GNSS_FAULTS + GYRO_FAULTS + (ROT_FAULTS if rate_of_turn else ())
    cases = []
    for _ in range(runs):
        cases.append(Case(vessel=str(rng.choice(vessels)), fault=str(rng.choice(kinds)),
                          start_s=float(np.round(rng.uniform(90.0, 200.0), 1)),
                          duration_s=float(np.round(rng.uniform(10.0, 120.0), 1)),
                          seed=int(rng.integers(1, 2**31 - 1)),
                          sea_direction_deg=float(np.round(rng.uniform(0.0, 360.0))),
                          hs_factor=float(np.round(rng.uniform(0.5, 1.5), 2)),
                          current_direction_deg=float(np.round(rng.uniform(0.0, 360.0))),
                          rate_of_turn=rate_of_turn))
    return cases


def _phases(case: Case, run: ProbedRun) -> str:
    """The largest true LF position / heading distance from the set-point before the fault (from 60 s), in it and
    after it (``--phases``; CyberShip II in mm)."""
    t = run.t_s
    position, heading = true_distances(run)
    position = position * (1.0 if case.vessel == "supply" else 1000.0)
    end = case.start_s + case.fault_duration_s
    parts = []
    for name, mask in (("before", (t >= 60.0) & (t < case.start_s)), ("in", (t >= case.start_s) & (t <= end)),
                       ("after", t > end)):
        parts.append(f"{name} {np.max(position[mask]):.3g}/{np.max(heading[mask]):.2f}" if mask.any() else f"{name} -")
    return "  | " + " ".join(parts)


def _row(case: Case, outcome: Outcome) -> str:
    v = VESSELS[case.vessel]
    within = "yes" if outcome.within(case) else "NO"
    back = "-"
    if outcome.left_dp:
        back = "never" if math.isinf(outcome.back_after_s) else f"{outcome.back_after_s:.0f}"
    noted = [code for code in outcome.alarms if any(key in code for key in NOTED)]
    scale = 1.0 if case.vessel == "supply" else 1000.0  # CyberShip II in mm
    unit = "m" if case.vessel == "supply" else "mm"
    return (f"{case.vessel:10s} {case.fault:13s} {case.start_s:6.1f} {case.fault_duration_s:6.1f} "
            f"{case.hs_factor:4.2f} {outcome.max_position_m * scale:7.3g}{unit:2s}/{v['position_bound_m'] * scale:.3g} "
            f"{outcome.max_heading_deg:6.2f} {within:4s} {outcome.final_mode:13s} {back:>5s}  {' '.join(noted)}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=20)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--vessels", default="supply,cybership2")
    parser.add_argument("--rate-of-turn", action="store_true",
                        help="a rate-of-turn sensor rot1 besides gnss1 and gyro1; its faults drawn too")
    parser.add_argument("--phases", action="store_true",
                        help="also the largest position/heading before the fault (from 60 s), in it and after it")
    parser.add_argument("--cases-out", type=Path)
    parser.add_argument("--cases-in", type=Path)
    args = parser.parse_args(argv)
    if args.cases_in:
        cases = [Case(**json.loads(line)) for line in args.cases_in.read_text().splitlines() if line.strip()]
    else:
        cases = draw_cases(args.runs, args.seed, args.vessels.split(","), args.rate_of_turn)
    if args.cases_out:
        args.cases_out.write_text("".join(json.dumps(dataclasses.asdict(c)) + "\n" for c in cases))
    print(f"{'vessel':10s} {'fault':13s} {'start':>6s} {'dur_s':>6s} {'Hs×':>4s} {'max pos/bound':>14s} "
          f"{'hdg°':>6s} {'ok':4s} {'final mode':13s} {'back':>5s}  alarms")
    within = 0
    left = 0
    wall = time.perf_counter()
    for case in cases:
        run, outcome = run_case(case)
        within += outcome.within(case)
        left += outcome.left_dp
        print(_row(case, outcome) + (_phases(case, run) if args.phases else ""), flush=True)
    print(f"\n{len(cases)} runs in {time.perf_counter() - wall:.0f} s: {within} within the bounds, "
          f"{len(cases) - within} outside; {left} left auto_position (fall-back)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
