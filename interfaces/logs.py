"""Captured-log decoding behind ``dpcontrol decode PROTOCOL FILE`` (docs/design.md §4.1).

Each protocol has one generator ``decode_<protocol>_log(source, stats=None) -> Iterator[dict]``
registered in :data:`LOG_DECODERS`; :func:`decode_log` dispatches on the protocol name. Every
yielded dict is one JSON line: either a decoded measurement ::

    {"source": "GP", "kind": "position", "lat_deg": ..., "lon_deg": ..., "quality": "rtk_fixed",
     "sample_time": 48500.6, ..., "sentence": "GGA", "line": 17}

or a rejected input ::

    {"rejected": "checksum", "detail": "...", "source": "GP", "raw": "$GPGGA,...", "sentence": "GGA", "line": 18}

Common keys (shared by all protocols, built by :func:`message_record` and :func:`rejected_record`,
same layout as ``interfaces.nmea2000.logs``): ``source`` (who sent it: for NMEA 0183 the talker
ID), ``kind`` (``position``, ``position_error``, ``heading``, ``rate_of_turn``,
``course_over_ground``, ``wind``, ``attitude``, ``heartbeat``), the message's fields under their
unit-suffixed names (``lat_deg``, ``heading_rad``, ``rate_radps`` ...; a missing value is left
out, enums are lower-case names), ``sample_time`` where the protocol carries one — for NMEA 0183
the UTC seconds since midnight of the sentence — then protocol context (``sentence``, ``line``).
``rejected`` carries the reason token, ``detail`` a human explanation and ``raw`` a short
printable excerpt (backslash escapes for binary bytes).

Counts that are not records (comment lines, ignored sentences, per-reason rejects) go into the
optional ``stats`` dict, which is filled as the generator runs.
"""

from __future__ import annotations

import calendar
import re
from collections.abc import Callable, Iterator

from interfaces.nmea0183.codec import DEFAULT_MAX_SENTENCE_CHARS, Frame, Nmea0183Decoder
from interfaces.records import (
    KINDS,
    LogSource,
    message_record,
    read_log_bytes,
    rejected_record,
    to_json_line,
)

__all__ = ["KINDS", "LOG_DECODERS", "LogSource", "decode_log", "decode_nmea0183_log", "message_record",
           "read_log_bytes", "rejected_record", "to_json_line"]


# ----------------------------------------------------------------------------------------------
# NMEA 0183

# A logger's capture time before the sentence: ISO 8601 date and time ('T' or a space between them, any
# fraction of a second, 'Z' or a UTC offset; none means UTC), then blanks, a comma or a semicolon, then the
# sentence's '$' or '!'. OpenRVDAS writes "2014-08-01T00:00:00.183000Z $HEHDT,...", others a space or a comma.
_CAPTURE_TIME_RE = re.compile(
    rb"(\d{4})-(\d{2})-(\d{2})[T ](\d{2}):(\d{2}):(\d{2}(?:\.\d+)?)(Z|[+-]\d{2}:?\d{2})?[ \t]*[,;]?[ \t]*(?=[$!])")


# An NMEA 4.10 TAG block before the sentence: \c:1577836800,s:GPS1*hh\ ('c' the UNIX time in seconds, or in
# milliseconds as some AIS loggers write it); its own checksum covers the characters between '\' and '*'.
_TAG_BLOCK_RE = re.compile(rb"\\([\x20-\x5b\x5d-\x7e]*?)\*([0-9A-Fa-f]{2})\\(?=[$!])")
_TAG_TIME_RE = re.compile(rb"(?:^|,)c:(\d{1,13})(?:,|$)")
_MILLISECONDS_FROM = 10**11  # a 'c' above this is in milliseconds (1e11 s is the year 5138)


def _tag_block(line: bytes) -> tuple[float | None, int] | None:
    """A valid TAG block at the start of ``line``: its capture time (``None`` without a ``c`` field) and where
    the sentence starts; ``None`` when there is none or its checksum does not match."""
    match = _TAG_BLOCK_RE.match(line)
    if match is None:
        return None
    content = match.group(1)
    checksum = 0
    for byte in content:
        checksum ^= byte
    if checksum != int(match.group(2), 16):
        return None
    time_field = _TAG_TIME_RE.search(content)
    if time_field is None:
        return None, match.end()
    value = int(time_field.group(1))
    return (value / 1000.0 if value > _MILLISECONDS_FROM else float(value)), match.end()


def capture_time_prefix(line: bytes) -> tuple[float | None, int] | None:
    """The capture time a logger wrote before an NMEA sentence, and where the sentence starts.

    Two forms: an ISO 8601 date-time (below), or an NMEA 4.10 TAG block (``\\c:1577836800*hh\\``, the
    time in UNIX seconds or milliseconds; a block without ``c`` gives no time, a block whose checksum
    does not match is not recognised).

    Parameters
    ----------
    line : bytes
        A line of a log.

    Returns
    -------
    (t_s, start) or None
        UNIX time [s] of the prefix (``None`` for a TAG block without time) and the index of the sentence's
        ``$``/``!``; ``None`` when the line does not start with a recognised prefix followed by a sentence
        (or the date-time is impossible).
    """
    if line[:1] == b"\\":
        return _tag_block(line)
    match = _CAPTURE_TIME_RE.match(line)
    if match is None:
        return None
    year, month, day, hour, minute = (int(match.group(k)) for k in range(1, 6))
    second = float(match.group(6))
    if not (1 <= month <= 12 and 1 <= day <= 31 and hour <= 23 and minute <= 59 and second < 61.0):
        return None
    t_s = calendar.timegm((year, month, day, hour, minute, 0, 0, 0, 0)) + second
    zone = match.group(7)
    if zone and zone != b"Z":
        sign = -1.0 if zone[:1] == b"-" else 1.0
        digits = zone[1:].replace(b":", b"")
        t_s -= sign * (int(digits[:2]) * 3600 + int(digits[2:]) * 60)
    return t_s, match.end()


def decode_nmea0183_log(source: LogSource, stats: dict[str, int] | None = None,
                        max_sentence_chars: int | None = None) -> Iterator[dict[str, object]]:
    """Decode an NMEA 0183 text log: one record per decoded message or rejected input.

    Parameters
    ----------
    source : path or bytes
        The log. Lines starting with ``#`` are comments (skipped, counted in ``stats["comments"]``).
        Binary data between sentences is allowed (rejected as ``garbage``).
    stats : dict, optional
        Filled with ``lines``, ``comments``, ``timestamped_lines`` and the decoder counters (``frames``,
        ``ok``, ``ignored``, ``rejected``, ``rejected.<reason>`` ...).
    max_sentence_chars : int, optional
        Longest sentence accepted (default :data:`~interfaces.nmea0183.codec.DEFAULT_MAX_SENTENCE_CHARS`).

    Yields
    ------
    dict
        Records as described in the module docstring; ``line`` is the 1-based line number where
        the sentence ended; ``sentence`` the sentence type (``GGA``). A line that starts with a logger's
        ISO 8601 capture time (:func:`capture_time_prefix`) gives its records ``t_s``, that time as UNIX
        seconds; the prefix is not garbage.
    """
    data = read_log_bytes(source)
    decoder = Nmea0183Decoder(DEFAULT_MAX_SENTENCE_CHARS if max_sentence_chars is None else max_sentence_chars)
    counts = stats if stats is not None else {}
    counts.update(decoder.counters)
    counts.update(lines=0, comments=0, timestamped_lines=0)
    line_number = 0
    t_s: float | None = None
    for line_number, line in enumerate(data.splitlines(keepends=True), start=1):
        if line.startswith(b"#"):
            counts["comments"] += 1
            continue
        stamp = capture_time_prefix(line)
        t_s = None
        if stamp is not None:
            counts["timestamped_lines"] += 1
            t_s, start = stamp
        yield from _nmea0183_records(decoder.feed_frames(line if stamp is None else line[start:]), line_number, t_s)
        counts.update(decoder.counters)
    yield from _nmea0183_records(decoder.flush(), line_number, t_s)
    counts.update(decoder.counters, lines=line_number)


def _nmea0183_records(frames: list[Frame], line: int, t_s: float | None) -> Iterator[dict[str, object]]:
    for frame in frames:
        talker, sentence = _split_address(frame.sentence)
        if frame.rejected is not None:
            yield rejected_record(talker, frame.rejected, sentence=sentence or None, t_s=t_s, line=line)
        for message in frame.messages:
            yield message_record(talker, message, sentence=sentence, t_s=t_s, line=line)


def _split_address(address: str) -> tuple[str, str]:
    """``GPGGA`` → (``GP``, ``GGA``); proprietary ``PGRME`` → (``P``, ``GRME``); unknown → ("", "")."""
    if not address:
        return "", ""
    if address.startswith("P"):
        return "P", address[1:]
    return address[:2], address[2:]


# ----------------------------------------------------------------------------------------------
# registry

from interfaces.mavlink.logs import decode_tlog  # noqa: E402  (they import records, not this module)
from interfaces.nmea2000.logs import decode_nmea2000_log  # noqa: E402

LOG_DECODERS: dict[str, Callable[..., Iterator[dict[str, object]]]] = {
    "nmea0183": decode_nmea0183_log,
    "nmea2000": decode_nmea2000_log,
    "mavlink": decode_tlog,
}
"""Protocol name (as typed after ``dpcontrol decode``) → log decoder."""


def decode_log(protocol: str, source: LogSource, stats: dict[str, int] | None = None,
               **options: object) -> Iterator[dict[str, object]]:
    """Decode a captured log of ``protocol`` (a key of :data:`LOG_DECODERS`).

    ``options`` go to that protocol's decoder (``max_sentence_chars`` for nmea0183, ``log_format`` for
    nmea2000); one the decoder does not take is a ``TypeError``.

    Raises
    ------
    ValueError
        For an unknown protocol, naming the known ones.
    """
    try:
        decoder = LOG_DECODERS[protocol]
    except KeyError:
        raise ValueError(f"unknown protocol {protocol!r}; known: {', '.join(sorted(LOG_DECODERS))}") from None
    return decoder(source, stats, **options)
