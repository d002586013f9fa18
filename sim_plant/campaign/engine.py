"""The campaign engine: lockstep runs as tasks of a Dask distributed cluster, local or remote.

Why Dask distributed and not Ray: a campaign is a bag of independent, CPU-bound, pure-Python tasks of seconds to
minutes whose inputs and outputs are small (a scenario mapping in, a summary dict out). Dask distributed does
exactly that with a pip-installable scheduler and worker (``dask scheduler``, ``dask worker tcp://HOST:8786``) that
run in the project's own virtual environment, the same ``Client`` API for a ``LocalCluster`` of processes on
this machine and for a remote cluster (one code path, as the campaign must behave the same on both), futures
with done-callbacks (results are written as they come, so Ctrl-C and resume lose nothing) and a worker that
dies being reported as that task's error (the campaign goes on). Ray offers the same pattern but brings its
own object store, dashboard and raylet daemons, a much larger install for no gain here.

One task per run; a worker process runs one task at a time (``threads_per_worker=1``: the simulation is
Python holding the GIL). The driver keeps the order: results arrive in any order, rows are written in run order.
"""

from __future__ import annotations

import logging
import math
import os
import queue
import signal
import threading
import time
import traceback
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from dpbase.frames import ssa_array
from sim_plant.bench.lockstep import LockstepSimulation, RunResult, _CtrlC, lockstep_config
from sim_plant.bench.report import summarise, wrap_headings
from sim_plant.campaign.spec import Run
from sim_plant.scenario import parse_scenario

log = logging.getLogger(__name__)

#: How long the driver waits for one result before it looks at Ctrl-C again [s].
POLL_S = 0.25


def default_workers() -> int:
    """One worker process per core this process may run on."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # (not on Linux)
        return max(1, os.cpu_count() or 1)


# -- the task -------------------------------------------------------------------------------------------------
def settled_metrics(result: RunResult, settle_s: float) -> dict[str, float | None]:
    """Station keeping after ``settle_s``: the true LF position's distance from the operator's set-point [m] and
    the true LF heading's difference from it [deg], max and RMS (None where no set-point gives one)."""
    c = result.columns
    d = c.data[: c.rows]
    t = d[:, c.index("t_s")]
    north = d[:, c.index("north_m")]
    east = d[:, c.index("east_m")]
    heading = d[:, c.index("heading_rad")]
    setpoint_north = np.full(t.size, np.nan)
    setpoint_east = np.full(t.size, np.nan)
    sp_h = np.full(t.size, np.nan)
    points = result.scenario.setpoints
    for i, point in enumerate(points):
        end = points[i + 1].t_s if i + 1 < len(points) else math.inf
        sel = (t >= point.t_s - 1e-9) & (t < end - 1e-9)
        if point.north_m is not None:
            setpoint_north[sel], setpoint_east[sel] = point.north_m, point.east_m
        if point.heading_rad is not None:
            sp_h[sel] = point.heading_rad
    after = t >= settle_s - 1e-9
    position = np.hypot(north - setpoint_north, east - setpoint_east)[after]
    head = np.degrees(np.abs(ssa_array(heading - sp_h)))[after]
    out: dict[str, float | None] = {}
    for name, values in (("position_error", position), ("heading_error", head)):
        unit = "m" if name == "position_error" else "deg"
        finite = values[np.isfinite(values)]
        out[f"{name}_max_after_settle_{unit}"] = round(float(np.max(finite)), 6) if finite.size else None
        out[f"{name}_rms_after_settle_{unit}"] = round(float(np.sqrt(np.mean(finite**2))), 6) if finite.size else None
    return out


def execute_run(run: Run) -> dict[str, Any]:
    """Run one campaign run (in a worker): ``{"status": "ok", "summary": ...}`` or ``{"status": "failed",
    "error": ...}`` — a failure of the run is its result, not the worker's."""
    wall0 = time.perf_counter()
    cpu0 = time.process_time()
    try:
        scenario = parse_scenario(run.scenario, file=f"<run {run.run}>")
        config = lockstep_config(scenario, file=f"<run {run.run}>")
        result = LockstepSimulation(scenario, config).run(duration_s=run.duration_s)
        wrap_headings(result.columns)
        summary = summarise(result)
        if run.settle_s is not None:
            summary["metrics"].update(settled_metrics(result, run.settle_s))
        return {"status": "ok", "summary": summary, "wall_s": time.perf_counter() - wall0,
                "cpu_s": time.process_time() - cpu0, "simulated_s": result.steps * config.sample_time_s}
    except KeyboardInterrupt:  # (a Ctrl-C that reached the worker: not the run's failure)
        return {"status": "interrupted"}
    except Exception as error:  # the run failed; the campaign goes on with the others
        return {"status": "failed", "error": f"{type(error).__name__}: {error}",
                "traceback": traceback.format_exc(limit=8), "wall_s": time.perf_counter() - wall0}


# -- the driver -----------------------------------------------------------------------------------------------
class Engine:
    """A Dask client on a local cluster of ``workers`` processes (default: one per core), or on the cluster at
    ``scheduler`` (``tcp://HOST:PORT``). Use as a context manager."""

    def __init__(self, workers: int | None = None, scheduler: str | None = None) -> None:
        if workers is not None and workers < 1:
            raise ValueError(f"workers must be ≥ 1, got {workers}")
        self.workers = workers
        self.scheduler = scheduler
        self.client: Any = None
        self.cluster: Any = None

    def __enter__(self) -> Engine:
        from distributed import Client, LocalCluster  # noqa: PLC0415 - heavy; only when a campaign runs

        # Dask's own INFO lines (scheduler, nannies, every worker's start and stop) are not the user's business
        if not log.isEnabledFor(logging.DEBUG):
            for name in ("distributed", "dask"):
                logging.getLogger(name).setLevel(logging.WARNING)

        if self.scheduler:
            self.client = Client(self.scheduler, timeout="20s")
        else:
            # The worker processes start with Ctrl-C ignored (an ignored signal stays ignored in the interpreter a
            # process starts): a terminal's Ctrl-C reaches the whole process group, and the driver alone decides what
            # happens — it cancels the runs and closes the cluster — instead of each worker dying with a traceback.
            main = threading.current_thread() is threading.main_thread()
            previous = signal.signal(signal.SIGINT, signal.SIG_IGN) if main else None
            try:
                self.cluster = LocalCluster(n_workers=self.workers or default_workers(), threads_per_worker=1,
                                            processes=True, host="127.0.0.1", dashboard_address="127.0.0.1:0",
                                            scheduler_kwargs={"dashboard": False}, silence_logs=logging.ERROR)
            finally:
                if main:
                    signal.signal(signal.SIGINT, previous)
            self.client = Client(self.cluster)
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Close the client and the local cluster (a remote cluster stays up)."""
        if self.client is not None:
            self.client.close()
            self.client = None
        if self.cluster is not None:
            self.cluster.close(timeout=30)  # (workers on a loaded machine may need more than the default 5 s to stop)
            self.cluster = None

    @property
    def n_workers(self) -> int:
        """Workers the scheduler knows now."""
        return len(self.client.scheduler_info().get("workers", {})) if self.client is not None else 0

    def run(self, runs: Sequence[Run], on_result: Callable[[Run, dict[str, Any]], None], *,
            progress: bool = False, description: str = "campaign") -> bool:
        """Submit ``runs`` and call ``on_result(run, result)`` in this thread as each finishes (any order).

        Returns True when every run finished, False after a Ctrl-C (the runs still going are cancelled; what
        finished before was passed to ``on_result``). A second Ctrl-C raises KeyboardInterrupt at once.
        """
        if not runs:
            return True
        done: queue.Queue[Any] = queue.Queue()
        futures = []
        by_key = {}
        for run in runs:
            future = self.client.submit(execute_run, run, key=f"run-{run.key}-{run.run}", pure=False, retries=0)
            by_key[future.key] = run
            future.add_done_callback(done.put)  # (called in the client's thread)
            futures.append(future)
        bar, task = _progress_bar(description, len(runs)) if progress else (None, None)
        ctrl_c = _CtrlC()
        remaining = len(runs)
        failed = 0
        t0 = time.perf_counter()
        try:
            while remaining:
                if ctrl_c.pressed:
                    self.client.cancel([f for f in futures if not f.done()])
                    return False
                try:
                    future = done.get(timeout=POLL_S)
                except queue.Empty:
                    continue
                if ctrl_c.pressed:  # a terminal's Ctrl-C reaches the local workers too: what ends now is not a result
                    continue
                run = by_key[future.key]
                if future.status == "finished":
                    result = future.result()
                elif future.status == "cancelled":
                    continue
                else:  # the worker died or the task could not be run there: this run's failure
                    error = future.exception()
                    result = {"status": "failed", "error": f"worker: {type(error).__name__}: {error}"}
                future.release()
                if result.get("status") == "interrupted":
                    continue
                remaining -= 1
                failed += result.get("status") != "ok"
                on_result(run, result)
                if bar is not None:
                    bar.update(task, advance=1, failed=failed)
            log.info("%d runs in %.1f s", len(runs), time.perf_counter() - t0)
            return True
        finally:
            ctrl_c.restore()
            if bar is not None:
                bar.stop()


def _progress_bar(description: str, total: int) -> tuple[Any, Any]:
    from rich.progress import (  # noqa: PLC0415
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    bar = Progress(TextColumn("[bold]{task.description}"), BarColumn(), MofNCompleteColumn(),
                   TextColumn("failed {task.fields[failed]}"), TimeElapsedColumn(), TextColumn("ETA"),
                   TimeRemainingColumn())
    task = bar.add_task(description, total=total, failed=0)
    bar.start()
    return bar, task
