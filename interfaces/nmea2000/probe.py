"""``python -m interfaces.nmea2000.probe``: a numbered NMEA 2000 traffic source for two-process tests.

Sends ``--count`` position reports on a python-can bus at ``--rate-hz``: PGN 129025 with
latitude ``LAT0_DEG + seq · STEP_DEG`` (so a receiver can tell which one it got), and every
``--fast-every``-th one also as a 129029 fast packet. Just before each send it reads
``time.monotonic()``; on Linux that is CLOCK_MONOTONIC, one clock for every process, so a receiver
stamping with ``time.monotonic()`` measures the one-way latency. At the end it prints one JSON
object: ``{"sent": [[seq, pgn, t_send_s], ...], "counters": {...}}``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time

from interfaces.messages import FixQuality, PositionFix
from interfaces.nmea2000.codec import PGN_GNSS_POSITION, PGN_POSITION_RAPID, N2kEncoder
from interfaces.nmea2000.transport import CanBusConfig, N2kCanWriter

LAT0_DEG = 10.0
LON0_DEG = 20.0
STEP_DEG = 1e-5  # 100 resolution steps of 129025 between numbers: unambiguous after quantisation


def sequence_of(lat_deg: float) -> int:
    """The probe number encoded in a latitude sent by this probe."""
    return round((lat_deg - LAT0_DEG) / STEP_DEG)


def main(argv: list[str] | None = None) -> int:
    """Send the numbered traffic (see the module docstring); returns the exit status."""
    parser = argparse.ArgumentParser(prog="python -m interfaces.nmea2000.probe", description=__doc__)
    parser.add_argument("--interface", default="remote")
    parser.add_argument("--channel", required=True)
    parser.add_argument("--count", type=int, default=100)
    parser.add_argument("--rate-hz", type=float, default=100.0)
    parser.add_argument("--source", type=int, default=35, help="NMEA 2000 source address")
    parser.add_argument("--fast-every", type=int, default=10, help="also send a 129029 every N (0: never)")
    args = parser.parse_args(argv)
    encoder = N2kEncoder(args.source)
    sent: list[list[float]] = []
    with N2kCanWriter(CanBusConfig(args.interface, args.channel)) as writer:
        period_s = 1.0 / args.rate_hz
        t0 = time.monotonic()
        for seq in range(args.count):
            # pacing a traffic generator, not waiting for a condition
            delay = t0 + seq * period_s - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            fix = PositionFix(LAT0_DEG + seq * STEP_DEG, LON0_DEG, FixQuality.GPS, utc_time_s=float(seq % 86400))
            frames = encoder.position_rapid(fix)
            t_send = time.monotonic()
            if writer.send(frames) == len(frames):
                sent.append([seq, PGN_POSITION_RAPID, t_send])
            if args.fast_every and seq % args.fast_every == 0:
                frames = encoder.gnss_position(fix)
                t_send = time.monotonic()
                if writer.send(frames) == len(frames):
                    sent.append([seq, PGN_GNSS_POSITION, t_send])
        counters = dict(writer.counters)
    json.dump({"sent": sent, "counters": counters}, sys.stdout)
    sys.stdout.write("\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
