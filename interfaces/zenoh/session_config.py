"""Explicit Zenoh session configuration (docs/design.md §4.4 and the §5 trap).

Zenoh's defaults are wrong for a vessel network: a peer listens on every interface
(``tcp/[::]:0``) and scouts by UDP multicast, so a DP controller would announce itself to, and
accept sessions from, anything on any network the computer is plugged into. Here nothing is left
to defaults that matter:

* ``mode`` is ``peer`` (or ``client`` towards a zenoh router);
* ``listen`` endpoints are exactly those configured — none by default, so a node that should
  accept connections (the daemon) says where, e.g. ``tcp/192.168.10.2:7447``;
* ``connect`` endpoints are exactly those configured, retried in the background with a bounded
  back-off (a daemon started before its peers still finds them, and finds them again after a
  restart) — opening never waits for a peer;
* multicast scouting is OFF; gossip scouting (peers learn about each other's *configured*
  listen endpoints through the peers they are connected to, one hop) is on by default so a
  monitor that connects to the daemon also reaches the plant; turn it off for a strict star;
* the link lease (how long a silent peer is considered alive) is explicit: the liveliness tokens
  of a peer whose link dies without closing are dropped after ``lease_s``;
* shared memory is off: our JSON payloads are a few kB, below zenoh's SHM threshold, and a
  hardened service should not create ``/dev/shm`` segments for nothing;
* ``tls`` / ``identities`` / ``insecure``: mutual TLS and Zenoh's access control by role
  (:mod:`interfaces.zenoh.security`).
"""

from __future__ import annotations

import json
import logging
import math
import re
from dataclasses import dataclass
from typing import Any

import zenoh

from dpbase.schema import ConfigError, Section, join
from interfaces.zenoh.security import ZenohSecurity, security_from_args

log = logging.getLogger(__name__)

MODES: tuple[str, ...] = ("peer", "client")
PROTOCOLS: tuple[str, ...] = ("tcp", "udp", "tls", "quic", "ws", "unixsock-stream")
# <protocol>/<address>[?<metadata>][#<config>] (zenoh's endpoint syntax); the address is checked by zenoh.
_ENDPOINT = re.compile(r"(?P<proto>[a-z][a-z0-9-]*)/(?P<address>[^?#\s]+)(?:\?[^#\s]*)?(?:#\S*)?")
_WILDCARD_HOSTS = ("0.0.0.0", "[::]", "::")
_HOST_PORT_PROTOCOLS = ("tcp", "udp", "tls", "quic")
MAX_MESSAGE_BYTES = 2 * 1024 * 1024
#: Where the operator's tools (``dpcontrol monitor``, ``dpcontrol setpoint``) connect when not told: a daemon on
#: this computer listening on zenoh's usual port (``deploy/config/*.yaml``).
LOCAL_DAEMON_CONNECT: tuple[str, ...] = ("tcp/127.0.0.1:7447",)


class ZenohOpenError(RuntimeError):
    """A zenoh session could not be opened (bad endpoint, port in use, router unreachable)."""


def check_endpoint(endpoint: object, where: str = "endpoint") -> str:
    """Validate the syntax of one zenoh endpoint (``tcp/127.0.0.1:7447``) and return it.

    Raises
    ------
    ValueError
        Not a string, not ``<protocol>/<address>``, or an unsupported protocol.
    """
    if not isinstance(endpoint, str):
        raise ValueError(f"{where}: expected an endpoint string like 'tcp/127.0.0.1:7447', got {endpoint!r}")
    match = _ENDPOINT.fullmatch(endpoint)
    if match is None:
        raise ValueError(f"{where}: expected '<protocol>/<address>' like 'tcp/127.0.0.1:7447', got {endpoint!r}")
    if match["proto"] not in PROTOCOLS:
        raise ValueError(f"{where}: unsupported protocol {match['proto']!r} in {endpoint!r} "
                         f"(expected one of {', '.join(PROTOCOLS)})")
    if match["proto"] in _HOST_PORT_PROTOCOLS:
        # zenoh itself accepts a bad port here and only fails (or retries silently) when it connects
        host, _, port = match["address"].rpartition(":")
        if not host or not port.isdigit() or int(port) > 65535:
            raise ValueError(f"{where}: expected '<host>:<port>' with a port of 0-65535 after "
                             f"'{match['proto']}/', got {endpoint!r}")
    return endpoint


def listens_everywhere(endpoint: str) -> bool:
    """True when ``endpoint`` binds every interface (``0.0.0.0`` or ``[::]``)."""
    address = endpoint.split("/", 1)[-1]
    return any(address.startswith(host + ":") or address == host for host in _WILDCARD_HOSTS)


@dataclass(frozen=True, slots=True)
class ZenohConfig:
    """How a node joins the zenoh network: explicit endpoints, no multicast scouting.

    Attributes
    ----------
    mode : {"peer", "client"}
        ``peer`` (default): talks directly to the peers it connects to or that connect to it.
        ``client``: goes through the zenoh router(s) in ``connect`` (at least one required).
    listen : tuple of str
        Endpoints to accept sessions on (``tcp/192.168.10.2:7447``); empty by default — never
        every interface unless written out explicitly (``tcp/0.0.0.0:7447`` logs a warning).
    connect : tuple of str
        Endpoints of peers/routers to connect to; retried in the background.
    gossip : bool
        Gossip scouting (one hop): learn the listen endpoints of the peers' peers and connect.
    lease_s : float
        Link lease announced to peers [s]: a peer that hears nothing for this long drops the link
        and with it our liveliness tokens. Keep-alives go out four times per lease.
    connect_retry_max_s : float
        Largest back-off between connection attempts to ``connect`` endpoints [s].
    shared_memory : bool
        Zenoh shared-memory transport between processes on one host (off: payloads are small).
    security : ZenohSecurity or None
        TLS files, identity → role map (access control) and the ``insecure`` waiver; ``None``: plaintext.
    """

    mode: str = "peer"
    listen: tuple[str, ...] = ()
    connect: tuple[str, ...] = ()
    gossip: bool = True
    lease_s: float = 3.0
    connect_retry_max_s: float = 1.0
    shared_memory: bool = False
    security: ZenohSecurity | None = None

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise ValueError(f"zenoh mode: expected one of {', '.join(MODES)}, got {self.mode!r}")
        for name in ("listen", "connect"):
            value = getattr(self, name)
            if isinstance(value, str) or not isinstance(value, tuple):
                raise ValueError(f"zenoh {name}: expected a tuple of endpoint strings, got {value!r}")
            for i, endpoint in enumerate(value):
                check_endpoint(endpoint, f"zenoh {name}[{i}]")
        if self.mode == "client" and not self.connect:
            raise ValueError("zenoh mode 'client' needs at least one connect endpoint (a router)")
        for name in ("lease_s", "connect_retry_max_s"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) \
                    or value <= 0.0:
                raise ValueError(f"zenoh {name}: expected a number > 0, got {value!r}")
        if self.lease_s < 0.1:
            raise ValueError(f"zenoh lease_s: expected at least 0.1 s, got {self.lease_s!r}")

    @classmethod
    def from_mapping(cls, value: object, path: str = "zenoh") -> ZenohConfig:
        """Build from a parsed config mapping (YAML ``zenoh:`` section); errors name the key path.

        Keys: ``mode``, ``listen`` (list), ``connect`` (list), ``gossip``, ``lease_s``,
        ``connect_retry_max_s``, ``shared_memory``, ``tls``, ``identities``, ``insecure`` (see
        :meth:`ZenohSecurity.from_mapping`); all optional. Unknown keys are rejected.

        Raises
        ------
        dpbase.schema.ConfigError
        """
        section = Section.of(value, path)
        defaults = cls()
        mode = section.string("mode", defaults.mode, choices=MODES)
        endpoints: dict[str, tuple[str, ...]] = {}
        for key in ("listen", "connect"):
            items = []
            for where, endpoint in section.items(key):
                try:
                    items.append(check_endpoint(endpoint, where))
                except ValueError:
                    raise ConfigError(where, "an endpoint '<protocol>/<address>' like 'tcp/127.0.0.1:7447' "
                                      f"with protocol one of {', '.join(PROTOCOLS)}", endpoint) from None
            endpoints[key] = tuple(items)
        gossip = section.boolean("gossip", defaults.gossip)
        lease_s = section.number("lease_s", defaults.lease_s, minimum=0.1)
        retry_s = section.number("connect_retry_max_s", defaults.connect_retry_max_s, minimum=0.0,
                                 exclusive_minimum=True)
        shared_memory = section.boolean("shared_memory", defaults.shared_memory)
        tls, identities = section.raw("tls", None), section.raw("identities", None)
        insecure = section.boolean("insecure", False)
        security = None if tls is None and identities is None and not insecure else \
            ZenohSecurity.from_mapping(tls, identities, insecure, path)
        section.finish()
        if mode == "client" and not endpoints["connect"]:
            raise ConfigError(join(path, "connect"), "at least one router endpoint in client mode", [])
        return cls(mode=mode, listen=endpoints["listen"], connect=endpoints["connect"], gossip=gossip,
                   lease_s=lease_s, connect_retry_max_s=retry_s, shared_memory=shared_memory, security=security)

    def settings(self, vessel: str | None = None) -> dict[str, Any]:
        """The zenoh configuration entries this config sets, as ``{json5 key path: value}``.

        Every entry that matters is written explicitly, so a zenoh upgrade that changes a default
        does not change how the vessel network behaves. ``vessel`` scopes the access-control rules
        (needed when :attr:`security` maps identities).
        """
        lease_ms = max(100, round(self.lease_s * 1000.0))
        retry_max_ms = max(1, round(self.connect_retry_max_s * 1000.0))
        retry = {"period_init_ms": min(100, retry_max_ms), "period_max_ms": retry_max_ms,
                 "period_increase_factor": 2.0}
        settings: dict[str, Any] = {
            "mode": self.mode,
            "listen/endpoints": list(self.listen),
            # A listener that cannot bind is a configuration error: fail at start (systemd restarts
            # and logs it) instead of running deaf.
            "listen/exit_on_failure": True,
            "connect/endpoints": list(self.connect),
            "scouting/multicast/enabled": False,
            "scouting/gossip/enabled": self.gossip,
            "scouting/gossip/multihop": False,
            # open() returns at once: with multicast off there is nothing to wait for, and the
            # connect endpoints are retried in the background.
            "scouting/delay": 0,
            "transport/link/tx/lease": lease_ms,
            "transport/link/tx/keep_alive": 4,
            # Our largest payload (the config reply) is at most 1 MiB: refuse to reassemble more
            # (zenoh's default is 1 GiB) so a misbehaving peer cannot make us allocate it.
            "transport/link/rx/max_message_size": MAX_MESSAGE_BYTES,
            "transport/shared_memory/enabled": self.shared_memory,
            "adminspace/enabled": False,
        }
        if self.mode == "peer":
            settings["connect/exit_on_failure"] = False
            settings["connect/retry"] = retry
        if self.security is not None:
            settings.update(self.security.settings(vessel))
        return settings

    def to_zenoh(self, vessel: str | None = None) -> zenoh.Config:
        """A :class:`zenoh.Config` with :meth:`settings` applied on top of an empty config."""
        config = zenoh.Config()
        for key, value in self.settings(vessel).items():
            config.insert_json5(key, json.dumps(value))
        return config


def open_session(config: ZenohConfig, vessel: str | None = None) -> zenoh.Session:
    """Open a zenoh session from an explicit :class:`ZenohConfig`.

    Returns without waiting for peers (connections are made in the background).

    Raises
    ------
    ZenohOpenError
        The configuration was refused or a listen endpoint could not be bound; the message names
        the endpoints and zenoh's reason.
    """
    for endpoint in config.listen:
        if listens_everywhere(endpoint):
            log.warning("zenoh listens on every interface (%s): prefer the vessel network's address", endpoint)
    try:
        return zenoh.open(config.to_zenoh(vessel))
    except (zenoh.ZError, ValueError) as exc:
        reason = str(exc).split(" at /", 1)[0]  # drop zenoh's Rust source location
        raise ZenohOpenError(f"cannot open zenoh session (mode={config.mode}, listen={list(config.listen)}, "
                             f"connect={list(config.connect)}): {reason}") from exc


def tool_config(args: Any, default_connect: tuple[str, ...] = LOCAL_DAEMON_CONNECT,
                identities: dict[str, tuple[str, ...]] | None = None) -> ZenohConfig:
    """The session of a tool that connects to a vessel (``dpcontrol monitor``/``setpoint``/``console``), from
    its ``--connect``/``--listen`` and TLS options (:func:`interfaces.zenoh.security.add_tls_arguments`):
    the one way every tool gets its secured zenoh configuration.

    Raises
    ------
    ValueError
        A bad endpoint, ``--tls-dir`` without ``--identity``, or TLS files that will not do (the message says
        which and why).
    """
    return ZenohConfig(listen=tuple(getattr(args, "listen", None) or ()),
                       connect=tuple(getattr(args, "connect", None) or default_connect),
                       security=security_from_args(args, identities))
