"""The systemd units in deploy/: required directives, and ``systemd-analyze verify`` with no warning.

``verify`` checks that ExecStart's binary exists, so the units are rendered with this
environment's console-script directory in place of the install prefix ``/opt/dpcontrol/venv/bin/``
— the install step does the same substitution (see the comments at the top of each unit).
"""

from __future__ import annotations

import re
import shutil
import subprocess
import sysconfig
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DEPLOY = ROOT / "deploy"
PREFIX = "/opt/dpcontrol/venv/bin/"
UNITS = ["dpcontrol.service", "dpcontrol@.service", "sim-plant.service"]
SYSTEMD_ANALYZE = shutil.which("systemd-analyze")


def _directives(text: str) -> dict[str, dict[str, list[str]]]:
    """``{section: {key: [values...]}}`` of the active (uncommented) lines."""
    sections: dict[str, dict[str, list[str]]] = {}
    current = ""
    for raw in text.splitlines():
        line = raw.strip()
        if not line or line.startswith(("#", ";")):
            continue
        if line.startswith("[") and line.endswith("]"):
            current = line[1:-1]
            sections.setdefault(current, {})
            continue
        key, _, value = line.partition("=")
        sections.setdefault(current, {}).setdefault(key.strip(), []).append(value.strip())
    return sections


def _render(unit: str, scripts: Path) -> str:
    return (DEPLOY / unit).read_text(encoding="utf-8").replace(PREFIX, str(scripts) + "/")


@pytest.mark.parametrize("unit", UNITS)
def test_unit_has_the_required_directives(unit: str) -> None:
    text = (DEPLOY / unit).read_text(encoding="utf-8")
    service = _directives(text)["Service"]

    def one(key: str) -> str:
        assert key in service, f"{unit}: {key}= missing"
        return service[key][-1]

    assert one("Type") == "notify"
    assert one("NotifyAccess") == "main"
    assert one("WatchdogSec") == "2s"
    assert one("Restart") == "on-failure"
    assert one("RestartSec")
    for key, value in [("ProtectSystem", "strict"), ("ProtectHome", "yes"), ("PrivateTmp", "yes"),
                       ("NoNewPrivileges", "yes"), ("SupplementaryGroups", "dialout")]:
        assert one(key) == value, key
    assert one("StateDirectory") and one("LogsDirectory")
    assert one("DynamicUser") == "yes"
    devices = " ".join(service["DeviceAllow"])
    assert "char-ttyS" in devices and "char-ttyUSB" in devices
    assert set(one("RestrictAddressFamilies").split()) == {"AF_UNIX", "AF_INET", "AF_INET6", "AF_CAN", "AF_NETLINK"}
    assert one("ExecStart").startswith(PREFIX)
    # Real-time scheduling is offered, commented out.
    for key in ("CPUSchedulingPolicy=fifo", "CPUSchedulingPriority=", "LimitRTPRIO="):
        assert re.search(rf"^#{re.escape(key)}", text, re.MULTILINE), key


def test_daemon_units_run_the_daemon_with_a_vessel_config() -> None:
    plain = _directives((DEPLOY / "dpcontrol.service").read_text())["Service"]["ExecStart"][0]
    template = _directives((DEPLOY / "dpcontrol@.service").read_text())["Service"]["ExecStart"][0]
    assert plain == f"{PREFIX}dpcontrol run --config /etc/dpcontrol/vessel.yaml"
    assert template == f"{PREFIX}dpcontrol run --config /etc/dpcontrol/%i.yaml"
    plant = _directives((DEPLOY / "sim-plant.service").read_text())["Service"]["ExecStart"][0]
    assert plant.startswith(f"{PREFIX}sim-plant hil ")


def _verify(paths: list[Path]) -> subprocess.CompletedProcess[str]:
    assert SYSTEMD_ANALYZE is not None
    return subprocess.run([SYSTEMD_ANALYZE, "verify", *map(str, paths)], capture_output=True, text=True,
                          timeout=60, check=False)


@pytest.mark.skipif(SYSTEMD_ANALYZE is None, reason="systemd-analyze is not installed")
def test_systemd_analyze_verify_reports_nothing(tmp_path: Path) -> None:
    scripts = Path(sysconfig.get_path("scripts"))
    for script in ("dpcontrol", "sim-plant"):
        assert (scripts / script).exists(), f"console script {script} not installed in {scripts}"
    paths = []
    for unit in UNITS:
        path = tmp_path / unit
        path.write_text(_render(unit, scripts), encoding="utf-8")
        paths.append(path)
    # Verify the template through an instance, as systemd would load it.
    targets = [tmp_path / "dpcontrol.service", tmp_path / "dpcontrol@supply.service", tmp_path / "sim-plant.service"]
    result = _verify(targets)
    assert result.returncode == 0, result.stderr
    assert result.stderr.strip() == "" and result.stdout.strip() == "", result.stderr + result.stdout


@pytest.mark.skipif(SYSTEMD_ANALYZE is None, reason="systemd-analyze is not installed")
def test_verify_would_catch_a_mistake(tmp_path: Path) -> None:
    # The check above is only worth something if verify complains about a bad unit.
    scripts = Path(sysconfig.get_path("scripts"))
    text = _render("dpcontrol.service", scripts).replace("ProtectHome=yes", "ProtectHome=yes\nProtectHoem=yes")
    path = tmp_path / "dpcontrol.service"
    path.write_text(text, encoding="utf-8")
    assert "ProtectHoem" in _verify([path]).stderr


@pytest.mark.skipif(SYSTEMD_ANALYZE is None, reason="systemd-analyze is not installed")
@pytest.mark.parametrize(("unit", "drop_in"), [("dpcontrol.service", "dpcontrol-tls.conf"),
                                               ("sim-plant.service", "sim-plant-tls.conf")])
def test_the_tls_drop_ins_verify_and_load_credentials(tmp_path: Path, unit: str, drop_in: str) -> None:
    # (verify reads drop-ins from the system's unit paths only: the drop-in's lines are appended to the unit)
    scripts = Path(sysconfig.get_path("scripts"))
    text = (DEPLOY / "tls" / drop_in).read_text(encoding="utf-8")
    assert len(_directives(text)["Service"]["LoadCredential"]) == 3  # the CA, the certificate, its key
    path = tmp_path / unit
    path.write_text(_render(unit, scripts) + "\n" + text, encoding="utf-8")
    result = _verify([path])
    assert result.returncode == 0 and result.stderr.strip() == "", result.stderr
