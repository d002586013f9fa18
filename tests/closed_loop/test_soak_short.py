"""The soak benchmark (``benchmarks/soak.py``, docs/fault-handling.md) in miniature: 40 simulated minutes with a random
fault every few minutes, in lockstep. The 24 h run is the benchmark; this keeps its machinery honest on
every commit: no exception, no NaN in any output, every detectable fault detected within its bound."""

from __future__ import annotations

from benchmark_module import load_benchmark


def test_forty_minutes_of_random_faults() -> None:
    soak = load_benchmark("soak")
    report = soak.run(hours=40.0 / 60.0, seed=7)
    assert report["exception"] is None, report["exception"]
    assert report["nonfinite_steps"] == 0, report["first_nonfinite"]
    faults = report["faults"]
    assert faults["injected"] >= 5
    assert faults["missed"] == 0 and faults["late"] == 0, report["fault_log"]
    assert faults["detected"] >= faults["injected"] - faults["not_detectable"]
    assert report["station_keeping_m"]["max"] < 10.0
