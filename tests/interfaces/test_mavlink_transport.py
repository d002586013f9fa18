"""MAVLink over UDP on 127.0.0.1: loopback twin, two processes, heartbeat loss on an injected clock, signing."""

from __future__ import annotations

import json
import math
import queue
import subprocess
import sys
import threading
import time
from collections.abc import Callable

import pytest

from interfaces.mavlink.codec import MavlinkEncoder
from interfaces.mavlink.probe import sequence_of
from interfaces.mavlink.transport import MavlinkUdpReader, MavlinkUdpSender, RawPacket
from interfaces.messages import (
    Attitude,
    FixQuality,
    Heading,
    LinkHeartbeat,
    LinkStatus,
    Measurement,
    PositionFix,
    RateOfTurn,
    RejectedInput,
)

WAIT_S = 10.0  # upper bound for anything to arrive on a loaded machine; never a sleep
KEY = bytes.fromhex("a1" * 32)


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


def wait_for(events: queue.Queue, predicate: Callable[[object], bool], timeout_s: float = WAIT_S) -> object:
    """The first event satisfying ``predicate`` (others are consumed); the test fails after ``timeout_s``."""
    deadline = time.monotonic() + timeout_s
    while (remaining := deadline - time.monotonic()) > 0:
        try:
            event = events.get(timeout=remaining)
        except queue.Empty:
            break
        if predicate(event):
            return event
    pytest.fail(f"no matching event within {timeout_s} s")


def is_measurement(kind: type) -> Callable[[object], bool]:
    return lambda e: isinstance(e, Measurement) and isinstance(e.message, kind)


def is_link(connected: bool) -> Callable[[object], bool]:
    return lambda e: isinstance(e, LinkStatus) and e.connected is connected


def test_udp_loopback_delivers_what_the_autopilot_sends() -> None:
    events, clock = queue.Queue(), SteppedClock(7.0)
    names = {(7, 1, "GPS_RAW_INT"): "gnss1", (7, 1): "autopilot"}
    with MavlinkUdpReader(events.put, clock=clock, source_names=names, deliver_raw=True) as reader, \
            MavlinkUdpSender(reader.address, MavlinkEncoder(7, 1)) as sender:
        encoder = sender.encoder
        fix = PositionFix(59.91, 10.75, FixQuality.RTK_FLOAT, num_satellites=15, hdop=0.6, altitude_m=3.0)
        assert sender.send(encoder.heartbeat())
        assert sender.send(encoder.gps_raw_int(fix))
        assert sender.send(encoder.attitude(Attitude(0.02, -0.01, 1.2), rate=RateOfTurn(-0.03)))
        up = wait_for(events, is_link(True))
        position = wait_for(events, is_measurement(PositionFix))
        heading = wait_for(events, is_measurement(Heading))
        rate = wait_for(events, is_measurement(RateOfTurn))
    assert up.source == "autopilot" and up.t_s == 7.0 and up.detail == "first heartbeat"
    assert position.source == "gnss1" and position.t_s == 7.0 and position.message.quality == FixQuality.RTK_FLOAT
    assert abs(position.message.lat_deg - 59.91) < 1e-7
    assert heading.source == "autopilot" and abs(heading.message.heading_rad - 1.2) < 1e-6
    assert abs(rate.message.rate_radps + 0.03) < 1e-6
    assert reader.counters["datagrams"] == 3 and sender.counters["packets_sent"] == 3


def test_raw_datagrams_and_rejects_reach_the_sink() -> None:
    events = queue.Queue()
    with MavlinkUdpReader(events.put, deliver_raw=True) as reader, MavlinkUdpSender(reader.address) as sender:
        packet = sender.encoder.heartbeat()
        sender.send(packet[:-4])  # a datagram cut short
        raw = wait_for(events, lambda e: isinstance(e, RawPacket))
        reject = wait_for(events, lambda e: isinstance(e, RejectedInput))
    assert raw.data == packet[:-4] and raw.peer == sender.address
    assert reject.rejected.reason == "truncated"
    assert reader.decoder.counters["rejected.truncated"] == 1


def test_heartbeat_loss_is_detected_on_the_injected_clock_and_recovers() -> None:
    events, clock = queue.Queue(), SteppedClock(100.0)
    with MavlinkUdpReader(events.put, clock=clock, heartbeat_timeout_s=5.0) as reader, \
            MavlinkUdpSender(reader.address, MavlinkEncoder(7, 1)) as sender:
        sender.start_heartbeat(period_s=1.0)
        assert wait_for(events, is_link(True)).t_s == 100.0
        sender.stop_heartbeat()  # the sender goes silent
        received = 1
        while received < sender.counters["packets_sent"]:  # every heartbeat sent is in (stamped 100.0)
            wait_for(events, is_measurement(LinkHeartbeat))
            received += 1
        clock.advance(4.9)
        reader.check_link()
        assert reader.peer_connected(7, 1), "4.9 s of silence is not a loss"
        clock.advance(0.2)
        reader.check_link()  # the reader thread may have noticed first: the event is reported once either way
        lost = wait_for(events, is_link(False))
        assert not reader.peer_connected(7, 1)
        assert lost.source == "mav:7/1" and lost.t_s == pytest.approx(105.1) and "no heartbeat" in lost.detail
        sender.start_heartbeat(period_s=1.0)  # the sender comes back
        back = wait_for(events, is_link(True))
    assert back.detail == "heartbeat resumed" and back.t_s == pytest.approx(105.1)
    assert reader.counters["link_lost"] == 1 and reader.counters["link_up"] == 2


def test_silence_from_start_is_reported() -> None:
    events, clock = queue.Queue(), SteppedClock(0.0)
    with MavlinkUdpReader(events.put, clock=clock, heartbeat_timeout_s=5.0) as reader:
        clock.advance(5.5)
        reader.check_link()
        status = wait_for(events, is_link(False))
    assert status.source == "mavlink" and "within 5 s of start" in status.detail


def test_signing_required_rejects_an_unsigned_sender() -> None:
    events = queue.Queue()
    with MavlinkUdpReader(events.put, signing_key=KEY) as reader, \
            MavlinkUdpSender(reader.address, MavlinkEncoder(3, 1)) as unsigned, \
            MavlinkUdpSender(reader.address, MavlinkEncoder(4, 1, signing_key=KEY, unix_clock=time.time)) as signed:
        unsigned.send(unsigned.encoder.heartbeat())
        reject = wait_for(events, lambda e: isinstance(e, RejectedInput))
        signed.send(signed.encoder.heartbeat())
        up = wait_for(events, is_link(True))
    assert reject.rejected.reason == "unsigned" and up.source == "mav:4/1"
    assert not reader.peer_connected(3, 1) and reader.decoder.counters["rejected.unsigned"] == 1


@pytest.mark.hil
@pytest.mark.parametrize("signing", [False, True])
def test_two_processes_over_udp(signing: bool) -> None:
    """A sender subprocess (the probe, a boat autopilot) → UDP 127.0.0.1 → reader here."""
    events = queue.Queue()
    count = 40
    with MavlinkUdpReader(events.put, signing_key=KEY if signing else None) as reader:
        command = [sys.executable, "-m", "interfaces.mavlink.probe", "--target", f"127.0.0.1:{reader.address[1]}",
                   "--count", str(count), "--rate-hz", "200", "--system-id", "5"]
        if signing:
            command += ["--signing-key", KEY.hex()]
        probe = subprocess.run(command, capture_output=True, timeout=60, check=False)
        assert probe.returncode == 0, probe.stderr.decode()[-2000:]
        sent = json.loads(probe.stdout)["sent"]
        assert [int(seq) for seq, _ in sent] == list(range(1, count + 1))
        received: dict[int, float] = {}
        while len(received) < count:
            m = wait_for(events, is_measurement(PositionFix))
            received[sequence_of(m.message.lat_deg)] = m.t_s
        assert reader.peer_connected(5, 1)
    assert reader.decoder.counters["rejected"] == 0
    latencies = [received[int(seq)] - t_send for seq, t_send in sent]
    assert all(0.0 < lat < WAIT_S and math.isfinite(lat) for lat in latencies)


def test_close_stops_the_thread() -> None:
    reader = MavlinkUdpReader(lambda e: None).start()
    thread = reader._thread
    reader.close()
    assert thread is not None and not thread.is_alive()


