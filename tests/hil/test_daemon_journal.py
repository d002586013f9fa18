"""What ``dpcontrol run`` writes to its log (the journal under systemd) when a sensor port is missing:
the engineer installing it sees the link alarm with the port and the reason, not a silent daemon; and
alarm transitions are drained every cycle even with the recorder off (they used to pile up)."""

from __future__ import annotations

import logging
import threading
from pathlib import Path

import pytest

from dpcontrol.runtime.config import parse_config
from dpcontrol.runtime.daemon import Daemon
from interfaces.zenoh.loopback import free_tcp_port


def test_a_missing_serial_port_is_in_the_log_and_events_do_not_pile_up(
        tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.INFO, logger="dpcontrol.runtime.daemon")
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
