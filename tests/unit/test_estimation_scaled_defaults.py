"""The wave filter's default frequencies follow the vessel: Froude scaled below 76.2 m, unchanged above, a
configuration's own values kept (dpcontrol/estimation/filter_config.py, "Wave frequencies")."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from dpbase.schema import ConfigError
from dpcontrol.estimation import WaveFilterConfig
from dpcontrol.estimation.filter_config import (
    DEFAULT_OMEGAS_RAD_S,
    REFERENCE_LENGTH_M,
    LengthScaledGrid,
    wave_frequency_scale,
)
from dpcontrol.estimation.pem import identify_wave_model
from dpcontrol.models.vessels import CYBERSHIP2, SHUTTLE_TANKER, SUPPLY, VesselData
from dpcontrol.runtime.config import parse_config

SEED000_GRID = (0.3, 0.45, 0.6, 0.75, 0.9, 1.05, 1.2, 1.35)
DT = 0.1
ROOT = Path(__file__).resolve().parents[2]


def _config(vessel: VesselData, **kwargs: object) -> WaveFilterConfig:
    return WaveFilterConfig(mass_matrix=vessel.mass_matrix, damping_matrix=vessel.damping_matrix, sample_time_s=DT,
                            length_m=vessel.length_m, **kwargs)  # type: ignore[arg-type]


def test_a_short_vessel_gets_the_froude_scaled_grid_and_range() -> None:
    scale = math.sqrt(REFERENCE_LENGTH_M / CYBERSHIP2.length_m)
    assert math.isclose(wave_frequency_scale(CYBERSHIP2.length_m), scale) and 7.7 < scale < 7.9
    config = _config(CYBERSHIP2)
    np.testing.assert_allclose(config.omegas_rad_s, np.array(SEED000_GRID) * scale, rtol=1e-12)
    assert type(config.omegas_rad_s) is tuple      # resolved once: a replace() does not scale again
    assert math.isclose(config.rpem_omega_min_rad_s, 0.2 * scale)
    # 2·s = 15.58 rad/s, under π/(2Δt) = 15.71 rad/s at 10 Hz; at 5 Hz the default bound stops at π/(2Δt)
    assert math.isclose(config.rpem_omega_max_rad_s, 2.0 * scale)
    slow = WaveFilterConfig(mass_matrix=CYBERSHIP2.mass_matrix, damping_matrix=CYBERSHIP2.damping_matrix,
                            sample_time_s=0.2, length_m=CYBERSHIP2.length_m)
    assert math.isclose(slow.rpem_omega_max_rad_s, 0.5 * math.pi / 0.2)
    pem = _config(CYBERSHIP2, kind="pem", omegas_rad_s=LengthScaledGrid((0.8,)))
    assert math.isclose(pem.omegas_rad_s[0], 0.8 * scale)


@pytest.mark.parametrize("vessel", [SUPPLY, SHUTTLE_TANKER])
def test_a_full_scale_vessel_keeps_the_grid_it_had(vessel: VesselData) -> None:
    config = _config(vessel)
    assert config.omegas_rad_s == SEED000_GRID
    assert (config.rpem_omega_min_rad_s, config.rpem_omega_max_rad_s) == (0.2, 2.0)
    assert tuple(DEFAULT_OMEGAS_RAD_S) == SEED000_GRID


def test_a_given_grid_and_range_are_kept() -> None:
    config = _config(CYBERSHIP2, omegas_rad_s=SEED000_GRID)
    assert config.omegas_rad_s == SEED000_GRID
    rpem = _config(CYBERSHIP2, kind="rpem", omegas_rad_s=(0.6,), rpem_omega_min_rad_s=0.2, rpem_omega_max_rad_s=2.0)
    assert (rpem.omegas_rad_s, rpem.rpem_omega_min_rad_s, rpem.rpem_omega_max_rad_s) == ((0.6,), 0.2, 2.0)
    # an unscaled ω0 outside the scaled default range is refused, naming the range
    with pytest.raises(ConfigError, match="initial ω0"):
        _config(CYBERSHIP2, kind="pem", omegas_rad_s=(0.6,))


def test_the_runtime_configuration_scales_only_what_it_does_not_give() -> None:
    mapping = yaml.safe_load((ROOT / "deploy" / "config" / "cybership2.yaml").read_text(encoding="utf-8"))
    scale = wave_frequency_scale(CYBERSHIP2.length_m)
    assert parse_config(mapping).estimator.wave_filter.omegas_rad_s == SEED000_GRID   # the example's own bank
    mapping["estimator"] = {"kind": "mmae"}
    np.testing.assert_allclose(parse_config(mapping).estimator.wave_filter.omegas_rad_s,
                               np.array(SEED000_GRID) * scale)
    mapping["estimator"] = {"kind": "pem"}
    pem = parse_config(mapping).estimator.wave_filter
    assert math.isclose(pem.omegas_rad_s[0], 0.8 * scale) and math.isclose(pem.rpem_omega_min_rad_s, 0.2 * scale)
    mapping["estimator"] = {"kind": "rpem", "omega0_rad_s": 3.0}
    assert parse_config(mapping).estimator.wave_filter.omegas_rad_s == (3.0,)
    supply = yaml.safe_load((ROOT / "deploy" / "config" / "supply.yaml").read_text(encoding="utf-8"))
    supply["estimator"] = {"kind": "mmae"}
    assert parse_config(supply).estimator.wave_filter.omegas_rad_s == SEED000_GRID


def test_pem_identifies_a_model_basin_sea_above_the_full_scale_decimation() -> None:
    """A 5.8 rad/s sea (0.75 rad/s × 7.8) at the 0.1 s control period: the record is no longer decimated to
    0.5 s (whose search would end at 0.8π/0.5 = 5.0 rad/s)."""
    rng = np.random.default_rng(11)
    scale = wave_frequency_scale(CYBERSHIP2.length_m)
    peak = 0.75 * scale
    omega = np.linspace(0.2, 3.0, 400) * scale
    elevation = omega**-5 * np.exp(-1.25 * (peak / omega) ** 4) \
        * 3.3 ** np.exp(-((omega - peak) ** 2) / (2 * 0.08**2 * peak**2))        # JONSWAP, γ 3.3
    spectrum = elevation / np.minimum(omega / peak, 3.0) ** 4                   # through a 1/ω² position response
    amplitude = np.sqrt(2.0 * spectrum * (omega[1] - omega[0]))
    t = np.arange(6000) * DT
    motion = np.empty((t.size, 3))
    std = np.array([0.01, 0.006, math.radians(0.5)])
    for j in range(3):
        x = (amplitude[:, None] * np.cos(omega[:, None] * t[None, :] + rng.uniform(0, 2 * math.pi, omega.size)[:, None])
             ).sum(axis=0)
        motion[:, j] = std[j] * x / x.std()
    found = float(omega[np.argmax(spectrum)])
    config = _config(CYBERSHIP2, kind="pem", omegas_rad_s=LengthScaledGrid((0.8,)))
    estimate = identify_wave_model(motion, DT, omega_range_rad_s=(config.rpem_omega_min_rad_s,
                                                                  config.rpem_omega_max_rad_s))
    assert estimate is not None
    assert abs(estimate.omega_rad_s / found - 1.0) <= 0.1, (estimate.omega_rad_s, found)
