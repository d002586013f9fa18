"""MRAC mass-estimate bias under combined moves, perfect state, no environment.

The MRAC (:class:`dpcontrol.control.mrac.MracController`, seed 003 eqs. (15)–(25)) is driven by the vessel's
default guidance (:class:`dpcontrol.guidance.reference_model.ReferenceModel`), as in the runtime, and closes the
loop directly on the plant's nonlinear truth model (:class:`sim_plant.vessel.DpVesselModel`: M_RB + M_A with
their Coriolis terms, linear and quadratic damping) with

* the plant's true state as the controller's estimate (η̂ = η, ν̂ = ν; no wave filter),
* no wind, current or waves, no sensor noise (b̂ = 0),
* the command applied as the plant's force exactly (no allocation, no thruster dynamics: nothing saturates), or
  through a first-order lag of ``command_lag_s`` (``--command-lag``: a stand-in for thruster dynamics and estimator
  lag, the delay the law sees between the reference's acceleration and the vessel's). With ``--lead`` the MRAC's
  ``actuator_time_constant_s`` is that lag (the lead of its feed-forward by the lag's inverse), not the vessel's
  thrusters'.

After a rest of ``rest_periods`` reference-model periods (the MRAC's entry rest is one) the set-point alternates
``moves`` times between the start pose and the start pose moved by ``0.08 L`` and ``10°`` (the MRAC's design move,
:func:`dpcontrol.control.mrac.default_mrac_config`), each held ``hold_periods`` periods. ``--kind`` chooses which
DOFs move together: ``sway-yaw`` (default: east and heading, surge never commanded at ψ ≈ 0), ``surge-yaw``,
``surge-sway`` or a single DOF (``surge``, ``sway``, ``yaw``). With ``--seed`` the signs of the moves are random
(a move goes from the current set-point by ±step in each moved DOF, reproducible for the seed); without it they
alternate out and back.

The result is each DOF's final mass estimate over the vessel's nominal (= true) M_ii. Nothing in this set-up is
wrong with the controller's model but its structure: the diagonal regressor and the feed-forward it implies.

Run (one vessel takes 1–20 s)::

    PYTHONPATH=$PWD python benchmarks/mrac_estimate_bias.py                       # all vessels, sway-yaw
    PYTHONPATH=$PWD python benchmarks/mrac_estimate_bias.py --kind sway --vessel supply
    PYTHONPATH=$PWD python benchmarks/mrac_estimate_bias.py --override '{"coupling": false}'
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from dpcontrol.control.mrac import MracController, default_mrac_config
from dpcontrol.guidance.reference_model import ReferenceModel, default_reference_config
from dpcontrol.models.vessels import BLUE_LADY, CYBERSHIP2, SHUTTLE_TANKER, SUPPLY, VesselData
from sim_plant.vessel import DpVesselModel

VESSELS: dict[str, VesselData] = {v.name: v for v in (SUPPLY, CYBERSHIP2, SHUTTLE_TANKER, BLUE_LADY)}
KINDS: dict[str, tuple[bool, bool, bool]] = {
    "sway-yaw": (False, True, True), "surge-yaw": (True, False, True), "surge-sway": (True, True, False),
    "surge": (True, False, False), "sway": (False, True, False), "yaw": (False, False, True),
    "all": (True, True, True),
}
STEP_PER_LENGTH = 0.08
STEP_YAW_RAD = math.radians(10.0)


@dataclass(frozen=True)
class BiasRun:
    """One run's set-up (see the module docstring).

    Attributes
    ----------
    kind : str
        Key of :data:`KINDS`: which DOFs each move changes.
    moves : int
        Number of set-point moves.
    hold_periods, rest_periods : float
        How long each set-point is held, and the rest before the first move [reference-model periods].
    steps_per_period : int
        Control (and plant RK4) steps per reference-model period.
    seed : int or None
        Random move signs; None: the ``pattern``.
    pattern : {"back", "onward"}
        Out and back, or every move adds the step again (the heading turns on).
    reference : {"model", "guidance"}
        The MRAC's ``reference`` (:class:`dpcontrol.control.mrac.MracConfig`).
    linear_plant : bool
        Diagnostic: the plant without its quadratic damping (the controller's design model has none).
    command_lag_s : float
        Time constant of a first-order lag between the command and the plant's force [s] (0: none).
    lead : bool
        The MRAC's ``actuator_time_constant_s`` is ``command_lag_s`` (the lead of its feed-forward); False: its
        default (no lead).
    override : dict, optional
        :class:`~dpcontrol.control.mrac.MracConfig` fields replaced after the defaults.
    """

    kind: str = "sway-yaw"
    moves: int = 24
    hold_periods: float = 4.0
    rest_periods: float = 2.0
    steps_per_period: int = 400
    seed: int | None = None
    pattern: str = "back"
    reference: str = "model"
    linear_plant: bool = False
    command_lag_s: float = 0.0
    lead: bool = False
    override: dict[str, Any] | None = None


def run(vessel: VesselData, options: BiasRun = BiasRun()) -> dict[str, Any]:
    """One run; returns the final â₂/M_ii per DOF, the worst |â₂/M_ii − 1| over the run and the peak tracking
    error after the first move (``e_b`` against y_M [m, m, rad])."""
    kind, moves, hold_periods, rest_periods = options.kind, options.moves, options.hold_periods, options.rest_periods
    steps_per_period, seed, pattern = options.steps_per_period, options.seed, options.pattern
    reference, linear_plant, override = options.reference, options.linear_plant, options.override
    config = default_mrac_config(vessel, reference=reference)
    if options.lead:  # the controller's actuators are this loop's: the command lag, not the vessel's thrusters
        config = replace(config, actuator_time_constant_s=(options.command_lag_s,) * 3)
    if override:
        config = replace(config, **override)
    controller = MracController(config)
    guidance = ReferenceModel(default_reference_config(vessel))
    plant = DpVesselModel(replace(vessel, quadratic_damping=np.zeros(3)) if linear_plant else vessel)
    period = config.natural_period_s[0]
    dt = period / steps_per_period
    step = np.array([STEP_PER_LENGTH * vessel.length_m, STEP_PER_LENGTH * vessel.length_m, STEP_YAW_RAD])
    moved = np.array(KINDS[kind], dtype=float)
    rng = np.random.default_rng(seed) if seed is not None else None
    x = np.zeros(6)  # [north, east, ψ, u, v, r]
    setpoint = np.zeros(3)
    guidance.reset(x[:3])
    controller.reset()
    nominal = np.array(config.mass_nominal)
    hold_steps = round(hold_periods * steps_per_period)
    schedule = [round(rest_periods * steps_per_period) + k * hold_steps for k in range(moves)]
    total = schedule[-1] + hold_steps if moves else round(rest_periods * steps_per_period)
    next_move = 0
    worst = np.zeros(3)
    peak_error = np.zeros(3)
    zero = np.zeros(3)
    applied = np.zeros(3)
    lag = 1.0 - math.exp(-dt / options.command_lag_s) if options.command_lag_s > 0.0 else 1.0
    for k in range(total):
        if next_move < moves and k == schedule[next_move]:
            if pattern == "onward":
                setpoint = setpoint + moved * step
            elif rng is None:
                setpoint = moved * step if next_move % 2 == 0 else np.zeros(3)
            else:
                setpoint = setpoint + moved * step * rng.choice((-1.0, 1.0), size=3)
            next_move += 1
        ref = guidance.step(dt, setpoint)
        out = controller.step(dt, x[:3].copy(), x[3:].copy(), zero, ref)
        if lag < 1.0:
            applied += lag * (out.tau_b - applied)
            tau = applied
        else:
            tau = out.tau_b
        plant.step(x, dt, float(tau[0]), float(tau[1]), float(tau[2]), 0.0, 0.0)
        ratio = controller.mass_hat / nominal - 1.0
        worst = np.maximum(worst, np.abs(ratio))
        if next_move:
            peak_error = np.maximum(peak_error, np.abs(out.error_b))
        if not np.all(np.isfinite(x)):
            break
    final = controller.mass_hat / nominal
    return {"vessel": vessel.name, "kind": kind, "moves": moves, "reference": reference, "seed": seed,
            "mass_ratio": [round(float(v), 4) for v in final],
            "worst_deviation": [round(float(v), 4) for v in worst],
            "damping_ratio": [round(float(a / c), 4) if c > 0 else None
                              for a, c in zip(controller.damping_hat, config.damping_nominal, strict=True)],
            "peak_error_b": [round(float(v), 4) for v in peak_error],
            "suspended": controller.mass_at_bound() is not None}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--vessel", action="append", choices=sorted(VESSELS),
                        help="vessel (repeatable; default: all four)")
    parser.add_argument("--kind", default="sway-yaw", choices=sorted(KINDS))
    parser.add_argument("--moves", type=int, default=24)
    parser.add_argument("--hold-periods", type=float, default=4.0)
    parser.add_argument("--steps-per-period", type=int, default=400)
    parser.add_argument("--seed", type=int, default=None, help="random move signs (default: out and back)")
    parser.add_argument("--pattern", default="back", choices=("back", "onward"),
                        help="back: out and back (default), onward: every move adds the step again")
    parser.add_argument("--reference", default="model", choices=("model", "guidance"))
    parser.add_argument("--override", default=None, help="JSON object of MracConfig fields")
    parser.add_argument("--linear-plant", action="store_true",
                        help="diagnostic: the plant without its quadratic damping")
    parser.add_argument("--command-lag", type=float, default=0.0,
                        help="time constant of a first-order lag of the command [s] (default 0: none)")
    parser.add_argument("--lead", action="store_true",
                        help="the MRAC leads its feed-forward by the command lag (actuator_time_constant_s)")
    parser.add_argument("--json", action="store_true", help="one JSON object per line")
    args = parser.parse_args(argv)
    override = json.loads(args.override) if args.override else None
    names = args.vessel or ["supply", "cybership2", "shuttle_tanker", "blue_lady"]
    if not args.json:
        print(f"{'vessel':16s} {'kind':10s} {'surge':>7s} {'sway':>7s} {'yaw':>7s}   "
              f"worst |â₂/M − 1|          peak |e_b| [m, m, deg]")
    for name in names:
        start = time.perf_counter()
        options = BiasRun(kind=args.kind, moves=args.moves, hold_periods=args.hold_periods,
                          steps_per_period=args.steps_per_period, seed=args.seed, pattern=args.pattern,
                          reference=args.reference, linear_plant=args.linear_plant,
                          command_lag_s=args.command_lag, lead=args.lead, override=override)
        result = run(VESSELS[name], options)
        result["seconds"] = round(time.perf_counter() - start, 1)
        if args.json:
            print(json.dumps(result), flush=True)
            continue
        ratio = result["mass_ratio"]
        worst = result["worst_deviation"]
        err = result["peak_error_b"]
        print(f"{name:16s} {args.kind:10s} {ratio[0]:7.3f} {ratio[1]:7.3f} {ratio[2]:7.3f}   "
              f"{worst[0]:6.3f} {worst[1]:6.3f} {worst[2]:6.3f}   "
              f"{err[0]:8.3f} {err[1]:8.3f} {math.degrees(err[2]):7.2f}"
              f"{'  SUSPENDED' if result['suspended'] else ''}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
