"""Outputs of ``sim-plant run``: ``timeseries.csv``, ``summary.json`` and the PNG plots (docs/design.md §4.3).

The time series has one row per control step and the columns of docs/design.md §4.3 (empty cell where
a value does not exist, headings wrapped to (−π, π]); the summary lists the bank's model
frequencies and the metrics an engineer judges a run by: station-keeping error against the
reference, estimation error against the plant's true low-frequency motion, the wave filter's
frequency estimate against the wave and motion spectrum peaks (docs/design.md §5 trap 3), the
wave-frequency content of the commanded force, the MRAC mass estimate against the true mass, and
the alarms and mode changes.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from scipy.signal import welch

from dpbase.frames import ssa_array
from dpcontrol.runtime.alarms import AlarmEvent
from dpcontrol.runtime.config import DaemonConfig
from dpcontrol.runtime.transport_health import MIN_BAD_FOR_ALARM
from sim_plant.bench.lockstep import Columns, RunResult
from sim_plant.faults import Fault

PLOT_POINTS = 20000


def write_timeseries_csv(columns: Columns, path: Path) -> None:
    """Write the rows as CSV: ``%.9g`` numbers, an empty cell for a missing value (NaN)."""
    data = columns.data[: columns.rows]
    fmt = ",".join(["%.9g"] * data.shape[1]) + "\n"
    with path.open("w", encoding="utf-8", newline="") as handle:
        handle.write(",".join(columns.names) + "\n")
        chunk = 4096
        for start in range(0, data.shape[0], chunk):
            block = "".join(fmt % tuple(row) for row in data[start:start + chunk].tolist())
            handle.write(block.replace("nan", ""))


def wrap_headings(columns: Columns) -> None:
    """Wrap every ``*heading*_rad`` column to (−π, π] in place."""
    for i, name in enumerate(columns.names):
        if "heading" in name and name.endswith("_rad"):
            values = columns.data[: columns.rows, i]
            finite = np.isfinite(values)
            values[finite] = ssa_array(values[finite])


def _rms(x: np.ndarray) -> float | None:
    x = x[np.isfinite(x)]
    return None if x.size == 0 else float(np.sqrt(np.mean(x * x)))


def _max_abs(x: np.ndarray) -> float | None:
    x = x[np.isfinite(x)]
    return None if x.size == 0 else float(np.max(np.abs(x)))


def _degrees(value_rad: float | None) -> float | None:
    return None if value_rad is None else math.degrees(value_rad)


def _round(value: float | None, digits: int = 6) -> float | None:
    return None if value is None or not math.isfinite(value) else round(value, digits)


def _finite_std(values: np.ndarray) -> float | None:
    """Standard deviation of the finite ``values``; None when there are none (a run shorter than the settling
    time: nanstd would warn and return NaN)."""
    finite = values[np.isfinite(values)]
    return float(np.std(finite)) if finite.size else None


def wave_frequency_std(signal: np.ndarray, dt_s: float, low_rad_s: float) -> float | None:
    """Standard deviation of the part of ``signal`` above ``low_rad_s``: √(∫_{ω ≥ low} PSD dω).

    The wave-frequency content of a commanded force: a wave filter should keep it small. The PSD is
    Welch's estimate (``scipy.signal.welch``: Hann-windowed segments of about 60 s, or the whole record
    if shorter, each linearly detrended), because a plain FFT of the record treats it as periodic: the
    jump between a force that ends at its holding value and one that started near zero, and any drift,
    spread over all frequencies and swamp the wave-frequency part (that was the old estimate's floor).
    """
    x = signal[np.isfinite(signal)]
    if x.size < 64:
        return None
    segment = int(min(x.size, 2 ** round(math.log2(max(64.0, 60.0 / dt_s)))))
    freq_hz, psd = welch(x, fs=1.0 / dt_s, nperseg=segment, detrend="linear")
    band = 2.0 * math.pi * freq_hz >= low_rad_s
    return float(math.sqrt(float(np.sum(psd[band])) * float(freq_hz[1] - freq_hz[0])))


def band_std(signal: np.ndarray, dt_s: float, band_rad_s: tuple[float, float]) -> float:
    """Standard deviation of the part of ``signal`` inside ``band_rad_s`` [rad/s] (FFT band-pass, mean
    removed): the wave-band motion of a rudder, where the record is a whole number of course changes and
    a plain FFT band-pass is what the seed 002 comparison needs."""
    x = signal - signal.mean()
    spectrum = np.fft.rfft(x)
    omega = 2.0 * math.pi * np.fft.rfftfreq(x.size, dt_s)
    spectrum[(omega < band_rad_s[0]) | (omega > band_rad_s[1])] = 0.0
    return float(np.std(np.fft.irfft(spectrum, x.size)))


def settle_time_s(low_rad_s: float) -> float:
    """Time skipped after DP engages before the wave-frequency metrics: three periods of the cutoff
    (the engagement transient's content at frequency ω has decayed within a few of its periods)."""
    return 3.0 * 2.0 * math.pi / low_rad_s


def summarise(result: RunResult) -> dict[str, Any]:
    """Metrics of a run (see the module docstring)."""
    c = result.columns
    d = c.data[: c.rows]

    def col(name: str) -> np.ndarray:
        return d[:, c.index(name)]

    dt = result.config.sample_time_s
    t = col("t_s")
    mode = col("mode")
    engaged = np.flatnonzero(mode > 0)
    summary: dict[str, Any] = {
        "scenario": result.scenario.name,
        "vessel": result.scenario.vessel.name,
        "duration_s": _round(float(t[-1]), 3),
        "seed": result.scenario.seed,
        "sample_time_s": dt,
        "steps": result.steps,
        "estimator": result.config.estimator.kind,
        "control": result.config.control.kind,
        "control_adapt": getattr(result.config.control.config, "adapt", None),
        "model_frequencies_rad_s": list(result.omegas_rad_s),
        "wall_time_s": _round(result.wall_s, 3),
        "speed_x_realtime": _round(float(t[-1]) / result.wall_s if result.wall_s > 0 else None, 1),
        "mode_changes": [{"t_s": round(m[0], 3), "from": m[1], "to": m[2], "reason": m[3]}
                         for m in result.mode_changes],
        "alarms": result.alarms,
        "alarm_events": [{"t_s": round(e.t_s, 3), "code": e.code, "raised": e.raised,
                          "severity": e.severity.name.lower(), "text": e.text} for e in result.alarm_events],
        "fault_detections": [{"t_s": d.fault.t_s, "kind": d.fault.kind, "target": d.fault.target,
                              "alarms": list(d.codes), "bound_s": _round(d.bound_s, 3),
                              "detected_after_s": _round(d.detected_s, 3), "alarm": d.code}
                             for d in fault_detections(result)],
        "counters": result.counters,
    }
    if result.interrupted_at_s is not None:  # Ctrl-C: the metrics cover the part that ran
        summary["interrupted_at_s"] = _round(result.interrupted_at_s, 3)
    metrics: dict[str, Any] = {}
    if engaged.size:
        k0 = int(engaged[0])
        summary["engaged_at_s"] = _round(float(t[k0]), 3)
        sl = slice(k0, None)
        error_north = col("north_m")[sl] - col("ref_north_m")[sl]
        error_east = col("east_m")[sl] - col("ref_east_m")[sl]
        e_h = ssa_array(col("heading_rad")[sl] - col("ref_heading_rad")[sl])
        horizontal = np.hypot(error_north, error_east)
        if np.any(mode[sl] == 2):  # position errors only mean something in DP (auto_position)
            metrics["position_error_rms_m"] = _round(_rms(horizontal[mode[sl] == 2]))
            metrics["position_error_max_m"] = _round(_max_abs(horizontal[mode[sl] == 2]))
        metrics["heading_error_rms_deg"] = _round(_degrees(_rms(e_h)))
        metrics["heading_error_max_deg"] = _round(_degrees(_max_abs(e_h)))
        total = np.hypot(col("north_total_m")[sl] - col("ref_north_m")[sl], col("east_total_m")[sl]
                         - col("ref_east_m")[sl])
        if np.any(mode[sl] == 2):
            metrics["total_position_error_max_m"] = _round(_max_abs(total[mode[sl] == 2]))
    est = slice(int(np.flatnonzero(np.isfinite(col("est_north_m")))[0]) if np.any(np.isfinite(col("est_north_m")))
                else d.shape[0], None)
    metrics["estimate_error_rms_north_m"] = _round(_rms(col("est_north_m")[est] - col("north_m")[est]))
    metrics["estimate_error_rms_east_m"] = _round(_rms(col("est_east_m")[est] - col("east_m")[est]))
    metrics["estimate_error_rms_heading_deg"] = _round(
        _degrees(_rms(ssa_array(col("est_heading_rad")[est] - col("heading_rad")[est]))))
    omega_hat = col("omega_hat_rad_s")
    if np.any(np.isfinite(omega_hat)):
        tail = slice(int(0.8 * d.shape[0]), None)
        metrics["omega_hat_final_rad_s"] = _round(float(omega_hat[np.isfinite(omega_hat)][-1]))
        metrics["omega_hat_mean_last_20pct_rad_s"] = _round(float(np.nanmean(omega_hat[tail])))
    peak = col("omega_peak_rad_s")
    motion = col("motion_peak_rad_s")
    if np.any(np.isfinite(peak)):
        metrics["wave_peak_final_rad_s"] = _round(float(peak[np.isfinite(peak)][-1]))
    if np.any(np.isfinite(motion)):
        metrics["motion_peak_final_rad_s"] = _round(float(motion[np.isfinite(motion)][-1]))
    if result.omegas_rad_s:
        first = c.index("weight_0")
        weights = d[:, first:first + len(result.omegas_rad_s)]
        final = weights[-1]
        if np.all(np.isfinite(final)):
            best = int(np.argmax(final))
            metrics["dominant_model_final_rad_s"] = result.omegas_rad_s[best]
            metrics["dominant_weight_final"] = _round(float(final[best]))
            metrics["weights_final"] = [_round(float(w)) for w in final]
        summary["dominant_model_by_sea_state"] = _dominant_by_sea_state(result, weights, t)
    low = None
    motion_values = motion[np.isfinite(motion)]
    if motion_values.size:
        low = 0.5 * float(np.min(motion_values))
    if low is not None and engaged.size:
        # from engagement + the settling time (the engagement transient is no wave-frequency content)
        start = int(engaged[0]) + round(settle_time_s(low) / dt)
        sl = slice(start, None)
        metrics["tau_wave_frequency_std"] = [_round(wave_frequency_std(col(n)[sl], dt, low))
                                             for n in ("tau_x_n", "tau_y_n", "tau_n_nm")]
        metrics["tau_wave_frequency_from_s"] = _round(float(t[min(start, t.size - 1)]), 3)
        metrics["tau_std"] = [_round(_finite_std(col(n)[sl])) for n in ("tau_x_n", "tau_y_n", "tau_n_nm")]
    mass = col("mrac_mass_surge_kg")
    if np.any(np.isfinite(mass)):
        true_mass = col("true_surge_mass_kg")
        last = np.flatnonzero(np.isfinite(mass))[-1]
        metrics["mrac_mass_surge_final_kg"] = _round(float(mass[last]), 1)
        metrics["true_surge_mass_final_kg"] = _round(float(true_mass[last]), 1)
        metrics["mrac_mass_surge_error_pct"] = _round(100.0 * (mass[last] - true_mass[last]) / true_mass[last], 3)
    if engaged.size:
        metrics.update(_setpoint_metrics(result, d, c.index, int(engaged[0])))
    summary["metrics"] = metrics
    return summary


def _setpoint_metrics(result: RunResult, d: np.ndarray, index: Any, k0: int) -> dict[str, Any]:
    """Per set-point segment (from each set-point time to the next, while engaged): the overshoot of
    the true LF position beyond a new position set-point along the direction of the move [m], and for
    the MRAC the tracking error ``|y − y_M|`` of the true LF position against its reference model
    (seed 003 Figs. 9, 13), horizontal [m]. Segments before engagement are left out."""
    t = d[:, index("t_s")]
    north = d[:, index("north_m")]
    east = d[:, index("east_m")]
    out: dict[str, Any] = {}
    points = result.scenario.setpoints
    bounds = [(float(sp.t_s), float(points[i + 1].t_s) if i + 1 < len(points) else math.inf)
              for i, sp in enumerate(points)]
    overshoots: list[float | None] = []
    for i in range(1, len(points)):
        start, end = bounds[i]
        sel = (t >= max(start, float(t[k0]))) & (t < end)
        old, new = points[i - 1], points[i]
        if new.north_m is None or old.north_m is None or new.east_m is None or old.east_m is None:
            continue  # a heading-only set-point on either side: no position move to overshoot
        step = (new.north_m - old.north_m, new.east_m - old.east_m)
        length = math.hypot(*step)
        if not np.any(sel) or length == 0.0:
            continue
        along = (step[0] * (north[sel] - new.north_m) + step[1] * (east[sel] - new.east_m)) / length
        overshoots.append(_round(max(0.0, float(np.max(along)))))
    if overshoots:
        out["overshoot_by_setpoint_m"] = overshoots
    ym = d[:, index("mrac_ref_model_north_m")]
    if np.any(np.isfinite(ym)):
        error = np.hypot(north - ym, east - d[:, index("mrac_ref_model_east_m")])
        valid = np.isfinite(error)
        valid[:k0] = False
        out["mrac_tracking_error_rms_m"] = _round(_rms(error[valid]))
        out["mrac_tracking_error_max_m"] = _round(_max_abs(error[valid]))
        by_segment = []
        for start, end in bounds:
            sel = valid & (t >= start) & (t < end)
            if np.any(sel):
                by_segment.append(_round(float(np.max(error[sel]))))
        out["mrac_tracking_error_max_by_setpoint_m"] = by_segment
    return out


def _dominant_by_sea_state(result: RunResult, weights: np.ndarray, t: np.ndarray) -> list[dict[str, Any]]:
    """For each sea state: the model that dominates at its end and when it first took over."""
    out = []
    states = result.scenario.sea_states
    for i, state in enumerate(states):
        end = states[i + 1].t_s if i + 1 < len(states) else float(t[-1]) + 1e-9
        mask = (t >= state.t_s) & (t < end) & np.all(np.isfinite(weights), axis=1)
        if not np.any(mask):
            continue
        idx = np.flatnonzero(mask)
        best = int(np.argmax(weights[idx[-1]]))
        dominant = np.argmax(weights[idx], axis=1) == best
        # first time from which the final model stays dominant until the end of the sea state
        not_dom = np.flatnonzero(~dominant)
        since = t[idx[0]] if not_dom.size == 0 else (t[idx[not_dom[-1] + 1]] if not_dom[-1] + 1 < idx.size else None)
        out.append({"from_s": state.t_s, "omega_peak_rad_s": getattr(state, "omega_peak_rad_s", None),
                    "dominant_model_rad_s": result.omegas_rad_s[best],
                    "dominant_from_s": None if since is None else round(float(since), 2),
                    "switch_time_s": None if since is None else round(float(since) - state.t_s, 2)})
    return out


def write_summary(result: RunResult, path: Path) -> dict[str, Any]:
    summary = summarise(result)
    path.write_text(json.dumps(summary, indent=2, allow_nan=False) + "\n", encoding="utf-8")
    return summary


@dataclass(frozen=True)
class PlotEvent:
    """A moment every time plot marks: ``kind`` is ``setpoint`` (a set-point change), ``dp_on`` / ``dp_off``
    (DP engaged / left: a mode change into or out of ``auto_position`` / ``auto_heading``) or ``sea`` (a new sea
    state begins, its cross-fade starts)."""

    t_s: float
    kind: str


EVENT_STYLE: dict[str, dict[str, Any]] = {
    "setpoint": {"color": "k", "ls": ":", "lw": 0.9},
    "dp_on": {"color": "tab:green", "ls": "-", "lw": 1.3},
    "dp_off": {"color": "tab:brown", "ls": "-", "lw": 1.3},
    "sea": {"color": "tab:purple", "ls": "-.", "lw": 1.1},
}
EVENT_LABEL = {"setpoint": "set-point change", "dp_on": "DP engaged", "dp_off": "DP left", "sea": "sea-state change"}
DP_MODES = ("auto_position", "auto_heading")


def plot_events(setpoint_times: Sequence[float], sea_state_times: Sequence[float],
                modes: Sequence[tuple[float, str]]) -> list[PlotEvent]:
    """The events to mark, in time order: set-point changes, sea-state changes (the first sea state, in force
    from the start, is no change) and DP engagement from ``modes``, ``(t_s, mode)`` of each mode in force
    from ``t_s`` on (a mode repeated is no change)."""
    events = [PlotEvent(float(t), "setpoint") for t in setpoint_times]
    events += [PlotEvent(float(t), "sea") for t in sorted(sea_state_times)[1:]]
    in_dp = False
    for t, mode in modes:
        now_dp = mode in DP_MODES
        if now_dp != in_dp:
            events.append(PlotEvent(float(t), "dp_on" if now_dp else "dp_off"))
        in_dp = now_dp
    return sorted(events, key=lambda e: e.t_s)


def run_events(result: RunResult) -> list[PlotEvent]:
    """:func:`plot_events` of a lockstep run: the scenario's set-points and sea states, its mode changes."""
    scenario = result.scenario
    initial = result.config.initial_mode
    modes = [(0.0, initial)] + [(t, to) for t, _from, to, _why in result.mode_changes]
    return plot_events([p.t_s for p in scenario.setpoints], [s.t_s for s in scenario.sea_states], modes)


def mark_events(fig: Any, events: Sequence[PlotEvent], t_range: tuple[float, float] | None = None) -> None:
    """Draw each event as a vertical line on every axes of ``fig`` (time on x) and a figure legend of the kinds
    drawn; events outside ``t_range`` (when given) are left out."""
    shown = [e for e in events if t_range is None or t_range[0] <= e.t_s <= t_range[1]]
    for ax in fig.axes:
        for event in shown:
            ax.axvline(event.t_s, **EVENT_STYLE[event.kind])
    kinds = [k for k in EVENT_STYLE if any(e.kind == k for e in shown)]
    if kinds:
        from matplotlib.lines import Line2D  # noqa: PLC0415

        fig.legend([Line2D([], [], **EVENT_STYLE[k]) for k in kinds], [EVENT_LABEL[k] for k in kinds],
                   loc="lower right", ncol=len(kinds), fontsize=8, frameon=False)


def write_plots(result: RunResult, out_dir: Path) -> list[Path]:  # noqa: PLR0915 - one plot after another
    """PNG plots an engineer expects (see the module docstring). Returns the written paths."""
    import matplotlib  # noqa: PLC0415  (heavy; only when plots are asked for)

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    c = result.columns
    d = c.data[: c.rows]
    step = max(1, d.shape[0] // PLOT_POINTS)
    d = d[::step]

    def col(name: str) -> np.ndarray:
        return d[:, c.index(name)]

    t = col("t_s")
    paths: list[Path] = []
    title = f"{result.scenario.name} — {result.config.estimator.kind} + {result.config.control.kind}"
    events = run_events(result)
    span = (float(t[0]), float(t[-1])) if t.size else None

    def save(fig: Any, name: str) -> Path:
        mark_events(fig, events, span)
        return _save(fig, out_dir / name)

    # the scenario's set-point as a step (what the operator asked for; the reference is the way there)
    setpoint = _setpoint_steps(result.scenario.setpoints, t)

    fig, axes = plt.subplots(3, 1, figsize=(11, 9), sharex=True)
    for ax, (truth, total, meas, est, ref, label, scale) in zip(axes, (
            ("north_m", "north_total_m", "meas_north_m", "est_north_m", "ref_north_m", "north [m]", 1.0),
            ("east_m", "east_total_m", "meas_east_m", "est_east_m", "ref_east_m", "east [m]", 1.0),
            ("heading_rad", "heading_total_rad", "meas_heading_rad", "est_heading_rad", "ref_heading_rad",
             "heading [deg]", 180.0 / math.pi)), strict=True):
        ax.plot(t, col(meas) * scale, color="0.75", lw=0.6, label="measurement (fused)")
        ax.plot(t, col(total) * scale, color="tab:blue", lw=0.5, alpha=0.5, label="true total (LF + WF)")
        ax.plot(t, col(truth) * scale, color="tab:blue", lw=1.4, label="true LF")
        ax.plot(t, col(est) * scale, color="tab:orange", lw=1.0, ls="--", label="LF estimate")
        ax.plot(t, col(ref) * scale, color="k", lw=0.8, ls=":", label="reference")
        ax.step(t, setpoint[truth] * scale, where="post", color="tab:red", lw=1.0, label="set-point")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper left", fontsize=8, ncol=3)
    axes[0].set_title(title)
    axes[-1].set_xlabel("t [s]")
    paths.append(save(fig, "pose.png"))

    if result.omegas_rad_s:
        first = c.index("weight_0")
        fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(11, 7), sharex=True)
        for i, omega in enumerate(result.omegas_rad_s):
            ax1.plot(t, d[:, first + i], lw=1.2, label=f"{omega:.2f} rad/s")
        ax1.set_ylabel("MMAE weight")
        ax1.set_ylim(-0.02, 1.02)
        ax1.legend(fontsize=8, ncol=4)
        ax1.grid(alpha=0.3)
        ax1.set_title(f"{title}: dynamic weights (cf. seed 000 Fig. 3)")
        ax2.plot(t, col("omega_hat_rad_s"), label="ω̂ (weight-averaged)")
        ax2.plot(t, col("omega_peak_rad_s"), "k--", lw=1, label="wave spectrum peak")
        ax2.plot(t, col("motion_peak_rad_s"), "r:", lw=1.2, label="motion spectrum peak")
        ax2.set_ylabel("ω [rad/s]")
        ax2.set_xlabel("t [s]")
        ax2.legend(fontsize=8)
        ax2.grid(alpha=0.3)
        paths.append(save(fig, "weights.png"))
    elif np.any(np.isfinite(col("omega_hat_rad_s"))):
        fig, ax = plt.subplots(figsize=(11, 4))
        ax.plot(t, col("omega_hat_rad_s"), label="ω̂")
        ax.plot(t, col("omega_peak_rad_s"), "k--", label="wave spectrum peak")
        ax.plot(t, col("motion_peak_rad_s"), "r:", label="motion spectrum peak")
        ax.set_ylabel("ω [rad/s]")
        ax.set_xlabel("t [s]")
        ax.legend()
        ax.grid(alpha=0.3)
        ax.set_title(f"{title}: peak frequency estimate")
        paths.append(save(fig, "omega.png"))

    fig, axes = plt.subplots(3, 1, figsize=(11, 8), sharex=True)
    for ax, (cmd, act, label) in zip(axes, (("tau_x_n", "tau_act_x_n", "X [N]"), ("tau_y_n", "tau_act_y_n", "Y [N]"),
                                            ("tau_n_nm", "tau_act_n_nm", "N [N·m]")), strict=True):
        ax.plot(t, col(cmd), lw=0.8, label="commanded")
        ax.plot(t, col(act), lw=0.8, alpha=0.8, label="delivered")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    axes[0].set_title(f"{title}: generalized force")
    axes[-1].set_xlabel("t [s]")
    paths.append(save(fig, "forces.png"))

    thrust_cols = [n for n in c.names if n.startswith("thrust_")]
    if thrust_cols:
        fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(11, 7), sharex=True)
        for name in thrust_cols:
            ax1.plot(t, col(name), lw=0.8, label=name[len("thrust_"):-2])
        for name in (n for n in c.names if n.startswith("azimuth_")):
            ax2.plot(t, np.degrees(col(name)), lw=0.8, label=name[len("azimuth_"):-4])
        ax1.set_ylabel("thrust command [N]")
        ax2.set_ylabel("azimuth / rudder [deg]")
        ax2.set_xlabel("t [s]")
        ax1.legend(fontsize=8, ncol=3)
        ax1.grid(alpha=0.3)
        ax2.grid(alpha=0.3)
        ax1.set_title(f"{title}: thruster usage")
        paths.append(save(fig, "thrusters.png"))

    if np.any(np.isfinite(col("mrac_mass_surge_kg"))):
        fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(11, 7), sharex=True)
        ax1.plot(t, col("mrac_mass_surge_kg"), label="MRAC surge mass estimate â2")
        ax1.plot(t, col("true_surge_mass_kg"), "k--", label="true surge mass (m + added)")
        ax1.set_ylabel("mass [kg]")
        ax1.legend(fontsize=8)
        ax1.grid(alpha=0.3)
        ax1.set_title(f"{title}: MRAC parameter estimates (cf. seed 003 Fig. 11)")
        ax2.plot(t, col("mrac_damping_surge_nspm"), label="surge damping estimate â1")
        ax2.set_ylabel("damping [N·s/m]")
        ax2.set_xlabel("t [s]")
        ax2.grid(alpha=0.3)
        paths.append(save(fig, "mrac.png"))
    return paths


def _setpoint_steps(setpoints: Sequence[Any], t: np.ndarray) -> dict[str, np.ndarray]:
    """The set-point in force at each ``t`` [s] per pose column (NaN before the first, or where a set-point
    leaves that coordinate out: heading-only)."""
    steps = {key: np.full(t.shape, np.nan) for key in ("north_m", "east_m", "heading_rad")}
    for point in sorted(setpoints, key=lambda p: p.t_s):
        after = t >= point.t_s
        for key, column in steps.items():
            value = getattr(point, key)
            column[after] = np.nan if value is None else value
    return steps


def _save(fig: Any, path: Path) -> Path:
    fig.tight_layout(rect=(0.0, 0.03, 1.0, 1.0) if fig.legends else None)
    fig.savefig(path, dpi=110)
    import matplotlib.pyplot as plt  # noqa: PLC0415

    plt.close(fig)
    return path


# ------------------------------------------------------------------------------------------------
# Fault injections: which alarm proves each one was detected, and when it was due (docs/fault-handling.md)
# ------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class FaultDetection:
    """How one injected fault was detected.

    Attributes
    ----------
    fault : Fault
    codes : tuple of str
        Alarm codes any of which proves the detection.
    bound_s : float or None
        Largest delay from the fault's start to the alarm allowed by the configuration [s] (None: the
        kind has no alarm of its own in this configuration, e.g. noise on the only reference).
    detected_s : float or None
        Delay to the first raise of one of ``codes`` at or after the start [s] (None: never).
    code : str or None
        The code that was raised first.
    """

    fault: Fault
    codes: tuple[str, ...]
    bound_s: float | None
    detected_s: float | None
    code: str | None

    @property
    def within_bound(self) -> bool:
        return self.detected_s is not None and self.bound_s is not None and self.detected_s <= self.bound_s + 1e-6


def expected_detection(fault: Fault, config: DaemonConfig) -> tuple[tuple[str, ...], float | None]:  # noqa: PLR0911 - one return per fault kind
    """The alarm codes that prove ``fault`` was detected, and the configured bound on the delay [s].

    Bounds (``dt`` the control period, ``T`` the target sensor's nominal period): freeze
    ``freeze_window_s + T + dt``; drop-out and invalid data ``stale_periods·T + dt``; a jump or a gyro
    offset beyond the prediction limit ``reject_persist_s + T + dt`` (the sample itself is rejected at
    once; the alarm comes when the rejection persists, or the estimator reset when every reference of
    the kind jumped; none for a jump shorter than ``reject_persist_s``, whose samples are rejected
    without an alarm); a drift ``limit / rate + median_filter_s + median_persist_s + 5 s`` with the median
    limit (≥ 3 references: isolation; 2: disagreement) or the prediction limit (alone); noise
    ``3 × variance_time_constant_s`` (≥ 2 references); a tripped drive ``feedback_timeout_s``; a thrust
    mismatch ``mismatch_persist_s + 2 s``; a burst ``dt + 1 s`` (none below ``MIN_BAD_FOR_ALARM`` items;
    NMEA 2000 fast packets time out after 0.75 s); an unplugged port ``dt``; a heartbeat loss
    ``heartbeat_timeout_s + 1 s + dt``.
    """
    hub = config.hub
    dt = config.sample_time_s
    target = fault.target
    routes = {r.sensor.name: r for r in config.routes}
    kind = fault.kind
    monitor = config.thruster_monitor
    if kind.startswith("thruster_"):
        code = (f"thruster.{target}.unavailable",)
        if kind == "thruster_not_ready":
            return code, monitor.feedback_timeout_s
        return code, monitor.mismatch_persist_s + 2.0
    route = routes.get(target)
    if route is None:
        return (), None
    period = 1.0 / route.sensor.nominal_rate_hz
    heading = route.sensor.kind.value == "heading"
    same_kind = [r for r in config.routes if r.sensor.kind is route.sensor.kind]
    n_refs = len(same_kind)
    transport = route.transport
    if kind in ("gnss_freeze", "gyro_freeze"):
        return (f"sensor.{target}.frozen",), hub.freeze_window_s + period + dt
    if kind in ("gnss_dropout", "gyro_dropout", "gnss_invalid", "gyro_invalid"):
        return (f"sensor.{target}.stale",), hub.stale_periods * period + dt
    if kind in ("gnss_jump", "gyro_offset"):
        limit = hub.heading_jump_min_rad if heading else hub.jump_min_m
        size = abs(fault.offset_rad) if heading else fault.offset_m
        if size <= limit:
            median = hub.median_heading_limit_rad if heading else hub.median_limit_m
            if size <= median or n_refs < 2:
                return (), None
            codes: tuple[str, ...] = ((f"sensor.{target}.isolated",) if n_refs >= 3
                                      else (f"{route.sensor.kind.value}.disagree",))
            return codes, hub.median_filter_s + hub.median_persist_s + 5.0
        if fault.end_s - fault.t_s < hub.reject_persist_s:
            return (), None  # each sample is rejected at once; too short to be marked (or to reset)
        return (f"sensor.{target}.rejected", "estimator.reset"), hub.reject_persist_s + period + dt
    if kind in ("gnss_drift", "gyro_drift"):
        rate = abs(fault.rate_radps) if heading else fault.rate_mps
        if rate <= 0.0:
            return (), None
        if n_refs >= 3:
            codes = (f"sensor.{target}.isolated", f"sensor.{target}.rejected")
            limit = hub.median_heading_limit_rad if heading else hub.median_limit_m
        elif n_refs == 2:
            codes = (f"{route.sensor.kind.value}.disagree", f"sensor.{target}.rejected")
            limit = hub.median_heading_limit_rad if heading else hub.median_limit_m
        else:
            codes = (f"sensor.{target}.rejected", "estimator.reset")
            limit = hub.heading_jump_min_rad if heading else hub.jump_min_m
        return codes, limit / rate + hub.median_filter_s + hub.median_persist_s + 5.0
    if kind == "gnss_noise":
        if n_refs < 2 or fault.factor <= hub.variance_alarm_factor:
            return (), None
        return (f"sensor.{target}.noisy",), 3.0 * hub.variance_time_constant_s
    if kind == "malformed_burst":
        if fault.count < MIN_BAD_FOR_ALARM:
            return (), None  # rejected and counted, below the alarm's minimum of bad frames
        return (f"transport.{transport}.error_rate",), dt + 1.0
    if kind == "serial_unplug":
        return (f"transport.{transport}.link", f"sensor.{target}.disconnected"), dt
    if kind == "heartbeat_loss":
        settings = next(t.settings for t in config.transports if t.name == transport)
        system = route.system_id or 1
        return (f"transport.{transport}.system{system}.link",), float(settings["heartbeat_timeout_s"]) + 1.0 + dt
    return (), None


def first_raise(events: Sequence[AlarmEvent], codes: Sequence[str], after_s: float,
                before_s: float = math.inf) -> tuple[float, str] | None:
    """Time and code of the first raise of one of ``codes`` in ``[after_s, before_s]`` (None: none)."""
    for event in events:
        if event.t_s > before_s + 1e-9:
            break
        if event.raised and event.t_s >= after_s - 1e-9 and event.code in codes:
            return event.t_s, event.code
    return None


def fault_detections(result: RunResult) -> list[FaultDetection]:
    """Detection of every fault of the scenario, from the run's alarm events (see :func:`expected_detection`):
    the first raise of one of its codes while it lasts (a permanent fault: to the end of the run), or within twice
    its bound of its start. A detection later than the bound is reported with its delay (the reader compares it
    with ``bound_s``), never as none."""
    out = []
    for fault in result.scenario.faults:
        codes, bound = expected_detection(fault, result.config)
        # searched while the fault lasts, and at least twice its bound (a burst has no duration)
        until = max(fault.end_s, fault.t_s + 2.0 * (bound or 0.0))
        hit = first_raise(result.alarm_events, codes, fault.t_s, until) if codes else None
        delay = None if hit is None else hit[0] - fault.t_s
        out.append(FaultDetection(fault, codes, bound, delay, None if hit is None else hit[1]))
    return out
