"""A rate-of-turn sensor (kind rate_of_turn) in the daemon's configuration, its routing, the hub's rot_* settings,
and the plant's ``rot`` sensor in a scenario: accepted where it belongs, refused with the key path elsewhere."""

from __future__ import annotations

import copy
import math
from typing import Any

import pytest

from dpbase.schema import ConfigError
from dpcontrol.runtime.config import parse_config
from dpcontrol.runtime.hub import SensorKind
from dpcontrol.runtime.inputs import SensorRouter
from interfaces.messages import Heading, RateOfTurn
from sim_plant.scenario import parse_scenario
from sim_plant.sensors import RotSpec

BASE: dict[str, Any] = {
    "vessel_id": "cs2",
    "vessel": "cybership2",
    "transports": [{"name": "serial", "protocol": "nmea0183", "port": "/dev/ttyUSB0", "baud": 38400},
                   {"name": "can0", "protocol": "nmea2000", "interface": "socketcan", "channel": "can0"}],
    "sensors": [{"name": "gnss1", "kind": "position", "transport": "serial", "rate_hz": 5, "sigma_m": 0.5},
                {"name": "gyro1", "kind": "heading", "transport": "serial", "sigma_deg": 0.1},
                {"name": "rot1", "kind": "rate_of_turn", "transport": "serial", "talker": "TI", "sigma_degps": 0.01},
                {"name": "rot2", "kind": "rate_of_turn", "transport": "can0", "source_address": 9}],
}


def test_a_rate_of_turn_sensor_is_configured_and_routed_apart_from_the_gyro() -> None:
    config = parse_config(copy.deepcopy(BASE))
    sensors = {s.name: s for s in config.sensors}
    assert sensors["rot1"].kind is SensorKind.RATE and sensors["rot1"].sigma == pytest.approx(math.radians(0.01))
    assert sensors["rot2"].sigma == pytest.approx(math.radians(0.05))  # the default
    router = SensorRouter(config.routes, config.transports)
    assert router.nmea0183("serial", "TIROT", RateOfTurn(0.01)) == "rot1"
    assert router.nmea0183("serial", "HEROT", RateOfTurn(0.01)) == "gyro1"  # the gyro's own rate stays its own
    assert router.nmea0183("serial", "HEHDT", Heading(1.0)) == "gyro1"
    assert router.nmea2000("can0", 9, RateOfTurn(0.01)) == "rot2"
    assert router.nmea2000("can0", 9, Heading(1.0)) is None  # a rate sensor takes no heading


def test_the_hubs_rate_of_turn_settings_are_parsed_in_their_units() -> None:
    config = copy.deepcopy(BASE)
    config["hub"] = {"rot_bias_window_s": 120, "rot_freeze_s": 0.5, "rot_max_degps": 10, "rot_sigma_degps": 0.02}
    hub = parse_config(config).hub
    assert hub.rot_bias_window_s == 120.0 and hub.rot_freeze_s == 0.5
    assert hub.rot_max_radps == pytest.approx(math.radians(10.0))
    assert hub.rot_sigma_radps == pytest.approx(math.radians(0.02))


def test_the_rate_checks_settings_are_parsed_in_their_units() -> None:
    config = copy.deepcopy(BASE)
    config["hub"] = {"rot_check_window_s": 60, "rot_check_sigma_factor": 4, "rot_check_min_deg": 2.0,
                     "rot_check_return_s": 20}
    hub = parse_config(config).hub
    assert hub.rot_check_window_s == 60.0 and hub.rot_check_sigma_factor == 4.0 and hub.rot_check_return_s == 20.0
    assert hub.rot_check_min_rad == pytest.approx(math.radians(2.0))
    defaults = parse_config(copy.deepcopy(BASE)).hub
    assert (defaults.rot_check_window_s, defaults.rot_check_sigma_factor, defaults.rot_check_return_s) == (30, 5, 10)
    assert defaults.rot_check_min_rad == pytest.approx(math.radians(1.0))


@pytest.mark.parametrize(("edit", "path_expected"), [
    (lambda c: c["sensors"][2].update(sigma_degps=0), "sensors[2].sigma_degps"),
    (lambda c: c["sensors"][2].update(sigma_degps=100), "sensors[2].sigma_degps"),
    (lambda c: c["sensors"][2].update(sigma_deg=0.1), "sensors[2].sigma_deg"),
    (lambda c: c["sensors"][2].update(sentences=["HDT"]), "sensors[2].sentences[0]"),
    (lambda c: c.update(hub={"rot_bias_window_s": 0}), "hub.rot_bias_window_s"),
    (lambda c: c.update(hub={"rot_max_degps": -1}), "hub.rot_max_degps"),
    (lambda c: c.update(hub={"rot_freeze_s": "long"}), "hub.rot_freeze_s"),
    (lambda c: c.update(hub={"rot_check_window_s": 0}), "hub.rot_check_window_s"),
    (lambda c: c.update(hub={"rot_check_sigma_factor": -5}), "hub.rot_check_sigma_factor"),
    (lambda c: c.update(hub={"rot_check_min_deg": 0}), "hub.rot_check_min_deg"),
    (lambda c: c.update(hub={"rot_check_return_s": "soon"}), "hub.rot_check_return_s"),
    # a rate sensor is no heading reference
    (lambda c: c.update(sensors=[c["sensors"][0], c["sensors"][2]]), "sensors"),
])
def test_a_bad_rate_of_turn_setting_is_refused_with_its_key_path(edit: Any, path_expected: str) -> None:
    config = copy.deepcopy(BASE)
    edit(config)
    with pytest.raises(ConfigError) as error:
        parse_config(config)
    assert str(error.value).startswith(path_expected + ":"), str(error.value)


SCENARIO: dict[str, Any] = {
    "name": "rot", "vessel": "supply", "duration_s": 10,
    "sensors": [{"name": "gnss1", "kind": "gnss"}, {"name": "gyro1", "kind": "gyro"},
                {"name": "rot1", "kind": "rot", "protocol": "nmea2000", "noise_degps": 0.02, "bias_degps": -0.05}],
}


def test_a_scenarios_rot_sensor_and_its_faults() -> None:
    scenario = dict(SCENARIO, faults=[{"t_s": 1, "kind": "rot_offset", "sensor": "rot1", "rate_degps": 0.1},
                                      {"t_s": 2, "kind": "gyro_freeze", "sensor": "gyro1", "duration_s": 1}])
    parsed = parse_scenario(scenario)
    spec = parsed.sensor("rot1")
    assert isinstance(spec, RotSpec) and spec.protocol == "nmea2000"
    assert spec.noise_radps == pytest.approx(math.radians(0.02))
    assert spec.bias_radps == pytest.approx(math.radians(-0.05))
    assert parsed.faults[0].rate_radps == pytest.approx(math.radians(0.1))


@pytest.mark.parametrize(("fault", "expected"), [
    ({"t_s": 1, "kind": "rot_freeze", "sensor": "gyro1"}, "faults[0].sensor: expected a rot (rate-of-turn) sensor"),
    ({"t_s": 1, "kind": "gyro_freeze", "sensor": "rot1"}, "faults[0].sensor: expected a gyro sensor"),
])
def test_a_fault_of_the_wrong_sensor_kind_is_refused(fault: dict[str, Any], expected: str) -> None:
    with pytest.raises(ConfigError) as error:
        parse_scenario(dict(SCENARIO, faults=[fault]))
    assert str(error.value).startswith(expected), str(error.value)


def test_a_scenarios_rot_noise_out_of_range_is_refused() -> None:
    scenario = copy.deepcopy(SCENARIO)
    scenario["sensors"][2]["noise_degps"] = 100
    with pytest.raises(ConfigError, match=r"sensors\[2\]\.noise_degps"):
        parse_scenario(scenario)


@pytest.mark.parametrize("protocol", ["nmea0183", "nmea2000", "mavlink"])
def test_a_rot_sensor_reaches_the_hub_over_each_protocol_beside_a_gyro_on_the_same(protocol: str) -> None:
    """$TIROT, PGN 127251 and MAVLink ATTITUDE yawspeed, through the encoders, the daemon's decoders and router: every
    sample reaches the rate sensor (none taken by the gyro on the same port, bus or link), and its bias is learnt."""
    from sim_plant.bench.lockstep import ProbedRun  # noqa: PLC0415 - a lockstep run, only here
    from sim_plant.bench.run import build_simulation  # noqa: PLC0415

    scenario = {"name": "rot-protocols", "vessel": "supply", "duration_s": 40, "seed": 2,
                "sensors": [{"name": "gnss1", "kind": "gnss", "protocol": protocol},
                            {"name": "gyro1", "kind": "gyro", "protocol": protocol},
                            {"name": "rot1", "kind": "rot", "protocol": protocol, "bias_degps": 0.05}]}
    run = ProbedRun.run(build_simulation(parse_scenario(scenario)))
    hub = run.simulation.controller.hub
    rate = hub._rate_sensors["rot1"]
    assert rate.samples >= 395 and rate.rejected_samples == 0
    assert hub._tracks["gyro1"].rate is not None and hub._tracks["gyro1"].rate.samples >= 395
    assert rate.bias_time_s > 0.0 and abs(math.degrees(rate.bias) - 0.05) < 0.02


def test_the_plants_rate_gyro_has_its_own_faults_and_ignores_the_gyros() -> None:
    import numpy as np  # noqa: PLC0415

    from sim_plant.faults import Fault  # noqa: PLC0415
    from sim_plant.sensors import InvalidFix, RotSensor  # noqa: PLC0415

    spec = RotSpec("rot1", noise_radps=0.0, bias_radps=0.001)
    faults = [Fault(1.0, "gyro_freeze", "gyro1", 10.0), Fault(2.0, "rot_offset", "rot1", 1.0, rate_radps=0.01),
              Fault(3.0, "rot_freeze", "rot1", 1.0), Fault(4.0, "rot_invalid", "rot1", 1.0),
              Fault(5.0, "rot_dropout", "rot1", 1.0)]
    sensor = RotSensor(spec, np.random.default_rng(1), faults)

    def at(t: float, rate: float) -> list[object]:
        while sensor.next_time_s < t - 1e-9:
            sensor.sample(sensor.next_time_s, 0.0, rate)
        return [s.message for s in sensor.sample(sensor.next_time_s, 0.0, rate)]

    assert at(1.5, 0.02)[0] == RateOfTurn(0.021)  # a gyro fault: the rate gyro runs on
    assert at(2.5, 0.02)[0].rate_radps == pytest.approx(0.031)  # type: ignore[attr-defined]
    frozen = at(3.0, 0.02)[0]
    assert at(3.5, 0.5)[0] == frozen  # frozen
    assert isinstance(at(4.5, 0.02)[0], InvalidFix)
    assert at(5.5, 0.02) == []
    assert at(6.5, -0.01)[0].rate_radps == pytest.approx(-0.009)  # type: ignore[attr-defined]
