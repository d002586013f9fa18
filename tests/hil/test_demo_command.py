"""``sim-plant demo``, the README's main command, end to end through its command line, shortened to 25 s.

The emulator and a real ``dpcontrol run`` as two processes over a pty, python-can remote, UDP and Zenoh on
127.0.0.1 (what ``make demo`` runs, without the live view): both exit 0, DP engages, zero thrust is the
last command, and the report and the closing lines say so.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from sim_plant.scenario import builtin_scenario_path

pytestmark = [pytest.mark.hil, pytest.mark.slow]

DURATION_S = 25.0
TIMEOUT_S = 240.0  # two cold interpreters (zenoh, scipy, numba's cache) on a loaded 2-core machine, the run, the plots


def test_the_demo_command_runs_and_reports(tmp_path: Path) -> None:
    out = tmp_path / "demo"
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1"}
    done = subprocess.run([sys.executable, "-m", "sim_plant.cli", "demo", "--duration", str(DURATION_S),
                           "--no-live", "--out", str(out)], capture_output=True, text=True, timeout=TIMEOUT_S,
                          env=env, check=False)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    lines = [line.removeprefix("sim-plant demo: ") for line in done.stdout.splitlines()]
    assert "stopped: dpcontrol exit 0, sim-plant exit 0" in lines, lines
    assert lines[-1] == f"report in {out / 'report'}"
    summary = json.loads((out / "report" / "summary.json").read_text(encoding="utf-8"))
    assert summary["dpcontrol_exit"] == 0 and summary["sim_plant_exit"] == 0
    assert summary["dp_engaged"] and summary["zero_thrust_commanded_last"], summary
    assert summary["dpcontrol_loop"]["cycles"] >= 0.5 * DURATION_S * 10
    assert any(line.startswith("DP engaged ") for line in lines), lines
    assert "last command: zero thrust, mode standby" in lines, lines
    assert any(line.startswith("control loop: ") and " 0 step errors" in line for line in lines), lines
    # the shortened run ends soon after the scenario's set-point change: its error is said to include the move
    change_s = yaml.safe_load(builtin_scenario_path("demo").read_text())["setpoints"][-1]["t_s"]
    assert DURATION_S / 2 < change_s < DURATION_S
    assert any(f"includes the move to the set-point of t = {change_s:g} s" in line for line in lines), lines
    assert sorted(p.suffix for p in (out / "report").iterdir()).count(".png") >= 1
