"""NMEA 2000 transport: python-can virtual loopback, the remote server between two processes, reconnects."""

from __future__ import annotations

import json
import math
import os
import queue
import select
import signal
import subprocess
import sys
import threading
import time
import uuid
from collections.abc import Callable

import can
import pytest

from dpbase.schema import ConfigError
from interfaces.messages import (
    Attitude,
    CourseOverGround,
    FixQuality,
    Heading,
    LinkStatus,
    Measurement,
    PositionFix,
    RateOfTurn,
    RejectedInput,
    Wind,
)
from interfaces.nmea2000.codec import PGN_GNSS_POSITION, PGN_POSITION_RAPID, N2kDecoder, N2kEncoder
from interfaces.nmea2000.probe import sequence_of
from interfaces.nmea2000.transport import (
    CanBusConfig,
    N2kCanReader,
    N2kCanWriter,
    RawFrame,
    start_remote_server,
)

WAIT_S = 10.0  # upper bound for anything to arrive on a loaded machine; never a sleep


class SteppedClock:
    """A thread-safe clock the test moves by hand."""

    def __init__(self, t_s: float = 0.0) -> None:
        self._t_s = t_s
        self._lock = threading.Lock()

    def __call__(self) -> float:
        with self._lock:
            return self._t_s

    def advance(self, dt_s: float) -> None:
        with self._lock:
            self._t_s += dt_s


def poll(events: queue.Queue, predicate: Callable[[object], bool], timeout_s: float) -> object | None:
    """The first event satisfying ``predicate`` (others are consumed), or ``None`` after ``timeout_s``."""
    deadline = time.monotonic() + timeout_s
    while (remaining := deadline - time.monotonic()) > 0:
        try:
            event = events.get(timeout=remaining)
        except queue.Empty:
            return None
        if predicate(event):
            return event
    return None


def wait_for(events: queue.Queue, predicate: Callable[[object], bool], timeout_s: float = WAIT_S) -> object:
    """Like :func:`poll`, but the test fails if nothing arrives."""
    event = poll(events, predicate, timeout_s)
    if event is None:
        pytest.fail(f"no matching event within {timeout_s} s")
    return event


def virtual_config() -> CanBusConfig:
    return CanBusConfig("virtual", f"test-{uuid.uuid4().hex}")


def is_link(connected: bool) -> Callable[[object], bool]:
    return lambda e: isinstance(e, LinkStatus) and e.connected is connected


def test_virtual_loopback_delivers_every_pgn_stamped_with_the_injected_clock() -> None:
    config, events, clock = virtual_config(), queue.Queue(), SteppedClock(42.0)
    encoder = N2kEncoder(35)
    sent = [PositionFix(63.43, 10.39, FixQuality.RTK_FIXED, utc_time_s=3.0), Heading(1.5), RateOfTurn(-0.02),
            Attitude(0.01, 0.02, -1.0), Wind(6.0, 2.0, "apparent"), CourseOverGround(0.5, 1.25)]
    with N2kCanReader(config, events.put, clock=clock, source_names={35: "gnss1"}, deliver_raw=True) as reader, \
            N2kCanWriter(config) as writer:
        assert reader.wait_connected(WAIT_S)
        frames = [frame for message in sent for frame in encoder.encode(message)]
        assert writer.send(frames) == len(frames) == 12
        got = [wait_for(events, lambda e: isinstance(e, Measurement)) for _ in sent]
    assert [type(m.message) for m in got] == [type(m) for m in sent]
    assert all(m.t_s == 42.0 and m.source == "gnss1" for m in got)
    assert abs(got[0].message.lat_deg - 63.43) < 1e-9 and got[0].message.quality == FixQuality.RTK_FIXED
    assert abs(got[1].message.heading_rad - 1.5) <= 0.5e-4 and got[4].message.reference == "apparent"
    assert reader.counters["frames_received"] == 12 and writer.counters["frames_sent"] == 12
    assert reader.decoder.counters["messages"] == 6


def test_raw_frames_and_link_status_reach_the_sink() -> None:
    config, events = virtual_config(), queue.Queue()
    with N2kCanReader(config, events.put, deliver_raw=True) as reader, N2kCanWriter(config) as writer:
        assert reader.wait_connected(WAIT_S)
        frames = N2kEncoder(7).heading(Heading(0.25))
        writer.send(frames)
        raw = wait_for(events, lambda e: isinstance(e, RawFrame))
        assert (raw.can_id, raw.data) == frames[0]
    seen = []
    while not events.empty():
        seen.append(events.get())
    assert any(isinstance(e, Measurement) for e in seen)


def test_incomplete_fast_packet_expires_on_an_idle_bus() -> None:
    config, events, clock = virtual_config(), queue.Queue(), SteppedClock(0.0)
    reader = N2kCanReader(config, events.put, clock=clock, decoder=N2kDecoder(fast_packet_timeout_s=0.75),
                          deliver_raw=True)
    with reader, N2kCanWriter(config) as writer:
        assert reader.wait_connected(WAIT_S)
        frames = N2kEncoder(9).gnss_position(PositionFix(1.0, 2.0, FixQuality.GPS))
        writer.send(frames[:-1])  # the last frame is lost
        for _ in frames[:-1]:  # the reader has them all (stamped 0.0) before time moves on
            wait_for(events, lambda e: isinstance(e, RawFrame))
        clock.advance(1.0)  # nothing else arrives: the reader's idle poll must drop the message
        reject = wait_for(events, lambda e: isinstance(e, RejectedInput))
    assert reject.rejected.reason == "truncated_fast_packet" and reject.source == "n2k:9" and reject.t_s == 1.0
    assert reader.decoder.counters["rejected.truncated_fast_packet"] == 1


def test_frames_that_are_not_nmea2000_are_counted_not_decoded() -> None:
    config, events = virtual_config(), queue.Queue()
    with N2kCanReader(config, events.put) as reader, N2kCanWriter(config).open() as writer:
        assert reader.wait_connected(WAIT_S)
        bus = config.open()
        try:
            bus.send(can.Message(arbitration_id=0x123, data=b"\x01", is_extended_id=False))
            bus.send(can.Message(arbitration_id=0x1FFFFFFF, is_error_frame=True, is_extended_id=True))
        finally:
            bus.shutdown()
        writer.send(N2kEncoder(7).heading(Heading(0.25)))  # a virtual channel keeps the order
        wait_for(events, lambda e: isinstance(e, Measurement))
    assert reader.counters["not_n2k_frames"] == 1 and reader.counters["error_frames"] == 1
    assert reader.decoder.counters["frames"] == 1


def test_a_sink_that_raises_does_not_stop_the_reader() -> None:
    config, events = virtual_config(), queue.Queue()
    calls = []

    def sink(event: object) -> None:
        calls.append(event)
        if len(calls) == 2:
            raise RuntimeError("consumer bug")
        events.put(event)

    with N2kCanReader(config, sink) as reader, N2kCanWriter(config) as writer:
        assert reader.wait_connected(WAIT_S)
        writer.send(N2kEncoder(7).heading(Heading(0.25)))  # event 2: raises
        writer.send(N2kEncoder(7).heading(Heading(0.5)))
        second = wait_for(events, lambda e: isinstance(e, Measurement))
    assert abs(second.message.heading_rad - 0.5) < 1e-3 and reader.counters["sink_errors"] == 1


def test_remote_server_in_a_thread_bridges_two_clients() -> None:
    events = queue.Queue()
    with start_remote_server(mode="thread") as server:
        assert server.alive and server.url.startswith("ws://127.0.0.1:")
        with N2kCanReader(server.bus_config(), events.put) as reader, N2kCanWriter(server.bus_config()) as writer:
            assert reader.wait_connected(WAIT_S)
            writer.send(N2kEncoder(7).heading(Heading(2.0)))
            got = wait_for(events, lambda e: isinstance(e, Measurement))
    assert abs(got.message.heading_rad - 2.0) < 1e-3
    assert not server.alive


@pytest.mark.hil
def test_two_processes_over_the_remote_server() -> None:
    """A sender subprocess (the probe) → python-can-remote server (a third process) → reader here."""
    events = queue.Queue()
    count, fast_every = 40, 10
    with start_remote_server(mode="process") as server, \
            N2kCanReader(server.bus_config(), events.put, clock=time.monotonic) as reader:
        assert reader.wait_connected(WAIT_S)
        probe = subprocess.run(
            [sys.executable, "-m", "interfaces.nmea2000.probe", "--channel", server.url, "--count", str(count),
             "--rate-hz", "200", "--fast-every", str(fast_every)], capture_output=True, timeout=60, check=False)
        assert probe.returncode == 0, probe.stderr.decode()[-2000:]
        sent = json.loads(probe.stdout)["sent"]
        expected = {(int(seq), int(pgn)) for seq, pgn, _ in sent}
        assert len(expected) == count + count // fast_every
        received: dict[tuple[int, int], float] = {}
        while set(received) != expected:
            m = wait_for(events, lambda e: isinstance(e, Measurement))
            pgn = PGN_GNSS_POSITION if m.message.utc_time_s is not None else PGN_POSITION_RAPID
            received[(sequence_of(m.message.lat_deg), pgn)] = m.t_s
    assert reader.decoder.counters["rejected"] == 0
    latencies = [received[(int(seq), int(pgn))] - t_send for seq, pgn, t_send in sent]
    assert all(0.0 < lat < WAIT_S for lat in latencies) and all(math.isfinite(lat) for lat in latencies)


@pytest.mark.hil
def test_reader_and_writer_reconnect_when_the_remote_server_restarts() -> None:
    events, clock = queue.Queue(), SteppedClock(0.0)
    server = start_remote_server(mode="process")
    reader = N2kCanReader(server.bus_config(), events.put)
    writer = N2kCanWriter(server.bus_config(), clock=clock, backoff_s=0.5)
    try:
        reader.start()
        assert reader.wait_connected(WAIT_S)
        writer.send(N2kEncoder(7).heading(Heading(1.0)))
        wait_for(events, lambda e: isinstance(e, Measurement))
        server.close()  # the bus goes away under both
        lost = wait_for(events, is_link(False))
        assert "bus error" in lost.detail
        server = start_remote_server(port=server.port, mode="process")
        wait_for(events, is_link(True))
        deadline = time.monotonic() + WAIT_S
        delivered = None
        while delivered is None and time.monotonic() < deadline:
            clock.advance(1.0)  # past the writer's backoff, without sleeping
            writer.send(N2kEncoder(7).heading(Heading(2.0)))
            delivered = poll(events, lambda e: isinstance(e, Measurement), timeout_s=0.2)
        assert delivered is not None and abs(delivered.message.heading_rad - 2.0) < 1e-3
        assert reader.counters["bus_errors"] >= 1 and reader.counters["reconnects"] == 1
        assert writer.counters["bus_errors"] + writer.counters["send_errors"] >= 1
    finally:
        writer.close()
        reader.close()
        server.close()


@pytest.mark.hil
def test_remote_server_process_does_not_outlive_its_parent() -> None:
    code = ("from interfaces.nmea2000.transport import start_remote_server\n"
            "server = start_remote_server(mode='process')\n"
            "print(server.pid, flush=True)\n")  # ... and exit without closing it
    parent = subprocess.run([sys.executable, "-c", code], capture_output=True, timeout=60, check=True)
    pid = int(parent.stdout)
    try:
        pidfd = os.pidfd_open(pid)
    except ProcessLookupError:
        return  # already gone
    try:
        exited, _, _ = select.select([pidfd], [], [], WAIT_S)  # a pidfd is readable once the process exits
    finally:
        os.close(pidfd)
    if not exited:
        os.kill(pid, signal.SIGKILL)
    assert exited, "the server kept running after its parent exited"


# --------------------------------------------------------------------------------------------
# a sensor known by its NAME (address claims, 60928)


def test_a_sensor_configured_by_name_follows_its_device_to_a_new_address() -> None:
    """On a python-can virtual bus through the daemon's input stage: the reader asks for the address claims
    (59904 from the null address), a compass routed by NAME is found at whatever address it claims."""
    from dpcontrol.runtime.config import parse_config  # noqa: PLC0415
    from dpcontrol.service.daemon import InputPump  # noqa: PLC0415
    from interfaces.messages import Heading as HeadingMessage  # noqa: PLC0415
    from interfaces.nmea2000.codec import make_can_id  # noqa: PLC0415

    channel = f"names-{uuid.uuid4().hex[:8]}"
    name = 0xC0320C0029E0F05A
    config = parse_config({
        "vessel_id": "names", "vessel": "cybership2",
        "transports": [{"name": "can0", "protocol": "nmea2000", "interface": "virtual", "channel": channel}],
        "sensors": [{"name": "gnss1", "kind": "position", "transport": "can0"},
                    {"name": "gyro1", "kind": "heading", "transport": "can0", "source_name": f"{name:016x}"}]})
    device = can.Bus(interface="virtual", channel=channel)
    pump = InputPump(config, clock=time.monotonic)
    pump.start()

    def send(frames: list[tuple[int, bytes]]) -> None:
        for can_id, data in frames:
            device.send(can.Message(arbitration_id=can_id, data=data, is_extended_id=True))

    def routed(deadline_s: float = 0.5) -> list[Measurement]:
        out: list[Measurement] = []
        end = time.monotonic() + deadline_s
        while time.monotonic() < end:
            pump.drain(time.monotonic(), out, [], [])
            time.sleep(0.02)
        return out

    try:
        request = device.recv(5.0)  # the reader's request for everybody's claim
        assert request is not None and request.arbitration_id == make_can_id(6, 59904, 254, 255)
        assert int.from_bytes(request.data[:3], "little") == 60928
        send(N2kEncoder(40).heading(HeadingMessage(1.0)))  # before its claim: nobody knows who 40 is
        assert routed() == []
        send([(make_can_id(6, 60928, 40, 255), name.to_bytes(8, "little"))])
        send(N2kEncoder(40).heading(HeadingMessage(1.0)) + N2kEncoder(41).heading(HeadingMessage(2.0)))
        assert [(m.source, round(m.message.heading_rad, 3)) for m in routed()] == [("gyro1", 1.0)]
        send([(make_can_id(6, 60928, 42, 255), name.to_bytes(8, "little"))])  # the compass re-claims at 42
        send(N2kEncoder(40).heading(HeadingMessage(1.5)) + N2kEncoder(42).heading(HeadingMessage(3.0)))
        assert [(m.source, round(m.message.heading_rad, 3)) for m in routed()] == [("gyro1", 3.0)]
    finally:
        pump.close()
        device.shutdown()


def test_source_name_is_checked_at_load() -> None:
    from dpcontrol.runtime.config import parse_config  # noqa: PLC0415

    base = {"vessel_id": "names", "vessel": "cybership2",
            "transports": [{"name": "can0", "protocol": "nmea2000", "interface": "virtual", "channel": "x"},
                           {"name": "serial", "protocol": "nmea0183", "port": "/dev/null"}],
            "sensors": [{"name": "gyro1", "kind": "heading", "transport": "can0", "source_name": "c0320c00"}]}
    with pytest.raises(ConfigError, match="source_name"):
        parse_config(base)
    base["sensors"][0].update(transport="serial", source_name="c0320c0029e0f05a")
    with pytest.raises(ConfigError, match="source_name"):
        parse_config(base)
