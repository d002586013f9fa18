"""MAVLink 2 codec: packets ⇄ the typed messages of :mod:`interfaces.messages` (pymavlink ``common``).

Pure (no clock read, no I/O). pymavlink parses, checks CRC and MAVLink 2 signatures and packs;
what is written here is the meaning:

* ``GPS_RAW_INT`` → :class:`PositionFix` (``fix_type`` < 2 = no fix → ``Rejected("invalid_fix")``;
  2/3 → GPS, 4 DGPS, 5 RTK float, 6 RTK fixed, 7 static → MANUAL (a fixed, not measured position),
  8 PPP → DGPS), plus :class:`CourseOverGround` from ``vel``/``cog`` and a dual-antenna
  :class:`Heading` from the ``yaw`` extension (0 = not provided, 36000 = north) when sent. A fix at
  lat = lon = 0 is a receiver's placeholder, not a position → ``Rejected("not_available")``.
* ``GLOBAL_POSITION_INT`` (the autopilot's fused estimate; no fix quality on the wire, reported as
  GPS) → :class:`PositionFix` (lat = lon = 0 is what autopilots send before they have a position →
  ``Rejected("not_available")``), :class:`Heading` from ``hdg`` (65535 = unknown → none), and
  :class:`CourseOverGround` from ``vx``/``vy``.
* ``ATTITUDE`` → :class:`Attitude`, :class:`Heading` (yaw in [-π, π] moved to [0, 2π); a yaw outside
  [-π, π] is no Euler angle and rejects the packet, it is not wrapped into a plausible heading) and
  :class:`RateOfTurn` (``yawspeed``: the body z rate r, equal to ψ̇ for small roll and pitch — the
  Euler-angle kinematics ψ̇ = (q sin φ + r cos φ)/cos θ, Fossen eq. (2.29), differ by < 1 % below
  8° of roll or pitch). NaN/inf floats are missing values, never numbers.

Every message a packet decodes to is checked against the physical limits of :mod:`interfaces.limits`;
one value outside them rejects the whole packet as ``out_of_range``.
* ``HEARTBEAT`` → :class:`LinkHeartbeat`; :class:`HeartbeatMonitor` turns heartbeats into link
  state (lost after ``timeout_s`` without one: 5 s = 5 missed beats at 1 Hz).

Signing (MAVLink 2): with a 32-byte key every packet must carry a valid signature; unsigned
(``unsigned``) and badly signed or replayed (``bad_signature``) packets are rejected and counted.
Without a key no signature is checked.

Resolution on the wire: lat/lon 1e-7° (≈ 1.1 cm; the encoder rounds, so ≤ 5.6 mm of latitude),
altitude 1 mm, HDOP 0.01, COG/heading/GPS yaw 0.01°, speeds 1 cm/s, ATTITUDE float32 (relative
6e-8), time_usec 1 µs.
"""

from __future__ import annotations

import hashlib
import hmac
import math
import threading
from collections import Counter
from collections.abc import Callable, Hashable, Iterable
from typing import Any, Final, NamedTuple

from pymavlink.dialects.v20 import common as mavlink2

from dpbase.frames import TWO_PI, ssa
from interfaces.limits import ROLL_MAX_RAD, violation
from interfaces.messages import (
    Attitude,
    CourseOverGround,
    FixQuality,
    Heading,
    LinkHeartbeat,
    PositionFix,
    RateOfTurn,
    Rejected,
    SensorMessage,
)

SIGNING_KEY_BYTES: Final = 32
SIGNING_EPOCH_UNIX_S: Final = 1_420_070_400  # MAVLink signing timestamps count 10 µs from 2015-01-01T00:00Z
UINT16_MAX: Final = 65535
UNIX_TIME_USEC_MIN: Final = 1_000_000_000_000_000  # time_usec above this (2001-09) is UNIX time, not time since boot
_RAW_KEEP: Final = 64

# GPS_FIX_TYPE → FixQuality (see module docstring); 0 NO_GPS and 1 NO_FIX are invalid.
_FIX_TYPES: Final[dict[int, FixQuality]] = {
    2: FixQuality.GPS, 3: FixQuality.GPS, 4: FixQuality.DGPS, 5: FixQuality.RTK_FLOAT, 6: FixQuality.RTK_FIXED,
    7: FixQuality.MANUAL, 8: FixQuality.DGPS,
}
_FIX_TYPE_OF: Final[dict[FixQuality, int]] = {
    FixQuality.GPS: 3, FixQuality.DGPS: 4, FixQuality.RTK_FLOAT: 5, FixQuality.RTK_FIXED: 6, FixQuality.MANUAL: 7,
}


def parse_signing_key(value: str | bytes) -> bytes:
    """A MAVLink 2 signing key from 32 raw bytes or 64 hexadecimal characters.

    Raises
    ------
    ValueError
        If the value is not a 32-byte key.
    """
    if isinstance(value, str):
        try:
            value = bytes.fromhex(value.strip())
        except ValueError as error:
            raise ValueError(f"signing key must be {2 * SIGNING_KEY_BYTES} hex digits: {error}") from error
    if not isinstance(value, bytes | bytearray) or len(value) != SIGNING_KEY_BYTES:
        raise ValueError(f"signing key must be {SIGNING_KEY_BYTES} bytes")
    return bytes(value)


def signing_timestamp(unix_time_s: float) -> int:
    """MAVLink 2 signing timestamp (10 µs units since 2015-01-01) of a UNIX time [s]."""
    return max(0, int((unix_time_s - SIGNING_EPOCH_UNIX_S) * 100_000))


def mavlink_source_name(system_id: int, component_id: int) -> str:
    """Default sensor name of a MAVLink system/component (``mav:1/1``; ``mav:?`` when unknown)."""
    return f"mav:{system_id}/{component_id}" if system_id >= 0 else "mav:?"


def wrap_2pi(angle_rad: float) -> float:
    """Wrap an angle to [0, 2π) [rad] (built on :func:`ssa`)."""
    wrapped = ssa(angle_rad)
    if wrapped < 0.0:
        wrapped += TWO_PI
    return 0.0 if wrapped >= TWO_PI else wrapped


def _finite(value: float) -> float | None:
    return value if math.isfinite(value) else None


def _centidegrees_to_rad(value: int) -> float:
    return wrap_2pi(math.radians(value / 100.0))


def _rad_to_centidegrees(angle_rad: float) -> int:
    """[0, 2π) rad → 0..35999 cdeg (rounded; 360.00° folds to 0)."""
    return round(math.degrees(wrap_2pi(angle_rad)) * 100.0) % 36000


class _MAVLink(mavlink2.MAVLink):
    """pymavlink's parser with the signature checked *before* the replay timestamp is recorded.

    pymavlink's ``check_signature`` stores a packet's timestamp as the stream's newest before it
    compares the signature, so one forged packet (CRC is public, the signature is not) with a
    future timestamp makes every genuine packet of that stream look like a replay until the real
    timestamps catch up. Same rules otherwise: per (link, system, component) stream a timestamp
    must increase; a new stream may be at most one minute behind the newest timestamp seen.
    """

    def check_signature(self, msgbuf: bytearray, srcSystem: int, srcComponent: int) -> bool:
        signing = self.signing
        digest = hashlib.sha256(signing.secret_key + bytes(msgbuf[:-6])).digest()[:6]
        if not hmac.compare_digest(digest, bytes(msgbuf[-6:])):
            return False
        t_low, t_high = self.mav_sign_unpacker.unpack(msgbuf[-12:-6])
        timestamp = t_low + (t_high << 32)
        stream = (msgbuf[-13], srcSystem, srcComponent)
        newest = signing.stream_timestamps.get(stream)
        if newest is not None and timestamp <= newest:
            return False  # replay or reordering
        if newest is None and timestamp + 6_000_000 < signing.timestamp:
            return False  # a "new" stream a minute or more in the past
        signing.stream_timestamps[stream] = timestamp
        signing.timestamp = max(signing.timestamp, timestamp)
        return True


class MavDecoded(NamedTuple):
    """One decoder result: a message or a reject, with the sender and the MAVLink message name."""

    system_id: int  # -1 when the packet was too broken to say
    component_id: int
    msg_name: str  # "" when unknown
    item: SensorMessage | Rejected


class MavlinkDecoder:
    """MAVLink 2 (and 1) decoder for whole datagrams or log records.

    Never raises on input. Accounting in :attr:`counters`: ``packets`` (what the parser
    delimited: packets good or bad, and stretches of garbage), ``messages`` (typed messages
    returned), ``rejected`` and ``rejected.<reason>`` (every returned reject, including a
    datagram's cut-off tail), ``ignored`` (well-formed packets of other message types).

    Parameters
    ----------
    signing_key : bytes, optional
        32-byte MAVLink 2 signing key: when given, only correctly signed packets are accepted.
    signing_time_s : float
        UNIX time [s] the signature check starts from: a *new* signed stream whose timestamp is more
        than a minute older is refused as a replay (pymavlink's rule). 0 accepts any new stream.
    """

    def __init__(self, signing_key: bytes | None = None, signing_time_s: float = 0.0) -> None:
        self._mav = _MAVLink(None)
        self._mav.robust_parsing = True  # bad bytes come back as BAD_DATA, not as exceptions
        self.signed = signing_key is not None
        if signing_key is not None:
            self._mav.signing.secret_key = parse_signing_key(signing_key)
            self._mav.signing.allow_unsigned_callback = None  # unsigned packets are rejected
            self._mav.signing.timestamp = signing_timestamp(signing_time_s)
        self.counters: Counter[str] = Counter()

    def _reset_parser(self) -> None:
        # pymavlink has no public reset; a datagram boundary ends any partial packet, which must
        # not be glued to the next datagram's bytes.
        mav = self._mav
        mav.buf = bytearray()
        mav.buf_index = 0
        mav.expected_length = mavlink2.HEADER_LEN_V1 + 2

    def decode_datagram(self, data: bytes | bytearray | memoryview) -> list[MavDecoded]:
        """Decode one UDP datagram (or one tlog record): whole packets, trailing bytes rejected."""
        out: list[MavDecoded] = []
        try:
            messages = self._mav.parse_buffer(bytes(data)) or []
        except Exception as error:  # robust parsing should not raise; the reader must survive if it does
            self._reset_parser()
            out.append(self._reject(-1, -1, "", Rejected("garbage", f"parser: {error!r}", bytes(data[:_RAW_KEEP]))))
            return out
        for message in messages:
            out.extend(self.decode_message(message))
        left = self._mav.buf_len()
        if left:
            tail = bytes(self._mav.buf[self._mav.buf_index:])
            self._reset_parser()
            out.append(self._reject(-1, -1, "", Rejected("truncated", f"{left} bytes of an incomplete packet",
                                                         tail[:_RAW_KEEP])))
        return out

    def decode_message(self, message: Any) -> list[MavDecoded]:
        """Decode one pymavlink message object (from :meth:`decode_datagram` or a pymavlink reader)."""
        self.counters["packets"] += 1
        name = message.get_type()
        if name == "BAD_DATA":
            return [self._reject(-1, -1, "", self._bad_data(message))]
        system_id, component_id = message.get_srcSystem(), message.get_srcComponent()
        convert = _CONVERTERS.get(name)
        if convert is None:
            self.counters["ignored"] += 1
            return []
        try:
            items = convert(message)
        except Exception as error:  # a converter bug on odd values must not take the reader down
            items = [Rejected("decode_error", f"{name}: {error!r}", bytes(message.get_msgbuf()[:_RAW_KEEP]))]
        problems = [problem for item in items if not isinstance(item, Rejected)
                    and (problem := violation(item)) is not None]
        if problems:  # one impossible value discredits the whole packet
            items = [Rejected("out_of_range", f"{name}: {problems[0]}", bytes(message.get_msgbuf()[:_RAW_KEEP]))]
        out = []
        for item in items:
            if isinstance(item, Rejected):
                out.append(self._reject(system_id, component_id, name, item))
            else:
                self.counters["messages"] += 1
                out.append(MavDecoded(system_id, component_id, name, item))
        return out

    def _reject(self, system_id: int, component_id: int, name: str, rejected: Rejected) -> MavDecoded:
        self.counters["rejected"] += 1
        self.counters["rejected." + rejected.reason] += 1
        return MavDecoded(system_id, component_id, name, rejected)

    @staticmethod
    def _bad_data(message: Any) -> Rejected:
        raw = bytes(message.data)
        why = str(message.reason)
        if why == "Invalid signature":
            signed = len(raw) > 2 and raw[0] == mavlink2.PROTOCOL_MARKER_V2 and raw[2] & mavlink2.MAVLINK_IFLAG_SIGNED
            return Rejected("bad_signature" if signed else "unsigned", why, raw[:_RAW_KEEP])
        if why == "Bad prefix":
            return Rejected("garbage", f"{len(raw)} bytes before a packet start", raw[:_RAW_KEEP])
        if "CRC" in why:
            return Rejected("checksum", why, raw[:_RAW_KEEP])
        return Rejected("bad_packet", why, raw[:_RAW_KEEP])


def _utc_time_s(time_usec: int) -> float | None:
    """Seconds of the UTC day from a UNIX-epoch ``time_usec``; ``None`` for time since boot."""
    if time_usec < UNIX_TIME_USEC_MIN:
        return None
    return (time_usec % 86_400_000_000) / 1e6


def _position(lat_e7: int, lon_e7: int, what: str, raw: bytes) -> tuple[float, float] | Rejected:
    lat, lon = lat_e7 * 1e-7, lon_e7 * 1e-7
    if abs(lat) > 90.0 or abs(lon) > 180.0:
        return Rejected("out_of_range", f"{what} lat {lat} lon {lon}", raw)
    return lat, lon


def _gps_raw_int(m: Any) -> list[SensorMessage | Rejected]:
    raw = bytes(m.get_msgbuf()[:_RAW_KEEP])
    quality = _FIX_TYPES.get(m.fix_type)
    if quality is None:
        return [Rejected("invalid_fix", f"GPS_RAW_INT fix_type {m.fix_type}", raw)]
    if m.lat == 0 and m.lon == 0:
        return [Rejected("not_available", f"GPS_RAW_INT fix_type {m.fix_type} at lat = lon = 0 (no position)", raw)]
    position = _position(m.lat, m.lon, "GPS_RAW_INT", raw)
    if isinstance(position, Rejected):
        return [position]
    out: list[SensorMessage | Rejected] = [PositionFix(
        position[0], position[1], quality, utc_time_s=_utc_time_s(m.time_usec),
        num_satellites=None if m.satellites_visible == 255 else m.satellites_visible,
        hdop=None if m.eph == UINT16_MAX else m.eph / 100.0, altitude_m=m.alt / 1000.0)]
    course = None if m.cog == UINT16_MAX or m.cog >= 36000 else _centidegrees_to_rad(m.cog)
    speed = None if m.vel == UINT16_MAX else m.vel / 100.0
    if course is not None or speed is not None:
        out.append(CourseOverGround(course, speed))
    yaw = getattr(m, "yaw", 0)  # extension field: 0 = this receiver gives no heading
    if yaw == UINT16_MAX:
        out.append(Rejected("not_available", "GPS_RAW_INT yaw configured but unavailable", raw))
    elif 0 < yaw <= 36000:
        out.append(Heading(_centidegrees_to_rad(yaw % 36000)))
    elif yaw:
        out.append(Rejected("out_of_range", f"GPS_RAW_INT yaw {yaw} cdeg", raw))
    return out


def _global_position_int(m: Any) -> list[SensorMessage | Rejected]:
    raw = bytes(m.get_msgbuf()[:_RAW_KEEP])
    if m.lat == 0 and m.lon == 0:
        return [Rejected("not_available", "GLOBAL_POSITION_INT lat = lon = 0 (no position yet)", raw)]
    position = _position(m.lat, m.lon, "GLOBAL_POSITION_INT", raw)
    if isinstance(position, Rejected):
        return [position]
    out: list[SensorMessage | Rejected] = [PositionFix(position[0], position[1], FixQuality.GPS,
                                                       altitude_m=m.alt / 1000.0)]
    if m.hdg != UINT16_MAX:
        if m.hdg >= 36000:
            out.append(Rejected("out_of_range", f"GLOBAL_POSITION_INT hdg {m.hdg} cdeg", raw))
        else:
            out.append(Heading(_centidegrees_to_rad(m.hdg)))
    speed = math.hypot(m.vx, m.vy) / 100.0
    # the NED velocity defines a course only while the vessel moves
    out.append(CourseOverGround(wrap_2pi(math.atan2(m.vy, m.vx)) if speed > 0.0 else None, speed))
    return out


def _attitude(m: Any) -> list[SensorMessage | Rejected]:
    roll, pitch, yaw = _finite(m.roll), _finite(m.pitch), _finite(m.yaw)
    rate = _finite(m.yawspeed)
    if roll is None and pitch is None and yaw is None and rate is None:
        return [Rejected("not_available", "ATTITUDE without finite values", bytes(m.get_msgbuf()[:_RAW_KEEP]))]
    out: list[SensorMessage | Rejected] = []
    if yaw is not None and not -ROLL_MAX_RAD <= yaw <= ROLL_MAX_RAD:
        return [Rejected("out_of_range", f"ATTITUDE yaw {yaw} rad is not in [-pi, pi]",
                         bytes(m.get_msgbuf()[:_RAW_KEEP]))]
    if roll is not None or pitch is not None or yaw is not None:
        out.append(Attitude(roll, pitch, None if yaw is None else ssa(yaw)))
    if yaw is not None:
        out.append(Heading(wrap_2pi(yaw)))
    if rate is not None:
        out.append(RateOfTurn(rate))
    return out


def _heartbeat(m: Any) -> list[SensorMessage | Rejected]:
    return [LinkHeartbeat(m.get_srcSystem(), m.get_srcComponent(), m.type)]


_CONVERTERS: Final[dict[str, Callable[[Any], list[SensorMessage | Rejected]]]] = {
    "GPS_RAW_INT": _gps_raw_int,
    "GLOBAL_POSITION_INT": _global_position_int,
    "ATTITUDE": _attitude,
    "HEARTBEAT": _heartbeat,
}
DECODED_MESSAGES: Final = frozenset(_CONVERTERS)


# --------------------------------------------------------------------------------------------
# Encoder (the emulator's autopilot)
# --------------------------------------------------------------------------------------------

class MavlinkEncoder:
    """Packs MAVLink 2 packets as a boat autopilot sends them (``MAV_TYPE_SURFACE_BOAT``,
    ``MAV_AUTOPILOT_GENERIC``), optionally signed.

    Thread-safe (a heartbeat thread and the emulator may share it: the sequence number and the
    signing timestamp are updated under a lock).

    Parameters
    ----------
    system_id, component_id : int
        Sender identity (1–255; component 1 = autopilot).
    signing_key : bytes, optional
        32-byte key: when given, every packet is signed with ``signing_link_id``.
    unix_clock : callable, optional
        UNIX time [s]; when given, the signing timestamp follows it (MAVLink requires the
        timestamp to track wall time so a restarted sender is not taken for a replay).
    utc_day_start_s : float
        UNIX time of the UTC midnight the emulated day starts at, to turn ``utc_time_s``
        (seconds of day) into GPS_RAW_INT's UNIX ``time_usec`` (default 2024-01-01T00:00Z).
    """

    def __init__(self, system_id: int = 1, component_id: int = 1, *, signing_key: bytes | None = None,
                 signing_link_id: int = 0, unix_clock: Callable[[], float] | None = None,
                 utc_day_start_s: float = 1_704_067_200.0) -> None:
        if not (1 <= system_id <= 255 and 0 <= component_id <= 255):
            raise ValueError(f"system_id must be 1..255 and component_id 0..255, got {system_id}/{component_id}")
        self._mav = mavlink2.MAVLink(None, srcSystem=system_id, srcComponent=component_id)
        self.system_id, self.component_id = system_id, component_id
        self._unix_clock = unix_clock
        self.utc_day_start_s = float(utc_day_start_s)
        if signing_key is not None:
            signing = self._mav.signing
            signing.secret_key = parse_signing_key(signing_key)
            signing.sign_outgoing = True
            signing.link_id = signing_link_id
            signing.timestamp = signing_timestamp(unix_clock()) if unix_clock is not None else 1
        self._lock = threading.Lock()

    def _pack(self, message: Any) -> bytes:
        with self._lock:
            if self._unix_clock is not None and self._mav.signing.sign_outgoing:
                signing = self._mav.signing
                signing.timestamp = max(signing.timestamp, signing_timestamp(self._unix_clock()))
            packet = bytes(message.pack(self._mav))
            self._mav.seq = (self._mav.seq + 1) % 256
        return packet

    def heartbeat(self, *, system_status: int = mavlink2.MAV_STATE_ACTIVE, base_mode: int = 0,
                  custom_mode: int = 0) -> bytes:
        """HEARTBEAT of a surface boat with a generic autopilot (send at 1 Hz)."""
        return self._pack(self._mav.heartbeat_encode(mavlink2.MAV_TYPE_SURFACE_BOAT, mavlink2.MAV_AUTOPILOT_GENERIC,
                                                     base_mode, custom_mode, system_status))

    def gps_raw_int(self, fix: PositionFix | None, *, time_usec: int | None = None,
                    course: CourseOverGround | None = None, heading: Heading | None = None,
                    fix_type: int | None = None) -> bytes:
        """GPS_RAW_INT. ``fix=None`` sends ``fix_type`` 1 (no fix).

        ``time_usec`` defaults to the fix's ``utc_time_s`` on the day starting at
        ``utc_day_start_s`` (0 when the fix has no time). ``heading`` fills the dual-antenna ``yaw``.

        Raises
        ------
        ValueError
            For a fix quality MAVLink has no ``fix_type`` for (PPS, dead reckoning, simulation).
        """
        if fix is None:
            lat_e7 = lon_e7 = alt_mm = 0
            eph, satellites = UINT16_MAX, 255
            kind = 1 if fix_type is None else fix_type
            utc = None
        else:
            if fix_type is None and fix.quality not in _FIX_TYPE_OF:
                raise ValueError(f"{fix.quality!r} has no MAVLink GPS_FIX_TYPE")
            kind = _FIX_TYPE_OF[fix.quality] if fix_type is None else fix_type
            lat_e7, lon_e7 = round(fix.lat_deg * 1e7), round(fix.lon_deg * 1e7)
            alt_mm = 0 if fix.altitude_m is None else round(fix.altitude_m * 1000.0)
            eph = UINT16_MAX if fix.hdop is None else min(round(fix.hdop * 100.0), UINT16_MAX - 1)
            satellites = 255 if fix.num_satellites is None else min(fix.num_satellites, 254)
            utc = fix.utc_time_s
        if time_usec is None:
            time_usec = 0 if utc is None else round((self.utc_day_start_s + utc) * 1e6)
        cog = UINT16_MAX if course is None or course.course_rad is None else _rad_to_centidegrees(course.course_rad)
        vel = UINT16_MAX if course is None or course.speed_mps is None else min(round(course.speed_mps * 100.0),
                                                                                 UINT16_MAX - 1)
        yaw = 0 if heading is None else (_rad_to_centidegrees(heading.heading_rad) or 36000)
        return self._pack(self._mav.gps_raw_int_encode(time_usec, kind, lat_e7, lon_e7, alt_mm, eph, UINT16_MAX,
                                                       vel, cog, satellites, yaw=yaw))

    def global_position_int(self, fix: PositionFix | None, *, time_boot_ms: int = 0, heading: Heading | None = None,
                            velocity_ned_mps: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> bytes:
        """GLOBAL_POSITION_INT (``fix=None``: lat = lon = 0, the "no position yet" convention)."""
        lat_e7 = 0 if fix is None else round(fix.lat_deg * 1e7)
        lon_e7 = 0 if fix is None else round(fix.lon_deg * 1e7)
        alt_mm = 0 if fix is None or fix.altitude_m is None else round(fix.altitude_m * 1000.0)
        hdg = UINT16_MAX if heading is None else _rad_to_centidegrees(heading.heading_rad)
        vx, vy, vz = (round(v * 100.0) for v in velocity_ned_mps)
        return self._pack(self._mav.global_position_int_encode(time_boot_ms, lat_e7, lon_e7, alt_mm, alt_mm,
                                                               vx, vy, vz, hdg))

    def attitude(self, attitude: Attitude | None, *, rate: RateOfTurn | None = None, time_boot_ms: int = 0,
                 roll_rate_radps: float = 0.0, pitch_rate_radps: float = 0.0) -> bytes:
        """ATTITUDE (yaw sent in (−π, π]; missing values as NaN, which the decoder reads as missing)."""
        nan = float("nan")
        roll = nan if attitude is None or attitude.roll_rad is None else attitude.roll_rad
        pitch = nan if attitude is None or attitude.pitch_rad is None else attitude.pitch_rad
        yaw = nan if attitude is None or attitude.yaw_rad is None else ssa(attitude.yaw_rad)
        yawspeed = nan if rate is None else rate.rate_radps
        return self._pack(self._mav.attitude_encode(time_boot_ms, roll, pitch, yaw, roll_rate_radps,
                                                    pitch_rate_radps, yawspeed))


class LinkChange(NamedTuple):
    """A change of heartbeat state: ``key`` (a (system, component) pair, or ``None`` for "nothing
    heard since start"), the new state, the time [s] and why."""

    key: Hashable | None
    connected: bool
    t_s: float
    detail: str


class HeartbeatMonitor:
    """Heartbeat-loss detection on an injected time base (pure: the caller passes ``t_s``).

    A peer is *connected* from its first heartbeat and *lost* once ``t_s − t_last > timeout_s``
    (5 s = about five missed heartbeats at the MAVLink-standard 1 Hz); it is connected again by
    its next heartbeat. If nothing at all has been heard ``timeout_s`` after ``start_t_s``, one
    ``key=None`` change says so.

    Parameters
    ----------
    timeout_s : float
        Silence [s] after which a peer is lost.
    start_t_s : float, optional
        Time the monitor started [s] (enables the "nothing heard" report).
    """

    def __init__(self, timeout_s: float = 5.0, start_t_s: float | None = None) -> None:
        if not timeout_s > 0.0:
            raise ValueError("timeout_s must be > 0")
        self.timeout_s = float(timeout_s)
        self._start_t_s = start_t_s
        self._last: dict[Hashable, float] = {}
        self._up: dict[Hashable, bool] = {}
        self._silence_reported = False

    def connected(self, key: Hashable) -> bool:
        """Whether ``key`` is currently connected."""
        return self._up.get(key, False)

    @property
    def peers(self) -> Iterable[Hashable]:
        """Every peer heard so far."""
        return tuple(self._last)

    def beat(self, key: Hashable, t_s: float) -> LinkChange | None:
        """Record a heartbeat; returns the change if ``key`` was new or lost."""
        self._last[key] = t_s
        if self._up.get(key):
            return None
        recovered = key in self._up
        self._up[key] = True
        return LinkChange(key, True, t_s, "heartbeat resumed" if recovered else "first heartbeat")

    def check(self, t_s: float) -> list[LinkChange]:
        """Peers lost by ``t_s`` (each reported once per loss)."""
        changes = []
        for key, last in self._last.items():
            if self._up[key] and t_s - last > self.timeout_s:
                self._up[key] = False
                changes.append(LinkChange(key, False, t_s, f"no heartbeat for {t_s - last:.1f} s "
                                                           f"(timeout {self.timeout_s:g} s)"))
        if (not self._last and not self._silence_reported and self._start_t_s is not None
                and t_s - self._start_t_s > self.timeout_s):
            self._silence_reported = True
            changes.append(LinkChange(None, False, t_s, f"no heartbeat within {self.timeout_s:g} s of start"))
        return changes
