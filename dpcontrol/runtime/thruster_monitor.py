"""Thruster health from drive feedback (docs/fault-handling.md).

A thruster is taken out of the allocation — and commanded to zero — when its drive reports it is
not ready, or when the thrust it delivers disagrees with what a healthy drive would deliver for the
commands it was given (stuck, dead, wrong sign). The expected thrust follows the commands through
the drive's first-order response and rate limit (``ThrusterSpec.time_constant_s``,
``thrust_rate_limit_nps``), so ordinary lag is not a fault. The disagreement must exceed
``mismatch_fraction`` of the drive's rating — or, at low load, half of the expected thrust, never less
than the absolute floor ``mismatch_floor_fraction`` of the rating — for ``mismatch_persist_s``, both
low-passed over 1 s. The floor is what keeps a drive asked for (almost) nothing from being judged on
noise: a limit relative to an expected 4e-16 N would latch a healthy drive delivering 0 N.

Only *new* feedback is judged: a sample repeated by the transport, or the last one of a drive that went
silent, says nothing about what the drive does now (compared with an expectation that keeps following
the commands, it made a mismatch out of a loss of feedback). A drive whose feedback returns after a loss
(the drives or the plant restarted) is judged afresh from what it reports then: no mismatch pending from
before the loss, the expected thrust starting at the delivered one.

A "not ready" thruster is re-admitted after it has reported ready for ``readmit_s``; a mismatch
failure latches until an operator resets it (``reset(name)``), because a drive that delivered the
wrong thrust once cannot be trusted again automatically.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, TypedDict

import numpy as np

from dpbase.jit import b1_1d, f8, f8_1d, f8_2d, i8, i8_1d, kernel
from dpcontrol.models.thrusters import ThrusterSpec
from dpcontrol.runtime.alarms import AlarmRegistry, Severity


@dataclass(frozen=True)
class ThrusterMonitorSettings:
    """Thruster fault detection from drive feedback (docs/fault-handling.md)."""

    feedback_timeout_s: float = 2.0
    mismatch_fraction: float = 0.25
    # absolute floor of the mismatch limit, a share of each drive's rating: a drive asked for (almost) nothing is
    # never judged on noise (see dpcontrol.runtime.thruster_monitor)
    mismatch_floor_fraction: float = 0.05
    mismatch_persist_s: float = 5.0
    shortfall_fraction: float = 0.1
    shortfall_persist_s: float = 10.0


MISMATCH_FILTER_S = 1.0  # time constant of the low-passed thrust mismatch [s]
RELATIVE_MISMATCH = 0.5  # share of the expected thrust the delivered one may miss at low load [-]
RELATIVE_FLOOR = 0.05  # default absolute floor of the mismatch limit, as a share of the rating [-]

# Columns of the monitor's per-drive table (float): constants, then the state ThrusterMonitor.update advances
# (NaN in a *_SINCE column: no such time), then the expected thrust when a mismatch failure latched (its text),
# the receive time of the last feedback sample judged and when it was judged [s], and whether the drive's feedback
# is lost (1.0; also before the first feedback): judged afresh when it returns
(D_RATING, D_TIME_CONSTANT, D_RATE, D_EXPECTED, D_ERROR, D_LIMIT, D_READY_SINCE, D_MISMATCH_SINCE,
 D_FAILED_EXPECTED, D_JUDGED_SAMPLE, D_JUDGED_AT, D_LOST) = range(12)
DRIVE_COLUMNS = 12
# Columns of the feedback table (float): the latest feedback per drive; FB_READY is NaN before the first one
FB_THRUST, FB_T, FB_READY = range(3)
FEEDBACK_COLUMNS = 3
# Event bits of one update per drive: what the Python side turns into alarm calls and fault texts
E_STALE = 1        # feedback seen before, none for more than the timeout
E_UNAVAILABLE = 2  # out of the allocation
E_NOT_READY = 4    # fresh feedback: the drive reports not ready
E_READMITTED = 8   # ready for readmit_s: back in use
E_FAILED = 16      # a mismatch failure latched this update


def mismatch_limit_n(rating_n: float, expected_n: float, fraction: float,
                     floor_fraction: float = RELATIVE_FLOOR) -> float:
    """How far a drive's delivered thrust may be from a healthy drive's ``expected_n`` [N]: ``fraction``
    of its rating ``rating_n``, or at low load :data:`RELATIVE_MISMATCH` of the expected thrust, never
    below the absolute floor ``floor_fraction`` × the rating."""
    return min(fraction * rating_n, max(RELATIVE_MISMATCH * abs(expected_n), floor_fraction * rating_n))


_mismatch_limit_compiled = kernel(f8(f8, f8, f8, f8))(mismatch_limit_n)  # the same source, for _advance


@kernel(i8(f8, f8, f8_1d, f8_2d, f8_2d, b1_1d, b1_1d, f8, f8, f8, f8, f8, b1_1d, i8_1d))
def _advance(t_s: float, dt_s: float, commanded_n: np.ndarray, drive: np.ndarray, feedback: np.ndarray,  # noqa: PLR0913, PLR0917 - a kernel: its state is arrays, numba's calls are positional
             not_ready: np.ndarray, failed: np.ndarray, timeout_s: float, fraction: float, floor_fraction: float,
             persist_s: float, readmit_s: float, available: np.ndarray, events: np.ndarray) -> int:
    """One :meth:`ThrusterMonitor.update` of every drive's numbers (module docstring); the alarms are the caller's.

    Parameters
    ----------
    t_s, dt_s : now and the time since the previous update [s]
    commanded_n : (n,) thrust commanded in the previous cycle [N]
    drive : (n, DRIVE_COLUMNS) the per-drive table (``D_*`` columns), advanced in place
    feedback : (n, 3) the latest feedback (``FB_*`` columns)
    not_ready, failed : (n,) the drive reported not ready / a mismatch failure is latched (in place)
    timeout_s, fraction, floor_fraction, persist_s, readmit_s : the monitor's settings
    available : (n,) out — in the allocation; events : (n,) out — ``E_*`` bits

    Returns
    -------
    int
        The number of drives with an event.
    """
    flagged = 0
    for i in range(drive.shape[0]):
        expected = drive[i, D_EXPECTED]
        # Expected delivered thrust: first-order lag with the drive's rate limit.
        if dt_s > 0.0:
            response = 1.0 - math.exp(-dt_s / drive[i, D_TIME_CONSTANT])
            limit = drive[i, D_RATE] * dt_s
            step = (commanded_n[i] - expected) * response
            # max(−limit, min(limit, step)) written out as before (NaN included)
            step = step if step < limit else limit
            expected += step if step > -limit else -limit
        event = 0
        ready_code = feedback[i, FB_READY]
        if math.isnan(ready_code) or t_s - feedback[i, FB_T] > timeout_s:
            # No (recent) feedback: availability keeps its last state; flag only if it was seen before. The
            # drive is judged afresh when it reports again.
            if not math.isnan(ready_code):
                event |= E_STALE
                drive[i, D_LOST] = 1.0
        else:
            ready = ready_code != 0.0
            delivered = feedback[i, FB_THRUST]
            if drive[i, D_LOST] != 0.0:
                # Feedback (back) after a loss: the drive (restarted, perhaps) starts from what it delivers now;
                # a mismatch pending before the loss is not carried over it.
                drive[i, D_LOST] = 0.0
                expected = delivered
                drive[i, D_ERROR] = 0.0
                drive[i, D_LIMIT] = np.inf
                drive[i, D_MISMATCH_SINCE] = np.nan
                drive[i, D_JUDGED_AT] = np.nan
            if not ready:
                not_ready[i] = True
                drive[i, D_READY_SINCE] = np.nan
                event |= E_NOT_READY
            elif not_ready[i]:
                if math.isnan(drive[i, D_READY_SINCE]):
                    drive[i, D_READY_SINCE] = t_s
                if t_s - drive[i, D_READY_SINCE] >= readmit_s:
                    not_ready[i] = False
                    expected = delivered
                    drive[i, D_ERROR] = 0.0
                    drive[i, D_LIMIT] = np.inf
                    event |= E_READMITTED
            sample_t = feedback[i, FB_T]
            if ready and not failed[i] and not not_ready[i] and sample_t != drive[i, D_JUDGED_SAMPLE]:
                # (a new sample only: a repeated one says nothing about what the drive does now)
                # The error and the limit are low-passed (the command of a drive in DP fluctuates; a dead
                # drive's error dips whenever its command does) and judged with hysteresis: the mismatch
                # persists until the filtered error falls below half the limit. The limit is
                # mismatch_fraction of the rating, or — when the drive is asked for less — half of what it
                # should deliver, floored at floor_fraction of the rating: a drive delivering nothing (or
                # pushing the wrong way) at 5–20 % load is a failure too. The filters advance by the time since
                # the last sample judged.
                error = abs(delivered - expected)
                limit_now = _mismatch_limit_compiled(drive[i, D_RATING], expected, fraction, floor_fraction)
                if not math.isfinite(drive[i, D_LIMIT]):
                    drive[i, D_LIMIT] = limit_now
                judged_at = drive[i, D_JUDGED_AT]
                elapsed = dt_s if math.isnan(judged_at) else t_s - judged_at
                drive[i, D_JUDGED_SAMPLE] = sample_t
                drive[i, D_JUDGED_AT] = t_s
                if elapsed > 0.0:
                    mismatch_alpha = -math.expm1(-elapsed / MISMATCH_FILTER_S)
                    drive[i, D_ERROR] += (error - drive[i, D_ERROR]) * mismatch_alpha
                    drive[i, D_LIMIT] += (limit_now - drive[i, D_LIMIT]) * mismatch_alpha
                limit = drive[i, D_LIMIT]
                since = drive[i, D_MISMATCH_SINCE]
                if drive[i, D_ERROR] > limit or (not math.isnan(since) and drive[i, D_ERROR] > 0.5 * limit):
                    if math.isnan(since):
                        drive[i, D_MISMATCH_SINCE] = t_s
                    if t_s - drive[i, D_MISMATCH_SINCE] >= persist_s:
                        failed[i] = True
                        drive[i, D_FAILED_EXPECTED] = expected
                        event |= E_FAILED
                else:
                    drive[i, D_MISMATCH_SINCE] = np.nan
        usable = not (not_ready[i] or failed[i])
        if not usable:
            expected = 0.0  # it is commanded to zero from now on
            event |= E_UNAVAILABLE
        drive[i, D_EXPECTED] = expected
        available[i] = usable
        events[i] = event
        if event != 0:
            flagged += 1
    return flagged


class ThrusterStatus(TypedDict):
    """One thruster's line of :meth:`ThrusterMonitor.status` (the status message's availability)."""

    name: str
    available: bool
    detail: str  # the fault, "" when none


@dataclass(frozen=True)
class ThrusterFeedback:
    """What a drive reports: delivered thrust [N], azimuth/rudder angle [rad], readiness."""

    name: str
    thrust_n: float
    azimuth_rad: float
    ready: bool
    t_s: float


class _Health:
    """One drive as the monitor sees it: its spec, last feedback and fault text; its numbers are row ``index`` of
    the monitor's per-drive table (``expected_n`` reads it, for diagnostics)."""

    __slots__ = ("_drive", "_index", "detail", "last_feedback", "spec")

    def __init__(self, spec: ThrusterSpec, drive: np.ndarray, index: int) -> None:
        self.spec = spec
        self.last_feedback: ThrusterFeedback | None = None
        self.detail = ""
        self._drive = drive
        self._index = index

    @property
    def expected_n(self) -> float:
        """What a healthy drive would deliver now [N]."""
        return float(self._drive[self._index, D_EXPECTED])


class ThrusterMonitor:
    """Tracks each thruster's availability from commands and feedback.

    Parameters
    ----------
    thrusters : sequence of ThrusterSpec
    settings : ThrusterMonitorSettings
    alarms : AlarmRegistry
    readmit_s : float
        Ready time before a "not ready" thruster is used again [s].

    Notes
    -----
    The numbers of every drive advance in one compiled call (:func:`_advance`, see :mod:`dpbase.jit`): the
    per-drive Python loop it replaced cost ≈ 3 µs a drive and step (lockstep profile of the shuttle tanker's six
    drives: 20 → 12 µs per update). It reports per drive which alarms and texts are due; the alarm calls stay
    here, and are skipped entirely on a step without any (the usual one).
    """

    def __init__(self, thrusters: Sequence[ThrusterSpec], settings: ThrusterMonitorSettings, alarms: AlarmRegistry,
                 readmit_s: float = 5.0) -> None:
        self.settings = settings
        self.alarms = alarms
        self.readmit_s = readmit_s
        n = len(thrusters)
        self._drive = np.zeros((n, DRIVE_COLUMNS))
        self._drive[:, D_RATING] = [spec.max_thrust_n for spec in thrusters]
        self._drive[:, D_TIME_CONSTANT] = [spec.time_constant_s for spec in thrusters]
        self._drive[:, D_RATE] = [spec.thrust_rate_limit_nps for spec in thrusters]
        self._drive[:, D_LIMIT] = np.inf  # the mismatch limit is set at the first feedback
        self._drive[:, D_READY_SINCE] = np.nan
        self._drive[:, D_MISMATCH_SINCE] = np.nan
        self._drive[:, D_JUDGED_SAMPLE] = np.nan
        self._drive[:, D_JUDGED_AT] = np.nan
        self._drive[:, D_LOST] = 1.0  # no feedback yet: the first is judged afresh
        self._not_ready = np.zeros(n, dtype=bool)
        self._failed = np.zeros(n, dtype=bool)
        self._events = np.zeros(n, dtype=np.int64)
        self._health = [_Health(spec, self._drive, i) for i, spec in enumerate(thrusters)]
        self._index = {spec.name: i for i, spec in enumerate(thrusters)}
        self.available = np.ones(n, dtype=bool)
        self.feedback_seen = False
        self.unknown_feedback = 0
        # the latest feedback per drive as a flat Python list of the feedback table's rows (a list item write is
        # cheaper than an array's), copied into the table in one call by the update that follows new feedback
        self._fb = [0.0, math.nan, math.nan] * n
        self._fb_angle = [spec.angle_rad for spec in thrusters]
        self._fb_new = False
        self._feedback = np.full((n, FEEDBACK_COLUMNS), np.nan)
        self._feedback_flat = self._feedback.reshape(-1)  # a view
        # name → (its _Health, index, positions of its thrust, time and readiness in _fb): see feedback
        self._slots = {spec.name: (self._health[i], i, FEEDBACK_COLUMNS * i + FB_THRUST, FEEDBACK_COLUMNS * i + FB_T,
                                   FEEDBACK_COLUMNS * i + FB_READY) for i, spec in enumerate(thrusters)}
        # alarm codes built once (an f-string per thruster and step cost more than the health logic)
        self._codes = [(f"thruster.{spec.name}.feedback_lost", f"thruster.{spec.name}.unavailable")
                       for spec in thrusters]
        # the codes this monitor has raised (only it raises them): clear() is called only for these, not for
        # every thruster and step (a registry look-up each, most of the monitor's cost)
        self._raised: set[str] = set()
        # (settings, readmit_s, and the four floats _advance takes from them): see update
        self._limits: tuple[Any, ...] = (None, math.nan)

    def feedback(self, items: Sequence[ThrusterFeedback]) -> None:
        """Store the latest feedback of each drive."""
        # (per drive, its record and list positions looked up once by name: the index arithmetic and the
        # attribute look-ups of a plain loop cost more than the writes, six to eight drives every cycle)
        fb = self._fb
        angles = self._fb_angle
        slots = self._slots
        seen = False
        for item in items:
            slot = slots.get(item.name)
            if slot is None:
                self.unknown_feedback += 1
                continue
            health, index, thrust, stamp, ready = slot
            health.last_feedback = item
            fb[thrust] = item.thrust_n
            fb[stamp] = item.t_s
            fb[ready] = 1.0 if item.ready else 0.0
            angles[index] = item.azimuth_rad
            seen = True
        if seen:
            self._fb_new = True
            self.feedback_seen = True

    def update(self, t_s: float, dt_s: float, commanded_thrust_n: np.ndarray) -> np.ndarray:
        """Advance the expected drive response by ``dt_s`` and decide availability.

        Parameters
        ----------
        t_s : float
            Now [s].
        dt_s : float
            Time since the previous call [s].
        commanded_thrust_n : ndarray, shape (n,)
            Thrust commanded in the previous cycle (what the drives are following) [N].

        Returns
        -------
        ndarray of bool, shape (n,)
            Availability mask for the allocator (a view, updated in place).
        """
        commanded = commanded_thrust_n
        if not (type(commanded) is np.ndarray and commanded.dtype == np.float64 and commanded.flags.carray):
            commanded = np.array(commanded, dtype=float)  # a copy: contiguous and writable, as _advance takes
        if commanded.shape != self.available.shape:
            raise ValueError(f"commanded_thrust_n must have one entry per thruster ({self.available.size}), "
                             f"got shape {commanded.shape}")
        if self._fb_new:
            self._feedback_flat[:] = self._fb
            self._fb_new = False
        limits = self._limits
        if limits[0] is not self.settings or limits[1] != self.readmit_s:
            # the settings as the kernel's floats, converted again only when settings or readmit_s are replaced
            s = self.settings
            limits = self._limits = (s, self.readmit_s, float(s.feedback_timeout_s), float(s.mismatch_fraction),
                                     float(s.mismatch_floor_fraction), float(s.mismatch_persist_s),
                                     float(self.readmit_s))
        _, _, timeout, fraction, floor_fraction, persist, readmit = limits
        flagged = _advance(float(t_s), float(dt_s), commanded, self._drive, self._feedback, self._not_ready,
                           self._failed, timeout, fraction, floor_fraction, persist, readmit, self.available,
                           self._events)
        if flagged or self._raised:
            self._raise_and_clear(t_s)
        return self.available

    def _raise_and_clear(self, t_s: float) -> None:
        """The fault texts and alarm calls of the events of the last :func:`_advance`, drive by drive."""
        s = self.settings
        alarms = self.alarms
        raised = self._raised
        for i, event in enumerate(self._events.tolist()):
            health = self._health[i]
            name = health.spec.name
            if event & E_NOT_READY:
                health.detail = "drive reports not ready"
            elif event & E_READMITTED:
                health.detail = ""
            if event & E_FAILED:
                health.detail = (f"delivered {self._fb[FEEDBACK_COLUMNS * i + FB_THRUST]:.4g} N, expected "
                                 f"{float(self._drive[i, D_FAILED_EXPECTED]):.4g} N")
            lost_code, unavailable_code = self._codes[i]
            if event & E_STALE:
                alarms.raise_(t_s, lost_code, Severity.WARNING,
                              f"{name}: no feedback for more than {s.feedback_timeout_s:g} s")
                raised.add(lost_code)
            elif lost_code in raised:
                alarms.clear(t_s, lost_code)
                raised.discard(lost_code)
            if event & E_UNAVAILABLE:
                alarms.raise_(t_s, unavailable_code, Severity.ALARM, f"{name} removed from allocation: {health.detail}")
                raised.add(unavailable_code)
            elif unavailable_code in raised:
                alarms.clear(t_s, unavailable_code)
                raised.discard(unavailable_code)

    def is_latched(self, name: str) -> bool:
        """Whether a mismatch failure of ``name`` is latched (out of the allocation until :meth:`reset`)."""
        index = self._index.get(name)
        return index is not None and bool(self._failed[index])

    def reset(self, name: str) -> bool:
        """Operator reset of a latched mismatch failure; returns whether the thruster exists."""
        index = self._index.get(name)
        if index is None:
            return False
        self._failed[index] = False
        drive = self._drive
        drive[index, D_MISMATCH_SINCE] = np.nan
        drive[index, D_ERROR] = 0.0
        drive[index, D_LIMIT] = np.inf
        feedback = self._health[index].last_feedback
        drive[index, D_EXPECTED] = feedback.thrust_n if feedback else 0.0
        return True

    def delivered_into(self, thrust_n: np.ndarray, azimuth_rad: np.ndarray) -> bool:
        """The latest delivered thrust and angle per thruster, written into the caller's arrays (no new
        arrays per control cycle).

        Parameters
        ----------
        thrust_n, azimuth_rad : ndarray, shape (n,)
            Filled with the latest delivered thrust [N] and azimuth / rudder angle [rad] per thruster
            (0 N and the spec's angle for a drive without feedback); untouched without any feedback.

        Returns
        -------
        bool
            Whether there was feedback (False: nothing written).
        """
        if not self.feedback_seen:
            return False
        thrust_n[:] = self._fb[FB_THRUST::FEEDBACK_COLUMNS]
        azimuth_rad[:] = self._fb_angle
        return True

    def status(self) -> list[ThrusterStatus]:
        """Per-thruster availability for the status message."""
        return [{"name": h.spec.name, "available": bool(self.available[i]), "detail": h.detail}
                for i, h in enumerate(self._health)]

    def state_dict(self) -> dict[str, object]:
        return {"latched": [h.spec.name for h, failed in zip(self._health, self._failed.tolist(), strict=True)
                            if failed]}

    def load_state_dict(self, state: dict[str, object]) -> None:
        latched = state.get("latched", [])
        if isinstance(latched, list):
            for name in latched:
                index = self._index.get(str(name))
                if index is not None:
                    self._failed[index] = True
                    self._health[index].detail = "latched failure before restart"
