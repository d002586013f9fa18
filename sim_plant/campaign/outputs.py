"""A campaign's outputs: ``campaign.csv`` (one row per run), ``campaign.json`` (counts and statistics) and plots.

Rows: ``run``, ``sample``, ``seed``, one column per varied path (the number drawn, or the label of a listed
value), every metric of the run's ``summary.json`` under the same name (a list metric as ``name[i]``), then
``engaged_at_s``, ``alarms_raised`` (codes in the order first raised), ``fault_detected_after_s[i]`` (per
scenario fault, from ``fault_detections``), ``status`` (``ok`` / ``failed``) and ``error`` (a failed run's
error). Nothing that depends on the machine (wall times) is in a row, so the same spec and seed give the same
rows on any number of workers.

Statistics per numeric column: count, min, median, p95, max — over all runs that finished ``ok``, and per value of
each paired entry; for a paired entry, also the paired differences against its first value (median of
``metric(value) − metric(first)`` over the samples where both finished, and the share of samples where the
value's metric is lower).
"""

from __future__ import annotations

import csv
import json
import math
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from sim_plant.campaign.spec import CampaignSpec, Run, VaryEntry

FIXED_COLUMNS = ("run", "sample", "seed")
TAIL_COLUMNS = ("status", "error")
DEFAULT_PLOT_METRICS = ("position_error_rms_m", "position_error_max_m", "heading_error_rms_deg",
                        "heading_error_max_deg", "position_error_max_after_settle_m",
                        "heading_error_max_after_settle_deg")


def flatten_metrics(summary: Mapping[str, Any]) -> dict[str, Any]:
    """The row cells of a run's summary (see the module docstring)."""
    cells: dict[str, Any] = {}
    for name, value in (summary.get("metrics") or {}).items():
        if isinstance(value, list):
            for i, item in enumerate(value):
                cells[f"{name}[{i}]"] = item
        else:
            cells[name] = value
    cells["engaged_at_s"] = summary.get("engaged_at_s")
    raised: list[str] = []
    for event in summary.get("alarm_events") or []:
        if event.get("raised") and event.get("code") not in raised:
            raised.append(str(event.get("code")))
    cells["alarms_raised"] = " ".join(raised)
    for i, detection in enumerate(summary.get("fault_detections") or []):
        cells[f"fault_detected_after_s[{i}]"] = detection.get("detected_after_s")
    return cells


def varied_cell(entry: VaryEntry, run: Run) -> Any:
    """A varied value in its row: a number as drawn, a listed value by its label."""
    value = run.values[entry.path]
    if entry.kind in ("uniform", "loguniform", "normal", "integers", "linspace") or (
            entry.kind == "same_as" and isinstance(value, (int, float))):
        return value
    return run.labels[entry.path]


def build_rows(spec: CampaignSpec, runs: Sequence[Run], results: Mapping[str, Mapping[str, Any]]
               ) -> tuple[list[str], list[dict[str, Any]]]:
    """(columns, rows) of the finished runs, in run order."""
    rows = []
    metric_columns: list[str] = []
    for run in runs:
        result = results.get(run.key)
        if result is None:
            continue
        row: dict[str, Any] = {"run": run.run, "sample": run.sample, "seed": run.seed}
        for entry in spec.entries:
            row[entry.path] = varied_cell(entry, run)
        if result.get("status") == "ok":
            cells = flatten_metrics(result["summary"])
            for name in cells:
                if name not in metric_columns:
                    metric_columns.append(name)
            row.update(cells)
            row["status"], row["error"] = "ok", ""
        else:
            row["status"], row["error"] = "failed", str(result.get("error", ""))
        rows.append(row)
    columns = [*FIXED_COLUMNS, *(e.path for e in spec.entries), *metric_columns, *TAIL_COLUMNS]
    return columns, rows


def _cell_text(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, float):  # (repr of a Python float: numpy 2 would write np.float64(...))
        return "" if not math.isfinite(value) else repr(float(value))
    if isinstance(value, (list, dict)):
        return json.dumps(value, separators=(",", ":"), sort_keys=True)
    return str(value)


def write_csv(path: Path, columns: Sequence[str], rows: Sequence[Mapping[str, Any]]) -> None:
    """``campaign.csv``: an empty cell where a run has no such value."""
    tmp = path.with_suffix(".csv.tmp")
    with tmp.open("w", encoding="utf-8", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(columns)
        for row in rows:
            writer.writerow([_cell_text(row.get(c)) for c in columns])
    tmp.replace(path)


def _stats(values: list[float]) -> dict[str, float | int]:
    a = np.asarray(values, dtype=float)
    return {"count": int(a.size), "min": float(a.min()), "median": float(np.median(a)),
            "p95": float(np.percentile(a, 95)), "max": float(a.max())}


def numeric_columns(columns: Sequence[str], rows: Sequence[Mapping[str, Any]], skip: Sequence[str]) -> list[str]:
    """The columns holding numbers in the ``ok`` rows (not ``skip``)."""
    out = []
    for column in columns:
        if column in skip or column in TAIL_COLUMNS:
            continue
        values = [r.get(column) for r in rows if r.get("status") == "ok" and r.get(column) is not None]
        if values and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values):
            out.append(column)
    return out


def _column_stats(rows: Sequence[Mapping[str, Any]], metrics: Sequence[str]) -> dict[str, Any]:
    out = {}
    for metric in metrics:
        values = [float(r[metric]) for r in rows if r.get("status") == "ok" and isinstance(r.get(metric), (int, float))
                  and math.isfinite(float(r[metric]))]
        if values:
            out[metric] = _stats(values)
    return out


def statistics(spec: CampaignSpec, runs: Sequence[Run], columns: Sequence[str], rows: Sequence[Mapping[str, Any]],
               results: Mapping[str, Mapping[str, Any]], *, interrupted: bool, workers: int | None) -> dict[str, Any]:
    """``campaign.json`` (see the module docstring)."""
    skip = [*FIXED_COLUMNS, *(e.path for e in spec.entries)]
    metrics = numeric_columns(columns, rows, skip)
    failures = [{"run": r["run"], "values": {e.path: r[e.path] for e in spec.entries}, "error": r["error"]}
                for r in rows if r["status"] != "ok"]
    finished = [results[r.key] for r in runs if r.key in results]
    doc: dict[str, Any] = {
        "name": spec.name, "spec": spec.source, "base": spec.base, "seed": spec.seed,
        "runs": len(runs), "finished": len(rows), "ok": sum(r["status"] == "ok" for r in rows),
        "failed": len(failures), "not_run": len(runs) - len(rows), "interrupted": interrupted,
        "varied": [{"path": e.path, "kind": e.kind, "paired": e.paired} for e in spec.entries],
        "simulated_s": round(sum(float(f.get("simulated_s", 0.0)) for f in finished), 3),
        "run_wall_s": round(sum(float(f.get("wall_s", 0.0)) for f in finished), 3),
        "workers": workers, "failures": failures,
        "metrics": _column_stats(rows, metrics),
    }
    by_paired: dict[str, Any] = {}
    differences: dict[str, Any] = {}
    for entry in spec.paired:
        groups = {label: [r for r in rows if r[entry.path] == label] for label in entry.labels}
        by_paired[entry.path] = {label: _column_stats(group, metrics) for label, group in groups.items()}
        first = entry.labels[0]
        differences[entry.path] = {}
        for label in entry.labels[1:]:
            differences[entry.path][f"{label} - {first}"] = _paired_differences(spec, entry, rows, metrics, first=first,
                                                                                 label=label)
    if by_paired:
        doc["by_paired"] = by_paired
        doc["paired_differences"] = differences
    return doc


def _paired_differences(spec: CampaignSpec, entry: VaryEntry, rows: Sequence[Mapping[str, Any]],
                        metrics: Sequence[str], *, first: str, label: str) -> dict[str, Any]:
    """Per metric: the median of metric(label) − metric(first) over the samples where both ran ``ok`` with the
    other paired entries equal, and the share of those samples where label's metric is lower."""
    others = [e.path for e in spec.paired if e.path != entry.path]

    def pair_key(row: Mapping[str, Any]) -> tuple[Any, ...]:
        return (row["sample"], *(row[p] for p in others))

    firsts = {pair_key(r): r for r in rows if r[entry.path] == first and r["status"] == "ok"}
    out = {}
    for metric in metrics:
        diffs = []
        for row in rows:
            if row[entry.path] != label or row["status"] != "ok":
                continue
            base = firsts.get(pair_key(row))
            a, b = row.get(metric), None if base is None else base.get(metric)
            if isinstance(a, (int, float)) and isinstance(b, (int, float)) and math.isfinite(a) and math.isfinite(b):
                diffs.append(float(a) - float(b))
        if diffs:
            d = np.asarray(diffs)
            out[metric] = {"pairs": int(d.size), "median_difference": float(np.median(d)),
                           "share_lower": float(np.mean(d < 0.0)), "share_higher": float(np.mean(d > 0.0))}
    return out


def _file_part(path: str) -> str:
    return re.sub(r"[^A-Za-z0-9_]+", "_", path).strip("_") or "value"


def write_plots(spec: CampaignSpec, rows: Sequence[Mapping[str, Any]], out_dir: Path) -> list[Path]:
    """``by_<paired path>.png`` (box plots of the metrics per value of each paired entry) and
    ``against_<path>.png`` (each metric against each varied value; one colour per value of the first paired
    entry). Returns the written paths."""
    import matplotlib  # noqa: PLC0415 - heavy; only when plotting

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    ok = [r for r in rows if r.get("status") == "ok"]
    wanted = spec.plot_metrics or DEFAULT_PLOT_METRICS
    metrics = [m for m in wanted if any(isinstance(r.get(m), (int, float)) for r in ok)][:4]
    if not ok or not metrics:
        return []
    paths = []
    colour_entry = spec.paired[0] if spec.paired else None
    for entry in spec.paired:
        fig, axes = plt.subplots(1, len(metrics), figsize=(3.6 * len(metrics), 4.0), squeeze=False)
        for ax, metric in zip(axes[0], metrics, strict=True):
            data = [[float(r[metric]) for r in ok if r[entry.path] == label and isinstance(r.get(metric), (int, float))]
                    for label in entry.labels]
            ax.boxplot([d if d else [math.nan] for d in data], tick_labels=list(entry.labels), showfliers=True)
            ax.set_title(metric, fontsize=9)
            ax.tick_params(axis="x", labelrotation=30, labelsize=8)
            ax.grid(alpha=0.3)
        fig.suptitle(f"{spec.name}: metrics per {entry.path} ({len(ok)} runs)")
        fig.tight_layout()
        paths.append(_save(fig, out_dir / f"by_{_file_part(entry.path)}.png"))
    for entry in spec.entries:
        if entry.paired:
            continue
        fig, axes = plt.subplots(1, len(metrics), figsize=(3.6 * len(metrics), 3.8), squeeze=False)
        if entry.kind == "same_as":
            continue  # (the same as the entry it copies)
        numeric = entry.kind in ("uniform", "loguniform", "normal", "integers", "linspace")
        categories = list(entry.labels) if not numeric else []
        for ax, metric in zip(axes[0], metrics, strict=True):
            groups = colour_entry.labels if colour_entry else (None,)
            for group in groups:
                sel = [r for r in ok if (group is None or r[colour_entry.path] == group)  # type: ignore[union-attr]
                       and isinstance(r.get(metric), (int, float))]
                if numeric:
                    x = [float(r[entry.path]) for r in sel]
                else:
                    x = [categories.index(r[entry.path]) if r[entry.path] in categories else -1 for r in sel]
                ax.plot(x, [float(r[metric]) for r in sel], "o", ms=4, alpha=0.7,
                        label=None if group is None else str(group))
            if not numeric:
                ax.set_xticks(range(len(categories)), categories, rotation=30, fontsize=8)
            ax.set_xlabel(entry.path, fontsize=8)
            ax.set_title(metric, fontsize=9)
            ax.grid(alpha=0.3)
        if colour_entry:
            axes[0][0].legend(fontsize=7, title=colour_entry.path, title_fontsize=7)
        fig.suptitle(f"{spec.name}: metrics against {entry.path}")
        fig.tight_layout()
        paths.append(_save(fig, out_dir / f"against_{_file_part(entry.path)}.png"))
    return paths


def _save(fig: Any, path: Path) -> Path:
    import matplotlib.pyplot as plt  # noqa: PLC0415

    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
