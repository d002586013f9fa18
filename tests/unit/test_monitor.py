"""``dpcontrol monitor``: the pure renderer on sample/missing/odd data, and the live loop over loopback."""

from __future__ import annotations

import argparse
import io
import math
import threading
from typing import Any

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from rich.console import Console
from rich.text import Text

from dpcontrol.monitor import (
    MONITOR_TOPICS,
    MonitorState,
    TopicView,
    add_arguments,
    render,
    run_monitor,
)
from interfaces.zenoh import schemas as sc
from interfaces.zenoh.loopback import free_tcp_port, loopback_endpoint, open_listener
from interfaces.zenoh.node import AliveState

TIMEOUT_S = 20.0


def _payloads(seq: int = 1) -> dict[str, bytes]:
    t = 100.0 + seq
    return {
        "estimate": sc.estimate_payload(t_s=t, seq=seq, estimator="mmae", eta_ned=[12.34, -5.5, math.radians(350.0)],
                                        nu_b=[0.25, -0.05, math.radians(1.5)], bias=[2e3, -1e3, 4e4],
                                        eta_wf_ned=[0.3, 0.2, 0.01], covariance_diag=np.ones(15)),
        "mmae": sc.mmae_payload(t_s=t, seq=seq, omegas_rad_s=[0.56, 0.73, 0.80], weights=[0.125, 0.625, 0.25],
                                omega_hat_rad_s=0.71),
        "control": sc.control_payload(t_s=t, seq=seq, controller="mrac", tau_b=[15e3, -25e3, 35e3],
                                      setpoint_ned=[10.0, -5.0, 0.0], reference_ned=[11.0, -5.0, 0.0],
                                      reference_nu_b=[0.1, 0.0, 0.0], tau_achieved_b=[15e3, -20e3, 35e3],
                                      mrac_mass=[6.36e6, 7.0e6, 4.0e9], mrac_damping=[1.0e5, 2.0e5, 3.0e8]),
        "status": sc.status_payload(
            t_s=t, seq=seq, mode="auto_position",
            sensors=[sc.SensorHealth("gnss1", "gnss", "ok", 0.12, 0.5),
                     sc.SensorHealth("gyro2", "gyro", "frozen", 3.5, 0.0, "[bold]no change[/bold] for 3 s")],
            alarms=[sc.Alarm("GYRO2_FROZEN", "alarm", "gyro2 frozen", 97.0, True),
                    sc.Alarm("GNSS1_STALE", "warning", "cleared", 50.0, False)],
            cycle=sc.CycleTiming(0.1, 142.0, 187.0, 3, 1.5),
            thrusters=[sc.ThrusterAvailability("bow", True), sc.ThrusterAvailability("stern", False, "trip")],
            request=sc.RequestOutcome(77, t - 12.0, "refused", "auto_heading refused: no estimate yet; mode standby"),
            consequence=sc.WorstCaseCheck(t - 0.5, (0.0, 150e3, 0.0),
                                          (sc.FailureGroupOutcome("bus_a", True, 0.58, "az_s"),
                                           sc.FailureGroupOutcome("bow_room", False, 1.0)))),
        "command": sc.command_payload(t_s=t, seq=seq, mode="auto_position", names=["bow", "stern"],
                                      thrust_n=[12e3, -8e3], azimuth_rad=[math.pi / 2, 0.0]),
        "feedback": sc.feedback_payload(t_s=t, seq=seq, names=["bow", "stern"], thrust_n=[11.5e3, math.nan],
                                        azimuth_rad=[math.pi / 2, 0.0], ready=[True, False]),
    }


def _state(now_s: float = 10.0, rx_t_s: float = 9.8, **overrides: Any) -> MonitorState:
    topics = {topic: TopicView(message=sc.parse_message(topic, payload), rx_t_s=rx_t_s, received=1)
              for topic, payload in _payloads().items()}
    fields: dict[str, Any] = {"topics": topics, "peers": 2, "alive": {
        "controller": AliveState(present=True, seen=True, since_t_s=1.0, losses=0),
        "plant": AliveState(present=False, seen=True, since_t_s=8.0, losses=1)}}
    fields.update(overrides)
    return MonitorState(vessel="supply", now_s=now_s, **fields)


def _text(renderable: Any, width: int = 140) -> str:
    console = Console(record=True, width=width, file=io.StringIO())
    console.print(renderable)
    return console.export_text()


def test_render_shows_every_part() -> None:
    text = _text(render(_state()))
    assert "vessel supply" in text and "mode auto_position" in text
    assert "controller ● alive" in text and "plant ✖ LOST" in text
    assert "12.34" in text and "-5.50" in text          # north / east estimate
    assert "350.0" in text                             # heading as a bearing in degrees
    assert "2.34" in text                              # north error 12.34 - 10.00
    assert "-10.0" in text                             # heading error wrapped: 350° vs 0° is -10°
    assert "62.5%" in text and "12.5%" in text         # MMAE weights
    assert "ω̂ = 0.710" in text and "moderate" in text  # seed 001 Table I
    assert "6360" in text                              # MRAC surge mass in tonnes
    assert "gyro2" in text and "frozen" in text
    assert "[bold]no change[/bold]" in text           # payload text is never markup
    assert "north [m]" in text and "X [kN]" in text    # unit brackets survive
    assert "bow" in text and "stern" in text and "no (trip)" in text
    assert "GYRO2_FROZEN" in text and "(1 active, 1 cleared)" in text
    assert "p99 187 µs" in text and "missed 3" in text and "host steal 1.5 %" in text
    # the last operator request (dpcontrol setpoint's answer), its age in the controller's time
    assert "last request refused 12 s ago: auto_heading refused: no estimate yet; mode standby" in text
    assert "worst case:  bus_a holds (az_s 58 %)  bow_room WOULD NOT HOLD" in text  # the consequence analysis


def _with(state: MonitorState, topic: str, payload: bytes) -> MonitorState:
    topics = dict(state.topics)
    topics[topic] = TopicView(message=sc.parse_message(topic, payload), rx_t_s=state.now_s - 0.2, received=1)
    return MonitorState(vessel=state.vessel, now_s=state.now_s, topics=topics, alive=state.alive, peers=state.peers,
                        wall_s=state.wall_s)


def _status(**fields: Any) -> bytes:
    return sc.status_payload(t_s=101.0, seq=1, mode="auto_position", **fields)


def test_forces_take_the_unit_of_their_magnitude_per_column() -> None:
    # a 1:70 model: newtons (no more "0.0 kN" everywhere); yaw moment column in N·m on its own
    model = sc.control_payload(t_s=101.0, seq=1, controller="pid", tau_b=[1.5, -0.82, 0.2],
                               tau_achieved_b=[1.4, -0.8, 0.19])
    text = _text(render(_with(_state(), "control", model)))
    assert "X [N]" in text and "Y [N]" in text and "N [N·m]" in text and "kN" not in text.split("Control")[1][:400]
    assert "1.50" in text and "-0.82" in text and "0.20" in text
    # a tanker: meganewtons in X, kilonewtons in Y, within one table
    tanker = sc.control_payload(t_s=101.0, seq=1, controller="pid", tau_b=[1.25e6, -3.5e4, 2.0e7])
    text = _text(render(_with(_state(), "control", tanker)))
    assert "X [MN]" in text and "Y [kN]" in text and "N [MN·m]" in text
    assert "1.25" in text and "-35.0" in text and "20.0" in text
    # thrust columns too: the model's thrusters in N
    command = sc.command_payload(t_s=101.0, seq=1, mode="auto_position", names=["bow", "stern"],
                                 thrust_n=[0.9, -0.35], azimuth_rad=[math.pi / 2, 0.0])
    text = _text(render(_with(_state(), "command", command)))
    assert "cmd [N]" in text and "0.90" in text and "-0.35" in text


def test_mrac_masses_read_against_nominal_with_what_each_does_coloured() -> None:
    """``MRAC mass / nominal``: per DOF the ratio and the state, coloured as the other states (learning green,
    held cyan, suspended by the supervision red, configured off dim); no row from a daemon that does not send
    them."""
    control = sc.control_payload(t_s=101.0, seq=1, controller="mrac", tau_b=[1e3, 2e3, 3e3],
                                 mrac_mass=[7.0e6, 6.86e6, 4.0e9], mrac_damping=[1e5, 2e5, 3e8],
                                 mrac_nominal=[6.25e6, 7.0e6, 4.0e9], mrac_state=("adapting", "frozen", "suspended"))
    panel = render(_with(_state(), "control", control))
    text = _text(panel)
    row = next(line for line in text.splitlines() if "MRAC mass /" in line)  # (the label wraps: "nominal" below)
    assert "1.12× adapting" in row and "0.98× frozen" in row and "1.00× suspended" in row
    console = Console(record=True, width=140, file=io.StringIO(), color_system="truecolor", force_terminal=True)
    console.print(panel)
    styled = console.export_text(styles=True)
    green, cyan, red = (Console(color_system="truecolor", force_terminal=True, file=io.StringIO()) for _ in range(3))
    for console_, word, style in ((green, "1.12× adapting", "green"), (cyan, "0.98× frozen", "cyan"),
                                  (red, "1.00× suspended", "bold red")):
        console_.print(Text(word, style=style), end="")
        assert console_.file.getvalue() in styled, word  # the cell drawn in its state's style
    off = sc.control_payload(t_s=101.0, seq=1, controller="mrac", tau_b=[1e3, 2e3, 3e3], mrac_mass=[6.25e6] * 3,
                             mrac_damping=[1e5] * 3, mrac_nominal=[6.25e6] * 3, mrac_state=("off",) * 3)
    assert "1.00× off" in _text(render(_with(_state(), "control", off)))
    assert "MRAC mass /" not in _text(render(_state()))  # an older daemon: masses only


def test_alarms_show_age_and_utc_time_full_codes_and_counts() -> None:
    code = "thrusters.drives_lost_" + "x" * 40  # 62 characters: the schema allows 64
    status = _status(alarms=[sc.Alarm(code, "alarm", "drives lost", 41.0, True),
                             sc.Alarm("GNSS1_STALE", "warning", "cleared", 50.0, False),
                             sc.Alarm("GNSS2_STALE", "warning", "cleared too", 55.0, False)])
    wall = 1_790_000_000.0  # 2026-09-21 14:13:20 UTC
    state = _with(MonitorState(vessel="supply", now_s=10.0, wall_s=wall), "status", status)
    text = _text(render(state), width=200)
    assert code in text                                   # not cut
    assert "(1 active, 2 cleared)" in text
    # raised 60 s before the status (daemon clock), which arrived 0.2 s ago: 60.2 s old, at 14:12:19.8 UTC
    assert "60 s" in text and "14:12:19" in text
    assert "since_t_s" not in text and "41.0" not in text  # never the daemon's monotonic seconds


def test_sea_state_reads_for_the_hull_and_shows_the_peak_period() -> None:
    def mmae_text(omega_hat: float, length_m: float) -> str:
        payload = sc.mmae_payload(t_s=101.0, seq=1, omegas_rad_s=[0.56, 0.73, 0.80], weights=[0.2, 0.3, 0.5],
                                  omega_hat_rad_s=omega_hat, sea_states=sc.SeaStateTable.froude_scaled(length_m))
        return _text(render(_with(_state(), "mmae", payload)), width=200)

    # CyberShip II (1.255 m): a 1.2 rad/s sea is far longer than its "high" band, not "high" at full scale
    text = mmae_text(1.2, 1.255)
    assert "Tp 5.2 s" in text and "long swell" in text and "sea state: high" not in text
    assert "sea state: calm" in mmae_text(8.0, 1.255)           # short model-basin waves
    assert "sea state: calm" in mmae_text(0.84, 100.0)           # seed 001's calm on its 100 m vessel
    assert "sea state: high" in mmae_text(0.56, 100.0)


def test_plant_and_feedback_come_from_the_daemons_status() -> None:
    # this monitor's own session sees no plant and no feedback; the daemon hears both
    alive = {"controller": AliveState(True, True, 1.0, 0), "plant": AliveState(False, False, None, 0)}
    state = MonitorState(vessel="supply", now_s=10.0, alive=alive)
    text = _text(render(_with(state, "status", _status(drives=sc.DrivesSeen(True, True, 0.1)))), width=200)
    assert "plant ● alive" in text and "not seen" not in text
    assert "feedback (daemon's 0.1 s)" in text
    text = _text(render(_with(state, "status", _status(drives=sc.DrivesSeen(False, True, None)))), width=200)
    assert "plant ✖ LOST" in text and "feedback (none received by the daemon)" in text
    # an older daemon that does not say: the monitor's own view, marked as such
    text = _text(render(_with(state, "status", _status())), width=200)
    assert "plant ○ not seen (monitor's view)" in text and "feedback (no data here)" in text


def test_render_with_no_data_at_all() -> None:
    text = _text(render(MonitorState(vessel="v1", now_s=0.0)))
    assert text.count("no data") >= 8
    assert "controller: ?" in text
    assert "last request" not in text  # (none yet)


def test_render_with_some_topics_missing_and_some_stale() -> None:
    state = _state(now_s=20.0, rx_t_s=19.9)
    topics = dict(state.topics)
    del topics["mmae"], topics["feedback"]
    topics["status"] = TopicView(message=topics["status"].message, rx_t_s=12.0, received=1)
    text = _text(render(MonitorState(vessel="supply", now_s=20.0, topics=topics)))
    assert "MMAE (no data)" in text
    assert "feedback (no data here)" in text  # (the status says nothing of the drives: this session's view)
    assert "stale 8.0 s" in text
    assert "12.34" in text  # the rest still shows


def test_render_reports_rejections() -> None:
    state = _state()
    topics = dict(state.topics)
    topics["feedback"] = TopicView(rejected=4, last_rejection="not_finite: thrusters[0].thrust_n")
    text = _text(render(MonitorState(vessel="supply", now_s=10.0, topics=topics)))
    assert "rejected feedback: 4" in text and "not_finite" in text


_ODD = st.recursive(st.none() | st.booleans() | st.integers() | st.just(10**400) | st.floats() | st.text(max_size=8),
                    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=6), inner, max_size=3),
                    max_leaves=10)


@given(st.data())
@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
def test_render_never_raises_on_odd_content(data: st.DataObject) -> None:
    # render() is fed validated messages, but it must not trust them: mutate fields at random.
    topics = {}
    for topic, payload in _payloads().items():
        message = dict(sc.parse_message(topic, payload))
        for key in data.draw(st.lists(st.sampled_from(sorted(message)), max_size=3), label=topic):
            message[key] = data.draw(_ODD)
        topics[topic] = TopicView(message=message, rx_t_s=data.draw(st.none() | st.floats(0, 20)))
    text = _text(render(MonitorState(vessel="x", now_s=10.0, topics=topics)))
    assert "vessel x" in text


def test_run_monitor_once_over_loopback() -> None:
    daemon, endpoint = open_listener("montest")
    try:
        publishers = {topic: daemon.publisher(topic) for topic in MONITOR_TOPICS}
        daemon.declare_alive("controller")
        out = io.StringIO()
        result: list[int] = []
        thread = threading.Thread(target=lambda: result.append(run_monitor(
            "montest", [endpoint], once=True, wait_s=TIMEOUT_S,
            console=Console(file=out, width=140, force_terminal=False))))
        thread.start()
        try:
            for topic, publisher in publishers.items():
                assert publisher.wait_matched(TIMEOUT_S), topic
            for topic, payload in _payloads().items():
                assert publishers[topic].put(payload)
        finally:
            thread.join(TIMEOUT_S + 5.0)
        assert not thread.is_alive()
        assert result == [0]
        text = out.getvalue()
        assert "controller ● alive" in text and "plant ○ not seen" in text
        assert "12.34" in text and "62.5%" in text and "GYRO2_FROZEN" in text
        assert "no data" not in text
    finally:
        daemon.close()


def test_run_monitor_once_with_nobody_there_says_so(capsys: Any) -> None:
    out = io.StringIO()
    endpoint = loopback_endpoint(free_tcp_port())
    code = run_monitor("ghost", [endpoint], once=True, wait_s=0.2, console=Console(file=out, width=100))
    assert code == 1
    assert "no data" in out.getvalue()
    # and on stderr, on one line, what was tried and what to check
    (line,) = capsys.readouterr().err.splitlines()
    assert line == (f"dpcontrol monitor: nothing heard from vessel 'ghost' within 0.2 s (connecting to {endpoint}; "
                    "0 zenoh peers): is `dpcontrol run` up, with this vessel_id, and is the endpoint its zenoh.listen?")


def test_run_monitor_live_for_a_duration() -> None:
    out = io.StringIO()
    code = run_monitor("ghost", [loopback_endpoint(free_tcp_port())], duration_s=0.3, refresh_hz=20.0,
                       console=Console(file=out, width=100, force_terminal=False))
    assert code == 0
    assert "dpcontrol monitor" in out.getvalue()


def test_run_monitor_rejects_bad_arguments(capsys: Any) -> None:
    assert run_monitor("a/b", ["tcp/127.0.0.1:1"], once=True) == 2
    assert "invalid vessel id" in capsys.readouterr().err
    assert run_monitor("ok", ["127.0.0.1:7447"], once=True) == 2
    assert "protocol" in capsys.readouterr().err
    assert run_monitor("ok", ["tcp/127.0.0.1:74470"], once=True) == 2  # zenoh would accept it, and never connect
    assert "port of 0-65535" in capsys.readouterr().err


def test_cli_arguments() -> None:
    parser = argparse.ArgumentParser()
    add_arguments(parser)
    args = parser.parse_args(["--vessel", "supply", "--connect", "tcp/10.0.0.1:7447", "--once", "--wait", "5"])
    assert (args.vessel, args.connect, args.once, args.wait, args.duration) == (
        "supply", ["tcp/10.0.0.1:7447"], True, 5.0, None)
