"""What ``dpcontrol run`` writes to its log (the journal under systemd) when a sensor port is missing:
the engineer installing it sees the link alarm with the port and the reason, not a silent daemon; and
alarm transitions are drained every cycle even with the recorder off (they used to pile up)."""

from __future__ import annotations

import logging
import threading
from pathlib import Path

import pytest

from dpcontrol.runtime.config import parse_config
from dpcontrol.service.daemon import Daemon
from interfaces.zenoh.loopback import free_tcp_port


def test_a_missing_serial_port_is_in_the_log_and_events_do_not_pile_up(
        tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.INFO, logger="dpcontrol.service.daemon")
    port = tmp_path / "no-tty"
    config = parse_config({
        "vessel_id": "journal", "vessel": "cybership2", "loop": {"rate_hz": 10},
        "transports": [{"name": "serial0", "protocol": "nmea0183", "port": str(port)}],
        "sensors": [{"name": "gnss1", "kind": "position", "transport": "serial0"},
                    {"name": "gyro1", "kind": "heading", "transport": "serial0"}],
        "zenoh": {"listen": [f"tcp/127.0.0.1:{free_tcp_port()}"]}})
    assert config.recorder.path is None
    daemon = Daemon(config)
    thread = threading.Thread(target=daemon.run, kwargs={"duration_s": 1.5, "install_signals": False})
    thread.start()
    thread.join(30.0)
    assert not thread.is_alive()
    lines = [(r.levelno, r.getMessage()) for r in caplog.records if r.getMessage().startswith("alarm ")]
    link = [text for level, text in lines if level == logging.WARNING and "transport.serial0.link" in text]
    assert len(link) == 1, lines
    assert link[0].startswith("alarm raised [WARNING] transport.serial0.link: serial0: link lost")
    assert str(port) in link[0] and "No such file or directory" in link[0]
    assert any("sensor.gnss1" in text for _, text in lines), lines
    assert daemon.alarms.drain_events() == []  # drained by the loop, recorder or not


def test_an_unwritable_state_file_is_an_alarm_and_one_log_line_not_one_a_second(
        tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.INFO)
    blocker = tmp_path / "a-file"
    blocker.write_text("kept\n")
    config = parse_config({
        "vessel_id": "journal", "vessel": "cybership2", "loop": {"rate_hz": 10},
        "transports": [{"name": "serial0", "protocol": "nmea0183", "port": str(tmp_path / "no-tty")}],
        "sensors": [{"name": "gnss1", "kind": "position", "transport": "serial0"},
                    {"name": "gyro1", "kind": "heading", "transport": "serial0"}],
        "state": {"path": str(blocker / "state.json"), "period_s": 0.5},
        "recorder": {"path": str(blocker / "records")},
        "zenoh": {"listen": [f"tcp/127.0.0.1:{free_tcp_port()}"]}})
    daemon = Daemon(config)
    thread = threading.Thread(target=daemon.run, kwargs={"duration_s": 3.0, "install_signals": False})
    thread.start()
    thread.join(30.0)
    assert not thread.is_alive()
    assert daemon.saver is not None and daemon.saver.failed >= 4  # tried every 0.5 s, failed every time
    messages = [r.getMessage() for r in caplog.records]
    saver_lines = [r.getMessage() for r in caplog.records if r.name == "dpcontrol.service.persist"]
    assert saver_lines == [f"cannot write state file {blocker / 'state.json'}: {blocker} is a file, not a folder"]
    state_alarm = [m for m in messages if m.startswith("alarm raised [WARNING] state.save_failed: ")]
    assert len(state_alarm) == 1 and str(blocker / "state.json") in state_alarm[0], messages
    recorder_alarm = [m for m in messages if m.startswith("alarm raised [WARNING] recorder.error: ")]
    assert len(recorder_alarm) == 1, messages
    assert "RecorderError(" not in recorder_alarm[0] and str(blocker) in recorder_alarm[0]  # the message, not a repr
    assert blocker.read_text() == "kept\n"
