"""Course-keeping heading Kalman filter, seed 002 eqs. (69)–(81), mariner autopilot case."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dpbase.frames import ssa
from dpcontrol.estimation.discretize import discretize
from dpcontrol.estimation.heading import (
    MARINER_COMPASS_STD_RAD,
    MARINER_K_PER_S,
    MARINER_OMEGA0_RAD_S,
    MARINER_SAMPLE_TIME_S,
    MARINER_T_S,
    MARINER_WAVE_INTENSITY,
    MARINER_ZETA,
    heading_model,
    mariner_heading_filter,
)
from dpcontrol.models.vessels import MARINER


def test_model_matrices_are_seed_002_eqs_80_81() -> None:
    m = heading_model(gain_per_s=0.185, time_constant_s=107.3, omega0_rad_s=1.2, zeta=0.1, wave_intensity=1.0,
                      yaw_accel_intensity=2.0, bias_intensity=3.0, compass_std_rad=0.01)
    A = np.array([[0, 1, 0, 0, 0], [-1.44, -0.24, 0, 0, 0], [0, 0, 0, 1, 0], [0, 0, 0, -1 / 107.3, 1],
                  [0, 0, 0, 0, 0]])
    assert np.allclose(m.A, A)
    assert np.allclose(m.B.ravel(), [0, 0, 0, 0.185 / 107.3, 0])
    assert np.array_equal(m.E, [[0, 0, 0], [1, 0, 0], [0, 0, 0], [0, 1, 0], [0, 0, 1]])
    assert np.array_equal(m.H, [[0, 1, 1, 0, 0]])
    assert np.allclose(np.diag(m.Qc), [1.0, 2.0, 3.0]) and math.isclose(m.R[0, 0], 1e-4)
    # the mariner case uses the vessel data of seed 002 and the stated sample period
    assert MARINER.nomoto_gain_per_s == MARINER_K_PER_S and MARINER.nomoto_time_constant_s == MARINER_T_S
    assert MARINER_SAMPLE_TIME_S == 0.5 and math.isclose(math.degrees(MARINER_COMPASS_STD_RAD), 0.5)
    # σ_w1² = 300 read in deg²/s³: a WF yaw of √(300/(4ζω0)) = 25° standard deviation
    assert math.isclose(math.degrees(math.sqrt(MARINER_WAVE_INTENSITY / (4 * MARINER_ZETA * MARINER_OMEGA0_RAD_S))),
                        25.0)


def _simulate(psi_commands, seconds: float, seed: int, psi0: float = 0.0, dropouts=()):
    """Nomoto ship (with a 1° rudder offset) + 2nd-order wave yaw, autopilot on the filtered heading."""
    rng = np.random.default_rng(seed)
    f = mariner_heading_filter(psi0_rad=psi0)
    h = MARINER_SAMPLE_TIME_S
    wave = heading_model(gain_per_s=MARINER_K_PER_S, time_constant_s=MARINER_T_S,
                         omega0_rad_s=MARINER_OMEGA0_RAD_S, zeta=MARINER_ZETA,
                         wave_intensity=MARINER_WAVE_INTENSITY, yaw_accel_intensity=0.0, bias_intensity=0.0,
                         compass_std_rad=MARINER_COMPASS_STD_RAD)
    d = discretize(wave.A[0:2, 0:2], np.zeros((2, 1)), wave.E[0:2, 0:1], wave.Qc[0:1, 0:1], h)
    chol = np.linalg.cholesky(d.Qd)
    xw = chol @ rng.standard_normal(2) * 3.0
    psi, r = psi0, 0.0
    offset = math.radians(1.0)
    rows = []
    delta = 0.0
    for k in range(int(seconds / h)):
        t = k * h
        psi_d = psi_commands(t)
        y = ssa(psi + xw[1] + rng.normal(0.0, MARINER_COMPASS_STD_RAD))
        meas = None if any(a <= t < b for a, b in dropouts) else y
        est = f.step(meas, delta)
        rows.append((t, psi, r, xw[1], est.psi_hat_rad, est.r_hat_radps, est.psi_wf_hat_rad, est.bias_hat_radps2))
        # PD autopilot on the LF estimate (seed 002 eq. (64) without the integral term), rudder ±35°
        delta = float(np.clip(-1.5 * ssa(est.psi_hat_rad - psi_d) - 60.0 * est.r_hat_radps, -0.61, 0.61))
        for _ in range(10):                                       # Nomoto (seed 002 eq. (57)), fine Euler
            r += h / 10 * (-r / MARINER_T_S + MARINER_K_PER_S / MARINER_T_S * (delta + offset))
            psi += h / 10 * r
        xw = d.Phi @ xw + chol @ rng.standard_normal(2)
    return np.array(rows), offset


def test_lf_heading_and_wf_yaw_are_separated() -> None:
    rows, offset = _simulate(lambda t: math.radians(20.0) if t >= 300.0 else 0.0, 1500.0, seed=1)
    t, psi, r, psi_w, psi_hat, r_hat, psi_w_hat, b_hat = rows.T
    settled = t > 200.0
    lf_err = np.degrees(np.abs(ssa_all(psi_hat - psi)))[settled]
    wf_err = np.degrees(np.abs(psi_w_hat - psi_w))[settled]
    wf_std = np.degrees(np.std(psi_w[settled]))
    assert wf_std > 15.0                                            # a large wave yaw is present …
    assert np.sqrt(np.mean(lf_err**2)) < 1.5 and lf_err.max() < 5.0  # … and stays out of the LF heading
    assert np.sqrt(np.mean(wf_err**2)) < 1.5                          # the WF heading is estimated
    assert np.degrees(np.sqrt(np.mean((r_hat - r)[settled] ** 2))) < 0.05
    # the bias state takes up the rudder offset (K/T·δ0)
    assert abs(b_hat[-1] - MARINER_K_PER_S / MARINER_T_S * offset) < 0.3 * MARINER_K_PER_S / MARINER_T_S * offset
    # and the autopilot, fed with the filtered heading, did the course change
    assert abs(math.degrees(ssa(psi[-1] - math.radians(20.0)))) < 2.0


def ssa_all(values: np.ndarray) -> np.ndarray:
    return np.array([ssa(v) for v in values])


def test_course_change_across_180_degrees_and_compass_dropouts() -> None:
    rows, _ = _simulate(lambda t: math.radians(-170.0) if t >= 200.0 else math.radians(170.0), 1200.0, seed=2,
                        psi0=math.radians(170.0), dropouts=((600.0, 620.0),))
    t, psi, _, _, psi_hat, _, _, _ = rows.T
    assert np.all((psi_hat > -math.pi) & (psi_hat <= math.pi))
    err = np.degrees(np.abs(ssa_all(psi_hat - psi)))
    assert err[t > 150.0].max() < 5.0
    assert abs(math.degrees(ssa(psi[-1] - math.radians(-170.0)))) < 2.0   # turned the short way through 180°
    assert abs(math.degrees(psi[-1] - psi[0])) < 30.0


def test_bad_rudder_input_raises_before_changing_the_filter() -> None:
    f = mariner_heading_filter()
    f.step(0.01, 0.0)
    x = f.filter.x.copy()
    with pytest.raises(ValueError, match="rudder"):
        f.step(0.02, math.nan)
    assert np.array_equal(f.filter.x, x)
