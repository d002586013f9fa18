"""Wind and current (sim_plant.environment): coefficients, gusts, slow current variation."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dpbase.wind_loads import BlendermannCoefficients
from sim_plant.environment.current import CurrentModel
from sim_plant.environment.spectra import gauss_markov_process, norsok_wind_spectrum_per_hz
from sim_plant.environment.wind import RHO_AIR_KGPM3, WindModel

SUPPLY_WIND = BlendermannCoefficients.of_type("offshore_supply_vessel", 280.0, 720.0, 76.2, 0.15 * 76.2)


def test_wind_coefficient_signs() -> None:
    cx, cy, cn = SUPPLY_WIND.coefficients(0.0)
    assert cx == pytest.approx(-0.55) and cy == pytest.approx(0.0) and cn == pytest.approx(0.0)
    cx, cy, _ = SUPPLY_WIND.coefficients(math.pi)
    assert cx == pytest.approx(0.80)  # from astern: stern coefficient, pushes ahead
    # γ_rw of dpbase.wind_loads: positive from port
    _, cy, cn = SUPPLY_WIND.coefficients(-math.pi / 2.0)
    assert cy == pytest.approx(-0.90)  # from starboard: pushed to port
    _, cy, cn = SUPPLY_WIND.coefficients(math.radians(-30.0))
    assert cy < 0.0 and cn < 0.0  # from the starboard bow: the bow is pushed to port
    _, cy, cn = SUPPLY_WIND.coefficients(math.radians(-150.0))
    assert cy < 0.0 and cn > 0.0  # from the starboard quarter: the stern is pushed to port


@settings(max_examples=50, deadline=None)
@given(gamma=st.floats(0.0, math.pi))
def test_wind_coefficients_are_mirror_symmetric(gamma) -> None:
    cx1, cy1, cn1 = SUPPLY_WIND.coefficients(gamma)
    cx2, cy2, cn2 = SUPPLY_WIND.coefficients(-gamma)
    assert cx1 == pytest.approx(cx2, abs=1e-12)
    assert cy1 == pytest.approx(-cy2, abs=1e-12)
    assert cn1 == pytest.approx(-cn2, abs=1e-12)


def test_wind_force_uses_the_relative_wind() -> None:
    model = WindModel(10.0, math.radians(90.0), SUPPLY_WIND, np.random.default_rng(0), gusts=False)
    x, y, _ = model.force_b(0.0, 0.0, 0.0, 0.0)  # wind from the east, heading north: from starboard
    q = 0.5 * RHO_AIR_KGPM3 * 100.0
    assert y == pytest.approx(-0.90 * q * 720.0)
    assert x == pytest.approx(0.0, abs=1e-9 * abs(y))
    calm = WindModel(1e-9, 0.0, SUPPLY_WIND, np.random.default_rng(0), gusts=False)
    x, y, _ = calm.force_b(0.0, 0.0, 5.0, 0.0)  # moving ahead in still air = 5 m/s head wind
    assert x == pytest.approx(-0.55 * 0.5 * RHO_AIR_KGPM3 * 25.0 * 280.0, rel=1e-6)
    assert WindModel(0.0, 0.0, SUPPLY_WIND, np.random.default_rng(0)).force_b(0.0, 0.0, 1.0, 0.0) == (0.0, 0.0, 0.0)


def test_gusts_have_the_norsok_variance_and_the_mean_speed() -> None:
    model = WindModel(12.0, 0.0, SUPPLY_WIND, np.random.default_rng(3), gusts=True)
    edges = np.geomspace(1.0 / 2000.0, 0.5, 20001)
    expected_var = np.trapezoid(norsok_wind_spectrum_per_hz(edges, 12.0), edges)
    assert model.gust is not None
    assert model.gust.variance == pytest.approx(expected_var, rel=0.05)
    t = np.arange(0.0, 100000.0, 1.0)
    speed = 12.0 + model.gust.series(t)
    assert speed.std() == pytest.approx(math.sqrt(expected_var), rel=0.1)
    assert speed.mean() == pytest.approx(12.0, abs=0.1 * math.sqrt(expected_var))
    assert min(model.speed_at(ti) for ti in t[:2000]) >= 0.0


def test_constant_current_flows_toward_its_direction() -> None:
    current = CurrentModel(0.5, math.radians(90.0), np.random.default_rng(0))
    vn, ve = current.velocity_ned(123.0)
    assert vn == pytest.approx(0.0, abs=1e-12) and ve == pytest.approx(0.5)
    assert not current.varies


def test_current_slow_variation_statistics() -> None:
    current = CurrentModel(0.5, 0.0, np.random.default_rng(1), speed_std_mps=0.05,
                           direction_std_rad=math.radians(5.0), time_constant_s=300.0)
    t = np.arange(0.0, 600000.0, 20.0)
    speeds, directions = zip(*(current.speed_direction(ti) for ti in t), strict=True)
    assert np.std(speeds) == pytest.approx(0.05, rel=0.15)
    assert np.std(directions) == pytest.approx(math.radians(5.0), rel=0.15)
    assert np.mean(speeds) == pytest.approx(0.5, abs=0.01)
    with pytest.raises(ValueError):
        CurrentModel(-1.0, 0.0, np.random.default_rng(0))


def test_gauss_markov_realisation_has_exponential_correlation() -> None:
    process = gauss_markov_process(2.0, 50.0, np.random.default_rng(4), n=64)
    t = np.arange(0.0, 400000.0, 5.0)
    x = process.series(t)
    assert x.std() == pytest.approx(2.0, rel=0.1)
    lag = 10  # 50 s
    assert np.corrcoef(x[:-lag], x[lag:])[0, 1] == pytest.approx(math.exp(-1.0), abs=0.08)
    assert process.value(123.0) == pytest.approx(float(process.series(np.array([123.0]))[0]))
