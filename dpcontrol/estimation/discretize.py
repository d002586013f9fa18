"""Exact zero-order-hold discretisation with the process noise integrated (Van Loan 1978).

Seed 002 eqs. (40)–(44) give ``Φ = exp(Ah)`` and ``Δ = A⁻¹(Φ − I)B``; A is singular here (the
ηp integrator, the random-walk bias), so the input matrix is taken from the augmented exponential
instead, which needs no inverse::

    exp([[A, B], [0, 0]] h) = [[Φ, Γ], [0, I]],          Γ = ∫₀ʰ e^{As} ds B

and the discrete process-noise covariance is the Van Loan integral (not ``E Qc Eᵀ h``)::

    exp([[−A, E Qc Eᵀ], [0, Aᵀ]] h) = [[·, F12], [0, F22]],   Qd = F22ᵀ F12
                                                              = ∫₀ʰ e^{As} E Qc Eᵀ e^{Aᵀs} ds

scipy's ``expm`` (Padé with scaling and squaring) does the exponentials; ``expm_frechet`` gives the
exact derivative ∂Φ/∂ω0 used by the RPEM sensitivity (seed 003 eq. (13)) — the upper-right block of
``exp([[A, ∂A], [0, A]] h)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.linalg import expm, expm_frechet


@dataclass(frozen=True, eq=False)
class DiscreteModel:
    """``x(k+1) = Φ x(k) + Γ u(k) + w(k)``, ``Cov w(k) = Qd`` (seed 002 eq. (40)).

    Attributes
    ----------
    Phi : ndarray, shape (n, n)
    Gamma : ndarray, shape (n, m)
    Qd : ndarray, shape (n, n)
        Symmetric positive semidefinite.
    sample_time_s : float
    """

    Phi: np.ndarray
    Gamma: np.ndarray
    Qd: np.ndarray
    sample_time_s: float


def zoh_input_matrix(A: np.ndarray, B: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """Φ = e^{Ah} and Γ = ∫₀ʰ e^{As} ds B from one augmented exponential (A may be singular)."""
    n, m = B.shape
    aug = np.zeros((n + m, n + m))
    aug[:n, :n] = A
    aug[:n, n:] = B
    F = expm(aug * h)
    return F[:n, :n].copy(), F[:n, n:].copy()


def van_loan_noise(A: np.ndarray, E: np.ndarray, Qc: np.ndarray, h: float) -> np.ndarray:
    """Qd = ∫₀ʰ e^{As} E Qc Eᵀ e^{Aᵀs} ds by Van Loan's method (returned exactly symmetric)."""
    n = A.shape[0]
    aug = np.zeros((2 * n, 2 * n))
    aug[:n, :n] = -A
    aug[:n, n:] = E @ Qc @ E.T
    aug[n:, n:] = A.T
    F = expm(aug * h)
    Qd = F[n:, n:].T @ F[:n, n:]
    return 0.5 * (Qd + Qd.T)


def discretize(A: np.ndarray, B: np.ndarray, E: np.ndarray, Qc: np.ndarray, h: float) -> DiscreteModel:
    """Exact discretisation of ``ẋ = Ax + Bu + Ew`` (white w of intensity Qc) over the period h [s]."""
    if not h > 0.0:
        raise ValueError(f"sample time must be > 0 s, got {h}")
    Phi, Gamma = zoh_input_matrix(A, B, h)
    return DiscreteModel(Phi=Phi, Gamma=Gamma, Qd=van_loan_noise(A, E, Qc, h), sample_time_s=float(h))


def transition_derivative(A: np.ndarray, dA: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """Φ = e^{Ah} and its exact derivative ∂Φ/∂θ for ∂A/∂θ = dA (Fréchet derivative of expm).

    Equals the upper-right block of ``exp([[A, dA], [0, A]] h)`` (block-triangular exponential).
    """
    return expm_frechet(A * h, dA * h, compute_expm=True)


def oscillator_discretization(omega_rad_s: float, zeta: float, h: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Closed-form Φ, ∂Φ/∂ω0 and unit-intensity Qd of one WF degree of freedom (0 < ζ < 1).

    For ``A = [[0, 1], [−ω0², −2ζω0]]`` (seed 000 eq. (1)) and noise input ``[0, 1]ᵀ``, with
    ``σ = ζω0``, ``ω_d = βω0``, ``β = √(1 − ζ²)``, ``E = e^{−σh}``, ``c = cos ω_d h``, ``s = sin ω_d h``::

        Φ = E [[c + (ζ/β)s,  s/ω_d], [−(ω0/β)s,  c − (ζ/β)s]]

    ∂Φ/∂ω0 is its exact derivative, and ``Qd = P∞ − Φ P∞ Φᵀ`` with the stationary covariance
    ``P∞ = diag(1/(4ζω0³), 1/(4ζω0))`` (exact for the stable oscillator, equal to the Van Loan integral).

    Written out by hand because the RPEM filter re-discretises this block at every sample as ω̂0
    moves: the closed form costs a few microseconds where ``expm_frechet`` + ``expm`` cost hundreds
    (and more under load). The tests check it against :func:`transition_derivative` and
    :func:`van_loan_noise`.

    Returns
    -------
    Phi, dPhi, Qd_unit : ndarray, shape (2, 2)
    """
    if not (omega_rad_s > 0.0 and 0.0 < zeta < 1.0 and h > 0.0):
        raise ValueError(f"needs ω0 > 0, 0 < ζ < 1, h > 0; got {omega_rad_s}, {zeta}, {h}")
    w = omega_rad_s
    beta = math.sqrt(1.0 - zeta * zeta)
    wd = beta * w
    E = math.exp(-zeta * w * h)
    c = math.cos(wd * h)
    s = math.sin(wd * h)
    r = zeta / beta
    Phi = E * np.array([[c + r * s, s / wd], [-(w / beta) * s, c - r * s]])
    t = h
    dPhi = np.array([
        [-E * t * s / beta,
         (E * (-zeta * t * s + beta * t * c)) / wd - E * s / (w * wd)],
        [-(E / beta) * (-zeta * t * w * s + s + w * beta * t * c),
         E * (-2.0 * zeta * t * c + t * s * (2.0 * zeta * zeta - 1.0) / beta)],
    ])
    P_inf = np.diag([1.0 / (4.0 * zeta * w**3), 1.0 / (4.0 * zeta * w)])
    Qd = P_inf - Phi @ P_inf @ Phi.T
    return Phi, dPhi, 0.5 * (Qd + Qd.T)
