"""``sim-plant run SCENARIO --out DIR``: a lockstep closed-loop run and its report."""

from __future__ import annotations

import logging
import sys
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from dpbase.schema import ConfigError
from dpcontrol.runtime.config import load_config, parse_config
from sim_plant.bench.lockstep import LockstepSimulation, RunResult, lockstep_config
from sim_plant.bench.report import wrap_headings, write_plots, write_summary, write_timeseries_csv
from sim_plant.scenario import Scenario

log = logging.getLogger(__name__)


@dataclass
class RunOutputs:
    """Where a run's report went, and its summary."""

    out_dir: Path
    timeseries: Path
    summary_path: Path
    plots: list[Path]
    summary: dict[str, Any]
    result: RunResult


def build_simulation(scenario: Scenario, controller_config: str | Path | None = None,
                     overrides: Mapping[str, Any] | None = None) -> LockstepSimulation:
    """The lockstep simulation of ``scenario``, with the scenario's controller section, a controller
    config file (its estimator, control, guidance ... and sensor names are used; its transports are
    replaced by the in-process codecs), and ``overrides`` (e.g. ``{"estimator": {"kind": "raw"}}``)."""
    if controller_config is None:
        return LockstepSimulation(scenario, lockstep_config(scenario, overrides, file=f"<scenario {scenario.name}>"))
    config = load_config(controller_config)
    if overrides:
        from dpbase.yamlfile import load_yaml  # noqa: PLC0415

        base = load_yaml(config.source_text) or {}
        if not isinstance(base, dict):  # (load_config accepted the file, so its text is a mapping)
            raise ConfigError("", "a mapping", base, file=str(controller_config))
        base.update(overrides)
        config = parse_config(base, file=str(controller_config), text=config.source_text)
    return LockstepSimulation(scenario, config)


def run_and_report(simulation: LockstepSimulation, out_dir: Path, *, plots: bool = True,
                   progress: bool | None = None, duration_s: float | None = None) -> RunOutputs:
    """Run to the end (or to a Ctrl-C) and write ``timeseries.csv``, ``summary.json`` and the plots into ``out_dir``."""
    out_dir.mkdir(parents=True, exist_ok=True)
    show = sys.stderr.isatty() if progress is None else progress
    callback = None
    bar = None
    if show:
        from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn  # noqa: PLC0415

        bar = Progress(TextColumn("[bold]{task.description}"), BarColumn(), TextColumn("{task.percentage:>5.1f} %"),
                       TimeRemainingColumn(), transient=True)
        task = bar.add_task(simulation.scenario.name, total=1.0)
        bar.start()

        def callback(t: float, total: float) -> None:
            bar.update(task, completed=t / total if total > 0 else 1.0)

    scenario = simulation.scenario
    log.info("%s: %g s to simulate (Ctrl-C ends the run early and writes the part that ran)", scenario.name,
             scenario.duration_s if duration_s is None else duration_s)
    try:  # Ctrl-C ends the run early: what ran is written like a whole run (summary: interrupted_at_s)
        result = simulation.run(progress=callback, duration_s=duration_s, interruptible=True)
    finally:
        if bar is not None:
            bar.stop()
    if result.steps == 0:
        raise KeyboardInterrupt  # interrupted before its first step finished: nothing to write
    wrap_headings(result.columns)
    timeseries = out_dir / "timeseries.csv"
    write_timeseries_csv(result.columns, timeseries)
    summary_path = out_dir / "summary.json"
    summary = write_summary(result, summary_path)
    written = write_plots(result, out_dir) if plots else []
    return RunOutputs(out_dir, timeseries, summary_path, written, summary, result)
