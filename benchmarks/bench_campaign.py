"""Campaign throughput: simulated hours per wall hour of a 20-run campaign, with 1 and with 2 local workers.

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_campaign.py [--runs 20] [--duration 600] [--workers 1 2]

The campaign is 20 random seas, winds and currents on the supply vessel (``supply-seed001``, PID, ``--duration``
simulated seconds each). Each worker count gets its own ``LocalCluster`` (the ``sim-plant campaign`` engine);
one short warm-up run per worker first (module imports, the compiled kernels' cache), then the clock runs from
the submission of the 20 runs to the last result. Printed: the wall time, simulated hours per wall hour, the speed-up
over one worker, how busy the workers were (Σ of the runs' wall times / the campaign's wall time: the speed-up the
engine would give if each run had a CPU to itself), the share of a CPU the runs got (their process time / wall
time), and the host's load and CPU steal while it ran — the machine is shared, so a number measured under load says
what the load left, not what the engine can do; rerun on a quiet machine.
"""

from __future__ import annotations

import argparse
import copy
import os
import time

from dpcontrol.platform_info import cpu_times, describe, describe_steal, host_steal, machine_info
from sim_plant.campaign.engine import Engine
from sim_plant.campaign.spec import expand, parse_campaign

SPEC = {
    "name": "bench", "base": "supply-seed001", "seed": 11,
    "set": {"sea_states": [{"t_s": 0, "spectrum": "jonswap", "hs_m": 2.0, "omega_peak_rad_s": 0.7,
                            "direction_deg": 0}]},
    "vary": {"sea_states[0].hs_m": {"uniform": [0.5, 3.5]}, "sea_states[0].direction_deg": {"uniform": [-60, 60]},
             "wind.speed_mps": {"uniform": [0, 12]}, "current.speed_mps": {"uniform": [0, 0.6]}},
}


def measure(workers: int, runs: int, duration_s: float) -> dict[str, float]:
    """Wall time and simulated time of the campaign on ``workers`` local processes."""
    spec = parse_campaign({**copy.deepcopy(SPEC), "runs": runs, "duration_s": duration_s}, file="<bench>")
    todo = expand(spec)
    warm = expand(parse_campaign({**copy.deepcopy(SPEC), "runs": workers, "duration_s": 5.0, "seed": 99},
                                 file="<warm-up>"))
    simulated = run_wall = run_cpu = 0.0
    failed = 0

    def count(_run: object, result: dict[str, object]) -> None:
        nonlocal simulated, failed, run_wall, run_cpu
        simulated += float(result.get("simulated_s", 0.0))  # type: ignore[arg-type]
        run_wall += float(result.get("wall_s", 0.0))  # type: ignore[arg-type]
        run_cpu += float(result.get("cpu_s", 0.0))  # type: ignore[arg-type]
        failed += result.get("status") != "ok"

    with Engine(workers=workers) as engine:
        engine.run(warm, lambda run, result: None)
        load0 = os.getloadavg()[0]
        times0 = cpu_times()
        t0 = time.perf_counter()
        engine.run(todo, count)
        wall = time.perf_counter() - t0
        steal = host_steal(times0, cpu_times())
        load1 = os.getloadavg()[0]
    return {"workers": workers, "wall_s": wall, "simulated_s": simulated, "failed": failed,
            "busy": run_wall / wall, "cpu_share": run_cpu / run_wall if run_wall else float("nan"),
            "sim_h_per_wall_h": simulated / wall, "load_before": load0, "load_after": load1,
            "steal": steal}  # type: ignore[dict-item]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=20)
    parser.add_argument("--duration", type=float, default=600.0, help="simulated seconds per run")
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    args = parser.parse_args()
    print(describe(machine_info()))
    results = [measure(n, args.runs, args.duration) for n in args.workers]
    base = results[0]["sim_h_per_wall_h"]
    for r in results:
        print(f"{r['workers']} worker(s): {args.runs} runs × {args.duration:g} s in {r['wall_s']:.1f} s wall: "
              f"{r['sim_h_per_wall_h']:.0f} simulated h per wall h ({r['sim_h_per_wall_h'] / base:.2f}× one worker); "
              f"{r['failed']} failed; workers busy {r['busy']:.2f} (Σ run wall / wall), runs got "
              f"{100 * r['cpu_share']:.0f} % of a CPU; load average {r['load_before']:.2f} → {r['load_after']:.2f}; "
              f"{describe_steal(r['steal'])}")  # type: ignore[arg-type]


if __name__ == "__main__":
    main()
