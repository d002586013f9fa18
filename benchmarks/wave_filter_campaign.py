"""How much wave motion reaches the DP controller: random seas per built-in DP vessel, filtered vs raw.

For each seed, a random sea for each vessel (CyberShip II, the supply vessel, the Blue Lady, the shuttle tanker),
station keeping at the origin in lockstep, run once per estimator (``mmae``, ``pem`` … and ``raw``: the same LF
filter without wave states, so the wave-frequency motion reaches the controller) with the same PID (the vessel's
example PID settings from ``deploy/config``, else the default PID). Measured from ``--settle`` s on:

* ``force×`` / ``yaw×``: the commanded force's wave-band std, raw / filtered — horizontal force (surge and sway
  together, √(σx² + σy²)) and yaw moment; the wave band is ``[ωm/2, 3ωm]`` with ωm the motion spectrum's peak
  (the plant's ``motion_peak_rad_s``), Welch PSD;
* ``lf%``: the wave-band std of the LF position estimate's error (estimate − true LF position: the wave motion
  the filter lets through) in % of the true wave-frequency position motion's (what the sensors see minus their
  noise), horizontal; ``lfψ%`` the same for the heading;
* ``ω̂/ωm``: the estimator's final peak-frequency estimate against the motion spectrum's peak;
* ``err``: LF position error RMS [m] in DP (true LF position against the setpoint), for the filtered and the
  raw run.

Random sea per (vessel, seed), from ``numpy.random.default_rng([vessel index, seed])``, Froude scaled to the
vessel with ``scale = min(1, L/76.2 m)`` (the supply vessel's length; a shorter hull is a model of a 76.2 m one):
JONSWAP Hs uniform in 0.5–4 m × scale, peak ωp uniform in 0.35–1.3 rad/s / √scale (CyberShip II × 7.8:
2.7–10.1 rad/s; the Blue Lady × 2.35), γ uniform in 1–5 (spectral width), direction uniform over the whole circle
relative to the heading; current 0–0.5 m/s × √scale toward a random direction; wind 0–12 m/s × √scale from within
±45° of the waves. ``--full-scale-periods`` keeps ωp in 0.35–1.3 rad/s for every vessel (a model in seas of
full-scale period, where CyberShip II's yaw loop lies inside the wave band); the draws are the same, only ωp
differs. ``--swell`` adds a swell to each sea from its own draws (see :func:`random_sea`): the same wind seas,
currents and winds, with a swell beside them.

The estimators: ``mmae`` with the example's grid when it has one (a vessel of at least 76.2 m; with
``--full-scale-periods`` every vessel), else the default grid scaled to the vessel (``DEFAULT_OMEGAS_RAD_S`` ×
√(76.2 m/L)): CyberShip II's example keeps seed 000's bank for the seed 000 sea, whose period is a full-scale
one, and that bank ends a decade below the Froude-scaled seas drawn here. ``pem`` with the vessel's defaults (ω0
and search range scaled the same way; with ``--full-scale-periods`` the unscaled 0.8 rad/s and 0.2–2 rad/s).

Usage::

    nice -n 10 .venv/bin/python benchmarks/wave_filter_campaign.py --seeds 0 1 --vessels supply
    nice -n 10 .venv/bin/python benchmarks/wave_filter_campaign.py --seeds $(seq 0 29) --json out.json
    nice -n 10 .venv/bin/python benchmarks/wave_filter_campaign.py --full-scale-periods --vessels cybership2
    nice -n 10 .venv/bin/python benchmarks/wave_filter_campaign.py --vessels blue_lady --sensor-noise-scale 0.1
    .venv/bin/python benchmarks/wave_filter_campaign.py --summarise out.json      # the table of what ran

``--sensor-noise-scale`` multiplies the seed scenario's position and heading sensor noise (and so the filters' R,
which follows the sensors): whether what a filter lets through is the waves or the sensors' noise.

Every line printed is one run; the summary at the end gives, per vessel and estimator, the share of runs with
≥ 10× (horizontal and yaw), the median ratios, the share with LF content ≤ 10 %, and the ω̂ hits.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from scipy.signal import welch

from dpcontrol.estimation.filter_config import DEFAULT_OMEGAS_RAD_S, wave_frequency_scale
from dpcontrol.models.vessels import vessel_from_config
from dpcontrol.runtime.config import CONTROLLER_SECTIONS
from sim_plant.bench.run import build_simulation
from sim_plant.scenario import parse_scenario

ROOT = Path(__file__).resolve().parents[1]
REFERENCE_LENGTH_M = 76.2        # the supply vessel: Hs 0.5–4 m at this length
#: vessel → (its seed scenario, for sensors and datum; its example configuration)
VESSELS: dict[str, tuple[str, str]] = {
    "cybership2": ("cs2-seed000.yaml", "cybership2.yaml"),
    "supply": ("supply-seed001.yaml", "supply.yaml"),
    "blue_lady": ("bluelady-seed004.yaml", "blue_lady.yaml"),
    "shuttle_tanker": ("tanker-seed003.yaml", "shuttle_tanker.yaml"),
}
DEFAULT_GRID = [float(w) for w in DEFAULT_OMEGAS_RAD_S]          # at full scale
#: the unscaled defaults of PEM (the campaign with --full-scale-periods)
FULL_SCALE_PEM = {"omega0_rad_s": 0.8, "rpem_omega_min_rad_s": 0.2, "rpem_omega_max_rad_s": 2.0}


def random_sea(vessel: str, seed: int, length_m: float, *, full_scale_periods: bool = False,
               swell: bool = False) -> dict[str, Any]:
    """The random environment of (vessel, seed), in scenario-file units (degrees).

    Froude scaled with ``scale = min(1, L/L_ref)``: heights × scale, speeds × √scale, frequencies / √scale
    (``full_scale_periods``: frequencies unscaled). The draws do not depend on ``full_scale_periods``. ``swell``:
    a swell beside the wind sea, from its own stream (the wind sea, current and wind are those drawn without it):
    Hs 0.5–2.5 m × scale, peak 0.35–0.6 rad/s (Tp 10–18 s at full scale), γ 3–8, from any direction.
    """
    rng = np.random.default_rng([list(VESSELS).index(vessel), seed])
    scale = min(1.0, length_m / REFERENCE_LENGTH_M)
    frequency_scale = 1.0 if full_scale_periods else 1.0 / math.sqrt(scale)
    wave_from = float(rng.uniform(0.0, 360.0))
    sea: dict[str, Any] = {"t_s": 0, "spectrum": "jonswap", "hs_m": round(float(rng.uniform(0.5, 4.0)) * scale, 4),
                           "omega_peak_rad_s": round(float(rng.uniform(0.35, 1.3)) * frequency_scale, 4),
                           "gamma": round(float(rng.uniform(1.0, 5.0)), 2), "direction_deg": round(wave_from, 1),
                           "fade_s": 1}
    if swell:
        swell_rng = np.random.default_rng([list(VESSELS).index(vessel), seed, 1])
        sea["swell"] = {"hs_m": round(float(swell_rng.uniform(0.5, 2.5)) * scale, 4),
                        "omega_peak_rad_s": round(float(swell_rng.uniform(0.35, 0.6)) * frequency_scale, 4),
                        "gamma": round(float(swell_rng.uniform(3.0, 8.0)), 2),
                        "direction_deg": round(float(swell_rng.uniform(0.0, 360.0)), 1)}
    return {
        "sea_states": [sea],
        "current": {"speed_mps": round(float(rng.uniform(0.0, 0.5)) * math.sqrt(scale), 4),
                    "direction_deg": round(float(rng.uniform(0.0, 360.0)), 1)},
        "wind": {"speed_mps": round(float(rng.uniform(0.0, 12.0)) * math.sqrt(scale), 3),
                 "direction_deg": round(wave_from + float(rng.uniform(-45.0, 45.0)), 1) % 360.0},
    }


def controller_sections(vessel: str, estimator: dict[str, Any], control: dict[str, Any] | None = None
                        ) -> dict[str, Any]:
    """The example configuration's controller sections with ``estimator`` and a PID (``control`` if given)."""
    config = yaml.safe_load((ROOT / "deploy" / "config" / VESSELS[vessel][1]).read_text(encoding="utf-8"))
    sections = {key: config[key] for key in CONTROLLER_SECTIONS if key in config}
    if control is not None:
        sections["control"] = control
    elif sections.get("control", {}).get("kind") != "pid":
        sections["control"] = {"kind": "pid"}
    sections["estimator"] = estimator
    sections.pop("loop", None)   # standby starts etc. are the installation's; the campaign engages DP at once
    return sections


def estimator_section(kind: str, vessel: str, *, full_scale_periods: bool = False) -> dict[str, Any]:
    """The estimator under test (module docstring): the example's MMAE grid when it has one and the seas are the
    ones it was chosen for, else the default grid (scaled to the vessel unless ``full_scale_periods``); PEM with
    the vessel's defaults (the unscaled ones with ``full_scale_periods``); the example's ``lf_yaw_bandwidth_rad_s``
    (a property of its yaw loop, not of the filter kind) for every wave filter."""
    config = yaml.safe_load((ROOT / "deploy" / "config" / VESSELS[vessel][1]).read_text(encoding="utf-8"))
    example = config.get("estimator", {})
    loop = {key: example[key] for key in ("lf_yaw_bandwidth_rad_s",) if key in example}
    frequency_scale = 1.0 if full_scale_periods else wave_frequency_scale(vessel_from_config(config["vessel"]).length_m)
    if kind == "mmae":
        grid = example.get("omegas_rad_s") if example.get("kind") == "mmae" and frequency_scale == 1.0 else None
        return {"kind": "mmae", "omegas_rad_s": grid or [round(frequency_scale * w, 4) for w in DEFAULT_GRID], **loop}
    if kind == "pem":
        return {"kind": "pem", **(FULL_SCALE_PEM if full_scale_periods else {}), **loop}
    if kind == "raw":
        # the baseline stays what it was before the wave filter's rule changed (LF velocity noise 0.002·√(gL),
        # bias drift 100 s): the measure must not move when the filter's tuning does
        return {"kind": "raw", **former_rule(vessel)}
    return {"kind": kind}


def former_rule(vessel: str) -> dict[str, float]:
    """The LF process-noise rule of the wave filters before docs/wave-filter.md's changes (for ``raw`` and
    ``--former-rule``)."""
    config = yaml.safe_load((ROOT / "deploy" / "config" / VESSELS[vessel][1]).read_text(encoding="utf-8"))
    length = vessel_from_config(config["vessel"]).length_m
    return {"lf_velocity_std_mps": 0.002 * math.sqrt(9.81 * length),
            "lf_yaw_rate_std_radps": 0.002 * math.sqrt(9.81 / length), "bias_drift_time_s": 100.0,
            "bias_yaw_drift_time_s": 100.0, "wf_heading_std_rad": math.radians(0.5)}


def band_std(x: np.ndarray, dt_s: float, low_rad_s: float, high_rad_s: float) -> float:
    """Std of ``x`` within [low, high] rad/s (Welch PSD, ~120 s Hann segments, linear detrend)."""
    x = x[np.isfinite(x)]
    segment = int(min(x.size, 2 ** round(math.log2(max(64.0, 120.0 / dt_s)))))
    freq_hz, psd = welch(x, fs=1.0 / dt_s, nperseg=segment, detrend="linear")
    omega = 2.0 * math.pi * freq_hz
    band = (omega >= low_rad_s) & (omega <= high_rad_s)
    return float(math.sqrt(float(np.sum(psd[band])) * float(freq_hz[1] - freq_hz[0])))


def run_one(vessel: str, seed: int, kind: str, duration_s: float, settle_s: float, *,  # noqa: PLR0913 - one keyword per option of the command line
            options: dict[str, Any] | None = None, control: dict[str, Any] | None = None, former: bool = False,
            full_scale_periods: bool = False, sensor_noise_scale: float = 1.0, swell: bool = False
            ) -> dict[str, Any]:
    """One run; the measured figures (see the module docstring). ``sensor_noise_scale`` multiplies the white noise
    of the seed scenario's position and heading sensors (and so the filters' R, which follows the sensors)."""
    base = yaml.safe_load((ROOT / "sim_plant" / "scenarios" / VESSELS[vessel][0]).read_text(encoding="utf-8"))
    length = vessel_from_config(base["vessel"]).length_m
    scenario_map = {key: base[key] for key in ("vessel", "datum", "sensors", "plant") if key in base}
    scenario_map["sensors"] = [{key: value * sensor_noise_scale if key in ("noise_m", "noise_deg") else value
                                for key, value in sensor.items()} for sensor in base["sensors"]]
    scenario_map.update(name=f"campaign-{vessel}-{seed}", duration_s=duration_s, seed=1000 + seed,
                        setpoints=[{"t_s": 0, "north_m": 0, "east_m": 0, "heading_deg": 0}],
                        **random_sea(vessel, seed, length, full_scale_periods=full_scale_periods, swell=swell))
    scenario = parse_scenario(scenario_map, file=f"<campaign {vessel} {seed}>")
    estimator = estimator_section(kind, vessel, full_scale_periods=full_scale_periods)
    if former and kind != "raw":
        estimator.update(former_rule(vessel))
    if options and kind != "raw":
        estimator.update(options)
    overrides = controller_sections(vessel, estimator, control)
    started = time.process_time()
    result = build_simulation(scenario, overrides=overrides).run(duration_s=duration_s)
    cpu_s = time.process_time() - started
    c = result.columns
    d = c.data[: c.rows]

    def col(name: str) -> np.ndarray:
        return d[:, c.index(name)]

    dt = result.config.sample_time_s
    t = col("t_s")
    keep = (t >= settle_s) & (col("mode") == 2)
    motion = col("motion_peak_rad_s")[keep]
    omega_m = float(np.nanmedian(motion))
    low, high = 0.5 * omega_m, min(3.0 * omega_m, 0.9 * math.pi / dt)

    def bs(name: str) -> float:
        return band_std(col(name)[keep], dt, low, high)

    wf_north = col("north_total_m") - col("north_m")
    wf_east = col("east_total_m") - col("east_m")
    wf_psi = col("heading_total_rad") - col("heading_rad")
    true_wf = math.hypot(band_std(wf_north[keep], dt, low, high), band_std(wf_east[keep], dt, low, high))
    true_wf_psi = band_std(wf_psi[keep], dt, low, high)
    error = np.hypot(col("north_m") - col("ref_north_m"), col("east_m") - col("ref_east_m"))[keep]
    omega_hat = col("omega_hat_rad_s")[keep]
    tail = omega_hat[int(0.8 * omega_hat.size):]
    return {
        "vessel": vessel, "seed": seed, "estimator": kind,
        "sea": random_sea(vessel, seed, length, full_scale_periods=full_scale_periods, swell=swell),
        "full_scale_periods": full_scale_periods, "grid_rad_s": estimator.get("omegas_rad_s"),
        "omega_motion_rad_s": omega_m, "band_rad_s": [low, high],
        "force_wf": math.hypot(bs("tau_x_n"), bs("tau_y_n")), "yaw_wf": bs("tau_n_nm"),
        "lf_wf_fraction": math.hypot(band_std((col("est_north_m") - col("north_m"))[keep], dt, low, high),
                                     band_std((col("est_east_m") - col("east_m"))[keep], dt, low, high)) / true_wf
        if true_wf > 0 else math.nan,
        "lf_heading_wf_fraction": band_std((col("est_heading_rad") - col("heading_rad"))[keep], dt, low, high)
        / true_wf_psi if true_wf_psi > 0 else math.nan,
        "true_wf_position_m": true_wf, "true_wf_heading_deg": math.degrees(true_wf_psi),
        "omega_hat_rad_s": float(np.nanmean(tail)) if np.any(np.isfinite(tail)) else math.nan,
        "lf_error_rms_m": float(np.sqrt(np.mean(error**2))) if error.size else math.nan,
        "cpu_s": cpu_s,
    }


def grid_step(vessel: str, omega: float, *, full_scale_periods: bool = False) -> float:
    """The MMAE grid's largest spacing [rad/s] (``omega``, the motion peak, is not used yet)."""
    grid = np.array(estimator_section("mmae", vessel, full_scale_periods=full_scale_periods)["omegas_rad_s"],
                    dtype=float)
    if grid.size < 2:
        return math.inf
    return float(np.max(np.diff(grid)))


def summarise(rows: list[dict[str, Any]], kinds: list[str]) -> None:
    """Acceptance-style table per vessel and filtered estimator."""
    print("\nvessel          estimator  runs  ≥10×(F&N)  median F×  median N×  LF≤10%  med LF%  ω̂ ok  "
          "err filt/raw [m]")
    for vessel in dict.fromkeys(r["vessel"] for r in rows):
        raw = {r["seed"]: r for r in rows if r["vessel"] == vessel and r["estimator"] == "raw"}
        for kind in kinds:
            if kind == "raw":
                continue
            runs = [(r, raw[r["seed"]]) for r in rows
                    if r["vessel"] == vessel and r["estimator"] == kind and r["seed"] in raw]
            if not runs:
                continue
            f = np.array([b["force_wf"] / max(a["force_wf"], 1e-12) for a, b in runs])
            n = np.array([b["yaw_wf"] / max(a["yaw_wf"], 1e-12) for a, b in runs])
            lf = np.array([a["lf_wf_fraction"] for a, _ in runs])
            if kind == "pem":
                hit = [abs(a["omega_hat_rad_s"] / a["omega_motion_rad_s"] - 1.0) <= 0.1 for a, _ in runs]
            else:
                hit = [abs(a["omega_hat_rad_s"] - a["omega_motion_rad_s"])
                       <= grid_step(vessel, a["omega_motion_rad_s"],
                                    full_scale_periods=a.get("full_scale_periods", True)) for a, _ in runs]
            err_f = np.median([a["lf_error_rms_m"] for a, _ in runs])
            err_r = np.median([b["lf_error_rms_m"] for _, b in runs])
            print(f"{vessel:<15} {kind:<9} {len(runs):>5}  {100 * np.mean((f >= 10) & (n >= 10)):>8.0f} %"
                  f"  {np.median(f):>9.1f}  {np.median(n):>9.1f}  {100 * np.mean(lf <= 0.1):>5.0f} %"
                  f"  {100 * np.median(lf):>6.1f}  {100 * np.mean(hit):>4.0f} %  {err_f:.3g}/{err_r:.3g}")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1])
    parser.add_argument("--vessels", nargs="+", choices=list(VESSELS), default=list(VESSELS))
    parser.add_argument("--estimators", nargs="+", default=["mmae", "pem", "raw"])
    parser.add_argument("--duration", type=float, default=1200.0, help="simulated seconds per run")
    parser.add_argument("--settle", type=float, default=600.0, help="measure from this time on [s]")
    parser.add_argument("--options", type=json.loads, help="estimator options added to every filtered run (JSON)")
    parser.add_argument("--control", type=json.loads, help="a control section replacing the example's PID (JSON)")
    parser.add_argument("--json", type=Path, help="write every run's figures here")
    parser.add_argument("--former-rule", action="store_true",
                        help="filtered runs with the LF noise rule before docs/wave-filter.md (\"today\")")
    parser.add_argument("--full-scale-periods", action="store_true",
                        help="peak 0.35-1.3 rad/s for every vessel, unscaled estimator frequencies (a model in "
                             "seas of full-scale period)")
    parser.add_argument("--sensor-noise-scale", type=float, default=1.0,
                        help="multiply the position and heading sensors' white noise (is a leak noise or waves?)")
    parser.add_argument("--swell", action="store_true",
                        help="a swell beside each wind sea (its own draws; the wind sea, current and wind unchanged)")
    parser.add_argument("--summarise", type=Path, help="only print the summary of a --json file")
    args = parser.parse_args()
    if args.summarise:
        rows = json.loads(args.summarise.read_text(encoding="utf-8"))
        summarise(rows, list(dict.fromkeys(r["estimator"] for r in rows)))
        return 0
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    rows: list[dict[str, Any]] = []
    print("vessel          seed estimator  ωm     ω̂      F_wf        N_wf        LF%    LFψ%   err[m]  cpu[s]",
          flush=True)
    for seed in args.seeds:
        for vessel in args.vessels:
            for kind in args.estimators:
                r = run_one(vessel, seed, kind, args.duration, args.settle, options=args.options, control=args.control,
                            former=args.former_rule, full_scale_periods=args.full_scale_periods,
                            sensor_noise_scale=args.sensor_noise_scale, swell=args.swell)
                rows.append(r)
                print(f"{vessel:<15} {seed:>4} {kind:<9} {r['omega_motion_rad_s']:.3f}  {r['omega_hat_rad_s']:.3f}  "
                      f"{r['force_wf']:10.4g}  {r['yaw_wf']:10.4g}  {100 * r['lf_wf_fraction']:5.1f}  "
                      f"{100 * r['lf_heading_wf_fraction']:5.1f}  {r['lf_error_rms_m']:.3g}  {r['cpu_s']:.0f}",
                      flush=True)
                if args.json:   # after every run: an interrupted campaign keeps what ran (--summarise reads it)
                    args.json.write_text(json.dumps(rows, indent=1), encoding="utf-8")
    summarise(rows, args.estimators)
    return 0


if __name__ == "__main__":
    sys.exit(main())
