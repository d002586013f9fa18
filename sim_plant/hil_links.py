"""Sensor links of the HIL emulator: the plant's sensor samples onto real transports.

One link per transport of the controller's configuration (:mod:`sim_plant.hil_config`), shared by
every sensor wired to it, each sensor encoded as the real device would be:

* :class:`SerialLink` (NMEA 0183): a pseudo-terminal (:class:`interfaces.nmea0183.PtyPair`) whose
  slave is reached through a symlink at the daemon's configured ``port``. A GNSS sends GGA + GST
  (or the controller's ``sentences``: GGA, GNS, RMC, GST), a gyrocompass THS + ROT (or HDT, THS,
  ROT), with the controller's ``talker`` (default GP / HE). Invalid samples are GGA quality 0
  (+ RMC status V when RMC is sent) and THS mode V (+ ROT status V); an HDT-only gyro
  goes silent (HDT has no validity field).
* :class:`N2kLink` (NMEA 2000): python-can bus from the controller's ``interface``/``channel``;
  for ``remote`` the emulator starts the python-can-remote server at the channel's port. A GNSS
  sends PGN 129029 (fast packet), a gyro 127250 (true) + 127251, each sensor from its own source
  address (the controller's ``source_address``, else a free one from 100 up). Invalid samples are
  129029 method "no GNSS" and 127250 (+ 127251) with the values "not available".
* :class:`MavlinkLink` (MAVLink 2 over UDP): the emulator is a boat autopilot
  (``MAV_TYPE_SURFACE_BOAT``) per system id (the controller's ``system_id``, else 1) sending to the
  daemon's ``udpin:HOST:PORT``: HEARTBEAT at 1 Hz (wall clock), GPS_RAW_INT for a GNSS, ATTITUDE
  (yaw, yaw rate; roll and pitch "unknown", a 3-DOF plant has none) for a gyro; signed when the
  controller has a signing key. Invalid samples are GPS_RAW_INT fix_type 0 and ATTITUDE without
  values.

Never blocking the emulator loop
--------------------------------
A pty buffers what nobody reads (~18 kB in the kernel) and then blocks its writer; a real serial
line simply loses what a closed or stalled port does not take. So the master side is non-blocking,
writes go through a small pending buffer (partial writes continue on the next call, whole sample
groups that do not fit are dropped and counted), and before each write the unread bytes on the
line are measured (``FIONREAD`` on a slave descriptor the link holds); above ``max_backlog_bytes``
(default 2048 B, about a second of a 10 Hz GNSS + gyro) they are discarded (``tcflush``) and
counted, as a real UART would lose them. So a daemon that opens the port late, or stalls, gets at
most ~1 s of old data, stamped as new by its reader — never a 10 s backlog. CAN (python-can-remote:
a websocket) and UDP sends do not block at these rates; failures are counted by the interface
writers, which reconnect by themselves.

Nothing a link does raises into the loop for bad data: encoding errors are counted per sensor and
logged once.
"""

from __future__ import annotations

import contextlib
import fcntl
import logging
import os
import struct
import termios
import time
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from interfaces.mavlink.codec import MavlinkEncoder
from interfaces.mavlink.transport import MavlinkUdpSender
from interfaces.messages import PositionFix, SensorMessage
from interfaces.nmea0183 import (
    PtyPair,
)
from interfaces.nmea2000.gateways import GATEWAY_KINDS, GatewayConfig, GatewayTwin
from interfaces.nmea2000.transport import CanBusConfig, N2kCanWriter, RemoteServerHandle, start_remote_server
from sim_plant.encoding import DATE_DAYS_SINCE_1970, MavlinkSensorEncoder, N2kSensorEncoder, NmeaSensorEncoder
from sim_plant.hil_config import (
    HEADING_SENTENCES,
    POSITION_SENTENCES,
    CanTransport,
    MavlinkTransport,
    SerialTransport,
    Wire,
)
from sim_plant.protocol_faults import mavlink_burst, n2k_burst, nmea0183_burst
from sim_plant.sensors import InvalidFix

log = logging.getLogger(__name__)

Record = Callable[[str, float, "dict[str, Any] | bytes"], None]
Message = SensorMessage | InvalidFix

# The emulated calendar day, 2024-01-01 (UTC): the same day MavlinkEncoder assumes by default, so
# RMC, PGN 129029 and GPS_RAW_INT agree. Sensor times are seconds of that day.
FIRST_AUTO_N2K_ADDRESS = 100
MAX_BACKLOG_BYTES = 2048
MAX_PENDING_BYTES = 8192


class HilLinkError(RuntimeError):
    """A link could not be set up (a path that is a real device, a server that does not start ...)."""


def _no_record(topic: str, t_s: float, payload: dict[str, Any] | bytes) -> None:
    del topic, t_s, payload


@dataclass
class SensorChannel:
    """One sensor on a link: identity, encoding choices, counters, and its latest valid output."""

    name: str
    kind: str  # "position" | "heading"
    counters: Counter[str] = field(default_factory=Counter)
    last: list[SensorMessage] = field(default_factory=list)  # latest valid messages (burst templates)
    source_address: int = -1
    system_id: int = 0
    rate_of_turn: bool = False  # a gyro that also sends its rate of turn (flagged invalid with the heading)
    coder: Any = None  # the sensor's encoder (sim_plant.encoding): the same bytes as in lockstep


class Link:
    """Base of the sensor links (see the module docstring).

    Parameters
    ----------
    name : str
        Transport name (from the controller configuration).
    record : callable, optional
        ``record(topic, t_s, payload)`` for every raw output (topic ``raw/<transport>``, payload
        ``{"data": bytes, "source": sensor, "transport": name[, "can_id": id][, "fault": kind]}``).
        Must not raise (the emulator wraps it).
    """

    protocol = ""

    def __init__(self, name: str, record: Record | None = None) -> None:
        self.name = name
        self.counters: Counter[str] = Counter()
        self.channels: dict[str, SensorChannel] = {}
        self._record = record or _no_record
        self._topic = f"raw/{name}"
        self._warned: set[str] = set()

    # -- set-up ------------------------------------------------------------------------------------
    def add(self, wire: Wire, fallback: Sequence[SensorMessage]) -> SensorChannel:
        """Connect a sensor; ``fallback`` stands in for its latest output until it has sent one."""
        channel = SensorChannel(wire.spec.name, wire.sensor.kind, last=list(fallback),
                                rate_of_turn=bool(getattr(wire.spec, "rate_of_turn", False)))
        self._configure(channel, wire)
        self.channels[channel.name] = channel
        return channel

    def _configure(self, channel: SensorChannel, wire: Wire) -> None:
        del channel, wire

    # -- output ------------------------------------------------------------------------------------
    def send(self, sensor: str, t_s: float, messages: Sequence[Message]) -> int:
        """Send one sample group (the messages a sensor produced at ``t_s``); returns items sent."""
        channel = self.channels[sensor]
        valid = [m for m in messages if not isinstance(m, InvalidFix)]
        if len(valid) < len(messages):
            channel.counters["invalid_samples"] += 1
        elif valid:
            channel.last = valid
        channel.counters["samples"] += 1
        try:
            return self._send(channel, t_s, messages)
        except (ValueError, TypeError, OverflowError) as error:  # a value the protocol cannot carry
            channel.counters["encode_errors"] += 1
            self._warn_once(f"encode:{sensor}", "%s: cannot encode a sample of %s: %s", self.name, sensor, error)
            return 0

    def _send(self, channel: SensorChannel, t_s: float, messages: Sequence[Message]) -> int:
        raise NotImplementedError

    def malformed_burst(self, sensor: str, t_s: float, count: int, rng: np.random.Generator) -> int:
        """Send ``count`` malformed items that look like ``sensor`` gone wrong; returns items sent."""
        channel = self.channels[sensor]
        try:
            sent = self._burst(channel, t_s, count, rng)
        except (ValueError, TypeError) as error:
            self._warn_once(f"burst:{sensor}", "%s: malformed burst for %s failed: %s", self.name, sensor, error)
            return 0
        channel.counters["malformed_items"] += sent
        return sent

    def _burst(self, channel: SensorChannel, t_s: float, count: int, rng: np.random.Generator) -> int:
        raise NotImplementedError

    def service(self, t_s: float) -> None:
        """Periodic work at plant time ``t_s`` (pending writes, heartbeats); cheap when idle."""
        del t_s

    @property
    def next_service_s(self) -> float:
        """Plant time of the next scheduled :meth:`service` work (inf: none)."""
        return float("inf")

    def describe(self) -> dict[str, Any]:
        """What the link is connected to (device path, bus, address), for logs and the summary."""
        return {"transport": self.name, "protocol": self.protocol}

    def snapshot(self) -> dict[str, Any]:
        """Counters of the link and of each sensor on it."""
        return {**self.describe(), "counters": dict(self.counters),
                "sensors": {name: dict(ch.counters) for name, ch in self.channels.items()}}

    def close(self) -> None:
        """Release the transport (idempotent)."""

    def _emit_record(self, t_s: float, sensor: str, data: bytes, **extra: Any) -> None:
        self._record(self._topic, t_s, {"data": data, "source": sensor, "transport": self.name, **extra})

    def _warn_once(self, key: str, message: str, *args: object) -> None:
        if key not in self._warned:
            self._warned.add(key)
            log.warning(message, *args)


# ==================================================================================================
# NMEA 0183 on a pseudo-terminal
# ==================================================================================================
class SerialLink(Link):
    """NMEA 0183 sensors on one pty whose slave the daemon opens at ``transport.port``.

    Parameters
    ----------
    transport : SerialTransport
    record : callable, optional
    max_backlog_bytes : int
        Unread bytes on the line above which they are discarded (see the module docstring).
    max_pending_bytes : int
        Bytes the link holds back while the pty does not take them (then groups are dropped).

    Raises
    ------
    HilLinkError
        The port path exists and is not a symlink (a real device or file: never replaced), or its
        folder does not exist.
    """

    protocol = "nmea0183"

    def __init__(self, transport: SerialTransport, record: Record | None = None, *,
                 max_backlog_bytes: int = MAX_BACKLOG_BYTES, max_pending_bytes: int = MAX_PENDING_BYTES) -> None:
        super().__init__(transport.name, record)
        self.transport = transport
        path = Path(transport.port)
        if path.exists() and not path.is_symlink():
            raise HilLinkError(f"transport {transport.name}: {path} exists and is not a symlink; the emulator "
                               "creates the port as a symlink to a pseudo-terminal and never replaces a real "
                               "device or file")
        if not path.parent.is_dir():
            raise HilLinkError(f"transport {transport.name}: folder {path.parent} of port {path} does not exist")
        if path.is_symlink():
            log.warning("%s: replacing the existing symlink %s -> %s", transport.name, path, os.readlink(path))
        self._max_backlog = max_backlog_bytes
        self._max_pending = max_pending_bytes
        self._pending = bytearray()
        self._line_fd = -1
        try:
            self.pty = PtyPair(link_path=path)
        except OSError as error:
            raise HilLinkError(f"transport {transport.name}: cannot create a pty at {path}: {error}") from error
        self._prepare()

    def _prepare(self) -> None:
        """Non-blocking master; our own slave descriptor to measure and discard the unread backlog."""
        flags = fcntl.fcntl(self.pty.master_fd, fcntl.F_GETFL)
        fcntl.fcntl(self.pty.master_fd, fcntl.F_SETFL, flags | os.O_NONBLOCK)
        self._line_fd = os.open(self.pty.slave_path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)

    @property
    def device_path(self) -> str:
        """The path the daemon opens (the symlink)."""
        return self.pty.device_path

    @property
    def plugged(self) -> bool:
        return self.pty.plugged

    def _configure(self, channel: SensorChannel, wire: Wire) -> None:
        position = channel.kind == "position"
        applicable = POSITION_SENTENCES if position else HEADING_SENTENCES
        if wire.sensor.sentences and not any(x in applicable for x in wire.sensor.sentences):
            log.warning("%s: sensor %s lists no %s sentence (%s): sending the defaults", self.name, channel.name,
                        channel.kind, ", ".join(wire.sensor.sentences))
        channel.coder = NmeaSensorEncoder(channel.kind, wire.sensor.talker, wire.sensor.sentences,
                                          rate_of_turn=channel.rate_of_turn)

    def encode(self, channel: SensorChannel, messages: Sequence[Message]) -> list[bytes]:
        """The sentences of one sample group (see :mod:`sim_plant.encoding`)."""
        return channel.coder.encode(messages)

    def _send(self, channel: SensorChannel, t_s: float, messages: Sequence[Message]) -> int:
        sentences = self.encode(channel, messages)
        if not sentences:
            return 0
        if not self._write(b"".join(sentences)):
            channel.counters["dropped_samples"] += 1
            return 0
        for sentence in sentences:
            self._emit_record(t_s, channel.name, sentence)
        channel.counters["sentences"] += len(sentences)
        return len(sentences)

    def _burst(self, channel: SensorChannel, t_s: float, count: int, rng: np.random.Generator) -> int:
        templates = self.encode(channel, channel.last)
        items = nmea0183_burst(templates, count, rng)
        if not items or not self._write(b"".join(items)):
            return 0
        for item in items:
            self._emit_record(t_s, channel.name, item, fault="malformed_burst")
        return len(items)

    # -- the line ----------------------------------------------------------------------------------
    def _write(self, data: bytes) -> bool:
        """Queue ``data`` and write what the pty takes now; ``False`` (counted) if it was dropped."""
        if not self.pty.plugged:
            self.counters["dropped_unplugged_bytes"] += len(data)
            return False
        self._discard_backlog()
        if len(self._pending) + len(data) > self._max_pending:
            self.counters["dropped_full_bytes"] += len(data)
            return False
        self._pending += data
        self._flush()
        return True

    def _discard_backlog(self) -> None:
        try:
            unread = struct.unpack("i", fcntl.ioctl(self._line_fd, termios.FIONREAD, b"\0\0\0\0"))[0]
            if unread > self._max_backlog:
                termios.tcflush(self._line_fd, termios.TCIFLUSH)
                self.counters["backlog_flushes"] += 1
                self.counters["backlog_bytes_discarded"] += unread + len(self._pending)
                self._pending.clear()  # may start mid-sentence; the stream resumes at a sentence start
        except OSError as error:
            self.counters["line_errors"] += 1
            self._warn_once("backlog", "%s: cannot inspect the pty line: %s", self.name, error)

    def _flush(self) -> None:
        while self._pending:
            try:
                written = os.write(self.pty.master_fd, self._pending)
            except BlockingIOError:
                self.counters["write_would_block"] += 1
                return
            except OSError as error:
                self.counters["write_errors"] += 1
                self.counters["dropped_error_bytes"] += len(self._pending)
                self._pending.clear()
                self._warn_once("write", "%s: write to the pty failed: %s", self.name, error)
                return
            del self._pending[:written]
            self.counters["bytes_written"] += written

    def service(self, t_s: float) -> None:
        if self._pending and self.pty.plugged:
            self._flush()

    # -- faults ------------------------------------------------------------------------------------
    def unplug(self) -> None:
        """Pull the cable: the pty and the symlink disappear; the daemon's reader sees EOF/EIO."""
        if not self.pty.plugged:
            return
        self._close_line()
        self.counters["dropped_unplugged_bytes"] += len(self._pending)
        self._pending.clear()
        self.pty.unplug()
        self.counters["unplugs"] += 1

    def replug(self) -> None:
        """Plug it back: a fresh pty behind the same symlink (what udev does for a USB adapter)."""
        if self.pty.plugged:
            return
        self.pty.replug()
        self._prepare()
        self.counters["replugs"] += 1

    def _close_line(self) -> None:
        if self._line_fd >= 0:
            with contextlib.suppress(OSError):
                os.close(self._line_fd)
            self._line_fd = -1

    def describe(self) -> dict[str, Any]:
        return {**super().describe(), "device": self.pty.device_path, "pty": self.pty.slave_path,
                "baud": self.transport.baud}

    @property
    def capacity_bytes_per_s(self) -> float:
        """What the configured line speed carries (8N1: 10 bits a byte). A pty has no limit, a real
        line at the same baud rate has: the summary compares the two."""
        return self.transport.baud / 10.0

    def close(self) -> None:
        self._close_line()
        self.pty.close()


# ==================================================================================================
# NMEA 2000 on a python-can bus
# ==================================================================================================
class N2kLink(Link):
    """NMEA 2000 sensors on one python-can bus (the daemon's ``interface``/``channel``).

    Parameters
    ----------
    transport : CanTransport
    record : callable, optional
    start_server : bool
        For a ``remote`` bus: start the python-can-remote server at the channel's host and port
        (default). False: connect to a server someone else runs.
    server_mode : {"process", "thread"}
        How the server runs (see :func:`interfaces.nmea2000.transport.start_remote_server`).

    Raises
    ------
    HilLinkError
        The server does not start, or the bus cannot be opened although the server is ours.
    """

    protocol = "nmea2000"

    def __init__(self, transport: CanTransport, record: Record | None = None, *, start_server: bool = True,
                 server_mode: str = "process") -> None:
        super().__init__(transport.name, record)
        self.transport = transport
        self.server: RemoteServerHandle | None = None
        self._addresses: set[int] = set()
        if transport.interface == "remote" and start_server:
            host, port = transport.remote_address()
            try:
                self.server = start_remote_server(host, port, channel=f"sim-plant-{transport.name}",
                                                  mode=server_mode)  # type: ignore[arg-type]
            except (RuntimeError, OSError) as error:
                raise HilLinkError(f"transport {transport.name}: cannot start the python-can-remote server on "
                                   f"{host}:{port}: {error}") from error
        self.bus: Any
        self.writer: GatewayTwin | N2kCanWriter  # (the same interface: open, send, counters, close)
        if transport.interface in GATEWAY_KINDS:  # the emulator plays the gateway (YD RAW server, NGT-1 pty)
            self.bus = GatewayConfig(transport.interface, transport.channel, dict(transport.options))
            self.writer = GatewayTwin(self.bus)
        else:
            self.bus = CanBusConfig(transport.interface, transport.channel, dict(transport.options))
            self.writer = N2kCanWriter(self.bus)
        try:
            self.writer.open()
        except Exception as error:  # python-can raises many types; the writer retries by itself later
            if self.server is not None:
                self.close()
                raise HilLinkError(f"transport {transport.name}: cannot open {self.bus.name}: {error!r}") from error
            log.warning("%s: cannot open %s yet (%r): will retry", self.name, self.bus.name, error)

    def _configure(self, channel: SensorChannel, wire: Wire) -> None:
        address = wire.sensor.source_address
        if address is None:
            address = FIRST_AUTO_N2K_ADDRESS
            while address in self._addresses:
                address += 1
        self._addresses.add(address)
        channel.source_address = address
        channel.coder = N2kSensorEncoder(address, rate_of_turn=channel.rate_of_turn)

    def reserve(self, addresses: Sequence[int]) -> None:
        """Addresses the controller configures for sensors on this bus: never auto-assigned to another."""
        self._addresses.update(addresses)

    def encode(self, channel: SensorChannel, messages: Sequence[Message]) -> list[tuple[int, bytes]]:
        """The CAN frames of one sample group (see :mod:`sim_plant.encoding`)."""
        frames = channel.coder.encode(messages)
        channel.counters["not_carried"] = channel.coder.counters["not_carried"]
        return frames

    def _send(self, channel: SensorChannel, t_s: float, messages: Sequence[Message]) -> int:
        frames = self.encode(channel, messages)
        return self._send_frames(channel, t_s, frames)

    def _send_frames(self, channel: SensorChannel, t_s: float, frames: list[tuple[int, bytes]],
                     **extra: Any) -> int:
        if not frames:
            return 0
        sent = self.writer.send(frames)
        for can_id, data in frames[:sent]:
            self._emit_record(t_s, channel.name, data, can_id=can_id, **extra)
        channel.counters["frames"] += sent
        if sent < len(frames):
            channel.counters["dropped_frames"] += len(frames) - sent
        return sent

    def _burst(self, channel: SensorChannel, t_s: float, count: int, rng: np.random.Generator) -> int:
        encoder = channel.coder.encoder
        fast: list[list[tuple[int, bytes]]] = []
        fix = next((m for m in channel.last if isinstance(m, PositionFix)), None)
        if channel.kind == "position" and fix is not None:
            fast = [encoder.gnss_position(fix, date_days=DATE_DAYS_SINCE_1970) for _ in range((count + 2) // 3)]
        items = n2k_burst(channel.kind, channel.source_address, count, rng, fast)
        done = 0
        for frames in items:
            if self._send_frames(channel, t_s, frames, fault="malformed_burst") == len(frames):
                done += 1
        return done

    def describe(self) -> dict[str, Any]:
        info = {**super().describe(), "bus": self.bus.name,
                "addresses": {name: ch.source_address for name, ch in self.channels.items()}}
        if self.server is not None:
            info["server"] = self.server.url
        return info

    def snapshot(self) -> dict[str, Any]:
        snap = super().snapshot()
        snap["writer"] = dict(self.writer.counters)
        return snap

    def close(self) -> None:
        with contextlib.suppress(Exception):
            self.writer.close()
        if self.server is not None:
            self.server.close()
            self.server = None


# ==================================================================================================
# MAVLink over UDP
# ==================================================================================================
class MavlinkLink(Link):
    """MAVLink sensors of one or more emulated autopilots (one per system id), sending to the daemon.

    Parameters
    ----------
    transport : MavlinkTransport
    record : callable, optional
    heartbeat_period_s : float
        HEARTBEAT period in plant time [s] (the emulator passes 1 s × speed: 1 Hz of wall time).
    """

    protocol = "mavlink"

    def __init__(self, transport: MavlinkTransport, record: Record | None = None, *,
                 heartbeat_period_s: float = 1.0) -> None:
        super().__init__(transport.name, record)
        if not heartbeat_period_s > 0.0:
            raise ValueError("heartbeat_period_s must be > 0")
        self.transport = transport
        self._period = heartbeat_period_s
        self._senders: dict[int, MavlinkUdpSender] = {}
        self._silent_until: dict[int, float] = {}
        self._next_heartbeat = 0.0

    def _sender(self, system_id: int) -> MavlinkUdpSender:
        sender = self._senders.get(system_id)
        if sender is None:
            key = self.transport.signing_key
            encoder = MavlinkEncoder(system_id, 1, signing_key=key, unix_clock=time.time if key else None)
            loopback = self.transport.host.startswith("127.")
            try:
                sender = MavlinkUdpSender((self.transport.host, self.transport.port), encoder,
                                          bind=("127.0.0.1" if loopback else "0.0.0.0", 0))
            except OSError as error:
                raise HilLinkError(f"transport {self.name}: cannot open a UDP socket: {error}") from error
            self._senders[system_id] = sender
        return sender

    def _configure(self, channel: SensorChannel, wire: Wire) -> None:
        channel.system_id = wire.sensor.system_id or 1
        channel.coder = MavlinkSensorEncoder(encoder=self._sender(channel.system_id).encoder)

    def encode(self, channel: SensorChannel, t_s: float, messages: Sequence[Message]) -> list[bytes]:
        """The MAVLink packets of one sample group (see :mod:`sim_plant.encoding`)."""
        packets = channel.coder.encode(t_s, messages)
        channel.counters["not_carried"] = channel.coder.counters["not_carried"]
        return packets

    def _send(self, channel: SensorChannel, t_s: float, messages: Sequence[Message]) -> int:
        return self._send_packets(channel, t_s, self.encode(channel, t_s, messages))

    def _send_packets(self, channel: SensorChannel, t_s: float, packets: list[bytes], **extra: Any) -> int:
        sender = self._senders[channel.system_id]
        sent = 0
        for packet in packets:
            if sender.send(packet):
                sent += 1
                self._emit_record(t_s, channel.name, packet, **extra)
        channel.counters["packets"] += sent
        if sent < len(packets):
            channel.counters["send_errors"] += len(packets) - sent
        return sent

    def _burst(self, channel: SensorChannel, t_s: float, count: int, rng: np.random.Generator) -> int:
        templates = self.encode(channel, t_s, channel.last)
        return self._send_packets(channel, t_s, mavlink_burst(templates, count, rng), fault="malformed_burst")

    # -- heartbeats --------------------------------------------------------------------------------
    def silence(self, sensor: str, until_s: float) -> None:
        """``heartbeat_loss``: the sensor's autopilot sends no HEARTBEAT before plant time ``until_s``."""
        system_id = self.channels[sensor].system_id
        self._silent_until[system_id] = max(until_s, self._silent_until.get(system_id, until_s))

    def service(self, t_s: float) -> None:
        if t_s < self._next_heartbeat:
            return
        for system_id, sender in self._senders.items():
            if t_s < self._silent_until.get(system_id, -1.0):
                self.counters["heartbeats_suppressed"] += 1
                continue
            packet = sender.encoder.heartbeat()
            if sender.send(packet):
                self.counters["heartbeats"] += 1
                self._record(self._topic, t_s, {"data": packet, "source": f"mav:{system_id}/1",
                                                "transport": self.name})
        # deadline grid, not "now + period": no drift; after a stall, resume from now
        self._next_heartbeat += self._period
        if self._next_heartbeat <= t_s:
            self._next_heartbeat = t_s + self._period

    @property
    def next_service_s(self) -> float:
        return self._next_heartbeat

    def describe(self) -> dict[str, Any]:
        return {**super().describe(), "remote": f"{self.transport.host}:{self.transport.port}",
                "signed": self.transport.signing_key is not None,
                "system_ids": {name: ch.system_id for name, ch in self.channels.items()}}

    def snapshot(self) -> dict[str, Any]:
        snap = super().snapshot()
        snap["senders"] = {str(sid): dict(s.counters) for sid, s in self._senders.items()}
        return snap

    def close(self) -> None:
        for sender in self._senders.values():
            with contextlib.suppress(OSError):
                sender.close()
        self._senders.clear()
