"""A shipped HIL pair (``deploy/hil/<name>/``) running as documented: ``sim-plant hil ... --engage`` and
``dpcontrol run`` as two processes on 127.0.0.1; importable as ``hil_pair`` (``tests/`` is on ``sys.path``).

The shipped files are used as they are, except for the places on this machine: the pseudo-terminal paths,
TCP/UDP ports and the Zenoh endpoint are moved to free ones (tests run beside each other and beside a bench
that may be running); every other key is the shipped one.
"""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from interfaces.zenoh.loopback import free_tcp_port, free_udp_port
from sim_plant.bench.demo import _NotifyListener, _spawn, _stop

ROOT = Path(__file__).resolve().parents[1]
PAIRS_DIR = ROOT / "deploy" / "hil"
START_TIMEOUT_S = 60.0  # cold interpreters importing zenoh, scipy, numba on a loaded 2-core machine


@dataclass
class RunningPair:
    vessel: str
    endpoint: str          # the daemon's zenoh listen endpoint
    run_dir: Path
    daemon_code: int | None = None
    plant_code: int | None = None

    def log(self, name: str) -> str:
        path = self.run_dir / name
        return path.read_text(errors="replace")[-4000:] if path.exists() else ""


def pair_names() -> list[str]:
    return sorted(p.name for p in PAIRS_DIR.iterdir() if (p / "dpcontrol.yaml").exists())


def relocate(pair: Path, short: Path, scenario_edit: Callable[[dict[str, Any]], None] | None = None
             ) -> tuple[Path, Path, str]:
    """The pair's files with their serial paths, ports and Zenoh endpoint moved to free places on this
    machine (and the scenario changed by ``scenario_edit``, when given); returns (scenario, config, the
    daemon's zenoh endpoint)."""
    config = yaml.safe_load((pair / "dpcontrol.yaml").read_text())
    for transport in config["transports"]:
        if transport["protocol"] == "nmea0183":
            transport["port"] = str(short / transport["name"])
        elif transport["protocol"] == "nmea2000":
            transport["channel"] = f"ws://127.0.0.1:{free_tcp_port()}/"
        elif transport["protocol"] == "mavlink":
            transport["url"] = f"udpin:127.0.0.1:{free_udp_port()}"
    assert len(config["zenoh"]["listen"]) == 1  # one endpoint, moved below
    endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
    config["zenoh"]["listen"] = [endpoint]
    config_file = short / "dpcontrol.yaml"
    config_file.write_text(yaml.safe_dump(config))
    scenario_file = short / "scenario.yaml"
    scenario = yaml.safe_load((pair / "scenario.yaml").read_text())
    if scenario_edit is not None:
        scenario_edit(scenario)
    scenario_file.write_text(yaml.safe_dump(scenario))
    return scenario_file, config_file, endpoint


@contextlib.contextmanager
def running_pair(name: str, run_dir: Path, short: Path, plant_duration_s: float,
                 scenario_edit: Callable[[dict[str, Any]], None] | None = None) -> Iterator[RunningPair]:
    """Start the plant (engaging DP as the operator), then the daemon, each once READY; stop the daemon
    first, then the plant, on leaving (their exit codes in the yielded object)."""
    scenario_file, config_file, endpoint = relocate(PAIRS_DIR / name, short, scenario_edit)
    running = RunningPair(yaml.safe_load(config_file.read_text())["vessel_id"], endpoint, run_dir)
    plant_notify, daemon_notify = _NotifyListener(short, "plant"), _NotifyListener(short, "daemon")
    emulator = _spawn([sys.executable, "-m", "sim_plant.cli", "--log-level", "WARNING", "hil", str(scenario_file),
                       "--controller-config", str(config_file), "--engage", "--out", str(run_dir / "plant"),
                       "--duration", str(plant_duration_s)], run_dir / "sim-plant.log", plant_notify)
    daemon = None
    try:
        assert plant_notify.wait_ready(START_TIMEOUT_S, emulator), running.log("sim-plant.log")
        daemon = _spawn([sys.executable, "-m", "dpcontrol.cli", "run", "--config", str(config_file)],
                        run_dir / "dpcontrol.log", daemon_notify)
        assert daemon_notify.wait_ready(START_TIMEOUT_S, daemon), running.log("dpcontrol.log")
        yield running
        running.daemon_code = _stop(daemon)
        running.plant_code = _stop(emulator)
    finally:
        for process in (daemon, emulator):
            if process is not None and process.poll() is None:
                process.kill()
        plant_notify.close()
        daemon_notify.close()
