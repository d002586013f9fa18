"""The example configurations an installer starts from (``deploy/config/*.yaml``) keep their vessel on station in
its seed scenario: each example's estimator, controller, guidance, allocation and limits (its sensor and transport
sections are the vessel's, not the simulation's) drive the lockstep closed loop, and neither the position nor the
heading deviation alarm (``deviation:``, the estimate against the reference) is raised, not even its warning.

This caught the supply vessel's example running MRAC: its adaptation lost the heading (53° median deviation in the
seed 001 sea); the example now runs the PID with the bias fed forward."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from dpcontrol.runtime.config import CONTROLLER_SECTIONS
from sim_plant.bench.run import build_simulation
from sim_plant.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = {  # example → the seed scenario of its vessel, and how much of it to run [s]
    "supply": ("supply-seed001.yaml", None),
    "shuttle_tanker": ("tanker-seed003.yaml", 1800.0),  # (12 h in all: its first half hour here)
    "cybership2": ("cs2-seed000.yaml", None),
    "blue_lady": ("bluelady-seed004.yaml", None),
    "mariner": ("mariner-seed002.yaml", None),
}


@pytest.mark.parametrize("example", sorted(EXAMPLES))
def test_the_example_holds_its_vessel_within_its_deviation_limits(example: str) -> None:
    config = yaml.safe_load((ROOT / "deploy" / "config" / f"{example}.yaml").read_text(encoding="utf-8"))
    scenario_name, duration = EXAMPLES[example]
    scenario = load_scenario(ROOT / "sim_plant" / "scenarios" / scenario_name)
    assert scenario.vessel.name == config["vessel"]
    overrides = {key: config[key] for key in CONTROLLER_SECTIONS if key in config}
    simulation = build_simulation(scenario, overrides=overrides)
    deviation = simulation.controller.deviation
    position, heading = [0.0], [0.0]

    def watch(_t_s: float, _out: object) -> None:
        if deviation.position_m is not None:
            position.append(deviation.position_m)
        if deviation.heading_rad is not None:
            heading.append(deviation.heading_rad)

    result = simulation.run(duration_s=duration, observer=watch, timeseries=False)
    assert result.mode_changes, "DP never engaged"
    measured = f"{example}: deviation at most {max(position):.2f} m, {math.degrees(max(heading)):.2f}°"
    raised = sorted({e.code for e in result.alarm_events if e.raised and ".deviation." in e.code})
    assert raised == [], measured
    limits = simulation.controller.config.deviation
    assert max(position) < limits.position_warning_m and max(heading) < limits.heading_warning_rad, measured
    assert len(heading) > 0.5 * result.steps  # watched (in DP) for most of the run
    assert np.all(np.isfinite(position))
