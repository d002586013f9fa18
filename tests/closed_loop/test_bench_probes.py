"""The two timing probes of ``benchmarks/`` in miniature: the lockstep stage breakdown accounts for the step
it splits, and the cold-cache probe times the steps and the kernel calls it says it times. (The numbers are
the benchmarks' business; these keep their machinery honest on every commit.)"""

from __future__ import annotations

from benchmark_module import load_benchmark


def test_stage_breakdown_accounts_for_the_step() -> None:
    stages_benchmark = load_benchmark("bench_lockstep_stages")
    result = stages_benchmark.run("tanker-seed003", duration_s=30.0)
    steps = result["steps"]
    assert steps == 301
    stages = result["stages"]
    for label in ("plant.advance", "controller.step", "hub.update", "estimator.step", "allocation",
                  "record (time-series row)"):
        assert stages[label]["calls"] >= steps - 1, label
        assert stages[label]["us_per_step"] > 0.0, label
    inner = ("hub.update", "estimator.step", "estimator.predicted_measurement", "force input", "control law",
             "monitor.update", "allocation")
    # the stages inside the step take less than the step; the loop's parts less than the loop
    inside = sum(stages[label]["us_per_step"] for label in inner if label in stages)
    assert inside < stages["controller.step"]["us_per_step"]
    outer = ("plant.advance", "inputs.measurements (encode → decode → route)", "controller.step",
             "record (time-series row)")
    assert sum(stages[label]["us_per_step"] for label in outer) < result["us_per_step"]
    table = stages_benchmark.format_table(result)
    assert "controller.step" in table and "allocation" in table


def test_cold_cache_probe_times_each_step_after_the_wait() -> None:
    probe = load_benchmark("bench_cold_cache")
    durations = probe._run("back-to-back", 12)
    assert durations.shape == (12,)
    assert (durations > 0.0).all() and (durations < 1e6).all()  # µs: a step, not a whole run


def test_cold_cache_probe_times_the_kernel_per_gap() -> None:
    probe = load_benchmark("bench_cold_cache")
    kernel = probe._kernel(3)
    assert list(kernel) == ["0 ms", "2 ms", "10 ms", "100 ms"]
    for row in kernel.values():
        # CPU time of one call [µs]: not nothing, and far less than the 100 ms waited before it
        assert 0.0 < row["syscall_us"] < 50_000.0
        assert 0.0 < row["udp_send_us"] < 50_000.0
