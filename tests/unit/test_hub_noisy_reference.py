"""A lone position reference whose noise grows: de-weighted while noisy, taken back when the noise ends
(dpcontrol/runtime/hub.py, "Noisy position references")."""

from __future__ import annotations

import math

import numpy as np

from dpbase.geodesy import LocalFrame
from dpcontrol.runtime.alarms import AlarmRegistry
from dpcontrol.runtime.hub import HubConfig, SensorConfig, SensorHub, SensorKind
from interfaces.messages import FixQuality, Heading, Measurement, PositionErrorStats, PositionFix

DATUM = LocalFrame(63.43, 10.39)
DT = 0.1  # the receiver's and the hub's period [s]
SIGMA_M = 0.5  # the receiver's configured (and healthy) noise [m]
CODE = "position.noisy_reference"


class LoneReceiver:
    """One GNSS (10 Hz, 0.5 m) and one gyro around a vessel at rest at the origin; the estimator's prediction is
    ``prediction`` with innovation variance 0.3 m² (a steady-state filter's)."""

    def __init__(self, seed: int = 1, prediction: tuple[float, float] = (0.0, 0.0), **overrides: float) -> None:
        sensors = [SensorConfig("gnss1", SensorKind.POSITION, 10.0, SIGMA_M),
                   SensorConfig("gyro1", SensorKind.HEADING, 10.0, math.radians(0.2))]
        self.alarms = AlarmRegistry()
        self.hub = SensorHub(sensors, HubConfig(**overrides), self.alarms, DATUM)
        self.rng = np.random.default_rng(seed)
        self.prediction = prediction
        self.t = 0.0
        self.noise_m = SIGMA_M
        self.gst_m: float | None = None
        self.t_s: list[float] = []
        self.weight: list[float] = []
        self.north: list[float] = []
        self.raised: list[bool] = []

    def run(self, seconds: float) -> None:
        for _ in range(round(seconds / DT)):
            self.t += DT
            north, east = self.noise_m * self.rng.standard_normal(2)
            lat, lon = DATUM.surface_to_geodetic(north, east)
            heading = Heading(math.radians(30.0) + 0.003 * self.rng.standard_normal())
            measurements = [Measurement(self.t, "gnss1", PositionFix(lat, lon, FixQuality.DGPS)),
                            Measurement(self.t, "gyro1", heading)]
            if self.gst_m is not None:
                measurements.append(Measurement(self.t, "gnss1", PositionErrorStats(self.gst_m, self.gst_m)))
            out = self.hub.update(self.t, measurements, [*self.prediction, math.radians(30.0)], [0.3, 0.3, 1e-5])
            self.t_s.append(self.t)
            self.weight.append(out.position_noise_weight)
            self.north.append(out.y_ned[0])
            self.raised.append(self.alarms.is_active(CODE))

    def episode(self, quiet_s: float, factor: float, noisy_s: float, after_s: float) -> None:
        """``quiet_s`` of the configured noise, ``noisy_s`` of ``factor`` times it, ``after_s`` of it again [s]."""
        self.run(quiet_s)
        self.noise_m = factor * SIGMA_M
        self.run(noisy_s)
        self.noise_m = SIGMA_M
        self.run(after_s)

    def between(self, t0_s: float, t1_s: float) -> np.ndarray:
        t = np.array(self.t_s)
        return (t > t0_s + 1e-9) & (t <= t1_s + 1e-9)


def test_a_lone_receiver_ten_times_noisier_is_de_weighted_and_taken_back_within_two_and_a_half_seconds() -> None:
    scene = LoneReceiver()
    scene.episode(30.0, 10.0, 60.0, 30.0)
    weight = np.array(scene.weight)
    north = np.array(scene.north)
    raised = np.array(scene.raised)
    assert np.all(weight[scene.between(0.0, 30.0)] == 1.0)
    assert not raised[scene.between(0.0, 30.0)].any()
    noisy = scene.between(32.5, 90.0)  # from the window's half (1.5 s) on, with margin
    assert np.all(weight[noisy] < 0.1)
    assert raised[noisy].all()
    # the estimator is fed the prediction's neighbourhood, not the receiver's 5 m scatter
    assert np.std(north[noisy]) < 0.5
    # whole again within 2.5 s of the noise's end (half of the 3 s window, and a noisy sample is in three second
    # differences), the alarm cleared
    assert np.all(weight[scene.between(92.5, 120.0)] == 1.0)
    assert not raised[scene.between(92.5, 120.0)].any()
    event = next(e for e in scene.alarms.drain_events() if e.code == CODE and e.raised)
    assert "gnss1" in event.text


def test_other_noise_factors_are_de_weighted_in_proportion() -> None:
    weights = {}
    for factor in (5.0, 20.0):
        scene = LoneReceiver(seed=2)
        scene.episode(20.0, factor, 30.0, 10.0)
        weight = np.array(scene.weight)
        weights[factor] = float(np.median(weight[scene.between(25.0, 50.0)]))
        assert np.all(weight[scene.between(52.5, 60.0)] == 1.0)
    # S/(S + ΔR), ΔR = (factor² − 3²)·σ² over S = 0.3 m² plus the prediction's growth while de-weighted
    assert 0.03 < weights[5.0] < 0.3
    assert weights[20.0] < 0.02


def test_a_receiver_that_says_it_is_noisy_is_de_weighted_at_its_first_sample() -> None:
    scene = LoneReceiver()
    scene.run(20.0)
    scene.noise_m = scene.gst_m = 10.0 * SIGMA_M
    scene.run(5.0)
    assert np.all(np.array(scene.weight)[scene.between(20.0, 25.0)] < 0.1)


def test_healthy_lone_receivers_are_never_de_weighted() -> None:
    for seed in (1, 2, 3):
        scene = LoneReceiver(seed=seed)
        scene.gst_m = SIGMA_M
        scene.run(600.0)
        assert min(scene.weight) == 1.0
        assert not any(scene.raised)


def test_taken_back_from_the_prediction_then_faded() -> None:
    # the estimate dead-reckoned 2 m off while de-weighted: back from there, not in a step to the receiver
    scene = LoneReceiver(prediction=(2.0, 0.0))
    scene.episode(20.0, 10.0, 30.0, 60.0)
    north = np.array(scene.north)
    back = next(t for t, w in zip(scene.t_s, scene.weight, strict=True) if t > 50.0 and w == 1.0)
    assert abs(np.mean(north[scene.between(back, back + 3.0)]) - 2.0) < 0.3
    assert abs(np.mean(north[scene.between(back + 80.0 - 30.0, 110.0)]) - 0.0) < 0.3
