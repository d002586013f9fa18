"""The controller stalls or dies (docs/fault-handling.md, case 11).

* A stalled daemon (SIGSTOP) stops sending ``WATCHDOG=1``; the test plays systemd with
  ``WatchdogSec=1``: it notices the silence, kills and restarts the daemon, which comes back READY
  and pings again.
* An unhealthy loop (every control step fails) keeps running but stops pinging the watchdog, so
  systemd would restart it — never a side thread keeping a broken loop "alive".
* The daemon killed in DP: the emulator's thruster drives ramp to zero (command timeout and
  liveliness loss), seen in the thrust the drives report.
"""

from __future__ import annotations

import csv
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
import yaml

from dpcontrol.runtime.config import parse_config
from dpcontrol.service.daemon import Daemon
from interfaces.systemd import SystemdNotifier
from interfaces.zenoh.loopback import free_tcp_port
from sim_plant.bench.demo import _NotifyListener, _spawn, _stop, emulator_command, prepare
from sim_plant.scenario import builtin_scenario_path

pytestmark = [pytest.mark.hil, pytest.mark.slow]

WATCHDOG_SEC = 1.0


def _config(tmp_path: Path) -> dict:
    return {"vessel_id": "wd", "vessel": "cybership2", "loop": {"rate_hz": 10},
            "transports": [{"name": "serial", "protocol": "nmea0183", "port": str(tmp_path / "no-tty")}],
            "sensors": [{"name": "gnss1", "kind": "position", "transport": "serial"},
                        {"name": "gyro1", "kind": "heading", "transport": "serial"}],
            "zenoh": {"listen": [f"tcp/127.0.0.1:{free_tcp_port()}"]}}


class FakeSystemd:
    """Receives sd_notify datagrams and records when each kind arrived."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
        self.sock.bind(str(path))
        self.sock.settimeout(0.05)
        self.events: list[tuple[float, str]] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                data = self.sock.recv(4096).decode()
            except TimeoutError:
                continue
            for line in data.split("\n"):
                if line:
                    self.events.append((time.monotonic(), line))

    def last(self, key: str) -> float | None:
        times = [t for t, line in self.events if line.startswith(key)]
        return times[-1] if times else None

    def wait(self, key: str, after: float, timeout_s: float) -> bool:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            last = self.last(key)
            if last is not None and last > after:
                return True
            time.sleep(0.05)
        return False

    def close(self) -> None:
        self._stop.set()
        self._thread.join(2.0)
        self.sock.close()


def _start(config_path: Path, systemd: FakeSystemd) -> subprocess.Popen[bytes]:
    env = dict(os.environ, NOTIFY_SOCKET=str(systemd.path), WATCHDOG_USEC=str(int(WATCHDOG_SEC * 1e6)))
    return subprocess.Popen([sys.executable, "-m", "dpcontrol.cli", "run", "--config", str(config_path)], env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def test_a_stalled_daemon_stops_the_watchdog_and_is_restarted(tmp_path: Path) -> None:
    config_path = tmp_path / "vessel.yaml"
    config_path.write_text(yaml.safe_dump(_config(tmp_path)))
    systemd = FakeSystemd(tmp_path / "notify.sock")
    first = second = None
    try:
        t0 = time.monotonic()
        first = _start(config_path, systemd)
        assert systemd.wait("READY=1", t0, 60.0)
        assert systemd.wait("WATCHDOG=1", time.monotonic(), 5.0)
        first.send_signal(signal.SIGSTOP)  # the controller hangs
        stopped = time.monotonic()
        time.sleep(WATCHDOG_SEC * 1.5)
        last_ping = systemd.last("WATCHDOG=1")
        assert last_ping is not None and last_ping < stopped + 0.2  # no ping while stalled
        # systemd: WatchdogSec elapsed without a ping → SIGABRT/SIGKILL and, Restart=on-failure, start again
        assert time.monotonic() - last_ping > WATCHDOG_SEC
        first.kill()
        first.wait(10.0)
        restart = time.monotonic()
        second = _start(config_path, systemd)
        assert systemd.wait("READY=1", restart, 60.0)
        assert systemd.wait("WATCHDOG=1", time.monotonic(), 5.0)
    finally:
        for process in (first, second):
            if process is not None and process.poll() is None:
                process.send_signal(signal.SIGCONT)
                process.kill()
                process.wait(10.0)
        systemd.close()


def test_an_unhealthy_loop_keeps_running_but_stops_pinging(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    systemd = FakeSystemd(tmp_path / "notify.sock")
    environ = {"NOTIFY_SOCKET": str(systemd.path), "WATCHDOG_USEC": str(int(WATCHDOG_SEC * 1e6))}
    daemon = Daemon(parse_config(_config(tmp_path)), notifier=SystemdNotifier(environ=environ))
    calls = {"n": 0}
    original = daemon.controller.step

    def step(*args: object, **kwargs: object) -> object:
        calls["n"] += 1
        if calls["n"] > 20:  # healthy for 2 s, then every step fails
            raise RuntimeError("injected fault in the control step")
        return original(*args, **kwargs)

    monkeypatch.setattr(daemon.controller, "step", step)
    thread = threading.Thread(target=daemon.run, kwargs={"duration_s": 5.0, "install_signals": False})
    thread.start()
    thread.join(30.0)
    assert not thread.is_alive()
    systemd.close()
    pings = [t for t, line in systemd.events if line == "WATCHDOG=1"]
    assert len(pings) >= 15  # while healthy, every cycle pinged
    assert calls["n"] >= 45  # the loop kept running after the fault (≈ 5 s at 10 Hz)
    assert daemon.stats.step_errors >= 25
    # after three failed cycles in a row the pings stopped: systemd's WatchdogSec restarts the service
    assert pings[-1] - pings[0] < 3.0


def test_killed_daemon_makes_the_drives_ramp_to_zero(tmp_path_factory: pytest.TempPathFactory) -> None:
    run_dir = tmp_path_factory.mktemp("kill")
    scenario = yaml.safe_load(builtin_scenario_path("demo").read_text())
    scenario["duration_s"] = 200.0
    scenario["sea_states"] = scenario["sea_states"][:1]
    scenario["setpoints"] = [{"t_s": 0.0, "north_m": 0.0, "east_m": 0.0, "heading_deg": 0.0},
                             {"t_s": 5.0, "north_m": 2.0, "east_m": 0.0, "heading_deg": 0.0}]
    source = run_dir / "source.yaml"
    source.write_text(yaml.safe_dump(scenario))
    scenario_file, config_file, wiring = prepare(source, run_dir)
    short = Path(wiring["short_dir"])
    plant_notify = _NotifyListener(short, "plant")
    daemon_notify = _NotifyListener(short, "daemon")
    emulator = _spawn(emulator_command(scenario_file, config_file, wiring, run_dir / "plant", 300.0),
                      run_dir / "sim-plant.log", plant_notify)
    daemon = None
    try:
        assert plant_notify.wait_ready(60.0, emulator)
        t_plant0 = time.monotonic()
        daemon = _spawn([sys.executable, "-m", "dpcontrol.cli", "run", "--config", str(config_file)],
                        run_dir / "dpcontrol.log", daemon_notify)
        assert daemon_notify.wait_ready(60.0, daemon)
        time.sleep(20.0)  # DP engaged, moving to the 2 m setpoint: thrusters working
        daemon.kill()
        killed_plant_t = time.monotonic() - t_plant0
        time.sleep(8.0)
    finally:
        if daemon is not None and daemon.poll() is None:
            daemon.kill()
        _stop(emulator)
        plant_notify.close()
        daemon_notify.close()
    with (run_dir / "plant" / "feedback.csv").open() as handle:
        rows = [(float(r["t_s"]), r["name"], float(r["thrust_n"])) for r in csv.DictReader(handle)]
    before = [abs(thrust) for t, _, thrust in rows if killed_plant_t - 3.0 < t < killed_plant_t]
    after = [abs(thrust) for t, _, thrust in rows if t > killed_plant_t + 5.0]
    assert max(before) > 0.01  # the drives were producing thrust in DP
    assert after and max(after) < 1e-6, max(after)  # command timeout (1 s) + ramp: all at zero
