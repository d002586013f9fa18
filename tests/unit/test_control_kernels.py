"""The compiled control and guidance kernels against the plain Python/numpy code they replaced.

Each reference below is the replaced per-step code, kept here as the specification: the MRAC step on Python
floats with scipy's ``expm`` for the reference model (15), the PID's numpy products, and the reference
model's Python loop. The kernels agree with them to rounding (the MRAC's transition matrix is now a closed
form, the PID's products plain sums instead of BLAS), take the same arguments and raise the same errors.
"""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest
from scipy.linalg import expm

from dpbase.frames import ssa
from dpcontrol.control import MracController, default_mrac_config
from dpcontrol.control.base import ALL_DOFS, HEADING_ONLY
from dpcontrol.control.kernels import reference_transition
from dpcontrol.control.mrac import PARAMETER_NAMES, REFERENCE_MODEL_NAMES
from dpcontrol.control.pid import PidController, default_pid_config
from dpcontrol.guidance import Reference, ReferenceModel, ReferenceModelConfig
from dpcontrol.models.vessels import CYBERSHIP2, SHUTTLE_TANKER, SUPPLY

TOLERANCE = 1e-6  # the controllers' saturation tolerance (relative)


# ---------------------------------------------------------------------- the replaced code
class PlainMrac:
    """The MRAC step as it was: Python floats, the reference model advanced with ``expm`` (seed 003 (15)–(21))."""

    def __init__(self, controller: MracController) -> None:
        config = controller.config
        self.beta0 = [float(v) for v in config.beta0]
        self.beta1 = [float(v) for v in config.beta1]
        self.g12 = list(controller._g12)
        self.ratio = [g22 / g12 for g12, g22 in zip(controller._g12, controller._g22, strict=True)]
        self.config = config
        self.adapt = controller.adapting
        m, c = list(config.mass_nominal), list(config.damping_nominal)
        lo, hi = config.mass_bounds_factor
        dlo, dhi = config.damping_bounds_factor
        self.a2_bounds = ([lo * v for v in m], [hi * v for v in m])
        self.a1_bounds = ([dlo * v for v in c],
                          [max(dhi * v, mv * b) for v, mv, b in zip(c, m, self.beta1, strict=True)])
        self.a2, self.a1 = list(m), list(c)
        self.y_m, self.yd_m = [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]
        self.initialised = False
        self.command = [0.0, 0.0, 0.0]
        self.achieved: list[float] | None = None

    def step(self, dt: float, eta: list[float], nu: list[float], bias: list[float], r: list[float],
             mask: tuple[bool, bool, bool]) -> tuple[list[float], list[float], list[float], list[float]]:
        c, s = math.cos(eta[2]), math.sin(eta[2])
        y_m, yd_m, b0, b1 = self.y_m, self.yd_m, self.beta0, self.beta1
        if not self.initialised:
            y_m[:] = [eta[0], eta[1], ssa(eta[2])]
            yd_m[:] = [c * nu[0] - s * nu[1], s * nu[0] + c * nu[1], nu[2]]
            self.initialised = True
        d = [r[0] - y_m[0], r[1] - y_m[1], ssa(r[2] - y_m[2])]
        ydd = [b0[i] * d[i] - b1[i] * yd_m[i] for i in range(3)]
        dn, de = eta[0] - y_m[0], eta[1] - y_m[1]
        e_b = [c * dn + s * de, -s * dn + c * de, ssa(eta[2] - y_m[2])]
        yd_b = [c * yd_m[0] + s * yd_m[1], -s * yd_m[0] + c * yd_m[1], yd_m[2]]
        ydd_b = [c * ydd[0] + s * ydd[1], -s * ydd[0] + c * ydd[1], ydd[2]]
        coupling = self.config.coupling
        if "rotation" in coupling:  # ν̇_M = Rᵀÿ_M − S(r_M)ν_M
            ydd_b[0] += yd_m[2] * yd_b[1]
            ydd_b[1] -= yd_m[2] * yd_b[0]
        ed_b = [nu[i] - yd_b[i] for i in range(3)]
        z = [ydd_b[i] - b1[i] * ed_b[i] - b0[i] * e_b[i] for i in range(3)]
        mass = self.config.mass_matrix
        known = np.zeros(3)
        if "inertia" in coupling:  # Σ_{j≠i} M_ij z_j over the enabled DOFs
            known += (mass - np.diag(np.diag(mass))) @ np.where(mask, z, 0.0)
        if "coriolis" in coupling:  # C(ν_M)ν_M, p = Mν_M
            p = mass @ np.array(yd_b)
            known += [-p[1] * yd_b[2], p[0] * yd_b[2], p[1] * yd_b[0] - p[0] * yd_b[1]]
        if "damping" in coupling:
            known += self.config.damping_off_diagonal @ np.array(nu)
        tau = [self.a2[i] * z[i] + self.a1[i] * nu[i] + known[i] - bias[i] if mask[i] else 0.0 for i in range(3)]
        if self.adapt:
            self._adapt(dt, z, nu, yd_b, ydd_b, e_b, ed_b, mask)
        self.command = tau
        params = [*self.a2, *self.a1, *y_m]
        for i in range(3):
            a = np.zeros((3, 3))
            a[0, 1], a[1, 0], a[1, 1], a[1, 2] = 1.0, -b0[i], -b1[i], b0[i]
            e = expm(a * dt)
            target = y_m[i] + d[i]
            y_new = e[0, 0] * y_m[i] + e[0, 1] * yd_m[i] + e[0, 2] * target
            yd_m[i] = e[1, 0] * y_m[i] + e[1, 1] * yd_m[i] + e[1, 2] * target
            y_m[i] = y_new
        y_m[2] = ssa(y_m[2])
        return tau, e_b, ed_b, params

    def _adapt(self, dt: float, z: list[float], nu: list[float], yd_b: list[float], ydd_b: list[float],
               e_b: list[float], ed_b: list[float], mask: tuple[bool, bool, bool]) -> None:
        cfg = self.config
        sigma = cfg.leakage_per_s
        for i in range(3):
            if not mask[i]:
                continue
            if self.achieved is not None and \
                    abs(self.achieved[i] - self.command[i]) > TOLERANCE * (1.0 + abs(self.command[i])):
                continue
            s_bar = e_b[i] + self.ratio[i] * ed_b[i]
            excess = abs(s_bar) - cfg.dead_zone[i]
            signal = self.g12[i] * math.copysign(excess, s_bar) if excess > 0.0 else 0.0
            v2, v1 = (ydd_b[i], yd_b[i]) if cfg.regressor == "reference" else (z[i], nu[i])
            gm, gc = cfg.adaptation_gain_mass[i], cfg.adaptation_gain_damping[i]
            rate2 = -gm * v2 * signal if abs(ydd_b[i]) > cfg.accel_threshold[i] else 0.0
            rate1 = -gc * v1 * signal if abs(yd_b[i]) > cfg.velocity_threshold[i] else 0.0
            for values, gamma, rate, nominal in ((self.a2, gm, rate2, cfg.mass_nominal[i]),
                                                 (self.a1, gc, rate1, cfg.damping_nominal[i])):
                k = sigma * gamma
                if k > 0.0:
                    target = nominal + rate / k
                    values[i] = target + (values[i] - target) * math.exp(-k * dt)
                else:
                    values[i] += dt * rate
            self.a2[i] = min(max(self.a2[i], self.a2_bounds[0][i]), self.a2_bounds[1][i])
            ceiling = self.a1_bounds[1][i]
            if gc > 0.0 and cfg.damping_bound_kappa > 0.0:  # the frozen loop (23) keeps c + â₂β₁ − â₁ > 0
                ceiling = min(ceiling, self.a1_bounds[0][i] + cfg.damping_bound_kappa * self.beta1[i] * self.a2[i])
            self.a1[i] = min(max(self.a1[i], self.a1_bounds[0][i]), ceiling)


class PlainPid:
    """The PID step as it was: numpy products on 3-vectors (Fossen 2021 §12.2; seed 002 eq. (35))."""

    def __init__(self, controller: PidController) -> None:
        config = controller.config
        self.config = config
        self.tracking = 1.0 / config.tracking_time_constants_s()
        self.integral = np.zeros(3)
        self.command = np.zeros(3)
        self.achieved: np.ndarray | None = None
        self.duty = np.zeros(3)

    def step(self, dt: float, eta: np.ndarray, nu: np.ndarray, bias: np.ndarray | None, reference: Reference,
             mask: tuple[bool, bool, bool]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        cfg = self.config
        c, s = math.cos(eta[2]), math.sin(eta[2])
        rot_t = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
        e_b = rot_t @ (eta - reference.eta_d_ned)
        e_b[2] = ssa(eta[2] - reference.eta_d_ned[2])
        nu_d = rot_t @ reference.eta_dot_d_ned
        e_dot = nu - nu_d
        tau = -(cfg.kp @ e_b) - cfg.kd @ e_dot
        if cfg.mass_matrix is not None:
            tau += cfg.mass_matrix @ (rot_t @ reference.eta_ddot_d_ned)
        if cfg.damping_matrix is not None:
            tau += cfg.damping_matrix @ nu_d
        if cfg.integral_action == "integrator":
            increment = -(cfg.ki @ e_b) * dt
            if self.achieved is not None:
                shortfall = self.achieved - self.command
                for i in range(3):
                    side = 0.0
                    if abs(shortfall[i]) > TOLERANCE * (1.0 + abs(self.command[i])):
                        side = 1.0 if shortfall[i] > 0.0 else -1.0
                    alpha = 1.0 - math.exp(-dt * self.tracking[i]) if self.tracking[i] > 0.0 else 1.0
                    self.duty[i] += alpha * (side - self.duty[i])
                    if abs(self.duty[i]) > 0.5 and side * self.duty[i] > 0.0:
                        if increment[i] * self.duty[i] < 0.0:
                            increment[i] = 0.0
                        increment[i] += dt * self.tracking[i] * shortfall[i]
            self.integral += increment
            if cfg.integral_limit is not None:
                np.clip(self.integral, -np.array(cfg.integral_limit), cfg.integral_limit, out=self.integral)
            tau += self.integral
        elif bias is not None:
            tau -= bias
        for i in range(3):
            if not mask[i]:
                tau[i] = 0.0
                self.integral[i] = 0.0
                self.duty[i] = 0.0
        self.command = tau.copy()
        return tau, e_b, e_dot


def plain_reference_step(model: ReferenceModelConfig, state: dict[str, list[float]], dt: float,
                         r: np.ndarray) -> None:
    """The reference model's Python loop as it was (semi-implicit Euler sub-steps, limits inside)."""
    omega = [2.0 * math.pi / p for p in model.natural_period_s]
    zeta = model.relative_damping
    rate = max(max(2.0 * z * w, w) for z, w in zip(zeta, omega, strict=True))
    substeps = max(1, math.ceil(dt * rate / 0.2))
    h = dt / substeps
    rf_north, rf_east, rf_psi = state["rf"]
    x_north, x_east, x_psi = state["x"]
    v_north, v_east, v_psi = state["v"]
    a_north = a_east = a_psi = 0.0
    r_psi = ssa(float(r[2]))
    for _ in range(substeps):
        rf_north += h * omega[0] * (r[0] - rf_north)
        rf_east += h * omega[1] * (r[1] - rf_east)
        rf_psi = ssa(rf_psi + h * omega[2] * ssa(r_psi - rf_psi))
        e_north, e_east, e_psi = rf_north - x_north, rf_east - x_east, ssa(rf_psi - x_psi)
        vc_north, vc_east = omega[0] / (2.0 * zeta[0]) * e_north, omega[1] / (2.0 * zeta[1]) * e_east
        speed = math.hypot(vc_north, vc_east)
        limit = min(model.max_speed_mps, math.sqrt(model.max_accel_mps2 * math.hypot(e_north, e_east)))
        if speed > limit:
            vc_north, vc_east = vc_north * (limit / speed), vc_east * (limit / speed)
        vc_psi = omega[2] / (2.0 * zeta[2]) * e_psi
        limit = min(model.max_yaw_rate_radps, math.sqrt(model.max_yaw_accel_radps2 * abs(e_psi)))
        if abs(vc_psi) > limit:
            vc_psi = math.copysign(limit, vc_psi)
        a_north, a_east = 2.0 * zeta[0] * omega[0] * (vc_north - v_north), 2.0 * zeta[1] * omega[1] * (vc_east - v_east)
        accel = math.hypot(a_north, a_east)
        if accel > model.max_accel_mps2:
            a_north, a_east = a_north * (model.max_accel_mps2 / accel), a_east * (model.max_accel_mps2 / accel)
        a_psi = 2.0 * zeta[2] * omega[2] * (vc_psi - v_psi)
        if abs(a_psi) > model.max_yaw_accel_radps2:
            a_psi = math.copysign(model.max_yaw_accel_radps2, a_psi)
        v_north, v_east, v_psi = v_north + h * a_north, v_east + h * a_east, v_psi + h * a_psi
        x_north, x_east, x_psi = x_north + h * v_north, x_east + h * v_east, ssa(x_psi + h * v_psi)
    state.update(rf=[rf_north, rf_east, rf_psi], x=[x_north, x_east, x_psi], v=[v_north, v_east, v_psi],
                 a=[a_north, a_east, a_psi])


def _inputs(rng: np.random.Generator, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, Reference]:
    eta = np.array([rng.normal(0.0, 20.0), rng.normal(0.0, 20.0), rng.uniform(-math.pi, math.pi)])
    nu = rng.normal(0.0, [0.3, 0.3, 0.01])
    bias = rng.normal(0.0, [3e4, 3e4, 1e6])
    target = eta + rng.normal(0.0, [5.0, 5.0, 0.2]) if k % 50 < 40 else eta
    return eta, nu, bias, Reference(target, rng.normal(0.0, [0.2, 0.2, 0.005]), rng.normal(0.0, [1e-3, 1e-3, 1e-5]))


# ---------------------------------------------------------------------- MRAC
@pytest.mark.parametrize("zeta", [0.3, 0.999999, 1.0, 1.000001, 2.5])
@pytest.mark.parametrize("period_s", [15.0, 200.0])
@pytest.mark.parametrize("dt", [0.01, 0.1, 1.0, 10.0])
def test_reference_transition_is_the_matrix_exponential(zeta: float, period_s: float, dt: float) -> None:
    omega = 2.0 * math.pi / period_s
    a = np.array([[0.0, 1.0, 0.0], [-omega**2, -2.0 * zeta * omega, omega**2], [0.0, 0.0, 0.0]])
    e = expm(a * dt)  # the zero-order hold of (15) with the input as a third state
    p11, p12, p21, p22 = reference_transition(omega, zeta, dt)
    np.testing.assert_allclose([p11, p12, p21, p22], [e[0, 0], e[0, 1], e[1, 0], e[1, 1]], rtol=1e-12, atol=1e-15)
    # the model's equilibrium is y = r: the input column is (I − Φ)[1, 0]ᵀ
    np.testing.assert_allclose([1.0 - p11, -p21], [e[0, 2], e[1, 2]], rtol=1e-9, atol=1e-15)


@pytest.mark.parametrize("variant", ["default", "plant_leakage", "fixed", "underdamped"])
def test_mrac_step_matches_the_python_floats_it_replaced(variant: str) -> None:
    # (learning at once: the Python code predates the rest after an entry, tested in test_control_mrac)
    config = dataclasses.replace(default_mrac_config(SUPPLY), entry_rest_s=0.0)
    if variant == "plant_leakage":
        config = dataclasses.replace(config, regressor="plant", leakage_per_s=2e-8,  # σΓ₁₁dt ≈ 0.01
                                     adaptation_gain_damping=(1e3, 1e3, 1e6), dead_zone=(0.0, 0.0, 0.0))
    elif variant == "fixed":
        config = dataclasses.replace(config, adapt=False)
    elif variant == "underdamped":
        config = dataclasses.replace(config, relative_damping=(0.5, 0.8, 1.4), accel_threshold=(0.0, 0.0, 0.0))
    controller = MracController(config)
    plain = PlainMrac(controller)
    rng = np.random.default_rng(3)
    for k in range(400):
        eta, nu, bias, reference = _inputs(rng, k)
        mask = HEADING_ONLY if k % 100 > 80 else ALL_DOFS
        dt = 0.1 + 1e-4 * rng.standard_normal()  # a measured period
        # the same state for both (compared per step: no drift of the rounding differences)
        state = controller.state_dict()
        plain.a2, plain.a1 = state["mass_hat"], state["damping_hat"]
        plain.y_m, plain.yd_m, plain.initialised = state["y_m_n"], state["y_dot_m_n"], state["initialised"]
        plain.command, plain.achieved = state["last_command_b"], state["last_achieved_b"]
        out = controller.step(dt, eta, nu, bias, reference, dof_enabled=mask)
        tau, e_b, ed_b, params = plain.step(dt, eta.tolist(), nu.tolist(), bias.tolist(),
                                            reference.eta_d_ned.tolist(), mask)
        np.testing.assert_allclose(out.tau_b, tau, rtol=1e-12, atol=1e-9)
        np.testing.assert_allclose(out.error_b, e_b, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(out.velocity_error_b, ed_b, rtol=1e-12, atol=1e-14)
        assert out.parameters is not None
        assert list(out.parameters) == [*PARAMETER_NAMES, *REFERENCE_MODEL_NAMES]
        np.testing.assert_allclose(list(out.parameters.values()), params, rtol=1e-13, atol=1e-12)
        state = controller.state_dict()  # y_M, ẏ_M advanced by the closed form and by expm
        np.testing.assert_allclose(state["y_m_n"], plain.y_m, rtol=1e-13, atol=1e-12)
        np.testing.assert_allclose(state["y_dot_m_n"], plain.yd_m, rtol=1e-12, atol=1e-15)
        assert controller.mass_hat_floats == tuple(controller.mass_hat.tolist())
        controller.notify_achieved(out.tau_b * (0.5 if k % 30 == 0 else 1.0))  # short now and then
        if k % 150 == 149:
            controller.reset()
    assert (variant == "fixed") == (controller.mass_hat.tolist() == list(config.mass_nominal))


def test_mrac_takes_any_vectors_and_raises_the_same_errors() -> None:
    config = default_mrac_config(SHUTTLE_TANKER)
    rng = np.random.default_rng(1)
    eta, nu, bias, reference = _inputs(rng, 0)
    a, b = MracController(config), MracController(config)
    first = a.step(0.1, eta, nu, bias, reference)
    # lists, a read-only and a strided array, a mask given as a list: converted, the same numbers
    frozen = bias.copy()
    frozen.setflags(write=False)
    strided = np.repeat(nu, 2)[::2]
    second = b.step(0.1, eta.tolist(), strided, frozen, Reference(reference.eta_d_ned.tolist(), reference.eta_dot_d_ned,
                                                                   reference.eta_ddot_d_ned), dof_enabled=[1, 1, 1])
    np.testing.assert_array_equal(first.tau_b, second.tau_b)
    assert first.parameters == second.parameters
    before = a.state_dict()
    for kwargs, match in (({"eta_hat_ned": [np.nan, 0.0, 0.0]}, "eta_hat_ned"), ({"nu_hat_b": [1.0, 2.0]}, "nu_hat_b"),
                          ({"bias_hat_b": [0.0, np.inf, 0.0]}, "bias_hat_b"),
                          ({"tau_wind_ff_b": np.array([0.0, 0.0, np.nan])}, "tau_wind_ff_b"),
                          ({"reference": Reference.hold(np.array([0.0, np.nan, 0.0]))}, "reference.eta_d_ned"),
                          ({"dof_enabled": (True, False)}, "dof_enabled")):
        args = {"eta_hat_ned": eta, "nu_hat_b": nu, "bias_hat_b": bias, "reference": reference, **kwargs}
        wind = args.pop("tau_wind_ff_b", None)
        dofs = args.pop("dof_enabled", ALL_DOFS)
        with pytest.raises(ValueError, match=match):
            a.step(0.1, args["eta_hat_ned"], args["nu_hat_b"], args["bias_hat_b"], args["reference"],
                   dof_enabled=dofs, tau_wind_ff_b=wind)
    with pytest.raises(ValueError, match="dt_s"):
        a.step(0.0, eta, nu, bias, reference)
    assert a.state_dict() == before  # nothing changed by the refused steps


def test_mrac_state_round_trip_keeps_the_mass_floats() -> None:
    config = dataclasses.replace(default_mrac_config(SUPPLY), accel_threshold=(0.0, 0.0, 0.0), entry_rest_s=0.0)
    a = MracController(config)
    rng = np.random.default_rng(2)
    for k in range(50):
        out = a.step(0.1, *_inputs(rng, k))
        a.notify_achieved(out.tau_b)
    assert a.mass_hat_floats != tuple(config.mass_nominal)  # it adapted
    b = MracController(config)
    b.load_state_dict(json.loads(json.dumps(a.state_dict())))
    assert b.mass_hat_floats == a.mass_hat_floats == tuple(a.mass_hat.tolist())
    assert b.state_dict() == a.state_dict()
    inputs = _inputs(rng, 0)
    np.testing.assert_array_equal(a.step(0.1, *inputs).tau_b, b.step(0.1, *inputs).tau_b)
    b.reset_parameters()
    assert b.mass_hat_floats == tuple(config.mass_nominal)


# ---------------------------------------------------------------------- PID
@pytest.mark.parametrize("variant", ["integrator", "bias_feedforward", "limited", "no_feedforward", "fast_tracking"])
def test_pid_step_matches_the_numpy_code_it_replaced(variant: str) -> None:
    vessel = CYBERSHIP2 if variant == "bias_feedforward" else SUPPLY
    config = default_pid_config(vessel, "bias_feedforward" if variant == "bias_feedforward" else "integrator",
                                reference_feedforward=variant != "no_feedforward")
    if variant == "limited":
        config = dataclasses.replace(config, integral_limit=(2e4, 2e4, 5e5), antiwindup_time_constant_s=(8.0, 8.0, 5.0))
    elif variant == "fast_tracking":  # T_t of a few steps: the saturation duty crosses 1/2 in the saturated spells
        config = dataclasses.replace(config, antiwindup_time_constant_s=(0.3, 0.3, 0.3))
    controller = PidController(config)
    plain = PlainPid(controller)
    rng = np.random.default_rng(4)
    for k in range(400):
        state = controller.state_dict()  # the same state for both (compared per step)
        plain.integral, plain.command = np.array(state["integral_force_b"]), np.array(state["last_command_b"])
        plain.achieved = None if state["last_achieved_b"] is None else np.array(state["last_achieved_b"])
        plain.duty = np.array(state["saturation_duty"])
        eta, nu, bias, reference = _inputs(rng, k)
        if vessel is CYBERSHIP2:
            bias = bias * 1e-4
        mask = HEADING_ONLY if k % 100 > 80 else ALL_DOFS
        given = None if k % 7 == 0 else bias
        out = controller.step(0.1, eta, nu, given, reference, dof_enabled=mask)
        tau, e_b, e_dot = plain.step(0.1, eta, nu, given, reference, mask)
        scale = np.max(np.abs(tau)) + 1.0
        np.testing.assert_allclose(out.tau_b, tau, rtol=1e-13, atol=1e-14 * scale)  # sums vs BLAS: rounding
        np.testing.assert_allclose(out.error_b, e_b, rtol=1e-13, atol=1e-13)
        np.testing.assert_allclose(out.velocity_error_b, e_dot, rtol=1e-13, atol=1e-15)
        np.testing.assert_allclose(controller.integral_force_b, plain.integral, rtol=1e-13, atol=1e-14 * scale)
        assert out.parameters is None
        controller.notify_achieved(out.tau_b * (0.3 if k % 40 < 10 else 1.0))  # saturated for a while


def test_pid_takes_any_vectors_and_raises_the_same_errors() -> None:
    config = default_pid_config(SUPPLY, "integrator")
    rng = np.random.default_rng(6)
    eta, nu, bias, reference = _inputs(rng, 0)
    a, b = PidController(config), PidController(config)
    first = a.step(0.1, eta, nu, bias, reference)
    second = b.step(0.1, eta.tolist(), tuple(nu), bias, Reference(list(reference.eta_d_ned), reference.eta_dot_d_ned,
                                                                  reference.eta_ddot_d_ned), dof_enabled=[1, 1, 1])
    np.testing.assert_array_equal(first.tau_b, second.tau_b)
    before = a.state_dict()
    for args, match in (((0.1, [np.nan, 0, 0], nu, None), "eta_hat_ned"), ((0.1, eta, [1.0, 2.0], None), "nu_hat_b"),
                        ((0.1, eta, nu, np.array([np.inf, 0.0, 0.0])), "bias_hat_b"), ((-1.0, eta, nu, None), "dt_s")):
        with pytest.raises(ValueError, match=match):
            a.step(*args, reference)
    with pytest.raises(ValueError, match="tau_wind_ff_b"):
        a.step(0.1, eta, nu, None, reference, tau_wind_ff_b=[0.0, np.nan, 0.0])
    with pytest.raises(ValueError, match="dof_enabled"):
        a.step(0.1, eta, nu, None, reference, dof_enabled=(True,))
    with pytest.raises(IndexError):
        a.step(0.1, eta, nu, None, Reference(np.zeros(2), np.zeros(3), np.zeros(3)))
    assert a.state_dict() == before


# ---------------------------------------------------------------------- reference model
def test_reference_model_kernel_matches_the_python_loop() -> None:
    config = ReferenceModelConfig(natural_period_s=(60.0, 80.0, 40.0), relative_damping=(1.0, 0.8, 1.2),
                                  max_speed_mps=0.6, max_accel_mps2=0.02)
    model = ReferenceModel(config)
    rng = np.random.default_rng(8)
    model.reset(np.array([1.0, -2.0, 3.0]), np.array([0.1, 0.0, 0.01]))
    saved = model.state_dict()
    state = {"rf": saved["prefilter_n"], "x": saved["eta_d_n"], "v": saved["eta_dot_d_n"]}
    setpoint = np.zeros(3)
    for k in range(3000):
        if k % 300 == 0:  # far and near moves, headings across ±180°
            setpoint = np.array([rng.normal(0.0, 300.0), rng.normal(0.0, 30.0), rng.uniform(-4.0, 4.0)])
        dt = [0.1, 0.05, 1.0, 3.0][k % 4]  # several sub-step counts
        reference = model.step(dt, setpoint)
        plain_reference_step(config, state, dt, setpoint)
        np.testing.assert_allclose(reference.eta_d_ned, state["x"], rtol=1e-13, atol=1e-12)
        np.testing.assert_allclose(reference.eta_dot_d_ned, state["v"], rtol=1e-12, atol=1e-14)
        np.testing.assert_allclose(reference.eta_ddot_d_ned, state["a"], rtol=1e-12, atol=1e-14)
    current = model.current()
    current.eta_d_ned[0] += 1.0  # new arrays: the model's state is not changed through them
    assert model.current().eta_d_ned[0] == current.eta_d_ned[0] - 1.0
    # any sequence as the set-point, as before
    np.testing.assert_array_equal(ReferenceModel(config).step(0.1, [1, 2, 3]).eta_d_ned,
                                  ReferenceModel(config).step(0.1, np.array([1.0, 2.0, 3.0])).eta_d_ned)
