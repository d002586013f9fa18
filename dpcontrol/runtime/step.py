"""The control step shared by the daemon and the lockstep simulation.

One call of :meth:`DpController.step` is one control period::

    operator requests → sensor hub (quality tests, voting, fusion) → wave filter (predict-check-correct)
    → modes and fall-backs → reference model → PD/PID/MRAC (or heading autopilot) → thruster health
    → QP allocation → thruster commands, status

Time is an argument (``t_s``): the daemon passes its monotonic clock, the lockstep simulation a
stepped clock. Nothing here reads a clock, sleeps or does I/O, so the same inputs give the same
commands — which is what makes a recorded run replayable.

Modes (docs/design.md §8): ``standby`` (no thrust), ``auto_heading`` (heading controlled, zero surge and
sway force), ``auto_position`` (DP). Entering a controlled mode is bumpless: the reference model
starts at the current estimate and velocity, and moves to the setpoint at its speed limits.
Fall-backs (docs/fault-handling.md): position references lost → dead reckoning on the model (alarm) and,
after ``dead_reckoning_limit_s``, the configured fall-back; heading lost → the configured
fall-back after ``heading_loss_limit_s``. The allocator's thrust-rate limits make every transition
a ramp, never a jump.
"""

from __future__ import annotations

import contextlib
import math
from collections import deque
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from enum import Enum
from typing import TYPE_CHECKING, Any

import numpy as np

from dpbase.frames import body_to_ned
from dpbase.geodesy import LocalFrame
from dpbase.requests import RequestOutcome, SetpointRequest
from dpbase.schema import ConfigError
from dpcontrol.allocation import AllocationResult, ThrustAllocator
from dpcontrol.control import ALL_DOFS, HEADING_ONLY, MassAdaptation, make_controller
from dpcontrol.estimation import WaveFilterOutput
from dpcontrol.estimation.wave_band import WaveBandMeter
from dpcontrol.guidance import Reference, ReferenceModel
from dpcontrol.runtime.alarms import AlarmRegistry, Severity
from dpcontrol.runtime.consequence import ConsequenceMonitor, ConsequenceReport
from dpcontrol.runtime.deviation import DeviationMonitor
from dpcontrol.runtime.estimators import MassAdaptiveEstimator, make_estimator
from dpcontrol.runtime.hub import HubOutput, SensorHub
from dpcontrol.runtime.thruster_monitor import ThrusterFeedback, ThrusterMonitor
from interfaces.messages import Measurement

if TYPE_CHECKING:  # the parser of the daemon's file reads transports and Zenoh settings: the step never loads it
    from dpcontrol.runtime.config import DaemonConfig

STATE_VERSION = 1
CAPABILITY_FLOOR = 0.05  # share of the fleet's capability below which a demand counts as small [-]
REQUEST_REFUSED_HOLD_S = 10.0  # operator.request_refused stays up this long after the last refusal [s]
RECENT_REQUESTS = 16  # outcomes kept for the status's ``requests`` (the last second's; see recent_requests)
RECENT_REQUESTS_S = 1.0  # how long an outcome stays in the status's ``requests`` [s]
_MASS_NAMES = ("surge mass", "sway mass", "yaw inertia")  # the MRAC's â₂ per DOF, for control.adaptation


class Mode(str, Enum):
    """Operating mode of the controller."""

    STANDBY = "standby"
    AUTO_HEADING = "auto_heading"
    AUTO_POSITION = "auto_position"


@dataclass
class StepOutput:
    """What one control period produced (reused between steps; copy what you keep).

    Attributes
    ----------
    t_s : float
        Time of the step [s].
    mode : Mode
    thrust_n, azimuth_rad : ndarray, shape (n,)
        Thruster commands [N], [rad] (azimuth / rudder / fixed angle).
    enabled : ndarray of bool, shape (n,)
        Thrusters in use (unavailable ones are commanded zero).
    tau_b, tau_achieved_b, shortfall_b : ndarray, shape (3,)
        Demanded, allocated and missing generalized force [N, N, N·m].
    setpoint_ned : ndarray, shape (3,)
        Operator target [north_m, east_m, psi_rad].
    reference : Reference or None
        Reference model output (None in standby).
    estimate : WaveFilterOutput or None
        The estimator's output (None until initialised).
    hub : HubOutput
        The fused measurement used.
    mrac : mapping or None
        MRAC parameter estimates.
    rejected_requests : list of str
        Operator requests refused this step, with the reason.
    """

    t_s: float = 0.0
    mode: Mode = Mode.STANDBY
    thrust_n: np.ndarray = field(default_factory=lambda: np.zeros(0))
    azimuth_rad: np.ndarray = field(default_factory=lambda: np.zeros(0))
    enabled: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))
    tau_b: np.ndarray = field(default_factory=lambda: np.zeros(3))
    tau_achieved_b: np.ndarray = field(default_factory=lambda: np.zeros(3))
    shortfall_b: np.ndarray = field(default_factory=lambda: np.zeros(3))
    setpoint_ned: np.ndarray = field(default_factory=lambda: np.zeros(3))
    reference: Reference | None = None
    estimate: WaveFilterOutput | None = None
    hub: HubOutput | None = None
    mrac: dict[str, float] | None = None
    allocation: AllocationResult | None = None
    rejected_requests: list[str] = field(default_factory=list)
    mode_changes: list[tuple[str, str, str]] = field(default_factory=list)


def _heading_dead_reckoning_text(hub: HubOutput) -> str:
    """The ``heading.dead_reckoning`` alarm's text: what carries the heading (the rate of turn of a named source,
    with the dead-reckoned heading's 1-σ, or the model) and for how long."""
    source = hub.heading_rate_source
    if source is None:
        return f"no heading reference: heading dead-reckoned on the model for {hub.heading_lost_s:.1f} s"
    return (f"no heading reference: heading dead-reckoned on the rate of turn ({source}, 1-sigma "
            f"{math.degrees(hub.heading_dr_sigma_rad):.2f} deg) for {hub.heading_lost_s:.1f} s")


def _position_dead_reckoning_text(hub: HubOutput) -> str:
    """The ``position.dead_reckoning`` alarm's text: what carries the position (a receiver's own velocity, when the
    velocity check rejected its position, with the dead-reckoned position's 1-σ; else the model) and for how long."""
    source = hub.position_velocity_source
    if source is None:
        return f"no position reference: dead reckoning for {hub.position_lost_s:.1f} s"
    return (f"no position reference: dead reckoning on the velocity of {source} (1-sigma "
            f"{hub.position_dr_sigma_m:.2f} m) for {hub.position_lost_s:.1f} s")


@contextlib.contextmanager
def _section_of_config(section: str, config: DaemonConfig) -> Iterator[None]:
    """Turn a ValueError raised while building from ``section`` into a :class:`ConfigError` naming it."""
    try:
        yield
    except ConfigError:
        raise
    except (ValueError, np.linalg.LinAlgError) as error:
        raise ConfigError(section, f"{section} settings from which the controller can be built", str(error),
                          file=config.source_file) from None


class DpController:
    """The whole controller of one vessel: hub, estimator, guidance, control, allocation, modes.

    Parameters
    ----------
    config : DaemonConfig
        Validated configuration.
    alarms : AlarmRegistry, optional
        Shared registry (the daemon adds its own alarms to it).
    stage_clock : callable, optional
        A clock for per-stage timing (``dpcontrol bench``); None in normal operation.
    """

    def __init__(self, config: DaemonConfig, alarms: AlarmRegistry | None = None,
                 stage_clock: Callable[[], float] | None = None) -> None:
        self.config = config
        self.alarms = alarms or AlarmRegistry()
        vessel = config.vessel
        self.dt_s = config.sample_time_s
        datum = None if config.datum is None else LocalFrame(config.datum[0], config.datum[1])
        self.hub = SensorHub(config.sensors, config.hub, self.alarms, datum)
        # A value that passes each key's own check can still leave nothing to build (a wave filter whose
        # Riccati equation has no stabilising solution): named here as the section it comes from, so that
        # check-config refuses what the daemon could not start with.
        with _section_of_config("estimator", config):
            self.estimator = make_estimator(config.estimator.kind, config.estimator.wave_filter, vessel, self.dt_s,
                                            dict(config.estimator.options))
        with _section_of_config("guidance", config):
            self.reference_model = ReferenceModel(config.guidance)
        with _section_of_config("control", config):
            self.controller = make_controller(config.control.config)
        # a course-keeping autopilot: heading only, the rudder set directly (see PositionController)
        self.rudder_steering = self.controller.rudder_steering
        # An adapting MRAC with a DP wave filter: the filter's model inertia follows the MRAC's mass estimate
        # between set-point moves (see MassAdaptiveEstimator: on M₀ alone the filter misleads the MRAC).
        self._mass_adaptive: MassAdaptiveEstimator | None = None
        # With every position reference lost: after how long [s], which fall-back (see _position_loss)
        fb = config.fallback
        self._position_loss_rule = (fb.dead_reckoning_limit_s, fb.position_loss) if self.estimator.dead_reckons \
            else (0.0, "hold_heading" if fb.position_loss == "dead_reckoning" else fb.position_loss)
        # MRAC supervision (_supervise): an estimate on a projection bound stops the adaptation
        self._mrac = self.controller.mass_adaptation
        if self._mrac is not None and self._mrac.adapting and self.estimator.force_model:
            self._mass_adaptive = MassAdaptiveEstimator(self.estimator, np.diag(vessel.mass_matrix))
            self.estimator = self._mass_adaptive
        # How an entry from standby starts the reference (ReferenceModelConfig.entry): at rest, so that DP stops
        # the drift the vessel had in standby at once, unless the controller needs the glide (an MRAC's learning
        # gate waits for the reference to rest after it; an autopilot's ship is under way, her turn no drift)
        entry = config.guidance.entry
        if entry == "auto":
            entry = "glide" if self._mrac is not None or self.rudder_steering else "stop"
        #: How an entry into DP from standby starts the reference: ``stop`` (at rest) or ``glide`` (at the estimated
        #: velocity); ``guidance.entry`` with ``auto`` resolved for this controller.
        self.entry: str = entry
        self.thrusters = vessel.thrusters
        with _section_of_config("allocation", config):
            self.allocator = ThrustAllocator(vessel.thrusters, self.dt_s, **dict(config.allocation))
        # The fastest the drives can change the generalized force (Σ |B|·Ṫmax per DOF) over the rigid-body +
        # added mass: the rate at which the reference acceleration fed forward may change (see _jerk_limited).
        geometry = self.allocator.geometry
        rates = np.array([t.thrust_rate_limit_nps for t in vessel.thrusters])
        self.force_rate_b = np.abs(geometry.B) @ rates[geometry.variable_thruster]  # [N/s, N/s, N·m/s]
        jerk = self.force_rate_b / np.diag(vessel.mass_matrix)
        horizontal = float(min(jerk[0], jerk[1]))  # a bound for any NED direction
        self._jerk_limit_n = np.array([horizontal, horizontal, float(jerk[2])])
        self._jerk_limit = self._jerk_limit_n.tolist()
        # the acceleration fed forward at the last step [m/s², m/s², rad/s²] (as floats: see _jerk_limited)
        self._accel_ff_ned: tuple[float, float, float] | None = None
        self._mass_sent: tuple[float, float, float] | None = None  # â₂ last given to the wave filter
        # CAPABILITY_FLOOR × the fleet's capability per DOF, as Python floats (constant; _capability_alarm)
        self._capability_floor = (CAPABILITY_FLOOR * self.allocator.capability_scale).tolist()
        self.monitor = ThrusterMonitor(vessel.thrusters, config.thruster_monitor, self.alarms)
        self.deviation = DeviationMonitor(config.deviation, self.alarms)  # position/heading deviation alarms
        # how much wave-frequency motion reaches the controller (status and record): the commanded force's and the
        # LF estimate's wave-band std, over the band the wave filter is configured for
        self.wave_band: WaveBandMeter | None = None
        if config.estimator.wave_filter is not None:
            omegas = config.estimator.wave_filter.omegas_rad_s or (0.8,)
            self.wave_band = WaveBandMeter(self.dt_s, (0.5 * min(*omegas, 0.6), max(2.0 * max(omegas), 1.5)))
        # this step's requests, each as (seq, why it was refused, what it did beyond the mode and set-point), and
        # the index of the one whose mode is the step's requested mode (a mode refusal is that request's)
        self._taken: list[tuple[int, list[str], list[str]]] = []
        self._mode_request: int | None = None
        # the worst-case failure check (consequence:), run by the caller after the command is out: not in step()
        self.consequence: ConsequenceMonitor | None = None
        if config.consequence.groups:
            with _section_of_config("consequence", config):
                self.consequence = ConsequenceMonitor(vessel.thrusters, config.consequence, self.alarms,
                                                      dict(config.allocation))
        n = len(vessel.thrusters)
        self.out = StepOutput(thrust_n=np.zeros(n), azimuth_rad=np.array([t.angle_rad for t in vessel.thrusters]),
                              enabled=np.zeros(n, dtype=bool))
        self.mode = Mode.STANDBY
        self._requested_mode = Mode(config.initial_mode)
        self.setpoint_ned = np.zeros(3)
        self._setpoint_given = False
        self._estimator_ready = False
        self._valid_since_t_s: float | None = None
        self._last_t_s: float | None = None
        self._tau_input_b = np.zeros(3)
        self._y_ned = np.zeros(3)  # the hub's fused measurement as the estimator takes it [m, m, rad] (see step)
        # the drives' delivered thrust [N] and angle [rad], refilled each cycle (see _update_force_input)
        self._delivered_thrust_n = np.zeros(n)
        self._delivered_azimuth_rad = np.zeros(n)
        self._zero3 = np.zeros(3)
        # the pose the controller made the vessel follow at this step when it is not η_d (MRAC: y_M), else None
        self._tracked_ned: np.ndarray | None = None
        self._fallback_reason = ""
        self._engaged_once = False
        self._shortfall_since: float | None = None
        self._dead_reckoning_alarm = False  # position.dead_reckoning / heading.lost raised (to be cleared)
        # (available mask, mode) → why the available thrusters cannot hold that mode's DOFs ("" they can); the mode
        # whose refusal raised thrusters.insufficient (None: not raised)
        self._thrust_verdicts: dict[tuple[bytes, Mode], str] = {}
        self._insufficient_for: Mode | None = None
        self._heading_lost_alarm = False
        # the mode a fall-back left and when (None: no fall-back to undo; see _restore)
        self._fell_back: tuple[Mode, float] | None = None
        # every request's outcome, newest last: the status lists the last second's (several in one cycle each
        # get their own answer) and the last (a sender finds its seq there)
        self.recent_requests: deque[RequestOutcome] = deque(maxlen=RECENT_REQUESTS)
        self._request_refused_t: float | None = None  # operator.request_refused raised at [s] (cleared 10 s on)
        self._stage_clock = stage_clock
        self.stage_us: dict[str, float] = {}
        rudders = [i for i, t in enumerate(vessel.thrusters) if t.kind == "propeller_rudder"]
        self._rudder_index = rudders[0] if rudders else None
        # Nomoto sign: positive δ (force to starboard) on a rudder aft of the origin turns the bow to port.
        self._rudder_sign = -1.0 if rudders and vessel.thrusters[rudders[0]].x_m < 0.0 else 1.0

    # ------------------------------------------------------------------ requests
    def request_mode(self, mode: str | Mode) -> None:
        """Ask for a mode (applied at the next step, if the conditions allow)."""
        self._requested_mode = Mode(mode)

    def accept_reference(self, name: str) -> bool:
        """The operator accepts reference ``name`` as the truth (:meth:`SensorHub.accept_reference`): a lone
        reference the prediction test rejects re-initialises the estimator on it at the next step, rather than
        after ``hub.single_reference_accept_s``. Returns whether the reference exists."""
        return self.hub.accept_reference(name)

    def _apply_requests(self, t_s: float, requests: Iterable[SetpointRequest]) -> None:
        """Apply this step's requests in their order of arrival, each answered on its own (:meth:`_report_requests`):
        a later set-point or mode replaces an earlier one of the same step, and that one's answer says so."""
        out = self.out
        taken = self._taken
        taken.clear()
        for request in requests:
            refusals: list[str] = []
            notes: list[str] = []
            if request.changes_pose:
                current = self.setpoint_ned if self._setpoint_given else self._estimate_pose()
                north, east, heading = request.resolve(float(current[0]), float(current[1]), float(current[2]))
                self.setpoint_ned[:] = (north, east, heading)
                self._setpoint_given = True
            if request.mode is not None:
                try:
                    self._requested_mode = Mode(request.mode)
                except ValueError:
                    refusals.append(f"unknown mode {request.mode!r}")
                else:
                    if self._mode_request is not None:
                        taken[self._mode_request][2].append(
                            f"mode {request.mode} requested after it in the same cycle (seq {request.seq})")
                    self._mode_request = len(taken)
                    self._fell_back = None  # the operator decides: no automatic return
            if request.reset_thruster is not None:
                self._reset_thruster(request.reset_thruster, refusals, notes)
            if request.accept_reference is not None:
                if self.accept_reference(request.accept_reference):
                    notes.append(f"reference {request.accept_reference} accepted as the truth")
                else:
                    refusals.append(f"accept_reference {request.accept_reference!r}: no such reference "
                                    f"({', '.join(self.hub.reference_names)})")
            out.rejected_requests.extend(refusals)
            taken.append((request.seq, refusals, notes))

    def _reset_thruster(self, name: str, refusals: list[str], notes: list[str]) -> None:
        """The operator clears a thruster's latched failure (the drive repaired): it rejoins the allocation at the
        next update unless its drive reports not ready; its mismatch judgement starts again from the feedback.
        Why not, or what was done, goes to the request's ``refusals`` or ``notes``."""
        latched = self.monitor.is_latched(name)
        if not self.monitor.reset(name):  # (False: no such thruster)
            refusals.append(f"reset_thruster {name!r}: no such thruster "
                            f"({', '.join(spec.name for spec in self.thrusters)})")
            return
        notes.append(f"{name} reset" if latched else f"{name} reset (no failure was latched)")

    def _report_requests(self, t_s: float, requests: Sequence[SetpointRequest]) -> None:
        """The outcome of each of this step's operator requests (:attr:`recent_requests`, :attr:`last_request`), and
        ``operator.request_refused`` (info) for a refused one, until 10 s after the last refusal: the operator sees
        why DP did not engage. A request is refused when any part of it was (the rest stays applied: the detail
        says what is in force); a mode the vessel cannot enter is the refusal of the request that asked for it."""
        refused = "; ".join(self.out.rejected_requests)
        if refused:
            if self._request_refused_t is not None:  # a new refusal is a new event (its own time in the status)
                self.alarms.clear(t_s, "operator.request_refused")
            self.alarms.raise_(t_s, "operator.request_refused", Severity.INFO, refused)
            self._request_refused_t = t_s
        elif self._request_refused_t is not None and t_s - self._request_refused_t > REQUEST_REFUSED_HOLD_S:
            self.alarms.clear(t_s, "operator.request_refused")
            self._request_refused_t = None
        if requests:
            north, east, heading = self.setpoint_ned.tolist()
            where = (f"set-point {north:.2f} m N, {east:.2f} m E, heading {math.degrees(heading) % 360.0:.1f}°"
                     if self._setpoint_given or self.mode is not Mode.STANDBY else "no set-point yet")
            in_force = f"mode {self.mode.value}, {where}"
            for request, (seq, refusals, notes) in zip(requests, self._taken, strict=False):
                detail = "; ".join([*refusals, in_force, *notes])
                self.recent_requests.append(RequestOutcome(seq, t_s, "refused" if refusals else "applied", detail,
                                                           request.role, request.identity))
            self._taken.clear()

    @property
    def last_request(self) -> RequestOutcome | None:
        """The outcome of the last operator request taken (None before the first)."""
        return self.recent_requests[-1] if self.recent_requests else None

    def requests_since(self, t_s: float) -> list[RequestOutcome]:
        """The outcomes of the requests taken at or after ``t_s`` [s], oldest first (at most
        :data:`RECENT_REQUESTS`)."""
        return [outcome for outcome in self.recent_requests if outcome.t_s >= t_s]

    @property
    def mass_adaptation(self) -> MassAdaptation | None:
        """The controller's inertia estimation (the MRAC), None for a controller with fixed parameters."""
        return self._mrac

    def adaptation_summary(self) -> tuple[tuple[str, str, str], tuple[float, float, float]] | None:
        """Per DOF (surge, sway, yaw) what the mass estimate does and its ratio to nominal, for the status.

        ``(states, ratios)``: :meth:`MassAdaptation.adaptation_states` and ``â₂ / a₂(0)`` [-]; None without an
        inertia estimation and when the controller did not run at the last step (standby, no estimate yet: the
        ``control`` payload has no ``mrac`` then either). Built when the status is, not every step.
        """
        adaptation = self._mrac
        if adaptation is None or self.out.mrac is None:
            return None
        mass = adaptation.mass_hat_floats
        nominal = adaptation.mass_nominal
        return adaptation.adaptation_states(), (mass[0] / nominal[0], mass[1] / nominal[1], mass[2] / nominal[2])

    def check_consequences(self, t_s: float) -> ConsequenceReport | None:
        """The worst-case failure check (:mod:`dpcontrol.runtime.consequence`) on the step just taken at ``t_s`` [s]:
        its mode, commanded force and the thrusters in use. Not part of :meth:`step` — a few QP solves once a
        second must not delay a command: the daemon calls it after the command is published. ``None`` when not
        configured or when no check ran this cycle."""
        if self.consequence is None:
            return None
        return self.consequence.update(t_s, self.mode.value, self.out.tau_b, self.monitor.available)

    def _estimate_pose(self) -> np.ndarray:
        if self._estimator_ready and self.out.estimate is not None:
            return self.out.estimate.eta_hat_ned
        return self.out.hub.y_ned if self.out.hub is not None else self._zero3  # type: ignore[return-value]

    # ------------------------------------------------------------------ the step
    def step(self, t_s: float, measurements: Sequence[Measurement] = (),
             feedback: Sequence[ThrusterFeedback] = (), requests: Sequence[SetpointRequest] = ()) -> StepOutput:
        """One control period at time ``t_s`` [s] (see the module docstring): the stages in their order."""
        clock = self._stage_clock
        t0 = clock() if clock else 0.0
        out = self.out
        out.t_s = t_s
        out.rejected_requests.clear()
        out.mode_changes.clear()
        self._mode_request = None  # (set by _apply_requests: which of this step's requests asked for a mode)
        dt = self.dt_s if self._last_t_s is None else min(max(t_s - self._last_t_s, 1e-3), 10.0 * self.dt_s)
        self._last_t_s = t_s
        if requests:  # (most cycles have none)
            self._apply_requests(t_s, requests)
        self.monitor.feedback(feedback)
        hub = self._hub_stage(t_s, measurements)
        t1 = clock() if clock else 0.0
        self._estimator_stage(t_s, hub)
        t2 = clock() if clock else 0.0
        self._update_mode(t_s, hub)
        if requests or out.rejected_requests or self._request_refused_t is not None:
            self._report_requests(t_s, requests)
        rudder_command = self._control_stage(t_s, dt)
        self._wave_band_stage()
        t3 = clock() if clock else 0.0
        # thruster health and allocation
        available = self.monitor.update(t_s, dt, out.thrust_n)
        if self._insufficient_for is not None:
            self._clear_insufficient(t_s)
        self._allocate(dt, available, rudder_command)
        t4 = clock() if clock else 0.0
        self._supervision_stage(t_s)
        if clock:
            t5 = clock()
            self.stage_us.update(hub=(t1 - t0) * 1e6, estimator=(t2 - t1) * 1e6, control=(t3 - t2) * 1e6,
                                 allocation=(t4 - t3) * 1e6, finish=(t5 - t4) * 1e6)
        out.mode = self.mode
        out.setpoint_ned[:] = self.setpoint_ned
        return out

    def _hub_stage(self, t_s: float, measurements: Sequence[Measurement]) -> HubOutput:
        """The sensor hub's tests and fusion of this period's measurements, against the estimator's prediction."""
        out = self.out
        predicted = variance = velocity_ned = None
        if self._estimator_ready:
            predicted_ned, variance_ned = self.estimator.predicted_measurement()
            # as Python floats: the hub's scalar arithmetic on numpy scalars costs several times more (same values)
            # (an estimator returning an ndarray subclass or a sequence is converted the same way, more slowly)
            predicted = (predicted_ned.tolist() if type(predicted_ned) is np.ndarray
                         else np.asarray(predicted_ned).tolist())
            variance = variance_ned.tolist() if type(variance_ned) is np.ndarray else np.asarray(variance_ned).tolist()
            estimate = out.estimate
            if estimate is not None:
                # body_to_ned's arithmetic on Python floats, without building an array (the hub reads two)
                psi = float(estimate.eta_hat_ned[2])
                u, v, r = estimate.nu_hat_b.tolist()
                c, s = math.cos(psi), math.sin(psi)
                velocity_ned = (c * u - s * v, s * u + c * v, r)
        hub = self.hub.update(t_s, measurements, predicted, variance, velocity_ned)
        out.hub = hub
        return hub

    def _estimator_stage(self, t_s: float, hub: HubOutput) -> None:
        """Start the estimator on the first fix of both kinds, re-initialise it on a hub reset, then step it."""
        y = self._y_ned  # refilled in place: every estimator and the reference model copy what they keep of it
        y[:] = hub.y_ned
        if not self._estimator_ready:
            if hub.position_available and hub.heading_available:
                self.estimator.reset(y)
                self._estimator_ready = True
                self._valid_since_t_s = t_s
        elif hub.position_reset or hub.heading_reset:
            self.estimator.reset(y)  # keeps the sea-state knowledge (MMAE weights, RPEM ω)
            if self.mode is not Mode.STANDBY:
                self.reference_model.reset(y)
                self._accel_ff_ned = None
        if self._estimator_ready:
            self._update_force_input()
            self.out.estimate = self.estimator.step(y, self._tau_input_b, hub.measured)

    def _control_stage(self, t_s: float, dt: float) -> float | None:
        """Guidance and control: the commanded force in ``out.tau_b``; returns the rudder command of a controller
        that steers with the rudder (None otherwise)."""
        out = self.out
        tau = out.tau_b
        out.mrac = None
        self._tracked_ned = None
        estimate = out.estimate
        if self.mode is Mode.STANDBY or estimate is None:
            out.reference = None
            tau[:] = 0.0
            return None
        setpoint = self.setpoint_ned
        if self.mode is Mode.AUTO_HEADING:
            target = np.array([estimate.eta_hat_ned[0], estimate.eta_hat_ned[1], setpoint[2]])
        else:
            target = setpoint
        reference = self._jerk_limited(dt, self.reference_model.step(dt, target))
        out.reference = reference
        dofs = HEADING_ONLY if self.mode is Mode.AUTO_HEADING else ALL_DOFS
        control = self.controller.step(dt, estimate.eta_hat_ned, estimate.nu_hat_b, estimate.bias_hat_b,
                                       reference, dof_enabled=dofs)
        tau[:] = control.tau_b
        self._tracked_ned = control.tracked_ned
        parameters = control.parameters
        if parameters is not None:
            # the controller builds a new dict every step: kept as it is (another mapping is copied)
            out.mrac = parameters if type(parameters) is dict else dict(parameters)
        if self._mrac is not None and self._mrac.adapting:
            self._supervise(self._mrac, t_s)
        if self._mass_adaptive is not None and self._mrac is not None and not any(self._mrac.excited):
            # only when â₂ changed (it is held between moves): saves an array and the filter's
            # ratio update on most steps; the same values give the same ratio
            mass = self._mrac.mass_hat_floats
            if mass != self._mass_sent:
                self._mass_adaptive.set_mass_estimate(np.array(mass))
                self._mass_sent = mass
        return control.rudder_rad

    def _wave_band_stage(self) -> None:
        """The wave-band meter of the commanded force (status ``wave_band``), reset in standby."""
        meter = self.wave_band
        if meter is None:
            return
        estimate = self.out.estimate
        if self.mode is Mode.STANDBY or estimate is None:
            if meter.steps:
                meter.reset()
        else:
            meter.follow_peak(estimate.omega_hat_rad_s)
            meter.update(self.out.tau_b, estimate.eta_hat_ned)

    def _supervision_stage(self, t_s: float) -> None:
        """After the allocation: the controller told what was achieved, the capability and deviation alarms."""
        out = self.out
        if self.mode is not Mode.STANDBY:
            self.controller.notify_achieved(out.tau_achieved_b)
        self._capability_alarm(t_s)
        estimate = out.estimate
        tracked = None if out.reference is None else out.reference.eta_d_ned
        if tracked is not None and self._tracked_ned is not None:
            # a controller that makes the vessel follow its own pose (the MRAC's y_M trails η_d by design: 8.7 m
            # in the tanker's 20 m move): the vessel strays from that pose, not from η_d
            tracked = self._tracked_ned
        self.deviation.update(t_s, self.mode.value, None if estimate is None else estimate.eta_hat_ned, tracked)

    def _jerk_limited(self, dt: float, reference: Reference) -> Reference:
        """The reference with its acceleration rate-limited to what the drives can follow.

        The reference model saturates its acceleration at the guidance limit without a jerk limit:
        a set-point far away (fault case 12: 1 km) takes η̈_d from 0 to the limit in one period, and the
        controller's feed-forward M·η̈_d makes that a force step (64 kN on the supply vessel, six
        times what its drives can change in 0.1 s). The feed-forward acceleration therefore follows
        η̈_d at most at ``(Σ|B|·Ṫmax) / M`` per DOF; pose and velocity references are unchanged (the
        PD terms see the reference move smoothly anyway).
        """
        a0, a1, a2 = reference.eta_ddot_d_ned.tolist()
        previous = self._accel_ff_ned
        if previous is None:
            self._accel_ff_ned = (a0, a1, a2)
            return reference
        # per DOF on Python floats (the numpy clip/compare on 3-vectors cost ~3× more); p + min(max(d, −l), l)
        # is np.clip's arithmetic, so the values are the same
        q0, q1, q2 = previous
        j0, j1, j2 = self._jerk_limit
        l0, l1, l2 = j0 * dt, j1 * dt, j2 * dt
        p0 = q0 + min(max(a0 - q0, -l0), l0)
        p1 = q1 + min(max(a1 - q1, -l1), l1)
        p2 = q2 + min(max(a2 - q2, -l2), l2)
        self._accel_ff_ned = (p0, p1, p2)
        if p0 == a0 and p1 == a1 and p2 == a2:
            return reference
        return Reference(reference.eta_d_ned, reference.eta_dot_d_ned, np.array((p0, p1, p2)))

    def _update_force_input(self) -> None:
        """The force the estimator predicts the next period with: what the drives deliver *now* (this
        cycle's feedback), else the force allocated last cycle; the rudder angle for an autopilot."""
        out = self.out
        if self.rudder_steering:
            rudder = 0.0 if self._rudder_index is None else float(out.azimuth_rad[self._rudder_index])
            self._tau_input_b[:] = (0.0, 0.0, self._rudder_sign * rudder)
            return
        if self.monitor.delivered_into(self._delivered_thrust_n, self._delivered_azimuth_rad):
            self.allocator.geometry.force_b(self._delivered_thrust_n, self._delivered_azimuth_rad,
                                            out=self._tau_input_b)
        else:
            self._tau_input_b[:] = out.tau_achieved_b

    def _allocate(self, dt: float, available: np.ndarray, rudder_command: float | None) -> None:
        out = self.out
        if self.mode is Mode.STANDBY or out.estimate is None:
            # Standby: thrust ramps to zero within the drives' rate limits (no jump).
            result = self.allocator.allocate(self._zero3, available, dt_s=dt)
        elif self.rudder_steering:
            # Course keeping: the rudder is commanded directly; the propeller holds its thrust.
            result = self.allocator.allocate(self._zero3, available, dt_s=dt)
        else:
            result = self.allocator.allocate(out.tau_b, available, dt_s=dt)
        out.allocation = result
        out.thrust_n[:] = result.thrust_n
        out.azimuth_rad[:] = result.azimuth_rad
        if rudder_command is not None and self._rudder_index is not None:
            out.azimuth_rad[self._rudder_index] = self._rudder_sign * rudder_command
        # (a copy or a fill: the mask & bool expression built a temporary array every cycle)
        if self.mode is Mode.STANDBY:
            out.enabled.fill(False)
        else:
            out.enabled[:] = available
        out.tau_achieved_b[:] = result.tau_achieved_b
        out.shortfall_b[:] = result.shortfall_b

    def _update_mode(self, t_s: float, hub: HubOutput) -> None:
        """The mode and fall-back rules of docs/fault-handling.md: auto-engage, reference-loss alarms and
        fall-backs, restoring the mode fallen back from, refusing what cannot be held, bumpless entry."""
        wanted = self._requested_mode
        # Auto-engage (HIL/lockstep convenience): DP once the estimator has settled.
        auto = self.config.auto_engage_s
        if auto is not None and not self._engaged_once and self._valid_since_t_s is not None \
                and t_s - self._valid_since_t_s >= auto and wanted is Mode.STANDBY:
            wanted = Mode.AUTO_HEADING if self.rudder_steering else Mode.AUTO_POSITION
            self._requested_mode = wanted
        dead_reckoning, heading_lost = self._reference_loss_alarms(t_s, hub)
        if self.mode is not Mode.STANDBY:
            fb = self.config.fallback
            if heading_lost and hub.heading_lost_s >= fb.heading_loss_limit_s:
                carrier = "the model" if hub.heading_rate_source is None else \
                    f"the rate of turn ({hub.heading_rate_source})"
                wanted = self._loss_limit(t_s, "heading", fb.heading_loss, fb.heading_loss_limit_s, wanted,
                                          carrier=carrier)
            elif self.mode is Mode.AUTO_POSITION and dead_reckoning:
                carrier = "the model" if hub.position_velocity_source is None else \
                    f"the velocity of {hub.position_velocity_source}"
                wanted = self._position_loss(t_s, hub.position_lost_s, wanted, carrier)
        fell_back = self._fell_back
        if fell_back is not None and wanted is self.mode and self._requested_mode is self.mode:
            wanted = self._restore(t_s, hub, fell_back)
        if wanted is self.mode:
            return
        if wanted is not Mode.STANDBY:
            refuse = self._refusal(t_s, hub, wanted)
            if refuse is not None:
                text = f"{wanted.value} refused: {refuse}"
                self.out.rejected_requests.append(text)
                if self._mode_request is not None:  # (None: the auto-engage asked, not the operator)
                    self._taken[self._mode_request][1].append(text)
                self._requested_mode = self.mode
                return
            if self.mode is Mode.STANDBY:
                self._bumpless_entry()
            self._engaged_once = True
        self._change_mode(t_s, wanted)

    def _reference_loss_alarms(self, t_s: float, hub: HubOutput) -> tuple[bool, bool]:
        """Raise or clear the position dead-reckoning and heading-loss alarms; returns (dead reckoning the
        position, heading lost)."""
        # (the alarm texts are built only while the alarm is active — formatting them every step cost more
        # than the rest of the mode logic — and an alarm is cleared only if this controller raised it)
        dead_reckoning = self._estimator_ready and not hub.position_available
        if dead_reckoning and self.mode is Mode.AUTO_POSITION:
            self.alarms.raise_(t_s, "position.dead_reckoning", Severity.ALARM, _position_dead_reckoning_text(hub))
            self._dead_reckoning_alarm = True
        elif self._dead_reckoning_alarm:
            self.alarms.clear(t_s, "position.dead_reckoning")
            self.alarms.clear(t_s, "position.dead_reckoning_limit")
            self._dead_reckoning_alarm = False
        heading_lost = self._estimator_ready and not hub.heading_available
        if heading_lost:
            self.alarms.raise_(t_s, "heading.lost", Severity.ALARM,
                               f"no heading reference for {hub.heading_lost_s:.1f} s")
            self._heading_lost_alarm = True
            if self.mode is not Mode.STANDBY:
                self.alarms.raise_(t_s, "heading.dead_reckoning", Severity.ALARM, _heading_dead_reckoning_text(hub))
        elif self._heading_lost_alarm:
            self.alarms.clear(t_s, "heading.lost")
            self.alarms.clear(t_s, "heading.dead_reckoning")
            self.alarms.clear(t_s, "heading.dead_reckoning_limit")
            self._heading_lost_alarm = False
        return dead_reckoning, heading_lost

    def _refusal(self, t_s: float, hub: HubOutput, wanted: Mode) -> str | None:
        """Why ``wanted`` (a controlled mode) cannot be engaged now, or None."""
        if not self._estimator_ready:
            return "no estimate yet (position and heading references needed)"
        if not hub.heading_available:
            return "no heading reference"
        if wanted is Mode.AUTO_POSITION and not hub.position_available:
            return "no position reference"
        return self._thrusters_insufficient(t_s, wanted) or None

    def _bumpless_entry(self) -> None:
        """Entering DP from standby: the reference starts at the estimate, at rest (``guidance.entry`` ``stop``)
        or moving as the vessel moves (``glide``).

        Why at rest by default: a vessel drifting in standby (the supply vessel at 0.14 m/s after 20 s in the
        failsafe campaign's 1.4× sea) is carried on by a gliding reference over its natural period (1.2 m more
        in that run) before DP pushes back; at rest, the controller's damping brakes her at once, up to what
        the drives give (their rate limits and the jerk limit of the fed-forward acceleration still apply).
        Measured in docs/fault-handling.md, "Entering DP while drifting".
        """
        estimate = self.out.estimate
        assert estimate is not None
        if self.entry == "stop":
            self.reference_model.reset(estimate.eta_hat_ned)
        else:
            nu_ned = body_to_ned(estimate.nu_hat_b, float(estimate.eta_hat_ned[2]))
            limits = self.config.guidance
            speed = math.hypot(nu_ned[0], nu_ned[1])
            if speed > limits.max_speed_mps:  # never start the reference faster than it may move
                nu_ned[:2] *= limits.max_speed_mps / speed
            nu_ned[2] = max(-limits.max_yaw_rate_radps, min(limits.max_yaw_rate_radps, nu_ned[2]))
            self.reference_model.reset(estimate.eta_hat_ned, nu_ned)
        self._accel_ff_ned = None
        self.controller.reset()
        if not self._setpoint_given:
            self.setpoint_ned[:] = estimate.eta_hat_ned

    def _change_mode(self, t_s: float, wanted: Mode) -> None:
        """Switch to ``wanted``: the change recorded with its reason, a restored fall-back announced."""
        self.out.mode_changes.append((self.mode.value, wanted.value, self._fallback_reason or "operator"))
        if self._fallback_reason.startswith("restored") and self._fell_back is not None:
            self._fell_back = None
            self.alarms.clear(t_s, "mode.fallback")
            text = f"{self._fallback_reason[len('restored: '):]}: {wanted.value} restored"
            self.alarms.raise_(t_s, "mode.restored", Severity.INFO, text)
            self.alarms.clear(t_s, "mode.restored")  # (an event in the record, not a standing alarm)
        elif not self._fallback_reason:  # the operator took over again: the fall-back is history
            self.alarms.clear(t_s, "mode.fallback")
        self._fallback_reason = ""
        self.mode = wanted
        self._requested_mode = wanted

    def _thrusters_insufficient(self, t_s: float, mode: Mode) -> str:
        """Why the thrusters available now cannot hold ``mode``'s degrees of freedom ("" when they can), raising
        ``thrusters.insufficient`` (critical) when they cannot: a controlled mode engaged without the means to
        hold it is a drift-off the operator believes is DP. ``auto_position`` holds surge, sway and yaw,
        ``auto_heading`` yaw; the available thrusters' columns of the configuration matrix B must span them
        (rank), a necessary condition the allocation's capability alarm completes with the forces needed."""
        available = self.monitor.available
        key = (available.tobytes(), mode)
        verdict = self._thrust_verdicts.get(key)
        if verdict is None:
            verdict = self._judge_thrusters(available, mode)
            if len(self._thrust_verdicts) < 256:  # (masks seen; bounded for a fleet of many drives)
                self._thrust_verdicts[key] = verdict
        if verdict:
            self.alarms.raise_(t_s, "thrusters.insufficient", Severity.CRITICAL, f"{mode.value} refused: {verdict}")
            self._insufficient_for = mode
        return verdict

    def _judge_thrusters(self, available: np.ndarray, mode: Mode) -> str:
        """:meth:`_thrusters_insufficient`'s verdict for an availability mask (uncached)."""
        if not available.any():
            return "no thruster available"
        if self.rudder_steering:
            if self._rudder_index is None or not available[self._rudder_index]:
                return "the rudder is not available"
            return ""
        geometry = self.allocator.geometry
        variables = geometry.variables_of(available)
        # the force of each available variable at its thruster's rating [N, N, N·m] ...
        columns = geometry.B[:, variables] * geometry.scale_n[geometry.variable_thruster[variables]]
        held = [0, 1, 2] if mode is Mode.AUTO_POSITION else [2]
        scale = self.allocator.capability_scale[held]
        # ... and the rank of the held DOFs' rows, each over the fleet's capability in it (N and N·m compared)
        rows = columns[held] / scale[:, None]
        if np.linalg.matrix_rank(rows, tol=1e-6) < len(held):
            names = ", ".join(spec.name for spec, ok in zip(self.thrusters, available.tolist(), strict=True) if ok)
            dofs = "surge, sway and yaw" if mode is Mode.AUTO_POSITION else "yaw"
            return f"the available thrusters ({names}) cannot produce {dofs}"
        return ""

    def _clear_insufficient(self, t_s: float) -> None:
        """Clear ``thrusters.insufficient`` once the thrusters available could hold the refused mode again."""
        mode = self._insufficient_for
        if mode is None:
            return
        available = self.monitor.available
        verdict = self._thrust_verdicts.get((available.tobytes(), mode))
        if verdict is None:
            verdict = self._judge_thrusters(available, mode)
        if not verdict:
            self.alarms.clear(t_s, "thrusters.insufficient")
            self._insufficient_for = None

    def _supervise(self, controller: MassAdaptation, t_s: float) -> None:
        """``control.adaptation``: an MRAC estimate on its projection bound suspends the adaptation.

        The controller returns to its nominal parameters, the fixed PD of seed 003 eq. (25), which holds
        the vessels whose adaptation was measured to run away (:meth:`MracController.mass_at_bound`). The
        alarm stays up until a restart, which adapts again.
        """
        dof = controller.mass_at_bound()
        if dof is None:
            return
        ratio = controller.mass_hat_floats[dof] / controller.mass_nominal[dof]
        controller.suspend_adaptation()  # (adapting is False from here on: no more supervision)
        self.alarms.raise_(t_s, "control.adaptation", Severity.ALARM,
                           f"MRAC {_MASS_NAMES[dof]} estimate reached its bound ({ratio:.2g}x nominal): adaptation "
                           "suspended, nominal parameters (fixed PD) until a restart")

    def _position_loss(self, t_s: float, lost_s: float, wanted: Mode, carrier: str) -> Mode:
        """In ``auto_position`` with every position reference lost for ``lost_s``: the mode wanted after it
        (``carrier``: what the position is dead-reckoned on, for the alarm text).

        An estimator without a vessel model (``dead_reckons`` False) only extrapolates the last velocity:
        holding position on it pushes against an error that exists only in the estimate (the Blue Lady 17 m
        off in a 90 s GNSS outage). Without a model there is no dead reckoning: the fall-back comes at once,
        and ``dead_reckoning`` means keeping the heading with no surge and sway force (``hold_heading``); the
        rule is resolved once, in ``__init__``.
        """
        limit_s, action = self._position_loss_rule
        if lost_s < limit_s:
            return wanted
        return self._loss_limit(t_s, "position", action, limit_s, wanted, carrier=carrier)

    def _loss_limit(self, t_s: float, kind: str, action: str, limit_s: float, wanted: Mode, *,
                    carrier: str) -> Mode:
        """Every ``kind`` (``position``/``heading``) reference lost for ``limit_s``: keep holding on what carries it
        (``carrier``: the model, a receiver's velocity, a rate of turn) with a critical alarm (``action``
        ``dead_reckoning``), or fall back to standby / auto_heading. Returns the mode wanted after it."""
        if action == "dead_reckoning":
            self.alarms.raise_(t_s, f"{kind}.dead_reckoning_limit", Severity.CRITICAL,
                               f"{kind} dead-reckoned beyond {limit_s:g} s: still holding on {carrier}; the "
                               "operator decides")
            return wanted
        fallback = Mode.STANDBY if action == "standby" else Mode.AUTO_HEADING
        self._fallback(t_s, fallback, f"{kind} references lost")
        return fallback

    def _fallback(self, t_s: float, mode: Mode, reason: str) -> None:
        self._fallback_reason = f"fallback: {reason}"
        self.alarms.raise_(t_s, "mode.fallback", Severity.ALARM, f"{reason}: fell back to {mode.value}")
        self._requested_mode = mode
        if self._fell_back is None:  # (the first fall-back's mode is the one to return to)
            self._fell_back = (self.mode, t_s)

    def _restore(self, t_s: float, hub: HubOutput, fell_back: tuple[Mode, float]) -> Mode:
        """The mode to be in after a fall-back: the one fallen back from once its references are back, if the
        fall-back has lasted less than ``fallback.restore_within_s`` (an event says so, ``mode.restored``);
        after that the operator decides (and ``mode.fallback`` stays up)."""
        mode, since = fell_back
        if t_s - since > self.config.fallback.restore_within_s:
            self._fell_back = None
            return self.mode
        if not (hub.heading_available and (hub.position_available or mode is not Mode.AUTO_POSITION)):
            return self.mode
        self._fallback_reason = f"restored: references back after {t_s - since:.1f} s of fall-back"
        return mode

    def _capability_alarm(self, t_s: float) -> None:
        """``thrusters.capability``: the allocator has left part of the demand unmet for
        ``shortfall_persist_s`` in some DOF — more than ``shortfall_fraction`` of the demanded force
        there, or of ``CAPABILITY_FLOOR`` × the fleet's capability when the demand is small.

        Relative to the demand, not to the fleet's capability alone: after losing both bow tunnels in a
        beam wind the stern azimuths miss 2 MN·m of a yaw demand of 0.3 MN·m — the heading is lost — yet
        that is under 10 % of the 34 MN·m the intact fleet could make.
        """
        # (the alarm is raised only while a shortfall is pending: with none pending there is nothing to clear)
        since = self._shortfall_since
        if self.mode is Mode.STANDBY:
            if since is not None:
                self.alarms.clear(t_s, "thrusters.capability")
                self._shortfall_since = None
            return
        # on Python floats (three numbers; numpy calls cost several times the arithmetic)
        s = self.config.thruster_monitor
        out = self.out
        fraction = s.shortfall_fraction
        f0, f1, f2 = self._capability_floor
        t0, t1, t2 = out.tau_b.tolist()
        m0, m1, m2 = out.shortfall_b.tolist()
        short = (abs(m0) > fraction * max(abs(t0), f0) or abs(m1) > fraction * max(abs(t1), f1)
                 or abs(m2) > fraction * max(abs(t2), f2))
        if short:
            if since is None:
                self._shortfall_since = t_s
                since = t_s
            if t_s - since >= s.shortfall_persist_s:
                self.alarms.raise_(t_s, "thrusters.capability", Severity.ALARM,
                                   "thrust demand exceeds the capability of the available thrusters")
        elif since is not None:
            self._shortfall_since = None
            self.alarms.clear(t_s, "thrusters.capability")

    # ------------------------------------------------------------------ persistence
    def state_dict(self, t_s: float) -> dict[str, Any]:
        """Everything needed to resume without a jump (docs/installation.md, restarts); JSON-able."""
        state: dict[str, Any] = {
            "version": STATE_VERSION, "t_s": t_s, "config_sha256": self.config.config_hash,
            "mode": self.mode.value, "setpoint_n": self.setpoint_ned.tolist(), "setpoint_given": self._setpoint_given,
            "datum": None if self.hub.datum is None else [self.hub.datum.lat0_deg, self.hub.datum.lon0_deg],
            "allocator": self.allocator.state_dict(), "monitor": self.monitor.state_dict(),
            "thrust_n": self.out.thrust_n.tolist(), "azimuth_rad": self.out.azimuth_rad.tolist(),
        }
        if self._estimator_ready:
            state["estimator"] = self.estimator.state_dict()
        if self.mode is not Mode.STANDBY:
            state["reference"] = self.reference_model.state_dict()
            if self._accel_ff_ned is not None:
                state["accel_ff_n"] = list(self._accel_ff_ned)
        state["controller"] = self.controller.state_dict()
        consequence = None if self.consequence is None else self.consequence.state_dict(t_s)
        if consequence is not None:
            state["consequence"] = consequence
        return state

    def load_state_dict(self, state: dict[str, Any], t_s: float) -> None:
        """Resume from :meth:`state_dict` (the caller checked its age and config hash)."""
        if state.get("version") != STATE_VERSION:
            raise ValueError("persisted state of another version")
        if state.get("datum") is not None and self.hub.datum is None:
            self.hub.datum = LocalFrame(*state["datum"])
        self.allocator.load_state_dict(state["allocator"])
        self.monitor.load_state_dict(state.get("monitor", {}))
        self.out.thrust_n[:] = state["thrust_n"]
        self.out.azimuth_rad[:] = state["azimuth_rad"]
        self.setpoint_ned[:] = state["setpoint_n"]
        self._setpoint_given = bool(state.get("setpoint_given", True))
        self._mass_sent = None  # the restored filter's mass ratio is not what was last sent
        if "estimator" in state:
            self.estimator.load_state_dict(state["estimator"])
            self._estimator_ready = True
            self._valid_since_t_s = t_s
        if "controller" in state:
            self.controller.load_state_dict(state["controller"])
        mode = Mode(state.get("mode", "standby"))
        if mode is not Mode.STANDBY and "reference" in state and self._estimator_ready:
            self.reference_model.load_state_dict(state["reference"])
            accel = state.get("accel_ff_n")
            if accel is None:
                self._accel_ff_ned = None
            else:
                a0, a1, a2 = np.array(accel, dtype=float).reshape(3).tolist()
                self._accel_ff_ned = (a0, a1, a2)
            self.mode = mode
            self._requested_mode = mode
            self._engaged_once = True
            if self.consequence is not None and "consequence" in state:
                self.consequence.load_state_dict(state["consequence"], t_s)
        self._last_t_s = t_s
