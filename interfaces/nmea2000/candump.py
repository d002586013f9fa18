"""Parser for the three Linux can-utils ``candump`` text formats found in CAN captures.

=============  ==================================================  =========
format         example                                             timestamp
=============  ==================================================  =========
``candump1``   ``<0x18eeff01> [8] 05 a0 be 1c 00 a0 a0 c0``        no
``candump2``   ``  can0  09F8027F   [8]  00 FC FF FF 00 00 FF FF``  no
``candump3``   ``(1502984866.421964) slcan0 09F112CC#FF725AFF7F``  yes (Unix s)
=============  ==================================================  =========

The identifier and data bytes are parsed by the ``nmea2000`` package's CANboat line parser
(``parse_line("candump", line)``), which validates hex digits and the ``[n]`` length against the
bytes present; it returns the decomposed identifier, which we compose back (exact for all 2²⁹
identifiers). The ``(seconds)`` timestamp of the third format is not returned by that parser, so
it is read here.
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterator
from dataclasses import dataclass

from nmea2000 import _canboat as canboat

MAX_LINE_CHARS = 512  # a candump line is < 100 characters; anything longer is garbage
_TIMESTAMP_RE = re.compile(r"\d{1,12}(?:\.\d{1,9})?")


@dataclass(frozen=True, slots=True)
class CandumpFrame:
    """One CAN frame read from a candump log.

    Attributes
    ----------
    t_s : float or None
        Capture time [s since the Unix epoch] (``candump -l`` format only).
    can_id : int
        29-bit identifier.
    data : bytes
        0–8 data bytes.
    line_no : int
        1-based line number in the file (0 when parsed from a lone string).
    """

    t_s: float | None
    can_id: int
    data: bytes
    line_no: int = 0


def is_metadata(line: str) -> bool:
    """Whether ``line`` carries no frame by design: blank, ``#`` comment, or candump's header."""
    stripped = line.strip()
    return not stripped or stripped.startswith("#") or stripped.startswith("interface =")


def parse_candump_line(line: str, line_no: int = 0) -> CandumpFrame | None:
    """Parse one line of any of the three candump formats.

    Returns
    -------
    CandumpFrame or None
        ``None`` for blank lines, comments and candump's ``interface = ...`` header.

    Raises
    ------
    ValueError
        With the reason, for a line that is neither metadata nor a well-formed frame.
    """
    if is_metadata(line):
        return None
    if len(line) > MAX_LINE_CHARS:
        raise ValueError(f"line of {len(line)} characters is too long for a candump frame")
    stripped = line.strip()
    if not stripped.isascii():  # canboat's parser (Rust) panics on a multi-byte character: never hand it one
        raise ValueError("non-ASCII byte in a candump line")
    try:
        parsed = canboat.parse_line("candump", stripped)
    except ValueError as error:
        raise ValueError(f"not a candump frame: {error}") from error
    if parsed is None:
        raise ValueError("not a candump frame")
    priority, pgn, source, destination, data = parsed
    if len(data) > 8:
        raise ValueError(f"{len(data)} data bytes in a classic CAN frame")
    t_s = None
    if stripped.startswith("("):
        text = stripped[1:stripped.index(")")]
        # candump -l writes seconds.microseconds; float() would also take nan, inf and 1e400
        if not _TIMESTAMP_RE.fullmatch(text):
            raise ValueError(f"candump timestamp ({text}) is not seconds.microseconds")
        t_s = float(text)
    return CandumpFrame(t_s, canboat.can_id_compose(priority, pgn, source, destination), bytes(data), line_no)


def _lines(source: str | os.PathLike[str] | bytes) -> Iterator[str]:
    if isinstance(source, bytes | bytearray | memoryview):
        yield from bytes(source).decode("ascii", errors="replace").splitlines()
        return
    with open(source, encoding="ascii", errors="replace") as handle:
        yield from handle


def read_candump(source: str | os.PathLike[str] | bytes) -> Iterator[CandumpFrame | tuple[int, str, str]]:
    """Iterate over the frames of a candump log (a path, or the log's content as bytes).

    Yields
    ------
    CandumpFrame
        For every frame line.
    (line_no, reason, excerpt) : tuple
        For every line that is not a frame and not metadata (bad input is reported, not fatal).
    """
    for line_no, line in enumerate(_lines(source), start=1):
        try:
            frame = parse_candump_line(line, line_no)
        except ValueError as error:
            yield (line_no, str(error), line.strip()[:80])
            continue
        if frame is not None:
            yield frame
