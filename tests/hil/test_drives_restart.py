"""The drives (the plant) restart under a running daemon (HIL bench: emulator and daemon as two processes, every
transport). DP is engaged and moving when the plant is killed outright; the daemon loses its references and
drives (it dead-reckons, alarmed); a new plant is started ~8 s later. Checked: no thruster is latched as
failed (the monitor judges a drive whose feedback returns afresh), and DP can be engaged afterwards: the operator
puts the controller in standby and asks for ``auto_position`` again with ``dpcontrol setpoint`` (both answered
``applied``). Bounded: about a minute of wall time."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml

from sim_plant.bench.demo import _NotifyListener, _spawn, _stop, emulator_command, prepare
from sim_plant.scenario import builtin_scenario_path

pytestmark = [pytest.mark.hil, pytest.mark.slow]

ENGAGED_S = 24.0  # DP engages at once (--engage); the 2 m set-point move starts at 20 s
DOWN_S = 8.0  # beyond the drives' feedback timeout (2 s)
BACK_S = 14.0  # the new plant's references and drives return; readmission and the re-check take a few seconds


def test_a_restarted_plant_leaves_no_thruster_latched_and_dp_engages_again(tmp_path: Path) -> None:
    scenario = yaml.safe_load(builtin_scenario_path("demo").read_text())
    scenario["duration_s"] = 300.0
    scenario["sea_states"] = scenario["sea_states"][:1]
    source = tmp_path / "source.yaml"
    source.write_text(yaml.safe_dump(scenario))
    scenario_file, config_file, wiring = prepare(source, tmp_path)
    short = Path(wiring["short_dir"])
    listeners = [_NotifyListener(short, name) for name in ("plant1", "plant2", "daemon")]
    first = emulator_command(scenario_file, config_file, wiring, tmp_path / "plant1", 300.0)
    second = [arg for arg in emulator_command(scenario_file, config_file, wiring, tmp_path / "plant2", 300.0)
              if arg != "--engage"]  # the operator engages, below
    processes: list[subprocess.Popen[bytes]] = []
    try:
        plant = _spawn(first, tmp_path / "plant1.log", listeners[0])
        processes.append(plant)
        assert listeners[0].wait_ready(60.0, plant), (tmp_path / "plant1.log").read_text()
        daemon = _spawn([sys.executable, "-m", "dpcontrol.cli", "run", "--config", str(config_file)],
                        tmp_path / "dpcontrol.log", listeners[2])
        processes.append(daemon)
        assert listeners[2].wait_ready(60.0, daemon), (tmp_path / "dpcontrol.log").read_text()
        time.sleep(ENGAGED_S)
        os.kill(plant.pid, signal.SIGKILL)  # a crash: no last word from the drives
        plant.wait(10.0)
        time.sleep(DOWN_S)
        plant = _spawn(second, tmp_path / "plant2.log", listeners[1])
        processes.append(plant)
        assert listeners[1].wait_ready(60.0, plant), (tmp_path / "plant2.log").read_text()
        time.sleep(BACK_S)
        answers = [subprocess.run([sys.executable, "-m", "dpcontrol.cli", "setpoint", "--vessel", wiring["vessel_id"],
                                   "--connect", wiring["zenoh"], "--timeout", "30", "--mode", mode,
                                   # the demo's network is secured: the operator is its bridge console
                                   "--tls-dir", wiring["tls_dir"], "--identity", "bridge"],
                                  capture_output=True, text=True, timeout=60.0, check=False)
                   for mode in ("standby", "auto_position")]
        time.sleep(1.0)
    finally:
        for process in reversed(processes):
            _stop(process)
        for listener in listeners:
            listener.close()
    log = (tmp_path / "dpcontrol.log").read_text()
    assert "dead reckoning" in log  # the daemon had lost the plant's references
    # the drives were lost and came back ...
    assert "thruster.bow_tunnel.feedback_lost" in log
    # ... and none was taken out of the allocation for it
    assert "removed from allocation" not in log, [line for line in log.splitlines() if "removed from" in line]
    for answer, mode in zip(answers, ("standby", "auto_position"), strict=True):
        assert answer.returncode == 0, (answer.stdout, answer.stderr)
        assert answer.stdout.startswith(f"{wiring['vessel_id']}: applied: mode {mode}"), answer.stdout
