"""MAVLink telemetry logs (``.tlog``) → the JSON-line objects of ``dpcontrol decode mavlink FILE``.

A tlog is a sequence of records: an 8-byte big-endian UNIX timestamp in microseconds, then one
MAVLink packet (v1 ``0xFE`` or v2 ``0xFD``, length from its header, +13 bytes when signed).
pymavlink can read tlogs through ``mavutil.mavlink_connection(path)``, but that reader takes its
dialect from a process-global setting and silently skips bytes while resynchronising; this one
uses the same parser (:class:`~interfaces.mavlink.codec.MavlinkDecoder`) with an explicit dialect
and reports every skipped stretch as a reject.

Objects are those of :func:`interfaces.nmea2000.logs.message_record` /
:func:`~interfaces.nmea2000.logs.rejected_record` (``source``, ``kind``, values, ``t_s`` = record
time [UNIX s], ``sample_time`` = UTC seconds of day where GPS_RAW_INT carries UNIX time, ``msg``
= MAVLink message name, ``offset`` = byte offset of the record).
"""

from __future__ import annotations

import io
import os
import struct
from collections.abc import Iterator
from typing import Any, BinaryIO

from interfaces.mavlink.codec import MavlinkDecoder, mavlink_source_name
from interfaces.messages import Rejected
from interfaces.records import message_record, rejected_record

_TIMESTAMP = struct.Struct(">Q")
_V1, _V2 = 0xFE, 0xFD
_MAX_RECORD = 8 + 10 + 255 + 2 + 13
_CHUNK = 1 << 20
# A record timestamp this far from the previous good one means we are misaligned (pymavlink's
# tlog reader uses the same three-day window).
_MAX_TIME_JUMP_US = 3 * 86_400 * 1_000_000
_MIN_UNIX_US, _MAX_UNIX_US = 946_684_800 * 10**6, 4_102_444_800 * 10**6  # 2000 … 2100


def _packet_length(buf: bytes | bytearray, i: int) -> int | None:
    """Length of the packet starting at ``buf[i]``, or ``None`` if no packet starts there."""
    marker = buf[i]
    if marker == _V2:
        return 12 + buf[i + 1] + (13 if buf[i + 2] & 0x01 else 0)
    if marker == _V1:
        return 8 + buf[i + 1]
    return None


def _plausible(buf: bytes | bytearray, i: int, previous_us: int | None) -> bool:
    """Whether a record (timestamp + packet start) plausibly begins at ``buf[i]``."""
    if buf[i + 8] not in (_V1, _V2):
        return False
    (t_us,) = _TIMESTAMP.unpack_from(buf, i)
    if previous_us is None:
        return _MIN_UNIX_US <= t_us <= _MAX_UNIX_US
    return abs(t_us - previous_us) <= _MAX_TIME_JUMP_US


def read_tlog(handle: BinaryIO) -> Iterator[tuple[int, int, bytes] | tuple[int, Rejected]]:
    """Split a tlog stream into records.

    Yields
    ------
    (offset, t_us, packet)
        A record at byte ``offset`` with its timestamp [µs since the UNIX epoch].
    (offset, Rejected)
        Bytes that are not a record (``garbage``, skipped until the next plausible record) or a
        record cut short at the end of the file (``truncated``).
    """
    buf = bytearray()
    base = 0  # file offset of buf[0]
    i = 0
    eof = False
    previous_us: int | None = None
    while True:
        while not eof and len(buf) - i < _MAX_RECORD:
            del buf[:i]
            base += i
            i = 0
            chunk = handle.read(_CHUNK)
            eof = not chunk
            buf += chunk
        remaining = len(buf) - i
        if remaining == 0:
            return
        if remaining < 11:  # only at the end of the file: too short for a timestamp and a header
            yield base + i, Rejected("truncated", f"{remaining} bytes at the end of the log", bytes(buf[i:]))
            return
        length = _packet_length(buf, i + 8)
        if length is not None and _plausible(buf, i, previous_us):
            if remaining - 8 < length:
                yield base + i, Rejected("truncated", f"record of {length} bytes cut by the end of the log",
                                         bytes(buf[i:i + 64]))
                return
            (t_us,) = _TIMESTAMP.unpack_from(buf, i)
            previous_us = t_us
            yield base + i, t_us, bytes(buf[i + 8:i + 8 + length])
            i += 8 + length
            continue
        # misaligned: skip to the next offset where a plausible record begins (a long corrupt
        # stretch is reported in pieces of at most one read chunk)
        start = i
        i += 1
        while len(buf) - i >= 11 and not _plausible(buf, i, previous_us):
            i += 1
        yield base + start, Rejected("garbage", f"{i - start} bytes that are not a tlog record",
                                     bytes(buf[start:min(i, start + 64)]))


def decode_tlog(source: str | os.PathLike[str] | bytes, stats: dict[str, int] | None = None, *,
                signing_key: bytes | None = None) -> Iterator[dict[str, Any]]:
    """Decode a MAVLink ``.tlog`` to JSON-line objects (see the module docstring).

    Parameters
    ----------
    source :
        The log's path, or its content as bytes.
    stats : dict, optional
        Filled as the generator runs: ``records``, ``skipped`` (non-record stretches) and the
        decoder counters (``packets``, ``messages``, ``ignored``, ``rejected``, ``rejected.<reason>`` …).
    signing_key : bytes, optional
        When given, unsigned or badly signed packets are rejected (as the live reader does).

    Raises
    ------
    OSError
        If the file cannot be read.
    """
    decoder = MavlinkDecoder(signing_key)
    counts = stats if stats is not None else {}
    counts.update(records=0, skipped=0)
    with (io.BytesIO(bytes(source)) if isinstance(source, bytes | bytearray | memoryview)
          else open(source, "rb")) as handle:
        for record in read_tlog(handle):
            if len(record) == 2:
                offset, rejected = record
                counts["skipped"] += 1
                yield rejected_record("mav:?", rejected, binary=True, offset=offset)
                continue
            offset, t_us, packet = record
            counts["records"] += 1
            t_s = t_us / 1e6
            for result in decoder.decode_datagram(packet):
                name = mavlink_source_name(result.system_id, result.component_id)
                if isinstance(result.item, Rejected):
                    yield rejected_record(name, result.item, binary=True, msg=result.msg_name or None,
                                          t_s=t_s, offset=offset)
                else:
                    yield message_record(name, result.item, msg=result.msg_name, t_s=t_s, offset=offset)
            counts.update(decoder.counters)
    counts.update(decoder.counters)
