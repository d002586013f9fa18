"""Kalman–Bucy filter for the Blue Lady (seed 004) against the CARE and its discrete counterpart."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.linalg import solve_continuous_are

from dpcontrol.estimation.kalman_bucy import (
    POSITION,
    VELOCITY,
    KalmanBucyFilter,
    blue_lady_model,
    body_velocity,
    discrete_counterpart,
)
from dpcontrol.runtime.estimators import KalmanBucyEstimator

DT = 0.1
DEG2 = (math.pi / 180.0) ** 2


def test_blue_lady_matrices_follow_seed_004_eqs_58_61_62() -> None:
    m = blue_lady_model()
    a = np.array([[0.0, 0.0], [1.0, 0.0]])
    for j in range(3):
        block = slice(2 * j, 2 * j + 2)
        assert np.array_equal(m.A[block, block], a)
        assert np.array_equal(m.B[block, j], [1.0, 0.0]) and np.array_equal(m.C[j, block], [0.0, 1.0])
    assert np.array_equal(m.G[0:2, 0:2], [[1.0, 0.0], [0.0, 0.01]]) and np.array_equal(m.G[2:4, 2:4], m.G[0:2, 0:2])
    assert np.array_equal(m.G[4:6, 4:6], np.diag([0.2, 0.01]))
    assert np.array_equal(m.Q[0:4, 0:4], np.diag([0.1, 0.2, 0.1, 0.2]))
    assert np.allclose(m.Q[4:6, 4:6], np.eye(2) * DEG2)                    # Q_ψ = I in degrees
    assert np.allclose(np.diag(m.R_sample), [0.01, 0.01, 0.1 * DEG2])       # R_ψ = 0.1 deg²
    assert np.allclose(m.intensity_R(DT), m.R_sample * DT)                  # seed 004 eq. (35)


def _trajectory(steps: int, seed: int):
    """Blue Lady manoeuvring: surge speed 1 ± 0.3 m/s, heading weaving ±40°, GPS and gyro noise."""
    m = blue_lady_model()
    rng = np.random.default_rng(seed)
    t = np.arange(steps + 1) * DT
    psi = 0.5 * np.sin(0.01 * t) + 0.2 * np.sin(0.05 * t)
    r = 0.005 * np.cos(0.01 * t) + 0.01 * np.cos(0.05 * t)
    speed = 1.0 + 0.3 * np.sin(0.02 * t)
    vx, vy = speed * np.cos(psi), speed * np.sin(psi)
    x = np.concatenate([[0.0], np.cumsum(0.5 * (vx[1:] + vx[:-1]) * DT)])
    y = np.concatenate([[0.0], np.cumsum(0.5 * (vy[1:] + vy[:-1]) * DT)])
    truth = np.stack([vx, x, vy, y, r, psi], axis=1)
    meas = truth[:, POSITION] + rng.standard_normal((steps + 1, 3)) * np.sqrt(np.diag(m.R_sample))
    return m, truth, meas


def test_riccati_solution_converges_to_the_care() -> None:
    m = blue_lady_model()
    kb = KalmanBucyFilter(m.A, m.B, m.C, m.G, m.Q, R=m.intensity_R(DT), dt_s=DT, x0=np.zeros(6),
                          P0=np.diag([1.0, 1.0, 1.0, 1.0, 0.01, 0.01]))
    initial_substeps = kb.substeps_for(kb.P)
    assert initial_substeps > 10                           # stiff at the start: many RK4 substeps
    for _ in range(2000):
        kb.step(np.zeros(3))
    care = solve_continuous_are(m.A.T, m.C.T, m.G @ m.Q @ m.G.T, m.intensity_R(DT))
    assert np.allclose(kb.P, care, rtol=1e-9, atol=1e-12 * np.abs(care).max())
    assert kb.substeps_for(kb.P) <= 3 < initial_substeps   # and cheap in steady state
    assert np.allclose(kb.gain, care @ m.C.T @ np.linalg.inv(m.intensity_R(DT)))


def test_kalman_bucy_and_discrete_filter_agree_on_the_velocities() -> None:
    steps = 3000
    m, truth, meas = _trajectory(steps, seed=1)
    x0 = np.zeros(6)
    x0[POSITION] = meas[0]
    P0 = np.diag([1.0, 0.1, 1.0, 0.1, 1e-4, 1e-4])
    kb = KalmanBucyFilter(m.A, m.B, m.C, m.G, m.Q, R=m.intensity_R(DT), dt_s=DT, x0=x0, P0=P0)
    dkf = discrete_counterpart(m, DT, x0=x0, P0=P0)
    x_kb = np.zeros((steps, 6))
    x_prior = np.zeros((steps, 6))
    for k in range(steps):
        dkf.correct(meas[k] - m.C @ dkf.x)          # seed 004 eqs. (14), (23), (24)
        dkf.predict(np.zeros(3))                    # eqs. (16), (19): x̄(k+1)
        x_prior[k] = dkf.x
        kb.step(meas[k])                            # integrates [t_k, t_k+1] with y_k held
        x_kb[k] = kb.x
    start = 300
    truth_next = truth[1:steps + 1]
    err_kb = np.sqrt(np.mean((x_kb[start:] - truth_next[start:]) ** 2, axis=0))
    err_d = np.sqrt(np.mean((x_prior[start:] - truth_next[start:]) ** 2, axis=0))
    diff = np.sqrt(np.mean((x_kb[start:] - x_prior[start:]) ** 2, axis=0))
    # both estimate the velocities from positions only, to the same accuracy …
    assert np.all(err_kb[VELOCITY] < 1.1 * err_d[VELOCITY]) and np.all(err_d[VELOCITY] < 1.1 * err_kb[VELOCITY])
    assert err_kb[VELOCITY][0] < 0.15 and err_kb[VELOCITY][2] < math.radians(0.2)
    # … and agree with each other far better than either agrees with the truth
    assert np.all(diff[VELOCITY] < 0.15 * err_d[VELOCITY])
    # positions: the held sample makes the continuous filter lag by about half a period (|v|·Δt/2)
    assert np.all(diff[POSITION][:2] < 1.3 * 0.5 * DT + 0.02)


def test_body_velocity_rotation_seed_004_eq_60() -> None:
    steps = 2000
    m, truth, meas = _trajectory(steps, seed=2)
    x0 = np.zeros(6)
    x0[POSITION] = meas[0]
    kb = KalmanBucyFilter(m.A, m.B, m.C, m.G, m.Q, R=m.intensity_R(DT), dt_s=DT, x0=x0,
                          P0=np.diag([1.0, 0.1, 1.0, 0.1, 1e-4, 1e-4]))
    errors = []
    for k in range(steps):
        kb.step(meas[k])
        nu_hat = body_velocity(kb.x[VELOCITY], kb.x[5])
        nu_true = body_velocity(truth[k + 1, VELOCITY], truth[k + 1, 5])
        errors.append(nu_hat - nu_true)
        # the true surge speed and zero sway come out of eq. (60) for the generated track
        assert math.isclose(nu_true[0], 1.0 + 0.3 * math.sin(0.02 * (k + 1) * DT), abs_tol=1e-9)
        assert abs(nu_true[1]) < 1e-9
    errors = np.array(errors)[300:]
    assert np.sqrt(np.mean(errors[:, 0] ** 2)) < 0.15 and np.sqrt(np.mean(errors[:, 1] ** 2)) < 0.15


@given(psi=st.floats(-math.pi, math.pi), vx=st.floats(-5, 5), vy=st.floats(-5, 5))
@settings(max_examples=50, deadline=None)
def test_body_velocity_is_the_transposed_rotation(psi: float, vx: float, vy: float) -> None:
    nu = body_velocity(np.array([vx, vy, 0.1]), psi)
    c, s = math.cos(psi), math.sin(psi)
    assert np.allclose([c * nu[0] - s * nu[1], s * nu[0] + c * nu[1]], [vx, vy], atol=1e-12)
    assert nu[2] == 0.1


def test_eq_31_noise_is_an_approximation_that_barely_moves_the_estimates() -> None:
    """Seed 004 eq. (31) ``Q_k = GQGᵀΔt`` drops the velocity–position correlation the exact integral has;
    the velocity estimates hardly notice."""
    steps = 2000
    m, truth, meas = _trajectory(steps, seed=3)
    x0 = np.zeros(6)
    x0[POSITION] = meas[0]
    P0 = np.diag([1.0, 0.1, 1.0, 0.1, 1e-4, 1e-4])
    exact = discrete_counterpart(m, DT, x0=x0, P0=P0, exact_noise=True)
    approx = discrete_counterpart(m, DT, x0=x0, P0=P0)
    assert exact.Qd[0, 1] > 0.0 and approx.Qd[0, 1] == 0.0
    assert np.allclose(np.diag(exact.Qd)[VELOCITY], np.diag(approx.Qd)[VELOCITY], rtol=1e-6)
    est = {"exact": np.zeros((steps, 6)), "approx": np.zeros((steps, 6))}
    for k in range(steps):
        for name, f in (("exact", exact), ("approx", approx)):
            f.correct(meas[k] - m.C @ f.x)
            est[name][k] = f.x
            f.predict(np.zeros(3))
    err = np.sqrt(np.mean((est["exact"][300:] - truth[300:steps]) ** 2, axis=0))
    diff = np.sqrt(np.mean((est["exact"][300:] - est["approx"][300:]) ** 2, axis=0))
    assert np.all(diff[VELOCITY] < 0.2 * err[VELOCITY])


def test_kalman_bucy_rejects_bad_settings() -> None:
    m = blue_lady_model()
    with pytest.raises(ValueError):
        KalmanBucyFilter(m.A, m.B, m.C, m.G, m.Q, R=m.intensity_R(DT), dt_s=0.0, x0=np.zeros(6), P0=np.eye(6))


def test_a_reset_starts_the_riccati_equation_near_the_measurement_noise_not_stiff() -> None:
    # P0 = I (1 rad² of heading against a 0.1 deg² sample) needed ~800 RK4 substeps per 0.1 s period after
    # every reset: 0.1 s of CPU per control cycle for the first seconds, a missed deadline each cycle
    estimator = KalmanBucyEstimator(0.1)
    estimator.reset(np.array([10.0, -5.0, math.radians(30.0)]))
    f = estimator._filter
    assert f is not None
    assert f.substeps_for(f.P) <= 10
    model = blue_lady_model()
    assert np.allclose(np.diag(f.P)[[1, 3, 5]], np.diag(model.R_sample))  # positions: one sample's variance
    for _ in range(20):
        estimator.step(np.array([10.0, -5.0, math.radians(30.0)]), np.zeros(3))
    assert estimator._filter.substeps_for(estimator._filter.P) <= 10
