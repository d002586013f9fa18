"""Wave and gust spectra, and their realisation as sums of sinusoids.

Numpy, plus one compiled kernel (:func:`sim_plant.kernels.cosine_sum`) for the per-step value of a
:class:`SpectralProcess`. Written out by hand rather than taken from a marine toolkit (mhkit has a
JONSWAP function) because the formulas are a few lines each and the toolkit would pull pandas/xarray
into a plant whose hot path must stay allocation-free; what matters here — normalisation to the
exact Hs and the frequency discretisation — is ours anyway.

Units: angular frequency ω [rad/s], spectral densities S(ω) [m²·s/rad] (waves) or per Hz where
named ``_per_hz``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from sim_plant.kernels import cosine_sum

GRAVITY_MPS2 = 9.81

SPECTRA: tuple[str, ...] = ("jonswap", "pierson_moskowitz")


def pierson_moskowitz_shape(omega_rad_s: np.ndarray, omega_peak_rad_s: float) -> np.ndarray:
    """Unnormalised Pierson–Moskowitz shape ``ω⁻⁵ exp(−5/4 (ωp/ω)⁴)`` (DNV-RP-C205 eq. 3.5.3).

    Parameters
    ----------
    omega_rad_s : ndarray
        Frequencies [rad/s] (> 0).
    omega_peak_rad_s : float
        Peak frequency ωp [rad/s].
    """
    w = np.asarray(omega_rad_s, dtype=float)
    ratio = omega_peak_rad_s / w
    return w**-5 * np.exp(-1.25 * ratio**4)


def wave_spectrum(omega_rad_s: np.ndarray, hs_m: float, omega_peak_rad_s: float, gamma: float = 3.3,
                  spectrum: str = "jonswap") -> np.ndarray:
    """One-sided wave elevation spectrum S(ω) normalised to ∫S dω = Hs²/16 exactly.

    JONSWAP (Hasselmann et al. 1973, seed 001 ref. [39]; DNV-RP-C205 eq. 3.5.5)::

        S(ω) ∝ ω⁻⁵ exp(−5/4 (ωp/ω)⁴) · γ^exp(−(ω−ωp)² / (2 σ² ωp²)),  σ = 0.07 (ω ≤ ωp), 0.09 (ω > ωp)

    Pierson–Moskowitz is the same with γ = 1. The usual normalising factor A_γ = 1 − 0.287 ln γ is
    an approximation (≈1 % off); the shape is integrated numerically instead so that the zeroth
    moment m0 = Hs²/16 holds to the integration accuracy.

    Parameters
    ----------
    omega_rad_s : ndarray
        Frequencies [rad/s].
    hs_m : float
        Significant wave height Hs = 4√m0 [m].
    omega_peak_rad_s : float
        Peak frequency ωp [rad/s].
    gamma : float
        JONSWAP peak enhancement γ ≥ 1 (ignored for Pierson–Moskowitz).
    spectrum : {"jonswap", "pierson_moskowitz"}

    Returns
    -------
    ndarray
        S(ω) [m²·s/rad], same shape as ``omega_rad_s``; 0 where ω ≤ 0.
    """
    if spectrum not in SPECTRA:
        raise ValueError(f"unknown wave spectrum {spectrum!r} (expected one of {', '.join(SPECTRA)})")
    g = 1.0 if spectrum == "pierson_moskowitz" else gamma
    w = np.asarray(omega_rad_s, dtype=float)
    out = np.zeros_like(w)
    positive = w > 0.0
    out[positive] = _shape(w[positive], omega_peak_rad_s, g)
    return out * (hs_m**2 / 16.0 / _shape_integral(omega_peak_rad_s, g))


def _shape(w: np.ndarray, wp: float, gamma: float) -> np.ndarray:
    base = pierson_moskowitz_shape(w, wp)
    if gamma == 1.0:
        return base
    sigma = np.where(w <= wp, 0.07, 0.09)
    return base * gamma ** np.exp(-((w - wp) ** 2) / (2.0 * sigma**2 * wp**2))


@lru_cache(maxsize=256)
def _shape_integral(wp: float, gamma: float) -> float:
    # The shape is negligible below 0.3 ωp (exp(−154)) and decays like ω⁻⁵ above; integrate to
    # 40 ωp and add the analytic ω⁻⁵ tail beyond (∫ ω⁻⁵ = ω⁻⁴/4).
    w = np.linspace(0.3 * wp, 40.0 * wp, 40001)
    s = _shape(w, wp, gamma)
    tail = (40.0 * wp) ** -4 / 4.0
    return float(np.trapezoid(s, w)) + tail


def frequency_bins(omega_peak_rad_s: float, gamma: float, n: int, spectrum: str = "jonswap", *,
                   low: float = 0.5, high: float = 4.0) -> np.ndarray:
    """Bin edges for ``n`` wave components over [low·ωp, high·ωp], finer where the energy is.

    The edges are equal-probability quantiles of the density ``√(S/S_max) + 0.1``: the peak region
    gets bins about ten times narrower than the tails, yet the tails (where a long hull's motion
    peak can sit, docs/design.md §5, trap 3) keep enough components.

    Returns
    -------
    ndarray, shape (n + 1,)
        Increasing edges [rad/s].
    """
    grid = np.linspace(low * omega_peak_rad_s, high * omega_peak_rad_s, 4001)
    s = wave_spectrum(grid, 1.0, omega_peak_rad_s, gamma, spectrum)
    density = np.sqrt(s / s.max()) + 0.1
    cdf = np.concatenate(([0.0], np.cumsum(0.5 * (density[1:] + density[:-1]) * np.diff(grid))))
    cdf /= cdf[-1]
    return np.interp(np.linspace(0.0, 1.0, n + 1), cdf, grid)


@dataclass(frozen=True)
class WaveComponents:
    """A realisation of a wave spectrum as ``n`` regular waves (long-crested).

    Attributes
    ----------
    omega_rad_s : ndarray, shape (n,)
        Component frequencies, one drawn uniformly in the central half of each (non-uniform) bin:
        no two are commensurate, so the record does not repeat, while S(ω_i)Δω_i stays close to
        the bin's integral (with draws over the whole bin the band powers scatter about twice as
        much) [rad/s].
    amplitude_m : ndarray, shape (n,)
        Deterministic amplitudes a_i = √(2 S(ω_i) Δω_i) [m] (Σ a_i²/2 ≈ Hs²/16).
    phase_rad : ndarray, shape (n,)
        Uniform random phases ε_i [rad].
    wavenumber_radpm : ndarray, shape (n,)
        Deep-water wave numbers k_i = ω_i²/g [rad/m].
    """

    omega_rad_s: np.ndarray
    amplitude_m: np.ndarray
    phase_rad: np.ndarray
    wavenumber_radpm: np.ndarray


def realise_waves(hs_m: float, omega_peak_rad_s: float, gamma: float, spectrum: str, n: int, *,
                  rng: np.random.Generator) -> WaveComponents:
    """Draw ``n`` components of a JONSWAP / Pierson–Moskowitz sea (seeded, deterministic)."""
    edges = frequency_bins(omega_peak_rad_s, gamma, n, spectrum)
    width = np.diff(edges)
    omega = edges[:-1] + rng.uniform(0.25, 0.75, n) * width
    amplitude = np.sqrt(2.0 * wave_spectrum(omega, hs_m, omega_peak_rad_s, gamma, spectrum) * width)
    phase = rng.uniform(0.0, 2.0 * math.pi, n)
    return WaveComponents(omega, amplitude, phase, omega**2 / GRAVITY_MPS2)


def norsok_wind_spectrum_per_hz(f_hz: np.ndarray, mean_speed_mps: float, height_m: float = 10.0) -> np.ndarray:
    """NORSOK / Frøya wind gust spectrum S(f) [m²/Hz] (NORSOK N-003, DNV-RP-C205 eq. 2.3.4)::

        S(f) = 320 (U0/10)² (z/10)^0.45 / (1 + f̃ⁿ)^(5/(3n)),
        f̃ = 172 f (z/10)^(2/3) (U0/10)^(−3/4),  n = 0.468,

    with U0 the 1-hour mean wind speed at 10 m [m/s] and z the height above the sea [m].
    """
    f = np.asarray(f_hz, dtype=float)
    u = mean_speed_mps / 10.0
    z = height_m / 10.0
    n = 0.468
    ft = 172.0 * f * z ** (2.0 / 3.0) * u**-0.75
    return 320.0 * u**2 * z**0.45 / (1.0 + ft**n) ** (5.0 / (3.0 * n))


class SpectralProcess:
    """A zero-mean stationary random process as a sum of cosines: x(t) = Σ c_j cos(ω_j t + θ_j).

    Stateless in time (any t, any order, same value), deterministic for a seed; used for wind
    gusts and slow current variation. ``value(t)`` is one kernel call
    (:func:`sim_plant.kernels.cosine_sum`).

    Parameters
    ----------
    omega_rad_s, amplitude : ndarray, shape (n,)
        Component frequencies [rad/s] and amplitudes [unit of x].
    phase_rad : ndarray, shape (n,)
    """

    __slots__ = ("_amplitude", "_omega", "_phase")

    def __init__(self, omega_rad_s: np.ndarray, amplitude: np.ndarray, phase_rad: np.ndarray) -> None:
        # C-contiguous float64: the layout of the kernel's arguments
        self._omega = np.ascontiguousarray(omega_rad_s, dtype=float)
        self._amplitude = np.ascontiguousarray(amplitude, dtype=float)
        self._phase = np.ascontiguousarray(phase_rad, dtype=float)

    @staticmethod
    def from_one_sided(omega_edges_rad_s: np.ndarray, density: np.ndarray, rng: np.random.Generator
                       ) -> SpectralProcess:
        """Realise a one-sided spectrum given on bins: amplitude √(2 S Δω) per bin, frequency jittered
        inside the bin, random phase. ``density`` [unit²·s/rad] is evaluated at the bin centres."""
        edges = np.asarray(omega_edges_rad_s, dtype=float)
        width = np.diff(edges)
        omega = edges[:-1] + rng.uniform(0.0, 1.0, width.size) * width
        amplitude = np.sqrt(2.0 * np.asarray(density, dtype=float) * width)
        return SpectralProcess(omega, amplitude, rng.uniform(0.0, 2.0 * math.pi, width.size))

    @property
    def variance(self) -> float:
        """Σ c_j²/2 [unit²]."""
        return float(0.5 * np.dot(self._amplitude, self._amplitude))

    def value(self, t_s: float) -> float:
        """x(t) [unit]."""
        return cosine_sum(t_s, self._omega, self._phase, self._amplitude)

    def series(self, t_s: np.ndarray) -> np.ndarray:
        """x(t) for an array of times (tests, plots)."""
        t = np.asarray(t_s, dtype=float)
        return np.cos(np.multiply.outer(t, self._omega) + self._phase) @ self._amplitude


def gauss_markov_process(sigma: float, time_constant_s: float, rng: np.random.Generator, n: int = 24
                         ) -> SpectralProcess:
    """A process with the spectrum of a first-order Gauss–Markov process (std ``sigma``, time
    constant T): S(ω) = (2σ²T/π) / (1 + (ωT)²) one-sided, realised on log-spaced bins over
    [0.02/T, 30/T] (about 98 % of the variance)."""
    edges = np.geomspace(0.02 / time_constant_s, 30.0 / time_constant_s, n + 1)
    centres = np.sqrt(edges[:-1] * edges[1:])
    density = (2.0 * sigma**2 * time_constant_s / math.pi) / (1.0 + (centres * time_constant_s) ** 2)
    return SpectralProcess.from_one_sided(edges, density, rng)
