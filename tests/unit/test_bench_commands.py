"""``dpcontrol bench`` and ``sim-plant bench`` as a user runs them (the real command lines, short runs): the
reports hold what they claim to have measured, and the machine it was measured on."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time

from dpcontrol.bench import format_bench
from dpcontrol.platform_info import (
    HostStealWindow,
    available_memory_bytes,
    cpu_times,
    describe,
    describe_steal,
    host_steal,
    machine_info,
)

ENV = {**os.environ, "OPENBLAS_NUM_THREADS": "1"}


def _run(module: str, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", module, *args], capture_output=True, text=True, timeout=300,
                          env=ENV, check=False)


def _check_machine(machine: dict[str, object]) -> None:
    assert machine["cpu"] and isinstance(machine["cpu"], str)
    assert isinstance(machine["usable_cpus"], int) and machine["usable_cpus"] >= 1
    assert machine["usable_cpus"] <= machine["logical_cpus"]  # type: ignore[operator]
    assert machine["python"] == ".".join(map(str, sys.version_info[:3]))
    assert machine["libraries"]["numba"]  # type: ignore[index]


def test_machine_info_describes_this_machine() -> None:
    info = machine_info()
    _check_machine(info)
    assert info["usable_cpus"] == len(os.sched_getaffinity(0))
    line = describe(info)
    assert line.startswith("machine: ") and info["cpu"] in line and info["python"] in line


def _check_steal(steal: dict[str, float] | None) -> None:
    # this suite runs on Linux: /proc/stat is there, and the run took some of the CPUs' time
    assert steal is not None
    assert steal["steal_s"] >= 0.0 and 0.0 <= steal["steal_percent"] <= 100.0


def test_cpu_times_reads_the_eight_counters_and_they_advance() -> None:
    before = cpu_times()
    assert before is not None and len(before) == 8 and all(v >= 0 for v in before)
    end = time.monotonic() + 0.05
    while time.monotonic() < end:  # 50 ms of CPU time: at least a few clock ticks
        pass
    after = cpu_times()
    assert after is not None and sum(after) > sum(before)
    _check_steal(host_steal(before, after))


def test_host_steal_is_the_steal_share_of_all_the_cpu_time_in_between() -> None:
    ticks = os.sysconf("SC_CLK_TCK")
    before = (1000, 0, 500, 8000, 10, 0, 5, 40)
    # 150 ticks user, 100 idle, 50 system, 50 steal: 50 of 350
    after = (1150, 0, 550, 8100, 10, 0, 5, 90)
    steal = host_steal(before, after)
    assert steal == {"steal_s": round(50 / ticks, 2), "steal_percent": round(100 * 50 / 350, 2)}
    assert "host steal 14.29 %" in describe_steal(steal)
    assert host_steal(before, before) is None  # no time passed: no share
    assert host_steal(None, after) is None and host_steal(before, None) is None
    assert describe_steal(None) == "host steal n/a"


def test_host_steal_window_reports_the_share_over_the_last_window() -> None:
    # one tick of steal and nine of user time per second, on synthetic counters
    counters = [(0, 0, 0, 0, 0, 0, 0, 0)]

    def read() -> tuple[int, ...] | None:
        return counters[-1]

    window = HostStealWindow(3.0, read=read)
    assert window.update(0.0) is None  # one reading: no interval yet
    for second in range(1, 6):
        user, steal = 9 * second, second
        if second >= 4:
            steal += 9 * (second - 3)  # from 3 s on, the host takes 9 ticks a second more
        counters.append((user, 0, 0, 0, 0, 0, 0, steal))
        share = window.update(float(second))
        if second <= 3:
            assert share == 10.0  # 1 of 10 ticks since t = 0
        else:  # over the last 3 s only (t = second - 3 .. second)
            old_user, old_steal = 9 * (second - 3), (second - 3) + 9 * max(second - 6, 0)
            assert share == round(100 * (steal - old_steal) / ((user - old_user) + (steal - old_steal)), 2)
    assert len(window._readings) <= 4  # bounded by the window, not by the run
    counters.append(None)  # type: ignore[arg-type]
    assert window.update(6.0) is None  # unreadable: unknown, not an error
    try:
        HostStealWindow(0.0)
    except ValueError as error:
        assert "window_s" in str(error)
    else:
        raise AssertionError("a zero window was accepted")


def test_dpcontrol_bench_json_reports_stages_cycle_and_machine() -> None:
    done = _run("dpcontrol.cli", "bench", "--iterations", "60", "--json")
    assert done.returncode == 0, done.stderr
    result = json.loads(done.stdout)
    assert result["iterations"] == 60
    _check_machine(result["machine"])
    _check_steal(result["host_steal"])
    assert "during the run: host steal " in format_bench(result)
    assert set(result["stages"]) == {"decode", "hub", "estimator", "control", "allocation", "encode_publish"}
    for stats in [*result["stages"].values(), result["cycle"]]:
        assert 0.0 < stats["median_us"] <= stats["p99_us"] <= stats["max_us"]
    # the whole cycle holds every stage: its median is at least the largest stage median
    assert result["cycle"]["median_us"] >= max(s["median_us"] for s in result["stages"].values())


def test_dpcontrol_bench_rejects_a_count_below_one() -> None:
    done = _run("dpcontrol.cli", "bench", "--iterations", "0")
    assert done.returncode == 2
    assert "expected a whole number >= 1" in done.stderr and "Traceback" not in done.stderr


def test_sim_plant_bench_json_and_text_report_both_runs() -> None:
    done = _run("sim_plant.cli", "bench", "--tanker-duration", "30", "--cs2-duration", "10", "--json")
    assert done.returncode == 0, done.stderr
    result = json.loads(done.stdout)
    _check_machine(result["machine"])
    runs = {run["scenario"]: run for run in result["runs"]}
    assert set(runs) == {"tanker-seed003", "cs2-seed000"}
    tanker = runs["tanker-seed003"]
    assert tanker["steps"] == 301 and tanker["control"] == "mrac" and tanker["estimator"] == "mmae"
    for run in runs.values():
        assert run["wall_s"] > 0.0
        # the speed is the simulated time over the wall time (both as reported: wall_s to 1 ms, speed to 0.1)
        rounding = run["speed_x_realtime"] * 0.0005 / run["wall_s"] + 0.05
        assert abs(run["speed_x_realtime"] - run["simulated_s"] / run["wall_s"]) <= rounding * 1.01
        assert len(run["ms_per_simulated_s_by_tenth"]) == 10
        _check_steal(run["host_steal"])
    text = _run("sim_plant.cli", "bench", "--tanker-duration", "10", "--cs2-duration", "5")
    assert text.returncode == 0, text.stderr
    assert "tanker-seed003" in text.stdout and "cs2-seed000" in text.stdout and "machine: " in text.stdout
    assert text.stdout.count("host steal ") == 2  # one per run


def test_available_memory_is_read_from_meminfo() -> None:
    available = available_memory_bytes()
    assert available is not None and available > 2**26  # Linux: more than 64 MiB on any machine that runs this
    with open("/proc/meminfo", encoding="ascii") as handle:
        total_kib = int(next(line for line in handle if line.startswith("MemTotal:")).split()[1])
    assert available <= total_kib * 1024
