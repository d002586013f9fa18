"""Campaign files (YAML) → a validated :class:`CampaignSpec` → the deterministic list of :class:`Run`.

A campaign is a base scenario and what to vary in it::

    name: supply-moves
    base: supply-seed001            # built-in scenario name, a scenario file (relative to this file) or a mapping
    duration_s: 900                 # optional: overrides the scenario's
    runs: 40                        # random samples (per grid cell); ignored when every entry is an unpaired grid
    seed: 1                         # the campaign's seed: every draw and every run's scenario seed derive from it
    settle_s: 300                   # optional: also the metrics after this time (…_after_settle)
    set:                            # optional: fixed changes of the base, same paths as vary
      controller.loop.auto_engage_s: 10
    vary:                           # dotted paths into the scenario, list indices allowed
      sea_states[0].hs_m: {uniform: [0.5, 3.5]}
      sea_states[0].direction_deg: {uniform: [0, 360]}
      controller.control.kind: {choice: [pid, mrac], paired: true}
      faults: {choice: [[], [{t_s: 300, kind: gyro_freeze, sensor: gyro1, duration_s: 60}]],
               labels: [none, gyro_freeze]}

Distributions: ``uniform: [low, high]``, ``loguniform: [low, high]`` (> 0), ``normal: [mean, std]``,
``integers: [low, high]`` (inclusive), ``choice: [values]`` (optional ``weights``), ``grid: [values]`` and
``linspace: [start, stop, count]`` (a grid of numbers, both ends included). ``choice``, ``grid`` and
``linspace`` take ``labels`` (names for the values in the table and the plots) and ``paired: true``.
``same_as: other.path`` (optional ``offset``, added to a number) copies another entry's value — co-linear weather:
``wind.direction_deg: {same_as: "sea_states[0].direction_deg"}``.

How the runs are formed:

* the unpaired grids span *cells* (their Cartesian product, in file order, the first varying slowest);
* each cell has ``runs`` *samples* (one, when every entry is an unpaired grid); a sample is one draw of every
  random entry and one scenario ``seed`` (the random sea, gusts, sensor noise), both from
  ``numpy.random.SeedSequence(seed, spawn_key=(cell, sample))`` — so the rows do not depend on the number
  of workers, and raising ``runs`` keeps the samples already drawn;
* each sample runs once per combination of the *paired* entries (a paired ``choice`` is run with every value):
  the same sea, wind, current and noise for each — e.g. PID and MRAC compared on identical weather.

Special paths: ``base`` varies the base scenario itself (``base: {grid: [supply-seed001, cs2-seed000]}``, e.g. a
vessel choice; the other paths then apply to each); setting ``controller.control.kind`` or
``controller.estimator.kind`` to another kind drops the base section's settings of the old kind (they belong
to another algorithm), keeping the sensor noise shared by the DP wave filters — as ``sim-plant run --control``
and ``--estimator`` do. A path that does not exist is created through mappings (``controller.control.kind``
in a scenario without a ``controller:``), never through lists: an index past a list's end is an error.

Every run's scenario and controller configuration is validated before any run starts; an error names the file,
the key path and, for a sampled value, the run and its values.
"""

from __future__ import annotations

import copy
import hashlib
import itertools
import json
import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from dpbase.schema import ConfigError, Section, join
from dpbase.yamlfile import read_yaml_file
from sim_plant.bench.lockstep import lockstep_config
from sim_plant.scenario import Scenario, builtin_scenario_names, builtin_scenario_path, parse_scenario

RANDOM_KINDS = ("uniform", "loguniform", "normal", "integers", "choice")
LIST_KINDS = ("choice", "grid", "linspace")
KINDS = ("uniform", "loguniform", "normal", "integers", "choice", "grid", "linspace", "same_as")
# The wave-filter keys that mean the same for every DP wave filter (the sensors' noise), kept when the
# estimator kind changes among them (as ``sim-plant run --estimator``).
WAVE_FILTER_KINDS = ("mmae", "kf", "rpem", "raw")
ESTIMATOR_SHARED_KEYS = ("position_noise_std_m", "heading_noise_std_rad")
_TOKEN = re.compile(r"([A-Za-z_][A-Za-z0-9_\-]*)|\[(\d+)\]")


class CampaignError(ValueError):
    """A campaign that cannot run as written (the message names the file, the key path or the run)."""


@dataclass(frozen=True)
class VaryEntry:
    """One ``vary:`` entry.

    Attributes
    ----------
    path : str
        The dotted path as written (also the column name of ``campaign.csv``).
    tokens : tuple
        The path split into mapping keys (str) and list indices (int).
    kind : str
        One of :data:`KINDS`.
    params : tuple of float
        ``uniform``/``loguniform``/``normal``/``integers`` parameters.
    values : tuple
        ``choice``/``grid``/``linspace`` values.
    labels : tuple of str
        A name per value (default: the value as text).
    weights : tuple of float or None
        ``choice`` probabilities (normalised).
    paired : bool
        Every sample runs once per value.
    """

    path: str
    tokens: tuple[str | int, ...]
    kind: str
    params: tuple[float, ...] = ()
    values: tuple[Any, ...] = ()
    labels: tuple[str, ...] = ()
    weights: tuple[float, ...] | None = None
    paired: bool = False

    same_as: str | None = None
    offset: float = 0.0

    @property
    def random(self) -> bool:
        """Drawn per sample (not a grid, not paired, not a copy)."""
        return self.kind in RANDOM_KINDS and not self.paired

    @property
    def cell_grid(self) -> bool:
        """An unpaired grid: its values span cells."""
        return self.kind in ("grid", "linspace") and not self.paired

    def label(self, value: Any) -> str:
        """The label of ``value`` (listed values), or the value as compact text."""
        for known, label in zip(self.values, self.labels, strict=True):
            if known == value:
                return label
        return value_text(value)


@dataclass(frozen=True)
class CampaignSpec:
    """A validated campaign file (see the module docstring)."""

    name: str
    bases: Mapping[str, Mapping[str, Any]]
    base: str
    runs: int
    seed: int
    entries: tuple[VaryEntry, ...]
    fixed: tuple[tuple[str, tuple[str | int, ...], Any], ...] = ()
    duration_s: float | None = None
    settle_s: float | None = None
    description: str = ""
    plot_metrics: tuple[str, ...] = ()
    source: str | None = None

    @property
    def paired(self) -> tuple[VaryEntry, ...]:
        return tuple(e for e in self.entries if e.paired)


@dataclass(frozen=True)
class Run:
    """One run of a campaign.

    Attributes
    ----------
    run : int
        Position in the campaign (0-based; the row order of ``campaign.csv``).
    sample : int
        The sample it belongs to (paired runs share it: same draws, same seed).
    seed : int
        The scenario's seed.
    values : dict
        Varied path → value.
    labels : dict
        Varied path → the value's label.
    scenario : dict
        The complete scenario mapping (validated).
    duration_s : float
    settle_s : float or None
    key : str
        Hash of what the run computes (scenario, duration, settle time): a finished run with this key is not run
        again (resume).
    """

    run: int
    sample: int
    seed: int
    values: dict[str, Any]
    labels: dict[str, str]
    scenario: dict[str, Any]
    duration_s: float
    settle_s: float | None
    key: str = ""
    tags: dict[str, Any] = field(default_factory=dict)


def value_text(value: Any) -> str:
    """A value as compact text for a table cell or a plot label (JSON for lists and mappings)."""
    if isinstance(value, str):
        return value
    if isinstance(value, float):
        return repr(float(value))
    return json.dumps(value, separators=(",", ":"), sort_keys=True, default=str)


def run_key(scenario: Mapping[str, Any], duration_s: float, settle_s: float | None) -> str:
    """The resume key of a run: a hash of what it computes."""
    text = json.dumps({"scenario": scenario, "duration_s": duration_s, "settle_s": settle_s}, sort_keys=True,
                      default=str, separators=(",", ":"))
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:20]


# -- paths ----------------------------------------------------------------------------------------------------
def parse_path(text: object, where: str) -> tuple[str | int, ...]:
    """``sea_states[0].hs_m`` → ``("sea_states", 0, "hs_m")`` (ConfigError at ``where`` if malformed)."""
    if not isinstance(text, str) or not text:
        raise ConfigError(where, "a dotted path such as sea_states[0].hs_m", text)
    tokens: list[str | int] = []
    position = 0
    while position < len(text):
        if tokens and text[position] == ".":
            position += 1
        match = _TOKEN.match(text, position)
        if match is None or (match.group(2) is not None and not tokens):
            raise ConfigError(where, "a dotted path such as sea_states[0].hs_m (keys, '.', [index])", text)
        tokens.append(match.group(1) if match.group(1) is not None else int(match.group(2)))
        position = match.end()
        if position < len(text) and text[position] not in ".[":
            raise ConfigError(where, "a dotted path such as sea_states[0].hs_m (keys, '.', [index])", text)
    return tuple(tokens)


def set_path(data: dict[str, Any], tokens: Sequence[str | int], value: Any, where: str) -> None:
    """Set ``value`` at ``tokens`` in the scenario mapping ``data`` (in place; see the module docstring)."""
    node: Any = data
    done = ""
    for i, token in enumerate(tokens):
        last = i == len(tokens) - 1
        if isinstance(token, int):
            if not isinstance(node, list):
                raise ConfigError(where, f"a list at {done or '<root>'} of the scenario", node)
            if token >= len(node):
                raise ConfigError(where, f"an index below {len(node)}: {done} has {len(node)} entries in the "
                                  "scenario", token)
            if last:
                node[token] = copy.deepcopy(value)
                return
            node = node[token]
        else:
            if not isinstance(node, dict):
                raise ConfigError(where, f"a mapping at {done or '<root>'} of the scenario", node)
            if last:
                if _is_kind_switch(tokens) and isinstance(node.get("kind"), str) and node.get("kind") != value:
                    kept = {k: v for k, v in node.items() if tokens[1] == "estimator" and k in ESTIMATOR_SHARED_KEYS
                            and node["kind"] in WAVE_FILTER_KINDS and value in WAVE_FILTER_KINDS}
                    node.clear()
                    node.update(kept)
                node[token] = copy.deepcopy(value)
                return
            if node.get(token) is None:
                if isinstance(tokens[i + 1], int):
                    raise ConfigError(where, f"a list at {join(done, token)} of the scenario (there is none)",
                                      show_got=False)
                node[token] = {}
            node = node[token]
        done = join(done, token)


def _is_kind_switch(tokens: Sequence[str | int]) -> bool:
    return len(tokens) == 3 and tokens[0] == "controller" and tokens[1] in ("control", "estimator") \
        and tokens[2] == "kind"


# -- loading --------------------------------------------------------------------------------------------------
def load_campaign(path: str | Path) -> CampaignSpec:
    """Read and validate a campaign file (ConfigError naming the file and the key path)."""
    _, data = read_yaml_file(path, what="a readable campaign file")
    return parse_campaign(data, file=str(path), base_dir=Path(path).resolve().parent)


def builtin_campaign_names() -> list[str]:
    """Names of the campaigns shipped in ``sim_plant/campaigns`` (without ``.yaml``)."""
    from importlib import resources  # noqa: PLC0415

    folder = resources.files("sim_plant") / "campaigns"
    return sorted(p.name[: -len(".yaml")] for p in folder.iterdir() if p.name.endswith(".yaml"))


def campaign_path(text: str) -> Path:
    """A campaign file, or the path of a shipped campaign by name (KeyError listing them if unknown)."""
    path = Path(text)
    if path.exists() or text.endswith((".yaml", ".yml")) or "/" in text:
        return path
    from importlib import resources  # noqa: PLC0415

    names = builtin_campaign_names()
    if text not in names:
        raise KeyError(f"no campaign file {text!r} and no built-in campaign of that name (known: {', '.join(names)})")
    return Path(str(resources.files("sim_plant") / "campaigns" / f"{text}.yaml"))


def parse_campaign(data: object, file: str | None = None, base_dir: Path | None = None) -> CampaignSpec:
    """Validate a parsed campaign mapping (ConfigError naming ``file`` and the key path)."""
    try:
        return _parse(data, file, base_dir or Path.cwd())
    except ConfigError as error:
        raise (error.with_file(file) if file and not error.file else error) from None


def _load_base(value: object, where: str, base_dir: Path) -> tuple[str, dict[str, Any]]:
    """A base scenario reference → (label, mapping)."""
    if isinstance(value, Mapping):
        if len(value) == 1 and next(iter(value)) in KINDS:  # a distribution where the scenario goes
            raise ConfigError(where, f"one scenario (a name, a file or a mapping); to vary it, write it under "
                              f"vary: (vary: {{base: {{{next(iter(value))}: [...]}}}})", dict(value))
        return str(value.get("name", "inline")), copy.deepcopy(dict(value))
    if not isinstance(value, str) or not value:
        raise ConfigError(where, "a built-in scenario name, a scenario file or a scenario mapping", value)
    candidate = Path(value) if Path(value).is_absolute() else base_dir / value
    if candidate.exists():
        _, data = read_yaml_file(candidate, what="a readable scenario file")
    elif value in builtin_scenario_names():
        _, data = read_yaml_file(builtin_scenario_path(value), what="a readable scenario file")
    else:
        raise ConfigError(where, f"a built-in scenario ({', '.join(builtin_scenario_names())}) or a scenario file "
                          f"(relative to {base_dir})", value)
    if not isinstance(data, Mapping):
        raise ConfigError(where, "a scenario file holding a mapping", value)
    return value, copy.deepcopy(dict(data))


def _number_list(sec: Section, key: str, where: str, count: int, what: str) -> tuple[float, ...]:
    raw = sec.raw(key)
    if not isinstance(raw, (list, tuple)) or len(raw) != count or not all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in raw):
        raise ConfigError(join(where, key), f"{count} numbers {what}", raw)
    return tuple(float(v) for v in raw)


def _entry(path_text: str, value: object, where: str) -> VaryEntry:
    tokens = parse_path(path_text, where)
    sec = Section.of(value, where)
    kinds = [k for k in KINDS if sec.has(k)]
    if len(kinds) != 1:
        raise ConfigError(where, f"exactly one of {', '.join(KINDS)}", value)
    kind = kinds[0]
    key = join(where, kind)
    params: tuple[float, ...] = ()
    values: tuple[Any, ...] = ()
    if kind in ("uniform", "loguniform", "integers"):
        params = _number_list(sec, kind, where, 2, "[low, high]")
        if params[1] < params[0]:
            raise ConfigError(key, "low ≤ high", list(params))
        if kind == "loguniform" and params[0] <= 0.0:
            raise ConfigError(key, "low > 0 for loguniform", list(params))
        if kind == "integers" and not all(float(p).is_integer() for p in params):
            raise ConfigError(key, "two integers [low, high]", list(params))
    elif kind == "normal":
        params = _number_list(sec, kind, where, 2, "[mean, std]")
        if params[1] < 0.0:
            raise ConfigError(key, "std ≥ 0", list(params))
    elif kind == "linspace":
        start, stop, count = _number_list(sec, kind, where, 3, "[start, stop, count]")
        if not count.is_integer() or count < 1:
            raise ConfigError(key, "a whole count ≥ 1 as the third number", count)
        values = tuple(float(v) for v in np.linspace(start, stop, int(count)))
    elif kind == "same_as":
        other = sec.string("same_as")
        offset = sec.number("offset", 0.0)
        sec.finish()
        return VaryEntry(path_text, tokens, kind, same_as=other, offset=offset)
    else:
        raw = sec.raw(kind)
        if not isinstance(raw, list) or not raw:
            raise ConfigError(key, "a non-empty list of values", raw)
        values = tuple(copy.deepcopy(raw))
    labels: tuple[str, ...] = ()
    weights = None
    paired = False
    if kind in LIST_KINDS:
        paired = sec.boolean("paired", False)
        if sec.has("labels"):
            raw_labels = sec.raw("labels")
            if not isinstance(raw_labels, list) or len(raw_labels) != len(values) or len(set(map(str, raw_labels))) \
                    != len(raw_labels):
                raise ConfigError(join(where, "labels"), f"{len(values)} distinct names, one per value", raw_labels)
            labels = tuple(str(v) for v in raw_labels)
        else:
            labels = tuple(value_text(v) for v in values)
        if kind == "choice" and sec.has("weights"):
            raw_w = _number_list(sec, "weights", where, len(values), "≥ 0, one per value")
            if any(w < 0 for w in raw_w) or sum(raw_w) <= 0:
                raise ConfigError(join(where, "weights"), "numbers ≥ 0 with a positive sum", list(raw_w))
            weights = tuple(w / sum(raw_w) for w in raw_w)
    sec.finish()
    if tokens == ("base",) and kind not in LIST_KINDS:
        raise ConfigError(where, "choice, grid or linspace of base scenarios", kind)
    return VaryEntry(path_text, tokens, kind, params, values, labels, weights, paired)


def _parse(data: object, file: str | None, base_dir: Path) -> CampaignSpec:
    root = Section.of(data, "")
    name = root.string("name")
    description = root.string("description") if root.has("description") else ""
    base_label, base = _load_base(root.raw("base"), "base", base_dir)
    duration = root.optional_number("duration_s", minimum=0.0, exclusive_minimum=True)
    settle = root.optional_number("settle_s", minimum=0.0)
    seed = root.integer("seed", 0, minimum=0)
    runs_given = root.has("runs")
    runs = root.integer("runs", 1, minimum=1, maximum=1_000_000)
    fixed = []
    for path_text, value in Section.of(root.raw("set", {}), "set").data.items():
        where = join("set", path_text)
        fixed.append((path_text, parse_path(path_text, where), copy.deepcopy(value)))
    vary = Section.of(root.raw("vary", {}), "vary")
    entries = tuple(_entry(path_text, value, join("vary", path_text)) for path_text, value in vary.data.items())
    plot_metrics = tuple(str(m) for m in root.raw("plot_metrics", []) or [])
    root.finish()
    paths = [e.path for e in entries]
    for entry in entries:
        if entry.kind == "same_as":
            target = next((e for e in entries if e.path == entry.same_as), None)
            if target is None or target.kind == "same_as":
                raise ConfigError(join(join("vary", entry.path), "same_as"),
                                  f"another entry of vary ({', '.join(paths)})", entry.same_as)
    if not runs_given and any(not e.cell_grid and e.kind != "same_as" for e in entries):
        raise ConfigError("runs", "the number of random samples (the campaign varies more than grids)", show_got=False)
    bases = {base_label: base}
    for entry in entries:
        if entry.tokens == ("base",):
            loaded = [_load_base(v, f"{join('vary', entry.path)}.{entry.kind}[{i}]", base_dir)
                      for i, v in enumerate(entry.values)]
            bases.update(dict(loaded))
            entry_labels = entry.labels if entry.labels != tuple(value_text(v) for v in entry.values) else tuple(
                label for label, _ in loaded)
            object.__setattr__(entry, "values", tuple(label for label, _ in loaded))
            object.__setattr__(entry, "labels", entry_labels)
    # a path the base cannot take is reported now, with its key in the campaign file
    for label, mapping in bases.items():
        trial = copy.deepcopy(mapping)
        for path_text, tokens, value in fixed:
            set_path(trial, tokens, value, join("set", path_text))
        for entry in entries:
            if entry.tokens != ("base",):
                sample = entry.values[0] if entry.values else entry.params[0] if entry.params else 0.0
                try:
                    set_path(trial, entry.tokens, sample, join("vary", entry.path))
                except ConfigError as error:
                    raise ConfigError(error.path, f"{error.expected} (base {label})", error.got,
                                      show_got=error.show_got) from None
    return CampaignSpec(name=name, bases=bases, base=base_label, runs=runs, seed=seed, entries=entries,
                        fixed=tuple(fixed), duration_s=duration, settle_s=settle, description=description,
                        plot_metrics=plot_metrics, source=file)


# -- expansion ------------------------------------------------------------------------------------------------
def _draw(entry: VaryEntry, rng: np.random.Generator) -> Any:
    if entry.kind == "uniform":
        return float(rng.uniform(entry.params[0], entry.params[1]))
    if entry.kind == "loguniform":
        return float(math.exp(rng.uniform(math.log(entry.params[0]), math.log(entry.params[1]))))
    if entry.kind == "normal":
        return float(rng.normal(entry.params[0], entry.params[1]))
    if entry.kind == "integers":
        return int(rng.integers(int(entry.params[0]), int(entry.params[1]), endpoint=True))
    index = int(rng.choice(len(entry.values), p=entry.weights))
    return copy.deepcopy(entry.values[index])


def sample_seed(campaign_seed: int, cell: int, sample: int) -> np.random.SeedSequence:
    """The seed sequence of one sample (its draws and its scenario seed)."""
    return np.random.SeedSequence(campaign_seed, spawn_key=(cell, sample))


def expand(spec: CampaignSpec, *, validate: bool = True) -> list[Run]:
    """The campaign's runs, in order (see the module docstring); each scenario and controller configuration
    validated (CampaignError naming the run and its values).
    """
    grids = [e for e in spec.entries if e.cell_grid]
    paired = [e for e in spec.entries if e.paired]
    random_entries = [e for e in spec.entries if e.random]
    samples_per_cell = 1 if spec.entries and not random_entries and not paired else spec.runs
    varies_seed = any(e.tokens == ("seed",) for e in spec.entries) or any(t == ("seed",) for _, t, _ in spec.fixed)
    runs: list[Run] = []
    checked: dict[str, None] = {}
    for cell, grid_values in enumerate(itertools.product(*[e.values for e in grids])):
        for j in range(samples_per_cell):
            sequence = sample_seed(spec.seed, cell, j)
            rng = np.random.default_rng(sequence)
            seed = int(sequence.generate_state(1, dtype=np.uint32)[0] >> 1)
            drawn = {e.path: _draw(e, rng) for e in random_entries}
            sample_index = len({r.sample for r in runs})
            for combo in itertools.product(*[e.values for e in paired]):
                values: dict[str, Any] = {}
                for entry in spec.entries:
                    if entry.cell_grid:
                        values[entry.path] = grid_values[grids.index(entry)]
                    elif entry.paired:
                        values[entry.path] = combo[paired.index(entry)]
                    elif entry.kind != "same_as":
                        values[entry.path] = drawn[entry.path]
                for entry in spec.entries:
                    if entry.kind == "same_as":
                        source = values[entry.same_as]  # type: ignore[index]
                        values[entry.path] = source + entry.offset if isinstance(source, (int, float)) \
                            and not isinstance(source, bool) else copy.deepcopy(source)
                values = {e.path: values[e.path] for e in spec.entries}
                runs.append(_make_run(spec, len(runs), sample_index, seed, values, varies_seed=varies_seed,
                                      validate=validate, checked=checked))
    return runs


def _make_run(spec: CampaignSpec, index: int, sample: int, seed: int, values: dict[str, Any], *, varies_seed: bool,
              validate: bool, checked: dict[str, None]) -> Run:
    base_label = next((v for e, v in ((e, values[e.path]) for e in spec.entries) if e.tokens == ("base",)), spec.base)
    scenario = copy.deepcopy(dict(spec.bases[base_label]))
    if not varies_seed:
        scenario["seed"] = seed
    if spec.duration_s is not None:
        scenario["duration_s"] = spec.duration_s
    for path_text, tokens, value in spec.fixed:
        set_path(scenario, tokens, value, join("set", path_text))
    # kind switches first: they clear the section the other paths may then fill
    ordered = sorted(spec.entries, key=lambda e: not _is_kind_switch(e.tokens))
    for entry in ordered:
        if entry.tokens != ("base",):
            set_path(scenario, entry.tokens, values[entry.path], join("vary", entry.path))
    labels = {e.path: e.label(values[e.path]) for e in spec.entries}
    run_seed = int(scenario.get("seed", 0)) if isinstance(scenario.get("seed", 0), int) else seed
    if validate:
        where = f"{spec.source or spec.name}: run {index} ({', '.join(f'{k} = {v}' for k, v in labels.items())})"
        parsed = _validate(scenario, where, checked)
        duration = parsed.duration_s
    else:
        duration = float(scenario.get("duration_s", 0.0))
    key = run_key(scenario, duration, spec.settle_s)
    return Run(index, sample, run_seed, values, labels, scenario, duration, spec.settle_s, key)


def _validate(scenario: dict[str, Any], where: str, checked: dict[str, None]) -> Scenario:
    try:
        parsed = parse_scenario(scenario)
    except ConfigError as error:
        raise CampaignError(f"{where}: {error}") from None
    # the controller configuration of each distinct controller/vessel/sensor combination (parsing is the cost)
    signature = json.dumps([scenario.get("controller"), scenario.get("vessel"), scenario.get("sensors")],
                           sort_keys=True, default=str)
    if signature not in checked:
        try:
            lockstep_config(parsed, file="<controller>")
        except (ConfigError, ValueError) as error:
            raise CampaignError(f"{where}: controller: {error}") from None
        checked[signature] = None
    return parsed
