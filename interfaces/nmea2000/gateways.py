"""NMEA 2000 through a gateway instead of a CAN card: Yacht Devices raw over TCP/UDP, Actisense NGT-1 over serial.

A small vessel's bus often reaches the computer through a gateway:

* **Yacht Devices YDWG-02 / YDEN-02, RAW protocol** (``ydwg_tcp``, ``ydwg_udp``): every CAN frame as a
  text line ``hh:mm:ss.sss R 09F80115 A0 7D E6 18 00 00 FF FF`` (received by the gateway ``R``, sent by it
  ``T``; both were on the bus), over a TCP connection to the gateway (its default port 1457) or in UDP
  datagrams it sends (default 1456). Lines are parsed by canboat's parser (``parse_line("ydwg02")``),
  the frames decoded like CAN frames (fast packets reassembled here).
* **Actisense NGT-1** (``ngt1_serial``): the binary Actisense protocol on a serial port (USB, 115200
  baud): DLE/STX framing, a checksum, and every message already reassembled by the gateway. The
  protocol — the start-up commands, unstuffing, checksum, 0x93 "message received" — is canboat's
  (``GatewayCodec("ngt1")``); messages are decoded whole (:meth:`N2kDecoder.decode_message`).

:class:`N2kGatewayReader` has the interface of :class:`~interfaces.nmea2000.transport.N2kCanReader`
(``start``, ``wait_connected``, ``connected``, ``close``, a context manager; the same events to the same
sink: Measurement, RawFrame, RejectedInput, LinkStatus) so the two plug into one transport registry.
It reconnects with exponential backoff after a refused or lost connection, a vanished serial device or
EOF; nothing the gateway sends ends the thread.

Loopback twins, for tests and the plant emulator: :class:`YdwgRawServer` (serves YD RAW lines to TCP
clients, or sends them in UDP datagrams) and :class:`Ngt1Writer` (writes NGT-1 packets to a serial port,
e.g. the master side of a :class:`~interfaces.nmea0183.transport.PtyPair`). Both take the CAN frames of
:class:`~interfaces.nmea2000.codec.N2kEncoder` like :class:`~interfaces.nmea2000.transport.N2kCanWriter`.
The NGT-1 twin writes the gateway's side of the protocol, which canboat's codec (a host's) does not:
the 0x93 packet layout is written by hand from canboat's ``actisense-serial`` reader.
"""

from __future__ import annotations

import contextlib
import logging
import re
import socket
import threading
import time
from collections import Counter
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

import serial
from nmea2000 import _canboat as canboat

from interfaces.messages import LinkStatus, Measurement, Rejected, RejectedInput
from interfaces.nmea2000.codec import FAST_PACKET_PGNS, FastPacketAssembler, Frame, N2kDecoder
from interfaces.nmea2000.transport import N2kReaderThread, RawFrame

logger = logging.getLogger(__name__)

Clock = Callable[[], float]
N2kEvent = Measurement | RawFrame | RejectedInput | LinkStatus

GATEWAY_KINDS = ("ydwg_tcp", "ydwg_udp", "ngt1_serial")
"""``interface`` names of the gateways (the CAN ones are python-can's)."""
YDWG_TCP_PORT, YDWG_UDP_PORT = 1457, 1456
MAX_LINE_BYTES = 256
"""A YD RAW line is < 60 bytes; a longer run without a line end is garbage and is dropped."""
_RAW_KEEP = 64


@dataclass(frozen=True)
class GatewayConfig:
    """Which gateway, where: configured like a CAN bus (``interface``, ``channel``, ``options``).

    Attributes
    ----------
    kind : str
        One of :data:`GATEWAY_KINDS`.
    channel : str
        ``host:port`` of the gateway (``ydwg_tcp``: the gateway to connect to; ``ydwg_udp``: the local
        address to receive on, e.g. ``0.0.0.0:1456``), or the serial device (``ngt1_serial``).
    options : mapping
        ``baudrate`` for ``ngt1_serial`` (default 115200); ``connect_timeout_s`` for ``ydwg_tcp``.
    """

    kind: str
    channel: str
    options: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.kind not in GATEWAY_KINDS:
            raise ValueError(f"gateway {self.kind!r} is not one of {', '.join(GATEWAY_KINDS)}")
        if self.kind != "ngt1_serial":
            self.endpoint()  # a bad host:port is a configuration error, not a reconnect loop

    @property
    def name(self) -> str:
        return f"{self.kind}:{self.channel}"

    def endpoint(self) -> tuple[str, int]:
        """``(host, port)`` of a YDWG channel."""
        match = re.fullmatch(r"(.+):(\d{1,5})", self.channel)
        if match is None or not 0 <= int(match.group(2)) <= 65535:
            raise ValueError(f"{self.kind} channel {self.channel!r} is not HOST:PORT")
        return match.group(1).strip("[]"), int(match.group(2))


class N2kGatewayReader(N2kReaderThread):
    """Background reader: gateway bytes → decoded NMEA 2000 events for a sink (see the module docstring).

    Parameters
    ----------
    gateway : GatewayConfig
    sink, clock, source_names, decoder, deliver_raw, poll_s, backoff_s, decode
        As for :class:`~interfaces.nmea2000.transport.N2kCanReader`. ``RawFrame.data`` of an NGT-1
        message is its whole payload (the gateway has joined the fast-packet frames).
    """

    _words = ("gateway connected", "gateway reconnected after {failures} failure(s)",
              "cannot reach the gateway: {error!r}", "gateway link lost: {error!r}")

    def __init__(self, gateway: GatewayConfig, sink: Callable[[N2kEvent], Any], *, clock: Clock = time.monotonic,
                 source_names: Mapping[int, str] | None = None, decoder: N2kDecoder | None = None,
                 deliver_raw: bool = False, poll_s: float = 0.1,
                 backoff_s: tuple[float, float] = (0.05, 2.0), decode: bool = True) -> None:
        super().__init__(gateway.name, sink, clock=clock, source_names=source_names, decoder=decoder,
                         deliver_raw=deliver_raw, poll_s=poll_s, backoff_s=backoff_s, decode=decode)
        self.gateway = gateway
        self._link_handle: Any = None
        self._buffer = bytearray()
        self._codec: Any = None

    # ---- connection ---------------------------------------------------------------------------

    def _open(self) -> Any:
        kind = self.gateway.kind
        if kind == "ngt1_serial":
            port = serial.Serial(self.gateway.channel, int(self.gateway.options.get("baudrate", 115200)),
                                 timeout=self.poll_s)
            self._codec = canboat.GatewayCodec("ngt1")
            port.write(self._codec.open())  # the NGT-1's start-up commands: receive all PGNs
            return port
        host, port_number = self.gateway.endpoint()
        if kind == "ydwg_tcp":
            sock = socket.create_connection((host, port_number),
                                            timeout=float(self.gateway.options.get("connect_timeout_s", 2.0)))
        else:
            sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            sock.bind((host, port_number))
        sock.settimeout(self.poll_s)
        return sock

    def _read(self) -> bytes | None:
        """Bytes from the gateway, ``None`` when nothing came within ``poll_s``; raises on a lost link."""
        handle = self._link_handle
        if self.gateway.kind == "ngt1_serial":
            data = handle.read(4096)
            return data or None
        try:
            data = handle.recv(65536)
        except TimeoutError:
            return None
        if not data and self.gateway.kind == "ydwg_tcp":
            raise ConnectionError("the gateway closed the connection")
        return data

    def _drop_link(self) -> None:
        handle, self._link_handle = self._link_handle, None
        self._buffer.clear()
        if handle is not None:
            with contextlib.suppress(Exception):
                handle.close()

    def _open_link(self) -> None:
        self._link_handle = self._open()

    def _receive(self) -> bytes | None:
        return self._read()

    def _handle(self, item: bytes, t_s: float) -> None:
        self.counters["bytes_received"] += len(item)
        try:
            self._on_bytes(item, t_s)
        except Exception as error:  # the decoders are fuzzed not to raise; belt and braces for the thread
            self.counters["decoder_errors"] += 1
            logger.exception("n2k gateway decoding raised")
            self._emit(RejectedInput(t_s, "n2k:?", Rejected("decode_error", repr(error), item[:_RAW_KEEP])))

    # ---- decoding -----------------------------------------------------------------------------

    def _reject(self, t_s: float, reason: str, detail: str, raw: bytes) -> None:
        self.counters["rejected." + reason] += 1
        self._emit(RejectedInput(t_s, "n2k:?", Rejected(reason, detail, raw[:_RAW_KEEP])))

    def _on_bytes(self, data: bytes, t_s: float) -> None:
        if self.gateway.kind == "ngt1_serial":
            for event, value in self._codec.receive(data, int(t_s * 1000.0)):
                if event == "frame":
                    prio, pgn, source, destination, payload = value
                    self.counters["messages_received"] += 1
                    if self.deliver_raw:
                        self._emit(RawFrame(t_s, canboat.can_id_compose(prio, pgn, source, destination),
                                            bytes(payload)))
                    if self.decode:
                        self._deliver(self.decoder.decode_message(pgn, source, payload, t_s), t_s)
                elif event == "send":
                    with contextlib.suppress(Exception):
                        self._link_handle.write(value)
                else:
                    self._reject(t_s, "bad_gateway_packet", f"NGT-1: {value}", b"")
            return
        buffer = self._buffer
        buffer += data
        if self.gateway.kind == "ydwg_udp" and not buffer.endswith(b"\n"):
            buffer += b"\n"  # a datagram ends its last line
        *lines, rest = bytes(buffer).split(b"\n")
        buffer.clear()
        if len(rest) > MAX_LINE_BYTES:
            self._reject(t_s, "garbage", f"{len(rest)} bytes without a line end", rest)
        else:
            buffer += rest
        for line in lines:
            self._on_line(line.strip(), t_s)

    def _on_line(self, line: bytes, t_s: float) -> None:
        if not line:
            return
        self.counters["lines_received"] += 1
        try:
            text = line.decode("ascii")  # canboat's parser panics on a multi-byte character: ASCII only
            parsed = canboat.parse_line("ydwg02", text)
        except (UnicodeDecodeError, ValueError) as error:
            self._reject(t_s, "garbage", f"not a YD RAW line: {error}", line)
            return
        if parsed is None:
            self._reject(t_s, "garbage", "not a YD RAW line", line)
            return
        prio, pgn, source, destination, payload = parsed
        can_id = canboat.can_id_compose(prio, pgn, source, destination)
        if self.deliver_raw:
            self._emit(RawFrame(t_s, can_id, bytes(payload)))
        if self.decode:
            self._deliver(self.decoder.decode_frame(can_id, bytes(payload), t_s), t_s)


# ----------------------------------------------------------------------------------------------
# loopback twins (the gateway's side)


def ydwg_raw_line(can_id: int, data: bytes, t_s: float, direction: str = "R") -> bytes:
    """One YD RAW line, ``hh:mm:ss.sss R 09F80115 A0 7D ...`` CR LF (``t_s`` as seconds of the day)."""
    millis = round(t_s * 1000.0) % 86_400_000
    seconds, ms = divmod(millis, 1000)
    stamp = f"{seconds // 3600:02d}:{seconds // 60 % 60:02d}:{seconds % 60:02d}.{ms:03d}"
    return f"{stamp} {direction} {can_id:08X} {' '.join(f'{b:02X}' for b in data)}\r\n".encode("ascii")


class YdwgRawServer:
    """The YDWG-02/YDEN-02 side of the RAW protocol on 127.0.0.1: TCP clients or UDP datagrams.

    Parameters
    ----------
    protocol : {"tcp", "udp"}
        ``tcp``: listen on ``(host, port)`` (0: a free port, see :attr:`port`) and send every frame to
        each connected client; ``udp``: send datagrams to ``(host, port)``.
    clock : callable
        Time of day for the lines' stamps [s].
    """

    def __init__(self, protocol: str = "tcp", host: str = "127.0.0.1", port: int = 0, *,
                 clock: Clock = time.time) -> None:
        if protocol not in ("tcp", "udp"):
            raise ValueError(f"protocol {protocol!r} is not tcp/udp")
        self.protocol = protocol
        self.clock = clock
        self._clients: list[socket.socket] = []
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        if protocol == "tcp":
            self._server = socket.create_server((host, port))
            self._server.settimeout(0.1)
            self.host, self.port = self._server.getsockname()[:2]
            self._thread = threading.Thread(target=self._accept, name="ydwg-twin", daemon=True)
            self._thread.start()
        else:
            self._server = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            self.host, self.port = host, port

    @property
    def clients(self) -> int:
        with self._lock:
            return len(self._clients)

    def _accept(self) -> None:
        while not self._stop.is_set():
            try:
                client, _ = self._server.accept()
            except (TimeoutError, OSError):
                continue
            with self._lock:
                self._clients.append(client)

    def send_bytes(self, data: bytes) -> None:
        """Send bytes as they are (for fault injection: garbage, cut lines)."""
        if self.protocol == "udp":
            self._server.sendto(data, (self.host, self.port))
            return
        with self._lock:
            for client in list(self._clients):
                try:
                    client.sendall(data)
                except OSError:
                    self._clients.remove(client)
                    client.close()

    def send(self, frames: Iterable[Frame]) -> int:
        """Send CAN frames (``(can_id, data)``, as :class:`N2kEncoder` makes them) as RAW lines; returns the count."""
        t_s = self.clock()
        lines = [ydwg_raw_line(can_id, bytes(data), t_s) for can_id, data in frames]
        self.send_bytes(b"".join(lines))
        return len(lines)

    def disconnect_clients(self) -> None:
        """Close every client connection (a gateway reboot, as the reader sees it)."""
        with self._lock:
            for client in self._clients:
                client.close()
            self._clients.clear()

    def close(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(2.0)
        self.disconnect_clients()
        self._server.close()

    def __enter__(self) -> YdwgRawServer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


_DLE, _STX, _ETX, _N2K_RECEIVED = 0x10, 0x02, 0x03, 0x93


def ngt1_packet(prio: int, pgn: int, source: int, destination: int, payload: bytes, *, timestamp_ms: int = 0) -> bytes:
    """An NGT-1 "N2K message received" packet (command 0x93) as the gateway writes it.

    Layout (canboat's ``actisense-serial``): DLE STX, 0x93, length, priority, PGN (3 bytes, little
    endian), destination, source, timestamp [ms] (4 bytes), payload length, payload, a checksum making
    the byte sum 0 mod 256, DLE ETX; a DLE inside is sent twice.
    """
    body = (bytes([prio, pgn & 0xFF, (pgn >> 8) & 0xFF, (pgn >> 16) & 0xFF, destination, source])
            + (timestamp_ms & 0xFFFFFFFF).to_bytes(4, "little") + bytes([len(payload)]) + payload)
    message = bytes([_N2K_RECEIVED, len(body)]) + body
    message += bytes([-sum(message) & 0xFF])
    return bytes([_DLE, _STX]) + message.replace(bytes([_DLE]), bytes([_DLE, _DLE])) + bytes([_DLE, _ETX])


class Ngt1Writer:
    """The NGT-1's side of a serial link: CAN frames in, reassembled, written as 0x93 packets.

    Parameters
    ----------
    write : callable
        Writes bytes to the port (e.g. ``PtyPair.write``, or a ``serial.Serial``'s ``write``).
    """

    def __init__(self, write: Callable[[bytes], Any], *, clock: Clock = time.monotonic) -> None:
        self._write = write
        self.clock = clock
        self._assembler = FastPacketAssembler()

    def send(self, frames: Iterable[Frame]) -> int:
        """Send CAN frames as the gateway would: single frames at once, fast packets once complete.

        Returns
        -------
        int
            Packets written.
        """
        t_s = self.clock()
        packets = []
        for can_id, data in frames:
            prio, pgn, source, destination = canboat.can_id_decompose(can_id)
            payload: bytes | None = bytes(data)
            if pgn in FAST_PACKET_PGNS:
                payload, _dropped = self._assembler.push(source, pgn, bytes(data), t_s)
            if payload is not None:
                packets.append(ngt1_packet(prio, pgn, source, destination, payload, timestamp_ms=int(t_s * 1000.0)))
        if packets:
            self._write(b"".join(packets))
        return len(packets)


class GatewayTwin:
    """The gateway a :class:`GatewayConfig` describes, played by the emulator: the interface of
    :class:`~interfaces.nmea2000.transport.N2kCanWriter` (``open``, ``send(frames) -> int``, ``counters``,
    ``close``), so a HIL link sends its sensors' frames through a gateway as through a CAN bus.

    ``ydwg_tcp``: a YD RAW server listening at the channel's HOST:PORT (the daemon connects to it);
    ``ydwg_udp``: datagrams to HOST:PORT (where the daemon receives); ``ngt1_serial``: a pseudo-terminal
    whose slave is linked at the channel's path (the daemon opens it), written without blocking (frames
    the daemon does not read in time are dropped and counted, as a real gateway's buffer overflows).
    """

    def __init__(self, gateway: GatewayConfig, *, clock: Clock = time.time) -> None:
        self.gateway = gateway
        self.clock = clock
        self.counters: Counter[str] = Counter()
        self._server: YdwgRawServer | None = None
        self._pty: Any = None
        self._ngt1: Ngt1Writer | None = None

    @property
    def name(self) -> str:
        return self.gateway.name

    def open(self) -> GatewayTwin:
        kind = self.gateway.kind
        if kind == "ngt1_serial":
            import fcntl  # noqa: PLC0415  (POSIX only, like the pty)
            import os  # noqa: PLC0415

            from interfaces.nmea0183.transport import PtyPair  # noqa: PLC0415

            self._pty = PtyPair(link_path=self.gateway.channel)
            flags = fcntl.fcntl(self._pty.master_fd, fcntl.F_GETFL)
            fcntl.fcntl(self._pty.master_fd, fcntl.F_SETFL, flags | os.O_NONBLOCK)
            self._ngt1 = Ngt1Writer(self._write_pty, clock=self.clock)
        else:
            host, port = self.gateway.endpoint()
            self._server = YdwgRawServer("tcp" if kind == "ydwg_tcp" else "udp", host, port, clock=self.clock)
        return self

    def _write_pty(self, data: bytes) -> None:
        import os  # noqa: PLC0415

        try:
            written = os.write(self._pty.master_fd, data)
        except BlockingIOError:
            written = 0
        if written < len(data):
            self.counters["bytes_dropped"] += len(data) - written

    def send(self, frames: Iterable[Frame]) -> int:
        """Send CAN frames through the gateway; returns how many were taken (all of them: a gateway
        accepts what the bus carries; what its client does not read is its client's loss)."""
        frames = list(frames)
        if self._server is not None:
            self._server.send(frames)
        elif self._ngt1 is not None:
            self.counters["packets_sent"] += self._ngt1.send(frames)
        else:
            return 0
        self.counters["frames_sent"] += len(frames)
        return len(frames)

    def close(self) -> None:
        if self._server is not None:
            self._server.close()
            self._server = None
        if self._pty is not None:
            self._pty.close()
            self._pty = None
