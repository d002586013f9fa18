"""RPEM adaptive-frequency wave filter (seed 003 eqs. (10)–(14), λ = 0.996)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_estimation_support import jonswap_motion, measure, run_filter, simulate_design_model, simulate_vessel

from dpcontrol.estimation.factory import make_wave_filter
from dpcontrol.estimation.filter_config import WaveFilterConfig
from dpcontrol.estimation.rpem import RpemWaveFilter
from dpcontrol.models.vessels import CYBERSHIP2, SHUTTLE_TANKER

Q_SEED000 = np.array([0.09, 0.09, 1e-4, 1e-3, 1e-3, 1e-4, 1e-3, 1e-3, 1e-4])
R_SAMPLE = np.array([1e-4, 1e-4, 1e-8]) / 0.1


def _tanker_sea(omega_peak: float, seed: int, dt: float = 1.0, duration_s: float = 2400.0):
    """Shuttle tanker (seed 003, ballast) holding position in a JONSWAP sea with a flat RAO."""
    steps = int(duration_s / dt)
    rng = np.random.default_rng(seed)
    V = SHUTTLE_TANKER
    M, D = np.diag(V.mass_matrix), np.diag(V.damping_matrix)
    wn = np.array([0.03, 0.03, 0.04])
    lf = simulate_vessel(V.mass_matrix, V.damping_matrix, dt, steps, rng, kp=M * wn**2,
                         kd=np.maximum(2 * M * wn - D, 0.0), bias_ned=np.array([1e5, -5e4, 2e6]),
                         force_std=np.array([2e4, 4e4, 2e6]), substeps=2)
    wf = jonswap_motion(np.arange(steps) * dt, omega_peak, np.array([0.5, 0.8, math.radians(0.3)]), rng)
    y = measure(lf["eta"], wf, np.array([0.3, 0.3, math.radians(0.1)]), rng)
    return y, lf


def _tanker_rpem(omega0: float, dt: float = 1.0, **kwargs) -> RpemWaveFilter:
    V = SHUTTLE_TANKER
    return make_wave_filter(WaveFilterConfig(mass_matrix=V.mass_matrix, damping_matrix=V.damping_matrix,
                                             sample_time_s=dt, length_m=V.length_m, kind="rpem",
                                             omegas_rad_s=(omega0,), position_noise_std_m=0.3, **kwargs))


@pytest.mark.parametrize("start_factor", [0.5, 1.5])
def test_rpem_converges_to_the_motion_peak_from_50_percent_off(start_factor: float) -> None:
    """JONSWAP sea (flat RAO: motion peak = wave peak 0.6 rad/s); λ = 0.996 as in seed 003."""
    omega_peak = 0.6
    y, lf = _tanker_sea(omega_peak, seed=3)
    f = _tanker_rpem(start_factor * omega_peak)
    assert f.config.rpem_forgetting == 0.996
    out = run_filter(f, y, lf["tau"])
    omega = out["omega"]
    converged = omega[2 * omega.size // 3:].mean()          # the estimate over the last 800 s
    assert abs(converged / omega_peak - 1.0) <= 0.10, converged
    assert abs(omega[0] - start_factor * omega_peak) < 1e-12   # it did start 50 % off


def test_rpem_finds_the_frequency_of_design_model_data() -> None:
    """Data from the design model itself at ω0 = 0.8 rad/s (seed 000's full-scale-period sea on CyberShip II, so
    the range is the unscaled 0.2–2 rad/s): no spectral mismatch, tighter bound."""
    rng = np.random.default_rng(5)
    M, D = np.diag(CYBERSHIP2.mass_matrix), np.diag(CYBERSHIP2.damping_matrix)
    wn = np.array([0.3, 0.3, 0.4])
    data = simulate_design_model(CYBERSHIP2.mass_matrix, CYBERSHIP2.damping_matrix, 0.8, 0.1, Q_SEED000,
                                 np.diag(R_SAMPLE), 0.1, 3000, rng, kp=M * wn**2, kd=2 * M * wn - D)
    for start in (0.4, 1.2):
        f = make_wave_filter(WaveFilterConfig(
            mass_matrix=CYBERSHIP2.mass_matrix, damping_matrix=CYBERSHIP2.damping_matrix, sample_time_s=0.1,
            kind="rpem", omegas_rad_s=(start,), rpem_omega_min_rad_s=0.2, rpem_omega_max_rad_s=2.0,
            process_noise_intensity=tuple(Q_SEED000),
            position_noise_std_m=math.sqrt(R_SAMPLE[0]), heading_noise_std_rad=math.sqrt(R_SAMPLE[2])))
        omega = run_filter(f, data["y"], data["tau"])["omega"]
        assert abs(omega[-500:].mean() / 0.8 - 1.0) < 0.05, (start, omega[-500:].mean())


def test_rpem_estimate_is_projected_onto_its_range() -> None:
    y, lf = _tanker_sea(1.6, seed=4, duration_s=1200.0)
    f = _tanker_rpem(0.6, rpem_omega_min_rad_s=0.3, rpem_omega_max_rad_s=1.0)
    omega = run_filter(f, y, lf["tau"])["omega"]
    assert np.all((omega >= 0.3) & (omega <= 1.0))
    assert omega[-1] == 1.0                            # pushed against the bound by a sea above the range
    assert f.output.omegas_rad_s == (0.6,)


def test_sensitivity_recursion_follows_the_finite_difference() -> None:
    """Seed 003 eq. (13) (∂K/∂ω0 neglected) against the finite difference of filters at ω ± δ, with the
    adaptation frozen: the two sensitivities of the predicted measurement agree closely."""
    y, lf = _tanker_sea(0.6, seed=6, duration_s=400.0)
    delta = 1e-5
    filters = [_tanker_rpem(w) for w in (0.6, 0.6 + delta, 0.6 - delta)]
    for f in filters:
        f._warmup_steps = 10**9                        # freeze ω̂0 at its initial value
        f.reset(y[0])
    rec, fd = [], []
    for k in range(400):
        if k > 100:
            rec.append(filters[0].filter.H @ filters[0].dx)
            fd.append(filters[1].filter.H @ (filters[1].filter.x - filters[2].filter.x) / (2 * delta))
        for f in filters:
            f.step(y[k], lf["tau"][k])
    rec = np.array(rec).ravel()
    fd = np.array(fd).ravel()
    cosine = rec @ fd / (np.linalg.norm(rec) * np.linalg.norm(fd))
    assert cosine > 0.95, cosine
    assert 0.7 < np.linalg.norm(rec) / np.linalg.norm(fd) < 1.3
