"""Every Zenoh payload schema of dpcontrol, in one place (docs/design.md §4.4).

Payloads are UTF-8 JSON objects (zenoh encoding ``application/json``) with a common envelope:

* ``schema`` — ``"<name>/<version>"``, e.g. ``"dpcontrol.thrusters.command/1"``; a change that
  breaks readers bumps the version;
* ``t_s`` — the publisher's clock when the content was computed [s] (the daemon's injected clock:
  monotonic in real time, simulated in lockstep). Consumers judge staleness by their own receive
  time, never by comparing clocks across hosts;
* ``seq`` — per-publisher counter (0, 1, 2, …) to see drops and restarts.

Missing data is ``null``, never NaN: JSON has no NaN, and builders turn non-finite floats into
``null`` (except in a thruster command, where a non-finite value is refused: see
:func:`command_payload`).

Two kinds of functions live here:

* **builders** (``*_payload``) — called by the daemon/plant every cycle: plain dicts and lists of
  floats, one JSON encode (orjson), bytes out. Cheap by construction (see ``benchmarks/bench_zenoh.py``).
* **validating parsers** — for what arrives from outside: :func:`parse_setpoint` (operator →
  daemon), :func:`parse_feedback` (drives → daemon), :func:`parse_command` (daemon → drives, as
  read by the plant/drives), and :func:`parse_message` for any schema (validated ``dict``, used by
  the monitor). Garbage, a wrong schema, missing or unknown fields, NaN/inf, wrong types or
  out-of-range values return a :class:`interfaces.messages.Rejected` with a machine-readable
  ``reason`` (one of :data:`REJECT_REASONS`) and a ``detail`` naming the field path. They never
  raise into the caller.

The validation is a small declarative spec (:class:`Record`, :class:`Array`, :class:`Number`, …)
written by hand: no JSON-Schema library is a dependency of the project, and these specs double as
the documentation of each schema and give field-path error messages in one line.

Schemas (version 1; ``?`` = may be ``null``)
--------------------------------------------
``dpcontrol.thrusters.command/1`` (daemon → drives, ``dp/<vessel>/thrusters/command``)::

    mode: "standby" | "auto_heading" | "auto_position"
    thrusters: [{name, thrust_n, azimuth_rad, enabled}]
        azimuth_rad: force direction for azimuths, rudder angle for propeller_rudder,
                     the fixed angle for tunnels/propellers (body frame, clockwise from the bow)

``dpcontrol.thrusters.feedback/1`` (drives → daemon)::

    thrusters: [{name, thrust_n?, azimuth_rad?, ready}]

``dpcontrol.estimate/1``::

    estimator: str  (mmae | kf | rpem | kalman_bucy | raw ...)
    pose_n?: {north_m?, east_m?, heading_rad?}          LF pose, NED
    velocity_b?: {surge_mps?, sway_mps?, yaw_rate_radps?} LF velocity, body
    bias?: {frame: "ned" | "body", x_n?, y_n?, n_nm?}   slowly varying bias force (seed 002 b)
    wave_n?: {north_m?, east_m?, heading_rad?}           WF motion estimate
    covariance_diag?: [float?]                            diagonal of P (estimator state order)

``dpcontrol.mmae/1``::

    omegas_rad_s: [float]   model peak frequencies;  weights: [float] (same length, sum 1)
    omega_hat_rad_s?: float;  sea_state?: str  (classified by a :class:`SeaStateTable`)

``dpcontrol.control/1``::

    controller: str  (pid | mrac ...)
    setpoint?: {north_m?, east_m?, heading_rad?}
    reference?: {north_m?, east_m?, heading_rad?, surge_mps?, sway_mps?, yaw_rate_radps?}
    tau_b?, tau_achieved_b?, shortfall_b?: {x_n?, y_n?, n_nm?}
    mrac?: {mass: {surge_kg?, sway_kg?, yaw_kgm2?}, damping: {surge_kgps?, sway_kgps?, yaw_kgm2ps?},
            nominal: {surge_kg?, sway_kg?, yaw_kgm2?}, ratio: {surge?, sway?, yaw?},   mass / nominal [-]
            state: {surge, sway, yaw}}   adapting | frozen | suspended | off; these three may be absent

``dpcontrol.status/1``::

    mode: str
    sensors: [{name, kind, state (ok|stale|frozen|rejected|invalid|disconnected), age_s?, weight?, detail}]
    alarms: [{code, severity (info|warning|alarm|critical), text, since_t_s?, active}]
    cycle?: {period_s, duration_us?, p99_us?, missed_deadlines, host_steal_percent?}
    thrusters: [{name, available, detail}]
    request?: {seq, t_s, outcome (applied|refused), detail}   the last operator request taken
    requests?: [{seq, t_s, outcome, detail}]   every request taken in the last second, oldest first (≤ 16)
    consequence?: {t_s, demand_b: {x_n, y_n, n_nm}, groups: [{name, holds, utilisation?, busiest?}]}   worst case
    drives?: {present, seen, feedback_age_s?}   the plant/drives as the daemon sees them: their liveliness
                                                 token, and the age of the last thruster feedback it received
    adaptation?: {state: {surge, sway, yaw}, ratio: {surge?, sway?, yaw?}}   the MRAC's mass estimates in DP: what
                                                 each does and its ratio to nominal (absent: no MRAC, or standby)

``dpcontrol.setpoint/1`` (operator → daemon, ``dp/<vessel>/setpoint``) — see :func:`parse_setpoint`;
here ``?`` means the field may be left out (or be ``null``: not given)::

    mode?: "standby" | "auto_heading" | "auto_position"
    north_m?, east_m?            absolute NED position (both together)
    heading_deg? | heading_rad?  absolute heading (one of them)
    move_north_m?, move_east_m?  relative move in NED
    move_surge_m?, move_sway_m?  relative move along the current setpoint's heading (body axes)
    turn_deg? | turn_rad?        relative heading change (clockwise positive)
    reset_thruster?              a thruster whose latched failure the operator clears (repaired: readmitted)
    accept_reference?            a lone reference the prediction test rejects, taken as the truth now

``dpcontrol.config/1`` (reply of the ``dp/<vessel>/config`` queryable)::

    config: {...}  the running configuration as a JSON object
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Callable, Collection, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Final

import numpy as np

# the request and sea-state types are the controller's vocabulary (dpbase): this wire module parses into and
# encodes from them
from dpbase.frames import ssa
from dpbase.requests import RequestOutcome, SetpointRequest
from dpbase.sea_states import SEA_STATES_SEED001, SeaStateTable
from interfaces.messages import Rejected

# --------------------------------------------------------------------------------------------
# Vocabulary
# --------------------------------------------------------------------------------------------

MODES: tuple[str, ...] = ("standby", "auto_heading", "auto_position")
# what became of an operator request (the status's ``request.outcome``)
REQUEST_OUTCOMES: tuple[str, ...] = ("applied", "refused")
SENSOR_STATES: tuple[str, ...] = ("ok", "waiting", "stale", "frozen", "rejected", "isolated", "invalid",
                                  "disconnected")
SEVERITIES: tuple[str, ...] = ("info", "warning", "alarm", "critical")
BIAS_FRAMES: tuple[str, ...] = ("ned", "body")
#: What an MRAC inertia estimate is doing, per DOF (``control.mrac.state``, ``status.adaptation.state``): moved by the
#: law lately, held for want of excitation, stopped by the supervision (alarm ``control.adaptation``), configured off.
#: The controller's :data:`dpcontrol.control.base.ADAPTATION_STATES` (a test keeps the two equal).
ADAPTATION_STATES: tuple[str, ...] = ("adapting", "frozen", "suspended", "off")

#: Every ``Rejected.reason`` a parser here can return.
REJECT_REASONS: frozenset[str] = frozenset({
    "wrong_type",        # payload or field of the wrong JSON type
    "too_long",          # payload larger than the schema's limit
    "not_utf8",
    "not_json",
    "too_deep",          # nesting beyond what the parser accepts
    "not_object",        # top level is not a JSON object
    "duplicate_field",   # the same key twice in one object
    "missing_field",
    "unknown_field",     # a key the schema does not have (typos must not pass silently)
    "wrong_schema",      # a different schema name
    "unsupported_version",
    "not_finite",        # NaN / Infinity
    "out_of_range",
    "bad_value",         # not one of the allowed words / pattern
    "too_many",
    "too_few",
    "duplicate",         # e.g. two thrusters with the same name
    "length_mismatch",   # e.g. weights and omegas of different lengths
    "conflict",          # mutually exclusive fields (heading_deg and heading_rad ...)
    "incomplete",        # fields that go together (north_m without east_m)
    "empty",             # a request that asks for nothing
    "unknown_thruster",
})

_MAX_FORCE_N: Final = 1.0e9       # sanity bound for forces/moments in any message [N], [N·m]
_MAX_THRUST_N: Final = 1.0e8      # sanity bound for one thruster [N]
_MAX_POSITION_M: Final = 1.0e7    # sanity bound for NED positions in daemon output [m]
_MAX_SPEED_MPS: Final = 100.0
_MAX_RATE_RADPS: Final = 10.0
_ANGLE_LIMIT_RAD: Final = 2.0 * math.pi + 1e-9
_MAX_TIME_S: Final = 1.0e10       # covers monotonic clocks and Unix time
_MAX_SEQ: Final = 2**63 - 1
_IDENT: Final = r"[A-Za-z0-9_.:-]+"
_isfinite = math.isfinite


# --------------------------------------------------------------------------------------------
# Declarative validation
# --------------------------------------------------------------------------------------------

Path = tuple[str | int, ...]


def _where(path: Path) -> str:
    """``("thrusters", 2, "thrust_n") -> "thrusters[2].thrust_n"`` (built only when reporting an error)."""
    out = ""
    for part in path:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else str(part))
    return out or "payload"


class _InvalidError(Exception):
    """Internal: a validation failure with a reason token and a field path."""

    def __init__(self, reason: str, path: Path, message: str) -> None:
        detail = f"{_where(path)}: {message}"
        super().__init__(detail)
        self.reason = reason
        self.detail = detail


def _type_name(value: object) -> str:
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "a boolean"
    if isinstance(value, (int, float)):
        return "a number"
    if isinstance(value, str):
        return "a string"
    if isinstance(value, list):
        return "a list"
    if isinstance(value, dict):
        return "an object"
    return type(value).__name__


def _show(value: object) -> str:
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


class Spec:
    """A field of a schema: ``check(value, path)`` returns the normalised value or raises.

    ``path`` is the field's key path as a tuple; it is formatted only when reporting an error, so
    validating a good message costs no string building.
    """

    nullable: bool = False

    def check(self, value: Any, path: Path) -> Any:  # pragma: no cover - abstract
        raise NotImplementedError


class Number(Spec):
    """A finite JSON number in ``[minimum, maximum]`` (booleans are not numbers); returns float."""

    __slots__ = ("maximum", "minimum", "nullable")

    def __init__(self, minimum: float = -math.inf, maximum: float = math.inf, *, nullable: bool = False) -> None:
        self.minimum = minimum
        self.maximum = maximum
        self.nullable = nullable

    def check(self, value: Any, path: Path) -> float | None:
        kind = type(value)
        if kind is float:  # the common case first
            number = value
        elif kind is int:
            try:
                number = float(value)
            except OverflowError:  # a huge JSON integer
                raise _InvalidError("out_of_range", path, "number too large") from None
        elif value is None and self.nullable:
            return None
        else:
            raise _InvalidError("wrong_type", path, f"expected a number, got {_type_name(value)}")
        if not self.minimum <= number <= self.maximum:
            if not math.isfinite(number):
                raise _InvalidError("not_finite", path, f"expected a finite number, got {number!r}")
            raise _InvalidError("out_of_range", path, f"{number:g} outside [{self.minimum:g}, {self.maximum:g}]")
        if not _isfinite(number):  # ±inf with infinite bounds
            raise _InvalidError("not_finite", path, f"expected a finite number, got {number!r}")
        return number


class Integer(Spec):
    """A JSON integer in ``[minimum, maximum]``; returns int."""

    __slots__ = ("maximum", "minimum")

    def __init__(self, minimum: int = 0, maximum: int = _MAX_SEQ) -> None:
        self.minimum = minimum
        self.maximum = maximum

    def check(self, value: Any, path: Path) -> int:
        if type(value) is not int:
            raise _InvalidError("wrong_type", path, f"expected an integer, got {_type_name(value)}")
        if value < self.minimum or value > self.maximum:
            raise _InvalidError("out_of_range", path, f"{value} outside [{self.minimum}, {self.maximum}]")
        return value


class Text(Spec):
    """A string: one of ``choices``, or matching ``pattern`` (full match), at most ``max_len`` long."""

    __slots__ = ("choices", "max_len", "nullable", "pattern")

    def __init__(self, *, choices: Collection[str] | None = None, pattern: str | None = None, max_len: int = 64,
                 nullable: bool = False) -> None:
        self.choices = frozenset(choices) if choices is not None else None
        self.pattern = re.compile(pattern) if pattern is not None else None
        self.max_len = max_len
        self.nullable = nullable

    def check(self, value: Any, path: Path) -> str | None:
        if type(value) is not str:
            if value is None and self.nullable:
                return None
            raise _InvalidError("wrong_type", path, f"expected a string, got {_type_name(value)}")
        if len(value) > self.max_len:
            raise _InvalidError("out_of_range", path, f"string longer than {self.max_len} characters")
        if self.choices is not None and value not in self.choices:
            raise _InvalidError("bad_value", path,
                                f"expected one of {', '.join(sorted(self.choices))}, got {_show(value)}")
        if self.pattern is not None and self.pattern.fullmatch(value) is None:
            raise _InvalidError("bad_value", path, f"{_show(value)} does not match {self.pattern.pattern}")
        return value


class Flag(Spec):
    """A JSON boolean."""

    def check(self, value: Any, path: Path) -> bool:
        if type(value) is not bool:
            raise _InvalidError("wrong_type", path, f"expected true or false, got {_type_name(value)}")
        return value


class AnyObject(Spec):
    """Any JSON object (already free of NaN by the decoder); returned as is."""

    def check(self, value: Any, path: Path) -> dict[str, Any]:
        if type(value) is not dict:
            raise _InvalidError("wrong_type", path, f"expected an object, got {_type_name(value)}")
        return value


class Record(Spec):
    """A JSON object with known fields; unknown fields are rejected (a typo must not pass silently).

    Parameters
    ----------
    fields : mapping of str to Spec
    optional : collection of str
        Fields that may be absent (absent → ``None`` in the result).
    nullable : bool
        The whole record may be ``null``.
    """

    __slots__ = ("fields", "items", "nullable", "optional")

    def __init__(self, fields: Mapping[str, Spec], *, optional: Collection[str] = (), nullable: bool = False) -> None:
        self.fields = dict(fields)
        self.items = tuple(self.fields.items())
        self.optional = frozenset(optional)
        self.nullable = nullable

    def check(self, value: Any, path: Path) -> dict[str, Any] | None:
        if type(value) is not dict:
            if value is None and self.nullable:
                return None
            raise _InvalidError("wrong_type", path, f"expected an object, got {_type_name(value)}")
        fields = self.fields
        if len(value) > len(fields) or not all(key in fields for key in value):
            unknown = next(key for key in value if key not in fields)
            raise _InvalidError("unknown_field", (*path, unknown), f"unknown field (expected {', '.join(fields)})")
        out: dict[str, Any] = {}
        for key, spec in self.items:
            if key in value:
                out[key] = spec.check(value[key], (*path, key))
            elif key in self.optional:
                out[key] = None
            else:
                raise _InvalidError("missing_field", (*path, key), "missing")
        return out


class Array(Spec):
    """A JSON list of ``item``, ``min_len``..``max_len`` long; ``unique`` names a field that must differ."""

    __slots__ = ("item", "max_len", "min_len", "nullable", "unique")

    def __init__(self, item: Spec, *, min_len: int = 0, max_len: int = 64, unique: str | None = None,
                 nullable: bool = False) -> None:
        self.item = item
        self.min_len = min_len
        self.max_len = max_len
        self.unique = unique
        self.nullable = nullable

    def check(self, value: Any, path: Path) -> list[Any] | None:
        if type(value) is not list:
            if value is None and self.nullable:
                return None
            raise _InvalidError("wrong_type", path, f"expected a list, got {_type_name(value)}")
        if len(value) > self.max_len:
            raise _InvalidError("too_many", path, f"{len(value)} items, at most {self.max_len}")
        if len(value) < self.min_len:
            raise _InvalidError("too_few", path, f"{len(value)} items, at least {self.min_len}")
        check = self.item.check
        out = [check(element, (*path, i)) for i, element in enumerate(value)]
        if self.unique is not None:
            seen: set[Any] = set()
            for i, element in enumerate(out):
                key = element[self.unique]
                if key in seen:
                    raise _InvalidError("duplicate", (*path, i, self.unique), f"{_show(key)} appears twice")
                seen.add(key)
        return out


@dataclass(frozen=True)
class Schema:
    """One payload schema: name, version, body fields, size limit and cross-field checks."""

    name: str
    version: int
    body: Record
    max_bytes: int = 65_536
    cross_check: Callable[[dict[str, Any]], None] | None = None

    @property
    def id(self) -> str:
        """``"<name>/<version>"`` as written in the ``schema`` field."""
        return f"{self.name}/{self.version}"


# --------------------------------------------------------------------------------------------
# The schemas
# --------------------------------------------------------------------------------------------

_NAME = Text(pattern=_IDENT, max_len=64)
_AZIMUTH = Number(-_ANGLE_LIMIT_RAD, _ANGLE_LIMIT_RAD)


def _pose(nullable: bool = True) -> Record:
    return Record({"north_m": Number(-_MAX_POSITION_M, _MAX_POSITION_M, nullable=True),
                   "east_m": Number(-_MAX_POSITION_M, _MAX_POSITION_M, nullable=True),
                   "heading_rad": Number(-_ANGLE_LIMIT_RAD, _ANGLE_LIMIT_RAD, nullable=True)}, nullable=nullable)


def _force() -> Record:
    return Record({"x_n": Number(-_MAX_FORCE_N, _MAX_FORCE_N, nullable=True),
                   "y_n": Number(-_MAX_FORCE_N, _MAX_FORCE_N, nullable=True),
                   "n_nm": Number(-_MAX_FORCE_N, _MAX_FORCE_N, nullable=True)}, nullable=True)


def _velocity_fields() -> dict[str, Spec]:
    return {"surge_mps": Number(-_MAX_SPEED_MPS, _MAX_SPEED_MPS, nullable=True),
            "sway_mps": Number(-_MAX_SPEED_MPS, _MAX_SPEED_MPS, nullable=True),
            "yaw_rate_radps": Number(-_MAX_RATE_RADPS, _MAX_RATE_RADPS, nullable=True)}


def _positive(nullable: bool = True) -> Number:
    return Number(0.0, 1e12, nullable=nullable)


def _check_mmae(body: dict[str, Any]) -> None:
    omegas, weights = body["omegas_rad_s"], body["weights"]
    if len(omegas) != len(weights):
        raise _InvalidError("length_mismatch", ("weights",), f"{len(weights)} values for {len(omegas)} models")
    total = math.fsum(weights)
    if abs(total - 1.0) > 1e-3:
        raise _InvalidError("out_of_range", ("weights",), f"sum to {total:.6g}, expected 1")


COMMAND = Schema("dpcontrol.thrusters.command", 1, Record({
    "mode": Text(choices=MODES),
    "thrusters": Array(Record({"name": _NAME, "thrust_n": Number(-_MAX_THRUST_N, _MAX_THRUST_N),
                               "azimuth_rad": _AZIMUTH, "enabled": Flag()}), unique="name"),
}), max_bytes=16_384)

FEEDBACK = Schema("dpcontrol.thrusters.feedback", 1, Record({
    "thrusters": Array(Record({"name": _NAME, "thrust_n": Number(-_MAX_THRUST_N, _MAX_THRUST_N, nullable=True),
                               "azimuth_rad": Number(-_ANGLE_LIMIT_RAD, _ANGLE_LIMIT_RAD, nullable=True),
                               "ready": Flag()}), min_len=1, unique="name"),
}), max_bytes=16_384)

ESTIMATE = Schema("dpcontrol.estimate", 1, Record({
    "estimator": Text(pattern=_IDENT, max_len=32),
    "pose_n": _pose(),
    "velocity_b": Record(_velocity_fields(), nullable=True),
    "bias": Record({"frame": Text(choices=BIAS_FRAMES),
                    "x_n": Number(-_MAX_FORCE_N, _MAX_FORCE_N, nullable=True),
                    "y_n": Number(-_MAX_FORCE_N, _MAX_FORCE_N, nullable=True),
                    "n_nm": Number(-_MAX_FORCE_N, _MAX_FORCE_N, nullable=True)}, nullable=True),
    "wave_n": _pose(),
    "covariance_diag": Array(Number(0.0, math.inf, nullable=True), max_len=256, nullable=True),
}))

MMAE = Schema("dpcontrol.mmae", 1, Record({
    "omegas_rad_s": Array(Number(0.0, 100.0), min_len=1, max_len=64),
    "weights": Array(Number(0.0, 1.0), min_len=1, max_len=64),
    "omega_hat_rad_s": Number(0.0, 100.0, nullable=True),
    "sea_state": Text(pattern=_IDENT, max_len=32, nullable=True),
}), cross_check=_check_mmae)

# an MRAC estimate against nominal [-] (its projection keeps it within [0.3, 5] by default) and what it does, per DOF
_ADAPTATION_RATIO = Record({dof: Number(0.0, 1e6, nullable=True) for dof in ("surge", "sway", "yaw")})
_ADAPTATION_STATE = Record({dof: Text(choices=ADAPTATION_STATES) for dof in ("surge", "sway", "yaw")})

CONTROL = Schema("dpcontrol.control", 1, Record({
    "controller": Text(pattern=_IDENT, max_len=32),
    "setpoint": _pose(),
    "reference": Record({**_pose().fields, **_velocity_fields()}, nullable=True),
    "tau_b": _force(),
    "tau_achieved_b": _force(),
    "shortfall_b": _force(),
    "mrac": Record({
        "mass": Record({"surge_kg": _positive(), "sway_kg": _positive(), "yaw_kgm2": _positive()}),
        "damping": Record({"surge_kgps": _positive(), "sway_kgps": _positive(), "yaw_kgm2ps": _positive()}),
        # added in version 1 (optional: a publisher from before them stays valid)
        "nominal": Record({"surge_kg": _positive(), "sway_kg": _positive(), "yaw_kgm2": _positive()}),
        "ratio": _ADAPTATION_RATIO,
        "state": _ADAPTATION_STATE,
    }, optional=("nominal", "ratio", "state"), nullable=True),
}))

_REQUEST_OUTCOME = Record({"seq": Integer(0, _MAX_SEQ), "t_s": Number(0.0, _MAX_TIME_S),
                           "outcome": Text(choices=REQUEST_OUTCOMES), "detail": Text(max_len=256),
                           "role": Text(max_len=32), "identity": Text(max_len=128)},
                          optional=("role", "identity"))

STATUS = Schema("dpcontrol.status", 1, Record({
    "mode": Text(pattern=_IDENT, max_len=32),
    "sensors": Array(Record({"name": _NAME, "kind": Text(pattern=_IDENT, max_len=32),
                             "state": Text(choices=SENSOR_STATES), "age_s": Number(0.0, _MAX_TIME_S, nullable=True),
                             "weight": Number(0.0, 1.0, nullable=True), "detail": Text(max_len=256)}),
                     unique="name"),
    "alarms": Array(Record({"code": Text(pattern=_IDENT, max_len=64), "severity": Text(choices=SEVERITIES),
                            "text": Text(max_len=256), "since_t_s": Number(0.0, _MAX_TIME_S, nullable=True),
                            "active": Flag()}), max_len=256),
    "cycle": Record({"period_s": Number(0.0, 3600.0), "duration_us": Number(0.0, 1e12, nullable=True),
                     "p99_us": Number(0.0, 1e12, nullable=True), "missed_deadlines": Integer(),
                     "host_steal_percent": Number(0.0, 100.0, nullable=True)},
                    optional=("host_steal_percent",), nullable=True),
    "thrusters": Array(Record({"name": _NAME, "available": Flag(), "detail": Text(max_len=256)}), unique="name"),
    "request": _REQUEST_OUTCOME,
    "requests": Array(_REQUEST_OUTCOME, max_len=16),
    "consequence": Record({"t_s": Number(0.0, _MAX_TIME_S), "demand_b": _force(),
                           "groups": Array(Record({"name": _NAME, "holds": Flag(),
                                                   "utilisation": Number(0.0, 1e6, nullable=True),
                                                   "busiest": _NAME}, optional=("busiest",)),
                                           unique="name", max_len=64)}),
    "drives": Record({"present": Flag(), "seen": Flag(), "feedback_age_s": Number(0.0, _MAX_TIME_S, nullable=True)}),
    "wave_band": Record({"force_n": Number(0.0, _MAX_FORCE_N), "moment_nm": Number(0.0, _MAX_FORCE_N),
                         "lf_position_m": Number(0.0, 1e6), "lf_heading_deg": Number(0.0, 360.0)}),
    "adaptation": Record({"state": _ADAPTATION_STATE, "ratio": _ADAPTATION_RATIO}),
}, optional=("request", "requests", "consequence", "drives", "wave_band", "adaptation")))

SETPOINT = Schema("dpcontrol.setpoint", 1, Record({
    "mode": Text(choices=MODES, nullable=True),
    "north_m": Number(nullable=True), "east_m": Number(nullable=True),
    "heading_deg": Number(-360.0, 360.0, nullable=True),
    "heading_rad": Number(-_ANGLE_LIMIT_RAD, _ANGLE_LIMIT_RAD, nullable=True),
    "move_north_m": Number(nullable=True), "move_east_m": Number(nullable=True),
    "move_surge_m": Number(nullable=True), "move_sway_m": Number(nullable=True),
    "turn_deg": Number(-360.0, 360.0, nullable=True),
    "turn_rad": Number(-_ANGLE_LIMIT_RAD, _ANGLE_LIMIT_RAD, nullable=True),
    "reset_thruster": Text(pattern=_IDENT, max_len=64, nullable=True),
    "accept_reference": Text(pattern=_IDENT, max_len=64, nullable=True),
}, optional=("mode", "north_m", "east_m", "heading_deg", "heading_rad", "move_north_m", "move_east_m",
             "move_surge_m", "move_sway_m", "turn_deg", "turn_rad", "reset_thruster", "accept_reference")),
                  max_bytes=4_096)

CONFIG = Schema("dpcontrol.config", 1, Record({"config": AnyObject()}), max_bytes=1_048_576)

#: Schema of each topic (keys of :class:`interfaces.zenoh.keys.VesselKeys`) and of the config reply.
SCHEMAS: dict[str, Schema] = {"command": COMMAND, "feedback": FEEDBACK, "estimate": ESTIMATE, "mmae": MMAE,
                              "control": CONTROL, "status": STATUS, "setpoint": SETPOINT, "config": CONFIG}

_ENVELOPE_T = Number(0.0, _MAX_TIME_S)
_ENVELOPE_SEQ = Integer(0, _MAX_SEQ)


# --------------------------------------------------------------------------------------------
# Decoding
# --------------------------------------------------------------------------------------------

def _reject_constant(name: str) -> Any:
    raise _InvalidError("not_finite", (), f"{name} is not a finite number (JSON has no NaN/Infinity)")


def _no_duplicates(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    out = dict(pairs)
    if len(out) != len(pairs):
        seen: set[str] = set()
        for key, _ in pairs:
            if key in seen:
                raise _InvalidError("duplicate_field", (key,), "appears twice in one object")
            seen.add(key)
    return out


_DECODER = json.JSONDecoder(parse_constant=_reject_constant, object_pairs_hook=_no_duplicates)


def _decode(payload: object, schema: Schema) -> dict[str, Any]:
    """Bytes → validated, normalised dict (envelope + body), or raise :class:`_InvalidError`."""
    if isinstance(payload, str):
        payload = payload.encode("utf-8", "surrogatepass")
    if not isinstance(payload, (bytes, bytearray, memoryview)):
        raise _InvalidError("wrong_type", (), f"expected bytes, got {type(payload).__name__}")
    raw = bytes(payload)
    if len(raw) > schema.max_bytes:
        raise _InvalidError("too_long", (), f"{len(raw)} bytes, at most {schema.max_bytes} for {schema.id}")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise _InvalidError("not_utf8", (), f"not UTF-8 ({exc.reason} at byte {exc.start})") from None
    try:
        data = _DECODER.decode(text)
    except RecursionError:
        raise _InvalidError("too_deep", (), "nested too deeply") from None
    except ValueError as exc:  # json.JSONDecodeError and int-size limits
        raise _InvalidError("not_json", (), f"not JSON ({str(exc)[:80]})") from None
    if not isinstance(data, dict):
        raise _InvalidError("not_object", (), f"expected a JSON object, got {_type_name(data)}")
    if "schema" not in data:
        raise _InvalidError("missing_field", ("schema",), f"missing (expected {schema.id!r})")
    tag = data["schema"]
    if not isinstance(tag, str):
        raise _InvalidError("wrong_type", ("schema",), f"expected a string, got {_type_name(tag)}")
    if tag != schema.id:
        name = tag.rsplit("/", 1)[0]
        if name == schema.name:
            raise _InvalidError("unsupported_version", ("schema",),
                                f"{_show(tag)} is not supported (expected {schema.id!r})")
        raise _InvalidError("wrong_schema", ("schema",), f"expected {schema.id!r}, got {_show(tag)}")
    if "t_s" not in data:
        raise _InvalidError("missing_field", ("t_s",), "missing")
    if "seq" not in data:
        raise _InvalidError("missing_field", ("seq",), "missing")
    t_s = _ENVELOPE_T.check(data["t_s"], ("t_s",))
    seq = _ENVELOPE_SEQ.check(data["seq"], ("seq",))
    body = {key: value for key, value in data.items() if key not in ("schema", "t_s", "seq")}
    out = schema.body.check(body, ())
    assert out is not None
    if schema.cross_check is not None:
        schema.cross_check(out)
    out["schema"] = tag
    out["t_s"] = t_s
    out["seq"] = seq
    return out


def _rejected(exc: _InvalidError, payload: object) -> Rejected:
    raw = payload if isinstance(payload, bytes) else b""
    return Rejected(reason=exc.reason, detail=exc.detail, raw=raw[:256])


def parse_message(topic: str, payload: object) -> dict[str, Any] | Rejected:
    """Validate any payload against the schema of ``topic`` (a key of :data:`SCHEMAS`).

    Parameters
    ----------
    topic : str
        ``command``, ``feedback``, ``estimate``, ``mmae``, ``control``, ``status``, ``setpoint``
        or ``config``.
    payload : bytes
        The received bytes (``str`` is accepted and encoded as UTF-8).

    Returns
    -------
    dict or Rejected
        The normalised content (numbers as float, absent optional fields as ``None``, envelope
        fields ``schema``, ``t_s``, ``seq`` included), or why it was refused. Never raises.
    """
    schema = SCHEMAS.get(topic)
    if schema is None:
        return Rejected(reason="wrong_schema", detail=f"unknown topic {topic!r}")
    try:
        return _decode(payload, schema)
    except _InvalidError as exc:
        return _rejected(exc, payload)


# --------------------------------------------------------------------------------------------
# Typed messages for the inputs that drive actions
# --------------------------------------------------------------------------------------------

@dataclass(frozen=True, slots=True)
class ThrusterSetpoint:
    """One thruster in a command: thrust [N] and angle [rad] (body frame, clockwise from the bow)."""

    name: str
    thrust_n: float
    azimuth_rad: float
    enabled: bool


@dataclass(frozen=True, slots=True)
class CommandMessage:
    """A validated ``dpcontrol.thrusters.command/1``."""

    t_s: float
    seq: int
    mode: str
    thrusters: tuple[ThrusterSetpoint, ...]


@dataclass(frozen=True, slots=True)
class ThrusterReadback:
    """One thruster in a feedback message: delivered thrust [N] and angle [rad], ``None`` if unknown."""

    name: str
    thrust_n: float | None
    azimuth_rad: float | None
    ready: bool


@dataclass(frozen=True, slots=True)
class FeedbackMessage:
    """A validated ``dpcontrol.thrusters.feedback/1``."""

    t_s: float
    seq: int
    thrusters: tuple[ThrusterReadback, ...]


@dataclass(frozen=True, slots=True)
class SetpointLimits:
    """Range limits an operator setpoint must respect.

    Attributes
    ----------
    max_offset_m : float
        Largest absolute north/east distance from the datum [m].
    max_move_m : float
        Largest relative move in one request, per axis [m].
    """

    max_offset_m: float = 10_000.0
    max_move_m: float = 1_000.0


def parse_command(payload: object, *, thruster_names: Collection[str] | None = None) -> CommandMessage | Rejected:
    """Validate a thruster command (as the drives/plant receive it).

    Parameters
    ----------
    payload : bytes
    thruster_names : collection of str, optional
        The drives' thrusters; a command naming another thruster is rejected (``unknown_thruster``).

    Returns
    -------
    CommandMessage or Rejected
        Angles wrapped to (−π, π]. Never raises.
    """
    result = parse_message("command", payload)
    if isinstance(result, Rejected):
        return result
    entries = []
    for i, item in enumerate(result["thrusters"]):
        if thruster_names is not None and item["name"] not in thruster_names:
            return Rejected("unknown_thruster", f"thrusters[{i}].name: {item['name']!r} is not a known thruster",
                            bytes(payload)[:256] if isinstance(payload, bytes) else b"")
        entries.append(ThrusterSetpoint(item["name"], item["thrust_n"], ssa(item["azimuth_rad"]), item["enabled"]))
    return CommandMessage(result["t_s"], result["seq"], result["mode"], tuple(entries))


def parse_feedback(payload: object, *, thruster_names: Collection[str] | None = None) -> FeedbackMessage | Rejected:
    """Validate thruster feedback from the drives (drives → daemon).

    Parameters
    ----------
    payload : bytes
    thruster_names : collection of str, optional
        The configured thrusters; feedback about another thruster is rejected (``unknown_thruster``).
        A message may cover a subset (one drive controller per thruster is fine).

    Returns
    -------
    FeedbackMessage or Rejected
        Angles wrapped to (−π, π]. Never raises.
    """
    result = parse_message("feedback", payload)
    if isinstance(result, Rejected):
        return result
    entries = []
    for i, item in enumerate(result["thrusters"]):
        if thruster_names is not None and item["name"] not in thruster_names:
            return Rejected("unknown_thruster", f"thrusters[{i}].name: {item['name']!r} is not a known thruster",
                            bytes(payload)[:256] if isinstance(payload, bytes) else b"")
        azimuth = item["azimuth_rad"]
        entries.append(ThrusterReadback(item["name"], item["thrust_n"], None if azimuth is None else ssa(azimuth),
                                        item["ready"]))
    return FeedbackMessage(result["t_s"], result["seq"], tuple(entries))


def parse_setpoint(payload: object, *, limits: SetpointLimits = SetpointLimits()) -> SetpointRequest | Rejected:  # noqa: PLR0911 - one return per refusal reason
    """Validate an operator setpoint request.

    Accepted forms (all with the envelope ``schema``/``t_s``/``seq``):

    * absolute: ``{"north_m": 10, "east_m": -5, "heading_deg": 90}`` (position and/or heading);
    * relative: ``{"move_surge_m": 5}``, ``{"move_north_m": 2, "move_east_m": 1}``, ``{"turn_deg": -10}``;
    * mode only: ``{"mode": "auto_position"}``; ``mode`` may accompany any of the above;
    * a thruster's latched failure cleared: ``{"reset_thruster": "bow_tunnel_1"}`` (alone or with the above);
    * a lone reference accepted as the truth: ``{"accept_reference": "gnss1"}`` (alone or with the above).

    Rules: ``north_m`` and ``east_m`` together (``incomplete`` otherwise); at most one of
    ``heading_deg``/``heading_rad`` and of ``turn_deg``/``turn_rad``; no absolute position with a
    translational move, no absolute heading with a turn (``conflict``); something must be asked
    (``empty``); positions within ``limits.max_offset_m`` of the datum, moves within
    ``limits.max_move_m`` (``out_of_range``). Never raises.
    """
    result = parse_message("setpoint", payload)
    if isinstance(result, Rejected):
        return result
    raw = bytes(payload)[:256] if isinstance(payload, bytes) else b""
    r = result

    def reject(reason: str, detail: str) -> Rejected:
        return Rejected(reason, detail, raw)

    if (r["north_m"] is None) != (r["east_m"] is None):
        return reject("incomplete", "north_m and east_m: give both or neither")
    if r["heading_deg"] is not None and r["heading_rad"] is not None:
        return reject("conflict", "heading_deg and heading_rad: give one")
    if r["turn_deg"] is not None and r["turn_rad"] is not None:
        return reject("conflict", "turn_deg and turn_rad: give one")
    moves = ("move_north_m", "move_east_m", "move_surge_m", "move_sway_m")
    moving = [key for key in moves if r[key] is not None]
    if r["north_m"] is not None and moving:
        return reject("conflict", f"north_m/east_m with {moving[0]}: absolute and relative position in one request")
    heading = r["heading_rad"] if r["heading_deg"] is None else math.radians(r["heading_deg"])
    turn = r["turn_rad"] if r["turn_deg"] is None else math.radians(r["turn_deg"])
    if heading is not None and turn is not None:
        return reject("conflict", "heading and turn in one request")
    for key in ("north_m", "east_m"):
        if r[key] is not None and abs(r[key]) > limits.max_offset_m:
            return reject("out_of_range",
                          f"{key}: {r[key]:g} m is farther than {limits.max_offset_m:g} m from the datum")
    for key in moving:
        if abs(r[key]) > limits.max_move_m:
            return reject("out_of_range", f"{key}: {r[key]:g} m is more than {limits.max_move_m:g} m in one request")
    request = SetpointRequest(
        t_s=r["t_s"], seq=r["seq"], mode=r["mode"], north_m=r["north_m"], east_m=r["east_m"],
        heading_rad=None if heading is None else ssa(heading),
        move_north_m=r["move_north_m"], move_east_m=r["move_east_m"], move_surge_m=r["move_surge_m"],
        move_sway_m=r["move_sway_m"], turn_rad=turn, reset_thruster=r["reset_thruster"],
        accept_reference=r["accept_reference"])
    if request.mode is None and not request.changes_pose and request.reset_thruster is None \
            and request.accept_reference is None:
        return reject("empty", "request asks for nothing: give a mode, a position, a heading, a move, a thruster "
                               "to reset or a reference to accept")
    return request


# --------------------------------------------------------------------------------------------
# Builders (hot path: plain dicts of floats, one encode)
# --------------------------------------------------------------------------------------------

# Encoding is most of a builder's cost: the standard library spends ~0.3 µs formatting each float
# (30 floats ≈ 10 µs), orjson ~20× less. orjson already comes with the nmea2000 dependency; the
# standard library stays as the fallback. Both write the same JSON (shortest round-trip floats).
# allow_nan=False is a last guard: builders turn non-finite floats into None before encoding.
_STDLIB_ENCODER = json.JSONEncoder(separators=(",", ":"), allow_nan=False, ensure_ascii=False)


def _encode_stdlib(obj: dict[str, Any]) -> bytes:
    return _STDLIB_ENCODER.encode(obj).encode("utf-8")


_encode: Callable[[dict[str, Any]], bytes]
try:
    import orjson
except ImportError:  # pragma: no cover - orjson comes with nmea2000
    _encode = _encode_stdlib
else:
    _encode = orjson.dumps


def _num(value: Any) -> float | None:
    """A float, or None for None/NaN/inf (missing data is None, never NaN)."""
    if value is None:
        return None
    x = float(value)
    return x if _isfinite(x) else None


def _floats(values: Any) -> list[float | None]:
    """A 1-D list of floats with non-finite values as None (accepts numpy arrays, lists, tuples)."""
    return [x if _isfinite(x) else None for x in np.asarray(values, dtype=float).ravel().tolist()]


def _vec3(values: Any, names: tuple[str, str, str]) -> dict[str, float | None] | None:
    if values is None:
        return None
    a, b, c = _floats(values)
    return {names[0]: a, names[1]: b, names[2]: c}


def _pose_dict(values: Any) -> dict[str, float | None] | None:
    if values is None:
        return None
    north, east, heading = _floats(values)
    return {"north_m": north, "east_m": east, "heading_rad": None if heading is None else ssa(heading)}


_FORCE = ("x_n", "y_n", "n_nm")


def command_payload(*, t_s: float, seq: int, mode: str, names: Sequence[str], thrust_n: Any, azimuth_rad: Any,
                    enabled: Sequence[bool] | np.ndarray | None = None) -> bytes:
    """Encode a thruster command (daemon → drives).

    Parameters
    ----------
    t_s : float
        Daemon clock [s].
    seq : int
        Publisher counter.
    mode : {"standby", "auto_heading", "auto_position"}
    names : sequence of str, length m
        Thruster names (as in the vessel's ThrusterSpec).
    thrust_n : array_like, shape (m,)
        Commanded thrust along each thruster's force direction [N].
    azimuth_rad : array_like, shape (m,)
        Azimuth / rudder / fixed angle, body frame, clockwise from the bow [rad]; wrapped with ssa.
    enabled : sequence of bool, optional
        Default all True.

    Raises
    ------
    ValueError
        Unknown mode, mismatched lengths, or a non-finite thrust/angle: a command with NaN is a bug
        upstream and must not reach the drives (they would reject it anyway).
    """
    if mode not in MODES:
        raise ValueError(f"command mode must be one of {', '.join(MODES)}, got {mode!r}")
    thrust = np.asarray(thrust_n, dtype=float).ravel().tolist()
    azimuth = np.asarray(azimuth_rad, dtype=float).ravel().tolist()
    flags = [True] * len(names) if enabled is None else [bool(e) for e in enabled]
    if not len(names) == len(thrust) == len(azimuth) == len(flags):
        raise ValueError(f"command: {len(names)} names, {len(thrust)} thrusts, {len(azimuth)} angles, "
                         f"{len(flags)} enabled flags")
    thrusters = []
    for name, f, a, e in zip(names, thrust, azimuth, flags, strict=True):
        if not (_isfinite(f) and _isfinite(a)):
            raise ValueError(f"command for thruster {name}: non-finite thrust {f!r} or angle {a!r}")
        thrusters.append({"name": name, "thrust_n": f, "azimuth_rad": ssa(a), "enabled": e})
    return _encode({"schema": COMMAND.id, "t_s": float(t_s), "seq": int(seq), "mode": mode,
                    "thrusters": thrusters})


def feedback_payload(*, t_s: float, seq: int, names: Sequence[str], thrust_n: Any, azimuth_rad: Any,
                     ready: Sequence[bool]) -> bytes:
    """Encode thruster feedback (drives/plant → daemon): delivered thrust [N], angle [rad], ready flag.

    Non-finite thrust or angle (a drive that cannot measure) becomes ``null``.
    """
    thrust = _floats(thrust_n)
    azimuth = [None if a is None else ssa(a) for a in _floats(azimuth_rad)]
    flags = [bool(r) for r in ready]
    if not len(names) == len(thrust) == len(azimuth) == len(flags):
        raise ValueError(f"feedback: {len(names)} names, {len(thrust)} thrusts, {len(azimuth)} angles, "
                         f"{len(flags)} ready flags")
    return _encode({"schema": FEEDBACK.id, "t_s": float(t_s), "seq": int(seq),
                    "thrusters": [{"name": n, "thrust_n": f, "azimuth_rad": a, "ready": r}
                                  for n, f, a, r in zip(names, thrust, azimuth, flags, strict=True)]})


def estimate_payload(*, t_s: float, seq: int, estimator: str, eta_ned: Any, nu_b: Any, bias: Any = None,
                     bias_frame: str = "ned", eta_wf_ned: Any = None, covariance_diag: Any = None) -> bytes:
    """Encode the state estimate.

    Parameters
    ----------
    estimator : str
        Estimator kind (``mmae``, ``kf``, ``rpem``, ``kalman_bucy``, ``raw`` ...).
    eta_ned : array_like, shape (3,) or None
        LF pose ``[north_m, east_m, psi_rad]`` (NED); heading wrapped with ssa.
    nu_b : array_like, shape (3,) or None
        LF body velocity ``[u_mps, v_mps, r_radps]``.
    bias : array_like, shape (3,), optional
        Bias force ``b`` [N, N, N·m] (seed 002), in ``bias_frame`` (``ned`` or ``body``).
    eta_wf_ned : array_like, shape (3,), optional
        WF motion estimate ``[north_m, east_m, psi_rad]``.
    covariance_diag : array_like, shape (n,), optional
        Diagonal of the error covariance, estimator state order.
    """
    if bias_frame not in BIAS_FRAMES:
        raise ValueError(f"bias_frame must be one of {', '.join(BIAS_FRAMES)}, got {bias_frame!r}")
    bias_dict = None
    if bias is not None:
        x, y, n = _floats(bias)
        bias_dict = {"frame": bias_frame, "x_n": x, "y_n": y, "n_nm": n}
    return _encode({
        "schema": ESTIMATE.id, "t_s": float(t_s), "seq": int(seq), "estimator": estimator,
        "pose_n": _pose_dict(eta_ned),
        "velocity_b": _vec3(nu_b, ("surge_mps", "sway_mps", "yaw_rate_radps")),
        "bias": bias_dict,
        "wave_n": _pose_dict(eta_wf_ned),
        "covariance_diag": None if covariance_diag is None else _floats(covariance_diag),
    })


def mmae_payload(*, t_s: float, seq: int, omegas_rad_s: Any, weights: Any, omega_hat_rad_s: float | None,
                 sea_states: SeaStateTable = SEA_STATES_SEED001) -> bytes:
    """Encode the MMAE bank state: model frequencies [rad/s], weights, ω̂ [rad/s] and its sea-state class.

    Parameters
    ----------
    omegas_rad_s, weights : array_like, shape (N,)
        Model peak frequencies and their (normalised) weights.
    omega_hat_rad_s : float or None
        Estimated peak frequency (e.g. weighted mean, seed 000).
    sea_states : SeaStateTable
        Classification boundaries (seed 001 Table I by default).
    """
    omega_hat = _num(omega_hat_rad_s)
    return _encode({"schema": MMAE.id, "t_s": float(t_s), "seq": int(seq), "omegas_rad_s": _floats(omegas_rad_s),
                    "weights": _floats(weights), "omega_hat_rad_s": omega_hat,
                    "sea_state": sea_states.classify(omega_hat)})


def control_payload(*, t_s: float, seq: int, controller: str, tau_b: Any, setpoint_ned: Any = None,  # noqa: PLR0913 - one keyword-only argument per field of the payload
                    reference_ned: Any = None, reference_nu_b: Any = None, tau_achieved_b: Any = None,
                    shortfall_b: Any = None, mrac_mass: Any = None, mrac_damping: Any = None,
                    mrac_nominal: Any = None, mrac_state: Sequence[str] | None = None) -> bytes:
    """Encode the controller state.

    Parameters
    ----------
    controller : str
        ``pid``, ``mrac`` ...
    tau_b : array_like, shape (3,) or None
        Commanded generalised force ``[X_n, Y_n, N_nm]`` (body).
    setpoint_ned, reference_ned : array_like, shape (3,), optional
        Operator setpoint and reference-model output ``[north_m, east_m, psi_rad]`` (NED).
    reference_nu_b : array_like, shape (3,), optional
        Reference velocity ``[u_mps, v_mps, r_radps]`` (body).
    tau_achieved_b : array_like, shape (3,), optional
        Force the allocation can deliver (body).
    shortfall_b : array_like, shape (3,), optional
        ``tau_b − tau_achieved_b``; computed when omitted and both are given.
    mrac_mass, mrac_damping : array_like, shape (3,), optional
        MRAC estimates of mass ``[kg, kg, kg·m²]`` and linear damping ``[kg/s, kg/s, kg·m²/s]``
        per DOF (seed 003); ``mrac`` is ``null`` when both are omitted.
    mrac_nominal : array_like, shape (3,), optional
        The nominal masses the estimates start from ``[kg, kg, kg·m²]``: with ``mrac_mass`` also their ratio
        (``mrac.nominal``, ``mrac.ratio``; absent when omitted).
    mrac_state : 3 str, optional
        What each mass estimate does, one of :data:`ADAPTATION_STATES` per DOF (``mrac.state``; absent when
        omitted).
    """
    reference = None
    if reference_ned is not None or reference_nu_b is not None:
        reference = _pose_dict(reference_ned) or {"north_m": None, "east_m": None, "heading_rad": None}
        reference.update(_vec3(reference_nu_b, ("surge_mps", "sway_mps", "yaw_rate_radps"))
                         or {"surge_mps": None, "sway_mps": None, "yaw_rate_radps": None})
    if shortfall_b is None and tau_b is not None and tau_achieved_b is not None:
        shortfall_b = np.asarray(tau_b, dtype=float) - np.asarray(tau_achieved_b, dtype=float)
    mrac: dict[str, Any] | None = None
    if mrac_mass is not None or mrac_damping is not None:
        mrac = {"mass": _vec3(mrac_mass, ("surge_kg", "sway_kg", "yaw_kgm2"))
                or {"surge_kg": None, "sway_kg": None, "yaw_kgm2": None},
                "damping": _vec3(mrac_damping, ("surge_kgps", "sway_kgps", "yaw_kgm2ps"))
                or {"surge_kgps": None, "sway_kgps": None, "yaw_kgm2ps": None}}
        if mrac_nominal is not None:
            mrac["nominal"] = _vec3(mrac_nominal, ("surge_kg", "sway_kg", "yaw_kgm2"))
            mrac["ratio"] = _adaptation_ratio(mrac_mass, mrac_nominal)
        if mrac_state is not None:
            mrac["state"] = _per_dof(mrac_state)
    return _encode({"schema": CONTROL.id, "t_s": float(t_s), "seq": int(seq), "controller": controller,
                    "setpoint": _pose_dict(setpoint_ned), "reference": reference,
                    "tau_b": _vec3(tau_b, _FORCE), "tau_achieved_b": _vec3(tau_achieved_b, _FORCE),
                    "shortfall_b": _vec3(shortfall_b, _FORCE), "mrac": mrac})


@dataclass(frozen=True, slots=True)
class SensorHealth:
    """One sensor line of the status message."""

    name: str
    kind: str
    state: str
    age_s: float | None = None
    weight: float | None = None
    detail: str = ""


@dataclass(frozen=True, slots=True)
class Alarm:
    """One alarm of the status message (``since_t_s`` on the daemon clock)."""

    code: str
    severity: str
    text: str
    since_t_s: float | None
    active: bool


@dataclass(frozen=True, slots=True)
class CycleTiming:
    """Control-loop timing: period [s], last duration and p99 [µs], missed deadlines (count), and the share of
    the CPUs the hypervisor gave to other guests lately [%] (0 on dedicated hardware; None: not known)."""

    period_s: float
    duration_us: float | None
    p99_us: float | None
    missed_deadlines: int
    host_steal_percent: float | None = None


@dataclass(frozen=True, slots=True)
class FailureGroupOutcome:
    """Whether the thrusters left after one failure group's loss would hold the demand, the largest thrust of
    those left as a share of its rating [-] (None: none left), and which thruster that is."""

    name: str
    holds: bool
    utilisation: float | None
    busiest: str | None = None


@dataclass(frozen=True, slots=True)
class WorstCaseCheck:
    """The last worst-case failure check (consequence analysis): when [s, controller clock], the demand checked
    ``(X [N], Y [N], N [N·m])`` in body axes, and each failure group's outcome."""

    t_s: float
    demand_b: tuple[float, float, float]
    groups: tuple[FailureGroupOutcome, ...]


@dataclass(frozen=True, slots=True)
class ThrusterAvailability:
    """Whether the allocation may use a thruster, and why not."""

    name: str
    available: bool
    detail: str = ""


@dataclass(frozen=True)
class DrivesSeen:
    """The thruster drives (or plant) as the daemon sees them: liveliness token ``present`` now, ever
    ``seen``, and ``feedback_age_s`` [s], the age of the last thruster feedback received (``None``: none yet)."""

    present: bool
    seen: bool
    feedback_age_s: float | None


@dataclass(frozen=True, slots=True)
class AdaptationSummary:
    """What the MRAC's mass estimates do, per DOF (surge, sway, yaw): one of :data:`ADAPTATION_STATES` each, and
    the estimate over its nominal value [-] (None: not a number)."""

    state: tuple[str, str, str]
    ratio: tuple[float | None, float | None, float | None]


def _per_dof(values: Sequence[Any]) -> dict[str, Any]:
    surge, sway, yaw = values
    return {"surge": surge, "sway": sway, "yaw": yaw}


def _adaptation_ratio(mass: Any, nominal: Any) -> dict[str, float | None]:
    """``mass / nominal`` per DOF (None where either is missing, not finite or the nominal not > 0)."""
    ratios: list[float | None] = []
    for m, n in zip(_floats(mass) if mass is not None else (None, None, None), _floats(nominal), strict=True):
        ratios.append(_num(m / n) if m is not None and n is not None and n > 0.0 else None)
    return _per_dof(ratios)


def status_payload(*, t_s: float, seq: int, mode: str, sensors: Sequence[SensorHealth] = (),  # noqa: PLR0913 - one keyword-only argument per field of the payload
                   alarms: Sequence[Alarm] = (), cycle: CycleTiming | None = None,
                   thrusters: Sequence[ThrusterAvailability] = (), request: RequestOutcome | None = None,
                   consequence: WorstCaseCheck | None = None, requests: Sequence[RequestOutcome] = (),
                   drives: DrivesSeen | None = None,
                   wave_band: Mapping[str, float] | None = None,
                   adaptation: AdaptationSummary | None = None) -> bytes:
    """Encode the daemon status: mode, per-sensor health, alarms, cycle timing, thruster availability, the
    outcome of the last operator request (``request``, absent before the first) and of each one taken lately
    (``requests``, oldest first, the last 16 at most; absent when none), and the last worst-case failure check
    (``consequence``, absent when none ran: not configured, or not in DP), and how much wave motion reaches
    the controller (``wave_band``: the wave-band std of the commanded horizontal force [N] and yaw moment [N·m]
    and of the LF position [m] and heading [deg] estimate; absent outside DP and in the first averaging time),
    and what the MRAC's mass estimates do (``adaptation``: per DOF the state and the ratio to nominal; absent
    without an MRAC and outside DP)."""
    extra: dict[str, Any] = {} if request is None else {"request": _request_outcome(request)}
    if drives is not None:
        extra["drives"] = {"present": bool(drives.present), "seen": bool(drives.seen),
                           "feedback_age_s": None if drives.feedback_age_s is None
                           else max(0.0, min(float(drives.feedback_age_s), _MAX_TIME_S))}
    if requests:
        extra["requests"] = [_request_outcome(outcome) for outcome in requests[-16:]]
    if consequence is not None:
        extra["consequence"] = {
            "t_s": float(consequence.t_s), "demand_b": _vec3(consequence.demand_b, _FORCE),
            "groups": [{"name": g.name, "holds": bool(g.holds), "utilisation": _num(g.utilisation),
                        **({} if g.busiest is None else {"busiest": g.busiest})} for g in consequence.groups]}
    if wave_band is not None:
        extra["wave_band"] = {"force_n": float(wave_band["force_n"]), "moment_nm": float(wave_band["moment_nm"]),
                              "lf_position_m": float(wave_band["lf_position_m"]),
                              "lf_heading_deg": math.degrees(float(wave_band["lf_heading_rad"]))}
    if adaptation is not None:
        extra["adaptation"] = {"state": _per_dof(adaptation.state),
                               "ratio": _per_dof([_num(r) for r in adaptation.ratio])}
    return _encode({
        "schema": STATUS.id, "t_s": float(t_s), "seq": int(seq), "mode": mode,
        "sensors": [{"name": s.name, "kind": s.kind, "state": s.state, "age_s": _num(s.age_s),
                     "weight": _num(s.weight), "detail": s.detail} for s in sensors],
        "alarms": [{"code": a.code, "severity": a.severity, "text": a.text, "since_t_s": _num(a.since_t_s),
                    "active": bool(a.active)} for a in alarms],
        "cycle": None if cycle is None else {
            "period_s": float(cycle.period_s), "duration_us": _num(cycle.duration_us),
            "p99_us": _num(cycle.p99_us), "missed_deadlines": int(cycle.missed_deadlines),
            "host_steal_percent": _num(cycle.host_steal_percent)},
        "thrusters": [{"name": t.name, "available": bool(t.available), "detail": t.detail} for t in thrusters],
        **extra,
    })


def _request_outcome(outcome: RequestOutcome) -> dict[str, Any]:
    by = {key: value[:128] for key, value in (("role", outcome.role), ("identity", outcome.identity)) if value}
    return {"seq": int(outcome.seq), "t_s": float(outcome.t_s), "outcome": outcome.outcome,
            "detail": outcome.detail[:256], **by}


def setpoint_payload(*, t_s: float, seq: int, mode: str | None = None, north_m: float | None = None,  # noqa: PLR0913 - one keyword-only argument per field of the payload
                     east_m: float | None = None, heading_deg: float | None = None, heading_rad: float | None = None,
                     move_north_m: float | None = None, move_east_m: float | None = None,
                     move_surge_m: float | None = None, move_sway_m: float | None = None,
                     turn_deg: float | None = None, turn_rad: float | None = None,
                     reset_thruster: str | None = None, accept_reference: str | None = None) -> bytes:
    """Encode an operator setpoint request (fields left ``None`` are omitted); see :func:`parse_setpoint`."""
    fields = {"mode": mode, "north_m": north_m, "east_m": east_m, "heading_deg": heading_deg,
              "heading_rad": heading_rad, "move_north_m": move_north_m, "move_east_m": move_east_m,
              "move_surge_m": move_surge_m, "move_sway_m": move_sway_m, "turn_deg": turn_deg, "turn_rad": turn_rad,
              "reset_thruster": reset_thruster, "accept_reference": accept_reference}
    body = {key: value for key, value in fields.items() if value is not None}
    return _encode({"schema": SETPOINT.id, "t_s": float(t_s), "seq": int(seq), **body})


def _jsonable(value: Any) -> Any:
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, (set, frozenset, tuple)):
        return list(value)
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")


def config_payload(*, t_s: float, seq: int, config: Mapping[str, Any]) -> bytes:
    """Encode the running configuration (reply of the config queryable).

    ``config`` is a JSON-able mapping (numpy arrays and tuples become lists).

    Raises
    ------
    ValueError
        The mapping holds NaN/inf or objects JSON cannot represent.
    """
    try:
        return json.dumps({"schema": CONFIG.id, "t_s": float(t_s), "seq": int(seq), "config": dict(config)},
                          separators=(",", ":"), allow_nan=False, default=_jsonable).encode("utf-8")
    except TypeError as exc:
        raise ValueError(f"config is not JSON serialisable: {exc}") from None
