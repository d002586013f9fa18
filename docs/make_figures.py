"""README figures the built-in ``sim-plant run`` plots do not draw: comparisons across runs.

Reads the ``timeseries.csv`` of ``sim-plant run`` output directories and writes three PNGs:

* ``seed004-bluelady-velocity.png`` — Kalman–Bucy velocity estimates against the plant's true LF
  velocities (cf. seed 004 Figs. 4–6); the y axes span t ≥ 25 s, clipping the filter's start-up transient;
* ``seed002-mariner-rudder.png`` — rudder angle with and without the wave filter (cf. seed 002 Fig. 9);
* ``seed003-tanker-tracking.png`` — MRAC against the fixed-gain PD (adaptation off): tracking error
  y − y_M in surge and the MRAC surge mass estimate (cf. seed 003 Figs. 9, 11 and 13).

Usage (from the repository root, after the runs listed in the README's Results section)::

    .venv/bin/python docs/make_figures.py --results /tmp/results --out docs/img

``--results`` holds the run directories ``bluelady``, ``mariner``, ``mariner-nofilter``, ``tanker-mrac``
and ``tanker-fixed``; a figure whose runs are missing is skipped with a message.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from sim_plant.bench.report import band_std

ENGAGED_S = 20.0  # every seed scenario engages DP / the autopilot at 20 s
KB_SETTLED_S = 25.0  # seed 004: the Kalman–Bucy start-up transient (P0 = I) is over
MARINER_WAVE_BAND_RAD_S = (0.7, 1.8)  # around the mariner's yaw motion peak (1.05–1.33 rad/s encounter)
PLOT_POINTS = 20_000  # long runs are decimated for drawing only; metrics use every sample


def read_columns(run_dir: Path, names: tuple[str, ...]) -> dict[str, np.ndarray]:
    """Columns ``names`` of ``run_dir/timeseries.csv`` (header row of column names, then numbers; empty = NaN)."""
    path = run_dir / "timeseries.csv"
    with path.open() as f:
        header = f.readline().strip().split(",")
    missing = [n for n in names if n not in header]
    if missing:
        raise KeyError(f"{path}: no column(s) {missing}")
    index = [header.index(n) for n in names]
    # an empty field is missing data (e.g. no MRAC state before engagement): NaN here
    data = np.loadtxt(path, delimiter=",", skiprows=1, usecols=index, ndmin=2,
                      converters=lambda field: float(field) if field.strip() else math.nan)
    return {name: data[:, i] for i, name in enumerate(names)}


def rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x * x)))


def bluelady_velocity(run_dir: Path, out: Path) -> None:
    axes_spec = (("surge_mps", "u [m/s]", 1.0), ("sway_mps", "v [m/s]", 1.0),
                 ("yaw_rate_radps", "r [deg/s]", 180.0 / math.pi))
    names = ("t_s", *(n for n, _, _ in axes_spec), *(f"est_{n}" for n, _, _ in axes_spec))
    c = read_columns(run_dir, names)
    t = c["t_s"]
    settled = t >= KB_SETTLED_S
    fig, axes = plt.subplots(3, 1, figsize=(11, 8), sharex=True)
    for ax, (name, label, scale) in zip(axes, axes_spec, strict=True):
        error = rms((c[f"est_{name}"] - c[name])[settled]) * scale
        unit = label.split("[")[1].rstrip("]")
        print(f"seed004 {name}: estimate error rms (t >= {KB_SETTLED_S:g} s) = {error:.4f} {unit}")
        ax.plot(t, c[f"est_{name}"] * scale, color="tab:blue", lw=0.7,
                label=f"Kalman–Bucy estimate (error rms {error:.3g} {unit})")
        ax.plot(t, c[name] * scale, color="k", lw=1.2, label="true (plant LF)")
        # y range of the settled part: the first seconds' start-up transient (P0 = I) is clipped
        low, high = (float(f(np.r_[c[f"est_{name}"][settled], c[name][settled]] * scale)) for f in (np.min, np.max))
        margin = 0.15 * (high - low)
        ax.set_ylim(low - margin, high + margin)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
        ax.legend(loc="upper right", fontsize=8)
    axes[0].set_title("bluelady-seed004 — velocities estimated from GNSS + gyro only (cf. seed 004 Figs. 4–6)")
    axes[-1].set_xlabel("t [s]")
    save(fig, out / "seed004-bluelady-velocity.png")


def mariner_rudder(filtered_dir: Path, unfiltered_dir: Path, out: Path) -> None:
    names = ("t_s", "azimuth_main_propeller_rad", "heading_rad", "ref_heading_rad")
    runs = {"with wave filter": read_columns(filtered_dir, names),
            "wave filter off": read_columns(unfiltered_dir, names)}
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(11, 7), sharex=True)
    wf = {}
    for (label, c), color in zip(runs.items(), ("tab:blue", "tab:red"), strict=True):
        t = c["t_s"]
        engaged = t >= ENGAGED_S
        # the runtime commands azimuth −δ for a rudder aft (see tests/closed_loop/test_seed002.py)
        delta_deg = -np.degrees(c["azimuth_main_propeller_rad"])
        wf[label] = band_std(delta_deg[engaged], float(t[1] - t[0]), MARINER_WAVE_BAND_RAD_S)
        error_deg = np.degrees(np.angle(np.exp(1j * (c["heading_rad"] - c["ref_heading_rad"]))))
        ax1.plot(t, np.degrees(c["heading_rad"]), color=color, lw=0.9,
                 label=f"heading, {label} (error rms {rms(error_deg[engaged]):.2f}°)")
        ax2.plot(t, delta_deg, color=color, lw=0.8, alpha=0.85,
                 label=f"δ, {label} (WF band σ {wf[label]:.2f}°)")
    ax1.plot(t, np.degrees(c["ref_heading_rad"]), "k:", lw=1.0, label="heading reference")
    ratio = wf["wave filter off"] / wf["with wave filter"]
    print(f"seed002 rudder WF band {MARINER_WAVE_BAND_RAD_S} rad/s std: " + ", ".join(
        f"{k} {v:.3f} deg" for k, v in wf.items()) + f"; ratio {ratio:.2f}")
    ax1.set_ylabel("heading [deg]")
    ax1.legend(loc="upper right", fontsize=8)
    ax1.grid(alpha=0.3)
    ax1.set_title(f"mariner-seed002 — rudder with and without the wave filter: {ratio:.1f}× less WF rudder "
                  "(cf. seed 002 Fig. 9)")
    ax2.set_ylabel("rudder δ [deg]")
    ax2.set_xlabel("t [s]")
    ax2.legend(loc="upper right", fontsize=8)
    ax2.grid(alpha=0.3)
    save(fig, out / "seed002-mariner-rudder.png")


def tanker_tracking(mrac_dir: Path, fixed_dir: Path, out: Path) -> None:
    names = ("t_s", "north_m", "mrac_ref_model_north_m", "mrac_mass_surge_kg", "true_surge_mass_kg")
    runs = {"MRAC": read_columns(mrac_dir, names), "fixed-gain PD (mrac-fixed)": read_columns(fixed_dir, names)}
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(11, 7), sharex=True)
    for (label, c), color in zip(runs.items(), ("tab:blue", "tab:red"), strict=True):
        t_h = c["t_s"] / 3600.0
        step = max(1, t_h.size // PLOT_POINTS)
        # e = y − y_M of the true LF surge position (summary.json's mrac_tracking_error_* use the same y)
        error = c["north_m"] - c["mrac_ref_model_north_m"]
        engaged = c["t_s"] >= ENGAGED_S
        for name, hours in (("first hour", t_h < 1.0), ("last hour", t_h >= t_h[-1] - 1.0)):
            sel = engaged & hours
            print(f"seed003 {label}: |y - y_M| {name} max {np.max(np.abs(error[sel])):.3f} m, "
                  f"rms {rms(error[sel]):.3f} m")
        ax1.plot(t_h[::step], error[::step], color=color, lw=0.6, alpha=0.8, label=f"{label}: y − y_M (true LF)")
        if label == "MRAC":
            ax2.plot(t_h[::step], c["mrac_mass_surge_kg"][::step], color=color, lw=1.0,
                     label="MRAC surge mass estimate")
            ax2.plot(t_h[::step], c["true_surge_mass_kg"][::step], "k--", lw=1.0, label="true surge mass (m + added)")
            final = c["mrac_mass_surge_kg"][-1] / c["true_surge_mass_kg"][-1] - 1.0
            print(f"seed003 MRAC mass estimate at the end: {100.0 * final:+.1f} % of the true surge mass")
    ax1.set_ylabel("surge tracking error [m]")
    ax1.legend(loc="upper left", fontsize=8)
    ax1.grid(alpha=0.3)
    ax1.set_title("tanker-seed003 — 12 h offloading, mass × 2.66: MRAC against fixed gains "
                  "(cf. seed 003 Figs. 9, 11, 13)")
    ax2.set_ylabel("mass [kg]")
    ax2.set_xlabel("t [h]")
    ax2.legend(loc="upper left", fontsize=8)
    ax2.grid(alpha=0.3)
    save(fig, out / "seed003-tanker-tracking.png")


def save(fig: plt.Figure, path: Path) -> None:
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    print(f"wrote {path} ({path.stat().st_size / 1e3:.0f} kB)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--results", type=Path, default=Path("/tmp/results"), help="directory of the run outputs")
    parser.add_argument("--out", type=Path, default=Path(__file__).parent / "img", help="where the PNGs go")
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    figures = ((bluelady_velocity, ("bluelady",)), (mariner_rudder, ("mariner", "mariner-nofilter")),
               (tanker_tracking, ("tanker-mrac", "tanker-fixed")))
    for make, runs in figures:
        dirs = [args.results / r for r in runs]
        if all((d / "timeseries.csv").is_file() for d in dirs):
            make(*dirs, args.out)
        else:
            print(f"skipped {make.__name__}: needs {', '.join(str(d) for d in dirs)}")


if __name__ == "__main__":
    main()
