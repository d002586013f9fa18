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

#: Each controller kind: its configuration parser and the controller its configuration builds.
_KINDS: dict[str, tuple[Callable[[object, VesselData, str], ControlConfig], Callable[[Any], PositionController]]] = {
    "mrac": (mrac_config_from_mapping, MracController),
    "pid": (pid_config_from_mapping, PidController),
    "autopilot": (autopilot_config_from_mapping, AutopilotController),
}
CONTROL_KINDS: tuple[str, ...] = tuple(_KINDS)
_CONTROLLERS: dict[type, Callable[[Any], PositionController]] = {
    MracConfig: MracController, PidConfig: PidController, AutopilotConfig: AutopilotController}


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
