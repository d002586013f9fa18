"""Waves (sim_plant.environment): spectra, components, RAOs, WF motion spectrum, drift, cross-fades."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.signal import welch

from dpcontrol.models.vessels import CYBERSHIP2, MARINER, SHUTTLE_TANKER, SUPPLY
from sim_plant.environment.rao import HullDimensions, motion_raos, reflection_coefficient
from sim_plant.environment.spectra import frequency_bins, realise_waves, wave_spectrum
from sim_plant.environment.waves import SeaState, WaveEnvironment, WaveField, motion_peaks


def _hull(vessel) -> HullDimensions:
    return HullDimensions(vessel.length_m, vessel.beam_m, vessel.draft_m)


def _field(vessel, state: SeaState, seed: int = 0) -> WaveField:
    comps = realise_waves(state.hs_m, state.omega_peak_rad_s, state.gamma, state.spectrum, state.components,
                          rng=np.random.default_rng(seed))
    return WaveField(comps, state.direction_rad, _hull(vessel))


@pytest.mark.parametrize(("spectrum", "gamma"), [("jonswap", 3.3), ("jonswap", 7.0), ("jonswap", 1.0),
                                                 ("pierson_moskowitz", 1.0)])
def test_spectrum_zeroth_moment_is_hs_squared_over_16(spectrum, gamma) -> None:
    w = np.linspace(1e-3, 30.0, 300001)
    s = wave_spectrum(w, 2.5, 0.7, gamma, spectrum)
    assert np.trapezoid(s, w) == pytest.approx(2.5**2 / 16.0, rel=2e-3)
    assert w[np.argmax(s)] == pytest.approx(0.7, rel=2e-3)


def test_jonswap_is_peakier_than_pierson_moskowitz() -> None:
    w = np.array([0.7])
    assert wave_spectrum(w, 2.0, 0.7, 3.3)[0] > 1.5 * wave_spectrum(w, 2.0, 0.7, spectrum="pierson_moskowitz")[0]
    with pytest.raises(ValueError, match="unknown wave spectrum"):
        wave_spectrum(w, 2.0, 0.7, spectrum="bretschneider")


def test_components_carry_the_sea_state() -> None:
    comps = realise_waves(3.0, 0.6, 3.3, "jonswap", 200, rng=np.random.default_rng(5))
    hs = 4.0 * math.sqrt(0.5 * float(np.sum(comps.amplitude_m**2)))
    assert hs == pytest.approx(3.0, rel=0.02)
    edges = frequency_bins(0.6, 3.3, 200)
    assert np.all(comps.omega_rad_s > edges[:-1]) and np.all(comps.omega_rad_s < edges[1:])
    assert np.all((comps.phase_rad >= 0.0) & (comps.phase_rad < 2.0 * math.pi))
    np.testing.assert_allclose(comps.wavenumber_radpm, comps.omega_rad_s**2 / 9.81)
    # bins are finer at the peak than in the tails
    widths = np.diff(edges)
    peak_bin = int(np.searchsorted(edges, 0.6)) - 1
    assert widths[peak_bin] < 0.3 * widths[-1]


def test_components_are_deterministic_per_seed() -> None:
    a = realise_waves(2.0, 0.8, 3.3, "jonswap", 120, rng=np.random.default_rng(1))
    b = realise_waves(2.0, 0.8, 3.3, "jonswap", 120, rng=np.random.default_rng(1))
    c = realise_waves(2.0, 0.8, 3.3, "jonswap", 120, rng=np.random.default_rng(2))
    np.testing.assert_array_equal(a.omega_rad_s, b.omega_rad_s)
    np.testing.assert_array_equal(a.phase_rad, b.phase_rad)
    assert not np.allclose(a.phase_rad, c.phase_rad)


def test_record_does_not_repeat_like_an_equally_spaced_sum() -> None:
    """Equal spacing Δω repeats exactly after 2π/Δω; the jittered non-uniform grid does not."""
    state = SeaState(0.0, 2.0, 0.8, 0.0)
    field = _field(SUPPLY, state, seed=3)
    spacing = np.diff(field.components.omega_rad_s)
    assert np.std(spacing) / np.mean(spacing) > 0.3
    period = 2.0 * math.pi / float(np.mean(spacing))
    t = np.arange(0.0, 600.0, 0.5)
    first = field.motion_series(t, 0.0)[:, 0]
    later = field.motion_series(t + period, 0.0)[:, 0]
    assert abs(np.corrcoef(first, later)[0, 1]) < 0.5


def test_rao_long_wave_limits() -> None:
    hull = _hull(SUPPLY)
    w = np.array([0.02])
    k = w**2 / 9.81
    for beta in np.radians([0.0, 30.0, 90.0, 135.0, 180.0, -60.0]):
        rx, ry, rpsi = motion_raos(w, beta, hull)
        assert rx[0] == pytest.approx(math.cos(beta), abs=1e-3)  # particle following
        assert ry[0] == pytest.approx(math.sin(beta), abs=1e-3)
        assert rpsi[0] == pytest.approx(k[0] * math.sin(beta) * math.cos(beta), rel=1e-2, abs=1e-12)


def test_rao_averages_out_waves_shorter_than_the_hull() -> None:
    hull = _hull(SHUTTLE_TANKER)
    lam = hull.length_m / 4.0
    w = np.array([math.sqrt(9.81 * 2.0 * math.pi / lam)])
    rx, _, _ = motion_raos(w, math.pi, hull)
    assert abs(rx[0]) < 0.15
    rx_short_hull, _, _ = motion_raos(w, math.pi, _hull(CYBERSHIP2))
    assert abs(rx_short_hull[0]) > 0.9


def test_long_hull_motion_peak_is_below_the_wave_peak() -> None:
    """Seed 003 Fig. 4 / docs/design.md §5, trap 3: tanker surge peak at a longer period than the waves (10 s)."""
    sea = SeaState(0.0, 2.0, 2.0 * math.pi / 10.0, 0.0, "pierson_moskowitz", 1.0)
    surge_peak, _, _ = motion_peaks(sea, _hull(SHUTTLE_TANKER), math.pi)
    assert 2.0 * math.pi / surge_peak > 11.0
    short = SeaState(0.0, 1.2, 0.93, math.radians(30.0))
    peaks = motion_peaks(short, _hull(CYBERSHIP2), math.radians(210.0))
    assert peaks[0] == pytest.approx(0.93, rel=0.01)
    assert peaks[1] == pytest.approx(0.93, rel=0.01)


@pytest.mark.parametrize(("vessel", "state"), [
    (CYBERSHIP2, SeaState(0.0, 1.2, 0.93, math.radians(30.0))),
    (SUPPLY, SeaState(0.0, 2.0, 0.73, math.radians(30.0))),
    (SHUTTLE_TANKER, SeaState(0.0, 2.0, 2.0 * math.pi / 10.0, 0.0, "pierson_moskowitz", 1.0)),
], ids=["cybership2", "supply", "tanker"])
def test_wf_motion_spectrum_matches_rao_squared_times_wave_spectrum(vessel, state) -> None:
    """Welch PSD of the simulated WF motion vs |RAO|²S in three 10 %-wide bands around each motion
    peak (seed 003 eq. (2)): within 10 %."""
    field = _field(vessel, state, seed=0)
    dt = 0.5
    t = np.arange(32768) * dt
    heading = 0.0
    motion = field.motion_series(t, heading)
    beta = field.relative_direction(heading)
    peaks = motion_peaks(state, field.hull, beta)
    freq_hz, psd_hz = welch(motion, fs=1.0 / dt, nperseg=4096, axis=0)
    w = 2.0 * math.pi * freq_hz
    psd = psd_hz / (2.0 * math.pi)
    w_fine = np.linspace(0.2 * state.omega_peak_rad_s, 6.0 * state.omega_peak_rad_s, 40000)
    s_fine = wave_spectrum(w_fine, state.hs_m, state.omega_peak_rad_s, state.gamma, state.spectrum)
    checked = 0
    for dof, rao in enumerate(motion_raos(w_fine, beta, field.hull)):
        if peaks[dof] is None:
            continue
        theory = rao**2 * s_fine
        for lo, hi in ((0.85, 0.95), (0.95, 1.05), (1.05, 1.15)):
            band = (w >= lo * peaks[dof]) & (w < hi * peaks[dof])
            band_fine = (w_fine >= lo * peaks[dof]) & (w_fine < hi * peaks[dof])
            measured = psd[band, dof].sum() * (w[1] - w[0])
            expected = np.trapezoid(theory[band_fine], w_fine[band_fine])
            assert measured == pytest.approx(expected, rel=0.10), (dof, lo)
            checked += 1
    assert checked >= 3


def test_wf_motion_evaluate_matches_series_and_rate_is_the_derivative() -> None:
    state = SeaState(0.0, 2.0, 0.8, math.radians(40.0))
    field = _field(SUPPLY, state, seed=4)
    heading = math.radians(10.0)
    t0 = 123.4
    x, y, psi, rate, _, _ = field.evaluate(t0, 0.0, 0.0, heading)
    ref = field.motion_series(np.array([t0]), heading)[0]
    np.testing.assert_allclose([x, y, psi], ref, rtol=1e-3, atol=1e-6)  # table interpolation in β
    # moving vessel (Doppler): d/dt ψ_w along the path n(t) = U t
    speed = 5.0
    eps = 1e-3

    def psi_at(t: float) -> float:
        return field.evaluate(t, speed * t, 0.0, heading)[2]

    rate_moving = field.evaluate(t0, speed * t0, 0.0, heading, north_rate_mps=speed)[3]
    numeric = (psi_at(t0 + eps) - psi_at(t0 - eps)) / (2.0 * eps)
    assert rate_moving == pytest.approx(numeric, rel=1e-4)
    assert abs(rate_moving - rate) > 1e-3 * abs(rate)


def test_moving_vessel_sees_the_encounter_frequency() -> None:
    state = SeaState(0.0, 4.0, 0.9, math.radians(60.0))
    field = _field(MARINER, state, seed=2)
    heading = 0.0
    beta = field.relative_direction(heading)
    speed = 7.7
    along = speed * math.cos(beta)
    dt = 0.25
    t = np.arange(16384) * dt
    yaw = np.array([field.evaluate(ti, speed * ti, 0.0, heading)[2] for ti in t])
    freq_hz, psd = welch(yaw, fs=1.0 / dt, nperseg=4096)
    measured = 2.0 * math.pi * freq_hz[np.argmax(psd)]
    expected = motion_peaks(state, field.hull, beta, along)[2]
    static = motion_peaks(state, field.hull, beta)[2]
    assert expected > 1.2 * static  # head-ish seas: encounter frequency above the wave frequency
    assert measured == pytest.approx(expected, rel=0.08)


def test_reflection_coefficient_limits() -> None:
    w = np.array([0.01, 0.5, 1.0, 2.0, 6.0])
    r = reflection_coefficient(w, 10.0)
    assert r[0] < 1e-6
    assert np.all(np.diff(r) > 0.0)
    assert r[-1] == pytest.approx(1.0, abs=1e-6)


def test_mean_drift_scales_with_hs_squared_and_direction() -> None:
    small = _field(SUPPLY, SeaState(0.0, 2.0, 0.8, math.radians(90.0)), seed=7)
    large = _field(SUPPLY, SeaState(0.0, 4.0, 0.8, math.radians(90.0)), seed=7)
    fs = small.mean_drift_b(0.0)
    fl = large.mean_drift_b(0.0)
    assert fl[1] == pytest.approx(4.0 * fs[1], rel=1e-9)
    assert fs[1] < 0.0  # waves from starboard (east, heading north) push the vessel to port
    assert abs(fs[0]) < 1e-6 * abs(fs[1])
    head = _field(SUPPLY, SeaState(0.0, 2.0, 0.8, 0.0), seed=7).mean_drift_b(0.0)
    assert head[0] < 0.0 and abs(head[0]) < abs(fs[1])  # head seas push astern, less than beam-on
    # the slowly varying force averages to the mean (Newman)
    t = np.arange(0.0, 20000.0, 1.0)
    forces = []
    for ti in t:
        _, _, _, _, ac, as_ = small.evaluate(ti, 0.0, 0.0, 0.0)
        forces.append((ac * ac + as_ * as_) * small.drift_factors()[1])
    assert float(np.mean(forces)) == pytest.approx(fs[1], rel=0.08)
    assert float(np.std(forces)) > 0.3 * abs(fs[1])  # it does vary slowly


def test_model_scale_hull_feels_no_drift_from_full_scale_waves() -> None:
    cs2 = _field(CYBERSHIP2, SeaState(0.0, 1.2, 0.93, math.radians(90.0))).mean_drift_b(0.0)
    supply = _field(SUPPLY, SeaState(0.0, 1.2, 0.93, math.radians(90.0))).mean_drift_b(0.0)
    assert abs(cs2[1]) < 1e-6 * abs(supply[1])


def _env(states, seed=0):
    return WaveEnvironment(states, _hull(SUPPLY), lambda i: np.random.default_rng([seed, i]))


def test_sea_state_change_is_cross_faded_without_a_jump() -> None:
    states = [SeaState(0.0, 1.0, 0.84, 0.0), SeaState(100.0, 4.0, 0.56, 0.0, fade_s=30.0)]
    env = _env(states)
    times = np.arange(60.0, 170.0, 0.05)
    x = np.array([env.evaluate(t, 0.0, 0.0, 0.0).surge_m for t in times])
    steps = np.abs(np.diff(x))
    before = steps[times[1:] < 100.0].max()
    after = steps[times[1:] > 130.0].max()
    across = steps[(times[1:] >= 99.0) & (times[1:] <= 131.0)].max()
    assert across <= 1.2 * max(before, after)
    # outside the fade the output is exactly one field
    old_field = env._fields_of(0)[0]
    new_field = env._fields_of(1)[0]
    assert env.evaluate(99.9, 0.0, 0.0, 0.0).surge_m == pytest.approx(old_field.evaluate(99.9, 0, 0, 0)[0])
    assert env.evaluate(130.1, 0.0, 0.0, 0.0).surge_m == pytest.approx(new_field.evaluate(130.1, 0, 0, 0)[0])
    assert env.peaks(99.0, 0.0).omega_peak_rad_s == pytest.approx(0.84)
    assert env.peaks(101.0, 0.0).omega_peak_rad_s == pytest.approx(0.56)


def test_calm_before_the_first_sea_state_and_in_zero_hs() -> None:
    env = _env([SeaState(50.0, 0.0, 0.8, 0.0), SeaState(100.0, 2.0, 0.8, 0.0, fade_s=20.0)])
    assert env.evaluate(10.0, 0.0, 0.0, 0.0).surge_m == 0.0
    assert env.evaluate(60.0, 0.0, 0.0, 0.0).surge_m == 0.0
    assert env.peaks(60.0, 0.0).motion_peak_rad_s is None
    ramp = [abs(env.evaluate(t, 0.0, 0.0, 0.0).surge_m) for t in np.arange(100.0, 101.0, 0.1)]
    assert ramp[0] == 0.0 and max(ramp) < 0.05  # fades in from calm
    with pytest.raises(ValueError, match="fade"):
        _env([SeaState(0.0, 1.0, 0.8, 0.0), SeaState(10.0, 1.0, 0.8, 0.0, fade_s=30.0)])


def test_peaks_for_velocity_are_the_peaks_at_the_speed_along_the_waves() -> None:
    """WaveEnvironment.peaks_for_velocity (the plant's truth, once per step) is peaks() at the speed along χ."""
    env = _env([SeaState(50.0, 0.0, 0.8, 0.0), SeaState(100.0, 2.0, 0.8, math.radians(40.0)),
                SeaState(200.0, 3.0, 0.6, math.radians(-120.0), fade_s=20.0)])
    rng = np.random.default_rng(3)
    for t in (10.0, 60.0, 100.0, 150.0, 205.0, 300.0):
        for heading, vn, ve in rng.uniform([-4.0, -3.0, -3.0], [4.0, 3.0, 3.0], size=(20, 3)):
            prop = env.propagation_rad(t)
            along = 0.0 if prop is None else vn * math.cos(prop) + ve * math.sin(prop)
            assert env.peaks_for_velocity(t, heading, vn, ve) == env.peaks(t, heading, along)
