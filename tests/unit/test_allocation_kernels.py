"""The compiled allocation kernels against the plain numpy/Python formulas they replaced, on random inputs."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from dpbase.frames import ssa
from dpcontrol.allocation import ThrustAllocator
from dpcontrol.allocation.allocator import AllocationResult, _result
from dpcontrol.allocation.geometry import AZIMUTH, RUDDER
from dpcontrol.allocation.kernels import EPS_ANGLE, TWO_PI, _sector_window
from dpcontrol.models.thrusters import ThrusterSpec
from dpcontrol.models.vessels import BUILTIN_VESSELS
from dpcontrol.runtime.alarms import AlarmRegistry
from dpcontrol.runtime.config import ThrusterMonitorSettings
from dpcontrol.runtime.thruster_monitor import ThrusterMonitor

DT = 0.1
RATE = math.radians(12.0)


def ring(n: int, rate: float | None = RATE) -> tuple[ThrusterSpec, ...]:
    """n azimuths of 300 kN on an ellipse (the benchmark's layout)."""
    return tuple(ThrusterSpec(f"az{k}", "azimuth", x_m=30.0 * math.cos(2 * math.pi * k / n),
                              y_m=8.0 * math.sin(2 * math.pi * k / n), max_thrust_n=300e3, min_thrust_n=0.0,
                              thrust_rate_limit_nps=60e3, azimuth_rate_limit_radps=rate) for k in range(n))


def extended_numpy(geometry, thrust: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """The extended thrust f(T, α) as vectorised numpy (geometry module docstring)."""
    f = np.zeros(geometry.n_variables)
    first = geometry.first_variable
    az = geometry.azimuth_index
    f[first[az]] = thrust[az] * np.cos(angle[az])
    f[first[az] + 1] = thrust[az] * np.sin(angle[az])
    rud = geometry.rudder_index
    f[first[rud]] = thrust[rud]
    f[first[rud] + 1] = np.where(thrust[rud] > 0.0, thrust[rud] * geometry.rudder_lift_per_rad * angle[rud], 0.0)
    f[first[geometry.fixed_index]] = thrust[geometry.fixed_index]
    return f


@pytest.mark.parametrize("name", sorted(BUILTIN_VESSELS))
def test_extended_thrust_and_force_are_the_numpy_formulas(name) -> None:
    geometry = ThrustAllocator(BUILTIN_VESSELS[name].thrusters, DT).geometry
    rng = np.random.default_rng(7)
    n = len(geometry.specs)
    scale = geometry.scale_n
    for _ in range(200):
        thrust = rng.uniform(-1.0, 1.0, n) * scale
        angle = rng.uniform(-math.pi, math.pi, n)
        f = extended_numpy(geometry, thrust, angle)
        assert np.array_equal(geometry.extended_from_commands(thrust, angle), f)  # the same operations
        out = np.zeros(3)
        tau = geometry.force_b(thrust, angle, out=out)
        assert tau is out
        # B f summed in another order than BLAS's: equal to rounding
        np.testing.assert_allclose(tau, geometry.B @ f, rtol=1e-13, atol=1e-12 * float(np.max(scale)))
    # lists and non-contiguous views are converted; a wrong length is an error, not a read past the end
    thrust = rng.uniform(0.0, 1.0, 2 * n)[::2] * scale
    np.testing.assert_array_equal(geometry.force_b(thrust, list(angle)), geometry.force_b(thrust.copy(), angle))
    with pytest.raises(ValueError, match="thrust_n"):
        geometry.force_b(np.zeros(n + 1), angle)
    with pytest.raises(ValueError, match="out"):
        geometry.force_b(thrust, angle, out=np.zeros(4))


def _previous(allocator: ThrustAllocator, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    n = len(allocator.thrusters)
    prev_t = rng.uniform(0.0, 1.0, n) * 300e3
    prev_t[rng.random(n) < 0.2] = 0.0  # some idle (no lower thrust-rate row)
    prev_a = rng.uniform(-math.pi, math.pi, n)
    available = rng.random(n) > 0.15
    return prev_t, prev_a, available


def _rows(snapshot: dict[str, np.ndarray], q: int, block: int, nv: int) -> tuple[np.ndarray, ...]:
    """Azimuth q's block of the last QP: (x, y, upper, lower) per row, and its variables' bounds."""
    rows = 3 + q * block + np.arange(block)
    A = snapshot["A"]
    return (A[rows, 2 * q], A[rows, 2 * q + 1], snapshot["bupper"][nv + rows], snapshot["blower"][nv + rows],
            snapshot["bupper"][2 * q:2 * q + 2], snapshot["blower"][2 * q:2 * q + 2])


def test_narrow_azimuth_rows_are_the_numpy_formulas() -> None:
    """Rate window α_prev ± α̇dt with one chord either side (allocator, _azimuth_rows_narrow docstring)."""
    n = 6
    allocator = ThrustAllocator(ring(n), DT)
    rng = np.random.default_rng(3)
    nv = allocator.geometry.n_variables + 6
    for _ in range(50):
        prev_t, prev_a, available = _previous(allocator, rng)
        tau = rng.normal(0.0, 0.1, 3) * allocator.capability_scale
        allocator.allocate(tau, available, prev_t, prev_a)
        snapshot = allocator.qp_snapshot()
        block = (snapshot["A"].shape[0] - 3) // n
        c = block - 3
        delta = RATE * DT
        step = 60e3 * DT
        r = np.where(available, np.minimum(300e3, prev_t + step), 0.0) / 300e3
        low = (prev_t - step) / 300e3
        for q in range(n):
            a = prev_a[q]
            x, y, upper, lower, var_upper, var_lower = _rows(snapshot, q, block, nv)
            mids = np.array([a - 0.5 * delta, a + 0.5 * delta])
            edges = np.array([a - delta, a + delta])
            expected_x = np.concatenate([np.cos(mids), np.zeros(c - 2), [np.sin(edges[0]), -np.sin(edges[1]),
                                                                          np.cos(a)]])
            expected_y = np.concatenate([np.sin(mids), np.zeros(c - 2), [-np.cos(edges[0]), np.cos(edges[1]),
                                                                          np.sin(a)]])
            expected_upper = np.concatenate([np.full(2, r[q] * np.cos(0.5 * delta)), np.ones(c - 2), [0.0, 0.0,
                                                                                                      np.inf]])
            rate_row = low[q] if (low[q] > 0.0 and available[q]) else -np.inf
            expected_lower = np.concatenate([np.full(2, -np.inf), -np.ones(c - 2), [-np.inf, -np.inf, rate_row]])
            np.testing.assert_allclose(x, expected_x, rtol=1e-15, atol=1e-16)
            np.testing.assert_allclose(y, expected_y, rtol=1e-15, atol=1e-16)
            np.testing.assert_allclose(upper, expected_upper, rtol=1e-15, atol=0.0)
            np.testing.assert_allclose(lower, expected_lower, rtol=1e-15, atol=0.0)
            np.testing.assert_allclose(var_upper, [r[q], r[q]], rtol=1e-15, atol=0.0)
            np.testing.assert_array_equal(var_lower, -var_upper)


@pytest.mark.parametrize(("rate", "dt"), [(RATE, 2.0), (None, DT)])
def test_general_azimuth_polygon_is_the_numpy_construction(rate, dt) -> None:
    """A window wider than one polygon side (24 sides of 15°): the inscribed polygon from the window's low edge
    to its high edge with a vertex at α_prev (the full circle without a rate limit), then the cone edges and the
    lower thrust-rate row (allocator module docstring)."""
    n = 4
    allocator = ThrustAllocator(ring(n, rate), dt)
    rng = np.random.default_rng(5)
    nv = allocator.geometry.n_variables + 6
    side = TWO_PI / 24
    for _ in range(50):
        prev_t, prev_a, available = _previous(allocator, rng)
        tau = rng.normal(0.0, 0.1, 3) * allocator.capability_scale
        allocator.allocate(tau, available, prev_t, prev_a, dt_s=dt)
        snapshot = allocator.qp_snapshot()
        block = (snapshot["A"].shape[0] - 3) // n
        c = block - 3
        step = 60e3 * dt
        radius = np.minimum(300e3, prev_t + step)
        for q in range(n):
            a = prev_a[q]
            x, y, upper, lower, var_upper, _ = _rows(snapshot, q, block, nv)
            active = available[q] and radius[q] > 0.0
            if not active:
                np.testing.assert_array_equal(np.abs(x) + np.abs(y), 0.0)
                np.testing.assert_array_equal(var_upper, 0.0)
                continue
            r = radius[q] / 300e3
            full = rate is None
            lo, hi = (a - TWO_PI, a) if full else (a - rate * dt, a + rate * dt)
            k1 = math.ceil((a - lo) / side - 1e-9)
            k2 = math.ceil((hi - a) / side - 1e-9)
            vertices = np.concatenate([np.linspace(lo, a, k1 + 1), np.linspace(a, hi, k2 + 1)[1:]])
            mid = 0.5 * (vertices[1:] + vertices[:-1])
            half = 0.5 * np.diff(vertices)
            used = k1 + k2
            np.testing.assert_allclose(x[:used], np.cos(mid), atol=1e-14)
            np.testing.assert_allclose(y[:used], np.sin(mid), atol=1e-14)
            np.testing.assert_allclose(upper[:used], r * np.cos(half), rtol=1e-14)
            np.testing.assert_array_equal(lower[:used], -np.inf)
            np.testing.assert_array_equal(np.abs(x[used:c]) + np.abs(y[used:c]), 0.0)  # unused chord rows
            if full:  # no cone
                np.testing.assert_array_equal(np.abs(x[c:c + 2]) + np.abs(y[c:c + 2]), 0.0)
            else:
                np.testing.assert_allclose(x[c:c + 2], [np.sin(lo), -np.sin(hi)], atol=1e-15)
                np.testing.assert_allclose(y[c:c + 2], [-np.cos(lo), np.cos(hi)], atol=1e-15)
                np.testing.assert_array_equal(upper[c:c + 2], 0.0)
            low = prev_t[q] - step
            if low > 0.0:
                np.testing.assert_allclose([x[c + 2], y[c + 2], lower[c + 2]], [np.cos(a), np.sin(a), low / 300e3],
                                           rtol=1e-15, atol=1e-16)
            else:
                assert x[c + 2] == y[c + 2] == 0.0
            np.testing.assert_allclose(var_upper, [r, r], rtol=1e-15)


def sector_window_python(a: float, sectors: list[tuple[float, float]], wanted: float | None
                         ) -> tuple[bool, float, float, float, float]:
    """The Python implementation the kernel :func:`_sector_window` replaced (``wanted`` None: no direction)."""
    arc_lo, arc_hi = -math.inf, math.inf
    for start, width in sectors:
        offset = (a - start) % TWO_PI
        if EPS_ANGLE < offset < width - EPS_ANGLE:
            edge = a - offset if offset <= 0.5 * width else a + (width - offset)
            return True, a, a, edge, 0.0
        up = (start - a) % TWO_PI
        if up > TWO_PI - EPS_ANGLE:
            up = 0.0
        down = (a - (start + width)) % TWO_PI
        if down > TWO_PI - EPS_ANGLE:
            down = 0.0
        arc_hi = min(arc_hi, a + up)
        arc_lo = max(arc_lo, a - down)
    if wanted is None:
        return False, arc_lo, arc_hi, math.nan, 0.0
    short = a + ssa(wanted - a)
    target = None
    for candidate in (short, short - TWO_PI, short + TWO_PI):
        if arc_lo - EPS_ANGLE <= candidate <= arc_hi + EPS_ANGLE:
            target = min(max(candidate, arc_lo), arc_hi)
            break
    if target is None:
        target = arc_lo if abs(ssa(wanted - arc_lo)) <= abs(ssa(wanted - arc_hi)) else arc_hi
        return False, arc_lo, arc_hi, target, 0.0
    side = 0.0
    if abs(target - short) > EPS_ANGLE and abs(target - a) > EPS_ANGLE:
        side = 1.0 if target > a else -1.0
    return False, arc_lo, arc_hi, target, side


def test_sector_window_kernel_is_the_python_function() -> None:
    rng = np.random.default_rng(11)
    for _ in range(3000):
        count = int(rng.integers(1, 4))
        sectors = [(float(rng.uniform(0.0, TWO_PI)), float(rng.uniform(0.05, 1.5))) for _ in range(count)]
        a = float(rng.uniform(-math.pi, math.pi))
        if rng.random() < 0.1:
            a = ssa(sectors[0][0] + sectors[0][1])  # on a sector's edge
        wanted = None if rng.random() < 0.1 else a + ssa(float(rng.uniform(-math.pi, math.pi)) - a)
        table = np.array([(0.0, 0.0), *sectors])  # from row 1: the kernel reads its own rows only
        blocked, arc_lo, arc_hi, target, side = _sector_window(a, table, 1, count, math.nan if wanted is None
                                                                else wanted)
        expected = sector_window_python(a, sectors, wanted)
        assert (bool(blocked), arc_lo, arc_hi, side) == expected[:3] + expected[4:]
        assert target == expected[3] or (math.isnan(target) and math.isnan(expected[3]))


def test_commands_give_the_force_of_the_numpy_formula_for_every_mode() -> None:
    """tau_achieved_b is B f(T, α) of the commands (numpy), for a layout with every thruster mode."""
    specs = (*BUILTIN_VESSELS["shuttle_tanker"].thrusters, dataclasses.replace(ring(1)[0], name="extra"))
    allocator = ThrustAllocator(specs, DT)
    geometry = allocator.geometry
    assert {AZIMUTH, RUDDER} <= set(geometry.mode.tolist())
    rng = np.random.default_rng(2)
    for k in range(300):
        tau = rng.normal(0.0, 0.3 if k % 3 else 1.0, 3) * allocator.capability_scale
        result = allocator.allocate(tau)
        f = extended_numpy(geometry, result.thrust_n, result.azimuth_rad)
        np.testing.assert_allclose(result.tau_achieved_b, geometry.B @ f, rtol=1e-12,
                                   atol=1e-12 * float(np.max(allocator.capability_scale)))
        np.testing.assert_array_equal(result.shortfall_b, tau - result.tau_achieved_b)


def test_monitor_expected_thrust_is_the_first_order_lag_formula() -> None:
    """The monitor's compiled update: a healthy drive's expected thrust is the rate-limited first-order lag
    ``e += clip((c − e)(1 − e^{−dt/T}), −Ṫdt, Ṫdt)`` of the commands (thrusters module docstring)."""
    specs = BUILTIN_VESSELS["shuttle_tanker"].thrusters
    monitor = ThrusterMonitor(specs, ThrusterMonitorSettings(), AlarmRegistry())
    rng = np.random.default_rng(9)
    tc = np.array([s.time_constant_s for s in specs])
    rate = np.array([s.thrust_rate_limit_nps for s in specs])
    rating = np.array([s.max_thrust_n for s in specs])
    expected = np.zeros(len(specs))
    for k in range(500):
        dt = float(rng.choice([0.1, 0.1 + 1e-12, 0.0, 0.25]))
        command = rng.normal(0.0, 0.4, len(specs)) * rating
        available = monitor.update(0.1 * k, dt, command)
        if dt > 0.0:
            response = np.array([1.0 - math.exp(-dt / t) for t in tc])  # math.exp: the C library's, as the kernel's
            expected += np.clip((command - expected) * response, -rate * dt, rate * dt)
        assert available.all()  # no feedback: nothing to judge
        np.testing.assert_array_equal([h.expected_n for h in monitor._health], expected)


def test_allocation_result_fast_constructor_is_the_dataclass() -> None:
    fields = {"thrust_n": np.arange(3.0), "azimuth_rad": np.ones(3), "tau_achieved_b": np.zeros(3),
              "shortfall_b": np.full(3, 2.0), "saturated": True, "solver_status": "optimal", "iterations": 4}
    fast = _result(**fields)
    plain = AllocationResult(**fields)
    assert type(fast) is AllocationResult
    assert list(vars(fast)) == list(vars(plain)) == [f.name for f in dataclasses.fields(AllocationResult)]
    assert all(getattr(fast, name) is value for name, value in fields.items())
    with pytest.raises(dataclasses.FrozenInstanceError):
        fast.saturated = False  # type: ignore[misc]
