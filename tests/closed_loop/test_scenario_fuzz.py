"""A scenario or controller section with any number changed — by a factor from 0 to 10⁶, a sign, or an
absurd constant — is either refused with a ConfigError naming the key, or runs: never another exception
from the plant, the codecs or the controller. (A fuzz of this kind found a NaN crash in the wave model for
a 1e9 m/s current, a GST encoder error for a 1e9 m GNSS noise, and a controller that check-config accepted
but could not build.)"""

from __future__ import annotations

import copy
import math
from typing import Any

import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, given, note, settings
from hypothesis import strategies as st

from dpbase.schema import ConfigError
from dpcontrol.runtime.config import parse_config
from sim_plant.bench.lockstep import LockstepSimulation, controller_mapping, lockstep_config, lockstep_transports
from sim_plant.scenario import builtin_scenario_path, load_scenario, parse_scenario

SCENARIOS = ["cs2-seed000", "supply-seed001", "mariner-seed002", "demo"]
FACTORS = [0.0, 1e-6, 1e-3, 0.1, 10.0, 1e3, 1e6, -1.0]
CONSTANTS = [0.0, 1e-12, 1e12, -1.0]
RUN_S = 8.0  # long enough for the sensors, the hub and the first engaged steps; short for the suite


def _numeric_paths(node: Any, path: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
    if isinstance(node, dict):
        return [p for key, value in node.items() for p in _numeric_paths(value, (*path, key))]
    if isinstance(node, list):
        return [p for i, value in enumerate(node) for p in _numeric_paths(value, (*path, i))]
    if isinstance(node, (int, float)) and not isinstance(node, bool):
        return [path]
    return []


def _mutate(data: dict[str, Any], draw: st.DrawFn, skip: tuple[str, ...]) -> list[tuple[Any, ...]]:
    paths = [p for p in _numeric_paths(data) if p[0] not in skip]
    changes = []
    for _ in range(draw(st.integers(1, 3))):
        path = draw(st.sampled_from(paths))
        node = data
        for key in path[:-1]:
            node = node[key]
        old = node[path[-1]]
        new = old * draw(st.sampled_from(FACTORS)) if draw(st.booleans()) else draw(st.sampled_from(CONSTANTS))
        if isinstance(old, int) and math.isfinite(new) and abs(new) < 1e15:
            new = int(new)
        node[path[-1]] = new
        changes.append((path, old, new))
    return changes


def _run(simulation: LockstepSimulation) -> None:
    result = simulation.run(duration_s=RUN_S)
    names = result.columns.names
    rows = result.columns.data[: result.columns.rows]
    tau = rows[:, [names.index(n) for n in ("tau_x_n", "tau_y_n", "tau_n_nm")]]
    assert np.isfinite(tau).all(), "a commanded force is not finite"


@pytest.mark.parametrize("name", [*SCENARIOS, "bluelady-seed004", "tanker-seed003"])
def test_every_number_of_a_scenario_at_an_extreme_is_refused_by_name_or_runs(name: str) -> None:
    """Each numeric field alone at 1e12, -1e12 and 0 (exhaustive, deterministic)."""
    base = yaml.safe_load(builtin_scenario_path(name).read_text(encoding="utf-8"))
    ran = refused = 0
    for path in _numeric_paths(base):
        if path[0] in ("duration_s", "seed"):
            continue
        for value in (1e12, -1e12, 0.0):
            data = copy.deepcopy(base)
            node = data
            for key in path[:-1]:
                node = node[key]
            node[path[-1]] = value
            try:
                scenario = parse_scenario(data, file=f"<{name}>")
                simulation = LockstepSimulation(scenario, lockstep_config(scenario, file="<c>"))
            except ConfigError:
                refused += 1
                continue
            try:
                _run(simulation)
            except Exception as error:
                raise AssertionError(f"{name}: {path} = {value}: {type(error).__name__}: {error}") from error
            ran += 1
    assert ran > 0 and refused > 0


@st.composite
def _scenario_case(draw: st.DrawFn) -> tuple[str, dict[str, Any]]:
    name = draw(st.sampled_from(SCENARIOS))
    data = yaml.safe_load(builtin_scenario_path(name).read_text(encoding="utf-8"))
    note(f"{name}: {_mutate(data, draw, skip=('duration_s', 'seed'))}")
    return name, data


@settings(max_examples=30, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(case=_scenario_case())
def test_a_mutated_scenario_is_refused_by_name_or_runs(case: tuple[str, dict[str, Any]]) -> None:
    name, data = case
    try:
        scenario = parse_scenario(data, file=f"<{name}>")
        simulation = LockstepSimulation(scenario, lockstep_config(scenario, file="<c>"))
    except ConfigError as error:
        assert str(error).startswith((f"<{name}>: ", "<c>: ")), error
        return
    _run(simulation)


@st.composite
def _controller_case(draw: st.DrawFn) -> tuple[str, dict[str, Any]]:
    name = draw(st.sampled_from(SCENARIOS))
    mapping = copy.deepcopy(controller_mapping(_SCENARIOS[name]))
    note(f"{name}: {_mutate(mapping, draw, skip=('datum', 'sensors', 'vessel_id'))}")
    return name, mapping


_SCENARIOS = {name: load_scenario(builtin_scenario_path(name)) for name in SCENARIOS}


@settings(max_examples=30, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(case=_controller_case())
def test_a_mutated_controller_section_is_refused_by_name_or_runs(case: tuple[str, dict[str, Any]]) -> None:
    name, mapping = case
    try:
        config = parse_config(mapping, file="<controller>", transports=lockstep_transports(_SCENARIOS[name]))
        simulation = LockstepSimulation(_SCENARIOS[name], config)
    except ConfigError as error:
        assert str(error).startswith("<controller>: "), error
        return
    _run(simulation)
