"""Thruster drives (sim_plant.drives): response, limits, timeout, failures, forces, bad input."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dpbase.frames import ssa
from dpcontrol.models.thrusters import ThrusterSpec
from dpcontrol.models.vessels import BUILTIN_VESSELS, SUPPLY
from sim_plant.drives import CommandError, ThrusterCommand, ThrusterDrives

TUNNEL = ThrusterSpec("tunnel", "tunnel", x_m=30.0, y_m=0.0, max_thrust_n=100.0, min_thrust_n=-80.0,
                      thrust_rate_limit_nps=1000.0, time_constant_s=2.0, angle_rad=math.pi / 2)
SLOW = ThrusterSpec("slow", "propeller", x_m=-10.0, y_m=3.0, max_thrust_n=100.0, min_thrust_n=-100.0,
                    thrust_rate_limit_nps=5.0, time_constant_s=0.5)
AZI = ThrusterSpec("azi", "azimuth", x_m=-30.0, y_m=-4.0, max_thrust_n=200.0, min_thrust_n=0.0,
                   thrust_rate_limit_nps=1000.0, time_constant_s=0.5, azimuth_rate_limit_radps=math.radians(10.0))
RUDDER = ThrusterSpec("main", "propeller_rudder", x_m=-40.0, y_m=0.0, max_thrust_n=300.0, min_thrust_n=-150.0,
                      thrust_rate_limit_nps=1000.0, time_constant_s=0.5, azimuth_rate_limit_radps=math.radians(5.0),
                      rudder_max_angle_rad=math.radians(35.0), rudder_lift_per_rad=1.2)
H = 0.05


def _run(drives: ThrusterDrives, t0: float, seconds: float) -> float:
    t = t0
    for _ in range(round(seconds / H)):
        drives.update(t, H)
        t += H
    return t


def test_first_order_response_without_rate_limit() -> None:
    drives = ThrusterDrives([TUNNEL], timeout_s=100.0)
    drives.command(0.0, {"tunnel": ThrusterCommand(50.0)})
    _run(drives, 0.0, TUNNEL.time_constant_s)
    assert drives.thrust[0] == pytest.approx(50.0 * (1.0 - math.exp(-1.0)), rel=1e-9)


def test_saturation_and_rate_limit() -> None:
    drives = ThrusterDrives([SLOW], timeout_s=100.0)
    drives.command(0.0, {"slow": ThrusterCommand(1e6)})
    previous = 0.0
    t = 0.0
    for _ in range(200):
        drives.update(t, H)
        t += H
        assert drives.thrust[0] - previous <= SLOW.thrust_rate_limit_nps * H + 1e-12
        previous = drives.thrust[0]
    assert drives.thrust[0] == pytest.approx(50.0)  # 10 s at 5 N/s, still rate limited
    _run(drives, t, 30.0)
    assert drives.thrust[0] == pytest.approx(SLOW.max_thrust_n, rel=1e-6)
    drives.command(t, {"slow": ThrusterCommand(-1e6)})
    _run(drives, t, 60.0)
    assert drives.thrust[0] == pytest.approx(SLOW.min_thrust_n, rel=1e-6)


def test_azimuth_slews_the_short_way_at_its_rate_and_never_reverses_thrust() -> None:
    drives = ThrusterDrives([AZI], timeout_s=100.0)
    drives.angle[0] = math.radians(170.0)
    drives.command(0.0, {"azi": ThrusterCommand(-50.0, math.radians(-170.0))})
    _run(drives, 0.0, 1.0)
    assert math.degrees(drives.angle[0]) == pytest.approx(180.0, abs=1e-6) or \
        math.degrees(drives.angle[0]) == pytest.approx(-180.0, abs=1e-6)
    _run(drives, 1.0, 1.0)
    assert math.degrees(drives.angle[0]) == pytest.approx(-170.0, abs=1e-6)
    assert drives.thrust[0] == 0.0  # min_thrust_n = 0: an azimuth does not reverse


def test_rudder_is_clamped_and_rate_limited() -> None:
    drives = ThrusterDrives([RUDDER], timeout_s=100.0)
    drives.command(0.0, {"main": ThrusterCommand(100.0, math.radians(60.0))})
    _run(drives, 0.0, 2.0)
    assert math.degrees(drives.angle[0]) == pytest.approx(10.0, abs=1e-9)
    _run(drives, 2.0, 10.0)
    assert math.degrees(drives.angle[0]) == pytest.approx(35.0, abs=1e-9)


def test_stale_command_ramps_to_zero_and_a_fresh_one_restores() -> None:
    drives = ThrusterDrives([SLOW], timeout_s=5.0)
    drives.command(0.0, {"slow": ThrusterCommand(10.0)})
    t = _run(drives, 0.0, 5.0)  # up to the timeout: following the command
    assert drives.thrust[0] == pytest.approx(10.0, rel=1e-3)
    t = _run(drives, t, 0.5)
    # stale from the substep after t = 5 s on: down at the 5 N/s rate limit (9 substeps)
    assert drives.thrust[0] == pytest.approx(10.0 - 9 * SLOW.thrust_rate_limit_nps * H, rel=1e-3)
    t = _run(drives, t, 10.0)
    assert drives.thrust[0] == pytest.approx(0.0, abs=1e-6)
    drives.command(t, {"slow": ThrusterCommand(10.0)})
    _run(drives, t, 4.9)  # rate-limited ramp, then the first-order tail; fresh until 5 s
    assert drives.thrust[0] == pytest.approx(10.0, rel=1e-3)


def test_command_lost_ramps_to_zero_until_the_next_command() -> None:
    drives = ThrusterDrives([TUNNEL, AZI], timeout_s=100.0)
    drives.command(0.0, {"tunnel": ThrusterCommand(60.0), "azi": ThrusterCommand(100.0, 0.5)})
    t = _run(drives, 0.0, 10.0)
    angle = drives.angle[1]
    drives.command_lost(t)
    t = _run(drives, t, 40.0)
    assert drives.thrust == pytest.approx([0.0, 0.0], abs=1e-5)
    assert drives.angle[1] == angle  # azimuth holds
    drives.command(t, {"tunnel": ThrusterCommand(60.0)})
    _run(drives, t, 40.0)
    assert drives.thrust[0] == pytest.approx(60.0, rel=1e-3)


def test_disabled_command_means_zero_thrust() -> None:
    drives = ThrusterDrives([TUNNEL], timeout_s=100.0)
    drives.command(0.0, {"tunnel": ThrusterCommand(60.0, enabled=False)})
    _run(drives, 0.0, 10.0)
    assert drives.thrust[0] == 0.0


def test_failures_behave_as_specified() -> None:
    drives = ThrusterDrives([TUNNEL, AZI], timeout_s=100.0)
    drives.command(0.0, {"tunnel": ThrusterCommand(60.0), "azi": ThrusterCommand(100.0, 0.3)})
    t = _run(drives, 0.0, 20.0)
    # stuck: frozen at the onset values whatever the command
    drives.set_failure("azi", "stuck")
    stuck_thrust, stuck_angle = drives.thrust[1], drives.angle[1]
    drives.command(t, {"azi": ThrusterCommand(10.0, -1.0)})
    t = _run(drives, t, 10.0)
    assert (drives.thrust[1], drives.angle[1]) == (stuck_thrust, stuck_angle)
    drives.set_failure("azi", None)
    drives.command(t, {"azi": ThrusterCommand(100.0, 0.3)})
    t = _run(drives, t, 20.0)
    normal = drives.force_b()
    tunnel = drives.thrust[0]
    assert tunnel == pytest.approx(60.0, rel=1e-3)
    # zero: nothing delivered although the drive looks ready
    drives.set_failure("tunnel", "zero")
    fb = drives.feedback()[0]
    assert fb.thrust_n == 0.0 and fb.ready
    assert drives.force_b()[1] == pytest.approx(normal[1] - tunnel, rel=1e-12)
    drives.set_failure("tunnel", "wrong_sign")
    assert drives.feedback()[0].thrust_n == -tunnel
    assert drives.force_b()[1] == pytest.approx(normal[1] - 2.0 * tunnel, rel=1e-12)
    # not ready: tripped, spins down, ignores commands
    drives.set_failure("tunnel", "not_ready")
    assert not drives.feedback()[0].ready
    drives.command(t, {"tunnel": ThrusterCommand(80.0)})
    t = _run(drives, t, 30.0)
    assert drives.thrust[0] == pytest.approx(0.0, abs=1e-3)
    drives.set_failure("tunnel", None)
    drives.command(t, {"tunnel": ThrusterCommand(80.0)})
    _run(drives, t, 40.0)
    assert drives.thrust[0] == pytest.approx(80.0, rel=1e-3) and drives.feedback()[0].ready
    with pytest.raises(ValueError, match="unknown thruster failure"):
        drives.set_failure("tunnel", "on_fire")


def test_generalized_force_from_geometry_and_rudder_lift() -> None:
    drives = ThrusterDrives([TUNNEL, SLOW, AZI, RUDDER], timeout_s=1e9)
    drives.thrust[:] = [10.0, 20.0, 30.0, 40.0]
    drives.angle[2] = math.radians(90.0)
    drives.angle[3] = math.radians(10.0)
    fx, fy, n = drives.force_b()
    lift = 40.0 * 1.2 * math.radians(10.0)
    assert fx == pytest.approx(20.0 + 30.0 * math.cos(math.radians(90.0)) + 40.0)
    assert fy == pytest.approx(10.0 + 30.0 + lift)
    expected_n = 30.0 * 10.0 - 3.0 * 20.0 + (-30.0) * 30.0 - (-4.0) * 30.0 * math.cos(math.radians(90.0)) \
        + (-40.0) * lift
    assert n == pytest.approx(expected_n)
    drives.thrust[3] = -40.0  # astern: no rudder lift
    assert drives.force_b()[1] == pytest.approx(10.0 + 30.0)


def test_bad_commands_are_rejected_whole() -> None:
    drives = ThrusterDrives(SUPPLY.thrusters)
    drives.command(0.0, {"bow_tunnel_1": ThrusterCommand(1000.0)})
    before = list(drives._target_thrust)
    bad = [
        {"bow_tunnel_1": ThrusterCommand(2000.0), "no_such": ThrusterCommand(1.0)},
        {"bow_tunnel_1": ThrusterCommand(float("nan"))},
        {"bow_tunnel_1": ThrusterCommand(True)},  # type: ignore[arg-type]
        {"azimuth_port": ThrusterCommand(1.0, float("inf"))},
        {"azimuth_port": ThrusterCommand(1.0, 0.0, enabled=1)},  # type: ignore[arg-type]
        {"azimuth_port": (1.0, 0.0)},
    ]
    for command in bad:
        with pytest.raises(CommandError):
            drives.command(1.0, command)  # type: ignore[arg-type]
    assert drives._target_thrust == before
    with pytest.raises(CommandError, match="known: bow_tunnel_1"):
        drives.command(1.0, {"no_such": ThrusterCommand(1.0)})
    with pytest.raises(CommandError):
        drives.command(float("nan"), {})
    drives.command(1.0, {"bow_tunnel_1": ThrusterCommand(5)})  # an int is a fine number
    assert drives._target_thrust[0] == 5.0


@settings(max_examples=60, deadline=None)
@given(vessel=st.sampled_from(sorted(BUILTIN_VESSELS)),
       commands=st.lists(st.tuples(st.floats(-3.0, 3.0), st.floats(-10.0, 10.0), st.booleans(),
                                   st.floats(0.01, 0.3)), min_size=1, max_size=25))
def test_limits_hold_for_any_command_sequence(vessel, commands) -> None:
    """Saturation, thrust-rate and azimuth/rudder-rate limits hold whatever is commanded, how often."""
    specs = BUILTIN_VESSELS[vessel].thrusters
    drives = ThrusterDrives(specs, timeout_s=0.5)
    t = 0.0
    for scale, angle, enabled, h in commands:
        drives.command(t, {s.name: ThrusterCommand(scale * s.max_thrust_n, angle, enabled) for s in specs})
        before_thrust = list(drives.thrust)
        before_angle = list(drives.angle)
        drives.update(t, h)
        t += h
        for i, spec in enumerate(specs):
            assert spec.min_thrust_n - 1e-9 <= drives.thrust[i] <= spec.max_thrust_n + 1e-9
            assert abs(drives.thrust[i] - before_thrust[i]) <= spec.thrust_rate_limit_nps * h * (1 + 1e-12)
            if spec.azimuth_rate_limit_radps is not None:
                moved = abs(ssa(drives.angle[i] - before_angle[i]))
                assert moved <= spec.azimuth_rate_limit_radps * h * (1 + 1e-9)
            if spec.kind == "propeller_rudder":
                assert abs(drives.angle[i]) <= spec.rudder_max_angle_rad + 1e-12
            if spec.kind in ("tunnel", "propeller"):
                assert drives.angle[i] == spec.angle_rad


# -- the array fast paths (command_arrays: one kernel call; feedback_values: no object per drive) -----------
_ALL = [TUNNEL, SLOW, AZI, RUDDER]
_value = st.one_of(st.floats(-1e3, 1e3), st.sampled_from([0.0, -0.0, 100.0, -80.0, 300.0, -150.0, 1e6, -1e6]))
_angle = st.one_of(st.floats(-20.0, 20.0), st.sampled_from([0.0, -0.0, math.pi, -math.pi, math.radians(35.0)]))


@settings(max_examples=200, deadline=None)
@given(st.permutations(range(4)), st.lists(st.tuples(_value, _angle, st.booleans()), min_size=4, max_size=4),
       st.floats(0.0, 100.0))
def test_command_arrays_sets_what_command_sets(order, values, t_s) -> None:
    import numpy as np  # noqa: PLC0415 (the rest of this module needs no numpy)

    plain = ThrusterDrives(_ALL)
    fast = ThrusterDrives(_ALL)
    plain.command(t_s, {_ALL[i].name: ThrusterCommand(thrust, azimuth, on)
                        for i, (thrust, azimuth, on) in zip(order, values, strict=True)})
    thrust, azimuth, enabled = (np.array(column) for column in zip(*values, strict=True))
    fast.command_arrays(t_s, np.array(order, dtype=np.int64), thrust, azimuth, enabled.astype(bool))
    # bit for bit (signed zeros included): the kernel's comparisons are those of min(high, max(low, x))
    assert plain._state.tobytes() == fast._state.tobytes()
    assert plain._bank.tobytes() == fast._bank.tobytes()


def test_command_arrays_rejects_what_command_rejects_and_takes_other_types() -> None:
    import numpy as np  # noqa: PLC0415

    drives = ThrusterDrives(_ALL)
    drives.command(1.0, {"tunnel": ThrusterCommand(10.0), "azi": ThrusterCommand(20.0, 0.5)})
    before = drives._state.copy()
    order = np.arange(4, dtype=np.int64)
    for thrust, azimuth in (([1.0, math.nan, 1.0, 1.0], [0.0] * 4), ([1.0] * 4, [0.0, 0.0, math.inf, 0.0])):
        with pytest.raises(CommandError) as fast:
            drives.command_arrays(2.0, order, np.array(thrust), np.array(azimuth), np.ones(4, dtype=bool))
        with pytest.raises(CommandError) as plain:
            drives.command(2.0, {s.name: ThrusterCommand(a, b, True) for s, a, b in zip(_ALL, thrust, azimuth,
                                                                                       strict=True)})
        assert str(fast.value) == str(plain.value)
        assert np.array_equal(drives._state, before, equal_nan=True)  # nothing applied
    with pytest.raises(CommandError, match="command time"):
        drives.command_arrays(math.nan, order, np.ones(4), np.zeros(4), np.ones(4, dtype=bool))
    with pytest.raises(ValueError):  # lengths differ
        drives.command_arrays(2.0, order, np.ones(3), np.zeros(4), np.ones(4, dtype=bool))
    # integers, float32, a list: not the kernel's types, converted by the general path to the same targets
    drives.command_arrays(3.0, order, np.array([5, 6, 7, 8]), np.zeros(4, dtype=np.float32), [True] * 4)
    expected = ThrusterDrives(_ALL)
    expected.command(3.0, {s.name: ThrusterCommand(float(v), 0.0, True) for s, v in zip(_ALL, [5, 6, 7, 8],
                                                                                        strict=True)})
    assert drives._target_thrust == expected._target_thrust


def test_feedback_values_are_the_feedback() -> None:
    drives = ThrusterDrives(_ALL)
    drives.command(0.0, {"tunnel": ThrusterCommand(50.0), "azi": ThrusterCommand(100.0, 2.0),
                         "main": ThrusterCommand(-100.0, 0.3), "slow": ThrusterCommand(40.0)})
    drives.set_failure("slow", "wrong_sign")
    drives.set_failure("tunnel", "not_ready")
    _run(drives, 0.0, 1.0)
    thrusts, angles, ready = drives.feedback_values()
    assert [(f.name, f.thrust_n, f.azimuth_rad, f.ready) for f in drives.feedback()] == \
        list(zip(drives.names, thrusts, angles, ready, strict=True))
