"""Kalman–Bucy filter for the Blue Lady kinematic model (seed 004) and its discrete counterpart.

Model (seed 004 eqs. (53)–(59)): three decoupled double integrators in the earth frame, one per
degree of freedom, state ``x_j = [velocity, position]``::

    A_j = [[0, 0], [1, 0]],   B_j = [1, 0]ᵀ,   C_j = [0, 1]            (seed 004 eq. (58))

so ``x = [u_x, x, v_y, y, r, ψ]`` (6,), input u = accelerations [m/s², m/s², rad/s²] (zero when the
forces are unknown, as on the training ship), measurement ``y = [x, y, ψ]``. Noise matrices G, Q, R of
seed 004 eqs. (61)–(62)::

    G_x = G_y = [[1, 0], [0, 0.01]],  Q_x = Q_y = diag(0.1, 0.2),  R_x = R_y = 0.01
    G_ψ = diag(0.2, 0.01),            Q_ψ = I,                     R_ψ = 0.1

Units (seed 004 gives none): positions in m; R_x = 0.01 m² is the variance of one GPS sample
("determined based on the experimental tests"); the heading entries are read in **degrees**
(R_ψ = 0.1 deg², a gyro compass — 0.1 rad² would be an 18° standard deviation) and the whole ψ
degree of freedom is converted to SI by (π/180)². Q is the continuous intensity of the Kalman–Bucy
filter (seed 004 eq. (45)).

Filters
-------
* :class:`KalmanBucyFilter` — seed 004 eqs. (39), (45), (52): ``L = P Cᵀ R⁻¹``,
  ``Ṗ = AP + PAᵀ + GQGᵀ − PCᵀR⁻¹CP``, ``x̂̇ = Ax̂ + Bu + L(y − Cx̂)``, with the sampled measurement
  held over each period (the averaging of seed 004 eq. (32)) and ``R = R_k Δt`` (eq. (35)); the
  Riccati and state equations are integrated together with classical RK4, with as many substeps
  as the stiffness of the Riccati equation needs (a large P0 makes it stiff at the start).
* :func:`discrete_counterpart` — the discrete filter of seed 004 eqs. (14), (16), (19), (23), (24):
  ``Q_k = G Q Gᵀ Δt`` (eq. (31)) or the exact Van Loan integral, ``R_k = R/Δt`` (eq. (35)); run by
  :class:`~dpcontrol.estimation.kalman.KalmanFilter` (Joseph form, algebraically eq. (24)).
* :func:`body_velocity` — seed 004 eq. (60), earth-frame velocities to ``ν = [u, v, r]``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.linalg import block_diag, cho_factor, cho_solve

from dpbase.frames import ned_to_body
from dpcontrol.estimation.discretize import van_loan_noise, zoh_input_matrix
from dpcontrol.estimation.kalman import KalmanFilter

_DEG2 = (math.pi / 180.0) ** 2


@dataclass(frozen=True, eq=False)
class KinematicModel:
    """Continuous model ``ẋ = Ax + Bu + Gw``, ``y = Cx + v`` of seed 004 eqs. (56)–(62), SI units.

    Attributes
    ----------
    A : ndarray, shape (6, 6)
    B : ndarray, shape (6, 3)
    C : ndarray, shape (3, 6)
    G : ndarray, shape (6, 6)
    Q : ndarray, shape (6, 6)
        Continuous intensity of w.
    R_sample : ndarray, shape (3, 3)
        Variance of one measurement sample [m², m², rad²].
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    G: np.ndarray
    Q: np.ndarray
    R_sample: np.ndarray

    def intensity_R(self, dt_s: float) -> np.ndarray:
        """Continuous measurement-noise intensity ``R = R_k Δt`` (seed 004 eq. (35))."""
        return self.R_sample * dt_s


#: Indices of the velocity and position states of each degree of freedom in x (6,).
VELOCITY = np.array([0, 2, 4])
POSITION = np.array([1, 3, 5])


def blue_lady_model() -> KinematicModel:
    """The Blue Lady model of seed 004 eqs. (58), (61), (62) in SI units (see module docstring)."""
    a = np.array([[0.0, 0.0], [1.0, 0.0]])
    b = np.array([[1.0], [0.0]])
    c = np.array([[0.0, 1.0]])
    g_xy = np.array([[1.0, 0.0], [0.0, 0.01]])
    q_xy = np.diag([0.1, 0.2])
    g_psi = np.diag([0.2, 0.01])
    q_psi = np.eye(2) * _DEG2
    return KinematicModel(
        A=block_diag(a, a, a), B=block_diag(b, b, b), C=block_diag(c, c, c),
        G=block_diag(g_xy, g_xy, g_psi), Q=block_diag(q_xy, q_xy, q_psi),
        R_sample=np.diag([0.01, 0.01, 0.1 * _DEG2]))


class KalmanBucyFilter:
    """Continuous Kalman–Bucy filter (seed 004 eqs. (39), (45), (52)) stepped at the sample rate.

    Parameters
    ----------
    A, B, C, G, Q : ndarray
        Continuous model; Q the intensity of w.
    R : ndarray, shape (q, q)
        Continuous measurement-noise intensity (``R_k Δt``, seed 004 eq. (35)).
    dt_s : float
        Sample period [s]; each :meth:`step` integrates one period with y and u held.
    x0 : ndarray, shape (n,)
    P0 : ndarray, shape (n, n)
        Initial covariance (seed 004 eq. (46)).
    substeps : int
        Minimum RK4 steps per period (more are taken while the Riccati equation is stiff, see
        :meth:`substeps_for`).
    """

    def __init__(self, A: np.ndarray, B: np.ndarray, C: np.ndarray, G: np.ndarray, Q: np.ndarray, *,
                 R: np.ndarray, dt_s: float, x0: np.ndarray, P0: np.ndarray, substeps: int = 1) -> None:
        if not dt_s > 0.0 or substeps < 1:
            raise ValueError("dt_s must be > 0 and substeps >= 1")
        self.A = np.asarray(A, dtype=float)
        self.B = np.asarray(B, dtype=float)
        self.C = np.asarray(C, dtype=float)
        self.GQGt = np.asarray(G, dtype=float) @ np.asarray(Q, dtype=float) @ np.asarray(G, dtype=float).T
        factor = cho_factor(np.asarray(R, dtype=float))
        self.Ct_Rinv = cho_solve(factor, self.C).T            # Cᵀ R⁻¹ (n, q)
        self.Ct_Rinv_C = self.Ct_Rinv @ self.C
        self.dt_s = float(dt_s)
        self.substeps = int(substeps)
        self.x = np.array(x0, dtype=float)
        self.P = np.array(P0, dtype=float)
        self._a_rate = 2.0 * float(np.max(np.abs(np.linalg.eigvals(self.A))))

    @property
    def gain(self) -> np.ndarray:
        """L = P Cᵀ R⁻¹ (seed 004 eq. (39))."""
        return self.P @ self.Ct_Rinv

    def _derivatives(self, x: np.ndarray, P: np.ndarray, y: np.ndarray,
                     u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        L = P @ self.Ct_Rinv
        x_dot = self.A @ x + self.B @ u + L @ (y - self.C @ x)                          # eq. (52)
        AP = self.A @ P
        P_dot = AP + AP.T + self.GQGt - P @ self.Ct_Rinv_C @ P                           # eq. (45)
        return x_dot, P_dot

    def substeps_for(self, P: np.ndarray) -> int:
        """RK4 substeps for one period: at least ``substeps``, and enough that ``h·ρ ≤ 1``.

        ρ = 2·tr(P Cᵀ R⁻¹ C) + 2·max|eig(A)| bounds the fastest mode of the Riccati equation linearised
        at P (its Jacobian is ``δP ↦ (A − PCᵀR⁻¹C)δP + δP(A − PCᵀR⁻¹C)ᵀ``); RK4 is stable for
        h·ρ up to about 2.8. The equation is stiff while P is far above its steady state (a large
        P0), so a fixed step would blow up there.
        """
        rate = 2.0 * float(np.einsum("ij,ji->", P, self.Ct_Rinv_C)) + self._a_rate
        return max(self.substeps, math.ceil(self.dt_s * rate))

    def step(self, y: np.ndarray, u: np.ndarray | None = None) -> None:
        """Integrate one sample period with the measurement y (and input u) held (RK4)."""
        y = np.asarray(y, dtype=float)
        u = np.zeros(self.B.shape[1]) if u is None else np.asarray(u, dtype=float)
        x, P = self.x, self.P
        count = self.substeps_for(P)
        h = self.dt_s / count
        for _ in range(count):
            k1x, k1P = self._derivatives(x, P, y, u)
            k2x, k2P = self._derivatives(x + 0.5 * h * k1x, P + 0.5 * h * k1P, y, u)
            k3x, k3P = self._derivatives(x + 0.5 * h * k2x, P + 0.5 * h * k2P, y, u)
            k4x, k4P = self._derivatives(x + h * k3x, P + h * k3P, y, u)
            x = x + h / 6.0 * (k1x + 2.0 * k2x + 2.0 * k3x + k4x)
            P = P + h / 6.0 * (k1P + 2.0 * k2P + 2.0 * k3P + k4P)
            P = 0.5 * (P + P.T)
        self.x, self.P = x, P


def discrete_counterpart(model: KinematicModel, dt_s: float, *, x0: np.ndarray, P0: np.ndarray,
                         exact_noise: bool = False) -> KalmanFilter:
    """The discrete Kalman filter of seed 004 eqs. (14), (16), (19), (23), (24) at period Δt.

    ``F = e^{AΔt}`` (eq. (5)), ``Γ = ∫ e^{As} ds B``, ``Q_k = G Q Gᵀ Δt`` (eq. (31); the exact Van Loan
    integral with ``exact_noise=True``), ``R_k`` = the sample variance (eq. (35): ``R/Δt``).
    """
    F, Gamma = zoh_input_matrix(model.A, model.B, dt_s)
    Qk = van_loan_noise(model.A, model.G, model.Q, dt_s) if exact_noise else model.G @ model.Q @ model.G.T * dt_s
    return KalmanFilter(F, Gamma, model.C, Qk, model.R_sample, x0=x0, P0=P0)


def body_velocity(earth_velocity: np.ndarray, psi_rad: float) -> np.ndarray:
    """ν = [u, v, r] from the earth-frame rates ``[ẋ, ẏ, ψ̇]`` (seed 004 eq. (60), ``ν = Rᵀ(ψ) η̇``)."""
    return ned_to_body(earth_velocity, psi_rad)
