"""The runtime's per-step fast paths behave as the plain code they replace.

Second performance pass: the NMEA 0183 routing answer is remembered, the thruster monitor builds its alarm
codes once and clears only what it raised, the jerk limit runs on Python floats, and the mass-adaptive
wave filter reuses its output object. Each test states the behaviour the plain code had.
"""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from dpcontrol.models.thrusters import ThrusterSpec
from dpcontrol.runtime.alarms import AlarmRegistry
from dpcontrol.runtime.config import SensorRoute, ThrusterMonitorSettings, TransportConfig
from dpcontrol.runtime.hub import SensorConfig, SensorKind
from dpcontrol.runtime.inputs import SensorRouter
from dpcontrol.runtime.thrusters import ThrusterFeedback, ThrusterMonitor
from interfaces.messages import FixQuality, Heading, PositionFix, RateOfTurn


def _router() -> SensorRouter:
    gyro = SensorConfig("gyro1", SensorKind.HEADING, 10.0, 0.001)
    gnss = SensorConfig("gnss1", SensorKind.POSITION, 1.0, 0.5)
    transports = [TransportConfig("serial0", "nmea0183", {"port": "x"})]
    routes = [SensorRoute(gyro, "serial0", talker="HE"), SensorRoute(gnss, "serial0", talker="GP")]
    return SensorRouter(routes, transports)


def test_router_answers_and_counts_unrouted_every_time() -> None:
    router = _router()
    heading = Heading(1.0, "A")
    for _ in range(3):  # the second and later answers come from the cache
        assert router.nmea0183("serial0", "HETHS", heading) == "gyro1"
        assert router.nmea0183("serial0", "HEROT", RateOfTurn(0.01)) == "gyro1"
    assert router.unrouted == 0
    for expected in (1, 2, 3):  # a talker no route accepts: counted on every sentence, cached or not
        assert router.nmea0183("serial0", "IITHS", heading) is None
        assert router.unrouted == expected
    # the message type is part of the answer: a heading from the GNSS talker is not the GNSS
    assert router.nmea0183("serial0", "GPTHS", heading) is None
    assert router.nmea0183("serial0", "GPGGA", PositionFix(1.0, 2.0, FixQuality.GPS)) == "gnss1"
    assert router.nmea0183("other", "HETHS", heading) is None  # unknown transport


def test_router_cache_is_bounded() -> None:
    router = _router()
    heading = Heading(1.0, "A")
    for i in range(5000):  # addresses come off the wire: garbage must not grow memory without bound
        router.nmea0183("serial0", f"Z{i:05d}", heading)
    assert router.unrouted == 5000
    assert len(router._nmea_cache) <= 1024
    assert router.nmea0183("serial0", "HETHS", heading) == "gyro1"


def _monitor() -> tuple[ThrusterMonitor, AlarmRegistry]:
    specs = [ThrusterSpec(name="bow", kind="tunnel", x_m=30.0, y_m=0.0, max_thrust_n=1e5, min_thrust_n=-1e5,
                          angle_rad=math.pi / 2, time_constant_s=1.0, thrust_rate_limit_nps=5e4),
             ThrusterSpec(name="stern", kind="tunnel", x_m=-30.0, y_m=0.0, max_thrust_n=1e5, min_thrust_n=-1e5,
                          angle_rad=math.pi / 2, time_constant_s=1.0, thrust_rate_limit_nps=5e4)]
    alarms = AlarmRegistry()
    return ThrusterMonitor(specs, ThrusterMonitorSettings(feedback_timeout_s=1.0), alarms, readmit_s=1.0), alarms


def test_monitor_alarms_raise_and_clear_as_before() -> None:
    monitor, alarms = _monitor()
    command = np.zeros(2)
    t = 0.0
    monitor.update(t, 0.1, command)  # no feedback ever: nothing raised
    assert alarms.drain_events() == []
    for k in range(1, 6):  # healthy feedback
        t = 0.1 * k
        monitor.feedback([ThrusterFeedback("bow", 0.0, 0.0, True, t), ThrusterFeedback("stern", 0.0, 0.0, True, t)])
        assert monitor.update(t, 0.1, command).all()
    assert alarms.drain_events() == []
    # the bow drive stops reporting: feedback_lost after the timeout, cleared when it reports again
    for k in range(6, 25):
        t = 0.1 * k
        monitor.feedback([ThrusterFeedback("stern", 0.0, 0.0, True, t)])
        monitor.update(t, 0.1, command)
    assert alarms.is_active("thruster.bow.feedback_lost")
    assert not alarms.is_active("thruster.stern.feedback_lost")
    monitor.feedback([ThrusterFeedback("bow", 0.0, 0.0, False, t), ThrusterFeedback("stern", 0.0, 0.0, True, t)])
    available = monitor.update(t + 0.1, 0.1, command)
    assert not alarms.is_active("thruster.bow.feedback_lost")
    assert available.tolist() == [False, True]  # not ready: out of the allocation, alarmed
    assert alarms.is_active("thruster.bow.unavailable")
    events = [(e.code, e.raised) for e in alarms.drain_events()]
    assert events == [("thruster.bow.feedback_lost", True), ("thruster.bow.feedback_lost", False),
                      ("thruster.bow.unavailable", True)]
    # ready again for readmit_s: back in use, the alarm cleared once
    t += 0.1
    for k in range(1, 15):
        t += 0.1
        monitor.feedback([ThrusterFeedback("bow", 0.0, 0.0, True, t), ThrusterFeedback("stern", 0.0, 0.0, True, t)])
        available = monitor.update(t, 0.1 + 1e-12 * k, command)  # a jittering measured period
    assert available.tolist() == [True, True]
    assert [(e.code, e.raised) for e in alarms.drain_events()] == [("thruster.bow.unavailable", False)]


def test_monitor_expected_thrust_follows_the_rate_limit() -> None:
    monitor, _ = _monitor()
    command = np.array([1e5, -1e5])
    monitor.update(0.0, 0.1, command)
    expected = [h.expected_n for h in monitor._health]
    # the first-order step (1 − e^{−0.1}) · 100 kN ≈ 9.5 kN exceeds Ṫmax·dt = 5 kN: rate-limited
    assert expected == [5e4 * 0.1, -5e4 * 0.1]
    monitor.update(0.1, 0.0, command)  # dt = 0: nothing moves
    assert [h.expected_n for h in monitor._health] == expected


@given(st.lists(st.floats(-1e3, 1e3), min_size=3, max_size=3), st.lists(st.floats(-1e3, 1e3), min_size=3, max_size=3),
       st.lists(st.floats(0.0, 10.0), min_size=3, max_size=3), st.floats(1e-3, 1.0))
def test_jerk_limit_on_floats_is_numpy_clip(accel: list[float], previous: list[float], jerk: list[float],
                                            dt: float) -> None:
    """The float arithmetic of DpController._jerk_limited gives np.clip's values bit for bit."""
    a = np.array(accel)
    p = np.array(previous)
    limit = np.array(jerk) * dt
    reference = p + np.clip(a - p, -limit, limit)
    floats = [pi + min(max(ai - pi, -ji * dt), ji * dt) for ai, pi, ji in zip(accel, previous, jerk, strict=True)]
    assert floats == reference.tolist()
