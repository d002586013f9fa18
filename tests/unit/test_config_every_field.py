"""Fault case 13: an invalid configuration is refused at start with the key named — every sensor,
transport, thruster, hub, fall-back, thruster-monitor and consequence field, each given a value of the wrong type.

The field lists are the parsers' own key sets (written out here so that a new field without a test
shows up as a missing case in review); each case replaces one field of a valid configuration with a
string no field accepts as a number, or a number where a string is required, and must be refused by
``parse_config`` — and by the daemon's ``run`` at start (exit code 2, the key path on stderr).
"""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import pytest
import yaml

from dpbase.schema import ConfigError
from dpcontrol.cli import main
from dpcontrol.runtime.config import parse_config
from dpcontrol.runtime.hub import HubConfig

VALID: dict[str, Any] = {
    "vessel_id": "sv1",
    "vessel": {"base": "supply", "thrusters": [
        {"name": "bow", "kind": "tunnel", "x_m": 30.0, "y_m": 0.0, "max_thrust_n": 1.5e5},
        {"name": "az", "kind": "azimuth", "x_m": -30.0, "y_m": 0.0, "max_thrust_n": 3e5,
         "azimuth_rate_limit_degps": 10, "forbidden_sectors_deg": [[80, 100]]},
        {"name": "main", "kind": "propeller_rudder", "x_m": -35.0, "y_m": 0.0, "max_thrust_n": 4e5,
         "rudder_max_angle_deg": 35, "rudder_lift_per_rad": 0.8, "min_thrust_n": -2e5,
         "thrust_rate_limit_nps": 8e4, "time_constant_s": 1.5, "angle_deg": 0}]},
    "transports": [{"name": "serial", "protocol": "nmea0183", "port": "/dev/ttyUSB0", "baud": 38400},
                   {"name": "can0", "protocol": "nmea2000", "interface": "socketcan", "channel": "can0"},
                   {"name": "mav", "protocol": "mavlink", "url": "udpin:127.0.0.1:14550",
                    "heartbeat_timeout_s": 5.0}],
    "sensors": [{"name": "gnss1", "kind": "position", "transport": "serial", "rate_hz": 5, "sigma_m": 0.5,
                 "lever_arm_m": [1.0, 0.0], "talker": "GN", "sentences": ["GGA", "GST"]},
                {"name": "gnss2", "kind": "position", "transport": "mav", "rate_hz": 5, "sigma_m": 0.5,
                 "system_id": 1},
                {"name": "gyro1", "kind": "heading", "transport": "can0", "rate_hz": 10, "source_address": 7,
                 "sigma_deg": 0.1}],
    "fallback": {"dead_reckoning_limit_s": 60, "position_loss": "hold_heading", "heading_loss_limit_s": 5,
                 "heading_loss": "standby", "restore_within_s": 300},
    "thruster_monitor": {"feedback_timeout_s": 2, "mismatch_fraction": 0.25, "mismatch_floor_fraction": 0.05,
                         "mismatch_persist_s": 5,
                         "shortfall_fraction": 0.1, "shortfall_persist_s": 10},
    "consequence": {"groups": {"bus_a": ["bow", "az"]}, "period_s": 1, "averaging_s": 30, "demand_factor": 1.25,
                    "persist_s": 10, "tolerance": 0.002, "utilisation_warning": 0.9},
}

SENSOR_FIELDS = {  # (sensor index, field) → bad value
    (0, "name"): 12, (0, "kind"): 3, (0, "transport"): 1.5, (0, "rate_hz"): "fast", (0, "sigma_m"): "small",
    (0, "lever_arm_m"): "bow", (0, "talker"): 7, (0, "sentences"): "GGA", (1, "system_id"): "one",
    (2, "source_address"): "seven", (2, "sigma_deg"): "tiny", (2, "rate_hz"): 0, (2, "source_name"): 7,
}
TRANSPORT_FIELDS = {
    (0, "name"): 5, (0, "protocol"): 183, (0, "port"): 0, (0, "baud"): "fast", (0, "max_sentence_chars"): "long",
    (1, "interface"): 1, (1, "channel"): [0], (1, "options"): "fd", (1, "variation_deg"): "east",
    (2, "url"): 14550, (2, "heartbeat_timeout_s"): "long", (2, "signing_key_hex"): "secret",
}
THRUSTER_FIELDS = {
    (0, "name"): 1, (0, "kind"): "jet", (0, "x_m"): "bow", (0, "y_m"): "centre", (0, "max_thrust_n"): "max",
    (2, "min_thrust_n"): "min", (2, "thrust_rate_limit_nps"): "quick", (2, "time_constant_s"): "slow",
    (2, "angle_deg"): "ahead", (1, "azimuth_rate_limit_degps"): "quick", (1, "forbidden_sectors_deg"): [[80]],
    (2, "rudder_max_angle_deg"): "hard", (2, "rudder_lift_per_rad"): "some",
}


def _refused(config: dict[str, Any], key_path: str) -> None:
    with pytest.raises(ConfigError) as excinfo:
        parse_config(config, file="vessel.yaml")
    assert key_path in str(excinfo.value), str(excinfo.value)


def test_the_valid_configuration_is_valid() -> None:
    config = parse_config(copy.deepcopy(VALID))
    assert [s.name for s in config.sensors] == ["gnss1", "gnss2", "gyro1"]
    assert [t.name for t in config.vessel.thrusters] == ["bow", "az", "main"]


@pytest.mark.parametrize(("index", "field"), list(SENSOR_FIELDS))
def test_every_sensor_field(index: int, field: str) -> None:
    config = copy.deepcopy(VALID)
    config["sensors"][index][field] = SENSOR_FIELDS[(index, field)]
    _refused(config, f"sensors[{index}].{field}")


@pytest.mark.parametrize(("index", "field"), list(TRANSPORT_FIELDS))
def test_every_transport_field(index: int, field: str) -> None:
    config = copy.deepcopy(VALID)
    config["transports"][index][field] = TRANSPORT_FIELDS[(index, field)]
    _refused(config, f"transports[{index}].{field}")


@pytest.mark.parametrize(("index", "field"), list(THRUSTER_FIELDS))
def test_every_thruster_field(index: int, field: str) -> None:
    config = copy.deepcopy(VALID)
    config["vessel"]["thrusters"][index][field] = THRUSTER_FIELDS[(index, field)]
    _refused(config, f"vessel.thrusters[{index}].{field}")


def _hub_keys() -> list[str]:
    return [key.replace("_rad", "_deg") for key in vars(HubConfig())]


@pytest.mark.parametrize("field", _hub_keys())
def test_every_hub_field(field: str) -> None:
    for bad in ("soon", -1.0):
        config = copy.deepcopy(VALID)
        config["hub"] = {field: bad}
        _refused(config, f"hub.{field}")


@pytest.mark.parametrize(("section", "field"), [(s, f) for s in ("fallback", "thruster_monitor", "consequence")
                                               for f in VALID[s]])
def test_every_fallback_and_monitor_field(section: str, field: str) -> None:
    config = copy.deepcopy(VALID)
    config[section][field] = "never" if isinstance(VALID[section][field], (int, float)) else 42
    _refused(config, f"{section}.{field}")


def test_the_daemon_refuses_to_start_naming_the_key(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    for where, field, bad in (("sensors", "sigma_m", "small"), ("thrusters", "max_thrust_n", "max")):
        config = copy.deepcopy(VALID)
        if where == "sensors":
            config["sensors"][0][field] = bad
            key = f"sensors[0].{field}"
        else:
            config["vessel"]["thrusters"][0][field] = bad
            key = f"vessel.thrusters[0].{field}"
        path = tmp_path / "vessel.yaml"
        path.write_text(yaml.safe_dump(config))
        assert main(["run", "--config", str(path), "--duration", "1"]) == 2
        assert key in capsys.readouterr().err
