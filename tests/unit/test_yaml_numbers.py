"""Configuration and scenario files read numbers as YAML 1.2 does (``dpbase.yamlfile.load_yaml``).

PyYAML alone implements YAML 1.1, where ``6.0e6`` and ``1e3`` are strings: a mass of ``6.0e6`` kg was
refused as "expected a number". Users write floats that way, and every other YAML reader takes them as floats.
"""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from dpbase.yamlfile import load_yaml
from dpcontrol.runtime.config import load_config

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize(("text", "value"), [
    ("6.0e6", 6.0e6), ("6e6", 6e6), ("1E3", 1e3), ("-2.5e-3", -2.5e-3), ("+1.", 1.0), (".5", 0.5),
    ("-.inf", float("-inf")), ("12", 12), ("0x1A", 26), ("1_000", 1000),
])
def test_numbers_are_read_as_yaml_1_2_numbers(text: str, value: float) -> None:
    parsed = load_yaml(f"x: {text}")["x"]
    assert parsed == value
    assert type(parsed) is type(value)


def test_pyyaml_alone_reads_these_as_strings_so_the_loader_matters() -> None:
    assert yaml.safe_load("x: 6.0e6")["x"] == "6.0e6"


def test_strings_stay_strings_and_the_safe_loader_is_unchanged() -> None:
    assert load_yaml("x: '6e6'\ny: 6e6x\nz: e6\nw: yes")["x"] == "6e6"
    assert load_yaml("y: 6e6x")["y"] == "6e6x"
    assert load_yaml("z: e6")["z"] == "e6"
    assert yaml.safe_load("x: 1e3")["x"] == "1e3"
    with pytest.raises(yaml.constructor.ConstructorError):
        load_yaml("x: !!python/object:os.system {}")


def test_a_configuration_with_exponent_floats_is_accepted(tmp_path: Path) -> None:
    text = (ROOT / "deploy" / "config" / "supply.yaml").read_text(encoding="utf-8")
    text = text.replace("sigma_m: 0.5, lever_arm_m: [15.0, 2.0]", "sigma_m: 5e-1, lever_arm_m: [1.5e1, 2e0]")
    assert "5e-1" in text
    path = tmp_path / "supply.yaml"
    path.write_text(text, encoding="utf-8")
    config = load_config(path)
    sensor = next(s for s in config.sensors if s.name == "dgnss1")
    assert sensor.sigma == pytest.approx(0.5)
    assert tuple(sensor.lever_arm_m) == pytest.approx((15.0, 2.0))
