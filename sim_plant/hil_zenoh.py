"""The HIL emulator's Zenoh side: the drives (commands in, feedback out), liveliness, and the operator.

:class:`PlantZenoh` holds one explicit peer session (:class:`interfaces.zenoh.ZenohNode`: endpoints
from the controller configuration, multicast scouting off) with

* a validating subscriber of ``dp/<vessel>/thrusters/command`` into a bounded FIFO that the
  emulator loop drains every tick (each command keeps its raw bytes for the recorder; unknown
  thrusters, NaN, wrong schema … are rejected and counted by the subscriber);
* the publisher of ``dp/<vessel>/thrusters/feedback`` (used by the loop only);
* the ``dp/<vessel>/alive/plant`` liveliness token, and a watcher of ``alive/controller`` whose
  changes are queued (with their plant time) for the loop, which calls ``plant.command_lost`` on a
  loss;
* a ``dp/<vessel>/status`` subscriber and the ``dp/<vessel>/setpoint`` publisher, used by
  :class:`Operator`.

:class:`Operator` is a thread that plays the operator station when asked to (``engage``; otherwise it
sends nothing): it publishes the scenario's setpoints at their (plant) times, sends the setpoint in
force again whenever the controller's liveliness appears (a daemon started late, or restarted, still
gets its target), and asks for DP (``auto_position``; ``auto_heading`` for a heading-only scenario)
as an operator does: once the controller's status shows what the mode needs (the drives heard, a thruster
available, a heading reference and, for ``auto_position``, a position reference in state ``ok``), or once
``engage_timeout_s`` has passed without that (the daemon's refusal then says why), repeating the request
until the status shows that mode or the timeout passes again. It runs beside the real-time loop so that a
blocking setpoint publisher (setpoints are never dropped, see :mod:`interfaces.zenoh.node`) cannot delay a
sensor sample.
"""

from __future__ import annotations

import collections
import functools
import logging
import math
import threading
import time
from collections.abc import Callable, Collection, Sequence
from dataclasses import dataclass
from typing import Any

from interfaces.messages import Rejected
from interfaces.zenoh import schemas
from interfaces.zenoh.node import Inbox, LatestSlot, Received, ZenohNode
from interfaces.zenoh.session_config import ZenohConfig
from sim_plant.scenario import Setpoint

log = logging.getLogger(__name__)

Clock = Callable[[], float]
COMMAND_INBOX = 256  # commands held between two loop ticks (≥ 10 Hz daemon × a 25 s stall)


@dataclass(frozen=True, slots=True)
class ReceivedCommand:
    """A validated thruster command and the bytes it came in (for the recorder)."""

    raw: bytes
    message: schemas.CommandMessage


def parse_command_keeping_raw(payload: bytes, *,
                              thruster_names: Collection[str]) -> ReceivedCommand | Rejected:
    """:func:`interfaces.zenoh.schemas.parse_command` that keeps the raw payload with the result."""
    result = schemas.parse_command(payload, thruster_names=thruster_names)
    if isinstance(result, Rejected):
        return result
    return ReceivedCommand(bytes(payload), result)


class PlantZenoh:
    """The plant's zenoh session (see the module docstring).

    Parameters
    ----------
    config : ZenohConfig
        Explicit session configuration.
    vessel : str
        Vessel ID (the daemon's ``vessel_id``).
    thruster_names : sequence of str
        The plant's drives (commands naming others are rejected).
    clock : callable
        Plant time [s]: receive times of commands and liveliness changes are stamped with it.

    Raises
    ------
    interfaces.zenoh.ZenohOpenError
        The session could not be opened (an endpoint that cannot be bound ...).
    """

    def __init__(self, config: ZenohConfig, vessel: str, thruster_names: Sequence[str], *, clock: Clock) -> None:
        self.thruster_names = tuple(thruster_names)
        self._clock = clock
        self._events: collections.deque[tuple[float, bool]] = collections.deque()
        self._history: list[dict[str, Any]] = []
        self._lock = threading.Lock()
        self._listeners: list[Callable[[], None]] = []
        self.node = ZenohNode(config, vessel, clock=clock)
        # the subscribers' sinks, kept with their item types (a subscriber's .sink is typed as any sink)
        self._command_inbox: Inbox[Received[ReceivedCommand]] = Inbox(maxlen=COMMAND_INBOX)
        self._status_slot: LatestSlot[Received[dict[str, Any]]] = LatestSlot(on_put=self._notify)
        try:
            self.commands = self.node.subscribe(
                "command", self._command_inbox,
                parse=functools.partial(parse_command_keeping_raw, thruster_names=set(self.thruster_names)))
            self.feedback = self.node.publisher("feedback")
            self.status = self.node.subscribe("status", self._status_slot)
            self.setpoint = self.node.publisher("setpoint")
            self.controller = self.node.watch_alive("controller", on_change=self._on_controller)
            self.token = self.node.declare_alive("plant")
        except BaseException:
            self.node.close()
            raise

    # -- liveliness of the controller (zenoh thread → loop) ----------------------------------------
    def _on_controller(self, present: bool, t_s: float) -> None:
        self._events.append((t_s, present))  # deque.append is atomic: no lock on zenoh's thread
        with self._lock:
            self._history.append({"t_s": t_s, "role": "controller", "present": present})
        self._notify()

    def _notify(self) -> None:
        for listener in self._listeners:
            listener()

    def add_listener(self, callback: Callable[[], None]) -> None:
        """Call ``callback`` (tiny, never blocking) on a controller liveliness change or a new status."""
        self._listeners.append(callback)

    def take_liveliness(self) -> list[tuple[float, bool]]:
        """Controller liveliness changes ``(plant t_s, present)`` since the last call, oldest first."""
        events = []
        while self._events:
            events.append(self._events.popleft())
        return events

    @property
    def liveliness_history(self) -> list[dict[str, Any]]:
        """Every controller liveliness change so far (``t_s``, ``role``, ``present``)."""
        with self._lock:
            return list(self._history)

    # -- drives --------------------------------------------------------------------------------------
    def take_commands(self) -> list[Received[ReceivedCommand]]:
        """The commands received since the last call, oldest first."""
        return self._command_inbox.drain()

    def latest_status(self) -> Received[dict[str, Any]] | None:
        """The controller's newest status (None before the first), without consuming it."""
        return self._status_slot.latest()

    def publish_feedback(self, t_s: float, names: Sequence[str], thrust_n: Sequence[float],
                         azimuth_rad: Sequence[float], ready: Sequence[bool]) -> tuple[int, bytes | None]:
        """Publish one feedback message; returns its ``seq`` and payload (None if zenoh refused it)."""
        seq = self.feedback.next_seq()
        payload = schemas.feedback_payload(t_s=t_s, seq=seq, names=names, thrust_n=thrust_n,
                                           azimuth_rad=azimuth_rad, ready=ready)
        return seq, (payload if self.feedback.put(payload) else None)

    def snapshot(self) -> dict[str, Any]:
        """Counters for the summary."""
        stats = self.commands.stats
        return {
            "endpoints": {"listen": list(self.node.config.listen), "connect": list(self.node.config.connect)},
            "peers": len(self.node.peers()),
            "commands": {"received": stats.received, "accepted": stats.accepted, "rejected": stats.rejected,
                         "dropped_inbox_full": self._command_inbox.dropped,
                         "last_rejection": None if stats.last_rejection is None else
                         f"{stats.last_rejection.reason}: {stats.last_rejection.detail}"},
            "feedback_put_failures": self.feedback.failures,
            "status_received": self._status_slot.count,
        }

    def close(self) -> None:
        """Undeclare the token first (the daemon sees the plant go at once), then close the session."""
        self.node.close()


def ready_to_engage(status: dict[str, Any], mode: str) -> bool:
    """Whether a controller status shows what ``mode`` needs, as the operator reads it before asking: the
    drives heard and a thruster available, a heading reference and (``auto_position``) a position reference
    in state ``ok``. A request sent before that is refused by the daemon (``operator.request_refused``)."""
    drives = status.get("drives")
    if drives is not None and not drives.get("present"):
        return False
    if not any(thruster.get("available") for thruster in status.get("thrusters", ())):
        return False
    kinds_ok = {sensor.get("kind") for sensor in status.get("sensors", ()) if sensor.get("state") == "ok"}
    needed = {"heading", "position"} if mode == "auto_position" else {"heading"}
    return needed <= kinds_ok


class Operator:
    """The operator station of a HIL run (see the module docstring).

    Parameters
    ----------
    zenoh : PlantZenoh
    setpoints : sequence of Setpoint
        The scenario's setpoints (plant times).
    clock : callable
        Plant time [s].
    speed : float
        Plant seconds per wall second (to turn plant time differences into waits).
    engage : bool
        Request DP once the controller is up.
    engage_mode : str
        The mode to request (``auto_position`` or ``auto_heading``).
    engage_timeout_s, engage_retry_s : float
        Wall time [s] to keep trying after the first request, and between requests.
    """

    def __init__(self, zenoh: PlantZenoh, setpoints: Sequence[Setpoint], clock: Clock, *, speed: float = 1.0,
                 engage: bool = False, engage_mode: str = "auto_position", engage_timeout_s: float = 60.0,
                 engage_retry_s: float = 2.0) -> None:
        if engage_mode not in schemas.MODES:
            raise ValueError(f"engage_mode must be one of {', '.join(schemas.MODES)}")
        self._zenoh = zenoh
        self._setpoints = tuple(setpoints)
        self._clock = clock
        self._speed = speed
        self._engage = engage
        self._mode = engage_mode
        self._timeout_s = engage_timeout_s
        self._retry_s = engage_retry_s
        self._wake = threading.Event()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._lock = threading.Lock()
        self._published: list[dict[str, Any]] = []
        self._engage_state: dict[str, Any] = {"requested": engage, "mode": engage_mode if engage else None,
                                              "engaged": False, "attempts": 0, "t_s": None, "gave_up": False}
        self._first_request: float | None = None  # wall time of the first mode request
        self._first_status: float | None = None  # wall time of the controller's first status
        self._next_request = -math.inf
        zenoh.add_listener(self._wake.set)

    def start(self) -> None:
        """Start the operator thread (once the plant clock runs)."""
        if self._thread is None:
            self._thread = threading.Thread(target=self._run, name="hil-operator", daemon=True)
            self._thread.start()

    def stop(self, timeout_s: float = 5.0) -> None:
        """Stop the thread (a setpoint being published is finished first)."""
        self._stop.set()
        self._wake.set()
        if self._thread is not None:
            self._thread.join(timeout_s)

    @property
    def published(self) -> list[dict[str, Any]]:
        """Setpoints published so far (scheduled ``t_s``, ``sent_t_s``, target, ``resent``)."""
        with self._lock:
            return list(self._published)

    @property
    def engage_state(self) -> dict[str, Any]:
        with self._lock:
            return dict(self._engage_state)

    def _publish_setpoint(self, point: Setpoint, now: float, resent: bool) -> None:
        publisher = self._zenoh.setpoint
        payload = schemas.setpoint_payload(t_s=now, seq=publisher.next_seq(), north_m=point.north_m,
                                           east_m=point.east_m, heading_rad=point.heading_rad)
        ok = publisher.put(payload)
        with self._lock:
            self._published.append({"t_s": point.t_s, "sent_t_s": now, "north_m": point.north_m,
                                    "east_m": point.east_m, "heading_rad": point.heading_rad, "resent": resent,
                                    "ok": ok})

    def _run(self) -> None:
        try:
            self._loop()
        except Exception:  # the operator must not take the emulator down; the run goes on without it
            log.exception("HIL operator failed")

    def _loop(self) -> None:
        # The scenario's setpoints are operator requests: sent only when the operator role was asked for
        # (``engage``), never by a plant merely standing in for the drives (a restarted plant would otherwise
        # move the vessel's set-point by itself).
        next_index = 0 if self._engage else len(self._setpoints)
        current: Setpoint | None = None
        controller_seen = self._zenoh.controller.present
        while not self._stop.is_set():
            now = self._clock()
            while next_index < len(self._setpoints) and self._setpoints[next_index].t_s <= now:
                current = self._setpoints[next_index]
                next_index += 1
                self._publish_setpoint(current, now, resent=False)
            present = self._zenoh.controller.present
            if present and not controller_seen and current is not None:
                self._publish_setpoint(current, now, resent=True)  # a (re)started daemon gets its target
            controller_seen = present
            wait_s = math.inf
            if next_index < len(self._setpoints):
                wait_s = (self._setpoints[next_index].t_s - now) / self._speed
            if self._engage:
                wait_s = min(wait_s, self._engage_step(present, now, time.monotonic()))
            self._wake.wait(max(0.0, wait_s) if math.isfinite(wait_s) else None)
            self._wake.clear()

    def _engage_step(self, present: bool, now: float, wall: float) -> float:
        """One look at the DP handshake; returns how long [s] to wait before looking again (inf: done).

        Status arrivals and liveliness changes wake the thread earlier (listeners).
        """
        state = self._engage_state
        if state["engaged"] or state["gave_up"]:
            return math.inf
        status = self._zenoh.latest_status()
        if not present or status is None:
            return math.inf  # wait for the controller and its first status
        if status.message.get("mode") == self._mode:
            with self._lock:
                state.update(engaged=True, t_s=now)
            log.info("controller is in %s", self._mode)
            return math.inf
        if self._first_status is None:
            self._first_status = wall
        if self._first_request is None and not ready_to_engage(status.message, self._mode) \
                and wall < self._first_status + self._timeout_s:
            return self._retry_s  # (a status arrival wakes the thread sooner)
        if self._first_request is not None and wall >= self._first_request + self._timeout_s:
            with self._lock:
                state["gave_up"] = True
            log.warning("controller did not enter %s within %.0f s of the first request", self._mode, self._timeout_s)
            return math.inf
        if wall >= self._next_request:
            publisher = self._zenoh.setpoint
            publisher.put(schemas.setpoint_payload(t_s=now, seq=publisher.next_seq(), mode=self._mode))
            with self._lock:
                state["attempts"] += 1
            if self._first_request is None:
                self._first_request = wall
            self._next_request = wall + self._retry_s
        return self._next_request - wall
