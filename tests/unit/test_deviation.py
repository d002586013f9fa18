"""Position and heading deviation alarms (``dpcontrol/runtime/deviation.py``, ``deviation:``): the estimated
low-frequency pose against the guidance's reference, a warning and an alarm limit each, a persistence, a
hysteresis band, and the modes that watch each quantity."""

from __future__ import annotations

import copy
import math
from typing import Any

import numpy as np
import pytest

from dpbase.schema import ConfigError
from dpcontrol.bench import bench_config
from dpcontrol.runtime.alarms import AlarmRegistry, Severity
from dpcontrol.runtime.config import DeviationSettings, parse_config
from dpcontrol.runtime.deviation import CLEAR_FRACTION, DeviationMonitor
from dpcontrol.runtime.step import DpController, Mode

REFERENCE = np.array([10.0, -5.0, math.radians(90.0)])


def _monitor(**settings: Any) -> tuple[DeviationMonitor, AlarmRegistry]:
    alarms = AlarmRegistry()
    return DeviationMonitor(DeviationSettings(**settings), alarms), alarms


def _hold(monitor: DeviationMonitor, t0_s: float, t1_s: float, offset: tuple[float, float, float],
          mode: str = "auto_position") -> None:
    """10 Hz steps from t0 to t1 (excluded) with the estimate ``offset`` [m, m, rad] from the reference."""
    for k in range(round((t1_s - t0_s) * 10)):
        monitor.update(t0_s + 0.1 * k, mode, REFERENCE + np.array(offset), REFERENCE)


def _active(alarms: AlarmRegistry) -> list[tuple[str, Severity, float | None]]:
    return sorted((a.code, a.severity, a.since_t_s) for a in alarms.active())


def test_warning_then_alarm_after_the_persistence_and_clearing_below_the_band() -> None:
    monitor, alarms = _monitor()  # 3 / 5 m, 3 / 5°, 1 s
    _hold(monitor, 0.0, 10.0, (2.0, 2.0, 0.0))  # 2.83 m: inside the warning limit
    assert not alarms.active() and monitor.position_m == pytest.approx(math.hypot(2.0, 2.0))
    _hold(monitor, 10.0, 10.5, (3.0, 0.5, 0.0))  # 3.04 m for half a second: not yet
    assert not alarms.active()
    _hold(monitor, 10.5, 20.0, (3.0, 0.5, 0.0))
    assert _active(alarms) == [("position.deviation.warning", Severity.WARNING, pytest.approx(11.0))]
    assert alarms.active()[0].text == "position deviation 3.0 m from the reference (warning limit 3 m)"
    _hold(monitor, 20.0, 30.0, (0.0, -5.5, 0.0))  # beyond the alarm limit: both up, the log shows the escalation
    assert _active(alarms) == [("position.deviation.alarm", Severity.ALARM, pytest.approx(21.0)),
                               ("position.deviation.warning", Severity.WARNING, pytest.approx(11.0))]
    # back to 4.5 m: above 80 % of the alarm limit (the band): the alarm stays; below it for 1 s: cleared
    _hold(monitor, 30.0, 40.0, (4.5, 0.0, 0.0))
    assert alarms.is_active("position.deviation.alarm")
    _hold(monitor, 40.0, 50.0, (3.9, 0.0, 0.0))
    assert [a.code for a in alarms.active()] == ["position.deviation.warning"]
    _hold(monitor, 50.0, 60.0, (0.8 * 3.0 - 0.01, 0.0, 0.0))
    assert not alarms.active()
    events = [(e.code, e.raised, round(e.t_s, 1)) for e in alarms.drain_events()]
    assert events == [("position.deviation.warning", True, 11.0), ("position.deviation.alarm", True, 21.0),
                      ("position.deviation.alarm", False, 41.0), ("position.deviation.warning", False, 51.0)]
    assert CLEAR_FRACTION == 0.8


def test_a_deviation_that_flickers_over_the_limit_is_not_raised() -> None:
    monitor, alarms = _monitor(persist_s=2.0)
    for k in range(300):  # 3.2 m and 2.9 m alternately each 0.5 s: never 2 s above
        offset = 3.2 if (k // 5) % 2 == 0 else 2.9
        monitor.update(0.1 * k, "auto_position", REFERENCE + np.array([offset, 0.0, 0.0]), REFERENCE)
    assert not alarms.active()


def test_heading_wraps_and_is_watched_in_auto_heading_too() -> None:
    monitor, alarms = _monitor()
    north = np.array([0.0, 0.0, math.radians(1.0)])
    for k in range(30):  # 359° against 1°: 2°, not 358°
        monitor.update(0.1 * k, "auto_heading", np.array([50.0, 0.0, math.radians(359.0)]), north)
    assert monitor.heading_rad == pytest.approx(math.radians(2.0)) and not alarms.active()
    assert monitor.position_m is None  # 50 m off: auto_heading does not hold position
    for k in range(30, 60):
        monitor.update(0.1 * k, "auto_heading", np.array([50.0, 0.0, math.radians(354.0)]), north)
    assert _active(alarms) == [("heading.deviation.alarm", Severity.ALARM, pytest.approx(4.0)),
                               ("heading.deviation.warning", Severity.WARNING, pytest.approx(4.0))]
    assert "heading deviation 7.0 deg from the reference (alarm limit 5 deg)" in [a.text for a in alarms.active()]


def test_standby_and_auto_heading_release_what_they_do_not_hold() -> None:
    monitor, alarms = _monitor(persist_s=0.0)
    _hold(monitor, 0.0, 1.0, (6.0, 0.0, math.radians(6.0)))
    assert len(alarms.active()) == 4
    _hold(monitor, 1.0, 1.1, (6.0, 0.0, math.radians(6.0)), mode="auto_heading")  # position no longer held
    assert sorted(a.code for a in alarms.active()) == ["heading.deviation.alarm", "heading.deviation.warning"]
    monitor.update(1.1, "standby", None, None)
    assert not alarms.active() and monitor.heading_rad is None


CONFIG: dict[str, Any] = {
    "vessel_id": "osv1", "vessel": "supply",
    "transports": [{"name": "serial0", "protocol": "nmea0183", "port": "/dev/null"}],
    "sensors": [{"name": "gnss1", "kind": "position", "transport": "serial0"},
                {"name": "gyro1", "kind": "heading", "transport": "serial0"}],
}


def test_configuration_and_its_errors() -> None:
    assert parse_config(CONFIG).deviation == DeviationSettings()  # full-scale defaults: 3 / 5 m, 3 / 5°, 1 s
    config = copy.deepcopy(CONFIG)
    config["deviation"] = {"position_warning_m": 0.2, "position_alarm_m": 0.3, "heading_warning_deg": 4,
                           "heading_alarm_deg": 8, "persist_s": 2}
    settings = parse_config(config).deviation
    assert (settings.position_warning_m, settings.position_alarm_m, settings.persist_s) == (0.2, 0.3, 2)
    assert settings.heading_alarm_rad == pytest.approx(math.radians(8.0))
    for wrong, path, expected in (
            ({"position_alarm_m": 2.0}, "deviation.position_alarm_m", "more than position_warning_m (3 m)"),
            ({"heading_warning_deg": 6}, "deviation.heading_alarm_deg", "more than heading_warning_deg"),
            ({"heading_warning_deg": 170, "heading_alarm_deg": 190}, "deviation.heading_alarm_deg", "less than 180"),
            ({"position_warning_m": 0}, "deviation.position_warning_m", ""),
            ({"persist_s": -1}, "deviation.persist_s", ""),
            ({"position_limit_m": 3}, "deviation.position_limit_m", "")):
        config["deviation"] = wrong
        with pytest.raises(ConfigError) as error:
            parse_config(config)
        assert error.value.path == path and expected in str(error.value), wrong


def test_the_controller_watches_the_estimate_against_the_reference() -> None:
    controller = DpController(bench_config())
    controller.step(0.0)  # standby, no estimate: nothing watched
    assert controller.deviation.position_m is None and controller.deviation.heading_rad is None


def _drive(monitor: DeviationMonitor, t0_s: float, t1_s: float, north_of_t) -> None:
    """10 Hz steps from t0 to t1 with the estimate ``north_of_t(t)`` [m] north of the reference."""
    for k in range(round((t1_s - t0_s) * 10)):
        t = t0_s + 0.1 * k
        monitor.update(t, "auto_position", REFERENCE + np.array([north_of_t(t), 0.0, 0.0]), REFERENCE)


def test_a_drift_off_is_alarmed_before_the_deviation_limits() -> None:
    """The vessel accelerating away under an unbalanced force (0.01 m/s²): drift-off raised while the deviation
    is still under the 3 m warning limit, cleared once she is brought back."""
    monitor, alarms = _monitor()
    _drive(monitor, 0.0, 10.0, lambda t: 0.1 * math.sin(t))  # station keeping: no alarm
    assert alarms.active() == []
    raised_at = None
    for k in range(300):
        t = 10.0 + 0.1 * k
        monitor.update(t, "auto_position", REFERENCE + np.array([0.005 * (t - 10.0) ** 2, 0.0, 0.0]), REFERENCE)
        if alarms.is_active("position.drift_off") and raised_at is None:
            raised_at = t
    assert raised_at is not None
    assert 0.005 * (raised_at - 10.0) ** 2 < 3.0  # before the warning limit
    assert not alarms.is_active("position.deviation.warning") or raised_at < min(
        a.since_t_s for a in alarms.active() if a.code == "position.deviation.warning")
    _drive(monitor, 40.0, 60.0, lambda t: max(4.5 - 0.5 * (t - 40.0), 0.0))  # brought back
    assert not alarms.is_active("position.drift_off")


def test_a_step_or_a_steady_offset_is_no_drift_off() -> None:
    monitor, alarms = _monitor()
    _drive(monitor, 0.0, 30.0, lambda t: 2.0 if t >= 5.0 else 0.0)  # a 2 m step (a set-point change)
    _drive(monitor, 30.0, 60.0, lambda t: 2.0 + 0.01 * (t - 30.0))  # a slow, steady creep (no acceleration)
    assert not alarms.is_active("position.drift_off")
    assert all(e.code != "position.drift_off" for e in alarms.drain_events())


def test_no_drift_off_alarm_when_disabled() -> None:
    monitor, alarms = _monitor(drift_off_horizon_s=0.0)
    _drive(monitor, 0.0, 30.0, lambda t: 0.005 * t * t)
    assert not alarms.is_active("position.drift_off")


def test_the_drift_off_horizon_is_the_vessels() -> None:
    """Default horizon: 30 s for a full-scale vessel, Froude-scaled below 76.2 m (CyberShip II's 1.255 m: 3.85 s);
    an explicit ``drift_off_horizon_s`` wins."""
    assert parse_config(CONFIG).deviation.drift_off_horizon_s == 30.0
    model = copy.deepcopy(CONFIG) | {"vessel": "cybership2"}
    assert parse_config(model).deviation.drift_off_horizon_s == pytest.approx(30.0 * math.sqrt(1.255 / 76.2))
    model["deviation"] = {"drift_off_horizon_s": 12}
    assert parse_config(model).deviation.drift_off_horizon_s == 12.0


def _model_scale_wander(horizon_s: float) -> AlarmRegistry:
    """A model-scale vessel holding station: the LF position wanders ±4 cm about 6 cm over 30 s (CyberShip II in
    a sea; 2.4 m over 4 min at full scale), under 0.2 / 0.3 m limits."""
    monitor, alarms = _monitor(position_warning_m=0.2, position_alarm_m=0.3, drift_off_horizon_s=horizon_s)
    _drive(monitor, 0.0, 120.0, lambda t: 0.06 + 0.04 * math.sin(2.0 * math.pi * t / 30.0))
    return alarms


def test_a_model_scale_wander_is_no_drift_off() -> None:
    model = copy.deepcopy(CONFIG) | {"vessel": "cybership2"}
    assert all(e.code != "position.drift_off"
               for e in _model_scale_wander(parse_config(model).deviation.drift_off_horizon_s).drain_events())
    # the full-scale horizon extrapolates each rise of the wander past the 0.3 m limit (the HIL bench's false
    # alarm: measured margins up to 1.25x the limit in lockstep, 0.43x with the vessel's horizon)
    assert any(e.code == "position.drift_off" for e in _model_scale_wander(30.0).drain_events())


@pytest.mark.parametrize("y_m", ["model", "guidance"])
def test_an_mrac_is_watched_from_its_reference_model_not_from_the_guidance(y_m: str) -> None:
    """Seed 003's MRAC makes the vessel follow its reference model y_M, which trails η_d by design (eq. (15)):
    a vessel that follows y_M during a move is not off position, so the deviation is measured from y_M. The
    default MRAC's y_M is η_d itself (one reference)."""
    controller = DpController(bench_config({"kind": "mrac", "reference": y_m}))
    controller.estimator.reset(np.zeros(3))
    controller._estimator_ready = True
    controller.mode = Mode.AUTO_POSITION
    controller.reference_model.reset(np.zeros(3))
    controller.setpoint_ned[:] = (20.0, 0.0, 0.0)
    controller.out.estimate = controller.estimator.step(np.zeros(3), np.zeros(3))  # held at the origin
    for k in range(300):
        controller._control_stage(0.1 * k, 0.1)
        controller._supervision_stage(0.1 * k)
    mrac, reference = controller.out.mrac, controller.out.reference
    assert mrac is not None and reference is not None
    estimate = controller.out.estimate.eta_hat_ned
    from_model = math.hypot(estimate[0] - mrac["ref_model_north_m"], estimate[1] - mrac["ref_model_east_m"])
    from_guidance = math.hypot(*(estimate[:2] - reference.eta_d_ned[:2]))
    if y_m == "model":
        assert from_guidance - from_model > 1.0  # y_M trails η_d in the move
    else:
        assert from_guidance == pytest.approx(from_model, abs=1e-9) and from_guidance > 1.0
    assert controller.deviation.position_m == pytest.approx(from_model, abs=1e-9)
