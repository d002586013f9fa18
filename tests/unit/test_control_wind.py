"""Wind load model for feed-forward (seed 002 eqs. (18)–(22)), Blendermann and tabulated coefficients."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dpbase.schema import ConfigError
from dpbase.wind_loads import blendermann_type
from dpcontrol.control import (
    BlendermannCoefficients,
    TabulatedCoefficients,
    WindFeedforward,
    wind_feedforward_from_mapping,
)
from dpcontrol.control.wind import RHO_AIR_KGPM3, default_wind_coefficients
from dpcontrol.models.vessels import BUILTIN_VESSELS, SUPPLY

WIND = WindFeedforward.for_vessel(SUPPLY)


def test_head_wind_pushes_astern_with_the_frontal_area() -> None:
    assert WIND is not None
    tau = WIND.force_b(15.0, 0.0, 0.0)  # wind from the north, vessel heading north
    cdl_head = blendermann_type("offshore_supply").cd_longitudinal_head
    expected = -0.5 * RHO_AIR_KGPM3 * 15.0**2 * SUPPLY.frontal_wind_area_m2 * cdl_head
    assert tau[0] == pytest.approx(expected)
    assert tau[1] == pytest.approx(0.0, abs=1e-9) and tau[2] == pytest.approx(0.0, abs=1e-6)
    tail = WIND.force_b(15.0, math.pi, 0.0)
    assert tail[0] > 0.0


def test_beam_winds_push_to_leeward_and_the_heading_rotates_the_load() -> None:
    starboard = WIND.force_b(10.0, math.radians(90.0), 0.0)  # from the east: on the starboard side
    assert starboard[1] < 0.0  # pushed to port
    assert starboard[1] == pytest.approx(-0.5 * RHO_AIR_KGPM3 * 100.0 * SUPPLY.lateral_wind_area_m2
                                         * blendermann_type("offshore_supply").cd_transverse)
    port = WIND.force_b(10.0, math.radians(-90.0), 0.0)
    np.testing.assert_allclose(port, -starboard, atol=1e-6)
    # wind from the north on a vessel heading east comes from port: pushed to starboard
    rotated = WIND.force_b(10.0, 0.0, math.radians(90.0))
    np.testing.assert_allclose(rotated, port, atol=1e-6)


@settings(max_examples=50, deadline=None)
@given(angle=st.floats(0.01, math.pi - 0.01), speed=st.floats(0.5, 40.0))
def test_loads_are_mirror_symmetric_and_scale_with_the_speed_squared(angle, speed) -> None:
    a = WIND.force_b(speed, angle, 0.0)
    b = WIND.force_b(speed, -angle, 0.0)
    np.testing.assert_allclose(b, [a[0], -a[1], -a[2]], rtol=1e-9, atol=1e-9 * np.abs(a).max())
    np.testing.assert_allclose(WIND.force_b(2.0 * speed, angle, 0.0), 4.0 * a, rtol=1e-12, atol=1e-9)
    assert a[1] < 0.0  # from starboard (0 < β < π) always towards port


def test_relative_wind_includes_the_vessel_velocity() -> None:
    # a vessel surging at 3 m/s in still air feels a 3 m/s head wind
    np.testing.assert_allclose(WIND.force_b(0.0, 0.0, 0.0, np.array([3.0, 0.0, 0.0])),
                               WIND.force_b(3.0, 0.0, 0.0), rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(WIND.force_b(0.0, 1.0, 0.0), 0.0)
    with pytest.raises(ValueError):
        WIND.force_b(-1.0, 0.0, 0.0)
    with pytest.raises(ValueError):
        WIND.force_b(1.0, math.nan, 0.0)


def test_yaw_moment_turns_the_bow_away_from_a_bow_quartering_wind() -> None:
    tau = WIND.force_b(10.0, math.radians(45.0), 0.0)  # from the starboard bow
    assert tau[2] < 0.0  # bow turned to port (downwind)


def test_tabulated_coefficients_interpolate_periodically() -> None:
    gamma = np.radians([-180.0, -90.0, 0.0, 90.0])
    table = TabulatedCoefficients(gamma, np.array([0.6, 0.0, -0.5, 0.0]), np.array([0.0, -0.8, 0.0, 0.8]),
                                  np.array([0.0, 0.0, 0.0, 0.0]))
    assert table.coefficients(math.radians(45.0)) == pytest.approx((-0.25, 0.4, 0.0))
    assert table.coefficients(math.radians(135.0)) == pytest.approx((0.3, 0.4, 0.0))  # wraps to −180°
    assert table.coefficients(math.radians(180.0)) == pytest.approx((0.6, 0.0, 0.0))
    feed = WindFeedforward(table, 100.0, 300.0, 50.0)
    assert feed.force_b(10.0, 0.0, 0.0)[0] == pytest.approx(-0.5 * RHO_AIR_KGPM3 * 100.0 * 100.0 * 0.5)
    with pytest.raises(ValueError):
        TabulatedCoefficients(np.array([0.0, -1.0]), np.zeros(2), np.zeros(2), np.zeros(2))
    with pytest.raises(ValueError):
        TabulatedCoefficients(np.array([0.0, 1.0]), np.zeros(3), np.zeros(2), np.zeros(2))


def test_every_built_in_vessel_has_coefficients() -> None:
    for vessel in BUILTIN_VESSELS.values():
        coefficients = default_wind_coefficients(vessel)
        assert isinstance(coefficients, BlendermannCoefficients)
        cx, cy, _ = coefficients.coefficients(0.0)
        assert cx < 0.0 and cy == pytest.approx(0.0)
    with pytest.raises(ValueError):
        BlendermannCoefficients(0.9, 0.5, 0.5, 0.5, -1.0, 1.0, 1.0)
    with pytest.raises(ValueError):  # the feed-forward needs both areas (the shared law allows 0, the plant uses it)
        WindFeedforward(BlendermannCoefficients(0.9, 0.5, 0.5, 0.5, 0.0, 1.0, 1.0), 0.0, 1.0, 1.0)


def test_wind_feedforward_config() -> None:
    default = wind_feedforward_from_mapping({}, SUPPLY)
    assert default is not None
    np.testing.assert_allclose(default.force_b(12.0, 0.7, 0.1), WIND.force_b(12.0, 0.7, 0.1))
    assert wind_feedforward_from_mapping(None, SUPPLY) is None
    assert wind_feedforward_from_mapping({"enabled": False, "coefficients": "table"}, SUPPLY) is None
    table = wind_feedforward_from_mapping({"coefficients": "table", "gamma_deg": [-180, -90, 0, 90],
                                           "cx": [0.6, 0.0, -0.5, 0.0], "cy": [0.0, -0.8, 0.0, 0.8],
                                           "cn": [0, 0, 0, 0]}, SUPPLY)
    assert table.force_b(10.0, 0.0, 0.0)[0] == pytest.approx(-0.5 * RHO_AIR_KGPM3 * 100.0
                                                             * SUPPLY.frontal_wind_area_m2 * 0.5)
    tanker = wind_feedforward_from_mapping({"vessel_type": "tanker_loaded", "centroid_x_m": 20.0}, SUPPLY)
    assert tanker.force_b(10.0, 0.5, 0.0)[2] != pytest.approx(WIND.force_b(10.0, 0.5, 0.0)[2])
    with pytest.raises(ConfigError, match=r"wind_feedforward\.vessel_type"):
        wind_feedforward_from_mapping({"vessel_type": "yacht"}, SUPPLY)
    with pytest.raises(ConfigError, match=r"wind_feedforward\.gamma_deg"):
        wind_feedforward_from_mapping({"coefficients": "table", "gamma_deg": [0, -10], "cx": [0, 0],
                                       "cy": [0, 0], "cn": [0, 0]}, SUPPLY)
    with pytest.raises(ConfigError, match=r"wind_feedforward\.cx"):
        wind_feedforward_from_mapping({"coefficients": "table", "gamma_deg": [0, 10], "cx": [0],
                                       "cy": [0, 0], "cn": [0, 0]}, SUPPLY)
