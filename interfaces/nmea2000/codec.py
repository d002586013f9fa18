"""NMEA 2000 codec: 29-bit CAN frames ⇄ the typed messages of :mod:`interfaces.messages`.

Pure (no clock, no I/O): every call takes the receive time ``t_s`` from its caller.

What comes from the ``nmea2000`` package (the CANboat PGN database compiled to Rust) and what is
written here, and why:

* **Field layouts, scaling and sentinels** — ``nmea2000.backend.decode`` / ``DATABASE.encode``. The
  database knows that 0x7FFF…/0xFFFF… ("not available"), 0x…FE ("error") and 0x…FD ("reserved")
  are not numbers and reports them as ``None``; we turn ``None`` into :class:`Rejected` or a
  ``None`` field, never a number.
* **29-bit identifier** (priority, PGN with PDU1/PDU2 handling, source, destination) —
  ``can_id_decompose`` / ``can_id_compose`` from the same library.
* **Fast-packet fragmentation** (encoder side) — ``fast_packet_fragment``.
* **Fast-packet reassembly** is written here (:class:`FastPacketAssembler`): the library's
  ``Reassembler`` has no clock, so stale partial messages never expire and a lost frame is never
  reported; we must count every dropped message and bound the state (docs/design.md §5 "nothing a sensor
  sends may crash the code" and docs/protocols.md).
* **Payload length check** is written here: the library decodes a truncated single frame into a
  number built from the bytes that are there (a 2-byte 129025 decodes to latitude 5.13e-05°), so a
  payload shorter than the fields we read is rejected before decoding.
* **Validity rules** (129029 method/integrity, heading reference, plausible ranges) are ours.

Resolutions on the wire (quantisation of a round trip is half of these): 129025 lat/lon 1e-7°
(≈ 5.6 mm of latitude at half a step); 129029 lat/lon 1e-16°, altitude 1e-6 m, time 1e-4 s,
HDOP 0.01; 129026 COG 1e-4 rad, SOG 0.01 m/s; 127250 heading/deviation/variation 1e-4 rad;
127251 rate 3.125e-8 rad/s; 127257 yaw/pitch/roll 1e-4 rad; 130306 speed 0.01 m/s, angle 1e-4 rad.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, Final, NamedTuple

from nmea2000 import _canboat as canboat
from nmea2000 import backend

from dpbase.frames import TWO_PI, ssa
from interfaces.limits import violation
from interfaces.messages import (
    Attitude,
    CourseOverGround,
    FixQuality,
    Heading,
    PositionFix,
    RateOfTurn,
    Rejected,
    SensorMessage,
    Wind,
)

PGN_VESSEL_HEADING: Final = 127250
PGN_RATE_OF_TURN: Final = 127251
PGN_ATTITUDE: Final = 127257
PGN_POSITION_RAPID: Final = 129025
PGN_COG_SOG_RAPID: Final = 129026
PGN_GNSS_POSITION: Final = 129029
PGN_WIND: Final = 130306
PGN_ADDRESS_CLAIM: Final = 60928
PGN_MAGNETIC_VARIATION: Final = 127258
STATE_PGNS: Final = frozenset({PGN_ADDRESS_CLAIM, PGN_MAGNETIC_VARIATION})
"""PGNs that give no measurement but change how later ones are read (who an address is, the variation)."""

# canboat identifiers of the PGN definitions we use (one variant each).
_PGN_IDS: Final[dict[int, str]] = {
    PGN_VESSEL_HEADING: "vesselHeading",
    PGN_RATE_OF_TURN: "rateOfTurn",
    PGN_ATTITUDE: "attitude",
    PGN_POSITION_RAPID: "positionRapidUpdate",
    PGN_COG_SOG_RAPID: "cogSogRapidUpdate",
    PGN_GNSS_POSITION: "gnssPositionData",
    PGN_WIND: "windData",
}
SUPPORTED_PGNS: Final = frozenset(_PGN_IDS)
FAST_PACKET_PGNS: Final = frozenset(p for p in SUPPORTED_PGNS if backend.is_fast_pgn(p))

# Fields each decoder reads; a payload must cover all of them (see module docstring).
_USED_FIELDS: Final[dict[int, tuple[str, ...]]] = {
    PGN_VESSEL_HEADING: ("heading", "deviation", "variation", "reference"),
    PGN_RATE_OF_TURN: ("rate",),
    PGN_ATTITUDE: ("yaw", "pitch", "roll"),
    PGN_POSITION_RAPID: ("latitude", "longitude"),
    PGN_COG_SOG_RAPID: ("cogReference", "cog", "sog"),
    PGN_GNSS_POSITION: ("time", "latitude", "longitude", "altitude", "method", "integrity", "numberOfSvs", "hdop"),
    PGN_WIND: ("windSpeed", "windAngle", "reference"),
}


def _min_payload_bytes(pgn: int) -> int:
    """Bytes a payload of ``pgn`` needs to carry every field we read (from the canboat database)."""
    info = backend.DATABASE.pgn_info(_PGN_IDS[pgn])
    end_bits = [f.bit_offset + f.bit_length for f in info.fields
                if f.id in _USED_FIELDS[pgn] and f.bit_offset is not None and f.bit_length is not None]
    return (max(end_bits) + 7) // 8


MIN_PAYLOAD_BYTES: Final[dict[int, int]] = {pgn: _min_payload_bytes(pgn) for pgn in SUPPORTED_PGNS}

# Default priorities a sensor uses for these PGNs (canboat / NMEA 2000 appendix B defaults).
DEFAULT_PRIORITY: Final[dict[int, int]] = {
    PGN_VESSEL_HEADING: 2, PGN_RATE_OF_TURN: 2, PGN_ATTITUDE: 3, PGN_POSITION_RAPID: 2,
    PGN_COG_SOG_RAPID: 2, PGN_GNSS_POSITION: 3, PGN_WIND: 2,
}

BROADCAST: Final = 255
MAX_FAST_PACKET_BYTES: Final = 223  # 6 bytes in frame 0 + 31 frames × 7 bytes
_RAW_KEEP: Final = 64  # bytes of an offending input kept in a Rejected (bounded for the recorder)

# 129029 "method" (GNS_METHOD) codes 1..8 are the GGA quality codes; 0 no GNSS, 9..13 reserved,
# 14 error, 15 not available → invalid. Integrity (GNS_INTEGRITY): 0 no checking, 1 safe,
# 2 caution, 3 unsafe → caution and unsafe are invalid fixes.
_VALID_METHODS: Final = frozenset(range(1, 9))
_BAD_INTEGRITY: Final[dict[int, str]] = {2: "caution", 3: "unsafe"}
# 130306 WIND_REFERENCE codes we can express as :class:`Wind` (angle from north / from the bow).
_WIND_REFERENCES: Final[dict[int, str]] = {0: "true", 2: "apparent"}
_WIND_CODES: Final[dict[str, int]] = {v: k for k, v in _WIND_REFERENCES.items()}


class N2kHeader(NamedTuple):
    """The fields of a 29-bit NMEA 2000 / J1939 identifier.

    ``pgn`` has the destination byte cleared for PDU1 (PF < 240) PGNs; ``destination`` is 255
    (broadcast) for PDU2 PGNs.
    """

    priority: int
    pgn: int
    source: int
    destination: int


def parse_can_id(can_id: int) -> N2kHeader:
    """Split a 29-bit CAN identifier into priority, PGN, source and destination.

    Raises
    ------
    ValueError
        If ``can_id`` is not an integer in [0, 2²⁹).
    """
    if not isinstance(can_id, int) or not 0 <= can_id <= 0x1FFFFFFF:
        raise ValueError(f"CAN identifier {can_id!r} is not a 29-bit integer")
    return N2kHeader(*canboat.can_id_decompose(can_id))


def make_can_id(priority: int, pgn: int, source: int, destination: int = BROADCAST) -> int:
    """Compose a 29-bit CAN identifier (inverse of :func:`parse_can_id`).

    Raises
    ------
    ValueError
        If a field is out of range (priority 0–7, PGN < 2¹⁸, addresses 0–255).
    """
    if not (0 <= priority <= 7 and 0 <= pgn < 1 << 18 and 0 <= source <= 255 and 0 <= destination <= 255):
        raise ValueError(f"bad identifier fields: priority={priority} pgn={pgn} source={source} "
                         f"destination={destination}")
    return canboat.can_id_compose(priority, pgn, source, destination)


def n2k_source_name(address: int) -> str:
    """Default sensor name of a NMEA 2000 source address (``n2k:35``; ``n2k:?`` when unknown)."""
    return f"n2k:{address}" if address >= 0 else "n2k:?"


def wrap_2pi(angle_rad: float) -> float:
    """Wrap an angle to [0, 2π) [rad], the range headings are sent in (built on :func:`ssa`)."""
    wrapped = ssa(angle_rad)
    if wrapped < 0.0:
        wrapped += TWO_PI
    return 0.0 if wrapped >= TWO_PI else wrapped


class N2kDecoded(NamedTuple):
    """One decoder result: a message or a reject, with where it came from."""

    source_address: int  # -1 when the frame was too broken to say
    pgn: int  # -1 likewise
    item: SensorMessage | Rejected


def _dropped(decoded: N2kDecoded) -> Rejected:
    """The reject of a message the fast-packet assembler dropped (its items are always rejects)."""
    item = decoded.item
    if not isinstance(item, Rejected):  # pragma: no cover - the assembler makes only rejects
        raise TypeError(f"fast-packet drop carries {type(item).__name__}, not Rejected")
    return item


# --------------------------------------------------------------------------------------------
# Fast packet
# --------------------------------------------------------------------------------------------

@dataclass(slots=True)
class _Partial:
    t0_s: float
    length: int  # total payload bytes, -1 until frame 0 has been seen
    frames: dict[int, bytes]


def fast_packet_frame_count(length: int) -> int:
    """Number of CAN frames a fast-packet payload of ``length`` bytes takes (6 + 7 + 7 …)."""
    return 1 if length <= 6 else 1 + (length - 6 + 6) // 7  # 1 + ceil((length − 6) / 7)


class FastPacketAssembler:
    """Reassembles NMEA 2000 fast-packet messages per (source, PGN, sequence id).

    Frame layout (NMEA 2000 fast packet): byte 0 = sequence id (3 bits) << 5 | frame index
    (5 bits); frame 0 carries the payload length in byte 1 and 6 payload bytes, later frames 7.
    Frames may arrive out of order and interleaved with other sources or sequence ids.

    A message that cannot complete is *dropped and counted*: when a frame index repeats (the
    sender has started a new message with the same sequence id, so the old one lost frames),
    when it is older than ``timeout_s`` (measured from its first frame), or when more than
    ``max_partial`` messages are open (the oldest goes). The default timeout, 0.75 s, is the
    T1 value ISO 11783-3 uses for its transport protocol; a fast packet is normally sent
    back-to-back in a few milliseconds.

    Parameters
    ----------
    timeout_s : float
        Age [s] after which an incomplete message is dropped.
    max_partial : int
        Maximum number of incomplete messages kept (bounded memory on a hostile bus).
    """

    def __init__(self, timeout_s: float = 0.75, max_partial: int = 64) -> None:
        if not timeout_s > 0.0 or max_partial < 1:
            raise ValueError("timeout_s must be > 0 and max_partial >= 1")
        self.timeout_s = float(timeout_s)
        self.max_partial = int(max_partial)
        # insertion order == creation order, so expiry scans from the front only
        self._partials: dict[tuple[int, int, int], _Partial] = {}

    @property
    def pending(self) -> int:
        """Number of incomplete messages held."""
        return len(self._partials)

    def push(self, source: int, pgn: int, data: bytes, t_s: float) -> tuple[bytes | None, list[N2kDecoded]]:
        """Add one frame.

        Parameters
        ----------
        source, pgn : int
            From the CAN identifier.
        data : bytes
            The frame's data field (2–8 bytes).
        t_s : float
            Receive time [s] on the caller's clock (non-decreasing for expiry to work).

        Returns
        -------
        payload : bytes or None
            The complete payload (trimmed to its announced length) when this frame completed it.
        rejects : list of N2kDecoded
            Messages dropped by this call (expired, superseded, overflowed) and an invalid frame,
            each a :class:`Rejected` with its source and PGN.
        """
        rejects = self.expire(t_s) if self._partials else []
        if len(data) < 2:
            rejects.append(N2kDecoded(source, pgn, Rejected(
                "bad_fast_packet", f"PGN {pgn} from {source}: {len(data)}-byte frame", bytes(data))))
            return None, rejects
        seq, index = data[0] >> 5, data[0] & 0x1F
        key = (source, pgn, seq)
        if index == 0 and data[1] > MAX_FAST_PACKET_BYTES:
            rejects.append(N2kDecoded(source, pgn, Rejected(
                "bad_fast_packet", f"PGN {pgn} from {source}: length {data[1]} > 223", bytes(data))))
            return None, rejects
        partial = self._partials.get(key)
        if partial is not None and index in partial.frames:
            # the sender reused this sequence id: the old message will never complete
            del self._partials[key]
            rejects.append(self._dropped(key, partial, "superseded by a new message with the same sequence id"))
            partial = None
        if partial is None:
            if len(self._partials) >= self.max_partial:
                old_key = next(iter(self._partials))
                rejects.append(self._dropped(old_key, self._partials.pop(old_key), "too many open messages"))
            partial = self._partials[key] = _Partial(t_s, -1, {})
        if index == 0:
            partial.length = data[1]
        n_frames = fast_packet_frame_count(partial.length) if partial.length >= 0 else 32
        if index >= n_frames:
            rejects.append(N2kDecoded(source, pgn, Rejected(
                "bad_fast_packet", f"PGN {pgn} from {source}: frame {index} beyond the {n_frames} frames of a "
                f"{partial.length}-byte message", bytes(data))))
            if not partial.frames:
                del self._partials[key]
            return None, rejects
        partial.frames[index] = bytes(data)
        if partial.length < 0 or len(partial.frames) < n_frames:
            return None, rejects
        del self._partials[key]
        if max(partial.frames) >= n_frames:
            # early out-of-order frames that do not fit the announced length
            rejects.append(self._dropped(key, partial, "frame indices do not fit the announced length",
                                         reason="bad_fast_packet"))
            return None, rejects
        frames = partial.frames
        payload = frames[0][2:] + b"".join(frames[i][1:] for i in range(1, n_frames))
        if len(payload) < partial.length:
            rejects.append(self._dropped(key, partial, f"short frames: {len(payload)} of {partial.length} bytes",
                                         reason="bad_fast_packet"))
            return None, rejects
        return payload[:partial.length], rejects

    def expire(self, t_s: float) -> list[N2kDecoded]:
        """Drop (and return as rejects) every incomplete message older than ``timeout_s`` at ``t_s``."""
        out: list[N2kDecoded] = []
        while self._partials:
            key, partial = next(iter(self._partials.items()))
            if t_s - partial.t0_s <= self.timeout_s:
                break
            del self._partials[key]
            out.append(self._dropped(key, partial, f"incomplete after {self.timeout_s:g} s"))
        return out

    @staticmethod
    def _dropped(key: tuple[int, int, int], partial: _Partial, why: str,
                 reason: str = "truncated_fast_packet") -> N2kDecoded:
        source, pgn, seq = key
        have = sorted(partial.frames)
        total = fast_packet_frame_count(partial.length) if partial.length >= 0 else "?"
        raw = b"".join(partial.frames[i] for i in have)[:_RAW_KEEP]
        return N2kDecoded(source, pgn, Rejected(
            reason, f"PGN {pgn} from {source} seq {seq}: frames {have} of {total}; {why}", raw))


# --------------------------------------------------------------------------------------------
# Decoder
# --------------------------------------------------------------------------------------------

def _fields(pgn: int, payload: bytes) -> dict[str, object] | None:
    """Field id → value (SI units; lookup codes as integers; ``None`` = not available)."""
    message = backend.decode(pgn, payload, units="si")
    if message is None:
        return None
    return {f.id: f.raw_value for f in message.fields}


def _number(fields: Mapping[str, object], key: str) -> float | None:
    """A numeric field as a finite float, or ``None`` (canboat gives int, float or ``None``)."""
    value = fields.get(key)
    if value is None:
        return None
    value = float(value)  # type: ignore[arg-type]
    return value if math.isfinite(value) else None


def _code(fields: Mapping[str, object], key: str) -> int | None:
    value = fields.get(key)
    return value if isinstance(value, int) and not isinstance(value, bool) else None


class N2kDecoder:
    """Stateful NMEA 2000 decoder: CAN frames in, typed messages and rejects out.

    Decodes PGNs 129025, 129029 (fast packet), 129026, 127250, 127251, 127257 and 130306;
    other PGNs are ignored (counted). Never raises on input: every frame is accounted for in
    :attr:`counters`: ``frames`` = ``ignored`` + ``bad_frame`` + ``single_frames`` +
    ``fast_packet_frames``; every returned reject adds one to ``rejected`` and to
    ``rejected.<reason>``, every returned message one to ``messages``; and ``messages`` +
    ``rejected`` = ``single_frames`` + ``fast_packet_messages`` + ``whole_messages`` (reassembled by a
    gateway, :meth:`decode_message`) + the fast-packet rejects (``truncated_fast_packet``,
    ``bad_fast_packet``) + ``bad_frame``.

    Validity before values:

    * 129029: method 0 "no GNSS", 9–15 (reserved, error, not available) or integrity
      "caution"/"unsafe" → ``Rejected("invalid_fix")``; method 1–8 → :class:`FixQuality` 1–8.
    * 129025 carries no quality: it takes the method of the latest 129029 from the same source
      if that is at most ``fix_state_max_age_s`` old (an invalid one rejects it), otherwise it
      is assumed to be a plain GNSS fix (``FixQuality.GPS``, counted as ``assumed_quality``).
    * 127250: only a *true* heading is a heading measurement; a magnetic one becomes true with a
      variation (true = sensor + deviation + variation, deviation 0 when not sent, NMEA 2000
      convention): the one in the message; else the latest 127258 of the bus at most
      ``variation_max_age_s`` old (the compass's own source preferred); else ``variation_rad`` when
      configured; otherwise ``Rejected("magnetic_heading")``.
    * 127258 (magnetic variation) and 60928 (ISO address claim) give no message (counted ``ignored``
      and ``variations`` / ``address_claims``): they are kept as state. A claim tells the 64-bit NAME
      of the device at an address (:meth:`name_of`, :meth:`address_of`); when another NAME claims an
      address, what was known of the address (fix state, variation) is forgotten
      (``address_changes``).
    * 129026: a magnetic course has no variation in this PGN → ``course_rad=None``.
    * 130306: references "true (ground, north)" and "apparent" become :class:`Wind`; the others
      (magnetic, true boat/water referenced) → ``Rejected("unsupported_reference")``.
    * "Not available"/"error" values → ``None`` fields, or ``Rejected("not_available")`` when
      nothing usable is left; values outside their physical range (:mod:`interfaces.limits`: a
      129026 speed of 655 m/s, a 129029 altitude of 9e12 m, an attitude angle beyond π ...) →
      ``Rejected("out_of_range")``.

    Parameters
    ----------
    fast_packet_timeout_s, max_partial :
        See :class:`FastPacketAssembler`.
    fix_state_max_age_s : float
        How long a 129029 fix quality applies to the 129025 rapid updates of its source [s].
    variation_rad : float, optional
        Magnetic variation (east positive) [rad] for magnetic 127250 headings when neither the message
        nor a recent 127258 gives one: the value of the vessel's chart, for a bus without a variation.
    variation_max_age_s : float
        How long a 127258 variation applies [s] (senders repeat it every second; a device gone silent
        for a minute no longer vouches for it).
    """

    def __init__(self, fast_packet_timeout_s: float = 0.75, max_partial: int = 64,
                 fix_state_max_age_s: float = 3.0, variation_rad: float | None = None,
                 variation_max_age_s: float = 60.0) -> None:
        if variation_rad is not None and not -math.pi <= variation_rad <= math.pi:
            raise ValueError(f"variation_rad={variation_rad!r} is not in [-pi, pi]")
        if not variation_max_age_s > 0.0:
            raise ValueError(f"variation_max_age_s={variation_max_age_s!r} must be > 0")
        self.assembler = FastPacketAssembler(fast_packet_timeout_s, max_partial)
        self.fix_state_max_age_s = float(fix_state_max_age_s)
        self.variation_rad = variation_rad
        self.variation_max_age_s = float(variation_max_age_s)
        self.counters: Counter[str] = Counter()
        # source address → (t_s of the latest 129029, its quality or None when it was invalid)
        self._fix_state: dict[int, tuple[float, FixQuality | None]] = {}
        # source address → (t_s, variation [rad]) of its latest 127258
        self._variation: dict[int, tuple[float, float]] = {}
        self._names: dict[int, int] = {}  # address → NAME (60928)
        self._variation_choice: dict[int | None, int] = {}  # compass address → the 127258 sender it uses

    # ---- bus state -----------------------------------------------------------------------

    def name_of(self, address: int) -> int | None:
        """The 64-bit NAME the device at ``address`` claimed it with, if a claim was seen."""
        return self._names.get(address)

    def address_of(self, name: int) -> int | None:
        """The address the device with ``name`` claimed last, if any."""
        return next((address for address, claimed in self._names.items() if claimed == name), None)

    def bus_variation(self, t_s: float, source: int | None = None) -> float | None:
        """The magnetic variation [rad] the bus gave at most ``variation_max_age_s`` before ``t_s``, for the
        compass at ``source``; ``None`` when no 127258 is that fresh.

        The compass's own variation if it sends one; else one other sender's, kept while it stays fresh.
        Devices on one bus do disagree (canboat's can0-1.pcap: -4.2° from two of them, +2.4° from six):
        taking whichever spoke last would jump the heading by their difference at every message.
        """
        fresh = {address: entry for address, entry in self._variation.items()
                 if 0.0 <= t_s - entry[0] <= self.variation_max_age_s}
        if not fresh:
            return None
        if source in fresh:
            return fresh[source][1]
        chosen = self._variation_choice.get(source)
        if chosen not in fresh:
            chosen = min(fresh)  # the lowest address: the same choice whatever order they spoke in
            self._variation_choice[source] = chosen  # type: ignore[index]
        return fresh[chosen][1]

    def _state(self, pgn: int, source: int, payload: bytes, t_s: float) -> None:
        """Read a 60928 or 127258 into the bus state (a malformed one is counted and left out)."""
        counters = self.counters
        if pgn == PGN_ADDRESS_CLAIM:
            if len(payload) < 8:
                counters["bad_address_claim"] += 1
                return
            counters["address_claims"] += 1
            name = int.from_bytes(payload[:8], "little")
            if self._names.get(source, name) != name:  # another device took this address
                counters["address_changes"] += 1
                self._fix_state.pop(source, None)
                self._variation.pop(source, None)
            for address in [a for a, claimed in self._names.items() if claimed == name and a != source]:
                del self._names[address]  # the device moved to a new address
            self._names[source] = name
            return
        try:
            fields = _fields(pgn, payload)
        except Exception:  # a library surprise on odd bytes: no variation from it
            fields = None
        variation = None if fields is None or len(payload) < 6 else _number(fields, "variation")
        if variation is None or not -math.pi - 1e-4 <= variation <= math.pi + 1e-4:
            counters["variation_unusable"] += 1
            return
        counters["variations"] += 1
        self._variation[source] = (t_s, variation)

    # ---- frames --------------------------------------------------------------------------

    def decode_frame(self, can_id: int, data: bytes | bytearray | memoryview, t_s: float) -> list[N2kDecoded]:
        """Decode one CAN frame received at ``t_s`` [s].

        Returns
        -------
        list of N2kDecoded
            Usually empty (ignored PGN, fast-packet frame pending) or one item; more when stale
            fast-packet messages were dropped by this call.
        """
        counters = self.counters
        counters["frames"] += 1
        if not isinstance(can_id, int) or not 0 <= can_id <= 0x1FFFFFFF \
                or not isinstance(data, bytes | bytearray | memoryview) or len(data) > 8:
            counters["bad_frame"] += 1
            raw = bytes(data)[:_RAW_KEEP] if isinstance(data, bytes | bytearray | memoryview) else b""
            return [self._reject(-1, -1, Rejected("bad_frame", f"identifier {can_id!r}, data {raw.hex()}", raw))]
        _priority, pgn, source, _destination = canboat.can_id_decompose(can_id)
        if pgn not in SUPPORTED_PGNS:
            counters["ignored"] += 1
            if pgn in STATE_PGNS:
                self._state(pgn, source, bytes(data), t_s)
            return self.expire(t_s) if self.assembler.pending else []
        data = bytes(data)
        if pgn in FAST_PACKET_PGNS:
            counters["fast_packet_frames"] += 1
            payload, dropped = self.assembler.push(source, pgn, data, t_s)
            out = [self._reject(d.source_address, d.pgn, _dropped(d)) for d in dropped]
            if payload is not None:
                counters["fast_packet_messages"] += 1
                out.append(self._finish(source, pgn, self.decode_payload(pgn, payload, source, t_s)))
            return out
        counters["single_frames"] += 1
        out = self.expire(t_s) if self.assembler.pending else []
        out.append(self._finish(source, pgn, self.decode_payload(pgn, data, source, t_s)))
        return out

    def decode_message(self, pgn: int, source: int, payload: bytes | bytearray | memoryview,
                       t_s: float) -> list[N2kDecoded]:
        """Decode one whole message as a gateway delivers it (fast packets already joined: Actisense,
        iKonvert, canboat's FAST format), received at ``t_s`` [s].

        Counted as ``whole_messages`` (or ``ignored_messages`` for a PGN not decoded here); otherwise as
        :meth:`decode_frame`.
        """
        counters = self.counters
        out = self.expire(t_s) if self.assembler.pending else []
        if pgn not in SUPPORTED_PGNS:
            counters["ignored_messages"] += 1
            if pgn in STATE_PGNS:
                self._state(pgn, source, bytes(payload), t_s)
            return out
        counters["whole_messages"] += 1
        out.append(self._finish(source, pgn, self.decode_payload(pgn, bytes(payload), source, t_s)))
        return out

    def expire(self, t_s: float) -> list[N2kDecoded]:
        """Drop fast-packet messages that went stale by ``t_s``; call it when the bus is idle too."""
        return [self._reject(d.source_address, d.pgn, _dropped(d)) for d in self.assembler.expire(t_s)]

    def _reject(self, source: int, pgn: int, rejected: Rejected) -> N2kDecoded:
        self.counters["rejected"] += 1
        self.counters["rejected." + rejected.reason] += 1
        return N2kDecoded(source, pgn, rejected)

    def _finish(self, source: int, pgn: int, item: SensorMessage | Rejected) -> N2kDecoded:
        if isinstance(item, Rejected):
            return self._reject(source, pgn, item)
        self.counters["messages"] += 1
        return N2kDecoded(source, pgn, item)

    # ---- payloads ------------------------------------------------------------------------

    def decode_payload(self, pgn: int, payload: bytes, source: int = 0, t_s: float = 0.0) -> SensorMessage | Rejected:
        """Decode a complete PGN payload (wire order, fast packets reassembled).

        Does not touch :attr:`counters` (the frame-level API does).

        Raises
        ------
        ValueError
            If ``pgn`` is not one of :data:`SUPPORTED_PGNS` (a programming error, not bad input).
        """
        if pgn not in SUPPORTED_PGNS:
            raise ValueError(f"PGN {pgn} is not decoded here (supported: {sorted(SUPPORTED_PGNS)})")
        raw = bytes(payload[:_RAW_KEEP])
        need = MIN_PAYLOAD_BYTES[pgn]
        if len(payload) < need:
            return Rejected("truncated", f"PGN {pgn}: {len(payload)} bytes, need {need}", raw)
        try:
            fields = _fields(pgn, bytes(payload))
            if fields is None:
                return Rejected("decode_error", f"PGN {pgn}: the canboat decoder returned nothing", raw)
            item = _DECODERS[pgn](self, fields, source, t_s, raw)
        except Exception as error:  # a library surprise (odd value type) must not take the reader down
            return Rejected("decode_error", f"PGN {pgn}: {type(error).__name__}: {error}", raw)
        problem = None if isinstance(item, Rejected) else violation(item)
        return item if problem is None else Rejected("out_of_range", f"PGN {pgn}: {problem}", raw)

    def _position_rapid(self, f: Mapping[str, object], source: int, t_s: float, raw: bytes) -> PositionFix | Rejected:
        lat, lon = _number(f, "latitude"), _number(f, "longitude")
        if lat is None or lon is None:
            return Rejected("not_available", "129025 latitude/longitude not available", raw)
        if abs(lat) > 90.0 or abs(lon) > 180.0:
            return Rejected("out_of_range", f"129025 lat {lat} lon {lon}", raw)
        state = self._fix_state.get(source)
        if state is not None and t_s - state[0] <= self.fix_state_max_age_s:
            quality = state[1]
            if quality is None:
                return Rejected("invalid_fix", "129025 while the latest 129029 of this source has no valid fix", raw)
        else:
            quality = FixQuality.GPS
            self.counters["assumed_quality"] += 1
        return PositionFix(lat, lon, quality)

    def _gnss_position(self, f: Mapping[str, object], source: int, t_s: float, raw: bytes) -> PositionFix | Rejected:
        method, integrity = _code(f, "method"), _code(f, "integrity")
        if method not in _VALID_METHODS or integrity in _BAD_INTEGRITY:
            self._fix_state[source] = (t_s, None)
            if method not in _VALID_METHODS or integrity is None:
                why = f"method {method}"
            else:
                why = f"integrity {_BAD_INTEGRITY[integrity]}"
            return Rejected("invalid_fix", f"129029 {why}", raw)
        lat, lon = _number(f, "latitude"), _number(f, "longitude")
        if lat is None or lon is None:
            self._fix_state[source] = (t_s, None)
            return Rejected("not_available", "129029 latitude/longitude not available", raw)
        if abs(lat) > 90.0 or abs(lon) > 180.0:
            return Rejected("out_of_range", f"129029 lat {lat} lon {lon}", raw)
        quality = FixQuality(method)
        self._fix_state[source] = (t_s, quality)
        utc_time_s = _number(f, "time")
        if utc_time_s is not None and not 0.0 <= utc_time_s < 86401.0:  # 86400 allows a leap second
            utc_time_s = None
        satellites = _code(f, "numberOfSvs")
        return PositionFix(lat, lon, quality, utc_time_s=utc_time_s, num_satellites=satellites,
                           hdop=_number(f, "hdop"), altitude_m=_number(f, "altitude"))

    def _cog_sog(self, f: Mapping[str, object], _source: int, _t_s: float, raw: bytes) -> CourseOverGround | Rejected:
        cog, sog = _number(f, "cog"), _number(f, "sog")
        if _code(f, "cogReference") != 0:  # magnetic (no variation here), error or not available
            cog = None
        if cog is not None and cog >= TWO_PI + 1e-4:
            return Rejected("out_of_range", f"129026 COG {cog} rad", raw)
        if cog is None and sog is None:
            return Rejected("not_available", "129026 no true COG and no SOG", raw)
        return CourseOverGround(None if cog is None else wrap_2pi(cog), sog)

    def _vessel_heading(self, f: Mapping[str, object], source: int, t_s: float, raw: bytes) -> Heading | Rejected:
        heading = _number(f, "heading")
        if heading is None:
            return Rejected("not_available", "127250 heading not available", raw)
        if heading >= TWO_PI + 1e-4:  # one LSB of slack: 2π itself is rounded up on the wire
            return Rejected("out_of_range", f"127250 heading {heading} rad", raw)
        reference = _code(f, "reference")
        if reference == 0:
            return Heading(wrap_2pi(heading))
        if reference == 1:
            variation = _number(f, "variation")
            if variation is None:
                variation = self.bus_variation(t_s, source)
            if variation is None:
                variation = self.variation_rad
            if variation is None:
                return Rejected("magnetic_heading", "127250 magnetic heading without variation (none in the "
                                "message, no 127258 on the bus, none configured)", raw)
            deviation = _number(f, "deviation") or 0.0
            return Heading(wrap_2pi(heading + deviation + variation))
        return Rejected("not_available", f"127250 heading reference {reference}", raw)

    def _rate_of_turn(self, f: Mapping[str, object], _source: int, _t_s: float, raw: bytes) -> RateOfTurn | Rejected:
        rate = _number(f, "rate")
        if rate is None:
            return Rejected("not_available", "127251 rate not available", raw)
        return RateOfTurn(rate)

    def _attitude(self, f: Mapping[str, object], _source: int, _t_s: float, raw: bytes) -> Attitude | Rejected:
        yaw, pitch, roll = _number(f, "yaw"), _number(f, "pitch"), _number(f, "roll")
        if yaw is None and pitch is None and roll is None:
            return Rejected("not_available", "127257 yaw/pitch/roll not available", raw)
        # int16 × 1e-4 rad reaches ±3.2767: beyond ±π it is no Euler angle, and rejected (interfaces.limits),
        # not wrapped into a plausible yaw
        return Attitude(roll, pitch, yaw)

    def _wind(self, f: Mapping[str, object], _source: int, _t_s: float, raw: bytes) -> Wind | Rejected:
        reference = _WIND_REFERENCES.get(_code(f, "reference"))  # type: ignore[arg-type]
        if reference is None:
            return Rejected("unsupported_reference", f"130306 wind reference {_code(f, 'reference')}", raw)
        speed, angle = _number(f, "windSpeed"), _number(f, "windAngle")
        if speed is None or angle is None:
            return Rejected("not_available", "130306 wind speed/angle not available", raw)
        if angle >= TWO_PI + 1e-4:
            return Rejected("out_of_range", f"130306 wind angle {angle} rad", raw)
        return Wind(speed, wrap_2pi(angle), reference)


_DECODERS: Final = {
    PGN_POSITION_RAPID: N2kDecoder._position_rapid,
    PGN_GNSS_POSITION: N2kDecoder._gnss_position,
    PGN_COG_SOG_RAPID: N2kDecoder._cog_sog,
    PGN_VESSEL_HEADING: N2kDecoder._vessel_heading,
    PGN_RATE_OF_TURN: N2kDecoder._rate_of_turn,
    PGN_ATTITUDE: N2kDecoder._attitude,
    PGN_WIND: N2kDecoder._wind,
}


# --------------------------------------------------------------------------------------------
# Encoder (for the plant emulator)
# --------------------------------------------------------------------------------------------

Frame = tuple[int, bytes]
"""One CAN frame: (29-bit identifier, 1–8 data bytes)."""


class N2kEncoder:
    """Encodes typed messages into the CAN frames a NMEA 2000 sensor at ``source_address`` sends.

    Every method returns a list of frames (one for single-frame PGNs, several for 129029, which is
    split into fast-packet frames with a per-PGN 3-bit sequence id). ``None`` instead of a message
    sends the PGN with "not available" fields — what the emulator uses to exercise invalid data.

    Parameters
    ----------
    source_address : int
        The sender's NMEA 2000 address, 0–251.
    priority : mapping of int to int, optional
        Per-PGN priority overrides (defaults: :data:`DEFAULT_PRIORITY`).

    Raises
    ------
    ValueError
        From every method if a value cannot be represented (out of the PGN field's range).
    """

    def __init__(self, source_address: int, priority: Mapping[int, int] | None = None) -> None:
        if not 0 <= source_address <= 251:
            raise ValueError(f"source_address must be 0..251, got {source_address}")
        self.source_address = source_address
        self._priority = {**DEFAULT_PRIORITY, **(priority or {})}
        self._sequence: dict[int, int] = {}

    def _payload(self, pgn: int, fields: Mapping[str, object]) -> bytes:
        values = {k: v for k, v in fields.items() if v is not None}  # omitted field = not available
        try:
            return backend.DATABASE.encode(_PGN_IDS[pgn], values)
        except canboat.EncodeError as error:
            raise ValueError(f"PGN {pgn}: {error}") from error

    def _frames(self, pgn: int, payload: bytes) -> list[Frame]:
        can_id = canboat.can_id_compose(self._priority[pgn], pgn, self.source_address, BROADCAST)
        if pgn not in FAST_PACKET_PGNS:
            return [(can_id, payload)]
        seq = self._sequence.get(pgn, 0)
        self._sequence[pgn] = (seq + 1) & 0x7
        return [(can_id, bytes(chunk)) for chunk in canboat.fast_packet_fragment(seq, payload)]

    def payload(self, pgn: int, fields: Mapping[str, object]) -> bytes:
        """Low level: the payload of ``pgn`` from canboat field ids (SI units; ``None`` = not available)."""
        if pgn not in SUPPORTED_PGNS:
            raise ValueError(f"PGN {pgn} is not encoded here")
        return self._payload(pgn, fields)

    def frames(self, pgn: int, fields: Mapping[str, object]) -> list[Frame]:
        """Low level: the CAN frames of ``pgn`` from canboat field ids (see :meth:`payload`)."""
        return self._frames(pgn, self.payload(pgn, fields))

    def position_rapid(self, fix: PositionFix | None) -> list[Frame]:
        """PGN 129025 (lat/lon only, 1e-7°)."""
        return self.frames(PGN_POSITION_RAPID, {} if fix is None else
                           {"latitude": fix.lat_deg, "longitude": fix.lon_deg})

    def gnss_position(self, fix: PositionFix | None, *, date_days: int | None = None, sid: int | None = None,
                      method: int | None = None, integrity: int = 0, gnss_type: int = 0) -> list[Frame]:
        """PGN 129029 GNSS position data (fast packet).

        ``fix=None`` sends method 0 "no GNSS" with no position. ``method``/``integrity`` override
        the values derived from the fix (to emulate a receiver flagging its own fix).
        """
        if fix is None:
            fields: dict[str, object] = {"method": 0 if method is None else method, "integrity": integrity,
                                         "referenceStations": 0, "sid": sid, "date": date_days}
        else:
            fields = {"sid": sid, "date": date_days, "time": fix.utc_time_s, "latitude": fix.lat_deg,
                      "longitude": fix.lon_deg, "altitude": fix.altitude_m, "gnssType": gnss_type,
                      "method": int(fix.quality) if method is None else method, "integrity": integrity,
                      "numberOfSvs": fix.num_satellites, "hdop": fix.hdop, "referenceStations": 0}
        return self.frames(PGN_GNSS_POSITION, fields)

    def cog_sog(self, cog: CourseOverGround | None, *, sid: int | None = None) -> list[Frame]:
        """PGN 129026 (true COG reference)."""
        if cog is None:
            return self.frames(PGN_COG_SOG_RAPID, {"sid": sid})
        return self.frames(PGN_COG_SOG_RAPID, {
            "sid": sid, "cogReference": 0,
            "cog": None if cog.course_rad is None else wrap_2pi(cog.course_rad), "sog": cog.speed_mps})

    def vessel_heading(self, heading_rad: float | None, *, reference: str = "true", deviation_rad: float | None = None,
                       variation_rad: float | None = None, sid: int | None = None) -> list[Frame]:
        """PGN 127250 with an explicit reference (``"true"`` or ``"magnetic"``)."""
        if reference not in ("true", "magnetic"):
            raise ValueError(f"reference must be 'true' or 'magnetic', got {reference!r}")
        return self.frames(PGN_VESSEL_HEADING, {
            "sid": sid, "heading": None if heading_rad is None else wrap_2pi(heading_rad),
            "deviation": deviation_rad, "variation": variation_rad,
            "reference": 0 if reference == "true" else 1})

    def heading(self, heading: Heading | None, *, sid: int | None = None) -> list[Frame]:
        """PGN 127250 true heading (``None``: heading not available)."""
        return self.vessel_heading(None if heading is None else heading.heading_rad, sid=sid)

    def rate_of_turn(self, rot: RateOfTurn | None, *, sid: int | None = None) -> list[Frame]:
        """PGN 127251."""
        return self.frames(PGN_RATE_OF_TURN, {"sid": sid, "rate": None if rot is None else rot.rate_radps})

    def attitude(self, attitude: Attitude | None, *, sid: int | None = None) -> list[Frame]:
        """PGN 127257 (yaw sent wrapped to (−π, π])."""
        if attitude is None:
            return self.frames(PGN_ATTITUDE, {"sid": sid})
        return self.frames(PGN_ATTITUDE, {
            "sid": sid, "yaw": None if attitude.yaw_rad is None else ssa(attitude.yaw_rad),
            "pitch": attitude.pitch_rad, "roll": attitude.roll_rad})

    def wind(self, wind: Wind | None, *, sid: int | None = None) -> list[Frame]:
        """PGN 130306 (reference ``"true"`` = ground referenced to north, or ``"apparent"``)."""
        if wind is None:
            return self.frames(PGN_WIND, {"sid": sid, "reference": _WIND_CODES["apparent"]})
        if wind.reference not in _WIND_CODES:
            raise ValueError(f"wind reference must be one of {sorted(_WIND_CODES)}, got {wind.reference!r}")
        return self.frames(PGN_WIND, {"sid": sid, "windSpeed": wind.speed_mps, "windAngle": wrap_2pi(wind.angle_rad),
                                      "reference": _WIND_CODES[wind.reference]})

    def encode(self, message: SensorMessage) -> list[Frame]:
        """Encode any supported message with its natural PGN (a PositionFix as 129029).

        Raises
        ------
        TypeError
            For a message type NMEA 2000 does not carry here (e.g. LinkHeartbeat).
        """
        encoder = _ENCODERS.get(type(message))
        if encoder is None:
            raise TypeError(f"no NMEA 2000 encoding for {type(message).__name__}")
        return encoder(self, message)


_ENCODERS: Final[dict[type, Callable[[N2kEncoder, Any], list[Frame]]]] = {
    PositionFix: N2kEncoder.gnss_position,
    CourseOverGround: N2kEncoder.cog_sog,
    Heading: N2kEncoder.heading,
    RateOfTurn: N2kEncoder.rate_of_turn,
    Attitude: N2kEncoder.attitude,
    Wind: N2kEncoder.wind,
}
