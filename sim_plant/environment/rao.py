"""Parametric motion RAOs and wave-drift coefficients derived from the hull's main dimensions.

No hydrodynamic database exists for the built-in vessels, so the first-order (wave-frequency)
horizontal motions are derived from a box hull of length L, beam B and draft T, free in surge,
sway and yaw (no restoring in the horizontal plane). For a regular wave of amplitude ζ, frequency
ω, deep-water wave number k = ω²/g, travelling at angle β relative to the bow (β = 0 following
seas, β = π head seas, β = +π/2 waves running to starboard), the Froude–Krylov force on the box
divided by its mass times ω² gives, per unit wave amplitude:

* surge  x/ζ = cos β · D(kT) · F(k L |cos β| / 2) · F(k B |sin β| / 2)               [m/m]
* sway   y/ζ = sin β · D(kT) · F(k L |cos β| / 2) · F(k B |sin β| / 2)               [m/m]
* yaw    ψ/ζ = k sin β cos β · D(kT) · G(k L |cos β| / 2) · F(k B |sin β| / 2)       [rad/m]

with the depth factor D(x) = (1 − e^{−x})/x (pressure decay over the draft). The exact box
integrals are F(q) = sin q / q and G(q) = 3 (sin q − q cos q)/q³; a real hull has no sharp ends,
so their zeros are smoothed out and we use envelopes with the same long-wave curvature and the
same decay power:

    F(q) = (1 + q²/3)^(−1/2)              (sin q/q = 1 − q²/6 + …, envelope ∝ 1/q)
    G(q) = (1 + q²/5 + q⁴/9)^(−1/2)       (1 − q²/10 + …, envelope 3/q²)

Consequences (tested): long waves (λ ≫ L) move the vessel with the water particles (|x/ζ| → |cos β|,
|y/ζ| → |sin β|) and yaw it with the wave slope (ψ/ζ → k sin 2β / 2); waves shorter than the hull
are averaged out, so a long vessel's motion spectrum |RAO|²·S peaks *below* the wave peak (seed 003
Fig. 4: tanker surge motion peak 12.5 s for 10 s waves; docs/design.md §5, trap 3), while a short one
(CyberShip II) follows the waves and its motion peak sits on the wave peak.

Phases: the surge/sway displacement is that of the particles, ``a sin φ`` for an elevation
``a cos φ``; yaw follows the rotation of the displacement field, ``−a k sinβ cosβ cos φ``.

Wave drift (second order): the mean force per unit length on a surface-piercing wall of draft T
is ½ρg ζ² R², R the reflection coefficient, for which Ursell's (1947) exact thin-barrier result in
deep water is used:

    R(kT) = π I1(kT) / √(π² I1(kT)² + K1(kT)²)

(modified Bessel functions). It vanishes for waves much longer than the draft (a model ship in
full-scale waves feels no drift) and tends to 1 for short waves. A hull with beam reflects a bit
more than a thin wall, so this is on the low side; ``drift_scale`` in
:mod:`sim_plant.vessel_data` can raise it per vessel.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import special

from sim_plant.environment.spectra import GRAVITY_MPS2


@dataclass(frozen=True)
class HullDimensions:
    """Main dimensions used by the parametric RAOs and drift [m]."""

    length_m: float
    beam_m: float
    draft_m: float

    def __post_init__(self) -> None:
        if not (self.length_m > 0.0 and self.beam_m > 0.0 and self.draft_m > 0.0):
            raise ValueError(f"hull dimensions must be positive, got {self}")


def _f(q: np.ndarray) -> np.ndarray:
    return 1.0 / np.sqrt(1.0 + q * q / 3.0)


def _g(q: np.ndarray) -> np.ndarray:
    q2 = q * q
    return 1.0 / np.sqrt(1.0 + q2 / 5.0 + q2 * q2 / 9.0)


def _depth(x: np.ndarray) -> np.ndarray:
    # (1 − e^{−x})/x, with its limit 1 at x → 0 (expm1 keeps precision for tiny kT).
    x = np.asarray(x, dtype=float)
    out = np.ones_like(x)
    nz = x > 1e-12
    out[nz] = -np.expm1(-x[nz]) / x[nz]
    return out


def motion_raos(omega_rad_s: np.ndarray, beta_rad: float | np.ndarray, hull: HullDimensions
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Signed first-order motion RAOs (surge, sway, yaw) in body axes.

    Parameters
    ----------
    omega_rad_s : ndarray
        Wave frequencies [rad/s].
    beta_rad : float or ndarray
        Wave propagation direction relative to the bow [rad] (0 following, π head seas,
        +π/2 travelling to starboard); broadcast against ``omega_rad_s``.
    hull : HullDimensions

    Returns
    -------
    (ndarray, ndarray, ndarray)
        x/ζ [m/m], y/ζ [m/m], ψ/ζ [rad/m]; multiply by ``a sin φ`` (surge, sway) and
        ``−a cos φ`` (yaw). |RAO|² S(ω) is the motion spectrum (seed 003 eq. (2)).
    """
    w = np.asarray(omega_rad_s, dtype=float)
    beta = np.asarray(beta_rad, dtype=float)
    k = w * w / GRAVITY_MPS2
    cb = np.cos(beta)
    sb = np.sin(beta)
    q_l = 0.5 * k * hull.length_m * np.abs(cb)
    q_b = 0.5 * k * hull.beam_m * np.abs(sb)
    common = _depth(k * hull.draft_m) * _f(q_b)
    translation = common * _f(q_l)
    return cb * translation, sb * translation, k * sb * cb * common * _g(q_l)


def reflection_coefficient(omega_rad_s: np.ndarray, draft_m: float) -> np.ndarray:
    """Ursell's deep-water reflection coefficient of a wall of draft T, R(kT) ∈ [0, 1)."""
    x = np.asarray(omega_rad_s, dtype=float) ** 2 / GRAVITY_MPS2 * draft_m
    x = np.maximum(x, 1e-9)
    # Exponentially scaled Bessel functions: I1 = i1e·eˣ, K1 = k1e·e⁻ˣ, so
    # R = π i1e / √(π² i1e² + k1e² e^{−4x}) without overflow for large kT.
    i1 = special.i1e(x)
    k1 = special.k1e(x) * np.exp(-2.0 * x)
    return math.pi * i1 / np.sqrt((math.pi * i1) ** 2 + k1 * k1)


def drift_direction_factors(beta_rad: float, hull: HullDimensions, bow_factor: float = 0.5
                            ) -> tuple[float, float, float]:
    """Lengths [m, m, m²] turning the drift force per unit length ½ρg ζ²R² into body forces.

    Surge: the bow's projected width B (times ``bow_factor`` for a fine bow) in head/following
    seas, ∝ cos β|cos β|; sway: the side length L, ∝ sin β|sin β|; yaw: the sway force acting
    0.1 L toward the weather end (ahead for waves from forward, −cos β > 0), which turns the vessel
    beam-on as drift moments do.

    Returns
    -------
    (float, float, float)
        (l_x, l_y, l_ψ) so that τ_drift = F'·(l_x, l_y, l_ψ), F' = ½ρg|A|² [N/m].
    """
    cb = math.cos(beta_rad)
    sb = math.sin(beta_rad)
    l_x = bow_factor * hull.beam_m * cb * abs(cb)
    l_y = hull.length_m * sb * abs(sb)
    return l_x, l_y, l_y * 0.1 * hull.length_m * (-cb)
