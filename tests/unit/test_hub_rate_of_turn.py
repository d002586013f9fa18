"""Heading dead reckoning on the rate of turn (dpcontrol/runtime/hub.py): the bias estimate, the variance growth,
and no effect without a valid rate of turn."""

from __future__ import annotations

import itertools
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
PSI0 = math.radians(30.0)
AMPLITUDE = math.radians(2.0)  # the vessel yaws 2° at 0.05 rad/s plus the wave-frequency motion
OMEGA = 0.05


def _truth(t: float) -> tuple[float, float]:
    """Heading [rad] and yaw rate [rad/s] at ``t`` [s]."""
    psi = PSI0 + AMPLITUDE * math.sin(OMEGA * t) + math.radians(0.3) * math.sin(0.8 * t)
    rate = AMPLITUDE * OMEGA * math.cos(OMEGA * t) + math.radians(0.3) * 0.8 * math.cos(0.8 * t)
    return psi, rate


class Run:
    """A hub fed a gyro (heading, optionally its own ROT) and optionally a rate sensor; the estimator's prediction
    is the truth with the gyro's variance (a well-tuned filter)."""

    def __init__(self, *, rot_sensor: bool = True, gyro_rot: bool = True, seed: int = 3) -> None:
        sensors = [SensorConfig("gyro1", SensorKind.HEADING, 10.0, GYRO_SIGMA)]
        if rot_sensor:
            sensors.append(SensorConfig("rot1", SensorKind.RATE, 10.0, ROT_SIGMA))
        self.alarms = AlarmRegistry()
        self.hub = SensorHub(sensors, HubConfig(), self.alarms)
        self.rot_sensor = rot_sensor
        self.gyro_rot = gyro_rot
        self.rng = np.random.default_rng(seed)
        self.t = 0.0
        self.gyro_frozen: tuple[float, float] | None = None  # (heading, rate) repeated
        self.gyro_silent = False
        self.rot_frozen: float | None = None
        self.rot_value: float | None = None  # a fixed value sent instead (out of range ...)

    def step(self, n: int = 1) -> HubOutput:
        out = None
        for _ in range(n):
            self.t += DT
            psi, rate = _truth(self.t)
            w_h, w_r, w_s = self.rng.standard_normal(3)
            heading = psi + GYRO_SIGMA * w_h
            gyro_rate = rate + math.radians(0.02) * w_r
            if self.gyro_frozen is not None:
                heading, gyro_rate = self.gyro_frozen
            measurements = []
            if not self.gyro_silent:
                measurements.append(Measurement(self.t, "gyro1", Heading(heading % (2 * math.pi))))
                if self.gyro_rot:
                    measurements.append(Measurement(self.t, "gyro1", RateOfTurn(gyro_rate)))
            if self.rot_sensor:
                value = rate + ROT_BIAS + ROT_SIGMA * w_s
                if self.rot_frozen is not None:
                    value = self.rot_frozen
                if self.rot_value is not None:
                    value = self.rot_value
                measurements.append(Measurement(self.t, "rot1", RateOfTurn(value)))
            out = self.hub.update(self.t, measurements, [0.0, 0.0, psi], [1.0, 1.0, GYRO_SIGMA ** 2])
        assert out is not None
        return out

    def freeze_gyro(self) -> None:
        psi, rate = _truth(self.t)
        self.gyro_frozen = (psi % (2 * math.pi), rate)


def test_the_rate_sensors_bias_is_learnt_against_the_gyro() -> None:
    run = Run()
    run.step(1200)  # 120 s: two bias windows
    bias = run.hub.rate_bias("rot1")
    # error ≈ σ_ψ/window + σ_r·√(T_s/window) ≈ 0.001 °/s
    assert abs(math.degrees(bias - ROT_BIAS)) < 0.004, math.degrees(bias)
    assert abs(math.degrees(run.hub.rate_bias("gyro1 rate of turn"))) < 0.004  # (the gyro's own ROT: no bias)
    status = {row["name"]: row for row in run.hub.sensor_status(run.t)}
    assert status["rot1"]["kind"] == "rate_of_turn" and status["rot1"]["state"] == "ok"
    assert "bias 0.03" in status["rot1"]["detail"]


def test_with_the_gyro_lost_the_heading_is_integrated_from_the_rate_with_a_growing_variance() -> None:
    run = Run()
    run.step(1200)
    run.gyro_silent = True
    sigmas = []
    errors = []
    for _ in range(400):  # 40 s
        out = run.step()
        if not out.heading_available:
            assert out.measured[2] and out.heading_rate_source == "rot1"
            sigmas.append(out.heading_dr_sigma_rad)
            errors.append(ssa(run.hub._dr_heading - _truth(run.t)[0]))  # type: ignore[operator]
    assert len(sigmas) > 390
    assert all(b >= a for a, b in itertools.pairwise(sigmas))  # grows monotonically
    assert sigmas[-1] > 1.2 * sigmas[0]
    # the dead-reckoned heading within 3σ of the truth after 40 s (without the bias: 1.2° off)
    assert abs(errors[-1]) < 3.0 * sigmas[-1] and abs(math.degrees(errors[-1])) < 0.2
    # the prediction test's variance grows with it, not with the model's drift (0.02°/s → 0.8° after 40 s)
    grown = run.hub._dead_reckoning_variance(run.t, [1.0, 1.0, 0.0])[2]
    assert grown == pytest.approx(sigmas[-1] ** 2, rel=0.05)
    assert math.sqrt(grown) < math.radians(0.8) / 2
    # the alarm-side: the gyro returns and is used again, the rate no longer fed
    run.gyro_silent = False
    out = run.step(20)
    assert out.heading_available and out.heading_rate_source is None and out.heading_dr_sigma_rad == 0.0


def test_a_frozen_or_out_of_range_rate_is_not_used() -> None:
    run = Run()
    run.step(1200)
    run.rot_frozen = 0.001
    run.step(15)  # 1.5 s > rot_freeze_s: frozen
    assert run.hub.sensor_status(run.t)[1]["state"] == SensorState.FROZEN.value
    assert run.alarms.is_active("sensor.rot1.frozen")
    run.gyro_silent = True
    out = run.step(20)
    assert not out.heading_available and not out.measured[2] and out.heading_rate_source is None  # (gyro silent)
    run.rot_frozen = None
    run.rot_value = math.radians(45.0)  # beyond rot_max (30°/s)
    run.gyro_rot = False
    out = run.step(20)
    assert out.heading_rate_source is None and not out.measured[2]
    assert run.hub._rate_sensors["rot1"].rejected_samples >= 20


def test_without_a_valid_rate_of_turn_nothing_changes() -> None:
    """A gyro whose own ROT freezes with its heading (the plant's fault model) gives the estimator exactly what
    a gyro without ROT gives: the model carries the heading."""
    with_rot, without = Run(rot_sensor=False, gyro_rot=True), Run(rot_sensor=False, gyro_rot=False)
    outputs = []
    for run in (with_rot, without):
        run.step(1200)
        run.freeze_gyro()
        trace = []
        for _ in range(500):
            out = run.step()
            trace.append((tuple(out.y_ned), out.measured, out.heading_available, out.heading_rate_source))
        run.gyro_frozen = None
        for _ in range(300):
            out = run.step()
            trace.append((tuple(out.y_ned), out.measured, out.heading_available, out.heading_rate_source))
        outputs.append(trace)
    assert outputs[0] == outputs[1]
    assert any(not available for _, _, available, _ in outputs[0])  # (the heading was lost)
    assert all(source is None for *_, source in outputs[0])


def test_the_gyros_own_rate_carries_the_heading_while_the_gyro_is_rejected() -> None:
    """A heading sensor's own ROT that is still valid (a lone gyro jumping: its heading rejected, its rate fine)."""
    run = Run(rot_sensor=False)
    run.step(1200)
    original = _truth
    offset = math.radians(10.0)
    out = None
    for _ in range(50):
        run.t += DT
        psi, rate = original(run.t)
        measurements = [Measurement(run.t, "gyro1", Heading((psi + offset) % (2 * math.pi))),
                        Measurement(run.t, "gyro1", RateOfTurn(rate))]
        out = run.hub.update(run.t, measurements, [0.0, 0.0, psi], [1.0, 1.0, GYRO_SIGMA ** 2])
    assert out is not None and not out.heading_available
    assert out.heading_rate_source == "gyro1 rate of turn" and out.measured[2]
    assert abs(math.degrees(ssa(out.y_ned[2] - original(run.t)[0]))) < 0.2
