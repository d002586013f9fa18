"""The daemon's transport registry (``dpcontrol.service.transports``): the reader each configured protocol gets,
and what it hands the daemon — the bytes as received and the link changes, undecoded — over real parts: pyserial
on a pseudo-terminal, a python-can virtual bus, a UDP socket on 127.0.0.1."""

from __future__ import annotations

import queue
import time
import uuid

import can
import pytest

from dpcontrol.runtime.config import parse_config
from dpcontrol.service.transports import READERS, RawInput, ReaderOptions, open_reader
from interfaces.mavlink.codec import MavlinkEncoder
from interfaces.mavlink.transport import MavlinkUdpSender
from interfaces.messages import FixQuality, Heading, LinkStatus, PositionFix
from interfaces.nmea0183 import encode_hdt
from interfaces.nmea0183.transport import PtyPair
from interfaces.nmea2000.codec import N2kEncoder
from interfaces.zenoh.loopback import free_udp_port

FIX = PositionFix(63.4, 10.4, FixQuality.RTK_FIXED, num_satellites=12, hdop=0.7, altitude_m=2.0)


def _transport(spec: dict) -> object:
    config = parse_config({"vessel_id": "transports", "vessel": "supply", "transports": [spec],
                           "sensors": [{"name": name, "kind": kind, "transport": spec["name"],
                                        **({"system_id": 1} if spec["protocol"] == "mavlink" else {}),
                                        **({"source_address": address} if spec["protocol"] == "nmea2000" else {})}
                                       for name, kind, address in (("gnss1", "position", 40),
                                                                   ("gyro1", "heading", 41))]})
    return config.transports[0]


def _events(events: queue.Queue, until: object, timeout_s: float = 5.0) -> list[object]:
    """Events until one satisfies ``until`` (a predicate), or the timeout."""
    out: list[object] = []
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        try:
            event = events.get(timeout=0.05)
        except queue.Empty:
            continue
        out.append(event)
        if until(event):
            break
    return out


def test_every_protocol_of_the_configuration_has_a_reader() -> None:
    from dpcontrol.runtime.config import PROTOCOLS  # noqa: PLC0415

    assert set(READERS) == set(PROTOCOLS)


def test_a_serial_reader_hands_over_the_bytes_as_read_and_its_link() -> None:
    events: queue.Queue = queue.Queue()
    with PtyPair() as pty:
        reader = open_reader(_transport({"name": "serial0", "protocol": "nmea0183", "port": pty.device_path}),
                             events.put, ReaderOptions(time.monotonic))
        reader.start()
        try:
            opened = _events(events, lambda e: isinstance(e, LinkStatus))
            assert isinstance(opened[-1], LinkStatus) and opened[-1].connected
            sentence = encode_hdt(Heading(0.5), "HE")
            pty.write(sentence[:10])
            time.sleep(0.1)
            pty.write(sentence[10:])
            received = b""
            for event in _events(events, lambda _e: False, timeout_s=0.5):
                assert isinstance(event, RawInput) and event.can_id is None
                received += event.data
            assert received == sentence  # undecoded, in whatever chunks the port gave
        finally:
            reader.close()


def test_a_can_reader_hands_over_each_frame_with_its_identifier() -> None:
    channel = f"test-{uuid.uuid4().hex}"
    events: queue.Queue = queue.Queue()
    reader = open_reader(_transport({"name": "can0", "protocol": "nmea2000", "interface": "virtual",
                                     "channel": channel}), events.put, ReaderOptions(time.monotonic))
    reader.start()
    try:
        assert any(isinstance(e, LinkStatus) and e.connected for e in _events(events, lambda e: True))
        frames = N2kEncoder(41).gnss_position(FIX, date_days=20000)  # a fast packet: several frames
        with can.Bus(interface="virtual", channel=channel) as bus:
            for can_id, data in frames:
                bus.send(can.Message(arbitration_id=can_id, data=data, is_extended_id=True))
            got = _events(events, lambda _e: False, timeout_s=0.5)
        assert [(e.can_id, e.data) for e in got if isinstance(e, RawInput)] == [(i, d) for i, d in frames]
    finally:
        reader.close()


def test_a_mavlink_reader_hands_over_each_datagram() -> None:
    port = free_udp_port()
    events: queue.Queue = queue.Queue()
    reader = open_reader(_transport({"name": "mav0", "protocol": "mavlink", "url": f"udpin:127.0.0.1:{port}"}),
                         events.put, ReaderOptions(time.monotonic))
    reader.start()
    try:
        with MavlinkUdpSender(("127.0.0.1", port), MavlinkEncoder(1, 1)) as sender:
            packets = [sender.encoder.heartbeat(), sender.encoder.gps_raw_int(FIX)]
            for packet in packets:
                sender.send(packet)
            got = _events(events, lambda e: isinstance(e, RawInput) and e.data == packets[-1])
        assert [e.data for e in got if isinstance(e, RawInput)] == packets
    finally:
        reader.close()


@pytest.mark.parametrize("url", ["udpout:127.0.0.1:14550", "tcp:127.0.0.1:5760", "udpin:127.0.0.1:70000"])
def test_a_mavlink_url_the_reader_cannot_listen_on_is_refused_by_the_configuration(url: str) -> None:
    from dpbase.schema import ConfigError  # noqa: PLC0415

    with pytest.raises(ConfigError, match="url"):
        _transport({"name": "mav0", "protocol": "mavlink", "url": url})


def test_an_in_process_transport_has_no_reader() -> None:
    from dpcontrol.runtime.config import in_process_transport  # noqa: PLC0415

    with pytest.raises(ValueError, match="in-process transport has no device"):
        open_reader(in_process_transport("lockstep_mavlink", "mavlink"), lambda _event: None,
                    ReaderOptions(time.monotonic))
