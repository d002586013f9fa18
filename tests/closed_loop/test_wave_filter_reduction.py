"""The wave filter keeps the wave-frequency motion out of the commanded force (seed 002 Fig. 7).

CyberShip II in the shipped ``cs2-seed000`` sea (JONSWAP Hs = 0.08 m, ωp = 0.93 rad/s, through the RAOs),
keeping station at the origin for 450 s, twice with the same seed 000 PID: once with the MMAE wave
filter of the scenario, once fed "raw" measurements (``estimator: {kind: raw}``: the same LF filter and
noise settings without wave states, so the WF motion reaches the controller). The measure is the
report's wave-frequency content (:func:`sim_plant.bench.report.wave_frequency_std`): the standard
deviation of the commanded force above half the motion-spectrum peak (Welch PSD), taken once the bank
has identified the sea (t ≥ 250 s; the 0.9 rad/s model leads from ≈ 218 s in this run). Measured:
surge 20×, sway 14× there; over the whole run from engagement + settling (the summary's
``tau_wave_frequency_std``, including the first ~150 s with the weights still spread over the low-
frequency models) 14× and 11×.

Station keeping, not the 10 m step: the step's acceleration-limited reference puts force steps into
the commanded surge force (≈ 0.015 N above 0.47 rad/s with a perfect estimate), which is manoeuvring,
not wave-frequency content; with the step the surge ratio is 9.2×, sway 9.9× (see the report).

Yaw is reported, not asserted: CyberShip II's wave yaw in these long waves is a broadband signal whose
energy lies mostly at 1.3–5 rad/s (yaw RAO ∝ wave number, so |RAO|²S decays only as 1/ω), above the
notch of any WF model near 0.93 rad/s and inside the seed 000 yaw loop's bandwidth (√(7.652/2.76) =
1.67 rad/s); the wave filter does not reduce it (ratio ≈ 1), and neither makes it large (0.06 N·m of 1.5).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from sim_plant.bench.lockstep import LockstepSimulation
from sim_plant.bench.report import summarise, wave_frequency_std
from sim_plant.bench.run import build_simulation
from sim_plant.scenario import Setpoint, builtin_scenario_path, load_scenario

DURATION_S = 450.0
SETTLED_FROM_S = 250.0        # the bank has identified the sea (0.9 rad/s model leading from ≈ 218 s)
REDUCTION = 10.0              # at least 10× less wave-frequency force than raw feedback
STATION_RMS_BOUND_M = 0.05    # LF position error RMS after engagement (measured 0.033 m)
# maximum, engagement transient included: the vessel drifts with the current for the 20 s before DP
# engages (measured 0.133 m, then within 0.05 m of the setpoint). Measured with the gliding entry
# (``guidance.entry: glide``), whose reference follows the drift she had and decelerates it: the bound is how
# closely she tracks that. The default entry for a PID, ``stop``, starts the reference at rest where DP was
# engaged, so the error against it there is her stopping distance by design (0.198 m), while her distance
# from the set-point is smaller (test_the_stop_entry_keeps_her_closer_to_the_setpoint)
STATION_MAX_BOUND_M = 0.16
ENTRY = {"guidance": {"entry": "glide"}}


Run = tuple[dict, np.ndarray, "dict | None"]   # summary, WF-band force std (3,), the status's wave_band


def _simulation(overrides: dict | None = None) -> LockstepSimulation:
    scenario = load_scenario(builtin_scenario_path("cs2-seed000"))
    scenario = dataclasses.replace(scenario, setpoints=(Setpoint(0.0, 0.0, 0.0, 0.0),))
    return build_simulation(scenario, overrides=overrides)


def _run(estimator_kind: str) -> Run:
    overrides: dict = dict(ENTRY)
    if estimator_kind == "raw":   # the same noise settings, no wave states
        overrides["estimator"] = {"kind": "raw", "position_noise_std_m": 0.01, "heading_noise_std_rad": 1e-4}
    simulation = _simulation(overrides)
    result = simulation.run(duration_s=DURATION_S)
    c = result.columns
    data = c.data[: c.rows]
    t = data[:, c.index("t_s")]
    low = 0.5 * float(np.nanmin(data[:, c.index("motion_peak_rad_s")]))
    settled = t >= SETTLED_FROM_S
    wf = np.array([wave_frequency_std(data[settled, c.index(n)], result.config.sample_time_s, low)
                   for n in ("tau_x_n", "tau_y_n", "tau_n_nm")])
    return summarise(result), wf, simulation.controller.wave_band.summary()


@pytest.fixture(scope="module")
def filtered() -> Run:
    return _run("mmae")


@pytest.fixture(scope="module")
def raw() -> Run:
    return _run("raw")


def test_the_comparison_is_like_for_like(filtered: Run, raw: Run) -> None:
    assert filtered[0]["estimator"] == "mmae" and raw[0]["estimator"] == "raw"
    assert filtered[0]["control"] == raw[0]["control"] == "pid"
    assert filtered[0]["metrics"]["dominant_model_final_rad_s"] == 0.9


def test_wave_frequency_force_is_reduced_tenfold_in_surge_and_sway(filtered: Run,
                                                                  raw: Run) -> None:
    wf, wr = filtered[1], raw[1]
    ratio = wr / wf
    # raw feedback really carries the waves: far above the filtered floor (the test is not vacuous)
    assert wr[0] > 0.1 and wr[1] > 0.05, wr
    assert ratio[0] >= REDUCTION and ratio[1] >= REDUCTION, (
        f"surge {wr[0]:.4f}/{wf[0]:.4f} = {ratio[0]:.1f}×, sway {wr[1]:.4f}/{wf[1]:.4f} = {ratio[1]:.1f}×, "
        f"yaw {wr[2]:.4f}/{wf[2]:.4f} = {ratio[2]:.1f}×")


def test_station_keeping_within_the_documented_bound(filtered: Run) -> None:
    m = filtered[0]["metrics"]
    assert m["position_error_rms_m"] <= STATION_RMS_BOUND_M, m["position_error_rms_m"]
    assert m["position_error_max_m"] <= STATION_MAX_BOUND_M, m["position_error_max_m"]
    assert m["heading_error_max_deg"] <= 1.5, m["heading_error_max_deg"]
    assert math.isfinite(m["omega_hat_final_rad_s"])


def test_the_status_shows_how_much_wave_motion_reaches_the_controller(filtered: Run,
                                                                      raw: Run
                                                                      ) -> None:
    """The status's ``wave_band`` (the controller's running meter) tells the filtered run from the raw one.

    Measured 0.039 N against 0.233 N (6×): less than the offline measure's 14–20× because the meter's first-order
    band-pass is broad, its average (10 periods of the band's lower edge) still holds the engagement, and the raw
    run, without ω̂, keeps the configured band (0.15–2.7 rad/s), which reaches into the seed 000 loop's bandwidth.
    """
    band_f, band_r = filtered[2], raw[2]
    assert band_f is not None and band_r is not None
    assert band_r["force_n"] > 4.0 * band_f["force_n"], (band_r, band_f)
    assert band_f["lf_position_m"] < band_r["lf_position_m"], (band_r, band_f)


def _largest_distance_after_engagement_m(simulation: LockstepSimulation, until_s: float) -> tuple[float, float]:
    """The true LF position's distance from the set-point (the origin) when DP engaged and its largest after [m]."""
    result = simulation.run(duration_s=until_s)
    c = result.columns
    data = c.data[: c.rows]
    t = data[:, c.index("t_s")]
    distance = np.hypot(data[:, c.index("north_m")], data[:, c.index("east_m")])
    engaged = next(change[0] for change in result.mode_changes if change[2] == "auto_position")
    after = t >= engaged - 1e-9
    return float(distance[after][0]), float(np.max(distance[after]))


def test_the_stop_entry_keeps_her_closer_to_the_setpoint() -> None:
    """The default entry (``stop``) brakes the 20 s of drift at once: her largest distance from the set-point after
    the engagement is smaller than with the gliding reference (measured 0.730 m against 0.804 m, 0.668 m at the
    engagement)."""
    at_entry, stop = _largest_distance_after_engagement_m(_simulation(), 60.0)
    _, glide = _largest_distance_after_engagement_m(_simulation(ENTRY), 60.0)
    assert at_entry > 0.5, at_entry  # she did drift (the test is not vacuous)
    assert stop < glide - 0.03, (stop, glide)
