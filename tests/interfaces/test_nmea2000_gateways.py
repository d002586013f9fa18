"""NMEA 2000 through gateways, on real sockets (127.0.0.1) and a real pseudo-terminal.

Yacht Devices RAW over TCP and UDP against :class:`YdwgRawServer`, Actisense NGT-1 over a pty against
:class:`Ngt1Writer`: the emulator's frames arrive as the measurements they encode (a 129029 fast packet
reassembled, by the reader for YD RAW, by the twin gateway for the NGT-1), damaged input is rejected with
a reason and the reader goes on, a lost connection is reported and recovered.
"""

from __future__ import annotations

import math
import queue
import socket
import time

import pytest
from nmea2000 import _canboat as canboat

from interfaces.messages import FixQuality, Heading, LinkStatus, Measurement, PositionFix, RateOfTurn, RejectedInput
from interfaces.nmea0183.transport import PtyPair
from interfaces.nmea2000.codec import N2kEncoder
from interfaces.nmea2000.gateways import (
    GatewayConfig,
    N2kGatewayReader,
    Ngt1Writer,
    YdwgRawServer,
    ngt1_packet,
    ydwg_raw_line,
)
from interfaces.nmea2000.transport import RawFrame

WAIT_S = 5.0
FIX = PositionFix(59.9127, 10.7461, FixQuality.RTK_FIXED, utc_time_s=43200.5, num_satellites=14, hdop=0.6,
                  altitude_m=3.2)


def traffic() -> list[tuple[int, bytes]]:
    encoder = N2kEncoder(35)
    return encoder.gnss_position(FIX) + encoder.heading(Heading(1.25)) + encoder.rate_of_turn(RateOfTurn(-0.02))


def collect(events: queue.Queue, count: int, kinds: tuple[type, ...] = (Measurement,)) -> list:
    out, deadline = [], time.monotonic() + WAIT_S
    while len(out) < count and time.monotonic() < deadline:
        try:
            event = events.get(timeout=0.1)
        except queue.Empty:
            continue
        if isinstance(event, kinds):
            out.append(event)
    return out


def check_measurements(measurements: list[Measurement]) -> None:
    by_type = {type(m.message): m for m in measurements}
    fix = by_type[PositionFix].message
    assert abs(fix.lat_deg - FIX.lat_deg) < 1e-9 and abs(fix.lon_deg - FIX.lon_deg) < 1e-9
    assert fix.quality == FixQuality.RTK_FIXED and fix.num_satellites == 14
    assert abs(by_type[Heading].message.heading_rad - 1.25) <= 1e-4
    assert abs(by_type[RateOfTurn].message.rate_radps + 0.02) <= 1e-6
    assert {m.source for m in measurements} == {"n2k:35"}


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def test_ydwg_raw_over_tcp_decodes_reports_damage_and_reconnects() -> None:
    events: queue.Queue = queue.Queue()
    with YdwgRawServer("tcp") as gateway, N2kGatewayReader(
            GatewayConfig("ydwg_tcp", f"127.0.0.1:{gateway.port}"), events.put, deliver_raw=True) as reader:
        assert reader.wait_connected(WAIT_S)
        deadline = time.monotonic() + WAIT_S
        while gateway.clients < 1 and time.monotonic() < deadline:
            time.sleep(0.01)
        gateway.send(traffic())
        check_measurements(collect(events, 3))
        gateway.send_bytes(b"00:00:01.000 R ZZZZ 00\r\n" + b"\xff" * 300 + b"\r\n")
        rejects = collect(events, 2, (RejectedInput,))
        assert [r.rejected.reason for r in rejects] == ["garbage", "garbage"]
        gateway.disconnect_clients()  # the gateway reboots: reported, and the reader connects again
        lost = collect(events, 1, (LinkStatus,))
        assert lost and not lost[0].connected
        deadline = time.monotonic() + WAIT_S
        while gateway.clients < 1 and time.monotonic() < deadline:
            time.sleep(0.01)
        gateway.send(traffic())
        assert len(collect(events, 3)) == 3
        assert reader.counters["reconnects"] == 1 and reader.counters["rejected.garbage"] == 2


def test_ydwg_raw_over_udp() -> None:
    events: queue.Queue = queue.Queue()
    port = free_udp_port()
    with N2kGatewayReader(GatewayConfig("ydwg_udp", f"127.0.0.1:{port}"), events.put) as reader, \
            YdwgRawServer("udp", port=port) as gateway:
        assert reader.wait_connected(WAIT_S)
        gateway.send(traffic())
        check_measurements(collect(events, 3))


def test_actisense_ngt1_over_a_serial_port() -> None:
    events: queue.Queue = queue.Queue()
    with PtyPair() as pty, N2kGatewayReader(GatewayConfig("ngt1_serial", pty.device_path), events.put,
                                            deliver_raw=True) as reader:
        assert reader.wait_connected(WAIT_S)
        gateway = Ngt1Writer(pty.write)
        assert gateway.send(traffic()) == 3  # the fast packet reassembled by the gateway: 3 messages
        received = collect(events, 6, (Measurement, RawFrame))
        assert [len(e.data) for e in received if isinstance(e, RawFrame)] == [43, 8, 8]  # 129029 whole
        check_measurements([e for e in received if isinstance(e, Measurement)])
        damaged = bytearray(ngt1_packet(2, 127250, 35, 255, bytes.fromhex("ff103bff7fcef5fc")))
        damaged[-3] ^= 0x55  # the checksum no longer adds up
        pty.write(bytes(damaged))
        (reject,) = collect(events, 1, (RejectedInput,))
        assert reject.rejected.reason == "bad_gateway_packet"
        gateway.send(N2kEncoder(35).heading(Heading(2.0)))
        (heading,) = collect(events, 1)
        assert math.isclose(heading.message.heading_rad, 2.0, abs_tol=1e-4)


def test_raw_frames_and_lines_round_trip() -> None:
    can_id = canboat.can_id_compose(2, 127250, 35, 255)
    line = ydwg_raw_line(can_id, bytes(range(8)), 3661.5)
    assert line == b"01:01:01.500 R 09F11223 00 01 02 03 04 05 06 07\r\n"
    assert canboat.parse_line("ydwg02", line.decode().strip()) == (2, 127250, 35, 255, bytes(range(8)))


def test_a_bad_gateway_channel_is_a_configuration_error() -> None:
    with pytest.raises(ValueError, match="HOST:PORT"):
        GatewayConfig("ydwg_tcp", "gateway.local")
    with pytest.raises(ValueError, match="ngt1_serial"):
        GatewayConfig("seatalk", "/dev/ttyUSB0")


def test_the_daemon_reads_a_gateway_configured_like_a_can_bus() -> None:
    """The daemon's input stage with ``interface: ydwg_tcp``: routed measurements from the twin gateway, and a
    magnetic compass turned true with the transport's configured ``variation_deg`` (no 127258 on this bus)."""
    from dpbase.schema import ConfigError  # noqa: PLC0415
    from dpcontrol.runtime.config import parse_config  # noqa: PLC0415
    from dpcontrol.service.daemon import InputPump  # noqa: PLC0415

    with YdwgRawServer("tcp") as gateway:
        config = {"vessel_id": "gw", "vessel": "cybership2",
                  "transports": [{"name": "ydwg", "protocol": "nmea2000", "interface": "ydwg_tcp",
                                  "channel": f"127.0.0.1:{gateway.port}", "variation_deg": -15.0}],
                  "sensors": [{"name": "gnss1", "kind": "position", "transport": "ydwg", "source_address": 35},
                              {"name": "gyro1", "kind": "heading", "transport": "ydwg", "source_address": 36}]}
        pump = InputPump(parse_config(config), clock=time.monotonic)
        pump.start()
        try:
            deadline = time.monotonic() + WAIT_S
            while gateway.clients < 1 and time.monotonic() < deadline:
                time.sleep(0.01)
            gateway.send(N2kEncoder(35).gnss_position(FIX) + N2kEncoder(36).vessel_heading(1.0, reference="magnetic"))
            measurements: list[Measurement] = []
            while len(measurements) < 2 and time.monotonic() < deadline:
                pump.drain(time.monotonic(), measurements, [], [])
                time.sleep(0.02)
        finally:
            pump.close()
        by_sensor = {m.source: m.message for m in measurements}
        assert by_sensor["gnss1"].lat_deg == pytest.approx(FIX.lat_deg, abs=1e-9)
        assert by_sensor["gyro1"].heading_rad == pytest.approx(1.0 - math.radians(15.0), abs=1e-4)
        config["transports"][0]["channel"] = "no-port"
        with pytest.raises(ConfigError, match="channel"):
            parse_config(config)


@pytest.mark.parametrize("kind", ["ydwg_tcp", "ydwg_udp", "ngt1_serial"])
def test_the_emulators_gateway_twin_feeds_the_daemons_reader(kind: str, tmp_path) -> None:
    """GatewayTwin (what sim-plant's NMEA 2000 link uses for a gateway interface) against the reader."""
    from interfaces.nmea2000.gateways import GatewayTwin  # noqa: PLC0415
    from sim_plant.hil_config import parse_controller_wiring  # noqa: PLC0415

    channel = str(tmp_path / "ttyNGT1") if kind == "ngt1_serial" else f"127.0.0.1:{free_udp_port()}"
    if kind == "ydwg_tcp":
        with socket.create_server(("127.0.0.1", 0)) as probe:
            channel = f"127.0.0.1:{probe.getsockname()[1]}"
    wiring = parse_controller_wiring({
        "vessel_id": "gw",
        "transports": [{"name": "n2k", "protocol": "nmea2000", "interface": kind, "channel": channel}],
        "sensors": [{"name": "gnss1", "kind": "position", "transport": "n2k"}]})
    assert wiring.transports["n2k"].interface == kind
    gateway = GatewayConfig(kind, channel)
    events: queue.Queue = queue.Queue()
    twin = GatewayTwin(gateway).open()
    try:
        with N2kGatewayReader(gateway, events.put) as reader:
            assert reader.wait_connected(WAIT_S)
            deadline = time.monotonic() + WAIT_S
            while kind == "ydwg_tcp" and twin._server.clients < 1 and time.monotonic() < deadline:
                time.sleep(0.01)  # the reader's connection is accepted by the twin's thread
            assert twin.send(traffic()) == 9
            check_measurements(collect(events, 3))
    finally:
        twin.close()
