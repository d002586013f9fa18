"""The emulator's Zenoh side against a fake controller (this tests the emulator, not the daemon).

The fake controller listens on a free loopback port named in the controller configuration (the
emulator connects to it), declares ``alive/controller``, publishes a status at 10 Hz and thruster
commands while told to, and answers a mode request by reporting that mode. In one run:

1. a command with an unknown thruster and a non-JSON payload are rejected and counted;
2. commands: the plant's drives follow (feedback shows thrust and rudder angle);
3. commands stop: after the drive timeout (1 s) the thrust ramps to zero;
4. commands again, then the controller's liveliness token is undeclared with the last one: the
   drives ramp to zero at once (``command_lost``), not after the timeout;
5. throughout: the scenario's setpoints arrive on ``dp/<vessel>/setpoint`` at their times, and the
   ``--engage`` handshake ends with the controller in ``auto_position``.
"""

from __future__ import annotations

import csv
import itertools
import threading
from pathlib import Path
from typing import Any

import pytest

from interfaces.zenoh import schemas as sc
from interfaces.zenoh.loopback import open_listener
from interfaces.zenoh.node import Inbox
from sim_plant.emulator import HilOptions

VESSEL = "hil-zenoh"
NAMES = ["bow_tunnel", "main_port", "main_starboard"]
THRUST_N = 1.5      # cybership2 main_port: max 2 N, time constant 0.3 s, 4 N/s
RUDDER_RAD = 0.2
TIMEOUT_S = 1.0     # the scenario's drive command timeout
UP_N = 0.97 * THRUST_N
DOWN_N = 0.05


class FakeController(threading.Thread):
    """Status at 10 Hz, commands while ``commanding``, and a mode request turns into that status."""

    def __init__(self, node: Any) -> None:
        super().__init__(name="fake-controller", daemon=True)
        self.node = node
        self.status = node.publisher("status")
        self.command = node.publisher("command")
        self.setpoints = node.subscribe("setpoint", Inbox(maxlen=1000))
        self.mode = "standby"
        self.commanding = threading.Event()
        self.received_setpoints: list[sc.SetpointRequest] = []
        self.last_seq = -1
        self._halt = threading.Event()
        self._lock = threading.Lock()

    def run(self) -> None:
        while not self._halt.wait(0.1):  # the controller's own 10 Hz cycle
            for item in self.setpoints.sink.drain():
                self.received_setpoints.append(item.message)
                if item.message.mode is not None:
                    self.mode = item.message.mode
            # (what the operator waits for before asking for DP: references ok, drives heard, thrusters up)
            self.status.put(sc.status_payload(
                t_s=0.0, seq=self.status.next_seq(), mode=self.mode,
                sensors=[sc.SensorHealth("gnss1", "position", "ok"), sc.SensorHealth("gyro1", "heading", "ok")],
                thrusters=[sc.ThrusterAvailability(name, True) for name in NAMES],
                drives=sc.DrivesSeen(present=True, seen=True, feedback_age_s=0.1)))
            with self._lock:
                if self.commanding.is_set():
                    seq = self.command.next_seq()
                    self.command.put(sc.command_payload(t_s=0.0, seq=seq, mode="auto_position", names=NAMES,
                                                        thrust_n=[0.0, THRUST_N, 0.0],
                                                        azimuth_rad=[1.5707963, RUDDER_RAD, 0.0]))
                    self.last_seq = seq

    def stop_commanding(self) -> int:
        """Stop; returns the seq of the last command sent."""
        with self._lock:
            self.commanding.clear()
            return self.last_seq

    def close(self) -> None:
        self._halt.set()
        if self.is_alive():
            self.join(10.0)


class Feedback:
    """Every feedback message the fake controller receives, with a wait on a condition of the newest."""

    def __init__(self, node: Any) -> None:
        self.subscriber = node.subscribe("feedback", Inbox(maxlen=100000))
        self.items: list[sc.FeedbackMessage] = []

    def wait(self, predicate: Any, timeout_s: float) -> bool:
        sink = self.subscriber.sink
        seen = len(self.items)
        while True:
            self.items += [r.message for r in sink.drain()]
            if len(self.items) > seen and predicate(self.items[-1]):
                return True
            seen = len(self.items)
            if not sink.wait_count(sink.count + 1, timeout_s):
                return False


def thrust(message: sc.FeedbackMessage, name: str = "main_port") -> float:
    return next(t.thrust_n for t in message.thrusters if t.name == name)


@pytest.fixture(scope="module")
def run(rig: Any, tmp_path_factory: pytest.TempPathFactory, closing: list[Any]) -> dict[str, Any]:
    folder = tmp_path_factory.mktemp("hil_zenoh")
    node, endpoint = open_listener(VESSEL, lease_s=1.0)
    closing.append(node)
    feedback = Feedback(node)
    plant_alive = node.watch_alive("plant")
    controller = rig.write_yaml(folder / "vessel.yaml", {
        "vessel_id": VESSEL,
        "transports": [{"name": "serial0", "protocol": "nmea0183", "port": str(folder / "ttyGNSS")}],
        "sensors": [{"name": "gnss1", "kind": "position", "transport": "serial0"}],
        "zenoh": {"listen": [endpoint]},
    })
    scenario = rig.write_yaml(folder / "scenario.yaml", {
        "name": "hil-zenoh", "vessel": "cybership2", "duration_s": 60, "seed": 5,
        "plant": {"thruster_timeout_s": TIMEOUT_S},
        "setpoints": [{"t_s": 0, "north_m": 0, "east_m": 0, "heading_deg": 0},
                      {"t_s": 1.5, "north_m": 2, "east_m": 0, "heading_deg": 10}],
        "sensors": [{"name": "gnss1", "kind": "gnss", "rate_hz": 1}],
    })
    out = folder / "out"
    emulator = rig.EmulatorRun(scenario, controller, HilOptions(out_dir=out, engage=True, engage_retry_s=0.3))
    closing.append(emulator)
    fake = FakeController(node)
    closing.append(fake)
    emulator.start()
    steps: dict[str, Any] = {"plant_alive": plant_alive.wait_for(True, rig.WAIT_S)}
    # 1. rubbish on the command key
    bad = node.publisher("command")
    assert bad.wait_matched(rig.WAIT_S)
    bad.put(sc.command_payload(t_s=0.0, seq=0, mode="auto_position", names=["nonexistent"], thrust_n=[1.0],
                               azimuth_rad=[0.0]))
    bad.put(b"\x00 not json")
    # 2. the controller comes up and commands
    token = node.declare_alive("controller")
    fake.start()
    fake.commanding.set()
    steps["up1"] = feedback.wait(lambda m: thrust(m) >= UP_N, rig.WAIT_S)
    # 3. silence: the drive timeout
    steps["seq1"] = fake.stop_commanding()
    steps["down1"] = feedback.wait(lambda m: thrust(m) <= DOWN_N, rig.WAIT_S)
    # 4. commands again, then the controller goes away with its last command
    fake.commanding.set()
    steps["up2"] = feedback.wait(lambda m: thrust(m) >= UP_N, rig.WAIT_S)
    steps["seq2"] = fake.stop_commanding()
    token.close()
    steps["down2"] = feedback.wait(lambda m: thrust(m) <= DOWN_N, rig.WAIT_S)
    fake.close()
    emulator.emulator.stop()
    summary = emulator.join()
    emulator.close()
    steps["plant_gone"] = plant_alive.wait_for(False, rig.WAIT_S)

    def read(name: str) -> list[dict[str, str]]:
        with open(out / name, newline="", encoding="utf-8") as stream:
            return list(csv.DictReader(stream))

    return {"summary": summary, "steps": steps, "feedback": feedback.items, "fake": fake,
            "commands": read("commands.csv"), "feedback_csv": read("feedback.csv")}


def _command_time(run: dict[str, Any], seq: int) -> float:
    return next(float(r["t_s"]) for r in run["commands"] if int(r["seq"]) == seq and r["name"] == "main_port")


def _first_drop_after(run: dict[str, Any], t_s: float) -> float:
    """Plant time of the first feedback after ``t_s`` whose main_port thrust is below its plateau."""
    return next(m.t_s for m in run["feedback"] if m.t_s > t_s and thrust(m) < UP_N)


def test_rubbish_commands_are_rejected_and_counted(run: dict[str, Any]) -> None:
    commands = run["summary"]["zenoh"]["commands"]
    assert commands["rejected"] == 2
    assert commands["accepted"] == run["summary"]["counts"]["commands_applied"] > 0
    assert all(r["name"] in NAMES for r in run["commands"])


def test_the_drives_follow_the_commands(run: dict[str, Any]) -> None:
    steps = run["steps"]
    assert steps["plant_alive"] and steps["up1"] and steps["up2"]
    plateau = [m for m in run["feedback"] if thrust(m) >= UP_N]
    assert plateau and all(abs(thrust(m) - THRUST_N) < 0.05 * THRUST_N for m in plateau)
    assert all(abs(thrust(m, "bow_tunnel")) < 1e-9 and abs(thrust(m, "main_starboard")) < 1e-9 for m in plateau)
    rudder = [next(t.azimuth_rad for t in m.thrusters if t.name == "main_port") for m in plateau]
    assert all(abs(a - RUDDER_RAD) < 1e-6 for a in rudder)
    assert all(t.ready for m in run["feedback"] for t in m.thrusters)
    # the feedback the fake controller got is what the emulator says it published, at 10 Hz of plant time
    published = sorted({float(r["t_s"]) for r in run["feedback_csv"]})
    assert {m.t_s for m in run["feedback"]} <= set(published)
    assert all(abs(b - a - 0.1) < 1e-6 for a, b in itertools.pairwise(published))


def test_a_silent_controller_makes_the_drives_ramp_to_zero_after_the_timeout(run: dict[str, Any]) -> None:
    assert run["steps"]["down1"]
    t_last = _command_time(run, run["steps"]["seq1"])
    t_drop = _first_drop_after(run, t_last)
    # thrust holds until the command is TIMEOUT_S old (one 0.05 s substep and one 0.1 s feedback tick of slack)
    assert t_last + TIMEOUT_S - 0.05 <= t_drop <= t_last + TIMEOUT_S + 0.2


def test_losing_the_controllers_liveliness_ramps_to_zero_at_once(run: dict[str, Any]) -> None:
    summary = run["summary"]
    assert run["steps"]["down2"]
    assert [e["present"] for e in summary["liveliness"]] == [True, False]
    assert summary["counts"]["command_lost_events"] == 1
    t_lost = summary["liveliness"][-1]["t_s"]
    t_last = _command_time(run, run["steps"]["seq2"])
    t_drop = _first_drop_after(run, t_last)
    assert t_drop <= t_lost + 0.2
    assert t_drop < t_last + TIMEOUT_S - 0.3  # not the drive timeout


def test_the_scenarios_setpoints_arrive_at_their_times(run: dict[str, Any]) -> None:
    received = run["fake"].received_setpoints
    targets = [(s.north_m, s.east_m, round(s.heading_rad, 6)) for s in received if s.north_m is not None]
    assert (2.0, 0.0, round(0.17453292519943295, 6)) in targets
    published = run["summary"]["setpoints"]
    second = [p for p in published if p["t_s"] == 1.5 and not p["resent"]]
    assert len(second) == 1 and 1.5 <= second[0]["sent_t_s"] < 1.5 + 0.3
    # the target in force is sent again when the controller appears
    assert any(p["resent"] for p in published)


def test_engage_brings_the_controller_into_dp(run: dict[str, Any]) -> None:
    engage = run["summary"]["engage"]
    assert engage["requested"] and engage["engaged"] and engage["mode"] == "auto_position"
    assert engage["attempts"] >= 1 and not engage["gave_up"]
    assert any(s.mode == "auto_position" for s in run["fake"].received_setpoints)


def test_the_plant_token_comes_and_goes(run: dict[str, Any]) -> None:
    assert run["steps"]["plant_gone"]
    assert run["summary"]["stopped_by"] == "stop"


def test_without_engage_the_plant_sends_no_operator_request(rig: Any, tmp_path: Path, closing: list[Any]) -> None:
    """The scenario's set-points are operator requests: a plant that only stands in for the drives (no
    --engage) sends none, neither at their times nor to a controller it sees appear."""
    node, endpoint = open_listener(VESSEL + "-quiet", lease_s=1.0)
    closing.append(node)
    requests = node.subscribe("setpoint", Inbox(maxlen=100))
    controller = rig.write_yaml(tmp_path / "vessel.yaml", {
        "vessel_id": VESSEL + "-quiet",
        "transports": [{"name": "serial0", "protocol": "nmea0183", "port": str(tmp_path / "ttyGNSS")}],
        "sensors": [{"name": "gnss1", "kind": "position", "transport": "serial0"}],
        "zenoh": {"listen": [endpoint]},
    })
    scenario = rig.write_yaml(tmp_path / "scenario.yaml", {
        "name": "quiet", "vessel": "cybership2", "duration_s": 60, "seed": 5,
        "setpoints": [{"t_s": 0, "north_m": 0, "east_m": 0, "heading_deg": 0},
                      {"t_s": 0.5, "north_m": 2, "east_m": 0, "heading_deg": 10}],
        "sensors": [{"name": "gnss1", "kind": "gnss", "rate_hz": 1}],
    })
    fake = FakeController(node)  # alive (its token) and publishing status, as a daemon would
    closing.append(fake)
    node.declare_alive("controller")
    fake.start()
    emulator = rig.EmulatorRun(scenario, controller, HilOptions(out_dir=tmp_path / "out"))
    closing.append(emulator)
    emulator.start()
    assert node.wait_for_peers(1, rig.WAIT_S)
    # 2.5 s of plant time: both set-points are due, the controller has been seen; nothing may arrive
    assert not requests.sink.wait_count(1, 2.5)
    emulator.emulator.stop()
    summary = emulator.join()
    assert summary["setpoints"] == [] and not summary["engage"]["requested"]
    assert emulator.emulator.controller_seen
