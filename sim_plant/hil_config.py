"""The wiring of a hardware-in-the-loop rig, read from the controller's own YAML configuration.

``sim-plant hil SCENARIO --controller-config FILE`` must speak to the daemon on exactly the ports,
buses and addresses the daemon was configured with. Those live in the daemon's configuration file
(``dpcontrol run --config FILE``), but the plant never imports the controller (docs/design.md §1), so
this module reads the few keys it needs from that file itself. It is a reader of a *file format*,
not controller code: every key it reads is validated (errors name the file, the key path and what
was expected, like every other configuration error of the project); every other key is left to the
daemon, which validates its own file.

Keys read (all others ignored)::

    vessel_id: cs2                       # zenoh key chunk dp/<vessel_id>/...
    transports:
      - {name: serial0, protocol: nmea0183, port: /tmp/dp/ttyGNSS, baud: 4800}
      - {name: can0, protocol: nmea2000, interface: remote, channel: "ws://127.0.0.1:54701/", options: {}}
      - {name: mav0, protocol: mavlink, url: "udpin:127.0.0.1:14550", signing_key_hex: ...}
    sensors:
      - {name: gnss1, kind: position, transport: serial0, talker: GP, sentences: [GGA, GST]}
      - {name: gyro2, kind: heading, transport: can0, source_address: 41}
      - {name: gnss3, kind: position, transport: mav0, system_id: 7}
    zenoh: {mode: peer, listen: ["tcp/127.0.0.1:7447"], connect: []}

Scenario sensors are matched to controller sensors by name (:func:`wire_sensors`): a scenario
``gnss`` must be a controller ``position`` sensor, a ``gyro`` a ``heading`` sensor, a ``rot`` a ``rate_of_turn``
sensor. The controller's
transport decides the protocol on the rig (the scenario's ``protocol`` is what the lockstep
simulation uses); a difference is reported as a note.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

from dpbase.schema import ConfigError, Section, join
from dpbase.yamlfile import read_yaml_file
from interfaces.zenoh.keys import validate_vessel_id
from interfaces.zenoh.session_config import check_endpoint
from sim_plant.encoding import HEADING_SENTENCES, POSITION_SENTENCES
from sim_plant.scenario import Scenario
from sim_plant.sensors import SensorSpec

KINDS: tuple[str, ...] = ("position", "heading", "rate_of_turn")
SENSOR_KIND_OF: dict[str, str] = {"gnss": "position", "gyro": "heading", "rot": "rate_of_turn"}
PROTOCOLS: tuple[str, ...] = ("nmea0183", "nmea2000", "mavlink")
SENTENCES: tuple[str, ...] = POSITION_SENTENCES + HEADING_SENTENCES  # what the daemon accepts in ``sentences``
MAX_N2K_SENDER_ADDRESS = 251  # 252/253 are "no address"/"null", a sensor cannot send from them
_TALKER_RE = re.compile(r"[A-Z0-9]{2}")
# hosts a daemon may name for "this machine" → where the emulator sends / binds on loopback
_LOCAL_HOSTS = {"localhost": "127.0.0.1", "0.0.0.0": "127.0.0.1", "": "127.0.0.1"}


@dataclass(frozen=True)
class SerialTransport:
    """An NMEA 0183 serial line: the device path the daemon opens and its line speed."""

    name: str
    port: str
    baud: int = 4800
    protocol: str = "nmea0183"


@dataclass(frozen=True)
class CanTransport:
    """An NMEA 2000 bus as python-can configuration (``remote``: ``channel`` is ``ws://host:port/``)."""

    name: str
    interface: str
    channel: str
    options: Mapping[str, Any] = field(default_factory=dict)
    protocol: str = "nmea2000"

    def remote_address(self) -> tuple[str, int]:
        """``(host, port)`` of a ``remote`` bus's server (from ``channel``).

        Raises
        ------
        ValueError
            Not a ``remote`` interface, or a channel that is not ``ws://host:port/``.
        """
        if self.interface != "remote":
            raise ValueError(f"transport {self.name}: interface {self.interface!r} has no server address")
        parts = urlsplit(self.channel)
        try:
            port = parts.port
        except ValueError:
            port = None
        if parts.scheme not in ("ws", "wss") or port is None or not 0 < port < 65536:
            raise ValueError(f"transport {self.name}: channel {self.channel!r} is not a URL like ws://127.0.0.1:54701/")
        host = parts.hostname or ""
        return _LOCAL_HOSTS.get(host, host), port


@dataclass(frozen=True)
class MavlinkTransport:
    """A MAVLink link the daemon listens on (``udpin:HOST:PORT``): the emulator sends to HOST:PORT."""

    name: str
    host: str
    port: int
    signing_key: bytes | None = None
    heartbeat_timeout_s: float = 5.0
    protocol: str = "mavlink"


Transport = SerialTransport | CanTransport | MavlinkTransport


@dataclass(frozen=True)
class SensorWiring:
    """A controller sensor and how it is picked out of its transport (talker, address, system id)."""

    name: str
    kind: str
    transport: str
    talker: str | None = None
    sentences: tuple[str, ...] = ()
    source_address: int | None = None
    system_id: int | None = None
    where: str = ""  # key path in the controller file, for error messages


@dataclass(frozen=True)
class ZenohWiring:
    """The daemon's zenoh endpoints (``zenoh.listen`` / ``zenoh.connect``) and, on a secured network, its
    identity → roles map (``zenoh.identities``), which the emulator's own session enforces too."""

    mode: str = "peer"
    listen: tuple[str, ...] = ()
    connect: tuple[str, ...] = ()
    identities: Mapping[str, tuple[str, ...]] = field(default_factory=dict)


@dataclass(frozen=True)
class ControllerWiring:
    """What the emulator needs from the daemon's configuration file."""

    vessel_id: str
    transports: Mapping[str, Transport]
    sensors: Mapping[str, SensorWiring]
    zenoh: ZenohWiring
    source: str | None = None


@dataclass(frozen=True)
class Wire:
    """One scenario sensor connected to its controller sensor and transport."""

    spec: SensorSpec
    sensor: SensorWiring
    transport: Transport


# -- reading --------------------------------------------------------------------------------------
def load_controller_wiring(path: str | Path) -> ControllerWiring:
    """Read the rig wiring from a daemon configuration file.

    Raises
    ------
    ConfigError
        Unreadable file, invalid YAML, or an invalid value of a key read here (names the file and
        the key path).
    """
    _, data = read_yaml_file(path, what="a readable controller configuration file")
    return parse_controller_wiring(data, file=str(path))


def parse_controller_wiring(data: object, file: str | None = None) -> ControllerWiring:
    """Validate an already-parsed controller configuration mapping (see the module docstring).

    Raises
    ------
    ConfigError
        Naming ``file`` (when given), the key path and what was expected.
    """
    try:
        return _parse(data, file)
    except ConfigError as error:
        raise (error.with_file(file) if file else error) from None


def _parse(data: object, file: str | None) -> ControllerWiring:
    root = Section.of(data, "")
    vessel_id = root.string("vessel_id")
    try:
        validate_vessel_id(vessel_id)
    except ValueError as error:
        raise ConfigError("vessel_id", "1-64 characters from [A-Za-z0-9_-] (a zenoh key chunk)", vessel_id) from error
    transports: dict[str, Transport] = {}
    for where, item in root.items("transports", required=True, min_items=1):
        transport = _transport(Section.of(item, where))
        if transport.name in transports:
            raise ConfigError(join(where, "name"), "a transport name not used before", transport.name)
        transports[transport.name] = transport
    sensors: dict[str, SensorWiring] = {}
    for where, item in root.items("sensors", required=True, min_items=1):
        sensor = _sensor(Section.of(item, where), transports)
        if sensor.name in sensors:
            raise ConfigError(join(where, "name"), "a sensor name not used before", sensor.name)
        sensors[sensor.name] = sensor
    zenoh = _zenoh(root.section("zenoh"))
    return ControllerWiring(vessel_id, transports, sensors, zenoh, file)


def _transport(sec: Section) -> Transport:
    name = sec.string("name")
    protocol = sec.string("protocol", choices=PROTOCOLS)
    if protocol == "nmea0183":
        return SerialTransport(name, sec.string("port"), sec.integer("baud", 4800, minimum=300))
    if protocol == "nmea2000":
        interface = sec.string("interface")
        channel = sec.raw("channel", None)
        if isinstance(channel, bool) or not isinstance(channel, (str, int)) or channel == "":
            raise ConfigError(join(sec.path, "channel"), "a python-can channel (string or integer)", channel)
        options = sec.section("options")
        transport = CanTransport(name, interface, str(channel), dict(options.data))
        # (imported here: the gateways bring pyserial and python-can, which sim-plant --help never needs)
        from interfaces.nmea2000.gateways import GATEWAY_KINDS, GatewayConfig  # noqa: PLC0415

        if interface in GATEWAY_KINDS:  # a gateway the emulator plays (YD RAW server, NGT-1 on a pty)
            try:
                GatewayConfig(interface, str(channel), dict(options.data))
            except ValueError as error:
                raise ConfigError(join(sec.path, "channel"), str(error), channel) from None
        if interface == "remote":
            try:
                transport.remote_address()
            except ValueError:
                raise ConfigError(join(sec.path, "channel"), "a python-can-remote URL like ws://127.0.0.1:54701/",
                                  channel) from None
        return transport
    url = sec.string("url")
    host, port = _udpin(url, join(sec.path, "url"))
    key = None
    key_hex = sec.raw("signing_key_hex", None)
    if key_hex is not None:
        if not isinstance(key_hex, str) or not re.fullmatch(r"[0-9a-fA-F]{64}", key_hex):
            raise ConfigError(join(sec.path, "signing_key_hex"), "64 hexadecimal digits (a 32-byte key)",
                              show_got=False)
        key = bytes.fromhex(key_hex)
    timeout = sec.number("heartbeat_timeout_s", 5.0, minimum=0.0, exclusive_minimum=True)
    return MavlinkTransport(name, host, port, key, timeout)


def _udpin(url: str, where: str) -> tuple[str, int]:
    """``udpin:HOST:PORT`` (or mavutil's synonym ``udp:HOST:PORT``) → where to send datagrams."""
    match = re.fullmatch(r"(udpin|udp):([^:\s]*):(\d{1,5})", url)
    if match is None or not 0 < int(match[3]) < 65536:
        raise ConfigError(where, "a MAVLink URL the daemon listens on, udpin:HOST:PORT (the emulator sends there)",
                          url)
    host = match[2]
    return _LOCAL_HOSTS.get(host, host), int(match[3])


def _sensor(sec: Section, transports: Mapping[str, Transport]) -> SensorWiring:
    name = sec.string("name")
    kind = sec.string("kind", choices=KINDS)
    transport_name = sec.string("transport", choices=list(transports))
    protocol = transports[transport_name].protocol
    talker = None
    if sec.has("talker"):
        talker = sec.raw("talker")
        if protocol != "nmea0183" or not isinstance(talker, str) or not _TALKER_RE.fullmatch(talker):
            raise ConfigError(join(sec.path, "talker"), "a 2-character NMEA 0183 talker ID on an nmea0183 transport",
                              talker)
    sentences: tuple[str, ...] = ()
    if sec.has("sentences"):
        items = sec.items("sentences", min_items=1)
        if protocol != "nmea0183":
            raise ConfigError(join(sec.path, "sentences"), "sentences only on an nmea0183 transport", protocol)
        for where, value in items:
            if value not in SENTENCES:
                raise ConfigError(where, f"one of {', '.join(SENTENCES)}", value)
        sentences = tuple(value for _, value in items)
    source_address = None
    if sec.has("source_address"):
        if protocol != "nmea2000":
            raise ConfigError(join(sec.path, "source_address"), "source_address only on an nmea2000 transport",
                              protocol)
        source_address = sec.integer("source_address", minimum=0, maximum=MAX_N2K_SENDER_ADDRESS)
    system_id = None
    if sec.has("system_id"):
        if protocol != "mavlink":
            raise ConfigError(join(sec.path, "system_id"), "system_id only on a mavlink transport", protocol)
        system_id = sec.integer("system_id", minimum=1, maximum=255)
    return SensorWiring(name, kind, transport_name, talker, sentences, source_address, system_id, sec.path)


def _zenoh(sec: Section) -> ZenohWiring:
    mode = sec.string("mode", "peer", choices=("peer", "client"))
    endpoints: dict[str, tuple[str, ...]] = {}
    for key in ("listen", "connect"):
        found = []
        for where, value in sec.items(key):
            try:
                found.append(check_endpoint(value, where))
            except ValueError:
                raise ConfigError(where, "a zenoh endpoint like tcp/127.0.0.1:7447", value) from None
        endpoints[key] = tuple(found)
    identities: dict[str, tuple[str, ...]] = {}
    raw = sec.raw("identities", None)
    for name, held in (raw.items() if isinstance(raw, Mapping) else ()):
        roles = (held,) if isinstance(held, str) else tuple(held) if isinstance(held, list) else None
        if roles is None or not all(isinstance(r, str) for r in roles):
            raise ConfigError(join(join(sec.path, "identities"), str(name)), "a role or a list of roles", held)
        identities[str(name)] = roles
    return ZenohWiring(mode, endpoints["listen"], endpoints["connect"], identities)


# -- matching -------------------------------------------------------------------------------------
def wire_sensors(scenario: Scenario, wiring: ControllerWiring) -> tuple[list[Wire], list[str]]:
    """Connect every scenario sensor to the controller sensor of the same name.

    Returns
    -------
    wires : list of Wire
        In scenario order.
    notes : list of str
        Human-readable notes: scenario sensors the controller does not read (not emitted),
        controller sensors the scenario does not have (the daemon will see them missing), and
        protocol differences (the controller's wiring is used).

    Raises
    ------
    ConfigError
        A kind mismatch (a scenario gyro wired as a controller position sensor ...), two NMEA 2000
        sensors on one bus with the same source address, or no scenario sensor wired at all.
    """
    file = wiring.source
    wires: list[Wire] = []
    notes: list[str] = []
    for spec in scenario.sensors:
        sensor = wiring.sensors.get(spec.name)
        if sensor is None:
            notes.append(f"scenario sensor {spec.name} is not in the controller configuration: not emitted")
            continue
        expected = SENSOR_KIND_OF[spec.kind]
        if sensor.kind != expected:
            raise ConfigError(join(sensor.where, "kind"),
                              f"{expected} (scenario sensor {spec.name} is a {spec.kind})", sensor.kind, file=file)
        transport = wiring.transports[sensor.transport]
        if transport.protocol != spec.protocol:
            notes.append(f"sensor {spec.name}: scenario protocol {spec.protocol}, controller transport "
                         f"{transport.name} is {transport.protocol}: sent as {transport.protocol}")
        wires.append(Wire(spec, sensor, transport))
    scenario_names = {spec.name for spec in scenario.sensors}
    notes.extend(f"controller sensor {name} is not in the scenario: the daemon will see it missing"
                 for name in wiring.sensors if name not in scenario_names)
    if not wires:
        raise ConfigError("sensors", "at least one sensor named like a scenario sensor "
                          f"({', '.join(sorted(scenario_names)) or 'none'})", sorted(wiring.sensors), file=file)
    notes.extend(_indistinct(wires))
    used: dict[tuple[str, int], str] = {}
    for wire in wires:
        address = wire.sensor.source_address
        if address is None:
            continue
        key = (wire.transport.name, address)
        if key in used:
            raise ConfigError(join(wire.sensor.where, "source_address"),
                              f"an address not used by {used[key]} on the same bus", address, file=file)
        used[key] = wire.sensor.name
    return wires, notes


def _indistinct(wires: list[Wire]) -> list[str]:
    """Notes on sensors of one kind the daemon cannot tell apart on a shared transport (same NMEA 0183
    talker, same MAVLink system id): it will take their messages as one sensor's."""
    seen: dict[tuple[str, str, object], str] = {}
    notes = []
    for wire in wires:
        sensor = wire.sensor
        if wire.transport.protocol == "nmea0183":
            origin: object = sensor.talker or ("GP" if sensor.kind == "position" else "HE")
        elif wire.transport.protocol == "mavlink":
            origin = sensor.system_id or 1
        else:
            continue
        key = (wire.transport.name, sensor.kind, origin)
        if key in seen:
            notes.append(f"sensors {seen[key]} and {sensor.name} share {wire.transport.name} as the same origin "
                         f"({origin}): the daemon cannot tell them apart")
        else:
            seen[key] = sensor.name
    return notes


def zenoh_endpoints(wiring: ZenohWiring, listen: tuple[str, ...] | None = None,
                    connect: tuple[str, ...] | None = None) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """The emulator's zenoh ``(listen, connect)`` endpoints.

    Derived from the controller configuration: a daemon in ``client`` mode reaches the vessel network
    through the router(s) it connects to, and so does the emulator; a peer daemon that listens is
    connected to; a peer daemon that only *connects* is reached by listening on its ``connect``
    endpoints (the emulator is then what they point at). Either way the two sessions meet without
    multicast scouting. Explicit ``listen``/``connect`` (command line) are added to those (a monitor's
    endpoint beside the daemon's, say): giving one never loses the way to the daemon.

    Raises
    ------
    ValueError
        No endpoint at all: the daemon neither listens nor connects, and none was given.
    """
    derived: tuple[tuple[str, ...], tuple[str, ...]] = ((), ())
    if wiring.mode == "client" and wiring.connect:
        derived = ((), wiring.connect)
    elif wiring.listen:
        derived = ((), wiring.listen)
    elif wiring.connect:
        derived = (wiring.connect, ())
    added_listen = tuple(e for e in listen or () if e not in derived[0])
    added_connect = tuple(e for e in connect or () if e not in derived[1])
    endpoints = (tuple(dict.fromkeys(derived[0] + added_listen)), tuple(dict.fromkeys(derived[1] + added_connect)))
    # (an endpoint both listened on and connected to would connect the session to itself)
    endpoints = (endpoints[0], tuple(e for e in endpoints[1] if e not in endpoints[0]))
    if not endpoints[0] and not endpoints[1]:
        raise ValueError("the controller configuration has no zenoh listen or connect endpoint: give the "
                         "emulator's own with --zenoh-listen/--zenoh-connect")
    return endpoints
