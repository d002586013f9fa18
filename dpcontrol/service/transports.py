"""The daemon's transports: one reader per configured transport, chosen by its configuration.

A reader opens its device (a serial port, a CAN bus through python-can, an NMEA 2000 gateway, a UDP port),
reads in its own thread and hands the daemon what arrived, undecoded, as typed events: a :class:`RawInput`
(the bytes of one read, one CAN frame or gateway message, one datagram, with the receive time), a
:class:`~interfaces.messages.RejectedInput` (what a gateway's framing could not read) or a
:class:`~interfaces.messages.LinkStatus` (the device opened, lost, reopened). Decoding, counting and routing
happen in the daemon's loop thread, in the input stage every other reader of raw inputs uses
(:mod:`dpcontrol.runtime.ingest`).

:data:`READERS` chooses the reader from the transport's ``protocol``, the way python-can chooses
``Bus(interface=...)``; an NMEA 2000 transport's ``interface`` then chooses a CAN bus or one of the gateways of
:data:`interfaces.nmea2000.gateways.GATEWAY_KINDS`. A new gateway is one class and one entry there; a new
protocol one factory here and one input class in :mod:`dpcontrol.runtime.ingest`. Nothing in the daemon
branches on protocol names.

Service shell: threads and devices (the readers themselves live in ``interfaces/``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

from dpcontrol.runtime.config import TransportConfig
from interfaces.messages import LinkStatus, RejectedInput

Clock = Callable[[], float]


@dataclass(frozen=True, slots=True)
class RawInput:
    """Bytes a transport received, undecoded.

    Attributes
    ----------
    t_s : float
        Receive time on the daemon's clock [s].
    data : bytes
        A serial read (any chunking), a CAN frame's data or a gateway's whole message, a UDP datagram.
    can_id : int or None
        The 29-bit CAN identifier (NMEA 2000 only).
    """

    t_s: float
    data: bytes
    can_id: int | None = None


InputEvent = RawInput | RejectedInput | LinkStatus
"""What a reader hands the daemon."""

InputSink = Callable[[InputEvent], None]
"""Called on the reader's thread for every event, in arrival order; must be quick and thread-safe."""


class Reader(Protocol):
    """A transport reader: started once, closed once (reads, and reconnects, in between on its own)."""

    def start(self) -> object:
        """Open the device (or keep trying) and start reading in a background thread."""
        ...

    def close(self) -> object:
        """Stop reading, close the device, join the thread."""
        ...


@dataclass(frozen=True, slots=True)
class ReaderOptions:
    """What the daemon adds to a transport's configuration.

    Attributes
    ----------
    clock : callable
        The daemon's clock [s]: every receive time is taken on it.
    request_address_claims : bool
        NMEA 2000: ask every device for its address claim on opening (a route names a device by NAME).
    """

    clock: Clock
    request_address_claims: bool = False


ReaderFactory = Callable[[TransportConfig, InputSink, ReaderOptions], Reader]


def _serial_reader(transport: TransportConfig, sink: InputSink, options: ReaderOptions) -> Reader:
    """NMEA 0183 on a serial port (pyserial): every read's bytes, and the port's link changes."""
    from interfaces.nmea0183.transport import SerialReader  # noqa: PLC0415 - pyserial only when configured

    settings = transport.settings
    return SerialReader(settings["port"], source=transport.name, clock=options.clock, baudrate=settings["baud"],
                        max_sentence_chars=settings["max_sentence_chars"], decode=False,
                        on_data=lambda t_s, data: sink(RawInput(t_s, data)), on_link=sink)


def _nmea2000_reader(transport: TransportConfig, sink: InputSink, options: ReaderOptions) -> Reader:
    """NMEA 2000 on a CAN bus (python-can's ``interface``) or through a gateway (YDWG, NGT-1)."""
    from interfaces.nmea2000.gateways import GATEWAY_KINDS, GatewayConfig, N2kGatewayReader  # noqa: PLC0415
    from interfaces.nmea2000.transport import CanBusConfig, N2kCanReader, RawFrame  # noqa: PLC0415

    def deliver(event: object) -> None:
        if isinstance(event, RawFrame):
            sink(RawInput(event.t_s, event.data, event.can_id))
        elif isinstance(event, RejectedInput | LinkStatus):
            sink(event)

    settings = transport.settings
    channel = "" if settings["channel"] is None else str(settings["channel"])
    options_of_bus = dict(settings.get("options") or {})
    if settings["interface"] in GATEWAY_KINDS:
        return N2kGatewayReader(GatewayConfig(settings["interface"], channel, options_of_bus), deliver,
                                clock=options.clock, decode=False)
    return N2kCanReader(CanBusConfig(settings["interface"], channel or "can0", options_of_bus), deliver,
                        clock=options.clock, decode=False, request_address_claims=options.request_address_claims)


def _mavlink_reader(transport: TransportConfig, sink: InputSink, options: ReaderOptions) -> Reader:
    """MAVLink 2 on a UDP port (``udpin:HOST:PORT``): every datagram (the heartbeat watch is the input stage's)."""
    from interfaces.mavlink.transport import MavlinkUdpReader, RawPacket, parse_udpin  # noqa: PLC0415

    def deliver(event: object) -> None:
        if isinstance(event, RawPacket):
            sink(RawInput(event.t_s, event.data))
        elif isinstance(event, LinkStatus):
            sink(event)

    return MavlinkUdpReader(deliver, bind=parse_udpin(transport.settings["url"]), clock=options.clock,
                            decode=False)


READERS: dict[str, ReaderFactory] = {
    "nmea0183": _serial_reader,
    "nmea2000": _nmea2000_reader,
    "mavlink": _mavlink_reader,
}
"""Protocol name (a transport's ``protocol`` key) → the factory of its reader."""


def open_reader(transport: TransportConfig, sink: InputSink, options: ReaderOptions) -> Reader:
    """The reader of ``transport`` (not started), delivering to ``sink``.

    Raises
    ------
    ValueError
        The protocol has no reader (the configuration parser admits only known ones), or the device's settings
        are refused by its reader.
    """
    if transport.in_process:
        raise ValueError(f"transport {transport.name}: an in-process transport has no device to read")
    factory = READERS.get(transport.protocol)
    if factory is None:
        raise ValueError(f"transport {transport.name}: no reader for protocol {transport.protocol!r}")
    return factory(transport, sink, options)
