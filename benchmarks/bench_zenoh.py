"""Zenoh benchmark: loopback round-trip latency and the cost of the payload builders/parsers.

Measures

* ``raw``: round trip of a small payload between two peer sessions in this process over
  ``tcp/127.0.0.1`` — publisher A → subscriber B echoes on another key → subscriber A
  (docs/design.md §6 budget: about 130 µs median, 180 µs p99);
* ``full``: the same loop through the real schemas — A builds and puts a thruster command
  (8 thrusters), B's validating subscriber parses it and echoes a feedback message, A's validating
  subscriber parses that;
* ``two_process`` (optional): the raw round trip with the echo in a child process (no shared GIL);
* the per-call cost of every builder the daemon calls each cycle, and of the parsers.

Usage::

    .venv/bin/python benchmarks/bench_zenoh.py [--n 2000] [--two-process] [--json]

``run(...) -> dict`` returns the numbers (µs). Timings on a shared, loaded machine are noisy.
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import textwrap
import threading
import time
import timeit
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import zenoh

from interfaces.zenoh import schemas as sc
from interfaces.zenoh.loopback import loopback_pair, open_listener
from interfaces.zenoh.node import LatestSlot, ZenohNode

ROOT = Path(__file__).resolve().parents[1]
VESSEL = "bench"
PING = f"dp/{VESSEL}/bench/ping"
PONG = f"dp/{VESSEL}/bench/pong"
NAMES = [f"t{i}" for i in range(8)]


def _summary(samples_ns: list[int], lost: int) -> dict[str, float]:
    us = np.asarray(samples_ns, dtype=float) / 1e3
    return {"n": int(us.size), "lost": lost, "median_us": float(np.median(us)), "p99_us": float(np.percentile(us, 99)),
            "min_us": float(us.min()), "max_us": float(us.max())}


def _ping_pong(send: Callable[[int], None], done: threading.Event, n: int, warmup: int) -> dict[str, float]:
    samples: list[int] = []
    lost = 0
    for i in range(n + warmup):
        done.clear()
        start = time.perf_counter_ns()
        send(i)
        if not done.wait(1.0):
            lost += 1
            continue
        if i >= warmup:
            samples.append(time.perf_counter_ns() - start)
    return _summary(samples, lost)


def _raw_round_trip(a: ZenohNode, b: ZenohNode, n: int, warmup: int) -> dict[str, float]:
    express = {"express": True, "congestion_control": zenoh.CongestionControl.DROP,
               "priority": zenoh.Priority.REAL_TIME}
    ping = a.session.declare_publisher(PING, **express)
    pong = b.session.declare_publisher(PONG, **express)
    done = threading.Event()
    echo = b.session.declare_subscriber(PING, lambda sample: pong.put(sample.payload))
    back = a.session.declare_subscriber(PONG, lambda _sample: done.set())
    try:
        _wait_matched(ping)
        _wait_matched(pong)
        payload = b"x" * 64
        return _ping_pong(lambda _i: ping.put(payload), done, n, warmup)
    finally:
        for entity in (back, echo, pong, ping):
            entity.undeclare()


def _wait_matched(publisher: Any, timeout_s: float = 10.0) -> None:
    matched = threading.Event()
    listener = publisher.declare_matching_listener(lambda s: matched.set() if s.matching else None)
    try:
        if publisher.matching_status.matching:
            return
        if not matched.wait(timeout_s):
            raise TimeoutError("no matching subscriber")
    finally:
        listener.undeclare()


def _full_round_trip(a: ZenohNode, b: ZenohNode, n: int, warmup: int) -> dict[str, float]:
    command_pub = a.publisher("command")
    feedback_pub = b.publisher("feedback")
    thrust = np.linspace(-1e5, 1e5, len(NAMES))
    azimuth = np.linspace(-3.0, 3.0, len(NAMES))
    ready = [True] * len(NAMES)
    def echo() -> None:  # runs in B's subscriber callback, as a drive would answer
        item = commands.take()
        if item is not None:
            msg = item.message
            feedback_pub.put(sc.feedback_payload(t_s=msg.t_s, seq=feedback_pub.next_seq(), names=NAMES,
                                                 thrust_n=[t.thrust_n for t in msg.thrusters],
                                                 azimuth_rad=[t.azimuth_rad for t in msg.thrusters], ready=ready))

    commands: LatestSlot[Any] = LatestSlot(on_put=echo)
    b.subscribe("command", commands)
    done = threading.Event()
    a.subscribe("feedback", LatestSlot(on_put=done.set))
    assert command_pub.wait_matched(10.0) and feedback_pub.wait_matched(10.0)

    def send(i: int) -> None:
        command_pub.put(sc.command_payload(t_s=float(i), seq=command_pub.next_seq(), mode="auto_position",
                                           names=NAMES, thrust_n=thrust, azimuth_rad=azimuth))

    return _ping_pong(send, done, n, warmup)


CHILD_ECHO = textwrap.dedent(f"""
    import sys, zenoh
    from interfaces.zenoh import ZenohConfig, ZenohNode
    node = ZenohNode(ZenohConfig(connect=(sys.argv[1],)), {VESSEL!r})
    pong = node.session.declare_publisher({PONG!r}, express=True, congestion_control=zenoh.CongestionControl.DROP,
                                          priority=zenoh.Priority.REAL_TIME)
    echo = node.session.declare_subscriber({PING!r}, lambda sample: pong.put(sample.payload))
    print("ready", flush=True)
    sys.stdin.read()
    node.close()
""")


def _two_process_round_trip(n: int, warmup: int) -> dict[str, float]:
    node, endpoint = open_listener(VESSEL)
    child = subprocess.Popen([sys.executable, "-c", CHILD_ECHO, endpoint], cwd=ROOT, stdin=subprocess.PIPE,
                             stdout=subprocess.PIPE)
    try:
        assert child.stdout is not None and child.stdout.readline().strip() == b"ready"
        ping = node.session.declare_publisher(PING, express=True, congestion_control=zenoh.CongestionControl.DROP,
                                              priority=zenoh.Priority.REAL_TIME)
        done = threading.Event()
        back = node.session.declare_subscriber(PONG, lambda _sample: done.set())
        _wait_matched(ping)
        payload = b"x" * 64
        # The child's pong publisher may match us a moment after our ping matches it: warm-up covers that.
        result = _ping_pong(lambda _i: ping.put(payload), done, n, warmup)
        back.undeclare()
        ping.undeclare()
        return result
    finally:
        if child.stdin is not None:
            child.stdin.close()
        try:
            child.wait(10.0)
        except subprocess.TimeoutExpired:
            child.kill()
            child.wait()
        node.close()


def _cost_us(fn: Callable[[], object], number: int = 2000, repeat: int = 5) -> float:
    """Median over ``repeat`` runs of the mean time per call [µs]."""
    return float(np.median(timeit.repeat(fn, number=number, repeat=repeat)) / number * 1e6)


def codec_costs() -> dict[str, float]:
    """Per-call cost [µs] of the builders the daemon calls each cycle and of the parsers."""
    rng = np.random.default_rng(0)
    thrust, azimuth = rng.uniform(-1e5, 1e5, 8), rng.uniform(-3, 3, 8)
    eta, nu, bias, wf, cov = rng.normal(size=3), rng.normal(size=3), rng.normal(size=3), rng.normal(size=3), \
        rng.uniform(0.1, 1.0, 15)
    omegas = np.linspace(0.3, 1.35, 8)
    weights = np.full(8, 1 / 8)
    sensors = [sc.SensorHealth(f"s{i}", "gnss", "ok", 0.1, 0.25) for i in range(4)]
    alarms = [sc.Alarm("A1", "warning", "text", 1.0, True), sc.Alarm("A2", "alarm", "text", 2.0, False)]
    cycle = sc.CycleTiming(0.1, 140.0, 180.0, 0)
    avail = [sc.ThrusterAvailability(n, True) for n in NAMES]
    builders: dict[str, Callable[[], bytes]] = {
        "command": lambda: sc.command_payload(t_s=1.0, seq=1, mode="auto_position", names=NAMES, thrust_n=thrust,
                                              azimuth_rad=azimuth),
        "estimate": lambda: sc.estimate_payload(t_s=1.0, seq=1, estimator="mmae", eta_ned=eta, nu_b=nu, bias=bias,
                                                eta_wf_ned=wf, covariance_diag=cov),
        "mmae": lambda: sc.mmae_payload(t_s=1.0, seq=1, omegas_rad_s=omegas, weights=weights, omega_hat_rad_s=0.7),
        "control": lambda: sc.control_payload(t_s=1.0, seq=1, controller="mrac", tau_b=eta, setpoint_ned=eta,
                                              reference_ned=eta, reference_nu_b=nu, tau_achieved_b=nu,
                                              mrac_mass=bias, mrac_damping=bias),
        "status": lambda: sc.status_payload(t_s=1.0, seq=1, mode="auto_position", sensors=sensors, alarms=alarms,
                                            cycle=cycle, thrusters=avail),
    }
    out = {f"build_{name}_us": _cost_us(fn) for name, fn in builders.items()}
    out["build_all_per_cycle_us"] = sum(out.values())
    out["bytes_per_cycle"] = float(sum(len(fn()) for fn in builders.values()))
    command = builders["command"]()
    feedback = sc.feedback_payload(t_s=1.0, seq=1, names=NAMES, thrust_n=thrust, azimuth_rad=azimuth,
                                   ready=[True] * 8)
    setpoint = sc.setpoint_payload(t_s=1.0, seq=1, north_m=10.0, east_m=-5.0, heading_deg=90.0)
    out["parse_setpoint_us"] = _cost_us(lambda: sc.parse_setpoint(setpoint))
    out["parse_feedback_us"] = _cost_us(lambda: sc.parse_feedback(feedback))
    out["parse_command_us"] = _cost_us(lambda: sc.parse_command(command))
    out["parse_status_us"] = _cost_us(lambda: sc.parse_message("status", builders["status"]()), number=500)
    return out


def run(n: int = 2000, warmup: int = 200, two_process: bool = False) -> dict[str, Any]:
    """Run the benchmark; every latency in µs (median, p99, min, max) and every cost in µs per call."""
    result: dict[str, Any] = {"codec": codec_costs()}
    with loopback_pair(VESSEL) as (a, b):
        result["raw"] = _raw_round_trip(a, b, n, warmup)
    with loopback_pair(VESSEL) as (a, b):
        result["full"] = _full_round_trip(a, b, n, warmup)
    if two_process:
        result["two_process"] = _two_process_round_trip(n, warmup)
    return result


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=2000, help="round trips per measurement (default 2000)")
    parser.add_argument("--two-process", action="store_true", help="also measure with the echo in a child process")
    parser.add_argument("--json", action="store_true", help="print JSON")
    args = parser.parse_args(argv)
    result = run(n=args.n, two_process=args.two_process)
    if args.json:
        print(json.dumps(result, indent=2))
        return 0
    for name in ("raw", "full", "two_process"):
        if name in result:
            r = result[name]
            print(f"{name:12s} round trip: median {r['median_us']:7.1f} µs  p99 {r['p99_us']:7.1f} µs  "
                  f"min {r['min_us']:6.1f}  max {r['max_us']:8.1f}  (n={r['n']}, lost {r['lost']})")
    for key, value in result["codec"].items():
        print(f"{key:26s} {value:9.1f}" if math.isfinite(value) else f"{key:26s} {value}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
