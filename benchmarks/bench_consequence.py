"""The consequence analysis: what one worst-case failure check costs, and when fault case 14 warns.

* ``cost``: :class:`~dpcontrol.runtime.consequence.ConsequenceMonitor` driven at 10 Hz in DP as the daemon
  drives it (one ``update`` per cycle, a check once a second), with a 0.1 s sleep after every ten calls so
  that each check finds the caches as the live loop leaves them; and the same checks back to back. The supply
  vessel with three failure groups (two switchboards and the bow thruster room), CyberShip II with one (its
  bow tunnel), each under a steady demand.
* ``case14``: ``sim_plant/scenarios/faults/14-consequence.yaml`` in lockstep — when DP engaged, when each
  ``consequence.<group>`` alarm and ``consequence.<group>.utilisation`` warning was raised, how long before the
  tunnels trip (120 s).

On the 2026-12-03 development VM (2 cores): at 09:07 UTC, a test suite running beside it, supply, three groups,
0.56 ms median and 1.0 ms at most between sleeps, 0.25 ms back to back; CyberShip II 0.30 / 0.12 ms. At 09:55,
with the margin warnings, idle: 0.59 ms median, 0.92 ms at most, 0.20 ms back to back; CyberShip II 0.32 /
0.06 ms. Case 14: ``consequence.bow_room`` at 47 s, 73 s before the trip; bus_a and bus_b at 130 s, 10 s after
it; the warnings ``consequence.bus_a.utilisation`` at 81 s and ``bus_b.utilisation`` at 101 s.

Usage::

    .venv/bin/python benchmarks/bench_consequence.py
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from dpcontrol.allocation.consequence import FailureGroup
from dpcontrol.models.vessels import BUILTIN_VESSELS
from dpcontrol.runtime.alarms import AlarmRegistry
from dpcontrol.runtime.config import ConsequenceSettings
from dpcontrol.runtime.consequence import ConsequenceMonitor
from sim_plant.bench.lockstep import ProbedRun
from sim_plant.bench.run import build_simulation
from sim_plant.scenario import load_scenario

CASE_14 = Path(__file__).resolve().parents[1] / "sim_plant" / "scenarios" / "faults" / "14-consequence.yaml"
TRIP_S = 120.0
CASES = {
    "supply, 3 groups": ("supply", (FailureGroup("bus_a", ("bow_tunnel_1", "azimuth_port")),
                                    FailureGroup("bus_b", ("bow_tunnel_2", "azimuth_starboard")),
                                    FailureGroup("bow_room", ("bow_tunnel_1", "bow_tunnel_2"))),
                         [1e4, 1e5, 1e5]),
    "cybership2, 1 group": ("cybership2", (FailureGroup("bow_tunnel", ("bow_tunnel",)),), [0.05, -0.16, 0.0]),
}


def _check_times_us(vessel: str, groups: tuple[FailureGroup, ...], demand: list[float], seconds: int,
                    sleep: bool) -> list[float]:
    thrusters = BUILTIN_VESSELS[vessel].thrusters
    monitor = ConsequenceMonitor(thrusters, ConsequenceSettings(groups=groups, averaging_s=1.0), AlarmRegistry())
    available = np.ones(len(thrusters), dtype=bool)
    tau = np.array(demand)
    times = []
    t_s = 0.0
    for _ in range(seconds):
        for _ in range(10):
            start = time.perf_counter()
            ran = monitor.update(t_s, "auto_position", tau * (1.0 + 0.01 * np.sin(t_s)), available)
            if ran is not None:
                times.append((time.perf_counter() - start) * 1e6)
            t_s += 0.1
        if sleep:
            time.sleep(0.1)
    return times


def main() -> int:
    print("cost of one check (ConsequenceMonitor.update at a check time)")
    for label, (vessel, groups, demand) in CASES.items():
        for sleep in (True, False):
            times = _check_times_us(vessel, groups, demand, 40, sleep)
            rest = times[1:]
            print(f"  {label:<22} {'between 0.1 s sleeps' if sleep else 'back to back':<21} first "
                  f"{times[0]:7.0f} µs, then median {np.median(rest):6.0f} µs, max {max(rest):6.0f} µs "
                  f"({len(rest)} checks)")
    run = ProbedRun.run(build_simulation(load_scenario(CASE_14)))
    engaged = next(t for t, _old, new, _why in run.result.mode_changes if new == "auto_position")
    print(f"fault case 14 ({CASE_14.name}): DP from {engaged:g} s, both bow tunnels trip at {TRIP_S:g} s")
    for code in ("bow_room", "bus_a", "bus_b", "bus_a.utilisation", "bus_b.utilisation", "bow_room.utilisation"):
        raised = next((t for t, up in run.events(f"consequence.{code}") if up), None)
        when = "never" if raised is None else f"{raised:g} s ({raised - TRIP_S:+g} s from the trip)"
        print(f"  consequence.{code:<20} raised {when}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
