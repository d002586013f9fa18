"""Each GNSS position against the receiver's own velocity (SOG/COG; dpcontrol/runtime/hub.py, "Velocity check"): a
slowly drifting position rejected and the position dead-reckoned on the velocity; a healthy receiver never rejected
in waves, set-point moves, turns with a lever arm and at rest (COG meaningless); no velocity, no check."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dpbase.geodesy import LocalFrame, lever_arm_ned
from dpcontrol.runtime.alarms import AlarmRegistry
from dpcontrol.runtime.hub import HubConfig, HubOutput, SensorConfig, SensorHub, SensorKind, SensorState
from interfaces.messages import CourseOverGround, FixQuality, Heading, Measurement, PositionFix

DATUM = LocalFrame(60.35, 2.75)
DT = 0.1  # control period [s]
GNSS_SIGMA = 0.3  # the supply vessel's receiver [m]
VELOCITY_SIGMA = 0.02  # its Doppler velocity [m/s]
CODE = "position.velocity_disagreement"


class Vessel:
    """A vessel's true motion: ``moves`` [(t0, t1, v_north, v_east)] of the control origin at constant velocity,
    ``turns`` [(t0, t1, rate)] [rad/s], on top the wave-frequency motion (``wave_m`` amplitude at 0.8 and 0.55
    rad/s) and 0.3° of wave yaw. Returns the control origin's position, heading and NED velocity, yaw rate."""

    def __init__(self, *, wave_m: float = 1.0, moves=(), turns=()) -> None:
        self.wave_m = wave_m
        self.moves = moves
        self.turns = turns

    def at(self, t: float) -> tuple[float, float, float, float, float, float]:
        north = east = v_north = v_east = 0.0
        for t0, t1, mn, me in self.moves:
            span = min(max(t - t0, 0.0), t1 - t0)
            north += mn * span
            east += me * span
            if t0 <= t < t1:
                v_north += mn
                v_east += me
        psi = 0.5
        r = 0.0
        for t0, t1, rate in self.turns:
            psi += rate * min(max(t - t0, 0.0), t1 - t0)
            if t0 <= t < t1:
                r += rate
        a = self.wave_m
        north += a * math.sin(0.8 * t) + 0.6 * a * math.sin(0.55 * t + 1.0)
        east += 0.7 * a * math.cos(0.8 * t + 0.3) + 0.5 * a * math.sin(0.55 * t)
        v_north += a * 0.8 * math.cos(0.8 * t) + 0.6 * a * 0.55 * math.cos(0.55 * t + 1.0)
        v_east += -0.7 * a * 0.8 * math.sin(0.8 * t + 0.3) + 0.5 * a * 0.55 * math.cos(0.55 * t)
        psi += math.radians(0.3) * math.sin(0.8 * t)
        r += math.radians(0.3) * 0.8 * math.cos(0.8 * t)
        return north, east, psi, v_north, v_east, r


class Run:
    """A hub fed one GNSS (5 Hz, with SOG/COG unless ``velocity`` is off) with an antenna lever arm and one gyro
    (10 Hz); the estimator's prediction is the truth. ``drift`` (t0, t1, rate [m/s]) moves the reported position at
    45°, as the plant's gnss_drift (back at once at t1)."""

    def __init__(self, vessel: Vessel, *, seed: int = 1, lever_arm=(30.0, 5.0), velocity: bool = True,
                 drift: tuple[float, float, float] | None = None, freeze: tuple[float, float] | None = None,
                 **hub: float) -> None:
        sensors = [SensorConfig("gnss1", SensorKind.POSITION, 5.0, GNSS_SIGMA, lever_arm, VELOCITY_SIGMA),
                   SensorConfig("gyro1", SensorKind.HEADING, 10.0, math.radians(0.05))]
        self.alarms = AlarmRegistry()
        self.hub = SensorHub(sensors, HubConfig(**hub), self.alarms, DATUM)
        self.vessel = vessel
        self.lever_arm = lever_arm
        self.velocity = velocity
        self.drift = drift
        self.freeze = freeze  # (t0, t1): the receiver repeats its last position and velocity, as the plant's freeze
        self._last_gnss: list[Measurement] = []
        self.rng = np.random.default_rng(seed)
        self.t = 0.0
        self.k = 0
        self.rejected_at: float | None = None
        self.max_ratio = 0.0  # largest |D| / limit while accepted
        self.out: HubOutput | None = None

    def error(self, t: float) -> tuple[float, float]:
        if self.drift is None or not self.drift[0] <= t < self.drift[1]:
            return 0.0, 0.0
        grown = self.drift[2] * (t - self.drift[0])
        return grown * math.cos(math.pi / 4), grown * math.sin(math.pi / 4)

    def step(self, seconds: float) -> HubOutput:
        for _ in range(round(seconds / DT)):
            self.k += 1
            t = self.t = self.k * DT
            north, east, psi, v_north, v_east, r = self.vessel.at(t)
            measurements = [Measurement(t, "gyro1", Heading((psi + math.radians(0.05) * self.rng.standard_normal())
                                                            % (2 * math.pi)))]
            if self.k % 2 == 0 and self.freeze is not None and self.freeze[0] <= t < self.freeze[1]:
                measurements += [Measurement(t, m.source, m.message) for m in self._last_gnss]
            elif self.k % 2 == 0:  # 5 Hz
                arm_north, arm_east = lever_arm_ned(*self.lever_arm, psi)
                noise = self.rng.standard_normal(4)
                e_north, e_east = self.error(t)
                lat, lon = DATUM.surface_to_geodetic(north + arm_north + e_north + GNSS_SIGMA * noise[0],
                                                     east + arm_east + e_east + GNSS_SIGMA * noise[1])
                measurements.append(Measurement(t, "gnss1", PositionFix(lat, lon, FixQuality.DGPS)))
                if self.velocity:  # the antenna's: v + r × lever arm (body y starboard: r·(−y, x) in body axes)
                    x, y = self.lever_arm
                    a_north, a_east = lever_arm_ned(-r * y, r * x, psi)
                    vn = v_north + a_north + VELOCITY_SIGMA * noise[2]
                    ve = v_east + a_east + VELOCITY_SIGMA * noise[3]
                    measurements.append(Measurement(t, "gnss1", CourseOverGround(math.atan2(ve, vn) % (2 * math.pi),
                                                                                 math.hypot(vn, ve))))
                self._last_gnss = measurements[1:]
            self.out = self.hub.update(t, measurements, [north, east, psi], [0.25, 0.25, 1e-6])
            check = self.hub._tracks["gnss1"].velocity  # (the statistic is what is tested)
            assert check is not None
            if check.rejected:
                if self.rejected_at is None:
                    self.rejected_at = t
            elif check.count > 1 and math.isfinite(check.limit):
                self.max_ratio = max(self.max_ratio, math.hypot(*check.disagreement) / check.limit)
        assert self.out is not None
        return self.out


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_healthy_receiver_in_waves_moves_and_turns_is_never_rejected(seed: int) -> None:
    """Waves (1 m), a 20 m set-point move at 0.5 m/s, a 30° turn at 1°/s with a 30 m × 5 m lever arm, station
    keeping in between: 20 min, never rejected, the disagreement below 0.7 of the limit (the 1 m floor is ~9σ)."""
    vessel = Vessel(moves=[(200.0, 240.0, 0.35, 0.35), (600.0, 650.0, -0.2, 0.1)],
                    turns=[(400.0, 430.0, math.radians(1.0)), (800.0, 830.0, -math.radians(1.0))])
    run = Run(vessel, seed=seed)
    run.step(1200.0)
    assert run.rejected_at is None
    assert not run.alarms.is_active(CODE)
    assert run.hub.state_of("gnss1") is SensorState.OK
    assert run.max_ratio < 0.7


def test_healthy_receiver_at_rest_where_the_course_is_noise() -> None:
    """No waves, no motion: SOG is the noise (≈ 0.03 m/s), COG uniformly random — the velocity vector is still
    right, so nothing accumulates: never rejected."""
    run = Run(Vessel(wave_m=0.0), seed=4, lever_arm=(0.0, 0.0))
    run.step(900.0)
    assert run.rejected_at is None and run.max_ratio < 0.7


def test_slow_drift_is_rejected_and_the_position_dead_reckoned_on_the_velocity() -> None:
    """0.1 m/s from 300 s for 80 s (8 m, the prediction test's 4 m floor would follow half of it): rejected once the
    disagreement passes the 1 m floor, the alarm names the receiver; the position fed to the estimator is the
    velocity's, within a metre of the truth throughout; back to the true position at the drift's end, the receiver
    is taken back and the alarm clears."""
    run = Run(Vessel(moves=[(320.0, 340.0, 0.2, 0.0)]), drift=(300.0, 380.0, 0.1))
    run.step(299.0)
    assert run.rejected_at is None
    worst = 0.0
    while run.t < 380.0:
        out = run.step(1.0)
        if run.rejected_at is not None:
            north, east, *_ = run.vessel.at(run.t)
            worst = max(worst, math.hypot(out.y_ned[0] - north, out.y_ned[1] - east))
            assert out.position_velocity_source == "gnss1" and not out.position_available
    assert run.rejected_at is not None and run.rejected_at - 300.0 < 1.0 / 0.1 + 5.0
    assert worst < 1.0
    active = {a.code: a for a in run.alarms.active()}
    assert CODE in active and "gnss1" in active[CODE].text
    assert run.hub.state_of("gnss1") is SensorState.REJECTED
    run.step(15.0)  # the drift ended at 380 s: back at its level
    assert run.hub.state_of("gnss1") is SensorState.OK
    assert not run.alarms.is_active(CODE) and run.out is not None and run.out.position_velocity_source is None


def test_no_velocity_no_check() -> None:
    """A receiver that sends no SOG/COG: the check is off — the same drift is not seen by it (the prediction test
    is then all there is)."""
    run = Run(Vessel(), velocity=False, drift=(300.0, 380.0, 0.1))
    run.step(340.0)
    assert run.rejected_at is None and not run.alarms.is_active(CODE)
    check = run.hub._tracks["gnss1"].velocity
    assert check is not None and check.velocity_t_s is None and check.count == 0


def test_velocity_lost_while_rejected_ends_the_verdict() -> None:
    """The velocity stops while the receiver is rejected: nothing to compare with, the verdict ends (the position
    faces the other tests alone)."""
    run = Run(Vessel(), drift=(300.0, 1000.0, 0.1))
    run.step(320.0)
    assert run.alarms.is_active(CODE)
    run.velocity = False
    run.step(3.0)
    assert not run.alarms.is_active(CODE)
    assert not run.hub._tracks["gnss1"].velocity.rejected


def test_operator_accepts_the_rejected_receiver() -> None:
    run = Run(Vessel(), drift=(300.0, 1000.0, 0.1))
    run.step(320.0)
    assert run.alarms.is_active(CODE)
    assert run.hub.accept_reference("gnss1")
    run.step(0.2)
    assert not run.alarms.is_active(CODE)


def test_a_frozen_receiver_is_the_freeze_tests_not_a_velocity_disagreement() -> None:
    """A receiver that freezes during a move repeats its position *and* its velocity: the velocity's integral grows
    while the position stands. The freeze test rejects it; the velocity check restarts and says nothing, and the
    receiver is back when it reports again."""
    vessel = Vessel(wave_m=0.3, moves=[(100.0, 200.0, 0.4, 0.2)])
    run = Run(vessel, freeze=(120.0, 150.0))
    run.step(145.0)
    assert run.hub.state_of("gnss1") is SensorState.FROZEN
    run.step(60.0)
    assert run.rejected_at is None and not run.alarms.is_active(CODE)
    assert run.hub.state_of("gnss1") is SensorState.OK and run.out is not None and run.out.position_available
