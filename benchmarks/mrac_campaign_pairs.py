"""The MRAC campaigns' acceptance figures: per weather, the MRAC's error RMS over the PID's.

A paired campaign whose last varied key is the controller with two choices, a PID and an MRAC
(``sim_plant/campaigns/cs2-mrac.yaml``, ``bluelady-mrac.yaml``, ``tanker-moves.yaml``: runs ``2k`` and ``2k + 1``
share weather ``k``), written by ``sim-plant campaign SPEC --out DIR``. Prints, over the weathers where both runs
finished: the medians of ``position_error_rms_m`` and ``heading_error_rms_deg`` of the MRAC over the PID's, the share of
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


def load_runs(directory: Path) -> dict[int, dict[str, Any]]:
    """The finished runs of a campaign directory by run number (``DIR/runs/*.json``)."""
    runs = {}
    for path in (directory / "runs").glob("*.json"):
        record = json.loads(path.read_text(encoding="utf-8"))
        if record["result"]["status"] == "ok":
            runs[int(record["run"])] = record["result"]["summary"]
    return runs


def suspended_dof(summary: dict[str, Any]) -> str | None:
    """The DOF named by the run's ``control.adaptation`` alarm ("surge", "sway", "yaw"), None when not raised."""
    for alarm in summary["alarms"]:
        if alarm["code"] == "control.adaptation":
            text = alarm["text"]
            return next((dof for dof in ("surge", "sway", "yaw") if dof in text), "?")
    return None


def main() -> None:
    """Command line: see the module docstring."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("directory", type=Path, help="the campaign's --out directory")
    parser.add_argument("-v", "--verbose", action="store_true", help="one row per weather")
    args = parser.parse_args()
    runs = load_runs(args.directory)
    rows = []
    for k in range(0, max(runs, default=-1) + 1, 2):
        pair = {run["control"]: run for run in (runs.get(k), runs.get(k + 1)) if run is not None}
        pid, mrac = pair.get("pid"), pair.get("mrac")
        if pid is None or mrac is None:
            continue
        p, m = pid["metrics"], mrac["metrics"]
        rows.append((k // 2, m["position_error_rms_m"] / p["position_error_rms_m"],
                     m["heading_error_rms_deg"] / p["heading_error_rms_deg"], suspended_dof(mrac),
                     p["position_error_rms_m"], m["position_error_rms_m"], p["heading_error_rms_deg"],
                     m["heading_error_rms_deg"]))
    if not rows:
        raise SystemExit(f"no finished pair in {args.directory}")
    n = len(rows)
    position = [row[1] for row in rows]
    heading = [row[2] for row in rows]
    both = sum(row[1] <= TOLERANCE and row[2] <= TOLERANCE for row in rows)
    dofs = collections.Counter(row[3] for row in rows if row[3] is not None)
    print(f"{n} weathers: position ratio median {statistics.median(position):.3f}, <= {TOLERANCE}x in "
          f"{100 * sum(r <= TOLERANCE for r in position) / n:.0f} %; heading ratio median "
          f"{statistics.median(heading):.3f}, <= {TOLERANCE}x in "
          f"{100 * sum(r <= TOLERANCE for r in heading) / n:.0f} %; both in {both} of {n}; "
          f"adaptation suspended in {sum(dofs.values())} of {n} {dict(dofs)}")
    if args.verbose:
        print("weather  pos ratio  hdg ratio  suspended  pid pos [m]  mrac pos [m]  pid hdg [deg]  mrac hdg [deg]")
        for row in rows:
            print(f"{row[0]:7d}  {row[1]:9.2f}  {row[2]:9.2f}  {row[3] or '-':>9}  {row[4]:11.4f}  {row[5]:12.4f}  "
                  f"{row[6]:13.3f}  {row[7]:14.3f}")


if __name__ == "__main__":
    main()
