"""``sim-plant demo``, the README's main command, end to end through its command line, shortened to 25 s.

The emulator and a real ``dpcontrol run`` as two processes over a pty, python-can remote, UDP and Zenoh on
127.0.0.1 (what ``make demo`` runs, without the live view): both exit 0, DP engages, zero thrust is the
last command, and the report and the closing lines say so.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
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
    # secured as on a vessel: zenoh over mutual TLS, access control by role
    config = yaml.safe_load((out / "vessel.yaml").read_text(encoding="utf-8"))
    assert config["zenoh"]["listen"][0].startswith("tls/127.0.0.1:") and config["zenoh"]["identities"]["dp"]
    # certificates made for the demo are far from their end: no expiry warning is the fresh demo's one alarm
    assert not any("zenoh.certificate_expiring" in line for line in lines), lines


def _processes_mentioning(text: str) -> list[int]:
    """PIDs whose command line contains ``text`` (the run directory is in both children's)."""
    found = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                command = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
            except OSError:  # gone meanwhile
                continue
            if text in command and entry.name != str(os.getpid()):
                found.append(int(entry.name))
    return found


@pytest.mark.skipif(not Path("/proc/self/cmdline").exists(), reason="reads /proc")
def test_ctrl_c_ends_the_demo_early_in_order_with_a_report(tmp_path: Path) -> None:
    """Ctrl-C used to kill both processes (no zero-thrust command, no report), and SIGTERM or SIGHUP (a
    closed terminal) ended the demo with its two processes, in sessions of their own, still running."""
    out = tmp_path / "demo"
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1"}
    process = subprocess.Popen([sys.executable, "-m", "sim_plant.cli", "demo", "--duration", "200", "--no-live",
                                "--out", str(out)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    try:
        assert process.stdout is not None
        for line in process.stdout:  # "… dpcontrol ready; running …": both processes up
            if "dpcontrol ready" in line:
                break
        else:
            pytest.fail("the demo ended before dpcontrol was ready: " + process.stderr.read()[-3000:])
        children = [pid for pid in _processes_mentioning(str(out)) if pid != process.pid]
        assert len(children) == 2, children  # the emulator and the daemon
        time.sleep(4.0)
        process.send_signal(signal.SIGINT)
        rest, stderr = process.communicate(timeout=TIMEOUT_S)
    finally:
        if process.poll() is None:
            process.kill()
            process.communicate(timeout=30.0)
        leftover = [pid for pid in _processes_mentioning(str(out)) if pid != process.pid]
        for pid in leftover:  # (a failed test must not leave the demo's processes running: own sessions)
            os.kill(pid, signal.SIGKILL)
    assert leftover == []
    lines = [line.removeprefix("sim-plant demo: ") for line in rest.splitlines()]
    assert process.returncode == 130, rest[-3000:] + stderr[-3000:]
    assert any(line.startswith("SIGINT at t = ") for line in lines), lines
    assert "stopped: dpcontrol exit 0, sim-plant exit 0" in lines, lines
    assert "ended early by SIGINT: what follows covers the part that ran" in lines, lines
    assert "last command: zero thrust, mode standby" in lines, lines
    summary = json.loads((out / "report" / "summary.json").read_text(encoding="utf-8"))
    assert summary["interrupted_by"] == "SIGINT" and summary["zero_thrust_commanded_last"]
    assert summary["dpcontrol_loop"]["cycles"] < 100 * 10  # stopped long before its 200 s
    # the set-point reported is the one in force when it stopped, not the scenario's last
    assert summary["final_setpoint_t_s"] <= summary["position_error_window_s"][1]


@pytest.mark.parametrize("stop_signal", [signal.SIGTERM, signal.SIGHUP], ids=["SIGTERM", "SIGHUP"])
def test_termination_signals_interrupt_the_demo_like_ctrl_c(stop_signal: signal.Signals) -> None:
    """The demo's handler (in this process, as in the demo's main thread): the signal becomes a
    KeyboardInterrupt and is named, and the previous handlers come back."""
    from sim_plant.bench.demo import _StopSignals  # noqa: PLC0415

    before = signal.getsignal(stop_signal)
    signals = _StopSignals()
    signals.install()
    try:
        with pytest.raises(KeyboardInterrupt):
            os.kill(os.getpid(), stop_signal)
            time.sleep(1.0)  # (delivered at the next bytecode boundary of the main thread)
    finally:
        signals.restore()
    assert signals.received == stop_signal.name
    assert signal.getsignal(stop_signal) is before


@pytest.mark.skipif(sys.platform != "linux", reason="PR_SET_PDEATHSIG")
def test_a_killed_demo_takes_its_processes_with_it_in_order(tmp_path: Path) -> None:
    """SIGKILL leaves the demo no chance to stop anything: the kernel sends its two processes SIGTERM
    (PR_SET_PDEATHSIG), and the daemon stops as on any SIGTERM — zero thrust, standby."""
    out = tmp_path / "demo"
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1"}
    process = subprocess.Popen([sys.executable, "-m", "sim_plant.cli", "demo", "--duration", "200", "--no-live",
                                "--out", str(out)], stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True,
                               env=env)
    children: list[int] = []
    try:
        assert process.stdout is not None
        for line in process.stdout:
            if "dpcontrol ready" in line:
                break
        children = [pid for pid in _processes_mentioning(str(out)) if pid != process.pid]
        assert len(children) == 2, children
        process.kill()
        process.communicate(timeout=30.0)
        deadline = time.monotonic() + 30.0
        while time.monotonic() < deadline and [pid for pid in children if Path(f"/proc/{pid}").exists()]:
            time.sleep(0.2)
        left = [pid for pid in _processes_mentioning(str(out)) if pid != process.pid]
    finally:
        if process.poll() is None:
            process.kill()
        for pid in _processes_mentioning(str(out)):
            if pid != process.pid:
                os.kill(pid, signal.SIGKILL)
    assert left == []
    daemon_log = (out / "dpcontrol.log").read_text(encoding="utf-8", errors="replace")
    assert "stopping (SIGTERM): zero thrust commanded, mode standby" in daemon_log, daemon_log[-3000:]
