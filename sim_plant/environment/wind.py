"""Wind: mean speed and direction, NORSOK gusts, and the force they put on the vessel.

The force is the project's one wind-load law, :mod:`dpbase.wind_loads` (seed 002 eqs. (18)–(22) with
Blendermann's 1994 coefficients, Fossen 2021 §10.1.2; its sign convention: γ_rw = −atan2(v_rw, u_rw),
0 for a head wind, +π/2 for a wind from port, −π/2 from starboard), at the plant's air density
:data:`RHO_AIR_KGPM3`. The relative wind is the wind velocity minus the vessel velocity over ground.
Which Blendermann ship type a built-in vessel is lives in :mod:`sim_plant.vessel_data`.

Gusts: the NORSOK (Frøya) spectrum of :mod:`sim_plant.environment.spectra`, realised as 64
sinusoids between 1/2000 Hz and 0.5 Hz; direction fluctuations are not modelled.
"""

from __future__ import annotations

import math

import numpy as np

from dpbase.wind_loads import BlendermannCoefficients, relative_wind_angle
from sim_plant.environment.spectra import SpectralProcess, norsok_wind_spectrum_per_hz

RHO_AIR_KGPM3 = 1.225


def wind_force_b(coefficients: BlendermannCoefficients, speed_mps: float, gamma_rw_rad: float
                 ) -> tuple[float, float, float]:
    """τ_wind (X, Y, N) [N, N, N·m] at the plant's air density (seed 002 eq. (18)).

    Parameters
    ----------
    coefficients : BlendermannCoefficients
        The vessel's.
    speed_mps : float
        Relative wind speed V_rw [m/s].
    gamma_rw_rad : float
        Relative wind angle γ_rw [rad] (seed 002 eq. (20): 0 head wind, + from port).
    """
    return coefficients.force_b(speed_mps, gamma_rw_rad, RHO_AIR_KGPM3)


class WindModel:
    """Mean wind plus gusts, and the resulting force on the vessel.

    Parameters
    ----------
    speed_mps : float
        1-hour mean wind speed at the reference height [m/s].
    direction_from_rad : float
        Direction the wind comes FROM (NED, clockwise from north) [rad].
    coefficients : BlendermannCoefficients
        The vessel's (:mod:`dpbase.wind_loads`).
    rng : numpy.random.Generator
        Seeds the gust realisation.
    gusts : bool
        Add NORSOK gusts (the speed never goes below 0).
    height_m : float
        Reference height of ``speed_mps`` [m].
    """

    def __init__(self, speed_mps: float, direction_from_rad: float, coefficients: BlendermannCoefficients,
                 rng: np.random.Generator, *, gusts: bool = True, height_m: float = 10.0) -> None:
        self.mean_speed_mps = speed_mps
        self.direction_from_rad = direction_from_rad
        self.coefficients = coefficients
        self._to_north = -math.cos(direction_from_rad)  # unit vector the air moves toward (NED)
        self._to_east = -math.sin(direction_from_rad)
        self.gust: SpectralProcess | None = None
        if gusts and speed_mps > 0.0:
            edges_hz = np.geomspace(1.0 / 2000.0, 0.5, 65)
            centres_hz = np.sqrt(edges_hz[:-1] * edges_hz[1:])
            density = norsok_wind_spectrum_per_hz(centres_hz, speed_mps, height_m) / (2.0 * math.pi)
            self.gust = SpectralProcess.from_one_sided(2.0 * math.pi * edges_hz, density, rng)

    def speed_at(self, t_s: float) -> float:
        """True wind speed at ``t_s`` (mean + gust, ≥ 0) [m/s]."""
        if self.gust is None:
            return self.mean_speed_mps
        return max(0.0, self.mean_speed_mps + self.gust.value(t_s))

    def force_b(self, t_s: float, heading_rad: float, u_mps: float, v_mps: float) -> tuple[float, float, float]:
        """Wind force on the vessel in body axes [N, N, N·m] (seed 002 eqs. (18)–(22)).

        Parameters
        ----------
        t_s : float
            Time (sets the gust) [s].
        heading_rad : float
            Heading ψ [rad].
        u_mps, v_mps : float
            Vessel surge and sway velocity over ground (the air is at rest relative to ground
            apart from the wind).
        """
        if self.mean_speed_mps == 0.0:
            return 0.0, 0.0, 0.0
        speed = self.speed_at(t_s)
        c = math.cos(heading_rad)
        s = math.sin(heading_rad)
        wn = speed * self._to_north
        we = speed * self._to_east
        # air velocity relative to the vessel in body axes (air minus vessel: −(u_rw, v_rw) of
        # seed 002 eqs. (21)–(22))
        ua = c * wn + s * we - u_mps
        va = -s * wn + c * we - v_mps
        v_rel = math.hypot(ua, va)
        if v_rel == 0.0:
            return 0.0, 0.0, 0.0
        return wind_force_b(self.coefficients, v_rel, relative_wind_angle(-ua, -va))  # (20)
