"""Build a position controller from the ``control:`` section of a configuration (validated)."""

from __future__ import annotations

from collections.abc import Callable
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
