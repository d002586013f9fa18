"""The gyros against an independent rate-of-turn sensor (dpcontrol/runtime/hub.py, "Rate check"): a drifting gyro
rejected and the heading dead-reckoned on the rate, a rate that is off not rejecting a good gyro, no false alarm
from a noisy, biased rate over long runs, and the rate's bias never learning the drift."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dpbase.frames import ssa
from dpcontrol.runtime.alarms import AlarmRegistry
from dpcontrol.runtime.hub import HubConfig, HubOutput, SensorConfig, SensorHub, SensorKind, SensorState
from interfaces.messages import Heading, Measurement, RateOfTurn

DT = 0.1
GYRO_SIGMA = math.radians(0.05)
ROT_SIGMA = math.radians(0.01)
ROT_BIAS = math.radians(0.03)
DRIFT = math.radians(0.2)  # the plant's gyro_drift / rot_offset rate [rad/s]
PSI0 = math.radians(30.0)
CODE = "heading.rate_disagreement"


def _truth(t: float) -> tuple[float, float]:
    """Heading [rad] and yaw rate [rad/s] at ``t`` [s]: a vessel holding heading in DP (0.3° of slow yaw, as the
    supply vessel's in the fail-safe runs) and the wave-frequency motion."""
    psi = PSI0 + math.radians(0.3) * math.sin(0.02 * t) + math.radians(0.3) * math.sin(0.8 * t)
    rate = math.radians(0.3) * 0.02 * math.cos(0.02 * t) + math.radians(0.3) * 0.8 * math.cos(0.8 * t)
    return psi, rate


class Run:
    """A hub fed one or two gyros (with their own ROT) and a rate sensor; the estimator's prediction is the truth
    with the gyro's variance. ``drift`` [(t0, gyro name)] make a gyro drift at 0.2°/s from t0 (until ``drift_end``,
    when it steps back, as the plant's does); ``rot_offset`` likewise adds 0.2°/s to the rate sensor."""

    def __init__(self, *, gyros: int = 1, seed: int = 3, bias_walk_radps2: float = 0.0) -> None:
        self.gyros = [f"gyro{i + 1}" for i in range(gyros)]
        sensors = [SensorConfig(name, SensorKind.HEADING, 10.0, GYRO_SIGMA) for name in self.gyros]
        sensors.append(SensorConfig("rot1", SensorKind.RATE, 10.0, ROT_SIGMA))
        self.alarms = AlarmRegistry()
        self.hub = SensorHub(sensors, HubConfig(), self.alarms)
        self.rng = np.random.default_rng(seed)
        self.t = 0.0
        self.drift: dict[str, tuple[float, float]] = {}  # gyro → (start, end) [s]
        self.rot_offset: tuple[float, float] | None = None
        self.bias_walk = bias_walk_radps2  # the rate sensor's bias changes at this rate [rad/s²]

    def _gyro_error(self, name: str) -> float:
        window = self.drift.get(name)
        if window is None or not window[0] <= self.t < window[1]:
            return 0.0
        return DRIFT * (self.t - window[0])

    def step(self, n: int = 1) -> HubOutput:
        out = None
        for _ in range(n):
            self.t += DT
            psi, rate = _truth(self.t)
            noise = self.rng.standard_normal(2 * len(self.gyros) + 1)
            measurements = []
            for i, name in enumerate(self.gyros):
                error = self._gyro_error(name)
                heading = psi + error + GYRO_SIGMA * noise[2 * i]
                own_rate = rate + (DRIFT if error else 0.0) + math.radians(0.02) * noise[2 * i + 1]
                measurements += [Measurement(self.t, name, Heading(heading % (2 * math.pi))),
                                 Measurement(self.t, name, RateOfTurn(own_rate))]
            value = rate + ROT_BIAS + self.bias_walk * self.t + ROT_SIGMA * noise[-1]
            if self.rot_offset is not None and self.rot_offset[0] <= self.t < self.rot_offset[1]:
                value += DRIFT
            measurements.append(Measurement(self.t, "rot1", RateOfTurn(value)))
            out = self.hub.update(self.t, measurements, [0.0, 0.0, psi], [1.0, 1.0, GYRO_SIGMA ** 2])
        assert out is not None
        return out

    def rot_state(self) -> str:
        return next(row["state"] for row in self.hub.sensor_status(self.t) if row["name"] == "rot1")


def _until(run: Run, condition, limit_s: float) -> float:  # type: ignore[no-untyped-def]
    """Step until ``condition(out)``; the time it took [s] (inf: not within ``limit_s``)."""
    start = run.t
    while run.t - start < limit_s:
        if condition(run.step()):
            return run.t - start
    return math.inf


def test_a_drifting_lone_gyro_is_rejected_and_the_heading_dead_reckoned_on_the_rate() -> None:
    run = Run()
    run.step(1800)  # 180 s: the rate's bias learnt and checked
    bias_before = run.hub.rate_bias("rot1")
    assert abs(math.degrees(bias_before - ROT_BIAS)) < 0.004
    run.drift["gyro1"] = (run.t, run.t + 60.0)
    # D = 0.2°/s · t crosses the 1° floor of the limit after 5 s
    took = _until(run, lambda out: run.alarms.is_active(CODE), 20.0)
    assert 4.0 <= took <= 6.5, took
    assert run.hub.state_of("gyro1") is SensorState.REJECTED
    texts = {a.code: a.text for a in run.alarms.active()}
    assert "disagrees with rate of turn" in texts[CODE] and "gyro1 rejected" in texts[CODE], texts
    assert run.alarms.is_active("sensor.gyro1.rejected")
    out = run.step()
    assert not out.heading_available and out.heading_rate_source == "rot1" and out.measured[2]
    # dead-reckoned from where the rate says the heading is (the drift since the window's start removed), not from
    # the drifted gyro: within 0.2° of the truth through the rest of the drift, where the gyro goes 12° off
    worst = 0.0
    for _ in range(540):
        out = run.step()
        assert not out.heading_available
        worst = max(worst, abs(ssa(run.hub._dr_heading - _truth(run.t)[0])))  # type: ignore[operator]
    assert math.degrees(worst) < 0.2, math.degrees(worst)
    assert not run.alarms.is_active("heading.reference_rejected")  # (the rate check's, not the prediction test's)
    # the drift ends (the gyro steps back to the truth): taken back once the window agrees again (30 s + 10 s)
    back = _until(run, lambda out: out.heading_available, 60.0)
    assert 38.0 <= back <= 45.0, back
    assert not run.alarms.is_active(CODE) and run.hub.state_of("gyro1") is SensorState.OK
    # the bias never learnt the drift
    assert abs(math.degrees(run.hub.rate_bias("rot1") - bias_before)) < 0.002


def test_a_rate_sensor_that_is_off_never_rejects_a_good_gyro() -> None:
    """The plant's rot_offset (0.2°/s for 60 s): the disagreement is in the rate's integral, the gyro's heading is
    held: the rate is blamed (not dead-reckoned on), the gyro stays in use, and the rate comes back after."""
    run = Run()
    run.step(1800)
    bias_before = run.hub.rate_bias("rot1")
    run.rot_offset = (run.t, run.t + 60.0)
    took = _until(run, lambda out: run.alarms.is_active(CODE), 20.0)
    assert took < 7.0
    assert run.rot_state() == SensorState.REJECTED.value and run.alarms.is_active("sensor.rot1.rejected")
    for _ in range(1000):
        out = run.step()
        assert out.heading_available and run.hub.state_of("gyro1") is SensorState.OK
    assert not run.alarms.is_active(CODE) and run.rot_state() == SensorState.OK.value
    assert abs(math.degrees(run.hub.rate_bias("rot1") - bias_before)) < 0.002
    # and with the gyro then lost, the heading is dead-reckoned on the rate again, with its bias as before the fault
    run.gyros = []  # (the gyro silent from here)
    out = run.step(20)
    assert not out.heading_available and out.heading_rate_source == "rot1"


@pytest.mark.parametrize("seed", [1, 2, 3, 4, 5])
def test_no_false_alarm_with_a_good_gyro_and_a_noisy_biased_rate(seed: int) -> None:
    """30 min per seed, the rate's bias wandering 0.01°/s over the run (its bias instability): never rejected."""
    run = Run(seed=seed, bias_walk_radps2=math.radians(0.01) / 1800.0)
    worst = 0.0
    for _ in range(18000):
        out = run.step()
        assert not run.alarms.is_active(CODE), run.alarms.active()
        check = run.hub._tracks["gyro1"].check
        assert check is not None
        if check.count > 1 and math.isfinite(check.limit):
            worst = max(worst, abs(check.disagreement) / check.limit)
    assert out.heading_available and run.hub.state_of("gyro1") is SensorState.OK and run.rot_state() == "ok"
    assert 0.0 < worst < 0.5, worst  # (the largest disagreement at most half the limit)


def test_with_two_gyros_the_one_that_drifts_is_rejected_and_the_other_used() -> None:
    run = Run(gyros=2)
    run.step(1800)
    run.drift["gyro2"] = (run.t, run.t + 60.0)
    took = _until(run, lambda out: run.alarms.is_active(CODE), 20.0)
    assert took < 7.0
    assert run.hub.state_of("gyro2") is SensorState.REJECTED and run.hub.state_of("gyro1") is SensorState.OK
    out = run.step(100)
    assert out.heading_available and run.hub.weight_of("gyro1") == 1.0
    assert abs(math.degrees(ssa(out.y_ned[2] - _truth(run.t)[0]))) < 0.5


def test_a_blamed_rate_does_not_carry_the_heading_when_the_gyro_is_lost() -> None:
    """The rate is off (blamed by the check) when the lone gyro goes silent: the heading is dead-reckoned on the
    model, not integrated from a rate known to be wrong."""
    run = Run()
    run.step(1800)
    run.rot_offset = (run.t, run.t + 120.0)
    _until(run, lambda out: run.alarms.is_active(CODE), 20.0)
    assert run.rot_state() == SensorState.REJECTED.value
    run.gyros = []
    out = run.step(20)
    assert not out.heading_available and out.heading_rate_source is None


def test_in_a_turn_larger_than_the_disagreement_neither_is_rejected() -> None:
    """A lone gyro and a rate sensor with a 5 % scale error: in a 30° turn at 1°/s they disagree by 1.5° (beyond
    the 1° limit) and the turn is in both, so the share of the gyro's heading change says nothing: neither is
    rejected, and the alarm says the check cannot tell."""
    sensors = [SensorConfig("gyro1", SensorKind.HEADING, 10.0, GYRO_SIGMA),
               SensorConfig("rot1", SensorKind.RATE, 10.0, ROT_SIGMA)]
    alarms = AlarmRegistry()
    hub = SensorHub(sensors, HubConfig(), alarms)
    rng = np.random.default_rng(5)
    turn = (200.0, 230.0, math.radians(1.0))
    for k in range(1, 2801):
        t = k * DT
        psi, rate = _truth(t)
        psi += turn[2] * min(max(t - turn[0], 0.0), turn[1] - turn[0])
        rate += turn[2] if turn[0] <= t < turn[1] else 0.0
        noise = rng.standard_normal(2)
        measurements = [Measurement(t, "gyro1", Heading((psi + GYRO_SIGMA * noise[0]) % (2 * math.pi))),
                        Measurement(t, "rot1", RateOfTurn(1.05 * rate + ROT_BIAS + ROT_SIGMA * noise[1]))]
        out = hub.update(t, measurements, [0.0, 0.0, psi], [1.0, 1.0, GYRO_SIGMA ** 2])
        assert out.heading_available and hub.state_of("gyro1") is SensorState.OK
        rot = next(row["state"] for row in hub.sensor_status(t) if row["name"] == "rot1")
        assert rot == SensorState.OK.value
    events = [e for e in alarms.drain_events() if e.code == CODE and e.raised]
    assert events and "cannot tell" in events[0].text and "neither rejected" in events[0].text
