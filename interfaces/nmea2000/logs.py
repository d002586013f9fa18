"""NMEA 2000 candump logs → the JSON-line objects of ``dpcontrol decode nmea2000 FILE`` (DESIGN §4.1).

One object per decoded measurement::

    {"source": "n2k:0", "kind": "position", "pgn": 129025, "lat_deg": 52.1, "lon_deg": 4.3,
     "quality": "gps", "t_s": 1502984866.42, "line": 12}

(``sample_time`` = UTC seconds of day where the PGN carries one, i.e. 129029; ``t_s`` = capture
time where the candump format has one), and one per rejected input (``raw`` = hex of the
offending bytes; for a line that is not a frame, the line itself)::

    {"rejected": "truncated_fast_packet", "detail": "...", "source": "n2k:0", "pgn": 129029,
     "raw": "c01a...", "line": 812}

:func:`message_record` and :func:`rejected_record` are protocol-neutral (the MAVLink log decoder
uses them too).
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterator
from typing import Any

from interfaces.messages import (
    Rejected,
)
from interfaces.nmea2000.candump import CandumpFrame, read_candump
from interfaces.nmea2000.codec import N2kDecoded, N2kDecoder, n2k_source_name
from interfaces.records import message_record, rejected_record


def _record(result: N2kDecoded, t_s: float | None, line: int | None) -> dict[str, Any]:
    source = n2k_source_name(result.source_address)
    pgn = result.pgn if result.pgn >= 0 else None
    if isinstance(result.item, Rejected):
        return rejected_record(source, result.item, binary=True, pgn=pgn, t_s=t_s, line=line)
    return message_record(source, result.item, pgn=pgn, t_s=t_s, line=line)


def decode_candump_log(source: str | os.PathLike[str] | bytes,
                       stats: dict[str, int] | None = None) -> Iterator[dict[str, Any]]:
    """Decode a candump capture (any of the three formats) to JSON-line objects.

    Frames without a timestamp (``candump1``/``candump2``) are decoded with time 0, so a lost
    fast-packet frame is found when its sequence id is reused or at the end of the file, not by
    age. Lines that are not frames yield ``{"rejected": "garbage", ...}`` (``raw`` is the line).

    Parameters
    ----------
    source :
        The log's path, or its content as bytes.
    stats : dict, optional
        Filled as the generator runs: ``frames_read``, ``garbage_lines`` and the decoder counters
        (``frames``, ``ignored``, ``messages``, ``rejected``, ``rejected.<reason>`` …).

    Raises
    ------
    OSError
        If the file cannot be read.
    """
    decoder = N2kDecoder()
    counts = stats if stats is not None else {}
    counts.update(frames_read=0, garbage_lines=0)
    for item in read_candump(source):
        if not isinstance(item, CandumpFrame):
            line_no, reason, excerpt = item
            counts["garbage_lines"] += 1
            yield {"rejected": "garbage", "detail": reason, "source": "n2k:?", "raw": excerpt, "line": line_no}
            continue
        counts["frames_read"] += 1
        t_s = item.t_s if item.t_s is not None else 0.0
        for result in decoder.decode_frame(item.can_id, item.data, t_s):
            yield _record(result, item.t_s, item.line_no)
        counts.update(decoder.counters)
    for result in decoder.expire(math.inf):  # fast packets still incomplete at the end of the capture
        yield _record(result, None, None)
    counts.update(decoder.counters)
