"""A controlled mode is refused — the request answered ``refused`` with the reason, ``thrusters.insufficient``
(critical) raised — when no thruster is available or those left cannot produce the mode's degrees of freedom;
the alarm clears when the thrusters are back. CyberShip II (bow tunnel, two propellers with rudders), the
controller's own step with sensor samples and drive feedback, as the daemon runs it."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from dpbase.geodesy import LocalFrame
from dpbase.requests import SetpointRequest
from dpcontrol.runtime.alarms import Severity
from dpcontrol.runtime.config import parse_config
from dpcontrol.runtime.step import DpController, Mode
from dpcontrol.runtime.thruster_monitor import ThrusterFeedback
from interfaces.messages import FixQuality, Heading, Measurement, PositionFix

DT = 0.1
ROOT = Path(__file__).resolve().parents[2]
FRAME = LocalFrame(63.43, 10.39)


def _controller() -> DpController:
    return DpController(parse_config({
        "vessel_id": "t", "vessel": "cybership2", "datum": {"lat_deg": 63.43, "lon_deg": 10.39},
        "loop": {"rate_hz": 10},
        "transports": [{"name": "serial0", "protocol": "nmea0183", "port": "none"}],
        "sensors": [{"name": "gnss1", "kind": "position", "transport": "serial0", "sigma_m": 0.01},
                    {"name": "gyro1", "kind": "heading", "transport": "serial0", "sigma_deg": 0.01}]}))


def _run(controller: DpController, t: float, seconds: float, ready: dict[str, bool] | None = None,
         requests: list[SetpointRequest] | None = None) -> float:
    """Step ``seconds`` from ``t`` with still-vessel samples and drives delivering what was commanded."""
    for k in range(round(seconds / DT)):
        wiggle = 1e-3 * math.sin(3.0 * t)  # (identical samples would be frozen)
        samples = [Measurement(t, "gnss1", PositionFix(*FRAME.surface_to_geodetic(wiggle, 0.0), FixQuality.DGPS)),
                   Measurement(t, "gyro1", Heading(0.1 + wiggle))]
        feedback = [ThrusterFeedback(spec.name, float(controller.out.thrust_n[i]), float(controller.out.azimuth_rad[i]),
                                     True if ready is None else ready.get(spec.name, True), t)
                    for i, spec in enumerate(controller.thrusters)]
        controller.step(t, samples, feedback, requests if (requests and k == 0) else ())
        t += DT
    return t


def test_auto_position_with_every_thruster_unavailable_is_refused_with_a_critical_alarm() -> None:
    controller = _controller()
    t = _run(controller, 0.0, 3.0)
    names = [spec.name for spec in controller.thrusters]
    down = dict.fromkeys(names, False)
    t = _run(controller, t, 1.0, ready=down)
    assert not controller.monitor.available.any()
    t = _run(controller, t, 0.5, ready=down, requests=[SetpointRequest(t_s=t, seq=1, mode="auto_position")])
    assert controller.mode is Mode.STANDBY
    outcome = controller.last_request
    assert outcome is not None and outcome.seq == 1 and outcome.outcome == "refused"
    assert "auto_position refused: no thruster available" in outcome.detail
    alarm = [a for a in controller.alarms.active() if a.code == "thrusters.insufficient"]
    assert len(alarm) == 1 and alarm[0].severity is Severity.CRITICAL
    # auto_heading too
    t = _run(controller, t, 0.5, ready=down, requests=[SetpointRequest(t_s=t, seq=2, mode="auto_heading")])
    assert controller.mode is Mode.STANDBY and controller.last_request.outcome == "refused"  # type: ignore[union-attr]
    # the drives report ready again: back in the allocation after readmit_s, the alarm clears, DP engages
    t = _run(controller, t, controller.monitor.readmit_s + 1.0)
    assert controller.monitor.available.all()
    assert not controller.alarms.is_active("thrusters.insufficient")
    t = _run(controller, t, 0.5, requests=[SetpointRequest(t_s=t, seq=3, mode="auto_position")])
    assert controller.mode is Mode.AUTO_POSITION and controller.last_request.outcome == "applied"  # type: ignore[union-attr]


def test_a_tunnel_thruster_alone_may_hold_heading_but_not_position() -> None:
    controller = _controller()
    t = _run(controller, 0.0, 3.0)
    only_bow = {spec.name: spec.name == "bow_tunnel" for spec in controller.thrusters}
    t = _run(controller, t, 1.0, ready=only_bow)
    assert controller.monitor.available.tolist() == [spec.name == "bow_tunnel" for spec in controller.thrusters]
    t = _run(controller, t, 0.5, ready=only_bow, requests=[SetpointRequest(t_s=t, seq=1, mode="auto_position")])
    assert controller.mode is Mode.STANDBY
    detail = controller.last_request.detail  # type: ignore[union-attr]
    assert "cannot produce surge, sway and yaw" in detail and "bow_tunnel" in detail
    assert controller.alarms.is_active("thrusters.insufficient")
    t = _run(controller, t, 0.5, ready=only_bow, requests=[SetpointRequest(t_s=t, seq=2, mode="auto_heading")])
    assert controller.mode is Mode.AUTO_HEADING
    assert np.isfinite(controller.out.thrust_n).all()


@pytest.mark.parametrize("example", sorted(p.stem for p in (ROOT / "deploy" / "config").glob("*.yaml")))
def test_every_example_vessel_may_engage_with_all_its_thrusters(example: str) -> None:
    config = yaml.safe_load((ROOT / "deploy" / "config" / f"{example}.yaml").read_text(encoding="utf-8"))
    controller = DpController(parse_config(config))
    everything = np.ones(len(controller.thrusters), dtype=bool)
    modes = [Mode.AUTO_HEADING] if controller.rudder_steering else [Mode.AUTO_POSITION, Mode.AUTO_HEADING]
    for mode in modes:
        assert controller._judge_thrusters(everything, mode) == ""
    assert controller._judge_thrusters(np.zeros_like(everything), modes[0]) == "no thruster available"
