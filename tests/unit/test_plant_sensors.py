"""Sensor models (sim_plant.sensors): noise statistics, lever arm, faults, timing, messages."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dpbase.geodesy import LocalFrame
from interfaces.messages import CourseOverGround, FixQuality, Heading, PositionErrorStats, PositionFix, RateOfTurn
from sim_plant.faults import Fault
from sim_plant.sensors import GnssSensor, GnssSpec, GyroSensor, GyroSpec, InvalidFix

FRAME = LocalFrame(63.4305, 10.3951)


def _gnss(faults=(), seed=0, **kw) -> GnssSensor:
    spec = GnssSpec("gnss1", **{"noise_m": 0.0, "rate_hz": 5.0, **kw})
    return GnssSensor(spec, FRAME, np.random.default_rng(seed), faults, utc_start_s=36000.0)


def _gyro(faults=(), seed=0, **kw) -> GyroSensor:
    spec = GyroSpec("gyro1", **{"noise_rad": 0.0, "rot_noise_radps": 0.0, **kw})
    return GyroSensor(spec, np.random.default_rng(seed), faults, utc_start_s=36000.0)


def _run_gnss(sensor: GnssSensor, seconds: float, north=lambda t: 100.0, east=lambda t: -50.0, heading=0.0):
    out = []
    while sensor.next_time_s <= seconds + 1e-9:
        t = sensor.next_time_s
        out.extend(sensor.sample(t, north(t), east(t), heading))
    return out


def _ned(sample) -> tuple[float, float]:
    n, e, _ = FRAME.to_ned(sample.message.lat_deg, sample.message.lon_deg, sample.message.altitude_m or 0.0)
    return n, e


def _fixes(samples):
    return [s for s in samples if isinstance(s.message, PositionFix)]


def test_gnss_white_noise_statistics() -> None:
    sensor = _gnss(noise_m=0.3, gst=False)
    fixes = _fixes(_run_gnss(sensor, 600.0))
    err = np.array([_ned(s) for s in fixes]) - np.array([100.0, -50.0])
    assert len(fixes) == 3001
    np.testing.assert_allclose(err.std(axis=0), 0.3, rtol=0.05)
    assert np.all(np.abs(err.mean(axis=0)) < 4.0 * 0.3 / math.sqrt(len(fixes)))
    assert abs(np.corrcoef(err[:-1, 0], err[1:, 0])[0, 1]) < 0.1  # white


def test_gnss_gauss_markov_error_is_slow_and_has_the_configured_std() -> None:
    sensor = _gnss(markov_m=0.5, markov_time_constant_s=10.0, rate_hz=2.0, gst=False)
    err = np.array([_ned(s) for s in _fixes(_run_gnss(sensor, 6000.0))]) - np.array([100.0, -50.0])
    np.testing.assert_allclose(err.std(axis=0), 0.5, rtol=0.1)
    lag = 20  # 10 s at 2 Hz: correlation e^{-1}
    corr = np.corrcoef(err[:-lag, 1], err[lag:, 1])[0, 1]
    assert corr == pytest.approx(math.exp(-1.0), abs=0.1)


def test_gnss_lever_arm_is_rotated_with_the_heading() -> None:
    sensor = _gnss(lever_arm_m=(10.0, 2.0))
    sample = _fixes(sensor.sample(0.0, 0.0, 0.0, math.pi / 2.0))[0]
    n, e = _ned(sample)
    assert n == pytest.approx(-2.0, abs=1e-6)  # heading east: starboard points south
    assert e == pytest.approx(10.0, abs=1e-6)


def test_gnss_message_fields_and_gst() -> None:
    sensor = _gnss(noise_m=0.2, markov_m=0.1, quality=FixQuality.RTK_FIXED, satellites=17, hdop=0.6,
                   antenna_height_m=12.0)
    samples = sensor.sample(0.0, 0.0, 0.0, 0.0)
    fix, stats = samples[0].message, samples[1].message
    assert isinstance(fix, PositionFix) and isinstance(stats, PositionErrorStats)
    assert (fix.quality, fix.num_satellites, fix.hdop, fix.altitude_m) == (FixQuality.RTK_FIXED, 17, 0.6, 12.0)
    assert fix.utc_time_s == 36000.0
    assert stats.sigma_north_m == pytest.approx(math.hypot(0.2, 0.1))
    assert all(s.protocol == "nmea0183" and s.sensor == "gnss1" and s.valid for s in samples)


def test_gnss_faults() -> None:
    faults = [
        Fault(10.0, "gnss_freeze", "gnss1", 5.0),
        Fault(20.0, "gnss_jump", "gnss1", 5.0, offset_m=7.0, direction_rad=math.pi / 2.0),
        Fault(30.0, "gnss_drift", "gnss1", 10.0, rate_mps=0.5, direction_rad=0.0),
        Fault(45.0, "gnss_dropout", "gnss1", 5.0),
        Fault(55.0, "gnss_invalid", "gnss1", 5.0),
        Fault(10.0, "gnss_jump", "other", 100.0, offset_m=50.0),  # another sensor's: ignored
    ]
    sensor = _gnss(faults, gst=False)
    samples = _run_gnss(sensor, 70.0, north=lambda t: t, east=lambda t: 0.0)
    by_time = {s.t_s: s for s in samples if not isinstance(s.message, CourseOverGround)}

    def pos(t):
        return _ned(by_time[t])

    assert pos(9.8) == pytest.approx((9.8, 0.0), abs=1e-6)
    assert pos(12.0) == pos(9.8) == pos(14.8)  # frozen at the last fix before the fault
    assert by_time[12.0].message.utc_time_s == 36012.0  # the clock keeps running
    assert pos(15.0) == pytest.approx((15.0, 0.0), abs=1e-6)
    assert pos(22.0) == pytest.approx((22.0, 7.0), abs=1e-6)
    assert pos(25.0) == pytest.approx((25.0, 0.0), abs=1e-6)
    assert pos(38.0) == pytest.approx((38.0 + 0.5 * 8.0, 0.0), abs=1e-6)
    assert pos(40.0) == pytest.approx((40.0, 0.0), abs=1e-6)
    assert not [t for t in by_time if 45.0 <= t < 50.0]
    invalid = [s for s in samples if 55.0 <= s.t_s < 60.0]
    assert len(invalid) == 25 and all(not s.valid and isinstance(s.message, InvalidFix) for s in invalid)
    assert invalid[0].message.reason == "gnss_invalid" and invalid[0].message.lat_deg is not None
    assert by_time[60.0].valid


def test_gnss_noise_factor_scales_the_noise() -> None:
    sensor = _gnss([Fault(0.0, "gnss_noise", "gnss1", 300.0, factor=4.0)], noise_m=0.1, gst=True)
    samples = _run_gnss(sensor, 599.8)
    err = np.array([_ned(s)[0] for s in _fixes(samples)]) - 100.0
    assert err[:1500].std() == pytest.approx(0.4, rel=0.08)
    assert err[1500:].std() == pytest.approx(0.1, rel=0.08)
    stats = [s.message for s in samples if isinstance(s.message, PositionErrorStats)]
    assert stats[0].sigma_north_m == pytest.approx(0.4) and stats[-1].sigma_north_m == pytest.approx(0.1)


def test_sample_times_are_exact_and_utc_wraps_at_midnight() -> None:
    spec = GnssSpec("g", rate_hz=3.0, noise_m=0.0, offset_s=0.1, gst=False, velocity=False)
    sensor = GnssSensor(spec, FRAME, np.random.default_rng(0), (), utc_start_s=86399.0)
    samples = _run_gnss(sensor, 10.0)
    times = [s.t_s for s in samples]
    assert times[:3] == [0.1, 0.1 + 1.0 / 3.0, 0.1 + 2.0 / 3.0]
    assert times[-1] == pytest.approx(0.1 + 29.0 / 3.0)
    assert samples[-1].message.utc_time_s == pytest.approx(times[-1] - 1.0)


def test_same_seed_same_samples() -> None:
    a = _run_gnss(_gnss(seed=9, noise_m=0.3, markov_m=0.2), 20.0)
    b = _run_gnss(_gnss(seed=9, noise_m=0.3, markov_m=0.2), 20.0)
    c = _run_gnss(_gnss(seed=10, noise_m=0.3, markov_m=0.2), 20.0)
    assert a == b
    assert a != c


def _run_gyro(sensor: GyroSensor, seconds: float, heading=lambda t: 0.3, rate=lambda t: 0.01):
    out = []
    while sensor.next_time_s <= seconds + 1e-9:
        t = sensor.next_time_s
        out.extend(sensor.sample(t, heading(t), rate(t)))
    return out


def _headings(samples):
    return [s for s in samples if isinstance(s.message, Heading)]


def test_gyro_noise_bias_and_rate_of_turn() -> None:
    sensor = _gyro(noise_rad=math.radians(0.5), bias_rad=math.radians(1.0), rot_noise_radps=0.001)
    samples = _run_gyro(sensor, 300.0)
    heading = np.array([s.message.heading_rad for s in _headings(samples)])
    err = heading - 0.3
    assert err.mean() == pytest.approx(math.radians(1.0), abs=4.0 * math.radians(0.5) / math.sqrt(err.size))
    assert err.std() == pytest.approx(math.radians(0.5), rel=0.06)
    rot = np.array([s.message.rate_radps for s in samples if isinstance(s.message, RateOfTurn)])
    assert rot.size == heading.size == 3001
    assert rot.mean() == pytest.approx(0.01, abs=1e-4) and rot.std() == pytest.approx(0.001, rel=0.06)


def test_gyro_heading_is_sent_in_zero_to_two_pi() -> None:
    sensor = _gyro(noise_rad=math.radians(2.0))
    samples = _run_gyro(sensor, 100.0, heading=lambda t: 0.0)
    values = [s.message.heading_rad for s in _headings(samples)]
    assert min(values) >= 0.0 and max(values) < 2.0 * math.pi
    assert any(v > math.pi for v in values) and any(v < 0.1 for v in values)  # both sides of north


def test_gyro_faults() -> None:
    faults = [
        Fault(10.0, "gyro_offset", "gyro1", 5.0, offset_rad=math.radians(3.0)),
        Fault(20.0, "gyro_drift", "gyro1", 10.0, rate_radps=math.radians(0.5)),
        Fault(35.0, "gyro_freeze", "gyro1", 5.0),
        Fault(45.0, "gyro_dropout", "gyro1", 5.0),
        Fault(55.0, "gyro_invalid", "gyro1", 2.0),
    ]
    sensor = _gyro(faults)
    samples = _run_gyro(sensor, 60.0, heading=lambda t: 0.01 * t)
    by_time = {round(s.t_s, 6): s.message for s in _headings(samples)}
    assert by_time[12.0].heading_rad == pytest.approx(0.12 + math.radians(3.0))
    assert by_time[16.0].heading_rad == pytest.approx(0.16)
    assert by_time[28.0].heading_rad == pytest.approx(0.28 + math.radians(0.5) * 8.0)
    assert by_time[37.0].heading_rad == by_time[34.9].heading_rad
    assert not [t for t in by_time if 45.0 <= t < 50.0]
    invalid = [s for s in samples if not s.valid]
    assert len(invalid) == 20 and invalid[0].message.kind == "heading"
    assert by_time[57.0].heading_rad == pytest.approx(0.57)


def _velocities(samples) -> dict[float, tuple[float, float]]:
    """(north, east) velocity [m/s] of each CourseOverGround, by time."""
    return {s.t_s: (s.message.speed_mps * math.cos(s.message.course_rad),
                    s.message.speed_mps * math.sin(s.message.course_rad))
            for s in samples if isinstance(s.message, CourseOverGround)}


def test_gnss_velocity_is_the_antennas_true_velocity_over_ground() -> None:
    """SOG/COG: the antenna's velocity at the epoch, the lever arm's r × l included; none with the first fix."""
    sensor = _gnss(lever_arm_m=(10.0, 0.0), velocity_noise_mps=0.0, gst=False)
    out = []
    while sensor.next_time_s <= 20.0 + 1e-9:  # 0.5 m/s north, turning at 0.01 rad/s from north
        t = sensor.next_time_s
        out.extend(sensor.sample(t, 0.5 * t, 0.0, 0.01 * t))
    velocity = _velocities(out)
    assert 0.0 not in velocity and len(velocity) == 100
    for t, (v_north, v_east) in velocity.items():
        if t < 0.3:  # (the second fix: the mean over the first epoch)
            continue
        psi = 0.01 * t
        assert v_north == pytest.approx(0.5 - 10.0 * 0.01 * math.sin(psi), abs=1e-4)
        assert v_east == pytest.approx(10.0 * 0.01 * math.cos(psi), abs=1e-4)


def test_gnss_velocity_ignores_drift_and_jump_freezes_with_the_position() -> None:
    """A drift or a jump moves the position only (the Doppler velocity does not see them); a frozen receiver
    repeats both; invalid and dropped-out samples send none."""
    faults = [Fault(10.0, "gnss_drift", "gnss1", 10.0, rate_mps=0.5, direction_rad=1.0),
              Fault(25.0, "gnss_jump", "gnss1", 5.0, offset_m=7.0),
              Fault(35.0, "gnss_freeze", "gnss1", 5.0),
              Fault(45.0, "gnss_dropout", "gnss1", 5.0),
              Fault(55.0, "gnss_invalid", "gnss1", 5.0)]
    sensor = _gnss(faults, velocity_noise_mps=0.0, gst=False)
    velocity = _velocities(_run_gnss(sensor, 70.0, north=lambda t: 0.3 * (t - 5.0) ** 2 / 10.0 if t > 5.0 else 0.0,
                                     east=lambda t: -0.1 * t))
    before = velocity[max(t for t in velocity if t < 35.0)]
    for t, v in velocity.items():
        if 35.0 <= t < 40.0:
            assert v == before  # frozen: the last one repeated
        elif t > 5.5:  # the true velocity, whatever the position's faults (after the drop-out too)
            assert v == pytest.approx((0.3 * (t - 5.0) / 5.0, -0.1), abs=1e-6)
    assert before[0] == pytest.approx(0.3 * (34.8 - 5.0) / 5.0)
    assert not [t for t in velocity if 45.0 <= t < 50.0 or 55.0 <= t < 60.0]


def test_gnss_velocity_noise_and_its_own_stream() -> None:
    """White noise of the configured σ per axis (× the gnss_noise factor), drawn from a stream of its own: the
    positions are the same with the velocity on or off."""
    sensor = _gnss(noise_m=0.3, velocity_noise_mps=0.05, gst=False)
    samples = _run_gnss(sensor, 600.0)
    v = np.array(list(_velocities(samples).values()))
    np.testing.assert_allclose(v.std(axis=0), 0.05, rtol=0.06)
    assert np.all(np.abs(v.mean(axis=0)) < 4.0 * 0.05 / math.sqrt(len(v)))
    without = _run_gnss(_gnss(noise_m=0.3, velocity=False, gst=False), 600.0)
    assert _fixes(samples) == _fixes(without) and not _velocities(without)
    noisy = _gnss([Fault(0.0, "gnss_noise", "gnss1", None, factor=3.0)], velocity_noise_mps=0.05, gst=False)
    v = np.array(list(_velocities(_run_gnss(noisy, 300.0)).values()))
    np.testing.assert_allclose(v.std(axis=0), 0.15, rtol=0.08)
