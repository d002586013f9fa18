"""``dpcontrol bench``: latency of the full control cycle, per stage.

One cycle as the daemon runs it: decode the sensor bytes that arrived (NMEA 0183 GGA + GST from a
GNSS, THS + ROT from a gyro) → route → sensor hub → MMAE wave filter (N = 8 models, 15 states)
→ reference model → MRAC → QP thrust allocation for six azimuth thrusters → encode the command and
publish it on a real (loopback, unconnected) Zenoh session. The vessel is the supply vessel with its
thrusters replaced by six azimuths, in a moderate sea: a slowly turning, drifting pose with wave
motion, so the filter, the controller and the allocator all work.

Timings are wall-clock (``time.perf_counter_ns``) per iteration; the report gives median, p99 and
max in µs per stage and for the whole cycle.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping
from typing import Any

import numpy as np

from dpbase.geodesy import LocalFrame
from dpcontrol.models.thrusters import ThrusterSpec
from dpcontrol.models.vessels import SUPPLY, VesselData
from dpcontrol.platform_info import cpu_times, describe, describe_steal, host_steal, machine_info
from dpcontrol.runtime.config import DaemonConfig, parse_config
from dpcontrol.runtime.ingest import transport_inputs
from dpcontrol.runtime.inputs import SensorRouter
from dpcontrol.runtime.step import DpController, Mode
from interfaces.messages import FixQuality, Heading, Measurement, PositionErrorStats, PositionFix, RateOfTurn
from interfaces.nmea0183 import encode_gga, encode_gst, encode_rot, encode_ths
from interfaces.zenoh import schemas

STAGES = ("decode", "hub", "estimator", "control", "allocation", "encode_publish")


def _six_azimuth_vessel() -> VesselData:
    from dataclasses import replace  # noqa: PLC0415

    positions = [(30.0, -4.0), (30.0, 4.0), (0.0, -7.0), (0.0, 7.0), (-33.0, -4.5), (-33.0, 4.5)]
    thrusters = tuple(
        ThrusterSpec(f"azimuth_{i + 1}", "azimuth", x_m=x, y_m=y, max_thrust_n=250e3, min_thrust_n=0.0,
                     thrust_rate_limit_nps=50e3, time_constant_s=2.0, azimuth_rate_limit_radps=math.radians(12.0))
        for i, (x, y) in enumerate(positions))
    return replace(SUPPLY, name="supply_6az", thrusters=thrusters)


def bench_config(control: Mapping[str, Any] | None = None) -> DaemonConfig:
    """The configuration of the benchmark vessel (six azimuths, MMAE N = 8, MRAC; ``control`` another section)."""
    mapping: dict[str, Any] = {
        "vessel_id": "bench",
        "vessel": _six_azimuth_vessel(),
        "datum": {"lat_deg": 60.0, "lon_deg": 5.0},
        "loop": {"rate_hz": 10, "initial_mode": "auto_position"},
        "transports": [{"name": "serial", "protocol": "nmea0183", "port": "bench"}],
        "sensors": [{"name": "gnss1", "kind": "position", "transport": "serial", "rate_hz": 10, "sigma_m": 0.5},
                    {"name": "gyro1", "kind": "heading", "transport": "serial", "rate_hz": 10, "sigma_deg": 0.1}],
        "estimator": {"kind": "mmae", "omegas_rad_s": [0.3, 0.45, 0.6, 0.75, 0.9, 1.05, 1.2, 1.35]},
        "control": dict(control) if control is not None else {"kind": "mrac"},
    }
    return parse_config(mapping, file="<bench>")


def _sentences(n: int, dt: float) -> list[bytes]:
    """Pre-encoded sensor traffic for ``n`` cycles (what the serial ports would deliver)."""
    frame = LocalFrame(60.0, 5.0)
    rng = np.random.default_rng(1)
    out = []
    for k in range(n):
        t = k * dt
        north = 2.0 * math.sin(0.01 * t) + 0.8 * math.sin(0.8 * t) + 0.3 * rng.standard_normal()
        east = 1.5 * math.cos(0.013 * t) + 0.5 * math.sin(0.7 * t + 1.0) + 0.3 * rng.standard_normal()
        heading = math.radians(10.0 * math.sin(0.005 * t) + 1.0 * math.sin(0.9 * t))
        lat, lon = frame.surface_to_geodetic(north, east)
        utc = 36000.0 + t
        out.append(encode_gga(PositionFix(lat, lon, FixQuality.DGPS, utc, 12, 0.8, 0.0), "GP", utc)
                   + encode_gst(PositionErrorStats(0.5, 0.5, 1.0, 0.5, utc), "GP", utc)
                   + encode_ths(Heading(heading % (2.0 * math.pi)), "HE")
                   + encode_rot(RateOfTurn(math.radians(0.9) * math.cos(0.9 * t)), "HE"))
    return out


def run_bench(iterations: int = 3000, warmup: int = 200, publish: bool = True) -> dict[str, Any]:
    """Time ``iterations`` control cycles (after ``warmup`` untimed ones).

    Returns
    -------
    dict
        ``{"iterations", "machine", "stages": {stage: {median_us, p99_us, max_us}}, "cycle": {...}, "host_steal"}``
        (``machine``: :func:`~dpcontrol.platform_info.machine_info`, read before the run; ``host_steal``:
        :func:`~dpcontrol.platform_info.host_steal` over the run, None where it cannot be read).

    Raises
    ------
    ValueError
        ``iterations`` < 1 or ``warmup`` < 0.
    """
    if iterations < 1 or warmup < 0:
        raise ValueError(f"run_bench needs iterations >= 1 and warmup >= 0, got {iterations} and {warmup}")
    machine = machine_info()
    config = bench_config()
    wave_filter = config.estimator.wave_filter
    if wave_filter is None:  # (the report names its number of models; bench_config selects the MMAE filter)
        raise RuntimeError(f"the bench configuration has no wave filter (estimator {config.estimator.kind!r})")
    controller = DpController(config, stage_clock=time.perf_counter)
    # the input stage the lockstep and replay read through (decode, count, route)
    serial = transport_inputs(config.transports, SensorRouter(config.routes, config.transports))["serial"]
    dt = config.sample_time_s
    traffic = _sentences(iterations + warmup, dt)
    names = [t.name for t in config.vessel.thrusters]
    node = publisher = None
    if publish:
        from interfaces.zenoh.node import ZenohNode  # noqa: PLC0415
        from interfaces.zenoh.session_config import ZenohConfig  # noqa: PLC0415

        node = ZenohNode(ZenohConfig(mode="peer"), "bench")
        publisher = node.publisher("command")
    timings = np.zeros((iterations, len(STAGES) + 1))
    measurements: list[Measurement] = []
    clock = time.perf_counter_ns
    ticks = cpu_times()
    try:
        for k in range(iterations + warmup):
            t = k * dt
            c0 = clock()
            measurements.clear()
            serial.feed(t, traffic[k], measurements)
            c1 = clock()
            out = controller.step(t, measurements)
            c2 = clock()
            payload = schemas.command_payload(t_s=t, seq=k, mode=out.mode.value, names=names,
                                              thrust_n=out.thrust_n, azimuth_rad=out.azimuth_rad,
                                              enabled=out.enabled)
            if publisher is not None:
                publisher.put(payload)
            c3 = clock()
            if k >= warmup:
                row = timings[k - warmup]
                stage = controller.stage_us
                row[0] = (c1 - c0) / 1e3
                row[1] = stage.get("hub", 0.0)
                row[2] = stage.get("estimator", 0.0)
                row[3] = stage.get("control", 0.0)
                row[4] = stage.get("allocation", 0.0) + stage.get("finish", 0.0)
                row[5] = (c3 - c2) / 1e3
                row[6] = (c3 - c0) / 1e3
    finally:
        if node is not None:
            node.close()
    steal = host_steal(ticks, cpu_times())
    if controller.mode is not Mode.AUTO_POSITION:
        raise RuntimeError(f"the bench vessel did not reach DP (mode {controller.mode.value})")

    def stats(values: np.ndarray) -> dict[str, float]:
        return {"median_us": round(float(np.median(values)), 1), "p99_us": round(float(np.percentile(values, 99)), 1),
                "max_us": round(float(np.max(values)), 1)}

    return {"iterations": iterations, "machine": machine, "vessel": config.vessel.name, "thrusters": len(names),
            "estimator": f"{config.estimator.kind} N={len(wave_filter.omegas_rad_s)}",
            "control": config.control.kind,
            "stages": {name: stats(timings[:, i]) for i, name in enumerate(STAGES)},
            "cycle": stats(timings[:, -1]), "host_steal": steal}


def format_bench(result: dict[str, Any]) -> str:
    """A human-readable table of :func:`run_bench`'s result."""
    lines = [f"dpcontrol bench — {result['iterations']} cycles, {result['vessel']} ({result['thrusters']} azimuths), "
             f"{result['estimator']}, {result['control']}",
             f"{'stage':<16}{'median µs':>12}{'p99 µs':>12}{'max µs':>12}"]
    for name, s in [*result["stages"].items(), ("full cycle", result["cycle"])]:
        lines.append(f"{name:<16}{s['median_us']:>12.1f}{s['p99_us']:>12.1f}{s['max_us']:>12.1f}")
    lines.append(describe(result["machine"]))
    lines.append(f"during the run: {describe_steal(result['host_steal'])}")
    return "\n".join(lines)
