"""Fault case 12: an operator setpoint 1 km away, and a garbage setpoint message.

* In lockstep (``sim_plant/scenarios/faults/12-setpoint-far.yaml``): the reference moves to the far target
  at the guidance limits and the demanded force has no spike — per step it changes no more than in the
  station-keeping part of the run plus what the drives can change in one step (before the runtime fed
  the controller a jerk-limited reference acceleration, the supply vessel's surge demand jumped 65 kN in
  one step, six times that) — and no thrust command changes faster than its drive's rate limit.
* The daemon in-process with Zenoh on loopback: a garbage setpoint payload is rejected by
  ``interfaces.zenoh.schemas.parse_setpoint`` and the daemon raises ``operator.setpoint_rejected`` in its
  status; nothing of the request is applied.
"""

from __future__ import annotations

import threading
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from status_sink import StatusSink

from dpcontrol.runtime.config import parse_config
from dpcontrol.service.daemon import Daemon
from interfaces.messages import Rejected
from interfaces.systemd import SystemdNotifier
from interfaces.zenoh import schemas
from interfaces.zenoh.loopback import free_tcp_port
from interfaces.zenoh.node import ZenohNode
from interfaces.zenoh.session_config import ZenohConfig
from sim_plant.bench.lockstep import ProbedRun
from sim_plant.bench.run import build_simulation
from sim_plant.scenario import load_scenario

FAULTS = Path(__file__).resolve().parents[2] / "sim_plant" / "scenarios" / "faults"
DT = 0.1
WAIT_S = 30.0  # generous bound for zenoh on a loaded 2-core machine


@pytest.fixture(scope="module")
def far() -> ProbedRun:
    return ProbedRun.run(build_simulation(load_scenario(FAULTS / "12-setpoint-far.yaml")))


def test_case12_far_setpoint_is_a_rate_limited_reference_without_a_force_spike(far: ProbedRun) -> None:
    run = far
    guidance = run.simulation.config.guidance
    north = run.col("ref_north_m")
    speed = np.abs(np.diff(north[run.between(100.0, 300.0)])) / DT
    assert speed.max() <= guidance.max_speed_mps * 1.001  # the reference travels at its speed limit
    assert north[-1] > 50.0  # and it does travel
    drives_per_step = run.simulation.controller.force_rate_b * DT
    baseline = run.force_step_n(60.0, 100.0)
    moving = run.force_step_n(100.0, 300.0)
    assert np.all(moving <= baseline + drives_per_step), (moving, baseline, drives_per_step)
    assert run.thrust_rate_excess_n() <= 1e-6
    assert np.nanmax(run.position_error_m()[run.between(60.0, 300.0)]) <= 5.0  # the vessel follows the reference
    # the deviation alarms watch the reference, not the set-point 1 km away: following it is no deviation
    assert 1000.0 - north[-1] > 500.0
    for code in ("position.deviation.warning", "position.deviation.alarm", "heading.deviation.warning"):
        assert run.events(code) == [], code


GARBAGE = [
    b"\x00\xff not json at all",
    b'{"schema": "dpcontrol.setpoint/1", "t_s": 1.0, "seq": 1, "north_m": 5.0}',            # incomplete
    b'{"schema": "dpcontrol.setpoint/1", "t_s": 1.0, "seq": 2, "north_m": 1e9, "east_m": 0}',  # out of range
]


@pytest.mark.parametrize("payload", GARBAGE)
def test_case12_parse_setpoint_rejects_garbage(payload: bytes) -> None:
    assert isinstance(schemas.parse_setpoint(payload), Rejected)


def test_case12_garbage_setpoint_raises_the_status_alarm_in_the_daemon(tmp_path: Path) -> None:
    port = free_tcp_port()
    config = parse_config({
        "vessel_id": "sp", "vessel": "cybership2", "loop": {"rate_hz": 10},
        "transports": [{"name": "serial", "protocol": "nmea0183", "port": str(tmp_path / "no-tty")}],
        "sensors": [{"name": "gnss1", "kind": "position", "transport": "serial"},
                    {"name": "gyro1", "kind": "heading", "transport": "serial"}],
        "zenoh": {"listen": [f"tcp/127.0.0.1:{port}"]}})
    daemon = Daemon(config, notifier=SystemdNotifier(environ={}))
    thread = threading.Thread(target=daemon.run, kwargs={"duration_s": 60.0, "install_signals": False})
    thread.start()
    operator = None
    try:
        operator = ZenohNode(ZenohConfig(connect=(f"tcp/127.0.0.1:{port}",)), "sp")
        statuses = StatusSink()
        operator.subscribe("status", statuses)
        assert statuses.wait_for(lambda s: True, WAIT_S) is not None  # the daemon is publishing
        setpoint = operator.publisher("setpoint")
        assert setpoint.wait_matched(WAIT_S)
        for payload in GARBAGE:
            assert setpoint.put(payload)

        def rejected_alarm(status: dict[str, Any]) -> bool:
            return any(a["code"] == "operator.setpoint_rejected" and a["active"] for a in status["alarms"])

        status = statuses.wait_for(rejected_alarm, WAIT_S)
        assert status is not None
        alarm = next(a for a in status["alarms"] if a["code"] == "operator.setpoint_rejected")
        assert alarm["text"].startswith("setpoint rejected")
        assert status["mode"] == "standby"
        assert 1 <= daemon._setpoints.stats.rejected <= len(GARBAGE)
        assert not daemon.controller._setpoint_given  # nothing of the garbage was applied
    finally:
        daemon.request_stop()
        thread.join(30.0)
        if operator is not None:
            operator.close()
    assert not thread.is_alive()
