"""The ``sim-plant campaign`` and ``sim-plant capability`` sub-commands (added to :mod:`sim_plant.cli`'s parser).

Exit status as the other sub-commands: 0 done, 1 the command failed at run time, 2 a usage or configuration error
(the message names the file and key), 130 interrupted (Ctrl-C; ``campaign`` still writes what finished).
A failed *run* of a campaign is one of its results, not a failure of the command.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from dpcontrol.arguments import positive_number

EXIT_OK, EXIT_FAILURE, EXIT_USAGE, EXIT_INTERRUPTED = 0, 1, 2, 130


def _workers(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number of workers ≥ 1, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a whole number of workers ≥ 1, got {text!r}")
    return value


def _add_engine_options(sub: argparse.ArgumentParser) -> None:
    sub.add_argument("--workers", type=_workers, default=None,
                     help="local worker processes (default: one per core; ignored with --scheduler)")
    sub.add_argument("--scheduler", metavar="ADDRESS", default=None,
                     help="run on the Dask cluster at this scheduler address (tcp://HOST:PORT) instead")
    sub.add_argument("--progress", action=argparse.BooleanOptionalAction, default=None,
                     help="progress bar (default: when stderr is a terminal)")


def add_campaign_commands(commands: Any) -> None:
    """Add ``campaign`` and ``capability`` to the ``sim-plant`` sub-command parsers."""
    sub = commands.add_parser("campaign", help="many lockstep runs sampled from a spec, in parallel",
                              description="Run the lockstep simulations a campaign spec samples (docs/campaigns.md) "
                              "on local worker processes or a Dask cluster: DIR/campaign.csv, campaign.json, plots. "
                              "Rerunning into the same DIR skips the finished runs.")
    sub.add_argument("spec", help="campaign YAML file, or the name of a built-in campaign (sim_plant/campaigns)")
    sub.add_argument("--out", type=Path, required=True, help="output directory (also the resume state)")
    _add_engine_options(sub)
    sub.add_argument("--retry-failed", action="store_true", help="run the runs that failed before again")
    sub.add_argument("--no-plots", action="store_true")
    sub.add_argument("--list", action="store_true", help="print the runs (id, seed, values) and exit")
    sub.set_defaults(handler=_cmd_campaign)

    cap = commands.add_parser("capability", help="DP capability plot (DNV-ST-0111 style, Level 1 or 3)",
                              description="The largest wind each direction in which the vessel keeps position "
                              "(docs/campaigns.md, 'Capability'): DIR/capability.json and DIR/capability.png.")
    cap.add_argument("vessel", metavar="VESSEL_OR_CONFIG",
                     help="built-in vessel name (supply, cybership2, ...) or a controller configuration file")
    cap.add_argument("--out", type=Path, required=True)
    cap.add_argument("--level", type=int, choices=(1, 3), default=1,
                     help="1: static balance of the mean loads; 3: closed-loop lockstep runs (bisection)")
    cap.add_argument("--directions", type=_workers, default=36, help="environment directions (default 36)")
    cap.add_argument("--failed", action="append", default=[], metavar="NAMES",
                     help="a failure case: comma-separated thruster names or a consequence group of the config; "
                     "'worst' = the worst single failure (each group and each thruster). Repeat for several cases; "
                     "the intact case is always computed")
    cap.add_argument("--current-mps", type=float, default=0.5, help="co-linear current (default 0.5 m/s)")
    cap.add_argument("--dynamic-allowance", type=positive_number, nargs="?", const=1.25, default=1.0,
                     metavar="FACTOR", help="Level 1: multiply the environmental loads by FACTOR (DNV-ST-0111 "
                     "Level 1: 1.25, the value without FACTOR; default 1 = none)")
    cap.add_argument("--max-wind-mps", type=positive_number, default=40.0, help="search limit (default 40 m/s)")
    cap.add_argument("--max-excursion-m", type=positive_number, default=5.0, help="Level 3 position limit (5 m)")
    cap.add_argument("--max-heading-deg", type=positive_number, default=3.0, help="Level 3 heading limit (3 deg)")
    cap.add_argument("--settle-s", type=positive_number, default=300.0,
                     help="Level 3: time before the limits apply (default 300 s)")
    cap.add_argument("--window-s", type=positive_number, default=600.0,
                     help="Level 3: time after settling in which the limits must hold (default 600 s)")
    cap.add_argument("--iterations", type=_workers, default=6, help="Level 3 bisection steps (default 6)")
    cap.add_argument("--seed", type=int, default=1, help="Level 3 scenario seed (the same sea for every run)")
    _add_engine_options(cap)
    cap.set_defaults(handler=_cmd_capability)


def _progress(flag: bool | None) -> bool:
    return sys.stderr.isatty() if flag is None else flag


def _cmd_campaign(args: argparse.Namespace) -> int:
    from dpbase.schema import ConfigError  # noqa: PLC0415
    from dpcontrol.outputs import unwritable_folder  # noqa: PLC0415
    from sim_plant.campaign.run import run_campaign  # noqa: PLC0415
    from sim_plant.campaign.spec import CampaignError, campaign_path, expand, load_campaign  # noqa: PLC0415

    try:
        spec = load_campaign(campaign_path(args.spec))
        if args.list:
            for run in expand(spec):
                values = ", ".join(f"{k} = {v}" for k, v in run.labels.items())
                print(f"{run.run}\tsample {run.sample}\tseed {run.seed}\t{values}")
            return EXIT_OK
    except (ConfigError, CampaignError, KeyError) as error:
        message = error.args[0] if isinstance(error, KeyError) and error.args else error
        print(f"sim-plant campaign: {message}", file=sys.stderr)
        return EXIT_USAGE
    unwritable = unwritable_folder(args.out)
    if unwritable is not None:
        print(f"sim-plant campaign: {unwritable}", file=sys.stderr)
        return EXIT_USAGE
    try:
        outcome = run_campaign(spec, args.out, workers=args.workers, scheduler=args.scheduler,
                               progress=_progress(args.progress), retry_failed=args.retry_failed,
                               plots=not args.no_plots)
    except (ConfigError, CampaignError) as error:
        print(f"sim-plant campaign: {error}", file=sys.stderr)
        return EXIT_USAGE
    except OSError as error:  # the scheduler could not be reached, or DIR could not be written
        print(f"sim-plant campaign: {error}", file=sys.stderr)
        return EXIT_FAILURE
    summary = outcome.summary
    print(f"sim-plant campaign: {spec.name}: {summary['finished']} of {summary['runs']} runs finished "
          f"({outcome.skipped} from before), {summary['ok']} ok, {summary['failed']} failed"
          + (", interrupted" if outcome.interrupted else ""))
    for metric in ("position_error_rms_m", "position_error_max_m", "heading_error_rms_deg", "heading_error_max_deg"):
        stats = summary["metrics"].get(metric)
        if stats:
            print(f"  {metric}: median {stats['median']:.3g}, p95 {stats['p95']:.3g}, max {stats['max']:.3g}")
    for path, pairs in summary.get("paired_differences", {}).items():
        for name, per_metric in pairs.items():
            stats = per_metric.get("position_error_rms_m")
            if stats:
                print(f"  {path}: {name}: position_error_rms_m median difference {stats['median_difference']:+.3g} m, "
                      f"lower in {100 * stats['share_lower']:.0f} % of {stats['pairs']} pairs")
    print(f"sim-plant campaign: wrote {args.out / 'campaign.csv'}, {args.out / 'campaign.json'} and "
          f"{len(outcome.plots)} plots")
    return EXIT_INTERRUPTED if outcome.interrupted else EXIT_OK


def _cmd_capability(args: argparse.Namespace) -> int:
    from dpbase.schema import ConfigError  # noqa: PLC0415
    from dpcontrol.outputs import unwritable_folder  # noqa: PLC0415
    from sim_plant.campaign.capability import CapabilityOptions, load_subject, run_capability  # noqa: PLC0415

    try:
        subject = load_subject(args.vessel)
        options = CapabilityOptions(level=args.level, directions=args.directions, failed=tuple(args.failed),
                                    current_mps=args.current_mps, dynamic_allowance=args.dynamic_allowance,
                                    max_wind_mps=args.max_wind_mps, max_excursion_m=args.max_excursion_m,
                                    max_heading_deg=args.max_heading_deg, settle_s=args.settle_s,
                                    window_s=args.window_s, iterations=args.iterations, seed=args.seed)
        cases = subject.failure_cases(options.failed)
    except (ConfigError, KeyError, ValueError) as error:
        message = error.args[0] if isinstance(error, KeyError) and error.args else error
        print(f"sim-plant capability: {message}", file=sys.stderr)
        return EXIT_USAGE
    unwritable = unwritable_folder(args.out)
    if unwritable is not None:
        print(f"sim-plant capability: {unwritable}", file=sys.stderr)
        return EXIT_USAGE
    try:
        document = run_capability(subject, cases, options, args.out, workers=args.workers, scheduler=args.scheduler,
                                  progress=_progress(args.progress))
    except KeyboardInterrupt:
        print("sim-plant capability: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except OSError as error:
        print(f"sim-plant capability: {error}", file=sys.stderr)
        return EXIT_FAILURE
    for case in document["cases"]:
        wind = case["max_wind_mps"]
        print(f"sim-plant capability: {document['vessel']} level {document['level']} {case['case']}: "
              f"min {min(wind):.1f} m/s, max {max(wind):.1f} m/s over {len(wind)} directions")
    print(f"sim-plant capability: wrote {args.out / 'capability.json'} and {args.out / 'capability.png'}")
    return EXIT_OK
