"""Joseph-form Kalman filter, DARE steady-state gains, pattern gains and the MMAE weight generators."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dpcontrol.estimation.design_model import dp_design_model
from dpcontrol.estimation.discretize import discretize
from dpcontrol.estimation.kalman import (
    PATTERNS,
    KalmanFilter,
    is_covariance,
    pattern_code,
    pattern_gains,
    solve_prior_covariance,
    steady_state_filter,
)
from dpcontrol.estimation.weighting import apply_floor, bayes_step, dwsg_step
from dpcontrol.models.vessels import CYBERSHIP2, SUPPLY

Q_SEED000 = np.array([0.09, 0.09, 1e-4, 1e-3, 1e-3, 1e-4, 1e-3, 1e-3, 1e-4])
R_SEED000 = np.diag([1e-4, 1e-4, 1e-8]) / 0.1   # seed 000 intensities → per-sample variance at h = 0.1 s


def _cs2(omega: float = 0.9, h: float = 0.1):
    m = dp_design_model(CYBERSHIP2.mass_matrix, CYBERSHIP2.damping_matrix, omega, zeta=0.1,
                        wf_intensity=Q_SEED000[0:3], force_intensity=Q_SEED000[3:6], bias_intensity=Q_SEED000[6:9])
    return m, discretize(m.A, m.B, m.E, m.Qc, h)


def _supply(omega: float = 0.7, h: float = 0.2):
    m = dp_design_model(SUPPLY.mass_matrix, SUPPLY.damping_matrix, omega, zeta=0.1,
                        wf_intensity=[0.16, 0.16, 2.1e-5], force_intensity=[3.1e9, 1.7e10, 1.8e12],
                        bias_intensity=[1.8e7, 1.8e7, 7.6e10])
    return m, discretize(m.A, m.B, m.E, m.Qc, h), np.diag([0.15**2, 0.15**2, math.radians(0.1) ** 2])


def _dare_residual(Phi, H, Qd, R, P):
    S = H @ P @ H.T + R
    return Phi @ P @ Phi.T - Phi @ P @ H.T @ np.linalg.solve(S, H @ P @ Phi.T) + Qd - P


@pytest.mark.parametrize("case", ["cs2", "supply"])
def test_dare_solution_is_stabilising_fixed_point(case: str) -> None:
    if case == "cs2":
        m, d = _cs2()
        R = R_SEED000
    else:
        m, d, R = _supply()
    ss = steady_state_filter(d.Phi, m.H, d.Qd, R)
    P = ss.P_prior
    assert np.abs(_dare_residual(d.Phi, m.H, d.Qd, R, P)).max() <= 1e-9 * np.abs(P).max()
    assert np.allclose(P, P.T) and np.linalg.eigvalsh(P).min() > 0.0
    closed_loop = d.Phi @ (np.eye(m.n) - ss.K @ m.H)
    assert np.max(np.abs(np.linalg.eigvals(closed_loop))) < 1.0
    assert np.allclose(ss.K, P @ m.H.T @ np.linalg.inv(m.H @ P @ m.H.T + R))


def test_steady_state_gain_equals_converged_time_varying_gain() -> None:
    m, d = _cs2()
    ss = steady_state_filter(d.Phi, m.H, d.Qd, R_SEED000)
    kf = KalmanFilter(d.Phi, d.Gamma, m.H, d.Qd, R_SEED000, x0=np.zeros(15), P0=np.eye(15))
    for _ in range(6000):
        kf.correct(np.zeros(3))
        kf.predict(np.zeros(3))
    assert np.allclose(kf.K, ss.K, rtol=1e-6, atol=1e-9 * np.abs(ss.K).max())
    assert np.allclose(kf.P, ss.P_prior, rtol=1e-6, atol=1e-9 * np.abs(ss.P_prior).max())


def test_joseph_update_equals_standard_form_with_the_optimal_gain() -> None:
    m, d = _cs2()
    rng = np.random.default_rng(1)
    A = rng.standard_normal((15, 15))
    P0 = A @ A.T + np.eye(15)
    kf = KalmanFilter(d.Phi, d.Gamma, m.H, d.Qd, R_SEED000, x0=np.zeros(15), P0=P0)
    eps = rng.standard_normal(3)
    kf.correct(eps)
    K = P0 @ m.H.T @ np.linalg.inv(m.H @ P0 @ m.H.T + R_SEED000)
    assert np.allclose(kf.x, K @ eps)
    assert np.allclose(kf.P, (np.eye(15) - K @ m.H) @ P0, rtol=1e-8, atol=1e-10)   # seed 002 eq. (54)


def test_partial_update_uses_only_the_measured_rows() -> None:
    m, d = _cs2()
    kf = KalmanFilter(d.Phi, d.Gamma, m.H, d.Qd, R_SEED000, x0=np.zeros(15), P0=np.eye(15))
    rows = np.array([2])
    kf.correct(np.array([0.01]), rows)
    K = np.eye(15) @ m.H[rows].T / (m.H[rows] @ m.H[rows].T + R_SEED000[2, 2])
    assert np.allclose(kf.x, (K * 0.01).ravel())
    assert kf.S.shape == (1, 1)


@given(seed=st.integers(0, 2**32 - 1), pattern_seq=st.lists(st.sampled_from(PATTERNS), min_size=50, max_size=50))
@settings(max_examples=15, deadline=None)
def test_covariance_stays_symmetric_positive_definite_over_long_runs(seed: int, pattern_seq) -> None:
    """Joseph form, badly scaled supply-vessel model, random availability patterns, 3000 steps."""
    m, d, R = _supply()
    rng = np.random.default_rng(seed)
    kf = KalmanFilter(d.Phi, d.Gamma, m.H, d.Qd, R, x0=np.zeros(15), P0=np.diag(rng.uniform(0.1, 10.0, 15)) * 1e2)
    scale = np.sqrt(np.diag(solve_prior_covariance(d.Phi, m.H, d.Qd, R)))
    for k in range(3000):
        measured = pattern_seq[k % len(pattern_seq)]
        rows = np.flatnonzero(measured)
        if rows.size:
            kf.correct(rng.standard_normal(rows.size) * np.sqrt(np.diag(R))[rows], rows)
        kf.predict(rng.standard_normal(3) * 1e4)
        if k % 100 == 0:
            assert np.array_equal(kf.P, kf.P.T)
            assert np.linalg.eigvalsh(kf.P / np.outer(scale, scale)).min() > 0.0
    assert np.all(np.isfinite(kf.P))


def test_pattern_gains_cover_every_pattern_and_zero_the_missing_channels() -> None:
    m, d = _cs2()
    gains = pattern_gains(d.Phi, m.H, d.Qd, R_SEED000)
    assert sorted(gains) == list(range(8))
    full = gains[pattern_code((True, True, True))]
    assert np.allclose(full.K, steady_state_filter(d.Phi, m.H, d.Qd, R_SEED000).K)
    for measured in PATTERNS:
        g = gains[pattern_code(measured)]
        missing = [i for i in range(3) if not measured[i]]
        assert not np.any(g.K[:, missing]) and not np.any(g.S_inv[missing]) and not np.any(g.S_inv[:, missing])
        # a measurement never increases the covariance; nothing measured leaves it unchanged
        assert np.all(np.diag(g.P_post) <= np.diag(g.P_prior) * (1 + 1e-12))
        if not any(measured):
            assert np.array_equal(g.P_post, g.P_prior) and g.log_det_S == 0.0
    heading_only = gains[pattern_code((False, False, True))]
    position_only = gains[pattern_code((True, True, False))]
    assert heading_only.K[8, 2] > 0.01 * full.K[8, 2] > 0.0       # the heading state is still corrected
    assert position_only.K[6, 0] > 0.01 * full.K[6, 0] > 0.0 and position_only.K[7, 1] > 0.0


def test_unobservable_pattern_has_no_stationary_solution() -> None:
    m, d = _cs2()
    with pytest.raises(ValueError, match="stabilising"):
        solve_prior_covariance(d.Phi, m.H[2:3], d.Qd, R_SEED000[2:3, 2:3])


# ---------------------------------------------------------------------------------------------
# Weight generators


def _dwsg_rk4(p: np.ndarray, L: np.ndarray, lam: float, dt: float, steps: int = 20000) -> np.ndarray:
    """Reference: fine RK4 integration of seed 000 eq. (18) with L held."""
    h = dt / steps

    def f(q):
        return -lam * (1.0 - L / (q @ L)) * q

    q = p.copy()
    for _ in range(steps):
        k1 = f(q)
        k2 = f(q + 0.5 * h * k1)
        k3 = f(q + 0.5 * h * k2)
        k4 = f(q + h * k3)
        q = q + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return q


@given(seed=st.integers(0, 10_000), lam_dt=st.floats(0.01, 5.0), spread=st.floats(0.0, 8.0))
@settings(max_examples=25, deadline=None)
def test_dwsg_exact_step_matches_fine_integration(seed: int, lam_dt: float, spread: float) -> None:
    rng = np.random.default_rng(seed)
    p = rng.dirichlet(np.ones(6))
    log_l = rng.uniform(-spread, 0.0, 6)
    ref = _dwsg_rk4(p, np.exp(log_l), lam_dt, 1.0, steps=2000)
    q = p.copy()
    dwsg_step(q, log_l, rate_per_s=lam_dt, dt_s=1.0, floor=0.0)
    assert math.isclose(q.sum(), 1.0, rel_tol=1e-12) and np.all(q >= 0.0)
    assert np.allclose(q, ref, atol=1e-7)
    # invariant to a common offset of the log-likelihoods (only ratios matter)
    q2 = p.copy()
    dwsg_step(q2, log_l + 123.0, rate_per_s=lam_dt, dt_s=1.0, floor=0.0)
    assert np.allclose(q, q2, atol=1e-12)


def test_dwsg_converges_to_the_best_model_and_the_floor_bounds_the_odds() -> None:
    p = np.full(4, 0.25)
    log_l = np.array([-1.0, -0.2, -3.0, -0.5])
    for _ in range(2000):
        dwsg_step(p, log_l, rate_per_s=1.0, dt_s=0.1, floor=1e-3)
    assert np.argmax(p) == 1 and p[1] > 0.99
    assert np.all(p >= 1e-3 * p.max() * (1 - 1e-12))


def test_bayes_step_is_the_posterior_and_forgetting_bounds_the_odds() -> None:
    rng = np.random.default_rng(4)
    log_l = rng.normal(size=(50, 3))
    log_w = np.zeros(3)
    p = np.full(3, 1 / 3)
    for row in log_l:
        bayes_step(log_w, p, row, forgetting=1.0, log_floor=-math.inf)
    posterior = np.exp(log_l.sum(0) - log_l.sum(0).max())
    assert np.allclose(p, posterior / posterior.sum())
    # with forgetting α the log-odds stay ≤ max|Δ log L| / (1 − α), whatever the run length
    alpha = 0.99
    log_w[:] = 0.0
    for _ in range(20000):
        bayes_step(log_w, p, np.array([0.0, -0.01, -0.02]), forgetting=alpha, log_floor=-math.inf)
    assert -log_w.min() <= 0.02 / (1 - alpha) * (1 + 1e-9)
    assert p[0] > p[1] > p[2] > 0.0


@pytest.mark.parametrize("weighting", ["bayes", "dwsg"])
def test_weights_do_not_lock_after_a_long_time_on_one_model(weighting: str) -> None:
    """10 000 samples favouring model 0, then model 2 is better: model 2 must take over, quickly."""
    p = np.full(3, 1 / 3)
    log_w = np.zeros(3)

    def step(log_l: np.ndarray) -> None:
        if weighting == "bayes":
            bayes_step(log_w, p, log_l, forgetting=math.exp(-0.1 / 200.0), log_floor=math.log(1e-6))
        else:
            dwsg_step(p, log_l, rate_per_s=1.0, dt_s=0.1, floor=1e-6)

    for _ in range(10000):
        step(np.array([0.0, -0.5, -0.5]))
    assert p[0] > 0.99
    samples = 0
    while p[2] <= 0.9 and samples < 3000:
        step(np.array([-0.5, -0.5, 0.0]))
        samples += 1
    assert p[2] > 0.9 and samples * 0.1 < 60.0, samples


def test_apply_floor_is_relative_to_the_leader() -> None:
    p = np.array([0.999999999, 1e-12, 1e-9])
    apply_floor(p, 1e-4)
    assert math.isclose(p.sum(), 1.0) and np.all(p[1:] >= 1e-4 * p[0] * (1 - 1e-12))


def test_is_covariance_judges_a_badly_scaled_covariance_by_its_correlations() -> None:
    """A DP covariance spans 10⁻⁷ … 10¹² (position m², bias N²): rounding makes its smallest eigenvalue
    slightly negative although it is a covariance; an indefinite or asymmetric matrix is still refused."""
    rng = np.random.default_rng(3)
    A = rng.standard_normal((15, 15))
    corr = A @ A.T + 1e-6 * np.eye(15)
    scale = np.logspace(-4, 6, 15)                       # standard deviations 1e-4 … 1e6
    P = corr * scale[:, None] * scale[None, :]
    P = 0.5 * (P + P.T)
    P_rounded = P.copy()
    P_rounded[0, 0] -= 1e-12 * P[0, 0]                    # rounding-sized perturbation
    assert is_covariance(P) and is_covariance(P_rounded)
    indefinite = P.copy()
    indefinite[0, 1] = indefinite[1, 0] = 1.5 * math.sqrt(P[0, 0] * P[1, 1])   # |correlation| > 1
    assert not is_covariance(indefinite)
    asymmetric = P.copy()
    asymmetric[0, 1] *= 1.01
    assert not is_covariance(asymmetric)
    negative_variance = P.copy()
    negative_variance[2, 2] = -1.0
    assert not is_covariance(negative_variance)
    zero_row = P.copy()
    zero_row[3, :] = zero_row[:, 3] = 0.0
    assert is_covariance(zero_row)
    zero_row[3, 4] = zero_row[4, 3] = 1.0                 # covariance with a zero-variance state
    assert not is_covariance(zero_row)
    assert not is_covariance(np.full((3, 3), np.nan))
