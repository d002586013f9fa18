"""Nonlinear PID / PD + bias feed-forward on the linear CyberShip II model (seed 000)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from dpbase.frames import rotation_nb
from dpbase.schema import ConfigError
from dpcontrol.control import ALL_DOFS, HEADING_ONLY, PidConfig, PidController, default_pid_config
from dpcontrol.control.factory import control_config_from_mapping, make_controller
from dpcontrol.control.mrac import MracController
from dpcontrol.control.pid import SEED000_KD, SEED000_KI, SEED000_KP, pole_placement_gains
from dpcontrol.guidance import Reference, ReferenceModel, default_reference_config
from dpcontrol.models.vessels import CYBERSHIP2, SUPPLY

BIAS_B = np.array([0.3, -0.2, 0.05])  # constant environmental force on the model [N, N, N·m]


def simulate(controller, *, bias_b=BIAS_B, bias_hat=None, duration_s=600.0, dt_s=0.1, step_at_s=40.0,
             target=(10.0, 0.0, 0.0), guidance=True, tau_max=None, antiwindup=True):
    """Linear CS2 (M ν̇ + D ν = τ + b, η̇ = R(ψ)ν) under a controller; 10 m step at 40 s (seed 000)."""
    M, D = CYBERSHIP2.mass_matrix, CYBERSHIP2.damping_matrix
    Minv = np.linalg.inv(M)
    model = ReferenceModel(default_reference_config(CYBERSHIP2))
    model.reset(np.zeros(3))
    eta = np.zeros(3)
    nu = np.zeros(3)
    steps = round(duration_s / dt_s)
    log = np.zeros((steps, 3))
    for k in range(steps):
        setpoint = np.array(target) if k * dt_s >= step_at_s else np.zeros(3)
        ref = model.step(dt_s, setpoint) if guidance else Reference.hold(setpoint)
        out = controller.step(dt_s, eta, nu, bias_hat, ref)
        tau = out.tau_b if tau_max is None else np.clip(out.tau_b, -tau_max, tau_max)
        if antiwindup:
            controller.notify_achieved(tau)
        h = dt_s / 10
        for _ in range(10):
            nu = nu + h * (Minv @ (tau + bias_b - D @ nu))
            eta = eta + h * (rotation_nb(eta[2]) @ nu)
        log[k] = eta
    return log


def test_cybership2_defaults_are_the_seed_000_gains() -> None:
    config = default_pid_config(CYBERSHIP2)
    np.testing.assert_array_equal(config.kp, SEED000_KP)
    np.testing.assert_array_equal(config.ki, SEED000_KI)
    np.testing.assert_array_equal(config.kd, SEED000_KD)


def test_pid_reaches_a_10_m_step_without_steady_state_error_against_a_constant_bias() -> None:
    log = simulate(PidController(default_pid_config(CYBERSHIP2, "integrator")))
    np.testing.assert_allclose(log[-1], [10.0, 0.0, 0.0], atol=1e-3)
    assert log[:, 0].max() < 10.0 + 0.05  # the guidance keeps the step smooth


def test_pd_with_bias_feedforward_reaches_the_step_without_steady_state_error() -> None:
    log = simulate(PidController(default_pid_config(CYBERSHIP2, "bias_feedforward")), bias_hat=BIAS_B)
    np.testing.assert_allclose(log[-1], [10.0, 0.0, 0.0], atol=1e-3)
    # without the compensation the same PD keeps an offset ≈ K_P⁻¹ b (so the test above can fail)
    log = simulate(PidController(default_pid_config(CYBERSHIP2, "bias_feedforward")), bias_hat=None)
    offset = np.linalg.solve(np.array(SEED000_KP), BIAS_B)
    np.testing.assert_allclose(log[-1], np.array([10.0, 0.0, 0.0]) + offset, atol=2e-3)
    assert abs(offset[0]) > 0.05


def test_anti_windup_with_the_achieved_force_limits_the_overshoot_after_saturation() -> None:
    tau_max = np.array([1.5, 1.5, 0.5])  # thrusters far weaker than a raw 10 m step asks for
    kwargs = {"guidance": False, "tau_max": tau_max, "duration_s": 300.0, "bias_b": np.zeros(3)}
    with_aw = simulate(PidController(default_pid_config(CYBERSHIP2)), **kwargs)
    without = simulate(PidController(default_pid_config(CYBERSHIP2)), antiwindup=False, **kwargs)
    overshoot_with = with_aw[:, 0].max() - 10.0
    overshoot_without = without[:, 0].max() - 10.0
    assert overshoot_without > 0.5
    assert overshoot_with < 0.5 * overshoot_without
    np.testing.assert_allclose(with_aw[-1, 0], 10.0, atol=1e-2)


def _wave_run(bias_y, *, wave_m: float, duration_s: float, antiwindup: bool = True) -> np.ndarray:
    """Linear CS2 holding the origin against a sway bias ``bias_y(t)`` [N] with sway thrust limited to ±0.5 N; the
    controller sees the position and velocity with a wave-frequency sway motion of ``wave_m`` at 0.8 rad/s (an
    estimator that filters no waves). Rows (t, sway, τ_I sway, commanded sway, delivered sway)."""
    M, D = CYBERSHIP2.mass_matrix, CYBERSHIP2.damping_matrix
    Minv = np.linalg.inv(M)
    tau_max = np.array([2.0, 0.5, 0.5])
    controller = PidController(default_pid_config(CYBERSHIP2))
    ref = Reference.hold(np.zeros(3))
    eta = np.zeros(3)
    nu = np.zeros(3)
    dt = 0.1
    log = np.zeros((round(duration_s / dt), 5))
    for k in range(log.shape[0]):
        t = k * dt
        wave = np.array([0.0, wave_m * math.sin(0.8 * t), 0.0])
        wave_rate = np.array([0.0, 0.8 * wave_m * math.cos(0.8 * t), 0.0])
        out = controller.step(dt, eta + wave, nu + wave_rate, None, ref)
        tau = np.clip(out.tau_b, -tau_max, tau_max)
        if antiwindup:
            controller.notify_achieved(tau)
        force = tau + np.array([0.0, bias_y(t), 0.0])
        for _ in range(10):
            nu = nu + dt / 10 * (Minv @ (force - D @ nu))
            eta = eta + dt / 10 * (rotation_nb(eta[2]) @ nu)
        log[k] = (t, eta[1], controller.integral_force_b[1], out.tau_b[1], tau[1])
    return log


def test_wave_frequency_saturation_does_not_bleed_the_integral() -> None:
    # a 0.25 N bias, half the 0.5 N the thrusters give, and a demand whose wave-frequency part (std 0.28 N) is cut
    # at the limit a third of the time: the low-frequency demand is within capability and the integral must
    # hold the vessel on station (anti-windup at every cut peak left her 0.039 m off, 16 % of the need short)
    log = _wave_run(lambda t: -0.25, wave_m=0.05, duration_s=600.0)
    last = log[:, 0] >= 400.0
    assert np.mean(np.abs(log[last, 3]) > 0.5) > 0.25  # the peaks are cut
    assert abs(log[last, 1].mean()) < 0.005
    assert log[last, 4].mean() == pytest.approx(0.25, rel=0.02)  # the need delivered on average
    assert log[last, 2].mean() >= 0.25  # (above the need: the clipped peaks' share of the mean)


def test_anti_windup_still_acts_when_the_low_frequency_demand_is_beyond_capability() -> None:
    # 0.6 N against 0.5 N until 150 s, then 0.25 N, with the same wave motion in the feedback: the integral must
    # not wind up while she is pushed off, and she must come back without overshoot once it is within reach
    bias = lambda t: -0.6 if t < 150.0 else -0.25  # noqa: E731
    log = _wave_run(bias, wave_m=0.05, duration_s=450.0)
    loaded = (log[:, 0] >= 50.0) & (log[:, 0] < 150.0)
    assert log[log[:, 0] < 150.0][-1, 1] < -1.5  # pushed off: the demand is beyond capability
    assert log[loaded, 2].max() < 0.5  # never beyond what the thrusters give
    free = _wave_run(bias, wave_m=0.05, duration_s=450.0, antiwindup=False)
    assert free[loaded, 2].max() > 10.0  # (what it is without anti-windup)
    after = log[:, 0] >= 150.0
    off = np.nonzero(np.abs(log[after, 1]) > 0.05)[0]
    assert log[after][off[-1], 0] - 150.0 < 120.0  # back within 5 cm for good (measured 90 s)
    assert log[after, 1].max() < 0.05  # no overshoot


def test_errors_are_rotated_into_the_vessel_parallel_frame() -> None:
    controller = PidController(default_pid_config(SUPPLY, "bias_feedforward", reference_feedforward=False))
    eta = np.array([1.0, 0.0, math.radians(90.0)])  # 1 m north of the set-point, heading east
    ref = Reference.hold(np.array([0.0, 0.0, math.radians(-179.0)]))
    out = controller.step(0.1, eta, np.zeros(3), None, ref)
    np.testing.assert_allclose(out.error_b, [0.0, -1.0, math.radians(-91.0)], atol=1e-12)  # north is to port
    np.testing.assert_allclose(out.tau_b, -controller.config.kp @ out.error_b, rtol=1e-12)
    # the heading error takes the short way: 90° → −179° is −91°, not +269°


def test_feedforward_wind_bias_and_dof_mask() -> None:
    config = default_pid_config(SUPPLY, "bias_feedforward")
    controller = PidController(config)
    ref = Reference(np.zeros(3), np.array([0.1, 0.0, 0.0]), np.array([0.001, 0.0, 0.0]))
    base = controller.step(0.1, np.zeros(3), np.zeros(3), None, ref).tau_b
    np.testing.assert_allclose(base, SUPPLY.mass_matrix @ [0.001, 0, 0] + SUPPLY.damping_matrix @ [0.1, 0, 0]
                               - config.kd @ [-0.1, 0, 0])
    bias = np.array([1e4, -2e4, 3e5])
    wind = np.array([-5e3, 1e3, 2e4])
    out = controller.step(0.1, np.zeros(3), np.zeros(3), bias, ref, tau_wind_ff_b=wind)
    np.testing.assert_allclose(out.tau_b, base - bias - wind)
    out = controller.step(0.1, np.zeros(3), np.zeros(3), bias, ref, dof_enabled=HEADING_ONLY)
    assert out.tau_b[0] == 0.0 and out.tau_b[1] == 0.0
    assert out.tau_b[2] == pytest.approx(base[2] - bias[2] - 0.0)
    with pytest.raises(ValueError):
        controller.step(0.1, np.zeros(3), np.zeros(3), None, ref, dof_enabled=(True, True))


def test_pole_placement_gives_the_asked_natural_frequency_and_damping() -> None:
    kp, kd, ki = pole_placement_gains(SUPPLY.mass_matrix, SUPPLY.damping_matrix, [100.0, 120.0, 90.0],
                                      [1.0, 0.8, 0.9])
    M, D = SUPPLY.mass_matrix, SUPPLY.damping_matrix
    A = np.block([[np.zeros((3, 3)), np.eye(3)], [-np.linalg.solve(M, kp), -np.linalg.solve(M, D + kd)]])
    poles = np.linalg.eigvals(A)
    expected = []
    for period, zeta in ((100.0, 1.0), (120.0, 0.8), (90.0, 0.9)):
        w = 2 * math.pi / period
        expected.extend(np.roots([1.0, 2 * zeta * w, w * w]))
    # same characteristic polynomial ⇔ same poles (robust to the ordering of repeated real parts)
    np.testing.assert_allclose(np.poly(poles).real, np.poly(np.array(expected)).real, rtol=1e-8, atol=1e-14)
    np.testing.assert_allclose(ki, 0.1 * kp @ np.diag([2 * math.pi / t for t in (100.0, 120.0, 90.0)]))


def test_state_dict_round_trip_continues_the_integrator() -> None:
    a = PidController(default_pid_config(CYBERSHIP2))
    ref = Reference.hold(np.array([1.0, 0.5, 0.1]))
    for _ in range(30):
        a.step(0.1, np.zeros(3), np.zeros(3), None, ref)
    a.notify_achieved(np.array([0.5, 0.5, 0.1]))
    b = PidController(default_pid_config(CYBERSHIP2))
    b.load_state_dict(json.loads(json.dumps(a.state_dict())))
    np.testing.assert_array_equal(a.step(0.1, np.zeros(3), np.zeros(3), None, ref).tau_b,
                                  b.step(0.1, np.zeros(3), np.zeros(3), None, ref).tau_b)
    assert np.any(a.integral_force_b != 0.0)
    assert np.any(a.saturation_duty != 0.0)  # the command of the step before was not achieved
    np.testing.assert_array_equal(a.saturation_duty, b.saturation_duty)
    old = a.state_dict()
    del old["saturation_duty"]  # a state saved before the duty existed
    b.load_state_dict(old)
    assert np.all(b.saturation_duty == 0.0)
    with pytest.raises(ValueError, match="saturation_duty"):
        b.load_state_dict({**old, "saturation_duty": [0.0, 1.5, 0.0]})
    a.reset()
    assert np.all(a.integral_force_b == 0.0)
    with pytest.raises(ValueError, match="invalid PID state"):
        b.load_state_dict({"integral_force_b": [0.0, float("nan"), 0.0], "last_command_b": [0, 0, 0]})


def test_bad_input_raises_clear_errors() -> None:
    controller = PidController(default_pid_config(CYBERSHIP2))
    ref = Reference.hold(np.zeros(3))
    for args in ((0.0, np.zeros(3), np.zeros(3)), (0.1, [np.nan, 0, 0], np.zeros(3)), (0.1, np.zeros(3), [1, 2])):
        with pytest.raises(ValueError):
            controller.step(*args, None, ref)
    with pytest.raises(ValueError):
        controller.notify_achieved(np.array([np.inf, 0.0, 0.0]))
    with pytest.raises(ValueError):
        PidConfig(kp=np.eye(2), kd=np.eye(3))
    with pytest.raises(ValueError):
        PidConfig(kp=np.eye(3), kd=np.eye(3), integral_action="both")  # type: ignore[arg-type]


def test_control_config_from_mapping_builds_either_controller() -> None:
    pid = make_controller(control_config_from_mapping({"kind": "pid", "integral_action": "bias_feedforward",
                                                       "natural_period_s": [80, 90, 70]}, SUPPLY))
    assert isinstance(pid, PidController)
    assert pid.config.integral_action == "bias_feedforward"
    kp, _, _ = pole_placement_gains(SUPPLY.mass_matrix, SUPPLY.damping_matrix, [80, 90, 70], [1, 1, 1])
    np.testing.assert_allclose(pid.config.kp, kp)
    explicit = control_config_from_mapping({"kind": "pid", "kp": np.eye(3).tolist(), "kd": np.eye(3).tolist(),
                                            "ki": np.zeros((3, 3)).tolist()}, SUPPLY)
    np.testing.assert_array_equal(explicit.kp, np.eye(3))
    assert isinstance(make_controller(control_config_from_mapping(None, SUPPLY)), MracController)
    with pytest.raises(ConfigError, match=r"control\.kind"):
        control_config_from_mapping({"kind": "lqr"}, SUPPLY)
    with pytest.raises(ConfigError, match=r"control\.kp"):
        control_config_from_mapping({"kind": "pid", "kp": [[1, 0, 0]]}, SUPPLY)
    with pytest.raises(ConfigError, match=r"control\.gain"):
        control_config_from_mapping({"kind": "pid", "gain": 1}, SUPPLY)
    with pytest.raises(ConfigError, match=r"control\.natural_period_s"):
        control_config_from_mapping({"kind": "pid", "natural_period_s": -5}, SUPPLY)
    assert ALL_DOFS == (True, True, True)


def test_a_setpoint_1_km_away_gives_no_force_spike_through_the_guidance() -> None:
    """The reference moves at the configured speed, so the force stays near M·a_max + D·v_max."""
    M, D = SUPPLY.mass_matrix, SUPPLY.damping_matrix
    config = default_reference_config(SUPPLY)
    controller = PidController(default_pid_config(SUPPLY, "bias_feedforward"))
    model = ReferenceModel(config)
    model.reset(np.zeros(3))
    Minv = np.linalg.inv(M)
    eta = np.zeros(3)
    nu = np.zeros(3)
    peak = np.zeros(3)
    for _ in range(3000):
        ref = model.step(1.0, np.array([1000.0, 0.0, 0.0]))
        tau = controller.step(1.0, eta, nu, None, ref).tau_b
        peak = np.maximum(peak, np.abs(tau))
        for _ in range(10):
            nu = nu + 0.1 * (Minv @ (tau - D @ nu))
            eta = eta + 0.1 * (rotation_nb(eta[2]) @ nu)
    steady = M[0, 0] * config.max_accel_mps2 + D[0, 0] * config.max_speed_mps
    assert peak[0] < 1.5 * steady
    assert eta[0] == pytest.approx(1000.0, abs=0.5)
    # a raw 1 km step (no guidance) would ask K_P · 1000 m at once
    raw = PidController(default_pid_config(SUPPLY, "bias_feedforward")).step(
        1.0, np.zeros(3), np.zeros(3), None, Reference.hold(np.array([1000.0, 0.0, 0.0]))).tau_b
    assert abs(raw[0]) > 50.0 * steady
