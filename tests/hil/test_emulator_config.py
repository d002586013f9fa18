"""The emulator's reader of the controller configuration, sensor wiring and options (pure, fast)."""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import pytest
import yaml

from dpbase.schema import ConfigError
from sim_plant.emulator import HilOptions
from sim_plant.hil_config import (
    CanTransport,
    MavlinkTransport,
    SerialTransport,
    ZenohWiring,
    load_controller_wiring,
    parse_controller_wiring,
    wire_sensors,
    zenoh_endpoints,
)
from sim_plant.scenario import parse_scenario

KEY = "00112233445566778899aabbccddeeff00112233445566778899aabbccddeeff"
CONFIG: dict[str, Any] = {
    "vessel_id": "cs2",
    "vessel": "cybership2",
    "loop": {"rate_hz": 10},
    "transports": [
        {"name": "serial0", "protocol": "nmea0183", "port": "/tmp/dp/ttyNAV", "baud": 38400},
        {"name": "can0", "protocol": "nmea2000", "interface": "remote", "channel": "ws://localhost:54701/",
         "options": {"receive_own_messages": False}},
        {"name": "mav0", "protocol": "mavlink", "url": "udpin:0.0.0.0:14550", "signing_key_hex": KEY,
         "heartbeat_timeout_s": 3.0},
    ],
    "sensors": [
        {"name": "gnss1", "kind": "position", "transport": "serial0", "talker": "GN", "sentences": ["GGA", "RMC"],
         "sigma_m": 0.5},
        {"name": "gyro1", "kind": "heading", "transport": "serial0"},
        {"name": "gnss2", "kind": "position", "transport": "can0", "source_address": 40},
        {"name": "gyro3", "kind": "heading", "transport": "mav0", "system_id": 7},
    ],
    "zenoh": {"mode": "peer", "listen": ["tcp/127.0.0.1:7447"]},
    "estimator": {"kind": "mmae"},
}
SCENARIO: dict[str, Any] = {
    "name": "wiring", "vessel": "cybership2", "duration_s": 10,
    "sensors": [
        {"name": "gnss1", "kind": "gnss", "protocol": "nmea0183"},
        {"name": "gyro1", "kind": "gyro", "protocol": "nmea0183"},
        {"name": "gnss2", "kind": "gnss", "protocol": "nmea0183"},
        {"name": "gnss9", "kind": "gnss", "protocol": "nmea0183"},
    ],
}


def _config(**changes: Any) -> dict[str, Any]:
    """A copy of CONFIG with ``changes`` applied at dotted paths (``"sensors.0.kind": ...``)."""
    data = copy.deepcopy(CONFIG)
    for path, value in changes.items():
        *parents, last = path.split(".")
        node: Any = data
        for key in parents:
            node = node[int(key)] if isinstance(node, list) else node[key]
        if isinstance(node, list):
            node[int(last)] = value
        elif value is ...:
            del node[last]
        else:
            node[last] = value
    return data


def test_reads_the_keys_it_needs_and_ignores_the_rest() -> None:
    wiring = parse_controller_wiring(CONFIG)
    assert wiring.vessel_id == "cs2"
    serial, can, mav = (wiring.transports[n] for n in ("serial0", "can0", "mav0"))
    assert serial == SerialTransport("serial0", "/tmp/dp/ttyNAV", 38400)
    assert isinstance(can, CanTransport) and can.remote_address() == ("127.0.0.1", 54701)
    assert can.options == {"receive_own_messages": False}
    assert isinstance(mav, MavlinkTransport) and (mav.host, mav.port) == ("127.0.0.1", 14550)
    assert mav.signing_key == bytes.fromhex(KEY) and mav.heartbeat_timeout_s == 3.0
    gnss1 = wiring.sensors["gnss1"]
    assert (gnss1.kind, gnss1.talker, gnss1.sentences) == ("position", "GN", ("GGA", "RMC"))
    assert wiring.sensors["gnss2"].source_address == 40 and wiring.sensors["gyro3"].system_id == 7
    assert wiring.zenoh == ZenohWiring("peer", ("tcp/127.0.0.1:7447",), ())


@pytest.mark.parametrize(("changes", "path"), [
    ({"vessel_id": ...}, "vessel_id"),
    ({"vessel_id": "cs2/a"}, "vessel_id"),
    ({"transports": ...}, "transports"),
    ({"transports.0.protocol": "rs232"}, "transports[0].protocol"),
    ({"transports.0.baud": "fast"}, "transports[0].baud"),
    ({"transports.1.channel": "can0"}, "transports[1].channel"),
    ({"transports.1.channel": None}, "transports[1].channel"),
    ({"transports.2.url": "tcp:127.0.0.1:5760"}, "transports[2].url"),
    ({"transports.2.url": "udpin:127.0.0.1:99999"}, "transports[2].url"),
    ({"transports.2.signing_key_hex": "abcd"}, "transports[2].signing_key_hex"),
    ({"transports.1.name": "serial0"}, "transports[1].name"),
    ({"sensors.0.transport": "serial9"}, "sensors[0].transport"),
    ({"sensors.0.kind": "gnss"}, "sensors[0].kind"),
    ({"sensors.0.talker": "G"}, "sensors[0].talker"),
    ({"sensors.2.talker": "GP"}, "sensors[2].talker"),
    ({"sensors.0.sentences": ["GGA", "GSA"]}, "sensors[0].sentences[1]"),
    ({"sensors.2.sentences": ["GGA"]}, "sensors[2].sentences"),
    ({"sensors.2.source_address": 252}, "sensors[2].source_address"),
    ({"sensors.0.source_address": 3}, "sensors[0].source_address"),
    ({"sensors.0.system_id": 3}, "sensors[0].system_id"),
    ({"sensors.3.system_id": 0}, "sensors[3].system_id"),
    ({"sensors.1.name": "gnss1"}, "sensors[1].name"),
    ({"zenoh.listen": ["localhost:7447"]}, "zenoh.listen[0]"),
    ({"zenoh.mode": "router"}, "zenoh.mode"),
])
def test_invalid_keys_name_their_path(changes: dict[str, Any], path: str) -> None:
    with pytest.raises(ConfigError) as error:
        parse_controller_wiring(_config(**changes), file="vessel.yaml")
    assert str(error.value).startswith(f"vessel.yaml: {path}: expected")


def test_file_errors_name_the_file(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match=r"missing\.yaml"):
        load_controller_wiring(tmp_path / "missing.yaml")
    broken = tmp_path / "broken.yaml"
    broken.write_text("vessel_id: [unclosed\n", encoding="utf-8")
    with pytest.raises(ConfigError, match=r"broken\.yaml: <root>: expected valid YAML"):
        load_controller_wiring(broken)
    good = tmp_path / "good.yaml"
    good.write_text(yaml.safe_dump(CONFIG), encoding="utf-8")
    assert load_controller_wiring(good).source == str(good)


def test_wiring_follows_the_controller_and_notes_what_does_not_match() -> None:
    wires, notes = wire_sensors(parse_scenario(SCENARIO), parse_controller_wiring(CONFIG, file="v.yaml"))
    assert [(w.spec.name, w.transport.name) for w in wires] == [("gnss1", "serial0"), ("gyro1", "serial0"),
                                                              ("gnss2", "can0")]
    assert any("gnss2" in n and "sent as nmea2000" in n for n in notes)
    assert any("gnss9" in n and "not emitted" in n for n in notes)
    assert any("gyro3" in n and "missing" in n for n in notes)


def test_sensors_the_daemon_cannot_tell_apart_are_noted() -> None:
    scenario = parse_scenario({**SCENARIO, "sensors": [*SCENARIO["sensors"][:3],
                                                       {"name": "gnss9", "kind": "gnss", "protocol": "nmea0183"}]})
    same_talker = _config(**{"sensors.2": {"name": "gnss9", "kind": "position", "transport": "serial0",
                                           "talker": "GN"}})
    _, notes = wire_sensors(scenario, parse_controller_wiring(same_talker))
    assert any("gnss1 and gnss9 share serial0" in n for n in notes)
    _, notes = wire_sensors(scenario, parse_controller_wiring(CONFIG))
    assert not any("share" in n for n in notes)


def test_wiring_errors() -> None:
    scenario = parse_scenario(SCENARIO)
    with pytest.raises(ConfigError, match=r"v\.yaml: sensors\[2\]\.kind: expected position \(scenario sensor gnss2"):
        wire_sensors(scenario, parse_controller_wiring(_config(**{"sensors.2.kind": "heading"}), file="v.yaml"))
    two_on_one_address = _config(**{"sensors.0": {"name": "gnss1", "kind": "position", "transport": "can0",
                                                  "source_address": 40}})
    with pytest.raises(ConfigError, match=r"sensors\[2\]\.source_address: expected an address not used by gnss1"):
        wire_sensors(scenario, parse_controller_wiring(two_on_one_address))
    nothing = _config(sensors=[{"name": "other", "kind": "position", "transport": "serial0"}])
    with pytest.raises(ConfigError, match="at least one sensor named like a scenario sensor"):
        wire_sensors(scenario, parse_controller_wiring(nothing))


def test_zenoh_endpoints_meet_in_both_directions() -> None:
    listen_only = ZenohWiring(listen=("tcp/127.0.0.1:7447",))
    connect_only = ZenohWiring(connect=("tcp/127.0.0.1:7448",))
    assert zenoh_endpoints(listen_only) == ((), ("tcp/127.0.0.1:7447",))
    assert zenoh_endpoints(connect_only) == (("tcp/127.0.0.1:7448",), ())
    both = ZenohWiring(listen=("tcp/127.0.0.1:7447",), connect=("tcp/127.0.0.1:7448",))
    assert zenoh_endpoints(both) == ((), ("tcp/127.0.0.1:7447",))
    # given endpoints are added: the way to the daemon stays
    assert zenoh_endpoints(both, listen=("tcp/127.0.0.1:9000",)) == (("tcp/127.0.0.1:9000",), ("tcp/127.0.0.1:7447",))
    assert zenoh_endpoints(listen_only, connect=("tcp/127.0.0.1:9001", "tcp/127.0.0.1:7447")) == (
        (), ("tcp/127.0.0.1:7447", "tcp/127.0.0.1:9001"))
    assert zenoh_endpoints(ZenohWiring(), listen=("tcp/127.0.0.1:9000",)) == (("tcp/127.0.0.1:9000",), ())
    via_router = ZenohWiring(mode="client", connect=("tcp/10.0.0.1:7447",))
    assert zenoh_endpoints(via_router) == ((), ("tcp/10.0.0.1:7447",))  # the same router, never its address
    with pytest.raises(ValueError, match="no zenoh listen or connect endpoint"):
        zenoh_endpoints(ZenohWiring())


@pytest.mark.parametrize("bad", [{"speed": 0.0}, {"speed": float("nan")}, {"duration_s": -1.0},
                                 {"can_server_mode": "fork"}, {"deadline_tolerance_s": True},
                                 {"serial_backlog_bytes": 10}])
def test_invalid_options_are_refused(bad: dict[str, Any]) -> None:
    with pytest.raises(ValueError):
        HilOptions(**bad)
