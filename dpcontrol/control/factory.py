"""Build a position controller from the ``control:`` section of a configuration (validated)."""

from __future__ import annotations

from dpbase.schema import Section
from dpcontrol.control.base import PositionController
from dpcontrol.control.mrac import MracConfig, MracController, mrac_config_from_mapping
from dpcontrol.control.pid import PidConfig, PidController, pid_config_from_mapping
from dpcontrol.models.vessels import VesselData

CONTROL_KINDS: tuple[str, ...] = ("mrac", "pid")


def control_config_from_mapping(value: object, vessel: VesselData, path: str = "control") -> PidConfig | MracConfig:
    """Validate ``control: {kind: mrac | pid, ...}`` (default ``mrac``) over the vessel's defaults.

    See :func:`~dpcontrol.control.mrac.mrac_config_from_mapping` and
    :func:`~dpcontrol.control.pid.pid_config_from_mapping` for the keys of each kind.

    Raises
    ------
    ConfigError
        Naming the key path and what was expected.
    """
    section = Section.of(value, path)
    kind = section.string("kind", "mrac", choices=CONTROL_KINDS)
    data = dict(section.data)
    data["kind"] = kind
    if kind == "pid":
        return pid_config_from_mapping(data, vessel, path)
    return mrac_config_from_mapping(data, vessel, path)


def make_controller(config: PidConfig | MracConfig) -> PositionController:
    """The controller for a config from :func:`control_config_from_mapping`."""
    if isinstance(config, MracConfig):
        return MracController(config)
    if isinstance(config, PidConfig):
        return PidController(config)
    raise TypeError(f"not a controller configuration: {config!r}")
