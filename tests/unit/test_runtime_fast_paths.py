"""The runtime's per-step fast paths behave as the plain code they replace.

Second performance pass: the NMEA 0183 routing answer is remembered, the thruster monitor builds its alarm
codes once and clears only what it raised, the jerk limit runs on Python floats, and the mass-adaptive
wave filter reuses its output object. Third: the sensor hub computes the GST σ without temporaries, keeps
the fade factor of its bumpless offsets between steps and searches for an all-rejecting kind only while a
reference is rejected; the control step clears its alarms only when it raised them and keeps the jerk-limited
acceleration as floats. Each test states the behaviour the plain code had.
"""

from __future__ import annotations

import json
import math

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from dpbase.geodesy import LocalFrame
from dpcontrol.bench import bench_config
from dpcontrol.guidance import Reference
from dpcontrol.models.thrusters import ThrusterSpec
from dpcontrol.runtime.alarms import AlarmRegistry
from dpcontrol.runtime.config import SensorRoute, ThrusterMonitorSettings, TransportConfig
from dpcontrol.runtime.hub import HubConfig, HubOutput, SensorConfig, SensorHub, SensorKind, _gst_sigma
from dpcontrol.runtime.inputs import SensorRouter
from dpcontrol.runtime.step import DpController, Mode
from dpcontrol.runtime.thruster_monitor import ThrusterFeedback, ThrusterMonitor
from dpcontrol.runtime.transport_health import TransportHealth
from interfaces.messages import FixQuality, Heading, Measurement, PositionFix, RateOfTurn


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


# ---------------------------------------------------------------------- third pass: hub and control step
@given(st.one_of(st.none(), st.floats(-5.0, 5.0)), st.one_of(st.none(), st.floats(-5.0, 5.0)))
def test_gst_sigma_is_the_rms_of_the_present_positive_sigmas(north: float | None, east: float | None) -> None:
    """The hub's GST σ without the per-message list and generator: the same float as the plain formula."""
    sigmas = [s for s in (north, east) if s is not None and s > 0.0]
    expected = math.sqrt(sum(s * s for s in sigmas) / len(sigmas)) if sigmas else None
    assert _gst_sigma(north, east) == expected


def _two_gnss_hub() -> tuple[SensorHub, AlarmRegistry]:
    sensors = [SensorConfig("gnss1", SensorKind.POSITION, 10.0, 0.3),
               SensorConfig("gnss2", SensorKind.POSITION, 10.0, 0.6),
               SensorConfig("gyro1", SensorKind.HEADING, 10.0, 0.002)]
    alarms = AlarmRegistry()
    return SensorHub(sensors, HubConfig(readmit_s=1.0), alarms, LocalFrame(60.0, 5.0)), alarms


def _samples(hub: SensorHub, t: float, north: dict[str, float]) -> list[Measurement]:
    """Fixes at ``north`` [m] (and 0 m east) and a heading of 0.5 rad, with a few cm / 0.006° of wiggle
    (identical values would be frozen)."""
    frame = hub.datum
    assert frame is not None
    wiggle = math.sin(7.0 * t)
    out = [Measurement(t, name, PositionFix(*frame.surface_to_geodetic(value + 0.03 * wiggle, 0.0), FixQuality.DGPS))
           for name, value in north.items()]
    return [*out, Measurement(t, "gyro1", Heading(0.5 + 1e-4 * wiggle))]


def test_hub_offsets_fade_with_each_periods_own_decay() -> None:
    """The fade factor exp(−dt/switch_blend_s) is kept between steps: with a jittering period it is the
    factor of each step's own dt."""
    hub, _ = _two_gnss_hub()
    rng = np.random.default_rng(2)
    t = 0.0
    for _ in range(30):  # both fused; gnss2 sits 2 m north of gnss1
        t += 0.1
        hub.update(t, _samples(hub, t, {"gnss1": 0.0, "gnss2": 2.0}), None, None)
    for _ in range(5):  # gnss1 drops out: the bias between the two is added and faded out
        t += 0.1
        hub.update(t, _samples(hub, t, {"gnss2": 2.0}), None, None)
    previous = hub._position_offset[0]
    assert previous < -1.0
    for _ in range(20):
        dt = 0.1 + 1e-3 * rng.standard_normal()
        t += dt
        hub.update(t, _samples(hub, t, {"gnss2": 2.0}), None, None)
        assert hub._position_offset[0] == previous * math.exp(-dt / hub.config.switch_blend_s)
        previous = hub._position_offset[0]


def test_hub_searches_for_an_all_rejecting_kind_only_while_a_reference_is_rejected() -> None:
    hub, alarms = _two_gnss_hub()
    t = 0.0
    variance = [0.1, 0.1, 1e-6]
    for k in range(200):
        t += 0.1
        wrong = k < 150  # the estimate is 20 m off for 15 s: both references fail the prediction test
        predicted = [20.0 if wrong else 1.0, 0.0, 0.5]
        out = hub.update(t, _samples(hub, t, {"gnss1": 1.0, "gnss2": 1.0}), predicted, variance)
        assert hub._rejecting is any(track.rejecting_since_t_s is not None for track in hub._tracks.values())
        if out.position_reset:  # after reject_persist_s of failures (from 0.1 s) the references are trusted again
            persist = hub.config.reject_persist_s
            assert persist <= t - 0.1 < persist + 0.1 + 1e-9
            assert alarms.is_active("estimator.reset")
    assert not hub._rejecting
    assert sum(e.code == "estimator.reset" and e.raised for e in alarms.drain_events()) == 1


def _controller() -> DpController:
    return DpController(bench_config())


def test_capability_alarm_raises_and_clears_as_before_and_clears_only_what_it_raised() -> None:
    controller = _controller()
    alarms = controller.alarms
    out = controller.out
    persist = controller.config.thruster_monitor.shortfall_persist_s
    controller.mode = Mode.AUTO_POSITION
    out.tau_b[:] = (1e5, 0.0, 0.0)
    t = 0.0
    for short in [False] * 5 + [True] * round(persist / 0.1 + 5) + [False] * 5 + [True] * 3 + [False] * 3:
        out.shortfall_b[:] = (5e4 if short else 0.0, 0.0, 0.0)
        controller._capability_alarm(t)
        t += 0.1
    events = [(e.code, e.raised) for e in alarms.drain_events()]
    assert events == [("thrusters.capability", True), ("thrusters.capability", False)]
    controller.mode = Mode.STANDBY  # nothing pending: nothing to clear, no event
    controller._capability_alarm(t)
    assert alarms.drain_events() == []


def test_mode_alarms_clear_only_what_the_controller_raised() -> None:
    controller = _controller()
    alarms = controller.alarms
    controller._estimator_ready = True
    controller.mode = controller._requested_mode = Mode.AUTO_POSITION
    hub = HubOutput(position_available=True, heading_available=True)
    controller._update_mode(0.0, hub)
    assert alarms.drain_events() == []
    hub.position_available, hub.position_lost_s = False, 0.5
    controller._update_mode(0.1, hub)
    controller._update_mode(0.2, hub)  # still active: the text follows the time lost, no new event
    assert alarms.is_active("position.dead_reckoning")
    hub.position_available, hub.position_lost_s = True, 0.0
    controller._update_mode(0.3, hub)
    controller._update_mode(0.4, hub)
    assert [(e.code, e.raised) for e in alarms.drain_events()] == [("position.dead_reckoning", True),
                                                                   ("position.dead_reckoning", False)]


def test_jerk_limited_acceleration_persists_as_a_list() -> None:
    controller = _controller()
    controller._jerk_limited(0.1, Reference(np.zeros(3), np.zeros(3), np.zeros(3)))
    limited = controller._jerk_limited(0.1, Reference(np.zeros(3), np.zeros(3), np.array([1.0, -1.0, 1e-3])))
    step = [j * 0.1 for j in controller._jerk_limit]
    assert limited.eta_ddot_d_ned.tolist() == [min(1.0, step[0]), -min(1.0, step[1]), min(1e-3, step[2])]
    assert controller._accel_ff_ned == tuple(limited.eta_ddot_d_ned.tolist())
    # persisted as before (a list of 3 floats) and restored
    controller.estimator.reset(np.zeros(3))
    controller._estimator_ready = True
    controller.mode = Mode.AUTO_POSITION
    controller.reference_model.reset(np.zeros(3))
    state = json.loads(json.dumps(controller.state_dict(0.0)))
    assert state["accel_ff_n"] == limited.eta_ddot_d_ned.tolist()
    other = _controller()
    other.load_state_dict(state, 0.0)
    assert other._accel_ff_ned == controller._accel_ff_ned


@given(st.lists(st.tuples(st.floats(0.0, 60.0), st.sampled_from([None, None, "checksum", "invalid_fix", "garbage"])),
                max_size=200), st.floats(0.0, 70.0))
def test_error_rate_is_the_sum_over_the_ring_slots_in_the_window(frames: list[tuple[float, str | None]],
                                                                 t_s: float) -> None:
    health = TransportHealth(window_s=10.0, bucket_s=0.5)
    for t, reason in sorted(frames, key=lambda frame: frame[0]):
        health.add(t, reason)
    newest = math.floor(t_s / health.bucket_s)
    oldest = newest - health._n + 1
    good = bad = 0
    for slot in range(health._n):  # the plain scan, slot by slot
        if oldest <= health._slot[slot] <= newest:
            good += health._good[slot]
            bad += health._bad[slot]
    assert health.rate(t_s) == ((bad / (good + bad) if good + bad else 0.0), bad)


def test_monitor_delivered_into_fills_the_latest_feedback() -> None:
    monitor, _ = _monitor()
    thrust = np.full(2, 7.0)
    angle = np.full(2, 7.0)
    assert not monitor.delivered_into(thrust, angle)  # no feedback yet: nothing written
    assert thrust.tolist() == [7.0, 7.0] and angle.tolist() == [7.0, 7.0]
    monitor.feedback([ThrusterFeedback("stern", -2.5e4, 1.5, True, 0.1)])  # the bow has not reported
    assert monitor.delivered_into(thrust, angle)
    assert thrust.tolist() == [0.0, -2.5e4]  # 0 N for a drive without feedback
    assert angle.tolist() == [math.pi / 2, 1.5]  # and its spec's angle


def test_monitor_limits_follow_replaced_readmit_time() -> None:
    monitor, _ = _monitor()
    command = np.zeros(2)
    monitor.update(0.0, 0.1, command)
    assert monitor._limits[2:] == (1.0, float(monitor.settings.mismatch_fraction),
                                   float(monitor.settings.mismatch_floor_fraction),
                                   float(monitor.settings.mismatch_persist_s), 1.0)
    monitor.readmit_s = 3.0
    monitor.update(0.1, 0.1, command)
    assert monitor._limits[-1] == 3.0
