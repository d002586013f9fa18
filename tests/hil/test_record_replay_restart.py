"""Black-box recorder, exact replay and bumpless restart on the HIL bench (docs/design.md §10).

One HIL session (emulator + daemon as two processes, all transports) is used for three checks:

1. the daemon is killed with SIGKILL while in DP: its recording is readable up to at most 1 s before
   the kill;
2. it is restarted at once (what ``Restart=on-failure`` does): it resumes from the persisted state in
   DP, and the first commands continue from the last ones — the largest step of any thruster command
   across the restart is measured and bounded by that thruster's rate limit over the gap;
3. the first recording is replayed with ``dpcontrol replay`` through the same step: the commands are
   identical; with another estimator they are not, and the comparison is written beside them.
Plus, without the emulator: an unwritable recorder path raises an alarm and the loop keeps running;
``dpcontrol log export`` opens a recording as CSV.
"""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

from dpcontrol.cli import main as dpcontrol_main
from dpcontrol.logtools import read_records
from dpcontrol.models.vessels import CYBERSHIP2
from interfaces.recorder import list_log_files
from interfaces.zenoh.loopback import free_tcp_port
from interfaces.zenoh.node import LatestSlot, ZenohNode
from interfaces.zenoh.session_config import ZenohConfig
from sim_plant.bench.demo import _NotifyListener, _spawn, _stop, emulator_command, prepare
from sim_plant.scenario import builtin_scenario_path

pytestmark = [pytest.mark.hil, pytest.mark.slow]

RUN_BEFORE_KILL_S = 25.0
RUN_AFTER_RESTART_S = 10.0


def _wait_for(predicate, timeout_s: float, poll_s: float = 0.2) -> bool:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(poll_s)
    return predicate()


@pytest.fixture(scope="module")
def session(tmp_path_factory: pytest.TempPathFactory) -> dict:
    run_dir = tmp_path_factory.mktemp("restart")
    scenario = yaml.safe_load(builtin_scenario_path("demo").read_text())
    scenario["duration_s"] = 300.0
    scenario["sea_states"] = scenario["sea_states"][:1]
    scenario["setpoints"] = [{"t_s": 0.0, "north_m": 0.0, "east_m": 0.0, "heading_deg": 0.0},
                             {"t_s": 10.0, "north_m": 0.5, "east_m": 0.0, "heading_deg": 0.0}]
    source = run_dir / "source.yaml"
    source.write_text(yaml.safe_dump(scenario))
    scenario_file, config_file, wiring = prepare(source, run_dir)
    first_records = run_dir / "records"
    short = Path(wiring["short_dir"])
    plant_notify = _NotifyListener(short, "plant")
    notify1 = _NotifyListener(short, "daemon1")
    notify2 = _NotifyListener(short, "daemon2")
    emulator = _spawn(emulator_command(scenario_file, config_file, wiring, run_dir / "plant", 400.0),
                      run_dir / "sim-plant.log", plant_notify)
    daemon = restarted = None
    result: dict = {"run_dir": run_dir, "config": config_file, "wiring": wiring}
    try:
        assert plant_notify.wait_ready(60.0, emulator), (run_dir / "sim-plant.log").read_text()
        daemon = _spawn([sys.executable, "-m", "dpcontrol.cli", "run", "--config", str(config_file)],
                        run_dir / "dpcontrol-1.log", notify1)
        assert notify1.wait_ready(60.0, daemon), (run_dir / "dpcontrol-1.log").read_text()
        time.sleep(RUN_BEFORE_KILL_S)  # real-time scenario: DP engages and moves to the setpoint
        os.kill(daemon.pid, signal.SIGKILL)
        killed_at = time.monotonic()
        daemon.wait(10.0)
        result["killed_at"] = killed_at
        # keep the first recording apart (the restarted daemon records into the same directory)
        kept = run_dir / "records-before-kill"
        kept.mkdir()
        for path in list_log_files(first_records):
            path.rename(kept / path.name)
        result["records"] = kept
        restarted = _spawn([sys.executable, "-m", "dpcontrol.cli", "run", "--config", str(config_file),
                            "--stats-out", str(run_dir / "stats-2.json")], run_dir / "dpcontrol-2.log", notify2)
        assert notify2.wait_ready(60.0, restarted), (run_dir / "dpcontrol-2.log").read_text()
        time.sleep(RUN_AFTER_RESTART_S)
        result["restart_code"] = _stop(restarted)
        result["stats_after_restart"] = json.loads((run_dir / "stats-2.json").read_text())
    finally:
        for process in (daemon, restarted):
            if process is not None and process.poll() is None:
                process.kill()
        _stop(emulator)
        for listener in (plant_notify, notify1, notify2):
            listener.close()
    return result


def _plant_commands(run_dir: Path) -> list[tuple[float, str, str, float, float]]:
    rows = []
    with (run_dir / "plant" / "commands.csv").open() as handle:
        header = handle.readline().strip().split(",")
        for line in handle:
            values = dict(zip(header, line.strip().split(","), strict=False))
            rows.append((float(values["t_s"]), values["mode"], values["name"], float(values["thrust_n"]),
                         float(values["azimuth_rad"])))
    return rows


def test_sigkill_leaves_a_readable_record_up_to_one_second_before_the_kill(session: dict) -> None:
    records = list(read_records(session["records"], ("command",)))
    assert len(records) > 100
    last_t = max(r.t_s for r in records)
    # the daemon's t_s is its monotonic clock — the same CLOCK_MONOTONIC as the test's
    assert session["killed_at"] - last_t <= 1.0 + 0.1, (session["killed_at"], last_t)


def test_restart_resumes_in_dp_without_a_command_jump(session: dict) -> None:
    stats = session["stats_after_restart"]
    assert stats["resumed_from_state"] is True, stats
    assert session["restart_code"] == 0
    # the controller replica resumed from the same state: it agrees with the resumed primary
    assert stats["replica"]["mismatches"] == 0 and stats["replica"]["compared"] > 0, stats["replica"]
    commands = _plant_commands(session["run_dir"])
    by_time: dict[float, dict[str, float]] = {}
    modes: dict[float, str] = {}
    for t, mode, name, thrust, _ in commands:
        by_time.setdefault(t, {})[name] = thrust
        modes[t] = mode
    times = sorted(by_time)
    gaps = np.diff(times)
    k = int(np.argmax(gaps))  # the restart: the longest silence of commands
    before, after = times[k], times[k + 1]
    assert modes[after] == "auto_position", "the restarted daemon should resume DP"
    gap = after - before
    limits = {t.name: t.thrust_rate_limit_nps for t in CYBERSHIP2.thrusters}
    steps = {name: abs(by_time[after][name] - by_time[before][name]) for name in by_time[before]}
    # rate limits continue from the persisted last command: the step is bounded by the rate × time since
    # that command was saved (≤ period + gap), never a jump to a fresh solution
    for name, step in steps.items():
        assert step <= limits[name] * (gap + 1.2), (name, step, gap)
    session["max_command_step_n"] = max(steps.values())
    print(f"restart gap {gap:.2f} s; largest thrust command step across the restart: "
          f"{max(steps.values()):.4f} N ({steps})")


def test_replay_reproduces_the_recorded_commands_exactly(session: dict, tmp_path: Path,
                                                          capsys: pytest.CaptureFixture[str]) -> None:
    code = dpcontrol_main(["replay", str(session["records"]), "--config", str(session["config"]),
                           "--out", str(tmp_path / "same"), "--no-plots"])
    report = json.loads(capsys.readouterr().out)
    assert code == 0, report
    assert report["same_config"] is True
    assert report["identical"] is True, report
    assert report["cycles_compared"] > 100
    assert report["max_thrust_difference_n"] == 0.0


def test_replay_with_another_estimator_writes_the_comparison(session: dict, tmp_path: Path,
                                                              capsys: pytest.CaptureFixture[str]) -> None:
    other = yaml.safe_load(Path(session["config"]).read_text())
    other["estimator"] = {"kind": "kf", "omega_rad_s": 0.8}
    path = tmp_path / "kf.yaml"
    path.write_text(yaml.safe_dump(other))
    dpcontrol_main(["replay", str(session["records"]), "--config", str(path), "--out", str(tmp_path / "kf")])
    report = json.loads(capsys.readouterr().out)
    assert report["same_config"] is False
    assert report["identical"] is False and report["max_thrust_difference_n"] > 0.0
    assert (tmp_path / "kf" / "commands.csv").exists() and (tmp_path / "kf" / "commands.png").exists()


def test_log_export_opens_the_record_as_csv(session: dict, tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    assert dpcontrol_main(["log", "export", str(session["records"]), "--csv", str(tmp_path / "csv")]) == 0
    written = {Path(p).name for p in capsys.readouterr().out.split()}
    assert {"command.csv", "estimate.csv", "cycle.csv", "raw.csv"} <= written
    header = (tmp_path / "csv" / "estimate.csv").read_text().splitlines()[0]
    assert "eta_n[0]" in header


def test_unwritable_recorder_path_raises_an_alarm_and_the_loop_keeps_running(tmp_path: Path) -> None:
    blocker = tmp_path / "not-a-directory"
    blocker.write_text("a file where the recordings should go")
    port = free_tcp_port()
    config = {
        "vessel_id": "rec", "vessel": "cybership2", "loop": {"rate_hz": 10},
        "transports": [{"name": "serial", "protocol": "nmea0183", "port": str(tmp_path / "missing-tty")}],
        "sensors": [{"name": "gnss1", "kind": "position", "transport": "serial"},
                    {"name": "gyro1", "kind": "heading", "transport": "serial"}],
        "zenoh": {"listen": [f"tcp/127.0.0.1:{port}"]},
        "recorder": {"path": str(blocker / "records")},
    }
    path = tmp_path / "vessel.yaml"
    path.write_text(yaml.safe_dump(config))
    sock_path = tmp_path / "n.sock"
    listener = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    listener.bind(str(sock_path))
    env = dict(os.environ, NOTIFY_SOCKET=str(sock_path))


    process = subprocess.Popen([sys.executable, "-m", "dpcontrol.cli", "run", "--config", str(path)], env=env,
                               stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    node = None
    try:
        listener.settimeout(60.0)
        assert b"READY=1" in listener.recv(4096)
        node = ZenohNode(ZenohConfig(connect=(f"tcp/127.0.0.1:{port}",)), "rec")
        status = LatestSlot()
        subscriber = node.subscribe("status", status)
        assert _wait_for(lambda: status.latest() is not None and any(
            a["code"] == "recorder.error" for a in status.latest().message["alarms"]), 30.0), \
            (subscriber.stats.last_rejection.detail if subscriber.stats.last_rejection else None, process.poll())
        first = status.latest().message["seq"]
        assert _wait_for(lambda: status.latest().message["seq"] >= first + 20, 10.0)  # still cycling at 10 Hz
    finally:
        if node is not None:
            node.close()
        process.send_signal(signal.SIGTERM)
        assert process.wait(20.0) == 0
        listener.close()
