"""The shipped HIL bench (``deploy/hil/<vessel>/``): each pair of controller configuration and scenario runs
as documented (docs/hil.md) — ``sim-plant hil SCENARIO --controller-config FILE --engage`` and
``dpcontrol run --config FILE`` as two processes on 127.0.0.1 — and holds DP for 30 s with no alarm.

The shipped files are used as they are, except for the places on this machine: the pseudo-terminal
paths, TCP/UDP ports and Zenoh endpoint are moved to free ones (tests run beside each other and beside
a bench that may be running); every other key is the shipped one.
"""

from __future__ import annotations

import sys
import threading
import time
from pathlib import Path
from typing import Any

import pytest
import yaml

from interfaces.zenoh.config import ZenohConfig
from interfaces.zenoh.loopback import free_tcp_port, free_udp_port
from interfaces.zenoh.node import ZenohNode
from sim_plant.bench.demo import _NotifyListener, _spawn, _stop

pytestmark = [pytest.mark.hil, pytest.mark.slow]

ROOT = Path(__file__).resolve().parents[2]
PAIRS = sorted(p.name for p in (ROOT / "deploy" / "hil").iterdir() if (p / "dpcontrol.yaml").exists())
ENGAGE_TIMEOUT_S = 60.0  # cold interpreters, first fixes, the operator's first request on a loaded machine
HOLD_S = 30.0


def _relocated(pair: Path, short: Path) -> tuple[Path, Path, str]:
    """The pair's files with their serial paths, ports and Zenoh endpoint moved to free places on this
    machine; returns (scenario, config, the daemon's zenoh endpoint)."""
    config = yaml.safe_load((pair / "dpcontrol.yaml").read_text())
    for transport in config["transports"]:
        if transport["protocol"] == "nmea0183":
            transport["port"] = str(short / transport["name"])
        elif transport["protocol"] == "nmea2000":
            transport["channel"] = f"ws://127.0.0.1:{free_tcp_port()}/"
        elif transport["protocol"] == "mavlink":
            transport["url"] = f"udpin:127.0.0.1:{free_udp_port()}"
    endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
    assert config["zenoh"]["listen"] == [config["zenoh"]["listen"][0]]  # one endpoint, moved below
    config["zenoh"]["listen"] = [endpoint]
    config_file = short / "dpcontrol.yaml"
    config_file.write_text(yaml.safe_dump(config))
    scenario_file = short / "scenario.yaml"
    scenario_file.write_text((pair / "scenario.yaml").read_text())
    return scenario_file, config_file, endpoint


@pytest.mark.parametrize("name", PAIRS)
def test_shipped_pair_holds_dp_for_30_s_with_no_alarm(name: str, tmp_path_factory: pytest.TempPathFactory) -> None:
    assert {"cybership2", "supply"} <= set(PAIRS)
    run_dir = tmp_path_factory.mktemp(f"hil-{name}")
    short = Path(tmp_path_factory.mktemp("s"))
    scenario_file, config_file, endpoint = _relocated(ROOT / "deploy" / "hil" / name, short)
    vessel = yaml.safe_load(config_file.read_text())["vessel_id"]
    plant_notify, daemon_notify = _NotifyListener(short, "plant"), _NotifyListener(short, "daemon")
    emulator = _spawn([sys.executable, "-m", "sim_plant.cli", "--log-level", "WARNING", "hil", str(scenario_file),
                       "--controller-config", str(config_file), "--engage", "--out", str(run_dir / "plant"),
                       "--duration", str(ENGAGE_TIMEOUT_S + HOLD_S + 30.0)], run_dir / "sim-plant.log", plant_notify)
    daemon = None
    statuses: list[tuple[float, dict[str, Any]]] = []
    lock = threading.Lock()
    try:
        assert plant_notify.wait_ready(60.0, emulator), (run_dir / "sim-plant.log").read_text()
        daemon = _spawn([sys.executable, "-m", "dpcontrol.cli", "run", "--config", str(config_file)],
                        run_dir / "dpcontrol.log", daemon_notify)
        assert daemon_notify.wait_ready(60.0, daemon), (run_dir / "dpcontrol.log").read_text()

        class Sink:
            def put(self, item: Any) -> None:
                with lock:
                    statuses.append((time.monotonic(), item.message))

        node = ZenohNode(ZenohConfig(mode="peer", connect=(endpoint,)), vessel)
        try:
            node.subscribe("status", Sink())
            deadline = time.monotonic() + ENGAGE_TIMEOUT_S
            engaged_at = None
            while engaged_at is None and time.monotonic() < deadline:
                time.sleep(0.2)  # polling the collected statuses (they arrive at 10 Hz)
                with lock:
                    engaged_at = next((t for t, s in statuses if s["mode"] == "auto_position"), None)
            assert engaged_at is not None, (run_dir / "dpcontrol.log").read_text()[-3000:]
            time.sleep(max(0.0, engaged_at + HOLD_S - time.monotonic()))  # real time: DP holds for 30 s
        finally:
            node.close()
        daemon_code = _stop(daemon)
        plant_code = _stop(emulator)
    finally:
        for process in (daemon, emulator):
            if process is not None and process.poll() is None:
                process.kill()
        plant_notify.close()
        daemon_notify.close()
    with lock:
        held = [s for t, s in statuses if engaged_at <= t <= engaged_at + HOLD_S]
    assert len(held) >= 0.8 * 10 * HOLD_S  # the status at ~10 Hz throughout
    assert all(s["mode"] == "auto_position" for s in held), {s["mode"] for s in held}
    raised = {(a["code"], a["severity"]) for s in held for a in s["alarms"] if a["active"]}
    assert not raised, raised
    # the daemon hears the drives the whole time (what the monitor and console show)
    assert all(s["drives"]["present"] and s["drives"]["feedback_age_s"] < 1.0 for s in held)
    assert daemon_code == 0 and plant_code == 0, (daemon_code, plant_code)
