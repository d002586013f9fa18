"""Physical limits of every value a decoder emits, one table for NMEA 0183, NMEA 2000 and MAVLink.

A field can be well formed and still impossible: a rate of turn of 1e56 rad/s, an HDOP of -3, a speed
over ground of 655 m/s (a 16-bit "not available" sentinel a sender scaled by mistake), an altitude of
9e12 m. Every codec passes each message it is about to emit through :func:`violation`; a message with
a value outside these limits becomes ``Rejected("out_of_range")`` (counted like every other reason),
never a measurement. NaN and ±inf fail every comparison below, so a non-finite value is always out
of range.

The limits are what the physical world allows a GNSS receiver, compass or rate sensor on a vessel to
report, with the reasons given next to each, not what a DP vessel usually sees: a rare but real value
must pass (the hub's own plausibility checks judge the rest).
"""

from __future__ import annotations

import math
from typing import Final

from interfaces.messages import (
    Attitude,
    CourseOverGround,
    Heading,
    LinkHeartbeat,
    PositionErrorStats,
    PositionFix,
    RateOfTurn,
    SensorMessage,
    Wind,
)

ANGLE_SLACK_RAD: Final = 1e-4
"""One least significant bit of NMEA 2000 angles (1e-4 rad): an encoder rounding π or 2π up stays in range."""

HEADING_MAX_RAD: Final = 2.0 * math.pi
"""Headings and courses are directions in [0, 2π) once decoded; 2π itself may be sent for north."""

ROLL_MAX_RAD: Final = math.pi + ANGLE_SLACK_RAD
"""Roll and yaw of an attitude are Euler angles in [-π, π] (Fossen's zyx convention)."""

PITCH_MAX_RAD: Final = math.pi / 2.0 + ANGLE_SLACK_RAD
"""Pitch is the zyx Euler angle θ in [-π/2, π/2] (beyond it the attitude is written with another roll and yaw)."""

RATE_OF_TURN_MAX_RADPS: Final = math.pi
"""Half a turn a second (10 800 °/min). Ships turn a few °/s and fast craft a few tens; every marine rate
sensor's range is within it."""

SPEED_MAX_MPS: Final = 1000.0 * 1852.0 / 3600.0
"""1000 knots (514 m/s): civil GNSS receivers stop reporting above it (the COCOM export limit), and a
16-bit speed sentinel scaled by 0.01 (655.35 m/s) lies above it."""

WIND_SPEED_MAX_MPS: Final = 120.0
"""Above the strongest gust ever measured at the surface (113 m/s, Barrow Island 1996)."""

ALTITUDE_MIN_M: Final = -1000.0
"""Below the lowest shore on Earth (Dead Sea, -430 m) with room for a geoid model's error."""

ALTITUDE_MAX_M: Final = 100_000.0
"""The Kármán line: above it a receiver is no longer on a vessel or in the air."""

HDOP_MAX: Final = 100.0
"""Receivers write DOPs with two integer digits (99.9 or 99.99 mean "very poor"); above is not a DOP."""

SATELLITES_MAX: Final = 99
"""The satellites-used field of GGA and GNS has two digits; more than all the navigation satellites a
receiver can see at once anyway."""

POSITION_SIGMA_MAX_M: Final = 1.0e7
"""A 1-σ position error larger than the Earth's diameter (GST, 1.27e7 m) says nothing; 1e7 m is the
largest value receivers send when they have no estimate (gpsd's corpus: u-blox and SkyTraq)."""

UTC_DAY_S: Final = 86401.0
"""Seconds of a UTC day, a leap second included."""


def _outside(value: float | None, low: float, high: float) -> bool:
    """Whether an optional value lies outside [low, high] (NaN and ±inf always do; ``None`` never)."""
    return value is not None and not low <= value <= high


def violation(message: SensorMessage) -> str | None:
    """The first value of ``message`` outside its physical limits, described, or ``None`` when all are in range.

    Parameters
    ----------
    message : SensorMessage
        A decoded message about to be emitted.

    Returns
    -------
    str or None
        E.g. ``"rate_radps 1e+56 is not in [-3.14159, 3.14159]"``; ``None`` when every field is finite
        and within the limits of this module.
    """
    checks: tuple[tuple[str, float | None, float, float], ...]
    if isinstance(message, PositionFix):
        checks = (("lat_deg", message.lat_deg, -90.0, 90.0), ("lon_deg", message.lon_deg, -180.0, 180.0),
                  ("utc_time_s", message.utc_time_s, 0.0, UTC_DAY_S),
                  ("num_satellites", message.num_satellites, 0, SATELLITES_MAX),
                  ("hdop", message.hdop, 0.0, HDOP_MAX),
                  ("altitude_m", message.altitude_m, ALTITUDE_MIN_M, ALTITUDE_MAX_M))
    elif isinstance(message, Heading):
        checks = (("heading_rad", message.heading_rad, 0.0, HEADING_MAX_RAD),
                  ("utc_time_s", message.utc_time_s, 0.0, UTC_DAY_S))
    elif isinstance(message, RateOfTurn):
        checks = (("rate_radps", message.rate_radps, -RATE_OF_TURN_MAX_RADPS, RATE_OF_TURN_MAX_RADPS),)
    elif isinstance(message, CourseOverGround):
        checks = (("course_rad", message.course_rad, 0.0, HEADING_MAX_RAD),
                  ("speed_mps", message.speed_mps, 0.0, SPEED_MAX_MPS))
    elif isinstance(message, Attitude):
        checks = (("roll_rad", message.roll_rad, -ROLL_MAX_RAD, ROLL_MAX_RAD),
                  ("pitch_rad", message.pitch_rad, -PITCH_MAX_RAD, PITCH_MAX_RAD),
                  ("yaw_rad", message.yaw_rad, -ROLL_MAX_RAD, ROLL_MAX_RAD))
    elif isinstance(message, Wind):
        checks = (("speed_mps", message.speed_mps, 0.0, WIND_SPEED_MAX_MPS),
                  ("angle_rad", message.angle_rad, 0.0, HEADING_MAX_RAD))
    elif isinstance(message, PositionErrorStats):
        sigma = POSITION_SIGMA_MAX_M
        checks = (("sigma_north_m", message.sigma_north_m, 0.0, sigma),
                  ("sigma_east_m", message.sigma_east_m, 0.0, sigma),
                  ("sigma_altitude_m", message.sigma_altitude_m, 0.0, sigma),
                  ("rms_range_m", message.rms_range_m, 0.0, sigma),
                  ("utc_time_s", message.utc_time_s, 0.0, UTC_DAY_S),
                  ("sigma_major_m", message.sigma_major_m, 0.0, sigma),
                  ("sigma_minor_m", message.sigma_minor_m, 0.0, sigma),
                  ("orientation_rad", message.orientation_rad, -ROLL_MAX_RAD, ROLL_MAX_RAD))
    elif isinstance(message, LinkHeartbeat):
        checks = (("system_id", message.system_id, 0, 255), ("component_id", message.component_id, 0, 255),
                  ("vehicle_type", message.vehicle_type, 0, 255))
    else:
        return f"{type(message).__name__} has no limits"
    for name, value, low, high in checks:
        if _outside(value, low, high):
            return f"{name} {value!r} is not in [{low:g}, {high:g}]"
    return None
