"""The real-time loop itself: speed and duration, and a loop that stalls and catches up."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

from sim_plant.emulator import HilOptions

DURATION_S = 3.0
STALL_S = 1.6


def _files(tmp_path: Path, rig: Any, duration_s: float) -> tuple[Path, Path]:
    controller = rig.write_yaml(tmp_path / "vessel.yaml", {
        "vessel_id": "rt",
        "transports": [{"name": "serial0", "protocol": "nmea0183", "port": str(tmp_path / "ttyNAV")}],
        "sensors": [{"name": "gnss1", "kind": "position", "transport": "serial0"},
                    {"name": "gyro1", "kind": "heading", "transport": "serial0"}],
        "zenoh": {"listen": [f"tcp/127.0.0.1:{rig.free_port()}"]},
    })
    scenario = rig.write_yaml(tmp_path / "scenario.yaml", {
        "name": "rt", "vessel": "cybership2", "duration_s": duration_s,
        "sensors": [{"name": "gnss1", "kind": "gnss", "rate_hz": 10}, {"name": "gyro1", "kind": "gyro", "rate_hz": 10}],
    })
    return scenario, controller


def test_speed_and_duration(tmp_path: Path, rig: Any) -> None:
    scenario, controller = _files(tmp_path, rig, 100.0)
    run = rig.EmulatorRun(scenario, controller, HilOptions(speed=5.0, duration_s=2.5))
    try:
        start = time.monotonic()
        summary = run.start().join()
        wall = time.monotonic() - start
    finally:
        run.close()
    assert summary["duration_s"] == 2.5 and summary["stopped_by"] == "duration"
    assert 0.5 - 0.05 <= summary["wall_s"] <= wall and wall < 0.5 + 5.0  # 2.5 s of plant time at 5×
    assert summary["counts"]["truth_rows"] == summary["counts"]["feedback_published"] == 26
    assert summary["sensors"]["gnss1"]["samples"] == summary["sensors"]["gyro1"]["samples"] == 26
    assert summary["loop"]["catchups"] == 0


def test_a_stalled_loop_jumps_to_the_present_and_still_ends_on_time(tmp_path: Path, rig: Any) -> None:
    scenario, controller = _files(tmp_path, rig, DURATION_S)
    stalled: list[float] = []

    def record(topic: str, t_s: float, payload: object) -> None:
        if topic == "feedback" and t_s >= 1.0 and not stalled:
            stalled.append(t_s)
            time.sleep(STALL_S)  # a deliberate stall of the loop thread (a suspended process), not a wait

    run = rig.EmulatorRun(scenario, controller, HilOptions(out_dir=tmp_path / "out"), record=record)
    try:
        summary = run.start().join()
    finally:
        run.close()
    loop = summary["loop"]
    assert stalled and loop["catchups"] == 1 and loop["missed_deadlines"] >= 1
    assert loop["lateness_ms"]["max"] >= 1e3 * (STALL_S - 0.2)
    assert summary["duration_s"] == DURATION_S and summary["stopped_by"] == "duration"
    # the gap was integrated in one go: its samples were skipped (counted), not sent in a burst
    sent = summary["sensors"]["gnss1"]["samples"]
    skipped = summary["counts"]["samples_skipped"]
    assert skipped >= 2 * 10 * (STALL_S - 1.0 - 0.2)  # two sensors at 10 Hz, at least the beyond-catch-up part
    assert sent + skipped / 2 == round(DURATION_S * 10) + 1
    rows = (tmp_path / "out" / "truth.csv").read_text().splitlines()[1:]
    times = [float(r.split(",")[0]) for r in rows]
    assert times == sorted(times) and times[-1] == DURATION_S and len(times) < round(DURATION_S * 10) + 1
