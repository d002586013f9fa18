"""Wind loads on a ship: seed 002 eqs. (18)–(22) with Blendermann's (1994) coefficients — the one law.

Both the controller's wind feed-forward (:mod:`dpcontrol.control.wind`) and the plant's wind
(:mod:`sim_plant.environment.wind`) compute their loads here; each keeps only its own kinematics
(where the wind velocity comes from) and its own air density.

Equations (seed 002; Fossen 2021 §10.1)::

    τ_wind = ½ ρ_a V_rw² [A_Fw C_X(γ_rw),  A_Lw C_Y(γ_rw),  A_Lw L_oa C_N(γ_rw)]ᵀ      (18)
    V_rw   = √(u_rw² + v_rw²)                                                      (19)
    γ_rw   = −atan2(v_rw, u_rw)                                                    (20)
    u_rw   = u − u_w,   v_rw = v − v_w                                             (21)–(22)

with ``(u, v)`` the vessel's and ``(u_w, v_w)`` the wind's velocity in body axes.

**Sign convention** (the one used throughout the project; papers differ): γ_rw of eq. (20) is the
direction the relative wind comes FROM, measured from the bow, positive towards PORT —
γ_rw = 0 a head wind, γ_rw = +π/2 a wind on the port beam, γ_rw = −π/2 on the starboard beam,
|γ_rw| = π a tail wind. (A bow-relative angle positive to starboard, as in DNV-ST-0111 capability
plots, is −γ_rw.) The forces are in body axes (x forward, y starboard, N positive turning the bow to
starboard), so a head wind pushes the vessel astern (X < 0) and a wind from starboard pushes it to
port (Y < 0).

Coefficients: the smooth closed-form fit of Blendermann (1994), "Parameter identification of wind
loads on ships", J. Wind Eng. Ind. Aerodyn. 51, 339–351 (as written in Fossen 2021 §10.1.2)::

    Δ   = 1 − ½ δ (1 − C_Dl/C_Dt) sin²(2γ_rw),        C_Dl = C_Dl,AF(γ_rw) · A_Fw/A_Lw
    C_X = −C_Dl,AF(γ_rw) cos γ_rw / Δ,   C_Y = C_Dt sin γ_rw / Δ,
    C_N = [s_L/L_oa − 0.18 (|γ_rw| − π/2)] C_Y

where ``C_Dl,AF`` takes its head-wind (bow) value for |γ_rw| ≤ π/2 and its tail-wind (stern) value
otherwise, and ``s_L`` is the longitudinal position of the lateral-area centroid (forward of midship
positive): the lateral force acts ahead of the centroid when the wind comes from forward and behind
it from aft, so the vessel weather-vanes. Without a lateral area (A_Lw = 0) Δ = 1.

The parameters per ship type are Blendermann's table, :data:`BLENDERMANN_TYPES` (the one table of
the project; :data:`BLENDERMANN_TYPE_ALIASES` keeps the controller's earlier short names valid).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import NamedTuple, Protocol


class BlendermannType(NamedTuple):
    """Blendermann's (1994) parameters of one ship type (nondimensional).

    Attributes
    ----------
    cd_transverse : float
        ``C_Dt``, beam-wind drag coefficient on the lateral area.
    cd_longitudinal_head : float
        ``C_Dl,AF(0)``, head-wind (bow) drag coefficient on the frontal area.
    cd_longitudinal_tail : float
        ``C_Dl,AF(π)``, tail-wind (stern) drag coefficient on the frontal area.
    cross_force : float
        ``δ``, cross-force parameter.
    """

    cd_transverse: float
    cd_longitudinal_head: float
    cd_longitudinal_tail: float
    cross_force: float


#: Blendermann (1994) table: (C_Dt, C_Dl,AF head, C_Dl,AF tail, δ) per ship type (as in Fossen 2021 §10.1.2).
BLENDERMANN_TYPES: Mapping[str, BlendermannType] = MappingProxyType({
    "car_carrier": BlendermannType(0.95, 0.55, 0.60, 0.80),
    "cargo_vessel_loaded": BlendermannType(0.85, 0.65, 0.55, 0.40),
    "cargo_vessel_container_on_deck": BlendermannType(0.85, 0.55, 0.50, 0.40),
    "container_ship_loaded": BlendermannType(0.90, 0.55, 0.55, 0.40),
    "destroyer": BlendermannType(0.85, 0.60, 0.65, 0.65),
    "diving_support_vessel": BlendermannType(0.90, 0.60, 0.80, 0.55),
    "drilling_vessel": BlendermannType(1.00, 0.85, 0.925, 0.10),
    "ferry": BlendermannType(0.90, 0.45, 0.50, 0.80),
    "fishing_vessel": BlendermannType(0.95, 0.70, 0.70, 0.40),
    "lng_tanker": BlendermannType(0.70, 0.60, 0.65, 0.50),
    "offshore_supply_vessel": BlendermannType(0.90, 0.55, 0.80, 0.55),
    "passenger_liner": BlendermannType(0.90, 0.40, 0.40, 0.80),
    "research_vessel": BlendermannType(0.85, 0.55, 0.65, 0.60),
    "speed_boat": BlendermannType(0.90, 0.55, 0.60, 0.60),
    "tanker_loaded": BlendermannType(0.70, 0.90, 0.55, 0.40),
    "tanker_ballast": BlendermannType(0.70, 0.75, 0.55, 0.40),
    "tender": BlendermannType(0.85, 0.55, 0.55, 0.65),
})

#: Other accepted spellings of a ship type (the controller's ``wind_feedforward.vessel_type`` names).
BLENDERMANN_TYPE_ALIASES: Mapping[str, str] = MappingProxyType({
    "offshore_supply": "offshore_supply_vessel",
    "cargo_loaded": "cargo_vessel_loaded",
})

#: Every accepted ship-type name: the table's, then the aliases.
BLENDERMANN_TYPE_NAMES: tuple[str, ...] = (*BLENDERMANN_TYPES, *BLENDERMANN_TYPE_ALIASES)


def blendermann_type(name: str) -> BlendermannType:
    """Blendermann parameters of a ship type.

    Parameters
    ----------
    name : str
        A key of :data:`BLENDERMANN_TYPES` or of :data:`BLENDERMANN_TYPE_ALIASES`.

    Returns
    -------
    BlendermannType

    Raises
    ------
    KeyError
        For an unknown name (the message lists the known ones).
    """
    row = BLENDERMANN_TYPES.get(BLENDERMANN_TYPE_ALIASES.get(name, name))
    if row is None:
        raise KeyError(f"unknown Blendermann ship type {name!r}; one of {', '.join(BLENDERMANN_TYPE_NAMES)}")
    return row


class WindCoefficients(Protocol):
    """Nondimensional wind coefficients as functions of the relative wind angle (eq. (18))."""

    def coefficients(self, gamma_rw_rad: float) -> tuple[float, float, float]:
        """``(C_X, C_Y, C_N)`` at ``γ_rw`` [rad] (eq. (20), the module's sign convention)."""
        ...


def relative_wind_angle(u_rw_mps: float, v_rw_mps: float) -> float:
    """Relative wind angle ``γ_rw = −atan2(v_rw, u_rw)`` (seed 002 eq. (20)).

    Parameters
    ----------
    u_rw_mps, v_rw_mps : float
        Vessel velocity minus wind velocity in body axes, eqs. (21)–(22) [m/s].

    Returns
    -------
    float
        γ_rw in [−π, π] [rad]: where the relative wind comes from, from the bow, positive to port.
    """
    return -math.atan2(v_rw_mps, u_rw_mps)


def wind_load_b(dynamic_pressure_pa: float, coefficients: tuple[float, float, float], frontal_area_m2: float,
                lateral_area_m2: float, length_m: float) -> tuple[float, float, float]:
    """Wind load in body axes from the dynamic pressure and the coefficients (seed 002 eq. (18)).

    Parameters
    ----------
    dynamic_pressure_pa : float
        ``q = ½ ρ_a V_rw²`` [Pa].
    coefficients : tuple of float
        ``(C_X, C_Y, C_N)`` at the relative wind angle.
    frontal_area_m2, lateral_area_m2 : float
        ``A_Fw``, ``A_Lw`` [m²].
    length_m : float
        ``L_oa`` [m].

    Returns
    -------
    tuple of float
        ``(X, Y, N)`` [N, N, N·m].
    """
    cx, cy, cn = coefficients
    q = dynamic_pressure_pa
    return q * frontal_area_m2 * cx, q * lateral_area_m2 * cy, q * lateral_area_m2 * length_m * cn


@dataclass(frozen=True)
class BlendermannCoefficients:
    """Blendermann (1994) closed-form wind coefficients of one vessel (see the module docstring).

    Attributes
    ----------
    cd_transverse : float
        ``C_Dt`` (> 0).
    cd_longitudinal_head, cd_longitudinal_tail : float
        ``C_Dl,AF`` for head (|γ_rw| ≤ π/2) and tail winds, on the frontal area.
    cross_force : float
        ``δ``, cross-force parameter.
    frontal_area_m2, lateral_area_m2 : float
        ``A_Fw``, ``A_Lw`` [m²] (≥ 0).
    length_m : float
        ``L_oa`` [m] (> 0).
    centroid_x_m : float
        ``s_L``: lateral-area centroid forward of midship [m].
    """

    cd_transverse: float
    cd_longitudinal_head: float
    cd_longitudinal_tail: float
    cross_force: float
    frontal_area_m2: float
    lateral_area_m2: float
    length_m: float
    centroid_x_m: float = 0.0

    def __post_init__(self) -> None:
        values = (self.cd_transverse, self.cd_longitudinal_head, self.cd_longitudinal_tail, self.cross_force,
                  self.frontal_area_m2, self.lateral_area_m2, self.length_m, self.centroid_x_m)
        if not all(math.isfinite(v) for v in values):
            raise ValueError(f"wind coefficients, areas and lengths must be finite, got {values}")
        if not (self.frontal_area_m2 >= 0.0 and self.lateral_area_m2 >= 0.0 and self.length_m > 0.0):
            raise ValueError("wind areas must be >= 0 and the length > 0")
        if not self.cd_transverse > 0.0:
            raise ValueError(f"C_Dt must be > 0, got {self.cd_transverse}")

    @staticmethod
    def of_type(ship_type: str, frontal_area_m2: float, lateral_area_m2: float, length_m: float,
                centroid_x_m: float = 0.0) -> BlendermannCoefficients:
        """Coefficients of a Blendermann ship type (a name of :data:`BLENDERMANN_TYPE_NAMES`).

        Parameters
        ----------
        ship_type : str
        frontal_area_m2, lateral_area_m2 : float
            ``A_Fw``, ``A_Lw`` [m²].
        length_m : float
            ``L_oa`` [m].
        centroid_x_m : float
            ``s_L`` [m].
        """
        cdt, head, tail, delta = blendermann_type(ship_type)
        return BlendermannCoefficients(cdt, head, tail, delta, frontal_area_m2, lateral_area_m2, length_m,
                                       centroid_x_m)

    def coefficients(self, gamma_rw_rad: float) -> tuple[float, float, float]:
        """``(C_X, C_Y, C_N)`` for a relative wind from ``γ_rw`` [rad] (eq. (20): + from port)."""
        g = gamma_rw_rad
        cdl_af = self.cd_longitudinal_head if abs(g) <= 0.5 * math.pi else self.cd_longitudinal_tail
        if self.lateral_area_m2 > 0.0:
            cdl = cdl_af * self.frontal_area_m2 / self.lateral_area_m2
            den = 1.0 - 0.5 * self.cross_force * (1.0 - cdl / self.cd_transverse) * math.sin(2.0 * g) ** 2
        else:
            den = 1.0
        cx = -cdl_af * math.cos(g) / den
        cy = self.cd_transverse * math.sin(g) / den
        cn = (self.centroid_x_m / self.length_m - 0.18 * (abs(g) - 0.5 * math.pi)) * cy
        return cx, cy, cn

    def force_b(self, speed_mps: float, gamma_rw_rad: float, air_density_kgpm3: float
                ) -> tuple[float, float, float]:
        """Wind load ``τ_wind`` in body axes (eq. (18)).

        Parameters
        ----------
        speed_mps : float
            Relative wind speed V_rw [m/s].
        gamma_rw_rad : float
            Relative wind angle γ_rw [rad] (eq. (20)).
        air_density_kgpm3 : float
            ρ_a [kg/m³].

        Returns
        -------
        tuple of float
            ``(X, Y, N)`` [N, N, N·m].
        """
        q = 0.5 * air_density_kgpm3 * speed_mps * speed_mps
        return wind_load_b(q, self.coefficients(gamma_rw_rad), self.frontal_area_m2, self.lateral_area_m2,
                           self.length_m)
