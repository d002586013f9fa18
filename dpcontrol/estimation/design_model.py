"""Linear DP design model for the wave filters (seed 002 eqs. (30)–(39), seed 001 eqs. (33)–(38)).

One builder, :func:`dp_design_model`, covers both papers and the "wave filter off" case:

* seed 002 (and seed 000 eq. (14), whose ν row lacks the minus on M⁻¹D — seed 002 eq. (38) is
  right): random-walk bias ``ḃp = w3``;
* seed 001: first-order Markov bias ``ḃp = −T⁻¹bp + w3`` with time constants ``T = diag(Tx, Ty, Tψ)``;
* ``omega_rad_s=None``: the same low-frequency (LF) model with no wave states (``raw``).

State vector (vessel-parallel coordinates, seed 002 eq. (14) ``ηp = Rᵀ(ψ)η``), n = 15::

    x = [ ξ1 (3) | ξ2 = η_w (3) | ηp (3) | bp (3) | ν (3) ]
          0:3      3:6            6:9      9:12     12:15

and n = 9 without wave states (``x = [ηp, bp, ν]``). The wave-frequency (WF) motion is
``η_w = C_w ξ = ξ2`` (seed 000/001 ``C_w = [0 I]``): per degree of freedom the transfer function
from the driving noise to the WF motion is ``s / (s² + 2ζω0 s + ω0²)`` (seed 002 eq. (27) up to the
gain), whose power spectrum peaks at ω0. Continuous model, seed 002 eqs. (36)–(39)::

    ξ̇  = A_w(ω0) ξ + E_w w1
    η̇p = ν
    ḃp = −T⁻¹ bp + w3                      (T⁻¹ = 0: seed 002 random walk)
    ν̇  = M⁻¹ bp − M⁻¹D ν + M⁻¹ τ + M⁻¹ w2
    y  = ηp + ξ2 + v

Process noise ``w = [w1, w2, w3]`` (9,) with diagonal intensity ``Qc = diag(Q1, Q2, Q3)``
(seed 002 eq. (45)); w1 drives the WF "velocity" ξ̇2 [m/s, m/s, rad/s → Q1 in m²/s, m²/s, rad²/s],
w2 is a force [N, N, N·m → Q2 in N²·s, N²·s, N²·m²·s], w3 drives the bias
[N/s, N/s, N·m/s → Q3 in N²/s, N²/s, N²·m²/s].

WF noise intensity rule (see docs/design.md §5, the MMAE trap): for ``ẍ + 2ζω0ẋ + ω0²x = w`` with
intensity q the WF motion ``ξ2 = ẋ`` has variance ``q / (4ζω0)``. :func:`wf_intensity_for_variance`
returns the intensity that gives every model of a bank the *same* WF motion variance, so the
models differ only in spectral shape, not in how much wave motion they expect.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

#: Index slices of the 15-state wave-filter model (the 9-state raw model starts at ``ETA``−6).
XI1 = slice(0, 3)
XI2 = slice(3, 6)
N_WAVE_STATES = 6


@dataclass(frozen=True)
class StateIndex:
    """Where each block lives in the state vector of a :class:`DesignModel`.

    Attributes
    ----------
    n : int
        Number of states (15 with wave states, 9 without).
    xi1, xi2 : slice or None
        WF states ξ1 (integral of the WF motion) and ξ2 = η_w (WF motion), or None (raw model).
    eta, bias, nu : slice
        LF pose ηp [m, m, rad], bias bp [N, N, N·m] and body velocity ν [m/s, m/s, rad/s].
    """

    n: int
    xi1: slice | None
    xi2: slice | None
    eta: slice
    bias: slice
    nu: slice

    @staticmethod
    def for_model(with_waves: bool) -> StateIndex:
        off = N_WAVE_STATES if with_waves else 0
        return StateIndex(
            n=off + 9,
            xi1=XI1 if with_waves else None,
            xi2=XI2 if with_waves else None,
            eta=slice(off, off + 3),
            bias=slice(off + 3, off + 6),
            nu=slice(off + 6, off + 9),
        )

    @property
    def has_waves(self) -> bool:
        return self.xi2 is not None

    def horizontal_pairs(self, rotate_waves: bool) -> tuple[tuple[int, int], ...]:
        """(x, y) index pairs of the vessel-parallel vectors that turn with the heading.

        ηp and bp always (seed 001 eqs. (30)–(31), the ψ̇S terms); the WF states too when they are
        earth-frame states (seed 002, ``rotate_waves=True``); body-frame WF states (seed 001 eq.
        (34)) and ν never.
        """
        pairs = [(self.eta.start, self.eta.start + 1), (self.bias.start, self.bias.start + 1)]
        if rotate_waves and self.has_waves:
            pairs += [(XI1.start, XI1.start + 1), (XI2.start, XI2.start + 1)]
        return tuple(pairs)


@dataclass(frozen=True, eq=False)
class DesignModel:
    """Continuous-time linear design model ``ẋ = A x + B τ + E w``, ``y = H x + v``.

    Attributes
    ----------
    A : ndarray, shape (n, n)
    B : ndarray, shape (n, 3)
        Input matrix of the body force τ_b [N, N, N·m].
    E : ndarray, shape (n, r)
        Noise input matrix (seed 002 eq. (39)); r = 9 with wave states, 6 without.
    H : ndarray, shape (3, n)
        Measurement matrix ``[C_w I 0 0]`` (seed 002 eq. (39)).
    Qc : ndarray, shape (r, r)
        Process-noise intensity (diagonal), SI units (see module docstring).
    omega_rad_s : float or None
        WF peak frequency ω0 [rad/s] (None: no wave states).
    zeta : float
        WF relative damping ζ [-].
    index : StateIndex
    """

    A: np.ndarray
    B: np.ndarray
    E: np.ndarray
    H: np.ndarray
    Qc: np.ndarray
    omega_rad_s: float | None
    zeta: float
    index: StateIndex

    @property
    def n(self) -> int:
        return self.index.n


def wave_matrices(omega_rad_s: float, zeta: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """WF model matrices ``A_w, E_w, C_w`` of seed 000 eq. (1)/(5) (seed 001 eqs. (1)–(2)).

    ``A_w = [[0, I], [−Ω, −Λ]]`` with ``Ω = ω0² I``, ``Λ = 2ζω0 I``; ``E_w = [0; I]``;
    ``C_w = [0 I]``. Returns arrays of shapes (6, 6), (6, 3), (3, 6).
    """
    eye = np.eye(3)
    A_w = np.zeros((6, 6))
    A_w[0:3, 3:6] = eye
    A_w[3:6, 0:3] = -(omega_rad_s**2) * eye
    A_w[3:6, 3:6] = -2.0 * zeta * omega_rad_s * eye
    E_w = np.vstack([np.zeros((3, 3)), eye])
    C_w = np.hstack([np.zeros((3, 3)), eye])
    return A_w, E_w, C_w


def wave_matrix_derivative(omega_rad_s: float, zeta: float) -> np.ndarray:
    """∂A_w/∂ω0 (6, 6): ``[[0, 0], [−2ω0 I, −2ζ I]]`` (for the RPEM sensitivity, seed 003 eq. (13))."""
    dA = np.zeros((6, 6))
    dA[3:6, 0:3] = -2.0 * omega_rad_s * np.eye(3)
    dA[3:6, 3:6] = -2.0 * zeta * np.eye(3)
    return dA


def wf_intensity_for_variance(omega_rad_s: float, zeta: float, wf_std: Sequence[float]) -> np.ndarray:
    """WF driving-noise intensity giving the WF motion ξ2 the standard deviation ``wf_std``.

    For ``ẍ + 2ζω0ẋ + ω0²x = w`` with intensity q, ``Var(ẋ) = q / (4ζω0)``, hence
    ``q = 4ζω0·σ²``.

    Parameters
    ----------
    omega_rad_s : float
        ω0 [rad/s].
    zeta : float
        ζ [-].
    wf_std : sequence of 3 floats
        WF motion standard deviation [m, m, rad].

    Returns
    -------
    ndarray, shape (3,)
        Intensities [m²/s, m²/s, rad²/s].
    """
    std = np.asarray(wf_std, dtype=float)
    return 4.0 * zeta * omega_rad_s * std**2


def dp_design_model(
    mass_matrix: np.ndarray,
    damping_matrix: np.ndarray,
    omega_rad_s: float | None,
    *,
    zeta: float,
    wf_intensity: Sequence[float] | np.ndarray | None,
    force_intensity: Sequence[float] | np.ndarray,
    bias_intensity: Sequence[float] | np.ndarray,
    bias_time_constants_s: Sequence[float] | None = None,
) -> DesignModel:
    """Build the DP design model of seed 002 eqs. (36)–(39) / seed 001 eqs. (33)–(38).

    Parameters
    ----------
    mass_matrix, damping_matrix : ndarray, shape (3, 3)
        M = M_RB + M_A [kg, kg·m, kg·m²] and linear damping D (seed 002 eqs. (10)–(12)).
    omega_rad_s : float or None
        WF peak frequency ω0 [rad/s]; None builds the 9-state model without wave states.
    zeta : float
        WF relative damping ζ [-] (ignored without wave states).
    wf_intensity : sequence of 3 floats or None
        Q1, intensity of w1 [m²/s, m²/s, rad²/s] (ignored without wave states).
    force_intensity : sequence of 3 floats
        Q2, intensity of the force noise w2 [N²·s, N²·s, N²·m²·s].
    bias_intensity : sequence of 3 floats
        Q3, intensity of the bias noise w3 [N²/s, N²/s, N²·m²/s].
    bias_time_constants_s : sequence of 3 floats or None
        (Tx, Ty, Tψ) [s] of the seed 001 eq. (35) Markov bias; None: seed 002 random walk ``ḃp = w3``.

    Returns
    -------
    DesignModel
    """
    M = np.asarray(mass_matrix, dtype=float)
    D = np.asarray(damping_matrix, dtype=float)
    if M.shape != (3, 3) or D.shape != (3, 3):
        raise ValueError("mass and damping matrices must be 3x3")
    with_waves = omega_rad_s is not None
    if omega_rad_s is not None and not (omega_rad_s > 0.0 and zeta > 0.0):
        raise ValueError(f"wave model needs omega_rad_s > 0 and zeta > 0, got {omega_rad_s}, {zeta}")
    index = StateIndex.for_model(with_waves)
    n = index.n
    M_inv = np.linalg.inv(M)
    eye = np.eye(3)

    A = np.zeros((n, n))
    A[index.eta, index.nu] = eye                       # η̇p = ν                 (seed 002 eq. (31))
    if bias_time_constants_s is not None:
        T = np.asarray(bias_time_constants_s, dtype=float)
        if T.shape != (3,) or np.any(T <= 0.0):
            raise ValueError(f"bias time constants must be 3 positive numbers, got {bias_time_constants_s}")
        A[index.bias, index.bias] = -np.diag(1.0 / T)   # ḃp = −T⁻¹bp + w3       (seed 001 eq. (35))
    A[index.nu, index.bias] = M_inv                     # ν̇ = M⁻¹bp − M⁻¹Dν + M⁻¹τ (seed 002 eq. (38))
    A[index.nu, index.nu] = -M_inv @ D

    B = np.zeros((n, 3))
    B[index.nu, :] = M_inv

    H = np.zeros((3, n))
    H[:, index.eta] = eye                               # y = ηp + C_w ξ + v      (seed 002 eq. (34))

    blocks_q = [np.asarray(force_intensity, dtype=float), np.asarray(bias_intensity, dtype=float)]
    r = 6
    if omega_rad_s is not None:  # with_waves
        A_w, E_w, C_w = wave_matrices(float(omega_rad_s), zeta)
        A[0:6, 0:6] = A_w
        H[:, 0:6] = C_w
        if wf_intensity is None:
            raise ValueError("a wave model needs the WF noise intensity")
        blocks_q.insert(0, np.asarray(wf_intensity, dtype=float))
        r = 9
    for q in blocks_q:
        if q.shape != (3,) or not np.all(np.isfinite(q)) or np.any(q < 0.0):
            raise ValueError(f"noise intensities must be 3 finite numbers >= 0, got {q}")

    E = np.zeros((n, r))
    col = 0
    if with_waves:
        E[0:6, 0:3] = E_w                               # w1 → ξ̇2
        col = 3
    E[index.nu, col:col + 3] = M_inv                    # w2 → ν̇ through M⁻¹
    E[index.bias, col + 3:col + 6] = eye                # w3 → ḃp
    Qc = np.diag(np.concatenate(blocks_q))
    return DesignModel(A=A, B=B, E=E, H=H, Qc=Qc, omega_rad_s=None if omega_rad_s is None else float(omega_rad_s),
                       zeta=float(zeta), index=index)
