"""Wind load feed-forward (seed 002 eqs. (18)–(22), (35)).

The law — eqs. (18)–(22), Blendermann's (1994) coefficients, their ship-type table and the sign
convention — is :mod:`dpbase.wind_loads`, shared with the plant. Here: the controller's side, the
estimate ``τ̂_wind`` from a wind *measurement*. The controller adds ``−τ̂_wind`` (seed 002 eq. (35)).

The API takes the meteorological direction the wind blows *from* (as an anemometer or NMEA MWD
reports it): ``β_w = wind_from + π`` is the direction the air moves towards, and
``(u_w, v_w) = V_w (cos(β_w − ψ), sin(β_w − ψ))`` the wind velocity in body axes (seed 002 writes β_w
relative to the hull; here the earth-fixed direction is rotated by the heading). γ_rw is eq. (20),
``−atan2(v_rw, u_rw)``: 0 for a head wind, −90° for a wind from starboard, +90° from port.

Coefficients: :class:`~dpbase.wind_loads.BlendermannCoefficients` (the closed-form fit; the type by
vessel of :func:`default_wind_type`, centroid at midship unless configured) or
:class:`TabulatedCoefficients` — measured tables (e.g. from model tests or CFD, seed 002 Fig. 6) in the
same γ_rw convention, interpolated periodically in γ.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from dpbase.schema import ConfigError, Section
from dpbase.wind_loads import (
    BLENDERMANN_TYPE_NAMES,
    BlendermannCoefficients,
    WindCoefficients,
    relative_wind_angle,
    wind_load_b,
)
from dpcontrol.models.vessels import VesselData

RHO_AIR_KGPM3 = 1.226  # ISA sea level, 15 °C


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


def default_wind_type(vessel: VesselData) -> str:
    """Blendermann ship type (a key of :data:`dpbase.wind_loads.BLENDERMANN_TYPES`) of a built-in vessel.

    Tankers and Blue Lady (a VLCC model) → tanker loaded/ballast by draft; the mariner → cargo
    vessel loaded; CyberShip II, supply and inline vessels → offshore supply vessel.
    """
    if vessel.name.startswith("shuttle_tanker") or vessel.name == "blue_lady":
        return "tanker_ballast" if vessel.name == "shuttle_tanker" else "tanker_loaded"
    if vessel.name == "mariner":
        return "cargo_vessel_loaded"
    return "offshore_supply_vessel"


def default_wind_coefficients(vessel: VesselData) -> BlendermannCoefficients | None:
    """Blendermann coefficients of :func:`default_wind_type` (None without wind areas).

    Centroid at midship (``s_L = 0``).
    """
    if vessel.frontal_wind_area_m2 <= 0.0 or vessel.lateral_wind_area_m2 <= 0.0:
        return None
    return BlendermannCoefficients.of_type(default_wind_type(vessel), vessel.frontal_wind_area_m2,
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
        coefficients = self._coefficients.coefficients(relative_wind_angle(u_rw, v_rw))  # (20)
        q = 0.5 * self._rho * v_rw2
        return np.array(wind_load_b(q, coefficients, self._af, self._al, self._loa))  # (18)


def wind_feedforward_from_mapping(value: object, vessel: VesselData, path: str = "wind_feedforward"
                                  ) -> WindFeedforward | None:
    """Validate a ``wind_feedforward:`` config mapping (None or ``{enabled: false}``: no feed-forward).

    Keys: ``enabled`` (bool, default true), ``coefficients``: ``blendermann`` (default) with
    ``vessel_type`` (a name of :data:`dpbase.wind_loads.BLENDERMANN_TYPE_NAMES`, default
    :func:`default_wind_type`) and ``centroid_x_m``, or
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
        # a vessel without wind areas of its own (the areas come from this section) counts as a supply vessel
        has_areas = default_wind_coefficients(vessel) is not None
        default_type = default_wind_type(vessel) if has_areas else "offshore_supply_vessel"
        vessel_type = section.string("vessel_type", default_type, choices=BLENDERMANN_TYPE_NAMES)
        coefficients = BlendermannCoefficients.of_type(vessel_type, frontal, lateral, length,
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
