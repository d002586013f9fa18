"""``dpcontrol console`` in a real headless browser (Debian's Chromium through its chromedriver, Selenium),
against the shipped CyberShip II HIL pair running as two processes (:mod:`hil_pair`):

* the page loads and shows the pose of the running daemon within a second, and keeps updating;
* a set-point entered in the page goes through the request path of ``dpcontrol setpoint``: the page shows the
  controller's answer and the daemon's published set-point becomes it (heard by a Zenoh session of the test's
  own, not through the console);
* a console started without ``--allow-actions`` shows no actions and refuses a request posted to it anyway.

Screenshots are taken into the test's folder; with ``DPCONTROL_SCREENSHOTS=docs/img`` they are kept there
(how docs/console.md's pictures are made).
"""

from __future__ import annotations

import json
import math
import os
import queue
import subprocess
import sys
import threading
import time
import urllib.error
import urllib.request
from pathlib import Path
from typing import Any

import pytest
from hil_pair import ROOT, running_pair

from interfaces.zenoh.loopback import free_tcp_port
from interfaces.zenoh.node import LatestSlot, ZenohNode
from interfaces.zenoh.session_config import ZenohConfig
from sim_plant.cli import main as sim_plant_main

pytestmark = [pytest.mark.hil, pytest.mark.slow]

CHROMIUM, CHROMEDRIVER = "/usr/bin/chromium", "/usr/bin/chromedriver"
BROWSER_FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", "--no-first-run", "--window-size=1600,1250")
WAIT_S = 60.0
SETPOINT = (0.5, 0.3, 10.0)  # north [m], east [m], heading [deg]: a small move for the 1.26 m model

if not (os.access(CHROMIUM, os.X_OK) and os.access(CHROMEDRIVER, os.X_OK)):
    pytest.skip("Debian's chromium and chromium-driver are not installed (`make test` installs them: "
                ".ci/install-test-browser)", allow_module_level=True)

from selenium import webdriver  # noqa: E402 - after the skip: only with a browser to drive
from selenium.webdriver.chrome.options import Options  # noqa: E402
from selenium.webdriver.chrome.service import Service  # noqa: E402
from selenium.webdriver.common.by import By  # noqa: E402
from selenium.webdriver.support.ui import WebDriverWait  # noqa: E402


def _browser() -> Any:
    options = Options()
    options.binary_location = CHROMIUM
    for flag in BROWSER_FLAGS:
        options.add_argument(flag)
    return webdriver.Chrome(service=Service(CHROMEDRIVER), options=options)


class Console:
    """``dpcontrol console`` as a process; :attr:`url` once it says where it serves."""

    def __init__(self, vessel: str, endpoint: str, *extra: str) -> None:
        self.process = subprocess.Popen(
            [sys.executable, "-m", "dpcontrol.cli", "console", "--vessel", vessel, "--connect", endpoint,
             "--http", f"127.0.0.1:{free_tcp_port()}", *extra],
            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, cwd=ROOT,
            env={**os.environ, "PYTHONUNBUFFERED": "1"})
        self.lines: queue.Queue[str] = queue.Queue()
        self.output: list[str] = []
        threading.Thread(target=self._read, daemon=True).start()
        deadline = time.monotonic() + WAIT_S
        self.url = ""
        while not self.url and time.monotonic() < deadline:
            try:
                line = self.lines.get(timeout=1.0)
            except queue.Empty:
                assert self.process.poll() is None, "".join(self.output)
                continue
            if " at http://" in line:
                self.url = line.split(" at ", 1)[1].split()[0]
        assert self.url, "".join(self.output)

    def _read(self) -> None:
        assert self.process.stdout is not None
        for line in self.process.stdout:
            self.output.append(line)
            self.lines.put(line)

    def post(self, path: str, data: Any) -> tuple[int, dict[str, Any]]:
        request = urllib.request.Request(self.url.rstrip("/") + path, data=json.dumps(data).encode(),
                                         headers={"Content-Type": "application/json"}, method="POST")
        try:
            with urllib.request.urlopen(request, timeout=30.0) as reply:
                return reply.status, json.loads(reply.read())
        except urllib.error.HTTPError as error:
            return error.code, json.loads(error.read())

    def stop(self) -> int | None:
        self.process.terminate()
        try:
            return self.process.wait(20.0)
        except subprocess.TimeoutExpired:
            self.process.kill()
            return self.process.wait(5.0)


def _only_first_setpoint(scenario: dict[str, Any]) -> None:
    """The plant, as the operator, keeps the scenario's first set-point only: the test's own is the next."""
    scenario["setpoints"] = scenario["setpoints"][:1]


def _text(driver: Any, element_id: str) -> str:
    return driver.find_element(By.ID, element_id).text


def test_console_shows_the_live_vessel_and_applies_a_setpoint(tmp_path_factory: pytest.TempPathFactory) -> None:
    run_dir = tmp_path_factory.mktemp("console")
    short = Path(tmp_path_factory.mktemp("s"))
    shots = Path(os.environ.get("DPCONTROL_SCREENSHOTS") or run_dir)
    if not shots.is_absolute():
        shots = ROOT / shots
    # the vessel's capability polar, as sim-plant capability writes it (intact and worst single failure)
    capability = run_dir / "capability"
    assert sim_plant_main(["capability", str(ROOT / "deploy" / "config" / "cybership2.yaml"), "--out", str(capability),
                           "--directions", "12", "--failed", "worst"]) == 0
    with running_pair("cybership2", run_dir, short, 300.0, _only_first_setpoint) as pair:
        control: LatestSlot[Any] = LatestSlot()
        node = ZenohNode(ZenohConfig(mode="peer", connect=(pair.endpoint,)), pair.vessel)
        console = Console(pair.vessel, pair.endpoint, "--allow-actions")
        readonly = Console(pair.vessel, pair.endpoint, "--capability", str(capability / "capability.json"))
        driver = _browser()
        try:
            node.subscribe("control", control)
            # the daemon in DP (the plant engages it), its estimate on the page
            driver.get(console.url)
            WebDriverWait(driver, WAIT_S, 0.1).until(lambda d: _text(d, "mode") == "AUTO POSITION",
                                                     f"never in DP: {pair.log('dpcontrol.log')}")
            # 1. a page opened on a running daemon shows its pose within a second of loading
            driver.get(console.url)
            loaded = time.monotonic()
            WebDriverWait(driver, 5.0, 0.02).until(lambda d: _text(d, "pose-north") not in ("—", ""))
            assert time.monotonic() - loaded < 1.0
            assert float(_text(driver, "pose-north")) == pytest.approx(0.0, abs=0.3)  # (held at its first set-point)
            hull = driver.find_element(By.ID, "hull").get_attribute("points")
            assert hull and len(hull.split()) == 5  # the outline drawn at the pose
            # 2. it keeps updating: the snapshot clock moves, the estimate stays fresh, the pose changes
            first = (_text(driver, "clock"), _text(driver, "pose-north"), _text(driver, "pose-east"),
                     _text(driver, "speed"))
            WebDriverWait(driver, 10.0, 0.2).until(lambda d: _text(d, "clock") != first[0])
            WebDriverWait(driver, 10.0, 0.2).until(
                lambda d: (_text(d, "pose-north"), _text(d, "pose-east"), _text(d, "speed")) != first[1:])
            age = _text(driver, "age-estimate").lower()  # (the panel titles are set in capitals)
            assert age.endswith(" s") and not age.startswith("stale") and float(age.split()[0]) < 1.0, age
            assert len(driver.find_elements(By.CSS_SELECTOR, "#thrust line")) == 3  # a vector per thruster
            assert "weight" in _text(driver, "mmae") and _text(driver, "sea-state") not in ("—", "")
            shots.mkdir(parents=True, exist_ok=True)
            assert driver.save_screenshot(str(shots / "console.png"))
            # 3. a set-point entered in the page is applied by the daemon
            north, east, heading = SETPOINT
            for element_id, value in (("act-north", north), ("act-east", east), ("act-heading", heading)):
                field = driver.find_element(By.ID, element_id)
                field.clear()
                field.send_keys(str(value))
            driver.find_element(By.ID, "act-setpoint").click()
            WebDriverWait(driver, 30.0, 0.1).until(
                lambda d: d.find_element(By.ID, "answer").get_attribute("data-outcome") is not None)
            answer = _text(driver, "answer")
            assert answer.startswith("applied: "), answer
            deadline = time.monotonic() + 10.0
            applied = None
            while time.monotonic() < deadline:  # the daemon's own control message, heard by the test's session
                latest = control.latest()
                setpoint = None if latest is None else latest.message.get("setpoint")
                if setpoint and abs(setpoint["north_m"] - north) < 1e-6 and abs(setpoint["east_m"] - east) < 1e-6:
                    applied = setpoint
                    break
                time.sleep(0.1)
            assert applied is not None, control.latest()
            assert math.degrees(applied["heading_rad"]) == pytest.approx(heading, abs=1e-6)
            WebDriverWait(driver, 5.0, 0.1).until(lambda d: _text(d, "sp-north-v") == f"{north:.2f}")
            time.sleep(3.0)  # the reference on its way to the new set-point, for the screenshot
            assert driver.save_screenshot(str(shots / "console-setpoint.png"))
            # an invalid request is refused with the daemon's parser's reason, nothing sent
            status, reply = console.post("/api/request", {"heading_deg": 400})
            assert status == 400 and reply["outcome"] == "invalid" and "nothing sent" in reply["detail"], reply
            # 4. read-only unless started with --allow-actions
            driver.get(readonly.url)
            WebDriverWait(driver, 5.0, 0.05).until(lambda d: _text(d, "pose-north") not in ("—", ""))
            assert not driver.find_element(By.ID, "actions").is_displayed()
            assert driver.find_element(By.ID, "readonly").is_displayed()
            status, reply = readonly.post("/api/request", {"mode": "standby"})
            assert status == 403 and reply["outcome"] == "not_sent", reply
            time.sleep(1.0)
            assert driver.find_element(By.ID, "mode").text == "AUTO POSITION"  # nothing reached the daemon
            # 5. given the capability file, the polar is drawn with its cases (absent from the other console)
            assert driver.find_element(By.ID, "capability-panel").is_displayed()
            legend = _text(driver, "capability-legend")
            assert "intact" in legend and "worst" in legend.lower(), legend
            assert driver.execute_script(  # something drawn: pixels of the canvas that are not transparent
                "const c = document.getElementById('capability');"
                "return c.getContext('2d').getImageData(0, 0, c.width, c.height).data.some((v, i) => i % 4 == 3 && v);")
            assert driver.save_screenshot(str(shots / "console-capability.png"))
            driver.get(console.url)
            WebDriverWait(driver, 5.0, 0.05).until(lambda d: _text(d, "pose-north") not in ("—", ""))
            assert not driver.find_element(By.ID, "capability-panel").is_displayed()
        finally:
            driver.quit()
            node.close()
            codes = (console.stop(), readonly.stop())
    assert codes == (0, 0), console.output + readonly.output
