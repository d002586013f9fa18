"""The HIL operator asks for DP only once the controller's status shows what the mode needs
(:func:`sim_plant.hil_zenoh.ready_to_engage`), as an operator reads the console before pressing the button:
a request sent earlier is refused by the daemon and leaves ``operator.request_refused`` up for 10 s."""

from __future__ import annotations

from typing import Any

import pytest

from interfaces.zenoh import schemas as sc
from sim_plant.hil_zenoh import ready_to_engage

OK = [sc.SensorHealth("gnss1", "position", "ok", 0.1, 1.0), sc.SensorHealth("gyro1", "heading", "ok", 0.1, 1.0)]
THRUSTERS = [sc.ThrusterAvailability("bow", True), sc.ThrusterAvailability("main", True)]
DRIVES = sc.DrivesSeen(present=True, seen=True, feedback_age_s=0.1)


def status(**changes: Any) -> dict[str, Any]:
    """A status as the plant's subscriber receives it: encoded by the daemon's builder, parsed by the schema."""
    fields: dict[str, Any] = {"sensors": OK, "thrusters": THRUSTERS, "drives": DRIVES, **changes}
    message = sc.parse_message("status", sc.status_payload(t_s=1.0, seq=1, mode="standby", **fields))
    assert isinstance(message, dict), message
    return message


def test_a_ready_controller_may_be_engaged_in_either_mode() -> None:
    assert ready_to_engage(status(), "auto_position")
    assert ready_to_engage(status(), "auto_heading")


@pytest.mark.parametrize("changes", [
    {"drives": sc.DrivesSeen(present=False, seen=False, feedback_age_s=None)},
    {"thrusters": [sc.ThrusterAvailability("bow", False, "no feedback"),
                   sc.ThrusterAvailability("main", False, "no feedback")]},
    {"sensors": [OK[0], sc.SensorHealth("gyro1", "heading", "waiting")]},
    {"sensors": [OK[1]]},
    {"sensors": [sc.SensorHealth("gnss1", "position", "stale"), OK[1]]},
], ids=["drives-absent", "no-thruster", "heading-waiting", "no-position-sensor", "position-stale"])
def test_auto_position_waits_for_what_it_needs(changes: dict[str, Any]) -> None:
    assert not ready_to_engage(status(**changes), "auto_position")


def test_auto_heading_needs_no_position_reference() -> None:
    assert ready_to_engage(status(sensors=[OK[1]]), "auto_heading")
    assert not ready_to_engage(status(sensors=[OK[0]]), "auto_heading")


def test_a_status_without_the_drives_record_is_judged_on_the_rest() -> None:
    """(an older daemon's status carries no ``drives``: its thrusters' availability still says)"""
    assert ready_to_engage(status(drives=None), "auto_position")
