"""NMEA 0183 codec: bytes ⇄ typed messages (pure: no I/O, no clock, no threads).

Decoding is a stream decoder, :class:`Nmea0183Decoder`, that frames arbitrary chunks of a byte
stream into sentences and turns each into typed messages of :mod:`interfaces.messages` or a
:class:`~interfaces.messages.Rejected`. Sentence syntax is checked by pynmea2 (``pynmea2.parse``). The
checksum is verified here on the bytes (pynmea2's own check XORs ``ord()`` of each character, three times
the cost) and a sentence whose checksum does not match is handed to ``pynmea2.parse(..., check=True)``
whole, so what is rejected and why is pynmea2's verdict either way. Everything pynmea2 does not do safely
is done here (docs/design.md §5):

* the checksum is *mandatory* (pynmea2 accepts a sentence without one unless told);
* validity flags are read *before* values: GGA quality 0, RMC status ``V``, FAA mode ``N``
  (RMC, GNS), THS mode ``V``, ROT/MWV status ``V`` give a ``Rejected``, never a message;
* empty fields are *no data* (pynmea2 turns an empty latitude into 0.0, we reject);
* numbers are parsed strictly (``float()`` would accept ``nan``, ``inf``, ``1e5``, ``1_0``)
  and range-checked (minutes < 60, |lat| ≤ 90°, heading in [0°, 360°] ...);
* THS (true heading and status) is missing from pynmea2 1.19; it is registered below.

Framing rules (all skips are counted per reason, none is fatal):

* a sentence starts at ``$`` (or ``!``, encapsulated) and ends at CR, LF or CR LF;
* bytes outside a sentence are ``garbage`` (binary protocols, noise, half lines after a
  reconnect), counted once per run between terminators;
* a sentence cut short by the start of the next one (two ``$`` in one line, a missing CR LF)
  is ``merged``; the sentence that follows is decoded normally;
* a sentence longer than ``max_sentence_chars`` (``$`` to LF; default
  :data:`DEFAULT_MAX_SENTENCE_CHARS`, 128, above NMEA 0183's 82 so that high-precision receivers are
  read) is ``too_long``; the buffer never holds more than that many bytes of an unterminated line, so
  garbage without a newline cannot grow memory.

Every message a sentence decodes to is checked against the physical limits of
:mod:`interfaces.limits` (a rate of turn beyond half a turn a second, a negative HDOP, a speed above
1000 kn ...): one value outside them rejects the sentence as ``out_of_range``.

Counters (``Nmea0183Decoder.counters``) keep ``frames == ok + ignored + rejected`` at all times:
``ok`` frames produced at least one message, ``ignored`` frames are well-formed sentences with a
valid checksum of a type we do not use (GSV, GSA, proprietary, AIS ...), and each rejected
frame adds one to ``rejected`` and to ``rejected.<reason>``.

Encoders (``encode_gga`` ...) are what the plant emulator sends. Latitude and longitude are
written with 7 decimals of arc-minutes, like RTK receivers: the quantisation is at most
0.5e-7 arc-minute, ≤ 0.093 mm along each axis (:data:`LATLON_QUANTISATION_M`), and every encoded
sentence stays within the standard 82 characters.
"""

from __future__ import annotations

import functools
import math
import operator
import re
from collections.abc import Callable
from typing import NamedTuple

import pynmea2

from dpbase.frames import ssa
from dpbase.geodesy import WGS84_A_M, WGS84_E2
from interfaces.limits import violation
from interfaces.messages import (
    CourseOverGround,
    FixQuality,
    Heading,
    PositionErrorStats,
    PositionFix,
    RateOfTurn,
    Rejected,
    SensorMessage,
    Wind,
)

# ----------------------------------------------------------------------------------------------
# constants

NMEA_MAX_SENTENCE_CHARS = 82
"""NMEA 0183 limit: ``$`` through the checksum and CR LF (what the encoders keep to)."""

DEFAULT_MAX_SENTENCE_CHARS = 128
"""Longest sentence the decoder accepts by default, ``$`` through CR LF.

Receivers in high-precision mode (u-blox HPNMEA, Trimble, SkyTraq, Unicore, Hemisphere RTK) write 8
decimals of arc-minutes and break NMEA's 82: up to 93 characters in gpsd's corpus of 115 receivers.
GGA with every field at its widest high-precision width (``hhmmss.sss``, ``ddmm.mmmmmmmm``,
``dddmm.mmmmmmmm``, 2-digit satellites, ``99.99`` HDOP, ``-99999.999`` altitude, ``-999.999``
separation, ``999.9`` age, 4-digit station) is 101 characters; 128, the next power of two, leaves
room for a receiver wider still. The limit only bounds memory and ends a runaway line: 128 bytes are
as harmless as 82."""

LATLON_MINUTE_DECIMALS = 7
"""Decimals of arc-minutes written by the encoders."""

LATLON_QUANTISATION_M = 0.5e-7 * math.radians(1.0 / 60.0) * WGS84_A_M / math.sqrt(1.0 - WGS84_E2)
"""Worst-case rounding of an encoded latitude or longitude along its axis [m]: half a unit of the
7th decimal of an arc-minute times the largest WGS-84 radius of curvature (polar, 6399.6 km), i.e.
0.093 mm; the horizontal error is at most √2 times that (0.13 mm)."""

HEADING_DECIMALS = 3
"""Decimals of degrees in encoded headings: quantisation 0.0005° = 8.7e-6 rad."""

RAW_EXCERPT_BYTES = 96
"""How many bytes of an offending input a :class:`Rejected` keeps."""

KNOT_MPS = 1852.0 / 3600.0
"""One knot [m/s]."""

REJECT_REASONS = (
    "garbage",         # bytes outside any sentence (binary protocols, noise)
    "merged",          # a sentence cut short by the start of another one (missing CR LF)
    "too_long",        # longer than max_sentence_chars
    "unterminated",    # an incomplete line left at flush() (end of a log, a reconnect)
    "malformed",       # not the NMEA sentence syntax (bad characters, address, checksum field)
    "no_checksum",     # the checksum is mandatory
    "checksum",        # checksum mismatch
    "invalid_fix",     # GNSS says no fix: GGA quality 0, RMC status V, FAA mode N (or manual/simulated)
    "invalid_status",  # heading/rate/wind sensor says invalid: THS mode V, ROT/MWV status V
    "no_data",         # a required field is empty
    "bad_field",       # a field is not a number in the NMEA format
    "out_of_range",    # a well-formed value outside its physical limits (interfaces.limits)
)
"""Machine-readable reasons a frame becomes a :class:`Rejected` (``counters["rejected.<reason>"]``)."""

_FAA_QUALITY = {
    "A": FixQuality.GPS,
    "D": FixQuality.DGPS,
    "P": FixQuality.PPS,
    "R": FixQuality.RTK_FIXED,
    "F": FixQuality.RTK_FLOAT,
    "E": FixQuality.DEAD_RECKONING,
    "M": FixQuality.MANUAL,
    "S": FixQuality.SIMULATION,
}
_QUALITY_FAA = {quality: mode for mode, quality in _FAA_QUALITY.items()}
# rank of FAA modes when a GNS sentence carries one per constellation: the best one describes the fix
_FAA_RANK = "RFPDAEMS"
_QUALITY_BY_CODE = tuple(sorted(FixQuality))  # GGA quality code → FixQuality without Enum.__call__
_NOT_MEASURED = frozenset({FixQuality.MANUAL, FixQuality.SIMULATION})
_MWV_SPEED_UNIT_MPS = {"M": 1.0, "K": 1.0 / 3.6, "N": KNOT_MPS, "S": 0.44704}


# pynmea2 1.19 has no THS (docs/design.md §5). Subclassing TalkerSentence is pynmea2's documented way
# to add a sentence: its metaclass registers the class by name, so this is the one import-time
# effect of this module (idempotent, and skipped if a later pynmea2 brings its own THS).
if "THS" not in pynmea2.TalkerSentence.sentence_types:

    class THS(pynmea2.TalkerSentence):
        """True heading and status (NMEA 0183 v3.0): heading [deg], mode indicator A/E/M/S/V."""

        fields = (
            ("Heading, degrees True", "heading", float),
            ("Mode indicator", "mode_indicator"),
        )


# ----------------------------------------------------------------------------------------------
# strict field parsing
# Written by hand on purpose: pynmea2's converters return 0.0 for an empty latitude, accept
# out-of-range minutes and fall back to the raw string when a conversion fails.

_NUMBER_RE = re.compile(r"[+-]?(?:\d+(?:\.\d*)?|\.\d+)")
_UNSIGNED_RE = re.compile(r"\d+(?:\.\d*)?|\.\d+")
_INT_RE = re.compile(r"\d+")
_LAT_RE = re.compile(r"(\d{2})(\d{2}(?:\.\d*)?)")
_LON_RE = re.compile(r"(\d{3})(\d{2}(?:\.\d*)?)")
_TIME_RE = re.compile(r"(\d{2})(\d{2})(\d{2}(?:\.\d*)?)")


class _FieldError(Exception):
    """A field that makes the sentence unusable: ``reason`` is one of :data:`REJECT_REASONS`."""

    def __init__(self, reason: str, detail: str) -> None:
        super().__init__(detail)
        self.reason = reason
        self.detail = detail


def _number(text: str, name: str, *, signed: bool = True) -> float | None:
    """A decimal number, or ``None`` for an empty field."""
    if not text:
        return None
    if not (_NUMBER_RE if signed else _UNSIGNED_RE).fullmatch(text):
        raise _FieldError("bad_field", f"{name} {text!r} is not a{'' if signed else 'n unsigned'} decimal number")
    return float(text)


def _integer(text: str, name: str) -> int | None:
    if not text:
        return None
    if not _INT_RE.fullmatch(text):
        raise _FieldError("bad_field", f"{name} {text!r} is not an integer")
    return int(text)


def _required(value: float | None, name: str) -> float:
    if value is None:
        raise _FieldError("no_data", f"{name} is empty")
    return value


def _coordinate(text: str, hemisphere: str, is_lat: bool) -> float | None:
    """``ddmm.mmmm,N`` / ``dddmm.mmmm,E`` → signed degrees; ``None`` when both fields are empty."""
    name = "latitude" if is_lat else "longitude"
    if not text and not hemisphere:
        return None
    if not text or not hemisphere:
        raise _FieldError("no_data", f"{name} {text!r},{hemisphere!r} is incomplete")
    match = (_LAT_RE if is_lat else _LON_RE).fullmatch(text)
    if match is None:
        raise _FieldError("bad_field", f"{name} {text!r} is not {'ddmm.mmmm' if is_lat else 'dddmm.mmmm'}")
    minutes = float(match.group(2))
    if minutes >= 60.0:
        raise _FieldError("bad_field", f"{name} {text!r} has {minutes} minutes")
    value = int(match.group(1)) + minutes / 60.0
    if value > (90.0 if is_lat else 180.0):
        raise _FieldError("out_of_range", f"{name} {text!r} is beyond {'90' if is_lat else '180'} degrees")
    positive, negative = ("N", "S") if is_lat else ("E", "W")
    if hemisphere == positive:
        return value
    if hemisphere == negative:
        return -value
    raise _FieldError("bad_field", f"{name} hemisphere {hemisphere!r} is not {positive}/{negative}")


def _utc_time_s(text: str) -> float | None:
    """``hhmmss.ss`` → seconds since midnight UTC; ``None`` for an empty field."""
    if not text:
        return None
    match = _TIME_RE.fullmatch(text)
    if match is None:
        raise _FieldError("bad_field", f"UTC time {text!r} is not hhmmss.ss")
    hours, minutes, seconds = int(match.group(1)), int(match.group(2)), float(match.group(3))
    if hours > 23 or minutes > 59 or seconds >= 61.0:  # 60.x: a leap second
        raise _FieldError("out_of_range", f"UTC time {text!r} is not a time of day")
    return hours * 3600.0 + minutes * 60.0 + seconds


def _angle_deg(text: str, name: str) -> float | None:
    """A direction in [0°, 360°] (360 is sent by some sensors for north) → [0°, 360°)."""
    value = _number(text, name, signed=False)
    if value is None:
        return None
    if value > 360.0:
        raise _FieldError("out_of_range", f"{name} {text!r} is not in [0, 360] deg")
    return 0.0 if value == 360.0 else value


def _fields(data: list[str], count: int) -> list[str]:
    """At least ``count`` fields: ``data`` itself when it has them (a decoder reads only the first ``count``),
    else padded with empty strings for those a short sentence does not carry."""
    return data if len(data) >= count else [*data, *([""] * (count - len(data)))]


# ----------------------------------------------------------------------------------------------
# sentence decoders: fields (after the address) → messages
# (messages are built with positional arguments, in their field order: a keyword call of a dataclass
# __init__ costs twice as much, and one message is built per sentence)


def _gga(data: list[str], strict: bool) -> tuple[SensorMessage, ...]:
    """GGA: time, lat, N/S, lon, E/W, quality, satellites, HDOP, altitude, M, separation, M, age, station."""
    f = _fields(data, 14)
    quality_code = _integer(f[5], "GGA quality")
    if quality_code is None:
        raise _FieldError("no_data", "GGA quality is empty")
    if quality_code == 0:
        raise _FieldError("invalid_fix", "GGA quality 0 (no fix)")
    if quality_code >= len(_QUALITY_BY_CODE):
        raise _FieldError("bad_field", f"GGA quality {quality_code} is not defined")
    quality = _QUALITY_BY_CODE[quality_code]
    if strict and quality in _NOT_MEASURED:
        raise _FieldError("invalid_fix", f"GGA quality {quality_code} ({quality.name.lower()}) is not a measurement")
    satellites = _integer(f[6], "GGA satellites")
    if satellites == 0 and quality != FixQuality.DEAD_RECKONING:
        # a satellite fix from no satellites is a stale or placeholder position (Garmin, MTK and
        # Hemisphere receivers send it while losing lock); gpsd also reports no fix for it
        raise _FieldError("invalid_fix", f"GGA quality {quality_code} with 0 satellites used")
    lat = _required(_coordinate(f[1], f[2], True), "GGA latitude")
    lon = _required(_coordinate(f[3], f[4], False), "GGA longitude")
    altitude = _number(f[8], "GGA altitude")
    if f[9] not in ("M", ""):
        raise _FieldError("bad_field", f"GGA altitude unit {f[9]!r} is not M")
    return (PositionFix(lat, lon, quality, _utc_time_s(f[0]), satellites, _number(f[7], "GGA HDOP", signed=False),
                        altitude),)


def _faa_quality(mode: str, sentence: str, strict: bool) -> FixQuality:
    """Quality from an FAA mode indicator string (one character, or one per constellation in GNS)."""
    if not mode:
        raise _FieldError("no_data", f"{sentence} mode indicator is empty")
    for char in mode:
        if char != "N" and char not in _FAA_QUALITY:
            raise _FieldError("bad_field", f"{sentence} mode indicator {mode!r} is not A/D/E/F/M/N/P/R/S")
    usable = [char for char in mode if char != "N" and not (strict and _FAA_QUALITY[char] in _NOT_MEASURED)]
    if not usable:
        what = "no fix" if set(mode) == {"N"} else "manual or simulated, not a measurement"
        raise _FieldError("invalid_fix", f"{sentence} mode indicator {mode!r} ({what})")
    return _FAA_QUALITY[min(usable, key=_FAA_RANK.index)]


def _rmc(data: list[str], strict: bool) -> tuple[SensorMessage, ...]:
    """RMC: time, status, lat, N/S, lon, E/W, SOG [kn], COG [deg], date, variation, E/W, mode, nav status.

    The NMEA 4.1 navigational status (field 13, ``V`` from u-blox = "not provided") says nothing
    about the fix and is ignored (pynmea2's ``is_valid`` wrongly rejects it).
    """
    f = _fields(data, 12)
    status = f[1]
    if status == "V":
        raise _FieldError("invalid_fix", "RMC status V (navigation receiver warning)")
    if status != "A":
        raise _FieldError("no_data" if not status else "bad_field", f"RMC status {status!r} is not A/V")
    quality = _faa_quality(f[11], "RMC", strict) if f[11] else FixQuality.GPS  # NMEA < 2.3: no mode
    lat = _required(_coordinate(f[2], f[3], True), "RMC latitude")
    lon = _required(_coordinate(f[4], f[5], False), "RMC longitude")
    utc = _utc_time_s(f[0])
    speed_kn = _number(f[6], "RMC speed", signed=False)
    course_deg = _angle_deg(f[7], "RMC course")
    fix = PositionFix(lat, lon, quality, utc)
    if speed_kn is None and course_deg is None:
        return (fix,)
    return (fix, CourseOverGround(None if course_deg is None else math.radians(course_deg),
                                  None if speed_kn is None else speed_kn * KNOT_MPS))


def _vtg(data: list[str], strict: bool) -> tuple[SensorMessage, ...]:
    """VTG: course true [deg], T, course magnetic, M, SOG [kn], N, SOG [km/h], K, mode (NMEA 2.3+).

    The FAA mode is read first (``N`` no fix → ``invalid_fix``; manual or simulated → ``invalid_fix`` when
    strict); the speed in knots is taken, else the one in km/h; the magnetic course is not used (no variation
    here). A course without its ``T`` (the pre-2.0 form without unit letters) is ``bad_field``.
    """
    f = _fields(data, 9)
    if f[8]:
        _faa_quality(f[8], "VTG", strict)
    if f[0] and f[1] != "T":
        raise _FieldError("bad_field", f"VTG course unit {f[1]!r} is not T")
    course_deg = _angle_deg(f[0], "VTG course")
    speed = _number(f[4], "VTG speed", signed=False)
    if speed is not None:
        if f[5] != "N":
            raise _FieldError("bad_field", f"VTG speed unit {f[5]!r} is not N")
        speed *= KNOT_MPS
    else:
        speed = _number(f[6], "VTG speed", signed=False)
        if speed is not None:
            if f[7] != "K":
                raise _FieldError("bad_field", f"VTG speed unit {f[7]!r} is not K")
            speed /= 3.6
    if speed is None and course_deg is None:
        raise _FieldError("no_data", "VTG carries neither a true course nor a speed")
    return (CourseOverGround(None if course_deg is None else math.radians(course_deg), speed),)


def _gns(data: list[str], strict: bool) -> tuple[SensorMessage, ...]:
    """GNS: time, lat, N/S, lon, E/W, mode (one char per constellation), satellites, HDOP, altitude, ..."""
    f = _fields(data, 9)
    quality = _faa_quality(f[5], "GNS", strict)
    satellites = _integer(f[6], "GNS satellites")
    if satellites == 0 and quality != FixQuality.DEAD_RECKONING:
        raise _FieldError("invalid_fix", f"GNS mode {f[5]!r} with 0 satellites used")
    lat = _required(_coordinate(f[1], f[2], True), "GNS latitude")
    lon = _required(_coordinate(f[3], f[4], False), "GNS longitude")
    return (PositionFix(lat, lon, quality, _utc_time_s(f[0]), satellites, _number(f[7], "GNS HDOP", signed=False),
                        _number(f[8], "GNS altitude")),)


def _gll(data: list[str], strict: bool) -> tuple[SensorMessage, ...]:
    """GLL: lat, N/S, lon, E/W, time, status A/V, mode (NMEA 2.3+; absent before).

    Status ``V`` or mode ``N`` is no fix; modes ``M``/``S`` are not measurements (strict). Without a mode
    (NMEA < 2.3) status ``A`` is a plain GNSS fix, as for RMC.
    """
    f = _fields(data, 7)
    status = f[5]
    if status == "V":
        raise _FieldError("invalid_fix", "GLL status V (data not valid)")
    if status != "A":
        raise _FieldError("no_data" if not status else "bad_field", f"GLL status {status!r} is not A/V")
    quality = _faa_quality(f[6], "GLL", strict) if f[6] else FixQuality.GPS
    lat = _required(_coordinate(f[0], f[1], True), "GLL latitude")
    lon = _required(_coordinate(f[2], f[3], False), "GLL longitude")
    return (PositionFix(lat, lon, quality, _utc_time_s(f[4])),)


def _gst(data: list[str], strict: bool) -> tuple[SensorMessage, ...]:
    """GST: time, RMS range, σ major, σ minor, orientation [deg], σ lat, σ lon, σ alt [m]."""
    del strict
    f = _fields(data, 8)
    utc = _utc_time_s(f[0])
    rms = _number(f[1], "GST rms", signed=False)
    major = _number(f[2], "GST sigma major", signed=False)
    minor = _number(f[3], "GST sigma minor", signed=False)
    # the orientation of an axis: SkyTraq sends it signed (-41.8 is the axis of 138.2); keep it in (-180, 180]
    orientation_deg = _number(f[4], "GST orientation")
    if orientation_deg is not None and abs(orientation_deg) > 360.0:
        raise _FieldError("out_of_range", f"GST orientation {f[4]!r} is not an angle in degrees")
    sigma_north = _number(f[5], "GST sigma latitude", signed=False)
    sigma_east = _number(f[6], "GST sigma longitude", signed=False)
    sigma_down = _number(f[7], "GST sigma altitude", signed=False)
    if (sigma_north is None or sigma_east is None) and (major is None or minor is None or orientation_deg is None):
        raise _FieldError("no_data", "GST has neither the latitude/longitude sigmas nor the error ellipse")
    return (PositionErrorStats(sigma_north, sigma_east, sigma_down, rms, utc, major, minor,
                               None if orientation_deg is None else ssa(math.radians(orientation_deg))),)


def _hdt(data: list[str], strict: bool) -> tuple[SensorMessage, ...]:
    """HDT: heading [deg], ``T``."""
    del strict
    f = _fields(data, 2)
    heading_deg = _required(_angle_deg(f[0], "HDT heading"), "HDT heading")
    if f[1] != "T":
        raise _FieldError("bad_field", f"HDT reference {f[1]!r} is not T (true)")
    return (Heading(math.radians(heading_deg)),)


def _ths(data: list[str], strict: bool) -> tuple[SensorMessage, ...]:
    """THS: heading [deg], mode indicator (A autonomous, E estimated, M manual, S simulator, V invalid)."""
    f = _fields(data, 2)
    mode = f[1]
    if mode == "V":
        raise _FieldError("invalid_status", "THS mode V (data not valid)")
    if not mode:
        raise _FieldError("no_data", "THS mode indicator is empty")
    if mode not in ("A", "E", "M", "S"):
        raise _FieldError("bad_field", f"THS mode {mode!r} is not A/E/M/S/V")
    if strict and mode in ("M", "S"):
        raise _FieldError("invalid_status", f"THS mode {mode} (manual or simulated, not a measurement)")
    heading_deg = _required(_angle_deg(f[0], "THS heading"), "THS heading")
    return (Heading(math.radians(heading_deg), mode),)


def _rot(data: list[str], strict: bool) -> tuple[SensorMessage, ...]:
    """ROT: rate of turn [deg/min] (negative: bow turns to port), status A/V."""
    del strict
    f = _fields(data, 2)
    if f[1] == "V":
        raise _FieldError("invalid_status", "ROT status V (data not valid)")
    if f[1] != "A":
        raise _FieldError("no_data" if not f[1] else "bad_field", f"ROT status {f[1]!r} is not A/V")
    rate_deg_min = _required(_number(f[0], "ROT rate"), "ROT rate")
    return (RateOfTurn(math.radians(rate_deg_min) / 60.0),)


def _mwv(data: list[str], strict: bool) -> tuple[SensorMessage, ...]:
    """MWV: wind angle [deg], reference R/T, speed, unit K/M/N/S, status A/V."""
    del strict
    f = _fields(data, 5)
    if f[4] == "V":
        raise _FieldError("invalid_status", "MWV status V (data not valid)")
    if f[4] != "A":
        raise _FieldError("no_data" if not f[4] else "bad_field", f"MWV status {f[4]!r} is not A/V")
    if f[1] not in ("R", "T"):
        raise _FieldError("no_data" if not f[1] else "bad_field", f"MWV reference {f[1]!r} is not R/T")
    if f[3] not in _MWV_SPEED_UNIT_MPS:
        raise _FieldError("no_data" if not f[3] else "bad_field", f"MWV speed unit {f[3]!r} is not K/M/N/S")
    angle_deg = _required(_angle_deg(f[0], "MWV angle"), "MWV angle")
    speed = _required(_number(f[2], "MWV speed", signed=False), "MWV speed")
    return (Wind(speed * _MWV_SPEED_UNIT_MPS[f[3]], math.radians(angle_deg), "apparent" if f[1] == "R" else "true"),)


_DECODERS: dict[str, Callable[[list[str], bool], tuple[SensorMessage, ...]]] = {
    "GGA": _gga, "RMC": _rmc, "VTG": _vtg, "GNS": _gns, "GLL": _gll, "GST": _gst, "HDT": _hdt, "THS": _ths,
    "ROT": _rot, "MWV": _mwv,
}
DECODED_SENTENCES = tuple(_DECODERS)
"""Sentence types that become messages; every other well-formed sentence is counted as ignored."""


# ----------------------------------------------------------------------------------------------
# stream decoder

_LINE_RE = re.compile(rb"[^\r\n]+")
_START_RE = re.compile(rb"[$!]")
_BAD_CHAR_RE = re.compile(rb"[^\x20-\x7e]")
_ADDRESS_RE = re.compile(rb"[$!]([A-Z][A-Z0-9]{3,5}),")
# What every framing check of Nmea0183Decoder._sentence lets through (printable ASCII, the last '*' followed
# by two hex digits and nothing else): one match instead of three checks for every well-formed sentence.
_FRAMED_RE = re.compile(rb"[\x20-\x7e]*\*[0-9A-Fa-f]{2}")
# One whole such sentence with its CR LF and no other start ('$', '!') or line end in it: the chunk a device
# writes per sentence, which needs no line splitting.
_WHOLE_SENTENCE_RE = re.compile(rb"[$!][\x20\x22\x23\x25-\x7e]*\*[0-9A-Fa-f]{2}\r\n")

_STARTS = frozenset(b"$!")


class Frame(NamedTuple):
    """One unit of the input stream and what became of it (for the recorder and for tests).

    Immutable; a named tuple because one is built per sentence and costs a quarter of a frozen dataclass.

    Attributes
    ----------
    raw : bytes
        The sentence without CR LF, or a bounded excerpt of a garbage run.
    sentence : str
        The address field (``"GPGGA"``) when the frame starts like a sentence, else ``""``.
    messages : tuple of SensorMessage
        What the frame decoded to; empty for ignored and rejected frames.
    rejected : Rejected or None
        Why the frame was rejected, ``None`` otherwise.
    """

    raw: bytes
    sentence: str
    messages: tuple[SensorMessage, ...]
    rejected: Rejected | None


class Nmea0183Decoder:
    """Streaming NMEA 0183 decoder: feed it bytes as they arrive, get typed messages back.

    Parameters
    ----------
    max_sentence_chars : int
        Longest accepted sentence, ``$`` through checksum plus CR LF: :data:`DEFAULT_MAX_SENTENCE_CHARS`
        (128) by default. NMEA 0183 says 82; receivers in high-precision mode (u-blox HPNMEA,
        Trimble/SkyTraq/Hemisphere RTK with 8 decimals of minutes) exceed it (93 characters).
    strict_validity : bool
        Reject fixes and headings that the sender marks as manual input or simulation (GGA quality
        7/8, FAA mode M/S, THS mode M/S): they are not measurements. ``False`` passes them on with
        their quality/mode.

    Notes
    -----
    Deterministic: the same bytes give the same frames whatever the chunking. Not thread-safe:
    one decoder per stream (the transport owns one).
    """

    def __init__(self, max_sentence_chars: int = DEFAULT_MAX_SENTENCE_CHARS, strict_validity: bool = True) -> None:
        if max_sentence_chars < 16:
            raise ValueError(f"max_sentence_chars={max_sentence_chars} is too small for any NMEA sentence")
        self.max_sentence_chars = max_sentence_chars
        self.strict_validity = strict_validity
        self._max_body = max_sentence_chars - 2  # '$' through the checksum, without CR LF
        # excerpts of over-long input are cut to what every chunking of the stream has seen when it is judged
        self._excerpt = min(self._max_body + 1, RAW_EXCERPT_BYTES)
        self._too_long_detail = f"sentence longer than {max_sentence_chars} characters"
        self._buf = bytearray()
        self._continuation = False  # the buffered line continues an over-long one already counted
        self.counters: dict[str, int] = self.zero_counters()

    @staticmethod
    def zero_counters() -> dict[str, int]:
        """A counter dictionary with every key present (so snapshots never change size)."""
        counters = {"frames": 0, "ok": 0, "ignored": 0, "rejected": 0, "messages": 0}
        counters.update({f"rejected.{reason}": 0 for reason in REJECT_REASONS})
        return counters

    @property
    def buffered_bytes(self) -> int:
        """Bytes of an unterminated line held back until its end arrives (≤ max_sentence_chars)."""
        return len(self._buf)

    # -- public API --------------------------------------------------------------------------

    def feed(self, data: bytes) -> list[SensorMessage | Rejected]:
        """Decode a chunk of the stream.

        Parameters
        ----------
        data : bytes
            Any number of bytes; sentences may be split across calls anywhere.

        Returns
        -------
        list of SensorMessage or Rejected
            In stream order, the messages of every sentence completed by this chunk and a
            :class:`Rejected` for every frame that did not decode. Ignored sentences are only counted.
        """
        out: list[SensorMessage | Rejected] = []
        for frame in self.feed_frames(data):
            if frame.rejected is not None:
                out.append(frame.rejected)
            else:
                out.extend(frame.messages)
        return out

    def feed_frames(self, data: bytes) -> list[Frame]:
        """Like :meth:`feed`, but one :class:`Frame` per sentence or garbage run, ignored ones included."""
        out: list[Frame] = []
        buf = self._buf
        if not buf and not self._continuation and type(data) is bytes and _WHOLE_SENTENCE_RE.fullmatch(data):
            # the usual chunk, one whole well-framed sentence (a device writes each sentence in one go): what the
            # general framing below does with it, without splitting lines, looking for starts or checking again
            self._sentence(data[:-2], out, framed=True)
            return out
        buf += data
        last = max(buf.rfind(b"\n"), buf.rfind(b"\r"))
        if last >= 0:
            complete = bytes(buf[:last])
            del buf[: last + 1]
            first = True
            for match in _LINE_RE.finditer(complete):
                # an over-long line's tail continues only up to its own terminator
                if first and match.start() != 0:
                    self._continuation = False
                first = False
                self._line(match.group(), True, "merged", out)
            self._continuation = False
        if len(buf) > self._max_body:
            self._overflow(out)
        return out

    def flush(self) -> list[Frame]:
        """End of stream (end of a file, a reconnect): reject what is left of an unterminated line."""
        out: list[Frame] = []
        if self._buf:
            data = bytes(self._buf)
            self._buf.clear()
            self._line(data, False, "unterminated", out)
        self._continuation = False
        return out

    # -- framing -----------------------------------------------------------------------------

    def _overflow(self, out: list[Frame]) -> None:
        """The unterminated tail is longer than any sentence: judge now what can be judged."""
        data = bytes(self._buf)
        self._buf.clear()
        start = max(data.rfind(b"$"), data.rfind(b"!"))
        if start < 0:
            if not self._continuation:
                self._reject(out, data, "garbage", "bytes outside any NMEA sentence")
            self._continuation = True
            return
        if start > 0:
            self._line(data[:start], False, "merged", out)
        tail = data[start:]
        if len(tail) > self._max_body:
            self._reject(out, tail, "too_long", self._too_long_detail)
            self._continuation = True
        else:
            self._continuation = False
            self._buf += tail

    def _line(self, line: bytes, terminated: bool, tail_reason: str, out: list[Frame]) -> None:
        """Split a line (or line fragment) at sentence starts; decode the terminated last sentence."""
        continuation = self._continuation
        self._continuation = False
        if terminated and line[0] in _STARTS and line.find(b"$", 1) < 0 and line.find(b"!", 1) < 0:
            self._sentence(line, out)  # the usual line: one sentence (what the general split below gives)
            return
        starts = [match.start() for match in _START_RE.finditer(line)]
        if not starts:
            if not continuation:
                self._reject(out, line, "garbage", "bytes outside any NMEA sentence")
            return
        if starts[0] > 0 and not continuation:
            self._reject(out, line[: starts[0]], "garbage", "bytes outside any NMEA sentence")
        starts.append(len(line))
        for k in range(len(starts) - 1):
            segment = line[starts[k]: starts[k + 1]]
            if k < len(starts) - 2 or not terminated:
                if len(segment) > self._max_body:
                    self._reject(out, segment, "too_long", self._too_long_detail)
                elif tail_reason == "merged":
                    self._reject(out, segment, "merged", "sentence not terminated by CR LF before the next start")
                else:
                    self._reject(out, segment, tail_reason, "sentence not terminated by CR LF")
            else:
                self._sentence(segment, out)

    def _reject(self, out: list[Frame], raw: bytes, reason: str, detail: str, sentence: str = "") -> None:
        counters = self.counters
        counters["frames"] += 1
        counters["rejected"] += 1
        counters["rejected." + reason] += 1
        excerpt = raw[: self._excerpt]
        if not sentence:  # say which sentence it was when the address survived (over-long, merged ...)
            match = _ADDRESS_RE.match(excerpt)
            sentence = match.group(1).decode("ascii") if match else ""
        out.append(Frame(excerpt, sentence, (), Rejected(reason, detail, excerpt)))

    def _sentence(self, raw: bytes, out: list[Frame], framed: bool = False) -> None:
        """One complete candidate sentence, ``$`` through the checksum, without CR LF.

        ``framed``: the caller has matched ``raw`` (with its CR LF) against :data:`_WHOLE_SENTENCE_RE`, so every
        framing check below but the length passes.
        """
        if len(raw) > self._max_body:
            self._reject(out, raw, "too_long", self._too_long_detail)
            return
        if not framed and _FRAMED_RE.fullmatch(raw) is None:
            self._framing_error(raw, out)
            return
        text = raw.decode("ascii")
        if text[0] == "!":  # encapsulated sentence (AIS): same checksum rule, pynmea2 expects '$'
            text = "$" + text[1:]
        comma = text.find(",")  # never at 0 (the start character): > 0 when there is one
        address = text[1:comma] if comma > 0 else text[1:-3]  # the last 3 characters are *hh
        try:
            if raw.find(b"*") == len(raw) - 3 and int(text[-2:], 16) == _checksum(raw[1:-3]):
                # Checksum verified here on the bytes, at a third of what pynmea2's XOR of ord() per character
                # costs; with its only '*' gone pynmea2 parses the rest exactly as after its own check.
                parsed = pynmea2.parse(text[:-3])
            else:  # a mismatch (or another '*'): pynmea2 judges the whole sentence, so reasons stay its own
                parsed = pynmea2.parse(text, check=True)
        except pynmea2.ChecksumError as exc:
            self._reject(out, raw, "checksum", str(exc.args[0][0]) if exc.args else "checksum mismatch", address)
            return
        except pynmea2.SentenceTypeError:  # raised after the checksum check: a valid sentence we do not know
            self._ignore(out, raw, address)
            return
        except Exception as exc:  # ParseError, or anything a pynmea2 sentence class raises on odd data
            self._reject(out, raw, "malformed", f"not an NMEA sentence ({type(exc).__name__})", address)
            return
        decoder = _DECODERS.get(parsed.sentence_type) if isinstance(parsed, pynmea2.TalkerSentence) else None
        if decoder is None:
            self._ignore(out, raw, address)
            return
        try:
            messages = decoder(parsed.data, self.strict_validity)
        except _FieldError as exc:
            self._reject(out, raw, exc.reason, exc.detail, address)
            return
        for message in messages:
            problem = violation(message)
            if problem is not None:
                self._reject(out, raw, "out_of_range", f"{address}: {problem}", address)
                return
        counters = self.counters
        counters["frames"] += 1
        counters["ok"] += 1
        counters["messages"] += len(messages)
        out.append(Frame(raw, address, messages, None))

    def _framing_error(self, raw: bytes, out: list[Frame]) -> None:
        """Reject a sentence that :data:`_FRAMED_RE` refused, for the first reason that applies."""
        if _BAD_CHAR_RE.search(raw):
            self._reject(out, raw, "malformed", "non-printable or non-ASCII byte in sentence")
        elif raw.rfind(b"*") < 0:
            self._reject(out, raw, "no_checksum", "checksum missing (mandatory)")
        else:  # the last '*' is not followed by exactly two hex digits
            self._reject(out, raw, "malformed", "checksum field is not *hh")

    def _ignore(self, out: list[Frame], raw: bytes, address: str) -> None:
        self.counters["frames"] += 1
        self.counters["ignored"] += 1
        out.append(Frame(raw, address, (), None))


def decode_sentence(sentence: bytes | str, max_sentence_chars: int = DEFAULT_MAX_SENTENCE_CHARS,
                    strict_validity: bool = True) -> list[SensorMessage | Rejected]:
    """Decode one complete sentence (with or without CR LF) — a convenience for tests and tools.

    Parameters
    ----------
    sentence : bytes or str
        ``$GPGGA,...*hh``.
    max_sentence_chars, strict_validity
        As for :class:`Nmea0183Decoder`.

    Returns
    -------
    list of SensorMessage or Rejected
        Empty for a valid sentence of a type that is not decoded.
    """
    data = sentence.encode("utf-8") if isinstance(sentence, str) else sentence  # non-ASCII → malformed
    decoder = Nmea0183Decoder(max_sentence_chars, strict_validity)
    return decoder.feed(data if data.endswith((b"\n", b"\r")) else data + b"\r\n")


# ----------------------------------------------------------------------------------------------
# encoders (what the plant emulator sends)

_TALKER_RE = re.compile(r"[A-Z0-9]{2}")
_RENDER_CHECKED: set[tuple[str, str]] = set()  # (talker, sentence type) pairs _render has validated


def _checksum(data: bytes) -> int:
    """The NMEA checksum of the characters between ``$`` and ``*``: the XOR of their bytes.

    The value of pynmea2's ``NMEASentence.checksum`` (which XORs ``ord`` of each character of the text),
    computed on the bytes, which saves the ``ord`` call per character.
    """
    return functools.reduce(operator.xor, data, 0)


def _render(talker: str, sentence_type: str, fields: list[str]) -> bytes:
    """``$<talker><type>,<fields>*hh\r\n`` with the NMEA checksum.

    The text is what pynmea2's ``TalkerSentence.render(checksum=True, dollar=True, newline="\r\n")`` writes
    (identifier, comma-joined fields, ``*%02X`` of the checksum); formatting it here skips building a sentence
    object whose attribute hooks cost more than the rest of the encoding.
    """
    if (talker, sentence_type) not in _RENDER_CHECKED:  # validated once per pair (a regex per sentence costs)
        if not _TALKER_RE.fullmatch(talker):
            raise ValueError(f"talker {talker!r} is not two upper-case letters or digits")
        if sentence_type not in pynmea2.TalkerSentence.sentence_types:
            raise ValueError(f"pynmea2 does not know the sentence type {sentence_type!r}")
        if len(_RENDER_CHECKED) < 1024:  # bounded: talkers come from configuration
            _RENDER_CHECKED.add((talker, sentence_type))
    head = f"${talker}{sentence_type},{','.join(fields)}*".encode("ascii")
    out = b"%b%02X\r\n" % (head, _checksum(head[1:-1]))
    if len(out) > NMEA_MAX_SENTENCE_CHARS:
        raise ValueError(f"{talker}{sentence_type} would be {len(out)} characters > {NMEA_MAX_SENTENCE_CHARS}")
    return out


def _not_in_range(name: str, value: float, low: float, high: float) -> ValueError:
    return ValueError(f"{name}={value!r} is not a finite number in [{low}, {high}]")


def _finite(value: float, name: str, low: float, high: float) -> float:
    """``value`` if it lies in [low, high] (finite bounds: NaN and ±inf fail the comparison), else ValueError."""
    if not low <= value <= high:
        raise _not_in_range(name, value, low, high)
    return value


# The encoders format with printf-style templates: one call for all the fields of a value, where an f-string
# with nested widths builds and parses a format spec per field (a third more work for the same text).
_MINUTE_SCALE = 10**LATLON_MINUTE_DECIMALS
_LAT_TEMPLATE = f"%02d%02d.%0{LATLON_MINUTE_DECIMALS}d"  # ddmm.mmmmmmm
_LON_TEMPLATE = f"%03d%02d.%0{LATLON_MINUTE_DECIMALS}d"  # dddmm.mmmmmmm


def _format_coordinate(value_deg: float, is_lat: bool) -> tuple[str, str]:
    """Signed degrees → (``ddmm.mmmmmmm``, hemisphere), rounded in integers so 59.99999999' carries."""
    limit = 90.0 if is_lat else 180.0
    _finite(value_deg, "latitude_deg" if is_lat else "longitude_deg", -limit, limit)
    units = round(abs(value_deg) * 60.0 * _MINUTE_SCALE)  # 1e-7 arc-minutes
    degrees, rest = divmod(units, 60 * _MINUTE_SCALE)
    minutes, fraction = divmod(rest, _MINUTE_SCALE)
    if is_lat:
        return _LAT_TEMPLATE % (degrees, minutes, fraction), ("S" if value_deg < 0.0 else "N")
    return _LON_TEMPLATE % (degrees, minutes, fraction), ("W" if value_deg < 0.0 else "E")


def _format_time(utc_time_s: float | None) -> str:
    """Seconds since midnight UTC → ``hhmmss.ss`` (10 ms); a value rounding to 24:00 wraps to 00:00."""
    if utc_time_s is None:
        return ""
    _finite(utc_time_s, "utc_time_s", 0.0, 86400.0)
    centis = round(utc_time_s * 100.0) % 8_640_000
    seconds, centi = divmod(centis, 100)
    hours, rest = divmod(seconds, 3600)
    return "%02d%02d%02d.%02d" % (hours, rest // 60, rest % 60, centi)  # noqa: UP031 (see _LAT_TEMPLATE)


def _format_optional(value: float | None, fmt: str, name: str, low: float, high: float) -> str:
    return "" if value is None else format(_finite(value, name, low, high), fmt)


def _format_sigma(value: float | None, name: str) -> str:
    """A GST standard deviation [m], 1 mm."""
    return _format_optional(value, ".3f", name, 0.0, 99999.0)


def _format_satellites(fix: PositionFix) -> str:
    """Satellites used, ``00``–``99``; zero only for dead reckoning (the decoder rejects a satellite fix from none)."""
    if fix.num_satellites is None:
        return ""
    count = int(_finite(fix.num_satellites, "num_satellites", 0, 99))
    if count == 0 and fix.quality != FixQuality.DEAD_RECKONING:
        raise ValueError(f"a {fix.quality.name} fix from 0 satellites is contradictory")
    return f"{count:02d}"


def _format_direction(angle_rad: float, decimals: int = HEADING_DECIMALS) -> str:
    """A direction [rad] → degrees in [0, 360) with ``decimals`` decimals (rounded, 360 → 0)."""
    if not -1e6 <= angle_rad <= 1e6:  # _finite, inlined: one per heading sentence
        raise _not_in_range("angle_rad", angle_rad, -1e6, 1e6)
    degrees = math.degrees(ssa(angle_rad))
    scale = 10**decimals
    units = round((degrees + 360.0 if degrees < 0.0 else degrees) * scale) % (360 * scale)
    return "%d.%0*d" % (units // scale, decimals, units % scale)  # noqa: UP031 (see _LAT_TEMPLATE)


def encode_gga(fix: PositionFix, talker: str = "GP", utc_time_s: float | None = None) -> bytes:
    """GGA from a fix: 7 decimals of minutes (≤ 0.093 mm), HDOP 0.01, altitude 1 mm, time 10 ms.

    Parameters
    ----------
    fix : PositionFix
        Position, quality (not ``INVALID``: see :func:`encode_gga_no_fix`), satellites, HDOP, altitude.
    talker : str
        Talker ID (``GP``, ``GN``, ...).
    utc_time_s : float or None
        Seconds since midnight UTC; defaults to ``fix.utc_time_s``.

    Returns
    -------
    bytes
        ``$GPGGA,...*hh\\r\\n`` (≤ 82 characters).
    """
    if fix.quality == FixQuality.INVALID:
        raise ValueError("a PositionFix is never INVALID; use encode_gga_no_fix() for a receiver without fix")
    lat, ns = _format_coordinate(fix.lat_deg, True)
    lon, ew = _format_coordinate(fix.lon_deg, False)
    sats = _format_satellites(fix)
    return _render(talker, "GGA", [
        _format_time(fix.utc_time_s if utc_time_s is None else utc_time_s), lat, ns, lon, ew,
        str(int(fix.quality)), sats, _format_optional(fix.hdop, ".2f", "hdop", 0.0, 99.99),
        _format_optional(fix.altitude_m, ".3f", "altitude_m", -99999.0, 99999.0), "M", "", "M", "", ""])


def encode_gga_no_fix(talker: str = "GP", utc_time_s: float | None = None) -> bytes:
    """GGA of a receiver without a fix (quality 0, empty position): for fault injection."""
    return _render(talker, "GGA", [_format_time(utc_time_s), "", "", "", "", "0", "00", "", "", "M", "", "M", "", ""])


def encode_gns(fix: PositionFix, talker: str = "GN", utc_time_s: float | None = None, systems: int = 2) -> bytes:
    """GNS from a fix; the mode indicator repeats the fix's FAA mode once per constellation (``systems``)."""
    if fix.quality == FixQuality.INVALID:
        raise ValueError("a PositionFix is never INVALID")
    if not 1 <= systems <= 4:
        raise ValueError(f"systems={systems} must be 1..4")
    lat, ns = _format_coordinate(fix.lat_deg, True)
    lon, ew = _format_coordinate(fix.lon_deg, False)
    sats = _format_satellites(fix)
    return _render(talker, "GNS", [
        _format_time(fix.utc_time_s if utc_time_s is None else utc_time_s), lat, ns, lon, ew,
        _QUALITY_FAA[fix.quality] * systems, sats, _format_optional(fix.hdop, ".2f", "hdop", 0.0, 99.99),
        _format_optional(fix.altitude_m, ".3f", "altitude_m", -99999.0, 99999.0), "", "", ""])


def encode_rmc(fix: PositionFix, course: CourseOverGround | None = None, talker: str = "GP",
               utc_time_s: float | None = None, date_ddmmyy: str = "") -> bytes:
    """RMC from a fix (status A, FAA mode from the quality) and optional course/speed over ground.

    Speed is written in knots with 2 decimals (5 mm/s), course in degrees with 2 decimals.
    """
    if fix.quality == FixQuality.INVALID:
        raise ValueError("a PositionFix is never INVALID; use encode_rmc_no_fix()")
    if date_ddmmyy and not re.fullmatch(r"\d{6}", date_ddmmyy):
        raise ValueError(f"date_ddmmyy={date_ddmmyy!r} is not ddmmyy")
    lat, ns = _format_coordinate(fix.lat_deg, True)
    lon, ew = _format_coordinate(fix.lon_deg, False)
    speed = course_text = ""
    if course is not None:
        if course.speed_mps is not None:
            speed = format(_finite(course.speed_mps, "speed_mps", 0.0, 999.99 * KNOT_MPS) / KNOT_MPS, ".2f")
        if course.course_rad is not None:
            course_text = _format_direction(course.course_rad, 2)
    return _render(talker, "RMC", [
        _format_time(fix.utc_time_s if utc_time_s is None else utc_time_s), "A", lat, ns, lon, ew,
        speed, course_text, date_ddmmyy, "", "", _QUALITY_FAA[fix.quality]])


def encode_rmc_no_fix(talker: str = "GP", utc_time_s: float | None = None, date_ddmmyy: str = "") -> bytes:
    """RMC of a receiver without a fix (status V, mode N): for fault injection."""
    return _render(talker, "RMC", [_format_time(utc_time_s), "V", "", "", "", "", "", "", date_ddmmyy, "", "", "N"])


def encode_vtg(course: CourseOverGround, talker: str = "GP", mode: str = "D") -> bytes:
    """VTG: true course in degrees with 2 decimals (empty when None), speed in knots and km/h with 3 decimals
    (0.26 mm/s), FAA ``mode`` (``D`` differential, ``A`` autonomous ...; ``N`` for fault injection)."""
    if mode not in _FAA_QUALITY and mode != "N":
        raise ValueError(f"VTG mode {mode!r} is not an FAA mode indicator")
    course_text = "" if course.course_rad is None else _format_direction(course.course_rad, 2)
    knots = kmh = ""
    if course.speed_mps is not None:
        speed = _finite(course.speed_mps, "speed_mps", 0.0, 999.99 * KNOT_MPS)
        knots = format(speed / KNOT_MPS, ".3f")
        kmh = format(speed * 3.6, ".3f")
    return _render(talker, "VTG", [course_text, "T", "", "M", knots, "N", kmh, "K", mode])


def encode_gst(stats: PositionErrorStats, talker: str = "GP", utc_time_s: float | None = None) -> bytes:
    """GST from error statistics: sigmas [m] with 3 decimals (1 mm), orientation [deg] with 1 decimal."""
    sigma = _format_sigma
    orientation = ""
    if stats.orientation_rad is not None:
        orientation = _format_direction(stats.orientation_rad, 1)
    return _render(talker, "GST", [
        _format_time(stats.utc_time_s if utc_time_s is None else utc_time_s),
        sigma(stats.rms_range_m, "rms_range_m"), sigma(stats.sigma_major_m, "sigma_major_m"),
        sigma(stats.sigma_minor_m, "sigma_minor_m"), orientation, sigma(stats.sigma_north_m, "sigma_north_m"),
        sigma(stats.sigma_east_m, "sigma_east_m"), sigma(stats.sigma_altitude_m, "sigma_altitude_m")])


def encode_hdt(heading: Heading, talker: str = "HE") -> bytes:
    """HDT: true heading in degrees [0, 360) with 3 decimals."""
    return _render(talker, "HDT", [_format_direction(heading.heading_rad), "T"])


def encode_ths(heading: Heading, talker: str = "HE", mode: str | None = None) -> bytes:
    """THS: true heading with mode (``mode`` or ``heading.mode`` or ``A``; ``V`` for fault injection)."""
    mode = mode or heading.mode or "A"
    if mode not in ("A", "E", "M", "S", "V"):
        raise ValueError(f"THS mode {mode!r} is not A/E/M/S/V")
    return _render(talker, "THS", [_format_direction(heading.heading_rad), mode])


def encode_rot(rate: RateOfTurn, talker: str = "HE", valid: bool = True) -> bytes:
    """ROT: rate of turn in deg/min with 2 decimals (1.5e-6 rad/s); ``valid=False`` sends status V."""
    rate_deg_min = math.degrees(_finite(rate.rate_radps, "rate_radps", -100.0, 100.0)) * 60.0
    return _render(talker, "ROT", [f"{rate_deg_min:.2f}", "A" if valid else "V"])


def encode_mwv(wind: Wind, talker: str = "WI") -> bytes:
    """MWV: angle [deg] with 1 decimal, speed in m/s with 2 decimals, status A."""
    if wind.reference not in ("apparent", "true"):
        raise ValueError(f"wind reference {wind.reference!r} is not 'apparent'/'true'")
    return _render(talker, "MWV", [
        _format_direction(wind.angle_rad, 1), "R" if wind.reference == "apparent" else "T",
        format(_finite(wind.speed_mps, "speed_mps", 0.0, 999.0), ".2f"), "M", "A"])
