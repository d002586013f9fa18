"""A swell beside the wind sea (sim_plant.environment.waves): superposed motion and drift, peaks, scenario keys."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dpbase.schema import ConfigError
from dpcontrol.models.vessels import SUPPLY
from sim_plant.environment.rao import HullDimensions
from sim_plant.environment.waves import SeaState, WaveEnvironment, WaveSystem
from sim_plant.scenario import parse_scenario

HULL = HullDimensions(SUPPLY.length_m, SUPPLY.beam_m, SUPPLY.draft_m)
WIND_SEA = {"t_s": 0.0, "hs_m": 1.5, "omega_peak_rad_s": 0.9, "direction_rad": 0.0}


def _env(state: SeaState) -> WaveEnvironment:
    return WaveEnvironment([state], HULL, lambda i: np.random.default_rng([4, i]))


def test_the_swell_adds_to_the_wind_sea_which_stays_as_it_was() -> None:
    swell = WaveSystem(2.0, 0.45, math.radians(100.0), gamma=6.0)
    alone, both = _env(SeaState(**WIND_SEA)), _env(SeaState(**WIND_SEA, swell=swell))
    swell_field = both._fields_of(0)[1]
    for t in np.arange(0.0, 300.0, 7.3):
        a = alone.evaluate(t, 3.0, -2.0, 0.2)
        b = both.evaluate(t, 3.0, -2.0, 0.2)
        x, y, p, r, ac, as_ = swell_field.evaluate(t, 3.0, -2.0, 0.2)
        # first-order motion is linear in the waves: the wind sea's realisation is unchanged by the swell
        assert (b.surge_m, b.sway_m, b.yaw_rad, b.yaw_rate_radps) == pytest.approx(
            (a.surge_m + x, a.sway_m + y, a.yaw_rad + p, a.yaw_rate_radps + r), abs=1e-12)
        # independent systems: their drift envelopes do not interfere, the forces add
        swell_drift = (ac * ac + as_ * as_) * np.array(swell_field.drift_factors())
        np.testing.assert_allclose(b.drift_b, np.add(a.drift_b, swell_drift), rtol=1e-12, atol=1e-9)
        assert np.any(np.abs(swell_drift) > 1.0)  # (the swell does push)


def test_the_motion_peak_follows_the_system_that_moves_the_vessel_most() -> None:
    # a long swell on the beam moves the supply vessel far more than a short head sea: its peak is the motion's
    beam_swell = WaveSystem(2.5, 0.45, math.radians(90.0), gamma=6.0)
    peaks = _env(SeaState(0.0, 1.0, 1.1, 0.0, swell=beam_swell)).peaks(10.0, 0.0)
    assert peaks.motion_peak_rad_s == pytest.approx(0.45, rel=0.1)
    assert peaks.omega_peak_rad_s == pytest.approx(0.45)  # the higher spectral peak
    # a faint swell leaves the wind sea's peak where it was
    faint = WaveSystem(0.05, 0.45, math.radians(90.0))
    with_faint = _env(SeaState(0.0, 1.5, 0.8, math.radians(90.0), swell=faint)).peaks(10.0, 0.0)
    without = _env(SeaState(0.0, 1.5, 0.8, math.radians(90.0))).peaks(10.0, 0.0)
    assert with_faint.omega_peak_rad_s == 0.8
    assert with_faint.motion_peak_rad_s == pytest.approx(without.motion_peak_rad_s, rel=0.02)
    # a swell alone (calm wind sea) is a sea
    only = SeaState(0.0, 0.0, 0.9, 0.0, swell=beam_swell)
    assert not only.calm and _env(only).peaks(10.0, 0.0).omega_peak_rad_s == pytest.approx(0.45)


def _scenario(sea_state: dict) -> dict:
    return {"name": "swell", "vessel": "supply", "duration_s": 10, "sea_states": [sea_state]}


def test_the_scenario_file_gives_a_swell_its_own_spectrum_and_direction() -> None:
    scenario = parse_scenario(_scenario({"t_s": 0, "hs_m": 1.0, "tp_s": 6.0, "direction_deg": 30,
                                         "swell": {"hs_m": 2.0, "tp_s": 14.0, "direction_deg": 120, "gamma": 7}}))
    state = scenario.sea_states[0]
    assert state.swell == WaveSystem(2.0, 2.0 * math.pi / 14.0, math.radians(120.0), "jonswap", 7.0, 200)
    assert [s.hs_m for s in state.systems()] == [1.0, 2.0]
    for swell, path in (({"hs_m": 2.0}, "sea_states[0].swell.omega_peak_rad_s"),
                        ({"hs_m": 2.0, "tp_s": 12, "period": 3}, "sea_states[0].swell"),
                        ({"hs_m": -1.0, "tp_s": 12}, "sea_states[0].swell.hs_m")):
        with pytest.raises(ConfigError) as error:
            parse_scenario(_scenario({"t_s": 0, "hs_m": 1.0, "tp_s": 6.0, "swell": swell}))
        assert error.value.path.startswith(path), (swell, error.value.path)
