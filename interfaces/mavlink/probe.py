"""``python -m interfaces.mavlink.probe``: a numbered MAVLink traffic source for two-process tests.

Sends a HEARTBEAT (then one every second), then ``--count`` GPS_RAW_INT packets at ``--rate-hz``
to ``--target host:port``, numbered by their latitude ``LAT0_DEG + seq · STEP_DEG`` (read back
with :func:`sequence_of`). Just before each send it reads ``time.monotonic()`` (Linux
CLOCK_MONOTONIC: one clock for every process, so a receiver stamping with ``time.monotonic()``
measures one-way latency). With ``--signing-key HEX`` every packet is signed. At the end it prints
one JSON object: ``{"sent": [[seq, t_send_s], ...], "counters": {...}}``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time

from interfaces.mavlink.codec import MavlinkEncoder, parse_signing_key
from interfaces.mavlink.transport import MavlinkUdpSender
from interfaces.messages import FixQuality, PositionFix

LAT0_DEG = 59.9
LON_DEG = 10.7
STEP_DEG = 1e-5  # 100 steps of the 1e-7° resolution: unambiguous after quantisation


def sequence_of(lat_deg: float) -> int:
    """The probe number encoded in a latitude sent by this probe."""
    return round((lat_deg - LAT0_DEG) / STEP_DEG)


def main(argv: list[str] | None = None) -> int:
    """Send the numbered traffic (see the module docstring); returns the exit status."""
    parser = argparse.ArgumentParser(prog="python -m interfaces.mavlink.probe", description=__doc__)
    parser.add_argument("--target", required=True, help="host:port of the reader")
    parser.add_argument("--count", type=int, default=100)
    parser.add_argument("--rate-hz", type=float, default=100.0)
    parser.add_argument("--system-id", type=int, default=1)
    parser.add_argument("--component-id", type=int, default=1)
    parser.add_argument("--signing-key", default=None, help="64 hex digits")
    args = parser.parse_args(argv)
    host, _, port = args.target.rpartition(":")
    key = None if args.signing_key is None else parse_signing_key(args.signing_key)
    encoder = MavlinkEncoder(args.system_id, args.component_id, signing_key=key, unix_clock=time.time)
    sent: list[list[float]] = []
    with MavlinkUdpSender((host, int(port)), encoder) as sender:
        sender.start_heartbeat(1.0)
        period_s = 1.0 / args.rate_hz
        t0 = time.monotonic()
        for seq in range(1, args.count + 1):
            # pacing a traffic generator, not waiting for a condition
            delay = t0 + seq * period_s - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            fix = PositionFix(LAT0_DEG + seq * STEP_DEG, LON_DEG, FixQuality.RTK_FIXED, num_satellites=12, hdop=0.8,
                              altitude_m=2.0)
            packet = encoder.gps_raw_int(fix, time_usec=seq)
            t_send = time.monotonic()
            if sender.send(packet):
                sent.append([seq, t_send])
        counters = dict(sender.counters)
    json.dump({"sent": sent, "counters": counters}, sys.stdout)
    sys.stdout.write("\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
