"""DP position controllers (nonlinear PID / PD + bias, MRAC), heading autopilot, wind feed-forward."""

from dpcontrol.control.autopilot import AutopilotConfig, AutopilotController, AutopilotOutput, HeadingAutopilot
from dpcontrol.control.base import ALL_DOFS, HEADING_ONLY, ControlOutput, MassAdaptation, PositionController
from dpcontrol.control.factory import (
    CONTROL_KINDS,
    ControlConfig,
    DefaultControl,
    control_config_from_mapping,
    default_control,
    make_controller,
)
from dpcontrol.control.mrac import MracConfig, MracController, default_mrac_config
from dpcontrol.control.pid import PidConfig, PidController, default_pid_config, pole_placement_gains
from dpcontrol.control.wind import (
    BlendermannCoefficients,
    TabulatedCoefficients,
    WindFeedforward,
    wind_feedforward_from_mapping,
)

__all__ = [
    "ALL_DOFS",
    "CONTROL_KINDS",
    "HEADING_ONLY",
    "AutopilotConfig",
    "AutopilotController",
    "AutopilotOutput",
    "BlendermannCoefficients",
    "ControlConfig",
    "ControlOutput",
    "DefaultControl",
    "HeadingAutopilot",
    "MassAdaptation",
    "MracConfig",
    "MracController",
    "PidConfig",
    "PidController",
    "PositionController",
    "TabulatedCoefficients",
    "WindFeedforward",
    "control_config_from_mapping",
    "default_control",
    "default_mrac_config",
    "default_pid_config",
    "make_controller",
    "pole_placement_gains",
    "wind_feedforward_from_mapping",
]
