"""sd_notify protocol against a fake service manager: a real AF_UNIX datagram socket."""

from __future__ import annotations

import os
import socket
import uuid
from collections.abc import Iterator
from pathlib import Path

import pytest

from interfaces.systemd import SystemdNotifier, socket_address, unset_environment


@pytest.fixture
def manager(tmp_path: Path) -> Iterator[tuple[socket.socket, str]]:
    """A bound datagram socket standing in for PID 1, and its ``NOTIFY_SOCKET`` value."""
    path = tmp_path / "notify"
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    sock.bind(str(path))
    sock.settimeout(5.0)
    yield sock, str(path)
    sock.close()


def _recv(sock: socket.socket) -> list[str]:
    return sock.recv(4096).decode().split("\n")


def test_messages_reach_the_manager(manager: tuple[socket.socket, str]) -> None:
    sock, path = manager
    notifier = SystemdNotifier({"NOTIFY_SOCKET": path})
    assert notifier.enabled
    assert notifier.ready(status="running at 10 Hz")
    assert _recv(sock) == ["READY=1", "STATUS=running at 10 Hz"]
    assert notifier.status("gnss1 stale\nheading ok")
    assert _recv(sock) == ["STATUS=gnss1 stale heading ok"]  # one line: a newline would start a field
    assert notifier.watchdog()
    assert _recv(sock) == ["WATCHDOG=1"]
    assert notifier.extend_timeout(2.5)
    assert _recv(sock) == ["EXTEND_TIMEOUT_USEC=2500000"]
    assert notifier.stopping()
    assert _recv(sock) == ["STOPPING=1"]
    assert notifier.sent == 5 and notifier.failures == 0
    notifier.close()


def test_abstract_namespace_socket() -> None:
    name = f"dpcontrol-test-{uuid.uuid4().hex}"
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    sock.bind(b"\0" + name.encode())
    sock.settimeout(5.0)
    try:
        with SystemdNotifier({"NOTIFY_SOCKET": "@" + name}) as notifier:
            assert notifier.ready()
            assert _recv(sock) == ["READY=1"]
    finally:
        sock.close()


def test_no_op_outside_systemd() -> None:
    notifier = SystemdNotifier({})
    assert not notifier.enabled
    assert not notifier.ready() and not notifier.watchdog() and not notifier.status("x") and not notifier.stopping()
    assert notifier.watchdog_interval_s() is None
    assert notifier.sent == 0 and notifier.failures == 0


@pytest.mark.parametrize("value", ["relative/path", "vsock:2:1234", ""])
def test_unusable_socket_names_disable_notification(value: str) -> None:
    notifier = SystemdNotifier({"NOTIFY_SOCKET": value})
    assert not notifier.enabled
    assert notifier.ready() is False


def test_socket_address_forms() -> None:
    assert socket_address("/run/systemd/notify") == "/run/systemd/notify"
    assert socket_address("@abc") == b"\0abc"
    assert socket_address(None) is None


def test_a_vanished_manager_is_counted_not_raised(tmp_path: Path) -> None:
    notifier = SystemdNotifier({"NOTIFY_SOCKET": str(tmp_path / "gone")})
    assert notifier.enabled
    assert notifier.watchdog() is False
    assert notifier.watchdog() is False
    assert notifier.failures == 2 and notifier.sent == 0


def test_a_full_queue_never_blocks_the_sender(manager: tuple[socket.socket, str]) -> None:
    _, path = manager  # never reads: the datagram queue fills up
    notifier = SystemdNotifier({"NOTIFY_SOCKET": path})
    results = [notifier.watchdog() for _ in range(20_000)]
    assert results[0] is True
    assert results.count(False) > 0  # dropped (EAGAIN), and we got here: nothing blocked
    assert notifier.sent + notifier.failures == 20_000


@pytest.mark.parametrize(("environ", "expected"), [
    ({"WATCHDOG_USEC": "2000000"}, 2.0),
    ({"WATCHDOG_USEC": "2000000", "WATCHDOG_PID": "4242"}, 2.0),
    ({"WATCHDOG_USEC": "2000000", "WATCHDOG_PID": "1"}, None),      # meant for another process
    ({"WATCHDOG_USEC": "2000000", "WATCHDOG_PID": "abc"}, None),
    ({"WATCHDOG_USEC": "0"}, None),
    ({"WATCHDOG_USEC": "-5"}, None),
    ({"WATCHDOG_USEC": "2s"}, None),
    ({}, None),
])
def test_watchdog_interval(environ: dict[str, str], expected: float | None) -> None:
    assert SystemdNotifier(environ, pid=4242).watchdog_interval_s() == expected


def test_watchdog_pid_defaults_to_this_process() -> None:
    environ = {"WATCHDOG_USEC": "500000", "WATCHDOG_PID": str(os.getpid())}
    assert SystemdNotifier(environ).watchdog_interval_s() == 0.5


def test_unset_environment_stops_children_inheriting_the_socket() -> None:
    environ = {"NOTIFY_SOCKET": "/run/x", "WATCHDOG_USEC": "1", "WATCHDOG_PID": "2", "PATH": "/bin"}
    unset_environment(environ)
    assert environ == {"PATH": "/bin"}
