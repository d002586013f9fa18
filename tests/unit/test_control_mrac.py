"""MRAC-augmented PD (seed 003): the 12 h offloading case on surge, robustness, structure, state."""

from __future__ import annotations

import dataclasses
import functools
import json
import math
from typing import Any

import numpy as np
import pytest
from scipy.linalg import solve_continuous_lyapunov

from dpbase.schema import ConfigError
from dpcontrol.control import MracConfig, MracController, PositionController, default_mrac_config
from dpcontrol.control.factory import control_config_from_mapping, make_controller
from dpcontrol.control.mrac import PARAMETER_NAMES, REFERENCE_MODEL_NAMES, reference_excitation
from dpcontrol.guidance import Reference, ReferenceModel, default_reference_config
from dpcontrol.models.vessels import SHUTTLE_TANKER, SHUTTLE_TANKER_FULL, SUPPLY
from sim_plant.bench.offloading_case import OffloadingCase, default_offloading_mrac_config, simulate_offloading

SURGE = (True, False, False)


@functools.cache
def offloading(adaptive: bool):
    """Seed 003's 12 h loading, single-DOF surge, dt = 1 s (corrections ±20 m every 30 min)."""
    return simulate_offloading(OffloadingCase(dt_s=1.0), adaptive)


def test_mrac_tracks_its_reference_model_through_12_h_of_loading() -> None:
    result = offloading(True)
    # the mass ramps from ballast to full load (the last sample is 1 s before the end)
    assert result.mass_true_kg[-1] / result.mass_true_kg[0] == pytest.approx(
        SHUTTLE_TANKER_FULL.mass_matrix[0, 0] / SHUTTLE_TANKER.mass_matrix[0, 0], rel=1e-4)
    assert result.tracking_error_after(3600.0) < 0.5  # seed 003: < 0.5 m after a short transient
    assert np.max(result.overshoots_m()) < 0.3


def test_mrac_estimates_the_mass_of_the_loaded_tanker() -> None:
    result = offloading(True)
    assert abs(result.final_mass_error()) < 0.10
    assert result.mass_hat_kg[-1] > 2.0 * result.mass_hat_kg[0]  # it followed the loading


def test_fixed_pd_tuned_at_ballast_overshoots_more_and_more() -> None:
    result = offloading(False)
    overshoots = result.overshoots_m()
    first, last = overshoots[1:5].mean(), overshoots[-4:].mean()
    assert last > 1.0
    assert last > 5.0 * first
    assert np.all(np.diff(overshoots[4::4]) > 0.0)  # growing hour by hour
    assert result.tracking_error_after(3600.0) > 2.0  # what the MRAC keeps below 0.5 m
    assert np.all(result.mass_hat_kg == result.mass_hat_kg[0])  # parameters frozen


def test_no_parameter_drift_while_station_keeping_in_waves() -> None:
    """12 h at rest in 0.6 m of WF surge and 0.3 m GNSS noise: the mass estimate must not wander."""
    ballast = OffloadingCase()
    case = OffloadingCase(duration_s=3 * 3600.0, correction_m=0.0, wf_rms_m=0.6, noise_rms_m=0.3,
                          mass_end_kg=ballast.mass_start_kg, damping_end_nspm=ballast.damping_start_nspm)
    robust = simulate_offloading(case, True)
    assert np.max(np.abs(robust.mass_hat_kg / robust.mass_true_kg - 1.0)) < 0.02
    # the pure law (21) without gating or dead zone drifts (parameter drift) — what the safeguards prevent
    bare = dataclasses.replace(default_offloading_mrac_config(), dead_zone=(0.0, 0.0, 0.0),
                               accel_threshold=(0.0, 0.0, 0.0), velocity_threshold=(0.0, 0.0, 0.0))
    pure = simulate_offloading(case, True, dataclasses.replace(bare, regressor="plant"))
    assert pure.mass_hat_kg[-1] / pure.mass_true_kg[-1] > 1.2
    # the reference-model regressor has nothing to correlate with the noise: no drift even without them
    reference = simulate_offloading(case, True, bare)
    assert np.max(np.abs(reference.mass_hat_kg / reference.mass_true_kg - 1.0)) < 0.02


def test_lyapunov_matrix_and_pd_equivalence_of_eq_25() -> None:
    config = default_mrac_config(SUPPLY)
    controller = MracController(config, adapt=False)
    beta0, beta1 = config.beta0, config.beta1
    for i in range(3):
        A = np.array([[0.0, 1.0], [-beta0[i], -beta1[i]]])
        G = solve_continuous_lyapunov(A.T, -np.diag(config.lyapunov_q))
        np.testing.assert_allclose(G @ A + A.T @ G, -np.diag(config.lyapunov_q), atol=1e-9 * np.abs(G).max())
        assert np.all(np.linalg.eigvalsh(G) > 0.0)
        assert controller._g12[i] == pytest.approx(G[0, 1]) and controller._g22[i] == pytest.approx(G[1, 1])
    # u = −â₂β₁ė − â₂β₀e + â₂ÿ_M + â₁ẏ: a PD with P = â₂β₀ and D = â₂β₁ (eq. (25))
    eta = np.array([2.0, -1.0, 0.05])
    nu = np.array([0.1, 0.05, 0.001])
    controller.step(0.1, np.zeros(3), np.zeros(3), None, Reference.hold(np.zeros(3)))  # y_M = 0, ẏ_M = 0
    out = controller.step(0.1, eta, nu, None, Reference.hold(np.zeros(3)))
    y_m, yd_m = np.zeros(3), np.zeros(3)  # the model stayed at rest (r = y_M = 0)
    p, d = controller.equivalent_pd_gains()
    m = np.array(config.mass_nominal)
    c = np.array(config.damping_nominal)
    e = out.error_b
    ed = out.velocity_error_b
    ydd = beta0 * (np.zeros(3) - y_m) - beta1 * yd_m
    # the known coupling of the nominal model (the supply vessel's M₂₃, D₂₃, D₃₂; C(ν_M)ν_M = 0 at rest): the PD of
    # eq. (25) with the matrix M̂ = diag(â₂) + M_off, P = M̂β₀, D = M̂β₁, plus the off-diagonal damping
    m_off = config.mass_matrix - np.diag(m)
    assert abs(m_off[1, 2]) > 0.0
    z = ydd - beta1 * ed - beta0 * e
    np.testing.assert_allclose(out.tau_b, -p * e - d * ed + m * ydd + c * nu + m_off @ z
                               + config.damping_off_diagonal @ nu, rtol=1e-12)
    np.testing.assert_allclose(p, m * beta0)
    np.testing.assert_allclose(d, m * beta1)
    # without it (coupling: []): seed 003's diagonal law, a PD per DOF
    diagonal = MracController(dataclasses.replace(config, coupling=()), adapt=False)
    diagonal.step(0.1, np.zeros(3), np.zeros(3), None, Reference.hold(np.zeros(3)))
    out = diagonal.step(0.1, eta, nu, None, Reference.hold(np.zeros(3)))
    np.testing.assert_allclose(out.tau_b, -p * out.error_b - d * out.velocity_error_b + m * ydd + c * nu, rtol=1e-12)


def _ideal_surge_adaptation(config: MracConfig, guidance: ReferenceModel | None, hours: float = 4.0
                            ) -> tuple[MracController, float, Any]:
    """Noise-free surge plant of twice the nominal mass, 20 m corrections every 30 min; the MRAC is driven
    by the raw set-point (seed 003) or by the guidance's reference (the runtime)."""
    controller = MracController(config)
    m_true = 2.0 * config.mass_nominal[0]
    c_true = config.damping_nominal[0]
    y = yd = 0.0
    dt = 1.0
    out = None
    for k in range(round(hours * 3600)):
        target = np.array([20.0 * ((k // 1800) % 2), 0.0, 0.0])
        reference = Reference.hold(target) if guidance is None else guidance.step(dt, target)
        out = controller.step(dt, np.array([y, 0.0, 0.0]), np.array([yd, 0.0, 0.0]), None, reference,
                              dof_enabled=SURGE)
        u = out.tau_b[0]
        decay = math.exp(-c_true / m_true * dt)
        v_inf = u / c_true
        y += v_inf * dt + (yd - v_inf) * m_true / c_true * (1.0 - decay)
        yd = v_inf + (yd - v_inf) * decay
    return controller, m_true, out


def test_adaptation_converges_to_the_true_mass_in_ideal_conditions() -> None:
    """Reference model driven by the set-point steps (seed 003): â₂ → m."""
    config = default_mrac_config(SHUTTLE_TANKER, step_driven=True)
    controller, m_true, out = _ideal_surge_adaptation(config, None)
    assert controller.mass_hat[0] == pytest.approx(m_true, rel=0.03)
    assert controller.mass_hat[1] == config.mass_nominal[1]  # disabled DOFs do not adapt
    assert out.parameters is not None and set(out.parameters) == set(PARAMETER_NAMES) | set(REFERENCE_MODEL_NAMES)
    assert out.parameters["mass_surge_kg"] == controller.mass_hat[0]


def test_default_gains_adapt_through_the_guidance_as_fast_as_through_steps() -> None:
    """In the runtime the guidance drives the reference model: far smoother than a step (ÿ_M ≈ 10× smaller
    for the tanker), so gains designed for steps would learn ≈ 100× slower. The default tuning scales Γ and
    the gating by the excitation of a move through the vessel's guidance: after two corrections (1.5 h) the
    estimate has converged as in the step-driven case; with the step-driven gains it has not."""
    guidance_config = default_reference_config(SHUTTLE_TANKER)
    moves = reference_excitation(guidance_config, (200.0,) * 3, (1.0,) * 3, (20.8, 20.8, math.radians(10.0)))
    assert moves.peak_accel[0] < 0.2 * (2.0 * math.pi / 200.0) ** 2 * 20.8  # much smoother than a step
    tuned, m_true, _ = _ideal_surge_adaptation(default_mrac_config(SHUTTLE_TANKER),
                                               ReferenceModel(guidance_config), hours=1.5)
    step_gains, _, _ = _ideal_surge_adaptation(default_mrac_config(SHUTTLE_TANKER, step_driven=True),
                                               ReferenceModel(guidance_config), hours=1.5)
    assert tuned.mass_hat[0] == pytest.approx(m_true, rel=0.05)
    assert abs(step_gains.mass_hat[0] - m_true) > 0.2 * m_true


def test_saturation_freezes_adaptation_and_projection_bounds_the_estimates() -> None:
    config = dataclasses.replace(default_mrac_config(SUPPLY), entry_rest_s=0.0)  # (learning at once)
    controller = MracController(config)
    controller.step(0.1, np.zeros(3), np.zeros(3), None, Reference.hold(np.zeros(3)))
    ref = Reference.hold(np.array([50.0, -30.0, 1.0]))  # makes the reference model accelerate
    out = controller.step(0.1, np.array([5.0, 2.0, 0.1]), np.zeros(3), None, ref)
    controller.notify_achieved(0.5 * out.tau_b)  # allocator delivered half in every DOF
    before = controller.mass_hat
    controller.step(0.1, np.array([5.0, 2.0, 0.1]), np.zeros(3), None, ref)
    np.testing.assert_array_equal(controller.mass_hat, before)
    # huge persistent errors with full delivery: the estimates stay within the physical bounds
    for _ in range(2000):
        out = controller.step(0.1, np.array([500.0, -300.0, 3.0]), np.array([-5.0, 3.0, 0.1]), None, ref)
        controller.notify_achieved(out.tau_b)
    lo, hi = config.mass_bounds_factor
    nominal = np.array(config.mass_nominal)
    assert np.all(controller.mass_hat >= lo * nominal - 1e-6) and np.all(controller.mass_hat <= hi * nominal + 1e-6)
    assert np.any(np.isclose(controller.mass_hat, lo * nominal) | np.isclose(controller.mass_hat, hi * nominal))
    assert np.all(controller.damping_hat >= 0.0)


def test_an_estimate_on_its_bound_is_reported_and_suspension_restores_the_fixed_pd() -> None:
    config = dataclasses.replace(default_mrac_config(SUPPLY), entry_rest_s=0.0)  # (learning at once)
    controller = MracController(config)
    assert controller.mass_at_bound() is None
    state = controller.state_dict()
    lo, hi = config.mass_bounds_factor
    nominal = list(config.mass_nominal)
    controller.load_state_dict({**state, "mass_hat": [nominal[0], 0.9 * lo * nominal[1], nominal[2]]})  # projected
    assert controller.mass_at_bound() == 1
    controller.load_state_dict({**state, "mass_hat": [nominal[0], nominal[1], 0.999 * hi * nominal[2]]})
    assert controller.mass_at_bound() is None  # inside the bounds
    controller.load_state_dict({**state, "mass_hat": [hi * nominal[0], nominal[1], lo * nominal[2]]})
    assert controller.mass_at_bound() == 0  # the first DOF on a bound
    controller.suspend_adaptation()
    assert not controller.adapting and controller.mass_at_bound() is None
    np.testing.assert_array_equal(controller.mass_hat, nominal)
    # a move that adapts an unsuspended controller leaves the suspended one at the fixed PD of eq. (25)
    adapting = MracController(config)
    ref = Reference.hold(np.array([50.0, -30.0, 1.0]))
    for c in (controller, adapting):
        c.step(0.1, np.zeros(3), np.zeros(3), None, Reference.hold(np.zeros(3)))
        for _ in range(200):
            out = c.step(0.1, np.array([5.0, 2.0, 0.1]), np.zeros(3), None, ref)
            c.notify_achieved(out.tau_b)
    assert not np.allclose(adapting.mass_hat, nominal)
    np.testing.assert_array_equal(controller.mass_hat, nominal)
    assert controller.excited == (False, False, False)


def test_the_runtime_finds_the_mass_adaptation_through_the_controller_protocol() -> None:
    """The step supervises whatever ``mass_adaptation`` a controller offers (no test of its class)."""
    mrac = MracController(default_mrac_config(SUPPLY))
    assert isinstance(mrac, PositionController) and mrac.mass_adaptation is mrac
    assert mrac.mass_nominal == tuple(float(m) for m in default_mrac_config(SUPPLY).mass_nominal)
    pid = make_controller(control_config_from_mapping({"kind": "pid"}, SUPPLY))
    assert isinstance(pid, PositionController) and pid.mass_adaptation is None


def test_nothing_is_learnt_after_an_entry_until_the_reference_has_rested() -> None:
    config = default_mrac_config(SUPPLY)
    period = config.natural_period_s[0]
    assert config.entry_rest_s == pytest.approx(period)  # the default design: one reference-model period
    assert default_mrac_config(SUPPLY, step_driven=True).entry_rest_s == 0.0  # seed 003's step study as written
    controller = MracController(config)
    nominal = list(config.mass_nominal)
    moving = Reference.hold(np.array([20.0, -10.0, 0.3]))  # the reference model accelerates towards it
    here = Reference.hold(np.zeros(3))
    eta_behind = np.array([-0.5, 0.5, -0.02])  # errors that would teach the law
    dt = 1.0

    def run(reference: Reference, seconds: float) -> None:
        for _ in range(int(seconds / dt)):
            out = controller.step(dt, eta_behind, np.zeros(3), None, reference)
            controller.notify_achieved(out.tau_b)

    # the entry (the first step) is at the estimate; a glide and a move straight away teach nothing
    run(moving, 0.5 * period)
    np.testing.assert_array_equal(controller.mass_hat, nominal)
    assert controller.excited == (False, False, False)
    assert controller.state_dict()["rest_s"] == [0.0, 0.0, 0.0]
    # a reference at rest for one period (its gate closed: the model settles on the hold), then a move learns
    run(here, 6.0 * period)
    assert min(controller.state_dict()["rest_s"]) >= config.entry_rest_s
    run(moving, 0.5 * period)
    assert not np.allclose(controller.mass_hat, nominal)
    # a new entry (reset) waits again, keeping what was learnt; the rest survives a save and a restore
    learnt = controller.mass_hat
    controller.reset()
    run(moving, 0.5 * period)
    np.testing.assert_array_equal(controller.mass_hat, learnt)
    restored = MracController(config)
    restored.load_state_dict(json.loads(json.dumps(controller.state_dict())))
    assert restored.state_dict() == controller.state_dict()
    older = {k: v for k, v in controller.state_dict().items() if k != "rest_s"}  # saved before the rest existed
    restored.load_state_dict(older)
    assert restored.state_dict()["rest_s"] == [config.entry_rest_s] * 3  # counted as rested, as it learnt then
    with pytest.raises(ValueError, match="rest_s"):
        restored.load_state_dict({**controller.state_dict(), "rest_s": [0.0, -1.0, 0.0]})


def test_sigma_modification_leaks_back_to_nominal_exactly() -> None:
    config = dataclasses.replace(default_mrac_config(SUPPLY), leakage_per_s=1e-3, dead_zone=(1e9, 1e9, 1e9),
                                 accel_threshold=(0.0, 0.0, 0.0))
    controller = MracController(config)
    state = controller.state_dict()
    state["mass_hat"] = [2.0 * m for m in config.mass_nominal]
    controller.load_state_dict(state)
    ref = Reference.hold(np.array([10.0, 0.0, 0.0]))
    for _ in range(10):
        controller.step(1.0, np.zeros(3), np.zeros(3), None, ref)
    nominal = np.array(config.mass_nominal)
    # with the error inside the dead zone â̇ = −σΓ(â − â_nom): exponential decay at rate σΓ
    expected = nominal + nominal * np.exp(-1e-3 * np.array(config.adaptation_gain_mass) * 10.0)
    assert config.adaptation_gain_mass[0] * 1e-3 * 10.0 > 0.1  # a visible decay
    np.testing.assert_allclose(controller.mass_hat[0], expected[0], rtol=1e-9)


def test_reference_model_is_bumpless_heading_safe_and_restartable() -> None:
    config = default_mrac_config(SUPPLY)
    a = MracController(config)
    eta = np.array([10.0, 20.0, math.radians(179.0)])
    nu = np.array([0.2, 0.0, 0.0])
    out = a.step(0.1, eta, nu, np.array([1e4, 0.0, 0.0]), Reference.hold(eta))
    np.testing.assert_allclose(out.error_b, 0.0, atol=1e-12)  # starts on the vessel
    np.testing.assert_allclose(out.velocity_error_b, 0.0, atol=1e-12)
    # heading reference across ±180°: y_M turns the short way and stays wrapped
    target = np.array([10.0, 20.0, math.radians(-179.0)])
    for _ in range(3000):
        out = a.step(0.1, eta, np.zeros(3), None, Reference.hold(target))
    y_m, _ = a.reference_model_state_ned
    assert abs(y_m[2]) > math.radians(178.0)
    assert -math.pi < y_m[2] <= math.pi
    assert abs(out.error_b[2]) < math.radians(2.5)
    b = MracController(config)
    b.load_state_dict(json.loads(json.dumps(a.state_dict())))
    np.testing.assert_array_equal(a.step(0.1, eta, nu, None, Reference.hold(target)).tau_b,
                                  b.step(0.1, eta, nu, None, Reference.hold(target)).tau_b)
    a.reset()
    out = a.step(0.1, eta, nu, None, Reference.hold(target))
    np.testing.assert_allclose(out.error_b, 0.0, atol=1e-12)  # re-initialised at the estimate
    np.testing.assert_array_equal(a.mass_hat, b.mass_hat)  # parameters survive a reset
    a.reset_parameters()
    np.testing.assert_array_equal(a.mass_hat, config.mass_nominal)


def test_config_validation() -> None:
    config = control_config_from_mapping({"kind": "mrac", "natural_period_s": 150, "dead_zone": [0.1, 0.1, 0.01],
                                          "leakage_per_s": 1e-4}, SUPPLY)
    assert isinstance(config, MracConfig)
    assert config.natural_period_s == (150.0, 150.0, 150.0)
    assert config.dead_zone == (0.1, 0.1, 0.01)
    with pytest.raises(ConfigError, match=r"control\.dead_zone"):
        control_config_from_mapping({"kind": "mrac", "dead_zone": [1, 2]}, SUPPLY)
    with pytest.raises(ConfigError, match="control"):
        control_config_from_mapping({"kind": "mrac", "mass_bounds_factor": [2.0, 5.0]}, SUPPLY)
    with pytest.raises(ConfigError, match=r"control\.gamma"):
        control_config_from_mapping({"kind": "mrac", "gamma": 1.0}, SUPPLY)
    with pytest.raises(ValueError):
        MracConfig(mass_nominal=(1.0, -1.0, 1.0), damping_nominal=(0, 0, 0), adaptation_gain_mass=(1, 1, 1),
                   adaptation_gain_damping=(1, 1, 1))


def test_adapt_and_regressor_keys_select_the_fixed_pd_and_the_law() -> None:
    fixed = control_config_from_mapping({"kind": "mrac", "adapt": False, "reference": "model"}, SHUTTLE_TANKER)
    assert isinstance(fixed, MracConfig) and fixed.adapt is False and fixed.regressor == "reference"
    assert control_config_from_mapping({"kind": "mrac"}, SHUTTLE_TANKER).reference == "guidance"  # (the default)
    controller = make_controller(fixed)
    assert isinstance(controller, MracController) and not controller.adapting
    plant = control_config_from_mapping({"kind": "mrac", "regressor": "plant"}, SHUTTLE_TANKER)
    assert plant.adapt is True and plant.regressor == "plant"
    assert MracController(plant, adapt=False).adapting is False  # the constructor argument still wins
    with pytest.raises(ConfigError, match=r"control\.adapt"):
        control_config_from_mapping({"kind": "mrac", "adapt": "sometimes"}, SHUTTLE_TANKER)
    with pytest.raises(ConfigError, match=r"control\.regressor"):
        control_config_from_mapping({"kind": "mrac", "regressor": "z"}, SHUTTLE_TANKER)
    # the frozen controller really is eq. (25): a step response leaves the parameters untouched and the
    # output carries the reference-model pose for the tracking error e = y − y_M
    out = controller.step(1.0, np.zeros(3), np.zeros(3), None, Reference.hold(np.array([20.0, 0.0, 0.0])))
    for _ in range(300):
        out = controller.step(1.0, np.zeros(3), np.zeros(3), None, Reference.hold(np.array([20.0, 0.0, 0.0])))
    assert controller.mass_hat.tolist() == list(fixed.mass_nominal)
    assert out.parameters is not None and 0.0 < out.parameters["ref_model_north_m"] < 20.0
    assert not any(controller.excited)


def test_a_guided_mrac_tracks_the_guidance_reference_itself() -> None:
    """``reference: guidance``: y_M is η_d (one reference, no second lag) and, at nominal mass, the law is the PD
    of eq. (25) on e = η̂ − η_d with the guidance's acceleration fed forward: u = â₂(η̈_d − β₁ė − β₀e) + â₁ẏ."""
    config = dataclasses.replace(default_mrac_config(SUPPLY, reference="guidance"), adapt=False)
    controller = MracController(config)
    guidance = ReferenceModel(default_reference_config(SUPPLY))
    guidance.reset(np.zeros(3))
    eta = np.array([0.5, -0.2, 0.01])
    nu = np.array([0.02, -0.01, 0.0005])
    beta0, beta1 = config.beta0, config.beta1
    m = np.array(config.mass_nominal)
    c = np.array(config.damping_nominal)
    for _ in range(300):  # into a 10 m, 10° move: the reference accelerates
        reference = guidance.step(0.1, np.array([10.0, 5.0, math.radians(10.0)]))
        out = controller.step(0.1, eta, nu, None, reference)
    assert out.parameters is not None
    y_m = [out.parameters[name] for name in REFERENCE_MODEL_NAMES]
    np.testing.assert_allclose(y_m, reference.eta_d_ned, rtol=0, atol=1e-12)  # the pose the operator sees
    psi = eta[2]
    rot = np.array([[math.cos(psi), math.sin(psi), 0.0], [-math.sin(psi), math.cos(psi), 0.0], [0.0, 0.0, 1.0]])
    e = rot @ (eta - reference.eta_d_ned)
    ed = nu - rot @ reference.eta_dot_d_ned
    assert np.abs(reference.eta_ddot_d_ned).max() > 0.0
    np.testing.assert_allclose(out.error_b, e, rtol=1e-9, atol=1e-12)
    # with the known coupling of the nominal model: the body-frame acceleration of the reference
    # ν̇_M = Rᵀη̈_d − S(r_d)ν_M, M = diag(â₂) + M_off, the Coriolis force C(ν_M)ν_M and the off-diagonal damping
    nu_m = rot @ reference.eta_dot_d_ned
    r_m = reference.eta_dot_d_ned[2]
    accel = rot @ reference.eta_ddot_d_ned + np.array([r_m * nu_m[1], -r_m * nu_m[0], 0.0])
    z = accel - beta1 * ed - beta0 * e
    mass = config.mass_matrix
    p = mass @ nu_m
    coriolis = np.array([-p[1] * r_m, p[0] * r_m, p[1] * nu_m[0] - p[0] * nu_m[1]])
    np.testing.assert_allclose(out.tau_b, mass @ z + c * nu + config.damping_off_diagonal @ nu + coriolis, rtol=1e-9)
    # seed 003's diagonal law (coupling: []): u = â₂(Rᵀη̈_d − β₁ė − β₀e) + â₁ẏ per DOF
    diagonal = MracController(dataclasses.replace(config, coupling=()))
    out = diagonal.step(0.1, eta, nu, None, reference)
    np.testing.assert_allclose(out.tau_b, m * (rot @ reference.eta_ddot_d_ned - beta1 * ed - beta0 * e) + c * nu,
                               rtol=1e-9)


def test_guided_gains_come_from_the_guidance_move_and_the_key_is_checked() -> None:
    guided = default_mrac_config(SHUTTLE_TANKER, reference="guidance")
    model = default_mrac_config(SHUTTLE_TANKER)
    assert guided.reference == "guidance" and model.reference == "model"
    assert guided.adaptation_gain_mass != model.adaptation_gain_mass  # the excitation of its own reference
    assert control_config_from_mapping({"kind": "mrac", "reference": "guidance"}, SHUTTLE_TANKER).reference \
        == "guidance"
    with pytest.raises(ConfigError, match="reference"):
        control_config_from_mapping({"kind": "mrac", "reference": "setpoint"}, SHUTTLE_TANKER)
    tuned, m_true, _ = _ideal_surge_adaptation(guided, ReferenceModel(default_reference_config(SHUTTLE_TANKER)),
                                               hours=1.5)
    assert tuned.mass_hat[0] == pytest.approx(m_true, rel=0.05)  # learns as fast as the cascade's tuning


def _move(controller: MracController, guidance: ReferenceModel, target: np.ndarray, seconds: float,
          dt: float = 0.1) -> list[tuple[str, str, str]]:
    """Step a vessel at rest at the origin behind the guidance towards ``target``; the states after each step."""
    eta = np.zeros(3)
    states = []
    for _ in range(round(seconds / dt)):
        controller.step(dt, eta, np.zeros(3), None, guidance.step(dt, target))
        states.append(controller.adaptation_states())
    return states


def test_adaptation_states_read_adapting_while_excited_frozen_after_the_hold_suspended_and_off() -> None:
    """What the operator reads per DOF (status and monitor): the gate open within the hold → adapting, held for
    want of excitation → frozen once the hold has passed, stopped by the supervision → suspended, adapt false →
    off."""
    config = dataclasses.replace(default_mrac_config(SHUTTLE_TANKER), entry_rest_s=0.0)
    controller = MracController(config)
    guidance = ReferenceModel(default_reference_config(SHUTTLE_TANKER))
    guidance.reset(np.zeros(3))
    hold = controller.adapting_hold_s
    assert hold == (10.0, 10.0, 10.0)  # 0.05 of the tanker's 200 s reference-model period
    at_rest = _move(controller, guidance, np.zeros(3), 5.0)
    assert at_rest[-1] == ("frozen", "frozen", "frozen")  # adaptation on, nothing to learn from
    moving = _move(controller, guidance, np.array([20.0, 0.0, 0.0]), 300.0)
    assert ("adapting", "frozen", "frozen") in moving  # surge excited; sway and yaw never
    first = moving.index(("adapting", "frozen", "frozen"))
    # one move reads adapting from its start to its end: the gate's closure while ÿ_M crosses zero is bridged
    assert all(s[0] == "adapting" for s in moving[first:first + 1500])
    settled = _move(controller, guidance, np.array([20.0, 0.0, 0.0]), 600.0)
    assert settled[-1] == ("frozen", "frozen", "frozen")
    # the hold measured from the last step the gate was open
    last_open = max(i for i, s in enumerate(moving + settled) if s[0] == "adapting")
    assert any(s[0] == "frozen" for s in (moving + settled)[last_open + 1:last_open + round(hold[0] / 0.1) + 2])
    controller.suspend_adaptation()
    assert controller.adaptation_states() == ("suspended", "suspended", "suspended")
    assert _move(controller, guidance, np.zeros(3), 200.0)[-1] == ("suspended",) * 3  # until a restart
    fixed = MracController(config, adapt=False)
    assert _move(fixed, guidance, np.array([40.0, 0.0, 0.0]), 200.0)[-1] == ("off", "off", "off")
    assert MracController(dataclasses.replace(config, adapt=False)).adaptation_states() == ("off", "off", "off")


def test_a_new_entry_reads_frozen_until_excited_again() -> None:
    """reset (an entry into DP) forgets the last excitation: nothing has been learnt in this entry yet."""
    config = dataclasses.replace(default_mrac_config(SHUTTLE_TANKER), entry_rest_s=0.0)
    controller = MracController(config)
    guidance = ReferenceModel(default_reference_config(SHUTTLE_TANKER))
    guidance.reset(np.zeros(3))
    assert _move(controller, guidance, np.array([20.0, 0.0, 0.0]), 60.0)[-1][0] == "adapting"
    controller.reset()
    assert controller.adaptation_states() == ("frozen", "frozen", "frozen")


def test_the_adaptation_states_are_the_wire_vocabulary() -> None:
    from dpcontrol.control.base import ADAPTATION_STATES  # noqa: PLC0415
    from interfaces.zenoh.schemas import ADAPTATION_STATES as WIRE  # noqa: PLC0415

    assert ADAPTATION_STATES == WIRE


def _weather_move(config: MracConfig, *, offset_m: float, wave_m: float, force_change_n: float = 0.0
                  ) -> MracController:
    """The supply vessel's guided MRAC with the vessel on its reference but for what the weather does: a surge
    error of ``offset_m`` (the weather force the bias estimate has not taken up) plus ``wave_m`` of
    wave-frequency motion (8 s), at rest for two reference-model periods and through a 15 m surge move. During the
    move the weather force changes by ``force_change_n`` over one period (a turn swings it across the hull), the
    bias estimate follows with a lag of half a period and the error is the force not yet taken up over the PD's
    stiffness P = m β₀. Nothing about the mass is wrong: whatever the estimate learns is drift."""
    controller = MracController(config)
    guidance = ReferenceModel(default_reference_config(SUPPLY))
    guidance.reset(np.zeros(3))
    period = config.natural_period_s[0]
    stiffness = config.mass_nominal[0] * float(config.beta0[0])
    dt = 0.5
    target = np.zeros(3)
    bias = np.zeros(3)
    force = 0.0
    t = 0.0
    while t < 5.0 * period:
        if t >= 2.0 * period:
            target = np.array([15.0, 0.0, 0.0])
            force = force_change_n * min((t - 2.0 * period) / period, 1.0)
        bias[0] += (1.0 - math.exp(-dt / (0.5 * period))) * (force - bias[0])
        reference = guidance.step(dt, target)
        wave = wave_m * math.sin(2.0 * math.pi * t / 8.0)
        wave_rate = wave_m * 2.0 * math.pi / 8.0 * math.cos(2.0 * math.pi * t / 8.0)
        eta = reference.eta_d_ned + np.array([offset_m + (force - bias[0]) / stiffness + wave, 0.0, 0.0])
        nu = reference.eta_dot_d_ned + np.array([wave_rate, 0.0, 0.0])
        controller.step(dt, eta, nu, bias.copy(), reference)
        t += dt
    return controller


def test_the_dead_zone_measured_at_rest_keeps_the_weather_out_of_the_mass() -> None:
    """The error the weather causes while the reference rests — here an offset of 0.7 m and 0.3 m of wave motion,
    the supply vessel's station-keeping error in a 13.6 m/s wind — is what the law would take for inertia when the
    reference accelerates through it. The dead zone sized from its RMS at rest (3 σ, measured after one period of
    rest) keeps the estimate at the nominal mass; the fixed dead zone (0.02 % of L) lets it drift onto its
    bound."""
    config = default_mrac_config(SUPPLY, reference="guidance")
    assert config.dead_zone_noise_factor == 3.0
    measured = _weather_move(config, offset_m=0.7, wave_m=0.3)
    assert measured.mass_at_bound() is None
    assert abs(measured.mass_hat[0] / config.mass_nominal[0] - 1.0) < 0.01
    fixed = _weather_move(dataclasses.replace(config, dead_zone_noise_factor=0.0), offset_m=0.7, wave_m=0.3)
    assert fixed.mass_at_bound() == 0

    # the key, and the measured level is part of the saved state
    keyed = control_config_from_mapping({"kind": "mrac", "dead_zone_noise_factor": 0}, SUPPLY)
    assert keyed.dead_zone_noise_factor == 0  # type: ignore[union-attr]
    assert default_mrac_config(SUPPLY).dead_zone_noise_factor == 0.0  # seed 003's reference model: the fixed d₀
    with pytest.raises(ConfigError, match=r"control\.dead_zone_noise_factor"):
        control_config_from_mapping({"kind": "mrac", "dead_zone_noise_factor": -1}, SUPPLY)
    restored = MracController(config)
    restored.load_state_dict(json.loads(json.dumps(measured.state_dict())))
    assert restored.state_dict() == measured.state_dict()
    assert measured.state_dict()["dead_zone_mean_square"][0] > 0.5**2


def test_the_dead_zone_widens_with_the_weather_force_that_changes_in_a_move() -> None:
    """A move that swings the weather (−40 kN over one period, taken up by the bias estimate with a lag of half a
    period) with no error at rest: the dead zone's weather term |w − w̄|/P keeps the estimate off its bound; the
    fixed dead zone lets the law take the lag for inertia and runs it onto the bound. (The term lags the error at
    the start of the change — w̄ follows the ramp more slowly than the error rises — so some drift is left.)"""
    config = default_mrac_config(SUPPLY, reference="guidance")
    measured = _weather_move(config, offset_m=0.0, wave_m=0.0, force_change_n=-40e3)
    assert measured.mass_at_bound() is None
    assert measured.mass_hat[0] / config.mass_nominal[0] > 0.6
    fixed = _weather_move(dataclasses.replace(config, dead_zone_noise_factor=0.0), offset_m=0.0, wave_m=0.0,
                          force_change_n=-40e3)
    assert fixed.mass_at_bound() == 0


def _held_against_a_current(config: MracConfig, force_n: float, periods: float, *,
                            capacity_n: float = math.inf) -> tuple[MracController, np.ndarray]:
    """The supply vessel's surge (m ẍ + c ẋ = τ + w, exact state, no bias estimate) held at the origin against
    a constant force ``w`` for ``periods`` reference-model periods; the thrusters give at most ``capacity_n``
    (the achieved force is reported, as the allocator does). Returns the controller and the positions [m]."""
    controller = MracController(config)
    m, c = config.mass_nominal[0], config.damping_nominal[0]
    reference = Reference(np.zeros(3), np.zeros(3), np.zeros(3))
    dt = 0.5
    x = v = 0.0
    steps = int(periods * config.natural_period_s[0] / dt)
    positions = np.empty(steps)
    for k in range(steps):
        tau = controller.step(dt, np.array([x, 0.0, 0.0]), np.array([v, 0.0, 0.0]), None, reference,
                              dof_enabled=SURGE).tau_b
        delivered = float(np.clip(tau[0], -capacity_n, capacity_n))
        controller.notify_achieved(np.array([delivered, 0.0, 0.0]))
        v += dt * (delivered + force_n - c * v) / m
        x += dt * v
        positions[k] = x
    return controller, positions


def test_the_integrator_removes_the_offset_where_the_estimator_gives_no_bias() -> None:
    """Without a bias estimate (seed 004's Kalman–Bucy filter) the MRAC's PD leaves the offset w/P of a steady
    force; ``integral_action: integrator`` integrates it away (K_I = 0.1 ω_M P, the PID's rule) and holds no
    more than the thrusters deliver (conditional integration)."""
    config = default_mrac_config(SUPPLY, reference="guidance")
    force = 40e3
    stiffness = config.mass_nominal[0] * float(config.beta0[0])
    _, plain = _held_against_a_current(config, force, 8.0)
    assert plain[-1] == pytest.approx(force / stiffness, rel=0.02)  # the PD's offset (≈ 2.6 m)
    integrating = dataclasses.replace(config, integral_action="integrator")
    controller, held = _held_against_a_current(integrating, force, 8.0)
    assert abs(held[-1]) < 0.02 * force / stiffness
    assert controller.state_dict()["integral_force_b"][0] == pytest.approx(-force, rel=0.02)
    restored = MracController(integrating)
    restored.load_state_dict(json.loads(json.dumps(controller.state_dict())))
    assert restored.state_dict() == controller.state_dict()
    controller.reset()  # a new entry into DP starts the integral from zero, as the PID's
    assert controller.state_dict()["integral_force_b"] == [0.0, 0.0, 0.0]
    # thrusters that give 30 kN against 40 kN: the vessel drifts (59 m in 4 periods) and the PD alone asks for
    # more than they give. The integral is not wound further into the saturated side (that would be −K_I ∫e, far
    # below −w) but pulled back towards the force achieved (back-calculation; measured +774 kN against the PD's
    # −990 kN: the command −216 kN on its way to the 30 kN delivered)
    short, drifting = _held_against_a_current(integrating, force, 4.0, capacity_n=30e3)
    assert drifting[-1] > 10.0
    assert short.state_dict()["integral_force_b"][0] > 0.0
    with pytest.raises(ConfigError, match=r"control\.integral_action"):
        control_config_from_mapping({"kind": "mrac", "integral_action": "both"}, SUPPLY)
    with pytest.raises(ConfigError, match=r"control\.integral_ratio"):
        control_config_from_mapping({"kind": "mrac", "integral_ratio": 0}, SUPPLY)
