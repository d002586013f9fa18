"""Guidance: the DP reference model (set-point → smooth η_d, η̇_d, η̈_d with speed limits)."""

from dpcontrol.guidance.reference_model import (
    Reference,
    ReferenceModel,
    ReferenceModelConfig,
    default_reference_config,
    reference_config_from_mapping,
)

__all__ = ["Reference", "ReferenceModel", "ReferenceModelConfig", "default_reference_config",
           "reference_config_from_mapping"]
