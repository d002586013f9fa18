"""Reference model: no overshoot at ζ = 1, limits inside the model, 1 km at the set speed, short way round."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dpbase.schema import ConfigError
from dpcontrol.guidance import (
    Reference,
    ReferenceModel,
    ReferenceModelConfig,
    default_reference_config,
    reference_config_from_mapping,
)
from dpcontrol.models.vessels import BUILTIN_VESSELS, SHUTTLE_TANKER, SUPPLY
from sim_plant.bench.run import build_simulation
from sim_plant.scenario import builtin_scenario_path, load_scenario

TANKER_LIKE = ReferenceModelConfig(natural_period_s=(200.0, 200.0, 200.0), relative_damping=(1.0, 1.0, 1.0),
                                   max_speed_mps=0.5, max_accel_mps2=0.01, max_yaw_rate_radps=math.radians(1.0),
                                   max_yaw_accel_radps2=math.radians(0.05))


def run(model: ReferenceModel, setpoint, duration_s: float, dt_s: float = 1.0) -> tuple[np.ndarray, ...]:
    steps = round(duration_s / dt_s)
    eta = np.zeros((steps, 3))
    vel = np.zeros((steps, 3))
    acc = np.zeros((steps, 3))
    target = np.asarray(setpoint, dtype=float)
    for k in range(steps):
        ref = model.step(dt_s, target)
        eta[k], vel[k], acc[k] = ref.eta_d_ned, ref.eta_dot_d_ned, ref.eta_ddot_d_ned
    return eta, vel, acc


@settings(max_examples=25, deadline=None)
@given(distance=st.floats(0.5, 400.0), bearing=st.floats(-math.pi, math.pi), turn=st.floats(-3.1, 3.1),
       period=st.floats(20.0, 250.0), speed=st.floats(0.2, 2.0), accel=st.floats(0.002, 0.05),
       zeta=st.floats(1.0, 1.5))
def test_step_responses_do_not_overshoot_and_respect_every_limit(distance, bearing, turn, period, speed, accel,
                                                                 zeta) -> None:
    config = ReferenceModelConfig((period, period, period), (zeta, zeta, zeta), speed, accel,
                                  math.radians(2.0), math.radians(0.2))
    model = ReferenceModel(config)
    model.reset(np.zeros(3))
    target = np.array([distance * math.cos(bearing), distance * math.sin(bearing), turn])
    # cruise + accelerating/braking (at half the limit near the end) + the linear tail
    duration = (distance / speed + 3.0 * speed / accel + 4.0 * math.sqrt(distance / accel)
                + abs(turn) / config.max_yaw_rate_radps + 4.0 * math.sqrt(abs(turn) / config.max_yaw_accel_radps2)
                + 3.0 * config.max_yaw_rate_radps / config.max_yaw_accel_radps2 + 14.0 * period)
    eta, vel, acc = run(model, target, duration, dt_s=2.0)
    # no overshoot along the line to the set-point, nor in heading
    progress = eta[:, :2] @ target[:2] / distance
    assert progress.max() <= distance * (1.0 + 1e-9)
    assert np.all(np.diff(progress) >= -1e-9 * distance)  # monotone
    assert np.max(np.sign(turn) * eta[:, 2]) <= abs(turn) + 1e-9
    # straight line: no cross-track motion
    cross = eta[:, 0] * math.sin(bearing) - eta[:, 1] * math.cos(bearing)
    assert np.max(np.abs(cross)) <= 1e-6 * distance
    # limits hold inside the model
    assert np.max(np.hypot(vel[:, 0], vel[:, 1])) <= speed * (1.0 + 1e-12)
    assert np.max(np.hypot(acc[:, 0], acc[:, 1])) <= accel * (1.0 + 1e-12)
    assert np.max(np.abs(vel[:, 2])) <= config.max_yaw_rate_radps * (1.0 + 1e-12)
    assert np.max(np.abs(acc[:, 2])) <= config.max_yaw_accel_radps2 * (1.0 + 1e-12)
    dv = np.diff(np.vstack([np.zeros(3), vel]), axis=0) / 2.0
    assert np.max(np.hypot(dv[:, 0], dv[:, 1])) <= accel * (1.0 + 1e-9)
    # and it arrives
    np.testing.assert_allclose(eta[-1], target, atol=1e-3 * distance + 1e-6)


def test_a_setpoint_1_km_away_moves_the_reference_at_the_configured_speed() -> None:
    model = ReferenceModel(TANKER_LIKE)
    model.reset(np.zeros(3))
    eta, vel, acc = run(model, [600.0, 800.0, 0.0], 3000.0)
    speed = np.hypot(vel[:, 0], vel[:, 1])
    cruise = speed > 0.999 * TANKER_LIKE.max_speed_mps
    assert np.sum(cruise) > 1500  # most of the way at full speed
    np.testing.assert_allclose(speed[cruise], TANKER_LIKE.max_speed_mps, rtol=1e-3)
    assert speed.max() <= TANKER_LIKE.max_speed_mps * (1.0 + 1e-12)
    # no force spike: the reference acceleration (what feed-forward turns into force) stays small
    assert np.max(np.hypot(acc[:, 0], acc[:, 1])) <= TANKER_LIKE.max_accel_mps2 * (1.0 + 1e-12)
    # travel time ≈ distance / speed plus a few time constants
    arrival = np.argmax(np.hypot(eta[:, 0] - 600.0, eta[:, 1] - 800.0) < 0.5)
    assert 2000 < arrival < 2000 + 4 * 200


def test_heading_takes_the_short_way_across_180_degrees() -> None:
    model = ReferenceModel(TANKER_LIKE)
    model.reset(np.array([0.0, 0.0, math.radians(170.0)]))
    eta, vel, _ = run(model, [0.0, 0.0, math.radians(-170.0)], 1500.0)
    assert np.all(np.abs(eta[:, 2]) >= math.radians(170.0) - 1e-9)  # never through 0°
    assert np.all(vel[:, 2] >= -1e-12)  # turning to starboard (clockwise) all the way
    assert eta[-1, 2] == pytest.approx(math.radians(-170.0), abs=1e-4)
    assert np.all((eta[:, 2] > -math.pi) & (eta[:, 2] <= math.pi))


def test_reset_is_bumpless_for_a_moving_vessel() -> None:
    model = ReferenceModel(TANKER_LIKE)
    eta0 = np.array([100.0, -50.0, 0.3])
    nu0 = np.array([0.3, -0.1, 0.002])  # NED velocity
    model.reset(eta0, nu0)
    ref = model.step(0.1, eta0)  # hold here
    np.testing.assert_allclose(ref.eta_d_ned, eta0 + 0.1 * nu0, atol=1e-4)
    np.testing.assert_allclose(ref.eta_dot_d_ned, nu0, atol=1e-4)
    assert np.all(np.abs(ref.eta_ddot_d_ned) < 1e-3)
    eta, vel, _ = run(model, eta0, 3000.0)
    np.testing.assert_allclose(vel[-1], 0.0, atol=1e-6)  # it stops and comes back smoothly
    np.testing.assert_allclose(eta[-1], eta0, atol=1e-3)


def test_first_step_without_reset_starts_at_the_setpoint() -> None:
    model = ReferenceModel(TANKER_LIKE)
    assert not model.initialised
    ref = model.step(0.1, np.array([5.0, 6.0, 7.0]))
    np.testing.assert_allclose(ref.eta_d_ned, [5.0, 6.0, 7.0 - 2 * math.pi], atol=1e-12)
    np.testing.assert_allclose(ref.eta_dot_d_ned, 0.0)


def test_state_dict_round_trip_is_json_and_exact() -> None:
    a = ReferenceModel(TANKER_LIKE)
    a.reset(np.zeros(3))
    for _ in range(50):
        a.step(1.0, np.array([50.0, 20.0, 1.0]))
    b = ReferenceModel(TANKER_LIKE)
    b.load_state_dict(json.loads(json.dumps(a.state_dict())))
    for _ in range(20):
        ra = a.step(1.0, np.array([50.0, 20.0, 1.0]))
        rb = b.step(1.0, np.array([50.0, 20.0, 1.0]))
    np.testing.assert_array_equal(ra.eta_d_ned, rb.eta_d_ned)
    np.testing.assert_array_equal(ra.eta_ddot_d_ned, rb.eta_ddot_d_ned)
    with pytest.raises(ValueError, match="invalid reference model state"):
        b.load_state_dict({"initialised": True})


def test_bad_input_raises_and_keeps_the_state() -> None:
    model = ReferenceModel(TANKER_LIKE)
    model.reset(np.zeros(3))
    model.step(1.0, np.array([10.0, 0.0, 0.0]))
    before = model.state_dict()
    for dt, setpoint in ((1.0, [np.nan, 0.0, 0.0]), (-1.0, [1.0, 0.0, 0.0]), (math.inf, [1.0, 0.0, 0.0]),
                         (1.0, [1.0, 2.0])):
        with pytest.raises(ValueError):
            model.step(dt, np.array(setpoint))
    assert model.state_dict() == before
    assert isinstance(model.step(0.0, np.array([10.0, 0.0, 0.0])), Reference)
    with pytest.raises(ValueError):
        ReferenceModelConfig(natural_period_s=(0.0, 1.0, 1.0))
    with pytest.raises(ValueError):
        ReferenceModelConfig(max_speed_mps=-1.0)


def test_defaults_are_froude_scaled_and_config_keys_are_validated() -> None:
    tanker = default_reference_config(SHUTTLE_TANKER)
    assert tanker.natural_period_s == (200.0, 200.0, 200.0)  # seed 003
    supply = default_reference_config(SUPPLY)
    cs2 = default_reference_config(BUILTIN_VESSELS["cybership2"])
    ratio = math.sqrt(SUPPLY.length_m / BUILTIN_VESSELS["cybership2"].length_m)
    assert supply.max_speed_mps / cs2.max_speed_mps == pytest.approx(ratio)
    assert supply.natural_period_s[0] / cs2.natural_period_s[0] == pytest.approx(ratio)
    config = reference_config_from_mapping({"max_speed_mps": 0.3, "max_yaw_rate_degps": 2.0,
                                            "natural_period_s": 120}, SUPPLY)
    assert config.max_speed_mps == 0.3
    assert config.max_yaw_rate_radps == pytest.approx(math.radians(2.0))
    assert config.natural_period_s == (120.0, 120.0, 120.0)
    with pytest.raises(ConfigError, match=r"guidance\.max_speed_mps"):
        reference_config_from_mapping({"max_speed_mps": -1}, SUPPLY)
    with pytest.raises(ConfigError, match=r"guidance\.speed"):
        reference_config_from_mapping({"speed": 1.0}, SUPPLY)
    with pytest.raises(ConfigError, match=r"guidance\.natural_period_s"):
        reference_config_from_mapping({"natural_period_s": [100, -1, 100]}, SUPPLY)


def test_the_entry_rule_is_read_and_resolved_per_controller() -> None:
    """``guidance.entry``: ``auto`` by default, ``stop`` or ``glide`` when given; the runtime resolves ``auto`` to a
    glide for an MRAC (its learning gate waits for the glide to end) and a rudder autopilot, to a stop otherwise."""
    assert reference_config_from_mapping(None, SUPPLY).entry == "auto"
    assert reference_config_from_mapping({"entry": "glide"}, SUPPLY).entry == "glide"
    with pytest.raises(ConfigError, match=r"guidance\.entry"):
        reference_config_from_mapping({"entry": "brake"}, SUPPLY)
    with pytest.raises(ValueError, match="entry"):
        ReferenceModelConfig(entry="brake")
    expected = {"supply-seed001": "stop", "cs2-seed000": "stop", "bluelady-seed004": "stop",
                "tanker-seed003": "glide", "mariner-seed002": "glide"}
    for name, entry in expected.items():
        simulation = build_simulation(load_scenario(builtin_scenario_path(name)))
        assert simulation.controller.entry == entry, name
    simulation = build_simulation(load_scenario(builtin_scenario_path("supply-seed001")),
                                  overrides={"guidance": {"entry": "glide"}})
    assert simulation.controller.entry == "glide"
