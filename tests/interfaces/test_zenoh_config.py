"""Explicit zenoh session configuration: no multicast, no listening anywhere unless told."""

from __future__ import annotations

import json

import pytest

from dpbase.schema import ConfigError
from interfaces.zenoh.loopback import free_tcp_port, loopback_endpoint
from interfaces.zenoh.node import ZenohNode
from interfaces.zenoh.session_config import (
    ZenohConfig,
    ZenohOpenError,
    check_endpoint,
    listens_everywhere,
    open_session,
)


def _get(config: ZenohConfig, key: str) -> object:
    return json.loads(config.to_zenoh().get_json(key))


def test_defaults_listen_nowhere_and_never_scout_by_multicast() -> None:
    config = ZenohConfig()
    assert config.mode == "peer"
    assert _get(config, "mode") == "peer"
    assert _get(config, "listen/endpoints") == []
    assert _get(config, "connect/endpoints") == []
    assert _get(config, "scouting/multicast/enabled") is False
    assert _get(config, "transport/shared_memory/enabled") is False


def test_endpoints_lease_and_gossip_are_written_explicitly() -> None:
    config = ZenohConfig(listen=("tcp/127.0.0.1:7447",), connect=("tcp/10.0.0.2:7447", "tcp/10.0.0.3:7447"),
                         gossip=False, lease_s=1.5)
    assert _get(config, "listen/endpoints") == ["tcp/127.0.0.1:7447"]
    assert _get(config, "connect/endpoints") == ["tcp/10.0.0.2:7447", "tcp/10.0.0.3:7447"]
    assert _get(config, "scouting/gossip/enabled") is False
    assert _get(config, "transport/link/tx/lease") == 1500
    assert _get(config, "connect/exit_on_failure") is False


@pytest.mark.parametrize(("kwargs", "match"), [
    ({"mode": "router"}, "mode"),
    ({"listen": "tcp/127.0.0.1:7447"}, "tuple"),
    ({"listen": ("127.0.0.1:7447",)}, "protocol"),
    ({"connect": ("serial//dev/ttyS0",)}, "protocol"),
    ({"mode": "client"}, "client"),
    ({"lease_s": 0.0}, "lease_s"),
    ({"lease_s": float("nan")}, "lease_s"),
    ({"connect_retry_max_s": -1.0}, "connect_retry_max_s"),
])
def test_invalid_configs_are_refused(kwargs: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        ZenohConfig(**kwargs)


def test_from_mapping_reads_yaml_section_and_names_key_paths() -> None:
    config = ZenohConfig.from_mapping({"listen": ["tcp/192.168.10.2:7447"], "connect": [], "lease_s": 2})
    assert config == ZenohConfig(listen=("tcp/192.168.10.2:7447",), lease_s=2.0)
    assert ZenohConfig.from_mapping(None) == ZenohConfig()
    with pytest.raises(ConfigError, match=r"zenoh\.listen\[1\]"):
        ZenohConfig.from_mapping({"listen": ["tcp/127.0.0.1:1", "nonsense"]})
    with pytest.raises(ConfigError, match=r"zenoh\.scouting"):
        ZenohConfig.from_mapping({"scouting": True})
    with pytest.raises(ConfigError, match=r"zenoh\.connect"):
        ZenohConfig.from_mapping({"mode": "client"})


def test_wildcard_detection() -> None:
    assert listens_everywhere("tcp/0.0.0.0:7447")
    assert listens_everywhere("tcp/[::]:0")
    assert not listens_everywhere("tcp/127.0.0.1:7447")


def test_open_session_reports_a_taken_port_clearly() -> None:
    endpoint = loopback_endpoint(free_tcp_port())
    first = open_session(ZenohConfig(listen=(endpoint,)))
    try:
        with pytest.raises(ZenohOpenError, match=endpoint.split("/", 1)[1]):
            open_session(ZenohConfig(listen=(endpoint,)))
    finally:
        first.close()


def test_a_node_started_before_its_peer_finds_it_later() -> None:
    # Nothing listens yet: open returns at once, and the connect endpoint is retried in the background.
    endpoint = loopback_endpoint(free_tcp_port())
    early = ZenohNode(ZenohConfig(connect=(endpoint,), connect_retry_max_s=0.2), "v")
    try:
        assert early.peers() == frozenset()
        late = ZenohNode(ZenohConfig(listen=(endpoint,)), "v")
        try:
            assert early.wait_for_peers(1, timeout_s=10.0)
            assert late.wait_for_peers(1, timeout_s=10.0)
        finally:
            late.close()
    finally:
        early.close()


@pytest.mark.parametrize("endpoint", ["tcp/127.0.0.1", "tcp/127.0.0.1:65536", "tcp/nohost:99999", "tcp/:7447",
                                      "udp/10.0.0.1:port", "tls/[::1]"])
def test_an_endpoint_without_a_valid_port_is_refused(endpoint: str) -> None:
    with pytest.raises(ValueError, match="expected '<host>:<port>' with a port of 0-65535"):
        check_endpoint(endpoint, "zenoh connect[0]")


@pytest.mark.parametrize("endpoint", ["tcp/127.0.0.1:0", "tcp/[::1]:7447", "tcp/vessel-pc.local:7447?prio=1",
                                      "udp/224.0.0.224:7446#iface=lo", "unixsock-stream//run/dp.sock"])
def test_valid_endpoints_pass(endpoint: str) -> None:
    assert check_endpoint(endpoint) == endpoint
