"""The composed plant (sim_plant.plant): API, determinism, time grid, truth, sensors, faults."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from interfaces.messages import Heading, PositionFix
from sim_plant.drives import CommandError, ThrusterCommand
from sim_plant.plant import Plant, PlantDivergedError
from sim_plant.scenario import builtin_scenario_path, load_scenario, parse_scenario

BASE = {
    "name": "plant-test",
    "vessel": "supply",
    "duration_s": 100,
    "seed": 5,
    "sea_states": [{"t_s": 0, "hs_m": 2.0, "omega_peak_rad_s": 0.8, "direction_deg": 30},
                   {"t_s": 20, "hs_m": 3.0, "omega_peak_rad_s": 0.6, "direction_deg": 30, "fade_s": 10}],
    "current": {"speed_mps": 0.3, "direction_deg": 200},
    "wind": {"speed_mps": 10.0, "direction_deg": 40},
    "sensors": [{"name": "gnss1", "kind": "gnss", "rate_hz": 5, "noise_m": 0.0, "gst": False},
                {"name": "gyro1", "kind": "gyro", "rate_hz": 10, "noise_deg": 0.0, "rot_noise_degps": 0.0}],
}


def _plant(**overrides) -> Plant:
    data = copy.deepcopy(BASE)
    data.update(overrides)
    return Plant(parse_scenario(data))


def _drive(plant: Plant, until: float, step: float = 0.1, command=None) -> list:
    samples = []
    k = round(plant.t_s / step)
    while (k + 1) * step <= until + 1e-9:
        k += 1
        if command is not None:
            plant.command(plant.t_s, command)
        plant.advance(k * step)
        samples.extend(plant.sensor_samples(k * step))
    return samples


CMD = {"azimuth_port": ThrusterCommand(1e5, 0.2), "azimuth_starboard": ThrusterCommand(1e5, -0.2),
       "bow_tunnel_1": ThrusterCommand(2e4)}


def test_same_scenario_same_run_and_a_different_seed_differs() -> None:
    a, b = _plant(), _plant()
    sa = _drive(a, 30.0, command=CMD)
    sb = _drive(b, 30.0, command=CMD)
    assert sa == sb
    assert a.truth == b.truth
    c = _plant(seed=6)
    _drive(c, 30.0, command=CMD)
    assert c.truth.wf_surge_m != a.truth.wf_surge_m


def test_result_does_not_depend_on_how_advance_is_chunked() -> None:
    a, b = _plant(), _plant()
    _drive(a, 10.0, step=0.1)
    b.advance(10.0)
    assert a.state() == pytest.approx(b.state(), rel=1e-12, abs=1e-12)
    assert b.sensor_samples(10.0) != []


def test_real_time_calls_at_arbitrary_times_follow_the_lockstep_run() -> None:
    """HIL: the emulator advances to wall-clock times that are not on the plant grid."""
    a, b = _plant(), _plant()
    a.advance(20.0)
    rng = np.random.default_rng(0)
    t = 0.0
    while t < 20.0:
        t = min(20.0, t + float(rng.uniform(0.001, 0.23)))
        b.advance(t)
    assert b.t_s == 20.0
    assert b.state() == pytest.approx(a.state(), rel=1e-6, abs=1e-6)
    assert [s.t_s for s in b.sensor_samples(20.0)] == [s.t_s for s in a.sensor_samples(20.0)]


@pytest.mark.parametrize("value", [math.inf, math.nan])
def test_a_state_that_leaves_the_finite_numbers_stops_the_plant_with_its_time_and_speeds(value: float) -> None:
    plant = _plant()
    plant.advance(1.0)
    plant._x[3] = value  # what an overflow leaves behind (a scenario far outside the models' range)
    with pytest.raises(PlantDivergedError, match=r"left the model's range at t = 1\.\d\d s \(surge (inf|nan) m/s"):
        plant.advance(2.0)


def test_advance_rejects_the_past_and_non_numbers() -> None:
    plant = _plant()
    plant.advance(1.0)
    plant.advance(1.0)  # no-op
    with pytest.raises(ValueError, match="before the plant time"):
        plant.advance(0.5)
    with pytest.raises(ValueError, match="finite"):
        plant.advance(float("nan"))
    with pytest.raises(CommandError):
        plant.command(1.0, {"nope": ThrusterCommand(1.0)})


def test_sensor_samples_come_once_in_time_order_at_their_rates() -> None:
    plant = _plant()
    first = plant.sensor_samples(1.0)
    second = plant.sensor_samples(1.0)
    assert second == []
    times = [s.t_s for s in first]
    assert times == sorted(times)
    gnss = [s for s in first if isinstance(s.message, PositionFix)]
    gyro = [s for s in first if isinstance(s.message, Heading)]
    assert [s.t_s for s in gnss] == pytest.approx([0.0, 0.2, 0.4, 0.6, 0.8, 1.0])
    assert len(gyro) == 11
    assert plant.t_s == 1.0


def test_sensors_see_the_total_motion() -> None:
    plant = _plant()
    for t in (3.0, 7.2, 21.0):
        samples = plant.sensor_samples(t)
        truth = plant.truth
        fix = next(s for s in samples if s.t_s == t and isinstance(s.message, PositionFix)).message
        n, e, _ = plant.frame.to_ned(fix.lat_deg, fix.lon_deg, 0.0)
        assert n == pytest.approx(truth.north_total_m, abs=1e-6)
        assert e == pytest.approx(truth.east_total_m, abs=1e-6)
        heading = next(s for s in samples if s.t_s == t and isinstance(s.message, Heading)).message
        assert math.remainder(heading.heading_rad - truth.heading_total_rad, 2 * math.pi) == pytest.approx(0, abs=1e-12)


def test_truth_is_consistent() -> None:
    plant = _plant()
    _drive(plant, 25.0, command=CMD)
    truth = plant.truth
    c, s = math.cos(truth.heading_rad), math.sin(truth.heading_rad)
    assert truth.north_total_m == pytest.approx(truth.north_m + c * truth.wf_surge_m - s * truth.wf_sway_m)
    assert truth.east_total_m == pytest.approx(truth.east_m + s * truth.wf_surge_m + c * truth.wf_sway_m)
    assert truth.omega_peak_rad_s == 0.6  # the second sea state (fading in since 20 s)
    assert truth.motion_peak_rad_s is not None and 0.5 < truth.motion_peak_rad_s < 0.7
    assert truth.current_north_mps == pytest.approx(0.3 * math.cos(math.radians(200.0)))
    assert truth.tau_act_b == pytest.approx(plant.drives.force_b())
    assert truth.tau_act_b[0] > 1e5  # two azimuths pushing ahead
    assert truth.wind_speed_mps > 0.0 and truth.tau_env_b[1] < 0.0  # wind from starboard bow
    assert truth.mass_factor == 1.0 and truth.surge_mass_kg == pytest.approx(plant.scenario.vessel.mass_matrix[0, 0])
    columns = truth.columns()
    assert columns["tau_act_x_n"] == truth.tau_act_b[0] and columns["heading_rad"] == truth.heading_rad
    fb = plant.feedback()
    assert [f.name for f in fb] == [t.name for t in plant.scenario.vessel.thrusters]
    assert fb[2].thrust_n > 0.0 and fb[2].azimuth_rad == pytest.approx(0.2, abs=1e-9)


def test_mass_schedule_is_followed() -> None:
    plant = _plant(mass_schedule=[{"t_s": 0, "factor": 1.0}, {"t_s": 10, "factor": 2.0}])
    masses = []
    for t in (0.0, 5.0, 10.0, 20.0):
        plant.advance(t)
        masses.append(plant.truth.mass_factor)
    assert masses[0] == 1.0
    assert masses[1] == pytest.approx(1.5, rel=2e-4)
    assert masses[2:] == [2.0, 2.0]
    assert plant.truth.surge_mass_kg == pytest.approx(2.0 * plant.scenario.vessel.mass_matrix[0, 0])


def test_thruster_faults_from_the_scenario_are_applied_in_their_window() -> None:
    plant = _plant(faults=[{"t_s": 2.0, "kind": "thruster_not_ready", "thruster": "bow_tunnel_1", "duration_s": 3.0},
                           {"t_s": 0.0, "kind": "thruster_zero", "thruster": "bow_tunnel_2"}])
    ready = {}
    for t in (1.9, 2.0, 4.9, 5.0):
        plant.advance(t)
        ready[t] = plant.feedback()[0].ready
    assert ready == {1.9: True, 2.0: False, 4.9: False, 5.0: True}
    plant.command(5.0, {"bow_tunnel_2": ThrusterCommand(1e5)})
    plant.advance(15.0)
    assert plant.feedback()[1].thrust_n == 0.0 and plant.drives.thrust[1] > 0.0


def test_stale_commands_and_lost_controller_ramp_the_drives_down() -> None:
    plant = _plant()
    _drive(plant, 20.0, command=CMD)
    assert plant.feedback()[2].thrust_n > 9e4
    plant.advance(21.0)  # last command at 19.9 s: still fresh
    assert plant.feedback()[2].thrust_n > 9e4
    plant.advance(40.0)
    # stale from the substep starting at 20.95 s (last command 19.9 s + 1 s timeout); from 1e5 N the
    # first-order decay (τ = 2 s) never exceeds the 50 kN/s rate limit
    assert plant.feedback()[2].thrust_n == pytest.approx(1e5 * math.exp(-(40.0 - 20.95) / 2.0), rel=1e-2)
    plant.command(40.0, CMD)
    plant.advance(41.0)
    assert plant.feedback()[2].thrust_n > 0.0
    before = plant.feedback()[2].thrust_n
    plant.command_lost(41.0)
    plant.advance(61.0)
    assert plant.feedback()[2].thrust_n == pytest.approx(before * math.exp(-20.0 / 2.0), rel=1e-2)


def test_uncontrolled_vessel_drifts_with_the_current_through_the_plant() -> None:
    plant = _plant(sea_states=[], wind={}, current={"speed_mps": 0.5, "direction_deg": 90},
                   vessel="cybership2", sensors=[])
    plant.advance(300.0)
    truth = plant.truth
    c, s = math.cos(truth.heading_rad), math.sin(truth.heading_rad)
    assert s * truth.surge_mps + c * truth.sway_mps == pytest.approx(0.5, rel=0.01)
    assert c * truth.surge_mps - s * truth.sway_mps == pytest.approx(0.0, abs=0.005)


def test_mariner_plant_reports_the_yaw_motion_peak_at_encounter_frequency() -> None:
    plant = Plant(load_scenario(builtin_scenario_path("mariner-seed002")))
    plant.advance(5.0)
    truth = plant.truth
    assert truth.motion_peak_rad_s == truth.motion_peaks_rad_s[2]
    assert truth.motion_peak_rad_s == pytest.approx(1.2, abs=0.05)  # seed 002's ω0
    assert truth.omega_peak_rad_s == 0.9
    assert truth.north_m == pytest.approx(5.0 * 7.7175, rel=1e-3)
    plant.command(5.0, {"main_propeller": ThrusterCommand(5e5, math.radians(10.0))})
    plant.advance(60.0)
    assert plant.truth.yaw_rate_radps < -1e-3  # positive rudder turns the bow to port
    assert plant.truth.tau_act_b[2] < 0.0


def test_tanker_offloading_runs_with_the_mass_schedule() -> None:
    plant = Plant(load_scenario(builtin_scenario_path("tanker-seed003")))
    plant.advance(600.0)
    truth = plant.truth
    assert truth.mass_factor == pytest.approx(1.0 + 1.66 * 600.0 / 43200.0, rel=2e-4)
    assert truth.motion_peak_rad_s is not None and truth.motion_peak_rad_s < 0.9 * truth.omega_peak_rad_s
    assert truth.north_m < -10.0  # the 1 m/s current from ahead sets the uncontrolled tanker astern
    assert np.isfinite(truth.tau_env_b).all()


@pytest.mark.parametrize("name", ["supply-seed001", "mariner-seed002", "tanker-seed003"])
def test_record_values_are_the_truth_fields(name: str) -> None:
    """Plant.record_values (one per lockstep step) gives exactly the fields of Plant.truth it names."""
    plant = Plant(load_scenario(builtin_scenario_path(name)))
    names = plant.drives.names
    for k in range(1, 40):
        t = k * 0.1
        plant.command(plant.t_s, {n: ThrusterCommand(1e4 * (i + 1), 0.1 * k, True) for i, n in enumerate(names)})
        plant.advance(t)
        plant.sensor_samples(t)
        values = plant.record_values()  # computed (no truth built yet this step)
        truth = plant.truth
        expected = (truth.t_s, truth.north_m, truth.east_m, truth.heading_rad, truth.north_total_m,
                    truth.east_total_m, truth.heading_total_rad, truth.surge_mps, truth.sway_mps,
                    truth.yaw_rate_radps, *truth.tau_act_b, truth.omega_peak_rad_s, truth.motion_peak_rad_s,
                    truth.mass_factor, truth.surge_mass_kg)
        assert values == expected
        assert plant.record_values() == expected  # from the cached truth
