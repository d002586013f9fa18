"""Wind: mean speed and direction, NORSOK gusts, Blendermann (1994) force coefficients.

Forces follow seed 002 eqs. (18)–(22)::

    τ_wind = ½ ρ_a V_rw² [A_F C_X(γ), A_L C_Y(γ), A_L L C_N(γ)]

with the relative wind speed V_rw and angle γ computed from the wind velocity minus the vessel
velocity. Sign convention here (stated because papers differ): γ is the direction the RELATIVE
wind comes FROM, measured from the bow, positive to starboard (γ = 0 head wind, γ = +π/2 wind on
the starboard beam). Then

    C_X = −C_Dl,AF(γ) cos γ / Δ,   C_Y = −C_Dt sin γ / Δ,
    Δ   = 1 − (δ/2)(1 − C_Dl/C_Dt) sin²(2γ),   C_Dl = C_Dl,AF · A_F / A_L,
    N   = Y · L (s_L/L − 0.18 (|γ| − π/2))

(Blendermann 1994, "Parameter identification of wind loads on ships", J. Wind Eng. Ind. Aerodyn.
51; as written in Fossen 2021 §10.1.2), so a head wind pushes the vessel astern, a wind from
starboard pushes it to port, and the lateral force acts ahead of the area centroid s_L when the
wind comes from forward, behind it from aft (the vessel weather-vanes). C_Dl,AF takes its bow value
for |γ| ≤ π/2 and its stern value otherwise. Parameters per ship type are Blendermann's table
(the constants below); which type a built-in vessel is lives in :mod:`sim_plant.vessel_data`.

Gusts: the NORSOK (Frøya) spectrum of :mod:`sim_plant.environment.spectra`, realised as 64
sinusoids between 1/2000 Hz and 0.5 Hz; direction fluctuations are not modelled.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sim_plant.environment.spectra import SpectralProcess, norsok_wind_spectrum_per_hz

RHO_AIR_KGPM3 = 1.225

# Blendermann (1994) Table: (C_Dt, C_Dl,AF bow, C_Dl,AF stern, δ) per ship type.
BLENDERMANN_TYPES: dict[str, tuple[float, float, float, float]] = {
    "car_carrier": (0.95, 0.55, 0.60, 0.80),
    "cargo_vessel_loaded": (0.85, 0.65, 0.55, 0.40),
    "cargo_vessel_container_on_deck": (0.85, 0.55, 0.50, 0.40),
    "container_ship_loaded": (0.90, 0.55, 0.55, 0.40),
    "destroyer": (0.85, 0.60, 0.65, 0.65),
    "diving_support_vessel": (0.90, 0.60, 0.80, 0.55),
    "drilling_vessel": (1.00, 0.85, 0.925, 0.10),
    "ferry": (0.90, 0.45, 0.50, 0.80),
    "fishing_vessel": (0.95, 0.70, 0.70, 0.40),
    "lng_tanker": (0.70, 0.60, 0.65, 0.50),
    "offshore_supply_vessel": (0.90, 0.55, 0.80, 0.55),
    "passenger_liner": (0.90, 0.40, 0.40, 0.80),
    "research_vessel": (0.85, 0.55, 0.65, 0.60),
    "speed_boat": (0.90, 0.55, 0.60, 0.60),
    "tanker_loaded": (0.70, 0.90, 0.55, 0.40),
    "tanker_ballast": (0.70, 0.75, 0.55, 0.40),
    "tender": (0.85, 0.55, 0.55, 0.65),
}


@dataclass(frozen=True)
class WindCoefficients:
    """Blendermann parameters and projected areas of one vessel.

    Attributes
    ----------
    cdt, cdl_af_bow, cdl_af_stern, delta : float
        Blendermann's C_Dt, C_Dl,AF(0), C_Dl,AF(π), δ.
    frontal_area_m2, lateral_area_m2 : float
        A_F, A_L [m²].
    length_m : float
        Length overall L [m].
    centroid_x_m : float
        s_L: longitudinal position of the lateral area's centroid, forward of midship [m].
    """

    cdt: float
    cdl_af_bow: float
    cdl_af_stern: float
    delta: float
    frontal_area_m2: float
    lateral_area_m2: float
    length_m: float
    centroid_x_m: float = 0.0

    @staticmethod
    def of_type(ship_type: str, frontal_area_m2: float, lateral_area_m2: float, length_m: float,
                centroid_x_m: float = 0.0) -> WindCoefficients:
        """Coefficients of a Blendermann ship type (a key of :data:`BLENDERMANN_TYPES`)."""
        cdt, bow, stern, delta = BLENDERMANN_TYPES[ship_type]
        return WindCoefficients(cdt, bow, stern, delta, frontal_area_m2, lateral_area_m2, length_m, centroid_x_m)

    def coefficients(self, gamma_rad: float) -> tuple[float, float, float]:
        """(C_X, C_Y, C_N) for a relative wind from ``gamma_rad`` (from the bow, + starboard)."""
        g = abs(gamma_rad)
        cdl_af = self.cdl_af_bow if g <= 0.5 * math.pi else self.cdl_af_stern
        if self.lateral_area_m2 > 0.0 and self.cdt > 0.0:
            cdl = cdl_af * self.frontal_area_m2 / self.lateral_area_m2
            den = 1.0 - 0.5 * self.delta * (1.0 - cdl / self.cdt) * math.sin(2.0 * gamma_rad) ** 2
        else:
            den = 1.0
        cx = -cdl_af * math.cos(gamma_rad) / den
        cy = -self.cdt * math.sin(gamma_rad) / den
        cn = (self.centroid_x_m / self.length_m - 0.18 * (g - 0.5 * math.pi)) * cy
        return cx, cy, cn

    def force_b(self, speed_mps: float, gamma_rad: float) -> tuple[float, float, float]:
        """τ_wind (X, Y, N) [N, N, N·m] for relative wind speed and angle (seed 002 eq. (18))."""
        q = 0.5 * RHO_AIR_KGPM3 * speed_mps * speed_mps
        cx, cy, cn = self.coefficients(gamma_rad)
        return (q * self.frontal_area_m2 * cx, q * self.lateral_area_m2 * cy,
                q * self.lateral_area_m2 * self.length_m * cn)


class WindModel:
    """Mean wind plus gusts, and the resulting force on the vessel.

    Parameters
    ----------
    speed_mps : float
        1-hour mean wind speed at the reference height [m/s].
    direction_from_rad : float
        Direction the wind comes FROM (NED, clockwise from north) [rad].
    coefficients : WindCoefficients
    rng : numpy.random.Generator
        Seeds the gust realisation.
    gusts : bool
        Add NORSOK gusts (the speed never goes below 0).
    height_m : float
        Reference height of ``speed_mps`` [m].
    """

    def __init__(self, speed_mps: float, direction_from_rad: float, coefficients: WindCoefficients,
                 rng: np.random.Generator, *, gusts: bool = True, height_m: float = 10.0) -> None:
        self.mean_speed_mps = speed_mps
        self.direction_from_rad = direction_from_rad
        self.coefficients = coefficients
        self._to_n = -math.cos(direction_from_rad)  # unit vector the air moves toward (NED)
        self._to_e = -math.sin(direction_from_rad)
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
        heading_rad : float
        u_mps, v_mps : float
            Vessel surge and sway velocity over ground (the air is at rest relative to ground
            apart from the wind).
        """
        if self.mean_speed_mps == 0.0:
            return 0.0, 0.0, 0.0
        speed = self.speed_at(t_s)
        c = math.cos(heading_rad)
        s = math.sin(heading_rad)
        wn = speed * self._to_n
        we = speed * self._to_e
        # air velocity relative to the vessel, body axes (seed 002 eqs. (21)–(22), with the sign
        # of the vessel velocity: u_rw here is air minus vessel)
        ua = c * wn + s * we - u_mps
        va = -s * wn + c * we - v_mps
        v_rel = math.hypot(ua, va)
        if v_rel == 0.0:
            return 0.0, 0.0, 0.0
        gamma = math.atan2(-va, -ua)  # the relative wind comes from the opposite of its velocity
        return self.coefficients.force_b(v_rel, gamma)
