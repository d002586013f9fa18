"""Readers of the NMEA 2000 capture formats boats log, and detection of which one a file is.

=============  ====================================================================  ===================
format         example line                                                          capture time
=============  ====================================================================  ===================
``candump``    ``(1502984866.421964) slcan0 09F112CC#FF725AFF7F`` (3 variants,        UNIX s (``-l`` only)
               see :mod:`interfaces.nmea2000.candump`)
``actisense``  ``A000057.055 09FF7 0FF00 3F9FDCFFFFFFFFFF`` (Actisense N2K ASCII,      s of day
               NGW-1/W2K-1; whole messages)
``plain``      ``2016-02-28T19:57:02.364Z,2,127250,7,255,8,ff,10,3b,ff,7f,ce,f5,fc``   UNIX s
               (canboat PLAIN: one frame a line; FAST: a whole message a line, more
               than 8 bytes; both mixed)
``ydwg``       ``00:29:58.617 R 0DFF180D A2 8C 50 C0 FF FF FF FF`` (Yacht Devices      s of day
               YDWG-02/YDEN-02 raw, received ``R`` and transmitted ``T``)
``ikonvert``   ``!PDGY,127250,2,3,255,481.734,2C20AAAAAAE=`` (Digital Yacht iKonvert;    s since start
               whole messages, base64)
``trc``        PEAK PCAN-View trace, ``;$FILEVERSION=1.1`` … ``1)  48.6  Rx  09F11201  8  FF 50 ...``  UNIX s
``pcap``       SocketCAN pcap or pcapng (link type 227, ``LINKTYPE_CAN_SOCKETCAN``)     UNIX s
=============  ====================================================================  ===================

What is read with a library, and what by hand:

* the lines of ``actisense``, ``plain``, ``ydwg``, ``ikonvert`` and ``candump`` are parsed by canboat's
  own line parser (``nmea2000._canboat.parse_line``, the parser of canboat's ``analyzer``), which checks
  hex digits, lengths and the base64 of iKonvert. It does not return the capture time: the time field
  of each format is read here (a few characters in a fixed place);
* ``trc`` is read by python-can's ``TRCReader`` (PCAN-View trace versions 1.0 to 2.1; the lines it
  skips, which it only logs, are reported like the others);
* ``pcap``/``pcapng`` containers are read by dpkt; the 16-byte SocketCAN header inside each packet
  (identifier with its flags, length, data) is unpacked here with :mod:`struct` — dpkt has no
  SocketCAN layer and the layout is fixed by Linux's ``struct can_frame``.

Every reader yields :class:`LogFrame` (a CAN frame, or a whole message as gateways deliver them) or
:class:`LogError` (a line or packet that is not one, with the reason); nothing raises on content.
"""

from __future__ import annotations

import calendar
import io
import logging
import re
import struct
from collections.abc import Callable, Iterator
from dataclasses import dataclass

from nmea2000 import _canboat as canboat

from interfaces.nmea2000.candump import is_metadata, parse_candump_line
from interfaces.records import LogSource, read_log_bytes

LOG_FORMATS = ("candump", "actisense", "plain", "ydwg", "ikonvert", "trc", "pcap")
"""Names accepted by ``dpcontrol decode nmea2000 --format`` (``fast`` is an alias of ``plain``)."""
_ALIASES = {"fast": "plain", "pcapng": "pcap", "actisense_ascii": "actisense", "ydwg02": "ydwg", "yden": "ydwg",
            "pcan": "trc"}
_PARSER_NAME = {"actisense": "actisense_ascii", "plain": "plain", "ydwg": "ydwg02", "ikonvert": "ikonvert"}
SNIFF_LINES = 200
"""Lines of a text log that format detection parses."""
MAX_MESSAGE_LINE_CHARS = 1024
"""Longest line of a format that writes whole messages: a 223-byte fast packet as canboat's FAST
(``,xx`` a byte, 669 characters) plus its header; anything longer is garbage."""


@dataclass(frozen=True, slots=True)
class LogFrame:
    """One CAN frame or one whole message of a capture.

    Attributes
    ----------
    t_s : float or None
        Capture time [s]: UNIX time where the format has a date (candump -l, plain, trc, pcap), seconds
        of the day (actisense, ydwg) or since the gateway started (ikonvert); ``None`` when it has none.
    priority, pgn, source, destination : int
        From the 29-bit identifier (or the gateway's header).
    data : bytes
        The frame's 0–8 bytes, or the whole payload when ``whole`` is true.
    whole : bool
        The gateway delivered the message reassembled (fast packets joined): decode as a payload.
    line : int
        1-based line number (packet number for pcap).
    """

    t_s: float | None
    priority: int
    pgn: int
    source: int
    destination: int
    data: bytes
    whole: bool
    line: int

    @property
    def can_id(self) -> int:
        return canboat.can_id_compose(self.priority, self.pgn, self.source, self.destination)


@dataclass(frozen=True, slots=True)
class LogError:
    """A line or packet that is not a frame of the format: its number, why, and a printable excerpt."""

    line: int
    reason: str
    excerpt: str


LogItem = LogFrame | LogError


def canonical_format(name: str) -> str:
    """The format name for ``name`` (case-insensitive, aliases resolved).

    Raises
    ------
    ValueError
        For a name that is no format, naming the known ones.
    """
    key = name.strip().lower()
    key = _ALIASES.get(key, key)
    if key not in LOG_FORMATS:
        raise ValueError(f"unknown NMEA 2000 log format {name!r}; known: {', '.join(LOG_FORMATS)} (fast = plain)")
    return key


# ----------------------------------------------------------------------------------------------
# capture times of the text formats (what canboat's parser does not return)

_ISO_RE = re.compile(r"(\d{4})-(\d{2})-(\d{2})[T-](\d{2}):(\d{2}):(\d{2}(?:\.\d+)?)Z?")
_DAY_TIME_RE = re.compile(r"(\d{2}):?(\d{2}):?(\d{2}(?:\.\d+)?)")


def _unix_time(text: str) -> float | None:
    """``2016-02-28T19:57:02.364Z`` or canboat's ``2011-04-25-10:16:43.004`` → UNIX s (UTC)."""
    match = _ISO_RE.fullmatch(text)
    if match is None:
        return None
    year, month, day, hour, minute = (int(match.group(k)) for k in range(1, 6))
    if not (1 <= month <= 12 and 1 <= day <= 31 and hour <= 23 and minute <= 59):
        return None
    return calendar.timegm((year, month, day, hour, minute, 0, 0, 0, 0)) + float(match.group(6))


def _day_seconds(text: str) -> float | None:
    """``00:29:58.617`` or ``000057.055`` → seconds of the day."""
    match = _DAY_TIME_RE.fullmatch(text)
    if match is None:
        return None
    hours, minutes, seconds = int(match.group(1)), int(match.group(2)), float(match.group(3))
    if hours > 23 or minutes > 59 or seconds >= 61.0:
        return None
    return hours * 3600.0 + minutes * 60.0 + seconds


def _seconds(text: str) -> float | None:
    try:
        value = float(text)
    except ValueError:
        return None
    return value if re.fullmatch(r"\d+(?:\.\d+)?", text) else None


_TIME_OF_LINE: dict[str, Callable[[str], float | None]] = {
    "actisense": lambda line: _day_seconds(line[1:line.find(" ")]) if line.startswith("A") else None,
    "plain": lambda line: _unix_time(line[:line.find(",")]),
    "ydwg": lambda line: _day_seconds(line[:line.find(" ")]),
    "ikonvert": lambda line: _seconds(line.split(",")[5]) if line.count(",") >= 6 else None,
}
# formats whose gateway hands over messages already reassembled (a payload, not a CAN frame)
_WHOLE = {"actisense": True, "ikonvert": True}


# ----------------------------------------------------------------------------------------------
# text readers


def _text_lines(data: bytes) -> Iterator[tuple[int, str]]:
    yield from enumerate(data.decode("ascii", errors="replace").splitlines(), start=1)


def read_text_format(data: bytes, log_format: str) -> Iterator[LogItem]:
    """Frames of a canboat-parsed text format (``actisense``, ``plain``, ``ydwg``, ``ikonvert``).

    Blank lines and ``#`` comments are skipped; iKonvert's control sentences (``$PDGY``, not
    ``!PDGY``) carry no frame and are skipped too.
    """
    parser = _PARSER_NAME[log_format]
    time_of = _TIME_OF_LINE[log_format]
    always_whole = _WHOLE.get(log_format, False)
    for number, line in _text_lines(data):
        stripped = line.strip()
        if not stripped or stripped.startswith("#"):
            continue
        if len(stripped) > MAX_MESSAGE_LINE_CHARS:
            yield LogError(number, f"line of {len(stripped)} characters is too long for a {log_format} frame",
                           stripped[:80])
            continue
        if not stripped.isascii():  # canboat's parser (Rust) panics on a multi-byte character: never hand it one
            yield LogError(number, f"non-ASCII byte in a {log_format} line", stripped[:80])
            continue
        try:
            parsed = canboat.parse_line(parser, stripped)
        except ValueError as error:
            yield LogError(number, f"not a {log_format} line: {error}", stripped[:80])
            continue
        if parsed is None:
            if log_format == "ikonvert" and stripped.startswith("$PDGY"):
                continue  # a gateway status sentence
            yield LogError(number, f"not a {log_format} line", stripped[:80])
            continue
        priority, pgn, source, destination, payload = parsed
        # (a YDWG 'T' line is a frame the gateway transmitted: it was on the bus too, and is read alike)
        yield LogFrame(time_of(stripped), priority, pgn, source, destination, bytes(payload),
                       always_whole or len(payload) > 8, number)


def read_candump_format(data: bytes) -> Iterator[LogItem]:
    """Frames of a candump log, any of its three variants."""
    for number, line in _text_lines(data):
        try:
            frame = parse_candump_line(line, number)
        except ValueError as error:
            yield LogError(number, str(error), line.strip()[:80])
            continue
        if frame is not None:
            priority, pgn, source, destination = canboat.can_id_decompose(frame.can_id)
            yield LogFrame(frame.t_s, priority, pgn, source, destination, frame.data, False, number)


class _Skipped(logging.Handler):
    """Collects what python-can's TRCReader logs about a line it skips (it yields nothing for it)."""

    def __init__(self) -> None:
        super().__init__(logging.INFO)
        self.skipped: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        message = record.getMessage()
        if "Failed to parse" in message or "Unsupported type" in message:
            self.skipped.append(message)


def read_trc(data: bytes) -> Iterator[LogItem]:
    """Frames of a PEAK PCAN-View trace (python-can's ``TRCReader``); only 29-bit data frames are NMEA 2000.

    A line python-can skips (it only logs it) is reported as a :class:`LogError` too, not lost.
    """
    from can.io.trc import TRCReader  # noqa: PLC0415  (python-can's log readers load on first use)

    trc_logger = logging.getLogger("can.io.trc")
    skipped = _Skipped()
    trc_logger.addHandler(skipped)
    propagate, trc_logger.propagate = trc_logger.propagate, False  # reported here, not printed as warnings
    number = 0
    try:
        reader = TRCReader(io.StringIO(data.decode("ascii", errors="replace")))
        for number, message in enumerate(reader, start=1):
            while skipped.skipped:
                yield LogError(0, f"PCAN-View line skipped by python-can: {skipped.skipped.pop(0)}", "")
            if not message.is_extended_id or message.is_remote_frame or message.is_error_frame:
                yield LogError(number, "not an extended (29-bit) data frame", f"{message.arbitration_id:X}")
                continue
            priority, pgn, source, destination = canboat.can_id_decompose(message.arbitration_id & 0x1FFFFFFF)
            yield LogFrame(float(message.timestamp), priority, pgn, source, destination, bytes(message.data)[:8],
                           False, number)
        while skipped.skipped:
            yield LogError(0, f"PCAN-View line skipped by python-can: {skipped.skipped.pop(0)}", "")
    except Exception as error:  # python-can stops at a line it cannot read: say where, keep what was read
        yield LogError(0, f"PCAN-View trace unreadable after message {number}: {type(error).__name__}: {error}", "")
    finally:
        trc_logger.removeHandler(skipped)
        trc_logger.propagate = propagate


_PCAP_MAGICS = (b"\xd4\xc3\xb2\xa1", b"\xa1\xb2\xc3\xd4", b"\x4d\x3c\xb2\xa1", b"\xa1\xb2\x3c\x4d")
_PCAPNG_MAGIC = b"\x0a\x0d\x0d\x0a"
LINKTYPE_CAN_SOCKETCAN = 227
_CAN_EFF_FLAG, _CAN_RTR_FLAG, _CAN_ERR_FLAG = 0x80000000, 0x40000000, 0x20000000
_SOCKETCAN_HEADER = struct.Struct(">IB3x")  # can_id (network order in LINKTYPE_CAN_SOCKETCAN), len, pad/res


def read_pcap(data: bytes) -> Iterator[LogItem]:
    """Frames of a SocketCAN capture in pcap or pcapng (dpkt reads the container)."""
    import dpkt  # noqa: PLC0415  (only for pcap files)

    try:
        reader = dpkt.pcapng.Reader(io.BytesIO(data)) if data[:4] == _PCAPNG_MAGIC else dpkt.pcap.Reader(
            io.BytesIO(data))
    except Exception as error:
        yield LogError(0, f"not a pcap/pcapng file: {type(error).__name__}: {error}", data[:16].hex())
        return
    link = reader.datalink()
    if link != LINKTYPE_CAN_SOCKETCAN:
        yield LogError(0, f"pcap link type {link} is not SocketCAN ({LINKTYPE_CAN_SOCKETCAN})", "")
        return
    number = 0
    try:
        for number, (t_s, packet) in enumerate(reader, start=1):
            if len(packet) < _SOCKETCAN_HEADER.size:
                yield LogError(number, f"{len(packet)}-byte packet is shorter than a SocketCAN header", packet.hex())
                continue
            can_id, length = _SOCKETCAN_HEADER.unpack_from(packet)
            if not can_id & _CAN_EFF_FLAG or can_id & (_CAN_RTR_FLAG | _CAN_ERR_FLAG):
                yield LogError(number, "not an extended (29-bit) data frame", f"{can_id:08X}")
                continue
            payload = packet[_SOCKETCAN_HEADER.size:_SOCKETCAN_HEADER.size + length]
            if length > 8 or len(payload) < length:
                yield LogError(number, f"length {length} with {len(packet) - _SOCKETCAN_HEADER.size} data bytes",
                               packet[:24].hex())
                continue
            priority, pgn, source, destination = canboat.can_id_decompose(can_id & 0x1FFFFFFF)
            yield LogFrame(float(t_s), priority, pgn, source, destination, bytes(payload), False, number)
    except Exception as error:  # a cut or damaged container: say where, keep what was read
        yield LogError(number + 1, f"pcap unreadable from here on: {type(error).__name__}: {error}", "")


# ----------------------------------------------------------------------------------------------
# detection and dispatch


def _parses(log_format: str, line: str) -> bool:
    if log_format == "candump":
        try:
            return parse_candump_line(line) is not None
        except ValueError:
            return False
    if not line.isascii():  # (canboat's parser panics on a multi-byte character)
        return False
    try:
        return canboat.parse_line(_PARSER_NAME[log_format], line) is not None
    except ValueError:
        return False


def detect_format(data: bytes) -> str | None:
    """The format of a capture, from its first bytes and lines; ``None`` when no format reads any line.

    Binary pcap/pcapng by their magic numbers, a PCAN-View trace by its ``;$FILEVERSION`` header or its
    ``;`` comment block, and the text formats by which canboat parser reads most of the first
    :data:`SNIFF_LINES` lines that are not blank or comments (ties go to the earlier format of
    :data:`LOG_FORMATS`).
    """
    if data[:4] in _PCAP_MAGICS or data[:4] == _PCAPNG_MAGIC:
        return "pcap"
    head = data[:65536].decode("ascii", errors="replace")
    if head.lstrip().startswith(";"):
        return "trc"
    lines = [line.strip() for line in head.splitlines() if not is_metadata(line)][:SNIFF_LINES]
    best, best_count = None, 0
    for log_format in ("candump", "actisense", "plain", "ydwg", "ikonvert"):
        count = sum(_parses(log_format, line) for line in lines)
        if count > best_count:
            best, best_count = log_format, count
    return best


def read_log(source: LogSource, log_format: str | None = None) -> tuple[str, Iterator[LogItem]]:
    """The format of a capture (given, or detected) and an iterator over its frames.

    Raises
    ------
    ValueError
        For an unknown ``log_format``.
    OSError
        If the file cannot be read.
    """
    data = read_log_bytes(source)
    name = canonical_format(log_format) if log_format is not None else (detect_format(data) or "candump")
    if name == "candump":
        return name, read_candump_format(data)
    if name == "trc":
        return name, read_trc(data)
    if name == "pcap":
        return name, read_pcap(data)
    return name, read_text_format(data, name)
