"""docs/configuration-keys.md is generated from the parser (``dpcontrol.config_reference``): it must be what the
parser reads today, and list every key the shipped example configurations use."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from dpbase.schema import REQUIRED, ConfigError, Section, recording_keys
from dpbase.yamlfile import read_yaml_file
from dpcontrol.config_reference import collect, reference_markdown, unit_of

ROOT = Path(__file__).resolve().parents[2]
REFERENCE = ROOT / "docs" / "configuration-keys.md"


def test_the_committed_reference_is_what_the_parser_reads() -> None:
    assert REFERENCE.read_text(encoding="utf-8") == reference_markdown(), (
        "docs/configuration-keys.md is stale: .venv/bin/python -m dpcontrol.config_reference > "
        "docs/configuration-keys.md")


def _paths(value: object, path: str = "") -> set[str]:
    """Key paths of a parsed YAML document, list indices folded (``sensors[].rate_hz``)."""
    out: set[str] = set()
    if isinstance(value, dict):
        for key, item in value.items():
            child = f"{path}.{key}" if path else str(key)
            out.add(child)
            out |= _paths(item, child)
    elif isinstance(value, list):
        for item in value:
            out |= _paths(item, f"{path}[]")
    return out


def test_every_key_of_every_example_is_in_the_reference() -> None:
    listed = {r.path for r in collect()}
    free = ("vessel.", "consequence.groups.", "allocation.thrust_weights.")  # names chosen by the user
    for example in sorted((ROOT / "deploy" / "config").glob("*.yaml")):
        _, mapping = read_yaml_file(example)
        used = {p for p in _paths(mapping) if not p.startswith(free) and "[]" not in p.rsplit(".", 1)[-1]}
        missing = sorted(p for p in used if p not in listed and not p.endswith("[]"))
        assert missing == [], f"{example.name}: keys missing from the reference: {missing}"


def test_the_recorder_sees_defaults_bounds_and_the_kind_that_reads_a_key() -> None:
    with recording_keys() as log:
        section = Section.of({"kind": "b", "gain": 2.0}, "ctl")
        section.string("kind", "a", choices=("a", "b"))
        section.number("gain", 1.0, minimum=0.0, exclusive_minimum=True)
    gain = next(r for r in log if r.path == "ctl.gain" and r.type == "number")
    assert (gain.default, gain.detail, gain.when) == (1.0, "> 0", "kind = b")
    kind = next(r for r in log if r.path == "ctl.kind" and r.type == "string")
    assert (kind.default, kind.detail, kind.when) == ("a", "one of a, b", "")
    with recording_keys() as log, pytest.raises(ConfigError):
        Section.of({}, "x").number("length_m")
    assert log[0].path == "x.length_m" and log[0].default is REQUIRED


def test_nothing_is_recorded_outside_a_recording_block() -> None:
    section = Section.of({"a_m": 1.0})
    section.number("a_m")
    with recording_keys() as log:
        pass
    assert log == []


def test_units_come_from_the_key_suffix() -> None:
    assert [unit_of(k) for k in ("rate_hz", "sigma_m", "max_speed_mps", "lease_s", "kind", "heading_alarm_deg",
                                 "omegas_rad_s", "sensors[].lever_arm_m")] == \
        ["Hz", "m", "m/s", "s", "", "°", "rad/s", "m"]
    assert re.search(r"\| `loop.rate_hz` \| all \| number \| Hz \| `10` \| >= 1, <= 100 \|", reference_markdown())
