"""Build a position controller from the ``control:`` section of a configuration (validated)."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from dpbase.schema import Section
from dpcontrol.control.autopilot import AutopilotConfig, AutopilotController, autopilot_config_from_mapping
from dpcontrol.control.base import PositionController
from dpcontrol.control.mrac import MracConfig, MracController, mrac_config_from_mapping
from dpcontrol.control.pid import PidConfig, PidController, pid_config_from_mapping
from dpcontrol.models.vessels import VesselData

ControlConfig = PidConfig | MracConfig | AutopilotConfig
"""A validated ``control:`` section of any kind."""

_Parser = Callable[[object, VesselData, str], ControlConfig]
_Builder = Callable[[Any], PositionController]

#: Each controller kind: its configuration parser, the configuration type and the controller it builds.
_KINDS: dict[str, tuple[_Parser, type, _Builder]] = {
    "mrac": (mrac_config_from_mapping, MracConfig, MracController),
    "pid": (pid_config_from_mapping, PidConfig, PidController),
    "autopilot": (autopilot_config_from_mapping, AutopilotConfig, AutopilotController),
}
CONTROL_KINDS: tuple[str, ...] = tuple(_KINDS)
_CONTROLLERS = {config_type: controller for _, config_type, controller in _KINDS.values()}


@dataclass(frozen=True)
class DefaultControl:
    """The controller a configuration without ``control.kind`` gets (:func:`default_control`).

    Attributes
    ----------
    section : mapping
        The ``control:`` section it stands for (``kind`` and the keys that make it the one measured; the keys
        the configuration gives override them).
    reason : str
        Why this one for this vessel (shown by ``dpcontrol check-config``).
    """

    section: Mapping[str, Any]
    reason: str

    def describe(self) -> str:
        """``pid (integral_action bias_feedforward)``: the kind and the keys it sets."""
        extra = ", ".join(f"{key} {value}" for key, value in self.section.items() if key != "kind")
        return f"{self.section['kind']}" + (f" ({extra})" if extra else "")


_FIXED_MASS = "her mass does not change: the MRAC is for a vessel whose mass does (seed 003's loading tanker)"
_TANKER = DefaultControl({"kind": "mrac"}, (
    "a shuttle tanker, whose mass grows 2.66× as she loads (seed 003): over the 12 h of loading (tanker-seed003) "
    "the MRAC kept her within 1.04 m of the guidance's reference (0.16 m rms, overshoot ≤ 0.53 m), the PID 4.43 m "
    "(overshoot growing to 3.94 m); in random moves and seas her position error is 0.46× the PID's (tanker-moves)"))
#: The controller measured to hold each built-in vessel (docs/configuration.md, the deploy/config examples).
_VESSEL_CONTROL: dict[str, DefaultControl] = {
    "shuttle_tanker": _TANKER,
    "shuttle_tanker_full": _TANKER,
    "supply": DefaultControl({"kind": "pid", "integral_action": "bias_feedforward"}, (
        "the MRAC lost her heading (strongly coupled sway and yaw: 12.6 m / 36° in 6 m moves before its "
        "supervision suspended it) and the PID's integrator winds up slowly (6.1 m off in fault case 10's beam "
        "weather, 2.3 m with the wave filter's bias fed forward)")),
    "cybership2": DefaultControl({"kind": "pid"}, f"seed 000's PID (App. A.3 gains, cs2-seed000); {_FIXED_MASS}"),
    "blue_lady": DefaultControl({"kind": "pid"}, f"seed 004's PID (bluelady-seed004); {_FIXED_MASS}"),
    "mariner": DefaultControl({"kind": "pid"}, (
        "a course-keeping ship (one propeller and rudder: no position to hold); with a DP estimator the PID, with "
        "estimator heading_kf the autopilot (seed 002, deploy/config/mariner.yaml)")),
}
_COURSE_KEEPING = DefaultControl({"kind": "autopilot"}, (
    "estimator heading_kf keeps a course: the autopilot is the controller it pairs with (seed 002)"))
_OWN_VESSEL = DefaultControl({"kind": "pid"}, (
    "a vessel of its own: the PID with gains from its matrices; the MRAC is for a vessel whose mass changes "
    "(seed 003's loading tanker): write control: {kind: mrac} for one"))


def default_control(builtin: str | None, *, course_keeping: bool = False) -> DefaultControl:
    """The controller measured to hold a vessel: what a configuration without ``control.kind`` runs.

    Parameters
    ----------
    builtin : str or None
        The built-in vessel the configuration's is (``vessel: supply``) or is based on (``vessel: {base: supply,
        …}``); None for a vessel of its own.
    course_keeping : bool
        The estimator is the course-keeping ``heading_kf``, which pairs with the autopilot only.

    Returns
    -------
    DefaultControl
        The shuttle tankers the MRAC (seed 003), the supply vessel the PID with the wave filter's bias fed
        forward, the other vessels the PID; the autopilot with ``heading_kf``.
    """
    if course_keeping:
        return _COURSE_KEEPING
    choice = _VESSEL_CONTROL.get(builtin or "")
    return _OWN_VESSEL if choice is None else choice


def control_config_from_mapping(value: object, vessel: VesselData, path: str = "control") -> ControlConfig:
    """Validate ``control: {kind: mrac | pid | autopilot, ...}`` (default ``mrac``) over the vessel's defaults.

    See :func:`~dpcontrol.control.mrac.mrac_config_from_mapping`,
    :func:`~dpcontrol.control.pid.pid_config_from_mapping` and
    :func:`~dpcontrol.control.autopilot.autopilot_config_from_mapping` for the keys of each kind.

    Raises
    ------
    ConfigError
        Naming the key path and what was expected.
    """
    section = Section.of(value, path)
    kind = section.string("kind", "mrac", choices=CONTROL_KINDS)
    data = dict(section.data)
    data["kind"] = kind
    return _KINDS[kind][0](data, vessel, path)


def make_controller(config: ControlConfig) -> PositionController:
    """The controller for a config from :func:`control_config_from_mapping`."""
    build = _CONTROLLERS.get(type(config))
    if build is None:
        raise TypeError(f"not a controller configuration: {config!r}")
    return build(config)
