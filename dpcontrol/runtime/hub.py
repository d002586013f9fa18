"""Sensor hub: validity, quality tests, voting and fusion of position and heading references.

What commercial DP systems run on every position reference (IMO MSC/Circ.645, MSC.1/Circ.1580),
applied to every position and heading sensor:

* **invalid** data never arrives here: the codecs turn GGA quality 0, RMC V, THS V, N2K
  "not available" into rejects; only valid messages are :class:`Measurement` s;
* **drop-out**: no sample for ``stale_periods`` × the nominal period → *stale*;
* **freeze**: identical values for ``freeze_window_s`` while time advances → *frozen* (rejected);
* **prediction** (jump): a sample further from the wave filter's predicted measurement than
  ``max(jump_min, k·√(S + σ²))`` is rejected at once; a sensor rejected continuously for
  ``reject_persist_s`` while the others agree is marked *rejected*;
* **variance**: each reference's residual variance about the prediction is tracked; its weight in
  the fusion is the inverse of the larger of that variance and its GST statistics (when present),
  and an alarm is raised when it exceeds ``variance_alarm_factor``² × the nominal variance and the
  quietest other reference's (after one ``variance_time_constant_s`` of samples; hysteresis);
* **median** (≥ 3 references): a reference further than ``median_limit`` from the median for
  ``median_persist_s`` is *isolated*; with two references a disagreement raises an alarm without
  isolation;
* **re-estimation**: when every live reference of a kind has failed the prediction test for
  ``reject_persist_s`` and none had a sample accepted in that time, it is the estimate that is wrong
  (long dead reckoning): the references are trusted again and the caller re-initialises the estimator.
  A *lone* reference of its kind (nothing to confirm it) is trusted so only after
  ``single_reference_accept_s`` (alarm ``<kind>.reference_rejected`` meanwhile: the loop dead-reckons), or
  at once when the operator accepts it (:meth:`SensorHub.accept_reference`);
* **repeats**: a value repeated exactly is no new sample (the reference stays alive, the estimator is not
  corrected with it; *frozen* after the window);

Fusion is the inverse-variance weighted mean of the healthy references (latest samples, moved to
the present with the estimated LF velocity). Bumpless, so that the estimator — and so the thrust —
never sees a jump:

* when the set of references in use changes, the step between the *levels* of the old and the new
  set (inverse-variance means of each reference's low-passed value: the bias between references,
  not one sample's noise) is added to the output and faded out over ``switch_blend_s``;
* a reference back to OK (after a drop-out, freeze, rejection, isolation or disconnection) is fused
  again only after ``readmit_s`` of good samples, so that its level has settled — unless none of
  its kind is in use;
* when references come back after all of a kind were lost, the output starts at the estimator's
  (dead-reckoned) prediction: the offset is the running mean of prediction − fused value over
  ``readmit_s``, then faded out over ``switch_blend_s``.

**Heading dead reckoning on the rate of turn.** A rate of turn (a ``rate_of_turn`` sensor: a rate gyro
independent of the gyrocompasses; or a heading sensor's own ROT) is a *source* while it is fresh (a sample
within ``stale_periods`` × its period), not frozen (its value changed within ``rot_freeze_s``, and within
``freeze_window_s`` if that is shorter: a rate gyro's noise changes every sample) and in range (``|r| ≤
rot_max``). While the heading is measured, each source's bias is learnt: b̂ ← b̂ + α((∫r dt − Δψ)/Δt − b̂)
between consecutive fresh fused headings, α = Δt / ``rot_bias_window_s`` (a running mean until a window has
passed). The differences of the heading noise telescope, so b̂'s error is ≈ σ_ψ/window + σ_r·√(T_s/window): 0.001
°/s for a 0.05° gyro over 60 s, against a rate gyro's turn-on bias of a few 0.01 °/s and its minutes-long bias
stability. From the last fresh heading on the hub integrates ψ_dr = ψ(t₀) + ∫(r − b̂)dt (ψ(t₀): that heading
combined with the estimator's prediction) with the first valid source whose bias has been learnt (rate sensors
first, in the configured order, then heading sensors' own). With every heading reference lost and a
source valid, ψ_dr is the heading measurement the estimator gets, with variance σ²_dr = σ²(t₀) + σ_r²T_s·τ +
(σ_b·τ)² (the rate noise's random walk and the bias uncertainty, τ = time since t₀): the estimators run
steady-state gains, so ψ_dr is fed as ŷ + S/(S + σ²_dr)·(ψ_dr − ŷ) (S the heading innovation variance), which is
the Kalman update with R + σ²_dr; and σ²_dr replaces the model's growth of the prediction test's variance. A gyro
coming back is blended in from the dead-reckoned prediction as after any loss. Without a valid source (the gyro's
own ROT froze or fell silent with it) nothing changes: the model carries the heading.

**Rate check** (with a ``rate_of_turn`` sensor). A lone gyro that drifts slowly is followed: nothing else measures
the heading, and the estimator's bias states learn the drift as a force. The rate sensor is independent of the
gyros, so each gyro's heading change is compared with it over a sliding window of T = ``rot_check_window_s``
(30 s), at each new gyro sample: D = Δψ_gyro − ∫(r − b̂)dt, against the limit max(``rot_check_min`` (1°),
k·σ_D), k = ``rot_check_sigma_factor`` (5), σ_D² = 2σ_ψ² + σ_r²T_s·T + σ_b̂²T² (the gyro's noise at both ends of
the window — its measured one when larger —, the rate noise's random walk, the bias estimate's error over T). σ_D
is 0.1–0.15° for a 0.05° gyro and a 0.01 °/s rate gyro; the floor covers what the statistic does not model (a rate
gyro's bias instability, up to 0.01 °/s × 30 s = 0.3°; a gyrocompass's dynamic errors) and is a third of the 3°
heading bound: a 0.2 °/s drift is caught after 5 s. Drifts slower than 1°/T (0.033 °/s) go unseen. The rate
sensor's bias is learnt in blocks of T, each committed only when the block after it also kept |D| within half the
limit (a drift that starts late in a block is seen in the next), so the bias never learns the drift; it is held
while the check has a verdict.

|D| beyond the limit: **which is wrong** — two sources cannot vote. Another gyro that agrees with the rate says the
disagreeing gyro; other gyros that disagree too say the rate. A lone gyro: the share of D in the gyro's own
heading change, φ = Δψ_gyro / D, decides. In DP the heading is held, so the vessel's own turn over the window is
small against D: a gyro that drifts shows the disagreement in its heading change (φ ≈ 1: the vessel has not yet
turned under the controller, which follows the gyro), a rate sensor that is off in its integral while the gyro's
heading stays (φ ≈ 0). φ ≥ 2/3: the gyro is *rejected* (``sensor.<gyro>.rejected``, "disagrees with rate of
turn") and — alone — the heading dead-reckoned on the rate from where the rate says it is (the gyro's heading at
the window's start + ∫(r − b̂)dt), not from the estimate that followed the drift; φ ≤ 1/3: the rate sensor is
rejected (not dead-reckoned on); in between, or in a turn larger than 3·|D|, neither: the alarm says it cannot
tell. Every verdict raises ``heading.rate_disagreement`` (alarm); it is decided once, when D first crosses the limit
(later the controller has turned the vessel after the drifting gyro and φ falls). The verdict ends — the gyro or
the rate taken back, the alarm cleared — when every gyro compared has kept |D| within half the limit for
``rot_check_return_s`` (10 s): after a drift that stops, a window later. Without a valid rate sensor (stale,
frozen, bias not yet learnt) nothing is compared and a verdict ends.

**Noisy position references.** The variance test weighs references against each other; a lone receiver (or all of
them at once) whose noise grows has nothing to be weighed against, and the estimator, whose steady-state gains are
tuned for the configured noise, would take it as it comes. Each position reference's *recent noise* is measured from
its own samples, independently of the estimator (whose feedback makes the residuals about its prediction look noisier
than the receiver is): the second divided difference of three consecutive samples, d = Δ₁/h₁ − Δ₂/h₂ per axis, is
zero for any constant velocity, offset or drift (a jump makes two large values) and σ²·(1/h₁² + (1/h₁ + 1/h₂)² +
1/h₂²) for white noise σ; the median of the normalised (d_n² + d_e²)/2 over the last ``noise_window_s`` (3 s, at
least 15 samples), divided by ln 2 (the median of χ²₂/2), is its variance. Every new sample counts, the ones the
prediction test rejects too, so that the median follows the noise up and down within half a window (1.5–2 s at
10 Hz). The noise of a reference is the larger of that and its GST's; ΔR = Σ w_i²·max(σ_i² − (κ·σ_cfg,i)², 0) over the
references in use (w_i their share in the fused value, σ_cfg,i the configured 1-σ, κ = ``noise_deweight_factor``, 3,
above what healthy receivers reach in this measure: docs/fault-handling.md). With ΔR > 0 the fused position is
fed as ŷ + S'/(S' + ΔR)·(y − ŷ), the Kalman update with R + ΔR, where S' = S + G and G is the prediction's variance
grown while de-weighted as in dead reckoning (√G at ``dead_reckoning_drift_mps``, each de-weighted update taking its
share off): a long noise lets the receiver back in by degrees instead of dead-reckoning on. The prediction test judges
a sample with the recent noise when that is larger. ``position.noisy_reference`` (warning) is raised while the gain
is below half its own (naming the receiver, its noise and the configured one) and clears when ΔR is 0 again: the
receiver is then taken back as after a loss, from the estimator's prediction, the error of the de-weighted time
measured over ``readmit_s`` and faded out over ``switch_blend_s``, so that the thrust does not step. Headings are not
de-weighted: a gyro's residuals hold the wave filter's yaw prediction error, well above its configured noise, and the
plant injects no heading noise to measure a rule on.

The hub is pure: time is the ``t_s`` argument; no clock, no I/O.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Iterable, Sequence
from dataclasses import InitVar, dataclass, field
from enum import Enum
from typing import TypedDict

from dpbase.frames import ssa
from dpbase.geodesy import LocalFrame, lever_arm_ned
from dpcontrol.runtime.alarms import AlarmRegistry, Severity
from interfaces.messages import (
    CourseOverGround,
    Heading,
    Measurement,
    PositionErrorStats,
    PositionFix,
    RateOfTurn,
)


class SensorKind(str, Enum):
    """What a sensor measures."""

    POSITION = "position"
    HEADING = "heading"
    RATE = "rate_of_turn"  # a rate gyro, independent of the gyrocompasses: heading dead reckoning only


class SensorState(str, Enum):
    """Health of one reference, as published in the status."""

    WAITING = "waiting"  # never delivered a valid sample
    OK = "ok"
    STALE = "stale"  # drop-out
    FROZEN = "frozen"
    REJECTED = "rejected"  # persistent prediction-test failures
    ISOLATED = "isolated"  # median test
    DISCONNECTED = "disconnected"  # transport reports link loss


_ALARM_STATES = frozenset({SensorState.STALE, SensorState.FROZEN, SensorState.REJECTED,
                           SensorState.DISCONNECTED})
_HEALTHY_STATES = (SensorState.OK, SensorState.ISOLATED)  # fused, or voted out by the median test only
# The recent noise of a position reference (module docstring, "Noisy position references"): a median of fewer samples
# is too loose (a healthy receiver would be found noisy now and then); the median of the per-sample variance estimate
# (d_n² + d_e²)/12 = σ²·χ²₂/2 over its mean: ln 2
_RECENT_MIN_SAMPLES = 15

_MEDIAN_CHI2_2 = math.log(2.0)
_MAX_SPEED_MPS = 100.0  # a speed over ground beyond this is no ship's (interfaces.limits allows more)


@dataclass(frozen=True)
class SensorConfig:
    """One position or heading reference.

    Attributes
    ----------
    name : str
        Sensor name (the ``source`` of its measurements).
    kind : SensorKind
    nominal_rate_hz : float
        Expected update rate [Hz] (drop-out detection).
    sigma : float
        Nominal 1-σ noise [m] for position, [rad] for heading, [rad/s] for a rate of turn.
    lever_arm_m : tuple of float
        Antenna position in the body frame (x forward, y starboard) [m]; position sensors only.
    velocity_sigma : float
        1-σ of the receiver's velocity (SOG/COG) per horizontal axis [m/s]; position sensors only (velocity check).
    """

    name: str
    kind: SensorKind
    nominal_rate_hz: float
    sigma: float
    lever_arm_m: tuple[float, float] = (0.0, 0.0)
    velocity_sigma: float = 0.1


@dataclass(frozen=True)
class HubConfig:
    """Thresholds of the quality tests (defaults: docs/fault-handling.md)."""

    stale_periods: float = 5.0
    freeze_window_s: float = 5.0
    freeze_tolerance_m: float = 1e-4
    freeze_tolerance_rad: float = 1e-7
    jump_sigma_factor: float = 5.0
    jump_min_m: float = 4.0
    heading_jump_min_rad: float = math.radians(5.0)
    reject_persist_s: float = 10.0
    single_reference_accept_s: float = 180.0
    dead_reckoning_drift_mps: float = 0.02
    dead_reckoning_drift_radps: float = math.radians(0.02)
    variance_time_constant_s: float = 20.0
    variance_alarm_factor: float = 3.0
    median_limit_m: float = 3.0
    median_heading_limit_rad: float = math.radians(2.0)
    median_persist_s: float = 2.0
    median_filter_s: float = 5.0
    switch_blend_s: float = 20.0
    readmit_s: float = 5.0
    error_rate_alarm: float = 0.2  # share of malformed frames on a transport (transport_health.py)
    error_rate_window_s: float = 10.0
    # Heading dead reckoning on the rate of turn (module docstring): the bias average's window [s], the time a
    # rate may stay unchanged before it counts as frozen [s], the physical range of a ship's rate of turn [rad/s]
    # (CyberShip II, a 1:70 model, turns √70 times faster than a ship), and the noise of a heading sensor's own
    # rate of turn, which its configuration does not give [rad/s]
    rot_bias_window_s: float = 60.0
    rot_freeze_s: float = 1.0
    rot_max_radps: float = math.radians(30.0)
    rot_sigma_radps: float = math.radians(0.05)
    # The gyros against the independent rate of turn (module docstring, "Rate check"): the sliding window [s], the
    # limit's factor on the disagreement's 1-σ [-] and its floor [rad], how long a rejected gyro (or a blamed rate
    # sensor) must agree again before it is taken back [s]
    rot_check_window_s: float = 30.0
    rot_check_sigma_factor: float = 5.0
    rot_check_min_rad: float = math.radians(1.0)
    rot_check_return_s: float = 10.0
    # Each position reference against its own velocity (SOG/COG; module docstring, "Velocity check"): the sliding
    # window [s], the limit's factor on the disagreement's 1-σ [-] and its floor [m], the time constant of the
    # low-pass of position − ∫velocity [s], how long a rejected receiver must be back at its level before it is
    # taken back [s]
    velocity_check_window_s: float = 30.0
    velocity_check_sigma_factor: float = 6.0
    velocity_check_min_m: float = 1.0
    velocity_check_filter_s: float = 2.0
    velocity_check_return_s: float = 5.0
    # The noise of the references in use against their configured one (module docstring, "Noisy position references"):
    # the window of the recent noise estimate [s] (at least 15 samples), the factor on the configured 1-σ above
    # which the excess variance is taken off the estimator's gain [-]
    noise_window_s: float = 3.0
    noise_deweight_factor: float = 3.0


@dataclass(eq=False, slots=True)
class _SensorTrack:
    """One reference's test state. Compared by identity (``eq=False``): the hub compares the lists of
    references it fused at consecutive steps; slots, because every field is read on every sample."""

    config: SensorConfig
    limits: InitVar[HubConfig]
    state: SensorState = SensorState.WAITING
    last_t_s: float | None = None  # receive time of the last sample (any, accepted or not)
    last_accepted_t_s: float | None = None
    value: tuple[float, float] = (0.0, 0.0)  # NED position [m] or (heading_rad, 0)
    accepted_value: tuple[float, float] = (0.0, 0.0)
    fresh: bool = False  # a new accepted sample since the last update
    frozen_since_t_s: float | None = None
    raw_previous: tuple[float, float] | None = None
    rejecting_since_t_s: float | None = None
    median_fail_since_t_s: float | None = None
    residual_variance: float | None = None  # measured noise variance (variance test) [m²] / [rad²]
    variance_samples: int = 0  # samples averaged into residual_variance
    previous_residual: tuple[float, float] | None = None
    previous_residual2: tuple[float, float] | None = None
    filtered: tuple[float, float] | None = None  # low-passed accepted value (median test, bumpless switch)
    filter_samples: int = 0  # samples in ``filtered`` since it (re)started
    usable_from_t_s: float = -math.inf  # readmission: not fused before this time
    noisy: bool = False  # variance alarm raised
    isolated_alarm: bool = False
    gst_sigma: float | None = None
    gst_t_s: float | None = None
    disconnected: bool = False
    samples: int = 0
    rejected_samples: int = 0
    detail: str = ""
    weight: float = 0.0
    # Constants of the sensor and hub configurations (both frozen), computed once: read on every sample
    name: str = field(init=False, default="")
    heading: bool = field(init=False, default=False)  # a heading reference (angles compared by ssa)
    nominal_period_s: float = field(init=False, default=0.0)  # 1 / nominal rate [s]
    stale_s: float = field(init=False, default=0.0)  # stale_periods × period: drop-out, filter restart [s]
    gst_valid_s: float = field(init=False, default=0.0)  # 3 × stale_periods × period: GST still current [s]
    continuity_s: float = field(init=False, default=0.0)  # 2.5 × period: residuals consecutive [s]
    variance_alpha: float = field(init=False, default=0.0)  # EWMA weight of the variance test [-]
    # a position reference's per-sample noise variances over the last noise_window_s (the recent noise)
    recent: deque[float] = field(init=False, default_factory=deque)
    recent_min: int = field(init=False, default=0)  # samples the recent noise needs before it counts
    recent_variance: float | None = None  # the recent noise variance [m²] (None: too few samples yet)
    # the last two accepted position samples (time [s], NED [m]), for the recent noise's second differences
    recent_previous: tuple[float, tuple[float, float], tuple[float, tuple[float, float]] | None] | None = None
    # the other references of its kind, in the configured order (the variance test's comparison)
    peers: list[_SensorTrack] = field(init=False, default_factory=list)
    rate: _RateSource | None = field(init=False, default=None)  # a heading sensor's own rate of turn
    check: _RateCheck | None = field(init=False, default=None)  # against the rate sensor (a rate sensor configured)
    velocity: _VelocityCheck | None = field(init=False, default=None)  # a position reference against its velocity
    antenna: tuple[float, float] = (0.0, 0.0)  # the last sample's antenna position, NED [m] (no lever arm applied)

    def __post_init__(self, limits: HubConfig) -> None:
        config = self.config
        period = 1.0 / config.nominal_rate_hz
        self.name = config.name
        self.heading = config.kind is SensorKind.HEADING
        self.nominal_period_s = period
        # the products in the order the tests wrote them, so that the limits are the same floats
        self.stale_s = limits.stale_periods * period
        self.gst_valid_s = 3.0 * limits.stale_periods * period
        self.continuity_s = 2.5 * period
        self.variance_alpha = min(1.0, period / limits.variance_time_constant_s)
        size = max(_RECENT_MIN_SAMPLES, math.ceil(limits.noise_window_s * config.nominal_rate_hz))
        self.recent = deque(maxlen=size)
        self.recent_min = (size + 1) // 2


@dataclass(eq=False, slots=True)
class _RateSource:
    """A rate of turn the heading can be dead-reckoned on: a ``rate_of_turn`` sensor, or a heading sensor's own
    (``owner``). Its validity tests and its bias estimate (module docstring)."""

    name: str
    sigma_radps: float  # white noise of one sample [rad/s]
    period_s: float  # nominal sample period [s]
    stale_s: float  # no sample for this long → stale [s]
    owner: _SensorTrack | None = None  # the heading sensor it belongs to (None: a rate sensor of its own)
    value: float = 0.0  # the latest in-range sample [rad/s]
    last_t_s: float | None = None  # receive time of that sample
    changed_t_s: float = -math.inf  # when its value last changed (freeze test) [s]
    samples: int = 0
    rejected_samples: int = 0  # out of range
    disconnected: bool = False
    state: SensorState = SensorState.WAITING
    bias: float = 0.0  # estimated bias [rad/s]
    bias_time_s: float = 0.0  # heading time the bias has averaged [s]
    bias_heading_var: float = 0.0  # variance of the fused heading it was learnt against [rad²]
    chain_heading: float | None = None  # fused heading at the start of the current bias span (None: no span)
    chain_t_s: float = 0.0
    chain_integral: float = 0.0  # ∫ r dt since chain_t_s [rad]
    # A rate sensor's bias is learnt in blocks of rot_check_window_s, each committed only once the block after it
    # has passed the rate check too (a drift that starts late in a block is seen in the next): the sum of
    # ∫r dt − Δψ [rad] and the time [s] of the block being collected and of the one waiting
    block_error: float = 0.0
    block_time_s: float = 0.0
    block_dirty: bool = False  # a disagreement built up during it: discarded
    pending_error: float = 0.0
    pending_time_s: float = 0.0  # (0: none waiting)
    blamed: bool = False  # the rate check found this rate wrong: not dead-reckoned on

    def valid(self, t_s: float, freeze_s: float) -> bool:
        """Fresh, not frozen, not disconnected (a sample out of range never becomes the value)."""
        last = self.last_t_s
        owner = self.owner
        return last is not None and t_s - last <= self.stale_s and t_s - self.changed_t_s < freeze_s \
            and not self.disconnected and (owner is None or not owner.disconnected)

    def bias_variance(self, window_s: float) -> float:
        """Variance of the bias estimate [rad²/s²]: the heading's noise over the averaged time (its differences
        telescope) and the rate noise averaged over it; infinite before any heading was compared."""
        span = min(self.bias_time_s, window_s)
        if span <= 0.0:
            return math.inf
        return 2.0 * self.bias_heading_var / (span * span) + self.sigma_radps ** 2 * self.period_s / span


@dataclass(eq=False, slots=True)
class _RateCheck:
    """A heading reference against the rate sensor over the sliding window (module docstring, "Rate check"): a
    ring of (time, the reference's unwrapped heading, ∫(r − b̂)dt) at each of its new samples, allocated once."""

    size: int  # ring capacity: twice the window's nominal samples, so a faster sensor only shortens the window
    times: list[float] = field(init=False)
    headings: list[float] = field(init=False)
    integrals: list[float] = field(init=False)
    head: int = -1  # newest entry
    tail: int = 0  # oldest entry in the window
    count: int = 0  # entries from tail to head
    samples: int = -1  # the reference's sample count at the last entry
    previous: float = 0.0  # its last raw heading [rad] (unwrapping)
    unwrapped: float = 0.0  # its heading made continuous [rad]
    disagreement: float = 0.0  # D = Δψ − ∫(r − b̂)dt over the window [rad]
    heading_change: float = 0.0  # Δψ over the window [rad]
    span_s: float = 0.0
    limit: float = math.inf  # max(floor, k·σ_D) [rad]
    rejected: bool = False  # found drifting: not fused
    agree_since_t_s: float | None = None  # |D| within half the limit since then
    detail: str = ""

    def __post_init__(self) -> None:
        self.times = [0.0] * self.size
        self.headings = [0.0] * self.size
        self.integrals = [0.0] * self.size

    def reset(self) -> None:
        """A gap (the reference stale, frozen or disconnected; the rate sensor changed): the window restarts."""
        self.count = 0
        self.head = -1
        self.tail = 0
        self.samples = -1
        self.disagreement = self.heading_change = self.span_s = 0.0
        self.limit = math.inf
        self.agree_since_t_s = None

    def add(self, t_s: float, heading: float, integral: float, window_s: float) -> None:
        """A new sample ``heading`` [rad] at ``t_s`` with the rate's integral [rad]; the window's D and span."""
        if self.count == 0:
            self.unwrapped = heading
        else:
            self.unwrapped += ssa(heading - self.previous)
        self.previous = heading
        size = self.size
        head = self.head = (self.head + 1) % size
        self.times[head] = t_s
        self.headings[head] = self.unwrapped
        self.integrals[head] = integral
        if self.count == size:  # full: the oldest goes
            self.tail = (self.tail + 1) % size
        else:
            self.count += 1
        times = self.times
        start = t_s - window_s
        while self.count > 1 and times[(self.tail + 1) % size] <= start:  # (the oldest entry at or before start)
            self.tail = (self.tail + 1) % size
            self.count -= 1
        tail = self.tail
        self.span_s = t_s - times[tail]
        self.heading_change = self.unwrapped - self.headings[tail]
        self.disagreement = self.heading_change - (integral - self.integrals[tail])


@dataclass(eq=False, slots=True)
class _VelocityCheck:
    """A position reference against its own velocity (module docstring, "Velocity check"): the integral of the
    velocity, and a ring of (time, low-passed antenna position − ∫v dt, its variance, the integral's variance) at
    each of the reference's new samples, allocated once."""

    size: int  # ring capacity: twice the window's nominal samples
    sigma_mps: float  # the velocity's 1-σ per axis [m/s]
    times: list[float] = field(init=False)
    north: list[float] = field(init=False)
    east: list[float] = field(init=False)
    variances: list[float] = field(init=False)  # of the low-passed value [m²]
    integral_variances: list[float] = field(init=False)  # of ∫v dt since the integral started [m²]
    head: int = -1
    tail: int = 0
    count: int = 0
    samples: int = -1  # the reference's sample count at the last entry
    velocity_t_s: float | None = None  # receive time of the latest velocity (None: none ever: the check is off)
    v_north: float = 0.0  # the latest velocity [m/s]
    v_east: float = 0.0
    integral_north: float = 0.0  # ∫v dt up to velocity_t_s [m]
    integral_east: float = 0.0
    integral_variance: float = 0.0  # σ_v² Σh² [m²]
    raw: tuple[float, float] = (0.0, 0.0)  # the last position − ∫v dt [m]
    raw2: tuple[float, float] = (0.0, 0.0)  # the one before
    noise_variance: float = 0.0  # of position − ∫v dt about its smooth part, per axis [m²] (second differences)
    noise_samples: int = 0
    filtered: tuple[float, float] = (0.0, 0.0)  # low-passed position − ∫v dt [m]
    filtered_variance: float = 0.0
    filter_samples: int = 0
    last_t_s: float = 0.0  # time of the last entry
    disagreement: tuple[float, float] = (0.0, 0.0)  # D over the window, (north, east) [m]
    span_s: float = 0.0
    limit: float = math.inf  # max(floor, k·σ_D) [m]
    rejected: bool = False
    # while rejected: the level before the disagreement (the window's oldest entry at the verdict), its
    # variance and the integral's variance then; |level now − it| within half the limit for return_s: back
    reference: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)
    agree_since_t_s: float | None = None
    detail: str = ""

    def __post_init__(self) -> None:
        self.times = [0.0] * self.size
        self.north = [0.0] * self.size
        self.east = [0.0] * self.size
        self.variances = [0.0] * self.size
        self.integral_variances = [0.0] * self.size

    def reset(self) -> None:
        """A gap (the position or the velocity stale, frozen, disconnected): the window and the low-pass restart."""
        self.count = 0
        self.head = -1
        self.tail = 0
        self.samples = -1
        self.filter_samples = 0
        self.disagreement = (0.0, 0.0)
        self.span_s = 0.0
        self.limit = math.inf

    def velocity(self, t_s: float, v_north: float, v_east: float, gap_s: float) -> None:
        """A velocity sample [m/s] at ``t_s``: the integral advanced (trapezoid) from the previous one; after a gap
        longer than ``gap_s`` the window restarts (the integral is not known across it)."""
        last = self.velocity_t_s
        if last is not None and 0.0 <= t_s - last <= gap_s:
            h = t_s - last
            self.integral_north += 0.5 * (self.v_north + v_north) * h
            self.integral_east += 0.5 * (self.v_east + v_east) * h
            self.integral_variance += self.sigma_mps * self.sigma_mps * h * h
        elif last is not None and self.count:
            self.reset()
        self.velocity_t_s = t_s
        self.v_north = v_north
        self.v_east = v_east

    def add(self, t_s: float, north_m: float, east_m: float, sigma_m: float, *, filter_s: float,
            window_s: float, variance_alpha: float) -> None:
        """A new position sample (antenna, NED [m]) at ``t_s``: position − ∫v dt (the integral carried to ``t_s``
        with the latest velocity) low-passed into the ring; the window's D and span. Its noise is the larger of
        ``sigma_m`` (what the receiver claims) and the one measured on position − ∫v dt itself: the velocity takes
        the vessel's motion out, wave motion included, so the second differences hold the receiver's noise (var =
        6σ² per axis); averaged with weight ``variance_alpha`` (a running mean first), not while rejected."""
        dt = t_s - (self.velocity_t_s if self.velocity_t_s is not None else t_s)
        q_north = north_m - (self.integral_north + self.v_north * dt)
        q_east = east_m - (self.integral_east + self.v_east * dt)
        if self.filter_samples >= 2 and not self.rejected:
            d_north = q_north - 2.0 * self.raw[0] + self.raw2[0]
            d_east = q_east - 2.0 * self.raw[1] + self.raw2[1]
            own = (d_north * d_north + d_east * d_east) / 12.0
            self.noise_samples += 1
            alpha = max(variance_alpha, 1.0 / self.noise_samples)
            self.noise_variance += alpha * (own - self.noise_variance)
        self.raw2 = self.raw
        self.raw = (q_north, q_east)
        noise = sigma_m * sigma_m
        if self.noise_samples >= 10:
            noise = max(noise, self.noise_variance)
        if self.filter_samples == 0:
            self.filtered = (q_north, q_east)
            self.filtered_variance = noise
            self.filter_samples = 1
        else:
            self.filter_samples += 1
            gap = max(t_s - self.last_t_s, 0.0)
            alpha = max(1.0 - math.exp(-gap / filter_s), 1.0 / self.filter_samples)
            f_north, f_east = self.filtered
            self.filtered = (f_north + alpha * (q_north - f_north), f_east + alpha * (q_east - f_east))
            self.filtered_variance = (1.0 - alpha) ** 2 * self.filtered_variance + alpha * alpha * noise
        self.last_t_s = t_s
        integral_variance = self.integral_variance + self.sigma_mps * self.sigma_mps * dt * dt
        size = self.size
        head = self.head = (self.head + 1) % size
        self.times[head] = t_s
        self.north[head], self.east[head] = self.filtered
        self.variances[head] = self.filtered_variance
        self.integral_variances[head] = integral_variance
        if self.count == size:
            self.tail = (self.tail + 1) % size
        else:
            self.count += 1
        times = self.times
        start = t_s - window_s
        while self.count > 1 and times[(self.tail + 1) % size] <= start:
            self.tail = (self.tail + 1) % size
            self.count -= 1
        tail = self.tail
        self.span_s = t_s - times[tail]
        self.disagreement = (self.north[head] - self.north[tail], self.east[head] - self.east[tail])

    def sigma(self, tail: int | None = None) -> float:
        """1-σ of D from the window's oldest entry (or entry ``tail``) to the newest [m]: the low-passed position
        noise at both ends and the velocity noise integrated in between."""
        tail = self.tail if tail is None else tail
        head = self.head
        return math.sqrt(self.variances[head] + self.variances[tail] +
                         max(self.integral_variances[head] - self.integral_variances[tail], 0.0))


def _healthy(tracks: list[_SensorTrack], t_s: float) -> list[_SensorTrack]:
    """The references of ``tracks`` fit to fuse at ``t_s``: OK or ISOLATED, with an accepted sample that is
    not stale."""
    return [t for t in tracks if t.state in _HEALTHY_STATES and t.last_accepted_t_s is not None and
            t_s - t.last_accepted_t_s <= t.stale_s]


class SensorStatus(TypedDict):
    """One reference's line of :meth:`SensorHub.sensor_status` (the status message's sensor health)."""

    name: str
    kind: str  # SensorKind value
    state: str  # SensorState value
    age_s: float | None  # since its last sample [s] (None: never heard)
    weight: float  # share in the fused value [-]
    sigma: float  # current 1-σ [m] or [rad]
    samples: int
    rejected: int
    detail: str


@dataclass
class HubOutput:
    """What the hub gives the estimator for one control step.

    Attributes
    ----------
    y_ned : list of float
        Fused measurement [north_m, east_m, psi_rad] (NED; heading wrapped).
    measured : tuple of bool
        Which of (north, east, heading) carry a new sample this step.
    position_available, heading_available : bool
        At least one healthy, non-stale reference of that kind.
    position_lost_s, heading_lost_s : float
        How long that kind has been unavailable [s] (0 when available).
    position_sigma_m : float
        1-σ of the fused position [m] (inverse-variance combination).
    yaw_rate_radps : float or None
        Latest rate of turn from a heading sensor [rad/s].
    heading_rate_source : str or None
        With every heading reference lost: the rate of turn the heading is dead-reckoned on (a sensor name,
        or ``<heading sensor> rate of turn``); None while a reference is in use or the model carries it.
    heading_dr_sigma_rad : float
        1-σ of that dead-reckoned heading [rad] (0 when not dead-reckoning on a rate of turn).
    position_velocity_source : str or None
        With every position reference lost and one of them rejected by the velocity check: the receiver whose own
        velocity the position is dead-reckoned on; None otherwise.
    position_dr_sigma_m : float
        1-σ of that dead-reckoned position [m] (0 when not dead-reckoning on a velocity).
    position_reset, heading_reset : bool
        Every reference of that kind has failed the prediction test for ``reject_persist_s``: the
        references agree with each other, so the *estimate* is wrong (e.g. after long dead
        reckoning). The hub accepted them again; the caller re-initialises the estimator there.
    position_noise_weight : float
        The share S'/(S' + ΔR) of the estimator's gain the fused position is given, ΔR the noise of the receivers
        in use beyond their configured one [-] (1: not de-weighted; module docstring, "Noisy position references").
    """

    y_ned: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    measured: tuple[bool, bool, bool] = (False, False, False)
    position_available: bool = False
    heading_available: bool = False
    position_lost_s: float = 0.0
    heading_lost_s: float = 0.0
    position_sigma_m: float = math.inf
    yaw_rate_radps: float | None = None
    heading_rate_source: str | None = None
    heading_dr_sigma_rad: float = 0.0
    position_velocity_source: str | None = None
    position_dr_sigma_m: float = 0.0
    position_reset: bool = False
    heading_reset: bool = False
    position_noise_weight: float = 1.0


class SensorHub:
    """Quality tests, voting and fusion of the configured references.

    Parameters
    ----------
    sensors : sequence of SensorConfig
    config : HubConfig
    alarms : AlarmRegistry
        Where detections are raised and cleared.
    datum : LocalFrame or None
        Local NED frame; ``None`` → the first valid fix becomes the datum.

    Notes
    -----
    The hub runs at the start of every control cycle, after the loop's idle time, when little of it is
    in the caches: its cost grows with the Python operations it executes. Hence the per-reference
    limits computed once (:class:`_SensorTrack`), the decay factor recomputed only when the period
    changes, the prediction-failure search skipped while no reference fails, and alarm texts built
    only when an alarm changes.
    """

    def __init__(self, sensors: Sequence[SensorConfig], config: HubConfig, alarms: AlarmRegistry,
                 datum: LocalFrame | None = None) -> None:
        self.config = config
        self.alarms = alarms
        self.datum = datum
        self._tracks: dict[str, _SensorTrack] = {s.name: _SensorTrack(s, config) for s in sensors
                                                 if s.kind is not SensorKind.RATE}
        self._all = list(self._tracks.values())
        self._position = [t for t in self._all if not t.heading]
        self._heading = [t for t in self._all if t.heading]
        for track in self._all:
            track.peers = [t for t in self._all if t is not track and t.heading is track.heading]
        # rate-of-turn sources, in the order they are preferred: rate sensors, then heading sensors' own
        self._rate_sensors = {s.name: _RateSource(s.name, s.sigma, 1.0 / s.nominal_rate_hz,
                                                  config.stale_periods / s.nominal_rate_hz)
                              for s in sensors if s.kind is SensorKind.RATE}
        for track in self._heading:
            track.rate = _RateSource(f"{track.name} rate of turn", config.rot_sigma_radps, track.nominal_period_s,
                                     track.stale_s, owner=track)
        self._rates = [*self._rate_sensors.values(), *(t.rate for t in self._heading if t.rate is not None)]
        # The rate check (module docstring): each heading reference against the first valid rate sensor
        self._checks = bool(self._rate_sensors) and bool(self._heading)
        if self._checks:
            for track in self._heading:
                track.check = _RateCheck(2 * math.ceil(config.rot_check_window_s * track.config.nominal_rate_hz) + 4)
        for track in self._position:  # the velocity check (module docstring): off until a velocity arrives
            track.velocity = _VelocityCheck(
                2 * math.ceil(config.velocity_check_window_s * track.config.nominal_rate_hz) + 4,
                track.config.velocity_sigma)
        self._velocity_seen = False  # some position reference has sent a velocity
        self._velocity_alarm = ""  # the text of position.velocity_disagreement while raised
        self._velocity_dr_variance: float | None = None  # σ²_dr of the position fed on a velocity (None: not)
        self._check_ref: _RateSource | None = None  # the rate sensor the headings were compared with last
        self._check_integral = 0.0  # ∫(r − b̂)dt of that rate sensor [rad]
        self._check_verdict: str | None = None  # heading.rate_disagreement raised: "gyro", "rate" or "unknown"
        # the heading dead-reckoned from the last fresh fused heading (None: no valid rate since), when, its
        # variance at the anchor and the rate noise's random walk since [rad²], the bias error's share [rad]
        self._dr_heading: float | None = None
        self._dr_t0_s = 0.0
        self._dr_var0 = 0.0
        self._dr_noise_var = 0.0
        self._dr_bias_sd = 0.0
        self._rot_dr_variance: float | None = None  # σ²_dr fed at the last update (None: not on a rate of turn)
        self._heading_raw = 0.0  # the fused heading without the bumpless offset [rad]
        self._heading_weight = 0.0  # Σ inverse variances of the headings fused [1/rad²]
        self._heading_chain_break = False  # the set of headings fused changed: no bias span across it
        self._out = HubOutput()
        # the references fused at the last step, in the configured order (empty: none of the kind in use)
        self._position_used: list[_SensorTrack] = []
        self._heading_used: list[_SensorTrack] = []
        self._position_offset = [0.0, 0.0]
        self._heading_offset = 0.0
        self._position_seen = False  # a reference of the kind has been fused since start
        self._heading_seen = False
        self._position_anchor_until_t_s = -math.inf  # return after a loss: offset measured until then
        self._heading_anchor_until_t_s = -math.inf
        self._position_anchor_samples = 0
        self._heading_anchor_samples = 0
        self._last_heading = 0.0
        self._position_lost_since: float | None = None
        self._heading_lost_since: float | None = None
        self._last_update_t_s: float | None = None
        self._yaw_rate: float | None = None
        self.unknown_sources = 0
        self._disagree = {"position": False, "heading": False}
        self._rejecting = False  # some reference has a prediction-test failure pending (see _all_rejecting)
        self._accept_requested: set[str] = set()  # references the operator accepted (accept_reference)
        self._base_variance: Sequence[float] | None = None  # this update's prediction variance before any growth
        self._lone_alarms: set[str] = set()  # <kind>.reference_rejected raised (see _lone_accepted)
        self._noise_alarm = False  # position.noisy_reference raised (see _noise_weights)
        self._noise_growth = 0.0  # the prediction's variance grown while the position is de-weighted [m²]
        self._freeze_limit_s = config.freeze_window_s - 1e-9
        # A rate is frozen no later than a heading sent with it: a gyro's own ROT that froze with its heading is
        # never integrated past the moment the heading is declared frozen (CyberShip II's Froude-scaled window,
        # 0.6 s, is shorter than rot_freeze_s)
        self._rot_freeze_s = min(config.rot_freeze_s, self._freeze_limit_s)
        self._decay_dt = -1.0  # the period the bumpless offsets' decay factor was computed for [s]
        self._decay = 1.0

    # ------------------------------------------------------------------ inputs
    def set_disconnected(self, name: str, disconnected: bool) -> None:
        """Mark a sensor's transport as disconnected (serial unplugged, heartbeat lost)."""
        track = self._tracks.get(name)
        if track is not None:
            track.disconnected = disconnected
        rate = self._rate_sensors.get(name)
        if rate is not None:
            rate.disconnected = disconnected

    def update(self, t_s: float, measurements: Iterable[Measurement], predicted_y_ned: Sequence[float] | None,
               predicted_variance: Sequence[float] | None, velocity_ned: Sequence[float] | None = None) -> HubOutput:
        """Ingest the measurements received since the last step and fuse them.

        Parameters
        ----------
        t_s : float
            Current time [s].
        measurements : iterable of Measurement
            New valid measurements, in receive order.
        predicted_y_ned : sequence of 3 floats or None
            The wave filter's predicted measurement [north_m, east_m, psi_rad] for this step (None
            before the estimator is initialised: the prediction test is skipped).
        predicted_variance : sequence of 3 floats or None
            Innovation variances of that prediction [m², m², rad²].
        velocity_ned : sequence of 2 floats or None
            Estimated LF velocity in NED [m/s], to move slower references' latest samples to ``t_s``.
        """
        last = self._last_update_t_s
        dt = 0.0 if last is None else max(t_s - last, 0.0)
        self._last_update_t_s = t_s
        if dt != self._decay_dt:  # the fade of the bumpless offsets over this period (the same every cycle)
            self._decay_dt = dt
            self._decay = math.exp(-dt / self.config.switch_blend_s) if dt > 0.0 else 1.0
        for each in self._all:
            each.fresh = False
        self._base_variance = predicted_variance
        if predicted_variance is not None and \
                (self._position_lost_since is not None or self._heading_lost_since is not None):
            predicted_variance = self._dead_reckoning_variance(t_s, predicted_variance)
        self._ingest(measurements, predicted_y_ned, predicted_variance)
        if self._checks:
            self._rate_check(t_s, dt)
        if self._velocity_seen:
            self._velocity_check(t_s)
        out = self._out
        if self._rejecting:  # (nothing to search for otherwise: the usual case)
            out.position_reset = self._all_rejecting(self._position, t_s)
            out.heading_reset = self._all_rejecting(self._heading, t_s)
            self._rejecting = any(t.rejecting_since_t_s is not None for t in self._all) or bool(self._accept_requested)
        else:
            out.position_reset = out.heading_reset = False
        if self._lone_alarms:  # a lone reference agrees again (or went away): the alarm clears
            for code, tracks_of_kind in (("position.reference_rejected", self._position),
                                         ("heading.reference_rejected", self._heading)):
                if code in self._lone_alarms and all(t.rejecting_since_t_s is None for t in tracks_of_kind):
                    self._lone_alarms.discard(code)
                    self.alarms.clear(t_s, code)
        if out.position_reset:  # no bumpless fade towards a wrong estimate
            self._position_offset = [0.0, 0.0]
            self._position_used = []
            self._position_anchor_until_t_s = -math.inf
        if out.heading_reset:
            self._heading_offset = 0.0
            self._heading_used = []
            self._heading_anchor_until_t_s = -math.inf
        self._refresh_states(t_s)
        # The healthy references of each kind, once for the median test and the fusion (the median test moves
        # references only between OK and ISOLATED, both healthy: the lists are the same after it).
        healthy_position = _healthy(self._position, t_s)
        healthy_heading = _healthy(self._heading, t_s)
        if len(healthy_position) > 1 or self._disagree["position"]:
            self._median_one(healthy_position, t_s, heading=False)
        if len(healthy_heading) > 1 or self._disagree["heading"]:
            self._median_one(healthy_heading, t_s, heading=True)
        # After a loss the references come back to an estimator that dead-reckoned: its prediction is the
        # anchor the step is faded from (not after a reset, which is there to trust the references).
        pos_new = self._fuse_position(t_s, velocity_ned, None if out.position_reset else predicted_y_ned,
                                      healthy_position)
        head_new = self._fuse_heading(t_s, None if out.heading_reset else predicted_y_ned, healthy_heading)
        out.measured = (pos_new, pos_new, head_new)
        if predicted_y_ned is not None and self._base_variance is not None and not out.position_reset:
            self._noise_weights(t_s, dt, predicted_y_ned, self._base_variance, pos_new)
        elif self._noise_alarm:
            self._noise_alarm = False
            self._noise_growth = 0.0
            self.alarms.clear(t_s, "position.noisy_reference")
        if self._velocity_seen:
            self._velocity_dead_reckoning(t_s, predicted_y_ned)
        out.yaw_rate_radps = self._yaw_rate
        if self._rates:
            self._rate_of_turn(t_s, dt, head_new, predicted_y_ned)
        self._availability(t_s)
        return out

    def _ingest(self, measurements: Iterable[Measurement], predicted_y_ned: Sequence[float] | None,
                predicted_variance: Sequence[float] | None) -> None:
        """Each measurement to its reference's tests (or its rate source), in receive order."""
        tracks = self._tracks
        for measurement in measurements:
            track = tracks.get(measurement.source)
            message = measurement.message
            if track is None:
                rate = self._rate_sensors.get(measurement.source)
                if rate is not None and isinstance(message, RateOfTurn):
                    self._ingest_rate(rate, measurement.t_s, message.rate_radps)
                else:
                    self.unknown_sources += 1
                continue
            if track.heading:
                if isinstance(message, Heading):
                    self._common_tests(track, measurement.t_s, (ssa(message.heading_rad), 0.0), predicted_y_ned,
                                       predicted_variance)
                elif isinstance(message, RateOfTurn):
                    self._yaw_rate = message.rate_radps
                    if track.rate is not None:
                        self._ingest_rate(track.rate, measurement.t_s, message.rate_radps)
            elif isinstance(message, PositionFix):
                self._ingest_position(track, measurement.t_s, message, predicted_y_ned, predicted_variance)
            elif isinstance(message, CourseOverGround):
                self._ingest_velocity(track, measurement.t_s, message)
            elif isinstance(message, PositionErrorStats):
                sigma = _gst_sigma(message.sigma_north_m, message.sigma_east_m)
                if sigma is not None:
                    track.gst_sigma = sigma
                    track.gst_t_s = measurement.t_s

    def _dead_reckoning_variance(self, t_s: float, variance: Sequence[float]) -> tuple[float, float, float]:
        """The prediction's variance grown while a kind is dead-reckoned: + (drift × time lost)² [m², rad²].

        The wave filter's steady-state gains carry the variance of a filter that is measured; dead reckoning
        on the model, its error grows (an unmodelled change of current or wind, a bias not quite learnt) at
        ``dead_reckoning_drift_mps`` / ``_radps`` (1σ). A reference that comes back consistent with the
        dead-reckoned prediction within that grown uncertainty is taken back (blended in from the prediction,
        see the module docstring) rather than rejected and, later, re-initialised on; a lone one that jumped
        further than the growth allows stays rejected (``single_reference_accept_s``).
        """
        cfg = self.config
        v0, v1, v2 = variance[0], variance[1], variance[2]
        if self._velocity_dr_variance is not None:  # on a receiver's velocity: its own, smaller growth
            v0 += self._velocity_dr_variance
            v1 += self._velocity_dr_variance
        elif self._position_lost_since is not None:
            grown = cfg.dead_reckoning_drift_mps * (t_s - self._position_lost_since)
            v0 += grown * grown
            v1 += grown * grown
        if self._rot_dr_variance is not None:  # on a rate of turn: its own, smaller growth (module docstring)
            v2 += self._rot_dr_variance
        elif self._heading_lost_since is not None:
            grown = cfg.dead_reckoning_drift_radps * (t_s - self._heading_lost_since)
            v2 += grown * grown
        return v0, v1, v2

    # ------------------------------------------------------------------ rate of turn
    def _ingest_rate(self, rate: _RateSource, t_s: float, value: float) -> None:
        """One rate-of-turn sample [rad/s]: out of the physical range (or not finite) it is rejected, else it is
        the source's value; an unchanged value keeps the source alive but not its freeze test."""
        rate.samples += 1
        if not abs(value) <= self.config.rot_max_radps:  # (NaN fails too)
            rate.rejected_samples += 1
            return
        if value != rate.value or rate.last_t_s is None:
            rate.changed_t_s = t_s
        rate.value = value
        rate.last_t_s = t_s

    def _rate_of_turn(self, t_s: float, dt: float, head_new: bool, predicted: Sequence[float] | None) -> None:
        """Validity and bias of every rate source, the heading integrated from the last fresh one, and — with
        every heading reference lost — that heading given to the estimator (module docstring)."""
        cfg = self.config
        freeze_s = self._rot_freeze_s
        heading_used = bool(self._heading_used)
        measured = heading_used and head_new
        if self._heading_chain_break or not heading_used:  # no bias span across a switch or a loss
            self._heading_chain_break = False
            for rate in self._rates:
                rate.chain_heading = None
        source: _RateSource | None = None
        for rate in self._rates:
            valid = rate.valid(t_s, freeze_s)
            if rate.owner is None:
                self._rate_state(rate, t_s, valid)
            if not valid:
                rate.chain_heading = None
                continue
            if source is None and rate.bias_time_s > 0.0 and not rate.blamed:  # (never compared with a heading: unused)
                source = rate
            if heading_used:
                self._learn_bias(rate, t_s, dt, measured)
        out = self._out
        if measured:
            self._anchor_dead_reckoning(t_s, predicted)
        elif source is None:
            self._dr_heading = None
        elif self._dr_heading is not None:
            self._dr_heading += (source.value - source.bias) * dt
            self._dr_noise_var += source.sigma_radps ** 2 * max(source.period_s, dt) * dt
            self._dr_bias_sd += math.sqrt(source.bias_variance(cfg.rot_bias_window_s)) * dt
        if heading_used or source is None or predicted is None:
            self._rot_dr_variance = None
            out.heading_rate_source = None
            out.heading_dr_sigma_rad = 0.0
            return
        self._feed_dead_reckoning(source, t_s, predicted)

    # ------------------------------------------------------------------ rate check
    def _check_reference(self, t_s: float) -> _RateSource | None:
        """The rate sensor the headings are compared with: the first valid one (in the configured order) whose bias
        has been learnt, blamed or not (a blamed one is compared on, to see it agree again)."""
        freeze_s = self._rot_freeze_s
        for rate in self._rate_sensors.values():
            if rate.bias_time_s > 0.0 and rate.valid(t_s, freeze_s):
                return rate
        return None

    def _rate_check(self, t_s: float, dt: float) -> None:
        """Each heading reference's change over the window against the rate sensor's ∫(r − b̂)dt; a disagreement
        beyond the limit rejects the gyro or blames the rate (:meth:`_rate_verdict`); agreement again for
        ``rot_check_return_s`` takes it back (module docstring, "Rate check")."""
        ref = self._check_reference(t_s)
        if ref is not self._check_ref:  # another rate, or none: the windows restart, nothing can be judged
            self._check_ref = ref
            for track in self._heading:
                if track.check is not None:
                    track.check.reset()
            if self._check_verdict is not None:
                self._release(t_s)  # (a gyro rejected meanwhile faces the prediction test alone)
        if ref is None:
            return
        self._check_integral += (ref.value - ref.bias) * dt
        cfg = self.config
        window = cfg.rot_check_window_s
        rate_var = ref.sigma_radps * ref.sigma_radps * ref.period_s
        bias_var = ref.bias_variance(cfg.rot_bias_window_s)
        building = False
        for track in self._heading:
            check = track.check
            if check is None:
                continue
            if track.state in (SensorState.STALE, SensorState.FROZEN, SensorState.DISCONNECTED) or \
                    track.disconnected or track.last_t_s is None or t_s - track.last_t_s > track.stale_s:
                if check.count:
                    check.reset()
                continue
            if check.samples != track.samples and track.frozen_since_t_s is None:  # a new sample (not a repeat)
                check.samples = track.samples
                check.add(t_s, track.value[0], self._check_integral, window)
                sigma = self._sigma(track)
                span = check.span_s
                check.limit = max(cfg.rot_check_min_rad, cfg.rot_check_sigma_factor * math.sqrt(
                    2.0 * sigma * sigma + rate_var * span + bias_var * span * span))
                if abs(check.disagreement) <= 0.5 * check.limit:
                    if check.agree_since_t_s is None:
                        check.agree_since_t_s = t_s
                else:
                    check.agree_since_t_s = None
                if abs(check.disagreement) > check.limit and self._check_verdict is None:
                    self._rate_verdict(track, ref, t_s)
            if check.count and check.agree_since_t_s is None:
                building = True
        if building or self._check_verdict is not None:  # no bias learnt from such a block (_close_block)
            ref.block_dirty = True
            if not building:
                self._maybe_release(t_s)

    def _rate_verdict(self, track: _SensorTrack, ref: _RateSource, t_s: float) -> None:
        """``track`` disagrees with ``ref``: which is wrong. Another heading reference that agrees with the rate
        says ``track``; others that disagree too say the rate. Alone, the share of the disagreement in the gyro's
        own heading change decides (module docstring): in DP the heading is held, so a gyro that drifts shows the
        disagreement in its heading change (share ≈ 1) and a rate that is off in its integral (share ≈ 0); in
        between, or in a turn larger than the disagreement, neither is rejected."""
        check = track.check
        assert check is not None
        others = [t.check for t in self._heading if t is not track and t.check is not None and t.check.count > 1
                  and not t.check.rejected]
        d_deg = math.degrees(check.disagreement)
        what = (f"{track.name} heading change {math.degrees(check.heading_change):.2f} deg, {ref.name} "
                f"{math.degrees(check.heading_change - check.disagreement):.2f} deg in {check.span_s:.1f} s "
                f"(limit {math.degrees(check.limit):.2f} deg)")
        share = check.heading_change / check.disagreement
        turn = max(abs(check.heading_change), abs(check.heading_change - check.disagreement))
        if any(c.agree_since_t_s is not None for c in others):
            verdict, why = "gyro", "another heading reference agrees with the rate"
        elif others:
            verdict, why = "rate", "the other heading references disagree with it too"
        elif turn > 3.0 * abs(check.disagreement):
            verdict, why = "unknown", "the vessel turned more than they disagree: cannot tell which is wrong"
        elif share >= 2.0 / 3.0:
            verdict, why = "gyro", f"{share:.0%} of it in the gyro's heading change"
        elif share <= 1.0 / 3.0:
            verdict, why = "rate", f"{share:.0%} of it in the gyro's heading change"
        else:
            verdict, why = "unknown", f"{share:.0%} of it in the gyro's heading change: cannot tell which is wrong"
        self._check_verdict = verdict
        if verdict == "gyro":
            check.rejected = True
            check.detail = track.detail = f"rate check: disagrees with rate of turn {ref.name} by {d_deg:.2f} deg"
            if self._heading_used == [track]:
                # the dead reckoning starts from where the rate says the heading is — the gyro's heading at the
                # window's start + ∫(r − b̂)dt since — not from the estimate, which followed the drift
                self._dr_heading = ssa(check.previous - check.disagreement)
                self._dr_t0_s = t_s
                self._dr_var0 = (check.limit / self.config.rot_check_sigma_factor) ** 2  # (σ_D, floored)
                self._dr_noise_var = self._dr_bias_sd = 0.0
            action = f"{track.name} rejected"
        elif verdict == "rate":
            ref.blamed = True
            action = f"{ref.name} not used"
        else:
            action = "neither rejected; the rate's bias held"
        self.alarms.raise_(t_s, "heading.rate_disagreement", Severity.ALARM,
                           f"{track.name} disagrees with rate of turn: {what}; {why}; {action}")

    def _maybe_release(self, t_s: float) -> None:
        """Every heading reference compared has agreed with the rate again for ``rot_check_return_s``: the
        rejected gyro or the blamed rate is taken back and the alarm clears. With none compared (every gyro lost)
        the verdict stands: a rate blamed a moment ago is not dead-reckoned on because nothing contradicts it now,
        and a rejected gyro that returns is taken back only when it agrees in rate again."""
        return_s = self.config.rot_check_return_s
        compared = False
        for track in self._heading:
            check = track.check
            if check is None or check.count <= 1:
                continue
            if check.agree_since_t_s is None or t_s - check.agree_since_t_s < return_s:
                return
            compared = True
        if compared:
            self._release(t_s)

    def _release(self, t_s: float) -> None:
        """The rate check's verdict ends: rejected gyros and a blamed rate are taken back."""
        for track in self._heading:
            if track.check is not None:
                track.check.rejected = False
                track.check.detail = ""
        for rate in self._rate_sensors.values():
            rate.blamed = False
        self._check_verdict = None
        self.alarms.clear(t_s, "heading.rate_disagreement")

    # ------------------------------------------------------------------ velocity check
    def _ingest_velocity(self, track: _SensorTrack, t_s: float, course: CourseOverGround) -> None:
        """A position reference's velocity (SOG/COG) → NED, into its check's integral. The vector sog·(cos, sin)(cog):
        at a speed near zero the course is noise, and so is its share in the vector. A speed without a course is a
        zero velocity when the speed is within 3σ of zero, else unusable (skipped: a gap if it lasts)."""
        check = track.velocity
        speed = course.speed_mps
        if check is None or speed is None or not 0.0 <= speed <= _MAX_SPEED_MPS:
            return
        if course.course_rad is None:
            if speed > 3.0 * check.sigma_mps:
                return
            v_north = v_east = 0.0
        else:
            v_north = speed * math.cos(course.course_rad)
            v_east = speed * math.sin(course.course_rad)
        self._velocity_seen = True
        check.velocity(t_s, v_north, v_east, track.stale_s)

    def _velocity_check(self, t_s: float) -> None:
        """Each position reference's change over the window against the integral of its own velocity; beyond the
        limit the reference is rejected; back at its level (against the velocity) for ``velocity_check_return_s``,
        it is taken back (module docstring, "Velocity check")."""
        cfg = self.config
        for track in self._position:
            check = track.velocity
            if check is None or check.velocity_t_s is None:
                continue
            last = track.last_t_s
            if t_s - check.velocity_t_s > track.stale_s or last is None or t_s - last > track.stale_s or \
                    track.disconnected or track.frozen_since_t_s is not None or \
                    track.state in (SensorState.STALE, SensorState.FROZEN, SensorState.DISCONNECTED):
                # no velocity (the check is off), or the position is missing or repeated: the window restarts
                if check.count:
                    check.reset()
                if check.rejected:
                    self._velocity_release(track, t_s)  # (left to the other tests)
                continue
            if check.samples == track.samples:
                continue
            check.samples = track.samples
            check.add(last, track.antenna[0], track.antenna[1], self._nominal_sigma(track),
                      filter_s=cfg.velocity_check_filter_s, window_s=cfg.velocity_check_window_s,
                      variance_alpha=track.variance_alpha)
            factor = cfg.velocity_check_sigma_factor
            if check.rejected:
                ref_north, ref_east, ref_variance, ref_integral_variance = check.reference
                f_north, f_east = check.filtered
                error = math.hypot(f_north - ref_north, f_east - ref_east)
                sigma = math.sqrt(check.filtered_variance + ref_variance +
                                  max(check.integral_variances[check.head] - ref_integral_variance, 0.0))
                limit = max(cfg.velocity_check_min_m, factor * sigma)
                if error <= 0.5 * limit:
                    if check.agree_since_t_s is None:
                        check.agree_since_t_s = t_s
                    elif t_s - check.agree_since_t_s >= cfg.velocity_check_return_s:
                        self._velocity_release(track, t_s)
                else:
                    check.agree_since_t_s = None
                continue
            check.limit = max(cfg.velocity_check_min_m, factor * check.sigma())
            d_north, d_east = check.disagreement
            distance = math.hypot(d_north, d_east)
            if distance > check.limit:
                self._velocity_verdict(track, check, distance, t_s)

    def _velocity_dead_reckoning(self, t_s: float, predicted: Sequence[float] | None) -> None:
        """No position reference in use and one rejected by the velocity check with its velocity fresh: the position
        is dead-reckoned on that velocity, from where it says the receiver is — its level before the disagreement
        + ∫v dt since, the lever arm taken off —, fed as ŷ + S/(S + σ²_dr)·(p_dr − ŷ) (the Kalman update with
        R + σ²_dr, as the heading on a rate of turn), σ²_dr the level's and the integrated velocity noise's."""
        out = self._out
        self._velocity_dr_variance = None
        out.position_velocity_source = None
        out.position_dr_sigma_m = 0.0
        if self._position_used or predicted is None:
            return
        for track in self._position:
            check = track.velocity
            if check is None or not check.rejected or check.velocity_t_s is None or \
                    t_s - check.velocity_t_s > track.stale_s:
                continue
            ref_north, ref_east, ref_variance, ref_integral_variance = check.reference
            dt = t_s - check.velocity_t_s
            north = ref_north + check.integral_north + check.v_north * dt
            east = ref_east + check.integral_east + check.v_east * dt
            arm_x, arm_y = track.config.lever_arm_m
            if arm_x or arm_y:
                heading = self._last_heading if self._heading_used else predicted[2]
                d_north, d_east = lever_arm_ned(arm_x, arm_y, heading)
                north -= d_north
                east -= d_east
            sigma_v = check.sigma_mps
            variance = ref_variance + max(check.integral_variance - ref_integral_variance, 0.0) + \
                sigma_v * sigma_v * dt * dt
            base = self._base_variance
            s_north, s_east = (base[0], base[1]) if base is not None else (variance, variance)
            y_ned = out.y_ned
            y_ned[0] = predicted[0] + _update_weight(s_north, variance) * (north - predicted[0])
            y_ned[1] = predicted[1] + _update_weight(s_east, variance) * (east - predicted[1])
            out.measured = (True, True, out.measured[2])
            out.position_velocity_source = track.name
            out.position_dr_sigma_m = math.sqrt(variance)
            self._velocity_dr_variance = variance
            return

    def _velocity_verdict(self, track: _SensorTrack, check: _VelocityCheck, distance: float, t_s: float) -> None:
        """``track``'s position moved otherwise than its own velocity says: the position is rejected (the velocity
        is the Doppler's, independent of what moves a position slowly: multipath, a correction), its level before
        the disagreement kept for its return."""
        tail = check.tail
        check.rejected = True
        check.agree_since_t_s = None
        check.reference = (check.north[tail], check.east[tail], check.variances[tail],
                           check.integral_variances[tail])
        d_north, d_east = check.disagreement
        check.detail = track.detail = (f"velocity check: position disagrees with its own velocity by {distance:.2f} m "
                                       f"in {check.span_s:.1f} s (limit {check.limit:.2f} m)")
        kind = "the only position reference" if len(self._position) == 1 else "position reference"
        self._velocity_alarm_text(t_s, f"{track.name} ({kind}): position moved {d_north:+.2f} m N, {d_east:+.2f} m E "
                                       f"more than its velocity (SOG/COG) integrates to in {check.span_s:.1f} s "
                                       f"(limit {check.limit:.2f} m); {track.name} rejected")

    def _velocity_release(self, track: _SensorTrack, t_s: float) -> None:
        """The velocity check's rejection of ``track`` ends; the window restarts (the disagreement is in it)."""
        check = track.velocity
        assert check is not None
        check.rejected = False
        check.detail = ""
        check.agree_since_t_s = None
        check.reset()
        self._velocity_alarm_text(t_s, "")

    def _velocity_alarm_text(self, t_s: float, text: str) -> None:
        """``position.velocity_disagreement`` raised with ``text`` (a new verdict), kept while a reference is
        rejected by the check, cleared when none is."""
        rejected = [t.name for t in self._position if t.velocity is not None and t.velocity.rejected]
        if not rejected:
            if self._velocity_alarm:
                self._velocity_alarm = ""
                self.alarms.clear(t_s, "position.velocity_disagreement")
            return
        if text:
            others = [name for name in rejected if not text.startswith(name)]
            if others:
                text += f" (also rejected: {', '.join(others)})"
            self._velocity_alarm = text
            self.alarms.raise_(t_s, "position.velocity_disagreement", Severity.ALARM, text)

    def _anchor_dead_reckoning(self, t_s: float, predicted: Sequence[float] | None) -> None:
        """A fresh fused heading: the dead reckoning starts again from it, combined with the estimator's prediction
        (prior variance P = S − R, the measurement's R = 1/Σw): one gyro sample's noise (0.05°) would otherwise
        stay in the dead-reckoned heading as an offset, where the filtered estimate is within a few 0.01°."""
        measured = self._out.y_ned[2]
        noise = 1.0 / self._heading_weight
        base = self._base_variance
        if predicted is None or base is None:
            self._dr_heading = measured
            self._dr_var0 = noise
        else:
            prior = max(base[2] - noise, 0.0)
            gain = prior / (prior + noise)
            self._dr_heading = predicted[2] + gain * ssa(measured - predicted[2])
            self._dr_var0 = gain * noise
        self._dr_t0_s = t_s
        self._dr_noise_var = self._dr_bias_sd = 0.0

    def _learn_bias(self, rate: _RateSource, t_s: float, dt: float, measured: bool) -> None:
        """Integrate ``rate`` over this period and, at a fresh fused heading, average (∫r dt − Δψ)/Δt into its
        bias (weight Δt / ``rot_bias_window_s``, a running mean over the first window)."""
        rate.chain_integral += rate.value * dt
        if not measured:
            return
        heading = self._heading_raw
        start = rate.chain_heading
        if start is not None:
            span = t_s - rate.chain_t_s
            if span > 0.0:
                error = rate.chain_integral - ssa(heading - start)
                if rate.owner is None and self._checks:  # a rate sensor: in checked blocks
                    rate.block_error += error
                    rate.block_time_s += span
                    if rate.block_time_s >= self.config.rot_check_window_s:
                        self._close_block(rate)
                else:
                    self._commit_bias(rate, error, span)
        rate.chain_heading = heading
        rate.chain_t_s = t_s
        rate.chain_integral = 0.0

    def _commit_bias(self, rate: _RateSource, error: float, span: float) -> None:
        """Average ``error`` = ∫r dt − Δψ [rad] over ``span`` [s] into the bias (weight span / window, a running
        mean over the first window)."""
        rate.bias_time_s += span
        alpha = min(1.0, span / min(self.config.rot_bias_window_s, rate.bias_time_s))
        rate.bias += alpha * (error / span - rate.bias)
        rate.bias_heading_var = 1.0 / self._heading_weight

    def _close_block(self, rate: _RateSource) -> None:
        """A rate sensor's bias block is complete: the one waiting is committed if this one passed the rate check
        too, this one waits for the next; a block in which a disagreement built up is discarded with the one
        waiting (the disagreement may have started in it). The first block is committed at once: there is no bias
        to check with before it."""
        if rate.block_dirty:
            rate.pending_time_s = 0.0
        elif rate.bias_time_s == 0.0:
            self._commit_bias(rate, rate.block_error, rate.block_time_s)
        else:
            if rate.pending_time_s > 0.0:
                self._commit_bias(rate, rate.pending_error, rate.pending_time_s)
            rate.pending_error = rate.block_error
            rate.pending_time_s = rate.block_time_s
        rate.block_error = rate.block_time_s = 0.0
        rate.block_dirty = False

    def _feed_dead_reckoning(self, source: _RateSource, t_s: float, predicted: Sequence[float]) -> None:
        """Every heading reference lost, ``source`` valid: the dead-reckoned heading is this period's heading
        measurement, weighted by its grown variance against the estimator's innovation variance."""
        out = self._out
        if self._dr_heading is None:  # no valid rate since the last fresh heading: start from the estimate
            self._dr_heading = predicted[2]
            self._dr_t0_s = t_s
            base = self._base_variance
            self._dr_var0 = base[2] if base is not None else 0.0
            self._dr_noise_var = self._dr_bias_sd = 0.0
        variance = self._dr_var0 + self._dr_noise_var + self._dr_bias_sd * self._dr_bias_sd
        base = self._base_variance
        innovation = base[2] if base is not None else variance
        out.y_ned[2] = ssa(predicted[2] + _update_weight(innovation, variance) * ssa(self._dr_heading - predicted[2]))
        out.measured = (out.measured[0], out.measured[1], True)
        out.heading_rate_source = source.name
        out.heading_dr_sigma_rad = math.sqrt(variance)
        self._rot_dr_variance = variance

    def _rate_state(self, rate: _RateSource, t_s: float, valid: bool) -> None:
        """A rate sensor's state for the status, with its ``sensor.<name>.<state>`` warning when it changes."""
        if valid:
            state = SensorState.REJECTED if rate.blamed else SensorState.OK
        elif rate.disconnected:
            state = SensorState.DISCONNECTED
        elif rate.last_t_s is None:
            state = SensorState.WAITING
        elif t_s - rate.last_t_s > rate.stale_s:
            state = SensorState.STALE
        else:
            state = SensorState.FROZEN
        previous = rate.state
        if state is previous:
            return
        rate.state = state
        for alarm_state in (previous, state):
            if alarm_state in _ALARM_STATES:
                self.alarms.set(t_s, f"sensor.{rate.name}.{alarm_state.value}", state is alarm_state,
                                Severity.WARNING, f"{rate.name}: rate of turn {alarm_state.value}")

    def _nominal_sigma(self, track: _SensorTrack) -> float:
        """1-σ the sensor claims: recent GST statistics, else the configured noise."""
        gst, gst_t_s = track.gst_sigma, track.gst_t_s  # (set together: both None or neither)
        if gst is not None and gst_t_s is not None and track.last_t_s is not None and \
                track.last_t_s - gst_t_s <= track.gst_valid_s:
            return gst
        return track.config.sigma

    def _sigma(self, track: _SensorTrack) -> float:
        """Current 1-σ of a reference: the larger of the claimed and the measured (variance test) noise."""
        nominal = self._nominal_sigma(track)
        variance = track.residual_variance
        if variance is not None:
            return math.sqrt(max(variance, nominal * nominal))
        return nominal

    def _ingest_position(self, track: _SensorTrack, t_s: float, fix: PositionFix,
                         predicted: Sequence[float] | None, variance: Sequence[float] | None) -> None:
        datum = self.datum
        if datum is None:
            datum = self.datum = LocalFrame(fix.lat_deg, fix.lon_deg, 0.0)
        north, east, _ = datum.to_ned(fix.lat_deg, fix.lon_deg, 0.0)
        track.antenna = (north, east)  # (the velocity check compares the antenna's motion with its velocity)
        arm_x, arm_y = track.config.lever_arm_m
        if arm_x or arm_y:
            heading = self._last_heading if self._heading_used else (predicted[2] if predicted else 0.0)
            d_north, d_east = lever_arm_ned(arm_x, arm_y, heading)
            north -= d_north
            east -= d_east
        self._common_tests(track, t_s, (north, east), predicted, variance, raw=track.antenna)

    def _common_tests(self, track: _SensorTrack, t_s: float, value: tuple[float, float],
                      predicted: Sequence[float] | None, variance: Sequence[float] | None, *,
                      raw: tuple[float, float] | None = None) -> None:
        """Freeze, prediction and variance tests of one sample: NED ``(north_m, east_m)`` or
        ``(psi_rad, 0)``; an accepted sample updates the reference's low-passed level. ``raw``: the sample as the
        sensor gave it (a GNSS antenna's position, before the lever arm is taken off with the current heading),
        which is what a frozen sensor repeats; None: ``value``."""
        cfg = self.config
        heading = track.heading
        v0, v1 = value
        track.samples += 1
        track.last_t_s = t_s
        track.value = value
        # Freeze: identical raw values while time advances (the antenna's: with a lever arm the corrected value
        # of a frozen receiver moves with the vessel's yaw)
        tolerance = cfg.freeze_tolerance_rad if heading else cfg.freeze_tolerance_m
        previous = track.raw_previous
        current = value if raw is None else raw
        track.raw_previous = current
        if previous is not None and abs(ssa(current[0] - previous[0]) if heading else current[0] - previous[0]) \
                <= tolerance and abs(current[1] - previous[1]) <= tolerance:
            if track.frozen_since_t_s is None:
                track.frozen_since_t_s = t_s - track.nominal_period_s
        else:
            track.frozen_since_t_s = None
        frozen_since = track.frozen_since_t_s
        if frozen_since is None and not heading:  # (every new position sample, rejected ones too)
            _recent_noise(track, t_s, value)
        if frozen_since is not None and t_s - frozen_since >= self._freeze_limit_s:
            track.rejected_samples += 1
            track.detail = f"identical values for {t_s - frozen_since:.1f} s"
            return
        last_accepted = track.last_accepted_t_s
        if track.rejecting_since_t_s is not None and variance is not self._base_variance and previous is not None \
                and _distance(current, previous, heading) <= (cfg.heading_jump_min_rad if heading else cfg.jump_min_m):
            # A reference being rejected that has not stepped since: its jump persists. Judged against the
            # filter's own variance, not the one grown by dead reckoning — that growth is the estimate's
            # uncertainty about a reference that was *absent*, and would let a persisting jump in after a while.
            # (One that steps back — the jump over — is judged against the grown variance, as a return.)
            variance = self._base_variance
        # Prediction test against the wave filter (total motion, LF + WF).
        if predicted is not None and variance is not None:
            # (judged as it would reach the estimator: with the offset the hub is fading out added — after a
            # return from dead reckoning that offset holds the estimate at its prediction, and the raw samples
            # differ from the prediction by it until it has faded)
            sigma = self._sigma(track)
            if heading:
                r0 = ssa(v0 + self._heading_offset - predicted[2])
                r1 = 0.0
                limit = max(cfg.heading_jump_min_rad, cfg.jump_sigma_factor * math.sqrt(variance[2] + sigma * sigma))
                distance = abs(r0)
            else:
                offset = self._position_offset
                r0 = v0 + offset[0] - predicted[0]
                r1 = v1 + offset[1] - predicted[1]
                if track.recent_variance is not None:  # (a receiver whose noise just grew: its recent noise)
                    sigma = math.sqrt(max(track.recent_variance, sigma * sigma))
                limit = max(cfg.jump_min_m,
                            cfg.jump_sigma_factor * math.sqrt(0.5 * (variance[0] + variance[1]) + sigma * sigma))
                distance = math.hypot(r0, r1)
            if distance > limit:
                track.rejected_samples += 1
                if track.rejecting_since_t_s is None:
                    track.rejecting_since_t_s = t_s
                    self._rejecting = True
                track.detail = f"prediction test: {distance:.3g} > {limit:.3g}"
                return
            track.rejecting_since_t_s = None
            # Variance test on the second difference of the residuals about the prediction: the
            # prediction removes the vessel's motion, the second difference what is left of it that is
            # smooth (bias, drift, slow prediction errors), leaving the sensor's white noise
            # (var(r_k − 2r_{k−1} + r_{k−2}) = 6σ²).
            p1 = track.previous_residual
            p2 = track.previous_residual2
            track.previous_residual2 = p1
            track.previous_residual = (r0, r1)
            if p1 is not None and p2 is not None and last_accepted is not None and \
                    t_s - last_accepted <= track.continuity_s:
                d0 = r0 - 2.0 * p1[0] + p2[0]
                d1 = r1 - 2.0 * p1[1] + p2[1]
                own = d0 * d0 / 6.0 if heading else (d0 * d0 + d1 * d1) / 12.0
                # Exponential average over variance_time_constant_s, started as a running mean (weight
                # 1/n for the n-th sample until that is below the EWMA's): the first squared residual alone
                # would be a one-sample χ² estimate that keeps the alarm ringing for a time constant.
                samples = track.variance_samples = track.variance_samples + 1
                alpha = max(track.variance_alpha, 1.0 / samples)
                measured = track.residual_variance
                track.residual_variance = own if measured is None else (1.0 - alpha) * measured + alpha * own
        else:
            track.previous_residual = track.previous_residual2 = None
        if frozen_since is not None:
            # A value repeated exactly is no new measurement: the reference stays alive (a quantised heading
            # repeats now and then) but the estimator is not corrected with it, so that a reference that froze
            # does not hold the estimate still for the freeze window (its bias states learn the vessel's true
            # motion as a force otherwise, and the dead reckoning that follows drifts). Frozen after the window.
            track.last_accepted_t_s = t_s
            track.detail = ""
            return
        # Low-pass the accepted values for the median test (so noise does not flip it on and off) and for
        # the level of each reference in a bumpless switch. After a gap it restarts as a running mean
        # (weight 1/n until that is below the low-pass weight): one raw sample is no level.
        filtered = track.filtered
        gap = 0.0 if last_accepted is None else max(t_s - last_accepted, 0.0)
        if filtered is None or last_accepted is None or gap > track.stale_s:
            track.filtered = value
            track.filter_samples = 1
        else:
            samples = track.filter_samples = track.filter_samples + 1
            alpha = max(1.0 - math.exp(-gap / cfg.median_filter_s), 1.0 / samples)
            f0, f1 = filtered
            track.filtered = (f0 + alpha * (ssa(v0 - f0) if heading else v0 - f0), f1 + alpha * (v1 - f1))
        track.last_accepted_t_s = t_s
        track.accepted_value = value
        track.fresh = True
        track.detail = ""

    def _all_rejecting(self, tracks: list[_SensorTrack], t_s: float) -> bool:
        """All live references of a kind rejected by the prediction test for long → trust them.

        Only when *no* reference of the kind had a sample accepted for ``reject_persist_s``: one that
        agrees with the estimate proves the estimate is not what is wrong (a single gyro 10° off must
        not re-initialise the estimator on itself). Frozen references do not count as live (their
        samples are rejected by the freeze test, not the prediction test); a single repeated value —
        NMEA 2000 headings come in 1e-4 rad steps — is not frozen.
        """
        if all(t.rejecting_since_t_s is None for t in tracks):
            return False  # nothing of this kind is being rejected (what the test below concludes then)
        persist = self.config.reject_persist_s
        # (nor one the rate check rejected: its heading drifts, however far it is from the estimate)
        live = [t for t in tracks if t.last_t_s is not None and not t.disconnected and
                t_s - t.last_t_s <= t.stale_s and t.state is not SensorState.FROZEN and
                (t.check is None or not t.check.rejected) and (t.velocity is None or not t.velocity.rejected)]
        accepted = [t for t in live if t.name in self._accept_requested and t.rejecting_since_t_s is not None]
        why = "all references disagreed with the estimate; estimator re-initialised on them"
        if accepted:  # the operator's word (accept_reference): at once
            live = accepted
            why = f"operator accepted {', '.join(t.name for t in accepted)}; estimator re-initialised on it"
        else:
            if not live or any(t.rejecting_since_t_s is None or t_s - t.rejecting_since_t_s < persist for t in live):
                return False
            if any(t.last_accepted_t_s is not None and t_s - t.last_accepted_t_s < persist for t in tracks):
                return False
            if len(live) == 1 and not self._lone_accepted(live[0], t_s):
                return False
        for track in live:
            self._accept_requested.discard(track.name)
            track.rejecting_since_t_s = None
            track.residual_variance = None
            track.variance_samples = 0
            track.recent.clear()
            track.recent_variance = None
            track.recent_previous = None
            track.previous_residual = track.previous_residual2 = None
            track.accepted_value = track.value
            track.last_accepted_t_s = track.last_t_s
            track.fresh = True
        self.alarms.raise_(t_s, "estimator.reset", Severity.ALARM, why)
        code = "heading.reference_rejected" if live[0].heading else "position.reference_rejected"
        if code in self._lone_alarms:
            self._lone_alarms.discard(code)
            self.alarms.clear(t_s, code)
        return True

    def _lone_accepted(self, track: _SensorTrack, t_s: float) -> bool:
        """A lone reference of its kind failing the prediction test: nothing confirms it, so it is not taken for
        the truth before ``single_reference_accept_s`` (a jump or a drift of that receiver would otherwise be
        followed after ``reject_persist_s``). Meanwhile the loop dead-reckons and ``<kind>.reference_rejected``
        says so; after that time it is accepted (the estimate, not the reference, is taken to be wrong)."""
        since = track.rejecting_since_t_s
        assert since is not None
        accept_s = self.config.single_reference_accept_s
        if t_s - since >= accept_s:
            return True
        kind = "heading" if track.heading else "position"
        code = f"{kind}.reference_rejected"
        if code not in self._lone_alarms:
            self._lone_alarms.add(code)
            self.alarms.raise_(t_s, code, Severity.ALARM,
                               f"{track.name}, the only {kind} reference, disagrees with the estimate "
                               f"({track.detail}): "
                               f"rejected, dead reckoning; taken as the truth after {accept_s:g} s or when the "
                               "operator accepts it")
        return False

    @property
    def reference_names(self) -> list[str]:
        """The configured references (sensors), in configuration order."""
        return list(self._tracks)

    def accept_reference(self, name: str) -> bool:
        """The operator accepts reference ``name`` as the truth: when it is failing the prediction test, the
        estimator is re-initialised on it at the next update (:attr:`HubOutput.position_reset` /
        ``heading_reset``). Returns whether such a reference exists."""
        track = self._tracks.get(name)
        if track is None:
            return False
        if track.velocity is not None and track.velocity.rejected:  # the operator's word over the velocity check
            self._velocity_release(track, self._last_update_t_s or 0.0)
        self._accept_requested.add(name)
        self._rejecting = True  # (the search for a reset runs at the next update)
        return True

    # ------------------------------------------------------------------ states and voting
    def _refresh_states(self, t_s: float) -> None:
        reject_persist = self.config.reject_persist_s
        freeze_limit = self._freeze_limit_s
        for track in self._all:
            last = track.last_t_s
            if track.disconnected:
                state = SensorState.DISCONNECTED
            elif last is None:
                state = SensorState.WAITING
            elif t_s - last > track.stale_s:
                state = SensorState.STALE
            elif track.frozen_since_t_s is not None and t_s - track.frozen_since_t_s >= freeze_limit:
                state = SensorState.FROZEN
            elif (track.rejecting_since_t_s is not None and t_s - track.rejecting_since_t_s >= reject_persist) or \
                    (track.check is not None and track.check.rejected) or \
                    (track.velocity is not None and track.velocity.rejected):
                # (or its heading rate disagrees with the ROT, or its position with its own velocity)
                state = SensorState.REJECTED
            elif track.state is SensorState.ISOLATED and track.median_fail_since_t_s is not None:
                state = SensorState.ISOLATED
            else:
                state = SensorState.OK
            previous = track.state
            if state is not previous:  # alarms change only with the state (no per-cycle text building)
                track.state = state
                if state is SensorState.OK:
                    self._readmit(track, t_s)
                name = track.name
                for alarm_state in (previous, state):
                    if alarm_state in _ALARM_STATES:
                        self.alarms.set(t_s, f"sensor.{name}.{alarm_state.value}", state is alarm_state,
                                        Severity.WARNING, f"{name}: {alarm_state.value} {track.detail}".strip())
            # (a reference alone of its kind has nothing to compare with: never noisy, no per-step search)
            noisy = self._noisy(track, state) if track.peers else False
            if noisy is not track.noisy:
                track.noisy = noisy
                name = track.name
                self.alarms.set(t_s, f"sensor.{name}.noisy", noisy, Severity.WARNING,
                                f"{name}: noise above {self.config.variance_alarm_factor:g}× nominal and the other "
                                "references (variance test)")

    def _noisy(self, track: _SensorTrack, state: SensorState) -> bool:
        """Variance alarm: the measured noise exceeds ``variance_alarm_factor`` × both its nominal and the
        quietest other reference of the same kind (cleared below 2/3 of that factor).

        The measured noise also holds what the wave filter could not predict (wave motion in a high
        sea), common to every reference; comparing with the quietest other reference removes it. A
        single reference has nothing to compare with, so it gets no alarm — its weight still follows
        its measured variance.
        """
        if state is not SensorState.OK:
            return False
        variance = self._settled_variance(track)
        if variance is None:
            return False
        others = [v for t in track.peers if t.state is SensorState.OK and (v := self._settled_variance(t)) is not None]
        if not others:
            return False
        floor = max(track.config.sigma ** 2, min(others))
        # hysteresis: raised above factor², cleared below (2/3 · factor)² (4× for the default 3), so a
        # variance estimate hovering at the limit does not toggle the alarm
        factor = self.config.variance_alarm_factor * (2.0 / 3.0 if track.noisy else 1.0)
        return variance > factor * factor * floor

    def _readmit(self, track: _SensorTrack, t_s: float) -> None:
        """A reference back to OK is fused only after ``readmit_s`` of good samples, when others of its
        kind are in use: its level (low-passed value) must settle before the bumpless switch measures
        the step to fade. With none in use it is needed at once (the estimator is dead-reckoning)."""
        in_use = self._heading_used if track.heading else self._position_used
        others = any(t is not track for t in in_use)
        track.usable_from_t_s = t_s + self.config.readmit_s if others else -math.inf

    def _settled_variance(self, track: _SensorTrack) -> float | None:
        """The measured variance once it averages at least one ``variance_time_constant_s`` of samples, else
        None."""
        variance = track.residual_variance
        if variance is not None and \
                track.variance_samples * track.nominal_period_s >= self.config.variance_time_constant_s:
            return variance
        return None

    def _median_one(self, tracks: list[_SensorTrack], t_s: float, *, heading: bool) -> None:
        """Median test (≥ 3 references) or disagreement alarm (2); with fewer it only clears that alarm
        (the caller skips it when there is nothing to clear)."""
        cfg = self.config
        kind = "heading" if heading else "position"
        limit = cfg.median_heading_limit_rad if heading else cfg.median_limit_m
        if len(tracks) >= 3 and self._disagree[kind]:
            self._disagree[kind] = False
            self.alarms.clear(t_s, f"{kind}.disagree")
        if len(tracks) >= 3:
            values = [t.filtered or t.accepted_value for t in tracks]
            if heading:
                ref = values[0][0]
                median = (ref + _median([ssa(v[0] - ref) for v in values]), 0.0)
            else:
                median = (_median([v[0] for v in values]), _median([v[1] for v in values]))
            for track, value in zip(tracks, values, strict=True):
                distance = _distance(value, median, heading)
                if distance > max(limit, 3.0 * self._nominal_sigma(track)):
                    if track.median_fail_since_t_s is None:
                        track.median_fail_since_t_s = t_s
                    if t_s - track.median_fail_since_t_s >= cfg.median_persist_s:
                        track.state = SensorState.ISOLATED
                        track.detail = f"median test: {distance:.3g} from the median"
                else:
                    track.median_fail_since_t_s = None
                    if track.state is SensorState.ISOLATED:
                        track.state = SensorState.OK
                        self._readmit(track, t_s)
                isolated = track.state is SensorState.ISOLATED
                if isolated is not track.isolated_alarm:
                    track.isolated_alarm = isolated
                    self.alarms.set(t_s, f"sensor.{track.name}.isolated", isolated, Severity.WARNING,
                                    f"{track.name}: isolated by the median test")
        elif len(tracks) == 2:
            a, b = tracks
            distance = _distance(a.filtered or a.accepted_value, b.filtered or b.accepted_value, heading)
            disagree = distance > max(limit, 3.0 * math.hypot(self._nominal_sigma(a), self._nominal_sigma(b)))
            for track in tracks:
                track.median_fail_since_t_s = None
                if track.state is SensorState.ISOLATED:
                    track.state = SensorState.OK
                    self._readmit(track, t_s)
            if disagree is not self._disagree[kind]:
                self._disagree[kind] = disagree
                self.alarms.set(t_s, f"{kind}.disagree", disagree, Severity.ALARM,
                                f"two {kind} references disagree by {distance:.3g}; cannot isolate")
        elif self._disagree[kind]:
            self._disagree[kind] = False
            self.alarms.clear(t_s, f"{kind}.disagree")

    # ------------------------------------------------------------------ fusion
    def _weights(self, tracks: list[_SensorTrack]) -> list[float]:
        """Inverse-variance weights 1/max(σ², 1e-12) of ``tracks`` [1/m², 1/rad²]."""
        return [1.0 / max(s * s, 1e-12) for s in map(self._sigma, tracks)]

    def _level(self, tracks: list[_SensorTrack], heading: bool) -> tuple[float, float] | None:
        """Inverse-variance weighted mean of the low-passed values of ``tracks`` (in the configured order):
        the level the fused output has with that set, without the sample-to-sample noise.
        ``(north_m, east_m)``, or ``(psi_rad, 0)`` for headings (means of angle differences to the first)."""
        # in the configured order: a sum in another order differs in the last bit, and replay would no longer
        # be exact
        filtered = [t for t in tracks if t.filtered is not None]
        if not filtered:
            return None
        values = [t.filtered for t in tracks if t.filtered is not None]  # (parallel to ``filtered``)
        weights = self._weights(filtered)
        total = sum(weights)
        if heading:
            ref = values[0][0]
            return ref + sum(w * ssa(v[0] - ref) for v, w in zip(values, weights, strict=True)) / total, 0.0
        return (sum(w * v[0] for v, w in zip(values, weights, strict=True)) / total,
                sum(w * v[1] for v, w in zip(values, weights, strict=True)) / total)

    def _fuse_position(self, t_s: float, velocity_ned: Sequence[float] | None, anchor: Sequence[float] | None,
                       healthy: list[_SensorTrack]) -> bool:
        for track in self._position:
            track.weight = 0.0
        usable = [t for t in healthy if t.state is SensorState.OK and t_s >= t.usable_from_t_s]
        if not usable:
            self._position_used = []
            return False
        weights = self._weights(usable)
        total = sum(weights)
        vn, ve = (velocity_ned[0], velocity_ned[1]) if velocity_ned is not None else (0.0, 0.0)
        north = east = 0.0
        fresh = False
        for track, weight in zip(usable, weights, strict=True):
            age = t_s - (track.last_accepted_t_s or t_s)
            value = track.accepted_value
            north += weight * (value[0] + vn * age)
            east += weight * (value[1] + ve * age)
            track.weight = weight / total
            if track.fresh:
                fresh = True
        north /= total
        east /= total
        in_use = self._position_used
        offset = self._position_offset
        if in_use and usable != in_use:  # (lists of the same tracks in the same order: the same set)
            # Bumpless switch: the step between the levels (low-passed values) of the old and the new set
            # — the bias between references — is added and faded out. Not the step between consecutive
            # outputs: that is mostly one sample's noise, which would then stay as a bias for a blend time.
            old_level = self._level(in_use, heading=False)
            new_level = self._level(usable, heading=False)
            if old_level is not None and new_level is not None:
                offset[0] += old_level[0] - new_level[0]
                offset[1] += old_level[1] - new_level[1]
        elif not in_use and anchor is not None and self._position_lost_since is not None and self._position_seen:
            # Back after a loss: the output starts at the dead-reckoned prediction and the dead-reckoning
            # error is faded out, rather than corrected by the wave filter within its gain's second or
            # two. The error is measured as the running mean of (prediction − fused) over readmit_s —
            # one sample would leave its noise as a bias for a blend time.
            self._position_anchor_samples = 0
            self._position_anchor_until_t_s = t_s + self.config.readmit_s
        self._position_used = usable
        self._position_seen = True
        if t_s < self._position_anchor_until_t_s and anchor is not None:
            if fresh:
                self._position_anchor_samples += 1
                weight = 1.0 / self._position_anchor_samples
                offset[0] += weight * (anchor[0] - north - offset[0])
                offset[1] += weight * (anchor[1] - east - offset[1])
        else:
            decay = self._decay
            offset[0] *= decay
            offset[1] *= decay
        y_ned = self._out.y_ned
        y_ned[0] = north + offset[0]
        y_ned[1] = east + offset[1]
        self._out.position_sigma_m = 1.0 / math.sqrt(total)
        return fresh

    def _fuse_heading(self, t_s: float, anchor: Sequence[float] | None, healthy: list[_SensorTrack]) -> bool:
        for track in self._heading:
            track.weight = 0.0
        usable = [t for t in healthy if t.state is SensorState.OK and t_s >= t.usable_from_t_s]
        if not usable:
            self._heading_used = []
            return False
        weights = self._weights(usable)
        total = sum(weights)
        ref = usable[0].accepted_value[0]
        terms = []  # the weighted differences to the first, summed with sum() as before (the same float)
        fresh = False
        for track, weight in zip(usable, weights, strict=True):
            terms.append(weight * ssa(track.accepted_value[0] - ref))
            track.weight = weight / total
            if track.fresh:
                fresh = True
        heading = ref + sum(terms) / total
        self._heading_raw = heading
        self._heading_weight = total
        in_use = self._heading_used
        if in_use and usable != in_use:
            old_level = self._level(in_use, heading=True)
            new_level = self._level(usable, heading=True)
            if old_level is not None and new_level is not None:
                self._heading_offset += ssa(old_level[0] - new_level[0])
            self._heading_chain_break = True
        elif not in_use and anchor is not None and self._heading_lost_since is not None and self._heading_seen:
            self._heading_anchor_samples = 0
            self._heading_anchor_until_t_s = t_s + self.config.readmit_s
        self._heading_used = usable
        self._heading_seen = True
        if t_s < self._heading_anchor_until_t_s and anchor is not None:
            if fresh:
                self._heading_anchor_samples += 1
                self._heading_offset += ssa(anchor[2] - heading - self._heading_offset) / self._heading_anchor_samples
        else:
            self._heading_offset *= self._decay
        fused = ssa(heading + self._heading_offset)
        self._last_heading = fused
        self._out.y_ned[2] = fused
        return fresh

    def _noise_weights(self, t_s: float, dt: float, predicted: Sequence[float], innovation: Sequence[float],
                       pos_new: bool) -> None:
        """The fused position of this step de-weighted by the noise of the receivers in use beyond their configured
        one (module docstring, "Noisy position references"): ŷ + S'/(S' + ΔR)·(y − ŷ), S' the innovation variance
        with the prediction's growth while de-weighted; ``position.noisy_reference`` while the gain is below half
        its own, and a bumpless return when it is whole again.

        Parameters
        ----------
        t_s : float
            Current time [s].
        dt : float
            Time since the last update [s].
        predicted : sequence of 3 floats
            The estimator's predicted measurement [north_m, east_m, psi_rad].
        innovation : sequence of 3 floats
            Its innovation variances S, not grown by dead reckoning [m², m², rad²].
        pos_new : bool
            Whether this step carries a new position measurement.
        """
        out = self._out
        excess, worst = self._noise_excess(self._position_used)
        growth = self._noise_growth
        if excess > 0.0:  # the prediction's error grows as in dead reckoning, while the receiver is heard less
            sd = math.sqrt(growth) + self.config.dead_reckoning_drift_mps * dt
            growth = sd * sd
        else:
            growth = 0.0
        weight_north = _update_weight(innovation[0] + growth, excess)
        weight_east = _update_weight(innovation[1] + growth, excess)
        if pos_new and excess > 0.0:
            y_ned = out.y_ned
            y_ned[0] = predicted[0] + weight_north * (y_ned[0] - predicted[0])
            y_ned[1] = predicted[1] + weight_east * (y_ned[1] - predicted[1])
            growth *= 1.0 - 0.5 * (weight_north + weight_east)  # (what the de-weighted update takes off it)
        self._noise_growth = growth
        weight = out.position_noise_weight = min(weight_north, weight_east)
        code = "position.noisy_reference"
        if self._noise_alarm:
            if excess <= 0.0:  # taken back: from the prediction, the error of the de-weighted time faded out
                self._noise_alarm = False
                self.alarms.clear(t_s, code)
                if self._position_used and self._position_lost_since is None:
                    self._position_anchor_samples = 0
                    self._position_anchor_until_t_s = t_s + self.config.readmit_s
            return
        if weight >= 0.5 or worst is None:
            return
        self._noise_alarm = True
        self.alarms.raise_(t_s, code, Severity.WARNING,
                           f"{worst.name}: noise {math.sqrt(self._noise_variance(worst)):.3g} m (GST or the last "
                           f"{self.config.noise_window_s:g} s) against {worst.config.sigma:.3g} m configured; fed to "
                           f"the estimator at {weight:.0%} of its gain")

    def _noise_variance(self, track: _SensorTrack) -> float:
        """A position reference's noise variance now: the larger of its recent measured one and its GST's [m²]
        (0 when neither is known)."""
        recent = track.recent_variance or 0.0
        gst, gst_t_s = track.gst_sigma, track.gst_t_s
        if gst is not None and gst_t_s is not None and track.last_t_s is not None and \
                track.last_t_s - gst_t_s <= track.gst_valid_s:
            return max(recent, gst * gst)
        return recent

    def _noise_excess(self, tracks: list[_SensorTrack]) -> tuple[float, _SensorTrack | None]:
        """ΔR = Σ w_i²·max(σ²_i − (κ·σ_cfg,i)², 0) over the position references in use (w_i their share in the fused
        value, σ²_i their noise now (:meth:`_noise_variance`), σ_cfg,i the configured 1-σ, κ =
        ``noise_deweight_factor``) [m²], and the reference with the largest term (None when ΔR is 0)."""
        factor = self.config.noise_deweight_factor
        excess = 0.0
        worst: _SensorTrack | None = None
        largest = 0.0
        for track in tracks:
            floor = factor * track.config.sigma
            term = self._noise_variance(track) - floor * floor
            if term > 0.0:
                term *= track.weight * track.weight
                excess += term
                if term > largest:
                    largest = term
                    worst = track
        return excess, worst

    def _availability(self, t_s: float) -> None:
        """At least one reference of each kind in use, and for how long none has been [s]."""
        out = self._out
        out.position_available = bool(self._position_used)
        out.heading_available = bool(self._heading_used)
        if out.position_available:
            self._position_lost_since = None
        elif self._position_lost_since is None:
            self._position_lost_since = t_s
        if out.heading_available:
            self._heading_lost_since = None
        elif self._heading_lost_since is None:
            self._heading_lost_since = t_s
        out.position_lost_s = 0.0 if self._position_lost_since is None else t_s - self._position_lost_since
        out.heading_lost_s = 0.0 if self._heading_lost_since is None else t_s - self._heading_lost_since

    # ------------------------------------------------------------------ reporting
    def sensor_status(self, t_s: float) -> list[SensorStatus]:
        """Per-sensor health for ``dp/<vessel>/status``."""
        rows: list[SensorStatus] = []
        for track in self._all:
            age = None if track.last_t_s is None else round(t_s - track.last_t_s, 3)
            check = track.check
            velocity = track.velocity
            detail = check.detail if check is not None and check.rejected else \
                velocity.detail if velocity is not None and velocity.rejected else track.detail
            rows.append({"name": track.name, "kind": track.config.kind.value, "state": track.state.value,
                         "age_s": age, "weight": round(track.weight, 4), "sigma": self._sigma(track),
                         "samples": track.samples, "rejected": track.rejected_samples, "detail": detail})
        source = self._out.heading_rate_source
        for rate in self._rate_sensors.values():
            age = None if rate.last_t_s is None else round(t_s - rate.last_t_s, 3)
            detail = f"bias {math.degrees(rate.bias):.3f} deg/s" if rate.bias_time_s > 0.0 else ""
            rows.append({"name": rate.name, "kind": SensorKind.RATE.value, "state": rate.state.value, "age_s": age,
                         "weight": 1.0 if source == rate.name else 0.0, "sigma": rate.sigma_radps,
                         "samples": rate.samples, "rejected": rate.rejected_samples, "detail": detail})
        return rows

    def rate_bias(self, name: str) -> float:
        """The bias estimated for rate source ``name`` (a rate sensor, or ``<heading sensor> rate of turn``)
        [rad/s]."""
        return next(rate.bias for rate in self._rates if rate.name == name)

    def state_of(self, name: str) -> SensorState:
        return self._tracks[name].state

    def weight_of(self, name: str) -> float:
        return self._tracks[name].weight


def _recent_noise(track: _SensorTrack, t_s: float, value: tuple[float, float]) -> None:
    """A new position sample ``value`` (NED [m]) at ``t_s`` [s] into the recent noise of its reference (module
    docstring, "Noisy position references"): the second divided difference of three consecutive samples,
    d = Δ₁/h₁ − Δ₂/h₂, is σ²·c per axis with c = 1/h₁² + (1/h₁ + 1/h₂)² + 1/h₂² for white noise σ, and 0 for any
    constant velocity, offset or drift (a jump makes two large ones, which the median ignores); (d_n² + d_e²)/(2c) is
    σ²·χ²₂/2, whose median over the window divided by ln 2 is the recent noise variance [m²], once the window is
    half full."""
    previous = track.recent_previous
    if previous is None or not 0.0 < t_s - previous[0] <= track.continuity_s:  # (a gap: the differences restart)
        track.recent_previous = (t_s, value, None)
        return
    t1, v1, before = previous
    track.recent_previous = (t_s, value, (t1, v1))
    if before is None:
        return
    t2, v2 = before
    h1 = t_s - t1
    h2 = t1 - t2
    if h2 <= 0.0:
        return
    d_north = (value[0] - v1[0]) / h1 - (v1[0] - v2[0]) / h2
    d_east = (value[1] - v1[1]) / h1 - (v1[1] - v2[1]) / h2
    c = 1.0 / (h1 * h1) + (1.0 / h1 + 1.0 / h2) ** 2 + 1.0 / (h2 * h2)
    recent = track.recent
    recent.append((d_north * d_north + d_east * d_east) / (2.0 * c))
    if len(recent) >= track.recent_min:
        track.recent_variance = _median(list(recent)) / _MEDIAN_CHI2_2


def _update_weight(innovation_variance: float, extra_variance: float) -> float:
    """S/(S + σ²): the share of a dead-reckoned measurement of variance σ² [m², rad²] the steady-state estimator
    takes, S its innovation variance — the Kalman update with R + σ² (module docstring); 1 when both are 0."""
    total = innovation_variance + extra_variance
    return innovation_variance / total if total > 0.0 else 1.0


def _gst_sigma(sigma_north_m: float | None, sigma_east_m: float | None) -> float | None:
    """RMS of the GST 1-σ position errors that are present and positive [m] (None: none is)."""
    north = sigma_north_m is not None and sigma_north_m > 0.0
    east = sigma_east_m is not None and sigma_east_m > 0.0
    if north and east:
        return math.sqrt((sigma_north_m * sigma_north_m + sigma_east_m * sigma_east_m) / 2)  # type: ignore[operator]
    if north:
        return math.sqrt(sigma_north_m * sigma_north_m)  # type: ignore[operator]
    if east:
        return math.sqrt(sigma_east_m * sigma_east_m)  # type: ignore[operator]
    return None


def _distance(a: tuple[float, float], b: tuple[float, float], heading: bool) -> float:
    if heading:
        return abs(ssa(a[0] - b[0]))
    return math.hypot(a[0] - b[0], a[1] - b[1])


def _median(values: list[float]) -> float:
    ordered = sorted(values)
    n = len(ordered)
    mid = n // 2
    return ordered[mid] if n % 2 else 0.5 * (ordered[mid - 1] + ordered[mid])
