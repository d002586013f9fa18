"""One controller per vessel. A second ``dpcontrol run`` for a vessel whose controller is alive on the
Zenoh network refuses to start (exit 1, one line naming the vessel and the token); thruster commands for
the vessel from any other process raise the critical ``controller.conflict`` alarm on the running
controller's status, cleared 10 s after the last. Real Zenoh sessions on 127.0.0.1."""

from __future__ import annotations

import subprocess
import sys
import threading
from pathlib import Path
from typing import Any

import pytest
import yaml
from status_sink import StatusSink

from dpcontrol.runtime.config import parse_config
from dpcontrol.service.daemon import Daemon
from interfaces.systemd import SystemdNotifier
from interfaces.zenoh.loopback import free_tcp_port
from interfaces.zenoh.node import ZenohNode
from interfaces.zenoh.session_config import ZenohConfig

pytestmark = pytest.mark.hil

WAIT_S = 30.0  # generous bound for zenoh on a loaded 2-core machine
VESSEL = "conflict"


def _config(tmp_path: Path, zenoh: dict[str, Any]) -> dict[str, Any]:
    # (the serial port does not exist: links down, the controller runs in standby and publishes every cycle)
    return {"vessel_id": VESSEL, "vessel": "cybership2", "loop": {"rate_hz": 10},
            "transports": [{"name": "serial0", "protocol": "nmea0183", "port": str(tmp_path / "no-tty")}],
            "sensors": [{"name": "gnss1", "kind": "position", "transport": "serial0"},
                        {"name": "gyro1", "kind": "heading", "transport": "serial0"}],
            "zenoh": zenoh}


def _conflict(status: dict[str, Any]) -> dict[str, Any] | None:
    return next((a for a in status["alarms"] if a["code"] == "controller.conflict" and a["active"]), None)


def test_a_second_controller_refuses_to_start_and_foreign_commands_raise_the_conflict_alarm(tmp_path: Path) -> None:
    port = free_tcp_port()
    first = Daemon(parse_config(_config(tmp_path, {"listen": [f"tcp/127.0.0.1:{port}"]})),
                   notifier=SystemdNotifier(environ={}))
    codes: list[int] = []
    thread = threading.Thread(target=lambda: codes.append(first.run(duration_s=120.0, install_signals=False)))
    thread.start()
    operator = None
    try:
        operator = ZenohNode(ZenohConfig(connect=(f"tcp/127.0.0.1:{port}",)), VESSEL)
        statuses = StatusSink()
        operator.subscribe("status", statuses)
        assert statuses.wait_for(lambda status: True, WAIT_S) is not None  # the first controller is up

        # a second controller for the same vessel, joining the first one's network: refused
        second_config = tmp_path / "second.yaml"
        second_config.write_text(yaml.safe_dump(_config(tmp_path, {"connect": [f"tcp/127.0.0.1:{port}"]})),
                                 encoding="utf-8")
        second = subprocess.run([sys.executable, "-m", "dpcontrol.cli", "run", "--config", str(second_config)],
                                check=False, capture_output=True, text=True, timeout=120.0)
        assert second.returncode == 1, second.stderr
        assert (f"another controller is alive for vessel '{VESSEL}' (dp/{VESSEL}/alive/controller)"
                in second.stderr), second.stderr
        latest = statuses.latest()
        assert latest is not None and _conflict(latest) is None  # (the refused one never commanded)

        # commands for the vessel's thrusters from another process (a controller that joined later)
        intruder = operator.publisher("command")
        assert intruder.wait_matched(WAIT_S)
        for _ in range(3):
            assert intruder.put(b'{"schema": "dpcontrol.command/1"}')
        status = statuses.wait_for(_conflict, WAIT_S)
        assert status is not None, "no controller.conflict alarm on the status"
        alarm = _conflict(status)
        assert alarm is not None and alarm["severity"] == "critical"
        assert f"another process publishes thruster commands for '{VESSEL}'" in alarm["text"]
        assert first._foreign_commands.count == 3  # its own commands (10 a second) are not counted
    finally:
        first.request_stop()
        thread.join(30.0)
        if operator is not None:
            operator.close()
    assert not thread.is_alive() and codes == [0]
