"""``sim-plant`` command line (composition layer): one function per sub-command.

* ``sim-plant run SCENARIO --out DIR``: lockstep closed loop, plant + the real controller step in one
  process (:mod:`sim_plant.bench.run`); timeseries.csv, summary.json, plots.
* ``sim-plant hil SCENARIO --controller-config FILE [--out DIR] [--speed 1.0] [--engage] [--duration S]``:
  the real-time emulator (:mod:`sim_plant.emulator`) for a separately started ``dpcontrol run --config FILE``.
* ``sim-plant demo``: emulator + daemon as two processes over all four transports, live view, report.
* ``sim-plant bench [--json]``: simulation speed (seed 003 12 h, seed 000).
* ``sim-plant campaign SPEC --out DIR`` and ``sim-plant capability VESSEL_OR_CONFIG --out DIR``: many lockstep
  runs on local processes or a Dask cluster, and DP capability plots (:mod:`sim_plant.campaign.commands`).

Exit status: 0 after a clean end (``hil``: duration reached, SIGTERM, SIGINT or SIGHUP), 1 when the
emulator fails at run time (a link that cannot be opened, an error in the loop; ``hil``: no controller
seen during the whole run), 2 for a usage or
configuration error (the message names the file and key), 130 when ``run``, ``demo`` or ``bench`` were
interrupted (Ctrl-C; ``run`` and ``demo`` still write what ran).
"""

from __future__ import annotations

import argparse
import logging
import os
import signal
import sys
from collections.abc import Mapping
from pathlib import Path
from types import FrameType
from typing import Any

from dpbase.yamlfile import load_yaml
from dpcontrol.arguments import positive_number
from interfaces.zenoh.security import add_tls_arguments

# Small matrices only: a threaded BLAS costs ~100x per LAPACK call on a loaded 2-core machine.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

EXIT_OK, EXIT_FAILURE, EXIT_USAGE = 0, 1, 2
EXIT_INTERRUPTED = 130  # as a shell reports a command ended by Ctrl-C (128 + SIGINT)


def build_parser() -> argparse.ArgumentParser:
    """The ``sim-plant`` argument parser with every sub-command."""
    parser = argparse.ArgumentParser(prog="sim-plant", description="Plant emulator of dpcontrol: vessel, sea, "
                                     "thrusters and sensors, in lockstep or in real time on real transports.")
    parser.add_argument("--log-level", default="INFO", help="logging level on stderr (default INFO)")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND")
    _add_run(commands)
    _add_hil(commands)
    _add_demo(commands)
    _add_bench(commands)
    _add_campaign_commands(commands)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``sim-plant`` console script."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help(sys.stderr)
        return EXIT_USAGE
    level = getattr(logging, str(args.log_level).upper(), None)
    if not isinstance(level, int):
        parser.error(f"unknown --log-level {args.log_level!r}")
    from dpcontrol.logsetup import configure_logging  # noqa: PLC0415 - after the environment above

    configure_logging(level, terminal_format="%(asctime)s %(name)s %(levelname)s %(message)s")
    try:
        return int(args.handler(args))
    except KeyboardInterrupt:  # Ctrl-C where a command has nothing to save: one line, not a traceback
        print(f"sim-plant {args.command}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED


# -- run ---------------------------------------------------------------------------------------------
def _add_run(commands: Any) -> None:
    sub = commands.add_parser("run", help="lockstep closed-loop simulation: plant + controller in one process")
    sub.add_argument("scenario", help="scenario YAML file or built-in name (cs2-seed000, supply-seed001, ...)")
    sub.add_argument("--out", type=Path, required=True, help="output directory (timeseries.csv, summary.json, PNGs)")
    sub.add_argument("--controller-config", type=Path, default=None,
                     help="controller configuration (its estimator, control, guidance, ...; sensors by name)")
    sub.add_argument("--estimator", choices=("mmae", "kf", "rpem", "raw", "kalman_bucy", "heading_kf"),
                     help="override the estimator kind")
    sub.add_argument("--control", choices=("pid", "mrac", "mrac-fixed", "autopilot"),
                     help="override the controller kind (mrac-fixed: MRAC structure with adaptation off)")
    sub.add_argument("--override", action="append", default=[], metavar="YAML",
                     help="controller config sections to override, e.g. '{estimator: {kind: kf, omega_rad_s: 0.9}}'")
    sub.add_argument("--duration", type=positive_number, default=None, help="stop after this many simulated seconds")
    sub.add_argument("--no-plots", action="store_true")
    sub.add_argument("--progress", action=argparse.BooleanOptionalAction, default=None,
                     help="progress bar (default: when stderr is a terminal)")
    sub.set_defaults(handler=_cmd_run)


def _cmd_run(args: argparse.Namespace) -> int:
    import yaml  # noqa: PLC0415

    from dpbase.schema import ConfigError  # noqa: PLC0415
    from dpcontrol.outputs import unwritable_folder  # noqa: PLC0415
    from sim_plant.bench.lockstep import SimulationTooLargeError  # noqa: PLC0415
    from sim_plant.bench.run import build_simulation, run_and_report  # noqa: PLC0415
    from sim_plant.plant import PlantDivergedError  # noqa: PLC0415
    from sim_plant.scenario import load_scenario  # noqa: PLC0415

    overrides: dict[str, Any] = {}
    try:
        for text in args.override:
            value = load_yaml(text)
            if not isinstance(value, dict):
                raise ValueError(f"--override {text!r}: expected a mapping of config sections")
            overrides.update(value)
        scenario = load_scenario(_scenario_path(args.scenario))
        if args.estimator:
            base = _kept_settings(scenario.controller.get("estimator"), args.estimator, ESTIMATOR_SHARED_KEYS)
            overrides["estimator"] = {**base, **overrides.get("estimator", {}), "kind": args.estimator}
        if args.control:
            kind = "mrac" if args.control == "mrac-fixed" else args.control
            base = _kept_settings(scenario.controller.get("control"), kind, ())
            control = {**base, **overrides.get("control", {}), "kind": kind}
            if args.control == "mrac-fixed":
                control["adapt"] = False
            overrides["control"] = control
        simulation = build_simulation(scenario, args.controller_config, overrides or None)
    except (ConfigError, ValueError, KeyError, OSError, yaml.YAMLError) as error:
        message = error.args[0] if isinstance(error, KeyError) and error.args else error
        print(f"sim-plant run: {message}", file=sys.stderr)
        return EXIT_USAGE
    unwritable = unwritable_folder(args.out)
    if unwritable is not None:
        print(f"sim-plant run: {unwritable}", file=sys.stderr)
        return EXIT_USAGE
    try:
        outputs = run_and_report(simulation, args.out, plots=not args.no_plots, progress=args.progress,
                                 duration_s=args.duration)
    except SimulationTooLargeError as error:  # refused before the run started
        print(f"sim-plant run: {error}", file=sys.stderr)
        return EXIT_USAGE
    except PlantDivergedError as error:  # the scenario drove the vessel's model out of its range
        print(f"sim-plant run: the run stopped: {error}", file=sys.stderr)
        return EXIT_FAILURE
    except OSError as error:  # the results could not be written (a full disk, the folder gone)
        print(f"sim-plant run: writing the results into {args.out} failed: {error}", file=sys.stderr)
        return EXIT_FAILURE
    summary = outputs.summary
    metrics = summary.get("metrics", {})
    interrupted = summary.get("interrupted_at_s")
    if interrupted is not None:
        print(f"sim-plant run: interrupted at t = {interrupted:g} s of {args.duration or scenario.duration_s:g} s; "
              "the outputs cover the part that ran")
    print(f"sim-plant run: {scenario.name}: {summary['steps']} steps of {summary['sample_time_s']} s in "
          f"{summary['wall_time_s']} s ({summary['speed_x_realtime']}x real time)")
    for key in ("position_error_rms_m", "position_error_max_m", "heading_error_rms_deg", "omega_hat_final_rad_s",
                "motion_peak_final_rad_s", "dominant_model_final_rad_s", "mrac_mass_surge_error_pct"):
        if metrics.get(key) is not None:
            print(f"  {key}: {metrics[key]}")
    print(f"  alarms: {describe_alarms(summary.get('alarm_events') or [])}")
    print(f"sim-plant run: wrote {outputs.timeseries}, {outputs.summary_path} and {len(outputs.plots)} plots "
          f"in {outputs.out_dir}")
    return EXIT_OK if interrupted is None else EXIT_INTERRUPTED


def describe_alarms(events: list[dict[str, Any]], most: int = 6) -> str:
    """Every alarm raised in a run, on one line, from the summary's ``alarm_events`` (the ``alarms`` list
    keeps only those active or cleared in the last minute of the run).

    Each code once, in the order first raised: ``code (severity, from t s[ to t s| still active][, raised
    N times])``; ``none`` when nothing was raised.
    """
    order: list[str] = []
    seen: dict[str, dict[str, Any]] = {}
    for event in events:
        code = str(event.get("code"))
        entry = seen.get(code)
        if entry is None:
            if not event.get("raised"):
                continue
            entry = seen[code] = {"severity": event.get("severity"), "first": event.get("t_s"), "raised": 0}
            order.append(code)
        entry["active"] = bool(event.get("raised"))
        entry["last"] = event.get("t_s")
        if event.get("raised"):
            entry["raised"] += 1
            entry["severity"] = event.get("severity")
    if not order:
        return "none"
    parts = []
    for code in order[:most]:
        entry = seen[code]
        span = "still active" if entry["active"] else f"to {float(entry['last'] or 0.0):.1f} s"
        times = f", raised {entry['raised']} times" if entry["raised"] > 1 else ""
        parts.append(f"{code} ({entry['severity']}, from {float(entry['first'] or 0.0):.1f} s {span}{times})")
    more = len(order) - most
    return ", ".join(parts) + (f", and {more} more in summary.json" if more > 0 else "")


# -- hil ---------------------------------------------------------------------------------------------
def _add_hil(commands: Any) -> None:
    sub = commands.add_parser(
        "hil", help="real-time emulator on real transports, for a separately started dpcontrol daemon",
        description="Run the plant of SCENARIO in real time, speaking NMEA 0183 (pseudo-terminals at the "
                    "daemon's serial ports), NMEA 2000 (python-can, remote server started), MAVLink (UDP) and "
                    "Zenoh as configured in the daemon's configuration file.")
    sub.add_argument("scenario", help="scenario YAML file, or the name of a built-in scenario (demo, cs2-seed000 ...)")
    sub.add_argument("--controller-config", required=True, type=Path, metavar="FILE",
                     help="the daemon's configuration file (dpcontrol run --config FILE)")
    sub.add_argument("--out", type=Path, metavar="DIR", help="write truth.csv, commands.csv, feedback.csv, "
                     "links.json and hil_summary.json here")
    sub.add_argument("--speed", type=positive_number, default=1.0, help="plant seconds per wall second (default 1)")
    sub.add_argument("--engage", action="store_true",
                     help="act as the operator: request DP (auto_position) once the controller is alive and "
                          "publishing status, and send the scenario's setpoints (without it, none are sent)")
    sub.add_argument("--duration", type=positive_number, metavar="S",
                     help="plant time to run [s] (default: the scenario's)")
    sub.add_argument("--zenoh-listen", action="append", metavar="ENDPOINT",
                     help="also listen here (repeatable), besides what the controller configuration implies")
    sub.add_argument("--zenoh-connect", action="append", metavar="ENDPOINT",
                     help="also connect here (repeatable), besides the controller's zenoh.listen endpoints")
    add_tls_arguments(sub)  # the emulator's own certificate on a secured vessel network
    sub.add_argument("--no-can-server", action="store_true",
                     help="do not start the python-can-remote server of 'remote' buses (someone else runs it)")
    sub.set_defaults(handler=_cmd_hil)


# The scenario's wave-filter keys that mean the same for every DP wave filter (the sensors' noise):
# kept when ``--estimator`` switches to another wave-filter kind.
ESTIMATOR_SHARED_KEYS = ("position_noise_std_m", "heading_noise_std_rad")
WAVE_FILTER_KINDS = ("mmae", "kf", "rpem", "raw")


def _kept_settings(section: Any, kind: str, shared_keys: tuple[str, ...]) -> dict[str, Any]:
    """What a ``--estimator``/``--control`` kind override keeps of the scenario's section: all of it for
    the same kind (only the kind was restated), the kind-independent keys for another DP wave filter,
    nothing otherwise (the scenario's other settings belong to a different algorithm)."""
    if not isinstance(section, Mapping):
        return {}
    settings = {k: v for k, v in section.items() if k != "kind"}
    old = section.get("kind")
    if old == kind:
        return settings
    if kind in WAVE_FILTER_KINDS and old in WAVE_FILTER_KINDS:
        return {k: v for k, v in settings.items() if k in shared_keys}
    return {}


def _scenario_path(text: str) -> Path:
    from sim_plant.scenario import builtin_scenario_path  # noqa: PLC0415 - keep --help fast

    path = Path(text)
    if path.exists() or text.endswith((".yaml", ".yml")):
        return path
    return builtin_scenario_path(text)  # a name, also faults/<name>; unknown: KeyError naming the known ones


def _cmd_hil(args: argparse.Namespace) -> int:
    # imported here so that `sim-plant --help` and the stubs do not load zenoh, python-can, pymavlink
    from dpbase.schema import ConfigError  # noqa: PLC0415
    from interfaces.zenoh.security import security_from_args  # noqa: PLC0415
    from sim_plant.emulator import HilEmulator, HilError, HilOptions  # noqa: PLC0415
    from sim_plant.hil_config import load_controller_wiring  # noqa: PLC0415
    from sim_plant.scenario import load_scenario  # noqa: PLC0415

    try:
        scenario = load_scenario(_scenario_path(args.scenario))
        wiring = load_controller_wiring(args.controller_config)
        security = security_from_args(args, wiring.zenoh.identities)
        if security is None and wiring.zenoh.identities:
            raise ValueError("the controller's zenoh network is secured (zenoh.identities): give the emulator's "
                             "certificate with --tls-dir DIR --identity NAME (an identity with roles drives, console)")
        options = HilOptions(speed=args.speed, duration_s=args.duration, engage=args.engage, out_dir=args.out,
                             zenoh_listen=None if args.zenoh_listen is None else tuple(args.zenoh_listen),
                             zenoh_connect=None if args.zenoh_connect is None else tuple(args.zenoh_connect),
                             can_server=not args.no_can_server, zenoh_security=security)
        emulator = HilEmulator(scenario, wiring, options)
    except (ConfigError, ValueError, KeyError, OSError) as error:
        message = error.args[0] if isinstance(error, KeyError) and error.args else error
        print(f"sim-plant hil: {message}", file=sys.stderr)
        return EXIT_USAGE

    def _on_signal(signum: int, _frame: FrameType | None) -> None:
        emulator.stop_from_signal(f"signal {signal.Signals(signum).name}")

    # SIGHUP too (the terminal that started the bench went away): an orderly stop, as for SIGTERM
    previous = {sig: signal.signal(sig, _on_signal) for sig in (signal.SIGTERM, signal.SIGINT, signal.SIGHUP)}
    try:
        try:
            emulator.open()
        except HilError as error:
            print(f"sim-plant hil: {error}", file=sys.stderr)
            return EXIT_FAILURE
        for wire in emulator.wires:
            link = emulator.links[wire.transport.name]
            where = link.describe()
            target = where.get("device") or where.get("bus") or where.get("remote")
            print(f"sim-plant hil: {wire.spec.name} ({wire.spec.kind}, {wire.spec.rate_hz:g} Hz) -> "
                  f"{wire.transport.protocol} {wire.transport.name} {target}", flush=True)
        print(f"sim-plant hil: zenoh vessel {wiring.vessel_id}, listen {list(emulator.zenoh_listen)}, "
              f"connect {list(emulator.zenoh_connect)}", flush=True)
        try:
            summary = emulator.run()
        except Exception as error:  # logged with its traceback by the emulator
            print(f"sim-plant hil: failed: {type(error).__name__}: {error}", file=sys.stderr)
            return EXIT_FAILURE
        loop = summary["loop"]
        print(f"sim-plant hil: stopped ({summary['stopped_by']}) at plant time {summary['duration_s']:.2f} s; "
              f"{loop['wakeups']} wake-ups, {loop['missed_deadlines']} missed deadlines, "
              f"{summary['counts']['commands_applied']} commands applied", flush=True)
        if not emulator.controller_seen:  # a bench that never met its controller tested nothing
            print(f"sim-plant hil: no controller for vessel {wiring.vessel_id!r} was seen during the whole run "
                  f"(liveliness dp/{wiring.vessel_id}/alive/controller; listening on {list(emulator.zenoh_listen)}, "
                  f"connecting to {list(emulator.zenoh_connect)}): is `dpcontrol run --config "
                  f"{args.controller_config}` running, and do the endpoints meet?", file=sys.stderr)
            return EXIT_FAILURE
        return EXIT_OK
    finally:
        emulator.close()
        for sig, handler in previous.items():
            signal.signal(sig, handler)


# -- demo --------------------------------------------------------------------------------------------
def _add_demo(commands: Any) -> None:
    sub = commands.add_parser("demo", help="emulator + the real daemon as two processes over pty, CAN, MAVLink "
                              "and zenoh, with a live view and a report")
    sub.add_argument("scenario", nargs="?", default="demo", help="scenario (default: the built-in demo, 120 s)")
    sub.add_argument("--out", type=Path, default=None, help="run directory (default: ./runs/demo-<time>)")
    sub.add_argument("--duration", type=positive_number, default=None, help="seconds (default: the scenario's)")
    sub.add_argument("--live", action=argparse.BooleanOptionalAction, default=None,
                     help="live terminal view (default: when stdout is a terminal)")
    sub.add_argument("--plaintext", action="store_true",
                     help="zenoh over plain TCP (default: mutual TLS and access control by role, as on a vessel)")
    sub.set_defaults(handler=_cmd_demo)


def _cmd_demo(args: argparse.Namespace) -> int:
    import json  # noqa: PLC0415

    from dpbase.schema import ConfigError  # noqa: PLC0415
    from dpcontrol.outputs import unwritable_folder  # noqa: PLC0415
    from sim_plant.bench.demo import DemoError, describe_summary, run_demo  # noqa: PLC0415
    from sim_plant.scenario import load_scenario  # noqa: PLC0415

    try:  # the scenario checked as `sim-plant run` and `hil` check it, before any process starts
        scenario_path = _scenario_path(args.scenario)
        load_scenario(scenario_path)
    except (ConfigError, KeyError) as error:
        message = error.args[0] if isinstance(error, KeyError) and error.args else error
        print(f"sim-plant demo: {message}", file=sys.stderr)
        return EXIT_USAGE
    unwritable = unwritable_folder(args.out if args.out is not None else Path("runs"))  # (run_demo's default)
    if unwritable is not None:
        print(f"sim-plant demo: {unwritable}", file=sys.stderr)
        return EXIT_USAGE
    try:
        report = run_demo(scenario_path, args.out, duration_s=args.duration, live=args.live, secure=not args.plaintext)
    except DemoError as error:
        print(f"sim-plant demo: {error}", file=sys.stderr)
        return EXIT_FAILURE
    except KeyboardInterrupt:  # (SIGINT, SIGTERM or SIGHUP before the run started: what started is stopped)
        print("sim-plant demo: interrupted before the run started; no report", file=sys.stderr)
        return EXIT_INTERRUPTED
    summary_file = report / "summary.json"
    interrupted = None
    if summary_file.exists():
        summary = json.loads(summary_file.read_text(encoding="utf-8"))
        interrupted = summary.get("interrupted_by")
        for line in describe_summary(summary):
            print(f"sim-plant demo: {line}")
    print(f"sim-plant demo: report in {report}")
    return EXIT_OK if interrupted is None else EXIT_INTERRUPTED


# -- bench -------------------------------------------------------------------------------------------
def _add_bench(commands: Any) -> None:
    sub = commands.add_parser("bench", help="simulation speed: simulated seconds per wall second")
    sub.add_argument("--json", action="store_true")
    sub.add_argument("--tanker-duration", type=positive_number, default=43200.0,
                     help="simulated seconds of the seed 003 tanker run (default: the full 12 h)")
    sub.add_argument("--cs2-duration", type=positive_number, default=300.0)
    sub.set_defaults(handler=_cmd_bench)


def _cmd_bench(args: argparse.Namespace) -> int:
    import json  # noqa: PLC0415

    from sim_plant.bench.speed import format_speed, run_speed_bench  # noqa: PLC0415

    result = run_speed_bench(tanker_duration_s=args.tanker_duration, cs2_duration_s=args.cs2_duration)
    print(json.dumps(result, indent=2) if args.json else format_speed(result))
    return EXIT_OK


# -- campaign, capability ------------------------------------------------------------------------------------
def _add_campaign_commands(commands: Any) -> None:
    from sim_plant.campaign.commands import add_campaign_commands  # noqa: PLC0415 - (argparse only: --help stays fast)

    add_campaign_commands(commands)


if __name__ == "__main__":
    sys.exit(main())
