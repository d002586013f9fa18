"""``dpcontrol console`` without a browser: the request fields a page may post, the address it serves on,
the outline it draws from the daemon's configuration, and the feed (snapshot, trail, acknowledgement) over
real Zenoh sessions on 127.0.0.1. The browser test is tests/hil/test_console_browser.py."""

from __future__ import annotations

import math
import time

import pytest

from dpcontrol.console import (
    ConsoleFeed,
    parse_http_address,
    request_fields_from_json,
    vessel_geometry,
)
from dpcontrol.setpoint import check_request
from interfaces.zenoh import schemas as sc
from interfaces.zenoh.loopback import open_listener
from interfaces.zenoh.node import ZenohNode
from interfaces.zenoh.security import is_loopback_host
from interfaces.zenoh.session_config import ZenohConfig


def test_request_fields_take_only_the_setpoint_options_and_finite_numbers() -> None:
    assert request_fields_from_json({"north_m": "1.5", "east_m": -2, "heading_deg": 10, "mode": ""}) == {
        "north_m": 1.5, "east_m": -2.0, "heading_deg": 10.0}
    assert request_fields_from_json({"reset_thruster": "bow", "turn_deg": None}) == {"reset_thruster": "bow"}
    for bad, why in (([1], "expected a JSON object"), ({"thrust_n": 5}, "unknown field 'thrust_n'"),
                     ({"north_m": "ten"}, "north_m: expected a number"), ({"north_m": "nan"}, "finite"),
                     ({"north_m": True}, "expected a number"), ({"mode": 3}, "mode: expected text"),
                     ({"mode": ""}, "nothing asked")):
        with pytest.raises(ValueError, match=why):
            request_fields_from_json(bad)


def test_the_daemons_parser_judges_what_the_page_sends_as_for_dpcontrol_setpoint() -> None:
    assert check_request({"north_m": 1.0, "east_m": 2.0, "heading_deg": 30.0}) is None
    assert "invalid request" in (check_request({"north_m": 1.0}) or "")   # north and east together
    assert "invalid request" in (check_request({"heading_deg": 400.0}) or "")
    assert "invalid request" in (check_request({"mode": "autopilot"}) or "")


def test_http_address_and_loopback() -> None:
    assert parse_http_address("127.0.0.1:8470") == ("127.0.0.1", 8470)
    assert parse_http_address("[::1]:80") == ("::1", 80)
    for bad in ("8470", ":8470", "host:port", "127.0.0.1:0x", "127.0.0.1:70000"):
        with pytest.raises(ValueError, match="--http"):
            parse_http_address(bad)
    assert is_loopback_host("127.0.0.1") and is_loopback_host("localhost") and is_loopback_host("::1")
    assert is_loopback_host("127.1.2.3")
    assert not is_loopback_host("0.0.0.0") and not is_loopback_host("192.168.1.10")
    assert not is_loopback_host("bridge-pc")


def test_vessel_geometry_from_the_daemons_configuration() -> None:
    geometry = vessel_geometry({"vessel": "supply"})
    assert geometry is not None and geometry["length_m"] == pytest.approx(76.2)
    assert {t["name"] for t in geometry["thrusters"]} >= {"bow_tunnel_1", "azimuth_port"}
    assert all(t["max_thrust_n"] > 0 >= t["min_thrust_n"] for t in geometry["thrusters"])
    assert vessel_geometry({"vessel": "no-such-vessel"}) is None and vessel_geometry(None) is None


def test_feed_snapshot_trail_and_acknowledgement_over_zenoh() -> None:
    daemon, endpoint = open_listener("console-unit")
    node = ZenohNode(ZenohConfig(connect=(endpoint,)), "console-unit")
    try:
        feed = ConsoleFeed(node, "console-unit")
        assert node.wait_for_peers(1, 20.0)
        estimate, status = daemon.publisher("estimate"), daemon.publisher("status")
        assert estimate.wait_matched(20.0) and status.wait_matched(20.0)

        def publish(north: float, alarm_since: float) -> None:
            estimate.put(sc.estimate_payload(t_s=1.0, seq=1, estimator="mmae", eta_ned=[north, 2.0, 0.1],
                                             nu_b=[0.0, 0.0, 0.0], bias=[0.0, 0.0, 0.0], eta_wf_ned=[0.0, 0.0, 0.0],
                                             covariance_diag=[1.0]))
            status.put(sc.status_payload(t_s=10.0, seq=1, mode="auto_position",
                                         alarms=[sc.Alarm("gnss1.frozen", "alarm", "frozen", alarm_since, True)]))

        def wait_for(predicate: object) -> dict:
            deadline = time.monotonic() + 20.0
            while time.monotonic() < deadline:
                snapshot = feed.snapshot()
                if predicate(snapshot):  # type: ignore[operator]
                    return snapshot
                time.sleep(0.05)
            raise AssertionError(feed.snapshot())

        publish(1.0, 4.0)
        snap = wait_for(lambda s: s["topics"]["estimate"] and s["topics"]["status"])
        assert snap["topics"]["estimate"]["message"]["pose_n"]["north_m"] == 1.0
        assert snap["topics"]["mmae"] is None and snap["acknowledged"] == []
        assert snap["trail_tip"][1:] == (1.0, 2.0) and abs(snap["trail_tip"][0] - time.time()) < 5.0
        feed.acknowledge("gnss1.frozen", 4.0)
        assert feed.snapshot()["acknowledged"] == [["gnss1.frozen", 4.0]]
        time.sleep(TRAIL_GAP_S)
        publish(1.5, 8.0)  # raised again (a new since): no longer acknowledged; the trail grows
        snap = wait_for(lambda s: s["topics"]["estimate"]["message"]["pose_n"]["north_m"] == 1.5
                        and s["topics"]["status"]["message"]["alarms"][0]["since_t_s"] == 8.0)
        assert snap["acknowledged"] == []
        assert [point[1] for point in feed.trail()] == [1.0, 1.5]
        assert all(math.isfinite(point[0]) for point in feed.trail())
    finally:
        node.close()
        daemon.close()


TRAIL_GAP_S = 0.6  # more than the trail's 0.5 s spacing


def test_a_port_in_use_is_one_line_and_exit_1(capsys: pytest.CaptureFixture[str]) -> None:
    import socket  # noqa: PLC0415

    from dpcontrol.console import run_console  # noqa: PLC0415

    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        assert run_console("v1", ZenohConfig(), http=f"127.0.0.1:{port}") == 1
    err = capsys.readouterr().err
    assert err.startswith(f"dpcontrol console: cannot serve on 127.0.0.1:{port}: ") and len(err.splitlines()) == 1
    assert run_console("v1", ZenohConfig(), http="127.0.0.1:http") == 2


def test_a_capability_file_is_read_as_sim_plant_capability_writes_it(tmp_path) -> None:
    import json  # noqa: PLC0415

    from dpcontrol.console import load_capability  # noqa: PLC0415
    from sim_plant.cli import main as sim_plant_main  # noqa: PLC0415

    assert sim_plant_main(["capability", "supply", "--out", str(tmp_path), "--directions", "8",
                           "--failed", "worst"]) == 0
    cap = load_capability(tmp_path / "capability.json")
    assert len(cap["directions_deg"]) == 8 and cap["cases"][0]["case"] == "intact"
    assert len(cap["cases"]) == 2 and all(len(c["max_wind_mps"]) == 8 for c in cap["cases"])
    bad = tmp_path / "bad.json"
    for text, words in (("not json", "Expecting value"), ("[1, 2]", "capability.json"),
                        (json.dumps({"directions_deg": [0, 90], "max_wind_mps": [1.0]}), "max_wind_mps")):
        bad.write_text(text, encoding="utf-8")
        with pytest.raises(ValueError, match=words):
            load_capability(bad)
    with pytest.raises(ValueError, match="No such file"):
        load_capability(tmp_path / "missing.json")
