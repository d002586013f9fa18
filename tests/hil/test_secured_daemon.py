"""A secured vessel network: a real daemon (in this process, links down: standby, publishing every cycle) with
mutual TLS and zenoh's access control by role, certificates made at test time, real zenoh sessions on
127.0.0.1. The shore (``monitor``) reads the status, liveliness and configuration (the estimate: see
tests/interfaces/test_zenoh_security.py; with no sensors there is none here), but its set-point, thruster
reset and thruster command never reach the daemon; the bridge (``console``) is obeyed and named in the answer
and the black box; a foreign process cannot publish feedback; the daemon will not listen off loopback in plaintext."""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from dpbase.schema import ConfigError
from dpcontrol.cli import main
from dpcontrol.logtools import read_records
from dpcontrol.runtime.config import parse_config
from dpcontrol.service.daemon import Daemon
from interfaces.systemd import SystemdNotifier
from interfaces.zenoh import pki, schemas
from interfaces.zenoh.loopback import free_tcp_port
from interfaces.zenoh.node import LatestSlot, ZenohNode
from interfaces.zenoh.security import ZenohSecurity
from interfaces.zenoh.session_config import ZenohConfig

pytestmark = pytest.mark.hil

VESSEL = "secured"
IDENTITIES = {"dp": "controller", "dp-soon": "controller", "drives": "drives", "bridge": "console",
              "shore": "monitor"}
TIMEOUT = "30"  # generous bound for zenoh on a loaded 2-core machine; an answer takes one cycle


def _config(tmp: Path, listen: str, **zenoh: Any) -> dict[str, Any]:
    return {"vessel_id": VESSEL, "vessel": "cybership2", "loop": {"rate_hz": 10},
            "transports": [{"name": "serial0", "protocol": "nmea0183", "port": str(tmp / "no-tty")}],
            "sensors": [{"name": "gnss1", "kind": "position", "transport": "serial0"},
                        {"name": "gyro1", "kind": "heading", "transport": "serial0"}],
            "recorder": {"path": str(tmp / "blackbox")},
            "zenoh": {"listen": [listen], **zenoh}}


@pytest.fixture(scope="module")
def vessel(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[Daemon, str, Path]]:
    tmp = tmp_path_factory.mktemp("secured")
    tls = tmp / "tls"
    pki.init_ca(tls, VESSEL)
    for name, role in [*IDENTITIES.items(), ("stranger", "drives")]:  # the stranger: our CA, no role
        pki.issue(tls, role, name)
    endpoint = f"tls/127.0.0.1:{free_tcp_port()}"
    config = _config(tmp, endpoint, tls={"dir": str(tls), "identity": "dp"}, identities=IDENTITIES)
    (tmp / "vessel.yaml").write_text(json.dumps(config), encoding="utf-8")
    daemon = Daemon(parse_config(config), notifier=SystemdNotifier(environ={}))
    codes: list[int] = []
    thread = threading.Thread(target=lambda: codes.append(daemon.run(duration_s=300.0, install_signals=False)))
    thread.start()
    try:
        yield daemon, endpoint, tmp
    finally:
        daemon.request_stop()
        thread.join(30.0)
    assert not thread.is_alive() and codes == [0]


def _node(tls: Path, endpoint: str, name: str) -> ZenohNode:
    return ZenohNode(ZenohConfig(connect=(endpoint,), security=ZenohSecurity(pki.IdentityFiles.in_dir(tls, name))),
                     VESSEL)


def _ask(endpoint: str, tls: Path, identity: str, *options: str,
         capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    code = main(["setpoint", "--vessel", VESSEL, "--connect", endpoint, "--tls-dir", str(tls), "--identity", identity,
                 "--timeout", TIMEOUT, *options])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


@pytest.mark.timeout(120)
def test_the_shore_reads_but_never_commands_the_bridge_commands(vessel: tuple[Daemon, str, Path],
                                                                 capsys: pytest.CaptureFixture[str]) -> None:
    daemon, endpoint, tmp = vessel
    tls = tmp / "tls"
    shore = _node(tls, endpoint, "shore")
    stranger = _node(tls, endpoint, "stranger")
    try:
        status = shore.subscribe("status", LatestSlot())
        alive = shore.watch_alive("controller")
        assert alive.wait_for(True, 15.0)
        assert status.sink.wait_count(1, 15.0)
        assert isinstance(shore.query_config(10.0), dict)
        # the shore's request never reaches the daemon: it is not even told that anybody subscribes
        before = daemon.controller.setpoint_ned.copy()
        setpoints_heard = daemon._setpoints.stats.received
        code, _out, err = _ask(endpoint, tls, "shore", "--north", "40", "--east", "0", "--timeout", "3",
                               capsys=capsys)
        assert code == 1 and "does not subscribe" in err
        # ... nor a raw put: set-point, thruster reset, thruster command; nor the stranger's feedback
        names = [t.name for t in daemon.config.vessel.thrusters]
        for sender in (shore, stranger):
            sp = sender.publisher("setpoint")
            sp.put(schemas.setpoint_payload(t_s=1.0, seq=sp.next_seq(), north_m=40.0, east_m=0.0,
                                            mode="auto_position"))
            sp.put(schemas.setpoint_payload(t_s=1.0, seq=sp.next_seq(), reset_thruster=names[0]))
        for sender in (shore, stranger):
            cmd = sender.publisher("command")
            cmd.put(schemas.command_payload(t_s=1.0, seq=cmd.next_seq(), mode="auto_position", names=names,
                                            thrust_n=np.ones(len(names)), azimuth_rad=np.zeros(len(names))))
            fb = sender.publisher("feedback")
            fb.put(schemas.feedback_payload(t_s=1.0, seq=fb.next_seq(), names=names, thrust_n=np.ones(len(names)),
                                            azimuth_rad=np.zeros(len(names)), ready=[True] * len(names)))
        time.sleep(1.5)  # fifteen cycles: anything let through would have been taken
        np.testing.assert_array_equal(daemon.controller.setpoint_ned, before)
        assert daemon._setpoints.stats.received == setpoints_heard
        assert daemon._foreign_commands.count == 0 and daemon._feedback_slot.count == 0
        assert "controller.conflict" not in {a.code for a in daemon.alarms.active()}

        # the bridge is obeyed, and named in the answer
        code, out, err = _ask(endpoint, tls, "bridge", "--north", "5", "--east", "-3", "--json", capsys=capsys)
        assert code == 0, err
        answer = json.loads(out)
        assert (answer["outcome"], answer["role"], answer["identity"]) == ("applied", "console", "bridge")
        np.testing.assert_allclose(daemon.controller.setpoint_ned[:2], [5.0, -3.0])
        last = daemon.controller.last_request
        assert last is not None and (last.role, last.identity) == ("console", "bridge")
        # the shore sees that answer in the status it may read
        assert status.sink.wait_count(status.sink.count + 2, 10.0)
        seen = status.sink.latest().message
        assert any(r["identity"] == "bridge" for r in (seen["requests"] or [seen["request"]]))
        seq = answer["seq"]
    finally:
        shore.close()
        stranger.close()
    # and in the black box (flushed within a second)
    deadline = time.monotonic() + 10.0
    found: list[dict[str, Any]] = []
    while not found and time.monotonic() < deadline:
        time.sleep(0.5)
        found = [r for rec in read_records(tmp / "blackbox", ["cycle"]) for r in rec.payload["requests"]
                 if r["seq"] == seq]
    assert found and found[0]["role"] == "console" and found[0]["identity"] == "bridge"
    recorded = [r for rec in read_records(tmp / "blackbox", ["cycle"]) for r in rec.payload["requests"]]
    assert {(r["role"], r["identity"]) for r in recorded} == {("console", "bridge")}  # nothing from the shore


@pytest.mark.timeout(60)
def test_the_drives_feedback_is_taken(vessel: tuple[Daemon, str, Path]) -> None:
    daemon, endpoint, tmp = vessel
    drives = _node(tmp / "tls", endpoint, "drives")
    try:
        assert drives.wait_for_peers(1, 15.0)
        names = [t.name for t in daemon.config.vessel.thrusters]
        fb = drives.publisher("feedback")
        assert fb.wait_matched(15.0)
        fb.put(schemas.feedback_payload(t_s=2.0, seq=fb.next_seq(), names=names, thrust_n=np.zeros(len(names)),
                                        azimuth_rad=np.zeros(len(names)), ready=[True] * len(names)))
        assert daemon._feedback_slot.wait_count(1, 10.0)
    finally:
        drives.close()


def test_no_plaintext_off_loopback_unless_insecure(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(ConfigError, match=r"unprotected: tcp/192\.0\.2\.1:7447"):
        parse_config(_config(tmp_path, "tcp/192.0.2.1:7447"))
    with pytest.raises(ConfigError, match=r"unprotected: tcp/0\.0\.0\.0:7447"):
        parse_config(_config(tmp_path, "tcp/0.0.0.0:7447"))
    # TLS alone (no access control by role) is not enough either
    pki.init_ca(tmp_path / "tls", VESSEL)
    pki.issue(tmp_path / "tls", "controller", "dp")
    with pytest.raises(ConfigError, match=r"unprotected: tls/192\.0\.2\.1:7447"):
        parse_config(_config(tmp_path, "tls/192.0.2.1:7447", tls={"dir": str(tmp_path / "tls"), "identity": "dp"}))
    assert parse_config(_config(tmp_path, "tcp/192.0.2.1:7447", insecure=True)).zenoh.security.insecure
    # dpcontrol run says so and exits 2 before opening anything
    path = tmp_path / "plain.yaml"
    path.write_text(json.dumps(_config(tmp_path, "tcp/192.0.2.1:7447")), encoding="utf-8")
    assert main(["run", "--config", str(path), "--duration", "1"]) == 2
    assert "insecure: true" in capsys.readouterr().err


def test_check_config_verifies_the_certificates(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    tls = tmp_path / "tls"
    assert main(["pki", "init", str(tls), "--vessel", VESSEL]) == 0
    assert main(["pki", "issue", "controller", "dp", "--dir", str(tls)]) == 0
    assert main(["pki", "issue", "console", "bridge", "--dir", str(tls)]) == 0
    capsys.readouterr()
    path = tmp_path / "vessel.yaml"

    def check(**tls_section: str) -> tuple[int, str]:
        config = _config(tmp_path, "tls/192.0.2.1:7447", tls=tls_section, identities=IDENTITIES)
        path.write_text(json.dumps(config), encoding="utf-8")
        code = main(["check-config", str(path)])
        captured = capsys.readouterr()
        return code, captured.out + captured.err

    code, text = check(dir=str(tls), identity="dp")
    assert code == 0 and "mutual TLS as 'dp'" in text and "WARNING" not in text, text
    assert main(["pki", "issue", "controller", "dp-soon", "--dir", str(tls), "--days", "10"]) == 0
    code, text = check(dir=str(tls), identity="dp-soon")
    assert code == 0 and "WARNING: a certificate expires in 10 days" in text, text
    code, text = check(dir="$CREDENTIALS_DIRECTORY_UNSET_HERE", identity="dp")
    assert code == 2 and "a variable is not set" in text, text
    code, text = check(dir=str(tls), identity="nobody")
    assert code == 2 and "nobody.pem: no such file" in text
    code, text = check(ca=str(tls / "ca.pem"), cert=str(tls / "bridge.pem"), key=str(tls / "bridge.key"),
                       identity="dp")
    assert code == 2 and "common name 'bridge', expected 'dp'" in text
    code, text = check(ca=str(tls / "ca.pem"), cert=str(tls / "bridge.pem"), key=str(tls / "bridge.key"))
    assert code == 2 and "role 'console', expected 'controller'" in text
