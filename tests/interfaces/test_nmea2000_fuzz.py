"""Fuzzing the NMEA 2000 decoder: 10⁵ random and mutated frames, nothing escapes, everything is counted."""

from __future__ import annotations

import math

import numpy as np
from physical_range import out_of_range

from interfaces.messages import (
    Attitude,
    CourseOverGround,
    FixQuality,
    Heading,
    PositionFix,
    RateOfTurn,
    Rejected,
    Wind,
)
from interfaces.nmea2000.codec import SUPPORTED_PGNS, N2kDecoder, N2kEncoder, make_can_id

N_RANDOM = 40_000
N_MUTATED = 70_000


def _valid_frames(rng: np.random.Generator) -> list[tuple[int, bytes]]:
    """A pool of well-formed frames of every PGN we decode (129029 as its 7 fast-packet frames)."""
    frames: list[tuple[int, bytes]] = []
    for address in (0, 17, 128):
        encoder = N2kEncoder(address)
        for _ in range(20):
            fix = PositionFix(float(rng.uniform(-90, 90)), float(rng.uniform(-180, 180)), FixQuality.RTK_FLOAT,
                              utc_time_s=float(rng.uniform(0, 86400)), num_satellites=9, hdop=0.9, altitude_m=3.0)
            frames += encoder.position_rapid(fix) + encoder.gnss_position(fix, date_days=19000)
            frames += encoder.cog_sog(CourseOverGround(float(rng.uniform(0, 6.28)), float(rng.uniform(0, 20))))
            frames += encoder.heading(Heading(float(rng.uniform(0, 6.28))))
            frames += encoder.rate_of_turn(RateOfTurn(float(rng.normal(0, 0.1))))
            frames += encoder.attitude(Attitude(0.01, -0.02, float(rng.uniform(-3, 3))))
            frames += encoder.wind(Wind(float(rng.uniform(0, 30)), float(rng.uniform(0, 6.28)), "apparent"))
    return frames


def _mutate(rng: np.random.Generator, can_id: int, data: bytes) -> tuple[object, object]:
    kind = int(rng.integers(0, 8))
    buf = bytearray(data)
    if kind == 0 and buf:  # flip one to three bits of the data
        for _ in range(int(rng.integers(1, 4))):
            i = int(rng.integers(0, len(buf)))
            buf[i] ^= 1 << int(rng.integers(0, 8))
    elif kind == 1:  # truncate
        del buf[int(rng.integers(0, len(buf) + 1)):]
    elif kind == 2:  # flip an identifier bit (other PGN, source, priority)
        can_id ^= 1 << int(rng.integers(0, 29))
    elif kind == 3 and buf:  # overwrite a field with a sentinel (not available / error / reserved)
        i = int(rng.integers(0, len(buf)))
        buf[i:i + 2] = bytes([0xFF, 0x7F]) if rng.random() < 0.5 else bytes([0xFE, 0xFF])
        del buf[8:]
    elif kind == 4 and buf:  # random bytes in place
        buf[:] = rng.integers(0, 256, len(buf), dtype=np.uint8).tobytes()
    elif kind == 5:  # too long for classic CAN, or not bytes at all
        return can_id, (bytes(buf) + b"\x00" * 9) if rng.random() < 0.5 else "not bytes"
    elif kind == 6:  # identifier out of 29 bits or of the wrong type
        return (can_id | (1 << 29)) if rng.random() < 0.5 else float(can_id), bytes(buf)
    # kind 7 (and empty data for the others): the frame unchanged — duplicates and reorderings
    return can_id, bytes(buf)


def _mutated_sequence(rng: np.random.Generator, encoder: N2kEncoder) -> list[tuple[object, object]]:
    """A whole 129029 fast-packet sequence with one sequence-level fault (or none)."""
    fix = PositionFix(float(rng.uniform(-90, 90)), float(rng.uniform(-180, 180)), FixQuality.GPS, utc_time_s=5.0)
    frames: list[tuple[object, object]] = list(encoder.gnss_position(fix))
    kind = int(rng.integers(0, 6))
    if kind == 0:  # a lost frame
        del frames[int(rng.integers(0, len(frames)))]
    elif kind == 1:  # two frames swapped
        i, j = rng.choice(len(frames), 2, replace=False)
        frames[i], frames[j] = frames[j], frames[i]
    elif kind == 2:  # a frame repeated
        i = int(rng.integers(0, len(frames)))
        frames.insert(i, frames[i])
    elif kind == 3:  # one frame damaged
        i = int(rng.integers(0, len(frames)))
        frames[i] = _mutate(rng, *frames[i])  # type: ignore[arg-type]
    return frames  # kinds 4, 5: intact


def _assert_clean(item: object) -> None:
    """A decoded message holds no NaN/inf and nothing outside its physical range."""
    assert out_of_range(item) == [], item
    if isinstance(item, Heading):
        assert 0.0 <= item.heading_rad < 2 * math.pi
    if isinstance(item, Wind):
        assert 0.0 <= item.angle_rad < 2 * math.pi


def test_fuzzed_frames_never_raise_and_every_reject_is_counted() -> None:
    rng = np.random.default_rng(20240611)
    pool = _valid_frames(rng)
    supported = np.array(sorted(SUPPORTED_PGNS))
    decoder = N2kDecoder(max_partial=32)
    n_messages = n_rejects = 0
    reasons: dict[str, int] = {}
    t_s = 0.0
    n_frames = N_RANDOM + N_MUTATED
    senders = [N2kEncoder(address) for address in (3, 4, 5)]
    queue: list[tuple[object, object]] = []
    for k in range(n_frames):
        t_s += 0.001
        if k < N_RANDOM:
            if rng.random() < 0.7:  # aim at the PGNs we decode so the field decoders are exercised
                can_id: object = make_can_id(int(rng.integers(0, 8)), int(rng.choice(supported)),
                                             int(rng.integers(0, 256)))
            else:
                can_id = int(rng.integers(0, 1 << 29))
            data: object = rng.integers(0, 256, int(rng.integers(0, 9)), dtype=np.uint8).tobytes()
        else:
            if not queue:
                if rng.random() < 0.5:  # whole fast-packet sequences from three sources, faulty or not
                    queue = _mutated_sequence(rng, senders[int(rng.integers(0, 3))])
                else:
                    queue = [_mutate(rng, *pool[int(rng.integers(0, len(pool)))])]
            can_id, data = queue.pop(0)
        for result in decoder.decode_frame(can_id, data, t_s):  # type: ignore[arg-type]
            if isinstance(result.item, Rejected):
                n_rejects += 1
                reasons[result.item.reason] = reasons.get(result.item.reason, 0) + 1
                assert len(result.item.raw) <= 64
            else:
                n_messages += 1
                _assert_clean(result.item)
    for result in decoder.expire(math.inf):
        n_rejects += 1
        reasons[result.item.reason] = reasons.get(result.item.reason, 0) + 1

    c = decoder.counters
    assert c["frames"] == n_frames >= 100_000
    assert c["frames"] == c["ignored"] + c["bad_frame"] + c["single_frames"] + c["fast_packet_frames"]
    assert c["messages"] == n_messages and c["rejected"] == n_rejects
    assert all(c["rejected." + reason] == count for reason, count in reasons.items())
    assert sum(v for k, v in c.items() if k.startswith("rejected.")) == n_rejects
    assert n_messages + n_rejects == (c["single_frames"] + c["fast_packet_messages"] + c["bad_frame"]
                                      + c["rejected.truncated_fast_packet"] + c["rejected.bad_fast_packet"])
    assert decoder.assembler.pending == 0
    # the fuzz reached every path that matters
    for reason in ("not_available", "truncated", "bad_frame", "truncated_fast_packet", "bad_fast_packet",
                   "out_of_range", "invalid_fix"):
        assert reasons.get(reason, 0) > 0, reason
    # decoded to values: a message, or values outside their physical limits (random payloads reach them often)
    assert c["fast_packet_messages"] > 100 and n_messages + reasons["out_of_range"] > 10_000
