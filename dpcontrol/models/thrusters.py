"""Thruster descriptions shared by the allocation (controller) and the plant's drives.

Body frame: ``x_m`` forward, ``y_m`` to starboard, measured from the vessel's control origin
(midship on the centre line). A thruster's force direction is ``angle_rad`` from the bow,
positive clockwise (to starboard), like a heading.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

from dpbase.schema import ConfigError, Section

ThrusterKind = Literal["tunnel", "azimuth", "propeller", "propeller_rudder"]
THRUSTER_KINDS: tuple[str, ...] = ("tunnel", "azimuth", "propeller", "propeller_rudder")


@dataclass(frozen=True)
class ThrusterSpec:
    """One thruster: geometry, limits and drive dynamics.

    Attributes
    ----------
    name : str
        Unique name (used in Zenoh commands and feedback).
    kind : {"tunnel", "azimuth", "propeller", "propeller_rudder"}
        ``tunnel``: fixed athwartship force (``angle_rad`` = π/2), reversible.
        ``azimuth``: force direction is the commanded azimuth.
        ``propeller``: fixed longitudinal force (``angle_rad`` = 0), reversible.
        ``propeller_rudder``: main propeller with a rudder in its slipstream; with positive thrust
        the rudder deflects the force by up to ``rudder_max_angle_rad``.
    x_m, y_m : float
        Position in the body frame [m].
    max_thrust_n : float
        Largest thrust along the force direction [N] (> 0).
    min_thrust_n : float
        Most negative thrust (reverse) [N] (<= 0; 0 for azimuths that do not reverse).
    thrust_rate_limit_nps : float
        Largest rate of change of thrust [N/s].
    time_constant_s : float
        First-order response time of the drive [s] (plant).
    angle_rad : float
        Fixed force direction for tunnel / propeller kinds [rad].
    azimuth_rate_limit_radps : float or None
        Azimuth / rudder slew rate [rad/s].
    forbidden_sectors_rad : tuple of (start, end)
        Azimuth sectors the thrust must not point into (e.g. wash onto a hull), clockwise from
        start to end [rad].
    rudder_max_angle_rad : float or None
        Rudder deflection limit for ``propeller_rudder`` [rad].
    rudder_lift_per_rad : float
        Rudder lift coefficient: sway force ≈ thrust · rudder_lift_per_rad · δ for positive thrust
        [1/rad].
    """

    name: str
    kind: ThrusterKind
    x_m: float
    y_m: float
    max_thrust_n: float
    min_thrust_n: float
    thrust_rate_limit_nps: float
    time_constant_s: float = 1.0
    angle_rad: float = 0.0
    azimuth_rate_limit_radps: float | None = None
    forbidden_sectors_rad: tuple[tuple[float, float], ...] = field(default_factory=tuple)
    rudder_max_angle_rad: float | None = None
    rudder_lift_per_rad: float = 0.0

    def __post_init__(self) -> None:
        if self.kind not in THRUSTER_KINDS:
            raise ValueError(f"thruster {self.name}: unknown kind {self.kind!r}")
        if not self.max_thrust_n > 0.0 or self.min_thrust_n > 0.0:
            raise ValueError(f"thruster {self.name}: need max_thrust_n > 0 >= min_thrust_n")


def parse_thruster(section: Section) -> ThrusterSpec:
    """Build a :class:`ThrusterSpec` from a config mapping (degrees at the edge: ``*_deg`` keys).

    Keys: ``name, kind, x_m, y_m, max_thrust_n, min_thrust_n, thrust_rate_limit_nps,
    time_constant_s, angle_deg, azimuth_rate_limit_degps, forbidden_sectors_deg,
    rudder_max_angle_deg, rudder_lift_per_rad``.
    """
    kind = section.string("kind", choices=THRUSTER_KINDS)
    default_angle = 90.0 if kind == "tunnel" else 0.0
    max_thrust = section.number("max_thrust_n", minimum=0.0, exclusive_minimum=True)
    min_thrust = section.number("min_thrust_n", 0.0 if kind == "azimuth" else -max_thrust, maximum=0.0)
    rate_deg = section.optional_number("azimuth_rate_limit_degps", minimum=0.0, exclusive_minimum=True)
    if kind == "azimuth" and rate_deg is None:
        rate_deg = 10.0
    rudder_deg = section.optional_number("rudder_max_angle_deg", minimum=0.0, maximum=90.0)
    if kind == "propeller_rudder" and rudder_deg is None:
        raise ConfigError(f"{section.path}.rudder_max_angle_deg",
                          "a rudder limit in degrees for kind propeller_rudder", None)
    sectors = []
    for where, item in section.items("forbidden_sectors_deg"):
        if not isinstance(item, list) or len(item) != 2:
            raise ConfigError(where, "a [start_deg, end_deg] pair", item)
        start = Section.of({"v": item[0]}, where).number("v")
        end = Section.of({"v": item[1]}, where).number("v")
        sectors.append((math.radians(start), math.radians(end)))
    spec = ThrusterSpec(
        name=section.string("name"),
        kind=kind,  # type: ignore[arg-type]
        x_m=section.number("x_m"),
        y_m=section.number("y_m"),
        max_thrust_n=max_thrust,
        min_thrust_n=min_thrust,
        thrust_rate_limit_nps=section.number("thrust_rate_limit_nps", max_thrust / 5.0, minimum=0.0,
                                             exclusive_minimum=True),
        time_constant_s=section.number("time_constant_s", 1.0, minimum=0.0, exclusive_minimum=True),
        angle_rad=math.radians(section.number("angle_deg", default_angle)),
        azimuth_rate_limit_radps=None if rate_deg is None else math.radians(rate_deg),
        forbidden_sectors_rad=tuple(sectors),
        rudder_max_angle_rad=None if rudder_deg is None else math.radians(rudder_deg),
        rudder_lift_per_rad=section.number("rudder_lift_per_rad", 0.0 if rudder_deg is None else 1.0,
                                           minimum=0.0),
    )
    section.finish()
    return spec
