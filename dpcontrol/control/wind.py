"""Wind load model for feed-forward (seed 002 eqs. (18)–(22), (35)).

    τ_wind = ½ ρ_a V_rw² [A_Fw C_X(γ_rw),  A_Lw C_Y(γ_rw),  A_Lw L_oa C_N(γ_rw)]ᵀ      (18)
    V_rw   = √(u_rw² + v_rw²)                                                      (19)
    γ_rw   = −atan2(v_rw, u_rw)                                                    (20)
    u_rw   = u − u_w,   v_rw = v − v_w                                             (21)–(22)

with ``(u_w, v_w) = V_w (cos(β_w − ψ), sin(β_w − ψ))`` the wind velocity in body axes, β_w the
direction the air moves *towards* (seed 002 writes β_w relative to the hull; here the earth-fixed
direction is rotated by the heading). With this sign convention γ_rw = 0 is a head wind,
γ_rw = −90° a wind from starboard and +90° from port (Blendermann 1994; Fossen 2021 §10.1).
The controller adds ``−τ̂_wind`` (seed 002 eq. (35)).

The API takes the meteorological direction the wind blows *from* (as an anemometer or NMEA MWD
reports it): ``β_w = wind_from + π``.

Coefficients: :class:`BlendermannCoefficients` — the smooth closed-form fit of Blendermann
(1994), "Parameter identification of wind loads on ships", J. Wind Eng. Ind. Aerodyn. 51,
339–351 (also Fossen 2021 §10.1.2):

    den = 1 − ½ δ (1 − C_Dl/C_Dt) sin²(2γ),          C_Dl = C_Dl,AF(γ) · A_Fw/A_Lw
    C_X = −C_Dl,AF(γ) cos γ / den,   C_Y = C_Dt sin γ / den,
    C_N = [s_L/L_oa − 0.18 (|γ| − π/2)] C_Y

where ``C_Dl,AF`` is the head-wind (|γ| ≤ 90°) or tail-wind value and ``s_L`` the longitudinal
position of the lateral-area centroid (forward of midship positive). Or
:class:`TabulatedCoefficients` — measured tables (e.g. from model tests or CFD, seed 002 Fig. 6),
interpolated periodically in γ.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from dpbase.schema import ConfigError, Section
from dpcontrol.models.vessels import VesselData

RHO_AIR_KGPM3 = 1.226  # ISA sea level, 15 °C


class WindCoefficients(Protocol):
    """Nondimensional wind coefficients as functions of the relative wind angle γ_rw [rad]."""

    def coefficients(self, gamma_rw_rad: float) -> tuple[float, float, float]:
        """``(C_X, C_Y, C_N)`` at ``γ_rw`` (seed 002 eq. (18) convention)."""
        ...


@dataclass(frozen=True)
class BlendermannCoefficients:
    """Blendermann (1994) closed-form wind coefficients (see module docstring).

    Attributes
    ----------
    cd_transverse : float
        ``C_Dt``, beam-wind drag coefficient.
    cd_longitudinal_head, cd_longitudinal_tail : float
        ``C_Dl,AF`` for head (|γ| ≤ 90°) and tail winds, on the frontal area.
    cross_force : float
        ``δ``, cross-force parameter.
    frontal_area_m2, lateral_area_m2, length_m : float
        ``A_Fw``, ``A_Lw``, ``L_oa``.
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
        if not (self.frontal_area_m2 > 0.0 and self.lateral_area_m2 > 0.0 and self.length_m > 0.0):
            raise ValueError("wind areas and length must be > 0")

    def coefficients(self, gamma_rw_rad: float) -> tuple[float, float, float]:
        g = gamma_rw_rad
        head = abs(g) <= 0.5 * math.pi
        cdl_af = self.cd_longitudinal_head if head else self.cd_longitudinal_tail
        cdl = cdl_af * self.frontal_area_m2 / self.lateral_area_m2
        den = 1.0 - 0.5 * self.cross_force * (1.0 - cdl / self.cd_transverse) * math.sin(2.0 * g) ** 2
        cx = -cdl_af * math.cos(g) / den
        cy = self.cd_transverse * math.sin(g) / den
        cn = (self.centroid_x_m / self.length_m - 0.18 * (abs(g) - 0.5 * math.pi)) * cy
        return cx, cy, cn


# Blendermann (1994) Table 2 parameters (C_Dt, C_Dl,AF head, C_Dl,AF tail, δ) for the ship types the
# built-in vessels belong to.
BLENDERMANN_TYPES: dict[str, tuple[float, float, float, float]] = {
    "offshore_supply": (0.90, 0.55, 0.80, 0.55),
    "tanker_loaded": (0.70, 0.90, 0.55, 0.40),
    "tanker_ballast": (0.70, 0.75, 0.55, 0.40),
    "cargo_loaded": (0.85, 0.65, 0.55, 0.40),
}


@dataclass(frozen=True)
class TabulatedCoefficients:
    """Wind coefficients from tables over γ ∈ [−π, π) (linear, periodic interpolation).

    Attributes
    ----------
    gamma_rad : ndarray, shape (k,)
        Strictly increasing relative wind angles within [−π, π) [rad].
    cx, cy, cn : ndarray, shape (k,)
        Coefficients at those angles.
    """

    gamma_rad: np.ndarray
    cx: np.ndarray
    cy: np.ndarray
    cn: np.ndarray

    def __post_init__(self) -> None:
        arrays = [np.asarray(a, dtype=float) for a in (self.gamma_rad, self.cx, self.cy, self.cn)]
        if any(a.ndim != 1 or a.shape != arrays[0].shape for a in arrays) or arrays[0].size < 2:
            raise ValueError("wind tables need equal-length 1-D arrays with at least 2 angles")
        if not all(np.all(np.isfinite(a)) for a in arrays):
            raise ValueError("wind tables must be finite")
        g = arrays[0]
        if np.any(np.diff(g) <= 0.0) or g[0] < -math.pi or g[-1] >= math.pi:
            raise ValueError("gamma_rad must increase strictly within [-pi, pi)")
        for name, array in zip(("gamma_rad", "cx", "cy", "cn"), arrays, strict=True):
            array.setflags(write=False)
            object.__setattr__(self, name, array)

    def coefficients(self, gamma_rw_rad: float) -> tuple[float, float, float]:
        period = 2.0 * math.pi
        return (float(np.interp(gamma_rw_rad, self.gamma_rad, self.cx, period=period)),
                float(np.interp(gamma_rw_rad, self.gamma_rad, self.cy, period=period)),
                float(np.interp(gamma_rw_rad, self.gamma_rad, self.cn, period=period)))


def default_wind_coefficients(vessel: VesselData) -> BlendermannCoefficients | None:
    """Blendermann coefficients for a built-in vessel type (None without wind areas).

    Types: tankers and Blue Lady (a VLCC model) → tanker loaded/ballast by draft; the mariner →
    cargo vessel loaded; CyberShip II, supply and inline vessels → offshore supply vessel.
    Centroid at midship (``s_L = 0``).
    """
    if vessel.frontal_wind_area_m2 <= 0.0 or vessel.lateral_wind_area_m2 <= 0.0:
        return None
    if vessel.name.startswith("shuttle_tanker") or vessel.name == "blue_lady":
        kind = "tanker_ballast" if vessel.name == "shuttle_tanker" else "tanker_loaded"
    elif vessel.name == "mariner":
        kind = "cargo_loaded"
    else:
        kind = "offshore_supply"
    cdt, head, tail, delta = BLENDERMANN_TYPES[kind]
    return BlendermannCoefficients(cdt, head, tail, delta, vessel.frontal_wind_area_m2,
                                   vessel.lateral_wind_area_m2, vessel.length_m)


class WindFeedforward:
    """Estimated wind load ``τ̂_wind`` from a wind measurement (seed 002 eqs. (18)–(22)).

    Parameters
    ----------
    coefficients : WindCoefficients
        ``C_X, C_Y, C_N`` as functions of γ_rw.
    frontal_area_m2, lateral_area_m2, length_m : float
        ``A_Fw``, ``A_Lw``, ``L_oa`` of eq. (18).
    air_density_kgpm3 : float
        ``ρ_a``.
    """

    def __init__(self, coefficients: WindCoefficients, frontal_area_m2: float, lateral_area_m2: float,
                 length_m: float, air_density_kgpm3: float = RHO_AIR_KGPM3) -> None:
        for name, value in (("frontal_area_m2", frontal_area_m2), ("lateral_area_m2", lateral_area_m2),
                            ("length_m", length_m), ("air_density_kgpm3", air_density_kgpm3)):
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"{name} must be finite and > 0, got {value!r}")
        self._coefficients = coefficients
        self._af = float(frontal_area_m2)
        self._al = float(lateral_area_m2)
        self._loa = float(length_m)
        self._rho = float(air_density_kgpm3)

    @staticmethod
    def for_vessel(vessel: VesselData, coefficients: WindCoefficients | None = None) -> WindFeedforward | None:
        """Feed-forward with the vessel's areas (None if the vessel has no wind areas)."""
        coefficients = coefficients or default_wind_coefficients(vessel)
        if coefficients is None:
            return None
        return WindFeedforward(coefficients, vessel.frontal_wind_area_m2, vessel.lateral_wind_area_m2,
                               vessel.length_m)

    def force_b(self, wind_speed_mps: float, wind_from_rad: float, psi_rad: float,
                nu_b: np.ndarray | None = None) -> np.ndarray:
        """Estimated wind load on the vessel ``τ̂_wind`` in body axes ``[N, N, N·m]``.

        Parameters
        ----------
        wind_speed_mps : float
            True wind speed V_w (>= 0) [m/s].
        wind_from_rad : float
            True direction the wind blows from, NED, clockwise from north [rad].
        psi_rad : float
            Heading [rad].
        nu_b : array_like, shape (3,), optional
            Body velocity (relative wind, eqs. (21)–(22)); zero if omitted.

        Returns
        -------
        ndarray, shape (3,)
            ``τ̂_wind`` (pass it as ``tau_wind_ff_b`` to a controller, which subtracts it).
        """
        if not (math.isfinite(wind_speed_mps) and wind_speed_mps >= 0.0):
            raise ValueError(f"wind_speed_mps must be finite and >= 0, got {wind_speed_mps!r}")
        if not (math.isfinite(wind_from_rad) and math.isfinite(psi_rad)):
            raise ValueError("wind direction and heading must be finite")
        u = v = 0.0
        if nu_b is not None:
            u, v = float(nu_b[0]), float(nu_b[1])
            if not (math.isfinite(u) and math.isfinite(v)):
                raise ValueError("nu_b must be finite")
        beta_w = wind_from_rad + math.pi  # direction the air moves towards
        u_w = wind_speed_mps * math.cos(beta_w - psi_rad)
        v_w = wind_speed_mps * math.sin(beta_w - psi_rad)
        u_rw = u - u_w  # (21)
        v_rw = v - v_w  # (22)
        v_rw2 = u_rw * u_rw + v_rw * v_rw  # (19) squared
        if v_rw2 == 0.0:
            return np.zeros(3)
        gamma = -math.atan2(v_rw, u_rw)  # (20)
        cx, cy, cn = self._coefficients.coefficients(gamma)
        q = 0.5 * self._rho * v_rw2
        return np.array([q * self._af * cx, q * self._al * cy, q * self._al * self._loa * cn])  # (18)


def wind_feedforward_from_mapping(value: object, vessel: VesselData, path: str = "wind_feedforward"
                                  ) -> WindFeedforward | None:
    """Validate a ``wind_feedforward:`` config mapping (None or ``{enabled: false}``: no feed-forward).

    Keys: ``enabled`` (bool, default true), ``coefficients``: ``blendermann`` (default) with
    ``vessel_type`` (one of :data:`BLENDERMANN_TYPES`, default by vessel) and ``centroid_x_m``, or
    ``table`` with ``gamma_deg``, ``cx``, ``cy``, ``cn`` (equal-length lists, γ increasing in
    [−180, 180)); ``frontal_area_m2``, ``lateral_area_m2``, ``length_m`` (default: the vessel's),
    ``air_density_kgpm3``.

    Raises
    ------
    ConfigError
        Naming the key path and what was expected.
    """
    if value is None:
        return None
    section = Section.of(value, path)
    if not section.boolean("enabled", True):
        for key in list(section.data):  # the rest of a disabled section is kept for later, not checked
            section.raw(key, None)
        return None
    kind = section.string("coefficients", "blendermann", choices=("blendermann", "table"))
    frontal = section.number("frontal_area_m2", vessel.frontal_wind_area_m2, minimum=0.0, exclusive_minimum=True)
    lateral = section.number("lateral_area_m2", vessel.lateral_wind_area_m2, minimum=0.0, exclusive_minimum=True)
    length = section.number("length_m", vessel.length_m, minimum=0.0, exclusive_minimum=True)
    density = section.number("air_density_kgpm3", RHO_AIR_KGPM3, minimum=0.0, exclusive_minimum=True)
    coefficients: WindCoefficients
    if kind == "blendermann":
        default = default_wind_coefficients(vessel)
        default_type = "offshore_supply"
        if default is not None:
            default_type = next((name for name, row in BLENDERMANN_TYPES.items()
                                 if row == (default.cd_transverse, default.cd_longitudinal_head,
                                            default.cd_longitudinal_tail, default.cross_force)), default_type)
        vessel_type = section.string("vessel_type", default_type, choices=BLENDERMANN_TYPES)
        cdt, head, tail, delta = BLENDERMANN_TYPES[vessel_type]
        coefficients = BlendermannCoefficients(cdt, head, tail, delta, frontal, lateral, length,
                                               section.number("centroid_x_m", 0.0))
    else:
        gamma = section.vector("gamma_deg")
        tables = [section.vector(key, len(gamma)) for key in ("cx", "cy", "cn")]
        try:
            coefficients = TabulatedCoefficients(np.radians(gamma), *tables)
        except ValueError as error:
            raise ConfigError(f"{section.path}.gamma_deg", "increasing angles in [-180, 180) (at least 2)",
                              str(error)) from None
    section.finish()
    return WindFeedforward(coefficients, frontal, lateral, length, density)
