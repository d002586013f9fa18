"""The fuzz tests' own statement of what a decoded message may hold: finite values within physical
limits, written out here (not imported from ``interfaces.limits``) so that a decoder or a limit gone
wrong is caught, not confirmed. Importable as ``physical_range``: ``tests/`` is on ``sys.path``.
"""

from __future__ import annotations

import math

from interfaces.messages import (
    Attitude,
    CourseOverGround,
    FixQuality,
    Heading,
    LinkHeartbeat,
    PositionErrorStats,
    PositionFix,
    RateOfTurn,
    Wind,
)

PI = math.pi
_BOUNDS: dict[type, dict[str, tuple[float, float]]] = {
    PositionFix: {"lat_deg": (-90, 90), "lon_deg": (-180, 180), "utc_time_s": (0, 86401), "num_satellites": (0, 99),
                  "hdop": (0, 100), "altitude_m": (-1000, 100_000)},
    Heading: {"heading_rad": (0, 2 * PI), "utc_time_s": (0, 86401)},
    RateOfTurn: {"rate_radps": (-PI, PI)},
    CourseOverGround: {"course_rad": (0, 2 * PI), "speed_mps": (0, 1000 * 1852 / 3600)},
    Attitude: {"roll_rad": (-PI - 1e-4, PI + 1e-4), "pitch_rad": (-PI / 2 - 1e-4, PI / 2 + 1e-4),
               "yaw_rad": (-PI - 1e-4, PI + 1e-4)},
    Wind: {"speed_mps": (0, 120), "angle_rad": (0, 2 * PI)},
    PositionErrorStats: {name: (0, 1e7) for name in ("sigma_north_m", "sigma_east_m", "sigma_altitude_m",
                                                     "rms_range_m", "sigma_major_m", "sigma_minor_m")}
    | {"utc_time_s": (0, 86401), "orientation_rad": (-PI - 1e-4, PI + 1e-4)},
    LinkHeartbeat: {"system_id": (0, 255), "component_id": (0, 255), "vehicle_type": (0, 255)},
}


def out_of_range(message: object) -> list[str]:
    """What is wrong with a decoded message: non-finite or out-of-range values, an invalid quality
    (empty when nothing is)."""
    bounds = _BOUNDS.get(type(message))
    if bounds is None:
        return [f"unknown message type {type(message).__name__}"]
    problems = []
    for name in message.__slots__:  # type: ignore[attr-defined]
        value = getattr(message, name)
        if isinstance(value, bool) or not isinstance(value, int | float):
            continue
        if not math.isfinite(value):
            problems.append(f"{name}={value!r} is not finite")
        elif name in bounds and not bounds[name][0] <= value <= bounds[name][1]:
            problems.append(f"{name}={value!r} is outside {bounds[name]}")
    if isinstance(message, PositionFix) and message.quality == FixQuality.INVALID:
        problems.append("an INVALID fix")
    if isinstance(message, Wind) and message.reference not in ("true", "apparent"):
        problems.append(f"wind reference {message.reference!r}")
    return problems
