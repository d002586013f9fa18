"""What an operator asks of the controller, and what became of it (docs/design.md §4.4).

The request is the daemon's and the simulation's input from the operator, whichever way it arrives (a Zenoh
``dp/<vessel>/setpoint`` payload parsed by :func:`interfaces.zenoh.schemas.parse_setpoint`, the console, or a
scenario's set-point schedule in lockstep); the control step reads it without knowing the wire, so it lives
here, below the step and the transports.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dpbase.frames import body_to_ned, ssa


@dataclass(frozen=True, slots=True)
class SetpointRequest:
    """A validated operator request (``dpcontrol.setpoint/1``); unset fields are ``None``.

    Absolute ``north_m``/``east_m`` come together; ``heading_rad`` is wrapped to (−π, π]
    (``heading_deg`` is converted). Relative parts: ``move_north_m``/``move_east_m`` in NED,
    ``move_surge_m``/``move_sway_m`` along the *current setpoint's* heading, ``turn_rad``
    clockwise. Use :meth:`resolve` to turn the request into an absolute target.

    ``role`` and ``identity`` are never read from the payload: the receiver sets them from the authenticated
    link the request came over (the sender's certificate common name and the role the configuration gives it;
    ``None`` on an unauthenticated network).
    """

    t_s: float
    seq: int
    mode: str | None = None
    north_m: float | None = None
    east_m: float | None = None
    heading_rad: float | None = None
    move_north_m: float | None = None
    move_east_m: float | None = None
    move_surge_m: float | None = None
    move_sway_m: float | None = None
    turn_rad: float | None = None
    reset_thruster: str | None = None
    accept_reference: str | None = None
    role: str | None = None
    identity: str | None = None

    @property
    def changes_pose(self) -> bool:
        """True when the request moves the position or heading setpoint (not only a mode change)."""
        return any(v is not None for v in (self.north_m, self.heading_rad, self.move_north_m, self.move_east_m,
                                           self.move_surge_m, self.move_sway_m, self.turn_rad))

    def resolve(self, north_m: float, east_m: float, heading_rad: float) -> tuple[float, float, float]:
        """The absolute target ``(north_m, east_m, heading_rad)`` given the current setpoint.

        Body moves are rotated with the current setpoint heading ψ: ``Δη = R_nb(ψ) [Δsurge, Δsway, 0]``
        (seed 002 eq. (3)); the result heading is wrapped with ``ssa``.
        """
        north = self.north_m if self.north_m is not None else north_m
        east = self.east_m if self.east_m is not None else east_m
        north += self.move_north_m or 0.0
        east += self.move_east_m or 0.0
        if self.move_surge_m is not None or self.move_sway_m is not None:
            delta_ned = body_to_ned(np.array([self.move_surge_m or 0.0, self.move_sway_m or 0.0, 0.0]), heading_rad)
            north += float(delta_ned[0])
            east += float(delta_ned[1])
        heading = self.heading_rad if self.heading_rad is not None else heading_rad
        heading = ssa(heading + (self.turn_rad or 0.0))
        return north, east, heading


@dataclass(frozen=True, slots=True)
class RequestOutcome:
    """What became of an operator request the controller took (``dp/<vessel>/setpoint``): the request's
    ``seq``, the controller time [s] of the step that took it, ``applied`` or ``refused``, and what is now in
    force or why not; the role and identity it came in under (see :class:`SetpointRequest`). A sender finds its
    own request by its ``seq``."""

    seq: int
    t_s: float
    outcome: str
    detail: str
    role: str | None = None
    identity: str | None = None
