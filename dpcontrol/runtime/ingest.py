"""The input stage: raw input of one transport → decoded, counted, routed measurements.

One :class:`TransportInput` per configured transport, chosen by its protocol from :data:`INPUTS` (the way
python-can chooses ``Bus(interface=...)``), holds that transport's decoder and feeds what it decodes through the
:class:`~dpcontrol.runtime.inputs.SensorRouter`: every frame counted in the transport's health (decoded, or
rejected with its reason), every routed message appended as a :class:`~interfaces.messages.Measurement` to the
caller's list. The daemon (the bytes its transport readers deliver, :mod:`dpcontrol.service.transports`), the
lockstep simulation (the plant's encoded bytes), ``dpcontrol replay`` (the recorded raw inputs) and ``dpcontrol
bench`` all read through it, so they decode and route exactly alike. A new protocol is one class here and its
entry in :data:`INPUTS`; nothing in the callers branches on protocol names.

Each raw input (an NMEA 0183 sentence, a CAN frame or gateway message, a MAVLink datagram) can be shown to an
observer (:data:`RawObserver`: the daemon's recorder, which numbers it) before its measurements are appended, so
a caller knows which raw input every measurement came from. :meth:`TransportInput.poll` runs what time alone
decides (fast packets given up, MAVLink heartbeat timeouts) and :meth:`TransportInput.link_changed` what a
link change does to the decoder (a serial line's half sentence is dropped).

Pure per-step logic: no clock, no I/O, no threads (the transports that read devices live in ``interfaces/``).
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Callable, Iterator, Mapping, Sequence
from typing import Any, ClassVar, cast

from dpcontrol.runtime.config import TransportConfig
from dpcontrol.runtime.inputs import SensorRouter, link_source
from dpcontrol.runtime.transport_health import InputHealth
from interfaces.mavlink.codec import HeartbeatMonitor, MavlinkDecoder, parse_signing_key
from interfaces.messages import LinkHeartbeat, LinkStatus, Measurement, Rejected
from interfaces.nmea0183 import Nmea0183Decoder
from interfaces.nmea0183.codec import DEFAULT_MAX_SENTENCE_CHARS, Frame
from interfaces.nmea2000.codec import N2kDecoder, parse_can_id

Count = Callable[..., None]
"""``count(t_s, reason=None)``: one frame of a transport, decoded (no reason) or rejected."""

RawObserver = Callable[[str, float, bytes, "str | None", dict[str, Any]], None]
"""``observe(transport, t_s, data, rejected, fields)``: one raw input as received (``rejected``: the decoder's
reason, None when accepted; ``fields``: ``sentence`` of an NMEA 0183 line, ``can_id`` of a CAN frame), shown
before the measurements it gives are appended."""


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
    on_raw : RawObserver or None
        Shown every raw input (the daemon's recorder); None: nobody.

    Attributes
    ----------
    rejected : int
        Frames rejected so far (malformed, invalid, unknown).
    """

    protocol: ClassVar[str]

    def __init__(self, transport: TransportConfig, router: SensorRouter, health: InputHealth | None,
                 on_raw: RawObserver | None = None) -> None:
        self.name = transport.name
        self.router = router
        self.on_raw = on_raw
        self.rejected = 0
        # the counter's bound method, taken once: several frames a step go through it
        self._count: Count = _uncounted if health is None else health.of(transport.name).add

    def _reject(self, t_s: float, reason: str) -> None:
        self.rejected += 1
        self._count(t_s, reason)

    def _accepted(self, t_s: float, results: Sequence[Any]) -> Iterator[Any]:
        """A decoder's results that are not :class:`Rejected`, each counted as it is taken; the rejected ones
        counted with their reason."""
        for result in results:
            item = result.item
            if isinstance(item, Rejected):
                self._reject(t_s, item.reason)
                continue
            self._count(t_s)
            yield result

    @abstractmethod
    def feed(self, t_s: float, data: bytes, out: list[Measurement] | None, *, can_id: int | None = None) -> None:
        """Decode one raw input received at ``t_s`` (s): count its frames, append its routed measurements to
        ``out`` (None: decode and count only, as for a malformed burst). ``can_id``: NMEA 2000 only."""

    @abstractmethod
    def feed_record(self, t_s: float, record: Mapping[str, Any], data: bytes, out: list[Measurement]) -> None:
        """Feed one input as the recorder stored it (``record``: the ``raw/<transport>`` payload)."""

    def expire(self, t_s: float) -> None:  # noqa: B027 - only protocols with reassembly state need it
        """Give up partial messages older than the protocol allows (NMEA 2000 fast packets)."""

    def poll(self, t_s: float, links: list[LinkStatus]) -> None:
        """What time alone decides at ``t_s`` (s), once per cycle: expiries, and link changes appended to
        ``links`` (MAVLink heartbeat timeouts)."""
        self.expire(t_s)

    def link_changed(self, t_s: float, connected: bool, out: list[Measurement] | None) -> None:  # noqa: B027
        """The transport's link was lost or regained at ``t_s`` (s) (only a byte stream holds a partial frame)."""


class Nmea0183Input(TransportInput):
    """A serial NMEA 0183 stream: bytes in any chunking (sentences split across reads are reassembled)."""

    protocol = "nmea0183"

    def __init__(self, transport: TransportConfig, router: SensorRouter, health: InputHealth | None,
                 on_raw: RawObserver | None = None) -> None:
        super().__init__(transport, router, health, on_raw)
        self.decoder = Nmea0183Decoder(transport.settings.get("max_sentence_chars", DEFAULT_MAX_SENTENCE_CHARS))

    def feed(self, t_s: float, data: bytes, out: list[Measurement] | None, *, can_id: int | None = None) -> None:
        self._frames(t_s, self.decoder.feed_frames(data), out)

    def link_changed(self, t_s: float, connected: bool, out: list[Measurement] | None) -> None:
        if not connected:  # the half sentence of a lost line is given up (counted as its decoder says)
            self._frames(t_s, self.decoder.flush(), out)

    def _frames(self, t_s: float, frames: Sequence[Frame], out: list[Measurement] | None) -> None:
        count = self._count
        route = self.router.nmea0183
        transport = self.name
        on_raw = self.on_raw
        for frame in frames:
            rejected = frame.rejected
            if on_raw is not None:
                on_raw(transport, t_s, frame.raw, None if rejected is None else rejected.reason,
                       {"sentence": frame.sentence or None})
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

    def __init__(self, transport: TransportConfig, router: SensorRouter, health: InputHealth | None,
                 on_raw: RawObserver | None = None) -> None:
        super().__init__(transport, router, health, on_raw)
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
        if self.on_raw is not None:
            self.on_raw(self.name, t_s, data, _first_rejection(results), {"can_id": can_id})
        self._results(t_s, results, out)

    def feed_record(self, t_s: float, record: Mapping[str, Any], data: bytes, out: list[Measurement]) -> None:
        can_id = record.get("can_id")
        if isinstance(can_id, int):
            self.feed(t_s, data, out, can_id=can_id)

    def expire(self, t_s: float) -> None:
        self._results(t_s, self.decoder.expire(t_s), None)

    def _results(self, t_s: float, results: Sequence[Any], out: list[Measurement] | None) -> None:
        for result in self._accepted(t_s, results):
            if out is not None:
                item = result.item
                address = result.source_address
                sensor = self.router.nmea2000(self.name, address, item, self.decoder.name_of(address))
                if sensor is not None:
                    out.append(Measurement(t_s, sensor, item))


class MavlinkInput(TransportInput):
    """A MAVLink 2 link: one UDP datagram per input (signed when the transport has a signing key).

    Parameters
    ----------
    start_t_s : float or None
        When the link was opened [s]: the autopilots' heartbeats are watched from then on (a
        :class:`~interfaces.mavlink.codec.HeartbeatMonitor` with the transport's ``heartbeat_timeout_s``; each
        system's loss and return, or nothing heard at all, are link changes of :meth:`poll`). None: heartbeats
        are only counted (replay: the recording has the link changes).
    signing_time_s : float
        Wall time [s] that starts the signature replay window of a signed link.
    """

    protocol = "mavlink"

    def __init__(self, transport: TransportConfig, router: SensorRouter, health: InputHealth | None,
                 on_raw: RawObserver | None = None, *, start_t_s: float | None = None,
                 signing_time_s: float = 0.0) -> None:
        super().__init__(transport, router, health, on_raw)
        key = transport.settings.get("signing_key_hex")
        self.decoder = MavlinkDecoder(parse_signing_key(key) if key else None, signing_time_s=signing_time_s)
        timeout = transport.settings.get("heartbeat_timeout_s")
        self.monitor = None if start_t_s is None or timeout is None else \
            HeartbeatMonitor(float(timeout), start_t_s=start_t_s)
        self._link_changes: list[LinkStatus] = []  # heartbeats that (re)connected a system, until the next poll

    def feed(self, t_s: float, data: bytes, out: list[Measurement] | None, *, can_id: int | None = None) -> None:
        results = self.decoder.decode_datagram(data)
        if self.on_raw is not None:
            self.on_raw(self.name, t_s, data, _first_rejection(results), {})
        for result in self._accepted(t_s, results):
            item = result.item
            if isinstance(item, LinkHeartbeat):
                if self.monitor is not None:
                    change = self.monitor.beat((item.system_id, item.component_id), t_s)
                    if change is not None:
                        self._link_changes.append(LinkStatus(t_s, link_source(self.name, item.system_id), True,
                                                             change.detail))
                continue
            if out is not None:
                sensor = self.router.mavlink(self.name, result.system_id, result.msg_name, item)
                if sensor is not None:
                    out.append(Measurement(t_s, sensor, item))

    def feed_record(self, t_s: float, record: Mapping[str, Any], data: bytes, out: list[Measurement]) -> None:
        self.feed(t_s, data, out)

    def poll(self, t_s: float, links: list[LinkStatus]) -> None:
        if self._link_changes:
            links.extend(self._link_changes)
            self._link_changes.clear()
        if self.monitor is not None:
            for change in self.monitor.check(t_s):
                # the monitor's keys are (system, component), as feed beats them; None: nothing heard at all
                system = None if change.key is None else cast(tuple[int, int], change.key)[0]
                links.append(LinkStatus(change.t_s, link_source(self.name, system), change.connected, change.detail))


def _first_rejection(results: Sequence[Any]) -> str | None:
    """The reason of the first rejection among a decoder's results (None: all accepted)."""
    for result in results:
        if isinstance(result.item, Rejected):
            return result.item.reason
    return None


INPUTS: dict[str, type[TransportInput]] = {cls.protocol: cls for cls in (Nmea0183Input, Nmea2000Input, MavlinkInput)}
"""Protocol name (a transport's ``protocol`` key) → its input class."""


def transport_inputs(transports: Sequence[TransportConfig], router: SensorRouter, health: InputHealth | None = None,
                     *, on_raw: RawObserver | None = None, start_t_s: float | None = None,
                     signing_time_s: float = 0.0) -> dict[str, TransportInput]:
    """One :class:`TransportInput` per configured transport, by name.

    ``on_raw`` is shown every raw input; ``start_t_s`` (s, the caller's clock) starts the MAVLink heartbeat
    watch (None: none), ``signing_time_s`` (s, wall time) a signed link's replay window.

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
            inputs[transport.name] = MavlinkInput(transport, router, health, on_raw, start_t_s=start_t_s,
                                                  signing_time_s=signing_time_s)
        else:
            inputs[transport.name] = cls(transport, router, health, on_raw)
    return inputs
