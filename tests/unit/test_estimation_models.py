"""Design model (seed 002 eqs. (30)–(39), seed 001 eqs. (33)–(38)) and its exact discretisation."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.linalg import expm, solve_continuous_lyapunov

from dpcontrol.estimation.design_model import (
    StateIndex,
    dp_design_model,
    wave_matrices,
    wave_matrix_derivative,
    wf_intensity_for_variance,
)
from dpcontrol.estimation.discretize import (
    discretize,
    oscillator_discretization,
    transition_derivative,
    van_loan_noise,
    zoh_input_matrix,
)
from dpcontrol.models.vessels import CYBERSHIP2, SUPPLY

Q_SEED000 = np.array([0.09, 0.09, 1e-4, 1e-3, 1e-3, 1e-4, 1e-3, 1e-3, 1e-4])  # seed 000 App. A (A.2)


def _cs2_model(omega: float | None = 0.93, bias_t: tuple[float, float, float] | None = None):
    return dp_design_model(CYBERSHIP2.mass_matrix, CYBERSHIP2.damping_matrix, omega, zeta=0.1,
                           wf_intensity=Q_SEED000[0:3], force_intensity=Q_SEED000[3:6],
                           bias_intensity=Q_SEED000[6:9], bias_time_constants_s=bias_t)


def test_matrices_match_seed_002_eq_38_39() -> None:
    m = _cs2_model(0.93)
    M_inv = np.linalg.inv(CYBERSHIP2.mass_matrix)
    D = CYBERSHIP2.damping_matrix
    idx = m.index
    assert m.A.shape == (15, 15) and m.B.shape == (15, 3) and m.E.shape == (15, 9) and m.H.shape == (3, 15)
    # WF block (seed 000 eq. (1)): [[0, I], [−Ω, −Λ]]
    A_w = m.A[0:6, 0:6]
    assert np.array_equal(A_w[0:3, 3:6], np.eye(3))
    assert np.allclose(A_w[3:6, 0:3], -(0.93**2) * np.eye(3))
    assert np.allclose(A_w[3:6, 3:6], -2 * 0.1 * 0.93 * np.eye(3))
    # η̇p = ν; ν̇ = M⁻¹bp − M⁻¹Dν (the minus sign seed 000 eq. (14) drops)
    assert np.array_equal(m.A[idx.eta, idx.nu], np.eye(3))
    assert np.allclose(m.A[idx.nu, idx.bias], M_inv)
    assert np.allclose(m.A[idx.nu, idx.nu], -M_inv @ D)
    assert np.all(np.linalg.eigvals(m.A[idx.nu, idx.nu]).real < 0.0)  # the LF velocity dynamics are stable
    assert np.array_equal(m.A[idx.bias, :], np.zeros((3, 15)))    # seed 002 random-walk bias
    # no coupling between the WF and the LF blocks
    assert not np.any(m.A[0:6, 6:]) and not np.any(m.A[6:, 0:6])
    assert np.allclose(m.B[idx.nu], M_inv) and not np.any(m.B[0:12])
    # y = ηp + C_w ξ (C_w = [0 I])
    assert np.array_equal(m.H[:, 3:6], np.eye(3)) and np.array_equal(m.H[:, idx.eta], np.eye(3))
    assert not np.any(m.H[:, 0:3]) and not np.any(m.H[:, 9:])
    # E: w1 → ξ̇2, w2 → ν̇ through M⁻¹, w3 → ḃp
    assert np.array_equal(m.E[3:6, 0:3], np.eye(3))
    assert np.allclose(m.E[idx.nu, 3:6], M_inv)
    assert np.array_equal(m.E[idx.bias, 6:9], np.eye(3))
    assert np.allclose(np.diag(m.Qc), Q_SEED000)


def test_markov_bias_of_seed_001_eq_35_and_raw_model() -> None:
    m = _cs2_model(0.8, bias_t=(600.0, 600.0, 300.0))
    assert np.allclose(m.A[m.index.bias, m.index.bias], -np.diag([1 / 600, 1 / 600, 1 / 300]))
    raw = _cs2_model(None)
    assert raw.n == 9 and raw.index == StateIndex.for_model(False) and raw.omega_rad_s is None
    assert np.array_equal(raw.H, np.hstack([np.eye(3), np.zeros((3, 6))]))
    # the raw model is the LF block of the wave model
    full = _cs2_model(0.8)
    assert np.allclose(raw.A, full.A[6:, 6:]) and np.allclose(raw.B, full.B[6:])


def test_design_model_rejects_bad_parameters() -> None:
    with pytest.raises(ValueError, match="omega_rad_s > 0"):
        _cs2_model(-0.5)
    with pytest.raises(ValueError, match="time constants"):
        _cs2_model(0.8, bias_t=(600.0, -1.0, 300.0))
    with pytest.raises(ValueError, match="intensities"):
        dp_design_model(CYBERSHIP2.mass_matrix, CYBERSHIP2.damping_matrix, 0.8, zeta=0.1,
                        wf_intensity=[1.0, -1.0, 0.0], force_intensity=[1, 1, 1], bias_intensity=[1, 1, 1])


@given(omega=st.floats(0.2, 2.0), zeta=st.floats(0.02, 0.9), std=st.floats(1e-3, 10.0))
@settings(max_examples=30, deadline=None)
def test_wf_intensity_gives_the_requested_wf_variance(omega: float, zeta: float, std: float) -> None:
    q = wf_intensity_for_variance(omega, zeta, [std, std, std])
    A_w, E_w, C_w = wave_matrices(omega, zeta)
    P = solve_continuous_lyapunov(A_w, -E_w @ np.diag(q) @ E_w.T)   # stationary covariance
    assert np.allclose(np.diag(C_w @ P @ C_w.T), std**2, rtol=1e-8)


@pytest.mark.parametrize("omega", [0.3, 0.93, None])
def test_discretisation_matches_expm_and_fine_euler(omega: float | None) -> None:
    m = _cs2_model(omega, bias_t=(500.0, 500.0, 200.0))
    h = 0.1
    d = discretize(m.A, m.B, m.E, m.Qc, h)
    assert np.allclose(d.Phi, expm(m.A * h), rtol=1e-12, atol=1e-14)
    # Γ against a fine Euler integration of ẋ = Ax + Bu over one period (u held), and against
    # the series Σ A^k h^{k+1}/(k+1)! B (A is singular, so no A⁻¹(Φ − I)B).
    steps = 20000
    dt = h / steps
    X = np.zeros((m.n, 3))
    for _ in range(steps):
        X = X + dt * (m.A @ X + m.B)
    assert np.allclose(d.Gamma, X, rtol=2e-4, atol=1e-12)
    series = sum(np.linalg.matrix_power(m.A, k) * h ** (k + 1) / math.factorial(k + 1) for k in range(25)) @ m.B
    assert np.allclose(d.Gamma, series, rtol=1e-10, atol=1e-15)
    # Qd against a fine Euler integration of Ṗ = AP + PAᵀ + E Qc Eᵀ from P(0) = 0
    P = np.zeros((m.n, m.n))
    GQG = m.E @ m.Qc @ m.E.T
    for _ in range(steps):
        P = P + dt * (m.A @ P + P @ m.A.T + GQG)
    assert np.allclose(d.Qd, P, rtol=2e-4, atol=1e-14 * np.abs(P).max())
    assert np.array_equal(d.Qd, d.Qd.T)
    assert np.linalg.eigvalsh(d.Qd).min() > -1e-12 * np.abs(d.Qd).max()
    # and it is *not* the crude Qc·h: the WF block has no noise on ξ1 in E Qc Eᵀ h, but does in Qd
    if omega is not None:
        assert d.Qd[0, 0] > 0.0 and (GQG * h)[0, 0] == 0.0


def test_discretised_noise_matches_sampled_statistics() -> None:
    """Monte Carlo: the covariance of x(h) from an Euler–Maruyama simulation equals Qd."""
    m = dp_design_model(np.eye(3), np.eye(3), 1.0, zeta=0.3, wf_intensity=[1.0, 0.5, 0.2],
                        force_intensity=[0.3, 0.3, 0.1], bias_intensity=[0.1, 0.1, 0.05])
    h = 0.5
    d = discretize(m.A, m.B, m.E, m.Qc, h)
    rng = np.random.default_rng(7)
    runs, steps = 20000, 100
    dt = h / steps
    x = np.zeros((runs, m.n))
    L = np.sqrt(np.diag(m.Qc) * dt)
    for _ in range(steps):
        x = x + dt * x @ m.A.T + (rng.standard_normal((runs, m.E.shape[1])) * L) @ m.E.T
    sample = x.T @ x / runs
    scale = np.sqrt(np.outer(np.diag(d.Qd), np.diag(d.Qd)))
    assert np.max(np.abs(sample - d.Qd) / scale) < 0.06


def test_supply_vessel_discretisation_is_well_conditioned() -> None:
    m = dp_design_model(SUPPLY.mass_matrix, SUPPLY.damping_matrix, 0.7, zeta=0.1, wf_intensity=[0.1, 0.1, 1e-5],
                        force_intensity=[3e9, 2e10, 2e12], bias_intensity=[2e7, 2e7, 8e10])
    d = discretize(m.A, m.B, m.E, m.Qc, 0.2)
    assert np.all(np.isfinite(d.Phi)) and np.all(np.isfinite(d.Qd))
    assert np.allclose(d.Phi, expm(m.A * 0.2), rtol=1e-10, atol=1e-14)
    assert np.linalg.eigvalsh(d.Qd / np.sqrt(np.outer(np.diag(d.Qd), np.diag(d.Qd)))).min() > -1e-10


@given(omega=st.floats(0.1, 3.0), zeta=st.floats(0.01, 0.95), h=st.floats(0.01, 2.0))
@settings(max_examples=60, deadline=None)
def test_oscillator_closed_form_equals_expm_frechet_and_van_loan(omega: float, zeta: float, h: float) -> None:
    A_w, _, _ = wave_matrices(omega, zeta)
    a = A_w[np.ix_([0, 3], [0, 3])]
    da = wave_matrix_derivative(omega, zeta)[np.ix_([0, 3], [0, 3])]
    Phi, dPhi, Qd = oscillator_discretization(omega, zeta, h)
    Phi_ref, dPhi_ref = transition_derivative(a, da, h)
    Q_ref = van_loan_noise(a, np.array([[0.0], [1.0]]), np.eye(1), h)
    assert np.allclose(Phi, Phi_ref, rtol=1e-9, atol=1e-12)
    assert np.allclose(dPhi, dPhi_ref, rtol=1e-7, atol=1e-10 * max(1.0, np.abs(dPhi_ref).max()))
    # Qd = P∞ − Φ P∞ Φᵀ cancels: its absolute error is a few ε·|P∞| (P∞ = diag(1/(4ζω³), 1/(4ζω))).
    p_inf = 1.0 / (4.0 * zeta * omega**3)
    assert np.allclose(Qd, Q_ref, rtol=1e-7, atol=50.0 * np.finfo(float).eps * max(p_inf, 1.0))


def test_transition_derivative_matches_finite_difference() -> None:
    h, zeta = 0.2, 0.1
    m0 = _cs2_model(0.9)
    dA = np.zeros((15, 15))
    dA[0:6, 0:6] = wave_matrix_derivative(0.9, zeta)
    _, dPhi = transition_derivative(m0.A, dA, h)
    step = 1e-6
    fd = (expm(_cs2_model(0.9 + step).A * h) - expm(_cs2_model(0.9 - step).A * h)) / (2 * step)
    assert np.allclose(dPhi, fd, atol=1e-8)
    assert np.any(np.abs(dPhi[0:6, 0:6]) > 1e-3) and not np.any(dPhi[6:, 6:])


def test_zoh_rejects_bad_period() -> None:
    m = _cs2_model(0.9)
    with pytest.raises(ValueError):
        discretize(m.A, m.B, m.E, m.Qc, 0.0)
    Phi, Gamma = zoh_input_matrix(m.A, m.B, 0.1)
    assert Phi.shape == (15, 15) and Gamma.shape == (15, 3)
    with pytest.raises(ValueError):
        oscillator_discretization(0.9, 1.0, 0.1)
