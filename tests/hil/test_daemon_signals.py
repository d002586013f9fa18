"""``dpcontrol run`` started by hand and its terminal closed: SIGHUP stops it as SIGTERM does — zero
thrust commanded, standby, STOPPING=1, exit 0 — instead of its default action, which ended the process
at once with the thrusters still on their last command. The last command is read over a real Zenoh
session on 127.0.0.1."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml

from interfaces.zenoh.loopback import free_tcp_port
from interfaces.zenoh.node import ZenohNode
from interfaces.zenoh.session_config import ZenohConfig

pytestmark = [pytest.mark.hil, pytest.mark.skipif(os.name != "posix", reason="signals")]


def _receive(sock: socket.socket, wanted: bytes, timeout_s: float) -> list[bytes]:
    got: list[bytes] = []
    deadline = time.monotonic() + timeout_s
    sock.settimeout(0.2)
    while time.monotonic() < deadline:
        try:
            got.append(sock.recv(4096))
        except TimeoutError:
            continue
        if wanted in got[-1]:
            return got
    pytest.fail(f"no {wanted!r} notification in {timeout_s} s; got {got!r}")


@pytest.mark.parametrize("stop_signal", [signal.SIGHUP, signal.SIGTERM], ids=["SIGHUP", "SIGTERM"])
def test_a_hangup_stops_the_daemon_in_order(tmp_path: Path, stop_signal: signal.Signals) -> None:
    port = free_tcp_port()
    config = tmp_path / "vessel.yaml"
    config.write_text(yaml.safe_dump({
        "vessel_id": "hangup", "vessel": "cybership2", "loop": {"rate_hz": 10},
        "transports": [{"name": "serial0", "protocol": "nmea0183", "port": str(tmp_path / "no-tty")}],
        "sensors": [{"name": "gnss1", "kind": "position", "transport": "serial0"},
                    {"name": "gyro1", "kind": "heading", "transport": "serial0"}],
        "zenoh": {"listen": [f"tcp/127.0.0.1:{port}"]}}), encoding="utf-8")
    notify = tmp_path / "notify.sock"
    with socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM) as sock:
        sock.bind(str(notify))
        env = {**os.environ, "NOTIFY_SOCKET": str(notify)}
        env.pop("WATCHDOG_USEC", None)
        env.pop("JOURNAL_STREAM", None)
        process = subprocess.Popen([sys.executable, "-m", "dpcontrol.cli", "run", "--config", str(config)],
                                   env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        node = None
        try:
            _receive(sock, b"READY=1", 120.0)
            node = ZenohNode(ZenohConfig(connect=(f"tcp/127.0.0.1:{port}",)), "hangup")
            commands = node.subscribe("command")
            assert commands.sink.wait_count(5, 20.0), "the test's session heard no commands"
            process.send_signal(stop_signal)
            _, stderr = process.communicate(timeout=30.0)
            stopping = _receive(sock, b"STOPPING=1", 5.0)
        finally:
            if process.poll() is None:
                process.kill()
                process.communicate(timeout=30.0)
            if node is not None:
                node.close()
    log = stderr.decode(errors="replace")
    assert process.returncode == 0, log
    assert any(b"STOPPING=1" in message for message in stopping)
    assert f"stopping ({stop_signal.name}): zero thrust commanded, mode standby" in log, log
    last = commands.sink.latest()
    assert last is not None and last.message.mode == "standby"
    assert [setpoint.thrust_n for setpoint in last.message.thrusters] == [0.0] * len(last.message.thrusters)
