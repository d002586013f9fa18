"""Roles on the vessel's zenoh network, enforced by zenoh itself (mutual TLS + access control), checked with
real sessions on 127.0.0.1 and certificates made at test time."""

from __future__ import annotations

import datetime as dt
import time
from pathlib import Path

import pytest

from dpbase.schema import ConfigError
from interfaces.zenoh import pki
from interfaces.zenoh.loopback import free_tcp_port
from interfaces.zenoh.node import Inbox, LatestSlot, ZenohNode
from interfaces.zenoh.schemas import command_payload, feedback_payload, setpoint_payload
from interfaces.zenoh.security import (
    ZenohSecurity,
    access_control,
    is_loopback,
    unprotected_endpoints,
)
from interfaces.zenoh.session_config import ZenohConfig

VESSEL = "sec1"
IDENTITIES = {"dp": "controller", "drives": "drives", "bridge": "console", "shore": "monitor",
              "hil": ("drives", "console")}  # (the HIL emulator stands for the drives and the operator)
# long enough for a TLS handshake and the declarations on a loaded 2-core host, short enough to keep the test brief
SETTLE_S = 1.0


@pytest.fixture(scope="module")
def vessel_pki(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("pki")
    pki.init_ca(d, VESSEL)
    for name, role in IDENTITIES.items():
        pki.issue(d, role if isinstance(role, str) else "+".join(role), name)
    pki.issue(d, "console", "stranger")  # signed by the vessel CA, but mapped to no role
    other = d / "other"
    pki.init_ca(other, "elsewhere")
    pki.issue(other, "console", "bridge")  # the right name from the wrong CA
    pki.issue(d, "console", "bridge-old", not_before=dt.datetime.now(dt.timezone.utc) - dt.timedelta(days=30),
              days=1)
    return d


def _security(d: Path, name: str, identities: dict[str, str] | None = None) -> ZenohSecurity:
    return ZenohSecurity(pki.IdentityFiles.in_dir(d, name), identities or {}, name)


def _daemon(d: Path) -> tuple[ZenohNode, str]:
    for _ in range(5):
        endpoint = f"tls/127.0.0.1:{free_tcp_port()}"
        try:
            config = ZenohConfig(listen=(endpoint,), security=_security(d, "dp", IDENTITIES))
            return ZenohNode(config, VESSEL), endpoint
        except Exception:
            continue
    raise RuntimeError("no free port")


def _client(d: Path, endpoint: str, name: str, *, files: pki.IdentityFiles | None = None) -> ZenohNode:
    security = ZenohSecurity(files or pki.IdentityFiles.in_dir(d, name), {}, name)
    return ZenohNode(ZenohConfig(connect=(endpoint,), security=security), VESSEL)


def test_acl_is_zenoh_access_control_with_default_deny() -> None:
    acl = access_control(VESSEL, IDENTITIES)
    assert acl["enabled"] and acl["default_permission"] == "deny"
    subjects = {s["id"]: s["cert_common_names"] for s in acl["subjects"]}
    assert subjects["console-identities"] == ["bridge", "hil"] and subjects["monitor-identities"] == ["shore"]
    monitor_puts = [r for r in acl["rules"] if r["id"].startswith("monitor-") and "put" in r["messages"]
                    and r["flows"] == ["ingress"]]
    assert monitor_puts == []  # the shore may put nothing
    console_in = next(r for r in acl["rules"] if r["id"] == "console-publish-in")
    assert console_in["key_exprs"] == [f"dp/{VESSEL}/setpoint"]


def test_loopback_and_unprotected_endpoints(vessel_pki: Path) -> None:
    assert is_loopback("tcp/127.0.0.1:7447") and is_loopback("tcp/[::1]:7447") and is_loopback("tcp/localhost:1")
    assert not is_loopback("tcp/192.168.10.2:7447") and not is_loopback("tcp/0.0.0.0:7447")
    secured = _security(vessel_pki, "dp", IDENTITIES)
    assert unprotected_endpoints(("tcp/192.168.10.2:7447",), (), None) == ["tcp/192.168.10.2:7447"]
    assert unprotected_endpoints(("tcp/192.168.10.2:7447",), (), secured) == ["tcp/192.168.10.2:7447"]
    assert unprotected_endpoints(("tls/192.168.10.2:7447", "tcp/127.0.0.1:7448"), (), secured) == []
    tls_only = ZenohSecurity(secured.files, {}, "dp")  # TLS without access control is not enough
    assert unprotected_endpoints(("tls/192.168.10.2:7447",), (), tls_only) == ["tls/192.168.10.2:7447"]


@pytest.mark.timeout(60)
def test_roles_enforced_by_zenoh_between_real_sessions(vessel_pki: Path) -> None:
    d = vessel_pki
    daemon, endpoint = _daemon(d)
    clients: list[ZenohNode] = []
    try:
        setpoints = daemon.subscribe("setpoint", Inbox())
        feedback = daemon.subscribe("feedback", LatestSlot())
        commands = daemon.subscribe("command", LatestSlot(), remote_only=True)
        status = daemon.publisher("status")
        estimate = daemon.publisher("estimate")
        daemon.serve_config(b'{"schema":"dpcontrol.config/1","t_s":0.0,"seq":0,"config":{}}')
        daemon.declare_alive("controller")

        console = _client(d, endpoint, "bridge")
        monitor = _client(d, endpoint, "shore")
        drives = _client(d, endpoint, "drives")
        stranger = _client(d, endpoint, "stranger")  # vessel CA, but no role
        clients += [console, monitor, drives, stranger]
        assert daemon.wait_for_peers(4, 10.0)
        names = set(daemon.link_identities().values())
        assert names == {"bridge", "shore", "drives", "stranger"}

        monitor_status = monitor.subscribe("status", LatestSlot())
        monitor_estimate = monitor.subscribe("estimate", LatestSlot(), parse=bytes)  # the transport, not the schema
        monitor_alive = monitor.watch_alive("controller")
        stranger_status = stranger.subscribe("status", LatestSlot())
        time.sleep(SETTLE_S)

        # the shore reads estimates, status, liveliness and the configuration ...
        status.put(b'{"schema":"dpcontrol.status/1","t_s":1.0,"seq":0,"mode":"standby","sensors":[],'
                   b'"alarms":[],"cycle":null,"thrusters":[]}')
        estimate.put(b"{}")
        assert monitor_status.sink.wait_count(1, 5.0)
        assert monitor_estimate.sink.wait_count(1, 5.0)
        assert monitor_alive.wait_for(True, 5.0)
        assert isinstance(monitor.query_config(5.0), dict)
        # ... a certificate with no role reads nothing
        assert stranger_status.sink.count == 0

        # the shore's set-point, thruster reset and thruster command, the stranger's feedback: never delivered
        for sender in (monitor, stranger):
            pub = sender.publisher("setpoint")
            pub.put(setpoint_payload(t_s=1.0, seq=pub.next_seq(), north_m=50.0, east_m=0.0))
            pub.put(setpoint_payload(t_s=1.0, seq=pub.next_seq(), reset_thruster="tunnel"))
            cmd = sender.publisher("command")
            cmd.put(command_payload(t_s=1.0, seq=cmd.next_seq(), mode="auto_position", names=["tunnel"],
                                    thrust_n=[1000.0], azimuth_rad=[0.0]))
            fb = sender.publisher("feedback")
            fb.put(feedback_payload(t_s=1.0, seq=fb.next_seq(), names=["tunnel"], thrust_n=[1000.0],
                                    azimuth_rad=[0.0], ready=[True]))
        # the drives' feedback and the bridge's set-point are delivered, the bridge's identity known
        fb = drives.publisher("feedback")
        fb.put(feedback_payload(t_s=2.0, seq=fb.next_seq(), names=["tunnel"], thrust_n=[10.0], azimuth_rad=[0.0],
                                ready=[True]))
        sp = console.publisher("setpoint")
        sp.put(setpoint_payload(t_s=2.0, seq=sp.next_seq(), north_m=1.0, east_m=2.0))
        assert setpoints.sink.wait_count(1, 5.0)
        assert feedback.sink.wait_count(1, 5.0)
        time.sleep(0.5)  # anything refused would have arrived by now
        got = setpoints.sink.drain()
        assert [r.message.north_m for r in got] == [1.0]
        assert daemon.identity_of(got[0].source_zid) == "bridge"
        assert feedback.sink.count == 1 and feedback.sink.latest().message.t_s == 2.0
        assert commands.sink.count == 0
        assert setpoints.stats.received == 1 and feedback.stats.received == 1 and commands.stats.received == 0
    finally:
        for client in clients:
            client.close()
        daemon.close()


@pytest.mark.timeout(60)
def test_no_certificate_other_ca_or_expired_is_refused(vessel_pki: Path) -> None:
    d = vessel_pki
    daemon, endpoint = _daemon(d)
    clients: list[ZenohNode] = []
    try:
        plain = ZenohNode(ZenohConfig(connect=(endpoint,)), VESSEL)  # tcp to a tls listener
        other = d / "other"
        wrong_ca = _client(d, endpoint, "bridge", files=pki.IdentityFiles(other / "ca.pem", other / "bridge.pem",
                                                                           other / "bridge.key"))
        expired = _client(d, endpoint, "bridge-old")
        clients += [plain, wrong_ca, expired]
        time.sleep(2 * SETTLE_S)
        assert daemon.link_identities() == {}
        assert not any(c.peers() for c in clients)
        ok = _client(d, endpoint, "bridge")
        clients.append(ok)
        assert ok.wait_for_peers(1, 10.0)
        assert set(daemon.link_identities().values()) == {"bridge"}
    finally:
        for client in clients:
            client.close()
        daemon.close()


def test_check_identity_files_explains_what_is_wrong(vessel_pki: Path, tmp_path: Path) -> None:
    d = vessel_pki
    assert pki.check_identity_files(pki.IdentityFiles.in_dir(d, "bridge"), expected_name="bridge") == "bridge"
    with pytest.raises(pki.PkiError, match="common name 'bridge', expected 'dp'"):
        pki.check_identity_files(pki.IdentityFiles.in_dir(d, "bridge"), expected_name="dp")
    with pytest.raises(pki.PkiError, match="expired"):
        pki.check_identity_files(pki.IdentityFiles.in_dir(d, "bridge-old"))
    other = d / "other"
    with pytest.raises(pki.PkiError, match="not by the configured CA"):
        pki.check_identity_files(pki.IdentityFiles(d / "ca.pem", other / "bridge.pem", other / "bridge.key"))
    with pytest.raises(pki.PkiError, match="does not belong"):
        pki.check_identity_files(pki.IdentityFiles(d / "ca.pem", d / "bridge.pem", d / "shore.key"))
    with pytest.raises(pki.PkiError, match="no such file"):
        pki.check_identity_files(pki.IdentityFiles(d / "ca.pem", tmp_path / "x.pem", d / "shore.key"))
    # keys are the owner's only
    assert (d / "bridge.key").stat().st_mode & 0o077 == 0
    with pytest.raises(pki.PkiError, match="a CA exists already"):
        pki.init_ca(d, VESSEL)


@pytest.mark.timeout(60)
def test_an_identity_with_two_roles_has_the_rights_of_both(vessel_pki: Path) -> None:
    daemon, endpoint = _daemon(vessel_pki)
    hil = None
    try:
        setpoints = daemon.subscribe("setpoint", Inbox())
        feedback = daemon.subscribe("feedback", LatestSlot())
        status = daemon.publisher("status")
        hil = _client(vessel_pki, endpoint, "hil")
        heard = hil.subscribe("status", LatestSlot(), parse=bytes)
        sp, fb = hil.publisher("setpoint"), hil.publisher("feedback")
        assert sp.wait_matched(10.0) and fb.wait_matched(10.0)
        sp.put(setpoint_payload(t_s=1.0, seq=sp.next_seq(), mode="auto_position"))
        fb.put(feedback_payload(t_s=1.0, seq=fb.next_seq(), names=["tunnel"], thrust_n=[1.0], azimuth_rad=[0.0],
                                ready=[True]))
        assert setpoints.sink.wait_count(1, 5.0) and feedback.sink.wait_count(1, 5.0)
        time.sleep(0.2)
        status.put(b"{}")
        assert heard.sink.wait_count(1, 5.0)
    finally:
        if hil is not None:
            hil.close()
        daemon.close()


@pytest.mark.parametrize(("tls", "wrong"), [
    ({"dir": "/etc/dpcontrol/tls", "identity": "dp controller"}, "a certificate common name"),
    ({"dir": "/etc/dpcontrol/tls"}, "this node's name"),
])
def test_a_wrong_tls_identity_is_a_config_error_naming_the_key(tls: dict[str, str], wrong: str) -> None:
    # (the key path was once built with a three-argument join that raised TypeError instead)
    with pytest.raises(ConfigError, match=wrong) as caught:
        ZenohSecurity.from_mapping(tls, None, False, "zenoh")
    assert "zenoh.tls.identity" in str(caught.value)
