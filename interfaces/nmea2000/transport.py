"""NMEA 2000 transport over python-can: a reader thread, a writer, and the remote-bus server.

The CAN interface is configuration, not code (docs/design.md §5): :class:`CanBusConfig` names a
python-can ``interface`` + ``channel`` (+ keyword options) —

* ``socketcan`` / ``can0`` on a vessel,
* ``virtual`` / any name inside one process (the loopback twin),
* ``remote`` / ``ws://127.0.0.1:PORT/`` between processes on this machine (no CAN in the
  kernel): python-can-remote's server bridges every client onto one ``virtual`` channel in the
  server's process; :func:`start_remote_server` starts it for tests and the HIL bench.

:class:`N2kCanReader` owns one bus in a background thread, stamps every frame with an injected
clock, decodes it with :class:`~interfaces.nmea2000.codec.N2kDecoder` and hands
:class:`~interfaces.messages.Measurement`, :class:`RawFrame`,
:class:`~interfaces.messages.RejectedInput` and :class:`~interfaces.messages.LinkStatus`
events to a sink (a callable, e.g. ``queue.Queue.put``). A bus error closes the bus, reports the
link down and reopens it with exponential backoff; the thread never dies on bad input or a
broken bus. :meth:`N2kCanReader.close` stops and joins it within a bounded time.
"""

from __future__ import annotations

import contextlib
import logging
import os
import selectors
import subprocess
import sys
import threading
import time
from collections import Counter
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import can

from interfaces.messages import LinkStatus, Measurement, Rejected, RejectedInput
from interfaces.nmea2000.codec import BROADCAST, PGN_ADDRESS_CLAIM, Frame, N2kDecoder, make_can_id, n2k_source_name

logger = logging.getLogger(__name__)

Clock = Callable[[], float]
PGN_ISO_REQUEST = 59904
NULL_ADDRESS = 254


@dataclass(frozen=True, slots=True)
class RawFrame:
    """A CAN frame as received, for the black-box recorder.

    Attributes
    ----------
    t_s : float
        Receive time on the reader's clock [s].
    can_id : int
        Arbitration identifier (29-bit for NMEA 2000).
    data : bytes
        0–8 data bytes.
    """

    t_s: float
    can_id: int
    data: bytes


N2kEvent = Measurement | RawFrame | RejectedInput | LinkStatus


@dataclass(frozen=True, slots=True)
class CanBusConfig:
    """Which python-can bus to open.

    Attributes
    ----------
    interface : str
        A python-can interface name (``socketcan``, ``virtual``, ``remote``, ``pcan`` …).
    channel : str
        Interface-specific channel (``can0``; a virtual channel name; ``ws://127.0.0.1:54701/``).
    options : mapping
        Further keyword arguments for ``can.Bus`` (``bitrate``, ``receive_own_messages`` …).
    """

    interface: str = "virtual"
    channel: str = "dpcontrol"
    options: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.interface not in can.VALID_INTERFACES:
            raise ValueError(f"unknown python-can interface {self.interface!r} "
                             f"(one of {', '.join(sorted(can.VALID_INTERFACES))})")
        if not isinstance(self.channel, str) or not self.channel:
            raise ValueError(f"channel must be a non-empty string, got {self.channel!r}")

    @property
    def name(self) -> str:
        """``interface:channel``, used as the link name in :class:`LinkStatus`."""
        return f"{self.interface}:{self.channel}"

    def open(self) -> can.BusABC:
        """Open the bus (raises what python-can raises: ``can.CanError``, ``OSError`` …)."""
        return can.Bus(interface=self.interface, channel=self.channel, **dict(self.options))


def shutdown_bus(bus: can.BusABC, timeout_s: float = 2.0) -> None:
    """Shut ``bus`` down without hanging on a dead peer and without leaving it half open.

    python-can-remote's ``RemoteBus.shutdown`` waits for the server to acknowledge the close, and
    raises (before marking the bus shut down, so ``__del__`` tries again and prints a traceback)
    when the socket is already broken. Run it in a helper thread; on failure close the socket and
    mark the bus shut down; if it does not return in ``timeout_s``, cut the socket so it does.
    """
    def _force_closed() -> None:
        sock = getattr(bus, "socket", None)
        if sock is not None:
            with contextlib.suppress(OSError):
                sock.close()
        with contextlib.suppress(Exception):
            can.BusABC.shutdown(bus)  # the base class only marks it shut down (and stops periodic tasks)

    def _shutdown() -> None:
        try:
            bus.shutdown()
        except Exception as error:  # a broken bus may fail to close; it is being dropped anyway
            logger.debug("bus shutdown: %r", error)
            _force_closed()

    worker = threading.Thread(target=_shutdown, name="can-bus-shutdown", daemon=True)
    worker.start()
    worker.join(timeout_s)
    if worker.is_alive():
        _force_closed()
        worker.join(timeout_s)


class N2kReaderThread:
    """What every NMEA 2000 reader shares (a CAN bus, a gateway): the reader thread and its life cycle, the
    reconnecting loop with doubling back-off, link-status events, and delivery of decoded results to the sink.

    A subclass says how its link opens (:meth:`_open_link`), how it receives (:meth:`_receive`: an item, or
    None after ``poll_s`` of silence; raises on a lost link), what it does with an item (:meth:`_handle`), how
    it closes (:meth:`_drop_link`), and the words of its link events (:attr:`_words`).

    Parameters
    ----------
    link_name : str
        The ``LinkStatus.source`` of its link events (the transport's name).
    sink, clock, source_names, decoder, deliver_raw, poll_s, backoff_s
        As for :class:`N2kCanReader`.
    """

    #: link-event texts: (open, reopened, cannot open, lost) — formatted with ``failures`` / ``error``
    _words = ("link open", "link reopened after {failures} failure(s)", "cannot open: {error!r}",
              "link error: {error!r}")
    _error_counter = "link_errors"

    def __init__(self, link_name: str, sink: Callable[[N2kEvent], Any], *, clock: Clock = time.monotonic,
                 source_names: Mapping[int, str] | None = None, decoder: N2kDecoder | None = None,
                 deliver_raw: bool = False, poll_s: float = 0.1,
                 backoff_s: tuple[float, float] = (0.05, 2.0), decode: bool = True) -> None:
        if not poll_s > 0.0 or not 0.0 < backoff_s[0] <= backoff_s[1]:
            raise ValueError("poll_s must be > 0 and 0 < backoff_s[0] <= backoff_s[1]")
        self.link_name = link_name
        self.sink = sink
        self.clock = clock
        self.decoder = decoder or N2kDecoder()
        self.deliver_raw = deliver_raw or not decode
        self.decode = decode
        self.poll_s = poll_s
        self.backoff_s = backoff_s
        self.counters: Counter[str] = Counter()
        self._names = dict(source_names or {})
        self._stop = threading.Event()
        self._connected = threading.Event()
        self._thread: threading.Thread | None = None

    # ---- life cycle ----------------------------------------------------------------------

    def start(self) -> Any:
        """Start the reader thread (opening the link happens in it). Returns ``self``."""
        if self._thread is not None:
            raise RuntimeError("reader already started")
        self._thread = threading.Thread(target=self._run, name=f"n2k-reader {self.link_name}", daemon=True)
        self._thread.start()
        return self

    def wait_connected(self, timeout_s: float) -> bool:
        """Block until the link is open (or ``timeout_s`` passes); returns whether it is."""
        return self._connected.wait(timeout_s)

    @property
    def connected(self) -> bool:
        """Whether the link is currently open."""
        return self._connected.is_set()

    def close(self, timeout_s: float = 3.0) -> None:
        """Stop the thread and close the link; returns within about ``timeout_s + poll_s``."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout_s + self.poll_s)
            if self._thread.is_alive():
                logger.warning("n2k reader %s did not stop within %.1f s", self.link_name, timeout_s)

    def __enter__(self) -> Any:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ---- what a link does (subclasses) -------------------------------------------------------

    def _open_link(self) -> None:
        raise NotImplementedError

    def _on_open(self) -> None:
        """Called each time the link has opened (e.g. to ask the bus for address claims)."""

    def _receive(self) -> Any:
        raise NotImplementedError

    def _handle(self, item: Any, t_s: float) -> None:
        raise NotImplementedError

    def _drop_link(self) -> None:
        raise NotImplementedError

    # ---- thread ---------------------------------------------------------------------------

    def _emit(self, event: N2kEvent) -> None:
        try:
            self.sink(event)
        except Exception:  # a broken consumer must not stop the reader
            self.counters["sink_errors"] += 1
            logger.exception("n2k reader sink raised")

    def _link(self, connected: bool, detail: str) -> None:
        if connected:
            self._connected.set()
        else:
            self._connected.clear()
        self._emit(LinkStatus(self.clock(), self.link_name, connected, detail))

    def _name(self, address: int) -> str:
        name = self._names.get(address)
        return name if name is not None else n2k_source_name(address)

    def _deliver(self, results: Iterable[Any], t_s: float) -> None:
        for result in results:
            name = self._name(result.source_address)
            if isinstance(result.item, Rejected):
                self._emit(RejectedInput(t_s, name, result.item))
            else:
                self._emit(Measurement(t_s, name, result.item))

    def _run(self) -> None:
        opened, reopened, cannot_open, lost = self._words
        backoff = self.backoff_s[0]
        failures = 0
        try:
            while not self._stop.is_set():
                if not self.connected:
                    try:
                        self._open_link()
                    except Exception as error:  # any driver or socket error: report, back off, retry
                        self.counters["open_errors"] += 1
                        if failures == 0:
                            self._link(False, cannot_open.format(error=error))
                        failures += 1
                        self._stop.wait(backoff)
                        backoff = min(2.0 * backoff, self.backoff_s[1])
                        continue
                    if failures:
                        self.counters["reconnects"] += 1
                    self._link(True, reopened.format(failures=failures) if failures else opened)
                    failures = 0
                    self._on_open()
                try:
                    item = self._receive()
                except Exception as error:  # CanError, OSError, reset, EOF, device unplugged …
                    self.counters[self._error_counter] += 1
                    self._drop_link()
                    failures += 1
                    self._link(False, lost.format(error=error))
                    # a link that opens but fails at once (bus-off) must not spin: keep doubling
                    self._stop.wait(backoff)
                    backoff = min(2.0 * backoff, self.backoff_s[1])
                    continue
                backoff = self.backoff_s[0]  # the link works
                t_s = self.clock()
                if item is None:
                    if self.decode and self.decoder.assembler.pending:
                        self._deliver(self.decoder.expire(t_s), t_s)
                    continue
                self._handle(item, t_s)
        finally:
            self._drop_link()
            self._connected.clear()


class N2kCanReader(N2kReaderThread):
    """Background reader: CAN bus → decoded NMEA 2000 events for a sink.

    Parameters
    ----------
    bus : CanBusConfig
        The bus to open (and reopen after errors).
    sink : callable
        Receives every event (:data:`N2kEvent`) from the reader thread; must be quick and
        thread-safe (``queue.Queue.put`` is). Exceptions it raises are counted and logged.
    clock : callable, optional
        Returns the receive time [s] (default ``time.monotonic``; a stepped clock in tests).
    source_names : mapping of int to str, optional
        NMEA 2000 source address → sensor name (default ``n2k:<address>``).
    decoder : N2kDecoder, optional
        A configured decoder (fast-packet timeout, …).
    deliver_raw : bool
        Also deliver every received frame as :class:`RawFrame`.
    poll_s : float
        Longest blocking read [s]: bounds the close latency and the fast-packet expiry delay on
        an idle bus.
    decode : bool
        Decode here. False: deliver only the raw frames (and link changes), for a caller that decodes on its
        own thread (the daemon's input stage, :mod:`dpcontrol.runtime.ingest`).
    backoff_s : (float, float)
        First and longest wait between reconnect attempts [s] (doubling).
    request_address_claims : bool
        Each time the bus opens, send an ISO request for the address claim (PGN 59904 asking for 60928)
        from the null address 254, which a node without an address may use (ISO 11783-5): every device
        answers with its claim, so the NAME of each address is known without waiting for a power-up.
        The only frame the reader ever sends; off by default (a listen-only reader).
    """

    _words = ("bus open", "bus reopened after {failures} failure(s)", "cannot open bus: {error!r}",
              "bus error: {error!r}")
    _error_counter = "bus_errors"

    def __init__(self, bus: CanBusConfig, sink: Callable[[N2kEvent], Any], *, clock: Clock = time.monotonic,
                 source_names: Mapping[int, str] | None = None, decoder: N2kDecoder | None = None,
                 deliver_raw: bool = False, poll_s: float = 0.1,
                 backoff_s: tuple[float, float] = (0.05, 2.0), request_address_claims: bool = False,
                 decode: bool = True) -> None:
        super().__init__(bus.name, sink, clock=clock, source_names=source_names, decoder=decoder,
                         deliver_raw=deliver_raw, poll_s=poll_s, backoff_s=backoff_s, decode=decode)
        self.bus_config = bus
        self.request_address_claims = request_address_claims
        self._bus: can.BusABC | None = None

    def _open_link(self) -> None:
        self._bus = self.bus_config.open()

    def _on_open(self) -> None:
        if self.request_address_claims:
            self._request_address_claims()

    def _receive(self) -> can.Message | None:
        assert self._bus is not None
        return self._bus.recv(self.poll_s)

    def _handle(self, item: can.Message, t_s: float) -> None:
        self._on_message(item, t_s)

    def _drop_link(self) -> None:
        bus, self._bus = self._bus, None
        if bus is not None:
            shutdown_bus(bus)

    def _request_address_claims(self) -> None:
        """ISO request (59904) for the address claim (60928), to all, from the null address 254."""
        request = can.Message(arbitration_id=make_can_id(6, PGN_ISO_REQUEST, NULL_ADDRESS, BROADCAST),
                              data=PGN_ADDRESS_CLAIM.to_bytes(3, "little"), is_extended_id=True)
        try:
            self._bus.send(request, timeout=self.poll_s)  # type: ignore[union-attr]
            self.counters["address_claim_requests"] += 1
        except Exception as error:  # a listen-only interface refuses: names come with the next claims
            self.counters["address_claim_request_errors"] += 1
            logger.info("n2k reader could not request address claims: %r", error)

    def _on_message(self, message: can.Message, t_s: float) -> None:
        counters = self.counters
        counters["frames_received"] += 1
        if message.is_error_frame:
            counters["error_frames"] += 1
            return
        if message.is_remote_frame or not message.is_extended_id:
            counters["not_n2k_frames"] += 1  # 11-bit or remote frames carry no NMEA 2000 PGN
            return
        data = bytes(message.data)
        if self.deliver_raw:
            self._emit(RawFrame(t_s, message.arbitration_id, data))
        if not self.decode:
            return
        try:
            results = self.decoder.decode_frame(message.arbitration_id, data, t_s)
        except Exception as error:  # the decoder is fuzzed not to raise; belt and braces for the thread
            counters["decoder_errors"] += 1
            logger.exception("n2k decoder raised")
            self._emit(RejectedInput(t_s, "n2k:?", Rejected("decode_error", repr(error), data)))
            return
        self._deliver(results, t_s)


class N2kCanWriter:
    """Sends NMEA 2000 frames (from :class:`~interfaces.nmea2000.codec.N2kEncoder`) on a bus.

    A bus delivers every frame on it to every node, the writer too; unread frames would pile up
    without bound (in python-can's ``virtual`` bus queue, or in the remote server for a ``remote``
    bus). So the writer runs a drain thread that reads and discards them (counted as
    ``frames_drained``) — which also notices at once when a remote server goes away.

    A send error, or the drain thread seeing the bus fail, closes the bus and is counted; the next
    :meth:`send` at least ``backoff_s`` later (on the injected clock) reopens it. Frames offered
    while the bus is down are dropped and counted, like a CAN controller in bus-off.

    Parameters
    ----------
    bus : CanBusConfig
    clock : callable, optional
        Time [s] for the reconnect backoff (default ``time.monotonic``).
    backoff_s : float
        Wait after a failure before the bus is reopened [s].
    poll_s : float
        Longest blocking read of the drain thread [s] (bounds :meth:`close`).
    """

    def __init__(self, bus: CanBusConfig, *, clock: Clock = time.monotonic, backoff_s: float = 0.5,
                 poll_s: float = 0.1) -> None:
        self.bus_config = bus
        self.clock = clock
        self.backoff_s = backoff_s
        self.poll_s = poll_s
        self.counters: Counter[str] = Counter()
        self._bus: can.BusABC | None = None
        self._drain: threading.Thread | None = None
        self._retry_at = -float("inf")
        self._lock = threading.Lock()
        self._closed = threading.Event()

    def open(self) -> N2kCanWriter:
        """Open the bus now (otherwise the first :meth:`send` does). Raises what python-can raises."""
        with self._lock:
            if self._bus is None:
                self._open_locked()
        return self

    def _open_locked(self) -> None:
        bus = self.bus_config.open()
        self._bus = bus
        self._drain = threading.Thread(target=self._drain_loop, args=(bus,), daemon=True,
                                       name=f"n2k-writer-drain {self.bus_config.name}")
        self._drain.start()

    def _drop_locked(self, why: str) -> None:
        bus, self._bus = self._bus, None
        self._retry_at = self.clock() + self.backoff_s
        logger.warning("n2k writer on %s: %s", self.bus_config.name, why)
        if bus is not None:
            shutdown_bus(bus)

    def _drain_loop(self, bus: can.BusABC) -> None:
        while not self._closed.is_set() and self._bus is bus:
            try:
                message = bus.recv(self.poll_s)
            except Exception as error:  # the bus broke under us: let the next send reopen it
                with self._lock:
                    if self._bus is bus:
                        self.counters["bus_errors"] += 1
                        self._drop_locked(f"bus error: {error!r}")
                return
            if message is not None:
                self.counters["frames_drained"] += 1

    def send(self, frames: Iterable[Frame]) -> int:
        """Send frames in order; returns how many went out (the rest were dropped and counted)."""
        frames = list(frames)
        sent = 0
        with self._lock:
            if self._closed.is_set():
                raise RuntimeError("writer is closed")
            if self._bus is None:
                if self.clock() < self._retry_at:
                    self.counters["frames_dropped"] += len(frames)
                    return 0
                try:
                    self._open_locked()
                except Exception as error:  # report and retry later; the emulator keeps running
                    self.counters["open_errors"] += 1
                    self.counters["frames_dropped"] += len(frames)
                    self._retry_at = self.clock() + self.backoff_s
                    logger.warning("n2k writer cannot open %s: %r", self.bus_config.name, error)
                    return 0
            assert self._bus is not None
            for can_id, data in frames:
                try:
                    self._bus.send(can.Message(arbitration_id=can_id, data=data, is_extended_id=True))
                except Exception as error:  # bus-off, broken socket …
                    self.counters["send_errors"] += 1
                    self.counters["frames_dropped"] += len(frames) - sent
                    self._drop_locked(f"send failed: {error!r}")
                    break
                sent += 1
            self.counters["frames_sent"] += sent
        return sent

    def close(self) -> None:
        """Stop the drain thread and close the bus."""
        self._closed.set()
        with self._lock:
            bus, self._bus = self._bus, None
            drain, self._drain = self._drain, None
        if drain is not None:
            drain.join(self.poll_s + 2.0)
        if bus is not None:
            shutdown_bus(bus)

    def __enter__(self) -> N2kCanWriter:
        return self.open()

    def __exit__(self, *exc: object) -> None:
        self.close()


# --------------------------------------------------------------------------------------------
# python-can-remote server
# --------------------------------------------------------------------------------------------

class RemoteServerHandle:
    """A running python-can-remote server bridging its clients onto one ``virtual`` channel.

    Attributes
    ----------
    host, port : str, int
        Where it listens.
    channel : str
        The virtual channel inside the server.
    mode : "thread" or "process"
    """

    def __init__(self, host: str, port: int, channel: str, mode: Literal["thread", "process"], *,
                 server: Any = None, thread: threading.Thread | None = None,
                 process: subprocess.Popen[bytes] | None = None) -> None:
        self.host, self.port, self.channel, self.mode = host, port, channel, mode
        self._server, self._thread, self._process = server, thread, process

    @property
    def url(self) -> str:
        """The ``channel`` of a python-can ``remote`` bus connecting to this server."""
        return f"ws://{self.host}:{self.port}/"

    def bus_config(self) -> CanBusConfig:
        """A :class:`CanBusConfig` for a client of this server."""
        return CanBusConfig("remote", self.url)

    @property
    def alive(self) -> bool:
        """Whether the server still runs."""
        if self._process is not None:
            return self._process.poll() is None
        return self._thread is not None and self._thread.is_alive()

    @property
    def pid(self) -> int | None:
        """Process id in ``process`` mode."""
        return None if self._process is None else self._process.pid

    def close(self, timeout_s: float = 5.0) -> None:
        """Stop the server and disconnect its clients (SIGTERM, then SIGKILL after ``timeout_s``)."""
        if self._process is not None:
            if self._process.poll() is None:
                self._process.terminate()
                try:
                    self._process.wait(timeout_s)
                except subprocess.TimeoutExpired:
                    self._process.kill()
                    self._process.wait(timeout_s)
            for pipe in (self._process.stdout, self._process.stdin):
                if pipe is not None:
                    with contextlib.suppress(OSError):
                        pipe.close()
            return
        if self._server is not None:
            _stop_server(self._server)
            if self._thread is not None:
                self._thread.join(timeout_s)

    def __enter__(self) -> RemoteServerHandle:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _stop_server(server: Any) -> None:
    """Stop a ``can_remote.RemoteServer``: no new clients, then close every client connection."""
    server.shutdown()
    for protocol in list(server.clients):
        with contextlib.suppress(Exception):
            protocol.terminate(ConnectionAbortedError("server closing"))
    server.server_close()


def start_remote_server(host: str = "127.0.0.1", port: int = 0, *, channel: str = "dpcontrol",
                        mode: Literal["thread", "process"] = "process", startup_timeout_s: float = 10.0,
                        log_path: str | os.PathLike[str] | None = None) -> RemoteServerHandle:
    """Start a python-can-remote server on ``host:port`` (``port=0``: a free port is chosen).

    Parameters
    ----------
    host, port :
        Listen address; keep ``127.0.0.1`` unless other machines must join.
    channel :
        Name of the ``virtual`` channel the server bridges its clients onto.
    mode :
        ``"process"`` (default, what the HIL bench uses: the server does not share a GIL with the
        reader or the emulator) or ``"thread"`` (in this process).
    startup_timeout_s :
        How long to wait for the server to listen.
    log_path :
        Process mode: append the server's log (warnings and errors) to this file; default: discarded.
        The server process also exits by itself when this process dies (it watches its stdin).

    Returns
    -------
    RemoteServerHandle
        With the real port and :meth:`RemoteServerHandle.bus_config` for clients.

    Raises
    ------
    RuntimeError
        If the server does not come up within ``startup_timeout_s``.
    OSError
        If the address cannot be bound (thread mode).
    """
    if mode == "thread":
        from can_remote import RemoteServer  # noqa: PLC0415 - only needed in this mode

        server = RemoteServer(host, port, interface="virtual", channel=channel)
        thread = threading.Thread(target=server.serve_forever, kwargs={"poll_interval": 0.1},
                                  name=f"can-remote-server:{server.server_port}", daemon=True)
        thread.start()
        return RemoteServerHandle(host, server.server_port, channel, mode, server=server, thread=thread)
    if mode != "process":
        raise ValueError(f"mode must be 'thread' or 'process', got {mode!r}")
    env = dict(os.environ)
    repo_root = str(Path(__file__).resolve().parents[2])
    env["PYTHONPATH"] = repo_root + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    with contextlib.ExitStack() as stack:
        log = stack.enter_context(open(log_path, "ab")) if log_path is not None else subprocess.DEVNULL
        process = subprocess.Popen(
            [sys.executable, "-m", "interfaces.nmea2000.remote_server", "--host", host, "--port", str(port),
             "--channel", channel, "--exit-with-stdin"],
            stdout=subprocess.PIPE, stderr=log, stdin=subprocess.PIPE, env=env)
    assert process.stdout is not None
    line = b""
    with selectors.DefaultSelector() as selector:
        selector.register(process.stdout, selectors.EVENT_READ)
        deadline = time.monotonic() + startup_timeout_s
        while not line.endswith(b"\n"):
            remaining = deadline - time.monotonic()
            if remaining <= 0 or not selector.select(remaining):
                break
            chunk = os.read(process.stdout.fileno(), 256)
            if not chunk:
                break
            line += chunk
    if not line.startswith(b"LISTENING "):
        process.kill()
        process.wait()
        process.stdout.close()
        if process.stdin is not None:
            process.stdin.close()
        raise RuntimeError(f"python-can-remote server did not start on {host}:{port} "
                           f"within {startup_timeout_s} s (said {line!r})")
    return RemoteServerHandle(host, int(line.split()[1]), channel, mode, process=process)
