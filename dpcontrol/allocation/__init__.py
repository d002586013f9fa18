"""Thrust allocation: thruster geometry (extended thrust) and the constrained QP (daqp)."""

from dpcontrol.allocation.allocator import AllocationResult, ThrustAllocator, allocator_kwargs_from_mapping
from dpcontrol.allocation.geometry import ThrusterGeometry, weighted_pseudo_inverse

__all__ = ["AllocationResult", "ThrustAllocator", "ThrusterGeometry", "allocator_kwargs_from_mapping",
           "weighted_pseudo_inverse"]
