"""``sim-plant campaign`` and ``sim-plant capability``: the spec and its errors, the runs it expands to, the engine
on a real Dask ``LocalCluster`` on 127.0.0.1 (2 worker processes, the ``--scheduler`` code path), determinism
across worker counts, resume, a failed run, Ctrl-C, and the capability plot's physical sanity.

Short runs only (60 s of simulated time and less): the throughput measurement is
``benchmarks/bench_campaign.py``.
"""

from __future__ import annotations

import copy
import csv
import json
import logging
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from distributed import LocalCluster

from dpbase.schema import ConfigError
from dpcontrol.models.vessels import BUILTIN_VESSELS
from sim_plant.campaign.capability import (
    TABLE_2_1,
    CapabilityOptions,
    FailureCase,
    StaticLoads,
    level1,
    load_subject,
    run_capability,
    sea_state_for_wind,
)
from sim_plant.campaign.engine import Engine, execute_run
from sim_plant.campaign.outputs import build_rows
from sim_plant.campaign.run import load_results, run_campaign
from sim_plant.campaign.spec import (
    CampaignError,
    builtin_campaign_names,
    campaign_path,
    expand,
    load_campaign,
    parse_campaign,
)
from sim_plant.cli import main
from sim_plant.environment.spectra import realise_waves
from sim_plant.environment.waves import WaveField
from sim_plant.environment.wind import RHO_AIR_KGPM3
from sim_plant.vessel import DpVesselModel

ROOT = Path(__file__).resolve().parents[2]
DP_VESSELS = ("cybership2", "supply", "shuttle_tanker", "blue_lady")

# six runs of 60 s: three random seas, each with PID and MRAC (paired), a fault or none drawn per sea
CI_SPEC: dict[str, Any] = {
    "name": "ci", "base": "supply-seed001", "duration_s": 60, "runs": 3, "seed": 7,
    "vary": {
        "sea_states[0].hs_m": {"uniform": [0.5, 3.0]},
        "sea_states[0].direction_deg": {"uniform": [0, 360]},
        "current.speed_mps": {"uniform": [0.0, 0.6]},
        "faults": {"choice": [[], [{"t_s": 30, "kind": "gyro_freeze", "sensor": "gyro1", "duration_s": 20}]],
                   "labels": ["none", "gyro_freeze"]},
        "controller.control.kind": {"choice": ["pid", "mrac"], "paired": True},
    },
}


@pytest.fixture(scope="module")
def scheduler() -> Any:
    """A real Dask LocalCluster on 127.0.0.1 with 2 worker processes; its address (the --scheduler path)."""
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                      dashboard_address="127.0.0.1:0", scheduler_kwargs={"dashboard": False},
                      silence_logs=logging.ERROR) as cluster:
        yield cluster.scheduler_address


def _spec(data: dict[str, Any]) -> Any:
    return parse_campaign(copy.deepcopy(data), file="test.yaml", base_dir=ROOT)


def _csv(path: Path) -> str:
    return (path / "campaign.csv").read_text(encoding="utf-8")


# -- the spec -----------------------------------------------------------------------------------------------------
@pytest.mark.parametrize(("change", "message"), [
    ({"vary": {"sea_states[0].hs_m": {"uniformly": [0, 1]}}},
     "test.yaml: vary.sea_states[0].hs_m: expected exactly one of uniform"),
    ({"vary": {"sea_states[0].hs_m": {"uniform": [3, 1]}}},
     "test.yaml: vary.sea_states[0].hs_m.uniform: expected low"),
    ({"vary": {"sea_states[0].hs_m": {"uniform": [1]}}}, "vary.sea_states[0].hs_m.uniform: expected 2 numbers"),
    ({"vary": {"sea_states[9].hs_m": {"uniform": [0, 1]}}}, "vary.sea_states[9].hs_m: expected an index below 4"),
    ({"vary": {"sea_states[0]..hs_m": {"uniform": [0, 1]}}}, "vary.sea_states[0]..hs_m: expected a dotted path"),
    ({"vary": {"wind.speed_mps.x": {"uniform": [0, 1]}}},
     "vary.wind.speed_mps.x: expected a mapping at wind.speed_mps"),
    ({"vary": {"faults": {"choice": [[], []], "labels": ["a"]}}}, "vary.faults.labels: expected 2 distinct names"),
    ({"vary": {"x": {"linspace": [0, 1, 2.5]}}}, "vary.x.linspace: expected a whole count"),
    ({"runs_count": 3}, "test.yaml: runs_count: expected a known key"),
    ({"base": "no-such-scenario"}, "test.yaml: base: expected a built-in scenario"),
])
def test_spec_errors_name_the_file_and_the_key_path(change: dict[str, Any], message: str) -> None:
    data = {**copy.deepcopy(CI_SPEC), **change}
    with pytest.raises(ConfigError) as error:
        _spec(data)
    assert message in str(error.value)


def test_a_sampled_value_the_scenario_refuses_names_the_run_and_the_key() -> None:
    data = copy.deepcopy(CI_SPEC)
    data["vary"]["sea_states[0].hs_m"] = {"uniform": [25.0, 45.0]}  # Hs above the plant's 30 m limit in some run
    with pytest.raises(CampaignError) as error:
        expand(_spec(data))
    text = str(error.value)
    assert text.startswith("test.yaml: run ") and "sea_states[0].hs_m = " in text
    assert "sea_states[0].hs_m: expected a number <= 30" in text


def test_a_controller_kind_the_controller_does_not_know_is_refused_before_any_run() -> None:
    data = copy.deepcopy(CI_SPEC)
    data["vary"]["controller.control.kind"] = {"choice": ["pid", "lqr"], "paired": True}
    with pytest.raises(CampaignError, match=r"run 1 .*controller: .*control\.kind"):
        expand(_spec(data))


def test_paired_runs_share_the_sea_and_the_draws_and_more_runs_keep_the_first() -> None:
    runs = expand(_spec(CI_SPEC))
    assert len(runs) == 6 and [r.run for r in runs] == list(range(6))
    for a, b in zip(runs[::2], runs[1::2], strict=True):
        assert a.sample == b.sample and a.seed == b.seed
        assert a.values["sea_states[0].hs_m"] == b.values["sea_states[0].hs_m"]
        assert a.values["faults"] == b.values["faults"]
        assert (a.values["controller.control.kind"], b.values["controller.control.kind"]) == ("pid", "mrac")
    assert len({r.seed for r in runs}) == 3  # one sea per sample
    more = expand(_spec({**CI_SPEC, "runs": 5}))
    assert [r.key for r in more[:6]] == [r.key for r in runs]  # the samples drawn before stay what they were
    assert expand(_spec(CI_SPEC)) == runs  # deterministic


def test_grids_span_cells_and_a_kind_switch_drops_the_old_kinds_settings() -> None:
    spec = _spec({"name": "g", "base": "supply-seed001", "seed": 2,
                  "set": {"controller.control": {"kind": "pid", "integral_action": "bias_feedforward"}},
                  "vary": {"current.speed_mps": {"grid": [0.1, 0.4]}, "wind.direction_deg": {"linspace": [0, 90, 3]},
                           "controller.control.kind": {"grid": ["pid", "mrac"]}}})
    runs = expand(spec)
    assert len(runs) == 12 and len({r.seed for r in runs}) == 12  # unpaired grids: a cell each, its own sea
    assert sorted({r.values["wind.direction_deg"] for r in runs}) == [0.0, 45.0, 90.0]
    kinds = {r.values["controller.control.kind"]: r.scenario["controller"]["control"] for r in runs}
    assert kinds["pid"] == {"kind": "pid", "integral_action": "bias_feedforward"}
    assert kinds["mrac"] == {"kind": "mrac"}  # a PID setting has no meaning for the MRAC


def test_vessel_choice_through_the_base_scenario() -> None:
    spec = _spec({"name": "v", "base": "supply-seed001", "duration_s": 30, "runs": 1,
                  "vary": {"base": {"choice": ["supply-seed001", "cs2-seed000"], "paired": True}}})
    runs = expand(spec)
    assert [r.scenario["vessel"] for r in runs] == ["supply", "cybership2"]
    assert runs[0].seed == runs[1].seed


def test_a_distribution_given_as_the_base_says_where_it_belongs() -> None:
    with pytest.raises(ConfigError, match=r"test\.yaml: base: expected one scenario .* under vary: "):
        _spec({"name": "v", "base": {"grid": ["supply-seed001", "cs2-seed000"]}, "runs": 1})


def test_every_shipped_campaign_is_valid_and_covers_every_built_in_dp_vessel() -> None:
    vessels = set()
    for name in builtin_campaign_names():
        spec = load_campaign(campaign_path(name))
        runs = expand(spec)
        assert runs, name
        vessels |= {r.scenario["vessel"] if isinstance(r.scenario["vessel"], str) else r.scenario["vessel"]["base"]
                    for r in runs}
    assert set(DP_VESSELS) <= vessels


# -- the engine on a LocalCluster -----------------------------------------------------------------------------------
def test_ci_campaign_every_run_finishes_with_finite_metrics(scheduler: str, tmp_path: Path) -> None:
    outcome = run_campaign(_spec(CI_SPEC), tmp_path, scheduler=scheduler, plots=True)
    summary = json.loads((tmp_path / "campaign.json").read_text(encoding="utf-8"))
    assert summary["runs"] == summary["ok"] == 6 and summary["failed"] == 0 and not summary["interrupted"]
    _, rows = build_rows(outcome_spec := _spec(CI_SPEC), outcome.runs, outcome.results)
    assert outcome_spec.name == "ci" and len(rows) == 6
    for row in rows:
        for metric in ("position_error_rms_m", "position_error_max_m", "heading_error_rms_deg",
                       "estimate_error_rms_north_m", "estimate_error_rms_heading_deg"):
            assert math.isfinite(row[metric]), (row["run"], metric)
    assert set(summary["by_paired"]["controller.control.kind"]) == {"pid", "mrac"}
    assert summary["paired_differences"]["controller.control.kind"]["mrac - pid"]["position_error_rms_m"]["pairs"] == 3
    assert (tmp_path / "by_controller_control_kind.png").stat().st_size > 10_000
    assert (tmp_path / "against_sea_states_0_hs_m.png").exists()


def test_rows_are_the_same_on_one_worker_two_workers_and_in_process(scheduler: str, tmp_path: Path) -> None:
    data = {**copy.deepcopy(CI_SPEC), "duration_s": 40, "runs": 2}
    run_campaign(_spec(data), tmp_path / "two", scheduler=scheduler, plots=False)
    run_campaign(_spec(data), tmp_path / "one", workers=1, plots=False)
    assert _csv(tmp_path / "one") == _csv(tmp_path / "two")
    spec = _spec(data)
    runs = expand(spec)
    direct = {runs[3].key: execute_run(runs[3])}  # the same run in this process, no Dask
    _, two_rows = build_rows(spec, runs, json_results(tmp_path / "two"))
    _, direct_rows = build_rows(spec, [runs[3]], direct)
    assert direct_rows[0] == two_rows[3]


def json_results(out_dir: Path) -> dict[str, Any]:
    return load_results(out_dir / "runs")


def test_resume_skips_the_finished_runs(scheduler: str, tmp_path: Path) -> None:
    data = {**copy.deepcopy(CI_SPEC), "duration_s": 30, "runs": 1}
    first = run_campaign(_spec(data), tmp_path, scheduler=scheduler, plots=False)
    assert first.skipped == 0 and len(first.results) == 2
    before = _csv(tmp_path).splitlines()
    again = run_campaign(_spec({**data, "runs": 2}), tmp_path, scheduler=scheduler, plots=False)
    assert again.skipped == 2 and len(again.results) == 4
    after = _csv(tmp_path).splitlines()
    assert after[:3] == before and len(after) == 5
    third = run_campaign(_spec({**data, "runs": 2}), tmp_path, scheduler=scheduler, plots=False)
    assert third.skipped == 4 and _csv(tmp_path).splitlines() == after


def test_a_failed_run_is_recorded_and_the_campaign_goes_on(scheduler: str, tmp_path: Path) -> None:
    # 10⁹ s of 10 Hz rows cannot be held in memory: that run fails when it starts, the other runs
    data = {"name": "f", "base": "cs2-seed000", "seed": 1,
            "vary": {"duration_s": {"grid": [20, 1.0e9, 25]}}}
    outcome = run_campaign(_spec(data), tmp_path, scheduler=scheduler, plots=False)
    summary = outcome.summary
    assert (summary["ok"], summary["failed"]) == (2, 1)
    assert summary["failures"][0]["run"] == 1 and "SimulationTooLargeError" in summary["failures"][0]["error"]
    rows = list(csv.DictReader(_csv(tmp_path).splitlines()))
    assert [(r["run"], r["duration_s"], r["status"]) for r in rows] == [
        ("0", "20", "ok"), ("1", "1000000000.0", "failed"), ("2", "25", "ok")]
    assert rows[1]["error"] == summary["failures"][0]["error"] and rows[0]["error"] == rows[2]["error"] == ""
    assert rows[1]["position_error_rms_m"] == "" and float(rows[0]["position_error_rms_m"]) >= 0.0


def test_ctrl_c_writes_what_finished_and_a_rerun_resumes(tmp_path: Path) -> None:
    spec = tmp_path / "spec.yaml"
    spec.write_text(yaml.safe_dump({"name": "c", "base": "cs2-seed000", "duration_s": 40, "runs": 40, "seed": 3,
                                    "vary": {"current.speed_mps": {"uniform": [0.0, 0.05]}}}), encoding="utf-8")
    out = tmp_path / "out"
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1"}
    command = [sys.executable, "-m", "sim_plant.cli", "--log-level", "WARNING", "campaign", str(spec),
               "--out", str(out), "--workers", "1", "--no-plots"]
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
                               start_new_session=True)
    try:
        deadline = time.monotonic() + 90.0
        while time.monotonic() < deadline and len(list((out / "runs").glob("*.json"))) < 2:
            assert process.poll() is None, process.communicate()
            time.sleep(0.1)
        os.kill(process.pid, signal.SIGINT)
        stdout, stderr = process.communicate(timeout=60)
    finally:
        if process.poll() is None:
            process.kill()
    assert process.returncode == 130, stderr
    assert "interrupted" in stdout
    summary = json.loads((out / "campaign.json").read_text(encoding="utf-8"))
    finished = len(list((out / "runs").glob("*.json")))
    assert summary["interrupted"] and 2 <= summary["finished"] == finished < 40
    assert len(_csv(out).splitlines()) == 1 + finished
    listed = subprocess.run([*command, "--list"], capture_output=True, text=True, env=env, timeout=60, check=True)
    assert len(listed.stdout.splitlines()) == 40


def test_cli_campaign_usage_errors_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    spec = tmp_path / "bad.yaml"
    spec.write_text("name: x\nbase: supply-seed001\nruns: 2\nvary: {wind.speed_mps: {uniform: [1]}}\n",
                    encoding="utf-8")
    assert main(["campaign", str(spec), "--out", str(tmp_path / "o")]) == 2
    assert "bad.yaml: vary.wind.speed_mps.uniform: expected 2 numbers" in capsys.readouterr().err


# -- capability -----------------------------------------------------------------------------------------------------
def test_the_wind_wave_table_is_dnv_st_0111_table_2_1() -> None:
    assert [row[0] for row in TABLE_2_1] == [1.5, 3.4, 5.4, 7.9, 10.7, 13.8, 17.1, 20.7, 24.4, 28.4, 32.6]
    for wind, hs, tp in TABLE_2_1:
        assert sea_state_for_wind(wind) == pytest.approx((hs, tp))
    winds = np.linspace(0.0, 40.0, 81)
    hs = [sea_state_for_wind(w)[0] for w in winds]
    assert np.all(np.diff(hs) > 0)


def test_static_loads_are_the_plants_models() -> None:
    vessel = BUILTIN_VESSELS["supply"]
    loads = StaticLoads(vessel, current_mps=0.0)
    model = DpVesselModel(vessel)
    beta = math.radians(30.0)
    hs, tp = sea_state_for_wind(15.0)
    rng = np.random.default_rng(5)
    # the plant's wave field of many realisations: its mean drift Σ b_i² scatters around the Level 1 integral
    drifts = []
    for _ in range(20):
        waves = WaveField(realise_waves(hs, 2 * math.pi / tp, 1.0, "pierson_moskowitz", 200, rng=rng),
                          beta, model.hull, vessel.water_density_kgpm3, model.extras.drift_scale)
        drifts.append(waves.mean_drift_b(0.0))
    assert np.mean(drifts, axis=0) == pytest.approx(loads.drift_b(beta, 15.0), rel=0.02)
    # β from starboard is γ_rw = −β in the wind law's convention (dpbase.wind_loads)
    assert loads.wind_b(beta, 15.0) == pytest.approx(model.wind.force_b(15.0, -beta, RHO_AIR_KGPM3))
    head = StaticLoads(vessel, current_mps=0.5).current_b(0.0)
    assert head[0] < 0 and abs(head[1]) < 1e-9 * abs(head[0])  # a head current pushes astern, nothing abeam


@pytest.mark.parametrize("name", DP_VESSELS)
def test_intact_holds_at_least_as_much_as_any_single_failure_in_every_direction(name: str) -> None:
    subject = load_subject(name)
    directions = [10.0 * k for k in range(36)]
    intact = np.array(level1(subject, FailureCase("intact"), directions, current_mps=0.5)["max_wind_mps"])
    assert intact.max() > 0.0
    for case in subject.single_failures():
        failed = np.array(level1(subject, case, directions, current_mps=0.5)["max_wind_mps"])
        assert np.all(intact >= failed), (case.name, directions[int(np.argmin(intact - failed))])
    # a ship-shaped hull holds more head-on than beam-on (less area, less drift against the wind)
    assert intact[0] >= intact[9] and intact[0] >= intact[27]


def test_a_symmetric_layout_gives_a_symmetric_plot_and_an_asymmetric_one_does_not() -> None:
    subject = load_subject("supply")  # tunnels on the centre line, azimuths at ±y: symmetric port/starboard
    directions = [10.0 * k for k in range(36)]
    intact = np.array(level1(subject, FailureCase("intact"), directions, current_mps=0.5)["max_wind_mps"])
    mirrored = np.r_[intact[0], intact[:0:-1]]  # β ↔ 360° − β
    assert np.max(np.abs(intact - mirrored)) <= 2 * 0.01  # the bisection's resolution
    lost = level1(subject, FailureCase("azimuth_port", ("azimuth_port",)), directions, current_mps=0.5)
    one_side = np.array(lost["max_wind_mps"])
    assert np.max(np.abs(one_side - np.r_[one_side[0], one_side[:0:-1]])) > 0.5


def test_the_dynamic_allowance_only_lowers_the_curve() -> None:
    subject = load_subject("supply")
    directions = [0.0, 45.0, 90.0, 135.0, 180.0]
    plain = np.array(level1(subject, FailureCase("intact"), directions, current_mps=0.5)["max_wind_mps"])
    allowed = np.array(level1(subject, FailureCase("intact"), directions, current_mps=0.5,
                              dynamic_allowance=1.25)["max_wind_mps"])
    assert np.all(allowed <= plain) and np.any(allowed < plain)


def test_cli_capability_level1_writes_the_contract_fields(tmp_path: Path) -> None:
    assert main(["capability", str(ROOT / "deploy/config/supply.yaml"), "--out", str(tmp_path), "--directions", "12",
                 "--failed", "bus_a", "--failed", "worst"]) == 0
    doc = json.loads((tmp_path / "capability.json").read_text(encoding="utf-8"))
    assert doc["level"] == 1 and doc["vessel"] == "supply" and doc["current_mps"] == 0.5
    assert doc["failed"] == ["bow_tunnel_1", "azimuth_port"] and len(doc["directions_deg"]) == 12
    assert len(doc["max_wind_mps"]) == len(doc["limiting_thruster"]) == 12
    assert [c["case"] for c in doc["cases"]][:2] == ["intact", "bus_a"]
    assert doc["cases"][2]["case"].startswith("worst single failure: ")
    assert (tmp_path / "capability.png").stat().st_size > 20_000
    assert main(["capability", "supply", "--out", str(tmp_path), "--failed", "bow_tunnel_9"]) == 2


def test_level3_is_at_most_level1_in_every_direction(scheduler: str, tmp_path: Path) -> None:
    subject = load_subject("cybership2")
    options = CapabilityOptions(level=3, directions=4, iterations=3, settle_s=150.0, window_s=150.0)
    with Engine(scheduler=scheduler) as engine:
        doc = run_capability(subject, subject.failure_cases([]), options, tmp_path, engine=engine)
    case = doc["cases"][0]
    assert all(len(points) == 3 for points in case["runs"])
    assert all(p["status"] == "ok" for points in case["runs"] for p in points)
    assert np.all(np.array(case["max_wind_mps"]) <= np.array(case["level1_max_wind_mps"]))
    assert any(p["held"] for points in case["runs"] for p in points)  # the loop holds in some weather
    assert any(not p["held"] for points in case["runs"] for p in points)  # and loses it in worse


@pytest.mark.parametrize("content", [b"\x7fELF\x02\x01\x01\x00" + bytes(16) + b"\xd0\x11",
                                     "name: Sjø\n".encode("latin-1")])
def test_campaign_and_capability_name_a_file_that_is_not_utf8_text(content: bytes, tmp_path: Path,
                                                                   capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "input.yaml"
    path.write_bytes(content)
    for argv, prefix in ((["campaign", str(path), "--out", str(tmp_path / "o")], "sim-plant campaign: "),
                         (["capability", str(path), "--out", str(tmp_path / "o")], "sim-plant capability: ")):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert err.startswith(f"{prefix}{path}: <root>: expected UTF-8 text"), err
        assert len(err.strip().splitlines()) == 1
