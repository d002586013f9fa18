"""``dpcontrol run``: the control loop on a monotonic clock, with real transports and Zenoh.

Threads: each transport has its reader thread (interfaces/…/transport.py, chosen by
:mod:`dpcontrol.service.transports`) that hands what it received, undecoded, to :class:`InputPump`'s queue
(decoded and routed in the loop thread by :mod:`dpcontrol.runtime.ingest`); Zenoh callbacks fill the
setpoint inbox and the feedback slot. The loop thread (the main thread) owns everything else: at every
deadline it drains the inputs, runs :meth:`DpController.step` (the same step the lockstep simulation runs), publishes
the command first, then estimate, MMAE, control and status, records, persists its state and — only
then, from this healthy loop — sends ``WATCHDOG=1`` to systemd (docs/design.md §5: a side thread pinging
the watchdog would keep a hung loop "alive").

Deadline scheduling: deadlines are ``t0 + k·T``; a late cycle runs at once, cycles that are missed
entirely are counted and skipped (the next deadline is the next one in the future), so the loop
never drifts and never bursts. The loop sleeps until ``loop.deadline_spin_ms`` before a deadline and
spins the rest with the GIL released (:mod:`dpcontrol.service.spin`): the cycle typically starts
within one ~20 µs spin slice of its deadline instead of a timer wake-up later.

SIGTERM/SIGINT: the loop commands zero thrust (standby) as its last command, publishes a final
status, saves its state, closes the recorder and exits 0.
"""

from __future__ import annotations

import collections
import copy
import dataclasses
import functools
import gc
import logging
import math
import os
import signal
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from dpcontrol.platform_info import HostStealWindow
from dpcontrol.runtime.alarms import AlarmEvent, AlarmJournal, AlarmRegistry, CountAlarm, Severity
from dpcontrol.runtime.config import DaemonConfig, config_summary
from dpcontrol.runtime.consequence import ConsequenceReport
from dpcontrol.runtime.ingest import transport_inputs
from dpcontrol.runtime.inputs import SensorRouter
from dpcontrol.runtime.step import RECENT_REQUESTS_S, DpController, Mode, StepOutput
from dpcontrol.runtime.thruster_monitor import ThrusterFeedback
from dpcontrol.runtime.transport_health import InputHealth
from dpcontrol.service.persist import BackgroundSaver, StateStore
from dpcontrol.service.replica import ControllerReplica
from dpcontrol.service.spin import DeadlineSpinner, loop_spinner
from dpcontrol.service.transports import InputEvent, RawInput, Reader, ReaderOptions, open_reader
from interfaces.messages import LinkStatus, Measurement, RejectedInput
from interfaces.recorder import Recorder, TopicSpec, default_topics
from interfaces.systemd import SystemdNotifier
from interfaces.zenoh import schemas
from interfaces.zenoh.node import Inbox, LatestSlot, Received, TopicSubscriber, ZenohNode
from interfaces.zenoh.pki import days_left
from interfaces.zenoh.schemas import SetpointRequest
from interfaces.zenoh.security import EXPIRY_WARNING_DAYS, unprotected_endpoints

log = logging.getLogger(__name__)

TIMING_WINDOW = 2048
# Raw inputs waiting for the loop: 25 s of a saturated 250 kbit/s NMEA 2000 bus (about 2000 frames/s), so
# nothing a sensor legitimately sends is ever dropped, while a flood on a UDP port
# or a loop stalled until the watchdog restarts it cannot grow the daemon's memory without bound.
MAX_PENDING_INPUTS = 50_000
# How long the start-up waits for the peers' liveliness tokens before declaring its own controller token [s]
# (they arrive within milliseconds on a LAN; a peer not connected by then is caught by its commands later)
CONTROLLER_CHECK_S = 0.5
RUNTIME_TOPICS = (
    TopicSpec("cycle", "dpcontrol.cycle",
              "What one control step consumed: the raw-input sequence numbers of its measurements, link "
              "changes, thruster feedback and operator requests, each with the role and identity (certificate common "
              "name) it came in under (dpcontrol replay feeds exactly these).",
              {"cycle": {"type": "integer"}, "inputs": {"type": "array"}, "links": {"type": "array"},
               "feedback": {"type": "array"}, "requests": {"type": "array"}}),
    TopicSpec("consequence", "dpcontrol.consequence",
              "The worst-case failure check: the demand checked and, per failure group, whether the thrusters "
              "left would hold it, the shortfall and the largest thrust of those left as a share of its rating.",
              {"demand_b": {"type": "array"}, "groups": {"type": "array"}}),
    TopicSpec("state_loaded", "dpcontrol.state", "Persisted state the daemon resumed from (bumpless restart).",
              {"state": {"type": "object"}}),
)
def status_payload(controller: DpController, alarms: AlarmRegistry, t_s: float, seq: int,
                   cycle: schemas.CycleTiming | None = None, *, drives: schemas.DrivesSeen | None = None) -> bytes:
    """The ``dp/<vessel>/status`` payload: mode, per-sensor health, alarms (active and recently cleared),
    thruster availability, cycle timing, the outcome of the last operator request (and of every one taken in
    the last second: several in one cycle, from two consoles, each get their answer) and the last worst-case
    failure check (in DP, when failure groups are configured), and the drives as the daemon sees them
    (``drives``: a monitor or console shows the daemon's view, not its own session's), and in DP what the MRAC's
    mass estimates do (``adaptation``). The lockstep simulation builds the same payload."""
    # texts are bounded by the status schema (256 characters)
    sensors = [schemas.SensorHealth(s["name"], s["kind"], s["state"], s["age_s"], s["weight"], s["detail"][:256])
               for s in controller.hub.sensor_status(t_s)]
    listed = [schemas.Alarm(a.code, a.severity.name.lower(), a.text[:256], a.since_t_s, a.active)
              for a in alarms.listed(t_s)]
    thrusters = [schemas.ThrusterAvailability(t["name"], t["available"], t["detail"][:256])
                 for t in controller.monitor.status()]
    report = None if controller.consequence is None else controller.consequence.last
    consequence = None if report is None else schemas.WorstCaseCheck(
        report.t_s, tuple(report.demand_b.tolist()),
        tuple(schemas.FailureGroupOutcome(o.group, o.holds, o.utilisation, o.busiest) for o in report.outcomes))
    adaptation = controller.adaptation_summary()
    return schemas.status_payload(t_s=t_s, seq=seq, mode=controller.mode.value, sensors=sensors,
                                  alarms=listed, cycle=cycle, thrusters=thrusters, request=controller.last_request,
                                  requests=controller.requests_since(t_s - RECENT_REQUESTS_S), consequence=consequence,
                                  drives=drives,
                                  wave_band=None if controller.wave_band is None else controller.wave_band.summary(),
                                  adaptation=None if adaptation is None else schemas.AdaptationSummary(*adaptation))


def consequence_record(report: ConsequenceReport) -> dict[str, Any]:
    """A worst-case failure check as a JSON-able mapping (the recorder's ``consequence`` topic)."""
    return {"t_s": report.t_s, "demand_b": report.demand_b.tolist(),
            "groups": [{"name": o.group, "holds": o.holds, "shortfall_b": o.shortfall_b.tolist(),
                        "utilisation": o.utilisation if math.isfinite(o.utilisation) else None}
                       for o in report.outcomes]}


def request_as_dict(request: SetpointRequest) -> dict[str, Any]:
    """A setpoint request as a JSON-able mapping (recorded; :func:`request_from_dict` reverses it)."""
    return {name: getattr(request, name) for name in request.__dataclass_fields__}


def request_from_dict(data: dict[str, Any]) -> SetpointRequest:
    return SetpointRequest(**data)


class InputPump:
    """Starts the transport readers; decodes, counts and routes what they received in the loop thread.

    The readers (:mod:`dpcontrol.service.transports`, one per configured transport, chosen by configuration) hand
    every raw input and link change, undecoded, to one deque from their threads (thread-safe appends); the loop
    drains it once per cycle through the input stage (:mod:`dpcontrol.runtime.ingest`: the code the lockstep
    simulation, replay and the bench run). At most ``max_pending`` raw inputs wait in it: beyond that, new ones
    are dropped and counted (:attr:`dropped`; the daemon raises ``inputs.overflow``); link changes never are.

    Every raw input gets a sequence number, recorded with it; every measurement is attributed the number of the
    raw input it came from, and every cycle records which it consumed: replay is exact.
    """

    def __init__(self, config: DaemonConfig, clock: Callable[[], float], recorder: Recorder | None = None,
                 max_pending: int | None = None) -> None:
        self.config = config
        self.clock = clock
        self.router = SensorRouter(config.routes, config.transports)
        self.recorder = recorder
        self._queue: collections.deque[tuple[str, InputEvent]] = collections.deque()
        self.max_pending = MAX_PENDING_INPUTS if max_pending is None else max_pending
        # inputs dropped because the queue was full, since the start (written by reader threads under
        # the lock: rare by construction, so the lock is off the normal path)
        self.dropped = 0
        self._dropped_lock = threading.Lock()
        self._readers: list[Reader] = []
        # decoded / malformed frames per transport and link changes: the same code as the lockstep runs
        self.health = InputHealth([t.name for t in config.transports], self.router, config.hub.error_rate_alarm,
                                  config.hub.error_rate_window_s)
        self.stages = transport_inputs(config.transports, self.router, self.health, on_raw=self._numbered,
                                       start_t_s=clock(), signing_time_s=time.time())
        self.decode_errors = 0  # inputs whose decoding raised (counted as rejected; see _decode_failed)
        self._seq = 0  # the last raw input's number (loop thread only)
        # where each raw input of the current drain starts in its measurement list: (index, number)
        self._starts: list[tuple[int, int]] = []
        self._out: list[Measurement] = []

    # ---------------------------------------------------------------- readers
    def start(self) -> None:
        for transport in self.config.transports:
            name = transport.name
            options = ReaderOptions(self.clock, request_address_claims=any(
                route.source_name is not None for route in self.router.routes_of(name)))
            try:
                reader = open_reader(transport, functools.partial(self.received, name), options)
                reader.start()
            except Exception as error:  # a missing device must not stop the controller (it reconnects)
                log.error("transport %s could not start: %s", name, error)
                self._queue.append((name, LinkStatus(self.clock(), name, False, f"start failed: {error}")))
                continue
            self._readers.append(reader)

    def received(self, transport: str, event: InputEvent) -> None:
        """A reader's event (any thread): queued for the loop, unless ``max_pending`` raw inputs already wait."""
        if isinstance(event, LinkStatus) or len(self._queue) < self.max_pending:
            self._queue.append((transport, event))
            return
        with self._dropped_lock:
            self.dropped += 1

    # ---------------------------------------------------------------- the loop side
    def drain(self, t_s: float, measurements: list[Measurement], links: list[LinkStatus], sources: list[int]) -> None:
        """Decode and route everything received since the last call, in arrival order, into ``measurements``
        (``sources``: the raw input number of each) and ``links``; then what time alone decides at ``t_s`` (s):
        fast packets given up, MAVLink heartbeat timeouts."""
        queue = self._queue
        stages = self.stages
        first = len(measurements)
        starts = self._starts
        starts.clear()
        self._out = measurements
        while queue:
            transport, event = queue.popleft()
            try:
                self._consume(transport, event, measurements, links)
            except Exception as error:  # (the codecs are fuzzed not to raise: belt and braces for the loop)
                self._decode_failed(transport, event.t_s, error)
        for transport, stage in stages.items():
            try:
                stage.poll(t_s, links)
            except Exception as error:
                self._decode_failed(transport, t_s, error)
        # each measurement's raw input: the last one that started at or before its place in the list
        k = 0
        seq = 0
        for i in range(first, len(measurements)):
            while k < len(starts) and starts[k][0] <= i:
                seq = starts[k][1]
                k += 1
            sources.append(seq)

    def _consume(self, transport: str, event: InputEvent, measurements: list[Measurement],
                 links: list[LinkStatus]) -> None:
        """One reader event through the transport's input stage."""
        stage = self.stages[transport]
        if type(event) is RawInput:
            stage.feed(event.t_s, event.data, measurements, can_id=event.can_id)
        elif isinstance(event, LinkStatus):
            stage.link_changed(event.t_s, event.connected, measurements)
            links.append(LinkStatus(event.t_s, transport, event.connected, event.detail))
        elif isinstance(event, RejectedInput):  # a gateway's framing could not read it: no raw input
            self.health.count(transport, event.t_s, event.rejected.reason)
            if self.recorder is not None:
                self.recorder.record_raw(transport, event.t_s, event.rejected.raw, rejected=event.rejected.reason)

    def _decode_failed(self, transport: str, t_s: float, error: Exception) -> None:
        """A decoder raised on what a sensor sent: the input is counted as rejected (``decode_error``, which the
        transport's error-rate alarm sees) and the loop goes on with the next one — a sensor's bytes never stop the
        control step (which would command zero thrust)."""
        self.decode_errors += 1
        self.health.count(transport, t_s, "decode_error")
        if self.decode_errors == 1 or self.decode_errors % 1000 == 0:  # (a flood must not flood the log)
            log.error("transport %s: decoding raised (%d so far): %r", transport, self.decode_errors, error)

    def _numbered(self, transport: str, t_s: float, data: bytes, rejected: str | None,
                  fields: dict[str, Any]) -> None:
        """The input stage shows a raw input (loop thread): number it, note where its measurements start,
        record it."""
        self._seq += 1
        self._starts.append((len(self._out), self._seq))
        if self.recorder is not None:
            self.recorder.record_raw(transport, t_s, data, rejected=rejected, seq=self._seq, **fields)

    def close(self) -> None:
        for reader in self._readers:
            try:
                reader.close()
            except Exception:  # closing must go on for the others
                log.exception("closing a transport reader failed")


class StepErrorLog:
    """Logs a failing control step without flooding the journal at the loop rate.

    The first failure of a run of failures, and each failure whose error differs from the one before,
    is logged with its traceback; the same error again is summarised once per ``repeat_s`` (s, loop
    clock) with the count; the first good step after failures is logged too. (Under systemd the watchdog
    restarts a daemon whose step keeps failing; run by hand it would otherwise log 10 tracebacks a second.)
    """

    def __init__(self, repeat_s: float = 10.0) -> None:
        self.repeat_s = repeat_s
        self._last_text: str | None = None
        self._last_logged_t = -math.inf
        self._unlogged = 0

    def failed(self, t_s: float, error: BaseException, in_a_row: int) -> None:
        text = f"{type(error).__name__}: {error}"
        if text != self._last_text:
            self._last_text = text
            self._last_logged_t = t_s
            self._unlogged = 0
            log.error("control step failed (%d in a row)", in_a_row, exc_info=error)
        elif t_s - self._last_logged_t >= self.repeat_s:
            self._last_logged_t = t_s
            log.error("control step still failing (%d in a row, %d since the last report): %s",
                      in_a_row, self._unlogged + 1, text)
            self._unlogged = 0
        else:
            self._unlogged += 1

    def recovered(self, failures: int) -> None:
        log.warning("control step recovered after %d failed cycles (last error: %s)", failures, self._last_text)
        self._last_text = None
        self._last_logged_t = -math.inf
        self._unlogged = 0


class GarbagePacer:
    """Python's cyclic garbage collection at a point of the control loop's choosing, not the allocator's.

    Automatic collection starts wherever an allocation crosses the threshold: inside a control step, or in
    a sensor reader's thread while it holds the GIL the step needs. On the HIL demo (2026-12-03) that was 59
    collections of the youngest generation in 116 s, 63 µs median and 260 µs at most each, in about one cycle
    in twenty. While a pacer is active, automatic collection is off and :meth:`collect` — called by the loop
    once the cycle's command, status and record are out — collects as the interpreter would have (the same
    thresholds, the same choice of generation), in the slack before the next deadline. Objects allocated by
    every thread are collected there. The daemon freezes what start-up allocated (``gc.freeze``) first, so
    even a full collection walks only what the loop has allocated since.
    """

    def __init__(self) -> None:
        self.thresholds = gc.get_threshold()
        self._was_enabled = gc.isenabled()
        gc.disable()
        self.collections = [0, 0, 0]  # per generation collected
        self.max_us = [0.0, 0.0, 0.0]
        self.total_us = 0.0

    def collect(self) -> int | None:
        """Collect if the interpreter would have by now; the generation collected, or None."""
        count0, count1, count2 = gc.get_count()
        t0, t1, t2 = self.thresholds
        if t0 <= 0 or count0 < t0:
            return None
        generation = 2 if count1 >= t1 and count2 >= t2 else 1 if count1 >= t1 else 0
        started = time.perf_counter()
        gc.collect(generation)
        elapsed_us = (time.perf_counter() - started) * 1e6
        self.collections[generation] += 1
        self.max_us[generation] = max(self.max_us[generation], elapsed_us)
        self.total_us += elapsed_us
        return generation

    def close(self) -> None:
        """Automatic collection as it was before."""
        if self._was_enabled:
            gc.enable()

    def as_dict(self) -> dict[str, Any]:
        """Collections per generation, the longest per generation [µs] and the total [ms] (``--stats-out``)."""
        return {"collections": list(self.collections), "max_us": [round(v, 1) for v in self.max_us],
                "total_ms": round(self.total_us / 1e3, 3)}


@dataclass
class LoopStats:
    """Cycle timing of the loop (µs), measured on the loop's monotonic clock.

    Per cycle: its duration, the time from its start to the thruster command being published, the
    lateness of its start against the deadline (jitter), and where the time to the command went —
    ``inputs`` (draining the readers, links, setpoints, feedback), ``step`` (the
    controller step) and ``command`` (building and publishing the command) — over the last
    ``TIMING_WINDOW`` cycles. ``step_off_cpu`` is the part of ``step`` in which the loop thread did
    not execute (its wall time less its thread CPU time, ``time.thread_time``): waiting for the GIL
    that another thread of the daemon holds, or its virtual CPU taken by the host (steal time). It
    tells a slow step that computed for long from one that waited — on the 2-core HIL VM the slow
    cycles of the tail were mostly the second kind.
    """

    period_s: float
    durations_us: np.ndarray = field(default_factory=lambda: np.zeros(TIMING_WINDOW))
    publish_us: np.ndarray = field(default_factory=lambda: np.zeros(TIMING_WINDOW))
    jitter_us: np.ndarray = field(default_factory=lambda: np.zeros(TIMING_WINDOW))
    phases_us: np.ndarray = field(default_factory=lambda: np.zeros((TIMING_WINDOW, 4)))
    count: int = 0
    missed_deadlines: int = 0
    step_errors: int = 0

    def add(self, duration_us: float, publish_us: float, jitter_us: float) -> None:
        i = self.count % TIMING_WINDOW
        self.durations_us[i] = duration_us
        self.publish_us[i] = publish_us
        self.jitter_us[i] = jitter_us
        self.count += 1

    def add_phases(self, inputs_us: float, step_us: float, command_us: float, step_cpu_us: float) -> None:
        """The phases of the cycle being timed (call before :meth:`add`); ``step_cpu_us`` is the loop
        thread's CPU time during the step."""
        row = self.phases_us[self.count % TIMING_WINDOW]
        row[0] = inputs_us
        row[1] = step_us
        row[2] = command_us
        row[3] = max(0.0, step_us - step_cpu_us)  # the two clocks differ by their resolution

    def summary(self) -> dict[str, Any]:
        n = min(self.count, TIMING_WINDOW)
        if n == 0:
            return {"cycles": 0, "missed_deadlines": self.missed_deadlines}

        def stats(values: np.ndarray) -> dict[str, float]:
            v = values[:n]
            return {"median": round(float(np.median(v)), 1), "p99": round(float(np.percentile(v, 99)), 1),
                    "max": round(float(np.max(v)), 1)}

        phases = self.phases_us
        return {"cycles": self.count, "window": n, "missed_deadlines": self.missed_deadlines,
                "step_errors": self.step_errors, "cycle_duration_us": stats(self.durations_us),
                "start_to_command_published_us": stats(self.publish_us),
                "period_jitter_us": stats(np.abs(self.jitter_us)),
                "phases_us": {"inputs": stats(phases[:, 0]), "step": stats(phases[:, 1]),
                              "command": stats(phases[:, 2]), "step_off_cpu": stats(phases[:, 3])}}


class Daemon:
    """The ``dpcontrol run`` service.

    Parameters
    ----------
    config : DaemonConfig
    clock : callable
        Monotonic clock [s].
    wall_clock : callable
        Wall clock [s] (persisted-state age across restarts).
    notifier : SystemdNotifier, optional
    """

    def __init__(self, config: DaemonConfig, *, clock: Callable[[], float] = time.monotonic,
                 wall_clock: Callable[[], float] = time.time, notifier: SystemdNotifier | None = None) -> None:
        self.config = config
        self.clock = clock
        self.wall_clock = wall_clock
        self.notifier = notifier or SystemdNotifier()
        self.alarms = AlarmRegistry()
        self.alarm_journal = AlarmJournal(log)
        self.controller = DpController(config, self.alarms)
        self.replica: ControllerReplica | None = None
        self.spinner: DeadlineSpinner | None = None  # (loop.deadline_spin_ms; built when the loop starts)
        self.garbage: GarbagePacer | None = None  # (built when the loop starts: it turns automatic collection off)
        # the persisted state the controller resumed from (a copy taken before loading) and when
        self._resumed_state: tuple[dict[str, Any], float] | None = None
        self.stats = LoopStats(config.sample_time_s)
        self._stop = threading.Event()
        self._stop_requested = False  # set with _stop, and alone by a signal handler (_on_signal says why)
        self.recorder: Recorder | None = None
        self.node: ZenohNode | None = None
        self.pump: InputPump | None = None
        self.saver: BackgroundSaver | None = None
        self.store: StateStore | None = None
        self._publishers: dict[str, Any] = {}
        self._names = [t.name for t in config.vessel.thrusters]
        self._seq = 0
        self._last_state_save = -math.inf
        self._last_stats_t = -math.inf
        self._cycle_summary: dict[str, Any] = {}
        self._host_steal = HostStealWindow(10.0)  # the hypervisor's share of the CPUs, for the status
        self._host_steal_percent: float | None = None
        self.realtime_detail = "normal scheduler"
        self.state_detail = ""
        self._setpoint_rejected = CountAlarm("operator.setpoint_rejected", Severity.INFO)
        self._inputs_overflow = CountAlarm("inputs.overflow", Severity.WARNING)
        self._conflict = CountAlarm("controller.conflict", Severity.CRITICAL)
        self.stopped_by: str | None = None

    @property
    def resumed_from_state(self) -> bool:
        """The controller resumed from a persisted state (else it started cold)."""
        return self._resumed_state is not None

    # ---------------------------------------------------------------- life cycle
    def request_stop(self) -> None:
        """Ask the loop to stop after the current cycle (from another thread; signals use :meth:`_on_signal`)."""
        self._stop_requested = True
        self._stop.set()

    def _on_signal(self, signum: int, _frame: Any = None) -> None:
        """SIGTERM / SIGINT / SIGHUP: stop after the current cycle; the signal is named in the stop's log line.

        Only sets flags. The handler runs on the loop's own thread, between two bytecodes of whatever it
        was doing — possibly inside ``Event.wait``, holding the event's (non-reentrant) lock, which
        ``Event.set`` would then wait for forever: the daemon hung on SIGHUP that way once in a full test
        run (no stop line, killed after 30 s). The loop sees the flag when its current wait ends, within
        one period. No logging here either (the logging lock, the same trap).
        """
        if self.stopped_by is None:
            self.stopped_by = signal.Signals(signum).name
        self._stop_requested = True

    def _open(self) -> None:
        cfg = self.config
        if cfg.recorder.path is not None:
            self.recorder = Recorder(cfg.recorder, topics=default_topics([t.name for t in cfg.transports],
                                                                         extra=RUNTIME_TOPICS),
                                     config={"vessel_id": cfg.vessel_id, "config_sha256": cfg.config_hash,
                                             "text": cfg.source_text},
                                     on_error=None)  # it logs each new error itself; the alarm is raised below
        if cfg.state.path is not None:
            self.store = StateStore(cfg.state.path, cfg.state.period_s, cfg.state.max_age_s,
                                    config_hash=cfg.config_hash)
            # (the saver logs each new error itself; the alarm is raised from the loop, in _persist)
            self.saver = BackgroundSaver(self.store)
            self._resume()
        self.node = ZenohNode(cfg.zenoh, cfg.vessel_id, clock=self.clock)
        node = self.node
        # sea-state classes for this hull (seed 001 Table I, Froude-scaled from its 100 m supply vessel)
        self._sea_states = schemas.SeaStateTable.froude_scaled(cfg.vessel.length_m)
        for notice in cfg.notices:  # (check-config prints them too)
            log.warning("configuration: %s", notice)
        security = cfg.zenoh.security
        open_to_all = unprotected_endpoints(cfg.zenoh.listen, cfg.zenoh.connect, security)
        if open_to_all:  # (the configuration refused this unless insecure: true)
            text = (f"zenoh insecure: {', '.join(open_to_all)} without mutual TLS and access control: anybody on "
                    "that network can command the vessel")
            log.warning("%s", text)
            self.alarms.raise_(self.clock(), "zenoh.insecure", Severity.WARNING, text)  # standing: never cleared
        if security is not None and security.files is not None:
            days = days_left(security.files)
            if days < EXPIRY_WARNING_DAYS:  # (links open stay when it ends; new ones, a restart's, are refused)
                self.alarms.raise_(self.clock(), "zenoh.certificate_expiring", Severity.WARNING,
                                   f"zenoh certificate or CA expires in {days:.0f} days: issue new ones "
                                   "(dpcontrol pki issue) before then")
        # One controller per vessel: two would command the same thrusters, each fighting the other's
        # forces. Refuse to start while another holds the controller token (a second `dpcontrol run` by
        # hand beside the service, a standby computer started in error); a controller that joins later
        # (a network that heals) is caught by its commands, below.
        if node.alive_elsewhere("controller", settle_s=CONTROLLER_CHECK_S):
            raise RuntimeError(f"another controller is alive for vessel {cfg.vessel_id!r} "
                               f"({node.keys.alive('controller')}): two controllers would command the same "
                               f"thrusters; stop that one first")
        for topic in ("command", "estimate", "mmae", "control", "status"):
            self._publishers[topic] = node.publisher(topic)
        # (an Inbox is the default store for setpoints: passed here so that its type is known)
        self._setpoints: TopicSubscriber[Inbox[Received[Any]]] = node.subscribe("setpoint", Inbox())
        # thruster commands for this vessel from any other session: a second controller (not validated: any
        # sample there that is not ours is the fault)
        self._foreign_commands: LatestSlot[Any] = LatestSlot()
        node.subscribe("command", self._foreign_commands, parse=bytes, remote_only=True)
        self._feedback_slot: LatestSlot[Any] = LatestSlot()
        import functools  # noqa: PLC0415

        node.subscribe("feedback", self._feedback_slot,
                       parse=functools.partial(schemas.parse_feedback, thruster_names=self._names))
        summary = config_summary(cfg)
        node.serve_config(lambda: schemas.config_payload(t_s=self.clock(), seq=self._seq, config=summary))
        node.declare_alive("controller")
        # The drives' (plant's) presence: its loss is a fault the operator must see.
        self._drives = node.watch_alive("plant")
        self.pump = InputPump(cfg, self.clock, self.recorder)
        if cfg.replica.enabled:  # after _resume(): from the state the primary resumed from, if any
            resumed = self._resumed_state
            self.replica = ControllerReplica(cfg, self.alarms, self.pump.health.mark_links,
                                             resumed_state=None if resumed is None else resumed[0],
                                             resumed_t_s=0.0 if resumed is None else resumed[1])
        self.pump.start()

    def _resume(self) -> None:
        """Bumpless restart: resume from a recent persisted state, else start cold in standby."""
        assert self.store is not None
        result = self.store.check(self.wall_clock())
        self.state_detail = f"{result.status.value}: {result.detail}".strip(": ")
        if result.state is None:
            log.info("cold start (persisted state %s)", self.state_detail)
            return
        try:
            t_s = self.clock()
            pristine = copy.deepcopy(result.state)  # for the controller replica (loading must not alter it)
            self.controller.load_state_dict(result.state, t_s)
            self._resumed_state = (pristine, t_s)
            if self.recorder is not None:
                self.recorder.record("state_loaded", t_s, {"t_s": t_s, "state": result.state})
            log.info("resumed from persisted state (age %.1f s, mode %s)", result.age_s or 0.0,
                     self.controller.mode.value)
        except (KeyError, ValueError, TypeError) as error:
            self.state_detail = f"unusable: {error}"
            log.warning("persisted state unusable, cold start: %s", error)
            self.controller = DpController(self.config, self.alarms)
            self._resumed_state = None

    def run(self, duration_s: float | None = None, install_signals: bool = True) -> int:
        """Run until SIGTERM, SIGINT or SIGHUP (or ``duration_s``); returns the exit code (0 on a clean stop).

        SIGHUP stops like SIGTERM: its default action would end the process at once, with no zero-thrust
        command, when the terminal or SSH session that started ``dpcontrol run`` by hand goes away. (It does
        not reload the configuration: a DP controller's settings do not change under a vessel in DP.)
        """
        if install_signals:
            for stop_signal in (signal.SIGTERM, signal.SIGINT, signal.SIGHUP):
                signal.signal(stop_signal, self._on_signal)
        try:
            self._open()
        except Exception as error:
            log.error("start-up failed: %s", error)
            self._close()
            return 1
        # Everything allocated so far (modules, the CANboat PGN database, MAVLink dialect, zenoh, the
        # model bank) lives as long as the process: move it out of the collector's reach, or every full
        # collection walks ~10^5 objects inside a control cycle (measured 17–23 ms per gc.collect() on
        # the demo configuration, 1 µs after gc.freeze()).
        gc.collect()
        gc.freeze()
        # from here on the loop collects garbage after each cycle's command, not wherever it piles up
        garbage = self.garbage = GarbagePacer()
        # the CPUs the readers and Zenoh's threads may use (before the loop thread pins itself): with one, a
        # spinning loop would keep them off it, so the loop sleeps to its deadlines (dpcontrol/service/spin.py)
        shared_cpus = len(os.sched_getaffinity(0))
        # after _open(): the reader and Zenoh threads exist already and keep the normal scheduler
        self._apply_realtime()
        period = self.config.sample_time_s
        t0 = self.clock()
        deadline = t0
        end = None if duration_s is None else t0 + duration_s
        ready_sent = False
        measurements: list[Measurement] = []
        links: list[LinkStatus] = []
        consecutive_errors = 0
        step_errors = StepErrorLog()
        watchdog_interval = self.notifier.watchdog_interval_s()
        replica = self.replica
        lead = self.config.replica.lead_s
        spin = self.config.realtime.spin_s
        spinner = self.spinner = loop_spinner(spin, self.clock, shared_cpus)
        if spinner is None:
            if spin > 0.0:
                log.info("loop.deadline_spin_ms: not spinning on a single CPU (the sensor readers need it)")
            spin = 0.0  # sleep all the way to each deadline
        try:
            while not self._stop_requested:
                # The replica recomputes the last cycle just before this deadline: a check of the computation,
                # and the primary's step then starts with warm caches. When the loop is already late it catches
                # up after the next command instead (ControllerReplica.hold).
                if replica is not None and replica.pending and self.clock() < deadline - lead:
                    if self._sleep_until(deadline - lead):
                        break
                    replica.check(self.clock(), ahead=True)
                # sleep to the spin window, spin the rest (dpcontrol/service/spin.py says why)
                if self._sleep_until(deadline - spin) or (spinner is not None and spinner.until(deadline, self._stop)):
                    break
                start = self.clock()
                if end is not None and start >= end:
                    break
                jitter = start - deadline
                measurements.clear()
                links.clear()
                try:
                    out, published = self._cycle(start, measurements, links)
                    if consecutive_errors:
                        step_errors.recovered(consecutive_errors)
                    consecutive_errors = 0
                except Exception as error:
                    self.stats.step_errors += 1
                    consecutive_errors += 1
                    step_errors.failed(start, error, consecutive_errors)
                    self.alarms.raise_(start, "controller.internal_error", Severity.CRITICAL,
                                       "control step raised; commanding zero thrust")
                    self._publish_zero(start)
                    out, published = None, self.clock()
                finish = self.clock()
                self.stats.add((finish - start) * 1e6, (published - start) * 1e6, jitter * 1e6)
                healthy = consecutive_errors < 3 and out is not None
                if healthy:
                    if not ready_sent:
                        self.notifier.ready()
                        self.notifier.status("controlling")
                        ready_sent = True
                    if watchdog_interval is not None:
                        self.notifier.watchdog()
                garbage.collect()  # (after the command, status and record: in the slack before the next deadline)
                # Next deadline: the next multiple of the period in the future (missed ones counted).
                deadline += period
                behind = self.clock() - deadline
                if behind > 0.0:
                    skipped = math.floor(behind / period) + 1
                    self.stats.missed_deadlines += skipped
                    deadline += skipped * period
            self._shutdown()
        finally:
            garbage.close()  # (automatic collection back, however the loop ended)
        return 0

    def _sleep_until(self, t_s: float) -> bool:
        """Sleep until ``t_s`` on the loop's clock (not at all once it is past); True if a stop was requested."""
        now = self.clock()
        if now < t_s:
            self._stop.wait(t_s - now)
        return self._stop_requested

    def _apply_realtime(self) -> None:
        """``loop.realtime_priority`` / ``loop.cpu_affinity`` for this (the loop's) thread.

        Not granted (no CAP_SYS_NICE / RLIMIT_RTPRIO, no such CPU): a warning alarm, and the loop runs on
        with the normal scheduler — the controller must not refuse to hold position over a scheduling
        privilege.
        """
        settings = self.config.realtime
        parts: list[str] = []
        problems: list[str] = []
        if settings.cpus:
            try:
                os.sched_setaffinity(0, settings.cpus)  # 0: the calling thread
                parts.append(f"cpus {list(settings.cpus)}")
            except (OSError, ValueError) as error:
                problems.append(f"cpu_affinity {list(settings.cpus)}: {error}")
        if settings.priority is not None:
            try:
                os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(settings.priority))
                parts.append(f"SCHED_FIFO {settings.priority}")
            except OSError as error:
                problems.append(f"realtime_priority {settings.priority}: {error}")
        self.realtime_detail = ", ".join(parts) if parts else "normal scheduler"
        if problems:
            text = "loop scheduling not granted (" + "; ".join(problems) + "): running with " + self.realtime_detail
            log.warning("%s", text)
            self.alarms.raise_(self.clock(), "loop.realtime", Severity.WARNING, text)

    # ---------------------------------------------------------------- one cycle
    def _cycle(self, t_s: float, measurements: list[Measurement], links: list[LinkStatus]) -> tuple[StepOutput, float]:
        assert self.pump is not None and self.node is not None
        sources: list[int] = []
        self.pump.drain(t_s, measurements, links, sources)
        self._check_overflow(t_s)
        self._check_conflict(t_s)
        self.pump.health.apply_links(t_s, links, self.controller.hub, self.alarms)
        requests = self._attributed(t_s, self._setpoints.sink.drain())
        rejected = self._setpoints.stats
        if self._setpoint_rejected.grew(self.alarms, t_s, rejected.rejected):
            why = rejected.last_rejection
            self.alarms.raise_(t_s, self._setpoint_rejected.code, self._setpoint_rejected.severity,
                               f"setpoint rejected: {why.reason if why else '?'} {why.detail if why else ''}".strip())
        feedback: list[ThrusterFeedback] = []
        latest = self._feedback_slot.latest()
        if latest is not None:
            for item in latest.message.thrusters:
                if item.thrust_n is not None and item.azimuth_rad is not None:
                    feedback.append(ThrusterFeedback(item.name, item.thrust_n, item.azimuth_rad, item.ready,
                                                     latest.rx_t_s))
        clock = self.clock
        seq = self._seq
        stepped_from = clock()
        cpu_from = time.thread_time()
        try:
            try:
                out = self.controller.step(t_s, measurements, feedback, requests)
            except Exception as error:  # the replica must raise the same from the same inputs
                if self.replica is not None:
                    self.replica.hold(t_s, seq, None, measurements=measurements, feedback=feedback,
                                      requests=requests, links=links, error=error)
                raise
            stepped = clock()
            step_cpu = time.thread_time() - cpu_from
            self._seq += 1
            self._publishers["command"].put(schemas.command_payload(
                t_s=t_s, seq=seq, mode=out.mode.value, names=self._names, thrust_n=out.thrust_n,
                azimuth_rad=out.azimuth_rad, enabled=out.enabled))
            published = clock()
        finally:
            # Exactly what this step consumed (dpcontrol replay reproduces it), recorded once the command is
            # out — building the record is not on the way to the thrusters — and also when the step raised.
            if self.recorder is not None:
                self.recorder.record("cycle", t_s, {
                    "t_s": t_s, "cycle": seq, "inputs": sources,
                    "links": [[status.source, status.connected, status.detail] for status in links],
                    "feedback": [[f.name, f.thrust_n, f.azimuth_rad, f.ready, f.t_s] for f in feedback],
                    "requests": [request_as_dict(r) for r in requests]})
        self.stats.add_phases((stepped_from - t_s) * 1e6, (stepped - stepped_from) * 1e6, (published - stepped) * 1e6,
                              step_cpu * 1e6)
        if self.replica is not None:
            self.replica.hold(t_s, seq, out, measurements=measurements, feedback=feedback, requests=requests,
                              links=links)
        self._publish_rest(t_s, seq, out)
        report = self.controller.check_consequences(t_s)  # (after the command: see DpController.check_consequences)
        if report is not None and self.recorder is not None:
            self.recorder.record("consequence", t_s, consequence_record(report))
        self.pump.health.update_alarms(t_s, self.alarms)
        drives = self._drives.state
        self.alarms.set(t_s, "thrusters.drives_lost", drives.seen and not drives.present, Severity.ALARM,
                        "the thruster drives' liveliness token is gone (dp/<vessel>/alive/plant)")
        # every cycle, recorder or not (the registry keeps the transitions until they are drained)
        events = self.alarms.drain_events()
        self.alarm_journal.write(t_s, events)
        self._record(t_s, out, seq, events)
        self._persist(t_s)
        return out, published

    def _publish_rest(self, t_s: float, seq: int, out: StepOutput) -> None:
        estimate = out.estimate
        pub = self._publishers
        kind = self.config.estimator.kind
        if estimate is not None:
            pub["estimate"].put(schemas.estimate_payload(
                t_s=t_s, seq=seq, estimator=kind, eta_ned=estimate.eta_hat_ned, nu_b=estimate.nu_hat_b,
                bias=estimate.bias_hat_b, bias_frame="body", eta_wf_ned=estimate.eta_wf_hat_ned,
                covariance_diag=estimate.covariance_diag))
            if estimate.weights is not None:
                pub["mmae"].put(schemas.mmae_payload(t_s=t_s, seq=seq, omegas_rad_s=estimate.omegas_rad_s,
                                                     weights=estimate.weights,
                                                     omega_hat_rad_s=estimate.omega_hat_rad_s,
                                                     sea_states=self._sea_states))
        mrac = out.mrac
        reference = out.reference
        adaptation = None if mrac is None else self.controller.mass_adaptation  # (the MRAC, stepped this cycle)
        pub["control"].put(schemas.control_payload(
            t_s=t_s, seq=seq, controller=self.config.control.kind, tau_b=out.tau_b, setpoint_ned=out.setpoint_ned,
            reference_ned=None if reference is None else reference.eta_d_ned, tau_achieved_b=out.tau_achieved_b,
            shortfall_b=out.shortfall_b,
            mrac_mass=None if mrac is None else [mrac.get("mass_surge_kg"), mrac.get("mass_sway_kg"),
                                                 mrac.get("inertia_yaw_kgm2")],
            mrac_damping=None if mrac is None else [mrac.get("damping_surge_nspm"), mrac.get("damping_sway_nspm"),
                                                    mrac.get("damping_yaw_nmsprad")],
            mrac_nominal=None if adaptation is None else adaptation.mass_nominal,
            mrac_state=None if adaptation is None else adaptation.adaptation_states()))
        pub["status"].put(self._status_payload(t_s, seq))

    def _status_payload(self, t_s: float, seq: int) -> bytes:
        if t_s - self._last_stats_t >= 1.0:
            self._cycle_summary = self.stats.summary()
            self._host_steal_percent = self._host_steal.update(t_s)
            self._last_stats_t = t_s
        durations = self._cycle_summary.get("cycle_duration_us", {})
        cycle = schemas.CycleTiming(self.config.sample_time_s, durations.get("median"), durations.get("p99"),
                                    self.stats.missed_deadlines, self._host_steal_percent)
        drives = self._drives.state
        latest = self._feedback_slot.latest()
        seen = schemas.DrivesSeen(drives.present, drives.seen,
                                  None if latest is None else max(0.0, self.clock() - latest.rx_t_s))
        return status_payload(self.controller, self.alarms, t_s, seq, cycle, drives=seen)

    def _record(self, t_s: float, out: StepOutput, seq: int, events: list[AlarmEvent]) -> None:
        recorder = self.recorder
        if recorder is None:
            return
        estimate = out.estimate
        if estimate is not None:
            recorder.record("estimate", t_s, {
                "t_s": t_s, "eta_n": estimate.eta_hat_ned.tolist(), "nu_b": estimate.nu_hat_b.tolist(),
                "bias_b": estimate.bias_hat_b.tolist(), "eta_wf_n": estimate.eta_wf_hat_ned.tolist(),
                "covariance_diag": estimate.covariance_diag.tolist(), "measured": list(estimate.measured)})
            if estimate.weights is not None:
                recorder.record("mmae", t_s, {"t_s": t_s, "weights": estimate.weights.tolist(),
                                              "omegas_rad_s": list(estimate.omegas_rad_s),
                                              "omega_hat_rad_s": estimate.omega_hat_rad_s})
        if out.reference is not None:
            recorder.record("reference", t_s, {"t_s": t_s, "eta_d_n": out.reference.eta_d_ned.tolist(),
                                               "eta_dot_d_n": out.reference.eta_dot_d_ned.tolist()})
        wave_band = None if self.controller.wave_band is None else self.controller.wave_band.summary()
        recorder.record("control", t_s, {"t_s": t_s, "tau_b": out.tau_b.tolist(), "mrac": out.mrac,
                                         "setpoint_n": out.setpoint_ned.tolist(), "wave_band": wave_band})
        recorder.record("allocation", t_s, {"t_s": t_s, "tau_achieved_b": out.tau_achieved_b.tolist(),
                                            "shortfall_b": out.shortfall_b.tolist()})
        recorder.record("command", t_s, {"t_s": t_s, "cycle": seq, "mode": out.mode.value, "names": self._names,
                                         "thrust_n": out.thrust_n.tolist(), "azimuth_rad": out.azimuth_rad.tolist(),
                                         "enabled": out.enabled.tolist()})
        for previous, new, reason in out.mode_changes:
            recorder.record("mode", t_s, {"t_s": t_s, "from": previous, "to": new, "reason": reason})
        for text in out.rejected_requests:
            recorder.record("mode", t_s, {"t_s": t_s, "rejected_request": text})
        for event in events:
            recorder.record("alarm", t_s, {"t_s": event.t_s, "code": event.code, "raised": event.raised,
                                           "severity": event.severity.name.lower(), "text": event.text})
        if not recorder.health.ok:
            error = recorder.health.error
            self.alarms.raise_(t_s, "recorder.error", Severity.WARNING,
                               f"black-box recorder: {error.message if error is not None else recorder.health.state}")
        else:
            self.alarms.clear(t_s, "recorder.error")

    def _attributed(self, t_s: float, received: list[Received[SetpointRequest]]) -> list[SetpointRequest]:
        """The operator requests with the role and identity they came in under; those from a role other than
        ``console`` dropped (recorded, alarmed).

        Zenoh's access control already lets only ``console`` identities put set-points; this checks again. The
        identity is the certificate common name of the link the request's sender (its source info) is connected
        over; a request without source info is named by the one console connected, else by the list of them.
        """
        if not received:
            return []
        assert self.node is not None
        security = self.config.zenoh.security
        if security is None or not security.identities:  # no authentication: nobody is known
            return [item.message for item in received]
        links = self.node.link_identities()
        taken: list[SetpointRequest] = []
        for item in received:
            identity = links.get(item.source_zid) if item.source_zid is not None else None
            roles = security.roles_of(identity)
            if identity is None:
                # (a plaintext link has no name, so no role: roles_of(None) is empty)
                consoles = sorted({n for n in links.values() if n is not None and "console" in security.roles_of(n)})
                identity = consoles[0] if len(consoles) == 1 else f"one of {', '.join(consoles) or 'none'}"
                roles = ("console",)  # (the access control let only console identities put it)
            role = "console" if "console" in roles else "/".join(roles) or "none"
            if role != "console":
                text = (f"operator request seq {item.message.seq} from {identity!r} (role {role}) refused: only "
                        "console identities may command")
                self.alarms.raise_(t_s, "operator.unauthorised", Severity.WARNING, text)
                if self.recorder is not None:
                    self.recorder.record("mode", t_s, {"t_s": t_s, "rejected_request": text, "role": role,
                                                       "identity": identity})
                continue
            taken.append(dataclasses.replace(item.message, role=role, identity=identity))
        return taken

    def _check_overflow(self, t_s: float) -> None:
        """``inputs.overflow`` while reader threads drop inputs (a full queue), cleared 10 s after the last."""
        assert self.pump is not None
        dropped = self.pump.dropped
        if self._inputs_overflow.grew(self.alarms, t_s, dropped):
            self.alarms.raise_(t_s, self._inputs_overflow.code, self._inputs_overflow.severity,
                               f"{dropped} sensor inputs dropped since the start: more than "
                               f"{self.pump.max_pending} were waiting for the control loop (an input flood, "
                               f"or a stalled loop)")

    def _check_conflict(self, t_s: float) -> None:
        """``controller.conflict`` (critical) while another process publishes this vessel's thruster
        commands; cleared 10 s after the last one heard. The loop goes on commanding: the operator, who
        knows which controller should have the vessel, stops the other."""
        heard = self._foreign_commands.count
        if self._conflict.grew(self.alarms, t_s, heard):
            self.alarms.raise_(t_s, self._conflict.code, self._conflict.severity,
                               f"another process publishes thruster commands for {self.config.vessel_id!r} "
                               f"({heard} heard since the start): two controllers command the same thrusters")

    def _persist(self, t_s: float) -> None:
        saver = self.saver
        if saver is None or t_s - self._last_state_save < self.config.state.period_s:
            return
        self._last_state_save = t_s
        # the outcome of the previous write (set by the saver's thread; a str read is atomic)
        failed = saver.last_error
        self.alarms.set(t_s, "state.save_failed", failed is not None, Severity.WARNING,
                        f"persisted state not written (a restart would start cold): {failed}")
        saver.submit(self.wall_clock(), self.controller.state_dict(t_s))

    # ---------------------------------------------------------------- shutdown
    def _publish_zero(self, t_s: float) -> None:
        pub = self._publishers.get("command")
        if pub is None:
            return
        n = len(self._names)
        self._seq += 1
        pub.put(schemas.command_payload(t_s=t_s, seq=self._seq, mode=Mode.STANDBY.value, names=self._names,
                                        thrust_n=np.zeros(n), azimuth_rad=self.controller.out.azimuth_rad,
                                        enabled=[False] * n))

    def _shutdown(self) -> None:
        t_s = self.clock()
        self.notifier.stopping()
        self.controller.request_mode(Mode.STANDBY)
        self.controller.mode = Mode.STANDBY
        self._publish_zero(t_s)  # the last command: zero thrust
        log.info("stopping (%s): zero thrust commanded, mode standby",
                 self.stopped_by or ("end of --duration" if not self._stop_requested else "stop requested"))
        if "status" in self._publishers:
            self._publishers["status"].put(self._status_payload(t_s, self._seq))
        if self.saver is not None:
            self.saver.submit(self.wall_clock(), self.controller.state_dict(t_s))
        self._close()

    def _close(self) -> None:
        if self.pump is not None:
            self.pump.close()
        if self.saver is not None:
            self.saver.close()
        if self.node is not None:
            self.node.close()
        if self.recorder is not None:
            self.recorder.close(5.0)
