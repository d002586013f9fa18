"""``dpcontrol`` command line (composition layer): run, check-config, monitor, console, setpoint, bench, decode,
replay, log, pki.

Exit codes: 0 success; 1 runtime failure; 2 invalid usage or configuration, or an input file named on the
command line that cannot be read (missing, a folder, no permission) — the message names the file, the key path
and what was expected; 130 interrupted (Ctrl-C; ``run`` stops in order on it instead). ``sim-plant`` uses
the same codes.
"""

from __future__ import annotations

import os

# Small matrices only: a multi-threaded BLAS costs ~100x per LAPACK call on a loaded 2-core computer
# (measured: a 10x10 expm took 4.1 ms instead of 37 µs). Set before numpy is first imported.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse
import json
import logging
import sys
from collections.abc import Sequence
from pathlib import Path

from dpbase.schema import ConfigError
from dpcontrol.arguments import positive_number

EXIT_INTERRUPTED = 130  # as a shell reports a command ended by Ctrl-C (128 + SIGINT)
# an input named on the command line that cannot be opened at all: a usage error (2), as check-config says
UNREADABLE_INPUT = (FileNotFoundError, IsADirectoryError, NotADirectoryError, PermissionError)


def _configure_logging(verbose: bool) -> None:
    from dpcontrol.logsetup import configure_logging  # noqa: PLC0415

    configure_logging(logging.DEBUG if verbose else logging.INFO)


def _cmd_run(args: argparse.Namespace) -> int:
    from dpcontrol.runtime.config import load_config  # noqa: PLC0415
    from dpcontrol.service.daemon import Daemon  # noqa: PLC0415
    from interfaces.zenoh.security import PkiError, check_security  # noqa: PLC0415

    _configure_logging(args.verbose)
    if args.stats_out:  # checked before the run: the stats are written when it ends, maybe hours later
        from dpcontrol.outputs import unwritable_folder  # noqa: PLC0415

        unwritable = unwritable_folder(Path(args.stats_out).resolve().parent)
        if unwritable is not None:
            print(f"dpcontrol: --stats-out {args.stats_out}: {unwritable}", file=sys.stderr)
            return 2
    try:
        config = load_config(args.config)
        check_security(config.zenoh.security, "controller")  # zenoh's own message would be a Rust error
        daemon = Daemon(config)  # (builds the controller: settings that pass one by one but build nothing)
    except (ConfigError, PkiError) as error:
        print(f"dpcontrol: invalid configuration: {error}", file=sys.stderr)
        return 2
    code = daemon.run(duration_s=args.duration)
    if args.stats_out:
        stats = daemon.stats.summary()
        stats["resumed_from_state"] = daemon.resumed_from_state
        stats["state"] = daemon.state_detail
        stats["scheduling"] = daemon.realtime_detail
        stats["replica"] = None if daemon.replica is None else daemon.replica.counters.as_dict()
        stats["garbage_collection"] = None if daemon.garbage is None else daemon.garbage.as_dict()
        spinner = daemon.spinner
        stats["deadline_spin"] = None if spinner is None else {
            "window_ms": config.realtime.spin_s * 1e3, "slice_iterations": spinner.iterations,
            "spun_s": round(spinner.spun_s, 3)}
        try:
            Path(args.stats_out).write_text(json.dumps(stats, indent=2) + "\n", encoding="utf-8")
        except OSError as error:  # (the folder went away, or the disk is full): say so; the run itself is over
            print(f"dpcontrol: --stats-out {args.stats_out}: not written: {error}", file=sys.stderr)
            return code or 1
    return code


def _cmd_check_config(args: argparse.Namespace) -> int:
    from dpcontrol.runtime.config import load_config  # noqa: PLC0415
    from dpcontrol.runtime.step import DpController  # noqa: PLC0415
    from interfaces.zenoh.security import PkiError, check_security  # noqa: PLC0415

    try:
        config = load_config(args.file)
        DpController(config)  # what the daemon builds first: settings that pass alone but build nothing
        security = check_security(config.zenoh.security, "controller")
    except (ConfigError, PkiError) as error:
        print(f"dpcontrol: invalid configuration: {error}", file=sys.stderr)
        return 2
    sensors = ", ".join(f"{s.name} ({s.kind.value})" for s in config.sensors)
    print(f"{args.file}: OK — vessel {config.vessel.name} as '{config.vessel_id}', {config.rate_hz:g} Hz, "
          f"estimator {config.estimator.kind}, control {config.control.kind}, "
          f"{len(config.vessel.thrusters)} thrusters, sensors: {sensors}; {security}")
    print(f"{args.file}: {config.control.origin(config.vessel.name)}")
    for notice in config.notices:  # accepted, but the file should change
        print(f"{args.file}: warning: {notice}", file=sys.stderr)
    return 0


def _cmd_monitor(args: argparse.Namespace) -> int:
    from dpcontrol.monitor import run_from_args  # noqa: PLC0415

    return run_from_args(args)


def _cmd_console(args: argparse.Namespace) -> int:
    from dpcontrol.console import run_from_args  # noqa: PLC0415

    return run_from_args(args)


def _cmd_setpoint(args: argparse.Namespace) -> int:
    from dpcontrol.setpoint import run_from_args  # noqa: PLC0415

    return run_from_args(args)


def _cmd_decode(args: argparse.Namespace) -> int:
    from interfaces.logs import LOG_DECODERS, decode_log, to_json_line  # noqa: PLC0415

    if args.protocol not in LOG_DECODERS:
        print(f"dpcontrol decode: unknown protocol {args.protocol!r} (one of {', '.join(LOG_DECODERS)})",
              file=sys.stderr)
        return 2
    options: dict[str, object] = {}
    for option, key, protocol in (("--max-sentence-chars", "max_sentence_chars", "nmea0183"),
                                  ("--format", "log_format", "nmea2000")):
        if getattr(args, key) is not None:
            if args.protocol != protocol:
                print(f"dpcontrol decode: {option} is an option of {protocol}, not {args.protocol}", file=sys.stderr)
                return 2
            options[key] = getattr(args, key)
    try:
        stats: dict[str, int] = {}
        out = sys.stdout
        for record in decode_log(args.protocol, args.file, stats, **options):
            out.write(to_json_line(record) + "\n")
    except BrokenPipeError:  # e.g. piped into head: not an error
        sys.stderr.close()
        return 0
    except OSError as error:
        print(f"dpcontrol decode: {error}", file=sys.stderr)
        return 2 if isinstance(error, UNREADABLE_INPUT) else 1
    except ValueError as error:  # an option the log contradicts (an unknown --format ...)
        print(f"dpcontrol decode: {error}", file=sys.stderr)
        return 2
    if args.stats:
        print(json.dumps(stats, sort_keys=True), file=sys.stderr)
    return 0


def _positive_int(text: str) -> int:
    """argparse type: a whole number >= 1 (a clear usage error instead of a traceback from the benchmark)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 1, got {text!r}")
    return value


def _cmd_bench(args: argparse.Namespace) -> int:
    from dpcontrol.bench import run_bench  # noqa: PLC0415

    result = run_bench(iterations=args.iterations)
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        from dpcontrol.bench import format_bench  # noqa: PLC0415

        print(format_bench(result))
    return 0


def _cmd_replay(args: argparse.Namespace) -> int:
    from dpcontrol.outputs import unwritable_folder  # noqa: PLC0415
    from dpcontrol.replay import replay  # noqa: PLC0415

    _configure_logging(False)
    out_dir = Path(args.out) if args.out else None
    unwritable = None if out_dir is None else unwritable_folder(out_dir)  # before replaying a day's recording
    if unwritable is not None:
        print(f"dpcontrol replay: {unwritable}", file=sys.stderr)
        return 2
    try:
        report = replay(Path(args.log), Path(args.config), out_dir, plots=not args.no_plots)
    except ConfigError as error:
        print(f"dpcontrol replay: invalid configuration: {error}", file=sys.stderr)
        return 2
    except (OSError, ValueError) as error:  # ValueError: the log is no recording, or one without inputs
        print(f"dpcontrol replay: {error}", file=sys.stderr)
        return 2 if isinstance(error, (*UNREADABLE_INPUT, ValueError)) else 1
    print(json.dumps(report, indent=2))
    return 0 if report.get("identical", True) or not report.get("same_config") else 1


def _cmd_log_export(args: argparse.Namespace) -> int:
    from dpcontrol.logtools import export_csv  # noqa: PLC0415
    from dpcontrol.outputs import unwritable_folder  # noqa: PLC0415

    unwritable = unwritable_folder(Path(args.csv))
    if unwritable is not None:
        print(f"dpcontrol log export: {unwritable}", file=sys.stderr)
        return 2
    try:
        paths = export_csv(args.log, args.csv)
    except (OSError, ValueError) as error:
        print(f"dpcontrol log export: {error}", file=sys.stderr)
        return 2 if isinstance(error, UNREADABLE_INPUT) else 1
    if not paths:
        print(f"dpcontrol log export: {args.log}: no records read — not a dpcontrol recording (MCAP), or empty; "
              "nothing written", file=sys.stderr)
        return 2  # the input is not what the command reads: as check-config on a file that is no configuration
    for path in paths:
        print(path)
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="dpcontrol", description="Dynamic positioning controller service.")
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("run", help="run the controller daemon (systemd Type=notify)")
    p.add_argument("--config", required=True, help="vessel configuration (YAML)")
    p.add_argument("--duration", type=positive_number, default=None,
                   help="stop after this many seconds (tests, benches)")
    p.add_argument("--stats-out", default=None, help="write the loop timing statistics (JSON) here at exit")
    p.add_argument("-v", "--verbose", action="store_true")
    p.set_defaults(func=_cmd_run)

    p = sub.add_parser("check-config", help="validate a configuration file")
    p.add_argument("file")
    p.set_defaults(func=_cmd_check_config)

    from dpcontrol.monitor import add_arguments  # noqa: PLC0415

    p = sub.add_parser("monitor", help="live view of a running controller over zenoh")
    add_arguments(p)
    p.set_defaults(func=_cmd_monitor)

    from dpcontrol.console import add_arguments as add_console_arguments  # noqa: PLC0415

    p = sub.add_parser("console", help="the operator's console in a web browser (served from this process)")
    add_console_arguments(p)
    p.set_defaults(func=_cmd_console)

    from dpcontrol.setpoint import add_arguments as add_setpoint_arguments  # noqa: PLC0415

    p = sub.add_parser("setpoint", help="ask a running controller for a mode or set-point and print its answer",
                       description="Send one operator request to the vessel's controller over zenoh and wait for "
                                   "its answer: exit 0 applied; 1 refused, no controller or no answer; 2 invalid "
                                   "request (nothing sent).")
    add_setpoint_arguments(p)
    p.set_defaults(func=_cmd_setpoint)

    p = sub.add_parser("bench", help="control-cycle latency benchmark")
    p.add_argument("--json", action="store_true")
    p.add_argument("--iterations", type=_positive_int, default=3000, help="timed cycles (default 3000)")
    p.set_defaults(func=_cmd_bench)

    p = sub.add_parser("decode", help="decode a captured log to JSON lines")
    p.add_argument("protocol", help="nmea0183 (text) | nmea2000 (candump, Actisense, PLAIN/FAST, YDWG raw, iKonvert, "
                                    "PCAN-View .trc, pcap/pcapng: detected) | mavlink (tlog)")
    p.add_argument("file")
    p.add_argument("--stats", action="store_true", help="print counters to stderr at the end")
    p.add_argument("--max-sentence-chars", type=_positive_int, default=None,
                   help="nmea0183: longest sentence accepted (default 128, above NMEA's 82 for high-precision GNSS)")
    p.add_argument("--format", dest="log_format", default=None,
                   help="nmea2000: the log's format instead of detecting it: candump, actisense, plain (= fast), "
                        "ydwg, ikonvert, trc, pcap")
    p.set_defaults(func=_cmd_decode)

    p = sub.add_parser("replay", help="replay a recording through the control step and compare")
    p.add_argument("log", help="recording (MCAP file or directory)")
    p.add_argument("--config", required=True, help="configuration to replay with")
    p.add_argument("--out", default=None, help="directory for the comparison (CSV, plots)")
    p.add_argument("--no-plots", action="store_true")
    p.set_defaults(func=_cmd_replay)

    p = sub.add_parser("log", help="recording tools")
    log_sub = p.add_subparsers(dest="log_command", required=True)
    q = log_sub.add_parser("export", help="export a recording to CSV files")
    q.add_argument("log")
    q.add_argument("--csv", required=True, help="output directory")
    q.set_defaults(func=_cmd_log_export)

    from dpcontrol import pki_command  # noqa: PLC0415

    pki_command.add_parser(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``dpcontrol`` console script."""
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args))
    except KeyboardInterrupt:  # Ctrl-C in bench, replay, log export …: one line, not a traceback
        print(f"dpcontrol {args.command}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED


if __name__ == "__main__":
    sys.exit(main())
