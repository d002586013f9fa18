"""Loopback twin of the zenoh transport: two peers on 127.0.0.1 in one process (tests, benchmarks).

One node listens on a free TCP port of 127.0.0.1, the other connects to it — the same explicit
peer ↔ peer set-up as on the vessel, without multicast and without touching another interface.
"""

from __future__ import annotations

import socket
import time
from collections.abc import Iterator
from contextlib import contextmanager

from interfaces.zenoh.node import Clock, ZenohNode
from interfaces.zenoh.session_config import ZenohConfig, ZenohOpenError

LOOPBACK = "127.0.0.1"


def free_tcp_port(host: str = LOOPBACK) -> int:
    """A TCP port that was free on ``host`` a moment ago (the OS picks it; racy by nature —
    :func:`open_listener` retries if another process takes it first)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind((host, 0))
        return int(sock.getsockname()[1])


def free_udp_port(host: str = LOOPBACK) -> int:
    """A UDP port that was free on ``host`` a moment ago (racy like :func:`free_tcp_port`)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind((host, 0))
        return int(sock.getsockname()[1])


def loopback_endpoint(port: int) -> str:
    """``tcp/127.0.0.1:<port>``."""
    return f"tcp/{LOOPBACK}:{port}"


def open_listener(vessel: str, *, lease_s: float = 3.0, clock: Clock = time.monotonic,
                  attempts: int = 5) -> tuple[ZenohNode, str]:
    """A node listening on a free loopback port; returns it with the endpoint peers connect to."""
    for attempt in range(attempts):
        endpoint = loopback_endpoint(free_tcp_port())
        try:
            return ZenohNode(ZenohConfig(listen=(endpoint,), lease_s=lease_s), vessel, clock=clock), endpoint
        except ZenohOpenError:
            if attempt == attempts - 1:
                raise
    raise AssertionError("unreachable")


def connector_config(endpoint: str, *, lease_s: float = 3.0) -> ZenohConfig:
    """Config of a peer that connects to ``endpoint`` and listens nowhere."""
    return ZenohConfig(connect=(endpoint,), lease_s=lease_s)


@contextmanager
def loopback_pair(vessel: str, *, lease_s: float = 3.0, clock: Clock = time.monotonic,
                  timeout_s: float = 10.0) -> Iterator[tuple[ZenohNode, ZenohNode]]:
    """Two connected nodes ``(listener, connector)`` on 127.0.0.1; both closed on exit.

    Raises
    ------
    TimeoutError
        The connector did not reach the listener within ``timeout_s``.
    """
    listener, endpoint = open_listener(vessel, lease_s=lease_s, clock=clock)
    try:
        connector = ZenohNode(connector_config(endpoint, lease_s=lease_s), vessel, clock=clock)
        try:
            if not connector.wait_for_peers(1, timeout_s):
                raise TimeoutError(f"loopback zenoh peer did not connect to {endpoint} within {timeout_s} s")
            yield listener, connector
        finally:
            connector.close()
    finally:
        listener.close()
