"""MAVLink over UDP: a reader thread with heartbeat-loss detection, and a sender for the emulator.

Our own UDP socket + pymavlink's parser rather than ``mavutil.mavlink_connection("udpin:…")``:
mavutil polls a non-blocking socket, selects its dialect through a process-global setting and
keeps no per-datagram boundary; a blocking ``recvfrom`` with a timeout gives a clean close and
no busy-wait, and every datagram is decoded on its own (a truncated packet is rejected, never
glued to the next datagram).

Loopback twin: a :class:`MavlinkUdpReader` bound to ``127.0.0.1:0`` (a free port) and a
:class:`MavlinkUdpSender` aimed at :attr:`MavlinkUdpReader.address`.
"""

from __future__ import annotations

import contextlib
import logging
import re
import socket
import threading
import time
from collections import Counter
from collections.abc import Callable, Hashable, Mapping
from dataclasses import dataclass
from typing import Any, cast

from interfaces.mavlink.codec import (
    HeartbeatMonitor,
    LinkChange,
    MavlinkDecoder,
    MavlinkEncoder,
    mavlink_source_name,
)
from interfaces.messages import LinkHeartbeat, LinkStatus, Measurement, Rejected, RejectedInput

logger = logging.getLogger(__name__)

Clock = Callable[[], float]
Address = tuple[str, int]
MAX_DATAGRAM = 65_535


@dataclass(frozen=True, slots=True)
class RawPacket:
    """A UDP datagram as received, for the black-box recorder.

    Attributes
    ----------
    t_s : float
        Receive time on the reader's clock [s].
    data : bytes
        The datagram (one or more MAVLink packets).
    peer : (str, int)
        Sender address.
    """

    t_s: float
    data: bytes
    peer: Address


MavEvent = Measurement | RawPacket | RejectedInput | LinkStatus

_UDPIN = re.compile(r"udp(?:in)?:(\[[0-9A-Fa-f:.]+\]|[^:\[\]]+):(\d{1,5})")


def parse_udpin(url: str) -> Address:
    """The listen address of a ``udpin:HOST:PORT`` URL (the form of MAVLink connection strings; ``udp:`` means the
    same there, pymavlink's ``mavutil``; an IPv6 host in brackets).

    Raises
    ------
    ValueError
        Another form (only listening on UDP is supported), or a port beyond 65535.
    """
    match = _UDPIN.fullmatch(url.strip())
    if match is None:
        raise ValueError(f"mavlink url {url!r}: only udpin:HOST:PORT (listening) is supported")
    port = int(match.group(2))
    if port > 65535:
        raise ValueError(f"mavlink url {url!r}: port {port} beyond 65535")
    return match.group(1).strip("[]"), port


class MavlinkUdpReader:
    """Background MAVLink reader on a UDP port (``udpin``), delivering events to a sink.

    The socket is bound in the constructor, so :attr:`address` is known (and free) before
    :meth:`start`. Each datagram is stamped with the injected ``clock`` and decoded; heartbeats
    feed a :class:`~interfaces.mavlink.codec.HeartbeatMonitor` on the same clock, checked after
    every datagram and at least every ``poll_s`` of real time (and whenever :meth:`check_link` is
    called, which a test with a stepped clock uses).

    Parameters
    ----------
    sink : callable
        Receives every :data:`MavEvent` (from the reader thread, or from :meth:`check_link`'s caller).
    bind : (str, int)
        Local address; port 0 picks a free one.
    clock : callable
        Receive time [s] (``time.monotonic`` by default; a stepped clock in tests).
    unix_clock : callable
        Wall time [s], only to start the signature replay window.
    signing_key : bytes, optional
        When given, only correctly signed MAVLink 2 packets are accepted.
    heartbeat_timeout_s : float
        Silence after which a peer is reported lost.
    source_names : mapping, optional
        ``(system, component, message_name)`` or ``(system, component)`` → sensor name (the first
        found wins; default ``mav:<system>/<component>``). The 3-key form separates e.g. a GNSS
        position (``GPS_RAW_INT``) from the autopilot's fused one (``GLOBAL_POSITION_INT``).
    deliver_raw : bool
        Also deliver every datagram as :class:`RawPacket`.
    poll_s : float
        Longest blocking read [s] (bounds :meth:`close` and the link-check period).
    namer : callable, optional
        ``(system, component, message_name) -> name``, consulted after ``source_names`` (lets a router
        that only knows system IDs and message names name every sender).
    decode : bool
        Decode and watch heartbeats here. False: deliver only the datagrams (:class:`RawPacket`), for a caller
        that decodes and monitors the links on its own thread (the daemon's input stage,
        :mod:`dpcontrol.runtime.ingest`).
    """

    def __init__(self, sink: Callable[[MavEvent], Any], *, bind: Address = ("127.0.0.1", 0),  # noqa: PLR0913 - the link's settings, keyword-only
                 clock: Clock = time.monotonic, unix_clock: Clock = time.time, signing_key: bytes | None = None,
                 heartbeat_timeout_s: float = 5.0, source_names: Mapping[tuple[Any, ...], str] | None = None,
                 deliver_raw: bool = False, poll_s: float = 0.1,
                 namer: Callable[[int, int, str], str] | None = None, decode: bool = True) -> None:
        if not poll_s > 0.0:
            raise ValueError("poll_s must be > 0")
        self.sink = sink
        self.clock = clock
        self.poll_s = poll_s
        self.deliver_raw = deliver_raw or not decode
        self.decode = decode
        self.decoder = MavlinkDecoder(signing_key, signing_time_s=unix_clock())
        self.counters: Counter[str] = Counter()
        self._names = dict(source_names or {})
        self._namer = namer
        self._bind = bind
        self._sock = self._open_socket(bind)
        self.address: Address = self._sock.getsockname()[:2]
        self._monitor = HeartbeatMonitor(heartbeat_timeout_s, start_t_s=clock())
        self._monitor_lock = threading.RLock()  # the reader thread and check_link() callers share the monitor
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def _open_socket(self, bind: Address) -> socket.socket:
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            sock.bind(bind)
            sock.settimeout(self.poll_s)
        except OSError:
            sock.close()
            raise
        return sock

    # ---- life cycle ----------------------------------------------------------------------

    def start(self) -> MavlinkUdpReader:
        """Start the reader thread. Returns ``self``."""
        if self._thread is not None:
            raise RuntimeError("reader already started")
        self._thread = threading.Thread(target=self._run, name=f"mavlink-reader {self.address}", daemon=True)
        self._thread.start()
        return self

    def close(self, timeout_s: float = 2.0) -> None:
        """Stop the thread and close the socket (returns within about ``timeout_s``)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout_s + self.poll_s)
            if self._thread.is_alive():
                logger.warning("mavlink reader thread did not stop within %.1f s", timeout_s)
        with contextlib.suppress(OSError):
            self._sock.close()

    def __enter__(self) -> MavlinkUdpReader:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ---- link state ----------------------------------------------------------------------

    def peer_connected(self, system_id: int, component_id: int) -> bool:
        """Whether that peer's heartbeats are currently arriving."""
        with self._monitor_lock:
            return self._monitor.connected((system_id, component_id))

    def check_link(self) -> list[LinkStatus]:
        """Run the heartbeat check at ``clock()`` now; emits and returns the changes (none when not decoding)."""
        if not self.decode:
            return []
        with self._monitor_lock:
            return [self._link(change) for change in self._monitor.check(self.clock())]

    def _link(self, change: LinkChange) -> LinkStatus:
        """Count and emit a link change (called with the monitor lock held, so changes keep their order)."""
        key = change.key
        if key is None:
            name = "mavlink"
        else:
            system_id, component_id = cast(tuple[int, int], key)  # the monitor's keys are (system, component)
            name = self._name(system_id, component_id, "HEARTBEAT")
        status = LinkStatus(change.t_s, name, change.connected, change.detail)
        self.counters["link_up" if change.connected else "link_lost"] += 1
        self._emit(status)
        return status

    # ---- thread ---------------------------------------------------------------------------

    def _emit(self, event: MavEvent) -> None:
        try:
            self.sink(event)
        except Exception:  # a broken consumer must not stop the link reader
            self.counters["sink_errors"] += 1
            logger.exception("mavlink reader sink raised")

    def _name(self, system_id: int, component_id: int, msg_name: str) -> str:
        names = self._names
        if names:
            name = names.get((system_id, component_id, msg_name)) or names.get((system_id, component_id))
            if name is not None:
                return name
        if self._namer is not None:
            return self._namer(system_id, component_id, msg_name)
        return mavlink_source_name(system_id, component_id)

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                data, peer = self._sock.recvfrom(MAX_DATAGRAM)
            except TimeoutError:
                self.check_link()
                continue
            except OSError as error:
                if self._stop.is_set():
                    break
                # e.g. the socket was closed under us: count, then rebind the same port
                self.counters["socket_errors"] += 1
                logger.warning("mavlink reader socket error: %r", error)
                self._stop.wait(self.poll_s)
                with contextlib.suppress(OSError):
                    self._sock.close()
                try:
                    self._sock = self._open_socket(self.address)
                except OSError as rebind_error:
                    logger.warning("mavlink reader cannot rebind %s: %r", self.address, rebind_error)
                continue
            self._on_datagram(data, peer[:2], self.clock())
            self.check_link()

    def _on_datagram(self, data: bytes, peer: Address, t_s: float) -> None:
        self.counters["datagrams"] += 1
        if self.deliver_raw:
            self._emit(RawPacket(t_s, data, peer))
        if not self.decode:
            return
        try:
            results = self.decoder.decode_datagram(data)
        except Exception as error:  # the decoder is fuzzed not to raise; belt and braces for the thread
            self.counters["decoder_errors"] += 1
            logger.exception("mavlink decoder raised")
            self._emit(RejectedInput(t_s, "mav:?", Rejected("decode_error", repr(error), data[:64])))
            return
        for result in results:
            name = self._name(result.system_id, result.component_id, result.msg_name)
            item = result.item
            if isinstance(item, Rejected):
                self._emit(RejectedInput(t_s, name, item))
                continue
            if isinstance(item, LinkHeartbeat):
                key: Hashable = (item.system_id, item.component_id)
                with self._monitor_lock:
                    change = self._monitor.beat(key, t_s)
                    if change is not None:
                        self._link(change)
            self._emit(Measurement(t_s, name, item))


class MavlinkUdpSender:
    """Sends MAVLink packets to a UDP address; optionally a 1 Hz heartbeat from its own thread.

    Parameters
    ----------
    remote : (str, int)
        Where the reader listens.
    encoder : MavlinkEncoder, optional
        The autopilot identity and signing (default: system 1, component 1, unsigned).
    bind : (str, int)
        Local address (port 0: any); the bound one is :attr:`address`.
    """

    def __init__(self, remote: Address, encoder: MavlinkEncoder | None = None, *,
                 bind: Address = ("127.0.0.1", 0)) -> None:
        self.remote = remote
        self.encoder = encoder or MavlinkEncoder()
        self.counters: Counter[str] = Counter()
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            self._sock.bind(bind)
        except OSError:
            self._sock.close()
            raise
        self.address: Address = self._sock.getsockname()[:2]
        self._heartbeat_stop = threading.Event()
        self._heartbeat: threading.Thread | None = None

    def send(self, packet: bytes) -> bool:
        """Send one datagram; returns ``False`` (counted) if the OS refused it."""
        try:
            self._sock.sendto(packet, self.remote)
        except OSError as error:  # e.g. ECONNREFUSED from an earlier ICMP error: keep going
            self.counters["send_errors"] += 1
            logger.debug("mavlink send to %s failed: %r", self.remote, error)
            return False
        self.counters["packets_sent"] += 1
        return True

    def start_heartbeat(self, period_s: float = 1.0) -> None:
        """Send a HEARTBEAT now and then every ``period_s`` [s] until :meth:`stop_heartbeat`."""
        if self._heartbeat is not None:
            return
        self._heartbeat_stop.clear()

        def _beat() -> None:
            while True:
                self.send(self.encoder.heartbeat())
                if self._heartbeat_stop.wait(period_s):
                    return

        self._heartbeat = threading.Thread(target=_beat, name="mavlink-heartbeat", daemon=True)
        self._heartbeat.start()

    def stop_heartbeat(self) -> None:
        """Stop the heartbeat thread (the link then looks lost to the reader)."""
        self._heartbeat_stop.set()
        if self._heartbeat is not None:
            self._heartbeat.join(2.0)
            self._heartbeat = None

    def close(self) -> None:
        """Stop the heartbeat and close the socket."""
        self.stop_heartbeat()
        self._sock.close()

    def __enter__(self) -> MavlinkUdpSender:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
