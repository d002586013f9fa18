"""NMEA 2000 transport latency between two processes, and codec cost per frame.

Three processes: the python-can-remote server (:func:`start_remote_server`, ``process`` mode),
a sender (``python -m interfaces.nmea2000.probe``) and the reader here. Latency = time the decoded
:class:`~interfaces.messages.Measurement` reaches the reader's sink − time just before the sender
called ``bus.send`` (both ``time.monotonic()``, CLOCK_MONOTONIC, one clock for all processes on
Linux). For 129029 it runs from the first of its 7 fast-packet frames to the decoded message.

Run: ``.venv/bin/python benchmarks/bench_n2k_transport.py [--count N] [--rate-hz R]`` (prints JSON).
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
from nmea2000 import backend

from interfaces.messages import FixQuality, Heading, Measurement, PositionFix
from interfaces.nmea2000.candump import parse_candump_line
from interfaces.nmea2000.codec import PGN_GNSS_POSITION, PGN_POSITION_RAPID, N2kDecoder, N2kEncoder
from interfaces.nmea2000.probe import sequence_of
from interfaces.nmea2000.transport import N2kCanReader, start_remote_server


def _stats_us(values_s: list[float]) -> dict[str, float]:
    if not values_s:
        return {}
    us = np.asarray(values_s) * 1e6
    return {"n": int(us.size), "median": float(np.median(us)), "p99": float(np.percentile(us, 99)),
            "max": float(us.max())}


def codec_costs(repeat: int = 5000) -> dict[str, float]:
    """Per-call cost [µs] of the codec paths (best of 3 runs of ``repeat`` calls)."""
    encoder, decoder = N2kEncoder(35), N2kDecoder()
    fix = PositionFix(63.4305149, 10.3950528, FixQuality.RTK_FIXED, utc_time_s=43210.5, num_satellites=14,
                      hdop=0.7, altitude_m=12.3)
    (rapid_id, rapid), = encoder.position_rapid(fix)
    (heading_id, heading), = encoder.heading(Heading(1.0))
    full = encoder.gnss_position(fix)
    payload = encoder.payload(PGN_GNSS_POSITION, {"latitude": 63.4, "longitude": 10.3, "method": 1,
                                                  "referenceStations": 0})
    line = f"(1502984866.421964) slcan0 {rapid_id:08X}#{rapid.hex().upper()}"

    def best(fn) -> float:
        return min(timeit.repeat(fn, number=repeat, repeat=3)) / repeat * 1e6

    def full_round_trip() -> None:
        for can_id, data in encoder.gnss_position(fix):
            decoder.decode_frame(can_id, data, 0.0)

    def full_decode() -> None:
        for can_id, data in full:
            decoder.decode_frame(can_id, data, 0.0)

    return {
        "decode_frame_129025": best(lambda: decoder.decode_frame(rapid_id, rapid, 0.0)),
        "decode_frame_127250": best(lambda: decoder.decode_frame(heading_id, heading, 0.0)),
        "decode_frame_ignored_pgn": best(lambda: decoder.decode_frame(0x18EEFF01, rapid, 0.0)),
        "decode_129029_7_frames": best(full_decode),
        "encode_129029": best(lambda: encoder.gnss_position(fix)),
        "encode_plus_decode_129029": best(full_round_trip),
        "library_only_decode_129025_payload": best(lambda: backend.decode(PGN_POSITION_RAPID, rapid, units="si")),
        "library_only_decode_129029_payload": best(lambda: backend.decode(PGN_GNSS_POSITION, payload, units="si")),
        "parse_candump_line": best(lambda: parse_candump_line(line)),
    }


def run(count: int = 2000, rate_hz: float = 200.0, fast_every: int = 10, timeout_s: float = 60.0) -> dict[str, Any]:
    """Measure the two-process latency (median, p99 µs) and the codec costs; returns a JSON-ready dict."""
    arrivals: dict[tuple[int, int], float] = {}
    done = threading.Event()
    expected = count + (count + fast_every - 1) // fast_every if fast_every else count

    def sink(event: object) -> None:
        if isinstance(event, Measurement) and isinstance(event.message, PositionFix):
            t_now = time.monotonic()
            pgn = PGN_GNSS_POSITION if event.message.utc_time_s is not None else PGN_POSITION_RAPID
            arrivals[(sequence_of(event.message.lat_deg), pgn)] = t_now
            if len(arrivals) >= expected:
                done.set()

    with start_remote_server(mode="process") as server, N2kCanReader(server.bus_config(), sink) as reader:
        if not reader.wait_connected(10.0):
            raise RuntimeError("reader did not connect to the remote server")
        probe = subprocess.run(
            [sys.executable, "-m", "interfaces.nmea2000.probe", "--channel", server.url, "--count", str(count),
             "--rate-hz", str(rate_hz), "--fast-every", str(fast_every)],
            capture_output=True, timeout=timeout_s + count / rate_hz, check=True)
        done.wait(timeout_s)
        decoder_counters = dict(reader.decoder.counters)
    sent = json.loads(probe.stdout)["sent"]
    latency: dict[int, list[float]] = {PGN_POSITION_RAPID: [], PGN_GNSS_POSITION: []}
    for seq, pgn, t_send in sent:
        t_arrival = arrivals.get((int(seq), int(pgn)))
        if t_arrival is not None:
            latency[int(pgn)].append(t_arrival - t_send)
    return {
        "transport": "python-can 'remote' (websocket) through a python-can-remote server process on 127.0.0.1",
        "path": "sender process → server process (virtual bus) → reader thread → decode → sink",
        "sent": len(sent), "received": len(arrivals), "lost": len(sent) - len(arrivals),
        "rate_hz": rate_hz,
        "latency_us": {"129025_single_frame": _stats_us(latency[PGN_POSITION_RAPID]),
                       "129029_fast_packet_7_frames": _stats_us(latency[PGN_GNSS_POSITION])},
        "decoder_counters": decoder_counters,
        "codec_us": codec_costs(),
    }


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--count", type=int, default=2000)
    parser.add_argument("--rate-hz", type=float, default=200.0)
    args = parser.parse_args()
    print(json.dumps(run(args.count, args.rate_hz), indent=2))
