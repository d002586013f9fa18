"""Batch prediction-error identification of the wave model (seed 002 eqs. (46)–(50)) and ``kind: pem``."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dpbase.schema import ConfigError
from dpcontrol.estimation import WaveFilterConfig, make_wave_filter
from dpcontrol.estimation.pem import PemWaveFilter, identify_wave_model, oscillator_polynomial
from dpcontrol.estimation.wave_band import WaveBandMeter
from dpcontrol.models.vessels import vessel_from_config

SUPPLY = vessel_from_config("supply")
DT = 0.1


def _motion(omega_peak: float, steps: int, rng: np.random.Generator, std: np.ndarray) -> np.ndarray:
    """WF position-like motion: JONSWAP (γ 3.3) elevation through a 1/ω² position response, 3 channels."""
    omega = np.linspace(0.2, 3.0, 400)
    elevation = omega**-5 * np.exp(-1.25 * (omega_peak / omega) ** 4) \
        * 3.3 ** np.exp(-((omega - omega_peak) ** 2) / (2 * 0.08**2 * omega_peak**2))
    spectrum = elevation / np.minimum(omega / omega_peak, 3.0) ** 4
    amplitude = np.sqrt(2.0 * spectrum * (omega[1] - omega[0]))
    t = np.arange(steps) * DT
    out = np.empty((steps, 3))
    for j in range(3):
        phase = rng.uniform(0.0, 2.0 * math.pi, omega.size)
        x = (amplitude[:, None] * np.cos(omega[:, None] * t[None, :] + phase[:, None])).sum(axis=0)
        out[:, j] = std[j] * x / x.std()
    return out, float(omega[np.argmax(spectrum)])


@pytest.mark.parametrize("omega_peak", [0.45, 0.75, 1.15])
def test_identified_peak_frequency_within_10_percent(omega_peak: float) -> None:
    rng = np.random.default_rng(int(omega_peak * 100))
    std = np.array([0.5, 0.3, math.radians(0.5)])
    noise = np.array([0.1, 0.1, math.radians(0.1)])
    motion, peak = _motion(omega_peak, 12000, rng, std)
    y = motion + rng.normal(0.0, 1.0, motion.shape) * noise
    estimate = identify_wave_model(y, DT, omega_range_rad_s=(0.2, 2.0), noise_var=noise**2)
    assert estimate is not None
    assert abs(estimate.omega_rad_s / peak - 1.0) <= 0.1, (estimate.omega_rad_s, peak)
    assert 0.0 < estimate.zeta < 0.6
    # the WF standard deviation with the noise removed
    np.testing.assert_allclose(estimate.wf_std, std, rtol=0.15)


def test_noise_alone_identifies_nothing() -> None:
    rng = np.random.default_rng(3)
    noise = np.array([0.3, 0.3, 0.01])
    y = rng.normal(0.0, 1.0, (6000, 3)) * noise
    assert identify_wave_model(y, DT, omega_range_rad_s=(0.2, 2.0), noise_var=noise**2) is None


def test_oscillator_polynomial_has_the_discrete_poles() -> None:
    a = oscillator_polynomial(0.8, 0.1, 0.25)
    poles = np.roots(a)
    s = np.log(poles) / 0.25
    np.testing.assert_allclose(np.sort(np.abs(s)), [0.8, 0.8], rtol=1e-9)
    np.testing.assert_allclose(-s.real / np.abs(s), [0.1, 0.1], rtol=1e-9)


def _pem_config(**kwargs) -> WaveFilterConfig:
    options = {"pem_first_s": 300.0, "pem_interval_s": 300.0, "pem_window_s": 600.0, **kwargs}
    return WaveFilterConfig(mass_matrix=SUPPLY.mass_matrix, damping_matrix=SUPPLY.damping_matrix, sample_time_s=DT,
                            kind="pem", omegas_rad_s=(1.2,), zeta=0.1, length_m=SUPPLY.length_m,
                            position_noise_std_m=0.1, heading_noise_std_rad=math.radians(0.1), **options)


def test_pem_filter_reidentifies_on_schedule_and_the_lf_estimate_does_not_jump() -> None:
    rng = np.random.default_rng(5)
    wave_filter = make_wave_filter(_pem_config())
    assert isinstance(wave_filter, PemWaveFilter)
    steps = 9000
    motion, peak = _motion(0.6, steps, rng, np.array([1.0, 1.0, math.radians(0.8)]))
    y = motion + rng.normal(0.0, 1.0, motion.shape) * np.array([0.1, 0.1, math.radians(0.1)])
    wave_filter.reset(y[0])
    jumps = []
    previous = None
    identified_at = []
    for k in range(steps):
        count = wave_filter.identifications
        out = wave_filter.step(y[k], np.zeros(3))
        if wave_filter.identifications != count:
            identified_at.append(k)
            jumps.append(np.abs(out.eta_hat_ned[:2] - previous).max())
        previous = out.eta_hat_ned[:2].copy()
    # first after pem_first_s, then every pem_interval_s
    assert identified_at == [2999, 5999, 8999]
    assert abs(wave_filter.omega_hat / peak - 1.0) <= 0.1
    assert out.omega_hat_rad_s == wave_filter.omega_hat and out.omegas_rad_s == (wave_filter.omega_hat,)
    assert out.weights is not None and out.weights.tolist() == [1.0]
    # the identified WF motion exceeds the rule's (0.01·L = 0.76 m): the model takes it
    assert wave_filter.wf_std[0] > 0.9
    # a rebuild carries the state over: no jump beyond one step's motion
    assert max(jumps) < 0.05


def test_pem_state_round_trip_and_bad_state() -> None:
    rng = np.random.default_rng(6)
    a = PemWaveFilter(_pem_config())
    motion, _ = _motion(0.8, 3500, rng, np.array([0.5, 0.5, 0.01]))
    a.reset(motion[0])
    for k in range(3500):
        a.step(motion[k], np.zeros(3))
    assert a.identifications == 1
    state = a.state_dict()
    b = PemWaveFilter(_pem_config())
    b.load_state_dict(state)
    assert b.omega_hat == a.omega_hat and b.zeta_hat == a.zeta_hat
    out_a = a.step(motion[-1], np.zeros(3))
    out_b = b.step(motion[-1], np.zeros(3))
    np.testing.assert_allclose(out_a.eta_hat_ned, out_b.eta_hat_ned, rtol=0, atol=1e-9)
    with pytest.raises(ValueError, match="pem"):
        b.load_state_dict({**state, "zeta_hat": 2.0})
    assert b.zeta_hat == a.zeta_hat


def test_pem_config_errors_name_the_field() -> None:
    with pytest.raises(ConfigError, match="pem_interval_s"):
        _pem_config(pem_interval_s=0.0)
    with pytest.raises(ConfigError, match="omegas_rad_s"):
        WaveFilterConfig(mass_matrix=SUPPLY.mass_matrix, damping_matrix=SUPPLY.damping_matrix, sample_time_s=DT,
                         kind="pem", omegas_rad_s=(0.5, 0.8))


def test_wave_band_meter_measures_the_wave_band_only() -> None:
    meter = WaveBandMeter(DT, (0.3, 2.0))
    t = np.arange(0.0, 900.0, DT)
    for tk in t:
        # a 10 N wave-frequency force on a 1000 N mean, a slow 50 N drift; heading across ±π with 0.01 rad waves
        meter.update(np.array([1000.0 + 10.0 * math.sin(0.8 * tk), 50.0 * math.sin(0.005 * tk), 0.0]),
                     np.array([0.0, 0.0, math.remainder(math.pi + 0.01 * math.sin(0.9 * tk), 2 * math.pi)]))
    summary = meter.summary()
    assert summary is not None
    assert summary["force_n"] == pytest.approx(10.0 / math.sqrt(2.0), rel=0.1)
    assert summary["lf_heading_rad"] == pytest.approx(0.01 / math.sqrt(2.0), rel=0.1)
    assert summary["moment_nm"] == 0.0 and summary["lf_position_m"] == 0.0
    meter.reset()
    assert meter.summary() is None
