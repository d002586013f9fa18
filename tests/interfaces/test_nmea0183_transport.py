"""NMEA 0183 serial transport on real pseudo-terminals (no mocks): delivery, unplug/replug, shutdown,
and end to end between two processes."""

from __future__ import annotations

import itertools
import os
import queue
import select
import threading
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
import serial
from benchmark_module import load_benchmark

from interfaces.messages import (
    FixQuality,
    Heading,
    LinkStatus,
    Measurement,
    PositionFix,
    Rejected,
    RejectedInput,
)
from interfaces.nmea0183 import (
    LinkState,
    PtyPair,
    ReceivedLine,
    SerialReader,
    SerialWriter,
    encode_gga,
    encode_hdt,
    encode_ths,
)

WAIT_S = 10.0  # upper bound for awaited events; they normally take milliseconds

FIX = PositionFix(63.4305, 10.3951, FixQuality.RTK_FIXED, 45296.5, 16, 0.6, 21.5)
GGA = encode_gga(FIX, talker="GN")
HDT = encode_hdt(Heading(1.25))


class Collector:
    """Thread-safe sink for reader callbacks, with an awaitable count."""

    def __init__(self) -> None:
        self.items: list = []
        self._cond = threading.Condition()

    def __call__(self, item: object) -> None:
        with self._cond:
            self.items.append(item)
            self._cond.notify_all()

    def wait_for(self, count: int, timeout_s: float = WAIT_S) -> bool:
        with self._cond:
            return self._cond.wait_for(lambda: len(self.items) >= count, timeout_s)


@pytest.fixture
def counting_clock() -> Callable[[], float]:
    """An injected clock the test controls: 1000.0, 1001.0, ... one tick per call."""
    ticks = itertools.count()
    lock = threading.Lock()

    def clock() -> float:
        with lock:
            return 1000.0 + next(ticks)

    return clock


@pytest.fixture
def pty(tmp_path: Path) -> Iterator[PtyPair]:
    with PtyPair(tmp_path / "ttyGNSS") as pair:
        yield pair


def test_delivers_measurements_rejects_and_raw_lines(pty: PtyPair, counting_clock: Callable[[], float]) -> None:
    measurements, lines = Collector(), Collector()
    with SerialReader(pty.device_path, source="gnss1", clock=counting_clock, on_measurement=measurements,
                      on_line=lines) as reader:
        assert reader.wait_connected(WAIT_S)
        # one sentence split over three writes, binary garbage, a bad checksum, a heading
        pty.write(GGA[:10])
        pty.write(GGA[10:50])
        pty.write(GGA[50:] + b"\x00\xb5\x62\x01\x07\r\n" + GGA[:-4] + b"00\r\n" + HDT)
        assert measurements.wait_for(2) and lines.wait_for(4)
        assert reader.state == LinkState.CONNECTED
    assert [type(m.message) for m in measurements.items] == [PositionFix, Heading]
    fix = measurements.items[0].message
    assert fix.quality == FixQuality.RTK_FIXED and abs(fix.lat_deg - FIX.lat_deg) < 1e-8
    assert all(m.source == "gnss1" and isinstance(m, Measurement) for m in measurements.items)
    assert all(m.t_s >= 1000.0 and m.t_s == int(m.t_s) for m in measurements.items)  # stamped by the injected clock
    reasons = [line.frame.rejected.reason for line in lines.items if line.frame.rejected]
    assert reasons == ["garbage", "checksum"]
    assert all(isinstance(line, ReceivedLine) for line in lines.items)
    assert lines.items[0].frame.raw == GGA[:-2]  # the raw sentence, for the recorder
    counters = reader.counters
    assert counters["ok"] == 2 and counters["rejected"] == 2 and counters["connects"] == 1
    assert counters["bytes_in"] == len(GGA) * 2 + len(HDT) + 7
    assert not reader.is_alive and reader.state == LinkState.CLOSED


def test_queue_receives_measurements_rejects_and_link_changes(pty: PtyPair) -> None:
    items: queue.Queue = queue.Queue()
    with SerialReader(pty.device_path, source="gyro1", clock=lambda: 5.0, out_queue=items) as reader:
        assert reader.wait_connected(WAIT_S)
        pty.write(encode_ths(Heading(0.5), mode="V") + encode_ths(Heading(0.5)))
        received = [items.get(timeout=WAIT_S) for _ in range(3)]
    assert isinstance(received[0], LinkStatus) and received[0].connected and received[0].source == "gyro1"
    assert isinstance(received[1], RejectedInput) and received[1].rejected.reason == "invalid_status"
    assert isinstance(received[2], Measurement) and received[2].message.mode == "A"


def test_unplug_and_replug_reconnects_without_losing_the_thread(pty: PtyPair) -> None:
    measurements, links = Collector(), Collector()
    reader = SerialReader(pty.device_path, source="gnss1", clock=lambda: 0.0, on_measurement=measurements,
                          on_link=links, reconnect_initial_s=0.01, reconnect_max_s=0.05).start()
    try:
        assert reader.wait_connected(WAIT_S)
        pty.write(GGA + GGA[:30])  # a half sentence is in flight when the cable is pulled
        assert measurements.wait_for(1)
        pty.unplug()  # the device disappears: EOF/EIO on the open port, then the path is gone
        assert reader.wait_disconnected(WAIT_S)
        assert reader.wait_counters(lambda c: c["open_failures"] >= 2, WAIT_S)  # retrying, with backoff
        assert reader.state == LinkState.DISCONNECTED and reader.is_alive
        pty.replug()
        assert reader.wait_connected(WAIT_S, connects=2)
        pty.write(HDT + GGA)
        assert measurements.wait_for(3)
    finally:
        assert reader.close()
    assert [type(m.message) for m in measurements.items] == [PositionFix, Heading, PositionFix]
    counters = reader.counters
    assert counters["disconnects"] == 1 and counters["connects"] == 2 and counters["internal_errors"] == 0
    assert counters["rejected.unterminated"] == 1  # the half sentence of the pulled cable, counted not glued
    assert [status.connected for status in links.items] == [True, False, True]


def test_closed_pty_without_symlink_is_a_counted_disconnect(tmp_path: Path) -> None:
    pair = PtyPair()
    reader = SerialReader(pair.device_path, source="gnss1", clock=lambda: 0.0, reconnect_initial_s=0.01,
                          reconnect_max_s=0.02).start()
    try:
        assert reader.wait_connected(WAIT_S)
        pair.close()  # EOF on the pty; the old slave path never comes back
        assert reader.wait_disconnected(WAIT_S)
        assert reader.wait_counters(lambda c: c["open_failures"] >= 3, WAIT_S)
        assert reader.is_alive and reader.state == LinkState.DISCONNECTED
        assert reader.last_error
    finally:
        assert reader.close()
    assert not reader.is_alive


def test_a_port_that_never_exists_keeps_retrying_until_closed(tmp_path: Path) -> None:
    links = Collector()
    reader = SerialReader(str(tmp_path / "ttyNothing"), source="gnss9", clock=lambda: 0.0, on_link=links,
                          reconnect_initial_s=0.01, reconnect_max_s=0.02).start()
    try:
        assert reader.wait_counters(lambda c: c["open_failures"] >= 3, WAIT_S)
        assert reader.state == LinkState.DISCONNECTED
    finally:
        assert reader.close()
    assert [status.connected for status in links.items] == [False]  # reported once, then counted


def test_failing_callback_is_counted_and_the_stream_goes_on(pty: PtyPair) -> None:
    good = Collector()
    calls = itertools.count()

    def flaky(measurement: Measurement) -> None:
        good(measurement)
        if next(calls) == 0:
            raise RuntimeError("consumer bug")

    with SerialReader(pty.device_path, source="gnss1", clock=lambda: 0.0, on_measurement=flaky) as reader:
        assert reader.wait_connected(WAIT_S)
        pty.write(GGA + HDT)
        assert good.wait_for(2)
        assert reader.is_alive
        assert reader.counters["callback_errors"] == 1


def test_failing_clock_is_counted_and_the_stream_goes_on(pty: PtyPair) -> None:
    measurements = Collector()
    calls = itertools.count()

    def clock() -> float:
        if next(calls) == 1:  # the read after the link event
            raise OSError("clock source gone")
        return 7.0

    with SerialReader(pty.device_path, source="gnss1", clock=clock, on_measurement=measurements) as reader:
        assert reader.wait_connected(WAIT_S)
        pty.write(GGA)
        assert measurements.wait_for(1)
        pty.write(HDT)
        assert measurements.wait_for(2)
        assert reader.is_alive and reader.counters["internal_errors"] == 1
    assert [m.t_s for m in measurements.items] == [7.0, 7.0]  # the last good time, never NaN


def test_close_wakes_a_blocked_read(pty: PtyPair) -> None:
    reader = SerialReader(pty.device_path, source="gnss1", clock=lambda: 0.0, read_timeout_s=60.0).start()
    assert reader.wait_connected(WAIT_S)
    assert reader.close(timeout_s=5.0)  # far below the 60 s read timeout: cancel_read() woke it
    assert not reader.is_alive and reader.state == LinkState.CLOSED


def test_port_is_locked_against_a_second_reader(pty: PtyPair) -> None:
    first = SerialReader(pty.device_path, source="a", clock=lambda: 0.0).start()
    # the second starts once the first holds the port (started together, either may win the lock)
    assert first.wait_connected(WAIT_S)
    second = SerialReader(pty.device_path, source="b", clock=lambda: 0.0, reconnect_initial_s=0.01).start()
    try:
        assert second.wait_counters(lambda c: c["open_failures"] >= 1, WAIT_S)
        assert "lock" in second.last_error.lower()
    finally:
        assert first.close() and second.close()


def test_rejected_items_keep_their_raw_bytes(pty: PtyPair) -> None:
    lines = Collector()
    with SerialReader(pty.device_path, source="gnss1", clock=lambda: 0.0, on_line=lines) as reader:
        assert reader.wait_connected(WAIT_S)
        pty.write(b"$GPGGA,,,,,,0,,,,M,,M,,*66\r\n")
        assert lines.wait_for(1)
    rejected = lines.items[0].frame.rejected
    assert isinstance(rejected, Rejected) and rejected.reason == "invalid_fix"
    assert rejected.raw == b"$GPGGA,,,,,,0,,,,M,,M,,*66"


def test_pty_is_raw_both_ways_and_the_writer_writes(pty: PtyPair) -> None:
    """Every byte value crosses unchanged (no CR/LF translation, no echo, no XON/XOFF or signal
    characters): first through the pty's own raw settings (a plain descriptor, before pyserial
    touches the terminal), then from the emulator's writer to the master, and into a pyserial port."""
    every_byte = bytes(range(256)) * 4

    def read_exactly(fd: int, count: int) -> bytes:
        received = b""
        while len(received) < count and select.select([fd], [], [], WAIT_S)[0]:
            received += os.read(fd, count - len(received))
        return received

    plain = os.open(pty.device_path, os.O_RDONLY | os.O_NOCTTY)
    try:
        pty.write(every_byte)
        assert read_exactly(plain, len(every_byte)) == every_byte
    finally:
        os.close(plain)
    with SerialWriter(pty.slave_path, baudrate=38400) as writer:
        writer.write(every_byte)
        assert read_exactly(pty.master_fd, len(every_byte)) == every_byte
    with serial.Serial(pty.device_path, timeout=WAIT_S) as port:
        pty.write(every_byte)
        assert port.read(len(every_byte)) == every_byte


def test_two_processes_over_a_pty_deliver_every_sentence() -> None:
    """The writer is a separate process (the emulator's role); the reader is here. Delivery, not timing."""
    result = load_benchmark("bench_nmea0183_transport").run(count=200, rate_hz=0.0)
    assert result["sent"] == 200 and result["delivered"] == 200 and result["lost"] == 0
    assert result["rejected"] == 0
    for key in ("write_to_decoded", "write_to_read"):
        assert 0.0 < result[key]["median_us"] <= result[key]["p99_us"] <= result[key]["max_us"]
