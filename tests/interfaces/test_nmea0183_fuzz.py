"""Fuzzing the NMEA 0183 stream decoder: 10⁵ random and mutated inputs, seeded, a few seconds.

Mutations of valid sentences: bit flips, truncation, insertion of random bytes, pure random bytes,
merged sentences (CR LF lost), over-long lines with a correct checksum, a field replaced by a
hostile token with a correct checksum (so the value checks, not the checksum, must catch it),
missing checksums, and unmodified sentences. Every input is followed by CR LF so each one's
frames can be told apart in one long-lived decoder (the stream state carries over inputs).
Checked: no exception escapes; every input that is not blank yields at least one frame; every
decoded value is finite and within physical limits (``physical_range``); the counters add up
(frames = ok + ignored + rejected, rejected = Σ per reason); unmodified sentences decode as they
do on their own; the buffer stays bounded.
"""

from __future__ import annotations

import math
from collections import Counter

import numpy as np
from physical_range import out_of_range

from interfaces.messages import (
    CourseOverGround,
    FixQuality,
    Heading,
    PositionErrorStats,
    PositionFix,
    RateOfTurn,
    Wind,
)
from interfaces.nmea0183 import (
    DEFAULT_MAX_SENTENCE_CHARS,
    REJECT_REASONS,
    Nmea0183Decoder,
    encode_gga,
    encode_gga_no_fix,
    encode_gns,
    encode_gst,
    encode_hdt,
    encode_mwv,
    encode_rmc,
    encode_rot,
    encode_ths,
)

N_INPUTS = 100_000
HOSTILE_TOKENS = ["", "nan", "inf", "-inf", "1e9", "-1", "999999", "A", "V", "N", "S", "M", "00", "0", "60.0",
                  "9000.000", "18100.0", "-0", "+5", ".", "1_0", "*", ",", "$", "0x1F", "361", "25", "-360"]


def nmea(body: bytes) -> bytes:
    checksum = 0
    for byte in body:
        checksum ^= byte
    return b"$" + body + b"*%02X\r\n" % checksum


def base_sentences(rng: np.random.Generator, count: int) -> list[bytes]:
    """Valid sentences of every decoded type, with random values, as the emulator sends them."""
    out = []
    qualities = [FixQuality.GPS, FixQuality.DGPS, FixQuality.RTK_FIXED, FixQuality.RTK_FLOAT]
    for _ in range(count):
        fix = PositionFix(float(rng.uniform(-90, 90)), float(rng.uniform(-180, 180)),
                          qualities[int(rng.integers(len(qualities)))], float(rng.uniform(0, 86399)),
                          int(rng.integers(4, 30)), float(rng.uniform(0.5, 5)), float(rng.uniform(-50, 500)))
        heading = Heading(float(rng.uniform(0, 2 * math.pi)))
        out += [
            encode_gga(fix), encode_rmc(fix, CourseOverGround(float(rng.uniform(0, 6)), float(rng.uniform(0, 10)))),
            encode_gns(fix), encode_hdt(heading), encode_ths(heading),
            encode_rot(RateOfTurn(float(rng.uniform(-0.1, 0.1)))),
            encode_gst(PositionErrorStats(*rng.uniform(0.01, 3, 4).tolist(), 1000.0, 0.4, 0.2, 0.5)),
            encode_mwv(Wind(float(rng.uniform(0, 30)), float(rng.uniform(0, 6)), "apparent")),
            encode_gga_no_fix(utc_time_s=5.0),
            b"$GPGSV,3,1,11,01,78,221,47,03,09,042,00,04,05,242,00,06,04,149,00*70\r\n",
        ]
    return out


def mutate(rng: np.random.Generator, sentence: bytes, other: bytes) -> tuple[str, bytes]:
    kind = int(rng.integers(9))
    data = bytearray(sentence)
    if kind == 0:  # bit flips
        for _ in range(int(rng.integers(1, 4))):
            position = int(rng.integers(len(data)))
            data[position] ^= 1 << int(rng.integers(8))
        return "bitflip", bytes(data)
    if kind == 1:  # truncated
        return "truncated", bytes(data[: int(rng.integers(1, len(data)))])
    if kind == 2:  # random bytes inserted
        position = int(rng.integers(len(data)))
        return "inserted", bytes(data[:position]) + rng.bytes(int(rng.integers(1, 12))) + bytes(data[position:])
    if kind == 3:  # random bytes only
        return "random", rng.bytes(int(rng.integers(1, 300)))
    if kind == 4:  # merged: CR LF lost (and maybe cut short) before the next sentence
        return "merged", bytes(data[: int(rng.integers(10, len(data) - 1))]) + other
    if kind == 5:  # over-long with a correct checksum
        body = bytes(data[1: data.rindex(b"*")]) + b",123.4567" * int(rng.integers(2, 30))
        return "overlong", nmea(body)
    if kind == 6:  # a field replaced by a hostile token, correct checksum: value checks must catch it
        fields = bytes(data[1: data.rindex(b"*")]).split(b",")
        fields[int(rng.integers(1, len(fields)))] = HOSTILE_TOKENS[int(rng.integers(len(HOSTILE_TOKENS)))].encode()
        return "field", nmea(b",".join(fields))
    if kind == 7:  # checksum removed
        return "no_checksum", bytes(data[: data.rindex(b"*")]) + b"\r\n"
    return "valid", sentence


def test_fuzzed_stream_never_raises_and_every_input_is_accounted_for() -> None:
    rng = np.random.default_rng(20240623)
    bases = base_sentences(rng, 60)
    alone = {sentence: Nmea0183Decoder().feed_frames(sentence) for sentence in bases}
    assert all(frames[0].messages for sentence, frames in alone.items() if sentence[3:6] in (b"RMC", b"HDT", b"ROT"))
    decoder = Nmea0183Decoder()
    kinds: Counter[str] = Counter()
    outcomes: Counter[str] = Counter()
    frames_total = 0
    for _ in range(N_INPUTS):
        sentence = bases[int(rng.integers(len(bases)))]
        kind, data = mutate(rng, sentence, bases[int(rng.integers(len(bases)))])
        kinds[kind] += 1
        before = decoder.counters["frames"]
        frames = decoder.feed_frames(data + b"\r\n")
        frames_total += len(frames)
        assert decoder.counters["frames"] - before == len(frames)
        assert decoder.buffered_bytes <= DEFAULT_MAX_SENTENCE_CHARS
        if data.strip(b"\r\n"):
            assert frames, (kind, data)
        if kind == "valid":  # whatever came before, a clean sentence after CR LF decodes as on its own
            assert frames == alone[sentence], data
        for frame in frames:
            outcomes[frame.rejected.reason if frame.rejected else ("ok" if frame.messages else "ignored")] += 1
            for message in frame.messages:  # finite, and within physical limits
                assert out_of_range(message) == [], (message, data)
    frames_total += len(decoder.flush())
    counters = decoder.counters
    assert sum(kinds.values()) == N_INPUTS
    assert counters["frames"] == frames_total == counters["ok"] + counters["ignored"] + counters["rejected"]
    assert counters["rejected"] == sum(counters[f"rejected.{reason}"] for reason in REJECT_REASONS)
    for reason in REJECT_REASONS:
        assert outcomes[reason] == counters[f"rejected.{reason}"]
    # every class of damage was produced and caught by its own check
    for reason in ("garbage", "merged", "too_long", "malformed", "no_checksum", "checksum", "bad_field", "no_data",
                   "invalid_fix"):
        assert counters[f"rejected.{reason}"] > 0, reason
