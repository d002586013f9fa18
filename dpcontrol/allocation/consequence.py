"""Worst-case failure check: can the thrusters left after a failure still produce a demanded force?

A DP class 2 or 3 vessel is laid out so that no single failure (a switchboard, an engine room, a
thruster) loses position; the *consequence analysis* of its DP control system checks online, in the
weather of the moment, that this still holds, and warns before the failure rather than after it
(DNV rules for DP-2/3, "consequence analysis"; IMO MSC/Circ.645 §3.4.2.4). Here each configured
failure group (the thrusters one failure takes out) is removed from the thrusters in use, and the
demand is allocated to the rest with the same constrained QP as the control loop
(:class:`~dpcontrol.allocation.allocator.ThrustAllocator`: Fossen 2021 ch. 11), statically: a long
sample time, so that the rate limits do not bind, and a few passes so that the azimuths settle where
the demand needs them (:func:`~dpcontrol.allocation.capability.static_allocation`, as the capability plots).

Pure computation: no clock, no I/O. The runtime (:mod:`dpcontrol.runtime.consequence`) averages the
demand, runs this at a low rate off the control cycle's path, and raises the alarms.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from dpcontrol.allocation.allocator import ThrustAllocator
from dpcontrol.allocation.capability import STATIC_SAMPLE_TIME_S, static_allocation
from dpcontrol.models.thrusters import ThrusterSpec


@dataclass(frozen=True, slots=True)
class FailureGroup:
    """The thrusters one failure takes out (a switchboard, an engine room, one thruster).

    Attributes
    ----------
    name : str
        E.g. ``bus_a``.
    thrusters : tuple of str
        Thruster names (of the vessel's layout).
    """

    name: str
    thrusters: tuple[str, ...]


@dataclass(frozen=True, slots=True)
class FailureOutcome:
    """What is left after one failure group is lost, against one demand.

    Attributes
    ----------
    group : str
    holds : bool
        The remaining thrusters produce the demand (shortfall within the tolerance in every DOF).
    shortfall_b : ndarray, shape (3,)
        Demand not produced ``[N, N, N·m]`` (body axes).
    utilisation : float
        Largest thrust of a remaining thruster as a share of its rating (1.0: one at its limit) [-].
    busiest : str or None
        The remaining thruster with that share (None: none left).
    """

    group: str
    holds: bool
    shortfall_b: np.ndarray
    utilisation: float
    busiest: str | None = None


class WorstCaseFailure:
    """Allocates a demand to the thrusters left after each failure group.

    Parameters
    ----------
    thrusters : sequence of ThrusterSpec
        The vessel's layout.
    groups : sequence of FailureGroup
        Thruster names must be in ``thrusters`` (checked when the configuration is read).
    tolerance : float
        A shortfall up to this share of the intact layout's capability in a DOF (Σ |B| T_max) still
        holds [-] (0.2 %: a yaw moment of 68 kN·m on the supply vessel): the QP's polygon approximation of an
        azimuth leaves small residuals at the edge.
    allocation : mapping, optional
        The control loop's allocator settings (weights, slack), so that the check allocates as it would.

    Notes
    -----
    One allocator per group, each keeping its own warm start (the azimuths it chose last time), so a
    steady demand is re-checked in one or two QP iterations.
    """

    def __init__(self, thrusters: Sequence[ThrusterSpec], groups: Sequence[FailureGroup], *,
                 tolerance: float = 0.002, allocation: Mapping[str, Any] | None = None) -> None:
        names = [spec.name for spec in thrusters]
        self._names = names
        self.groups = tuple(groups)
        self._allocators = [ThrustAllocator(thrusters, STATIC_SAMPLE_TIME_S, **dict(allocation or {}))
                            for _ in self.groups]
        self._lost = [np.array([name in group.thrusters for name in names]) for group in self.groups]
        self._rating = np.array([spec.max_thrust_n for spec in thrusters])
        self._reverse = np.array([-spec.min_thrust_n for spec in thrusters])
        #: the shortfall per DOF that still holds ``[N, N, N·m]``
        self.tolerance_b = tolerance * self._allocators[0].capability_scale if self._allocators else np.zeros(3)

    def evaluate(self, demand_b: np.ndarray, available: np.ndarray) -> tuple[FailureOutcome, ...]:
        """Each group's outcome for ``demand_b`` ``[N, N, N·m]`` with the thrusters ``available`` now (bool, (n,))."""
        demand = np.asarray(demand_b, dtype=float)
        outcomes = []
        for group, allocator, lost in zip(self.groups, self._allocators, self._lost, strict=True):
            left = available & ~lost
            result = static_allocation(allocator, demand, left)
            thrust = result.thrust_n
            # reverse thrust against the reverse rating (a tunnel's astern side may be weaker)
            limit = np.where(thrust >= 0.0, self._rating, np.maximum(self._reverse, 1e-9))
            share = np.abs(thrust) / limit
            busiest = int(np.argmax(np.where(left, share, -1.0))) if left.any() else None
            utilisation = float("inf") if busiest is None else float(share[busiest])
            shortfall = result.shortfall_b.copy()
            holds = bool(left.any() and np.all(np.abs(shortfall) <= self.tolerance_b))
            outcomes.append(FailureOutcome(group.name, holds, shortfall, utilisation,
                                           None if busiest is None else self._names[busiest]))
        return tuple(outcomes)
