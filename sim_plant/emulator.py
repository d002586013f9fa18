"""The real-time hardware-in-the-loop emulator behind ``sim-plant hil`` (docs/design.md §4.1).

The plant of a scenario (:class:`sim_plant.plant.Plant`) runs in real time against a separately
started ``dpcontrol run --config FILE``, on the transports that file configures
(:mod:`sim_plant.hil_config`): NMEA 0183 on pseudo-terminals, NMEA 2000 on a python-can bus
(python-can-remote between processes), MAVLink over UDP (:mod:`sim_plant.hil_links`), and Zenoh for
thruster commands and feedback, setpoints, status and liveliness (:mod:`sim_plant.hil_zenoh`)::

    scenario = load_scenario("sim_plant/scenarios/demo.yaml")
    wiring = load_controller_wiring("deploy/config/cybership2.yaml")
    with HilEmulator(scenario, wiring, HilOptions(out_dir=Path("out"))) as emulator:
        emulator.open()                 # ptys, CAN server + writer, UDP senders, zenoh session
        summary = emulator.run()        # until the duration, stop(), or SIGTERM in the CLI

Real time
---------
Plant time is ``(monotonic − start) · speed``. The loop is event driven: it sleeps until the next
*deadline* — the earliest of the next sensor sample (each sensor's exact schedule
``offset_s + k / rate_hz``), the next feedback/truth tick (``k / 10`` s), the next protocol-fault
event and the next MAVLink heartbeat — then advances the plant exactly to that time, so every
sample is sent at (not after) its own time and deadlines never drift. Work for a deadline that
starts more than ``deadline_tolerance_s`` of wall time late is a *missed deadline* (counted;
lateness and work time statistics go to the summary). A loop that falls more than
``max_catchup_s`` behind (a suspended process) jumps to the present: the plant integrates the gap
in one go and only the newest sample of each sensor is sent (the rest are counted as skipped).

Thruster commands are applied at their receive time (the plant is advanced to it first, so the
zero-order hold matches reality to within the tick); a loss of the controller's liveliness calls
``plant.command_lost`` at the time it was seen (drives ramp to zero); a silent controller is caught
by the drives' own command timeout.

Protocol faults of the scenario
-------------------------------
``malformed_burst`` (``count`` items of :mod:`sim_plant.protocol_faults` on the target sensor's
link), ``serial_unplug`` (the sensor's pty disappears for ``duration_s`` — every sensor on that
port with it — and comes back as a fresh pty behind the same path), ``heartbeat_loss`` (the target
sensor's MAVLink autopilot sends no HEARTBEAT for ``duration_s``). A fault on a sensor whose
controller transport cannot have it (unplugging a CAN sensor) is skipped and noted in the summary.
Sensor and thruster faults are the plant's own.

Outputs (``out_dir``)
---------------------
``truth.csv`` (``PlantTruth.columns()`` every 0.1 s of plant time), ``commands.csv`` (one row per
thruster of every command received: plant receive time, seq, mode, thrust, azimuth, enabled),
``feedback.csv`` (one row per thruster of every feedback published), ``links.json`` (what each link
is connected to and its counters) and ``hil_summary.json`` (duration, timing, missed deadlines,
samples per sensor — ``samples`` produced and offered to the link, ``dropped_samples`` /
``dropped_frames`` / ``send_errors`` what did not go out, ``invalid_samples``, ``malformed_items`` —,
commands, liveliness events, setpoints, engage result, faults, CPU, notes).

Recorder hook
-------------
``record(topic, t_s, payload)`` — the signature of :meth:`interfaces.recorder.Recorder.record`,
which a composition layer allowed to import the controller (``sim_plant.bench``) can pass in; the
plant never imports it — is called with plant time for every raw sensor output
(``raw/<transport>``: ``{"data", "source", "transport"[, "can_id"][, "fault"]}`` per NMEA sentence,
CAN frame or MAVLink packet, heartbeats included), every command received (``command``: the raw
JSON bytes) and every feedback published (``feedback``: the JSON bytes). An exception in it is
counted and logged once, never propagated into the loop.

systemd: ``READY=1`` once every link is up and the loop starts; ``WATCHDOG=1`` only from the loop,
and only while it keeps up (lateness below ``max_catchup_s``).
"""

from __future__ import annotations

import contextlib
import csv
import json
import logging
import math
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

import numpy as np

from interfaces.messages import FixQuality, Heading, PositionFix, RateOfTurn, SensorMessage
from interfaces.systemd import SystemdNotifier
from interfaces.zenoh.security import ZenohSecurity
from interfaces.zenoh.session_config import ZenohConfig
from sim_plant.drives import CommandError, ThrusterCommand
from sim_plant.hil_config import (
    CanTransport,
    ControllerWiring,
    MavlinkTransport,
    SerialTransport,
    Wire,
    wire_sensors,
    zenoh_endpoints,
)
from sim_plant.hil_links import HilLinkError, Link, MavlinkLink, N2kLink, SerialLink
from sim_plant.hil_zenoh import Operator, PlantZenoh, ReceivedCommand
from sim_plant.plant import Plant
from sim_plant.protocol_faults import ProtocolFaultAction, protocol_fault_actions
from sim_plant.scenario import Scenario
from sim_plant.sensors import SensorSample

log = logging.getLogger(__name__)

Record = Callable[[str, float, "dict[str, Any] | bytes"], None]
SUMMARY_SCHEMA = "sim_plant.hil_summary/1"
_EPS_S = 1e-9  # plant-time tolerance for "due" (event times are sums of floats)
_STREAM_BURSTS = 5  # random stream of malformed bursts (after the plant's streams 1–4)


class HilError(RuntimeError):
    """The emulator could not start (a link, the zenoh session ...); the message says which and why."""


@dataclass(frozen=True)
class HilOptions:
    """Run options of :class:`HilEmulator` (the CLI flags).

    Attributes
    ----------
    speed : float
        Plant seconds per wall second (1 for HIL; more to fast-forward an emulator-only run).
    duration_s : float or None
        Plant time to run [s]; None = the scenario's ``duration_s``.
    engage : bool
        Act as the operator and request DP once the controller is alive and publishing status.
    out_dir : Path or None
        Where the outputs go (created); None = no files.
    feedback_rate_hz, truth_rate_hz : float
        Thruster feedback publication and truth recording rates (plant time) [Hz].
    heartbeat_period_s : float
        MAVLink HEARTBEAT period in wall time [s].
    deadline_tolerance_s : float
        Wall-time lateness above which a deadline counts as missed [s].
    max_catchup_s : float
        Wall-time lateness above which the loop jumps to the present [s].
    zenoh_listen, zenoh_connect : tuple of str or None
        The emulator's own endpoints; None = derived from the controller configuration
        (:func:`sim_plant.hil_config.zenoh_endpoints`).
    zenoh_lease_s : float
        Link lease [s]: how fast a vanished peer (and its liveliness token) is noticed.
    zenoh_security : ZenohSecurity or None
        On a secured vessel network: the emulator's TLS identity and the identity → roles map its session
        enforces (the controller configuration's ``zenoh.identities``).
    can_server : bool
        Start the python-can-remote server of ``remote`` buses (False: someone else runs it).
    can_server_mode : {"process", "thread"}
    serial_backlog_bytes : int
        Unread bytes a pty may hold before they are discarded (see :mod:`sim_plant.hil_links`).
    engage_timeout_s, engage_retry_s : float
        DP request: give up after this long [s] from the first request; repeat every ... [s].
    stats_capacity : int
        Loop wake-ups kept for the timing percentiles (the most recent ones; counts cover all).
    """

    speed: float = 1.0
    duration_s: float | None = None
    engage: bool = False
    out_dir: Path | None = None
    feedback_rate_hz: float = 10.0
    truth_rate_hz: float = 10.0
    heartbeat_period_s: float = 1.0
    deadline_tolerance_s: float = 0.01
    max_catchup_s: float = 1.0
    zenoh_listen: tuple[str, ...] | None = None
    zenoh_connect: tuple[str, ...] | None = None
    zenoh_lease_s: float = 3.0
    zenoh_security: ZenohSecurity | None = None
    can_server: bool = True
    can_server_mode: str = "process"
    serial_backlog_bytes: int = 2048
    engage_timeout_s: float = 60.0
    engage_retry_s: float = 2.0
    stats_capacity: int = 1 << 18

    def __post_init__(self) -> None:
        for name in ("speed", "feedback_rate_hz", "truth_rate_hz", "heartbeat_period_s", "deadline_tolerance_s",
                     "max_catchup_s", "zenoh_lease_s", "engage_timeout_s", "engage_retry_s"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) \
                    or value <= 0.0:
                raise ValueError(f"{name} must be a finite number > 0, got {value!r}")
        if self.duration_s is not None and not (math.isfinite(self.duration_s) and self.duration_s > 0.0):
            raise ValueError(f"duration_s must be a finite number > 0, got {self.duration_s!r}")
        if self.can_server_mode not in ("process", "thread"):
            raise ValueError(f"can_server_mode must be 'process' or 'thread', got {self.can_server_mode!r}")
        if self.stats_capacity < 16 or self.serial_backlog_bytes < 256:
            raise ValueError("stats_capacity must be >= 16 and serial_backlog_bytes >= 256")


class PlantClock:
    """Plant time from the monotonic clock: ``(monotonic − start) · speed``, 0 before :meth:`start`."""

    def __init__(self, speed: float) -> None:
        self.speed = speed
        self.start_monotonic: float | None = None

    def start(self) -> float:
        self.start_monotonic = time.monotonic()
        return self.start_monotonic

    def __call__(self) -> float:
        start = self.start_monotonic
        return 0.0 if start is None else (time.monotonic() - start) * self.speed

    def wall(self, t_s: float) -> float:
        """The monotonic time at which plant time is ``t_s``."""
        assert self.start_monotonic is not None
        return self.start_monotonic + t_s / self.speed


class WakeStats:
    """Timing of the real-time loop: lateness of each wake-up and the work done for it.

    Counts, maxima and sums cover the whole run; percentiles come from the most recent
    ``capacity`` wake-ups (preallocated ring: nothing grows during a run).
    """

    def __init__(self, capacity: int, tolerance_s: float) -> None:
        self._late = np.zeros(capacity)
        self._work = np.zeros(capacity)
        self.tolerance_s = tolerance_s
        self.count = 0
        self.missed = 0
        self.catchups = 0
        self.max_late_s = 0.0
        self.max_work_s = 0.0
        self._sum_late = 0.0

    def add(self, late_s: float, work_s: float) -> None:
        i = self.count % self._late.size
        self._late[i] = late_s
        self._work[i] = work_s
        self.count += 1
        self._sum_late += late_s
        if late_s > self.tolerance_s:
            self.missed += 1
        self.max_late_s = max(self.max_late_s, late_s)
        self.max_work_s = max(self.max_work_s, work_s)

    def summary(self) -> dict[str, Any]:
        n = min(self.count, self._late.size)
        out: dict[str, Any] = {"wakeups": self.count, "missed_deadlines": self.missed,
                               "deadline_tolerance_ms": 1e3 * self.tolerance_s, "catchups": self.catchups}
        if n:
            late = 1e3 * self._late[:n]
            work = 1e6 * self._work[:n]
            p50, p99 = np.percentile(late, [50.0, 99.0])
            w50, w99 = np.percentile(work, [50.0, 99.0])
            out["lateness_ms"] = {"mean": 1e3 * self._sum_late / self.count, "p50": float(p50), "p99": float(p99),
                                  "max": 1e3 * self.max_late_s}
            out["work_us"] = {"p50": float(w50), "p99": float(w99), "max": 1e6 * self.max_work_s}
        return out


class HilOutputs:
    """CSV outputs of a run (rows streamed to buffered files: nothing accumulates in memory)."""

    def __init__(self, out_dir: Path) -> None:
        self.dir = out_dir
        out_dir.mkdir(parents=True, exist_ok=True)
        self._files: list[IO[str]] = []
        self._truth: Any = None
        self._truth_keys: list[str] = []
        self.commands = self._open("commands.csv", ["t_s", "seq", "mode", "name", "thrust_n", "azimuth_rad",
                                                    "enabled"])
        self.feedback = self._open("feedback.csv", ["t_s", "seq", "name", "thrust_n", "azimuth_rad", "ready"])

    def _open(self, name: str, header: Sequence[str]) -> Any:
        stream = open(self.dir / name, "w", newline="", encoding="utf-8", buffering=1 << 16)  # noqa: SIM115
        self._files.append(stream)
        writer = csv.writer(stream)
        writer.writerow(header)
        return writer

    def truth(self, columns: dict[str, float | None]) -> None:
        if self._truth is None:
            self._truth_keys = list(columns)
            self._truth = self._open("truth.csv", self._truth_keys)
        self._truth.writerow(["" if columns[k] is None else columns[k] for k in self._truth_keys])

    def write_json(self, name: str, data: Any) -> Path:
        path = self.dir / name
        tmp = path.with_name(path.name + ".tmp")
        tmp.write_text(json.dumps(data, indent=2, default=str) + "\n", encoding="utf-8")
        tmp.replace(path)
        return path

    def close(self) -> None:
        for stream in self._files:
            with contextlib.suppress(OSError):
                stream.close()
        self._files.clear()


class _SafeRecord:
    """Wraps the user's ``record`` callable: never raises into the loop; errors counted, logged once."""

    def __init__(self, record: Record | None) -> None:
        self._record = record
        self.errors = 0

    def __call__(self, topic: str, t_s: float, payload: dict[str, Any] | bytes) -> None:
        if self._record is None:
            return
        try:
            self._record(topic, t_s, payload)
        except Exception:
            self.errors += 1
            if self.errors == 1:
                log.exception("record callable failed (further failures are only counted)")


class HilEmulator:
    """The real-time emulator of one scenario against one controller configuration.

    Parameters
    ----------
    scenario : Scenario
    wiring : ControllerWiring
        From :func:`sim_plant.hil_config.load_controller_wiring`.
    options : HilOptions
    record : callable, optional
        The recorder hook (see the module docstring).
    notifier : SystemdNotifier, optional
        Default: one reading ``$NOTIFY_SOCKET`` (a no-op outside systemd).

    Raises
    ------
    dpbase.schema.ConfigError
        The scenario's sensors do not fit the controller's (see :func:`sim_plant.hil_config.wire_sensors`).
    ValueError
        No zenoh endpoint can be derived.
    """

    def __init__(self, scenario: Scenario, wiring: ControllerWiring, options: HilOptions | None = None, *,
                 record: Record | None = None, notifier: SystemdNotifier | None = None) -> None:
        self.scenario = scenario
        self.wiring = wiring
        self.options = options or HilOptions()
        self.wires, self.notes = wire_sensors(scenario, wiring)
        self.zenoh_listen, self.zenoh_connect = zenoh_endpoints(wiring.zenoh, self.options.zenoh_listen,
                                                                self.options.zenoh_connect)
        self.duration_s = self.options.duration_s or scenario.duration_s
        self.clock = PlantClock(self.options.speed)
        self.notifier = notifier or SystemdNotifier()
        self._record = _SafeRecord(record)
        self.plant = Plant(scenario)
        self.links: dict[str, Link] = {}
        self._link_of: dict[str, Link] = {}
        self.zenoh: PlantZenoh | None = None
        self.operator: Operator | None = None
        self.outputs: HilOutputs | None = None
        self.ready = threading.Event()
        self.stats = WakeStats(self.options.stats_capacity, self.options.deadline_tolerance_s)
        self._stop = threading.Event()
        self._stop_requested = False
        self._stop_reason = "duration"
        self._opened = False
        self._ran = False
        self._closed = False
        self._faults_done: list[dict[str, Any]] = []
        self._counts = {"commands_applied": 0, "commands_refused": 0, "command_lost_events": 0,
                        "feedback_published": 0, "feedback_failures": 0, "truth_rows": 0, "samples_skipped": 0,
                        "unwired_samples": 0}
        self._summary: dict[str, Any] | None = None
        self._k_feedback = 0  # index of the next feedback tick (plant time k / feedback_rate_hz)
        self._k_truth = 0

    # -- set-up ------------------------------------------------------------------------------------
    def open(self) -> None:
        """Create every link and the zenoh session (and the output folder).

        Raises
        ------
        HilError
            Naming the link or endpoint that failed; whatever was opened is closed again.
        """
        if self._opened:
            return
        self._opened = True
        try:
            self._open_links()
            self._open_zenoh()
            if self.options.out_dir is not None:
                self.outputs = HilOutputs(Path(self.options.out_dir))
        except HilLinkError as error:
            self.close()
            raise HilError(str(error)) from error
        except Exception as error:
            self.close()
            raise HilError(f"cannot start the emulator: {type(error).__name__}: {error}") from error
        for name, link in self.links.items():
            log.info("link %s: %s", name, json.dumps(link.describe(), default=str))
        for note in self.notes:
            log.info("%s", note)

    def _open_links(self) -> None:
        options = self.options
        for wire in self.wires:
            transport = wire.transport
            link = self.links.get(transport.name)
            if link is None:
                if isinstance(transport, SerialTransport):
                    link = SerialLink(transport, self._record, max_backlog_bytes=options.serial_backlog_bytes)
                elif isinstance(transport, CanTransport):
                    link = N2kLink(transport, self._record, start_server=options.can_server,
                                   server_mode=options.can_server_mode)
                    link.reserve([w.sensor.source_address for w in self.wires
                                  if w.transport.name == transport.name and w.sensor.source_address is not None])
                else:
                    assert isinstance(transport, MavlinkTransport)
                    link = MavlinkLink(transport, self._record,
                                       heartbeat_period_s=options.heartbeat_period_s * options.speed)
                self.links[transport.name] = link
            link.add(wire, self._fallback(wire))
            self._link_of[wire.spec.name] = link

    def _fallback(self, wire: Wire) -> list[SensorMessage]:
        """What a sensor "last sent" before its first sample (a malformed burst needs a template)."""
        init = self.scenario.initial
        if wire.spec.kind == "gnss":
            lat, lon = self.plant.frame.surface_to_geodetic(init.north_m, init.east_m)
            return [PositionFix(lat, lon, FixQuality.DGPS, self.scenario.utc_start_s, 12, 0.8, 0.0)]
        if wire.spec.kind == "rot":
            return [RateOfTurn(init.yaw_rate_radps)]
        return [Heading(init.heading_rad % (2.0 * math.pi))]

    def _open_zenoh(self) -> None:
        config = ZenohConfig(listen=self.zenoh_listen, connect=self.zenoh_connect, lease_s=self.options.zenoh_lease_s,
                             security=self.options.zenoh_security)
        names = [t.name for t in self.scenario.vessel.thrusters]
        self.zenoh = PlantZenoh(config, self.wiring.vessel_id, names, clock=self.clock)
        positional = any(p.north_m is not None for p in self.scenario.setpoints) or not self.scenario.setpoints
        self.operator = Operator(self.zenoh, self.scenario.setpoints, self.clock, speed=self.options.speed,
                                 engage=self.options.engage,
                                 engage_mode="auto_position" if positional else "auto_heading",
                                 engage_timeout_s=self.options.engage_timeout_s,
                                 engage_retry_s=self.options.engage_retry_s)

    # -- control -----------------------------------------------------------------------------------
    def stop(self, reason: str = "stop") -> None:
        """Ask the loop to end (from another thread); :meth:`run` then cleans up and returns."""
        self._stop_reason = reason
        self._stop_requested = True
        self._stop.set()

    def stop_from_signal(self, reason: str = "signal") -> None:
        """Like :meth:`stop`, for a signal handler running on the loop's own thread.

        Only sets a flag: ``Event.set`` takes a lock the interrupted ``Event.wait`` may hold. The
        loop sees the flag when its current wait ends (within one tick, ≤ 0.1 s).
        """
        self._stop_reason = reason
        self._stop_requested = True

    @property
    def controller_seen(self) -> bool:
        """Whether the controller's liveliness token was seen at any time since the zenoh session opened."""
        return self.zenoh is not None and self.zenoh.controller.state.seen

    @property
    def start_monotonic(self) -> float | None:
        """``time.monotonic()`` at plant time 0 (None before :meth:`run` starts the clock)."""
        return self.clock.start_monotonic

    def run(self) -> dict[str, Any]:
        """Run in real time until the duration passes or :meth:`stop`; close everything; return the summary.

        Raises
        ------
        HilError
            From :meth:`open` if it was not called yet and fails.
        RuntimeError
            Called a second time, or after :meth:`close`.
        """
        if self._ran or self._closed:
            raise RuntimeError("an emulator runs once: make a new one")
        self._ran = True
        self.open()
        cpu0, thread_cpu0 = time.process_time(), time.thread_time()
        wall0 = time.monotonic()
        error: BaseException | None = None
        try:
            self._loop()
        except BaseException as exc:
            error = exc
            self._stop_reason = f"error: {type(exc).__name__}: {exc}"
            log.exception("emulator loop failed")
            raise
        finally:
            self._finish(time.process_time() - cpu0, time.thread_time() - thread_cpu0, time.monotonic() - wall0,
                         error)
        assert self._summary is not None
        return self._summary

    # -- the loop ----------------------------------------------------------------------------------
    def _loop(self) -> None:
        assert self.zenoh is not None and self.operator is not None
        options = self.options
        plant = self.plant
        end = self.duration_s
        feedback_hz, truth_hz = options.feedback_rate_hz, options.truth_rate_hz  # grids advanced by _tick
        catchup_s = options.max_catchup_s
        actions = protocol_fault_actions(self.scenario.faults)
        links = list(self.links.values())
        watchdog_s = self.notifier.watchdog_interval_s()
        next_watchdog = 0.0
        self.clock.start()
        self.operator.start()
        self.notifier.ready(f"plant {self.scenario.name} running, links: {', '.join(self.links)}")
        self.ready.set()
        stop = self._stop
        while True:
            t_next = min(min((s.next_time_s for s in plant.sensors), default=math.inf),
                         self._k_feedback / feedback_hz, self._k_truth / truth_hz,
                         actions[0].t_s if actions else math.inf,
                         min((link.next_service_s for link in links), default=math.inf))
            final = t_next >= end - _EPS_S
            t = min(t_next, end)
            deadline = self.clock.wall(t)
            remaining = deadline - time.monotonic()
            if remaining > 0.0:
                stop.wait(remaining)
            if self._stop_requested:
                break
            woke = time.monotonic()
            late = woke - deadline
            if late > catchup_s and not final:
                # far behind (suspended, overloaded): jump to now instead of replaying the gap in a burst
                t = min(self.clock(), end)
                final = t >= end - _EPS_S
                self.stats.catchups += 1
                log.warning("emulator %.2f s behind real time: jumping to plant time %.2f s", late, t)
            self._tick(t, actions, links, catchup=late > catchup_s)
            done = time.monotonic()
            self.stats.add(late, done - woke)
            if watchdog_s is not None and late < catchup_s and done >= next_watchdog:
                self.notifier.watchdog()  # only from the loop, only while it keeps up (docs/design.md §5)
                next_watchdog = done + watchdog_s / 2.0
            if final:
                break

    def _tick(self, t: float, actions: list[ProtocolFaultAction], links: Sequence[Link], catchup: bool) -> None:
        """Everything due at plant time ``t`` (see the module docstring for the order)."""
        plant = self.plant
        self._apply_inputs(t)
        plant.advance(t)
        samples = plant.sensor_samples(t)
        while actions and actions[0].t_s <= t + _EPS_S and actions[0].order == 0:
            self._apply_fault(actions.pop(0), t)
        self._emit(samples, catchup)
        while actions and actions[0].t_s <= t + _EPS_S:
            self._apply_fault(actions.pop(0), t)
        for link in links:
            link.service(t)
        # feedback and truth on their grids k / rate (after a catch-up: once, then the next grid point)
        rate = self.options.feedback_rate_hz
        if self._k_feedback / rate <= t + _EPS_S:
            self._k_feedback = math.floor(t * rate + _EPS_S) + 1
            self._publish_feedback(t)
        rate = self.options.truth_rate_hz
        if self._k_truth / rate <= t + _EPS_S:
            self._k_truth = math.floor(t * rate + _EPS_S) + 1
            self._count("truth_rows")
            if self.outputs is not None:
                self.outputs.truth(plant.truth.columns())

    def _apply_inputs(self, t: float) -> None:
        """Commands and controller-liveliness changes, each at its receive time (clipped to [plant t, t])."""
        assert self.zenoh is not None
        plant = self.plant
        commands = self.zenoh.take_commands()
        changes = self.zenoh.take_liveliness()
        if not commands and not changes:
            return
        events: list[tuple[float, int, Any]] = [(c.rx_t_s, 1, c.message) for c in commands]
        events += [(t_s, 0, present) for t_s, present in changes]
        events.sort(key=lambda e: (e[0], e[1]))
        for rx_t, kind, item in events:
            plant.advance(min(max(rx_t, plant.t_s), t))
            if kind == 0:
                if not item:
                    plant.command_lost(rx_t)
                    self._count("command_lost_events")
                    log.warning("controller liveliness lost at plant time %.2f s: drives ramp to zero", rx_t)
                continue
            self._apply_command(rx_t, item)

    def _apply_command(self, rx_t: float, command: ReceivedCommand) -> None:
        message = command.message
        self._record("command", rx_t, command.raw)
        try:
            self.plant.command(rx_t, {s.name: ThrusterCommand(s.thrust_n, s.azimuth_rad, s.enabled)
                                      for s in message.thrusters})
        except CommandError as error:
            self._count("commands_refused")
            log.warning("thruster command refused: %s", error)
            return
        self._count("commands_applied")
        if self.outputs is not None:
            for s in message.thrusters:
                self.outputs.commands.writerow([rx_t, message.seq, message.mode, s.name, s.thrust_n, s.azimuth_rad,
                                                int(s.enabled)])

    def _emit(self, samples: Sequence[SensorSample], catchup: bool) -> None:
        """Send samples grouped per sensor and time; after a catch-up only each sensor's newest group."""
        groups: list[tuple[str, float, list[Any]]] = []
        for sample in samples:
            if groups and groups[-1][0] == sample.sensor and groups[-1][1] == sample.t_s:
                groups[-1][2].append(sample.message)
            else:
                groups.append((sample.sensor, sample.t_s, [sample.message]))
        if catchup:
            newest = {sensor: i for i, (sensor, _, _) in enumerate(groups)}
            self._counts["samples_skipped"] += len(groups) - len(newest)
            groups = [g for i, g in enumerate(groups) if newest[g[0]] == i]
        for sensor, t_s, messages in groups:
            link = self._link_of.get(sensor)
            if link is None:
                self._count("unwired_samples")
                continue
            link.send(sensor, t_s, messages)

    def _apply_fault(self, action: ProtocolFaultAction, t: float) -> None:
        fault = action.fault
        link = self._link_of.get(fault.target)
        entry: dict[str, Any] = {"t_s": action.t_s, "applied_t_s": t, "kind": fault.kind, "action": action.action,
                                 "target": fault.target}
        if link is None:
            entry["skipped"] = "sensor not wired to the controller"
        elif action.action == "burst":
            rng = np.random.default_rng([self.scenario.seed, _STREAM_BURSTS, action.index])
            entry["items"] = link.malformed_burst(fault.target, t, fault.count, rng)
        elif action.action in ("unplug", "replug"):
            if isinstance(link, SerialLink):
                (link.unplug if action.action == "unplug" else link.replug)()
                entry["device"] = link.device_path
            else:
                entry["skipped"] = f"{fault.target} is on {link.protocol}, not a serial line"
        elif isinstance(link, MavlinkLink):
            link.silence(fault.target, fault.end_s)
        else:
            entry["skipped"] = f"{fault.target} is on {link.protocol}, which has no heartbeat"
        if "skipped" in entry:
            log.warning("fault %s on %s at %.2f s skipped: %s", fault.kind, fault.target, t, entry["skipped"])
        else:
            log.info("fault %s (%s) on %s at plant time %.2f s", fault.kind, action.action, fault.target, t)
        self._faults_done.append(entry)

    def _publish_feedback(self, t: float) -> None:
        assert self.zenoh is not None
        feedback = self.plant.feedback()
        names = [f.name for f in feedback]
        thrust = [f.thrust_n for f in feedback]
        azimuth = [f.azimuth_rad for f in feedback]
        ready = [f.ready for f in feedback]
        seq, payload = self.zenoh.publish_feedback(t, names, thrust, azimuth, ready)
        if payload is None:
            self._count("feedback_failures")
            return
        self._count("feedback_published")
        self._record("feedback", t, payload)
        if self.outputs is not None:
            for f in feedback:
                self.outputs.feedback.writerow([t, seq, f.name, f.thrust_n, f.azimuth_rad, int(f.ready)])

    def _count(self, key: str) -> None:
        self._counts[key] += 1

    # -- the end -----------------------------------------------------------------------------------
    def _finish(self, cpu_s: float, loop_cpu_s: float, wall_s: float, error: BaseException | None) -> None:
        with contextlib.suppress(Exception):
            self.notifier.stopping(f"plant stopping ({self._stop_reason})")
        summary = self.summary(cpu_s=cpu_s, loop_cpu_s=loop_cpu_s, wall_s=wall_s)
        self._summary = summary
        try:
            self.close()
        finally:
            if self.outputs is not None:
                try:
                    self.outputs.write_json("links.json", summary["links"])
                    self.outputs.write_json("hil_summary.json", summary)
                except OSError as exc:
                    log.error("cannot write the summary to %s: %s", self.outputs.dir, exc)
                    if error is None:
                        raise

    def summary(self, *, cpu_s: float | None = None, loop_cpu_s: float | None = None,
                wall_s: float | None = None) -> dict[str, Any]:
        """The run summary so far (what ``hil_summary.json`` holds)."""
        simulated = self.plant.t_s
        sensors: dict[str, Any] = {}
        for wire in self.wires:
            link = self._link_of.get(wire.spec.name)
            channel = link.channels.get(wire.spec.name) if link is not None else None
            sensors[wire.spec.name] = {"transport": wire.transport.name, "protocol": wire.transport.protocol,
                                       "rate_hz": wire.spec.rate_hz,
                                       **({} if channel is None else dict(channel.counters))}
        links = {name: link.snapshot() for name, link in self.links.items()}
        notes = list(self.notes)
        wall = simulated / self.options.speed
        for name, link in self.links.items():
            if isinstance(link, SerialLink) and wall > 0.0:
                rate = link.counters["bytes_written"] / wall
                links[name]["line_bytes_per_s"] = rate
                if rate > link.capacity_bytes_per_s:
                    notes.append(f"{name}: {rate:.0f} B/s written, more than a real {link.transport.baud} baud line "
                                 f"carries ({link.capacity_bytes_per_s:.0f} B/s)")
        zenoh = self.zenoh.snapshot() if self.zenoh is not None else None
        operator = self.operator
        return {
            "schema": SUMMARY_SCHEMA,
            "scenario": self.scenario.name,
            "vessel_id": self.wiring.vessel_id,
            "speed": self.options.speed,
            "stopped_by": self._stop_reason,
            "duration_s": simulated,
            "planned_duration_s": self.duration_s,
            "wall_s": wall_s,
            "loop": self.stats.summary(),
            "cpu": {"process_s": cpu_s, "loop_thread_s": loop_cpu_s,
                    "process_s_per_simulated_s": None if cpu_s is None or simulated <= 0 else cpu_s / simulated},
            "sensors": sensors,
            "links": links,
            "zenoh": zenoh,
            "counts": dict(self._counts),
            "record_errors": self._record.errors,
            "liveliness": [] if self.zenoh is None else self.zenoh.liveliness_history,
            "setpoints": [] if operator is None else operator.published,
            "engage": None if operator is None else operator.engage_state,
            "faults": list(self._faults_done),
            "notes": notes,
        }

    def close(self) -> None:
        """Stop the operator, close the zenoh session (token first), the links and the output files."""
        if self._closed:
            return
        self._closed = True
        if self.operator is not None:
            self.operator.stop()
        if self.zenoh is not None:
            with contextlib.suppress(Exception):
                self.zenoh.close()
        for link in self.links.values():
            try:
                link.close()
            except Exception:  # keep closing the others
                log.exception("closing link %s failed", link.name)
        if self.outputs is not None:
            self.outputs.close()

    def __enter__(self) -> HilEmulator:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


