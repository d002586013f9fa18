"""The lockstep loop's per-step fast paths (sim_plant.bench.lockstep): rows packed into the result array, the
controller's commands and feedback passed as arrays, the truth columns from Plant.record_values."""

from __future__ import annotations

import math

import numpy as np

from sim_plant.bench.lockstep import LockstepSimulation
from sim_plant.scenario import builtin_scenario_path, load_scenario


def _simulation() -> LockstepSimulation:
    return LockstepSimulation(load_scenario(builtin_scenario_path("cs2-seed000")))


def test_packed_rows_are_the_recorded_rows_and_the_truth() -> None:
    simulation = _simulation()
    rows: list[list[float]] = []
    truths = []
    record = simulation._record

    def keep(*args: object) -> list[float]:
        row = record(*args)
        rows.append(list(row))
        truths.append(simulation.plant.truth)
        return row

    simulation._record = keep  # type: ignore[method-assign]
    result = simulation.run(duration_s=3.0)
    columns = result.columns
    assert columns.rows == len(rows) == 31
    assert np.array_equal(columns.data[: columns.rows], np.array(rows), equal_nan=True)
    # the truth columns are the PlantTruth fields of that step
    names = columns.names
    for row, truth in zip(rows, truths, strict=True):
        for name in ("t_s", "north_m", "east_m", "heading_rad", "north_total_m", "east_total_m", "heading_total_rad",
                     "surge_mps", "sway_mps", "yaw_rate_radps", "mass_factor"):
            assert row[names.index(name)] == getattr(truth, name)
        assert row[names.index("true_surge_mass_kg")] == truth.surge_mass_kg
        assert [row[names.index(f"tau_act_{axis}")] for axis in ("x_n", "y_n", "n_nm")] == list(truth.tau_act_b)


def test_a_row_struct_cannot_pack_goes_through_numpy() -> None:
    simulation = _simulation()
    record = simulation._record

    def with_none(*args: object) -> list[float]:
        row = record(*args)
        row[-1] = None  # numpy stores None as NaN in a float array; struct does not pack it
        return row

    simulation._record = with_none  # type: ignore[method-assign]
    result = simulation.run(duration_s=1.0)
    data = result.columns.data[: result.columns.rows]
    assert np.isnan(data[:, -1]).all() and np.isfinite(data[:, 0]).all()


def test_single_row_mode_keeps_the_last_row() -> None:
    full = _simulation().run(duration_s=2.0)
    single = _simulation().run(duration_s=2.0, timeseries=False)
    assert single.columns.rows == 0
    assert np.array_equal(single.columns.data[0], full.columns.data[full.columns.rows - 1], equal_nan=True)
    assert math.isclose(single.columns.data[0, 0], 2.0)
