"""The example configurations an installer starts from (``deploy/config/*.yaml``) keep their vessel on station in
its seed scenario (``benchmarks/example_configs.py``, which prints the numbers): each example's estimator,
controller, guidance, allocation and limits (its sensor and transport sections are the vessel's, not the
simulation's) drive the lockstep closed loop, and neither the position nor the heading deviation alarm
(``deviation:``, the estimate against the reference) is raised, not even its warning.

This caught the supply vessel's example running MRAC: its adaptation lost the heading (53° median deviation in the
seed 001 sea); the example now runs the PID with the bias fed forward. And the shuttle tanker's first 20 m set-point
correction (its run goes through it): the alarms measured the MRAC's vessel from the guidance's η_d, which the MRAC's
reference model y_M trails by design, and raised ``position.deviation.alarm`` at 8.7 m; they measure from y_M now."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from benchmark_module import load_benchmark

from dpcontrol.models.vessels import BUILTIN_VESSELS
from dpcontrol.runtime.config import parse_config

ROOT = Path(__file__).resolve().parents[2]


BENCHMARK = load_benchmark("example_configs")


@pytest.mark.parametrize("example", sorted(BENCHMARK.EXAMPLES))
def test_the_example_holds_its_vessel_within_its_deviation_limits(example: str) -> None:
    result = BENCHMARK.run_example(example)
    measured = f"{example}: deviation at most {result['position_max_m']:.2f} m, {result['heading_max_deg']:.2f}°"
    assert result["engaged"], "DP never engaged"
    assert result["deviation_alarms"] == [], measured
    config = yaml.safe_load((ROOT / "deploy" / "config" / f"{example}.yaml").read_text(encoding="utf-8"))
    limits = parse_config(config).deviation
    assert result["position_max_m"] < limits.position_warning_m, measured
    assert math.radians(result["heading_max_deg"]) < limits.heading_warning_rad, measured
    assert result["watched_steps"] > 0.5 * result["steps"]  # watched (in DP) for most of the run


def test_an_mrac_whose_estimates_run_to_a_bound_falls_back_to_its_fixed_pd() -> None:
    """CyberShip II under MRAC in its seed scenario, learning from the bumpless entry's glide (``entry_rest_s: 0``,
    as before 2026-12-03): the glide decelerates the drift the weather gave her, and the law took the weather's force
    for inertia: the mass estimates went from bound to bound within seconds (surge 5x, sway 0.3x) and the heading was
    lost by 180 deg. The supervision suspends the adaptation at the first bound (``control.adaptation``) and the
    controller holds her as the fixed PD of seed 003 eq. (25) does."""
    result = BENCHMARK.run_example("cybership2", control={"kind": "mrac", "entry_rest_s": 0.0, "reference": "model"})
    measured = f"deviation at most {result['position_max_m']:.2f} m, {result['heading_max_deg']:.2f} deg"
    assert "control.adaptation" in result["alarms"], measured
    nominal = np.diag(BUILTIN_VESSELS["cybership2"].mass_matrix)
    assert result["mass_estimates"] == pytest.approx(nominal.tolist())  # back to the nominal inertia
    assert result["position_max_m"] < 0.2, measured  # the example's warning limit
    assert result["heading_max_deg"] < 5.0, measured


@pytest.mark.parametrize(("example", "reference"), [("cybership2", "model"), ("supply", "guidance")])
def test_the_default_mrac_learns_nothing_from_the_entry_and_keeps_the_vessel(example: str, reference: str) -> None:
    """The MRAC (learning only after the reference has rested for one period after the entry) in the seed
    scenarios of the vessels whose adaptation ran away from the entry: no estimate reaches a bound, no position
    deviation warning (CyberShip II: 0.05 m; supply: 1.05 m, 1.05 deg; they were 1.6 m / 180 deg and 22 m / 64 deg).
    CyberShip II with seed 003's reference model: her seed scenario's 10 m move (8 ship lengths, at the guidance's
    speed limit) makes the default guided law take forces it does not model for inertia (surge mass 2.9x nominal,
    0.27 m; part of it her quadratic surge drag: with the ``drag`` coupling 2.2x, 0.11 m; docs/campaigns.md,
    "One reference")."""
    result = BENCHMARK.run_example(example, control={"kind": "mrac", "reference": reference})
    measured = f"{example}: deviation at most {result['position_max_m']:.2f} m, {result['heading_max_deg']:.2f} deg"
    assert "control.adaptation" not in result["alarms"], measured
    assert "position.deviation.warning" not in result["alarms"], measured
    assert result["heading_max_deg"] < 5.0, measured
