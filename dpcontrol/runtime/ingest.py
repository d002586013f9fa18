"""The input stage: raw input of one transport → decoded, counted, routed measurements.

One :class:`TransportInput` per configured transport, chosen by its protocol from :data:`INPUTS` (the way
python-can chooses ``Bus(interface=...)``), holds that transport's decoder and feeds what it decodes through the
:class:`~dpcontrol.runtime.inputs.SensorRouter`: every frame counted in the transport's health (decoded, or
rejected with its reason), every routed message appended as a :class:`~interfaces.messages.Measurement` to the
caller's list. The lockstep simulation (the plant's encoded bytes), ``dpcontrol replay`` (the recorded raw
inputs) and ``dpcontrol bench`` all read through it, so they decode and route exactly alike. A new protocol is
one class here and its entry in :data:`INPUTS`; nothing in the callers branches on protocol names.

Pure per-step logic: no clock, no I/O, no threads (the transports that read devices live in ``interfaces/``).
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping, Sequence
from typing import Any, ClassVar

from dpcontrol.runtime.config import TransportConfig
from dpcontrol.runtime.inputs import SensorRouter
from dpcontrol.runtime.transport_health import InputHealth
from interfaces.mavlink.codec import MavlinkDecoder, parse_signing_key
from interfaces.messages import LinkHeartbeat, Measurement, Rejected
from interfaces.nmea0183 import Nmea0183Decoder
from interfaces.nmea0183.codec import DEFAULT_MAX_SENTENCE_CHARS
from interfaces.nmea2000.codec import N2kDecoder, parse_can_id

Count = Callable[..., None]
"""``count(t_s, reason=None)``: one frame of a transport, decoded (no reason) or rejected."""

HeartbeatSink = Callable[[str, int, int, float], None]
"""``sink(transport, system_id, component_id, t_s)``: a MAVLink HEARTBEAT arrived."""


def _uncounted(_t_s: float, _reason: str | None = None) -> None:
    """Counter of a stage that keeps no transport health (replay: the recording has the counts)."""


class TransportInput(ABC):
    """Decoder and routing of one transport.

    Parameters
    ----------
    transport : TransportConfig
        The configured transport (its ``name``, ``protocol`` and protocol settings).
    router : SensorRouter
        Which configured sensor a decoded message belongs to.
    health : InputHealth or None
        Where every frame is counted (None: not counted).

    Attributes
    ----------
    rejected : int
        Frames rejected so far (malformed, invalid, unknown).
    """

    protocol: ClassVar[str]

    def __init__(self, transport: TransportConfig, router: SensorRouter, health: InputHealth | None) -> None:
        self.name = transport.name
        self.router = router
        self.rejected = 0
        # the counter's bound method, taken once: several frames a step go through it
        self._count: Count = _uncounted if health is None else health.of(transport.name).add

    def _reject(self, t_s: float, reason: str) -> None:
        self.rejected += 1
        self._count(t_s, reason)

    @abstractmethod
    def feed(self, t_s: float, data: bytes, out: list[Measurement] | None, *, can_id: int | None = None) -> None:
        """Decode one raw input received at ``t_s`` (s): count its frames, append its routed measurements to
        ``out`` (None: decode and count only, as for a malformed burst). ``can_id``: NMEA 2000 only."""

    @abstractmethod
    def feed_record(self, t_s: float, record: Mapping[str, Any], data: bytes, out: list[Measurement]) -> None:
        """Feed one input as the recorder stored it (``record``: the ``raw/<transport>`` payload)."""

    def expire(self, t_s: float) -> None:  # noqa: B027 - only protocols with reassembly state need it
        """Give up partial messages older than the protocol allows (NMEA 2000 fast packets)."""


class Nmea0183Input(TransportInput):
    """A serial NMEA 0183 stream: bytes in any chunking (sentences split across reads are reassembled)."""

    protocol = "nmea0183"

    def __init__(self, transport: TransportConfig, router: SensorRouter, health: InputHealth | None) -> None:
        super().__init__(transport, router, health)
        self.decoder = Nmea0183Decoder(transport.settings.get("max_sentence_chars", DEFAULT_MAX_SENTENCE_CHARS))

    def feed(self, t_s: float, data: bytes, out: list[Measurement] | None, *, can_id: int | None = None) -> None:
        count = self._count
        route = self.router.nmea0183
        transport = self.name
        for frame in self.decoder.feed_frames(data):
            rejected = frame.rejected
            if rejected is not None:
                self._reject(t_s, rejected.reason)
                continue
            count(t_s)
            if out is not None:
                for message in frame.messages:
                    sensor = route(transport, frame.sentence, message)
                    if sensor is not None:
                        out.append(Measurement(t_s, sensor, message))

    def feed_record(self, t_s: float, record: Mapping[str, Any], data: bytes, out: list[Measurement]) -> None:
        # the recorder keeps each sentence without its line terminator
        self.feed(t_s, data + b"\r\n", out)


class Nmea2000Input(TransportInput):
    """A NMEA 2000 bus: one CAN frame per input (fast packets reassembled, with expiry), or one whole message of
    more than 8 bytes as a gateway (NGT-1) delivers it. Magnetic headings take the transport's configured
    ``variation_deg`` when the bus broadcasts none; routes by device NAME follow the bus's address claims."""

    protocol = "nmea2000"

    def __init__(self, transport: TransportConfig, router: SensorRouter, health: InputHealth | None) -> None:
        super().__init__(transport, router, health)
        variation = transport.settings.get("variation_deg")
        self.decoder = N2kDecoder(variation_rad=None if variation is None else math.radians(variation))

    def feed(self, t_s: float, data: bytes, out: list[Measurement] | None, *, can_id: int | None = None) -> None:
        if can_id is None:
            raise ValueError(f"{self.name}: a NMEA 2000 frame needs its CAN identifier")
        if len(data) > 8:  # a whole message from a gateway: its identifier names the PGN and the source
            header = parse_can_id(can_id)
            results = self.decoder.decode_message(header.pgn, header.source, data, t_s)
        else:
            results = self.decoder.decode_frame(can_id, data, t_s)
        self._results(t_s, results, out)

    def feed_record(self, t_s: float, record: Mapping[str, Any], data: bytes, out: list[Measurement]) -> None:
        can_id = record.get("can_id")
        if isinstance(can_id, int):
            self.feed(t_s, data, out, can_id=can_id)

    def expire(self, t_s: float) -> None:
        self._results(t_s, self.decoder.expire(t_s), None)

    def _results(self, t_s: float, results: Sequence[Any], out: list[Measurement] | None) -> None:
        for result in results:
            item = result.item
            if isinstance(item, Rejected):
                self._reject(t_s, item.reason)
                continue
            self._count(t_s)
            if out is not None:
                address = result.source_address
                sensor = self.router.nmea2000(self.name, address, item, self.decoder.name_of(address))
                if sensor is not None:
                    out.append(Measurement(t_s, sensor, item))


class MavlinkInput(TransportInput):
    """A MAVLink 2 link: one UDP datagram per input (signed when the transport has a signing key).

    Parameters
    ----------
    on_heartbeat : HeartbeatSink or None
        Told of every HEARTBEAT (the link monitor of the caller); None: heartbeats are only counted.
    """

    protocol = "mavlink"

    def __init__(self, transport: TransportConfig, router: SensorRouter, health: InputHealth | None,
                 on_heartbeat: HeartbeatSink | None = None) -> None:
        super().__init__(transport, router, health)
        key = transport.settings.get("signing_key_hex")
        self.decoder = MavlinkDecoder(parse_signing_key(key) if key else None)
        self.on_heartbeat = on_heartbeat

    def feed(self, t_s: float, data: bytes, out: list[Measurement] | None, *, can_id: int | None = None) -> None:
        for result in self.decoder.decode_datagram(data):
            item = result.item
            if isinstance(item, Rejected):
                self._reject(t_s, item.reason)
                continue
            self._count(t_s)
            if isinstance(item, LinkHeartbeat):
                if self.on_heartbeat is not None:
                    self.on_heartbeat(self.name, item.system_id, item.component_id, t_s)
                continue
            if out is not None:
                sensor = self.router.mavlink(self.name, result.system_id, result.msg_name, item)
                if sensor is not None:
                    out.append(Measurement(t_s, sensor, item))

    def feed_record(self, t_s: float, record: Mapping[str, Any], data: bytes, out: list[Measurement]) -> None:
        self.feed(t_s, data, out)


INPUTS: dict[str, type[TransportInput]] = {cls.protocol: cls for cls in (Nmea0183Input, Nmea2000Input, MavlinkInput)}
"""Protocol name (a transport's ``protocol`` key) → its input class."""


def transport_inputs(transports: Sequence[TransportConfig], router: SensorRouter, health: InputHealth | None = None,
                     *, on_heartbeat: HeartbeatSink | None = None) -> dict[str, TransportInput]:
    """One :class:`TransportInput` per configured transport, by name.

    Raises
    ------
    ValueError
        A transport's protocol has no input class (the configuration parser admits only known ones).
    """
    inputs: dict[str, TransportInput] = {}
    for transport in transports:
        cls = INPUTS.get(transport.protocol)
        if cls is None:
            raise ValueError(f"transport {transport.name}: no input stage for protocol {transport.protocol!r}")
        if cls is MavlinkInput:
            inputs[transport.name] = MavlinkInput(transport, router, health, on_heartbeat)
        else:
            inputs[transport.name] = cls(transport, router, health)
    return inputs
