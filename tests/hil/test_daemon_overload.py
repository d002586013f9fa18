"""A daemon whose inputs arrive faster than its loop takes them, or whose step keeps failing: the
memory held for the loop stays bounded (with an alarm), and the log says what fails without a
traceback ten times a second."""

from __future__ import annotations

import logging
import threading
import time

import pytest

from dpcontrol.runtime.config import parse_config
from dpcontrol.service import daemon as daemon_module
from dpcontrol.service.daemon import Daemon, InputPump, StepErrorLog
from dpcontrol.service.transports import RawInput
from interfaces.mavlink.codec import MavlinkEncoder
from interfaces.mavlink.transport import MavlinkUdpSender
from interfaces.messages import FixQuality, Heading, LinkStatus, Measurement, PositionFix
from interfaces.nmea0183 import encode_hdt
from interfaces.zenoh.loopback import free_tcp_port, free_udp_port

SERIAL = {"vessel_id": "overload", "vessel": "cybership2",
          "transports": [{"name": "serial0", "protocol": "nmea0183", "port": "/dev/null"}],
          "sensors": [{"name": "gnss1", "kind": "position", "transport": "serial0"},
                      {"name": "gyro1", "kind": "heading", "transport": "serial0"}]}


def test_the_input_queue_drops_beyond_its_bound_but_keeps_link_changes() -> None:
    pump = InputPump(parse_config(SERIAL), clock=lambda: 0.0, max_pending=10)
    line = encode_hdt(Heading(0.5), "HE")
    for k in range(20):  # one read per line, as the serial reader hands them: 20 raw inputs for 10 places
        pump.received("serial0", RawInput(0.1 * k, line))
    pump.received("serial0", LinkStatus(2.0, "serial0", False, "gone"))  # as the reader's on_link does
    measurements: list[Measurement] = []
    links: list[LinkStatus] = []
    sources: list[int] = []
    pump.drain(2.0, measurements, links, sources)
    assert pump.dropped == 10
    assert len(measurements) == 10 and [m.t_s for m in measurements] == pytest.approx([0.1 * k for k in range(10)])
    assert sources == list(range(1, 11))  # each measurement names the raw input it came from
    assert [link.connected for link in links] == [False]
    pump.received("serial0", RawInput(3.0, line))  # room again after the drain
    pump.drain(3.0, measurements, links, sources)
    assert pump.dropped == 10 and measurements[-1].t_s == 3.0 and sources[-1] == 11


def test_a_decoder_that_raises_loses_one_input_not_the_cycle(caplog: pytest.LogCaptureFixture) -> None:
    """What a sensor sends never stops the control step (a raising step commands zero thrust): the input whose
    decoding raised is counted as rejected, the others of the same drain are decoded."""
    pump = InputPump(parse_config(SERIAL), clock=lambda: 0.0)
    line = encode_hdt(Heading(0.5), "HE")
    stage = pump.stages["serial0"]
    real_feed = stage.feed
    calls = 0

    def feed_that_raises_once(*args: object, **kwargs: object) -> None:
        nonlocal calls
        calls += 1
        if calls == 2:
            raise RuntimeError("a decoder bug")
        real_feed(*args, **kwargs)  # type: ignore[arg-type]

    stage.feed = feed_that_raises_once  # type: ignore[method-assign]
    for k in range(3):
        pump.received("serial0", RawInput(0.1 * k, line))
    measurements: list[Measurement] = []
    with caplog.at_level(logging.ERROR, logger="dpcontrol.service.daemon"):
        pump.drain(0.3, measurements, [], [])
    assert [m.t_s for m in measurements] == pytest.approx([0.0, 0.2])
    assert pump.decode_errors == 1 and pump.health.counters()["serial0"]["reason.decode_error"] == 1
    assert any("decoding raised" in r.getMessage() for r in caplog.records)


def test_a_udp_flood_beyond_the_bound_raises_inputs_overflow_and_control_goes_on(
        monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture) -> None:
    """Real pymavlink datagrams on 127.0.0.1, 600 at once against a bound of 50 (the real bound,
    50 000, is the same code with more memory)."""
    caplog.set_level(logging.WARNING, logger="dpcontrol.service.daemon")
    monkeypatch.setattr(daemon_module, "MAX_PENDING_INPUTS", 50)
    port = free_udp_port()
    config = parse_config({
        "vessel_id": "overload", "vessel": "cybership2", "loop": {"rate_hz": 10},
        "transports": [{"name": "autopilot", "protocol": "mavlink", "url": f"udpin:127.0.0.1:{port}"}],
        "sensors": [{"name": "gnss1", "kind": "position", "transport": "autopilot", "system_id": 7},
                    {"name": "gyro1", "kind": "heading", "transport": "autopilot", "system_id": 7}],
        "zenoh": {"listen": [f"tcp/127.0.0.1:{free_tcp_port()}"]}})
    daemon = Daemon(config)
    thread = threading.Thread(target=daemon.run, kwargs={"duration_s": 2.5, "install_signals": False})
    thread.start()
    try:
        time.sleep(0.8)
        with MavlinkUdpSender(("127.0.0.1", port), MavlinkEncoder(7, 1)) as sender:
            fix = PositionFix(63.4, 10.4, FixQuality.RTK_FIXED, num_satellites=12, hdop=0.7, altitude_m=2.0)
            sender.send(sender.encoder.heartbeat())
            packet = sender.encoder.gps_raw_int(fix)
            sent = sum(sender.send(packet) for _ in range(600))
    finally:
        thread.join(30.0)
    assert not thread.is_alive()
    assert sent == 600
    assert daemon.pump is not None and daemon.pump.max_pending == 50
    assert daemon.pump.dropped > 0  # the reader outpaced a 10 Hz drain of 50 places
    raised = [r.getMessage() for r in caplog.records if "inputs.overflow" in r.getMessage()]
    assert len(raised) == 1 and raised[0].startswith("alarm raised [WARNING] inputs.overflow: "), raised
    assert "waiting for the control loop" in raised[0]
    assert daemon.stats.step_errors == 0 and daemon.stats.count >= 20  # the loop ran on


def test_a_step_that_keeps_failing_logs_one_traceback_then_a_summary(caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.INFO, logger="dpcontrol.service.daemon")
    errors = StepErrorLog(repeat_s=10.0)
    for k in range(250):  # 25 s at 10 Hz, the same error every cycle
        errors.failed(0.1 * k, RuntimeError("the same fault"), k + 1)
    errors.failed(25.0, ValueError("another fault"), 251)
    errors.recovered(251)
    errors.failed(30.0, ValueError("another fault"), 1)  # a new run of failures: its traceback again
    records = [(r.getMessage(), r.exc_info is not None) for r in caplog.records]
    assert records == [
        ("control step failed (1 in a row)", True),
        ("control step still failing (101 in a row, 100 since the last report): RuntimeError: the same fault", False),
        ("control step still failing (201 in a row, 100 since the last report): RuntimeError: the same fault", False),
        ("control step failed (251 in a row)", True),
        ("control step recovered after 251 failed cycles (last error: ValueError: another fault)", False),
        ("control step failed (1 in a row)", True)]
