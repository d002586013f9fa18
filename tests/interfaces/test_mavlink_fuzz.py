"""Fuzzing the MAVLink decoder: 10⁵ random and mutated datagrams, nothing escapes, everything is counted."""

from __future__ import annotations

import math

import numpy as np
from physical_range import out_of_range

from interfaces.mavlink.codec import MavlinkDecoder, MavlinkEncoder
from interfaces.messages import (
    Attitude,
    CourseOverGround,
    FixQuality,
    Heading,
    PositionFix,
    RateOfTurn,
    Rejected,
)

N_RANDOM = 30_000
N_MUTATED = 70_000
KEY = bytes(range(100, 132))
NOW_S = 1_750_000_000.0
REASONS = {"garbage", "truncated", "checksum", "bad_packet", "unsigned", "bad_signature", "invalid_fix",
           "not_available", "out_of_range", "decode_error"}


def _pool(rng: np.random.Generator) -> list[bytes]:
    """Well-formed packets of every message we decode, unsigned and signed."""
    packets = []
    for encoder in (MavlinkEncoder(1, 1), MavlinkEncoder(2, 1, signing_key=KEY, unix_clock=lambda: NOW_S)):
        for _ in range(30):
            fix = PositionFix(float(rng.uniform(-90, 90)), float(rng.uniform(-180, 180)), FixQuality.RTK_FIXED,
                              utc_time_s=float(rng.uniform(0, 86400)), num_satellites=12, hdop=0.7, altitude_m=5.0)
            packets += [encoder.heartbeat(),
                        encoder.gps_raw_int(fix, course=CourseOverGround(1.0, 2.0), heading=Heading(0.3)),
                        encoder.global_position_int(fix, heading=Heading(2.0), velocity_ned_mps=(1.0, -1.0, 0.0)),
                        encoder.attitude(Attitude(0.01, -0.01, float(rng.uniform(-3, 3))), rate=RateOfTurn(0.01))]
    return packets


def _mutate(rng: np.random.Generator, pool: list[bytes]) -> bytes:
    packet = bytearray(pool[int(rng.integers(0, len(pool)))])
    kind = int(rng.integers(0, 7))
    if kind == 0:  # bit flips anywhere (header, payload, CRC, signature)
        for _ in range(int(rng.integers(1, 4))):
            i = int(rng.integers(0, len(packet)))
            packet[i] ^= 1 << int(rng.integers(0, 8))
    elif kind == 1:  # truncation
        del packet[int(rng.integers(0, len(packet))):]
    elif kind == 2:  # several packets in one datagram, with junk between
        junk = rng.integers(0, 256, int(rng.integers(0, 6)), dtype=np.uint8).tobytes()
        packet += junk + pool[int(rng.integers(0, len(pool)))]
    elif kind == 3:  # length byte lies
        packet[1] = int(rng.integers(0, 256))
    elif kind == 4:  # incompatibility flags (unknown flags, or "signed" without a signature)
        packet[2] = int(rng.integers(0, 256))
    elif kind == 5:  # random payload bytes with the header kept
        packet[10:] = rng.integers(0, 256, len(packet) - 10, dtype=np.uint8).tobytes()
    # kind 6: intact (replays of signed packets, duplicates)
    return bytes(packet)


def _assert_clean(item: object) -> None:
    """A decoded message holds no NaN/inf and nothing outside its physical range (physical_range)."""
    assert out_of_range(item) == [], item
    if isinstance(item, Heading):
        assert 0.0 <= item.heading_rad < 2 * math.pi


def test_fuzzed_datagrams_never_raise_and_every_reject_is_counted() -> None:
    rng = np.random.default_rng(77)
    pool = _pool(rng)
    decoders = [MavlinkDecoder(), MavlinkDecoder(KEY, signing_time_s=NOW_S)]
    # pool packets are replays for the signing decoder after their first use: also send fresh ones
    live = MavlinkEncoder(3, 1, signing_key=KEY, unix_clock=lambda: NOW_S)
    live_fix = PositionFix(1.0, 2.0, FixQuality.DGPS, utc_time_s=10.0)
    totals = [{"messages": 0, "rejected": 0, "reasons": {}} for _ in decoders]
    for k in range(N_RANDOM + N_MUTATED):
        if k < N_RANDOM:
            data = rng.integers(0, 256, int(rng.integers(0, 80)), dtype=np.uint8).tobytes()
            if rng.random() < 0.3:  # make the parser take the packet path, not just skip junk
                data = bytes([0xFD]) + data
        elif k & 1 and rng.random() < 0.5:
            data = _mutate(rng, [live.gps_raw_int(live_fix)])
        else:
            data = _mutate(rng, pool)
        which = k & 1
        decoder, total = decoders[which], totals[which]
        ignored_before = decoder.counters["ignored"]
        results = decoder.decode_datagram(data)
        assert results or not data or decoder.counters["ignored"] > ignored_before, data.hex()
        for result in results:
            if isinstance(result.item, Rejected):
                total["rejected"] += 1
                total["reasons"][result.item.reason] = total["reasons"].get(result.item.reason, 0) + 1
                assert len(result.item.raw) <= 64
            else:
                total["messages"] += 1
                _assert_clean(result.item)
    for decoder, total in zip(decoders, totals, strict=True):
        c = decoder.counters
        assert c["messages"] == total["messages"] > 1000 and c["rejected"] == total["rejected"]
        assert set(total["reasons"]) <= REASONS
        assert all(c["rejected." + reason] == n for reason, n in total["reasons"].items())
    assert {"garbage", "truncated", "checksum"} <= set(totals[0]["reasons"])
    assert {"unsigned", "bad_signature"} <= set(totals[1]["reasons"])
