"""NMEA 2000 captures → the JSON-line objects of ``dpcontrol decode nmea2000 FILE`` (docs/design.md §4.1).

Any format of :mod:`interfaces.nmea2000.logformats` (candump, Actisense, canboat PLAIN/FAST, Yacht
Devices raw, iKonvert, PCAN-View, SocketCAN pcap/pcapng), detected from the file or named. One object
per decoded measurement::

    {"source": "n2k:0", "kind": "position", "pgn": 129025, "lat_deg": 52.1, "lon_deg": 4.3,
     "quality": "gps", "t_s": 1502984866.42, "line": 12, "name": "c0320c0029e0f05a"}

(``sample_time`` = UTC seconds of day where the PGN carries one, i.e. 129029; ``t_s`` = capture
time where the format has one, see :class:`~interfaces.nmea2000.logformats.LogFrame`; ``name`` = the
64-bit NAME, in hex, the source's address was claimed with, once a 60928 claim was seen), and one per
rejected input (``raw`` = hex of the offending bytes; for a line that is not a frame, the line itself)::

    {"rejected": "truncated_fast_packet", "detail": "...", "source": "n2k:0", "pgn": 129029,
     "raw": "c01a...", "line": 812}
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any

from interfaces.messages import Rejected
from interfaces.nmea2000.codec import N2kDecoded, N2kDecoder, n2k_source_name
from interfaces.nmea2000.logformats import LogFrame, read_log
from interfaces.records import LogSource, message_record, rejected_record


def _record(result: N2kDecoded, t_s: float | None, line: int | None, decoder: N2kDecoder) -> dict[str, Any]:
    source = n2k_source_name(result.source_address)
    pgn = result.pgn if result.pgn >= 0 else None
    name = decoder.name_of(result.source_address)
    device = None if name is None else f"{name:016x}"  # the NAME its address was claimed with (60928)
    if isinstance(result.item, Rejected):
        return rejected_record(source, result.item, binary=True, pgn=pgn, t_s=t_s, line=line, name=device)
    return message_record(source, result.item, pgn=pgn, t_s=t_s, line=line, name=device)


def decode_nmea2000_log(source: LogSource, stats: dict[str, Any] | None = None,
                        log_format: str | None = None) -> Iterator[dict[str, Any]]:
    """Decode an NMEA 2000 capture to JSON-line objects.

    Frames without a capture time are decoded at the time of the previous one (0 at first), so a lost
    fast-packet frame is found when its sequence id is reused or at the end of the file, not by age.
    Lines or packets that are not frames yield ``{"rejected": "garbage", ...}`` (``raw`` is the line).

    Parameters
    ----------
    source :
        The log's path, or its content as bytes.
    stats : dict, optional
        Filled as the generator runs: ``format`` (the name read with), ``frames_read``, ``garbage_lines``
        and the decoder counters (``frames``, ``whole_messages``, ``ignored``, ``messages``, ``rejected``,
        ``rejected.<reason>`` …).
    log_format : str, optional
        One of :data:`~interfaces.nmea2000.logformats.LOG_FORMATS`; detected from the file when omitted.

    Raises
    ------
    ValueError
        For an unknown ``log_format``.
    OSError
        If the file cannot be read.
    """
    name, items = read_log(source, log_format)
    decoder = N2kDecoder()
    counts = stats if stats is not None else {}
    counts.update(format=name, frames_read=0, garbage_lines=0)
    clock = 0.0
    for item in items:
        if not isinstance(item, LogFrame):
            counts["garbage_lines"] += 1
            yield {"rejected": "garbage", "detail": item.reason, "source": "n2k:?", "raw": item.excerpt,
                   "line": item.line or None}
            continue
        counts["frames_read"] += 1
        if item.t_s is not None and math.isfinite(item.t_s):
            clock = item.t_s
        if item.whole:
            results = decoder.decode_message(item.pgn, item.source, item.data, clock)
        else:
            results = decoder.decode_frame(item.can_id, item.data, clock)
        for result in results:
            yield _record(result, item.t_s, item.line, decoder)
        counts.update(decoder.counters)
    for result in decoder.expire(math.inf):  # fast packets still incomplete at the end of the capture
        yield _record(result, None, None, decoder)
    counts.update(decoder.counters)


decode_candump_log = decode_nmea2000_log
"""The decoder's former name (it reads every format now, candump among them)."""
