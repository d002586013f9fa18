"""Which MRAC estimate reaches which projection bound in a campaign's runs, when, and on what error.

Runs the chosen samples of a campaign file (one controller label) in this process with
:meth:`dpcontrol.control.mrac.MracController.step` wrapped, and prints per DOF the mass estimate over its nominal
(final, min, max), the time it first reached a bound (the supervision then suspends the adaptation), how long the
mass gate was open, and the reference acceleration ÿ_M and the tracking error e at the move's start (``--at``)
and at the bound. The rest level before the move (``--rest``) is the error the weather alone causes.

Run (a supply run takes ≈ 4 s)::

    PYTHONPATH=$PWD python benchmarks/mrac_bound_trace.py sim_plant/campaigns/supply-mrac-reference.yaml 1 6 11
"""

from __future__ import annotations

import argparse
from typing import Any

import numpy as np

from dpcontrol.control import mrac
from sim_plant.bench.lockstep import LockstepSimulation, lockstep_config
from sim_plant.campaign.spec import expand, load_campaign
from sim_plant.scenario import parse_scenario

_LOG: list[tuple[float, ...]] = []
_STEP = mrac.MracController.step


def _logged_step(self: mrac.MracController, *args: Any, **kwargs: Any) -> Any:
    out = _STEP(self, *args, **kwargs)
    reference = args[4]
    ratio = self.mass_hat / np.array(self.mass_nominal)
    _LOG.append((self._clock_s, *reference.eta_ddot_d_ned[:3], *out.error_b, *ratio, float(self._excited)))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("campaign")
    parser.add_argument("samples", type=int, nargs="+")
    parser.add_argument("--label", default="mrac-guidance", help="the controller.control label to run")
    parser.add_argument("--rest", type=float, nargs=2, default=(250.0, 378.0), help="rest window before the move [s]")
    args = parser.parse_args()
    mrac.MracController.step = _logged_step  # type: ignore[method-assign]
    for run in expand(load_campaign(args.campaign)):
        if run.sample not in args.samples or run.labels.get("controller.control") != args.label:
            continue
        _LOG.clear()
        scenario = parse_scenario(run.scenario, file=args.campaign)
        LockstepSimulation(scenario, lockstep_config(scenario, file=args.campaign)).run(duration_s=run.duration_s)
        log = np.array(_LOG)  # t, ÿ_M (3), e_b (3), â₂/m (3), gate bits
        t = log[:, 0]
        rest = (t >= args.rest[0]) & (t < args.rest[1])
        print(f"sample {run.sample}: " + ", ".join(f"{k.split('.')[-1]} {v:.3g}" for k, v in run.values.items()
                                                  if not isinstance(v, dict)))
        for i, name in enumerate(("surge", "sway", "yaw")):
            ratio = log[:, 7 + i]
            gate = (log[:, 10].astype(int) >> i) & 1
            hit = np.nonzero((ratio <= 0.3 + 1e-9) | (ratio >= 5.0 - 1e-9))[0]
            error = log[:, 4 + i]
            rms = float(np.sqrt(np.mean(error[rest] ** 2)))
            line = (f"  {name}: â₂/m final {ratio[-1]:.3f} min {ratio.min():.3f} max {ratio.max():.3f}; gate open "
                    f"{gate.sum() * float(np.median(np.diff(t))):.0f} s; rest |e| rms {rms:.3g}"
                    f" max {np.abs(error[rest]).max():.3g}")
            if gate.any():
                k = int(gate.argmax())
                line += f"; gate opens t={t[k]:.0f} s, e={error[k]:.3g}"
            if hit.size:
                k = int(hit[0])
                line += f"; BOUND at t={t[k]:.0f} s, ÿ_M={log[k, 1 + i]:.2e}, e={error[k]:.3g}"
            print(line)


if __name__ == "__main__":
    main()
