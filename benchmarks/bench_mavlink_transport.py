"""MAVLink-over-UDP latency between two processes (unsigned and signed), and codec cost per packet.

A sender process (``python -m interfaces.mavlink.probe``, a boat autopilot with a 1 Hz heartbeat)
sends numbered GPS_RAW_INT packets to a :class:`~interfaces.mavlink.transport.MavlinkUdpReader`
on 127.0.0.1 here. Latency = time the decoded :class:`~interfaces.messages.Measurement` reaches the
reader's sink − time just before the sender's ``sendto`` (both ``time.monotonic()``,
CLOCK_MONOTONIC, one clock for all processes on Linux).

Run: ``.venv/bin/python benchmarks/bench_mavlink_transport.py [--count N] [--rate-hz R]`` (prints JSON).
Numbers are machine- and load-dependent.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import threading
import time
import timeit
from typing import Any

import numpy as np

from interfaces.mavlink.codec import MavlinkDecoder, MavlinkEncoder
from interfaces.mavlink.probe import sequence_of
from interfaces.mavlink.transport import MavlinkUdpReader
from interfaces.messages import Attitude, FixQuality, Measurement, PositionFix, RateOfTurn

KEY = bytes(range(32))


def _stats_us(values_s: list[float]) -> dict[str, float]:
    if not values_s:
        return {}
    us = np.asarray(values_s) * 1e6
    return {"n": int(us.size), "median": float(np.median(us)), "p99": float(np.percentile(us, 99)),
            "max": float(us.max())}


def codec_costs(repeat: int = 5000) -> dict[str, float]:
    """Per-call cost [µs] of the codec paths (best of 3 runs of ``repeat`` calls)."""
    fix = PositionFix(59.9, 10.7, FixQuality.RTK_FIXED, utc_time_s=100.0, num_satellites=12, hdop=0.8, altitude_m=2.0)
    plain, signed = MavlinkEncoder(1, 1), MavlinkEncoder(1, 1, signing_key=KEY, unix_clock=time.time)
    gps, att = plain.gps_raw_int(fix), plain.attitude(Attitude(0.0, 0.0, 1.0), rate=RateOfTurn(0.01))
    decoder = MavlinkDecoder()
    signed_decoder = MavlinkDecoder(KEY, signing_time_s=time.time())
    fresh = [signed.gps_raw_int(fix) for _ in range(3 * repeat)]  # signed packets are valid once (replay check)
    packets = iter(fresh)

    def best(fn, number: int = repeat) -> float:
        return min(timeit.repeat(fn, number=number, repeat=3)) / number * 1e6

    return {
        "decode_gps_raw_int": best(lambda: decoder.decode_datagram(gps)),
        "decode_attitude": best(lambda: decoder.decode_datagram(att)),
        "decode_gps_raw_int_signed": best(lambda: signed_decoder.decode_datagram(next(packets))),
        "encode_gps_raw_int": best(lambda: plain.gps_raw_int(fix)),
        "encode_gps_raw_int_signed": best(lambda: signed.gps_raw_int(fix)),
        "encode_heartbeat": best(plain.heartbeat),
    }


def _latency(count: int, rate_hz: float, signing: bool, timeout_s: float) -> dict[str, Any]:
    arrivals: dict[int, float] = {}
    done = threading.Event()

    def sink(event: object) -> None:
        if isinstance(event, Measurement) and isinstance(event.message, PositionFix):
            arrivals[sequence_of(event.message.lat_deg)] = time.monotonic()
            if len(arrivals) >= count:
                done.set()

    with MavlinkUdpReader(sink, signing_key=KEY if signing else None) as reader:
        command = [sys.executable, "-m", "interfaces.mavlink.probe", "--target", f"127.0.0.1:{reader.address[1]}",
                   "--count", str(count), "--rate-hz", str(rate_hz)]
        if signing:
            command += ["--signing-key", KEY.hex()]
        probe = subprocess.run(command, capture_output=True, timeout=timeout_s + count / rate_hz, check=True)
        done.wait(timeout_s)
        counters = dict(reader.decoder.counters)
    sent = json.loads(probe.stdout)["sent"]
    latency = [arrivals[int(seq)] - t_send for seq, t_send in sent if int(seq) in arrivals]
    return {"sent": len(sent), "received": len(arrivals), "lost": len(sent) - len(arrivals),
            "latency_us": _stats_us(latency), "decoder_counters": counters}


def run(count: int = 2000, rate_hz: float = 200.0, timeout_s: float = 60.0) -> dict[str, Any]:
    """Measure the two-process latency (median, p99 µs), unsigned and signed, and the codec costs."""
    return {
        "transport": "UDP on 127.0.0.1, pymavlink parser (MAVLink 2), reader thread with blocking recvfrom",
        "path": "sender process sendto → reader recvfrom → decode → sink",
        "rate_hz": rate_hz,
        "unsigned": _latency(count, rate_hz, False, timeout_s),
        "signed": _latency(count, rate_hz, True, timeout_s),
        "codec_us": codec_costs(),
    }


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--count", type=int, default=2000)
    parser.add_argument("--rate-hz", type=float, default=200.0)
    args = parser.parse_args()
    print(json.dumps(run(args.count, args.rate_hz), indent=2))
