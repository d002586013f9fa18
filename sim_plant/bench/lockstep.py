"""Lockstep closed loop: the plant and the real controller step, one process, a stepped clock.

This is the one place (with the rest of ``sim_plant/bench``) allowed to import both the plant and
the controller (DESIGN.md §1). The controller is the daemon's :class:`~dpcontrol.runtime.step.DpController`
— the same step, the same sensor hub, the same routing — and every sensor sample goes through the
real protocol codecs: plant sample → encoder → bytes → the daemon's decoders → measurement. So
quantisation, checksums and validity flags are exercised in every simulated second.

Deterministic for a scenario seed: the plant is seeded, the controller has no randomness, and
time is ``k · dt``.
"""

from __future__ import annotations

import copy
import math
import re
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from dpcontrol.runtime.config import DaemonConfig, SensorRoute, parse_config
from dpcontrol.runtime.inputs import SensorRouter
from dpcontrol.runtime.step import DpController, Mode, StepOutput
from dpcontrol.runtime.thrusters import ThrusterFeedback
from interfaces.mavlink.codec import MavlinkDecoder
from interfaces.messages import Measurement, Rejected
from interfaces.nmea0183 import Nmea0183Decoder
from interfaces.nmea2000.codec import N2kDecoder
from interfaces.zenoh.schemas import SetpointRequest
from sim_plant.encoding import MavlinkSensorEncoder, N2kSensorEncoder, NmeaSensorEncoder
from sim_plant.plant import Plant
from sim_plant.scenario import Scenario
from sim_plant.sensors import GnssSpec, SensorSample
from sim_plant.thrusters import ThrusterCommand

N2K_FIRST_ADDRESS = 100


def _vessel_id(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_\-]", "_", name)[:64] or "vessel"


def controller_mapping(scenario: Scenario, overrides: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """The controller configuration a lockstep run uses for ``scenario``.

    The vessel, one sensor per scenario sensor (its kind, rate, noise and lever arm, as an
    installation engineer would configure them from the data sheets) on a transport of its
    protocol, and the scenario's ``controller:`` section (``estimator``, ``control``, ``guidance``,
    ``allocation``, ``hub``, ``fallback``, ``loop``, ``thruster_monitor``) on top; ``overrides``
    (same keys) win over both. DP engages 20 s after the estimator starts unless ``loop`` says
    otherwise.
    """
    sensors = []
    transports: dict[str, dict[str, Any]] = {}
    address = N2K_FIRST_ADDRESS
    for spec in scenario.sensors:
        transport = f"lockstep_{spec.protocol}"
        if transport not in transports:
            transports[transport] = {
                "nmea0183": {"name": transport, "protocol": "nmea0183", "port": "lockstep"},
                "nmea2000": {"name": transport, "protocol": "nmea2000", "interface": "virtual", "channel": "lockstep"},
                "mavlink": {"name": transport, "protocol": "mavlink", "url": "udpin:127.0.0.1:0"},
            }[spec.protocol]
        entry: dict[str, Any] = {"name": spec.name, "transport": transport, "rate_hz": spec.rate_hz}
        if isinstance(spec, GnssSpec):
            entry.update(kind="position", sigma_m=max(math.hypot(spec.noise_m, spec.markov_m), 1e-3),
                         lever_arm_m=list(spec.lever_arm_m))
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
        "transports": list(transports.values()),
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
    """What a lockstep run produced."""

    scenario: Scenario
    config: DaemonConfig
    columns: Columns
    omegas_rad_s: tuple[float, ...]
    wall_s: float
    steps: int
    alarms: list[dict[str, Any]] = field(default_factory=list)
    mode_changes: list[tuple[float, str, str, str]] = field(default_factory=list)
    counters: dict[str, int] = field(default_factory=dict)


class _Inputs:
    """The daemon's decoders and router, fed with the plant's encoded bytes (no transport)."""

    def __init__(self, config: DaemonConfig, scenario: Scenario) -> None:
        self.router = SensorRouter(config.routes, config.transports)
        routes: dict[str, SensorRoute] = {r.sensor.name: r for r in config.routes}
        protocols = {t.name: t.protocol for t in config.transports}
        self.nmea: dict[str, Nmea0183Decoder] = {}
        self.n2k: dict[str, N2kDecoder] = {}
        self.mav: dict[str, MavlinkDecoder] = {}
        self.encoders: dict[str, Any] = {}
        self.transport_of: dict[str, str] = {}
        self.rejected = 0
        address = N2K_FIRST_ADDRESS
        for spec in scenario.sensors:
            route = routes.get(spec.name)
            if route is None:
                raise ValueError(f"scenario sensor {spec.name} has no sensor of that name in the controller config")
            protocol = protocols[route.transport]
            if protocol != spec.protocol:
                raise ValueError(f"sensor {spec.name}: the scenario sends {spec.protocol}, "
                                 f"the controller expects {protocol}")
            self.transport_of[spec.name] = route.transport
            if protocol == "nmea0183":
                self.nmea.setdefault(route.transport, Nmea0183Decoder())
                self.encoders[spec.name] = NmeaSensorEncoder(spec.kind, route.talker, route.sentences)
            elif protocol == "nmea2000":
                self.n2k.setdefault(route.transport, N2kDecoder())
                source = route.source_address if route.source_address is not None else address
                address = max(address, source) + 1
                self.encoders[spec.name] = N2kSensorEncoder(source)
            else:
                self.mav.setdefault(route.transport, MavlinkDecoder())
                self.encoders[spec.name] = MavlinkSensorEncoder(route.system_id or 1)

    def measurements(self, samples: list[SensorSample], out: list[Measurement]) -> None:
        """Encode each sample as its sensor would, decode it as the daemon does, route it."""
        router = self.router
        for sample in samples:
            transport = self.transport_of.get(sample.sensor)
            if transport is None:
                continue
            encoder = self.encoders[sample.sensor]
            t = sample.t_s
            if sample.protocol == "nmea0183":
                decoder = self.nmea[transport]
                for sentence in encoder.encode((sample.message,)):
                    for frame in decoder.feed_frames(sentence):
                        if frame.rejected is not None:
                            self.rejected += 1
                        for message in frame.messages:
                            name = router.nmea0183(transport, frame.sentence, message)
                            if name is not None:
                                out.append(Measurement(t, name, message))
            elif sample.protocol == "nmea2000":
                decoder = self.n2k[transport]
                for can_id, data in encoder.encode((sample.message,)):
                    for result in decoder.decode_frame(can_id, data, t):
                        if isinstance(result.item, Rejected):
                            self.rejected += 1
                            continue
                        name = router.nmea2000(transport, result.source_address, result.item)
                        if name is not None:
                            out.append(Measurement(t, name, result.item))
            else:
                decoder = self.mav[transport]
                for packet in encoder.encode(t, (sample.message,)):
                    for result in decoder.decode_datagram(packet):
                        if isinstance(result.item, Rejected):
                            self.rejected += 1
                            continue
                        name = router.mavlink(transport, result.system_id, result.msg_name, result.item)
                        if name is not None:
                            out.append(Measurement(t, name, result.item))


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


def column_names(n_models: int, thruster_names: list[str]) -> list[str]:
    """DESIGN.md §4.3 columns, then per-thruster commands and a few extras."""
    return (TRUTH_COLUMNS + MEASUREMENT_COLUMNS + ESTIMATE_COLUMNS + REFERENCE_COLUMNS + FORCE_COLUMNS
            + [f"weight_{i}" for i in range(n_models)] + TAIL_COLUMNS + MRAC_COLUMNS
            + [f"thrust_{name}_n" for name in thruster_names] + [f"azimuth_{name}_rad" for name in thruster_names]
            + EXTRA_COLUMNS)


MODE_CODES = {Mode.STANDBY: 0.0, Mode.AUTO_HEADING: 1.0, Mode.AUTO_POSITION: 2.0}


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
        self.config = config or parse_config(controller_mapping(scenario), file=f"<lockstep {scenario.name}>")
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

    def run(self, progress: Callable[[float, float], None] | None = None, duration_s: float | None = None) -> RunResult:
        """Run to the scenario's end (or ``duration_s``); returns the preallocated time series."""
        scenario = self.scenario
        dt = self.config.sample_time_s
        duration = scenario.duration_s if duration_s is None else duration_s
        steps = math.floor(duration / dt + 1e-9) + 1
        names = column_names(len(self.omegas), self.thruster_names)
        data = np.full((steps, len(names)), np.nan)
        columns = Columns(names, data)
        col = {name: i for i, name in enumerate(names)}
        plant = self.plant
        controller = self.controller
        setpoints = list(scenario.setpoints)
        next_setpoint = 0
        measurements: list[Measurement] = []
        feedback: list[ThrusterFeedback] = []
        commands = {name: ThrusterCommand(0.0, None, False) for name in self.thruster_names}
        mode_changes: list[tuple[float, str, str, str]] = []
        n_models = len(self.omegas)
        n_thr = len(self.thruster_names)
        i_weights = col["weight_0"] if n_models else 0
        i_thrust = col[f"thrust_{self.thruster_names[0]}_n"] if n_thr else 0
        i_azimuth = col[f"azimuth_{self.thruster_names[0]}_rad"] if n_thr else 0
        truth_cols = [col[c] for c in TRUTH_COLUMNS]
        wall0 = time.perf_counter()
        report_every = max(1, steps // 200)
        for k in range(steps):
            t = k * dt
            plant.advance(t)
            measurements.clear()
            self.inputs.measurements(plant.sensor_samples(t), measurements)
            feedback.clear()
            for item in plant.feedback():
                feedback.append(ThrusterFeedback(item.name, item.thrust_n, item.azimuth_rad, item.ready, t))
            requests: list[SetpointRequest] = []
            while next_setpoint < len(setpoints) and setpoints[next_setpoint].t_s <= t + 1e-9:
                sp = setpoints[next_setpoint]
                requests.append(SetpointRequest(t_s=t, seq=next_setpoint, north_m=sp.north_m, east_m=sp.east_m,
                                                heading_rad=sp.heading_rad))
                next_setpoint += 1
            out = controller.step(t, measurements, feedback, requests)
            for change in out.mode_changes:
                mode_changes.append((t, *change))
            for i, name in enumerate(self.thruster_names):
                commands[name] = ThrusterCommand(float(out.thrust_n[i]), float(out.azimuth_rad[i]),
                                                 bool(out.enabled[i]))
            plant.command(t, commands)
            self._record(data[k], col, truth_cols, out, (i_weights, n_models, i_thrust, i_azimuth, n_thr))
            if progress is not None and k % report_every == 0:
                progress(t, duration)
        wall = time.perf_counter() - wall0
        columns.rows = steps
        if progress is not None:
            progress(duration, duration)
        alarms = [a.as_dict() for a in controller.alarms.listed(steps * dt)]
        counters = {"decode_rejects": self.inputs.rejected, "unrouted": self.inputs.router.unrouted}
        return RunResult(scenario, self.config, columns, self.omegas, wall, steps, alarms, mode_changes, counters)

    def _record(self, row: np.ndarray, col: dict[str, int], truth_cols: list[int], out: StepOutput,
                blocks: tuple[int, int, int, int, int]) -> None:
        i_weights, n_models, i_thrust, i_azimuth, n_thr = blocks
        truth = self.plant.truth
        row[truth_cols] = (truth.t_s, truth.north_m, truth.east_m, truth.heading_rad, truth.north_total_m,
                           truth.east_total_m, truth.heading_total_rad, truth.surge_mps, truth.sway_mps,
                           truth.yaw_rate_radps)
        hub = out.hub
        if hub is not None and hub.position_available:
            row[col["meas_north_m"]] = hub.y_n[0]
            row[col["meas_east_m"]] = hub.y_n[1]
        if hub is not None and hub.heading_available:
            row[col["meas_heading_rad"]] = hub.y_n[2]
        estimate = out.estimate
        if estimate is not None:
            i = col["est_north_m"]
            row[i:i + 3] = estimate.eta_hat_n
            row[i + 3:i + 6] = estimate.nu_hat_b
            j = col["est_bias_x_n"]
            row[j:j + 3] = estimate.bias_hat_b
            if n_models and estimate.weights is not None:
                row[i_weights:i_weights + n_models] = estimate.weights
            if estimate.omega_hat_rad_s is not None:
                row[col["omega_hat_rad_s"]] = estimate.omega_hat_rad_s
        reference = out.reference
        if reference is not None:
            i = col["ref_north_m"]
            row[i:i + 3] = reference.eta_d_n
        i = col["tau_x_n"]
        row[i:i + 3] = out.tau_b
        row[i + 3:i + 6] = truth.tau_act_b
        row[col["omega_peak_rad_s"]] = truth.omega_peak_rad_s if truth.omega_peak_rad_s is not None else np.nan
        row[col["motion_peak_rad_s"]] = truth.motion_peak_rad_s if truth.motion_peak_rad_s is not None else np.nan
        row[col["mass_factor"]] = truth.mass_factor
        row[col["true_surge_mass_kg"]] = truth.surge_mass_kg
        if out.mrac is not None:
            for name in MRAC_COLUMNS:
                value = out.mrac.get(name[len("mrac_"):])
                if value is not None:
                    row[col[name]] = value
        if n_thr:
            row[i_thrust:i_thrust + n_thr] = out.thrust_n
            row[i_azimuth:i_azimuth + n_thr] = out.azimuth_rad
        row[col["mode"]] = MODE_CODES[out.mode]
