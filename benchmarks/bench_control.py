"""Control benchmark: thrust allocation, controller + guidance, QP solvers, seed 003 12 h case, capability.

Measures

* ``allocation``: one :meth:`ThrustAllocator.allocate` (constraints built, daqp solve, commands) for
  6 and 8 azimuths on an ellipse (the daemon benchmark's layout; 8 azimuths = 16 + 6 slack
  variables) and the built-in supply and shuttle-tanker layouts, under a smooth random demand
  (std 10 % of the capability scale Σ|B|·Tmax per DOF, two 20 s lags) with rate limits at 10 Hz;
  ``azimuth8_saturating`` (std 40 %) is saturated most of the time, the solver's hardest case.
  Target (docs/design.md §6): p99 ≤ 300 µs for 8 thrusters.
* ``control``: reference model + MRAC (and + PID) step on the supply vessel. Target: p99 ≤ 100 µs.
* ``--compare-solvers``: the same allocation QPs (captured from the 8-azimuth allocator) solved by
  daqp (the allocator's warm-started model, and cold ``daqp.solve``), quadprog and OSQP (warm
  started, fixed sparsity) — quadprog and OSQP only if importable (they are comparison-only
  dependencies: ``pip install quadprog osqp``).
* ``--offloading``: seed 003's 12 h loading of the shuttle tanker on a single-DOF surge model at
  dt = 0.1 s (:mod:`sim_plant.bench.offloading_case`): MRAC vs the fixed PD tuned at ballast.
* ``--capability``: the largest wind each built-in DP layout holds from every direction
  (:mod:`dpcontrol.allocation.capability`), all thrusters and worst single failure.

Usage::

    .venv/bin/python benchmarks/bench_control.py [--iterations 20000] [--json]
        [--compare-solvers] [--offloading] [--capability]

``run(iterations) -> dict`` returns the allocation and control timings. Timings on a shared,
loaded machine are noisy; run it alone for numbers worth quoting.
"""

from __future__ import annotations

import os

# One BLAS thread: the problems here are tiny, and OpenBLAS worker threads contending for a loaded
# 2-core machine make each LAPACK call (expm, Riccati) ~100× slower (measured: 4 ms vs 37 µs).
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import gc
import json
import math
import time
from collections.abc import Callable
from typing import Any

import daqp
import numpy as np

from dpcontrol.allocation import ThrustAllocator
from dpcontrol.allocation.capability import capability_mps
from dpcontrol.control import MracController, PidController, default_mrac_config, default_pid_config
from dpcontrol.guidance import ReferenceModel, default_reference_config
from dpcontrol.models.thrusters import ThrusterSpec
from dpcontrol.models.vessels import BUILTIN_VESSELS, SHUTTLE_TANKER, SUPPLY
from sim_plant.bench.offloading_case import OffloadingCase, simulate_offloading

DT_S = 0.1


def azimuth_ring(n: int) -> tuple[ThrusterSpec, ...]:
    """n azimuths of 300 kN on an ellipse 60 m × 16 m (12°/s, 60 kN/s)."""
    return tuple(ThrusterSpec(f"az{k}", "azimuth", x_m=30.0 * math.cos(2 * math.pi * k / n),
                              y_m=8.0 * math.sin(2 * math.pi * k / n), max_thrust_n=300e3, min_thrust_n=0.0,
                              thrust_rate_limit_nps=60e3, azimuth_rate_limit_radps=math.radians(12.0))
                 for k in range(n))


def demand_sequence(capability: np.ndarray, steps: int, seed: int = 0, level: float = 0.1) -> np.ndarray:
    """A smooth random demand like a DP controller's output, at DT_S.

    White noise through two first-order lags of 20 s (a controller's force is smooth: a
    first-order Ornstein–Uhlenbeck demand would turn its direction every sample, which no azimuth
    can follow), scaled to a standard deviation of ``level`` × the capability scale per DOF.
    """
    rng = np.random.default_rng(seed)
    a = math.exp(-DT_S / 20.0)
    out = np.zeros((steps, 3))
    x = np.zeros(3)
    y = np.zeros(3)
    for k in range(steps):
        x = a * x + math.sqrt(1.0 - a * a) * rng.standard_normal(3)
        y = a * y + (1.0 - a) * x
        out[k] = y
    return out * (level * capability / np.maximum(out.std(axis=0), 1e-12))


def _time_calls(call: Callable[[int], object], iterations: int, warmup: int = 200) -> dict[str, float]:
    for k in range(warmup):
        call(k)
    samples = np.empty(iterations)
    clock = time.perf_counter_ns
    gc_was_enabled = gc.isenabled()
    gc.disable()
    try:
        for k in range(iterations):
            start = clock()
            call(warmup + k)
            samples[k] = clock() - start
    finally:
        if gc_was_enabled:
            gc.enable()
    us = samples / 1e3
    return {"median_us": float(np.median(us)), "p99_us": float(np.percentile(us, 99)), "mean_us": float(us.mean())}


def bench_allocation(specs: tuple[ThrusterSpec, ...], iterations: int, level: float = 0.1) -> dict[str, float]:
    allocator = ThrustAllocator(specs, DT_S)
    taus = demand_sequence(allocator.capability_scale, iterations + 200, level=level)
    stats = {"iterations": 0, "saturated": 0}

    def call(k: int) -> None:
        result = allocator.allocate(taus[k])
        stats["iterations"] += result.iterations
        stats["saturated"] += result.saturated

    timing = _time_calls(call, iterations)
    calls = iterations + 200
    return {**timing, "thrusters": len(specs), "variables": allocator.geometry.n_variables + 6,
            "mean_solver_iterations": stats["iterations"] / calls, "saturated_fraction": stats["saturated"] / calls}


def bench_control(kind: str, iterations: int) -> dict[str, float]:
    vessel = SUPPLY
    model = ReferenceModel(default_reference_config(vessel))
    model.reset(np.zeros(3))
    controller = MracController(default_mrac_config(vessel)) if kind == "mrac" else PidController(
        default_pid_config(vessel))
    rng = np.random.default_rng(1)
    n = iterations + 200
    eta = np.cumsum(0.01 * rng.standard_normal((n, 3)), axis=0)
    nu = 0.05 * rng.standard_normal((n, 3))
    bias = np.array([2e4, -1e4, 3e5])
    setpoints = np.where((np.arange(n) // 3000 % 2)[:, None] == 1, [20.0, 10.0, 0.2], [0.0, 0.0, 0.0])

    def call(k: int) -> None:
        reference = model.step(DT_S, setpoints[k])
        out = controller.step(DT_S, eta[k], nu[k], bias, reference)
        controller.notify_achieved(out.tau_b)

    return _time_calls(call, iterations)


def run(iterations: int = 20000) -> dict[str, Any]:
    """Allocation and controller + guidance timings (µs per call: median, p99, mean).

    Returns ``{"allocation": {layout: {...}}, "control": {kind: {...}}, "allocation_p99_us_8_thrusters",
    "control_p99_us", "targets": {...}}``.
    """
    allocation = {
        "azimuth6": bench_allocation(azimuth_ring(6), iterations),
        "azimuth8": bench_allocation(azimuth_ring(8), iterations),
        "azimuth8_saturating": bench_allocation(azimuth_ring(8), iterations, level=0.4),
        "supply": bench_allocation(SUPPLY.thrusters, iterations),
        "shuttle_tanker": bench_allocation(SHUTTLE_TANKER.thrusters, iterations),
    }
    control = {"mrac+guidance": bench_control("mrac", iterations), "pid+guidance": bench_control("pid", iterations)}
    return {
        "allocation": allocation,
        "control": control,
        "allocation_p99_us_8_thrusters": allocation["azimuth8"]["p99_us"],
        "control_p99_us": control["mrac+guidance"]["p99_us"],
        "targets": {"allocation_p99_us_8_thrusters": 300.0, "control_p99_us": 100.0},
        "iterations": iterations,
    }


# ---------------------------------------------------------------------------------------------- solvers
def _capture_qps(count: int) -> list[dict[str, np.ndarray]]:
    allocator = ThrustAllocator(azimuth_ring(8), DT_S)
    taus = demand_sequence(allocator.capability_scale, count, seed=5, level=0.2)
    problems = []
    for tau in taus:
        allocator.allocate(tau)
        problems.append(allocator.qp_snapshot())
    return problems


def _general_rows(p: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Drop the all-zero (unused) rows: ``A, lower, upper, is_equality``."""
    n = p["H"].shape[0]
    rows = np.flatnonzero(np.any(p["A"] != 0.0, axis=1))
    return p["A"][rows], p["blower"][n:][rows], p["bupper"][n:][rows], p["sense"][n:][rows] == 5


def compare_solvers(count: int = 2000) -> dict[str, Any]:
    """Solve the same captured allocation QPs with daqp, quadprog and OSQP; time and accuracy."""
    problems = _capture_qps(count)
    n = problems[0]["H"].shape[0]
    out: dict[str, Any] = {"problems": count, "variables": n}

    # daqp, cold (a fresh solve of each problem)
    reference = []

    def daqp_cold(k: int) -> None:
        p = problems[k % count]
        x, _, flag, _ = daqp.solve(p["H"], p["f"], p["A"], p["bupper"], p["blower"], p["sense"], primal_tol=1e-9)
        if k < count:
            reference.append(np.array(x) if flag >= 1 else None)

    out["daqp_cold"] = _time_calls(daqp_cold, count, warmup=0)
    # daqp, warm (the allocator's way: one model, updated in place)
    model = daqp.Model()
    model.settings = {"primal_tol": 1e-9}
    first = problems[0]
    model.setup(first["H"], first["f"], first["A"], first["bupper"], first["blower"], first["sense"])

    def daqp_warm(k: int) -> None:
        p = problems[k % count]
        model.update(A=p["A"], bupper=p["bupper"], blower=p["blower"])
        model.solve()

    out["daqp_warm"] = _time_calls(daqp_warm, count, warmup=0)

    try:
        import quadprog  # comparison only  # noqa: PLC0415
    except ImportError:
        out["quadprog"] = "not installed"
    else:
        prepared = []
        for p in problems:
            A, lo, hi, eq = _general_rows(p)
            bounds = np.eye(n)
            blo, bhi = p["blower"][:n], p["bupper"][:n]
            C = [A[eq]]
            b = [hi[eq]]
            for M, low, high in ((A[~eq], lo[~eq], hi[~eq]), (bounds, blo, bhi)):
                keep = np.isfinite(high)
                C.append(-M[keep])
                b.append(-high[keep])
                keep = np.isfinite(low)
                C.append(M[keep])
                b.append(low[keep])
            prepared.append((np.vstack(C).T.copy(), np.concatenate(b), int(eq.sum())))
        errors = []

        def quadprog_solve(k: int) -> None:
            p = problems[k % count]
            C, b, meq = prepared[k % count]
            x = quadprog.solve_qp(p["H"], -p["f"], C, b, meq)[0]
            if k < count and reference[k] is not None:
                errors.append(float(np.max(np.abs(x - reference[k]))))

        out["quadprog"] = {**_time_calls(quadprog_solve, count, warmup=0),
                           "max_difference_to_daqp": max(errors) if errors else None}

    try:
        import osqp  # comparison only  # noqa: PLC0415
        from scipy import sparse  # noqa: PLC0415
    except ImportError:
        out["osqp"] = "not installed"
    else:
        stacked = [np.vstack([np.eye(n), p["A"]]) for p in problems]
        pattern = np.zeros_like(stacked[0], dtype=bool)
        for m in stacked:
            pattern |= m != 0.0
        rows, cols = np.nonzero(pattern.T)  # column-major order = CSC data order
        csc = sparse.csc_matrix((np.ones(rows.size), (cols, rows)), shape=pattern.shape)
        solver = osqp.OSQP()
        low0 = np.maximum(problems[0]["blower"], -1e20)
        high0 = np.minimum(problems[0]["bupper"], 1e20)
        solver.setup(sparse.csc_matrix(np.triu(problems[0]["H"])), problems[0]["f"], csc, low0, high0,
                     verbose=False, eps_abs=1e-7, eps_rel=1e-7, polish=True, warm_starting=True, max_iter=20000)
        errors = []

        def osqp_solve(k: int) -> None:
            i = k % count
            m = stacked[i]
            solver.update(Ax=m[cols, rows], l=np.maximum(problems[i]["blower"], -1e20),
                          u=np.minimum(problems[i]["bupper"], 1e20))
            result = solver.solve()
            if k < count and reference[k] is not None and result.x is not None:
                errors.append(float(np.max(np.abs(result.x - reference[k]))))

        out["osqp"] = {**_time_calls(osqp_solve, count, warmup=0),
                       "max_difference_to_daqp": max(errors) if errors else None}
    return out


# ---------------------------------------------------------------------------------------------- seed 003, capability
def offloading_12h(dt_s: float = 0.1) -> dict[str, Any]:
    """Seed 003's 12 h loading (single-DOF surge) for the MRAC and the fixed PD at ballast."""
    case = OffloadingCase(dt_s=dt_s)
    out: dict[str, Any] = {"dt_s": dt_s, "duration_s": case.duration_s,
                           "setpoint": "square wave 0 ↔ +20 m, switching every 30 min"}
    for name, adaptive in (("mrac", True), ("fixed_pd_ballast", False)):
        start = time.perf_counter()
        result = simulate_offloading(case, adaptive)
        overshoots = result.overshoots_m()
        out[name] = {
            "wall_s": time.perf_counter() - start,
            "max_tracking_error_after_1h_m": result.tracking_error_after(3600.0),
            "overshoot_first_hour_m": float(overshoots[1]),
            "overshoot_last_hour_m": float(overshoots[-2:].mean()),
            "max_overshoot_m": float(overshoots.max()),
            "final_mass_true_kg": float(result.mass_true_kg[-1]),
            "final_mass_hat_kg": float(result.mass_hat_kg[-1]),
            "final_mass_error": result.final_mass_error(),
            "max_force_n": float(np.max(np.abs(result.force_n))),
        }
    return out


def capability_table() -> dict[str, Any]:
    """Largest wind held (full-scale m/s) per built-in DP layout: all thrusters and worst single failure."""
    directions = np.radians(np.arange(0.0, 360.0, 15.0))
    out: dict[str, Any] = {}
    for name, vessel in BUILTIN_VESSELS.items():
        if name == "mariner":
            continue
        wind = capability_mps(vessel, directions)
        worst = (math.inf, "")
        for lost, spec in enumerate(vessel.thrusters):
            available = np.ones(len(vessel.thrusters), dtype=bool)
            available[lost] = False
            w = capability_mps(vessel, directions, available=available, iterations=12)
            worst = min(worst, (float(w.min()), spec.name))
        out[name] = {"min_mps": float(wind.min()), "min_at_deg": float(np.degrees(directions[int(wind.argmin())])),
                     "head_on_mps": float(wind[0]), "beam_mps": float(wind[6]),
                     "worst_single_failure": {"thruster": worst[1], "min_mps": worst[0]}}
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--iterations", type=int, default=20000)
    parser.add_argument("--json", action="store_true", help="print the results as JSON")
    parser.add_argument("--compare-solvers", action="store_true", help="daqp vs quadprog vs OSQP")
    parser.add_argument("--offloading", action="store_true", help="seed 003 12 h case at dt = 0.1 s (slow)")
    parser.add_argument("--capability", action="store_true", help="capability of the built-in layouts")
    args = parser.parse_args()
    results: dict[str, Any] = run(args.iterations)
    if args.compare_solvers:
        results["solvers"] = compare_solvers(min(args.iterations, 5000))
    if args.offloading:
        results["offloading"] = offloading_12h()
    if args.capability:
        results["capability"] = capability_table()
    if args.json:
        print(json.dumps(results, indent=2))
        return
    print(f"{'allocation':<24}{'median µs':>12}{'p99 µs':>12}{'mean µs':>12}{'iters':>8}{'sat %':>8}")
    for name, r in results["allocation"].items():
        print(f"{name:<24}{r['median_us']:>12.1f}{r['p99_us']:>12.1f}{r['mean_us']:>12.1f}"
              f"{r['mean_solver_iterations']:>8.1f}{100 * r['saturated_fraction']:>8.1f}")
    print(f"{'controller + guidance':<24}{'median µs':>12}{'p99 µs':>12}{'mean µs':>12}")
    for name, r in results["control"].items():
        print(f"{name:<24}{r['median_us']:>12.1f}{r['p99_us']:>12.1f}{r['mean_us']:>12.1f}")
    for section in ("solvers", "offloading", "capability"):
        if section in results:
            print(f"{section}: {json.dumps(results[section], indent=2)}")


if __name__ == "__main__":
    main()
