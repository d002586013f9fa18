"""Zenoh transport for one vessel: publishers, validating subscribers, config queryable, liveliness.

A :class:`ZenohNode` holds one session (opened from an explicit
:class:`~interfaces.zenoh.session_config.ZenohConfig`) and the entities declared on it. The daemon, the
plant emulator and the monitor each use one::

    node = ZenohNode(ZenohConfig(listen=("tcp/192.168.10.2:7447",)), "supply")
    command = node.publisher("command")                 # declare once ...
    command.put(command_payload(t_s=t, seq=command.next_seq(), ...))   # ... put bytes each cycle
    setpoints = node.subscribe("setpoint", Inbox())     # validated SetpointRequest in an Inbox
    for item in setpoints.sink.drain(): ...             # Received(rx_t_s, key, message)
    node.serve_config(config_json_bytes)                # dp/<vessel>/config queryable
    node.declare_alive("controller")                    # liveliness token
    plant = node.watch_alive("plant", on_change=...)    # presence / loss of the plant's token
    node.close()

Threading: zenoh calls our callbacks on its own threads. They stay tiny and never block: parse
(a few tens of µs for a setpoint or feedback message), store into a lock-protected slot, notify.
Nothing here raises into zenoh: a bad payload becomes a counted :class:`Rejected`, an unexpected
exception is counted and logged.

Query failures of :meth:`ZenohNode.query_config` are ``Rejected`` with reason ``no_reply``
(nobody answered in time) or ``reply_error`` (the queryable answered with an error).
"""

from __future__ import annotations

import collections
import functools
import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Generic, TypeVar, overload

import zenoh

from interfaces.messages import Rejected
from interfaces.zenoh import schemas
from interfaces.zenoh.keys import TOPICS, VesselKeys
from interfaces.zenoh.session_config import ZenohConfig, open_session

log = logging.getLogger(__name__)

T = TypeVar("T")
Clock = Callable[[], float]

JSON = zenoh.Encoding.APPLICATION_JSON


@dataclass(frozen=True, slots=True)
class Received(Generic[T]):
    """A validated message with its receive time on the consumer's clock [s], its key, and the zenoh ID of the
    session that says it sent it (``source_zid``, when the sender attached its source info; see
    :meth:`ZenohNode.identity_of`)."""

    rx_t_s: float
    key: str
    message: T
    source_zid: str | None = None


class _Sink(Generic[T]):
    """Base of the thread-safe stores a subscriber fills; ``wait_count`` lets tests await delivery."""

    def __init__(self, on_put: Callable[[], None] | None = None) -> None:
        self._cond = threading.Condition()
        self._count = 0
        self._on_put = on_put

    @property
    def count(self) -> int:
        """Items put since creation."""
        with self._cond:
            return self._count

    def wait_count(self, n: int, timeout_s: float) -> bool:
        """Block until at least ``n`` items were put (since creation) or ``timeout_s`` passes."""
        with self._cond:
            return self._cond.wait_for(lambda: self._count >= n, timeout_s)

    def put(self, item: T) -> None:
        with self._cond:
            self._store(item)
            self._count += 1
            self._cond.notify_all()
        if self._on_put is not None:
            self._on_put()

    def _store(self, item: T) -> None:  # pragma: no cover - abstract
        raise NotImplementedError


class LatestSlot(_Sink[T]):
    """Keeps only the newest item (telemetry, thruster feedback, commands at the drives)."""

    def __init__(self, on_put: Callable[[], None] | None = None) -> None:
        super().__init__(on_put)
        self._item: T | None = None
        self._taken = True

    def _store(self, item: T) -> None:
        self._item = item
        self._taken = False

    def latest(self) -> T | None:
        """The newest item (``None`` before the first one), without consuming it."""
        with self._cond:
            return self._item

    def take(self) -> T | None:
        """The newest item if it arrived since the last ``take``, else ``None``."""
        with self._cond:
            if self._taken:
                return None
            self._taken = True
            return self._item


class Inbox(_Sink[T]):
    """A bounded FIFO (operator setpoints: every request counts, relative moves add up).

    When full, the oldest item is dropped and counted in :attr:`dropped`.
    """

    def __init__(self, maxlen: int = 64, on_put: Callable[[], None] | None = None) -> None:
        super().__init__(on_put)
        self._items: collections.deque[T] = collections.deque()
        self._maxlen = maxlen
        self._dropped = 0

    def _store(self, item: T) -> None:
        if len(self._items) >= self._maxlen:
            self._items.popleft()
            self._dropped += 1
        self._items.append(item)

    @property
    def dropped(self) -> int:
        """Items discarded because the inbox was full."""
        with self._cond:
            return self._dropped

    def drain(self) -> list[T]:
        """All queued items, oldest first; empties the inbox."""
        with self._cond:
            items = list(self._items)
            self._items.clear()
            return items

    def get(self, timeout_s: float) -> T | None:
        """The oldest item, waiting up to ``timeout_s`` for one; ``None`` on timeout."""
        with self._cond:
            if not self._cond.wait_for(lambda: bool(self._items), timeout_s):
                return None
            return self._items.popleft()


@dataclass(frozen=True, slots=True)
class SubscriberStats:
    """Counters of one subscriber: samples received, accepted, rejected (bad payload), ignored
    (delete samples) and internal errors; the newest rejection."""

    received: int
    accepted: int
    rejected: int
    ignored: int
    errors: int
    last_rejection: Rejected | None


# The kind of store a subscriber fills: typed, so that ``subscriber.sink.latest()`` / ``.drain()`` check
SinkT = TypeVar("SinkT", bound=_Sink[Received[Any]])


class TopicSubscriber(Generic[SinkT]):
    """A subscriber that validates each sample and stores :class:`Received` messages in a sink.

    Rejections are counted and the last 16 kept (:attr:`recent_rejections`) for alarms and the
    black-box recorder; nothing propagates into zenoh's thread.
    """

    def __init__(self, session: zenoh.Session, key: str, parse: Callable[[bytes], Any], sink: SinkT,
                 clock: Clock, *, remote_only: bool = False) -> None:
        self.key = key
        self.sink = sink
        self._parse = parse
        self._clock = clock
        self._lock = threading.Lock()
        self._received = self._accepted = self._rejected = self._ignored = self._errors = 0
        self._recent: collections.deque[Rejected] = collections.deque(maxlen=16)
        self._subscriber = session.declare_subscriber(
            key, self._on_sample, allowed_origin=zenoh.Locality.REMOTE if remote_only else zenoh.Locality.ANY)

    def _on_sample(self, sample: zenoh.Sample) -> None:
        # Runs on a zenoh thread: tiny, never raises.
        try:
            rx_t_s = self._clock()
            if sample.kind != zenoh.SampleKind.PUT:
                with self._lock:
                    self._received += 1
                    self._ignored += 1
                return
            result = self._parse(sample.payload.to_bytes())
            with self._lock:
                self._received += 1
                if isinstance(result, Rejected):
                    self._rejected += 1
                    self._recent.append(result)
                else:
                    self._accepted += 1
            if not isinstance(result, Rejected):
                source = sample.source_info
                self.sink.put(Received(rx_t_s, str(sample.key_expr), result,
                                       None if source is None else str(source.source_id.zid)))
        except Exception:  # a callback must never raise into zenoh
            with self._lock:
                self._errors += 1
            log.exception("zenoh subscriber %s: unexpected error in callback", self.key)

    @property
    def stats(self) -> SubscriberStats:
        """A consistent snapshot of the counters."""
        with self._lock:
            return SubscriberStats(self._received, self._accepted, self._rejected, self._ignored, self._errors,
                                   self._recent[-1] if self._recent else None)

    @property
    def recent_rejections(self) -> tuple[Rejected, ...]:
        """Up to the last 16 rejections, oldest first."""
        with self._lock:
            return tuple(self._recent)

    def close(self) -> None:
        """Undeclare (no more callbacks afterwards)."""
        _undeclare(self._subscriber, self.key)


class TopicPublisher:
    """A declared publisher for one key: ``put(bytes)`` per cycle, ``next_seq()`` for the envelope.

    ``put`` never raises: a failure (session closed, queue full with blocking congestion control
    timing out) returns ``False`` and is counted in :attr:`failures`. ``next_seq``/``put`` are
    meant to be called from one thread (the loop that publishes).
    """

    def __init__(self, session: zenoh.Session, key: str, *, priority: zenoh.Priority,
                 congestion_control: zenoh.CongestionControl, express: bool, attach_source: bool = False) -> None:
        self.key = key
        self._publisher = session.declare_publisher(key, encoding=JSON, priority=priority,
                                                    congestion_control=congestion_control, express=express)
        # The sender's source info (its session's zenoh ID) lets the receiver name the authenticated link it
        # came over (ZenohNode.identity_of); operator requests carry it, the per-cycle topics do not.
        self._source_id = self._publisher.id if attach_source else None
        self._seq = -1
        self.failures = 0
        self._matched = threading.Event()
        self._listener: Any = None
        self._listener_lock = threading.Lock()

    def next_seq(self) -> int:
        """The next envelope sequence number (0, 1, 2, …)."""
        self._seq += 1
        return self._seq

    def put(self, payload: bytes) -> bool:
        """Publish ``payload`` (already-encoded JSON); ``False`` if zenoh refused it."""
        try:
            if self._source_id is None:
                self._publisher.put(payload)
            else:
                self._publisher.put(payload, source_info=zenoh.SourceInfo(self._source_id, max(self._seq, 0)))
        except zenoh.ZError as exc:
            self.failures += 1
            if self.failures == 1:
                log.warning("zenoh publisher %s: put failed: %s", self.key, exc)
            return False
        return True

    def _on_matching(self, status: Any) -> None:
        if getattr(status, "matching", False):
            self._matched.set()
        else:
            self._matched.clear()

    def wait_matched(self, timeout_s: float) -> bool:
        """Block until at least one subscriber matches this key (or ``timeout_s`` passes)."""
        with self._listener_lock:
            if self._listener is None:
                self._listener = self._publisher.declare_matching_listener(self._on_matching)
                if getattr(self._publisher.matching_status, "matching", False):
                    self._matched.set()
        return self._matched.wait(timeout_s)

    def close(self) -> None:
        """Undeclare the publisher (and its matching listener)."""
        if self._listener is not None:
            _undeclare(self._listener, self.key)
        _undeclare(self._publisher, self.key)


class ConfigServer:
    """The ``dp/<vessel>/config`` queryable: replies with the JSON the daemon gives it.

    ``provider`` is either ready bytes (render the config once at load time: the reply then
    costs nothing on zenoh's thread) or a cheap callable returning bytes.
    """

    def __init__(self, session: zenoh.Session, key: str, provider: bytes | Callable[[], bytes]) -> None:
        self.key = key
        self._provider = provider
        self.replies = 0
        self.errors = 0
        self._queryable = session.declare_queryable(key, self._on_query, complete=True)

    def update(self, provider: bytes | Callable[[], bytes]) -> None:
        """Replace what is served (e.g. after a configuration reload)."""
        self._provider = provider

    def _on_query(self, query: zenoh.Query) -> None:
        try:
            provider = self._provider
            payload = provider() if callable(provider) else provider
            query.reply(self.key, payload, encoding=JSON)
            self.replies += 1
        except Exception as exc:  # answer with an error, never raise into zenoh
            self.errors += 1
            log.warning("zenoh config queryable: cannot reply: %s", exc)
            try:
                query.reply_err(f"config unavailable: {exc}".encode())
            except Exception:
                log.exception("zenoh config queryable: reply_err failed")
        finally:
            query.drop()  # finalise now: Python finalisers are not prompt

    def close(self) -> None:
        _undeclare(self._queryable, self.key)


class AliveToken:
    """A liveliness token (``dp/<vessel>/alive/<role>``): present while declared and the session lives."""

    def __init__(self, session: zenoh.Session, key: str) -> None:
        self.key = key
        self._token = session.liveliness().declare_token(key)

    def close(self) -> None:
        """Undeclare: watchers see the loss at once."""
        _undeclare(self._token, self.key)


@dataclass(frozen=True, slots=True)
class AliveState:
    """Presence of a peer's liveliness token.

    Attributes
    ----------
    present : bool
        Token currently declared.
    seen : bool
        Ever seen since the watcher started (absent-and-never-seen is "not yet up", not a loss).
    since_t_s : float or None
        Local clock time of the last change [s].
    losses : int
        Present → absent transitions (each one is a fault).
    """

    present: bool
    seen: bool
    since_t_s: float | None
    losses: int


class LivelinessWatcher:
    """Watches one liveliness token; reports presence and loss (callback + state).

    The token of a peer that closes its session, undeclares, or whose process dies (the TCP link
    closes) disappears at once; a peer cut off by the network disappears after its link lease
    (:attr:`ZenohConfig.lease_s`).

    ``on_change(present, t_s)`` runs on a zenoh thread: keep it tiny (set a flag, queue an alarm).
    """

    def __init__(self, session: zenoh.Session, key: str, *, clock: Clock,
                 on_change: Callable[[bool, float], None] | None = None) -> None:
        self.key = key
        self._clock = clock
        self._on_change = on_change
        self._cond = threading.Condition()
        self._present = False
        self._seen = False
        self._since: float | None = None
        self._losses = 0
        self._subscriber = session.liveliness().declare_subscriber(key, self._on_sample, history=True)

    def _on_sample(self, sample: zenoh.Sample) -> None:
        try:
            present = sample.kind == zenoh.SampleKind.PUT
            t_s = self._clock()
            with self._cond:
                if present == self._present:
                    return
                self._present = present
                self._since = t_s
                if present:
                    self._seen = True
                else:
                    self._losses += 1
                self._cond.notify_all()
            if self._on_change is not None:
                self._on_change(present, t_s)
        except Exception:  # a callback must never raise into zenoh
            log.exception("zenoh liveliness watcher %s: unexpected error in callback", self.key)

    @property
    def state(self) -> AliveState:
        """A consistent snapshot."""
        with self._cond:
            return AliveState(self._present, self._seen, self._since, self._losses)

    @property
    def present(self) -> bool:
        with self._cond:
            return self._present

    def wait_for(self, present: bool, timeout_s: float) -> bool:
        """Block until the token is (``True``) or is not (``False``) present, or ``timeout_s`` passes."""
        with self._cond:
            return self._cond.wait_for(lambda: self._present == present, timeout_s)

    def close(self) -> None:
        _undeclare(self._subscriber, self.key)


def _undeclare(entity: Any, what: str) -> None:
    try:
        entity.undeclare()
    except Exception as exc:  # closing must go on whatever one entity says
        log.debug("zenoh: undeclare %s: %s", what, exc)


# QoS per topic: thruster commands first and never blocking the control loop; operator setpoints
# are never dropped (the operator tool may block a little instead).
_QOS: dict[str, tuple[zenoh.Priority, zenoh.CongestionControl, bool]] = {
    "command": (zenoh.Priority.REAL_TIME, zenoh.CongestionControl.DROP, True),
    "feedback": (zenoh.Priority.INTERACTIVE_HIGH, zenoh.CongestionControl.DROP, True),
    "setpoint": (zenoh.Priority.INTERACTIVE_HIGH, zenoh.CongestionControl.BLOCK, True),
    "estimate": (zenoh.Priority.DATA, zenoh.CongestionControl.DROP, False),
    "mmae": (zenoh.Priority.DATA, zenoh.CongestionControl.DROP, False),
    "control": (zenoh.Priority.DATA, zenoh.CongestionControl.DROP, False),
    "status": (zenoh.Priority.DATA, zenoh.CongestionControl.DROP, False),
}

#: Typed parser of each topic where one exists; the others give validated dicts.
_TYPED_PARSERS: dict[str, Callable[[bytes], Any]] = {
    "command": schemas.parse_command,
    "feedback": schemas.parse_feedback,
    "setpoint": schemas.parse_setpoint,
}


def default_parser(topic: str) -> Callable[[bytes], Any]:
    """Parser used by :meth:`ZenohNode.subscribe` when none is given."""
    if topic not in TOPICS:
        raise ValueError(f"unknown topic {topic!r}: expected one of {', '.join(TOPICS)}")
    return _TYPED_PARSERS.get(topic) or functools.partial(schemas.parse_message, topic)


class ZenohNode:
    """One zenoh session bound to one vessel's keys, and everything declared on it.

    Parameters
    ----------
    config : ZenohConfig
        Explicit session configuration.
    vessel : str
        Vessel ID (validated: see :func:`interfaces.zenoh.keys.validate_vessel_id`).
    clock : callable, optional
        Receive-time clock [s] (``time.monotonic`` by default; the runtime may inject its own).

    Raises
    ------
    ValueError
        Invalid vessel ID.
    interfaces.zenoh.session_config.ZenohOpenError
        The session could not be opened.
    """

    def __init__(self, config: ZenohConfig, vessel: str, *, clock: Clock = time.monotonic) -> None:
        self.keys = VesselKeys(vessel)
        self.config = config
        self._clock = clock
        self._entities: list[Any] = []
        self._peers: set[str] = set()
        self._declared_roles: set[str] = set()
        self._peer_cond = threading.Condition()
        self._closed = False
        self.session = open_session(config, vessel)
        try:
            self._transports = self.session.info.declare_transport_events_listener(self._on_transport, history=True)
        except Exception:
            self.session.close()
            raise

    # -- peers -----------------------------------------------------------------------------

    def _on_transport(self, event: Any) -> None:
        try:
            zid = str(event.transport.zid)
            with self._peer_cond:
                if event.kind == zenoh.SampleKind.PUT:
                    self._peers.add(zid)
                else:
                    self._peers.discard(zid)
                self._peer_cond.notify_all()
        except Exception:
            log.exception("zenoh transport listener: unexpected error")

    def peers(self) -> frozenset[str]:
        """Zenoh IDs of the nodes this session has a transport to right now."""
        with self._peer_cond:
            return frozenset(self._peers)

    def link_identities(self) -> dict[str, str | None]:
        """``{zenoh ID: authenticated name}`` of the links open now (the TLS certificate's common name a peer
        presented; ``None`` on a plaintext link)."""
        try:
            return {str(link.zid): link.auth_identifier for link in self.session.info.links()}
        except Exception as exc:  # a closing session: nobody is linked
            log.debug("zenoh links: %s", exc)
            return {}

    def identity_of(self, zid: str | None) -> str | None:
        """The authenticated name (certificate common name) of the peer session ``zid`` links to us, if any."""
        return None if zid is None else self.link_identities().get(zid)

    def wait_for_peers(self, count: int = 1, timeout_s: float = 5.0) -> bool:
        """Block until at least ``count`` peers are connected, or ``timeout_s`` passes."""
        with self._peer_cond:
            return self._peer_cond.wait_for(lambda: len(self._peers) >= count, timeout_s)

    # -- declarations ----------------------------------------------------------------------

    def _check_open(self) -> None:
        if self._closed:
            raise RuntimeError("zenoh node is closed")

    def _keep(self, entity: T) -> T:
        self._entities.append(entity)
        return entity

    def publisher(self, topic: str) -> TopicPublisher:
        """Declare the publisher of ``topic`` (``command``, ``estimate``, … — see :data:`keys.TOPICS`)."""
        self._check_open()
        key = self.keys.topic(topic)
        priority, congestion, express = _QOS[topic]
        return self._keep(TopicPublisher(self.session, key, priority=priority, congestion_control=congestion,
                                         express=express, attach_source=topic == "setpoint"))

    @overload
    def subscribe(self, topic: str, sink: SinkT, *, parse: Callable[[bytes], Any] | None = None,
                  remote_only: bool = False) -> TopicSubscriber[SinkT]: ...

    @overload
    def subscribe(self, topic: str, sink: None = None, *, parse: Callable[[bytes], Any] | None = None,
                  remote_only: bool = False) -> TopicSubscriber[_Sink[Received[Any]]]: ...

    def subscribe(self, topic: str, sink: _Sink[Received[Any]] | None = None, *,
                  parse: Callable[[bytes], Any] | None = None, remote_only: bool = False) -> TopicSubscriber[Any]:
        """Subscribe to ``topic`` with validation.

        Parameters
        ----------
        topic : str
        sink : LatestSlot or Inbox, optional
            Where validated :class:`Received` messages go; default :class:`Inbox` for setpoints
            (every request counts), :class:`LatestSlot` otherwise. Pass one to have its own methods
            (``latest``, ``drain``, ...) type-checked on ``subscriber.sink``: the default is typed as
            any sink, the topic deciding which.
        parse : callable, optional
            ``bytes -> message | Rejected``; default: the typed parser for ``command``,
            ``feedback``, ``setpoint`` (e.g. pass ``functools.partial(parse_feedback,
            thruster_names=...)`` to reject unknown thrusters), validated dicts otherwise.
        remote_only : bool
            Hear other sessions only, not this one's own publications (a publisher that listens for
            anybody else publishing on its key).
        """
        self._check_open()
        key = self.keys.topic(topic)
        if sink is None:
            sink = Inbox() if topic == "setpoint" else LatestSlot()
        return self._keep(TopicSubscriber(self.session, key, parse or default_parser(topic), sink, self._clock,
                                          remote_only=remote_only))

    def serve_config(self, provider: bytes | Callable[[], bytes]) -> ConfigServer:
        """Declare the ``dp/<vessel>/config`` queryable (see :func:`schemas.config_payload`)."""
        self._check_open()
        return self._keep(ConfigServer(self.session, self.keys.config, provider))

    def query_config(self, timeout_s: float = 2.0) -> dict[str, Any] | Rejected:
        """Ask the ``dp/<vessel>/config`` queryable; the validated ``dpcontrol.config/1`` payload or why not.

        Waits up to ``timeout_s`` in total: first for a queryable to be known on the network (a
        monitor started together with the daemon would otherwise ask before the declaration
        reached it), then for the reply.
        """
        self._check_open()
        deadline = time.monotonic() + timeout_s
        matched = threading.Event()
        querier = self.session.declare_querier(self.keys.config, timeout=timeout_s)
        try:
            listener = querier.declare_matching_listener(
                lambda status: matched.set() if getattr(status, "matching", False) else None)
            try:
                if getattr(querier.matching_status, "matching", False):
                    matched.set()
                if not matched.wait(max(0.0, deadline - time.monotonic())):
                    return Rejected("no_reply", f"{self.keys.config}: no config queryable within {timeout_s:g} s")
            finally:
                _undeclare(listener, "config querier matching listener")
            for reply in querier.get():  # ends when every queryable answered or on timeout
                sample = reply.ok
                if sample is not None:
                    return schemas.parse_message("config", sample.payload.to_bytes())
                error = reply.err
                text = error.payload.to_bytes().decode("utf-8", "replace") if error is not None else "?"
                return Rejected("reply_error", f"{self.keys.config}: {text[:200]}")
        except zenoh.ZError as exc:
            return Rejected("no_reply", f"{self.keys.config}: query failed: {exc}")
        finally:
            _undeclare(querier, "config querier")
        return Rejected("no_reply", f"{self.keys.config}: no reply within {timeout_s:g} s")

    def declare_alive(self, role: str) -> AliveToken:
        """Declare this process's liveliness token (``controller`` or ``plant``)."""
        self._check_open()
        self._declared_roles.add(role)
        return self._keep(AliveToken(self.session, self.keys.alive(role)))

    def alive_elsewhere(self, role: str, settle_s: float = 0.5) -> bool:
        """Whether another session holds the ``dp/<vessel>/alive/<role>`` token (ask before declaring one's own).

        Watches the token with its history for ``settle_s`` [s] and answers whether it is present at the
        end: the peers' declarations reach a session a few milliseconds after it opens (a liveliness
        *query* right after opening finds nothing). A peer not connected within that time is not seen.

        Raises
        ------
        RuntimeError
            This node declared that token itself (it would find its own).
        """
        self._check_open()
        if role in self._declared_roles:
            raise RuntimeError(f"this node holds the {role!r} token itself")
        watcher = LivelinessWatcher(self.session, self.keys.alive(role), clock=self._clock)
        try:
            # Present at the end of the window, not "seen at all": a new history subscriber is sometimes
            # told of a token undeclared just before, then of its loss (8–10 times in 30 on loopback).
            time.sleep(settle_s)
            return watcher.present
        finally:
            watcher.close()

    def watch_alive(self, role: str, on_change: Callable[[bool, float], None] | None = None) -> LivelinessWatcher:
        """Watch a peer's liveliness token (``controller`` or ``plant``)."""
        self._check_open()
        return self._keep(LivelinessWatcher(self.session, self.keys.alive(role), clock=self._clock,
                                            on_change=on_change))

    # -- shutdown --------------------------------------------------------------------------

    def close(self, timeout_s: float = 2.0) -> bool:
        """Undeclare everything (tokens first: peers see us go at once) and close the session.

        Returns ``False`` if the session did not close within ``timeout_s`` (it is then left to
        finish in a daemon thread; the process can still exit).
        """
        if self._closed:
            return True
        self._closed = True
        # Tokens first (peers see us go at once), then the rest in reverse order of declaration.
        ordered = sorted(reversed(self._entities), key=lambda e: not isinstance(e, AliveToken))
        for entity in ordered:
            try:
                entity.close()
            except Exception:  # keep closing the others
                log.exception("zenoh: closing %r failed", entity)
        self._entities.clear()
        _undeclare(self._transports, "transport events listener")
        closer = threading.Thread(target=self._close_session, name="zenoh-close", daemon=True)
        closer.start()
        closer.join(timeout_s)
        if closer.is_alive():
            log.warning("zenoh session did not close within %.1f s", timeout_s)
            return False
        return True

    def _close_session(self) -> None:
        try:
            self.session.close()
        except Exception as exc:
            log.warning("zenoh session close: %s", exc)

    @property
    def closed(self) -> bool:
        return self._closed

    def __enter__(self) -> ZenohNode:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
