"""Seed 000 in closed loop: CyberShip II, the 8-model MMAE wave filter on the nonlinear plant.

The shipped scenario ``cs2-seed000`` (JONSWAP Hs = 0.08 m, ωp = 0.93 rad/s from 30°, through the
plant's RAOs; sensors through the NMEA codecs; seed 000 App. A.3 PID; 10 m surge step at 40 s) runs
in lockstep for 450 s (a few seconds of wall time). Headlines (seed 000 Sect. 4 / Fig. 3):

* the weights settle on the 0.9 rad/s model and stay there: no chatter (the bug guarded here, also in
  the old conditions — Hs = 1.2 m, default tuning — where the per-sample likelihood made all eight
  models take turns at weight 1.0 every second);
* the estimated peak frequency agrees with the plant's *motion* spectrum peak (docs/design.md §5, trap 3);
* CyberShip II follows the 10 m step and keeps station within the bounds documented below.

Timing, measured (seed 1, see the report): the 0.9 model leads from ≈ 227 s and its weight exceeds
0.9 from ≈ 277 s — not seed 000's "about one minute". Two reasons, both measured: the first ≈ 100 s
are a low-frequency transient (filter convergence, DP engaging at 20 s, the step at 40 s), during
which the innovations tell nothing about the sea and the LF-validity gate holds the weights; and a
JONSWAP peak at 0.93 rad/s lies 20 % of a grid step above 0.9, where the prediction-error optimum
of a second-order WF model (≈ 5 % above a JONSWAP peak) leaves 0.9 and 1.05 within ~10 % of each
other in innovation energy, which takes ~100 s of clean data to resolve at the honest evidence rate.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from dpbase.frames import ssa_array
from sim_plant.bench.lockstep import RunResult
from sim_plant.bench.report import wrap_headings
from sim_plant.bench.run import build_simulation
from sim_plant.scenario import builtin_scenario_path, load_scenario

DURATION_S = 450.0
GRID = (0.3, 0.45, 0.6, 0.75, 0.9, 1.05, 1.2, 1.35)
I_09 = GRID.index(0.9)
GRID_STEP = 0.15
# Documented bounds (README "closed-loop results"), each with margin over the value measured for seed 1:
DOMINANT_BY_S = 260.0          # the 0.9 model leads from here to the end          (measured 227 s)
ABOVE_09_FROM_S = 320.0        # and its weight stays above 0.9 from here on        (measured 277 s)
CHATTER_JUMP = 0.5             # no weight may change by more than this within 1 s
STEP_ARRIVED_S = 260.0         # the reference has arrived at 10 m by then (speed limit 5.6 cm/s)
STATION_BOUND_M = 0.10         # LF position within this of the setpoint after arrival (measured 0.04 m)
TRACKING_BOUND_M = 0.20        # LF position within this of the reference throughout  (measured 0.13 m)
HEADING_BOUND_DEG = 1.5        # LF heading error, whole run after engagement        (measured 0.8°)


@pytest.fixture(scope="module")
def run() -> RunResult:
    simulation = build_simulation(load_scenario(builtin_scenario_path("cs2-seed000")))
    result = simulation.run(duration_s=DURATION_S)
    wrap_headings(result.columns)
    return result


def _col(result: RunResult, name: str) -> np.ndarray:
    c = result.columns
    return c.data[: c.rows, c.index(name)]


def _weights(result: RunResult) -> np.ndarray:
    return np.column_stack([_col(result, f"weight_{i}") for i in range(len(GRID))])


def _jumps(weights: np.ndarray, period_s: float = 0.1) -> int:
    """Number of 1 s windows over which some weight changes by more than ``CHATTER_JUMP``."""
    lag = round(1.0 / period_s)
    return int(np.sum(np.abs(weights[lag:] - weights[:-lag]).max(axis=1) > CHATTER_JUMP))


def test_the_scenario_is_the_seed_000_bank_and_sea(run: RunResult) -> None:
    assert run.omegas_rad_s == GRID
    assert run.config.estimator.kind == "mmae" and run.config.control.kind == "pid"
    sea = run.scenario.sea_states[0]
    assert sea.omega_peak_rad_s == 0.93 and sea.hs_m <= 0.1   # a model-scale sea (1:70), seed 000's peak
    motion = _col(run, "motion_peak_rad_s")
    assert abs(np.nanmedian(motion) - 0.93) < 0.01          # CS2 follows the waves: motion peak = wave peak


def test_weights_settle_on_the_0_9_model_without_chatter(run: RunResult) -> None:
    t = _col(run, "t_s")
    weights = _weights(run)
    assert np.all(np.isfinite(weights[t >= 1.0])) and np.allclose(weights[t >= 1.0].sum(axis=1), 1.0)
    leader = np.argmax(weights, axis=1)
    not_leading = np.flatnonzero(leader != I_09)
    leads_from = 0.0 if not_leading.size == 0 else float(t[not_leading[-1]]) + 0.1
    assert leads_from <= DOMINANT_BY_S, f"the 0.9 rad/s model leads only from {leads_from:.1f} s"
    late = t >= ABOVE_09_FROM_S
    assert np.all(weights[late, I_09] > 0.9), f"min weight after {ABOVE_09_FROM_S} s: {weights[late, I_09].min():.3f}"
    assert _jumps(weights[t >= 1.0]) == 0, "weights jump between models (chatter)"


@pytest.mark.parametrize("likelihood", ["band", "common"])
def test_no_chatter_in_the_conditions_that_made_the_weights_chatter(likelihood: str) -> None:
    """The first reproduction's measure: the old scenario (full-scale Hs = 1.2 m on the 1.255 m model) and
    the default estimator tuning (noise intensities 4× off the sensors). The per-sample likelihood
    ("common") makes the weights jump between models every second; the band-limited one does not."""
    scenario = load_scenario(builtin_scenario_path("cs2-seed000"))
    scenario = dataclasses.replace(scenario, sea_states=(dataclasses.replace(scenario.sea_states[0], hs_m=1.2),))
    estimator = {"kind": "mmae", "omegas_rad_s": list(GRID), "likelihood_scale": likelihood}
    result = build_simulation(scenario, overrides={"estimator": estimator}).run(duration_s=120.0)
    t = _col(result, "t_s")
    jumps = _jumps(_weights(result)[t >= 1.0])
    if likelihood == "band":
        assert jumps == 0, f"{jumps} one-second windows with a weight jump > {CHATTER_JUMP}"
    else:   # the cause, reproduced: hundreds of jumps in two minutes
        assert jumps > 100, jumps


def test_omega_hat_matches_the_motion_spectrum_peak(run: RunResult) -> None:
    """ω̂ = Σ p_i ω_i against the plant's |RAO|²S peak (docs/design.md §5, trap 3), over the last 100 s."""
    t = _col(run, "t_s")
    tail = t >= DURATION_S - 100.0
    omega_hat = _col(run, "omega_hat_rad_s")[tail]
    motion = _col(run, "motion_peak_rad_s")[tail]
    error = np.abs(omega_hat - motion)
    assert float(np.max(error)) <= 0.5 * GRID_STEP, f"|ω̂ − motion peak| up to {np.max(error):.3f} rad/s"


def test_follows_the_10_m_step_and_keeps_station(run: RunResult) -> None:
    t = _col(run, "t_s")
    engaged = t >= 20.0
    north, east = _col(run, "north_m"), _col(run, "east_m")
    ref_north, ref_east = _col(run, "ref_north_m"), _col(run, "ref_east_m")
    tracking = np.hypot(north - ref_north, east - ref_east)[engaged]
    assert float(np.max(tracking)) <= TRACKING_BOUND_M, f"tracking error up to {np.max(tracking):.3f} m"
    arrived = t >= STEP_ARRIVED_S
    assert np.all(np.abs(ref_north[arrived] - 10.0) < 1e-3) and np.all(np.abs(ref_east[arrived]) < 1e-3)
    station = np.hypot(north[arrived] - 10.0, east[arrived])
    assert float(np.max(station)) <= STATION_BOUND_M, f"station-keeping error up to {np.max(station):.3f} m"
    heading_error = np.degrees(np.abs(ssa_array(_col(run, "heading_rad") - _col(run, "ref_heading_rad"))))
    assert float(np.max(heading_error[engaged])) <= HEADING_BOUND_DEG, f"heading error {np.max(heading_error):.2f}°"


def test_the_lf_estimate_removes_the_wave_motion(run: RunResult) -> None:
    """The LF estimate is far closer to the true LF pose than the measurement (which carries the WF)."""
    t = _col(run, "t_s")
    late = t >= 100.0
    est = np.hypot(_col(run, "est_north_m") - _col(run, "north_m"), _col(run, "est_east_m") - _col(run, "east_m"))
    meas = np.hypot(_col(run, "meas_north_m") - _col(run, "north_m"), _col(run, "meas_east_m") - _col(run, "east_m"))
    rms_est = math.sqrt(float(np.mean(est[late] ** 2)))
    rms_meas = math.sqrt(float(np.mean(meas[late] ** 2)))
    assert rms_est < 0.5 * rms_meas, (rms_est, rms_meas)
