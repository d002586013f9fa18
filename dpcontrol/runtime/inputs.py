"""Routing of decoded sensor messages to the configured sensors.

A transport (serial port, CAN bus, MAVLink link) can carry several sensors — a GNSS compass sends
GGA and HDT on one port, an NMEA 2000 bus has many source addresses — and several kinds of message
for one sensor. :class:`SensorRouter` decides, from where a message came from (NMEA 0183 talker and
sentence, NMEA 2000 source address, MAVLink system/component and message name) and what it is,
which configured sensor it belongs to. The daemon applies it to what its transports deliver; the
lockstep simulation applies the same rules to what its in-process decoders produce, so both see
identical measurements.

Defaults, chosen so that one physical quantity is not counted twice:

* NMEA 0183 position sensors use GGA, GNS (and GST statistics); RMC and GLL only when listed in
  ``sentences`` (a receiver sending GGA and RMC or GLL for the same epoch would otherwise double it); the
  receiver's velocity (course and speed over ground) from VTG and RMC, whatever ``sentences`` lists (a velocity
  sent twice for one epoch is the same sample twice: the hub's velocity check integrates over time, not samples);
  heading sensors use HDT, THS (and ROT);
* NMEA 2000: every position (129025, 129029, and 129026 COG & SOG) and heading (127250) PGN from the configured
  source address and/or device NAME (or any source when none is configured);
* MAVLink: GPS_RAW_INT for position and its ``vel``/``cog`` (GLOBAL_POSITION_INT is the autopilot's fused
  estimate, not a reference), ATTITUDE for heading and rate of turn.

A rate of turn (NMEA 0183 ROT, NMEA 2000 127251, MAVLink ATTITUDE ``yawspeed``) goes to a ``rate_of_turn``
sensor (a rate gyro independent of the gyrocompasses) whose filters match it, else to a heading sensor's
(its own rate of turn): configure a rate sensor sharing a port, bus or autopilot with a gyrocompass with its
talker (``TI``), source address or system id, so that it does not take the gyrocompass's rate.
"""

from __future__ import annotations

from collections.abc import Sequence

from dpcontrol.runtime.config import SensorRoute, TransportConfig
from dpcontrol.runtime.hub import SensorKind
from interfaces.messages import CourseOverGround, Heading, PositionErrorStats, PositionFix, RateOfTurn, SensorMessage

NMEA_POSITION_DEFAULT = ("GGA", "GNS", "GST")
NMEA_HEADING_DEFAULT = ("HDT", "THS", "ROT")
NMEA_RATE_DEFAULT = ("ROT",)
NMEA_VELOCITY_SENTENCES = ("VTG", "RMC")  # a position sensor's course and speed over ground
MAVLINK_POSITION_MESSAGES = ("GPS_RAW_INT",)
MAVLINK_HEADING_MESSAGES = ("ATTITUDE",)
_SYSTEM_SEPARATOR = "#"


def link_source(transport: str, system_id: int | None = None) -> str:
    """The ``LinkStatus.source`` of a link change: the transport, or one MAVLink system on it
    (``autopilot#2``), whose heartbeat loss concerns only the sensors of that system."""
    return transport if system_id is None else f"{transport}{_SYSTEM_SEPARATOR}{system_id}"


def split_link_source(source: str) -> tuple[str, int | None]:
    """Inverse of :func:`link_source`: ``(transport, system_id or None)``."""
    transport, sep, system = source.rpartition(_SYSTEM_SEPARATOR)
    if sep and system.isdigit():
        return transport, int(system)
    return source, None


def link_alarm_code(source: str) -> str:
    """Alarm code of a link: ``transport.<name>.link`` or ``transport.<name>.system<N>.link``."""
    transport, system_id = split_link_source(source)
    return f"transport.{transport}.link" if system_id is None else f"transport.{transport}.system{system_id}.link"


def message_kind(message: SensorMessage) -> SensorKind | None:
    """Which kind of sensor a message feeds (None: not used by the hub)."""
    if isinstance(message, PositionFix | PositionErrorStats | CourseOverGround):
        return SensorKind.POSITION
    if isinstance(message, Heading | RateOfTurn):
        return SensorKind.HEADING
    return None


_UNKNOWN = object()  # not in the routing cache yet
_ROUTE_CACHE_SIZE = 1024


class SensorRouter:
    """Maps (transport, origin, message) to a configured sensor name.

    Parameters
    ----------
    routes : sequence of SensorRoute
        The configured sensors and their filters.
    transports : sequence of TransportConfig
    """

    def __init__(self, routes: Sequence[SensorRoute], transports: Sequence[TransportConfig]) -> None:
        self._protocol = {t.name: t.protocol for t in transports}
        self._by_transport: dict[str, list[SensorRoute]] = {t.name: [] for t in transports}
        for route in routes:
            self._by_transport[route.transport].append(route)
        self.unrouted = 0
        self._nmea_cache: dict[tuple[str, str, type], str | None] = {}

    def routes_of(self, transport: str) -> list[SensorRoute]:
        return self._by_transport.get(transport, [])

    def nmea0183(self, transport: str, address: str, message: SensorMessage) -> str | None:
        """Sensor for a message decoded from the NMEA 0183 sentence ``address`` (e.g. ``GPGGA``)."""
        # The answer depends only on (transport, address, message type) and the fixed routes: remembered, it
        # saves the search on every sentence (a few µs each). Bounded: addresses come off the wire.
        key = (transport, address, type(message))
        name = self._nmea_cache.get(key, _UNKNOWN)
        if name is _UNKNOWN:
            name = self._route_nmea0183(transport, address, message)
            if len(self._nmea_cache) < _ROUTE_CACHE_SIZE:
                self._nmea_cache[key] = name
        if name is None:
            self.unrouted += 1
        return name  # type: ignore[return-value]

    def _route_nmea0183(self, transport: str, address: str, message: SensorMessage) -> str | None:
        kind = message_kind(message)
        talker, sentence = address[:2], address[2:]
        if address.startswith("P"):  # proprietary: no talker field
            talker, sentence = "", address
        routes = self._by_transport.get(transport, ())
        if isinstance(message, RateOfTurn):  # a rate sensor's before a heading sensor's (module docstring)
            routes = sorted(routes, key=lambda r: r.sensor.kind is not SensorKind.RATE)
        for route in routes:
            route_kind = route.sensor.kind
            if route_kind is not kind and not (route_kind is SensorKind.RATE and kind is SensorKind.HEADING
                                               and isinstance(message, RateOfTurn)):
                continue
            if isinstance(message, CourseOverGround):
                allowed: tuple[str, ...] = NMEA_VELOCITY_SENTENCES
            else:
                allowed = route.sentences or (NMEA_POSITION_DEFAULT if route_kind is SensorKind.POSITION
                                              else NMEA_RATE_DEFAULT if route_kind is SensorKind.RATE
                                              else NMEA_HEADING_DEFAULT)
            if sentence not in allowed and not (sentence == "GST" and kind is SensorKind.POSITION):
                continue
            if route.talker is not None and route.talker != talker:
                continue
            return route.sensor.name
        return None

    def nmea2000(self, transport: str, source_address: int, message: SensorMessage,
                 source_name: int | None = None) -> str | None:
        """Sensor for a message from NMEA 2000 ``source_address``, whose device claimed it with ``source_name``
        (its 64-bit NAME, when a 60928 claim was seen): a route with a NAME follows the device to any address."""
        kind = message_kind(message)
        routes = self._by_transport.get(transport, ())
        if isinstance(message, RateOfTurn):
            for route in routes:
                if (route.sensor.kind is SensorKind.RATE and route.source_address in (None, source_address)
                        and route.source_name in (None, source_name)):
                    return route.sensor.name
        for route in routes:
            if (route.sensor.kind is kind and route.source_address in (None, source_address)
                    and route.source_name in (None, source_name)):
                return route.sensor.name
        self.unrouted += 1
        return None

    def mavlink(self, transport: str, system_id: int, msg_name: str, message: SensorMessage) -> str | None:
        """Sensor for a MAVLink message ``msg_name`` from ``system_id``."""
        kind = message_kind(message)
        allowed = MAVLINK_POSITION_MESSAGES if kind is SensorKind.POSITION else MAVLINK_HEADING_MESSAGES
        if msg_name not in allowed:
            self.unrouted += 1
            return None
        routes = self._by_transport.get(transport, ())
        if isinstance(message, RateOfTurn):
            for route in routes:
                if route.sensor.kind is SensorKind.RATE and route.system_id in (None, system_id):
                    return route.sensor.name
        for route in routes:
            if route.sensor.kind is kind and route.system_id in (None, system_id):
                return route.sensor.name
        self.unrouted += 1
        return None

    def sensors_on(self, source: str) -> list[str]:
        """Names of the sensors a link feeds (all marked disconnected when it is).

        ``source`` is a transport name, or one MAVLink system on it (:func:`link_source`): then the
        sensors filtered on that ``system_id``, and those with no filter (they may come from any
        system, so the loss of one cannot be ruled out).
        """
        transport, system_id = (source, None) if source in self._by_transport else split_link_source(source)
        routes = self._by_transport.get(transport, ())
        if system_id is None:
            return [route.sensor.name for route in routes]
        return [route.sensor.name for route in routes if route.system_id in (None, system_id)]
