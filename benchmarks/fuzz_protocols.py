"""Fuzz every protocol decoder with mutated inputs and print what became of them.

For each protocol, ``--inputs`` (default 10⁵) inputs built from valid traffic (what the plant emulator's
encoders send, with random values) and mutated: bit flips, truncation, inserted and random bytes, and
— with the framing kept valid (NMEA checksum, MAVLink CRC, CAN frame) — fields replaced by values drawn
over their whole wire type (huge, negative, NaN, ±inf, "not available" sentinels), so the value checks,
not the framing checks, are what is exercised. Printed per protocol: inputs, decoded messages,
rejects per reason, *escapes* (an exception out of the decoder) and *out of range* (a decoded value
non-finite or outside the physical limits of ``tests/physical_range.py``, the test suite's own
statement of them). Both must be zero.

    python benchmarks/fuzz_protocols.py [--inputs 100000] [--seed 1]

Exit status 1 when an escape or an out-of-range value was found.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from collections import Counter
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from physical_range import out_of_range  # the tests' own statement of the limits

from interfaces.mavlink.codec import MavlinkDecoder, MavlinkEncoder
from interfaces.messages import (
    Attitude,
    CourseOverGround,
    FixQuality,
    Heading,
    PositionErrorStats,
    PositionFix,
    RateOfTurn,
    Rejected,
    Wind,
)
from interfaces.nmea0183 import (
    Nmea0183Decoder,
    encode_gga,
    encode_gns,
    encode_gst,
    encode_hdt,
    encode_mwv,
    encode_rmc,
    encode_rot,
    encode_ths,
)
from interfaces.nmea2000.codec import SUPPORTED_PGNS, N2kDecoder, N2kEncoder, make_can_id

HOSTILE_NUMBERS = ["1" + "0" * 56, "-1" + "0" * 40, "240000", "-3", "9000000000000.0", "655.35", "1273.9", "10801",
                   "99999999", "-99999.999", "361", "360", "-0.5", "100", "0", "", "nan", "inf"]


class Tally:
    """What became of the inputs of one protocol."""

    def __init__(self) -> None:
        self.inputs = 0
        self.messages = 0
        self.reasons: Counter[str] = Counter()
        self.escapes: list[str] = []
        self.out_of_range: list[str] = []

    def items(self, items: list[object]) -> None:
        for item in items:
            if isinstance(item, Rejected):
                self.reasons[item.reason] += 1
            else:
                self.messages += 1
                problems = out_of_range(item)
                if problems:
                    self.out_of_range.append(f"{item!r}: {problems}")

    def run(self, inputs: Iterator[object], decode: Callable[[object], list[object]]) -> None:
        for data in inputs:
            self.inputs += 1
            try:
                self.items(decode(data))
            except Exception as error:  # an escape: reported, the fuzz goes on
                self.escapes.append(f"{type(error).__name__}: {error} on {data!r:.200}")


def _flip(rng: np.random.Generator, data: bytes) -> bytes:
    out = bytearray(data)
    for _ in range(int(rng.integers(1, 4))):
        i = int(rng.integers(len(out)))
        out[i] ^= 1 << int(rng.integers(8))
    return bytes(out)


def _generic(rng: np.random.Generator, data: bytes) -> bytes | None:
    """A framing mutation (bit flips, truncation, insertion, random bytes), or None for the protocol's own."""
    kind = int(rng.integers(6))
    if kind == 0:
        return _flip(rng, data)
    if kind == 1:
        return data[: int(rng.integers(len(data)))]
    if kind == 2:
        i = int(rng.integers(len(data)))
        return data[:i] + rng.bytes(int(rng.integers(1, 12))) + data[i:]
    if kind == 3:
        return rng.bytes(int(rng.integers(1, 100)))
    return None


# ----------------------------------------------------------------------------------------------
# NMEA 0183


def _nmea(body: bytes) -> bytes:
    checksum = 0
    for byte in body:
        checksum ^= byte
    return b"$" + body + b"*%02X\r\n" % checksum


def nmea0183_inputs(rng: np.random.Generator, count: int) -> Iterator[bytes]:
    bases = []
    for _ in range(50):
        fix = PositionFix(float(rng.uniform(-90, 90)), float(rng.uniform(-180, 180)), FixQuality.RTK_FIXED,
                          float(rng.uniform(0, 86399)), 12, 0.7, float(rng.uniform(-50, 500)))
        heading = Heading(float(rng.uniform(0, 2 * math.pi)))
        bases += [encode_gga(fix), encode_rmc(fix, CourseOverGround(1.0, 2.0)), encode_gns(fix), encode_hdt(heading),
                  encode_ths(heading), encode_rot(RateOfTurn(0.01)),
                  encode_gst(PositionErrorStats(0.1, 0.2, 0.3, 0.4, 10.0, 0.4, 0.2, 0.5)),
                  encode_mwv(Wind(5.0, 1.0, "apparent")), _nmea(b"GPGLL,5957.0062,N,01100.6429,E,120000.00,A,D")]
    for _ in range(count):
        base = bases[int(rng.integers(len(bases)))]
        mutated = _generic(rng, base)
        if mutated is None:  # a field replaced by a hostile number, checksum recomputed
            fields = base[1: base.rindex(b"*")].split(b",")
            hostile = HOSTILE_NUMBERS[int(rng.integers(len(HOSTILE_NUMBERS)))]
            fields[int(rng.integers(1, len(fields)))] = hostile.encode()
            mutated = _nmea(b",".join(fields))
        yield mutated + b"\r\n"


# ----------------------------------------------------------------------------------------------
# NMEA 2000


def nmea2000_inputs(rng: np.random.Generator, count: int) -> Iterator[list[tuple[int, bytes]]]:
    encoder = N2kEncoder(17)
    fix = PositionFix(59.9, 10.7, FixQuality.RTK_FIXED, 43200.0, 12, 0.7, 5.0)
    messages = [encoder.position_rapid(fix), encoder.gnss_position(fix), encoder.cog_sog(CourseOverGround(1.0, 2.0)),
                encoder.heading(Heading(1.0)), encoder.vessel_heading(1.0, reference="magnetic", variation_rad=0.1),
                encoder.rate_of_turn(RateOfTurn(0.01)), encoder.attitude(Attitude(0.01, 0.02, 0.5)),
                encoder.wind(Wind(5.0, 1.0, "apparent"))]
    pgns = sorted(SUPPORTED_PGNS)
    for _ in range(count):
        frames = [(can_id, bytes(data)) for can_id, data in messages[int(rng.integers(len(messages)))]]
        kind = int(rng.integers(4))
        k = int(rng.integers(len(frames)))
        can_id, data = frames[k]
        if kind == 0:  # payload bits flipped
            frames[k] = (can_id, _flip(rng, data))
        elif kind == 1:  # every payload byte random, the frame valid: the value checks must catch it
            frames = [(cid, (d[:1] + rng.bytes(len(d) - 1)) if len(frames) > 1 else rng.bytes(len(d)))
                      for cid, d in frames]
        elif kind == 2:  # a frame lost or cut
            frames[k] = (can_id, data[: int(rng.integers(len(data)))])
        else:  # a random frame of a supported PGN
            frames = [(make_can_id(int(rng.integers(8)), pgns[int(rng.integers(len(pgns)))], int(rng.integers(252))),
                       rng.bytes(int(rng.integers(0, 9))))]
        yield frames


# ----------------------------------------------------------------------------------------------
# MAVLink


def mavlink_inputs(rng: np.random.Generator, count: int) -> Iterator[bytes]:
    encoder = MavlinkEncoder(1, 1)
    mav = encoder._mav
    fix = PositionFix(59.9, 10.7, FixQuality.RTK_FIXED, 43200.0, 12, 0.7, 5.0)
    bases = [encoder.heartbeat(), encoder.gps_raw_int(fix, course=CourseOverGround(1.0, 2.0), heading=Heading(0.3)),
             encoder.global_position_int(fix, heading=Heading(2.0), velocity_ned_mps=(1.0, -1.0, 0.0)),
             encoder.attitude(Attitude(0.01, -0.01, 1.0), rate=RateOfTurn(0.01))]

    def i32() -> int:
        return int(rng.integers(-(2**31), 2**31))

    def u16() -> int:
        return int(rng.choice([0, 65535, int(rng.integers(65536))]))

    def f32() -> float:
        return float(rng.choice([math.nan, math.inf, -math.inf, float(rng.normal(0, 10)), float(rng.normal(0, 1e30))]))

    for _ in range(count):
        base = bases[int(rng.integers(len(bases)))]
        mutated = _generic(rng, base)
        if mutated is None:  # a valid packet whose fields are drawn over their whole wire types
            which = int(rng.integers(3))
            if which == 0:
                message = mav.gps_raw_int_encode(int(rng.integers(2**63)), int(rng.integers(256)), i32(), i32(), i32(),
                                                 u16(), u16(), u16(), u16(), int(rng.integers(256)), yaw=u16())
            elif which == 1:
                vx, vy = (int(v) for v in rng.integers(-32768, 32768, 2))
                message = mav.global_position_int_encode(0, i32(), i32(), i32(), i32(), vx, vy, 0, u16())
            else:
                message = mav.attitude_encode(0, f32(), f32(), f32(), 0.0, 0.0, f32())
            mutated = encoder._pack(message)
        yield mutated


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--inputs", type=int, default=100_000, help="mutated inputs per protocol (default 1e5)")
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    nmea0183_decoder, n2k_decoder, mav_decoder = Nmea0183Decoder(), N2kDecoder(), MavlinkDecoder()
    clock = iter(range(10**9))

    def n2k(frames: list[tuple[int, bytes]]) -> list[object]:
        t_s = next(clock) * 0.01
        return [r.item for can_id, data in frames for r in n2k_decoder.decode_frame(can_id, data, t_s)]

    runs = {
        "nmea0183": (nmea0183_inputs(rng, args.inputs), nmea0183_decoder.feed),
        "nmea2000": (nmea2000_inputs(rng, args.inputs), n2k),
        "mavlink": (mavlink_inputs(rng, args.inputs), lambda d: [r.item for r in mav_decoder.decode_datagram(d)]),
    }
    failed = False
    print(f"{'protocol':<10} {'inputs':>8} {'messages':>9} {'rejected':>9} {'escapes':>8} {'out of range':>13} "
          f"{'s':>6}  rejects by reason")
    for name, (inputs, decode) in runs.items():
        tally = Tally()
        start = time.perf_counter()
        tally.run(inputs, decode)  # type: ignore[arg-type]
        elapsed = time.perf_counter() - start
        reasons = ", ".join(f"{reason} {count}" for reason, count in tally.reasons.most_common())
        print(f"{name:<10} {tally.inputs:>8} {tally.messages:>9} {sum(tally.reasons.values()):>9} "
              f"{len(tally.escapes):>8} {len(tally.out_of_range):>13} {elapsed:>6.1f}  {reasons}")
        for problem in (tally.escapes + tally.out_of_range)[:5]:
            print(f"    {problem}")
        failed |= bool(tally.escapes or tally.out_of_range)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
