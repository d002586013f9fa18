"""Is this machine fit to measure loop latency? The same control step, back to back and once per period.

A 10 Hz control loop runs one step and then waits ~99 ms. On a machine shared with other work — a
virtual machine, whose host runs other guests on the same cores and caches — that wait leaves the step's
code and data evicted, and the next step runs from memory: slower by a factor that is a property of
the machine, not of the controller. This benchmark measures that factor, so that a latency number from
a HIL bench (``make demo``'s "cycle start → command published") can be read against it.

The controller is the demo's (CyberShip II, 8-model MMAE bank, PID) in a lockstep run; after a settling
period, every step's own duration is timed while the loop between two steps

* ``back-to-back``: goes straight on (the tight loop of ``sim-plant bench``);
* ``sleep``: also sleeps for one control period, 0.1 s, as the daemon does;
* ``busy``: busy-waits for 0.1 s instead (the CPU never idles: what is lost then is not lost to sleep
  states but to other work on the machine).

On the 2026-12-02 development VM (2 cores, idle): 186 µs back to back, 632 µs after a sleep (×3.4) and 594 µs
after busy-waiting (×3.2) — so not the sleep: the host's other work. Dedicated hardware should show ratios
near 1.

The same holds for the kernel, which the daemon enters after its step to publish the command. The
``kernel`` part times, in CPU time of the calling thread, a trivial system call (``getppid``) and the send of
one 645-byte datagram (the size of a thruster command) to a socket of this process on 127.0.0.1 — no reader
is woken, so it is the send path alone — back to back and after busy-waiting 2, 10 and 100 ms in Python.
On the 2026-12-02 development VM (a Firecracker micro-VM; two runs of this script, 13:00 and 13:20 UTC): the
system call 1.4–1.5 µs back to back, 15–17 µs after 10 ms; the send 7 µs back to back, 87–97 µs after 10 ms.
The daemon's "command" phase (``phases_us.command`` in a demo's summary: 110–220 µs median) pays the same
kind of cold path in Zenoh's ``put``, whatever the daemon does.

Usage::

    .venv/bin/python benchmarks/bench_cold_cache.py [--steps 150] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import socket
import time
from typing import Any

import numpy as np

from sim_plant.bench.run import build_simulation
from sim_plant.bench.speed import BANK_8
from sim_plant.scenario import builtin_scenario_path, load_scenario

PERIOD_S = 0.1
SETTLE_S = 5.0  # the estimator initialised and DP engaged before the timed steps


def _run(mode: str, steps: int) -> np.ndarray:
    """Step durations [µs] of ``steps`` control steps with ``mode``'s wait between them."""
    simulation = build_simulation(load_scenario(builtin_scenario_path("cs2-seed000")), overrides={"estimator": BANK_8})
    controller = simulation.controller
    step = controller.step
    durations: list[float] = []
    clock = time.perf_counter

    def timed_step(*args: Any) -> Any:
        start = clock()
        out = step(*args)
        durations.append(clock() - start)
        return out

    controller.step = timed_step  # type: ignore[method-assign]

    def wait(t_s: float, _out: Any) -> None:
        if t_s < SETTLE_S:
            return
        if mode == "sleep":
            time.sleep(PERIOD_S)
        elif mode == "busy":
            end = clock() + PERIOD_S
            while clock() < end:
                pass

    simulation.run(duration_s=SETTLE_S + steps * PERIOD_S, observer=wait, timeseries=False)
    settled = round(SETTLE_S / PERIOD_S) + 1  # the first step after the first wait
    return np.array(durations[settled:]) * 1e6


KERNEL_GAPS_S = (0.0, 0.002, 0.01, 0.1)
COMMAND_BYTES = 645  # a six-thruster command payload (interfaces.zenoh.schemas.command_payload)


def _busy_wait(duration_s: float) -> None:
    end = time.perf_counter() + duration_s
    while time.perf_counter() < end:
        pass


def _kernel(samples: int) -> dict[str, dict[str, float]]:
    """Median CPU time [µs] of a system call and of a loopback datagram send, per busy-wait gap before it.

    The datagrams go to a socket of this process bound on 127.0.0.1 that is never read: ``samples`` per gap
    (at most 4 × ``samples`` × 645 bytes in all, within the default receive buffer or dropped by the kernel).
    """
    receiver = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        receiver.bind(("127.0.0.1", 0))
        address = receiver.getsockname()
        payload = b"x" * COMMAND_BYTES
        cpu = time.thread_time
        out: dict[str, dict[str, float]] = {}
        for gap in KERNEL_GAPS_S:
            syscall, send = [], []
            for _ in range(samples):
                _busy_wait(gap)
                start = cpu()
                os.getppid()
                syscall.append(cpu() - start)
                _busy_wait(gap)
                start = cpu()
                sender.sendto(payload, address)
                send.append(cpu() - start)
            out[f"{gap * 1e3:g} ms"] = {"syscall_us": round(float(np.median(syscall)) * 1e6, 1),
                                        "udp_send_us": round(float(np.median(send)) * 1e6, 1)}
        return out
    finally:
        sender.close()
        receiver.close()


def run(steps: int = 150, kernel_samples: int = 40) -> dict[str, Any]:
    """Median / p99 step duration [µs] per mode and the ratios to back-to-back; the kernel probe per gap."""
    result: dict[str, Any] = {"steps": steps, "modes": {}, "kernel": _kernel(kernel_samples)}
    for mode in ("back-to-back", "sleep", "busy"):
        durations = _run(mode, steps)
        result["modes"][mode] = {"median_us": round(float(np.median(durations)), 1),
                                 "p99_us": round(float(np.percentile(durations, 99)), 1)}
    warm = result["modes"]["back-to-back"]["median_us"]
    for mode in ("sleep", "busy"):
        result["modes"][mode]["ratio_to_back_to_back"] = round(result["modes"][mode]["median_us"] / warm, 2)
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=150, help="timed steps per mode (default 150)")
    parser.add_argument("--json", action="store_true", help="print JSON instead of the table")
    args = parser.parse_args()
    result = run(args.steps)
    if args.json:
        print(json.dumps(result, indent=1))
        return
    print(f"controller step (CyberShip II, MMAE-8 + PID), {args.steps} steps per mode")
    for mode, row in result["modes"].items():
        ratio = row.get("ratio_to_back_to_back")
        print(f"{mode:13s} median {row['median_us']:7.1f} µs  p99 {row['p99_us']:7.1f} µs"
              + (f"  ×{ratio:.2f}" if ratio is not None else ""))
    print("kernel, CPU time of the calling thread (medians) after busy-waiting:")
    for gap, row in result["kernel"].items():
        print(f"  {gap:>6s}  getppid {row['syscall_us']:6.1f} µs  "
              f"645-byte UDP send to 127.0.0.1 {row['udp_send_us']:6.1f} µs")


if __name__ == "__main__":
    main()
