"""Compiled plant kernels (sim_plant.kernels) against the plain formulas they replaced, on seeded draws.

The vessel and drive kernels perform the same floating-point operations in the same order as the
plain Python they replaced, so they must agree bit for bit; the wave sums add their terms in another
order than numpy's matrix-vector product (last bits) and the mass matrix is inverted by cofactors
instead of LU (last bits).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from dpbase.frames import ssa
from dpcontrol.models.thrusters import ThrusterSpec
from dpcontrol.models.vessels import BUILTIN_VESSELS, MARINER, SHUTTLE_TANKER, SUPPLY
from sim_plant.drives import ThrusterCommand, ThrusterDrives
from sim_plant.environment.rao import HullDimensions, motion_raos
from sim_plant.environment.spectra import SpectralProcess, gauss_markov_process, realise_waves
from sim_plant.environment.waves import _BETA_GRID, _BETA_STEPS, WaveField
from sim_plant.kernels import (
    DP_PARAMETERS,
    MANOEUVRING_PARAMETERS,
    NO_DRIVE,
    W_B,
    W_PSI,
    W_X,
    W_Y,
    drives_force,
    plant_substep,
    rk4_step,
    vessel_derivative,
    wave_sums,
)
from sim_plant.vessel import DpVesselModel, ManoeuvringVesselModel, vessel_model

DP_VESSELS = [v for v in BUILTIN_VESSELS.values() if v.name != "mariner"]


# -- plain reference formulas (the Python the kernels replaced) -------------------------------------
def _dp_reference(p: np.ndarray):
    q = dict(zip(DP_PARAMETERS, p.tolist(), strict=True))
    m, mxg = q["m"], q["mxg"]
    a11, a12, a13, a21, a22, a23, a31, a32 = (q[k] for k in ("a11", "a12", "a13", "a21", "a22", "a23", "a31", "a32"))
    d11, d12, d13, d21, d22, d23, d31, d32, d33 = (q[f"d{i}{j}"] for i in (1, 2, 3) for j in (1, 2, 3))
    q1, q2, q3 = q["q1"], q["q2"], q["q3"]
    i11, i12, i13, i21, i22, i23, i31, i32, i33 = (q[f"i{i}{j}"] for i in (1, 2, 3) for j in (1, 2, 3))

    def f(psi, u, v, r, tx, ty, tn, cn, ce, rudder):
        c, s = math.cos(psi), math.sin(psi)
        uc, vc = c * cn + s * ce, c * ce - s * cn
        ur, vr = u - uc, v - vc
        p2 = m * v + mxg * r
        pa1 = a11 * ur + a12 * vr + a13 * r
        pa2 = a21 * ur + a22 * vr + a23 * r
        dc1, dc2 = r * vc, -r * uc
        f1 = (tx + p2 * r + pa2 * r - (d11 * ur + d12 * vr + d13 * r) - q1 * abs(ur) * ur
              + a11 * dc1 + a12 * dc2)
        f2 = (ty - m * u * r - pa1 * r - (d21 * ur + d22 * vr + d23 * r) - q2 * abs(vr) * vr
              + a21 * dc1 + a22 * dc2)
        f3 = (tn - (p2 * u - m * u * v) - (pa2 * ur - pa1 * vr) - (d31 * ur + d32 * vr + d33 * r)
              - q3 * abs(r) * r + a31 * dc1 + a32 * dc2)
        return (c * u - s * v, s * u + c * v, r, i11 * f1 + i12 * f2 + i13 * f3, i21 * f1 + i22 * f2 + i23 * f3,
                i31 * f1 + i32 * f2 + i33 * f3)

    return f


def _manoeuvring_reference(p: np.ndarray):
    q = dict(zip(MANOEUVRING_PARAMETERS, p.tolist(), strict=True))

    def f(psi, u, v, r, tx, ty, tn, cn, ce, rudder):
        c, s = math.cos(psi), math.sin(psi)
        uc, vc = c * cn + s * ce, c * ce - s * cn
        vr = v - vc
        big_u = math.sqrt(q["u0"] * q["u0"] + vr * vr)
        vp, rp = vr / big_u, r * q["length"] / big_u
        y = (q["y_v"] * vp + q["y_r"] * rp + q["y_d"] * rudder) * q["qy"] * big_u * big_u + ty
        n = (q["n_v"] * vp + q["n_r"] * rp + q["n_d"] * rudder) * q["qn"] * big_u * big_u + tn
        vr_dot = (q["m33"] * y - q["m23"] * n) / q["det"]
        r_dot = (q["m22"] * n - q["m32"] * y) / q["det"]
        ug = q["u0"] + uc
        return (c * ug - s * v, s * ug + c * v, r, r * vc, vr_dot - r * uc, r_dot)

    return f


def _rk4_reference(f, x: list[float], h: float, *a: float) -> list[float]:
    n, e, p, u, v, r = x
    k1 = f(p, u, v, r, *a)
    h2 = 0.5 * h
    k2 = f(p + h2 * k1[2], u + h2 * k1[3], v + h2 * k1[4], r + h2 * k1[5], *a)
    k3 = f(p + h2 * k2[2], u + h2 * k2[3], v + h2 * k2[4], r + h2 * k2[5], *a)
    k4 = f(p + h * k3[2], u + h * k3[3], v + h * k3[4], r + h * k3[5], *a)
    h6 = h / 6.0
    return [n + h6 * (k1[0] + 2.0 * (k2[0] + k3[0]) + k4[0]), e + h6 * (k1[1] + 2.0 * (k2[1] + k3[1]) + k4[1]),
            ssa(p + h6 * (k1[2] + 2.0 * (k2[2] + k3[2]) + k4[2])), u + h6 * (k1[3] + 2.0 * (k2[3] + k3[3]) + k4[3]),
            v + h6 * (k1[4] + 2.0 * (k2[4] + k3[4]) + k4[4]), r + h6 * (k1[5] + 2.0 * (k2[5] + k3[5]) + k4[5])]


class _ReferenceDrives:
    """The drive model in plain Python floats (sim_plant.drives before the kernels)."""

    def __init__(self, specs, timeout_s: float) -> None:
        self.specs = specs
        self.timeout = timeout_s
        self.thrust = [0.0] * len(specs)
        self.angle = [s.angle_rad if s.kind in ("tunnel", "propeller") else 0.0 for s in specs]
        self.target_thrust = [0.0] * len(specs)
        self.target_angle = list(self.angle)
        self.t_cmd = [-math.inf] * len(specs)
        self.failure = [None] * len(specs)
        self.lost = False
        self.alpha_h = -1.0
        self.alpha = [0.0] * len(specs)

    def command(self, t, commands) -> None:
        for i, s in enumerate(self.specs):
            cmd = commands.get(s.name)
            if cmd is None:
                continue
            self.target_thrust[i] = min(s.max_thrust_n, max(s.min_thrust_n, cmd.thrust_n)) if cmd.enabled else 0.0
            if cmd.azimuth_rad is not None and s.kind == "azimuth":
                self.target_angle[i] = ssa(cmd.azimuth_rad)
            elif cmd.azimuth_rad is not None and s.kind == "propeller_rudder":
                self.target_angle[i] = min(s.rudder_max_angle_rad, max(-s.rudder_max_angle_rad, cmd.azimuth_rad))
            self.t_cmd[i] = t
        self.lost = False

    def update(self, t: float, h: float) -> None:
        if abs(h - self.alpha_h) > 1e-12 * h:
            self.alpha = [-math.expm1(-h / s.time_constant_s) for s in self.specs]
            self.alpha_h = h
        for i, s in enumerate(self.specs):
            if self.failure[i] == "stuck":
                continue
            stale = self.failure[i] == "not_ready" or self.lost or t - self.t_cmd[i] > self.timeout
            target = 0.0 if stale else self.target_thrust[i]
            delta = (target - self.thrust[i]) * self.alpha[i]
            limit = s.thrust_rate_limit_nps * h
            self.thrust[i] += min(limit, max(-limit, delta))
            if stale or s.kind in ("tunnel", "propeller"):
                continue
            rate = math.inf if s.azimuth_rate_limit_radps is None else s.azimuth_rate_limit_radps
            azimuth = s.kind == "azimuth"
            err = ssa(self.target_angle[i] - self.angle[i]) if azimuth else self.target_angle[i] - self.angle[i]
            err = min(rate * h, max(-rate * h, err))
            self.angle[i] = ssa(self.angle[i] + err) if azimuth else self.angle[i] + err

    def delivered(self, i: int) -> float:
        return {"zero": 0.0, "wrong_sign": -self.thrust[i]}.get(self.failure[i], self.thrust[i])

    def force_b(self, skip: int = -1) -> tuple[float, float, float]:
        fx_sum = fy_sum = n_sum = 0.0
        for i, s in enumerate(self.specs):
            t = self.delivered(i)
            if i == skip or t == 0.0:
                continue
            if s.kind == "azimuth":
                fx, fy = t * math.cos(self.angle[i]), t * math.sin(self.angle[i])
            elif s.kind == "propeller_rudder":
                fx, fy = t, (t * s.rudder_lift_per_rad * self.angle[i] if t > 0.0 else 0.0)
            else:
                fx, fy = t * math.cos(s.angle_rad), t * math.sin(s.angle_rad)
            fx_sum += fx
            fy_sum += fy
            n_sum += s.x_m * fy - s.y_m * fx
        return fx_sum, fy_sum, n_sum


def _random_state(rng: np.random.Generator, length_m: float) -> list[float]:
    scale = 0.02 * length_m
    return [*rng.normal(0.0, 10.0, 2).tolist(), float(rng.uniform(-math.pi, math.pi)),
            *rng.normal(0.0, scale, 2).tolist(), float(rng.normal(0.0, scale / length_m))]


# -- vessel ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("vessel", DP_VESSELS, ids=lambda v: v.name)
def test_dp_parameters_hold_the_model_matrices(vessel) -> None:
    model = DpVesselModel(vessel)
    for factor in (1.0, 1.7, 2.66):
        model.set_mass_factor(factor)
        q = dict(zip(DP_PARAMETERS, model.params.tolist(), strict=True))
        assert (q["m"], q["mxg"]) == (model.mass_kg, model.mass_kg * model.xg_m)
        m_a = model.added_mass_matrix
        np.testing.assert_array_equal(m_a, m_a.T)
        assert [q[f"a{i}{j}"] for i, j in ((1, 1), (1, 2), (1, 3), (2, 1), (2, 2), (2, 3), (3, 1), (3, 2))] == \
            [m_a[i - 1, j - 1] for i, j in ((1, 1), (1, 2), (1, 3), (2, 1), (2, 2), (2, 3), (3, 1), (3, 2))]
        assert [q[f"d{i}{j}"] for i in (1, 2, 3) for j in (1, 2, 3)] == model.damping_matrix.ravel().tolist()
        assert [q["q1"], q["q2"], q["q3"]] == list(model.quadratic_damping)
        inverse = np.array([q[f"i{i}{j}"] for i in (1, 2, 3) for j in (1, 2, 3)]).reshape(3, 3)
        reference = np.linalg.inv(model.mass_matrix)
        np.testing.assert_allclose(inverse, reference, rtol=0.0, atol=1e-14 * np.abs(reference).max())


@pytest.mark.parametrize("vessel", [*DP_VESSELS, MARINER], ids=lambda v: v.name)
def test_vessel_derivative_and_rk4_step_are_the_plain_formulas(vessel) -> None:
    rng = np.random.default_rng(11)
    model = vessel_model(vessel)
    reference = _manoeuvring_reference if isinstance(model, ManoeuvringVesselModel) else _dp_reference
    for factor in (1.0, 2.3):
        model.set_mass_factor(factor)
        f = reference(model.params)
        for _ in range(50):
            x = _random_state(rng, vessel.length_m)
            if isinstance(model, ManoeuvringVesselModel):
                x[3] = model.surge_speed_mps
            force = 1e-3 * float(np.abs(model.params).max())
            inputs = (*rng.normal(0.0, force, 3).tolist(), *rng.normal(0.0, 0.5, 2).tolist(),
                      float(rng.uniform(-0.5, 0.5)))
            assert vessel_derivative(model.kind, model.params, *x[2:], *inputs) == f(*x[2:], *inputs)
            h = float(rng.uniform(0.01, 0.5))
            state = np.array(x)
            rk4_step(state, model.kind, model.params, h, *inputs)
            assert state.tolist() == _rk4_reference(f, x, h, *inputs)


# -- thruster drives ------------------------------------------------------------------------------
SPECS = [
    ThrusterSpec("tunnel", "tunnel", x_m=30.0, y_m=0.0, max_thrust_n=100.0, min_thrust_n=-80.0,
                 thrust_rate_limit_nps=1000.0, time_constant_s=2.0, angle_rad=math.pi / 2),
    ThrusterSpec("slow", "propeller", x_m=-10.0, y_m=3.0, max_thrust_n=100.0, min_thrust_n=-100.0,
                 thrust_rate_limit_nps=5.0, time_constant_s=0.5),
    ThrusterSpec("azi", "azimuth", x_m=-30.0, y_m=-4.0, max_thrust_n=200.0, min_thrust_n=0.0,
                 thrust_rate_limit_nps=1000.0, time_constant_s=0.5, azimuth_rate_limit_radps=math.radians(10.0)),
    ThrusterSpec("main", "propeller_rudder", x_m=-40.0, y_m=0.0, max_thrust_n=300.0, min_thrust_n=-150.0,
                 thrust_rate_limit_nps=1000.0, time_constant_s=0.5, azimuth_rate_limit_radps=math.radians(5.0),
                 rudder_max_angle_rad=math.radians(35.0), rudder_lift_per_rad=1.2),
]


@pytest.mark.parametrize("specs", [SPECS, *(v.thrusters for v in BUILTIN_VESSELS.values())],
                         ids=["all_kinds", *BUILTIN_VESSELS])
def test_drive_kernels_are_the_plain_drive_model(specs) -> None:
    """Random commands, failures, command losses and substep lengths: thrust, angle, force and feedback
    of the kernels equal the plain Python drive model bit for bit."""
    rng = np.random.default_rng(7)
    drives = ThrusterDrives(specs, timeout_s=0.7)
    reference = _ReferenceDrives(specs, timeout_s=0.7)
    t = 0.0
    for step in range(400):
        if rng.uniform() < 0.3:
            commands = {s.name: ThrusterCommand(float(rng.uniform(-1.2, 1.2)) * s.max_thrust_n,
                                                float(rng.uniform(-4.0, 4.0)) if rng.uniform() < 0.8 else None,
                                                bool(rng.uniform() < 0.9))
                        for s in specs if rng.uniform() < 0.8}
            drives.command(t, commands)
            reference.command(t, commands)
        if rng.uniform() < 0.02:
            drives.command_lost(t)
            reference.lost = True
        if rng.uniform() < 0.05:
            i = int(rng.integers(len(specs)))
            failure = [None, None, "stuck", "zero", "wrong_sign", "not_ready"][int(rng.integers(6))]
            drives.set_failure(specs[i].name, failure)
            reference.failure[i] = failure
        h = 0.05 if step % 7 else float(rng.uniform(0.001, 0.3))  # mostly the plant step, sometimes not
        drives.update(t, h)
        reference.update(t, h)
        t += h
        assert drives.thrust.tolist() == reference.thrust
        assert drives.angle.tolist() == reference.angle
        skip = int(rng.integers(-1, len(specs)))
        assert drives.force_b(skip) == reference.force_b(skip)
        feedback = drives.feedback()
        assert [f.thrust_n for f in feedback] == [reference.delivered(i) for i in range(len(specs))]
        assert [f.azimuth_rad for f in feedback] == [ssa(a) for a in reference.angle]


def test_plant_substep_is_force_then_rk4_then_drives() -> None:
    rng = np.random.default_rng(3)
    model = DpVesselModel(SUPPLY)
    drives = ThrusterDrives(SUPPLY.thrusters)
    drives.command(0.0, {s.name: ThrusterCommand(0.5 * s.max_thrust_n, 0.3) for s in SUPPLY.thrusters})
    twin = ThrusterDrives(SUPPLY.thrusters)
    twin.command(0.0, {s.name: ThrusterCommand(0.5 * s.max_thrust_n, 0.3) for s in SUPPLY.thrusters})
    x = np.array(_random_state(rng, SUPPLY.length_m))
    y = x.copy()
    env = rng.normal(0.0, 1e4, 3).tolist()
    current = (0.3, -0.2)
    for k in range(100):
        t = 0.05 * k
        plant_substep(x, model.kind, model.params, t, 0.05, *env, *current, *drives.arrays, NO_DRIVE)
        tx, ty, tn = drives_force(*twin.arrays[:3], NO_DRIVE)
        rk4_step(y, model.kind, model.params, 0.05, tx + env[0], ty + env[1], tn + env[2], *current, 0.0)
        twin.update(t, 0.05)
        assert x.tolist() == y.tolist()
        assert drives.thrust.tolist() == twin.thrust.tolist()


# -- waves ----------------------------------------------------------------------------------------
def _wave_field(seed: int = 0) -> WaveField:
    comps = realise_waves(2.0, 0.7, 3.3, "jonswap", 200, rng=np.random.default_rng(seed))
    return WaveField(comps, math.radians(30.0), HullDimensions(SHUTTLE_TANKER.length_m, SHUTTLE_TANKER.beam_m,
                                                                SHUTTLE_TANKER.draft_m))


def test_wave_sums_are_the_numpy_sums() -> None:
    rng = np.random.default_rng(5)
    field = _wave_field()
    omega, k, eps = field._omega, field._k, field._eps
    for _ in range(50):
        field._refresh(float(rng.uniform(-math.pi, math.pi)))
        w = field._weights
        t, d, d_rate, weight = (float(rng.uniform(0, 4e4)), float(rng.normal(0, 100)), float(rng.normal(0, 2)),
                                float(rng.uniform(0, 1)))
        phi = omega * t - k * d + eps
        s, c = np.sin(phi), np.cos(phi)
        expected = (weight * (w[W_X] @ s), weight * (w[W_Y] @ s), -weight * (w[W_PSI] @ c),
                    weight * ((w[W_PSI] * omega) @ s - d_rate * ((w[W_PSI] * k) @ s)), weight * (w[W_B] @ c),
                    weight * (w[W_B] @ s))
        # each sum to rounding of the sum of its terms' magnitudes
        magnitudes = weight * np.array([np.abs(w[W_X]).sum(), np.abs(w[W_Y]).sum(), np.abs(w[W_PSI]).sum(),
                                        np.abs(w[W_PSI] * (omega + abs(d_rate) * k)).sum(), np.abs(w[W_B]).sum(),
                                        np.abs(w[W_B]).sum()])
        error = np.abs(np.array(wave_sums(t, d, d_rate, weight, omega, k, eps, w)) - np.array(expected))
        assert np.all(error <= 1e-14 * magnitudes), error / magnitudes


def test_rao_rows_computed_on_demand_are_the_full_table() -> None:
    field = _wave_field(1)
    rx, ry, rpsi = motion_raos(field._omega[None, :], _BETA_GRID[:, None], field.hull)
    for j in range(_BETA_STEPS + 1):
        row = field._rao_row(j)
        np.testing.assert_allclose(row, np.stack((rx[j], ry[j], rpsi[j])) * field._a, rtol=1e-15, atol=0.0)


def test_spectral_process_value_is_the_numpy_cosine_sum() -> None:
    rng = np.random.default_rng(9)
    edges = 2.0 * math.pi * np.geomspace(1.0 / 2000.0, 0.5, 65)
    for process in (gauss_markov_process(0.3, 600.0, rng), SpectralProcess.from_one_sided(edges, np.ones(64), rng)):
        times = rng.uniform(0.0, 43200.0, 300)
        expected = process.series(times)  # cos(ω t + θ) @ c, numpy
        got = np.array([process.value(float(t)) for t in times])
        assert np.all(np.abs(got - expected) <= 1e-14 * np.abs(process._amplitude).sum())
