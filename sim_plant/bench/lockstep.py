"""Lockstep closed loop: the plant and the real controller step, one process, a stepped clock.

This is the one place (with the rest of ``sim_plant/bench``) allowed to import both the plant and
the controller (docs/design.md §1). The controller is the daemon's :class:`~dpcontrol.runtime.step.DpController`
— the same step, the same sensor hub, the same routing — and every sensor sample goes through the
real protocol codecs: plant sample → encoder → bytes → the daemon's decoders → measurement. So
quantisation, checksums and validity flags are exercised in every simulated second.

Deterministic for a scenario seed: the plant is seeded, the controller has no randomness, and
time is ``k · dt``.
"""

from __future__ import annotations

import copy
import math
import operator
import re
import signal
import struct
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from itertools import repeat
from typing import Any, NamedTuple

import numpy as np

from dpbase.requests import SetpointRequest
from dpcontrol.platform_info import available_memory_bytes
from dpcontrol.runtime.alarms import AlarmEvent
from dpcontrol.runtime.config import DaemonConfig, SensorRoute, TransportConfig, in_process_transport, parse_config
from dpcontrol.runtime.hub import SensorState
from dpcontrol.runtime.ingest import Nmea2000Input, TransportInput, transport_inputs
from dpcontrol.runtime.inputs import SensorRouter
from dpcontrol.runtime.step import DpController, Mode, StepOutput
from dpcontrol.runtime.thruster_monitor import ThrusterFeedback
from dpcontrol.runtime.transport_health import InputHealth
from interfaces.mavlink.codec import MavlinkEncoder
from interfaces.messages import LinkStatus, Measurement, PositionFix
from sim_plant.encoding import DATE_DAYS_SINCE_1970, MavlinkSensorEncoder, N2kSensorEncoder, NmeaSensorEncoder
from sim_plant.plant import Plant
from sim_plant.protocol_faults import (
    ProtocolFaultAction,
    mavlink_burst,
    n2k_burst,
    nmea0183_burst,
    protocol_fault_actions,
)
from sim_plant.scenario import Scenario
from sim_plant.sensors import GnssSpec, InvalidFix, RotSpec, SensorSample

N2K_FIRST_ADDRESS = 100
HEARTBEAT_PERIOD_S = 1.0  # MAVLink-standard HEARTBEAT rate of the emulated autopilots
STREAM_BURSTS = 5  # random stream of the malformed bursts (sim_plant/emulator.py uses the same)


def _vessel_id(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_\-]", "_", name)[:64] or "vessel"


def lockstep_transports(scenario: Scenario) -> list[TransportConfig]:
    """One in-process transport per protocol of the scenario's sensors (``lockstep_<protocol>``), in the order the
    sensors first use them: the plant's encoded bytes are handed to the input stage, no device is opened."""
    protocols = dict.fromkeys(spec.protocol for spec in scenario.sensors)
    return [in_process_transport(f"lockstep_{protocol}", protocol) for protocol in protocols]


def lockstep_config(scenario: Scenario, overrides: Mapping[str, Any] | None = None, *,
                    file: str | None = None) -> DaemonConfig:
    """The controller configuration of a lockstep run of ``scenario``: :func:`controller_mapping` on the
    in-process transports of :func:`lockstep_transports`.

    Raises
    ------
    ConfigError
        The scenario's ``controller:`` section or ``overrides`` are not a valid configuration.
    """
    return parse_config(controller_mapping(scenario, overrides), file=file or f"<lockstep {scenario.name}>",
                        transports=lockstep_transports(scenario))


def controller_mapping(scenario: Scenario, overrides: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """The controller configuration a lockstep run uses for ``scenario``, without its transports (the in-process
    ones of :func:`lockstep_transports`; :func:`lockstep_config` parses both).

    The vessel, one sensor per scenario sensor (its kind, rate, noise and lever arm, as an
    installation engineer would configure them from the data sheets) on the transport of its
    protocol, and the scenario's ``controller:`` section (``estimator``, ``control``, ``guidance``,
    ``allocation``, ``hub``, ``fallback``, ``loop``, ``thruster_monitor``, ``consequence``, ``deviation``) on top;
    ``overrides`` (same keys) win over both. DP engages 20 s after the estimator starts unless ``loop`` says
    otherwise.
    """
    sensors: list[dict[str, Any]] = []
    address = N2K_FIRST_ADDRESS
    for spec in scenario.sensors:
        transport = f"lockstep_{spec.protocol}"
        entry: dict[str, Any] = {"name": spec.name, "transport": transport, "rate_hz": spec.rate_hz}
        if isinstance(spec, GnssSpec):
            entry.update(kind="position", sigma_m=max(math.hypot(spec.noise_m, spec.markov_m), 1e-3),
                         lever_arm_m=list(spec.lever_arm_m), velocity_sigma_mps=max(spec.velocity_noise_mps, 1e-3))
        elif isinstance(spec, RotSpec):
            # (its own talker, TI: on a port shared with a gyro the gyro's HEROT stays the gyro's)
            entry.update(kind="rate_of_turn", sigma_degps=max(math.degrees(spec.noise_radps), 1e-4))
            if spec.protocol == "nmea0183":
                entry["talker"] = "TI"
        else:
            entry.update(kind="heading", sigma_deg=max(math.degrees(math.hypot(spec.noise_rad, spec.markov_rad)),
                                                       1e-3))
        if spec.protocol == "nmea2000":
            entry["source_address"] = address
            address += 1
        elif spec.protocol == "mavlink":
            entry["system_id"] = 1 + sum(1 for s in sensors if s.get("system_id") is not None)
        sensors.append(entry)
    controller = scenario.controller.to_dict() if hasattr(scenario.controller, "to_dict") \
        else copy.deepcopy(dict(scenario.controller))
    mapping: dict[str, Any] = {
        "vessel_id": _vessel_id(scenario.name),
        "vessel": scenario.vessel,
        "datum": {"lat_deg": scenario.datum.lat_deg, "lon_deg": scenario.datum.lon_deg},
        "loop": {"rate_hz": 10.0, "initial_mode": "standby", "auto_engage_s": 20.0},
        "sensors": sensors,
    }
    for source in (controller, dict(overrides or {})):
        for key, value in source.items():
            if key == "loop" and isinstance(value, Mapping):
                mapping["loop"] = {**mapping["loop"], **value}
            else:
                mapping[key] = copy.deepcopy(value)
    return mapping


@dataclass
class Columns:
    """Preallocated result arrays (one row per control step; NaN where a value does not exist)."""

    names: list[str]
    data: np.ndarray
    rows: int = 0

    def index(self, name: str) -> int:
        return self.names.index(name)


@dataclass
class RunResult:
    """What a lockstep run produced.

    Attributes
    ----------
    alarms : list of dict
        The alarms listed at the end (active, and cleared within the registry's ``keep_cleared_s``).
    alarm_events : list of AlarmEvent
        Every raise and clear during the run, in order (what the daemon records on its ``alarm`` topic).
    mode_changes : list of tuple
        ``(t_s, from, to, reason)`` of every mode change.
    interrupted_at_s : float or None
        Simulated time [s] of the step a Ctrl-C interrupted (``run(interruptible=True)``): the result then
        holds the steps before it. None: the run reached its end.
    counters : dict
        ``decode_rejects`` (all rejected frames), ``unrouted``, ``transports`` (per-transport decoded /
        malformed / flagged-invalid counts and reasons) and ``protocol_faults`` (what was carried out).
    """

    scenario: Scenario
    config: DaemonConfig
    columns: Columns
    omegas_rad_s: tuple[float, ...]
    wall_s: float
    steps: int
    alarms: list[dict[str, Any]] = field(default_factory=list)
    mode_changes: list[tuple[float, str, str, str]] = field(default_factory=list)
    counters: dict[str, Any] = field(default_factory=dict)
    alarm_events: list[AlarmEvent] = field(default_factory=list)
    interrupted_at_s: float | None = None


class _CtrlC:
    """Ctrl-C (SIGINT) as a flag the interruptible run checks between two steps, while the run lasts.

    Python's default handler raises KeyboardInterrupt wherever the main thread is at that moment; when that is a
    finalizer the garbage collector runs (a ``__del__``, a weakref callback), CPython reports the exception as
    "ignored" and the interrupt is lost: a CI test's Ctrl-C on a 12 h run went unanswered for 180 s, once in
    hundreds of runs. A flag cannot be lost. A second Ctrl-C raises at once, wherever the run is (the user
    insists); outside the main thread (no signal handler can be installed there) the default behaviour stays.
    """

    def __init__(self) -> None:
        self.pressed = False
        self._previous: Any = None
        if threading.current_thread() is threading.main_thread():
            self._previous = signal.signal(signal.SIGINT, self._on_sigint)

    def _on_sigint(self, _signum: int, _frame: Any) -> None:
        if self.pressed:
            raise KeyboardInterrupt
        self.pressed = True

    def restore(self) -> None:
        """The handler from before the run."""
        if self._previous is not None:
            signal.signal(signal.SIGINT, self._previous)
            self._previous = None


class _SensorPath(NamedTuple):
    """How one scenario sensor reaches the controller: its transport, protocol, kind (``position`` /
    ``heading``), encoder, its transport's input stage, and the MAVLink system id (None on other protocols)."""

    transport: str
    protocol: str
    kind: str
    encoder: Any
    stage: TransportInput
    system_id: int | None


class _Inputs:
    """The daemon's decoders, router and transport health, fed with the plant's encoded bytes (no transport).

    Protocol-level faults of the scenario are carried out here, on the bytes and link states the daemon
    would see: ``malformed_burst`` feeds :mod:`sim_plant.protocol_faults` items built from the target
    sensor's latest valid output into its transport's decoder; ``serial_unplug`` silences every sensor
    on that serial transport and reports the link lost (and back at the fault's end), as the daemon's
    serial reader does; ``heartbeat_loss`` stops the 1 Hz HEARTBEAT of the target's MAVLink system, and
    the daemon's own heartbeat monitor (:class:`interfaces.mavlink.codec.HeartbeatMonitor`, the
    transport's ``heartbeat_timeout_s``) declares that system lost. Every decoded or rejected frame is
    counted per transport by :class:`~dpcontrol.runtime.transport_health.InputHealth` — the daemon's code.
    """

    def __init__(self, config: DaemonConfig, scenario: Scenario) -> None:
        self.router = SensorRouter(config.routes, config.transports)
        self.health = InputHealth([t.name for t in config.transports], self.router, config.hub.error_rate_alarm,
                                  config.hub.error_rate_window_s)
        routes: dict[str, SensorRoute] = {r.sensor.name: r for r in config.routes}
        protocols = {t.name: t.protocol for t in config.transports}
        # (heartbeats watched from t = 0, as the daemon watches them from its start)
        self.stages = transport_inputs(config.transports, self.router, self.health, start_t_s=0.0)
        self.expiring = [stage for stage in self.stages.values() if isinstance(stage, Nmea2000Input)]
        self.paths: dict[str, _SensorPath] = {}
        self.last_valid: dict[str, list[Any]] = {}
        self.unplugged: set[str] = set()
        self.links: list[LinkStatus] = []
        self.applied: list[dict[str, Any]] = []
        self._mav_encoders: dict[tuple[str, int], MavlinkEncoder] = {}
        self._silent_until: dict[tuple[str, int], float] = {}
        self._heartbeat_watch: list[TransportInput] = []  # the MAVLink inputs of routed sensors
        self._next_heartbeat_s = 0.0
        self._seed = scenario.seed
        address = N2K_FIRST_ADDRESS
        for spec in scenario.sensors:
            route = routes.get(spec.name)
            if route is None:
                raise ValueError(f"scenario sensor {spec.name} has no sensor of that name in the controller config")
            protocol = protocols[route.transport]
            if protocol != spec.protocol:
                raise ValueError(f"sensor {spec.name}: the scenario sends {spec.protocol}, "
                                 f"the controller expects {protocol}")
            encoder: Any
            system_id = None
            if protocol == "nmea0183":
                encoder = NmeaSensorEncoder(spec.kind, route.talker, route.sentences)
            elif protocol == "nmea2000":
                source = route.source_address if route.source_address is not None else address
                address = max(address, source) + 1
                encoder = N2kSensorEncoder(source)
            else:
                system_id = route.system_id or 1
                key = (route.transport, system_id)
                if key not in self._mav_encoders:  # one autopilot per system id: its sensors share the sequence
                    self._mav_encoders[key] = MavlinkEncoder(system_id, 1)
                encoder = MavlinkSensorEncoder(encoder=self._mav_encoders[key])
            self.paths[spec.name] = _SensorPath(route.transport, protocol,
                                                "position" if isinstance(spec, GnssSpec) else
                                                "rate_of_turn" if isinstance(spec, RotSpec) else "heading",
                                                encoder, self.stages[route.transport], system_id)
        watched = {route.transport for route in config.routes if protocols[route.transport] == "mavlink"}
        self._heartbeat_watch.extend(self.stages[transport] for transport in sorted(watched))
        self.actions = protocol_fault_actions(scenario.faults)

    # ---------------------------------------------------------------- protocol faults
    def apply_faults(self, t: float, order: int) -> None:
        """Carry out the protocol-fault actions of ``order`` due by ``t``."""
        actions = self.actions
        i = 0
        while i < len(actions) and actions[i].t_s <= t + 1e-9:
            action = actions[i]
            if action.order != order:
                i += 1
                continue
            del actions[i]
            self._apply(action, t)

    def _apply(self, action: ProtocolFaultAction, t: float) -> None:
        fault = action.fault
        sensor = fault.target
        path = self.paths.get(sensor)
        entry: dict[str, Any] = {"t_s": t, "kind": fault.kind, "action": action.action, "target": sensor}
        if path is None:
            entry["skipped"] = f"{sensor} is not routed to the controller"
            self.applied.append(entry)
            return
        transport = path.transport
        if action.action == "burst":
            rng = np.random.default_rng([self._seed, STREAM_BURSTS, action.index])
            entry["items"] = self._burst(sensor, path, t, fault.count, rng)
        elif action.action == "unplug":
            if transport not in self.unplugged:
                self.unplugged.add(transport)
                self.links.append(LinkStatus(t, transport, False, "serial port closed (device unplugged)"))
        elif action.action == "replug":
            if transport in self.unplugged:
                self.unplugged.discard(transport)
                self.links.append(LinkStatus(t, transport, True, "serial port reopened"))
        else:  # silence: the target's autopilot sends no HEARTBEAT until the fault ends
            if path.system_id is None:  # (the scenario accepts heartbeat_loss only on a MAVLink sensor)
                raise ValueError(f"heartbeat_loss on {sensor}: not a MAVLink sensor")
            key = (transport, path.system_id)
            self._silent_until[key] = max(fault.end_s, self._silent_until.get(key, fault.end_s))
        self.applied.append(entry)

    def _burst(self, sensor: str, path: _SensorPath, t: float, count: int, rng: np.random.Generator) -> int:
        """Malformed items built from the sensor's latest valid output, through its transport's decoder."""
        last = self.last_valid.get(sensor)
        transport = path.transport
        if not last or transport in self.unplugged:
            return 0
        encoder = path.encoder
        stage = path.stage
        if path.protocol == "nmea0183":
            for line in nmea0183_burst(encoder.encode(last), count, rng):
                stage.feed(t, line, None)
            return count
        if path.protocol == "nmea2000":
            fix = next((m for m in last if isinstance(m, PositionFix)), None)
            fast = [] if fix is None else [encoder.encoder.gnss_position(fix, date_days=DATE_DAYS_SINCE_1970)
                                           for _ in range((count + 2) // 3)]
            for frames in n2k_burst(path.kind, encoder.source_address, count, rng, fast):
                for can_id, data in frames:
                    stage.feed(t, data, None, can_id=can_id)
            return count
        for packet in mavlink_burst(encoder.encode(t, last), count, rng):
            stage.feed(t, packet, None)
        return count

    def heartbeats(self, t: float) -> None:
        """The autopilots' 1 Hz HEARTBEAT (unless silenced) through the decoder into the heartbeat monitor;
        link changes go to :attr:`links`."""
        if not self._heartbeat_watch:
            return
        if t + 1e-9 >= self._next_heartbeat_s:
            self._next_heartbeat_s += HEARTBEAT_PERIOD_S
            for (transport, system_id), encoder in self._mav_encoders.items():
                if transport in self.unplugged or t < self._silent_until.get((transport, system_id), -math.inf):
                    continue
                self.stages[transport].feed(t, encoder.heartbeat(), None)
        for stage in self._heartbeat_watch:  # the daemon's heartbeat watch: systems heard, lost, never heard
            stage.poll(t, self.links)

    def expire(self, t: float) -> None:
        """Fast packets left incomplete for too long become rejects (as the daemon's CAN reader does)."""
        for stage in self.expiring:
            stage.expire(t)

    @property
    def rejected(self) -> int:
        """Frames rejected by the decoders so far (malformed, invalid, unknown)."""
        return sum(stage.rejected for stage in self.stages.values())

    def measurements(self, samples: list[SensorSample], out: list[Measurement]) -> None:
        """Encode each sample group (a sensor's messages of one instant) as its sensor would, decode it as
        the daemon does, route it."""
        n = len(samples)
        i = 0
        while i < n:
            first = samples[i]
            sensor = first.sensor
            t = first.t_s
            messages = [first.message]
            i += 1
            while i < n and samples[i].sensor == sensor and samples[i].t_s == t:
                messages.append(samples[i].message)
                i += 1
            self._group(sensor, t, messages, out)

    def _group(self, sensor: str, t: float, messages: list[Any], out: list[Measurement]) -> None:
        path = self.paths.get(sensor)
        if path is None or path.transport in self.unplugged:  # an unplugged port delivers nothing
            return
        for message in messages:
            if isinstance(message, InvalidFix):
                break
        else:
            if messages:
                self.last_valid[sensor] = messages  # what a malformed burst is built from
        stage = path.stage
        if path.protocol == "nmea0183":
            for sentence in path.encoder.encode(messages):
                stage.feed(t, sentence, out)
        elif path.protocol == "nmea2000":
            for can_id, data in path.encoder.encode(messages):
                stage.feed(t, data, out, can_id=can_id)
        else:
            for packet in path.encoder.encode(t, messages):
                stage.feed(t, packet, out)


TRUTH_COLUMNS = ["t_s", "north_m", "east_m", "heading_rad", "north_total_m", "east_total_m", "heading_total_rad",
                 "surge_mps", "sway_mps", "yaw_rate_radps"]
MEASUREMENT_COLUMNS = ["meas_north_m", "meas_east_m", "meas_heading_rad"]
ESTIMATE_COLUMNS = ["est_north_m", "est_east_m", "est_heading_rad", "est_surge_mps", "est_sway_mps",
                    "est_yaw_rate_radps"]
REFERENCE_COLUMNS = ["ref_north_m", "ref_east_m", "ref_heading_rad"]
FORCE_COLUMNS = ["tau_x_n", "tau_y_n", "tau_n_nm", "tau_act_x_n", "tau_act_y_n", "tau_act_n_nm"]
TAIL_COLUMNS = ["omega_hat_rad_s", "omega_peak_rad_s", "motion_peak_rad_s", "mass_factor"]
# MRAC parameter estimates, then its reference-model pose y_M (seed 003 eq. (15)) at the step's time, so the
# report can measure the tracking error |y − y_M| of the true LF pose (ControlOutput.parameters keys after "mrac_")
MRAC_COLUMNS = ["mrac_mass_surge_kg", "mrac_mass_sway_kg", "mrac_inertia_yaw_kgm2", "mrac_damping_surge_nspm",
                "mrac_damping_sway_nspm", "mrac_damping_yaw_nmsprad", "mrac_ref_model_north_m", "mrac_ref_model_east_m",
                "mrac_ref_model_heading_rad"]
EXTRA_COLUMNS = ["mode", "true_surge_mass_kg", "est_bias_x_n", "est_bias_y_n", "est_bias_n_nm"]
_MRAC_KEYS = [name[len("mrac_"):] for name in MRAC_COLUMNS]
_MRAC_VALUES = operator.itemgetter(*_MRAC_KEYS)  # a tuple of the values (KeyError when one is missing)
_NAN3 = (math.nan,) * 3
_NAN6 = (math.nan,) * 6
_NAN_MRAC = (math.nan,) * len(MRAC_COLUMNS)


def column_names(n_models: int, thruster_names: list[str]) -> list[str]:
    """docs/design.md §4.3 columns, then per-thruster commands and a few extras."""
    return (TRUTH_COLUMNS + MEASUREMENT_COLUMNS + ESTIMATE_COLUMNS + REFERENCE_COLUMNS + FORCE_COLUMNS
            + [f"weight_{i}" for i in range(n_models)] + TAIL_COLUMNS + MRAC_COLUMNS
            + [f"thrust_{name}_n" for name in thruster_names] + [f"azimuth_{name}_rad" for name in thruster_names]
            + EXTRA_COLUMNS)


MODE_CODES = {Mode.STANDBY: 0.0, Mode.AUTO_HEADING: 1.0, Mode.AUTO_POSITION: 2.0}
SENSOR_STATE_CODES: dict[SensorState, int] = {state: i for i, state in enumerate(SensorState)}


class SensorProbe:
    """Per-step health of every hub reference and thruster availability, kept in preallocated arrays (an
    ``observer`` of :meth:`LockstepSimulation.run`).

    Attributes (each of shape ``(steps, n_sensors)``, columns in :attr:`names` order)
    ----------
    state : ndarray of int
        :data:`SENSOR_STATE_CODES` of the sensor's state after the step.
    weight : ndarray of float
        Its weight in the fusion [-].
    accepted : ndarray of int
        Samples it has had accepted so far (a sample that passes every test).
    rejected : ndarray of int
        Samples rejected so far (frozen, prediction test).
    t_s : ndarray, shape (steps,)
    position_available, heading_available : ndarray of bool, shape (steps,)
    thruster_available : ndarray of bool, shape (steps, n_thrusters)
        The thruster monitor's availability mask after the step.

    Parameters
    ----------
    simulation : LockstepSimulation
    duration_s : float, optional
        Run length (default: the scenario's).
    """

    def __init__(self, simulation: LockstepSimulation, duration_s: float | None = None) -> None:
        self._hub = simulation.controller.hub
        self._tracks = list(self._hub._tracks.values())
        self.names = [track.config.name for track in self._tracks]
        duration = simulation.scenario.duration_s if duration_s is None else duration_s
        steps = math.floor(duration / simulation.config.sample_time_s + 1e-9) + 1
        n = len(self._tracks)
        self.t_s = np.full(steps, np.nan)
        self.state = np.zeros((steps, n), dtype=np.int8)
        self.weight = np.zeros((steps, n))
        self.accepted = np.zeros((steps, n), dtype=np.int64)
        self.rejected = np.zeros((steps, n), dtype=np.int64)
        self.position_available = np.zeros(steps, dtype=bool)
        self.heading_available = np.zeros(steps, dtype=bool)
        self._monitor = simulation.controller.monitor
        self.thruster_available = np.zeros((steps, len(simulation.thruster_names)), dtype=bool)
        self.rows = 0

    def __call__(self, t_s: float, out: StepOutput) -> None:
        k = self.rows
        if k >= self.t_s.size:
            return
        self.t_s[k] = t_s
        for j, track in enumerate(self._tracks):
            self.state[k, j] = SENSOR_STATE_CODES[track.state]
            self.weight[k, j] = track.weight
            self.accepted[k, j] = track.samples - track.rejected_samples
            self.rejected[k, j] = track.rejected_samples
        hub = out.hub
        if hub is not None:
            self.position_available[k] = hub.position_available
            self.heading_available[k] = hub.heading_available
        self.thruster_available[k] = self._monitor.available
        self.rows = k + 1

    def column(self, name: str) -> int:
        return self.names.index(name)

    def first_time(self, name: str, state: SensorState, after_s: float = 0.0) -> float | None:
        """First step time ≥ ``after_s`` at which sensor ``name`` is in ``state`` (None: never)."""
        t = self.t_s[: self.rows]
        hits = np.flatnonzero((t >= after_s - 1e-9) & (self.state[: self.rows, self.column(name)]
                                                         == SENSOR_STATE_CODES[state]))
        return None if hits.size == 0 else float(t[hits[0]])


class StatusProbe:
    """The ``dp/<vessel>/status`` payload the daemon would publish, built every ``every_s`` of a lockstep run
    with the daemon's own builder and parsed back through the status schema (an ``observer`` of
    :meth:`LockstepSimulation.run`).

    Attributes
    ----------
    samples : list of (float, dict)
        ``(t_s, parsed payload)``; a payload the schema rejects is kept as the :class:`Rejected`.
    """

    def __init__(self, simulation: LockstepSimulation, every_s: float = 1.0) -> None:
        from dpcontrol.service.daemon import status_payload  # noqa: PLC0415 (zenoh only when asked for)
        from interfaces.zenoh.schemas import parse_message  # noqa: PLC0415

        self._build = status_payload
        self._parse = parse_message
        self._simulation = simulation
        self._every = max(1, round(every_s / simulation.config.sample_time_s))
        self._k = 0
        self.samples: list[tuple[float, Any]] = []

    def __call__(self, t_s: float, out: StepOutput) -> None:
        del out
        k = self._k
        self._k += 1
        if k % self._every:
            return
        controller = self._simulation.controller
        payload = self._build(controller, controller.alarms, t_s, k)
        self.samples.append((t_s, self._parse("status", payload)))

    def active_codes(self, t_s: float) -> set[str]:
        """Alarm codes active in the first status published at or after ``t_s``."""
        for t, status in self.samples:
            if t >= t_s - 1e-9 and isinstance(status, dict):
                return {a["code"] for a in status["alarms"] if a["active"]}
        return set()

    def sensor_state(self, t_s: float, name: str) -> str | None:
        """A sensor's state in the first status published at or after ``t_s``."""
        for t, status in self.samples:
            if t >= t_s - 1e-9 and isinstance(status, dict):
                return next((s["state"] for s in status["sensors"] if s["name"] == name), None)
        return None


@dataclass
class ProbedRun:
    """A lockstep run with its per-step sensor health (:class:`SensorProbe`) and the status it published
    (:class:`StatusProbe`): what the fault-injection tests and the soak benchmark judge a run by."""

    simulation: LockstepSimulation
    result: RunResult
    sensors: SensorProbe
    status: StatusProbe

    @staticmethod
    def run(simulation: LockstepSimulation, *, status_every_s: float = 0.5,
            duration_s: float | None = None) -> ProbedRun:
        sensors = SensorProbe(simulation, duration_s)
        status = StatusProbe(simulation, status_every_s)
        result = simulation.run(duration_s=duration_s, observer=observers(sensors, status))
        return ProbedRun(simulation, result, sensors, status)

    def col(self, name: str) -> np.ndarray:
        """A time-series column (one value per control step)."""
        c = self.result.columns
        return c.data[: c.rows, c.index(name)]

    @property
    def t_s(self) -> np.ndarray:
        return self.col("t_s")

    def between(self, t0_s: float, t1_s: float) -> np.ndarray:
        """Boolean mask of the steps with ``t0_s ≤ t < t1_s``."""
        t = self.t_s
        return (t >= t0_s - 1e-9) & (t < t1_s - 1e-9)

    def position_error_m(self) -> np.ndarray:
        """Distance of the true LF position from the reference [m] (NaN where no reference)."""
        return np.hypot(self.col("north_m") - self.col("ref_north_m"), self.col("east_m") - self.col("ref_east_m"))

    def heading_error_rad(self) -> np.ndarray:
        """|true LF heading − reference heading| wrapped [rad] (NaN where no reference)."""
        error = self.col("heading_rad") - self.col("ref_heading_rad")
        return np.abs(np.angle(np.exp(1j * error)))

    def thrust_n(self) -> np.ndarray:
        """Commanded thrust per step, shape (steps, thrusters)."""
        names = self.simulation.thruster_names
        c = self.result.columns
        i = c.index(f"thrust_{names[0]}_n")
        return c.data[: c.rows, i:i + len(names)]

    def tau_b(self) -> np.ndarray:
        """Demanded generalized force per step, shape (steps, 3)."""
        c = self.result.columns
        i = c.index("tau_x_n")
        return c.data[: c.rows, i:i + 3]

    def thrust_rate_excess_n(self) -> float:
        """Largest per-step thrust command change beyond the drive's rate limit ``Ṫmax·dt`` [N], over every
        step and thruster — except a thruster taken out or put back in that step (a failed drive is
        commanded zero at once)."""
        thrust = self.thrust_n()
        if thrust.shape[0] < 2:
            return 0.0
        dt = self.simulation.config.sample_time_s
        rates = np.array([t.thrust_rate_limit_nps for t in self.simulation.config.vessel.thrusters])
        available = self.sensors.thruster_available[: thrust.shape[0]]
        steady = available[1:] & available[:-1]
        excess = np.abs(np.diff(thrust, axis=0)) - rates * dt
        excess[~steady] = 0.0
        return float(np.max(excess))

    def force_step_n(self, t0_s: float, t1_s: float) -> np.ndarray:
        """Largest per-step change of the demanded force in ``[t0_s, t1_s)``, per DOF [N, N, N·m]."""
        mask = self.between(t0_s, t1_s)
        tau = self.tau_b()
        steps = np.abs(np.diff(tau, axis=0))[mask[1:] & mask[:-1]]
        return steps.max(axis=0) if steps.size else np.zeros(3)

    def events(self, code: str) -> list[tuple[float, bool]]:
        """``(t_s, raised)`` of every transition of alarm ``code``."""
        return [(e.t_s, e.raised) for e in self.result.alarm_events if e.code == code]


def observers(*callbacks: Callable[[float, StepOutput], None]) -> Callable[[float, StepOutput], None]:
    """One ``observer`` calling each of ``callbacks`` in turn."""
    def observe(t_s: float, out: StepOutput) -> None:
        for callback in callbacks:
            callback(t_s, out)
    return observe


class SimulationTooLargeError(ValueError):
    """The run's time series would not fit in this machine's memory (raised before the run starts)."""


def _timeseries_array(rows: int, columns: int, dt: float) -> np.ndarray:
    """The NaN-filled ``rows × columns`` float64 array of a run, or :class:`SimulationTooLargeError`.

    A run whose rows would take more than half the memory available is refused before it starts: numpy
    may be granted the allocation (overcommit) and the process killed while it fills it, hours of a long
    run lost, or refused with a bare MemoryError.
    """
    need = rows * columns * 8
    available = available_memory_bytes()
    if available is None or need <= available / 2:
        try:
            return np.full((rows, columns), np.nan)
        except MemoryError:
            pass
    def size(n_bytes: float) -> str:
        return f"{n_bytes / 2**30:.1f} GiB" if n_bytes >= 2**30 else f"{n_bytes / 2**20:.1f} MiB"

    limit_s = "" if available is None else f"; at most about {available / 2 / (columns * 8) * dt / 3600:.1f} h here"
    have = "" if available is None else f", more than half of the {size(available)} available"
    raise SimulationTooLargeError(f"the time series of {rows} steps × {columns} columns needs {size(need)}{have}: "
                                  f"run a shorter duration{limit_s}")


class LockstepSimulation:
    """Plant + controller in lockstep (see the module docstring).

    Parameters
    ----------
    scenario : Scenario
    config : DaemonConfig, optional
        Controller configuration (default: :func:`controller_mapping` of the scenario).
    """

    def __init__(self, scenario: Scenario, config: DaemonConfig | None = None) -> None:
        self.scenario = scenario
        self.config = config or lockstep_config(scenario)
        self.plant = Plant(scenario)
        self.controller = DpController(self.config)
        self.inputs = _Inputs(self.config, scenario)
        self.thruster_names = [t.name for t in self.config.vessel.thrusters]
        plant_names = {t.name for t in scenario.vessel.thrusters}
        missing = [n for n in self.thruster_names if n not in plant_names]
        if missing:
            raise ValueError(f"the controller commands thrusters the plant does not have: {missing}")
        wave_filter = self.config.estimator.wave_filter
        self.omegas = tuple(wave_filter.omegas_rad_s) if wave_filter is not None and \
            self.config.estimator.kind == "mmae" else ()

    def run(self, progress: Callable[[float, float], None] | None = None, duration_s: float | None = None, *,  # noqa: PLR0915 - the simulation loop is one function so that its locals stay local (the hot path)
            observer: Callable[[float, StepOutput], None] | None = None, timeseries: bool = True,
            interruptible: bool = False) -> RunResult:
        """Run to the scenario's end (or ``duration_s``); returns the preallocated time series.

        Parameters
        ----------
        progress : callable, optional
            ``progress(t_s, duration_s)`` about 200 times per run.
        duration_s : float, optional
            Simulated time [s] (default: the scenario's).
        observer : callable, optional
            ``observer(t_s, out)`` after every control step (the step's output is reused: copy what you
            keep); :attr:`controller` and :attr:`inputs` may be inspected from it.
        timeseries : bool
            Keep one row per step (default). False keeps a single reused row (long runs: constant memory);
            the result then has no rows.
        interruptible : bool
            A KeyboardInterrupt (Ctrl-C) ends the run early with the steps completed so far
            (:attr:`RunResult.interrupted_at_s`) instead of propagating (default: it propagates).
        """
        scenario = self.scenario
        dt = self.config.sample_time_s
        duration = scenario.duration_s if duration_s is None else duration_s
        steps = math.floor(duration / dt + 1e-9) + 1
        names = column_names(len(self.omegas), self.thruster_names)
        data = _timeseries_array(steps if timeseries else 1, len(names), dt)
        columns = Columns(names, data)
        plant = self.plant
        controller = self.controller
        inputs = self.inputs
        alarms = controller.alarms
        hub = controller.hub
        setpoints = list(scenario.setpoints)
        next_setpoint = 0
        measurements: list[Measurement] = []
        feedback: list[ThrusterFeedback] = []
        # the plant's drive of each controller thruster (the controller's arrays are in its own order); the
        # feedback goes to the controller in the plant's order, as the drives report it
        drive_order = np.array([plant.drives.index(name) for name in self.thruster_names], dtype=np.int64)
        drive_names = plant.drives.names
        row_bytes = data.strides[0]
        pack_row = struct.Struct(f"={len(names)}d").pack_into
        data_buffer = data.data  # (its memoryview: numpy's stubs give ndarray the buffer protocol only from 3.12)
        mode_changes: list[tuple[float, str, str, str]] = []
        alarm_events: list[AlarmEvent] = []
        n_models = len(self.omegas)
        n_names = len(names)
        wall0 = time.perf_counter()
        report_every = max(1, steps // 200)
        interrupted_at = None
        k = 0
        ctrl_c = _CtrlC() if interruptible else None
        try:  # (no cost per step: Python's exceptions are free until raised)
            for k in range(steps):
                if ctrl_c is not None and ctrl_c.pressed:
                    raise KeyboardInterrupt  # (the handler's flag, between two steps: handled below)
                t = k * dt
                plant.advance(t)
                measurements.clear()
                inputs.links.clear()
                if inputs.actions:
                    inputs.apply_faults(t, 0)  # unplug / replug / heartbeat silence before the samples
                if inputs._heartbeat_watch:  # (heartbeats, expiries and link changes exist on some transports only)
                    inputs.heartbeats(t)
                inputs.measurements(plant.sensor_samples(t), measurements)
                if inputs.actions:
                    inputs.apply_faults(t, 1)  # malformed bursts after them
                if inputs.expiring:
                    inputs.expire(t)
                if inputs.links:
                    inputs.health.apply_links(t, inputs.links, hub, alarms)
                # the controller's feedback objects straight from the drives' lists (no plant-side feedback object
                # per drive in between: six fewer dataclass builds per step)
                feedback = list(map(ThrusterFeedback, drive_names, *plant.feedback_values(), repeat(t)))
                requests: list[SetpointRequest] = []
                while next_setpoint < len(setpoints) and setpoints[next_setpoint].t_s <= t + 1e-9:
                    sp = setpoints[next_setpoint]
                    requests.append(SetpointRequest(t_s=t, seq=next_setpoint, north_m=sp.north_m, east_m=sp.east_m,
                                                    heading_rad=sp.heading_rad))
                    next_setpoint += 1
                out = controller.step(t, measurements, feedback, requests)
                controller.check_consequences(t)  # (as the daemon, after the step; nothing when not configured)
                inputs.health.update_alarms(t, alarms)
                alarm_events.extend(alarms.drain_events())
                for change in out.mode_changes:
                    mode_changes.append((t, *change))
                # the controller's arrays straight into the drives (one kernel call; Plant.command_arrays applies
                # what Plant.command would with a ThrusterCommand per drive, and rejects the same)
                plant.command_arrays(t, drive_order, out.thrust_n, out.azimuth_rad, out.enabled)
                row = self._record(out, n_models, n_names)
                try:  # the float64s of the row packed into its bytes: a third cheaper than numpy's row assignment
                    pack_row(data_buffer, row_bytes * k if timeseries else 0, *row)
                except struct.error:  # a value struct cannot pack as a double: numpy converts it (or says why not)
                    data[k if timeseries else 0] = row
                if observer is not None:
                    observer(t, out)
                if progress is not None and k % report_every == 0:
                    progress(t, duration)
        except KeyboardInterrupt:
            if not interruptible:
                raise
            # step k did not finish (a row is written whole, at its end): keep the k before it
            interrupted_at = k * dt
            steps = k
        finally:
            if ctrl_c is not None:
                ctrl_c.restore()
        wall = time.perf_counter() - wall0
        columns.rows = steps if timeseries else 0
        if progress is not None and interrupted_at is None:
            progress(duration, duration)
        listed = [a.as_dict() for a in alarms.listed(steps * dt)]
        counters = {"decode_rejects": inputs.rejected, "unrouted": inputs.router.unrouted,
                    "transports": inputs.health.counters(), "protocol_faults": list(inputs.applied)}
        return RunResult(scenario, self.config, columns, self.omegas, wall, steps, listed, mode_changes, counters,
                         alarm_events, interrupted_at)

    def _record(self, out: StepOutput, n_models: int, n_names: int) -> list[float]:
        """One row of the time series, in :func:`column_names` order (NaN where a value does not exist).

        Built as a list of Python floats and written with one row assignment: a numpy item or slice write
        per column group cost several times more (the values are the same float64s).
        """
        nan = math.nan
        # (the truth fields a row keeps, without building the whole PlantTruth: see Plant.record_values)
        (t_s, north, east, heading_lf, north_total, east_total, heading_total, surge, sway, yaw_rate, tau_x, tau_y,
         tau_yaw, omega_peak, motion_peak, mass_factor, surge_mass) = self.plant.record_values()
        values = [t_s, north, east, heading_lf, north_total, east_total, heading_total, surge, sway, yaw_rate]
        hub = out.hub
        position = hub is not None and hub.position_available
        heading = hub is not None and hub.heading_available
        values += (hub.y_ned[0] if position else nan, hub.y_ned[1] if position else nan,  # type: ignore[union-attr]
                   hub.y_ned[2] if heading else nan)  # type: ignore[union-attr]
        estimate = out.estimate
        if estimate is not None:
            values += estimate.eta_hat_ned.tolist()
            values += estimate.nu_hat_b.tolist()
        else:
            values += _NAN6
        reference = out.reference
        values += reference.eta_d_ned.tolist() if reference is not None else _NAN3
        values += out.tau_b.tolist()
        values += (tau_x, tau_y, tau_yaw)
        if n_models:
            if estimate is not None and estimate.weights is not None:
                values += estimate.weights.tolist()
            else:
                values += [nan] * n_models
        omega_hat = None if estimate is None else estimate.omega_hat_rad_s
        values += (nan if omega_hat is None else omega_hat, nan if omega_peak is None else omega_peak,
                   nan if motion_peak is None else motion_peak, mass_factor)
        mrac = out.mrac
        if mrac is not None:
            try:
                got = _MRAC_VALUES(mrac)  # the nine values in one call
            except KeyError:
                got = tuple(mrac.get(key) for key in _MRAC_KEYS)
            values += [nan if value is None else value for value in got] if None in got else got
        else:
            values += _NAN_MRAC
        values += out.thrust_n.tolist()
        values += out.azimuth_rad.tolist()
        values += (MODE_CODES[out.mode], surge_mass)
        values += estimate.bias_hat_b.tolist() if estimate is not None else _NAN3
        if len(values) != n_names:
            raise RuntimeError("internal: the recorded row does not match the columns")
        return values
