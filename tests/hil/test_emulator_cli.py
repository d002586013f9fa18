"""``sim-plant`` command line: the sub-commands, configuration errors, and ``sim-plant hil`` as a
process under a stand-in for systemd (READY, WATCHDOG from the loop, SIGTERM → clean exit 0)."""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest
import yaml

from sim_plant.cli import _kept_settings, describe_alarms, main

ROOT = Path(__file__).resolve().parents[2]
START_TIMEOUT_S = 60.0  # a cold interpreter importing zenoh, scipy, python-can on a loaded 2-core machine


def _files(tmp_path: Path, rig: Any) -> tuple[Path, Path, Path]:
    port = tmp_path / "ttyGNSS"
    controller = rig.write_yaml(tmp_path / "vessel.yaml", {
        "vessel_id": "cli",
        "transports": [{"name": "serial0", "protocol": "nmea0183", "port": str(port)}],
        "sensors": [{"name": "gnss1", "kind": "position", "transport": "serial0"},
                    {"name": "gyro1", "kind": "heading", "transport": "serial0"}],
        "zenoh": {"listen": [f"tcp/127.0.0.1:{rig.free_port()}"]},   # nobody there: retried in the background
    })
    scenario = rig.write_yaml(tmp_path / "scenario.yaml", {"name": "cli", "vessel": "cybership2", "duration_s": 600})
    return scenario, controller, port


def test_run_refuses_a_missing_scenario_and_a_bad_override(tmp_path: Path,
                                                            capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["run", str(tmp_path / "missing.yaml"), "--out", str(tmp_path / "out")]) == 2
    assert "missing.yaml" in capsys.readouterr().err
    assert main(["run", "cs2-seed000", "--out", str(tmp_path / "out"), "--override", "[1, 2]"]) == 2
    assert "expected a mapping" in capsys.readouterr().err
    assert main(["run", "cs2-seed000", "--out", str(tmp_path / "out"), "--override", "{estimator: {kind: ekf}}"]) == 2
    assert "estimator.kind" in capsys.readouterr().err


def test_run_and_demo_refuse_an_output_folder_they_cannot_write_before_starting(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    blocker = tmp_path / "a-file"
    blocker.write_text("not a folder\n")
    for command in (["run", "cs2-seed000"], ["demo", "--duration", "5", "--no-live"]):
        started = time.monotonic()
        assert main([*command, "--out", str(blocker / "out")]) == 2
        err = capsys.readouterr().err
        assert f"cannot write into the output folder {blocker / 'out'}" in err, err
        assert time.monotonic() - started < 10.0  # refused up front: no simulation, no processes
    assert blocker.read_text() == "not a folder\n"


def test_no_command_prints_help(capsys: pytest.CaptureFixture[str]) -> None:
    assert main([]) == 2
    assert "hil" in capsys.readouterr().err


def test_configuration_errors_exit_2_naming_the_file(tmp_path: Path, rig: Any,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    scenario, controller, _ = _files(tmp_path, rig)
    assert main(["hil", str(scenario), "--controller-config", str(tmp_path / "nope.yaml")]) == 2
    assert "nope.yaml" in capsys.readouterr().err
    bad = rig.write_yaml(tmp_path / "bad.yaml", {**yaml.safe_load(controller.read_text()), "vessel_id": "a b"})
    assert main(["hil", str(scenario), "--controller-config", str(bad)]) == 2
    assert "bad.yaml: vessel_id: expected" in capsys.readouterr().err
    assert main(["hil", "no-such-builtin", "--controller-config", str(controller)]) == 2
    assert "unknown built-in scenario 'no-such-builtin'" in capsys.readouterr().err
    with pytest.raises(SystemExit) as usage:
        main(["hil", str(scenario), "--controller-config", str(controller), "--speed", "-1"])
    assert usage.value.code == 2


def test_a_link_that_cannot_open_exits_1(tmp_path: Path, rig: Any, capsys: pytest.CaptureFixture[str]) -> None:
    scenario, controller, port = _files(tmp_path, rig)
    port.write_text("a real file where the daemon's port should be")
    assert main(["hil", str(scenario), "--controller-config", str(controller)]) == 1
    assert "not a symlink" in capsys.readouterr().err
    assert port.read_text().startswith("a real file")


def _receive(sock: socket.socket, wanted: bytes, deadline: float) -> list[bytes]:
    """Notifications until one contains ``wanted`` (all of them returned), or fail at the deadline."""
    got = []
    while (remaining := deadline - time.monotonic()) > 0:
        sock.settimeout(remaining)
        try:
            message = sock.recv(4096)
        except TimeoutError:
            break
        got.append(message)
        if wanted in message:
            return got
    pytest.fail(f"no {wanted!r} notification; got {got!r}")


@pytest.mark.skipif(os.name != "posix", reason="systemd notification and signals")
@pytest.mark.parametrize("stop_signal", [signal.SIGTERM, signal.SIGHUP], ids=["SIGTERM", "SIGHUP"])
def test_hil_process_notifies_systemd_and_stops_cleanly_on_sigterm(tmp_path: Path, rig: Any,
                                                                  stop_signal: signal.Signals) -> None:
    """SIGHUP (the terminal that started the bench went away) stops it as SIGTERM does."""
    scenario, controller, port = _files(tmp_path, rig)
    out = tmp_path / "out"
    notify_path = tmp_path / "notify.sock"
    with socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM) as sock:
        sock.bind(str(notify_path))
        env = {**os.environ, "NOTIFY_SOCKET": str(notify_path), "WATCHDOG_USEC": "300000",
               "PYTHONPATH": str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", "")}
        env.pop("WATCHDOG_PID", None)
        process = subprocess.Popen(
            [sys.executable, "-m", "sim_plant.cli", "--log-level", "WARNING", "hil", str(scenario),
             "--controller-config", str(controller), "--out", str(out)],
            cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        try:
            _receive(sock, b"READY=1", time.monotonic() + START_TIMEOUT_S)
            assert port.is_symlink()  # links are up when READY is sent
            watchdog = _receive(sock, b"WATCHDOG=1", time.monotonic() + 5.0)
            watchdog += _receive(sock, b"WATCHDOG=1", time.monotonic() + 5.0)
            assert sum(b"WATCHDOG=1" in m for m in watchdog) >= 2
            process.send_signal(stop_signal)
            stdout, stderr = process.communicate(timeout=30.0)
            stopping = _receive(sock, b"STOPPING=1", time.monotonic() + 5.0)
        finally:
            if process.poll() is None:
                process.kill()
                process.communicate(timeout=30.0)
    # a clean stop; but no controller was there during the whole run: nothing was tested, and it says so
    assert process.returncode == 1, stderr.decode(errors="replace")
    assert b"no controller for vessel 'cli' was seen during the whole run" in stderr
    assert any(b"STOPPING=1" in m for m in stopping)
    assert b"gnss1 (gnss, 5 Hz) -> nmea0183 serial0 " + str(port).encode() in stdout
    summary = json.loads((out / "hil_summary.json").read_text())
    assert summary["stopped_by"] == f"signal {stop_signal.name}"
    assert 0.0 < summary["duration_s"] < 600.0
    assert (out / "truth.csv").exists() and not port.exists()


def test_hil_without_a_controller_for_the_whole_run_exits_1_saying_so(
        tmp_path: Path, rig: Any, capsys: pytest.CaptureFixture[str]) -> None:
    scenario, controller, _ = _files(tmp_path, rig)
    extra = f"tcp/127.0.0.1:{rig.free_port()}"
    assert main(["hil", str(scenario), "--controller-config", str(controller), "--duration", "1",
                 "--zenoh-listen", extra]) == 1
    captured = capsys.readouterr()
    assert "no controller for vessel 'cli' was seen during the whole run" in captured.err
    # --zenoh-listen added an endpoint; the daemon's (from its configuration) is still connected to
    daemon_endpoint = yaml.safe_load(controller.read_text())["zenoh"]["listen"][0]
    assert f"listen ['{extra}'], connect ['{daemon_endpoint}']" in captured.out


def test_kind_overrides_keep_what_still_applies(tmp_path: Path) -> None:
    """``--estimator`` keeps the scenario's sensor-noise tuning when switching between DP wave filters and
    its whole section when the kind is only restated; ``--control mrac-fixed`` keeps the MRAC settings."""
    rpem = {"kind": "rpem", "omega0_rad_s": 0.6, "position_noise_std_m": 0.52, "heading_noise_std_rad": 0.002}
    assert _kept_settings(rpem, "rpem", ("position_noise_std_m",)) == {k: v for k, v in rpem.items() if k != "kind"}
    assert _kept_settings(rpem, "mmae", ("position_noise_std_m", "heading_noise_std_rad")) == {
        "position_noise_std_m": 0.52, "heading_noise_std_rad": 0.002}
    assert _kept_settings(rpem, "kalman_bucy", ("position_noise_std_m",)) == {}
    assert _kept_settings(None, "mmae", ()) == {}
    out = tmp_path / "out"
    assert main(["run", "tanker-seed003", "--out", str(out), "--estimator", "rpem", "--control", "mrac-fixed",
                 "--duration", "20", "--no-plots", "--no-progress"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["control"] == "mrac" and summary["control_adapt"] is False
    # the scenario's ω0 = 0.6 rad/s kept (the default start would be 0.8 rad/s)
    assert summary["metrics"]["omega_hat_final_rad_s"] == pytest.approx(0.6, abs=0.05)


def test_describe_alarms_lists_every_code_raised_even_those_cleared_long_before_the_end() -> None:
    events = [
        {"t_s": 0.8, "code": "heading.lost", "raised": True, "severity": "alarm"},
        {"t_s": 10.3, "code": "heading.lost", "raised": False, "severity": "alarm"},
        {"t_s": 12.0, "code": "sensor.gnss1.stale", "raised": True, "severity": "warning"},
        {"t_s": 13.0, "code": "sensor.gnss1.stale", "raised": False, "severity": "warning"},
        {"t_s": 20.0, "code": "sensor.gnss1.stale", "raised": True, "severity": "warning"},
        {"t_s": 30.0, "code": "thrusters.capability", "raised": True, "severity": "alarm"},
        {"t_s": 31.0, "code": "never.raised", "raised": False, "severity": "info"},  # a clear alone: ignored
    ]
    assert describe_alarms(events) == (
        "heading.lost (alarm, from 0.8 s to 10.3 s), "
        "sensor.gnss1.stale (warning, from 12.0 s still active, raised 2 times), "
        "thrusters.capability (alarm, from 30.0 s still active)")
    assert describe_alarms([]) == "none"
    many = [{"t_s": float(i), "code": f"c{i}", "raised": True, "severity": "info"} for i in range(9)]
    assert describe_alarms(many, most=6).endswith("c5 (info, from 5.0 s still active), and 3 more in summary.json")


def test_run_prints_the_alarms_of_the_run(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    scenario = yaml.safe_load((ROOT / "sim_plant" / "scenarios" / "cs2-seed000.yaml").read_text(encoding="utf-8"))
    scenario.update(name="gyro-dies", duration_s=20)
    scenario["faults"] = [{"t_s": 5.0, "sensor": "gyro1", "kind": "gyro_dropout", "duration_s": 30.0}]
    path = tmp_path / "gyro-dies.yaml"
    path.write_text(yaml.safe_dump(scenario), encoding="utf-8")
    assert main(["run", str(path), "--out", str(tmp_path / "out"), "--no-plots", "--no-progress"]) == 0
    out = capsys.readouterr().out
    (line,) = [text for text in out.splitlines() if text.startswith("  alarms: ")]
    summary = json.loads((tmp_path / "out" / "summary.json").read_text(encoding="utf-8"))
    raised = {event["code"] for event in summary["alarm_events"] if event["raised"]}
    assert raised and all(code in line for code in raised), (line, raised)
    assert "still active" in line  # the gyro is still out at the end


def test_run_refuses_a_time_series_larger_than_the_memory_before_starting(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    import sim_plant.bench.lockstep as lockstep  # noqa: PLC0415

    monkeypatch.setattr(lockstep, "available_memory_bytes", lambda: 4 * 2**20)  # a machine with 4 MiB free
    started = time.monotonic()
    # 300 s at 10 Hz × 60 columns is 1.4 MiB: fits
    assert main(["run", "cs2-seed000", "--out", str(tmp_path / "fits"), "--no-plots", "--duration", "300"]) == 0
    capsys.readouterr()
    # 3000 s is 13.7 MiB: refused before the first step, with what it needs and what would fit
    assert main(["run", "cs2-seed000", "--out", str(tmp_path / "big"), "--no-plots", "--duration", "3000"]) == 2
    err = capsys.readouterr().err
    assert err == ("sim-plant run: the time series of 30001 steps × 60 columns needs 13.7 MiB, more than half of "
                   "the 4.0 MiB available: run a shorter duration; at most about 0.1 h here\n"), err
    assert not (tmp_path / "big" / "timeseries.csv").exists()
    assert time.monotonic() - started < 60.0


def test_run_says_when_its_results_cannot_be_written(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    import errno  # noqa: PLC0415

    import sim_plant.bench.run as run  # noqa: PLC0415

    def full_disk(*_args: object) -> None:
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(run, "write_timeseries_csv", full_disk)
    assert main(["run", "cs2-seed000", "--out", str(tmp_path / "out"), "--no-plots", "--duration", "5"]) == 1
    assert capsys.readouterr().err == (f"sim-plant run: writing the results into {tmp_path / 'out'} failed: "
                                       "[Errno 28] No space left on device\n")


def test_run_stops_with_one_line_when_the_plant_leaves_its_range(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    from sim_plant.plant import Plant  # noqa: PLC0415

    monkeypatch.setattr(Plant, "_state_finite", lambda plant: plant.t_s < 3.0)  # as if it overflowed at 3 s
    assert main(["run", "cs2-seed000", "--out", str(tmp_path / "out"), "--no-plots", "--duration", "10"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("sim-plant run: the run stopped: the vessel's motion left the model's range at "
                          "t = 3.00 s"), err
    assert "Traceback" not in err
