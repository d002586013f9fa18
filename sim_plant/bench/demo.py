"""``sim-plant demo``: the emulator and the real daemon as two processes, a live view, a report.

The demo is the hardware-in-the-loop bench on one machine:

1. a run directory (``./runs/demo-<UTC time>`` by default) gets the scenario (its sensors spread over
   all three sensor protocols: NMEA 0183 on a pseudo-terminal, NMEA 2000 on a python-can-remote
   bus, MAVLink over UDP) and a controller configuration wired to the same places, with free ports
   on 127.0.0.1;
2. ``sim-plant hil`` (the emulator) starts and creates the pty, the CAN server and the Zenoh peer;
   when it reports READY over a private ``NOTIFY_SOCKET`` (the systemd protocol), ``dpcontrol run``
   starts as a separate process; the emulator, acting as the operator, engages DP and sends the
   scenario's setpoints over Zenoh;
3. ``dpcontrol monitor``'s live view runs for the scenario's duration (or a line of progress every
   ten seconds when the output is not a terminal);
4. both get SIGTERM (the daemon first: it commands zero thrust last); the report — plots and
   ``summary.json`` from the plant's truth, the commands it received, the daemon's black-box
   recording and its loop timing, and the share of the CPUs the hypervisor took meanwhile (``host_steal``:
   0 on dedicated hardware; on a virtual machine, time in which both processes stood still) — is written
   to ``<run>/report``, and ``sim-plant demo`` prints its outcome (:func:`describe_summary`).

Ctrl-C (SIGINT), SIGTERM or SIGHUP during the run ends it early the same way — the daemon stopped first,
then the emulator, and a report of what ran (``summary.json``'s ``interrupted_by`` names the signal); before
the run has started they stop whatever was started, daemon first. The processes run in sessions of their
own, so a demo that died without stopping them would leave them running.
"""

from __future__ import annotations

import json
import math
import os
import resource
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from dpbase.schema import ConfigError
from dpbase.yamlfile import load_yaml, read_yaml_file
from dpcontrol.platform_info import cpu_times, describe_steal, host_steal
from dpcontrol.runtime.config import CONTROLLER_SECTIONS
from interfaces.zenoh.loopback import free_tcp_port, free_udp_port
from interfaces.zenoh.pki import IdentityFiles, init_ca, issue
from interfaces.zenoh.security import ZenohSecurity
from sim_plant.bench.report import PlotEvent, mark_events, plot_events

DEMO_SENSORS = [
    {"name": "gnss1", "kind": "gnss", "protocol": "nmea0183", "rate_hz": 10},
    {"name": "gyro1", "kind": "gyro", "protocol": "nmea0183", "rate_hz": 10},
    {"name": "gnss2", "kind": "gnss", "protocol": "nmea2000", "rate_hz": 5},
    {"name": "gyro2", "kind": "gyro", "protocol": "nmea2000", "rate_hz": 10},
    {"name": "gnss3", "kind": "gnss", "protocol": "mavlink", "rate_hz": 5},
]
READY_TIMEOUT_S = 60.0
# SCHED_FIFO priority of the daemon's loop thread in the demo when the user may set it (the middle of 1–99:
# above every normal process, below the kernel's own real-time threads)
DEMO_REALTIME_PRIORITY = 50
# The emulator runs this much longer than the scenario: the daemon is stopped first (SIGTERM), and the
# plant must still be there to receive its last command — zero thrust — before it is stopped in turn.
STOP_MARGIN_S = 30.0
#: The demo's zenoh identities and their roles (docs/security.md): the daemon; the emulator, which stands for
#: both the drives and the scenario's operator; the live view (a bridge console); a shore monitor for the reader.
DEMO_IDENTITIES: dict[str, tuple[str, ...]] = {"dp": ("controller",), "plant": ("drives", "console"),
                                              "bridge": ("console",), "shore": ("monitor",)}


class DemoError(RuntimeError):
    """The demo could not run (a process failed to start, a port could not be found ...)."""


class _NotifyListener:
    """A private sd_notify socket: learns when a child process says READY=1 (and collects its status)."""

    def __init__(self, directory: Path, name: str) -> None:
        self.path = directory / f"{name}.sock"
        self.sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
        self.sock.bind(str(self.path))
        self.messages: list[str] = []

    def wait_ready(self, timeout_s: float, process: subprocess.Popen[bytes]) -> bool:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if process.poll() is not None:
                return False
            self.sock.settimeout(min(0.5, max(0.01, deadline - time.monotonic())))
            try:
                data = self.sock.recv(4096).decode("utf-8", "replace")
            except TimeoutError:
                continue
            self.messages.append(data)
            if "READY=1" in data.split("\n"):
                return True
        return False

    def close(self) -> None:
        self.sock.close()


def realtime_priority_allowed(wanted: int = DEMO_REALTIME_PRIORITY) -> int | None:
    """The SCHED_FIFO priority this user may give the daemon's loop thread (≤ ``wanted``), or None.

    Root (CAP_SYS_NICE) may use any; another user up to its ``RLIMIT_RTPRIO`` (``ulimit -r``), which is
    0 on most desktops — the demo then runs the loop on the normal scheduler, without an alarm.
    """
    if not hasattr(os, "sched_setscheduler"):
        return None
    if os.geteuid() == 0:
        return wanted
    soft, _ = resource.getrlimit(resource.RLIMIT_RTPRIO)
    limit = wanted if soft == resource.RLIM_INFINITY else min(wanted, soft)
    return limit if limit >= 1 else None


def prepare(scenario_path: Path, run_dir: Path, *, realtime: bool = False,
            secure: bool = True) -> tuple[Path, Path, dict[str, Any]]:
    """Write the demo scenario and the controller configuration into ``run_dir``.

    ``realtime``: give the daemon's control-loop thread SCHED_FIFO (``loop.realtime_priority``) when this
    user may (:func:`realtime_priority_allowed`); it shortens the tail of the cycle latency on a shared
    machine. ``secure``: zenoh over mutual TLS with access control by role, as on a vessel (a CA and the
    certificates of :data:`DEMO_IDENTITIES` made in ``run_dir/tls``); else plaintext TCP on 127.0.0.1.
    Returns the two paths and the wiring (vessel id, zenoh endpoints, TLS directory, duration).
    """
    try:
        _, scenario = read_yaml_file(scenario_path, what="a readable scenario file")
    except ConfigError as error:
        raise DemoError(str(error)) from None
    if not isinstance(scenario, dict):
        raise DemoError(f"{scenario_path}: not a scenario mapping")
    protocols = {s.get("protocol", "nmea0183") for s in scenario.get("sensors") or []}
    if not {"nmea0183", "nmea2000", "mavlink"} <= protocols:
        scenario["sensors"] = DEMO_SENSORS  # the demo shows every transport
    short = Path(tempfile.mkdtemp(prefix="dp-demo-"))  # pty symlinks and sockets: short paths
    zenoh_port, can_port, mav_port = free_tcp_port(), free_tcp_port(), free_udp_port()
    plant_zenoh_port = free_tcp_port()
    scheme = "tls" if secure else "tcp"
    zenoh_section: dict[str, Any] = {"mode": "peer", "listen": [f"{scheme}/127.0.0.1:{zenoh_port}"]}
    tls_dir = None
    if secure:
        tls_dir = (run_dir / "tls").resolve()
        init_ca(tls_dir, "demo", overwrite=True)
        for name, roles in DEMO_IDENTITIES.items():
            # (a year: a certificate within EXPIRY_WARNING_DAYS of its end raises zenoh.certificate_expiring, which
            # a fresh demo would show as its one alarm)
            issue(tls_dir, "+".join(roles), name, days=365)
        zenoh_section.update(tls={"dir": str(tls_dir), "identity": "dp"},
                             identities={name: list(roles) for name, roles in DEMO_IDENTITIES.items()})
    controller = dict(scenario.get("controller") or {})
    transports = [
        {"name": "serial_nav", "protocol": "nmea0183", "port": str(short / "ttyNAV"), "baud": 38400},
        {"name": "can_nav", "protocol": "nmea2000", "interface": "remote", "channel": f"ws://127.0.0.1:{can_port}/"},
        {"name": "autopilot", "protocol": "mavlink", "url": f"udpin:127.0.0.1:{mav_port}"},
    ]
    transport_of = {"nmea0183": "serial_nav", "nmea2000": "can_nav", "mavlink": "autopilot"}
    sensors = []
    address = 40
    for spec in scenario["sensors"]:
        entry: dict[str, Any] = {"name": spec["name"], "transport": transport_of[spec.get("protocol", "nmea0183")],
                                 "rate_hz": spec.get("rate_hz", 5 if spec["kind"] == "gnss" else 10)}
        if spec["kind"] == "gnss":
            entry.update(kind="position", sigma_m=max(float(spec.get("noise_m", 0.02)), 0.01))
        else:
            entry.update(kind="heading", sigma_deg=max(float(spec.get("noise_deg", 0.05)), 0.02))
        if spec.get("protocol") == "nmea2000":
            entry["source_address"] = address
            address += 1
        elif spec.get("protocol") == "mavlink":
            entry["system_id"] = 1
        sensors.append(entry)
    config: dict[str, Any] = {
        "vessel_id": "demo",
        "vessel": scenario.get("vessel", "cybership2"),
        "datum": scenario.get("datum"),
        "loop": {"rate_hz": 10},
        "transports": transports,
        "sensors": sensors,
        "zenoh": zenoh_section,
        "recorder": {"path": str(run_dir / "records"), "flush_s": 0.5},
        "state": {"path": str(run_dir / "state.json"), "max_age_s": 30},
    }
    priority = realtime_priority_allowed() if realtime else None
    if priority is not None:
        config["loop"]["realtime_priority"] = priority
    for key in CONTROLLER_SECTIONS:
        if key in controller:
            config[key] = controller[key]
    if config["datum"] is None:
        del config["datum"]
    scenario_file = run_dir / "scenario.yaml"
    config_file = run_dir / "vessel.yaml"
    scenario_file.write_text(yaml.safe_dump(scenario, sort_keys=False), encoding="utf-8")
    config_file.write_text(yaml.safe_dump(config, sort_keys=False), encoding="utf-8")
    wiring = {"vessel_id": "demo", "zenoh": f"{scheme}/127.0.0.1:{zenoh_port}",
              "zenoh_plant": f"{scheme}/127.0.0.1:{plant_zenoh_port}", "short_dir": str(short),
              "tls_dir": None if tls_dir is None else str(tls_dir),
              "duration_s": float(scenario.get("duration_s", 120.0))}
    return scenario_file, config_file, wiring


def emulator_command(scenario_file: Path, config_file: Path, wiring: dict[str, Any], out_dir: Path,
                     duration_s: float) -> list[str]:
    """``sim-plant hil`` for the demo: engages DP as the operator; listens on its own zenoh endpoint (so a
    monitor sees the plant's liveliness too) and connects to the daemon's."""
    tls = [] if wiring.get("tls_dir") is None else ["--tls-dir", wiring["tls_dir"], "--identity", "plant"]
    return [sys.executable, "-m", "sim_plant.cli", "--log-level", "WARNING", "hil", str(scenario_file),
            "--controller-config", str(config_file), "--out", str(out_dir), "--engage", "--duration", str(duration_s),
            "--zenoh-listen", wiring["zenoh_plant"], "--zenoh-connect", wiring["zenoh"], *tls]


def _parent_death_signal() -> Any:
    """A ``preexec_fn`` for the children (Linux): SIGTERM when the demo dies, however it dies (SIGKILL too).

    The processes run in sessions of their own (a terminal's signals go to the demo, which stops them in
    order); without this a demo killed outright would leave them running. ``prctl`` is looked up here, in
    the parent: the child, between fork and exec, only calls it (no import, no lookup, no lock taken).
    """
    if sys.platform != "linux":
        return None
    import ctypes  # noqa: PLC0415

    prctl = ctypes.CDLL(None, use_errno=True).prctl
    pr_set_pdeathsig, sigterm = 1, int(signal.SIGTERM)  # <linux/prctl.h>
    return lambda: prctl(pr_set_pdeathsig, sigterm, 0, 0, 0)


def _spawn(args: list[str], log: Path, notify: _NotifyListener) -> subprocess.Popen[bytes]:
    env = dict(os.environ, NOTIFY_SOCKET=str(notify.path), PYTHONUNBUFFERED="1", OPENBLAS_NUM_THREADS="1")
    handle = log.open("wb")
    # (preexec_fn with threads running: safe here, it only calls a C function resolved before the fork)
    return subprocess.Popen(args, stdout=handle, stderr=subprocess.STDOUT, env=env, start_new_session=True,
                            preexec_fn=_parent_death_signal())  # noqa: PLW1509


def _stop(process: subprocess.Popen[bytes], timeout_s: float = 15.0) -> int | None:
    if process.poll() is None:
        process.send_signal(signal.SIGTERM)
        try:
            process.wait(timeout_s)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait(5.0)
    return process.returncode


class _StopSignals:
    """While active (main thread only), SIGINT, SIGTERM and SIGHUP raise KeyboardInterrupt in the main
    thread and are remembered: the demo then ends early in order instead of dying with its processes left
    running (SIGTERM's and SIGHUP's default actions skip every ``finally``)."""

    SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)

    def __init__(self) -> None:
        self.received: str | None = None
        self._previous: dict[int, Any] = {}

    def _on_signal(self, signum: int, _frame: Any) -> None:
        if self.received is None:
            self.received = signal.Signals(signum).name
        raise KeyboardInterrupt

    def install(self) -> None:
        if threading.current_thread() is threading.main_thread():  # (signal.signal works there only)
            self._previous = {sig: signal.signal(sig, self._on_signal) for sig in self.SIGNALS}

    def restore(self) -> None:
        for sig, handler in self._previous.items():
            signal.signal(sig, handler)
        self._previous = {}


def run_demo(scenario_path: Path, run_dir: Path | None = None, *, duration_s: float | None = None,
             live: bool | None = None, quiet: bool = False, secure: bool = True) -> Path:
    """Run the demo (see the module docstring); returns the report directory. ``secure``: see :func:`prepare`.

    Raises
    ------
    DemoError
        A process did not start.
    KeyboardInterrupt
        Interrupted (SIGINT, SIGTERM, SIGHUP) before the run started; whatever had started is stopped.
    """
    stamp = time.strftime("%Y%m%d-%H%M%S", time.gmtime())
    run_dir = run_dir or Path("runs") / f"demo-{stamp}"
    run_dir.mkdir(parents=True, exist_ok=True)
    scenario_file, config_file, wiring = prepare(scenario_path, run_dir, realtime=True, secure=secure)
    duration = duration_s if duration_s is not None else wiring["duration_s"]
    short = Path(wiring["short_dir"])
    say = (lambda *_: None) if quiet else (lambda text: print(f"sim-plant demo: {text}", flush=True))
    plant_notify = _NotifyListener(short, "plant")
    daemon_notify = _NotifyListener(short, "daemon")
    python = sys.executable
    emulator = daemon = None
    stop_signals = _StopSignals()
    try:
        stop_signals.install()
        say(f"run directory {run_dir}")
        emulator = _spawn(emulator_command(scenario_file, config_file, wiring, run_dir / "plant",
                                           duration + STOP_MARGIN_S),
                          run_dir / "sim-plant.log", plant_notify)
        if not plant_notify.wait_ready(READY_TIMEOUT_S, emulator):
            raise DemoError(f"the emulator did not become ready (see {run_dir / 'sim-plant.log'})")
        plant_start = time.monotonic()
        say("emulator ready: NMEA 0183 on a pty, NMEA 2000 on python-can-remote, MAVLink on UDP, Zenoh peer")
        daemon = _spawn([python, "-m", "dpcontrol.cli", "run", "--config", str(config_file), "--stats-out",
                         str(run_dir / "dpcontrol-stats.json")], run_dir / "dpcontrol.log", daemon_notify)
        if not daemon_notify.wait_ready(READY_TIMEOUT_S, daemon):
            raise DemoError(f"dpcontrol did not become ready (see {run_dir / 'dpcontrol.log'})")
        ticks = cpu_times()  # the hypervisor's share of the CPUs over the daemon's loop (host_steal)
        tls_dir = wiring["tls_dir"]
        tls_options = "" if tls_dir is None else f" --tls-dir {tls_dir} --identity shore"
        say(f"dpcontrol ready; running the {duration:g} s scenario (live view: dpcontrol monitor --vessel demo "
            f"--connect {wiring['zenoh']}{tls_options})")
        remaining = duration - (time.monotonic() - plant_start)
        show_live = sys.stdout.isatty() if live is None else live
        try:
            if show_live and remaining > 1.0:
                from dpcontrol.monitor import run_monitor  # noqa: PLC0415

                # (it returns on KeyboardInterrupt, which the stop signals raise)
                view = None if tls_dir is None else ZenohSecurity(IdentityFiles.in_dir(tls_dir, "bridge"))
                run_monitor(wiring["vessel_id"], (wiring["zenoh"], wiring["zenoh_plant"]), duration_s=remaining,
                            security=view)
            else:
                end = plant_start + duration
                while time.monotonic() < end:
                    if emulator.poll() is not None or daemon.poll() is not None:
                        break
                    time.sleep(min(10.0, max(0.0, end - time.monotonic())))
                    say(f"t = {time.monotonic() - plant_start:5.0f} s of {duration:g} s")
        except KeyboardInterrupt:
            stop_signals.received = stop_signals.received or "SIGINT"
        stop_signals.restore()  # a second Ctrl-C while stopping: the finally below stops what is left
        interrupted = stop_signals.received
        if interrupted is not None:
            say(f"{interrupted} at t = {time.monotonic() - plant_start:.0f} s of {duration:g} s: stopping dpcontrol, "
                "then the emulator; the report covers what ran")
        daemon_code = _stop(daemon)  # first: its last command is zero thrust, which the plant still receives
        steal = host_steal(ticks, cpu_times())
        time.sleep(0.5)  # the command's way over Zenoh to the emulator (published before the daemon exits)
        plant_code = _stop(emulator)
        say(f"stopped: dpcontrol exit {daemon_code}, sim-plant exit {plant_code}")
        report_dir = write_report(run_dir, wiring, daemon_code=daemon_code, plant_code=plant_code, host_steal=steal,
                                  interrupted_by=interrupted)
        return report_dir
    finally:
        stop_signals.restore()
        for process in (daemon, emulator):  # the daemon first: its last command is zero thrust
            if process is not None and process.poll() is None:
                _stop(process, timeout_s=5.0)
        plant_notify.close()
        daemon_notify.close()
        shutil.rmtree(short, ignore_errors=True)


# the HIL latency budgets (docs/performance.md) at 10 Hz: cycle start → command published p99 and period jitter p99 [µs]
PUBLISHED_P99_TARGET_US = 2000.0
JITTER_P99_TARGET_US = 2000.0


def describe_summary(summary: dict[str, Any]) -> list[str]:
    """The demo's outcome in a few lines for the terminal, from its ``summary.json``.

    What a test engineer checks first: whether DP engaged and held the set-point (on the plant's true
    low-frequency position), the control loop's timing against the HIL targets (with the host's steal,
    which sets the tail on a virtual machine) and the last command. A key the run could not produce
    (a process that died early) is said to be missing rather than guessed.
    """
    lines: list[str] = []
    if summary.get("interrupted_by"):
        lines.append(f"ended early by {summary['interrupted_by']}: what follows covers the part that ran")
    engage = (summary.get("sim_plant") or {}).get("engage") or {}
    if summary.get("dp_engaged"):
        when = engage.get("t_s")
        lines.append("DP engaged" + (f" {when:.1f} s after the emulator started" if isinstance(when, float) else ""))
    else:
        lines.append("DP did NOT engage (mode changes: "
                     f"{[m.get('to') for m in summary.get('mode_changes') or []]}; see the logs in the run directory)")
    error_max = summary.get("position_error_last_half_max_m")
    error_rms = summary.get("position_error_last_half_rms_m")
    final, setpoint = summary.get("final_position_m"), summary.get("final_setpoint_m")
    if error_max is not None and error_rms is not None:
        where = ""
        if final and setpoint and None not in setpoint:
            where = (f" (final position {final[0]:.3f} m N, {final[1]:.3f} m E; set-point "
                     f"{setpoint[0]:g} m N, {setpoint[1]:g} m E)")
        window = summary.get("position_error_window_s")
        changed = summary.get("final_setpoint_t_s")
        if window and changed is not None and changed > window[0]:
            # a short run (--duration) whose last set-point came in its second half: a move, not station keeping
            what = (f"true position against the set-point over the second half of the run, which includes the move "
                    f"to the set-point of t = {changed:g} s")
        else:
            what = "station keeping, true position against the set-point over the second half of the run"
        lines.append(f"{what}: {error_max:.3f} m at most, {error_rms:.3f} m rms{where}")
    else:
        lines.append("station keeping: no plant truth to measure it from")
    loop = summary.get("dpcontrol_loop") or {}
    published = (loop.get("start_to_command_published_us") or {}).get("p99")
    jitter = (loop.get("period_jitter_us") or {}).get("p99")
    if published is not None and jitter is not None:
        def timing(value: float, target: float) -> str:
            return f"{value / 1000:.2f} ms ({'within' if value <= target else 'OVER'} {target / 1000:g} ms)"
        lines.append(f"control loop: {loop.get('cycles', 0)} cycles, {loop.get('missed_deadlines', 0)} missed "
                     f"deadlines, {loop.get('step_errors', 0)} step errors; p99 cycle start → command published "
                     f"{timing(published, PUBLISHED_P99_TARGET_US)}, p99 period jitter "
                     f"{timing(jitter, JITTER_P99_TARGET_US)}; loop thread: {loop.get('scheduling', 'unknown')}")
    else:
        lines.append("control loop: no timing (the daemon wrote no stats)")
    lines.append(f"{describe_steal(summary.get('host_steal'))} during the run: the hypervisor's share of the "
                 "CPUs, 0 on dedicated hardware; on a virtual machine the timing tails grow with it")
    raised = summary.get("alarms_raised")
    if isinstance(raised, list):  # (the daemon's record: absent when it wrote none)
        lines.append("alarms raised during the run: " + (", ".join(map(str, raised)) if raised else "none")
                     + (" (the daemon's record: dpcontrol log export)" if raised else ""))
    for group, check in (summary.get("consequence") or {}).items():
        held, count, busiest = check.get("held", 0), check.get("checks", 0), check.get("utilisation_max")
        busy = "" if busiest is None else \
            f", the busiest thruster left at {100.0 * busiest:.0f} % of its rating at most"
        verdict = "held in every check" if held == count else f"NOT held in {count - held} of the checks"
        lines.append(f"worst-case failure check: losing {group}: {count} checks, {verdict}{busy}")
    last = summary.get("last_command") or {}
    if summary.get("zero_thrust_commanded_last"):
        lines.append(f"last command: zero thrust, mode {last.get('mode', '?')}")
    else:
        lines.append(f"last command: NOT zero thrust ({last or 'none received'})")
    return lines


def _read_csv(path: Path) -> dict[str, Any]:
    """Each column of a CSV file as a float array (NaN where a cell is not a number), and the text: its
    rows as lists of cells under ``"_text"``, its header under ``"_header"``; empty when there is no file."""
    if not path.exists():
        return {}
    with path.open(encoding="utf-8") as handle:
        header = handle.readline().strip().split(",")
        rows = [line.strip().split(",") for line in handle if line.strip()]
    columns: dict[str, Any] = {}
    for i, name in enumerate(header):
        values = []
        for row in rows:
            try:
                values.append(float(row[i]) if i < len(row) and row[i] != "" else math.nan)
            except ValueError:
                values.append(math.nan)
        columns[name] = np.array(values)
    columns["_text"] = rows
    columns["_header"] = header
    return columns


def write_report(run_dir: Path, wiring: dict[str, Any], *, daemon_code: int | None,  # noqa: PLR0915 - the report's sections one after another
                 plant_code: int | None, host_steal: dict[str, float] | None = None,
                 interrupted_by: str | None = None) -> Path:
    """Plots and ``summary.json`` of a demo run (see the module docstring); ``host_steal`` is
    :func:`~dpcontrol.platform_info.host_steal` over the daemon's run (None: not measured);
    ``interrupted_by`` the signal that ended the run early (None: it ran its duration)."""
    from dpcontrol.logtools import read_records  # noqa: PLC0415

    report = run_dir / "report"
    report.mkdir(exist_ok=True)
    truth = _read_csv(run_dir / "plant" / "truth.csv")
    commands = _read_csv(run_dir / "plant" / "commands.csv")
    scenario_file = run_dir / "scenario.yaml"
    scenario = load_yaml(scenario_file.read_text(encoding="utf-8"))
    if not isinstance(scenario, dict):  # (prepare() wrote it from a mapping)
        raise DemoError(f"{scenario_file}: not a scenario mapping")
    summary: dict[str, Any] = {"run_dir": str(run_dir), "dpcontrol_exit": daemon_code, "sim_plant_exit": plant_code,
                               "host_steal": host_steal, "interrupted_by": interrupted_by}
    stats_file = run_dir / "dpcontrol-stats.json"
    if stats_file.exists():
        summary["dpcontrol_loop"] = json.loads(stats_file.read_text(encoding="utf-8"))
    hil_file = run_dir / "plant" / "hil_summary.json"
    if hil_file.exists():
        hil = json.loads(hil_file.read_text(encoding="utf-8"))
        summary["sim_plant"] = {k: hil.get(k) for k in ("duration_s", "stopped_by", "loop", "counts", "engage")}
    # the daemon's record: estimate, mode changes, alarms
    estimates: list[tuple[float, list[float]]] = []
    weights: list[tuple[float, list[float]]] = []
    modes: list[dict[str, Any]] = []
    alarms: list[dict[str, Any]] = []
    checks: dict[str, dict[str, Any]] = {}  # the worst-case failure checks, per failure group
    cycle_t: dict[int, float] = {}  # daemon time of each command (by its seq): the daemon clock → plant time
    records_dir = run_dir / "records"
    if records_dir.exists():
        for record in read_records(records_dir, ("estimate", "mmae", "mode", "alarm", "consequence", "command")):
            p = record.payload
            if record.topic == "command":
                cycle_t[int(p["cycle"])] = float(p["t_s"])
            elif record.topic == "consequence":
                for group in p.get("groups") or []:
                    entry = checks.setdefault(str(group.get("name")), {"checks": 0, "held": 0, "utilisation_max": None})
                    entry["checks"] += 1
                    entry["held"] += bool(group.get("holds"))
                    share = group.get("utilisation")
                    if isinstance(share, (int, float)) and group.get("holds"):
                        entry["utilisation_max"] = max(entry["utilisation_max"] or 0.0, round(float(share), 3))
            elif record.topic == "estimate":
                estimates.append((float(p["t_s"]), p["eta_n"]))
            elif record.topic == "mmae":
                weights.append((float(p["t_s"]), p["weights"]))
            elif record.topic == "mode":
                modes.append(p)
            else:
                alarms.append(p)
    summary["mode_changes"] = modes
    summary["alarms_raised"] = sorted({a["code"] for a in alarms if a.get("raised")})
    summary["consequence"] = checks
    # station keeping on the plant's truth, against the scenario setpoints in force
    if truth:
        t = truth["t_s"]
        setpoints = sorted(scenario.get("setpoints") or [], key=lambda s: s["t_s"])
        ref_north = np.full_like(t, np.nan)
        ref_east = np.full_like(t, np.nan)
        for sp in setpoints:
            mask = t >= sp["t_s"]
            if sp.get("north_m") is not None:
                ref_north[mask] = sp["north_m"]
                ref_east[mask] = sp["east_m"]
        engaged_t = next((float(m["t_s"]) for m in modes if m.get("to") == "auto_position"), None)
        summary["dp_engaged"] = engaged_t is not None
        error = np.hypot(truth["north_m"] - ref_north, truth["east_m"] - ref_east)
        half_s = float(t[0] + 0.5 * (t[-1] - t[0]))
        settled = t >= half_s
        if np.any(np.isfinite(error[settled])):
            summary["position_error_last_half_max_m"] = round(float(np.nanmax(error[settled])), 4)
            summary["position_error_last_half_rms_m"] = round(float(np.sqrt(np.nanmean(error[settled] ** 2))), 4)
            summary["position_error_window_s"] = [round(half_s, 2), round(float(t[-1]), 2)]  # scenario time
        summary["final_position_m"] = [round(float(truth["north_m"][-1]), 4), round(float(truth["east_m"][-1]), 4)]
        # the last set-point in force at the end: a run cut short (--duration, Ctrl-C) never saw the later ones
        in_force = [sp for sp in setpoints if sp["t_s"] <= t[-1]]
        summary["final_setpoint_m"] = [None if not in_force else in_force[-1].get("north_m"),
                                       None if not in_force else in_force[-1].get("east_m")]
        summary["final_setpoint_t_s"] = None if not in_force else float(in_force[-1]["t_s"])
    if commands:
        text = commands["_text"]
        header = commands["_header"]
        if text:
            last_t = text[-1][header.index("t_s")]
            last = [row for row in text if row[header.index("t_s")] == last_t]
            summary["last_command"] = {"mode": last[0][header.index("mode")],
                                       "thrust_n": [float(r[header.index("thrust_n")]) for r in last]}
            summary["zero_thrust_commanded_last"] = all(
                abs(float(r[header.index("thrust_n")])) == 0.0 for r in last)
    (report / "summary.json").write_text(json.dumps(summary, indent=2, default=str) + "\n", encoding="utf-8")
    offset = _daemon_to_plant_s(commands, cycle_t)
    events = _demo_events(scenario, commands)
    _plots(report, truth, scenario, estimates, weights, events=events, daemon_to_plant_s=offset)
    return report


def _daemon_to_plant_s(commands: dict[str, Any], cycle_t: dict[int, float]) -> float | None:
    """Plant time minus daemon time [s]: the median, over the commands both recorded (the daemon by its cycle
    number, the plant by the command's seq), of the plant's receive time minus the daemon's cycle time (the
    commands' transit, well under a cycle, is in it); ``None`` when none matched."""
    if not commands or not cycle_t:
        return None
    differences = [t - cycle_t[int(seq)] for t, seq in zip(commands["t_s"], commands["seq"], strict=True)
                   if math.isfinite(seq) and int(seq) in cycle_t]
    return float(np.median(differences)) if differences else None


def _demo_events(scenario: dict[str, Any], commands: dict[str, Any]) -> list[PlotEvent]:
    """Set-point and sea-state changes of the scenario and the DP engagements the plant saw (the mode of the
    commands it received), all in plant time."""
    modes: list[tuple[float, str]] = []
    if commands:
        header, rows = commands["_header"], commands["_text"]
        t_col, mode_col = header.index("t_s"), header.index("mode")
        modes = [(float(row[t_col]), row[mode_col]) for row in rows if len(row) > mode_col]
    return plot_events([float(p["t_s"]) for p in scenario.get("setpoints") or []],
                       [float(s.get("t_s", 0.0)) for s in scenario.get("sea_states") or []], modes)


def _plots(report: Path, truth: dict[str, np.ndarray], scenario: dict[str, Any],
           estimates: list[tuple[float, list[float]]], weights: list[tuple[float, list[float]]],
           *, events: Sequence[PlotEvent] = (), daemon_to_plant_s: float | None = None) -> None:
    """pose.png (the plant's truth, the daemon's estimate and the set-point) and weights.png, on plant time,
    every event marked (:func:`sim_plant.bench.report.mark_events`)."""
    import matplotlib  # noqa: PLC0415

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    if not truth:
        return
    fig, axes = plt.subplots(3, 1, figsize=(11, 8), sharex=True)
    t = truth["t_s"]
    setpoint = {key: np.full(t.shape, np.nan) for key in ("north_m", "east_m", "heading_rad")}
    for point in sorted(scenario.get("setpoints") or [], key=lambda p: p["t_s"]):
        after = t >= float(point["t_s"])
        heading = point.get("heading_deg")
        for key, value in (("north_m", point.get("north_m")), ("east_m", point.get("east_m")),
                           ("heading_rad", None if heading is None else math.radians(heading))):
            setpoint[key][after] = np.nan if value is None else value
    for ax, (key, total, label, scale) in zip(axes, (("north_m", "north_total_m", "north [m]", 1.0),
                                                      ("east_m", "east_total_m", "east [m]", 1.0),
                                                      ("heading_rad", "heading_total_rad", "heading [deg]",
                                                       180 / math.pi)), strict=True):
        ax.plot(t, truth[total] * scale, lw=0.6, alpha=0.6, label="true total (plant)")
        ax.plot(t, truth[key] * scale, lw=1.4, label="true LF (plant)")
        if estimates and daemon_to_plant_s is not None:
            te = np.array([e[0] for e in estimates]) + daemon_to_plant_s
            index = ("north_m", "east_m", "heading_rad").index(key)
            values = np.array([e[1][index] for e in estimates])
            if key == "heading_rad":  # (the truth is wrapped to (-pi, pi])
                values = np.angle(np.exp(1j * values))
            ax.plot(te, values * scale, lw=1.0, ls="--", label="LF estimate (dpcontrol)")
        ax.step(t, setpoint[key] * scale, where="post", color="tab:red", lw=1.0, label="set-point")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8, ncol=4)
    axes[0].set_title("sim-plant demo: the vessel as the plant saw it")
    axes[-1].set_xlabel("plant time [s]")
    span = (float(t[0]), float(t[-1]))
    mark_events(fig, events, span)
    fig.tight_layout(rect=(0.0, 0.03, 1.0, 1.0))
    fig.savefig(report / "pose.png", dpi=110)
    plt.close(fig)
    if weights:
        fig, ax = plt.subplots(figsize=(11, 4))
        tw = np.array([w[0] for w in weights])
        values = np.array([w[1] for w in weights])
        omegas = (scenario.get("controller") or {}).get("estimator", {}).get("omegas_rad_s") or \
            list(range(values.shape[1]))
        # on plant time, where the scenario's events are; else on the daemon's, unmarked (no command matched)
        shift = -tw[0] if daemon_to_plant_s is None else daemon_to_plant_s
        for i in range(values.shape[1]):
            ax.plot(tw + shift, values[:, i], label=f"{omegas[i]} rad/s" if i < len(omegas) else str(i))
        ax.set_ylabel("MMAE weight")
        ax.set_xlabel("daemon time since the first estimate [s]" if daemon_to_plant_s is None else "plant time [s]")
        ax.legend(fontsize=8, ncol=4)
        ax.grid(alpha=0.3)
        ax.set_title("MMAE weights as published by dpcontrol")
        if daemon_to_plant_s is not None:
            mark_events(fig, events, (float(tw[0] + shift), float(tw[-1] + shift)))
        fig.tight_layout(rect=(0.0, 0.03, 1.0, 1.0))
        fig.savefig(report / "weights.png", dpi=110)
        plt.close(fig)
