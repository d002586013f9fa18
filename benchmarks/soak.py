"""Soak benchmark: 24 h of simulated DP with a random fault every few minutes (docs/fault-handling.md).

The supply vessel keeps station in lockstep — plant, sensors through the real codecs, the daemon's
hub, wave filter, PID, allocator and thruster monitor, one process, stepped clock — for ``hours`` of
simulated time, in a sea that changes every six hours, with three GNSS receivers and three
gyrocompasses (one of each on NMEA 0183, NMEA 2000 and MAVLink). Every few minutes (uniform 3–6 min,
seeded) one fault is injected, drawn from *every* kind the emulator implements — sensor
(``gnss_freeze``/``jump``/``drift``/``noise``/``dropout``/``invalid``, ``gyro_freeze``/``offset``/
``drift``/``dropout``/``invalid``), thruster (``thruster_stuck``/``zero``/``wrong_sign``/
``not_ready``) and protocol (``malformed_burst``, ``serial_unplug``, ``heartbeat_loss``) — on a random
target of the right type, for a random duration, with parameters in the range where the issue asks
for a detection (jumps ≥ 8 m, offsets ≥ 8°, noise ×5–8, bursts ≥ 150 items ...). Faults do not overlap:
each is followed by at least a minute of recovery. The soak plays the operator too: a thruster latched
out for a thrust mismatch is reset 10 s after its drive is healthy again, and DP is re-engaged if a
fall-back took it out of auto_position.

Checked every control step: no exception, no NaN/inf in the step's outputs (thrust and azimuth
commands, demanded/achieved/short force, the fused measurement, the estimate); the process's resident
memory is sampled every simulated 10 minutes (``/proc/self/statm``) — the time series is not kept
(``LockstepSimulation.run(timeseries=False)``), so memory must stay flat — and the live Python objects
are counted by type at 1 h and at the end (``gc.get_objects``): only the alarm record (``AlarmEvent``,
a few per fault) may grow. RSS alone moves in steps of a few MB when the allocator keeps arenas
(e.g. around a sea-state change, whose new wave components overlap the old for the cross-fade).

Detected, per fault (``sim_plant.bench.report.expected_detection``): one of the alarms that proves that
kind of fault on that target (e.g. ``sensor.gnss2.frozen``, ``transport.<bus>.error_rate``,
``thruster.<name>.unavailable``) raised at or after the fault's start, within the configured bound
(freeze window, stale periods, persistence times, heartbeat timeout ... see that function). ``late``:
raised, but after the bound; ``missed``: never raised during the fault and its recovery minute;
``not detectable``: the kind has no alarm for that configuration, or — for ``thruster_stuck``/``zero``/
``wrong_sign`` — the drive's thrust never differed from what a healthy drive would deliver by more than
the monitor's mismatch limit for the persistence time (a drive stuck at the thrust it is asked for is
not a detectable failure); for those kinds the bound counts from the first step the mismatch exceeded
the limit.

Plant integration at 10 Hz instead of the supply vessel's default 20 Hz (RK4, one substep per control
step; the drives' and the sensors' exact event times are kept): half the cost, and the 3–6 min fault
cycle is far slower than anything the coarser step changes.

Usage::

    .venv/bin/python benchmarks/soak.py [--hours 24] [--seed 1] [--json] [--out soak.json]

``run(hours=24.0, seed=1) -> dict``.
"""

from __future__ import annotations

import argparse
import gc
import json
import math
import os
import sys
import time
import traceback
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from dpcontrol.runtime.step import Mode, StepOutput
from dpcontrol.runtime.thruster_monitor import mismatch_limit_n
from sim_plant.bench.lockstep import LockstepSimulation, lockstep_config
from sim_plant.bench.report import expected_detection, first_raise
from sim_plant.faults import GNSS_FAULTS, GYRO_FAULTS, PROTOCOL_FAULTS, THRUSTER_FAULTS, Fault
from sim_plant.scenario import Scenario, parse_scenario

MEMORY_EVERY_S = 600.0
RECOVERY_S = 60.0                 # quiet time after each fault
FAULT_GAP_S = (180.0, 360.0)      # start-to-start spacing of the faults
OPERATOR_RESET_DELAY_S = 10.0     # a latched thruster is reset this long after its drive recovered
PLANT_RATE_HZ = 10.0
FIRST_FAULT_S = 300.0             # DP engaged and settled first

SENSORS = [
    {"name": "gnss1", "kind": "gnss", "protocol": "nmea0183", "rate_hz": 5, "noise_m": 0.3},
    {"name": "gnss2", "kind": "gnss", "protocol": "nmea2000", "rate_hz": 5, "noise_m": 0.3},
    {"name": "gnss3", "kind": "gnss", "protocol": "mavlink", "rate_hz": 5, "noise_m": 0.3},
    {"name": "gyro1", "kind": "gyro", "protocol": "nmea0183", "rate_hz": 10, "noise_deg": 0.05},
    {"name": "gyro2", "kind": "gyro", "protocol": "nmea2000", "rate_hz": 10, "noise_deg": 0.05},
    {"name": "gyro3", "kind": "gyro", "protocol": "mavlink", "rate_hz": 10, "noise_deg": 0.05},
]
SEA_STATES = [  # every 6 h: moderate, calm, high, moderate (supply vessel, seed 001's ranges)
    {"spectrum": "jonswap", "hs_m": 1.5, "omega_peak_rad_s": 0.79, "gamma": 3.3, "direction_deg": 30},
    {"spectrum": "jonswap", "hs_m": 1.0, "omega_peak_rad_s": 0.84, "gamma": 3.3, "direction_deg": 20},
    {"spectrum": "jonswap", "hs_m": 2.5, "omega_peak_rad_s": 0.65, "gamma": 3.3, "direction_deg": 40},
    {"spectrum": "jonswap", "hs_m": 1.5, "omega_peak_rad_s": 0.75, "gamma": 3.3, "direction_deg": 30},
]
ALL_KINDS = GNSS_FAULTS + GYRO_FAULTS + THRUSTER_FAULTS + PROTOCOL_FAULTS
MISMATCH_KINDS = ("thruster_stuck", "thruster_zero", "thruster_wrong_sign")


def plan_faults(duration_s: float, seed: int, thrusters: list[str]) -> list[dict[str, Any]]:
    """The scenario's ``faults:`` entries: one at a time, every kind in turn-free random order (seeded)."""
    rng = np.random.default_rng([seed, 8])
    gnss = [s["name"] for s in SENSORS if s["kind"] == "gnss"]
    gyros = [s["name"] for s in SENSORS if s["kind"] == "gyro"]
    serial = [s["name"] for s in SENSORS if s["protocol"] == "nmea0183"]
    mavlink = [s["name"] for s in SENSORS if s["protocol"] == "mavlink"]
    faults: list[dict[str, Any]] = []
    t = FIRST_FAULT_S
    while True:
        kind = str(rng.choice(ALL_KINDS))
        duration = float(rng.uniform(30.0, 120.0))
        entry: dict[str, Any] = {"t_s": round(t, 1), "kind": kind}
        if kind in GNSS_FAULTS:
            entry["sensor"] = str(rng.choice(gnss))
        elif kind in GYRO_FAULTS:
            entry["sensor"] = str(rng.choice(gyros))
        elif kind in THRUSTER_FAULTS:
            entry["thruster"] = str(rng.choice(thrusters))
        elif kind == "malformed_burst":
            entry["sensor"] = str(rng.choice(gnss + gyros))
            entry["count"] = int(rng.integers(150, 400))
            duration = 1.0  # a burst is instantaneous; its "duration" only spaces the plan
        elif kind == "serial_unplug":
            entry["sensor"] = str(rng.choice(serial))
        else:  # heartbeat_loss
            entry["sensor"] = str(rng.choice(mavlink))
        if kind == "gnss_jump":
            entry.update(offset_m=round(float(rng.uniform(8.0, 20.0)), 2),
                         direction_deg=round(float(rng.uniform(0.0, 360.0)), 1))
        elif kind == "gnss_drift":
            entry.update(rate_mps=round(float(rng.uniform(0.05, 0.2)), 3),
                         direction_deg=round(float(rng.uniform(0.0, 360.0)), 1))
            duration = max(duration, 3.0 / entry["rate_mps"] + 40.0)  # long enough to cross the median limit
        elif kind == "gnss_noise":
            entry["factor"] = round(float(rng.uniform(5.0, 8.0)), 2)
            duration = max(duration, 90.0)
        elif kind == "gyro_offset":
            entry["offset_deg"] = round(float(rng.choice([-1.0, 1.0]) * rng.uniform(8.0, 15.0)), 2)
        elif kind == "gyro_drift":
            entry["rate_degps"] = round(float(rng.choice([-1.0, 1.0]) * rng.uniform(0.05, 0.2)), 3)
            duration = max(duration, 2.0 / abs(entry["rate_degps"]) + 40.0)
        if kind != "malformed_burst":
            entry["duration_s"] = round(duration, 1)
        end = t + duration
        if end + RECOVERY_S > duration_s:
            break
        faults.append(entry)
        t = max(end + RECOVERY_S, t + float(rng.uniform(*FAULT_GAP_S)))
    return faults


def build_scenario(hours: float, seed: int) -> Scenario:
    """The soak scenario (supply vessel, six sensors, sea-state changes, planned faults)."""
    duration = hours * 3600.0
    from dpcontrol.models.vessels import vessel_from_config  # noqa: PLC0415

    thrusters = [t.name for t in vessel_from_config("supply", "vessel").thrusters]
    seas = [{"t_s": round(i * 6 * 3600.0, 1), **SEA_STATES[i % len(SEA_STATES)]}
            for i in range(max(1, math.ceil(hours / 6.0)))]
    return parse_scenario({
        "name": "soak", "vessel": "supply", "duration_s": duration, "seed": seed,
        "datum": {"lat_deg": 60.35, "lon_deg": 2.75}, "plant": {"rate_hz": PLANT_RATE_HZ},
        "controller": {"estimator": {"kind": "mmae", "omegas_rad_s": [0.56, 0.73, 0.80],
                                     "position_noise_std_m": 0.3, "heading_noise_std_rad": 8.7e-4},
                       "control": {"kind": "pid"}},
        "sea_states": seas, "current": {"speed_mps": 0.2, "direction_deg": 210},
        "wind": {"speed_mps": 7.0, "direction_deg": 30},
        "setpoints": [{"t_s": 0, "north_m": 0, "east_m": 0, "heading_deg": 0}],
        "sensors": SENSORS, "faults": plan_faults(duration, seed, thrusters)}, file="<soak>")


def _object_counts() -> Counter[str]:
    """Live Python objects by type (what would grow if something kept references)."""
    return Counter(type(o).__name__ for o in gc.get_objects())


def _rss_mb() -> float | None:
    """Resident set size of this process [MB] (Linux ``/proc/self/statm``), None elsewhere."""
    try:
        with open("/proc/self/statm", encoding="ascii") as handle:
            pages = int(handle.read().split()[1])
    except (OSError, ValueError, IndexError):
        return None
    return pages * os.sysconf("SC_PAGE_SIZE") / 1e6


@dataclass
class _Soak:
    """The per-step observer: NaN checks, memory samples, the operator, station-keeping statistics and
    the thrust mismatch a healthy drive model sees (detectability of the thruster faults)."""

    simulation: LockstepSimulation
    faults: tuple[Fault, ...]
    nonfinite_steps: int = 0
    first_nonfinite: dict[str, Any] | None = None
    memory: list[tuple[float, float]] = field(default_factory=list)
    reengaged: int = 0
    operator_resets: int = 0
    steps: int = 0
    error_max_m: float = 0.0
    error_sq: float = 0.0
    error_count: int = 0
    error_hist: np.ndarray = field(default_factory=lambda: np.zeros(2001, dtype=np.int64))
    mismatch_s: dict[int, float] = field(default_factory=dict)  # time the thrust mismatch exceeded the limit
    mismatch_first: dict[int, float] = field(default_factory=dict)  # when it first did

    def __post_init__(self) -> None:
        self._next_memory = 0.0
        self.objects_1h: Counter[str] | None = None
        self._controller = self.simulation.controller
        self._index = {name: i for i, name in enumerate(self.simulation.thruster_names)}
        self._thruster_faults = [(i, f) for i, f in enumerate(self.faults) if f.kind in MISMATCH_KINDS]
        self._pending_resets: list[tuple[float, str]] = sorted(
            (f.end_s + OPERATOR_RESET_DELAY_S, f.target) for f in self.faults if f.kind in MISMATCH_KINDS)
        self._busy = [(f.t_s, f.end_s + RECOVERY_S) for f in self.faults]

    def __call__(self, t_s: float, out: StepOutput) -> None:
        self.steps += 1
        self._check_finite(t_s, out)
        if t_s >= self._next_memory:
            rss = _rss_mb()
            if rss is not None:
                self.memory.append((t_s, rss))
            self._next_memory += MEMORY_EVERY_S
            if self.objects_1h is None and t_s >= 3600.0:
                self.objects_1h = _object_counts()
        controller = self._controller
        # the thrust mismatch a healthy-drive model sees during each thruster fault
        dt = self.simulation.config.sample_time_s
        fraction = self.simulation.config.thruster_monitor.mismatch_fraction
        floor_fraction = self.simulation.config.thruster_monitor.mismatch_floor_fraction
        for k, fault in self._thruster_faults:
            if fault.active(t_s):
                i = self._index[fault.target]
                health = controller.monitor._health[i]
                feedback = health.last_feedback
                rating = health.spec.max_thrust_n
                limit = mismatch_limit_n(rating, health.expected_n, fraction, floor_fraction)
                if feedback is not None and abs(feedback.thrust_n - health.expected_n) > limit:
                    self.mismatch_s[k] = self.mismatch_s.get(k, 0.0) + dt
                    self.mismatch_first.setdefault(k, t_s)
        # the operator: reset latched drives once healthy, re-engage DP after a fall-back
        while self._pending_resets and self._pending_resets[0][0] <= t_s:
            _, name = self._pending_resets.pop(0)
            if controller.monitor.reset(name):
                self.operator_resets += 1
        if controller.mode is not Mode.AUTO_POSITION and t_s > 60.0 and out.hub is not None \
                and out.hub.position_available and out.hub.heading_available \
                and not any(a <= t_s < b for a, b in self._busy):
            controller.request_mode(Mode.AUTO_POSITION)
            self.reengaged += 1
        # station keeping (true LF position − reference) while engaged
        if out.reference is not None and controller.mode is Mode.AUTO_POSITION:
            truth = self.simulation.plant.truth
            error = math.hypot(truth.north_m - float(out.reference.eta_d_ned[0]),
                               truth.east_m - float(out.reference.eta_d_ned[1]))
            self.error_max_m = max(self.error_max_m, error)
            self.error_sq += error * error
            self.error_count += 1
            self.error_hist[min(int(error / 0.01), 2000)] += 1

    def _check_finite(self, t_s: float, out: StepOutput) -> None:
        parts = {"thrust_n": out.thrust_n, "azimuth_rad": out.azimuth_rad, "tau_b": out.tau_b,
                 "tau_achieved_b": out.tau_achieved_b, "shortfall_b": out.shortfall_b}
        if out.hub is not None:
            parts["hub_y_n"] = np.asarray(out.hub.y_ned)
        if out.estimate is not None:
            parts.update(eta_hat_ned=out.estimate.eta_hat_ned, nu_hat_b=out.estimate.nu_hat_b,
                         bias_hat_b=out.estimate.bias_hat_b)
        for name, value in parts.items():
            if not np.all(np.isfinite(value)):
                self.nonfinite_steps += 1
                if self.first_nonfinite is None:
                    self.first_nonfinite = {"t_s": t_s, "output": name, "value": np.asarray(value).tolist()}
                return

    def error_percentile_m(self, q: float) -> float | None:
        total = int(self.error_hist.sum())
        if total == 0:
            return None
        index = int(np.searchsorted(np.cumsum(self.error_hist), q / 100.0 * total))
        return round(min(index, 2000) * 0.01, 2)


def _classify(result: Any, soak: _Soak) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    config = result.config
    events = result.alarm_events
    by_kind: dict[str, Counter[str]] = {kind: Counter() for kind in ALL_KINDS}
    rows = []
    for k, fault in enumerate(result.scenario.faults):
        codes, bound = expected_detection(fault, config)
        end = min(fault.end_s if math.isfinite(fault.end_s) else fault.t_s, result.steps * config.sample_time_s)
        hit = first_raise(events, codes, fault.t_s) if codes else None
        if hit is not None and hit[0] > end + RECOVERY_S:
            hit = None
        delay = None if hit is None else hit[0] - fault.t_s
        if bound is not None and fault.kind in MISMATCH_KINDS and k in soak.mismatch_first:
            bound += soak.mismatch_first[k] - fault.t_s  # detectable from when the drive's thrust goes wrong
        below_limit = fault.kind in MISMATCH_KINDS and delay is None and \
            soak.mismatch_s.get(k, 0.0) < config.thruster_monitor.mismatch_persist_s
        if not codes or bound is None or below_limit:
            outcome = "not_detectable"
        elif delay is None:
            outcome = "missed"
        elif delay <= bound + 1e-6:
            outcome = "detected"
        else:
            outcome = "late"
        by_kind[fault.kind][outcome] += 1
        rows.append({"t_s": fault.t_s, "kind": fault.kind, "target": fault.target, "outcome": outcome,
                     "delay_s": None if delay is None else round(delay, 2),
                     "bound_s": None if bound is None else round(bound, 2), "alarm": None if hit is None else hit[1]})
    totals: Counter[str] = Counter()
    for counts in by_kind.values():
        totals.update(counts)
    summary = {"injected": len(rows), **{k: totals.get(k, 0) for k in ("detected", "late", "missed",
                                                                       "not_detectable")},
               "by_kind": {kind: dict(counts) for kind, counts in by_kind.items()}}
    return summary, rows


def _unexplained_alarms(result: Any) -> dict[str, int]:
    """Alarms raised when no fault was active or recovering (false alarms), by code."""
    windows = [(f.t_s, (f.end_s if math.isfinite(f.end_s) else f.t_s) + RECOVERY_S) for f in result.scenario.faults]
    out: Counter[str] = Counter()
    for event in result.alarm_events:
        if event.raised and event.t_s > 60.0 and not any(a <= event.t_s <= b for a, b in windows):
            out[event.code] += 1
    return dict(out)


def run(hours: float = 24.0, seed: int = 1, progress: Callable[[float, float], None] | None = None) -> dict[str, Any]:
    """The soak run (see the module docstring); returns the report as a JSON-able dict."""
    scenario = build_scenario(hours, seed)

    simulation = LockstepSimulation(scenario, lockstep_config(scenario, file="<soak>"))
    soak = _Soak(simulation, scenario.faults)
    wall0 = time.perf_counter()
    error = None
    result = None
    try:
        result = simulation.run(progress=progress, observer=soak, timeseries=False)
    except Exception as exc:  # the soak reports it (with where), it does not hide it
        error = {"type": type(exc).__name__, "message": str(exc), "traceback": traceback.format_exc(),
                 "after_steps": soak.steps}
    wall = time.perf_counter() - wall0
    memory = soak.memory
    report: dict[str, Any] = {
        "hours": hours, "seed": seed, "plant_rate_hz": PLANT_RATE_HZ, "wall_s": round(wall, 1),
        "speed_x_realtime": round(hours * 3600.0 / wall, 1) if wall > 0 else None,
        "steps": soak.steps, "exception": error,
        "nonfinite_steps": soak.nonfinite_steps, "first_nonfinite": soak.first_nonfinite,
        "memory_mb": [(round(t / 3600.0, 2), round(m, 1)) for t, m in memory],
    }
    if len(memory) >= 4:
        later = [(t, m) for t, m in memory if t >= 3600.0] or memory
        hours_axis = np.array([t for t, _ in later]) / 3600.0
        values = np.array([m for _, m in later])
        slope = float(np.polyfit(hours_axis, values, 1)[0]) if len(later) >= 2 else 0.0
        report["memory_growth_mb_per_h_after_1h"] = round(slope, 3)
        report["memory_first_last_mb"] = [round(memory[0][1], 1), round(memory[-1][1], 1)]
    if soak.objects_1h is not None:
        end = _object_counts()
        growth = {k: end[k] - soak.objects_1h.get(k, 0) for k in end}
        report["objects_growth_after_1h"] = dict(sorted(((k, v) for k, v in growth.items() if v),
                                                        key=lambda kv: -abs(kv[1]))[:8])
    if result is not None:
        summary, rows = _classify(result, soak)
        report["faults"] = summary
        report["fault_log"] = rows
        report["alarms_outside_faults"] = _unexplained_alarms(result)
        report["mode_changes"] = len(result.mode_changes)
        report["fallbacks"] = sum(1 for m in result.mode_changes if m[3].startswith("fallback"))
        report["operator_reengaged"] = soak.reengaged
        report["operator_thruster_resets"] = soak.operator_resets
        report["alarm_events"] = len(result.alarm_events)
        report["decode"] = result.counters["transports"]
        report["protocol_faults_applied"] = len(result.counters["protocol_faults"])
    report["station_keeping_m"] = {
        "max": round(soak.error_max_m, 2),
        "rms": round(math.sqrt(soak.error_sq / soak.error_count), 3) if soak.error_count else None,
        "p50": soak.error_percentile_m(50.0), "p99": soak.error_percentile_m(99.0)}
    return report


def _format(report: dict[str, Any]) -> str:
    faults = report.get("faults", {})
    lines = [f"soak: {report['hours']:g} h simulated in {report['wall_s']:.0f} s ({report['speed_x_realtime']}x), "
             f"{report['steps']} steps, seed {report['seed']}",
             f"  exception: {None if report['exception'] is None else report['exception']['type']}; "
             f"non-finite steps: {report['nonfinite_steps']}",
             f"  memory: first/last {report.get('memory_first_last_mb')} MB, "
             f"growth after 1 h {report.get('memory_growth_mb_per_h_after_1h')} MB/h; "
             f"live objects grown after 1 h: {report.get('objects_growth_after_1h')}",
             f"  faults injected {faults.get('injected')}: detected {faults.get('detected')}, "
             f"late {faults.get('late')}, missed {faults.get('missed')}, not detectable {faults.get('not_detectable')}",
             f"  station keeping (LF − reference, engaged): {report['station_keeping_m']}",
             f"  alarms outside fault windows: {report.get('alarms_outside_faults')}",
             f"  fall-backs {report.get('fallbacks')}, operator re-engaged {report.get('operator_reengaged')}, "
             f"thruster resets {report.get('operator_thruster_resets')}"]
    for kind, counts in faults.get("by_kind", {}).items():
        lines.append(f"    {kind:<20} {counts}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--hours", type=float, default=24.0)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--json", action="store_true", help="print the whole report as JSON")
    parser.add_argument("--out", help="also write the JSON report to this file")
    args = parser.parse_args(argv)
    last = [time.perf_counter()]

    def progress(t: float, total: float) -> None:
        if time.perf_counter() - last[0] > 60.0:
            last[0] = time.perf_counter()
            print(f"  {t / 3600.0:6.2f} h of {total / 3600.0:g} h", file=sys.stderr, flush=True)

    report = run(args.hours, args.seed, progress)
    if args.out:
        with open(args.out, "w", encoding="utf-8") as handle:
            json.dump(report, handle, indent=1)
    print(json.dumps(report, indent=1) if args.json else _format(report))
    return 0 if report["exception"] is None and report["nonfinite_steps"] == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
