"""NMEA 0183 serial transport: a pyserial reader thread that survives unplugging, a writer, a pty twin.

:class:`SerialReader` opens a serial device (or any pyserial URL: ``socket://host:port`` for NMEA
over TCP, ``loop://``), reads it in a background thread, decodes with
:class:`~interfaces.nmea0183.codec.Nmea0183Decoder` and hands every decoded message on as a
:class:`~interfaces.messages.Measurement` stamped with the injected clock at the moment the bytes
were read. Rejected input goes on as :class:`~interfaces.messages.RejectedInput`, link changes as
:class:`~interfaces.messages.LinkStatus`, and every frame with its raw bytes as
:class:`ReceivedLine` (for the black-box recorder).

A port that closes, disappears or reports EOF (USB adapter unplugged, pty master closed) marks
the link disconnected (state, counter, a ``LinkStatus``) and is reopened with exponential backoff,
in the same thread, forever, until :meth:`SerialReader.close`. Nothing the device sends and no
exception in a callback ends the thread.

:class:`PtyPair` is the loopback twin for tests and the emulator: a real pseudo-terminal pair in
raw mode, whose slave path (optionally behind a symlink that can be "unplugged" and "replugged")
stands in for ``/dev/ttyUSB0``. :class:`SerialWriter` is the emulator side of a real port.
"""

from __future__ import annotations

import contextlib
import enum
import logging
import os
import queue
import threading
import tty
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import TypeVar

import serial

from interfaces.messages import LinkStatus, Measurement, RejectedInput
from interfaces.nmea0183.codec import DEFAULT_MAX_SENTENCE_CHARS, Frame, Nmea0183Decoder

_Item = TypeVar("_Item")

_log = logging.getLogger(__name__)


class LinkState(enum.Enum):
    """State of a :class:`SerialReader`'s link."""

    CONNECTING = "connecting"      # started, first open not yet attempted or in progress
    CONNECTED = "connected"        # port open and being read
    DISCONNECTED = "disconnected"  # open failed or the port went away; reconnecting with backoff
    CLOSED = "closed"              # close() was called; the thread has ended or is ending


@dataclass(frozen=True, slots=True)
class ReceivedLine:
    """One frame of the stream (sentence, garbage run) with its receive time, for the recorder.

    Attributes
    ----------
    t_s : float
        Receive time on the reader's clock [s].
    source : str
        The reader's sensor name.
    frame : Frame
        Raw bytes, the address, the decoded messages or the rejection.
    """

    t_s: float
    source: str
    frame: Frame


TRANSPORT_COUNTERS = ("bytes_in", "reads", "connects", "disconnects", "open_failures", "callback_errors",
                      "queue_full", "internal_errors")
"""Transport counters added to the decoder's in :attr:`SerialReader.counters`."""


class SerialReader:
    """Read, decode and deliver an NMEA 0183 stream from a serial port in a background thread.

    Parameters
    ----------
    port : str
        Device path (``/dev/ttyUSB0``, a pty slave, a symlink to either) or a pyserial URL.
    source : str
        Configured sensor name, put in every delivered item (``gnss1``).
    clock : callable
        Returns the current time [s] (monotonic in the daemon, stepped in lockstep); called once
        per read, right after the bytes arrive.
    baudrate : int
        Line speed [baud] (4800 for NMEA 0183, 38400 for high-speed NMEA).
    on_measurement : callable, optional
        Called with each :class:`~interfaces.messages.Measurement`, in stream order, on the reader thread.
    on_line : callable, optional
        Called with a :class:`ReceivedLine` for every frame (ok, ignored or rejected): the recorder's feed.
    on_link : callable, optional
        Called with a :class:`~interfaces.messages.LinkStatus` when the link is gained or lost.
    on_data : callable, optional
        Called with ``(t_s, data)`` for every read, the bytes as they arrived (any chunking).
    decode : bool
        Split and decode sentences here (``on_measurement``, ``on_line``, ``out_queue``). False: deliver only
        the bytes (``on_data``) and the link changes, for a caller that decodes on its own thread (the
        daemon's input stage, :mod:`dpcontrol.runtime.ingest`).
    out_queue : queue.Queue, optional
        Receives ``Measurement``, ``RejectedInput`` and ``LinkStatus`` items (``put_nowait``; when a
        bounded queue is full the item is dropped and ``counters["queue_full"]`` counts it).
    max_sentence_chars, strict_validity
        Decoder options, see :class:`~interfaces.nmea0183.codec.Nmea0183Decoder`.
    read_timeout_s : float
        Longest a read blocks before the thread checks for shutdown [s] (``close()`` also wakes it).
    reconnect_initial_s, reconnect_max_s : float
        Reconnection backoff: first delay, doubled after each failed open up to the maximum [s].
    exclusive : bool
        Lock the device (``flock``) so a second process cannot read it concurrently (posix devices).

    Notes
    -----
    Callbacks run on the reader thread and must be quick; an exception in one is counted in
    ``counters["callback_errors"]`` and logged, never propagated.
    """

    def __init__(  # noqa: PLR0913 - the serial port's settings, keyword-only
        self,
        port: str,
        *,
        source: str,
        clock: Callable[[], float],
        baudrate: int = 4800,
        on_measurement: Callable[[Measurement], None] | None = None,
        on_line: Callable[[ReceivedLine], None] | None = None,
        on_link: Callable[[LinkStatus], None] | None = None,
        on_data: Callable[[float, bytes], None] | None = None,
        decode: bool = True,
        out_queue: queue.Queue | None = None,
        max_sentence_chars: int = DEFAULT_MAX_SENTENCE_CHARS,
        strict_validity: bool = True,
        read_timeout_s: float = 0.2,
        reconnect_initial_s: float = 0.05,
        reconnect_max_s: float = 2.0,
        exclusive: bool = True,
    ) -> None:
        if not (read_timeout_s > 0.0 and 0.0 < reconnect_initial_s <= reconnect_max_s):
            raise ValueError("need read_timeout_s > 0 and 0 < reconnect_initial_s <= reconnect_max_s")
        self.port = port
        self.source = source
        self.baudrate = baudrate
        self._clock = clock
        self._on_measurement = on_measurement
        self._on_line = on_line
        self._on_link = on_link
        self._on_data = on_data
        self._decode = decode
        self._queue = out_queue
        self._read_timeout_s = read_timeout_s
        self._reconnect_initial_s = reconnect_initial_s
        self._reconnect_max_s = reconnect_max_s
        self._exclusive = exclusive
        self._decoder = Nmea0183Decoder(max_sentence_chars, strict_validity)
        self._transport_counters = dict.fromkeys(TRANSPORT_COUNTERS, 0)
        self._lock = threading.Lock()            # guards counters and decoder state against snapshots
        self._cond = threading.Condition()       # notified on every state change
        self._state = LinkState.CONNECTING
        self._stop = threading.Event()
        self._serial: serial.SerialBase | None = None
        self._thread: threading.Thread | None = None
        self._last_t_s = 0.0
        self.last_error = ""

    # -- lifecycle ----------------------------------------------------------------------------

    def start(self) -> SerialReader:
        """Start the reader thread (idempotent); returns ``self``."""
        if self._thread is None:
            self._thread = threading.Thread(target=self._run, name=f"nmea0183-reader-{self.source}", daemon=True)
            self._thread.start()
        return self

    def close(self, timeout_s: float = 2.0) -> bool:
        """Stop reading, close the port and join the thread.

        Parameters
        ----------
        timeout_s : float
            Longest wait for the thread [s]; a blocked read is woken at once (``cancel_read``),
            otherwise it ends within ``read_timeout_s``.

        Returns
        -------
        bool
            ``True`` when the thread has ended.
        """
        self._stop.set()
        port = self._serial
        cancel = getattr(port, "cancel_read", None)
        if cancel is not None:
            with contextlib.suppress(OSError, ValueError, serial.SerialException):  # closed under us: nothing to wake
                cancel()
        thread = self._thread
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout_s)
            if thread.is_alive():
                return False
        self._set_state(LinkState.CLOSED)
        return True

    def __enter__(self) -> SerialReader:
        return self.start()

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()

    # -- observation --------------------------------------------------------------------------

    @property
    def state(self) -> LinkState:
        """Current :class:`LinkState`."""
        return self._state

    @property
    def is_alive(self) -> bool:
        """The reader thread is running."""
        return self._thread is not None and self._thread.is_alive()

    @property
    def counters(self) -> dict[str, int]:
        """A consistent snapshot: decoder counters (``frames``, ``ok``, ``rejected.<reason>`` ...) + transport."""
        with self._lock:
            return {**self._decoder.counters, **self._transport_counters}

    def wait_connected(self, timeout_s: float, connects: int = 1) -> bool:
        """Wait until the port is open for the ``connects``-th time (1: first open) or the timeout [s]."""
        with self._cond:
            return self._cond.wait_for(
                lambda: self._state == LinkState.CONNECTED and self._transport_counters["connects"] >= connects,
                timeout_s)

    def wait_disconnected(self, timeout_s: float, disconnects: int = 1) -> bool:
        """Wait until the link has been lost ``disconnects`` times in total, or the timeout [s]."""
        return self.wait_counters(lambda counters: counters["disconnects"] >= disconnects, timeout_s)

    def wait_counters(self, predicate: Callable[[dict[str, int]], bool], timeout_s: float) -> bool:
        """Wait until ``predicate(transport counters)`` holds (checked at every link event), or the timeout [s]."""
        with self._cond:
            return self._cond.wait_for(lambda: predicate(self._transport_counters), timeout_s)

    # -- thread -------------------------------------------------------------------------------

    def _run(self) -> None:
        delay_s = self._reconnect_initial_s
        while not self._stop.is_set():
            try:
                port = self._open()
                if port is None:
                    if self._stop.wait(delay_s):
                        break
                    delay_s = min(2.0 * delay_s, self._reconnect_max_s)
                    continue
                delay_s = self._reconnect_initial_s
                try:
                    self._read_loop(port)
                except (serial.SerialException, OSError) as exc:  # unplugged, EOF, I/O error
                    self._lost(f"read failed: {exc}")
                finally:
                    self._close_port(port)
            except Exception as exc:  # a bug must not end the thread: count it, back off, carry on
                self._count("internal_errors")
                self.last_error = f"{type(exc).__name__}: {exc}"
                _log.exception("nmea0183 reader %s: internal error", self.source)
                if self._state == LinkState.CONNECTED:
                    with contextlib.suppress(Exception):
                        self._lost(self.last_error)
            if not self._stop.is_set():
                self._stop.wait(self._reconnect_initial_s)
        self._set_state(LinkState.CLOSED)

    def _open(self) -> serial.SerialBase | None:
        try:
            kwargs: dict[str, object] = {"baudrate": self.baudrate, "timeout": self._read_timeout_s}
            if "://" not in self.port:
                kwargs["exclusive"] = self._exclusive
            port = serial.serial_for_url(self.port, **kwargs)
        except (serial.SerialException, OSError, ValueError) as exc:
            self._count("open_failures")
            self.last_error = f"open {self.port} failed: {exc}"
            was_connected = self._state != LinkState.DISCONNECTED
            self._set_state(LinkState.DISCONNECTED)  # also wakes wait_counters()
            if was_connected:
                self._emit_link(False, self.last_error)
            return None
        self._serial = port
        if self._stop.is_set():  # close() raced with the open: do not start reading
            return port
        self._count("connects")
        self._set_state(LinkState.CONNECTED)
        self._emit_link(True, f"opened {self.port}")
        return port

    def _read_loop(self, port: serial.SerialBase) -> None:
        while not self._stop.is_set():
            data = port.read(1)  # blocks until a byte, the timeout, or cancel_read()
            if not data:
                continue
            waiting = port.in_waiting
            if waiting:
                data += port.read(waiting)
            t_s = self._now()
            with self._lock:
                self._transport_counters["reads"] += 1
                self._transport_counters["bytes_in"] += len(data)
                frames = self._decoder.feed_frames(data) if self._decode else []
            if self._on_data is not None:
                self._call_data(t_s, data)
            if frames:
                self._deliver(t_s, frames)

    def _lost(self, detail: str) -> None:
        """The port went away: count it, report it, and drop the half line the decoder holds."""
        self.last_error = detail
        with self._lock:
            self._transport_counters["disconnects"] += 1
            frames = self._decoder.flush()
        self._set_state(LinkState.DISCONNECTED)
        self._emit_link(False, detail)
        if frames:
            self._deliver(self._now(), frames)

    def _close_port(self, port: serial.SerialBase) -> None:
        self._serial = None
        with contextlib.suppress(serial.SerialException, OSError):  # already gone
            port.close()

    # -- delivery -----------------------------------------------------------------------------

    def _deliver(self, t_s: float, frames: list[Frame]) -> None:
        source = self.source
        for frame in frames:
            if self._on_line is not None:
                self._call(self._on_line, ReceivedLine(t_s, source, frame))
            if frame.rejected is not None:
                if self._queue is not None:
                    self._put(RejectedInput(t_s, source, frame.rejected))
                continue
            for message in frame.messages:
                measurement = Measurement(t_s, source, message)
                if self._on_measurement is not None:
                    self._call(self._on_measurement, measurement)
                if self._queue is not None:
                    self._put(measurement)

    def _emit_link(self, connected: bool, detail: str) -> None:
        status = LinkStatus(self._now(), self.source, connected, detail)
        if self._on_link is not None:
            self._call(self._on_link, status)
        if self._queue is not None:
            self._put(status)

    def _now(self) -> float:
        """The injected clock; if it fails, the last good time (counted as an internal error)."""
        try:
            self._last_t_s = self._clock()
        except Exception:
            self._count("internal_errors")
            _log.exception("nmea0183 reader %s: clock failed", self.source)
        return self._last_t_s

    def _call_data(self, t_s: float, data: bytes) -> None:
        try:
            self._on_data(t_s, data)  # type: ignore[misc]
        except Exception:
            self._count("callback_errors")
            _log.exception("nmea0183 reader %s: data callback failed", self.source)

    def _call(self, callback: Callable[[_Item], None], item: _Item) -> None:
        try:
            callback(item)
        except Exception:
            self._count("callback_errors")
            _log.exception("nmea0183 reader %s: callback failed", self.source)

    def _put(self, item: object) -> None:
        try:
            self._queue.put_nowait(item)  # type: ignore[union-attr]
        except queue.Full:
            self._count("queue_full")

    def _count(self, key: str) -> None:
        with self._lock:
            self._transport_counters[key] += 1

    def _set_state(self, state: LinkState) -> None:
        with self._cond:
            if self._state != LinkState.CLOSED:
                self._state = state
            self._cond.notify_all()


class SerialWriter:
    """The emulator side of a real serial port: open it and write bytes (pyserial).

    Parameters
    ----------
    port : str
        Device path or pyserial URL.
    baudrate : int
        Line speed [baud].
    write_timeout_s : float
        Longest a write may block (a stalled port raises ``serial.SerialTimeoutException``) [s].
    """

    def __init__(self, port: str, baudrate: int = 4800, write_timeout_s: float = 1.0) -> None:
        self._serial = serial.serial_for_url(port, baudrate=baudrate, write_timeout=write_timeout_s)

    def write(self, data: bytes) -> None:
        """Write all of ``data``; raises ``serial.SerialException`` if the port fails."""
        self._serial.write(data)

    def close(self) -> None:
        """Close the port."""
        self._serial.close()

    def __enter__(self) -> SerialWriter:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()


class PtyPair:
    """A real pseudo-terminal pair standing in for a serial cable: write the master, read the slave.

    The slave is put in raw mode (no echo, no CR/LF translation, no signal characters), so bytes
    arrive exactly as written, binary included. With ``link_path`` the device is reached through
    a symlink that :meth:`unplug` removes and :meth:`replug` points at a fresh pty — what udev does
    with ``/dev/serial/by-id/...`` when a USB adapter is pulled and plugged back.

    Parameters
    ----------
    link_path : str or Path, optional
        Where to create the symlink to the slave.
    """

    def __init__(self, link_path: str | Path | None = None) -> None:
        self._link = Path(link_path) if link_path is not None else None
        self.master_fd = -1
        self._slave_fd = -1
        self.slave_path = ""
        self.replug()

    @property
    def device_path(self) -> str:
        """The path a reader opens: the symlink when there is one, else the slave."""
        return str(self._link) if self._link is not None else self.slave_path

    @property
    def plugged(self) -> bool:
        """The pty exists (between :meth:`replug` and :meth:`unplug`)."""
        return self.master_fd >= 0

    def write(self, data: bytes) -> None:
        """Write all of ``data`` to the master (blocks while the slave's input buffer is full)."""
        view = memoryview(data)
        while view:
            written = os.write(self.master_fd, view)
            view = view[written:]

    def unplug(self) -> None:
        """Close both ends and remove the symlink: readers get EOF/EIO, reopening fails."""
        if self._link is not None and self._link.is_symlink():
            self._link.unlink()
        for fd in (self.master_fd, self._slave_fd):
            if fd >= 0:
                os.close(fd)
        self.master_fd = self._slave_fd = -1

    def replug(self) -> None:
        """Create a fresh pty (after :meth:`unplug`, or the first time) and point the symlink at it."""
        if self.plugged:
            self.unplug()
        master_fd, slave_fd = os.openpty()
        # keep a slave descriptor open: the pty (and its raw settings) lives while a reader reconnects
        tty.setraw(slave_fd)
        self.master_fd, self._slave_fd = master_fd, slave_fd
        self.slave_path = os.ttyname(slave_fd)
        if self._link is not None:
            temporary = self._link.with_name(self._link.name + ".new")
            if temporary.is_symlink():
                temporary.unlink()
            temporary.symlink_to(self.slave_path)
            temporary.replace(self._link)  # atomic: a reader never sees a half-made link

    def close(self) -> None:
        """Same as :meth:`unplug`."""
        self.unplug()

    def __enter__(self) -> PtyPair:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()
