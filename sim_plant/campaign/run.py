"""``sim-plant campaign SPEC --out DIR``: expand the spec, run what is not finished yet, write the outputs.

Each finished run is written at once to ``DIR/runs/<key>.json`` (its result: the whole ``summary.json`` of the
run, or its error), the key being a hash of what the run computes. Rerunning into the same ``DIR`` skips every run
whose file is there (resume; ``retry_failed`` runs the failed ones again); a Ctrl-C cancels the runs still going
and writes ``campaign.csv``, ``campaign.json`` and the plots from what finished.
"""

from __future__ import annotations

import json
import logging
import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from sim_plant.campaign.engine import Engine
from sim_plant.campaign.outputs import build_rows, statistics, write_csv, write_plots
from sim_plant.campaign.spec import CampaignSpec, Run, expand

log = logging.getLogger(__name__)


@dataclass
class CampaignOutcome:
    """What a campaign call did."""

    out_dir: Path
    runs: list[Run]
    results: dict[str, dict[str, Any]]
    skipped: int
    interrupted: bool
    summary: dict[str, Any]
    plots: list[Path]


def load_results(runs_dir: Path) -> dict[str, dict[str, Any]]:
    """The results already in ``DIR/runs`` by key (unreadable files are skipped: those runs run again)."""
    results: dict[str, dict[str, Any]] = {}
    if not runs_dir.is_dir():
        return results
    for path in runs_dir.glob("*.json"):
        try:
            data = json.loads(path.read_text(encoding="utf-8"))
            results[str(data["key"])] = data["result"]
        except (OSError, ValueError, KeyError, TypeError):
            log.warning("ignoring unreadable run file %s (that run runs again)", path)
    return results


def _write_json(path: Path, data: Any) -> None:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(data, indent=1, allow_nan=False, default=str) + "\n", encoding="utf-8")
    os.replace(tmp, path)


def write_outputs(spec: CampaignSpec, runs: list[Run], results: Mapping[str, dict[str, Any]], out_dir: Path, *,
                  interrupted: bool, workers: int | None, plots: bool = True) -> tuple[dict[str, Any], list[Path]]:
    """``campaign.csv``, ``campaign.json`` and the plots from the results at hand."""
    columns, rows = build_rows(spec, runs, results)
    write_csv(out_dir / "campaign.csv", columns, rows)
    summary = statistics(spec, runs, columns, rows, results, interrupted=interrupted, workers=workers)
    _write_json(out_dir / "campaign.json", summary)
    return summary, (write_plots(spec, rows, out_dir) if plots and rows else [])


def run_campaign(spec: CampaignSpec, out_dir: Path, *, workers: int | None = None, scheduler: str | None = None,
                 progress: bool = False, retry_failed: bool = False, plots: bool = True) -> CampaignOutcome:
    """Run ``spec`` into ``out_dir`` (see the module docstring).

    Raises
    ------
    CampaignError
        A run's scenario or controller configuration is invalid (before anything runs).
    """
    runs = expand(spec)
    runs_dir = out_dir / "runs"
    runs_dir.mkdir(parents=True, exist_ok=True)
    results = load_results(runs_dir)
    todo = [r for r in runs if r.key not in results or (retry_failed and results[r.key].get("status") != "ok")]
    skipped = len(runs) - len(todo)
    if skipped:
        log.info("%s: %d of %d runs already finished in %s (resumed)", spec.name, skipped, len(runs), out_dir)

    def on_result(run: Run, result: dict[str, Any]) -> None:
        results[run.key] = result
        _write_json(runs_dir / f"{run.key}.json", {"key": run.key, "run": run.run, "labels": run.labels,
                                                     "result": result})
        if result.get("status") != "ok":
            log.warning("run %d failed: %s", run.run, result.get("error"))

    finished = True
    n_workers = None
    if todo:
        with Engine(workers, scheduler) as engine:
            n_workers = engine.n_workers
            log.info("%s: %d runs on %d workers%s", spec.name, len(todo), n_workers,
                     f" at {scheduler}" if scheduler else " (local processes)")
            finished = engine.run(todo, on_result, progress=progress, description=spec.name)
    summary, written = write_outputs(spec, runs, results, out_dir, interrupted=not finished, workers=n_workers,
                                     plots=plots)
    return CampaignOutcome(out_dir, runs, results, skipped, not finished, summary, written)
