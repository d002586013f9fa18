"""Scenario files (sim_plant.scenario): shipped files parse, errors name the key path and file."""

from __future__ import annotations

import copy
import math
import pickle
from pathlib import Path

import pytest
import yaml

from dpbase.schema import ConfigError
from sim_plant.faults import FAULT_KINDS
from sim_plant.plant import Plant
from sim_plant.scenario import builtin_scenario_names, builtin_scenario_path, load_scenario, parse_scenario
from sim_plant.sensors import GnssSpec, GyroSpec

SHIPPED = ["bluelady-seed004", "cs2-seed000", "demo", "mariner-seed002", "supply-seed001", "tanker-seed003"]

BASE = {
    "name": "t",
    "vessel": "supply",
    "duration_s": 60,
    "sea_states": [{"t_s": 0, "hs_m": 1.0, "omega_peak_rad_s": 0.8},
                   {"t_s": 100, "hs_m": 2.0, "tp_s": 9.0, "spectrum": "pierson_moskowitz"}],
    "sensors": [{"name": "gnss1", "kind": "gnss"}, {"name": "gyro1", "kind": "gyro"},
                {"name": "gnss2", "kind": "gnss", "protocol": "mavlink"}],
}


def _with(path: str, value: object) -> dict:
    data = copy.deepcopy(BASE)
    node: object = data
    keys = path.split(".")
    for key in keys[:-1]:
        node = node[int(key)] if isinstance(node, list) else node.setdefault(key, {})  # type: ignore[index]
    last = keys[-1]
    if isinstance(node, list):
        node[int(last)] = value
    else:
        node[last] = value  # type: ignore[index]
    return data


def test_every_shipped_scenario_parses_and_runs() -> None:
    assert builtin_scenario_names() == SHIPPED
    for name in SHIPPED:
        scenario = load_scenario(builtin_scenario_path(name))
        assert scenario.name == name
        assert scenario.source is not None and scenario.source.endswith(f"{name}.yaml")
        assert "estimator" in scenario.controller and "control" in scenario.controller
        plant = Plant(scenario)
        plant.advance(2.0)
        assert plant.sensor_samples(2.0)


def test_seed_scenarios_carry_the_papers_numbers() -> None:
    cs2 = load_scenario(builtin_scenario_path("cs2-seed000"))
    assert cs2.sea_states[0].omega_peak_rad_s == 0.93
    assert cs2.setpoint_at(39.9).north_m == 0.0 and cs2.setpoint_at(40.0).north_m == 10.0
    supply = load_scenario(builtin_scenario_path("supply-seed001"))
    assert [s.t_s for s in supply.sea_states] == [0, 500, 1100, 2200]
    assert [s.omega_peak_rad_s for s in supply.sea_states] == [0.79, 0.84, 0.73, 0.56]
    tanker = load_scenario(builtin_scenario_path("tanker-seed003"))
    assert tanker.duration_s == 43200 and tanker.current.speed_mps == 1.0
    assert tanker.mass_factor_at(21600.0) == pytest.approx(1.83)
    assert tanker.sea_states[0].omega_peak_rad_s == pytest.approx(2.0 * math.pi / 10.0)
    moves = [p.north_m for p in tanker.setpoints]
    assert len(moves) == 24 and set(moves) == {0.0, 20.0}
    mariner = load_scenario(builtin_scenario_path("mariner-seed002"))
    assert all(p.north_m is None for p in mariner.setpoints)
    assert mariner.sensor("gyro1").noise_rad == pytest.approx(math.radians(0.5))
    blue = load_scenario(builtin_scenario_path("bluelady-seed004"))
    assert blue.wind.speed_mps == 2.0 and blue.sensor("gnss1").noise_m == pytest.approx(0.1)


def test_defaults() -> None:
    scenario = parse_scenario({"name": "x", "vessel": "cybership2", "duration_s": 10})
    assert [type(s) for s in scenario.sensors] == [GnssSpec, GyroSpec]
    assert scenario.sensors[0].noise_m == pytest.approx(0.01)  # seed 000 R = 1e-4 m²
    assert scenario.plant.thruster_timeout_s == 1.0 and scenario.plant.rate_hz == 20.0
    assert scenario.seed == 0 and scenario.sea_states == () and scenario.mass_factor_at(5.0) == 1.0
    assert scenario.setpoint_at(0.0) is None and scenario.sea_state_at(0.0) is None
    with pytest.raises(TypeError):
        scenario.controller["x"] = 1  # type: ignore[index]


def test_a_scenario_pickles_for_another_process() -> None:
    scenario = load_scenario(builtin_scenario_path("demo"))
    copied = pickle.loads(pickle.dumps(scenario))
    assert copied.controller == scenario.controller
    assert copied.controller.to_dict()["estimator"]["kind"] == "mmae"
    assert copied.sensors == scenario.sensors and copied.sea_states == scenario.sea_states


@pytest.mark.parametrize(("path", "value", "key"), [
    ("duraton_s", 5, "duraton_s"),
    ("sea_states.1.omega_peak_rads", 0.8, "sea_states[1].omega_peak_rads"),
    ("sensors.0.noise", 0.1, "sensors[0].noise"),
    ("wind.speed", 3.0, "wind.speed"),
    ("current.variation.std", 1.0, "current.variation.std"),
    ("plant.rate", 10, "plant.rate"),
])
def test_a_typo_is_named(path, value, key) -> None:
    with pytest.raises(ConfigError) as info:
        parse_scenario(_with(path, value), file="my.yaml")
    message = str(info.value)
    assert message.startswith("my.yaml: ")
    assert f"{key}: expected a known key" in message


@pytest.mark.parametrize(("path", "value", "where", "expected"), [
    ("duration_s", "long", "duration_s", "a number"),
    ("duration_s", -1, "duration_s", "> 0"),
    ("seed", 1.5, "seed", "an integer"),
    ("vessel", "titanic", "vessel", "a built-in vessel"),
    ("controller", [1, 2], "controller", "a mapping"),
    ("sea_states.0.spectrum", "bretschneider", "sea_states[0].spectrum", "one of jonswap"),
    ("sea_states.0.components", 20, "sea_states[0].components", ">= 100"),
    ("sea_states.1.t_s", 10, "sea_states[1].t_s", "fade_s"),
    ("sensors.0.kind", "sonar", "sensors[0].kind", "one of gnss, gyro"),
    ("sensors.0.protocol", "can", "sensors[0].protocol", "one of nmea0183"),
    ("sensors.1.name", "gnss1", "sensors[1].name", "not used before"),
    ("sensors.0.lever_arm_m", [1.0], "sensors[0].lever_arm_m", "a list of 2 numbers"),
    ("mass_schedule", [{"t_s": 10, "factor": 1}, {"t_s": 5, "factor": 2}], "mass_schedule[1].t_s", "increasing"),
    ("setpoints", [{"t_s": 0, "north_m": 1}], "setpoints[0].east_m", "together"),
    ("setpoints", [{"t_s": 0}], "setpoints[0].heading_deg", "a position"),
    ("datum.lat_deg", 91, "datum.lat_deg", "<= 90"),
    # beyond the models' range: typos that drove the integration to overflow (a traceback deep in the waves)
    ("current.speed_mps", 1e9, "current.speed_mps", "<= 10"),
    ("wind.speed_mps", 120, "wind.speed_mps", "<= 80"),
    ("sea_states.0.hs_m", 45, "sea_states[0].hs_m", "<= 30"),
    ("initial.surge_mps", 77175.0, "initial.surge_mps", "<= 30"),
    ("initial.yaw_rate_degps", -90, "initial.yaw_rate_degps", ">= -30"),
    ("sensors.0.noise_m", 1e9, "sensors[0].noise_m", "<= 1000"),  # was a ValueError from the GST encoder
    ("sensors.0.hdop", 150, "sensors[0].hdop", "<= 99.99"),
    ("sensors.1.noise_deg", 400, "sensors[1].noise_deg", "<= 180"),
])
def test_bad_values_name_the_key(path, value, where, expected) -> None:
    with pytest.raises(ConfigError) as info:
        parse_scenario(_with(path, value), file="s.yaml")
    assert f"s.yaml: {where}: expected" in str(info.value)
    assert expected in str(info.value)


def test_missing_required_keys_and_non_mapping_root() -> None:
    data = copy.deepcopy(BASE)
    del data["name"]
    with pytest.raises(ConfigError, match="name: expected a value"):
        parse_scenario(data)
    with pytest.raises(ConfigError, match="<root>: expected a mapping"):
        parse_scenario([1, 2])
    with pytest.raises(ConfigError, match="exactly one of omega_peak_rad_s or tp_s"):
        parse_scenario(_with("sea_states.0.tp_s", 9.0))


def _fault(**kw) -> dict:
    return _with("faults", [{"t_s": 5, **kw}])


@pytest.mark.parametrize("kind", FAULT_KINDS)
def test_every_fault_kind_parses(kind) -> None:
    extra: dict[str, object] = {}
    if kind.startswith("thruster"):
        extra["thruster"] = "bow_tunnel_1"
    elif kind.startswith("gyro"):
        extra["sensor"] = "gyro1"
    elif kind.startswith("rot_"):
        extra["sensor"] = "rot1"
    elif kind == "heartbeat_loss":
        extra["sensor"] = "gnss2"
    else:
        extra["sensor"] = "gnss1"
    params = {"gnss_jump": {"offset_m": 5.0, "direction_deg": 90}, "gnss_drift": {"rate_mps": 0.1},
              "gnss_noise": {"factor": 3.0}, "gyro_offset": {"offset_deg": 2.0}, "gyro_drift": {"rate_degps": 0.1},
              "rot_offset": {"rate_degps": 0.1}, "malformed_burst": {"count": 5}}.get(kind, {})
    data = _fault(kind=kind, duration_s=10, **extra, **params)
    data["sensors"].append({"name": "rot1", "kind": "rot"})
    scenario = parse_scenario(data)
    fault = scenario.faults[0]
    assert fault.kind == kind and fault.t_s == 5 and fault.end_s == 15
    if kind == "gnss_jump":
        assert fault.offset_m == 5.0 and fault.direction_rad == pytest.approx(math.pi / 2)
    if kind == "gyro_drift":
        assert fault.rate_radps == pytest.approx(math.radians(0.1))


@pytest.mark.parametrize(("fault", "where", "expected"), [
    ({"kind": "gnss_freeze", "sensor": "gnss9"}, "faults[0].sensor", "a sensor name"),
    ({"kind": "gnss_freeze", "sensor": "gyro1"}, "faults[0].sensor", "a gnss sensor"),
    ({"kind": "gyro_freeze", "target": "gnss1"}, "faults[0].target", "a gyro sensor"),
    ({"kind": "thruster_stuck", "thruster": "rudder"}, "faults[0].thruster", "a thruster of supply"),
    ({"kind": "thruster_stuck", "sensor": "bow_tunnel_1"}, "faults[0].sensor", "a thruster"),
    ({"kind": "serial_unplug", "sensor": "gnss2"}, "faults[0].sensor", "serial line"),
    ({"kind": "heartbeat_loss", "sensor": "gnss1"}, "faults[0].sensor", "MAVLink"),
    ({"kind": "gnss_freeze"}, "faults[0].sensor", "exactly one of"),
    ({"kind": "gnss_jump", "sensor": "gnss1", "offset_m": 1, "factor": 2}, "faults[0].factor", "a known key"),
    ({"kind": "gnss_freez", "sensor": "gnss1"}, "faults[0].kind", "one of gnss_freeze"),
    ({"kind": "gnss_freeze", "sensor": "gnss1", "duration_s": 0}, "faults[0].duration_s", "> 0"),
])
def test_bad_faults_name_the_key(fault, where, expected) -> None:
    with pytest.raises(ConfigError) as info:
        parse_scenario(_fault(**fault))
    assert f"{where}: expected" in str(info.value) and expected in str(info.value)


def test_inline_vessel_and_heading_only_setpoint() -> None:
    data = copy.deepcopy(BASE)
    data["vessel"] = {"base": "cybership2", "name": "cs2_heavy", "mass_kg": 30.0}
    data["setpoints"] = [{"t_s": 0, "heading_deg": 90}]
    scenario = parse_scenario(data)
    assert scenario.vessel.mass_kg == 30.0
    assert scenario.setpoints[0].heading_rad == pytest.approx(math.pi / 2) and scenario.setpoints[0].north_m is None
    data["vessel"] = {"base": "cybership2", "mass_kg": -1}
    with pytest.raises(ConfigError, match=r"vessel\.mass_kg"):
        parse_scenario(data)


def test_load_reports_bad_yaml_with_the_file(tmp_path: Path) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: [unclosed\n", encoding="utf-8")
    with pytest.raises(ConfigError) as info:
        load_scenario(bad)
    assert str(bad) in str(info.value) and "valid YAML" in str(info.value)
    good = tmp_path / "good.yaml"
    good.write_text(yaml.safe_dump(BASE), encoding="utf-8")
    assert load_scenario(good).source == str(good)
    typo = tmp_path / "typo.yaml"
    typo.write_text(yaml.safe_dump(_with("sensors.0.rate", 5)), encoding="utf-8")
    with pytest.raises(ConfigError, match=r"typo\.yaml: sensors\[0\]\.rate: expected a known key"):
        load_scenario(typo)
    with pytest.raises(KeyError, match="known: bluelady-seed004"):
        builtin_scenario_path("nope")
