"""Typed sensor messages: what every codec decodes to and encodes from.

Conventions: SI units and radians inside; latitude/longitude in degrees (WGS-84) because that is
what every protocol carries; missing data is ``None``, never NaN or 0. A message exists only when
the sensor said its data is valid — validity flags (GGA quality 0, RMC status V, FAA mode N,
THS mode V, NMEA 2000 "not available") turn into :class:`Rejected`, never into a message.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import IntEnum


class FixQuality(IntEnum):
    """GNSS fix quality, as in the GGA quality field (NMEA 0183) and PGN 129029 method."""

    INVALID = 0
    GPS = 1
    DGPS = 2
    PPS = 3
    RTK_FIXED = 4
    RTK_FLOAT = 5
    DEAD_RECKONING = 6
    MANUAL = 7
    SIMULATION = 8


@dataclass(frozen=True, slots=True)
class PositionFix:
    """A valid GNSS position.

    Attributes
    ----------
    lat_deg, lon_deg : float
        WGS-84 latitude and longitude [deg].
    quality : FixQuality
        Fix type; never ``INVALID`` (an invalid fix is a :class:`Rejected`).
    utc_time_s : float or None
        Sample time as seconds since midnight UTC, where the protocol carries one.
    num_satellites : int or None
    hdop : float or None
        Horizontal dilution of precision [-].
    altitude_m : float or None
        Altitude above mean sea level [m].
    """

    lat_deg: float
    lon_deg: float
    quality: FixQuality
    utc_time_s: float | None = None
    num_satellites: int | None = None
    hdop: float | None = None
    altitude_m: float | None = None


@dataclass(frozen=True, slots=True)
class PositionErrorStats:
    """GNSS pseudorange error statistics (NMEA GST): 1-σ position errors [m].

    ``sigma_major_m``, ``sigma_minor_m`` and ``orientation_rad`` describe the horizontal error
    ellipse (semi-axes [m], orientation of the semi-major axis from true north, clockwise [rad]);
    with them :meth:`covariance_ne_m2` gives the full horizontal covariance, north–east
    correlation included.
    """

    sigma_north_m: float | None
    sigma_east_m: float | None
    sigma_altitude_m: float | None = None
    rms_range_m: float | None = None
    utc_time_s: float | None = None
    sigma_major_m: float | None = None
    sigma_minor_m: float | None = None
    orientation_rad: float | None = None

    def covariance_ne_m2(self) -> tuple[float, float, float] | None:
        """Horizontal position error covariance in the local NED frame.

        From the error ellipse when it is complete, ``P = R(θ) diag(a², b²) R(θ)ᵀ`` with the
        semi-major axis along ``(cos θ, sin θ)`` in (north, east); otherwise the diagonal
        ``diag(σ_N², σ_E²)``.

        Returns
        -------
        tuple of float or None
            ``(P_nn, P_ee, P_ne)`` [m²], or ``None`` when neither form is available.
        """
        a, b, theta = self.sigma_major_m, self.sigma_minor_m, self.orientation_rad
        if a is not None and b is not None and theta is not None:
            c, s = math.cos(theta), math.sin(theta)
            return (a * a * c * c + b * b * s * s, a * a * s * s + b * b * c * c, (a * a - b * b) * s * c)
        if self.sigma_north_m is not None and self.sigma_east_m is not None:
            return (self.sigma_north_m ** 2, self.sigma_east_m ** 2, 0.0)
        return None


@dataclass(frozen=True, slots=True)
class Heading:
    """A valid true heading (HDT, THS, PGN 127250 true, ATTITUDE yaw).

    Attributes
    ----------
    heading_rad : float
        True heading, 0 = north, clockwise, wrapped to [0, 2π) as sent by sensors [rad].
    mode : str or None
        THS mode indicator (A autonomous, E estimated, M manual, S simulator) where sent.
    """

    heading_rad: float
    mode: str | None = None
    utc_time_s: float | None = None


@dataclass(frozen=True, slots=True)
class RateOfTurn:
    """Rate of turn (ROT, PGN 127251, ATTITUDE yawspeed) [rad/s], positive to starboard."""

    rate_radps: float


@dataclass(frozen=True, slots=True)
class CourseOverGround:
    """Course and speed over ground (RMC, PGN 129026)."""

    course_rad: float | None
    speed_mps: float | None


@dataclass(frozen=True, slots=True)
class Attitude:
    """Roll, pitch and (optional) yaw [rad] (PGN 127257, MAVLink ATTITUDE)."""

    roll_rad: float | None
    pitch_rad: float | None
    yaw_rad: float | None = None


@dataclass(frozen=True, slots=True)
class Wind:
    """Wind speed [m/s] and direction [rad] (PGN 130306, MWV).

    ``reference`` is ``"apparent"`` (angle relative to the bow, clockwise) or ``"true"``
    (direction the wind comes *from*, relative to north).
    """

    speed_mps: float
    angle_rad: float
    reference: str


@dataclass(frozen=True, slots=True)
class LinkHeartbeat:
    """A link-level heartbeat (MAVLink HEARTBEAT): proof the sender is alive."""

    system_id: int
    component_id: int
    vehicle_type: int | None = None


@dataclass(frozen=True, slots=True)
class Rejected:
    """Input that did not become a message, and why (counted, recorded, never fatal).

    ``reason`` is a short machine-readable token (``checksum``, ``too_long``, ``invalid_fix``,
    ``not_available``, ``garbage``, ``truncated_fast_packet`` ...); ``detail`` is for humans;
    ``raw`` keeps the offending bytes (bounded) for the black-box recorder.
    """

    reason: str
    detail: str = ""
    raw: bytes = b""


SensorMessage = (
    PositionFix | PositionErrorStats | Heading | RateOfTurn | CourseOverGround | Attitude | Wind | LinkHeartbeat
)


@dataclass(frozen=True, slots=True)
class Measurement:
    """A decoded message stamped by the transport that received it.

    Attributes
    ----------
    t_s : float
        Receive time on the consumer's clock (monotonic in the daemon, stepped in lockstep) [s].
    source : str
        Configured sensor name (e.g. ``gnss1``, ``gyro2``).
    message : SensorMessage
        The typed content.
    """

    t_s: float
    source: str
    message: SensorMessage


@dataclass(frozen=True, slots=True)
class RejectedInput:
    """A :class:`Rejected` input stamped by the transport that received it (for counters and the recorder).

    Attributes
    ----------
    t_s : float
        Receive time on the consumer's clock [s].
    source : str
        Sensor or link name the input came from (best effort: a garbled frame may not say).
    rejected : Rejected
        Why it did not become a message.
    """

    t_s: float
    source: str
    rejected: Rejected


@dataclass(frozen=True, slots=True)
class LinkStatus:
    """A change of a link's state reported by a transport (bus error, reconnect, heartbeat loss).

    Attributes
    ----------
    t_s : float
        Time of the change on the consumer's clock [s].
    source : str
        Link or peer name (``can:ws://...``, ``mavlink:1/1``).
    connected : bool
        ``True`` when the link (re)gained contact, ``False`` when it was lost.
    detail : str
        Human-readable cause.
    """

    t_s: float
    source: str
    connected: bool
    detail: str = ""
