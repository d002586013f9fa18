"""``dpcontrol setpoint``: one operator request to a running controller, and its answer. A real daemon (in this
process, links down: it runs in standby and publishes every cycle) and the command on real Zenoh sessions on
127.0.0.1: an applied set-point (exit 0, what is in force), a refused mode (exit 1, why), a relative move
resolved against the set-point in force, a latched thruster failure cleared, requests refused before sending
(exit 2, nothing reaches the controller), no controller (exit 1), and two consoles sending at once."""

from __future__ import annotations

import io
import json
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

from dpcontrol.cli import main
from dpcontrol.runtime.config import parse_config
from dpcontrol.service.daemon import Daemon
from dpcontrol.setpoint import run_setpoint
from interfaces.systemd import SystemdNotifier
from interfaces.zenoh import schemas
from interfaces.zenoh.loopback import free_tcp_port
from interfaces.zenoh.node import Inbox, ZenohNode
from interfaces.zenoh.session_config import ZenohConfig

pytestmark = pytest.mark.hil

VESSEL = "operator"
TIMEOUT = "30"  # generous bound for zenoh on a loaded 2-core machine; an answer takes one cycle


@pytest.fixture(scope="module")
def controller(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[Daemon, str]]:
    tmp_path = tmp_path_factory.mktemp("operator")
    port = free_tcp_port()
    config = {"vessel_id": VESSEL, "vessel": "cybership2", "loop": {"rate_hz": 10},
              "transports": [{"name": "serial0", "protocol": "nmea0183", "port": str(tmp_path / "no-tty")}],
              "sensors": [{"name": "gnss1", "kind": "position", "transport": "serial0"},
                          {"name": "gyro1", "kind": "heading", "transport": "serial0"}],
              "zenoh": {"listen": [f"tcp/127.0.0.1:{port}"]}}
    daemon = Daemon(parse_config(config), notifier=SystemdNotifier(environ={}))
    codes: list[int] = []
    thread = threading.Thread(target=lambda: codes.append(daemon.run(duration_s=300.0, install_signals=False)))
    thread.start()
    try:
        yield daemon, f"tcp/127.0.0.1:{port}"
    finally:
        daemon.request_stop()
        thread.join(30.0)
    assert not thread.is_alive() and codes == [0]


def _ask(endpoint: str, *options: str, capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    code = main(["setpoint", "--vessel", VESSEL, "--connect", endpoint, "--timeout", TIMEOUT, *options])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_a_set_point_is_applied_and_a_move_resolves_against_it(controller: tuple[Daemon, str],
                                                               capsys: pytest.CaptureFixture[str]) -> None:
    daemon, endpoint = controller
    code, out, err = _ask(endpoint, "--north", "5", "--east", "-3", "--heading", "90", capsys=capsys)
    assert code == 0, err
    assert out == f"{VESSEL}: applied: mode standby, set-point 5.00 m N, -3.00 m E, heading 90.0°\n"
    np.testing.assert_allclose(daemon.controller.setpoint_ned, [5.0, -3.0, np.pi / 2])

    # 2 m ahead along heading 90° is 2 m east; a 45° turn to starboard; as JSON
    code, out, err = _ask(endpoint, "--move-surge", "2", "--turn", "45", "--json", capsys=capsys)
    assert code == 0, err
    answer = json.loads(out)
    assert answer["outcome"] == "applied" and answer["vessel"] == VESSEL
    assert answer["detail"] == "mode standby, set-point 5.00 m N, -1.00 m E, heading 135.0°"
    assert daemon.controller.last_request is not None and daemon.controller.last_request.seq == answer["seq"]


def test_a_refused_mode_says_why(controller: tuple[Daemon, str], capsys: pytest.CaptureFixture[str]) -> None:
    daemon, endpoint = controller
    code, out, err = _ask(endpoint, "--mode", "auto_position", capsys=capsys)
    assert code == 1 and out == ""
    assert err.startswith(f"dpcontrol setpoint: {VESSEL}: refused: "), err
    assert "mode standby" in err  # what is still in force
    assert daemon.controller.mode.value == "standby"


def test_a_thruster_reset(controller: tuple[Daemon, str], capsys: pytest.CaptureFixture[str]) -> None:
    daemon, endpoint = controller
    daemon.controller.monitor.load_state_dict({"latched": ["main_port"]})  # (as a restart would find it)
    code, out, err = _ask(endpoint, "--reset-thruster", "main_port", capsys=capsys)
    assert code == 0, err
    assert out.startswith(f"{VESSEL}: applied: mode standby, ") and out.endswith("; main_port reset\n")
    assert not daemon.controller.monitor.is_latched("main_port")
    code, out, err = _ask(endpoint, "--reset-thruster", "stern_tunnel", capsys=capsys)
    assert code == 1 and out == ""
    assert "refused: reset_thruster 'stern_tunnel': no such thruster (bow_tunnel, main_port, main_starboard)" in err


def test_two_consoles_sending_in_one_cycle_each_get_their_answer(controller: tuple[Daemon, str]) -> None:
    """The bridge and the shore send at once: each gets the answer to its own request. Two requests put back to
    back on one publisher (microseconds apart: one cycle takes both, bar a cycle starting between them; each has
    its answer either way), then two `run_setpoint` threads at once."""
    daemon, endpoint = controller
    node = ZenohNode(ZenohConfig(connect=(endpoint,)), VESSEL)
    try:
        seen: dict[int, dict[str, Any]] = {}
        statuses: Inbox[Any] = Inbox(maxlen=1000)
        node.subscribe("status", statuses, parse=lambda payload: schemas.parse_message("status", payload))
        publisher = node.publisher("setpoint")
        assert publisher.wait_matched(float(TIMEOUT))
        assert publisher.put(schemas.setpoint_payload(t_s=1.0, seq=901, mode="auto_position"))  # links down: refused
        assert publisher.put(schemas.setpoint_payload(t_s=1.0, seq=902, heading_deg=20.0))
        deadline = time.monotonic() + float(TIMEOUT)
        while not {901, 902} <= seen.keys() and time.monotonic() < deadline:
            received = statuses.get(0.5)
            for outcome in ([] if received is None else received.message.get("requests") or ()):
                seen[outcome["seq"]] = outcome
    finally:
        node.close()
    assert seen[901]["outcome"] == "refused" and seen[901]["detail"].startswith("auto_position refused: ")
    assert seen[902]["outcome"] == "applied" and "heading 20.0°" in seen[902]["detail"]
    assert daemon.controller.mode.value == "standby"

    results: dict[str, tuple[int, str, str]] = {}

    def console(name: str, fields: dict[str, Any]) -> None:
        out, err = io.StringIO(), io.StringIO()
        code = run_setpoint(VESSEL, fields, connect=(endpoint,), timeout_s=float(TIMEOUT), out=out, err=err)
        results[name] = (code, out.getvalue(), err.getvalue())

    consoles = [threading.Thread(target=console, args=("bridge", {"move_north_m": 1.0})),
                threading.Thread(target=console, args=("shore", {"mode": "auto_heading"}))]
    for thread in consoles:
        thread.start()
    for thread in consoles:
        thread.join(2 * float(TIMEOUT))
    assert results["bridge"][0] == 0 and results["bridge"][1].startswith(f"{VESSEL}: applied: "), results
    assert results["shore"][0] == 1 and "refused: auto_heading refused: " in results["shore"][2], results


def test_invalid_requests_are_refused_before_sending(controller: tuple[Daemon, str],
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    daemon, endpoint = controller
    before = daemon.controller.last_request
    for options, reason in ((["--north", "5"], "incomplete"), (["--heading", "370"], "out_of_range"),
                            (["--north", "1", "--east", "1", "--move-north", "2"], "conflict"),
                            (["--move-surge", "5000"], "out_of_range"), ([], "empty")):
        code, out, err = _ask(endpoint, *options, capsys=capsys)
        assert (code, out) == (2, ""), options
        assert f"invalid request ({reason})" in err and err.rstrip().endswith("nothing sent"), err
    with pytest.raises(SystemExit) as exit_info:  # argparse: not a finite number
        main(["setpoint", "--vessel", VESSEL, "--north", "nan", "--east", "0"])
    assert exit_info.value.code == 2
    assert daemon.controller.last_request == before  # nothing reached the controller


def test_the_console_command_end_to_end(controller: tuple[Daemon, str]) -> None:
    _daemon, endpoint = controller
    done = subprocess.run([sys.executable, "-m", "dpcontrol.cli", "setpoint", "--vessel", VESSEL, "--connect",
                           endpoint, "--heading", "-10", "--timeout", TIMEOUT],
                          check=False, capture_output=True, text=True, timeout=120.0)
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith(f"{VESSEL}: applied: mode standby, set-point ") and "heading 350.0°" in done.stdout


def test_no_controller_is_an_error_not_a_hang() -> None:
    out, err = io.StringIO(), io.StringIO()
    fields: dict[str, Any] = {"mode": "standby"}
    code = run_setpoint("nobody", fields, connect=(f"tcp/127.0.0.1:{free_tcp_port()}",), timeout_s=1.0, out=out,
                        err=err)
    assert code == 1 and out.getvalue() == ""
    assert "no controller alive for vessel 'nobody' (dp/nobody/alive/controller) within 1 s" in err.getvalue()
