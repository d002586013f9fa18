"""Estimation benchmark: the cost of one wave-filter update.

Measures, per call of ``step()`` (correct + weights + blend + predict), on CyberShip II data:

* ``mmae``: the batched bank, N = 8 models × 15 states (target: p99 ≤ 150 µs; docs/design.md §6
  budget for a well-written batched bank: about 12 µs);
* ``mmae_loop``: the same bank written as a Python loop over 8 single filters (the docs/design.md §6
  comparison, about 130 µs), to show what batching buys;
* ``kf`` (steady state), ``kf_tv`` (time-varying Joseph form), ``raw``, ``rpem``;
* ``predicted_measurement``: the sensor hub's per-step query.

Usage::

    .venv/bin/python benchmarks/bench_estimation.py [--iterations 20000] [--json]

``run(iterations) -> dict`` returns median/p99/mean µs per kind. Timings on a shared, loaded
machine are noisy; run it alone for numbers worth quoting.
"""

from __future__ import annotations

import argparse
import gc
import json
import math
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from dpcontrol.estimation.factory import make_wave_filter
from dpcontrol.estimation.filter_config import WaveFilterConfig
from dpcontrol.models.vessels import CYBERSHIP2

DT_S = 0.1
OMEGAS = (0.3, 0.45, 0.6, 0.75, 0.9, 1.05, 1.2, 1.35)


def _inputs(iterations: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(0)
    t = np.arange(iterations) * DT_S
    y = np.stack([0.3 * np.sin(0.9 * t) + 0.01 * rng.standard_normal(iterations),
                  0.2 * np.cos(0.8 * t) + 0.01 * rng.standard_normal(iterations),
                  0.05 * np.sin(0.7 * t) + 0.001 * rng.standard_normal(iterations)], axis=1)
    tau = 0.1 * rng.standard_normal((iterations, 3))
    return y, tau


def _config(**kwargs: Any) -> WaveFilterConfig:
    return WaveFilterConfig(mass_matrix=CYBERSHIP2.mass_matrix, damping_matrix=CYBERSHIP2.damping_matrix,
                            sample_time_s=DT_S, length_m=CYBERSHIP2.length_m, **kwargs)


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
            call(k)
            samples[k] = clock() - start
    finally:
        if gc_was_enabled:
            gc.enable()
    us = samples / 1e3
    return {"median_us": float(np.median(us)), "p99_us": float(np.percentile(us, 99)), "mean_us": float(us.mean())}


class _LoopBank:
    """The MMAE bank as N separate steady-state filters stepped in a Python loop (for comparison)."""

    def __init__(self, config: WaveFilterConfig) -> None:
        self.bank = make_wave_filter(config)
        b = self.bank
        self.Phi = [b.Phi[i] for i in range(b.Phi.shape[0])]
        self.K = [b.K[0, i] for i in range(b.Phi.shape[0])]
        self.x = [b.x[i].copy() for i in range(b.Phi.shape[0])]
        self.w = 1.0 / b.common_scale
        self.p = b.p.copy()
        self.H = b.H
        self.Gamma = b.Gamma

    def step(self, y: np.ndarray, tau: np.ndarray) -> np.ndarray:
        log_l = np.empty(len(self.x))
        for i in range(len(self.x)):
            eps = y - self.H @ self.x[i]
            eps[2] = math.remainder(eps[2], 2.0 * math.pi)
            self.x[i] = self.x[i] + self.K[i] @ eps
            log_l[i] = -0.5 * float(eps @ (self.w * eps))
        log_p = 0.9995 * np.log(self.p) + log_l
        self.p = np.exp(log_p - log_p.max())
        self.p = np.maximum(self.p / self.p.sum(), 1e-6)
        self.p /= self.p.sum()
        x_hat = sum(p * x for p, x in zip(self.p, self.x, strict=True))
        for i in range(len(self.x)):
            self.x[i] = self.Phi[i] @ self.x[i] + self.Gamma @ tau
        return x_hat


def run(iterations: int = 20000) -> dict[str, Any]:
    """Time one MMAE update (N = 8 models × 15 states) and, for comparison, every other kind.

    Returns ``{"median_us", "p99_us", "mean_us"}`` of the MMAE update at the top level, plus
    ``"n_models"``, ``"n_states"``, ``"iterations"`` and ``"kinds": {kind: {median_us, p99_us, mean_us}}``.
    """
    y, tau = _inputs(iterations + 200)
    results: dict[str, dict[str, float]] = {}
    kinds = {
        "mmae": _config(kind="mmae", omegas_rad_s=OMEGAS),
        "kf": _config(kind="kf", omegas_rad_s=(0.9,)),
        "raw": _config(kind="raw", omegas_rad_s=()),
        "kf_tv": _config(kind="kf", omegas_rad_s=(0.9,), time_varying=True),
        "rpem": _config(kind="rpem", omegas_rad_s=(0.6,)),
    }
    for name, config in kinds.items():
        wave_filter = make_wave_filter(config)
        wave_filter.reset(y[0])
        results[name] = _time_calls(lambda k, f=wave_filter: f.step(y[k], tau[k]), iterations)
        if name == "mmae":
            results["predicted_measurement"] = _time_calls(lambda _k, f=wave_filter: f.predicted_measurement(),
                                                           iterations)
    loop = _LoopBank(kinds["mmae"])
    results["mmae_loop"] = _time_calls(lambda k: loop.step(y[k], tau[k]), iterations)
    return {**results["mmae"], "n_models": len(OMEGAS), "n_states": 15, "iterations": iterations,
            "kinds": results}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--iterations", type=int, default=20000)
    parser.add_argument("--json", action="store_true", help="print the results as JSON")
    args = parser.parse_args()
    results = run(args.iterations)
    if args.json:
        print(json.dumps(results, indent=2))
        return
    print(f"{'estimator update':<24}{'median µs':>12}{'p99 µs':>12}{'mean µs':>12}")
    for name, r in results["kinds"].items():
        print(f"{name:<24}{r['median_us']:>12.1f}{r['p99_us']:>12.1f}{r['mean_us']:>12.1f}")


if __name__ == "__main__":
    main()
