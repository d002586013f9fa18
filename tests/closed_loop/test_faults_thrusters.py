"""Fault case 10: thruster failures from the drives' feedback, re-allocation, capability shortfall.

``sim_plant/scenarios/faults/10-thruster-failures.yaml`` (a tripped azimuth, then a tunnel that loses its
propeller) and ``10-thruster-capability.yaml`` (both tunnels trip in a beam wind, then an azimuth turns
the wrong way) in lockstep: the plant's drives fail as the scenario says and report it only through
their feedback (thrust delivered, ready), which the controller's thruster monitor judges.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from dpcontrol.models.vessels import vessel_from_config
from dpcontrol.runtime.alarms import AlarmRegistry
from dpcontrol.runtime.config import ThrusterMonitorSettings
from dpcontrol.runtime.thruster_monitor import ThrusterFeedback, ThrusterMonitor
from sim_plant.bench.lockstep import ProbedRun
from sim_plant.bench.run import build_simulation
from sim_plant.drives import ThrusterCommand, ThrusterDrives
from sim_plant.scenario import load_scenario

FAULTS = Path(__file__).resolve().parents[2] / "sim_plant" / "scenarios" / "faults"
DT = 0.1
SETTLED_S = 60.0


def _raised(run: ProbedRun, code: str, after_s: float) -> float | None:
    return next((t for t, raised in run.events(code) if raised and t >= after_s - 1e-9), None)


def _cleared(run: ProbedRun, code: str, after_s: float) -> float | None:
    return next((t for t, raised in run.events(code) if not raised and t >= after_s - 1e-9), None)


def _index(run: ProbedRun, name: str) -> int:
    return run.simulation.thruster_names.index(name)


@pytest.fixture(scope="module")
def failures() -> ProbedRun:
    return ProbedRun.run(build_simulation(load_scenario(FAULTS / "10-thruster-failures.yaml")))


@pytest.fixture(scope="module")
def capability() -> ProbedRun:
    return ProbedRun.run(build_simulation(load_scenario(FAULTS / "10-thruster-capability.yaml")))


def _reallocated(run: ProbedRun, t0_s: float, t1_s: float) -> None:
    """The remaining thrusters produce the demanded force (no shortfall) in ``[t0_s, t1_s)``."""
    controller_scale = run.simulation.controller.allocator.capability_scale
    delivered = np.column_stack([run.col("tau_act_x_n"), run.col("tau_act_y_n"), run.col("tau_act_n_nm")])
    lag = round(10.0 / DT)  # the drives' first-order lag and rate limits: compare 10 s averages
    mask = run.between(t0_s, t1_s)
    demand = run.tau_b()[mask].mean(axis=0)
    achieved = delivered[mask].mean(axis=0)
    assert np.all(np.abs(demand - achieved) < 0.02 * controller_scale), (demand, achieved)
    assert mask.sum() >= lag


def test_case10_tripped_drive_is_removed_at_once_and_the_demand_reallocated(failures: ProbedRun) -> None:
    run = failures
    i = _index(run, "azimuth_port")
    code = "thruster.azimuth_port.unavailable"
    assert _raised(run, code, 100.0) == pytest.approx(100.0)  # the step that receives ready = false
    assert code in run.status.active_codes(100.0)
    out = run.between(100.0, 150.0)
    assert not run.sensors.thruster_available[out, i].any()
    assert np.all(run.thrust_n()[out, i] == 0.0)  # commanded zero
    _reallocated(run, 110.0, 150.0)
    # ready again at 150 s: used again after the monitor's re-admission time (5 s)
    readmit = run.simulation.controller.monitor.readmit_s
    assert _cleared(run, code, 150.0) == pytest.approx(150.0 + readmit)
    assert run.sensors.thruster_available[run.between(150.0 + readmit + DT, 190.0), i].all()
    assert not any(raised for _, raised in run.events("thrusters.capability"))


def test_case10_dead_drive_is_found_by_the_thrust_mismatch_and_latched(failures: ProbedRun) -> None:
    run = failures
    i = _index(run, "bow_tunnel_2")
    monitor = run.simulation.config.thruster_monitor
    code = "thruster.bow_tunnel_2.unavailable"
    raised = _raised(run, code, 190.0)
    assert raised is not None and monitor.mismatch_persist_s <= raised - 190.0 <= monitor.mismatch_persist_s + 2.0
    assert code in run.status.active_codes(raised)
    assert _cleared(run, code, raised) is None  # latched until an operator reset
    after = run.between(raised + DT, 260.0)
    assert np.all(run.thrust_n()[after, i] == 0.0)
    assert not run.sensors.thruster_available[after, i].any()
    _reallocated(run, raised + 10.0, 260.0)
    # the others never tripped
    others = [j for j in range(len(run.simulation.thruster_names)) if j not in (i, _index(run, "azimuth_port"))]
    assert run.sensors.thruster_available[:, others].all()


def test_case10_station_keeping_and_rate_limits_through_the_failures(failures: ProbedRun) -> None:
    run = failures
    assert run.thrust_rate_excess_n() <= 1e-6
    assert [(m[1], m[2]) for m in run.result.mode_changes] == [("standby", "auto_position")]
    window = run.between(SETTLED_S, 260.0)
    assert np.nanmax(run.position_error_m()[window]) <= 2.0
    assert np.degrees(np.nanmax(run.heading_error_rad()[window])) <= 3.0


def test_case10_capability_shortfall_alarm_when_the_weather_exceeds_what_is_left(capability: ProbedRun) -> None:
    run = capability
    for name in ("bow_tunnel_1", "bow_tunnel_2"):
        assert _raised(run, f"thruster.{name}.unavailable", 120.0) == pytest.approx(120.0)
    monitor = run.simulation.config.thruster_monitor
    raised = _raised(run, "thrusters.capability", 120.0)
    assert raised is not None and raised - 120.0 <= monitor.shortfall_persist_s + 1.0
    assert "thrusters.capability" in run.status.active_codes(raised)
    assert not any(r for t, r in run.events("thrusters.capability") if t < 120.0)  # none while intact
    # heading priority (the allocator's docstring): the two stern azimuths cannot give sway and yaw apart, and
    # the shortfall goes to sway — the yaw moment is met and the heading kept within 15° until the wrong-way
    # azimuth at 200 s (with equal weights the moment was given up: 6.7 % of the capability short, 32.8° off)
    window = run.between(135.0, 195.0)
    scale = run.simulation.controller.allocator.capability_scale
    yaw_short = np.abs(run.col("tau_n_nm")[window] - run.col("tau_act_n_nm")[window]).mean() / scale[2]
    sway_short = np.abs(run.col("tau_y_n")[window] - run.col("tau_act_y_n")[window]).mean() / scale[1]
    assert yaw_short < 0.01 < 0.1 < sway_short, (yaw_short, sway_short)
    assert np.degrees(np.nanmax(run.heading_error_rad()[run.between(120.0, 200.0)])) <= 15.0
    wrong = _raised(run, "thruster.azimuth_starboard.unavailable", 200.0)
    assert wrong is not None and wrong - 200.0 <= monitor.mismatch_persist_s + 2.0
    assert np.all(run.thrust_n()[run.between(wrong + DT, 230.0), _index(run, "azimuth_starboard")] == 0.0)
    assert run.thrust_rate_excess_n() <= 1e-6
    # in this beam weather the PID's integral needs minutes to bring the vessel back (measured 6.7 m)
    assert np.nanmax(run.position_error_m()[run.between(SETTLED_S, 120.0)]) <= 8.0


# ------------------------------------------------------------------------------------------ the monitor alone
def _drive_and_monitor(failure: str | None, load: float, seconds: float = 30.0, seed: int = 4) -> tuple[bool, float]:
    """One supply-vessel tunnel (150 kN) driven by a command fluctuating around ``load`` × its rating, with
    the plant's drive model (``sim_plant.drives.ThrusterDrives``) failing as ``failure`` from 5 s on.
    Returns whether the monitor took it out and when."""

    spec = next(t for t in vessel_from_config("supply", "vessel").thrusters if t.name == "bow_tunnel_1")
    drives = ThrusterDrives([spec])
    monitor = ThrusterMonitor([spec], ThrusterMonitorSettings(), AlarmRegistry())
    rng = np.random.default_rng(seed)
    command = np.zeros(1)
    removed_at = None
    for k in range(round(seconds / DT)):
        t = k * DT
        if failure is not None and abs(t - 5.0) < 1e-9:
            drives.set_failure(spec.name, failure)
        target = load * spec.max_thrust_n * (1.0 + 0.4 * math.sin(0.3 * t) + 0.2 * rng.standard_normal())
        feedback = drives.feedback()[0]
        monitor.feedback([ThrusterFeedback(spec.name, feedback.thrust_n, feedback.azimuth_rad, feedback.ready, t)])
        available = monitor.update(t, DT, command)
        command[0] = target if available[0] else 0.0
        drives.command(t, {spec.name: ThrusterCommand(float(command[0]))})
        for j in range(5):
            drives.update(t + j * DT / 5, DT / 5)
        if not available[0] and removed_at is None:
            removed_at = t
    return removed_at is not None, removed_at if removed_at is not None else math.inf


@pytest.mark.parametrize("load", [0.1, 0.3, 0.8])
def test_a_healthy_drive_is_never_taken_out(load: float) -> None:
    assert _drive_and_monitor(None, load) == (False, math.inf)


@pytest.mark.parametrize(("failure", "load"), [("zero", 0.1), ("zero", 0.5), ("wrong_sign", 0.04), ("wrong_sign", 0.6)])
def test_a_dead_or_reversed_drive_is_taken_out_at_any_meaningful_load(failure: str, load: float) -> None:
    removed, at = _drive_and_monitor(failure, load)
    persist = ThrusterMonitorSettings().mismatch_persist_s
    assert removed and persist <= at - 5.0 <= persist + 2.0


def test_a_drive_asked_for_almost_nothing_is_not_judged() -> None:
    # 2 % of the rating delivering nothing is below the 5 % floor: no alarm on noise-level thrust
    assert _drive_and_monitor("zero", 0.02) == (False, math.inf)
