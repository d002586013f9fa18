"""The built-in thruster layouts hold their vessel against a moderate environment from every direction."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dpcontrol.allocation import ThrustAllocator
from dpcontrol.allocation.capability import capability_mps, environment_load_b, holds
from dpcontrol.models.vessels import BUILTIN_VESSELS

DP_VESSELS = ["cybership2", "supply", "shuttle_tanker", "shuttle_tanker_full", "blue_lady"]
DIRECTIONS = np.radians(np.arange(0.0, 360.0, 15.0))
MODERATE_WIND_MPS = 10.0  # Beaufort 5, with 0.5 m/s of current and a fully developed 2.1 m sea


@pytest.mark.parametrize("name", DP_VESSELS)
def test_layout_holds_a_moderate_environment_from_every_direction(name) -> None:
    vessel = BUILTIN_VESSELS[name]
    allocator = ThrustAllocator(vessel.thrusters, 1.0e3)
    for beta in DIRECTIONS:
        load = environment_load_b(vessel, beta, MODERATE_WIND_MPS)
        assert holds(allocator, load), f"{name} cannot hold {MODERATE_WIND_MPS} m/s from {math.degrees(beta):.0f}°"
    # and the check can fail: a storm abeam is beyond every layout
    assert not holds(allocator, environment_load_b(vessel, math.pi / 2, 35.0))


@pytest.mark.parametrize("name", ["supply", "shuttle_tanker", "shuttle_tanker_full"])
def test_dp2_like_layouts_keep_capability_after_any_single_thruster_failure(name) -> None:
    vessel = BUILTIN_VESSELS[name]
    allocator = ThrustAllocator(vessel.thrusters, 1.0e3)
    n = len(vessel.thrusters)
    for lost in range(n):
        available = np.ones(n, dtype=bool)
        available[lost] = False
        for beta in DIRECTIONS:
            load = environment_load_b(vessel, beta, 8.0)
            assert holds(allocator, load, available), (vessel.thrusters[lost].name, math.degrees(beta))


def test_capability_is_highest_head_on_and_symmetric_for_a_symmetric_layout() -> None:
    vessel = BUILTIN_VESSELS["supply"]
    directions = np.radians([0.0, 60.0, 90.0, 270.0, 300.0])
    wind = capability_mps(vessel, directions, iterations=12)
    assert wind[0] > wind[2] >= MODERATE_WIND_MPS  # head-on better than abeam
    assert wind[2] == pytest.approx(wind[3], abs=0.1)  # port/starboard symmetric layout
    assert wind[1] == pytest.approx(wind[4], abs=0.1)
