"""Malformed input for the ``malformed_burst`` fault: what a flaky cable, a noisy bus or a confused
sensor puts on each link (pure: bytes and frames in, bytes and frames out, a seeded generator).

Each generator returns ``count`` items built from the target sensor's own valid output (its latest
sentences, frames or packets), so the rubbish looks like that sensor gone wrong, and every item is
something the receiving codec must reject — never a silently wrong value:

* NMEA 0183 (one item = one line ending in CR LF): a sentence with a wrong checksum, a run of
  binary garbage, a sentence truncated before its checksum. Each is exactly one rejected frame of
  :class:`interfaces.nmea0183.Nmea0183Decoder` (``checksum``, ``garbage``, ``no_checksum`` or
  ``malformed``), and never swallows the sentence that follows.
* NMEA 2000 (one item = one message's worth of CAN frames): a fast packet with its last frame
  missing (``truncated_fast_packet`` once the receiver gives up on it), a fast-packet first frame
  announcing more than 223 bytes (``bad_fast_packet``), a single-frame PGN cut short (``truncated``).
* MAVLink (one item = one UDP datagram): a packet with a payload byte flipped (CRC ``checksum``),
  a packet cut short (``truncated``), a datagram of bytes without a packet start (``garbage``).

The kinds take turns (item ``i`` is kind ``i mod 3``), so any count ≥ 3 exercises all of them.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from interfaces.nmea2000.codec import (
    MAX_FAST_PACKET_BYTES,
    MIN_PAYLOAD_BYTES,
    PGN_GNSS_POSITION,
    PGN_POSITION_RAPID,
    PGN_RATE_OF_TURN,
    PGN_VESSEL_HEADING,
    make_can_id,
)
from sim_plant.faults import Fault

Frame = tuple[int, bytes]

NMEA_KINDS: tuple[str, ...] = ("checksum", "garbage", "truncated")
N2K_KINDS: tuple[str, ...] = ("truncated_fast_packet", "bad_fast_packet", "truncated")
MAVLINK_KINDS: tuple[str, ...] = ("checksum", "truncated", "garbage")

# NMEA 0183: bytes that would start or end a sentence are kept out of the garbage runs
_NMEA_GARBAGE = np.array([b for b in range(256) if b not in b"$!\r\n"], dtype=np.uint8)
# MAVLink: no packet start markers (0xFD v2, 0xFE v1) in a garbage datagram
_MAV_GARBAGE = np.array([b for b in range(256) if b not in (0xFD, 0xFE)], dtype=np.uint8)
_MAV2_HEADER_BYTES = 10


def _pick(rng: np.random.Generator, templates: Sequence[bytes], what: str) -> bytes:
    if not templates:
        raise ValueError(f"no {what} to build malformed input from")
    return templates[int(rng.integers(len(templates)))]


def nmea0183_burst(templates: Sequence[bytes], count: int, rng: np.random.Generator) -> list[bytes]:
    """``count`` malformed lines built from valid ``templates`` (``$...*hh\\r\\n`` sentences).

    Raises
    ------
    ValueError
        ``count`` < 0, no templates, or a template that is not a checksummed sentence.
    """
    if count < 0:
        raise ValueError("count must be >= 0")
    out: list[bytes] = []
    for i in range(count):
        kind = NMEA_KINDS[i % 3]
        if kind == "garbage":
            n = int(rng.integers(8, 41))
            out.append(rng.choice(_NMEA_GARBAGE, n).tobytes() + b"\r\n")
            continue
        sentence = _pick(rng, templates, "NMEA 0183 sentences").rstrip(b"\r\n")
        star = sentence.rfind(b"*")
        if not sentence.startswith((b"$", b"!")) or star < 0 or len(sentence) - star != 3:
            raise ValueError(f"template {sentence!r} is not a checksummed NMEA 0183 sentence")
        if kind == "checksum":
            wrong = int(sentence[star + 1:], 16) ^ int(rng.integers(1, 256))  # nonzero XOR: always different
            out.append(sentence[:star + 1] + b"%02X" % wrong + b"\r\n")
        else:  # cut somewhere after the address, before the checksum field
            cut = int(rng.integers(min(7, star), star))
            out.append(sentence[:cut] + b"\r\n")
    return out


def n2k_burst(kind: str, source_address: int, count: int, rng: np.random.Generator,
              fast_packets: Sequence[Sequence[Frame]] = ()) -> list[list[Frame]]:
    """``count`` malformed NMEA 2000 messages from ``source_address``.

    Parameters
    ----------
    kind : {"position", "heading", "rate_of_turn"}
        A GNSS (fast packets of 129029, single frames of 129025), a gyrocompass (127250, 127251) or a
        rate-of-turn sensor (127251).
    source_address : int
        The sensor's address (0–251).
    count : int
    rng : numpy.random.Generator
    fast_packets : sequence of sequence of Frame
        For a GNSS: freshly encoded 129029 messages of that sensor (each with its own fast-packet
        sequence id), one per truncated item, i.e. ``ceil(count / 3)``; their last frame is left
        out. When they run out, a first frame announcing a bad length is sent instead. Ignored for
        a gyro, whose items are all cut-short single frames.

    Returns
    -------
    list of list of Frame
        One list of ``(can_id, data)`` frames per item.
    """
    if count < 0:
        raise ValueError("count must be >= 0")
    if kind not in ("position", "heading", "rate_of_turn"):
        raise ValueError(f"kind must be 'position', 'heading' or 'rate_of_turn', got {kind!r}")
    whole = [list(m) for m in fast_packets if len(m) > 1] if kind == "position" else []
    out: list[list[Frame]] = []
    for i in range(count):
        item = N2K_KINDS[i % 3] if kind == "position" else "truncated"
        if item == "truncated_fast_packet" and whole:
            out.append(whole.pop(0)[:-1])
        elif item in ("truncated_fast_packet", "bad_fast_packet"):
            data = bytes([int(rng.integers(8)) << 5, int(rng.integers(MAX_FAST_PACKET_BYTES + 1, 256))]) + rng.bytes(6)
            out.append([(make_can_id(3, PGN_GNSS_POSITION, source_address), data)])
        else:
            pgn = PGN_POSITION_RAPID if kind == "position" else PGN_RATE_OF_TURN if kind == "rate_of_turn" \
                else (PGN_VESSEL_HEADING, PGN_RATE_OF_TURN)[i % 2]
            n = int(rng.integers(1, MIN_PAYLOAD_BYTES[pgn]))
            out.append([(make_can_id(2, pgn, source_address), rng.bytes(n))])
    return out


def mavlink_burst(packets: Sequence[bytes], count: int, rng: np.random.Generator) -> list[bytes]:
    """``count`` malformed datagrams built from valid MAVLink 2 ``packets`` of the sensor.

    Raises
    ------
    ValueError
        ``count`` < 0, no packets, or a packet that is not MAVLink 2 with a payload.
    """
    if count < 0:
        raise ValueError("count must be >= 0")
    out: list[bytes] = []
    for i in range(count):
        kind = MAVLINK_KINDS[i % 3]
        if kind == "garbage":
            out.append(rng.choice(_MAV_GARBAGE, int(rng.integers(4, 33))).tobytes())
            continue
        packet = bytearray(_pick(rng, packets, "MAVLink packets"))
        if len(packet) < _MAV2_HEADER_BYTES + 3 or packet[0] != 0xFD or packet[1] == 0:
            raise ValueError("template is not a MAVLink 2 packet with a payload")
        if kind == "checksum":
            index = _MAV2_HEADER_BYTES + int(rng.integers(packet[1]))
            packet[index] ^= int(rng.integers(1, 256))  # CRC-16/MCRF4XX catches every single-byte error
            out.append(bytes(packet))
        else:
            out.append(bytes(packet[:int(rng.integers(3, len(packet) - 1))]))
    return out


@dataclass(frozen=True)
class ProtocolFaultAction:
    """One protocol-fault action on the emulator's or the lockstep's schedule."""

    t_s: float
    order: int  # 0: before the samples of the step (unplug, replug, silence), 1: after them (bursts)
    fault: Fault
    action: str  # "burst" | "unplug" | "replug" | "silence"
    index: int  # the fault's index in the scenario (seeds its random stream)


def protocol_fault_actions(faults: Sequence[Fault]) -> list[ProtocolFaultAction]:
    """The schedule of the scenario's protocol faults (``malformed_burst``, ``serial_unplug`` with its
    replug, ``heartbeat_loss``), by time, then order, then scenario index — the one schedule the
    real-time emulator and the lockstep simulation both carry out."""
    actions: list[ProtocolFaultAction] = []
    for index, fault in enumerate(faults):
        if fault.kind == "malformed_burst":
            actions.append(ProtocolFaultAction(fault.t_s, 1, fault, "burst", index))
        elif fault.kind == "serial_unplug":
            actions.append(ProtocolFaultAction(fault.t_s, 0, fault, "unplug", index))
            if math.isfinite(fault.end_s):
                actions.append(ProtocolFaultAction(fault.end_s, 0, fault, "replug", index))
        elif fault.kind == "heartbeat_loss":
            actions.append(ProtocolFaultAction(fault.t_s, 0, fault, "silence", index))
    return sorted(actions, key=lambda a: (a.t_s, a.order, a.index))
