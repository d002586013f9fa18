"""The configuration reference, generated from the parser itself: every key, its type, unit, default and bounds.

``dpcontrol/runtime/config.py`` and the sections it delegates to (estimator, controller, guidance, allocation …)
read each key through :class:`dpbase.schema.Section`; :func:`dpbase.schema.recording_keys` records those reads.
This module parses every example configuration of ``deploy/config/`` and variants of one of them (each estimator
kind, each controller kind, each transport protocol) while recording, and writes the union as a table per section,
so the reference cannot drift from the parser: ``tests/unit/test_config_reference.py`` regenerates it and compares.

Run ``.venv/bin/python -m dpcontrol.config_reference > docs/configuration-keys.md`` after changing a parser.
"""

from __future__ import annotations

import contextlib
import copy
import math
import sys
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

from dpbase.schema import REQUIRED, ConfigError, KeyRecord, VesselDefault, recording_keys
from dpbase.yamlfile import read_yaml_file
from dpcontrol.runtime.config import CONTROL_KINDS, ESTIMATOR_KINDS, parse_config

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "deploy" / "config"
BASE_EXAMPLE = "supply.yaml"

# unit of a key, from its suffix (docs/design.md §3: every key carries its unit)
UNITS = (("_m2", "m²"), ("_mps2", "m/s²"), ("_mps", "m/s"), ("_radps", "rad/s"), ("_rad_s", "rad/s"),
         ("_degps2", "°/s²"), ("_degps", "°/s"), ("_deg", "°"), ("_rad", "rad"), ("_hz", "Hz"), ("_ms", "ms"),
         ("_s", "s"), ("_kgm2", "kg·m²"), ("_kg", "kg"), ("_nm", "N·m"), ("_n", "N"), ("_mb", "MB"), ("_m", "m"))


def unit_of(path: str) -> str:
    """The unit a key's name carries (``""`` when none: a ratio, a count, a name)."""
    name = path.rsplit(".", 1)[-1].removesuffix("[]")
    for suffix, unit in UNITS:
        if name.endswith(suffix):
            return unit
    return ""


def _variants() -> Iterator[tuple[str, dict[str, Any]]]:
    """Every example, then the base example with each estimator kind, controller kind and transport protocol."""
    for path in sorted(EXAMPLES.glob("*.yaml")):
        _, mapping = read_yaml_file(path)
        assert isinstance(mapping, dict)
        yield path.name, mapping
    _, base = read_yaml_file(EXAMPLES / BASE_EXAMPLE)
    assert isinstance(base, dict)
    for kind in ESTIMATOR_KINDS:
        variant = copy.deepcopy(base)
        variant["estimator"] = {"kind": kind}
        yield f"estimator {kind}", variant
    for kind in CONTROL_KINDS:
        variant = copy.deepcopy(base)
        variant["control"] = {"kind": kind}
        yield f"control {kind}", variant
    variant = copy.deepcopy(base)
    variant["transports"].append({"name": "autopilot", "protocol": "mavlink", "url": "udpin:127.0.0.1:14550"})
    variant["sensors"].append({"name": "ap_gnss", "kind": "position", "transport": "autopilot", "rate_hz": 5,
                               "sigma_m": 1.0})
    yield "mavlink transport", variant
    variant = copy.deepcopy(base)
    variant["sensors"].append({"name": "rot1", "kind": "rate_of_turn", "transport": variant["sensors"][0]["transport"],
                               "rate_hz": 10, "sigma_degps": 0.01})
    yield "rate-of-turn sensor", variant
    # the optional sections given empty, so that their parsers read every key with its default
    variant = copy.deepcopy(base)
    for section in ("guidance", "allocation", "zenoh", "hub", "fallback", "thruster_monitor", "deviation", "loop"):
        variant.setdefault(section, {})
    variant["recorder"] = {"path": "/var/log/dpcontrol"}
    variant["state"] = {"path": "/var/lib/dpcontrol/state.json"}
    variant["datum"] = {"lat_deg": 60.0, "lon_deg": 5.0}
    yield "every section", variant


def collect() -> list[KeyRecord]:
    """The keys read while parsing every variant, one record per key path and kind (first read wins)."""
    seen: dict[tuple[str, str], KeyRecord] = {}
    for name, mapping in _variants():
        # a kind the base vessel cannot run (an autopilot on a DP vessel) is refused: what was read still counts
        with recording_keys() as log, contextlib.suppress(ConfigError):
            parse_config(mapping, file=name)
        for record in log:
            key = (record.path, record.when)
            old = seen.get(key)
            if old is None or (old.type == "value" and record.type != "value"):
                seen[key] = record
    return sorted(seen.values(), key=lambda r: (r.path.split(".")[0], r.path, r.when))


def _default(record: KeyRecord) -> str:
    if record.default is REQUIRED:
        return "**required**"
    value = record.default
    if value is None:
        return "—"
    if isinstance(value, VesselDefault):  # (this vessel's: configuration.md has the rule)
        return "per vessel"
    if isinstance(value, float) and math.isfinite(value):
        return f"`{value:g}`"
    if isinstance(value, bool):
        return f"`{str(value).lower()}`"
    return f"`{value}`" if value not in ([], {}) else "empty"


def _rows(records: Iterable[KeyRecord]) -> list[str]:
    """One row per key and meaning: the kinds that read a key alike share its row."""
    kinds: dict[tuple[str, str, str, str], list[str]] = {}
    for r in records:
        kinds.setdefault((r.path, r.type, _default(r), r.detail), []).append(r.when.partition(" = ")[2])
    rows = []
    for (path, type_, default, detail), whens in kinds.items():
        which = "all" if "" in whens else ", ".join(whens)
        rows.append(f"| `{path}` | {which} | {type_} | {unit_of(path)} | {default} | {detail.replace('|', '/')} |")
    return rows


def reference_markdown() -> str:
    """The whole reference as Markdown."""
    records = collect()
    lines = [
        "# Configuration keys (generated)",
        "",
        "Every key `dpcontrol run --config FILE` reads, generated from the parser by",
        "`.venv/bin/python -m dpcontrol.config_reference > docs/configuration-keys.md` (a test checks that this",
        "file is what the parser reads today). [configuration.md](configuration.md) says what the keys do.",
        "",
        "*kind*: the key is read only when its section's `kind` (or a transport's `protocol`) is one of those.",
        "*type* `value`: a value the parser",
        "checks itself (a name, a list of numbers, a vessel mapping …). Units come from the key's suffix; a key",
        "without one is a ratio, a count or a name. `—`: optional, no default.",
    ]
    sections: dict[str, list[KeyRecord]] = {}
    for r in records:
        sections.setdefault(r.path.split(".")[0].removesuffix("[]"), []).append(r)
    top = [r for r in records if "." not in r.path]
    lines += ["", "## Top level", "", "| key | kind | type | unit | default | bounds |", "|---|---|---|---|---|---|"]
    lines += _rows(top)
    for name, group in sections.items():
        nested = [r for r in group if "." in r.path]
        if not nested:
            continue
        lines += ["", f"## `{name}`", "", "| key | kind | type | unit | default | bounds |",
                  "|---|---|---|---|---|---|"]
        lines += _rows(nested)
    return "\n".join(lines) + "\n"


def main() -> int:
    sys.stdout.write(reference_markdown())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
