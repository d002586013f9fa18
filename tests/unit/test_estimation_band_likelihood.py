"""The band-limited, locally whitened, tempered MMAE likelihood (weighting.BandLikelihood) and its use in
the bank: prefilter arithmetic, scale invariance, tempering, the LF-validity gate, channel weighting by
WF motion, multi-rate groups, persistence, configuration."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.signal import sosfilt
from test_estimation_support import jonswap_motion, measure, run_filter, simulate_vessel

from dpbase.schema import ConfigError
from dpcontrol.estimation.factory import make_wave_filter
from dpcontrol.estimation.filter_config import WaveFilterConfig
from dpcontrol.estimation.weighting import BandLikelihood, _cascade_state_space, _Prefilter
from dpcontrol.models.vessels import CYBERSHIP2

DT = 0.1
GRID = (0.3, 0.45, 0.6, 0.75, 0.9, 1.05, 1.2, 1.35)


def _band(n_models: int = 3, **kwargs) -> BandLikelihood:
    options = {"sample_time_s": DT, "band_rad_s": (0.15, 2.0), "scale_time_s": 20.0, "lf_excess_limit": 2.0,
               "length_m": 1.255, "noise_var": (1e-4, 1e-4, 1e-8), "prior_wf_energy": (1e-3, 1e-6),
               "share_time_s": 100.0}
    options.update(kwargs)
    return BandLikelihood(n_models, **options)


@settings(max_examples=25, deadline=None)
@given(st.floats(0.05, 0.5), st.floats(1.2, 5.0), st.integers(1, 4))
def test_state_space_prefilter_is_the_sos_cascade(lo: float, ratio: float, gap: int) -> None:
    """The batched state-space form does the same arithmetic as scipy's sosfilt (band and low outputs)."""
    pre = _Prefilter((lo, lo * ratio), gap * DT, 2)
    rng = np.random.default_rng(3)
    x = rng.standard_normal(400)
    from scipy.signal import butter  # noqa: PLC0415

    fs = 2.0 * math.pi / (gap * DT)
    hi = min(lo * ratio, 0.9 * math.pi / (gap * DT))
    band = sosfilt(butter(2, [lo, hi], btype="bandpass", fs=fs, output="sos"), x)
    low = sosfilt(butter(2, lo, btype="lowpass", fs=fs, output="sos"), x)
    z = np.zeros(pre.A.shape[0])
    out = np.zeros((x.size, 2))
    for k, xk in enumerate(x):
        out[k] = pre.C @ z + pre.D * xk
        z = pre.A @ z + pre.B * xk
    assert np.allclose(out[:, 0], band, rtol=1e-9, atol=1e-12)
    assert np.allclose(out[:, 1], low, rtol=1e-9, atol=1e-12)


def test_band_energies_are_the_sos_filtered_innovations() -> None:
    """The compiled update filters every row (N innovations + the residual) and channel as scipy's sosfilt
    would, and its log-likelihoods are the band energies times the per-group coefficients."""
    from scipy.signal import butter  # noqa: PLC0415

    rng = np.random.default_rng(21)
    steps, n_models = 300, 3
    eps = _innovations(steps, rng, np.array([1.0, 1.5, 2.0]))
    residual = rng.standard_normal((steps, 3)) * np.array([0.02, 0.02, 0.002])
    band = _band(n_models)
    lo, hi = band.band_rad_s
    sos = butter(2, [lo, hi], btype="bandpass", fs=2.0 * math.pi / DT, output="sos")
    rows = np.concatenate([eps, residual[:, None, :]], axis=1)          # (steps, N + 1, 3)
    rows[:, :, 2] *= band.heading_scale_m                               # heading as ψ·L/2
    filtered = sosfilt(sos, rows, axis=0)
    for k in range(steps):
        band.update(eps[k], True, True, residual[k])
        expected = np.stack([filtered[k, :, 0] ** 2 + filtered[k, :, 1] ** 2, filtered[k, :, 2] ** 2], axis=1)
        assert np.allclose(band._energy_band, expected, rtol=1e-9, atol=1e-20)
        if band.gate_max > 0.0:
            assert np.allclose(band.log_l, band._energy_band[:n_models] @ band._coef, rtol=1e-12, atol=0.0)
    assert np.any(band.log_l != 0.0)


def test_cascade_of_one_section_is_its_biquad() -> None:
    sos = np.array([[0.2, 0.3, 0.1, 1.0, -0.5, 0.2]])
    A, B, C, D = _cascade_state_space(sos)
    assert np.allclose(A, [[0.5, 1.0], [-0.2, 0.0]]) and np.allclose(B, [0.3 + 0.5 * 0.2, 0.1 - 0.2 * 0.2])
    assert np.allclose(C, [1.0, 0.0]) and pytest.approx(0.2) == D


def _feed(band: BandLikelihood, eps: np.ndarray, residual: np.ndarray | None = None,
          position: np.ndarray | None = None) -> np.ndarray:
    """Run a sequence (steps, N, 3) through ``band``; returns the per-step log-likelihoods (steps, N)."""
    out = np.zeros(eps.shape[:2])
    for k in range(eps.shape[0]):
        pos = True if position is None else bool(position[k])
        band.update(eps[k], pos, True, np.zeros(3) if residual is None else residual[k])
        out[k] = band.log_l
    return out


def _innovations(steps: int, rng: np.random.Generator, scales: np.ndarray) -> np.ndarray:
    """White innovations (steps, N, 3) whose energy differs per model by ``scales`` (N,)."""
    e = rng.standard_normal((steps, scales.size, 3)) * 0.01
    e[:, :, 2] *= 0.01
    return e * np.sqrt(scales)[None, :, None]


def test_the_model_with_the_least_band_energy_gets_the_highest_likelihood() -> None:
    rng = np.random.default_rng(11)
    log_l = _feed(_band(), _innovations(3000, rng, np.array([1.3, 1.0, 1.6])))
    total = log_l[1000:].sum(axis=0)
    assert np.argmax(total) == 1 and total[1] > total[0] > total[2]


@settings(max_examples=10, deadline=None)
@given(st.floats(1e-3, 1e3))
def test_the_likelihood_is_invariant_to_the_innovation_scale(scale: float) -> None:
    """Local whitening: mis-set noise intensities or a bigger sea do not change what a sample says."""
    rng = np.random.default_rng(12)
    eps = _innovations(600, rng, np.array([1.2, 1.0, 1.5]))
    a = _feed(_band(), eps)
    b = _feed(_band(), eps * scale)
    assert np.allclose(a, b, rtol=1e-6, atol=1e-9)


def test_tempering_counts_independent_samples_not_correlated_ones() -> None:
    """Steady state, white innovations, 10 % energy difference: the log-odds gathered per second follow
    the Nyquist count B/π of independent samples × ½ × 0.1 — within a factor 2: the whitening scale is
    the smallest of the bank's (noisy) short-window energies, which raises the votes by ≈ 1.5 here —
    and stay far below the untempered 1/dt samples per second × ½ × 0.1 that made the weights chatter."""
    rng = np.random.default_rng(13)
    band = _band(2, lf_excess_limit=math.inf)
    log_l = _feed(band, _innovations(20000, rng, np.array([1.1, 1.0])))
    rate = float(np.mean(log_l[5000:, 1] - log_l[5000:, 0])) / DT      # nats per second
    nyquist = (2.0 - 0.15) / math.pi * 0.5 * 0.1                        # B/π · ½ · Δ(e²)/s
    untempered = 0.5 * 0.1 / DT                                         # every sample counted
    assert 0.5 * nyquist < rate < 2.0 * nyquist, (rate, nyquist)
    assert rate < 0.2 * untempered, (rate, untempered)


def test_the_lf_gate_holds_the_evidence_during_a_low_frequency_transient() -> None:
    rng = np.random.default_rng(14)
    eps = _innovations(4000, rng, np.array([1.2, 1.0, 1.5]))
    band = _band()
    _feed(band, eps[:2000])
    assert band.gate[0] > 0.9                                     # white innovations: full evidence
    t = np.arange(2000) * DT
    drift = 0.2 * np.sin(0.03 * t)[:, None] * np.array([1.0, 0.5, 0.8])   # LF mismatch, all models
    transient = eps[2000:].copy()
    transient[:, :, 0] += drift
    _feed(band, transient)
    # position (with the LF mismatch) is held; heading (still white) keeps (nearly) full evidence
    assert band.gate[0] < 0.01 and band.gate[1] > 0.5, band.gate


def test_a_channel_group_without_wave_motion_gets_no_vote() -> None:
    """WF share from the band-passed residual minus the noise floor: heading carries none here."""
    rng = np.random.default_rng(15)
    steps = 3000
    residual = np.zeros((steps, 3))
    residual[:, :2] = jonswap_motion(np.arange(steps) * DT, 0.9, np.array([0.02, 0.01]), rng)
    residual[:, :2] += rng.standard_normal((steps, 2)) * 0.01
    residual[:, 2] = rng.standard_normal(steps) * 1e-4            # gyro noise only
    band = _band(prior_wf_energy=(1e-4, 1e-4))                      # start undecided
    _feed(band, _innovations(steps, rng, np.array([1.0, 1.0, 1.0])), residual)
    assert band.wf_share[0] > 0.99 and band.wf_share[1] < 0.01, band.wf_share
    assert 0.5 < band.wf_energy[0] / (0.02**2 + 0.01**2) < 1.5   # the WF energy itself, noise removed


def test_multi_rate_groups_keep_their_states_between_samples() -> None:
    """Position every second period (5 Hz GNSS, 10 Hz loop): its prefilter runs at h = 0.2 s and its
    state is untouched in the periods without a fix."""
    rng = np.random.default_rng(16)
    eps = _innovations(400, rng, np.array([1.0, 1.2, 1.4]))
    band = _band()
    position = np.arange(400) % 2 == 0
    _feed(band, eps[:-1], position=position[:-1])
    state = band.state[:, 0:2].copy()
    band.update(eps[-1], False, True, np.zeros(3))                 # heading only
    assert np.array_equal(band.state[:, 0:2], state)
    assert set(band._filters) == {1, 2}                           # gap 1 (heading) and 2 (position)
    assert np.all(np.isfinite(band.log_l)) and np.any(band.log_l != 0.0)


def test_state_dict_round_trip_and_rejection() -> None:
    rng = np.random.default_rng(17)
    eps = _innovations(600, rng, np.array([1.0, 1.2, 1.4]))
    a, b = _band(), _band()
    _feed(a, eps[:300])
    b.load_state_dict(json.loads(json.dumps(a.state_dict())))
    assert np.array_equal(_feed(a, eps[300:]), _feed(b, eps[300:]))
    before = json.dumps(b.state_dict())
    bad = b.state_dict()
    bad["means"] = bad["means"][:-1]
    with pytest.raises(ValueError, match="means"):
        b.load_state_dict(bad)
    other = _band(band_rad_s=(0.2, 2.0))
    with pytest.raises(ValueError, match="band"):
        other.load_state_dict(a.state_dict())
    assert json.dumps(b.state_dict()) == before


def _cs2(**kwargs) -> WaveFilterConfig:
    base = {"mass_matrix": CYBERSHIP2.mass_matrix, "damping_matrix": CYBERSHIP2.damping_matrix, "sample_time_s": DT,
            "omegas_rad_s": GRID, "length_m": CYBERSHIP2.length_m, "position_noise_std_m": 0.01,
            "heading_noise_std_rad": 1e-4}
    base.update(kwargs)
    return WaveFilterConfig(**base)


def test_default_band_and_time_follow_the_grid() -> None:
    config = _cs2()
    assert config.likelihood_scale == "band"
    assert config.likelihood_band() == pytest.approx((0.15, 2.025))
    assert config.likelihood_scale_time_s() == pytest.approx(4.0 * math.pi / 0.3)
    explicit = _cs2(likelihood_band_rad_s=(0.2, 1.5), likelihood_time_s=30.0)
    assert explicit.likelihood_band() == (0.2, 1.5) and explicit.likelihood_scale_time_s() == 30.0


@pytest.mark.parametrize(("options", "key"), [
    ({"likelihood_band_rad_s": [1.0, 0.5]}, "likelihood_band_rad_s"),
    ({"likelihood_band_rad_s": [0.1, 40.0]}, "likelihood_band_rad_s"),    # above Nyquist at 10 Hz
    ({"likelihood_band_rad_s": [0.1]}, "likelihood_band_rad_s"),
    ({"likelihood_time_s": 0.0}, "likelihood_time_s"),
    ({"lf_excess_limit": 0.0}, "lf_excess_limit"),
    ({"lf_excess_limit": "big"}, "lf_excess_limit"),
])
def test_bad_likelihood_options_name_their_key(options: dict, key: str) -> None:
    with pytest.raises(ConfigError) as error:
        WaveFilterConfig.from_options(CYBERSHIP2.mass_matrix, CYBERSHIP2.damping_matrix, DT, kind="mmae",
                                      omegas_rad_s=GRID, zeta=0.1, options=options)
    assert error.value.path == f"estimator.{key}"


def test_inf_disables_the_gate() -> None:
    config = WaveFilterConfig.from_options(CYBERSHIP2.mass_matrix, CYBERSHIP2.damping_matrix, DT, kind="mmae",
                                           omegas_rad_s=GRID, zeta=0.1, options={"lf_excess_limit": ".inf"})
    assert math.isinf(config.lf_excess_limit)


def _jonswap_data(seconds: float, omega_peak: float, seed: int, wf_std: float = 0.02):
    steps = int(seconds / DT)
    rng = np.random.default_rng(seed)
    M, D = np.diag(CYBERSHIP2.mass_matrix), np.diag(CYBERSHIP2.damping_matrix)
    wn = np.array([0.1, 0.1, 0.15])
    lf = simulate_vessel(CYBERSHIP2.mass_matrix, CYBERSHIP2.damping_matrix, DT, steps, rng, kp=M * wn**2,
                         kd=2 * M * wn - D, bias_ned=np.array([0.1, -0.2, 0.01]),
                         force_std=np.array([0.05, 0.05, 0.005]),
                         bias_drift_std=np.array([0.005, 0.005, 0.0005]), substeps=2)
    wf = jonswap_motion(np.arange(steps) * DT, omega_peak, np.array([wf_std, 0.5 * wf_std, 1e-3]), rng)
    return measure(lf["eta"], wf, np.array([0.01, 0.01, 1e-4]), rng), lf


@pytest.mark.parametrize("scale", ["band", "common"])
def test_bank_with_band_likelihood_identifies_without_jumps_where_per_sample_weights_jump(scale: str) -> None:
    """A JONSWAP sea 3× bigger than the filters expect (wf std 6 cm vs σ_wf = 1.3 cm) on a nonlinear LF
    truth: the per-sample "common" likelihood makes weights jump within a second; the band one does not,
    and it ends on a neighbour of the peak."""
    y, lf = _jonswap_data(400.0, 0.9, seed=21, wf_std=0.06)
    out = run_filter(make_wave_filter(_cs2(likelihood_scale=scale)), y, lf["tau"])
    weights = out["weights"]
    jumps = int(np.sum(np.abs(weights[10:] - weights[:-10]).max(axis=1) > 0.5))
    if scale == "band":
        assert jumps == 0, jumps
        assert abs(out["omega"][-1] - 0.9) <= 0.15 + 1e-9, out["omega"][-1]
    else:
        assert jumps > 10, jumps


def test_pose_reset_keeps_the_weights_and_restarts_the_statistics() -> None:
    y, lf = _jonswap_data(200.0, 0.9, seed=22)
    f = make_wave_filter(_cs2())
    out = run_filter(f, y, lf["tau"])
    weights = out["weights"][-1].copy()
    f.reset(y[-1] + np.array([5.0, -3.0, 0.2]))            # a position jump: no sea-state evidence
    assert np.array_equal(f.output.weights, weights)
    assert f.band_likelihood is not None and f.band_likelihood.gate.max() == 0.0
    out2 = f.step(y[-1] + np.array([5.0, -3.0, 0.2]), lf["tau"][-1])
    assert np.allclose(out2.weights, weights, atol=1e-6)    # warm-up: the first sample says ~nothing
