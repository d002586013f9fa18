"""How a run's fault detections are read from its alarm events (``summary.json`` ``fault_detections``)."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import pytest

from dpcontrol.runtime.alarms import AlarmEvent, Severity
from dpcontrol.runtime.config import load_config
from sim_plant.bench.report import fault_detections
from sim_plant.faults import Fault

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize(("duration_s", "detected_s"), [(None, 217.0), (None, 205.0), (100.0, 217.0)])
def test_a_late_detection_is_reported_with_its_delay_not_as_none(duration_s: float | None,
                                                                  detected_s: float) -> None:
    """A drive that lost its propeller for good (thruster_zero, no end) and was found 17 s later, beyond its
    bound: the delay is reported (the reader compares it with the bound), not left empty as if never found."""
    config = load_config(ROOT / "deploy" / "config" / "shuttle_tanker.yaml")
    fault = Fault(t_s=200.0, kind="thruster_zero", target="bow_azimuth", duration_s=duration_s)
    code = "thruster.bow_azimuth.unavailable"
    events = [AlarmEvent(150.0, "position.deviation.warning", Severity.WARNING, "", True),
              AlarmEvent(detected_s, code, Severity.ALARM, "", True)]
    result = SimpleNamespace(scenario=SimpleNamespace(faults=[fault]), config=config, alarm_events=events)
    (detection,) = fault_detections(result)  # type: ignore[arg-type]
    assert detection.detected_s == pytest.approx(detected_s - 200.0) and detection.code == code
    assert detection.bound_s is not None and detection.bound_s < 17.0  # later than its bound, and said so
