"""Every time plot of ``sim-plant run`` and of the demo marks the set-point changes, DP engagement and the
sea-state changes (:func:`sim_plant.bench.report.mark_events`); fault scenarios run by name."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from matplotlib.figure import Figure

from sim_plant.bench import demo
from sim_plant.bench.lockstep import LockstepSimulation
from sim_plant.bench.report import PlotEvent, plot_events, write_plots
from sim_plant.cli import main as sim_plant_main
from sim_plant.scenario import builtin_scenario_path, load_scenario, parse_scenario


def test_plot_events_orders_setpoints_sea_states_and_dp_transitions() -> None:
    events = plot_events([0.0, 20.0], [0.0, 60.0], [(0.0, "standby"), (5.0, "auto_position"),
                                                      (9.0, "auto_position"), (30.0, "standby"),
                                                      (31.0, "auto_heading")])
    assert events == [PlotEvent(0.0, "setpoint"), PlotEvent(5.0, "dp_on"), PlotEvent(20.0, "setpoint"),
                      PlotEvent(30.0, "dp_off"), PlotEvent(31.0, "dp_on"), PlotEvent(60.0, "sea")]


def _vertical_lines(ax: Any) -> set[float]:
    return {float(line.get_xdata()[0]) for line in ax.get_lines()
            if len(line.get_xdata()) == 2 and line.get_xdata()[0] == line.get_xdata()[1]}


@pytest.fixture()
def saved_figures(monkeypatch: pytest.MonkeyPatch) -> list[tuple[str, Figure]]:
    saved: list[tuple[str, Figure]] = []
    original = Figure.savefig

    def savefig(self: Figure, path: Any, *args: Any, **kwargs: Any) -> None:
        saved.append((Path(path).name, self))
        original(self, path, *args, **kwargs)

    monkeypatch.setattr(Figure, "savefig", savefig)
    return saved


def test_every_run_plot_marks_the_setpoint_dp_and_sea_state_changes(tmp_path: Path,
                                                                     saved_figures: list[tuple[str, Figure]]) -> None:
    data = yaml.safe_load(builtin_scenario_path("demo").read_text())
    data.update(duration_s=40.0, setpoints=[{"t_s": 0, "north_m": 0, "east_m": 0, "heading_deg": 0},
                                             {"t_s": 12, "north_m": 1, "east_m": 0, "heading_deg": 0}])
    data["sea_states"][1]["t_s"] = 25.0
    result = LockstepSimulation(parse_scenario(data)).run()
    engaged = [t for t, _f, to, _w in result.mode_changes if to == "auto_position"]
    assert engaged  # the scenario engages DP
    paths = write_plots(result, tmp_path)
    assert {p.name for p in paths} >= {"pose.png", "weights.png", "forces.png", "thrusters.png"}
    assert len(saved_figures) == len(paths)
    for name, fig in saved_figures:
        for ax in fig.axes:
            marks = _vertical_lines(ax)
            assert {12.0, 25.0, engaged[0]} <= marks, (name, marks)
        labels = [t.get_text() for legend in fig.legends for t in legend.get_texts()]
        assert {"set-point change", "DP engaged", "sea-state change"} <= set(labels), (name, labels)
    pose = dict(saved_figures)["pose.png"]
    setpoint = next(line for line in pose.axes[0].get_lines() if line.get_label() == "set-point")
    assert np.nanmax(setpoint.get_ydata()) == 1.0  # the set-point itself is drawn, as a step to 1 m


def test_the_demo_plots_mark_events_on_plant_time(tmp_path: Path, saved_figures: list[tuple[str, Figure]]) -> None:
    scenario = yaml.safe_load(builtin_scenario_path("demo").read_text())
    # the plant's commands.csv: standby, then DP from plant time 3.05 s; the daemon's clock runs 1000 s behind
    rows = [[f"{0.1 * k + 0.05:.2f}", str(k), "standby" if k < 30 else "auto_position", "bow_tunnel", "0", "0", "1"]
            for k in range(1000)]
    commands = {"t_s": np.array([float(r[0]) for r in rows]), "seq": np.arange(1000.0),
                "_header": ["t_s", "seq", "mode", "name", "thrust_n", "azimuth_rad", "enabled"], "_text": rows}
    cycle_t = {k: 0.1 * k - 1000.0 for k in range(1000)}
    offset = demo._daemon_to_plant_s(commands, cycle_t)
    assert offset == pytest.approx(1000.05)
    events = demo._demo_events(scenario, commands)
    assert PlotEvent(3.05, "dp_on") in events and PlotEvent(20.0, "setpoint") in events
    assert PlotEvent(60.0, "sea") in events
    t = np.arange(0.0, 100.0, 0.1)
    truth = {key: np.zeros_like(t) for key in ("north_m", "north_total_m", "east_m", "east_total_m", "heading_rad",
                                               "heading_total_rad")}
    truth["t_s"] = t
    estimates = [(tk - 1000.0, [0.0, 0.0, 0.0]) for tk in t]
    weights = [(tk - 1000.0, [0.5, 0.5]) for tk in t]
    demo._plots(tmp_path, truth, scenario, estimates, weights, events=events, daemon_to_plant_s=offset)
    assert {name for name, _ in saved_figures} == {"pose.png", "weights.png"}
    for name, fig in saved_figures:
        for ax in fig.axes:
            assert {3.05, 20.0, 60.0} <= _vertical_lines(ax), name
        assert fig.axes[-1].get_xlim()[1] < 200.0  # plant time, not the daemon's clock


def test_fault_scenarios_run_by_name(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert load_scenario(builtin_scenario_path("faults/01-gnss-freeze")).faults
    code = sim_plant_main(["run", "faults/01-gnss-freeze", "--duration", "3", "--no-plots", "--out", str(tmp_path)])
    assert code == 0, capsys.readouterr().err
    assert (tmp_path / "summary.json").exists()
    assert sim_plant_main(["run", "faults/99-nothing", "--out", str(tmp_path)]) == 2
    assert "faults/01-gnss-freeze" in capsys.readouterr().err  # the known fault scenarios are listed
