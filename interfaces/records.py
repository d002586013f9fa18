"""JSON-line records of decoded and rejected inputs, shared by every protocol's log decoder.

One layout for ``dpcontrol decode`` whatever the protocol: a decoded message becomes
``{"source", "kind", <message fields>, <context>}``, a rejected input
``{"rejected": reason, "detail", "source", "raw", <context>}``. Text protocols keep a printable
excerpt of the raw bytes, binary protocols (NMEA 2000, MAVLink) a hex excerpt.
"""

from __future__ import annotations

import dataclasses
import enum
import json
import math
import os
from pathlib import Path

from interfaces.messages import (
    Attitude,
    CourseOverGround,
    Heading,
    LinkHeartbeat,
    PositionErrorStats,
    PositionFix,
    RateOfTurn,
    Rejected,
    SensorMessage,
    Wind,
)

LogSource = str | os.PathLike[str] | bytes
"""A captured log: a path, or its bytes."""

RAW_EXCERPT_CHARS = 100
"""Length of the printable ``raw`` excerpt of a rejected text input."""
RAW_HEX_BYTES = 32
"""Bytes kept (as hex) of a rejected binary input."""

KINDS: dict[type, str] = {
    PositionFix: "position",
    PositionErrorStats: "position_error",
    Heading: "heading",
    RateOfTurn: "rate_of_turn",
    CourseOverGround: "course_over_ground",
    Wind: "wind",
    Attitude: "attitude",
    LinkHeartbeat: "heartbeat",
}
"""The ``kind`` of each message type in a record."""


def read_log_bytes(source: LogSource) -> bytes:
    """The content of a log given as a path or as bytes."""
    if isinstance(source, bytes | bytearray | memoryview):
        return bytes(source)
    return Path(source).read_bytes()


def message_record(source: str, message: SensorMessage, **context: object) -> dict[str, object]:
    """A JSON-ready record of a decoded message.

    Parameters
    ----------
    source : str
        Who sent it (NMEA 0183 talker ID, NMEA 2000 source address, MAVLink system/component).
    message : SensorMessage
        The typed message.
    **context
        Protocol-specific keys appended after the message fields (``sentence``, ``line``, ``pgn`` ...);
        ``None`` values are left out.

    Returns
    -------
    dict
        ``source``, ``kind``, the message fields that have a value (``utc_time_s`` renamed
        ``sample_time``, enums as lower-case names), then the context.
    """
    record: dict[str, object] = {"source": source, "kind": KINDS.get(type(message), type(message).__name__.lower())}
    for field in dataclasses.fields(message):
        value = getattr(message, field.name)
        if value is None:
            continue
        if isinstance(value, enum.Enum):
            value = value.name.lower()
        record["sample_time" if field.name == "utc_time_s" else field.name] = value
    record.update({key: value for key, value in context.items() if value is not None})
    return record


def rejected_record(source: str, rejected: Rejected, *, binary: bool = False, **context: object) -> dict[str, object]:
    """A JSON-ready record of a rejected input: ``rejected`` (reason), ``detail``, ``source``, a ``raw``
    excerpt (printable text, or hex when ``binary``), then the context."""
    record: dict[str, object] = {"rejected": rejected.reason, "detail": rejected.detail, "source": source}
    if rejected.raw:
        record["raw"] = (rejected.raw[:RAW_HEX_BYTES].hex() if binary
                         else rejected.raw[:RAW_EXCERPT_CHARS].decode("ascii", "backslashreplace"))
    record.update({key: value for key, value in context.items() if value is not None})
    return record


def to_json_line(record: dict[str, object]) -> str:
    """One record as a compact JSON line (strict JSON: a missing value is ``null``, never ``NaN``).

    The decoders emit finite values only (every message passes :func:`interfaces.limits.violation`); a
    non-finite number that reached a record anyway (a context value) is written ``null`` rather than
    ending the output with an error.
    """
    try:
        return json.dumps(record, separators=(",", ":"), allow_nan=False)
    except ValueError:  # a NaN or ±inf: the only value json refuses in these records
        return json.dumps({key: None if isinstance(value, float) and not math.isfinite(value) else value
                           for key, value in record.items()}, separators=(",", ":"), allow_nan=False)
