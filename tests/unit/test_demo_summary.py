"""What ``sim-plant demo`` says at the end: the outcome a test engineer checks first, from ``summary.json``."""

from __future__ import annotations

import copy

from sim_plant.bench.demo import JITTER_P99_TARGET_US, PUBLISHED_P99_TARGET_US, describe_summary

# the shape write_report gives (values of a real 120 s run, 2026-12-02)
SUMMARY = {
    "dpcontrol_exit": 0, "sim_plant_exit": 0,
    "host_steal": {"steal_s": 2.73, "steal_percent": 1.16},
    "dpcontrol_loop": {"cycles": 1164, "missed_deadlines": 0, "step_errors": 0, "scheduling": "SCHED_FIFO 50",
                       "start_to_command_published_us": {"median": 1081.4, "p99": 2261.4, "max": 5412.5},
                       "period_jitter_us": {"median": 12.6, "p99": 690.0, "max": 5394.1}},
    "sim_plant": {"engage": {"requested": True, "engaged": True, "t_s": 3.716}},
    "mode_changes": [{"t_s": 73154.0, "from": "standby", "to": "auto_position", "reason": "operator"}],
    "dp_engaged": True,
    "position_error_last_half_max_m": 0.0433, "position_error_last_half_rms_m": 0.0092,
    "position_error_window_s": [60.29, 120.6],
    "final_position_m": [1.9996, -0.0021], "final_setpoint_m": [2, 0], "final_setpoint_t_s": 20.0,
    "last_command": {"mode": "standby", "thrust_n": [0.0, 0.0, 0.0]}, "zero_thrust_commanded_last": True,
    "alarms_raised": [],
}


def test_a_good_run_reads_as_one() -> None:
    text = "\n".join(describe_summary(SUMMARY))
    assert "DP engaged 3.7 s after the emulator started" in text
    assert "station keeping, true position against the set-point over the second half of the run: " \
           "0.043 m at most, 0.009 m rms" in text and "set-point 2 m N, 0 m E" in text
    assert "1164 cycles, 0 missed deadlines, 0 step errors" in text
    assert "command published 2.26 ms (OVER 2 ms)" in text  # the target is the HIL budget's, the value this run's
    assert "period jitter 0.69 ms (within 2 ms)" in text
    assert "loop thread: SCHED_FIFO 50" in text
    assert "host steal 1.16 %" in text
    assert "last command: zero thrust, mode standby" in text
    assert "alarms raised during the run: none" in text  # (the deviation alarms would be among them)
    assert "NOT" not in text
    strayed = describe_summary({**SUMMARY, "alarms_raised": ["position.deviation.alarm", "position.deviation.warning"]})
    assert "alarms raised during the run: position.deviation.alarm, position.deviation.warning (the daemon's " \
           "record: dpcontrol log export)" in strayed


def test_a_short_run_says_its_error_includes_the_move() -> None:
    # sim-plant demo --duration 25: the 2 m set-point of t = 20 s comes in its second half
    summary = copy.deepcopy(SUMMARY)
    summary.update(position_error_window_s=[12.85, 25.7], position_error_last_half_max_m=1.974,
                   position_error_last_half_rms_m=1.303)
    line = describe_summary(summary)[1]
    assert "includes the move to the set-point of t = 20 s: 1.974 m at most" in line
    assert "station keeping" not in line


def test_the_targets_are_inclusive() -> None:
    summary = copy.deepcopy(SUMMARY)
    loop = summary["dpcontrol_loop"]
    loop["start_to_command_published_us"]["p99"] = PUBLISHED_P99_TARGET_US
    loop["period_jitter_us"]["p99"] = JITTER_P99_TARGET_US + 1.0
    text = "\n".join(describe_summary(summary))
    assert "command published 2.00 ms (within 2 ms)" in text
    assert "period jitter 2.00 ms (OVER 2 ms)" in text  # 2001 µs: over, although it rounds to 2.00


def test_a_failed_run_says_what_is_missing() -> None:
    summary = copy.deepcopy(SUMMARY)
    summary.update(dp_engaged=False, mode_changes=[], zero_thrust_commanded_last=False,
                   last_command={"mode": "auto_position", "thrust_n": [1.0, 0.0, 0.0]})
    lines = describe_summary(summary)
    assert lines[0].startswith("DP did NOT engage")
    assert lines[-1].startswith("last command: NOT zero thrust") and "auto_position" in lines[-1]


def test_an_empty_summary_guesses_nothing() -> None:
    lines = describe_summary({})
    assert lines == [
        "DP did NOT engage (mode changes: []; see the logs in the run directory)",
        "station keeping: no plant truth to measure it from",
        "control loop: no timing (the daemon wrote no stats)",
        "host steal n/a during the run: the hypervisor's share of the CPUs, 0 on dedicated hardware; "
        "on a virtual machine the timing tails grow with it",
        "last command: NOT zero thrust (none received)",
    ]


def test_the_worst_case_failure_checks_are_summed_up() -> None:
    summary = copy.deepcopy(SUMMARY)
    summary["consequence"] = {"bow_tunnel": {"checks": 87, "held": 87, "utilisation_max": 0.893},
                              "port_shaft": {"checks": 87, "held": 80, "utilisation_max": 0.41}}
    lines = describe_summary(summary)
    assert "worst-case failure check: losing bow_tunnel: 87 checks, held in every check, the busiest thruster " \
           "left at 89 % of its rating at most" in lines
    assert any(line.startswith("worst-case failure check: losing port_shaft: 87 checks, NOT held in 7 of the checks")
               for line in lines)
    assert lines[-1].startswith("last command")
