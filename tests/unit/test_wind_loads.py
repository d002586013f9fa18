"""The one wind-load law (dpbase.wind_loads): signs, symmetry, the ship-type table, and the controller's
feed-forward and the plant's wind agreeing on the same relative wind."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dpbase.wind_loads import (
    BLENDERMANN_TYPE_ALIASES,
    BLENDERMANN_TYPE_NAMES,
    BLENDERMANN_TYPES,
    BlendermannCoefficients,
    blendermann_type,
    relative_wind_angle,
    wind_load_b,
)
from dpcontrol.control.wind import WindFeedforward, default_wind_coefficients
from dpcontrol.models.vessels import BUILTIN_VESSELS, SUPPLY
from sim_plant.environment.wind import RHO_AIR_KGPM3, WindModel
from sim_plant.vessel import DpVesselModel

LAW = BlendermannCoefficients.of_type("offshore_supply_vessel", 280.0, 720.0, 76.2, 0.15 * 76.2)


def test_head_wind_pushes_astern_and_a_tail_wind_ahead() -> None:
    x, y, n = LAW.force_b(10.0, 0.0, 1.2)
    assert x == pytest.approx(-0.5 * 1.2 * 100.0 * 280.0 * 0.55) and y == 0.0 and n == 0.0
    x, y, _ = LAW.force_b(10.0, math.pi, 1.2)
    assert x == pytest.approx(0.5 * 1.2 * 100.0 * 280.0 * 0.80) and abs(y) < 1e-9 * x  # the stern coefficient


def test_beam_winds_push_to_leeward() -> None:
    assert LAW.coefficients(-math.pi / 2.0)[1] == pytest.approx(-0.90)  # from starboard: towards port
    assert LAW.coefficients(math.pi / 2.0)[1] == pytest.approx(0.90)  # from port: towards starboard
    # the relative wind angle of eq. (20): a vessel drifting to starboard in still air feels a wind from starboard
    assert relative_wind_angle(0.0, 1.0) == pytest.approx(-math.pi / 2.0)
    assert relative_wind_angle(1.0, 0.0) == 0.0  # moving ahead: a head wind


@settings(max_examples=100, deadline=None)
@given(gamma=st.floats(0.0, math.pi), speed=st.floats(0.1, 40.0))
def test_port_and_starboard_winds_mirror_exactly(gamma: float, speed: float) -> None:
    x1, y1, n1 = LAW.force_b(speed, gamma, RHO_AIR_KGPM3)
    x2, y2, n2 = LAW.force_b(speed, -gamma, RHO_AIR_KGPM3)
    assert (x2, y2, n2) == (x1, -y1, -n1)


def test_the_lateral_force_acts_ahead_of_the_centroid_from_forward_and_behind_it_from_aft() -> None:
    centred = BlendermannCoefficients.of_type("tanker_loaded", 1000.0, 5000.0, 300.0)
    _, cy, cn = centred.coefficients(math.radians(-45.0))  # from the starboard bow
    assert cy < 0.0 and cn < 0.0  # the bow turns to port, downwind
    _, cy, cn = centred.coefficients(math.radians(-135.0))  # from the starboard quarter
    assert cy < 0.0 and cn > 0.0  # the stern goes to port


def test_one_table_with_the_old_spellings_as_aliases() -> None:
    assert len(BLENDERMANN_TYPES) == 17
    assert blendermann_type("offshore_supply") == blendermann_type("offshore_supply_vessel") == (0.90, 0.55, 0.80, 0.55)
    assert blendermann_type("cargo_loaded") == BLENDERMANN_TYPES["cargo_vessel_loaded"]
    assert set(BLENDERMANN_TYPE_ALIASES.values()) <= set(BLENDERMANN_TYPES)
    assert set(BLENDERMANN_TYPE_NAMES) == set(BLENDERMANN_TYPES) | set(BLENDERMANN_TYPE_ALIASES)
    with pytest.raises(KeyError, match="yacht"):
        blendermann_type("yacht")


def test_parameters_are_checked_and_zero_areas_give_no_load() -> None:
    for bad in ((0.0, 280.0, 720.0, 76.2), (0.9, -1.0, 720.0, 76.2), (0.9, 280.0, 720.0, 0.0),
                (0.9, math.nan, 720.0, 76.2)):
        cdt, frontal, lateral, length = bad
        with pytest.raises(ValueError):
            BlendermannCoefficients(cdt, 0.55, 0.8, 0.55, frontal, lateral, length)
    bare = BlendermannCoefficients.of_type("tender", 0.0, 0.0, 10.0)
    assert bare.force_b(20.0, 0.7, RHO_AIR_KGPM3) == (0.0, 0.0, 0.0)
    assert wind_load_b(2.0, (1.0, 2.0, 3.0), 10.0, 20.0, 5.0) == (20.0, 80.0, 600.0)


@settings(max_examples=60, deadline=None)
@given(wind_from=st.floats(-math.pi, math.pi), psi=st.floats(-math.pi, math.pi), speed=st.floats(0.5, 30.0))
def test_the_controller_and_the_plant_agree_for_the_same_relative_wind(wind_from: float, psi: float,
                                                                       speed: float) -> None:
    """Same vessel, same wind, same coefficients and air density: the same load from both sides."""
    plant = DpVesselModel(SUPPLY).wind
    feed = WindFeedforward(plant, plant.frontal_area_m2, plant.lateral_area_m2, plant.length_m, RHO_AIR_KGPM3)
    wind = WindModel(speed, wind_from, plant, np.random.default_rng(0), gusts=False)
    nu = np.array([0.8, -0.3, 0.0])
    np.testing.assert_allclose(feed.force_b(speed, wind_from, psi, nu), wind.force_b(0.0, psi, nu[0], nu[1]),
                               rtol=1e-9, atol=1e-9 * speed * speed * plant.lateral_area_m2 * plant.length_m)


def test_the_controller_default_is_the_plant_type_without_the_centroid() -> None:
    for vessel in BUILTIN_VESSELS.values():
        if vessel.name == "mariner":
            continue  # the plant's mariner is the manoeuvring model
        controller = default_wind_coefficients(vessel)
        plant = DpVesselModel(vessel).wind
        assert controller is not None
        assert controller.coefficients(0.4) == pytest.approx(
            BlendermannCoefficients(plant.cd_transverse, plant.cd_longitudinal_head, plant.cd_longitudinal_tail,
                                    plant.cross_force, plant.frontal_area_m2, plant.lateral_area_m2,
                                    plant.length_m).coefficients(0.4))
