"""The controller replica: a second :class:`~dpcontrol.runtime.step.DpController` one cycle behind.

The daemon keeps a second controller, built from the same configuration (and resumed from the same
persisted state), and feeds it exactly what the primary consumed — the cycle's measurements, thruster
feedback, operator requests and link changes — one cycle later, a few milliseconds before the next
deadline (``loop.replica_lead_ms``). The step is deterministic (:mod:`dpcontrol.runtime.step`: no
clock, no I/O), so the replica must compute, bit for bit, the command the primary published. Two
things come of it:

* **A check of the computation.** A replica command that differs from the primary's (beyond
  :data:`THRUST_TOLERANCE` of a thruster's rated thrust or :data:`AZIMUTH_TOLERANCE_RAD`, another
  mode, or a step that raised on one side only) means that one of the two states is no longer what
  its inputs made it — memory corruption, a thread writing where it must not, non-determinism
  brought in by a change. The warning ``controller.replica_mismatch`` is raised with the cycle and
  the size of the difference, and stays raised: from then on the two histories differ and no later
  comparison means anything. Restarting the daemon clears it — the primary resumes bumplessly from
  its persisted state and the replica from the same state. (Re-synchronising in place was tried:
  the persisted state is what a bumpless restart needs, not every bit of the filters' and hub's
  state, and the two never agreed exactly again.) The replica's own alarms go to a registry of its
  own and are never published.
* **Warm caches at the deadline.** The replica runs the same code over data of the same shape just
  before the primary does, so the primary's step starts with the code and the interpreter's caches
  warm. On a shared 2-core VM the step otherwise runs at about 3× its back-to-back cost because the
  host empties the caches between cycles (``benchmarks/bench_cold_cache.py``). On the HIL demo, in
  paired runs with the replica off and on, it took the median of the daemon's cycle start → command
  published from about 1.5 to 1.2 ms (README, benchmarks). After a mismatch the replica goes on
  stepping for this reason alone.

The replica costs one more controller step per cycle (the loop's CPU time doubles: about 1 % of a
core at 10 Hz) and the memory of a second model bank. ``loop.replica_check: false`` turns it off.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from dpbase.requests import SetpointRequest
from dpcontrol.runtime.alarms import AlarmRegistry, Severity
from dpcontrol.runtime.config import DaemonConfig
from dpcontrol.runtime.hub import SensorHub
from dpcontrol.runtime.step import DpController, Mode, StepOutput
from dpcontrol.runtime.thruster_monitor import ThrusterFeedback
from interfaces.messages import LinkStatus, Measurement

log = logging.getLogger(__name__)

REPLICA_ALARM = "controller.replica_mismatch"
THRUST_TOLERANCE = 1e-9  # largest agreed thrust difference, as a share of the thruster's rated thrust [-]
AZIMUTH_TOLERANCE_RAD = 1e-9  # largest agreed angle difference [rad]

MarkLinks = Callable[[Iterable[LinkStatus], SensorHub], None]


@dataclass
class _Held:
    """One primary cycle: what it consumed and what came of it (copies: the daemon reuses its lists).

    ``error`` is the exception the primary's step raised (``"TypeName: text"``), else None and the
    command is in ``mode``, ``thrust_n``, ``azimuth_rad``.
    """

    t_s: float
    cycle: int
    measurements: list[Measurement]
    feedback: list[ThrusterFeedback]
    requests: list[SetpointRequest]
    links: list[LinkStatus]
    error: str | None
    mode: Mode | None = None
    thrust_n: np.ndarray | None = None
    azimuth_rad: np.ndarray | None = None


@dataclass
class ReplicaCounters:
    """What the replica has done since the daemon started.

    Attributes
    ----------
    stepped : int
        Primary cycles the replica recomputed.
    ahead : int
        Of those, the ones recomputed before the next deadline (the others were caught up after the
        next command was published, when the loop was late).
    compared : int
        Cycles whose outcome was compared with the primary's (all of them until a mismatch).
    mismatches : int
        0, or 1 once a mismatch was found (comparisons stop there).
    last_mismatch : str
        What differed ("" if nothing did).
    """

    stepped: int = 0
    ahead: int = 0
    compared: int = 0
    mismatches: int = 0
    last_mismatch: str = ""

    def as_dict(self) -> dict[str, object]:
        return {"stepped": self.stepped, "ahead_of_deadline": self.ahead, "compared": self.compared,
                "mismatches": self.mismatches, "last_mismatch": self.last_mismatch}


def _error_text(error: BaseException) -> str:
    return f"{type(error).__name__}: {error}"


class ControllerReplica:
    """A second controller one cycle behind the primary (see the module docstring).

    Parameters
    ----------
    config : DaemonConfig
        The daemon's configuration (the replica is built from it, like the primary).
    alarms : AlarmRegistry
        The daemon's registry: ``controller.replica_mismatch`` is raised there.
    mark_links : callable
        Applies link changes to a hub as the daemon does to the primary's
        (:meth:`dpcontrol.runtime.transport_health.InputHealth.mark_links`).
    resumed_state : dict, optional
        The persisted state the primary was resumed from (a copy: loading may alter it), and
        ``resumed_t_s`` the time it was loaded at [s]: the replica loads the same.
    """

    def __init__(self, config: DaemonConfig, alarms: AlarmRegistry, mark_links: MarkLinks, *,
                 resumed_state: dict[str, Any] | None = None, resumed_t_s: float = 0.0) -> None:
        self.controller = DpController(config, AlarmRegistry())
        if resumed_state is not None:
            self.controller.load_state_dict(resumed_state, resumed_t_s)
        self.alarms = alarms
        self.mark_links = mark_links
        self.counters = ReplicaCounters()
        rated = np.array([t.max_thrust_n for t in config.vessel.thrusters], dtype=float)
        self._thrust_tolerance_n = THRUST_TOLERANCE * np.maximum(np.abs(rated), 1.0)
        self._held: _Held | None = None

    @property
    def pending(self) -> bool:
        """A primary cycle is waiting to be recomputed."""
        return self._held is not None

    @property
    def in_agreement(self) -> bool:
        """No mismatch so far."""
        return self.counters.mismatches == 0

    def hold(self, t_s: float, cycle: int, out: StepOutput | None, *, measurements: Sequence[Measurement],
             feedback: Sequence[ThrusterFeedback], requests: Sequence[SetpointRequest],
             links: Sequence[LinkStatus], error: BaseException | None = None) -> None:
        """Keep what the primary's cycle ``cycle`` consumed and its outcome — the command ``out``, or the
        ``error`` its step raised — for :meth:`check`.

        A cycle still pending is recomputed first: the replica never skips one.
        """
        if self._held is not None:
            self.check(t_s, ahead=False)
        held = _Held(t_s, cycle, list(measurements), list(feedback), list(requests), list(links),
                     None if error is None else _error_text(error))
        if out is not None and error is None:
            held.mode = out.mode
            held.thrust_n = out.thrust_n.copy()
            held.azimuth_rad = out.azimuth_rad.copy()
        self._held = held

    def check(self, now_s: float, *, ahead: bool) -> bool:
        """Recompute the pending cycle and compare its outcome with the primary's.

        Parameters
        ----------
        now_s : float
            The loop's clock [s] (the alarm's time).
        ahead : bool
            Run before the next deadline (True) or caught up after it (False); counted.

        Returns
        -------
        bool
            False when this cycle showed the (first) mismatch.
        """
        held = self._held
        if held is None:
            return True
        self._held = None
        counters = self.counters
        counters.stepped += 1
        if ahead:
            counters.ahead += 1
        replica_error: str | None = None
        out: StepOutput | None = None
        try:
            replica = self.controller
            if held.links:
                self.mark_links(held.links, replica.hub)
            out = replica.step(held.t_s, held.measurements, held.feedback, held.requests)
        except Exception as error:  # the primary's step may have raised the same: compared below
            replica_error = _error_text(error)
        if counters.mismatches:
            return True  # the histories differ already: the replica only keeps the caches warm
        counters.compared += 1
        difference = self._difference(held, out, replica_error)
        if difference is None:
            return True
        counters.mismatches = 1
        counters.last_mismatch = f"cycle {held.cycle}: {difference}"
        log.warning("controller replica disagrees at cycle %d: %s", held.cycle, difference)
        self.alarms.raise_(now_s, REPLICA_ALARM, Severity.WARNING,
                           f"controller replica disagrees since cycle {held.cycle}: {difference}. One of the two "
                           "controllers' states is not what its inputs made it; restart the daemon when convenient "
                           "(it resumes from its persisted state)")
        return False

    def _difference(self, held: _Held, out: StepOutput | None, replica_error: str | None) -> str | None:
        """None if the replica's outcome is the primary's, else what differs."""
        if held.error is not None or replica_error is not None:
            if held.error == replica_error:
                return None
            return f"the primary's step {'raised ' + held.error if held.error else 'returned'}, " \
                   f"the replica's {'raised ' + replica_error if replica_error else 'returned'}"
        assert out is not None and held.thrust_n is not None and held.azimuth_rad is not None
        if out.mode is not held.mode:
            return f"mode {out.mode.value}, primary {held.mode.value if held.mode else None}"
        if np.array_equal(out.thrust_n, held.thrust_n) and np.array_equal(out.azimuth_rad, held.azimuth_rad):
            return None
        thrust_error = np.abs(out.thrust_n - held.thrust_n)
        azimuth_error = np.abs(out.azimuth_rad - held.azimuth_rad)
        # NaN compares False: a NaN on either side counts as a difference
        if np.all(thrust_error <= self._thrust_tolerance_n) and np.all(azimuth_error <= AZIMUTH_TOLERANCE_RAD):
            return None
        return (f"thrust differs by up to {float(np.nanmax(thrust_error, initial=0.0)):.3g} N, "
                f"azimuth by up to {float(np.nanmax(azimuth_error, initial=0.0)):.3g} rad")
