"""Eclipse Zenoh interface: explicit session config, payload schemas, publishers/subscribers,
config queryable and liveliness (docs/design.md §4.4).

* :mod:`interfaces.zenoh.keys` — ``dp/<vessel>/…`` key expressions, vessel ID validation;
* :mod:`interfaces.zenoh.session_config` — :class:`ZenohConfig` and :func:`open_session` (peer mode,
  explicit endpoints, multicast scouting off);
* :mod:`interfaces.zenoh.schemas` — every JSON payload schema: builders and validating parsers
  (the pure codec, testable without a transport);
* :mod:`interfaces.zenoh.node` — :class:`ZenohNode` (the transport);
* :mod:`interfaces.zenoh.loopback` — two peers on 127.0.0.1 for tests and benchmarks;
* :mod:`interfaces.zenoh.security` — roles, mutual TLS and zenoh's access control (docs/security.md);
* :mod:`interfaces.zenoh.pki` — the vessel CA and role certificates (``cryptography``).
"""

from interfaces.zenoh.keys import ROLES, TOPICS, VesselKeys, validate_vessel_id
from interfaces.zenoh.node import (
    AliveState,
    AliveToken,
    ConfigServer,
    Inbox,
    LatestSlot,
    LivelinessWatcher,
    Received,
    SubscriberStats,
    TopicPublisher,
    TopicSubscriber,
    ZenohNode,
)
from interfaces.zenoh.session_config import ZenohConfig, ZenohOpenError, open_session

__all__ = [
    "ROLES",
    "TOPICS",
    "AliveState",
    "AliveToken",
    "ConfigServer",
    "Inbox",
    "LatestSlot",
    "LivelinessWatcher",
    "Received",
    "SubscriberStats",
    "TopicPublisher",
    "TopicSubscriber",
    "VesselKeys",
    "ZenohConfig",
    "ZenohNode",
    "ZenohOpenError",
    "open_session",
    "validate_vessel_id",
]
