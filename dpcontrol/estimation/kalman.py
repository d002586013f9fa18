"""Discrete Kalman filter (seed 002 eqs. (51)–(54)) in Joseph form, and steady-state gains (DARE).

* :class:`KalmanFilter` — the time-varying filter. The covariance update uses the Joseph form
  ``P = (I − KH) P⁻ (I − KH)ᵀ + K R Kᵀ``, which keeps P symmetric positive semidefinite for any
  gain and under rounding (seed 002 recommends a numerically safe form after eq. (54)); the
  innovation covariance is factored with Cholesky instead of inverted.
* :func:`steady_state_filter` — the stationary prior covariance from the discrete algebraic Riccati
  equation (seed 000 eq. (17a) in discrete time), solved by ``scipy.linalg.solve_discrete_are``.
* :func:`pattern_gains` — one gain set per measurement-availability pattern (position and heading
  arrive separately). A pattern that lacks a channel has no stationary solution of its own (the
  unmeasured position is not detectable), so each pattern's gain is the optimal one-sample gain
  from the full-measurement stationary prior ``P⁻``: ``K_π = P⁻H_πᵀ(H_πP⁻H_πᵀ + R_π)⁻¹``. It is
  exact for an isolated drop-out; during long drop-outs the filter predicts with its model ("dead
  reckoning") and the fixed gains stay bounded.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import cho_factor, cho_solve, solve_discrete_are

#: The 8 availability patterns of (north, east, heading), full measurement first.
PATTERNS: tuple[tuple[bool, bool, bool], ...] = tuple(
    sorted(((n, e, h) for n in (True, False) for e in (True, False) for h in (True, False)), key=lambda p: -sum(p)))


def pattern_code(measured: tuple[bool, bool, bool]) -> int:
    """Bit code of an availability pattern: bit 0 north, bit 1 east, bit 2 heading."""
    return int(bool(measured[0])) | (int(bool(measured[1])) << 1) | (int(bool(measured[2])) << 2)


class KalmanFilter:
    """Time-varying discrete Kalman filter, seed 002 eqs. (51)–(54), Joseph-form update.

    Parameters
    ----------
    Phi : ndarray, shape (n, n)
        Transition matrix Φ.
    Gamma : ndarray, shape (n, m)
        Input matrix Γ (seed 002 eq. (43), computed without A⁻¹).
    H : ndarray, shape (q, n)
        Measurement matrix.
    Qd : ndarray, shape (n, n)
        Discrete process-noise covariance.
    R : ndarray, shape (q, q)
        Measurement-noise covariance (per sample).
    x0 : ndarray, shape (n,)
        Initial prior state x̄(0).
    P0 : ndarray, shape (n, n)
        Initial prior covariance P̄(0), symmetric positive definite.

    Notes
    -----
    Arrays are copied; ``x`` and ``P`` hold the current estimate (prior after :meth:`predict`,
    posterior after :meth:`correct`).
    """

    def __init__(self, Phi: np.ndarray, Gamma: np.ndarray, H: np.ndarray, Qd: np.ndarray, R: np.ndarray, *,
                 x0: np.ndarray, P0: np.ndarray) -> None:
        self.Phi = np.array(Phi, dtype=float)
        self.Gamma = np.array(Gamma, dtype=float)
        self.H = np.array(H, dtype=float)
        self.Qd = np.array(Qd, dtype=float)
        self.R = np.array(R, dtype=float)
        self.x = np.array(x0, dtype=float)
        self.P = np.array(P0, dtype=float)
        n = self.Phi.shape[0]
        if self.x.shape != (n,) or self.P.shape != (n, n):
            raise ValueError("x0 must be (n,) and P0 (n, n)")
        self._eye = np.eye(n)
        self.K = np.zeros((n, self.H.shape[0]))
        self.S = self.H @ self.P @ self.H.T + self.R

    def innovation_covariance(self, rows: np.ndarray | None = None) -> np.ndarray:
        """S = H P Hᵀ + R for the measured rows (all rows if None)."""
        H = self.H if rows is None else self.H[rows]
        R = self.R if rows is None else self.R[np.ix_(rows, rows)]
        return H @ self.P @ H.T + R

    def correct(self, innovation: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
        """Measurement update, seed 002 eqs. (51), (53) and (54) (Joseph form).

        Parameters
        ----------
        innovation : ndarray, shape (q_used,)
            ``y − H x̄`` on the measured rows (the caller wraps angles with ``ssa``).
        rows : ndarray of int or None
            Which measurement rows are present (None: all).

        Returns
        -------
        ndarray, shape (q_used, q_used)
            The innovation covariance S used.
        """
        H = self.H if rows is None else self.H[rows]
        R = self.R if rows is None else self.R[np.ix_(rows, rows)]
        S = H @ self.P @ H.T + R
        PHt = self.P @ H.T
        K = cho_solve(cho_factor(S), PHt.T).T          # K = P Hᵀ S⁻¹ (seed 002 eq. (53))
        self.x = self.x + K @ innovation               # seed 002 eq. (51)
        I_KH = self._eye - K @ H
        P = I_KH @ self.P @ I_KH.T + K @ R @ K.T      # Joseph form of seed 002 eq. (54)
        self.P = 0.5 * (P + P.T)
        self.K = K
        self.S = S
        return S

    def predict(self, u: np.ndarray) -> None:
        """Time update, seed 002 eqs. (52) and (54): x̄ = Φx̂ + Γu, P̄ = ΦP̂Φᵀ + Qd."""
        self.x = self.Phi @ self.x + self.Gamma @ u
        P = self.Phi @ self.P @ self.Phi.T + self.Qd
        self.P = 0.5 * (P + P.T)


@dataclass(frozen=True, eq=False)
class SteadyStateFilter:
    """Stationary Kalman filter quantities for one measurement pattern.

    Attributes
    ----------
    P_prior : ndarray, shape (n, n)
        Stationary one-step prediction covariance P̄ (DARE solution).
    P_post : ndarray, shape (n, n)
        Covariance after the update, Joseph form.
    K : ndarray, shape (n, 3)
        Gain; columns of unmeasured channels are zero.
    S : ndarray, shape (3, 3)
        Innovation covariance ``H P̄ Hᵀ + R`` (all three channels, for the predicted-measurement test).
    S_inv : ndarray, shape (3, 3)
        Inverse of S on the measured channels, zero elsewhere.
    log_det_S : float
        log det of S on the measured channels (0 when nothing is measured).
    """

    P_prior: np.ndarray
    P_post: np.ndarray
    K: np.ndarray
    S: np.ndarray
    S_inv: np.ndarray
    log_det_S: float


def is_covariance(P: np.ndarray, tolerance: float = 1e-9) -> bool:
    """Whether ``P`` (n, n) is a symmetric positive semidefinite covariance, judged scale-free.

    A DP filter's covariance spans ~20 orders of magnitude (10⁻⁷ m² on a position, 10¹¹ N² on a bias
    force), so an eigenvalue test on ``P`` itself sees rounding errors of ~10⁻¹⁶·λ_max as negative
    eigenvalues. The test is made on the correlation matrix ``D^-½ P D^-½`` (D = diag P) instead, whose
    eigenvalues lie in [0, n] whatever the units: ``P`` passes when it is symmetric to ``tolerance``
    (relative), its diagonal is ≥ 0, and the correlation matrix's smallest eigenvalue is ≥ −``tolerance``.
    """
    if P.ndim != 2 or P.shape[0] != P.shape[1] or not np.all(np.isfinite(P)):
        return False
    if not np.allclose(P, P.T, rtol=tolerance, atol=0.0):
        return False
    d = np.diag(P)
    if np.any(d < 0.0):
        return False
    positive = d > 0.0
    # a zero variance needs zero covariances with every other state
    if np.any(P[~positive][:, positive] != 0.0):
        return False
    scale = 1.0 / np.sqrt(d[positive])
    sym = 0.5 * (P + P.T)[np.ix_(positive, positive)]
    corr = sym * scale[:, None] * scale[None, :]
    return bool(corr.size == 0 or np.linalg.eigvalsh(corr).min() >= -tolerance)


def solve_prior_covariance(Phi: np.ndarray, H: np.ndarray, Qd: np.ndarray, R: np.ndarray) -> np.ndarray:
    """Stationary prior covariance P̄ of the filter DARE (seed 000 eq. (17a), discrete time).

    ``P̄ = Φ P̄ Φᵀ − Φ P̄ Hᵀ (H P̄ Hᵀ + R)⁻¹ H P̄ Φᵀ + Qd`` — the control DARE of ``(Φᵀ, Hᵀ)``.

    Raises
    ------
    ValueError
        When the pair is not detectable/stabilisable (no stabilising solution).
    """
    try:
        P = solve_discrete_are(Phi.T, H.T, Qd, R)
    except (np.linalg.LinAlgError, ValueError) as error:
        raise ValueError(f"no stabilising solution of the filter Riccati equation: {error}") from None
    return 0.5 * (P + P.T)


def gain_for_prior(P_prior: np.ndarray, H: np.ndarray, R: np.ndarray,
                   measured: tuple[bool, bool, bool]) -> SteadyStateFilter:
    """Gain, posterior covariance and innovation statistics for one availability pattern."""
    n = P_prior.shape[0]
    q = H.shape[0]
    rows = np.flatnonzero(np.asarray(measured, dtype=bool))
    S_full = H @ P_prior @ H.T + R
    K = np.zeros((n, q))
    S_inv = np.zeros((q, q))
    P_post = P_prior.copy()
    log_det = 0.0
    if rows.size:
        H_r = H[rows]
        R_r = R[np.ix_(rows, rows)]
        S_r = S_full[np.ix_(rows, rows)]
        factor = cho_factor(S_r)
        K_r = cho_solve(factor, H_r @ P_prior).T
        K[:, rows] = K_r
        S_inv[np.ix_(rows, rows)] = cho_solve(factor, np.eye(rows.size))
        log_det = float(2.0 * np.sum(np.log(np.diag(factor[0]))))
        I_KH = np.eye(n) - K_r @ H_r
        P_post = I_KH @ P_prior @ I_KH.T + K_r @ R_r @ K_r.T
        P_post = 0.5 * (P_post + P_post.T)
    return SteadyStateFilter(P_prior=P_prior, P_post=P_post, K=K, S=S_full, S_inv=S_inv, log_det_S=log_det)


def steady_state_filter(Phi: np.ndarray, H: np.ndarray, Qd: np.ndarray, R: np.ndarray) -> SteadyStateFilter:
    """Steady-state Kalman filter for the full measurement (DARE + gain)."""
    return gain_for_prior(solve_prior_covariance(Phi, H, Qd, R), H, R, (True,) * H.shape[0])


def pattern_gains(Phi: np.ndarray, H: np.ndarray, Qd: np.ndarray,
                  R: np.ndarray) -> dict[int, SteadyStateFilter]:
    """Gain sets for all 8 availability patterns, keyed by :func:`pattern_code`.

    See the module docstring: every pattern uses the full-measurement stationary prior.
    """
    P_prior = solve_prior_covariance(Phi, H, Qd, R)
    return {pattern_code(p): gain_for_prior(P_prior, H, R, p) for p in PATTERNS}
