"""Fault cases 1–7 on the emulated plant: position and heading reference faults, in lockstep.

Each scenario in ``sim_plant/scenarios/faults/`` (its header says what is injected, what must happen
and the bound) runs once per module through the real codecs, the daemon's sensor hub, wave filter,
PID and allocator; the tests read the detection time from the hub's per-step state and the alarm
events (the record), check the alarm in the ``dp/<vessel>/status`` payload the daemon would publish
(built by the daemon's own builder and parsed back through the status schema), the response
(weights, mode, fall-back) and the station-keeping bound. Every bound is the configured one
(freeze window, stale periods, persistence times), not a measured value.

Common to every scenario (``_common``): every status payload is valid; the thrust commands never
change faster than the drives' rate limits; the true LF position stays within ``POSITION_BOUND_M``
of the reference and the heading within ``HEADING_BOUND_DEG`` from ``SETTLED_S`` on (the no-fault
run of the same sea stays within 1.5 m and 2°).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from dpcontrol.runtime.hub import SensorState
from sim_plant.bench.lockstep import ProbedRun
from sim_plant.bench.run import build_simulation
from sim_plant.scenario import load_scenario

FAULTS = Path(__file__).resolve().parents[2] / "sim_plant" / "scenarios" / "faults"
SETTLED_S = 60.0          # DP engages at 20 s; the PID integrator has settled the worst of it by then
POSITION_BOUND_M = 2.0    # true LF position − reference, from SETTLED_S on (scenario headers)
HEADING_BOUND_DEG = 3.0
DT = 0.1


def _run(name: str) -> ProbedRun:
    return ProbedRun.run(build_simulation(load_scenario(FAULTS / f"{name}.yaml")))


def _common(run: ProbedRun, *, position_bound_m: float = POSITION_BOUND_M, until_s: float = math.inf) -> None:
    rejected = [t for t, status in run.status.samples if not isinstance(status, dict)]
    assert rejected == [], "status payloads rejected by the schema"
    assert run.thrust_rate_excess_n() <= 1e-6  # no thrust command faster than its drive's rate limit
    window = run.between(SETTLED_S, until_s)
    assert np.nanmax(run.position_error_m()[window]) <= position_bound_m
    assert np.degrees(np.nanmax(run.heading_error_rad()[window])) <= HEADING_BOUND_DEG


def _period(run: ProbedRun, sensor: str) -> float:
    return next(1.0 / r.sensor.nominal_rate_hz for r in run.simulation.config.routes if r.sensor.name == sensor)


def _raised(run: ProbedRun, code: str, after_s: float) -> float:
    """Time of the first raise of ``code`` at or after ``after_s`` (fails if never)."""
    times = [t for t, raised in run.events(code) if raised and t >= after_s - 1e-9]
    assert times, f"{code} never raised after {after_s} s"
    return times[0]


def _cleared(run: ProbedRun, code: str, after_s: float) -> float:
    times = [t for t, raised in run.events(code) if not raised and t >= after_s - 1e-9]
    assert times, f"{code} never cleared after {after_s} s"
    return times[0]


def _accepted(run: ProbedRun, sensor: str, t0_s: float, t1_s: float) -> int:
    """Samples of ``sensor`` accepted by the hub in the steps ``t0_s < t ≤ t1_s``."""
    k0 = round(t0_s / DT)
    k1 = round(t1_s / DT)
    column = run.sensors.accepted[:, run.sensors.column(sensor)]
    return int(column[k1] - column[k0])


def _weight(run: ProbedRun, sensor: str, t0_s: float, t1_s: float) -> np.ndarray:
    return run.sensors.weight[run.between(t0_s, t1_s), run.sensors.column(sensor)]


def _modes(run: ProbedRun) -> list[tuple[float, str, str, str]]:
    return run.result.mode_changes


def _only_engaged(run: ProbedRun) -> None:
    """DP engaged once and never left auto_position (no restart, no fall-back)."""
    assert [(m[1], m[2]) for m in _modes(run)] == [("standby", "auto_position")]


# ------------------------------------------------------------------------------------------------ case 1
@pytest.fixture(scope="module")
def freeze() -> ProbedRun:
    return _run("01-gnss-freeze")


def test_case1_frozen_gnss_is_rejected_within_the_window_and_dp_continues(freeze: ProbedRun) -> None:
    run = freeze
    window = run.simulation.config.hub.freeze_window_s
    detected = run.sensors.first_time("gnss1", SensorState.FROZEN, 120.0)
    assert detected is not None and detected - 120.0 <= window + _period(run, "gnss1") + DT
    assert _raised(run, "sensor.gnss1.frozen", 120.0) == pytest.approx(detected)
    assert "sensor.gnss1.frozen" in run.status.active_codes(detected)
    assert run.status.sensor_state(detected, "gnss1") == "frozen"
    # response: no frozen sample used after the detection, gnss2 carries the fix, DP goes on
    assert _accepted(run, "gnss1", detected, 179.9) == 0
    assert np.all(_weight(run, "gnss1", detected, 180.0) == 0.0)
    assert np.all(_weight(run, "gnss2", detected, 180.0) == 1.0)
    _only_engaged(run)
    # moving again at 180 s: cleared, and fused again after the hub's readmission time
    assert _cleared(run, "sensor.gnss1.frozen", 180.0) <= 180.0 + DT
    readmit = run.simulation.config.hub.readmit_s
    assert np.all(_weight(run, "gnss1", 180.0 + readmit + 1.0, 219.0) > 0.2)


def test_case1_both_frozen_dead_reckons_on_the_model_without_fallback(freeze: ProbedRun) -> None:
    run = freeze
    hub = run.simulation.config.hub
    bound = hub.freeze_window_s + 0.2 + DT
    for sensor in ("gnss1", "gnss2"):
        assert _raised(run, f"sensor.{sensor}.frozen", 220.0) - 220.0 <= bound
    dead_reckoning = _raised(run, "position.dead_reckoning", 220.0)
    assert dead_reckoning - 220.0 <= bound
    assert "position.dead_reckoning" in run.status.active_codes(dead_reckoning)
    assert not run.sensors.position_available[run.between(dead_reckoning + DT, 250.0)].any()
    assert _cleared(run, "position.dead_reckoning", 250.0) <= 250.0 + DT
    _only_engaged(run)  # 30 s of dead reckoning < fallback.dead_reckoning_limit_s (60 s)
    _common(run)


# ------------------------------------------------------------------------------------------------ case 2
@pytest.fixture(scope="module")
def jump() -> ProbedRun:
    return _run("02-gnss-jump")


def test_case2_jump_is_rejected_from_the_first_sample(jump: ProbedRun) -> None:
    run = jump
    column = run.sensors.column("gnss1")
    k = round(120.0 / DT)  # the step that receives the first jumped sample (sampled at 120.0 s)
    assert run.sensors.rejected[k, column] == run.sensors.rejected[k - 1, column] + 1
    assert _accepted(run, "gnss1", 119.9, 180.0 - DT) == 0  # no jumped sample ever accepted
    hub = run.simulation.config.hub
    assert _raised(run, "sensor.gnss1.rejected", 120.0) - 120.0 <= hub.reject_persist_s + 0.2 + DT
    assert "sensor.gnss1.rejected" in run.status.active_codes(_raised(run, "sensor.gnss1.rejected", 120.0))
    assert not any(raised for _, raised in run.events("estimator.reset"))
    _only_engaged(run)


def test_case2_no_step_in_the_force_or_the_thrust(jump: ProbedRun) -> None:
    run = jump
    drives_per_step = run.simulation.controller.force_rate_b * DT
    baseline = run.force_step_n(SETTLED_S, 120.0)
    for t0, t1 in ((120.0, 135.0), (180.0, 190.0), (220.0, 235.0)):
        assert np.all(run.force_step_n(t0, t1) <= baseline + drives_per_step), (t0, run.force_step_n(t0, t1))
    est = np.column_stack([run.col("est_north_m"), run.col("est_east_m")])
    steps = np.hypot(*np.diff(est[run.between(SETTLED_S, 280.0)], axis=0).T)
    assert steps.max() < 0.2  # the estimate never follows a 10 m jump


def test_case2_both_jumping_briefly_is_ridden_out_on_the_model(jump: ProbedRun) -> None:
    run = jump
    for sensor in ("gnss1", "gnss2"):
        assert _accepted(run, sensor, 219.9, 226.0 - DT) == 0
    stale_s = run.simulation.config.hub.stale_periods * 0.2
    assert _raised(run, "position.dead_reckoning", 220.0) - 220.0 <= stale_s + DT
    assert _cleared(run, "position.dead_reckoning", 226.0) <= 226.0 + DT
    _common(run)


# ------------------------------------------------------------------------------------------------ case 3
@pytest.fixture(scope="module")
def drift3() -> ProbedRun:
    return _run("03-gnss-drift-three")


@pytest.fixture(scope="module")
def drift2() -> ProbedRun:
    return _run("03-gnss-drift-two")


def _drift_bound(run: ProbedRun, rate_mps: float) -> float:
    hub = run.simulation.config.hub
    return hub.median_limit_m / rate_mps + hub.median_filter_s + hub.median_persist_s + 5.0


def test_case3_median_test_isolates_the_drifting_reference_of_three(drift3: ProbedRun) -> None:
    run = drift3
    isolated = run.sensors.first_time("gnss3", SensorState.ISOLATED, 100.0)
    assert isolated is not None and isolated - 100.0 <= _drift_bound(run, 0.1)
    assert _raised(run, "sensor.gnss3.isolated", 100.0) == pytest.approx(isolated)
    assert "sensor.gnss3.isolated" in run.status.active_codes(isolated)
    assert np.all(_weight(run, "gnss3", isolated + DT, 180.0) == 0.0)
    assert np.all(_weight(run, "gnss1", isolated + DT, 180.0) + _weight(run, "gnss2", isolated + DT, 180.0)
                  == pytest.approx(1.0))
    _only_engaged(run)
    assert _cleared(run, "sensor.gnss3.isolated", 180.0) <= 180.0 + 2.0
    _common(run, position_bound_m=3.0)  # a third of the drift reaches the estimate before the isolation


def test_case3_two_references_disagreeing_alarm_without_isolation(drift2: ProbedRun) -> None:
    run = drift2
    raised = _raised(run, "position.disagree", 100.0)
    assert raised - 100.0 <= _drift_bound(run, 0.1)
    assert "position.disagree" in run.status.active_codes(raised)
    for sensor in ("gnss1", "gnss2"):
        assert not any(r for _, r in run.events(f"sensor.{sensor}.isolated"))
        assert not any(r for _, r in run.events(f"sensor.{sensor}.rejected"))
        assert np.all(_weight(run, sensor, 100.0, 150.0) > 0.2)  # both still used: nothing to tell them apart
    assert _cleared(run, "position.disagree", 150.0) <= 150.0 + 5.0
    _only_engaged(run)
    _common(run, position_bound_m=3.5)  # the vessel follows half the drift (the mean of the two)


# ------------------------------------------------------------------------------------------------ case 4
@pytest.fixture(scope="module")
def noise() -> ProbedRun:
    return _run("04-gnss-noise")


def test_case4_noisy_reference_loses_weight_by_the_variance_test(noise: ProbedRun) -> None:
    run = noise
    before = _weight(run, "gnss2", 80.0, 100.0)
    assert 0.3 < before.mean() < 0.7
    hub = run.simulation.config.hub
    raised = _raised(run, "sensor.gnss2.noisy", 100.0)
    assert raised - 100.0 <= 3.0 * hub.variance_time_constant_s
    assert "sensor.gnss2.noisy" in run.status.active_codes(raised)
    # inverse-variance weight at 5× the noise: 1/(1 + 25) ≈ 0.04 once the variance has been measured
    assert np.all(_weight(run, "gnss2", 100.0 + 3.0 * hub.variance_time_constant_s, 220.0) < 0.1)
    assert _cleared(run, "sensor.gnss2.noisy", 220.0) <= 220.0 + 3.0 * hub.variance_time_constant_s
    assert np.all(_weight(run, "gnss2", 250.0, 260.0) > 0.15)  # recovering


def test_case4_gst_statistics_set_the_weight_from_the_first_noisy_fix(noise: ProbedRun) -> None:
    run = noise
    assert np.all(_weight(run, "gnss1", 250.0, 260.0) > 0.3)  # (more than half while gnss2 recovers)
    first = round(260.0 / DT)  # the step receiving the first ×5 fix and its GST (sampled at 260.0 s)
    weights = run.sensors.weight[first - 1:first + 1, run.sensors.column("gnss1")]
    # its GST says σ × 5: the weight ratio to gnss2 drops 25-fold at once, before any variance is measured
    assert weights[1] < weights[0] / 4.0
    assert np.all(_weight(run, "gnss1", 260.0, 340.0) < 0.2)
    _only_engaged(run)
    _common(run)


# ------------------------------------------------------------------------------------------------ case 5
@pytest.fixture(scope="module")
def dropout() -> ProbedRun:
    return _run("05-gnss-dropout")


def test_case5_dropout_marks_stale_and_dp_continues(dropout: ProbedRun) -> None:
    run = dropout
    bound = run.simulation.config.hub.stale_periods * _period(run, "gnss1") + DT
    stale = run.sensors.first_time("gnss1", SensorState.STALE, 100.0)
    assert stale is not None and stale - 100.0 <= bound
    assert _raised(run, "sensor.gnss1.stale", 100.0) == pytest.approx(stale)
    assert "sensor.gnss1.stale" in run.status.active_codes(stale)
    assert np.all(_weight(run, "gnss2", stale, 130.0) == 1.0)
    assert run.sensors.position_available[run.between(100.0, 160.0)].all()
    assert _cleared(run, "sensor.gnss1.stale", 130.0) <= 130.0 + DT


def test_case5_all_lost_dead_reckoning_then_the_configured_fallback_without_a_jump(dropout: ProbedRun) -> None:
    run = dropout
    config = run.simulation.config
    bound = config.hub.stale_periods * 0.2 + DT
    dead_reckoning = _raised(run, "position.dead_reckoning", 160.0)
    assert dead_reckoning - 160.0 <= bound
    assert "position.dead_reckoning" in run.status.active_codes(dead_reckoning)
    limit = config.fallback.dead_reckoning_limit_s
    changes = _modes(run)[1:]
    assert len(changes) == 2
    t_fallback, old, new, reason = changes[0]
    assert (old, new) == ("auto_position", "auto_heading") and reason.startswith("fallback")  # hold_heading
    assert limit <= t_fallback - dead_reckoning <= limit + DT
    assert _raised(run, "mode.fallback", t_fallback) == pytest.approx(t_fallback)
    assert "mode.fallback" in run.status.active_codes(t_fallback)
    # the fall-back lasted less than fallback.restore_within_s: auto_position again when the references are back
    t_restored, old, new, reason = changes[1]
    assert (old, new) == ("auto_heading", "auto_position") and reason.startswith("restored")
    assert 250.0 <= t_restored <= 250.0 + 1.0 and t_restored - t_fallback < config.fallback.restore_within_s
    assert _raised(run, "mode.restored", t_restored) == pytest.approx(t_restored)
    assert not run.status.active_codes(t_restored + 1.0) & {"mode.fallback"}
    # auto_heading: zero surge/sway force, heading still held on the gyro
    after = run.between(t_fallback + DT, t_restored)
    assert np.all(run.tau_b()[after, :2] == 0.0)
    assert np.degrees(np.nanmax(run.heading_error_rad()[after])) <= HEADING_BOUND_DEG
    # never a jump: the estimate moves continuously through dead reckoning, the fall-back and the
    # references' return at 250 s (no estimator reset), and every thrust command within its rate limit
    est = np.column_stack([run.col("est_north_m"), run.col("est_east_m")])
    assert np.hypot(*np.diff(est[run.between(150.0, 280.0)], axis=0).T).max() < 0.2
    assert not any(raised for _, raised in run.events("estimator.reset"))
    assert run.col("mode")[-1] == 2.0  # auto_position, restored
    _common(run, until_s=t_fallback)


# ------------------------------------------------------------------------------------------------ case 6
@pytest.fixture(scope="module")
def invalid() -> ProbedRun:
    return _run("06-invalid-data")


@pytest.mark.parametrize(("sensor", "t0"), [("gnss1", 100.0), ("gyro1", 100.0), ("gnss2", 140.0),
                                            ("gyro2", 140.0), ("gnss3", 180.0), ("gyro3", 180.0)])
def test_case6_data_flagged_invalid_is_never_used(invalid: ProbedRun, sensor: str, t0: float) -> None:
    run = invalid
    assert _accepted(run, sensor, t0 - DT, t0 + 30.0 - DT) == 0
    samples = run.sensors.accepted[:, run.sensors.column(sensor)] + run.sensors.rejected[:, run.sensors.column(sensor)]
    assert samples[round((t0 + 30.0 - DT) / DT)] == samples[round((t0 - DT) / DT)]  # nothing reached the hub
    bound = run.simulation.config.hub.stale_periods * _period(run, sensor) + DT
    assert _raised(run, f"sensor.{sensor}.stale", t0) - t0 <= bound
    assert _cleared(run, f"sensor.{sensor}.stale", t0 + 30.0) <= t0 + 30.0 + DT


def test_case6_invalid_flags_are_counted_as_flagged_not_malformed(invalid: ProbedRun) -> None:
    run = invalid
    transports = run.result.counters["transports"]
    # 30 s of each sensor: GNSS 5 Hz (one GGA / 129029 / GPS_RAW_INT each), gyro 10 Hz
    assert transports["lockstep_nmea0183"]["reason.invalid_fix"] == 150          # GGA quality 0
    assert transports["lockstep_nmea0183"]["reason.invalid_status"] == 600       # THS V + ROT V
    assert transports["lockstep_nmea2000"]["reason.invalid_fix"] == 150          # 129029 "no GNSS"
    assert transports["lockstep_nmea2000"]["reason.not_available"] == 600        # 127250 + 127251 NA
    assert transports["lockstep_mavlink"]["reason.invalid_fix"] == 150           # GPS_RAW_INT fix_type 0
    assert transports["lockstep_mavlink"]["reason.not_available"] == 300         # ATTITUDE without values
    assert all(counts["rejected"] == 0 for counts in transports.values())
    assert not any(e.code.endswith(".error_rate") for e in run.result.alarm_events)
    _only_engaged(run)
    _common(run)


# ------------------------------------------------------------------------------------------------ case 7
@pytest.fixture(scope="module")
def gyro3() -> ProbedRun:
    return _run("07-gyro-three")


@pytest.fixture(scope="module")
def gyro2() -> ProbedRun:
    return _run("07-gyro-two")


def _yaw_excursion_deg(run: ProbedRun, t0_s: float, t1_s: float) -> float:
    """Largest change of the true LF heading from its value at ``t0_s`` within ``[t0_s, t1_s)``."""
    heading = run.col("heading_rad")
    mask = run.between(t0_s, t1_s)
    return float(np.degrees(np.max(np.abs(heading[mask] - heading[round(t0_s / DT)]))))


def test_case7_three_gyros_offset_gyro_voted_out_without_a_yaw_transient(gyro3: ProbedRun) -> None:
    run = gyro3
    column = run.sensors.column("gyro2")
    k = round(100.0 / DT)
    assert run.sensors.rejected[k, column] == run.sensors.rejected[k - 1, column] + 1  # first sample
    assert _accepted(run, "gyro2", 99.9, 160.0 - DT) == 0
    hub = run.simulation.config.hub
    raised = _raised(run, "sensor.gyro2.rejected", 100.0)
    assert raised - 100.0 <= hub.reject_persist_s + 0.1 + DT
    assert "sensor.gyro2.rejected" in run.status.active_codes(raised)
    assert _yaw_excursion_deg(run, 100.0, 115.0) <= 0.5
    frozen = run.sensors.first_time("gyro3", SensorState.FROZEN, 180.0)
    assert frozen is not None and frozen - 180.0 <= hub.freeze_window_s + 0.1 + DT
    assert _yaw_excursion_deg(run, 180.0, 195.0) <= 0.5
    assert not any(raised for _, raised in run.events("estimator.reset"))


def test_case7_all_gyros_lost_alarm_and_the_configured_fallback(gyro3: ProbedRun) -> None:
    run = gyro3
    config = run.simulation.config
    lost = _raised(run, "heading.lost", 240.0)
    assert lost - 240.0 <= config.hub.stale_periods * 0.1 + DT
    assert "heading.lost" in run.status.active_codes(lost)
    changes = _modes(run)[1:]
    assert len(changes) == 1
    t_fallback, old, new, reason = changes[0]
    assert (old, new) == ("auto_position", "standby") and reason.startswith("fallback")  # heading_loss: standby
    assert config.fallback.heading_loss_limit_s <= t_fallback - lost <= config.fallback.heading_loss_limit_s + DT
    assert "mode.fallback" in run.status.active_codes(t_fallback)
    # standby: the thrust ramps to zero at the drives' rate limits (checked in _common), and gets there
    thrust = run.thrust_n()
    ramp_s = max(t.max_thrust_n / t.thrust_rate_limit_nps for t in config.vessel.thrusters)
    assert np.all(np.abs(thrust[run.between(t_fallback + ramp_s + 1.0, 270.0)]) < 1e-6)
    _common(run, until_s=lost)


def test_case7_two_gyros_offset_then_freeze_switch_to_the_healthy_one(gyro2: ProbedRun) -> None:
    run = gyro2
    hub = run.simulation.config.hub
    assert _accepted(run, "gyro1", 99.9, 160.0 - DT) == 0
    assert _raised(run, "sensor.gyro1.rejected", 100.0) - 100.0 <= hub.reject_persist_s + 0.1 + DT
    # the healthy gyro agrees with the estimate: never an estimator reset onto the offset one
    assert not any(raised for _, raised in run.events("estimator.reset"))
    assert np.all(_weight(run, "gyro2", 100.6, 160.0) == 1.0)
    assert _yaw_excursion_deg(run, 100.0, 115.0) <= 0.5
    frozen = run.sensors.first_time("gyro2", SensorState.FROZEN, 190.0)
    assert frozen is not None and frozen - 190.0 <= hub.freeze_window_s + 0.1 + DT
    assert np.all(_weight(run, "gyro1", frozen + DT, 230.0) == 1.0)
    assert _yaw_excursion_deg(run, 190.0, 205.0) <= 0.5
    _only_engaged(run)
    _common(run)
