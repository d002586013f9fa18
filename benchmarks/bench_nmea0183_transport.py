"""Two-process NMEA 0183 latency over a pseudo-terminal: write timestamp → decoded measurement.

The writer is a separate process (this script with ``--writer``), like the plant emulator: it
creates a :class:`~interfaces.nmea0183.transport.PtyPair`, tells the parent the slave path, waits
for "go", then writes ``count`` GGA sentences at ``rate_hz`` (0: as fast as it can), each one
stamped with ``time.monotonic_ns()`` just before ``write()``; the sentence's UTC time field
carries its sequence number. The reader is a :class:`~interfaces.nmea0183.transport.SerialReader`
in this process; its callback stamps each decoded measurement with ``time.monotonic_ns()``.
``CLOCK_MONOTONIC`` is system-wide, so the two stamps are comparable across processes.

Reported (µs): ``write → decoded`` (what the control loop sees: pty, pyserial read, decode,
callback) and ``write → read`` (the Measurement's ``t_s``, stamped when the bytes were read,
before decoding): median, p99, max. Run::

    .venv/bin/python benchmarks/bench_nmea0183_transport.py [--count 1000] [--rate-hz 100] [--json]
"""

from __future__ import annotations

import argparse
import json
import selectors
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np

from interfaces.messages import FixQuality, Measurement, PositionFix
from interfaces.nmea0183 import PtyPair, SerialReader, encode_gga

_TIMEOUT_S = 30.0


def _writer(count: int, rate_hz: float) -> int:
    """The emulator side: create the pty, wait for "go", write, report the write times."""
    with PtyPair() as pty:
        print(json.dumps({"device": pty.slave_path}), flush=True)
        if sys.stdin.readline().strip() != "go":
            return 1
        sentences = [encode_gga(PositionFix(59.95 + 1e-6 * seq, 10.75, FixQuality.RTK_FIXED, float(seq), 14, 0.6, 12.0))
                     for seq in range(count)]
        write_ns = [0] * count
        period_ns = int(1e9 / rate_hz) if rate_hz > 0 else 0
        start_ns = time.monotonic_ns()
        for seq, sentence in enumerate(sentences):
            if period_ns:  # device pacing (a receiver's output rate), not synchronisation
                delay_s = (start_ns + seq * period_ns - time.monotonic_ns()) / 1e9
                if delay_s > 0:
                    time.sleep(delay_s)
            write_ns[seq] = time.monotonic_ns()
            pty.write(sentence)
        print(json.dumps({"write_ns": write_ns}), flush=True)
        sys.stdin.readline()  # keep the pty open until the reader has everything ("done" or EOF)
    return 0


def _read_json_line(process: subprocess.Popen, timeout_s: float) -> dict:
    """Await one JSON line from the writer, bounded in time."""
    with selectors.DefaultSelector() as selector:
        selector.register(process.stdout, selectors.EVENT_READ)
        if not selector.select(timeout_s):
            raise TimeoutError("the writer process did not answer")
    line = process.stdout.readline()
    if not line:
        raise RuntimeError(f"the writer process ended (exit code {process.wait()})")
    return json.loads(line)


def _percentiles_us(samples_ns: np.ndarray) -> dict[str, float]:
    samples_us = samples_ns / 1e3
    return {"median_us": float(np.median(samples_us)), "p99_us": float(np.percentile(samples_us, 99)),
            "max_us": float(samples_us.max()), "mean_us": float(samples_us.mean())}


def run(count: int = 1000, rate_hz: float = 100.0) -> dict:
    """Measure the two-process latency.

    Parameters
    ----------
    count : int
        Sentences to send (≤ 86400: the sequence number travels in the UTC time field).
    rate_hz : float
        Writer rate [Hz]; 0 writes back to back (a throughput test, latencies include queueing).

    Returns
    -------
    dict
        ``sent``, ``delivered``, ``lost``, ``rate_hz``, and ``write_to_decoded`` /
        ``write_to_read`` with ``median_us``, ``p99_us``, ``max_us``, ``mean_us``.
    """
    if not 1 <= count <= 86400:
        raise ValueError("count must be in 1..86400")
    decoded_ns = np.zeros(count, dtype=np.int64)
    read_s = np.zeros(count)
    delivered = 0
    all_in = threading.Event()

    def on_measurement(measurement: Measurement) -> None:
        nonlocal delivered
        now_ns = time.monotonic_ns()
        seq = round(measurement.message.utc_time_s)
        decoded_ns[seq] = now_ns
        read_s[seq] = measurement.t_s
        delivered += 1
        if delivered == count:
            all_in.set()

    process = subprocess.Popen([sys.executable, str(Path(__file__).resolve()), "--writer", "--count", str(count),
                                "--rate-hz", str(rate_hz)], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    reader = None
    try:
        device = _read_json_line(process, _TIMEOUT_S)["device"]
        reader = SerialReader(device, source="gnss1", clock=time.monotonic, on_measurement=on_measurement,
                              baudrate=115200).start()
        if not reader.wait_connected(_TIMEOUT_S):
            raise TimeoutError(f"could not open {device}: {reader.last_error}")
        process.stdin.write("go\n")
        process.stdin.flush()
        write_ns = np.array(_read_json_line(process, _TIMEOUT_S + count / max(rate_hz, 1.0))["write_ns"],
                            dtype=np.int64)
        all_in.wait(_TIMEOUT_S)
        counters = reader.counters
    finally:
        if reader is not None:
            reader.close()
        if process.stdin and not process.stdin.closed:
            process.stdin.write("done\n")
            process.stdin.close()
        process.wait(_TIMEOUT_S)
        if process.stdout:
            process.stdout.close()
    got = decoded_ns > 0
    return {
        "sent": count, "delivered": int(got.sum()), "lost": int(count - got.sum()), "rate_hz": rate_hz,
        "rejected": counters["rejected"], "reads": counters["reads"],
        "write_to_decoded": _percentiles_us(decoded_ns[got] - write_ns[got]),
        "write_to_read": _percentiles_us(np.round(read_s[got] * 1e9).astype(np.int64) - write_ns[got]),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--count", type=int, default=1000)
    parser.add_argument("--rate-hz", type=float, default=100.0)
    parser.add_argument("--json", action="store_true", help="print the result as JSON")
    parser.add_argument("--writer", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.writer:
        return _writer(args.count, args.rate_hz)
    result = run(args.count, args.rate_hz)
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        print(f"NMEA 0183 over a pty, two processes: {result['delivered']}/{result['sent']} delivered "
              f"at {result['rate_hz']:g} Hz")
        for key in ("write_to_decoded", "write_to_read"):
            stats = result[key]
            print(f"  {key:17s} median {stats['median_us']:7.1f} µs   p99 {stats['p99_us']:7.1f} µs   "
                  f"max {stats['max_us']:8.1f} µs")
    return 0 if result["lost"] == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
