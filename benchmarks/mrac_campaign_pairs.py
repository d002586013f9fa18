"""The MRAC campaigns' acceptance figures: per weather, the MRAC's error RMS over the PID's.

A paired campaign whose last varied key is ``controller.control`` with two choices, the PID first and the MRAC
second (``sim_plant/campaigns/cs2-mrac.yaml``, ``bluelady-mrac.yaml``; ``tanker-moves.yaml`` lists the MRAC first:
``--against pid``; runs ``2k`` and ``2k + 1`` share weather ``k``), written by ``sim-plant campaign SPEC --out DIR``.
With more than two paired choices (variants of the controller, labelled) the runs ``N k + j`` share weather ``k``
and each label is compared with the first (``--against`` another). Prints, per compared label, over the weathers
where both runs finished:
the medians of ``position_error_rms_m`` and ``heading_error_rms_deg`` of the MRAC over the PID's, the share of
weathers with each ratio ≤ 1.1, and in how many the MRAC's adaptation was suspended (the ``control.adaptation``
alarm) and in which DOF; with ``-v`` one row per weather.

Run::

    sim-plant campaign cs2-mrac --out runs/cs2-mrac --workers 1 --no-plots
    python benchmarks/mrac_campaign_pairs.py runs/cs2-mrac -v
"""

from __future__ import annotations

import argparse
import collections
import json
import statistics
from pathlib import Path
from typing import Any

TOLERANCE = 1.1  # the acceptance: the MRAC's RMS errors at most 1.1x the PID's in 90 % of the weathers


def controller_label(record: dict[str, Any]) -> str:
    """The run's label of the varied controller (``controller.control`` or a key under it, e.g. ``.kind``)."""
    return next((value for key, value in record["labels"].items() if key.startswith("controller.control")), "?")


def load_runs(directory: Path) -> tuple[dict[tuple[int, str], dict[str, Any]], list[str]]:
    """The finished runs of a campaign directory (``DIR/runs/*.json``) by (weather, ``controller.control`` label),
    and the labels in the order of the paired choice."""
    records = [json.loads(path.read_text(encoding="utf-8")) for path in (directory / "runs").glob("*.json")]
    by_slot: dict[int, str] = {}
    for record in records:
        by_slot.setdefault(int(record["run"]), controller_label(record))
    labels: list[str] = []
    for run in sorted(by_slot):
        if by_slot[run] in labels:
            break
        labels.append(by_slot[run])
    n = max(len(labels), 1)
    runs = {}
    for record in records:
        if record["result"]["status"] == "ok":
            runs[(int(record["run"]) // n, controller_label(record))] = record["result"]["summary"]
    return runs, labels


def suspended_dof(summary: dict[str, Any]) -> str | None:
    """The DOF named by the run's ``control.adaptation`` alarm ("surge", "sway", "yaw"), None when not raised."""
    for alarm in summary["alarms"]:
        if alarm["code"] == "control.adaptation":
            text = alarm["text"]
            return next((dof for dof in ("surge", "sway", "yaw") if dof in text), "?")
    return None


def compare(runs: dict[tuple[int, str], dict[str, Any]], baseline: str, label: str, verbose: bool) -> None:
    """Print the figures of ``label`` over ``baseline`` (see the module docstring)."""
    rows = []
    for k in sorted({weather for weather, _ in runs}):
        pid, mrac = runs.get((k, baseline)), runs.get((k, label))
        if pid is None or mrac is None:
            continue
        p, m = pid["metrics"], mrac["metrics"]
        rows.append((k, m["position_error_rms_m"] / p["position_error_rms_m"],
                     m["heading_error_rms_deg"] / p["heading_error_rms_deg"], suspended_dof(mrac),
                     p["position_error_rms_m"], m["position_error_rms_m"], p["heading_error_rms_deg"],
                     m["heading_error_rms_deg"]))
    if not rows:
        print(f"{label}: no finished pair with {baseline}")
        return
    n = len(rows)
    position = [row[1] for row in rows]
    heading = [row[2] for row in rows]
    both = sum(row[1] <= TOLERANCE and row[2] <= TOLERANCE for row in rows)
    dofs = collections.Counter(row[3] for row in rows if row[3] is not None)
    print(f"{label} / {baseline}: {n} weathers: position ratio median {statistics.median(position):.3f}, "
          f"<= {TOLERANCE}x in {100 * sum(r <= TOLERANCE for r in position) / n:.0f} %; heading ratio median "
          f"{statistics.median(heading):.3f}, <= {TOLERANCE}x in "
          f"{100 * sum(r <= TOLERANCE for r in heading) / n:.0f} %; both in {both} of {n}; "
          f"adaptation suspended in {sum(dofs.values())} of {n} {dict(dofs)}")
    if verbose:
        print("weather  pos ratio  hdg ratio  suspended  pid pos [m]  mrac pos [m]  pid hdg [deg]  mrac hdg [deg]")
        for row in rows:
            print(f"{row[0]:7d}  {row[1]:9.2f}  {row[2]:9.2f}  {row[3] or '-':>9}  {row[4]:11.4f}  {row[5]:12.4f}  "
                  f"{row[6]:13.3f}  {row[7]:14.3f}")


def main() -> None:
    """Command line: see the module docstring."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("directory", type=Path, help="the campaign's --out directory")
    parser.add_argument("-v", "--verbose", action="store_true", help="one row per weather")
    parser.add_argument("--against", help="the label to compare with (default: the first choice, the PID)")
    args = parser.parse_args()
    runs, labels = load_runs(args.directory)
    if not runs:
        raise SystemExit(f"no finished run in {args.directory}")
    baseline = args.against or labels[0]
    for label in labels:
        if label != baseline:
            compare(runs, baseline, label, args.verbose)


if __name__ == "__main__":
    main()
