"""DP capability plots in the manner of DNV-ST-0111: the largest wind, per direction, in which the vessel holds.

Directions β are where the weather comes *from* relative to the bow, clockwise (0° head-on, 90° from starboard);
wind, waves and current are co-linear (the current flows toward β + 180°). Wind speeds are full-scale 1-hour
means at 10 m; the built-in model-scale vessels (CyberShip II 1:70, Blue Lady 1:24,
:data:`dpcontrol.allocation.capability.MODEL_SCALE`) are run at the Froude-scaled environment (speeds ÷ √λ,
lengths ÷ λ, times ÷ √λ) and reported at full scale.

**Sea state from wind speed**: DNV-ST-0111 (Edition December 2021) Table 2-1, the Level 1 environment per
Beaufort number — mean wind speed, significant wave height H_s and peak period T_p — as transcribed in the
public ``WilliamBoland1/Prosjektoppgave_Collab`` repository (``dp_capability/standard.py``, checked there against
the standard's PDF); :data:`TABLE_2_1` below. Between rows H_s and T_p are interpolated linearly in wind speed;
above Beaufort 11 (32.6 m/s) the last segment is extended. The sea is a long-crested Pierson–Moskowitz spectrum
with that H_s and ω_p = 2π/T_p (the standard's Level 1 sea; its cos² spreading is not modelled by the plant).
The table's current (0.75 m/s from Beaufort 3) is replaced by ``--current-mps`` (default 0.5 m/s).

**Level 1** (static): the mean loads of the plant's own models on the vessel at rest at heading 0 —
wind: the plant's wind force (:func:`sim_plant.environment.wind.wind_force_b`, the Blendermann law of
:mod:`dpbase.wind_loads`, seed 002 eq. (18)) at γ_rw = −β (that law's angle is positive from port);
waves: the mean of the plant's drift model (:mod:`sim_plant.environment.waves`), ρg·s ∫ R(ω)² S(ω) dω times
the direction factors of :func:`~sim_plant.environment.rao.drift_direction_factors`, with Ursell's reflection
coefficient R and the vessel's drift scale s (the expectation of the plant's Σ b_i²: the integral on 2000 bins);
current: the force of the plant's relative-velocity damping and Munk moment
(:func:`sim_plant.kernels.vessel_derivative` at rest in the current, times M) — balanced by the thrusters left
with the control loop's QP allocation and the configured allocation settings
(:func:`dpcontrol.allocation.capability.static_allocation` / :func:`~dpcontrol.allocation.capability.holds`).
Bisection on wind speed to 0.01 m/s. Optionally the Level 1 *dynamic allowance* of DNV-ST-0111 [3.2.2]:
the environmental loads multiplied by 1.25 (``--dynamic-allowance``), standing for the thrust a real
controller needs above the mean to counter gusts, slowly-varying drift and its own motion.
``limiting_thruster`` is the thruster at the largest share of its rating at the largest wind held.

**Level 3** (time domain): lockstep runs of the whole closed loop (plant with waves, gusts, slowly-varying drift;
the controller with its wave filter, control law and allocation; the failed thrusters ``thruster_not_ready``
from t = 0) at heading 0 with the set-point at the origin; a run holds when, after ``settle_s``, the true LF
position stays within ``max_excursion_m`` of the set-point and the heading within ``max_heading_deg`` for
``window_s``. Bisection on wind speed per direction between 0 and 1.25 × the Level 1 value (so a Level 3 point
above Level 1 is possible and would show), all directions of a bisection step in parallel through the campaign
engine (:mod:`sim_plant.campaign.engine`), so a cluster speeds it up.
"""

from __future__ import annotations

import copy
import json
import logging
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, cast

import numpy as np

from dpbase.frames import ssa
from dpbase.schema import ConfigError
from dpbase.yamlfile import read_yaml_file
from dpcontrol.allocation.allocator import ThrustAllocator, allocator_kwargs_from_mapping
from dpcontrol.allocation.capability import MODEL_SCALE, STATIC_SAMPLE_TIME_S, holds, static_allocation
from dpcontrol.models.vessels import BUILTIN_VESSELS, GRAVITY_MPS2, VesselData
from dpcontrol.runtime.config import CONTROLLER_SECTIONS, parse_config
from sim_plant.campaign.spec import Run, run_key
from sim_plant.environment.rao import drift_direction_factors, reflection_coefficient
from sim_plant.environment.spectra import frequency_bins, wave_spectrum
from sim_plant.environment.wind import wind_force_b
from sim_plant.vessel import DpVesselModel

log = logging.getLogger(__name__)

#: DNV-ST-0111 (Dec 2021) Table 2-1, Beaufort 1–11: (mean wind speed [m/s], H_s [m], T_p [s]). Source: see the
#: module docstring.
TABLE_2_1: tuple[tuple[float, float, float], ...] = (
    (1.5, 0.1, 3.5), (3.4, 0.4, 4.5), (5.4, 0.8, 5.5), (7.9, 1.3, 6.5), (10.7, 2.1, 7.5), (13.8, 3.1, 8.5),
    (17.1, 4.2, 9.0), (20.7, 5.7, 10.0), (24.4, 7.4, 10.5), (28.4, 9.5, 11.5), (32.6, 12.1, 12.0),
)
DYNAMIC_ALLOWANCE_LEVEL1 = 1.25  # DNV-ST-0111 [3.2.2]: on the wind, current and wave loads of Level 1
WIND_RESOLUTION_MPS = 0.01
DRIFT_BINS = 2000
LEVEL3_SEARCH_FACTOR = 1.25


def sea_state_for_wind(wind_mps: float) -> tuple[float, float]:
    """(H_s [m], T_p [s]) for a full-scale wind speed by :data:`TABLE_2_1` (linear; extended above Beaufort 11;
    calm below 0.01 m/s)."""
    if wind_mps < 0.01:
        return 0.0, TABLE_2_1[0][2]
    winds = [0.0] + [row[0] for row in TABLE_2_1]
    hs = [0.0] + [row[1] for row in TABLE_2_1]
    tp = [TABLE_2_1[0][2]] + [row[2] for row in TABLE_2_1]
    if wind_mps <= winds[-1]:
        return float(np.interp(wind_mps, winds, hs)), float(np.interp(wind_mps, winds, tp))
    (w0, h0, p0), (w1, h1, p1) = TABLE_2_1[-2], TABLE_2_1[-1]
    s = (wind_mps - w1) / (w1 - w0)
    return h1 + s * (h1 - h0), p1 + s * (p1 - p0)


@dataclass(frozen=True)
class FailureCase:
    """A capability case: its name (``intact``, a group name or the thruster names) and the thrusters lost."""

    name: str
    failed: tuple[str, ...] = ()


@dataclass
class Subject:
    """What a capability plot is of: the vessel and the controller sections that matter (allocation settings,
    consequence groups; for Level 3 the whole controller)."""

    name: str
    vessel: VesselData
    vessel_entry: Any
    controller: dict[str, Any] = field(default_factory=dict)
    groups: dict[str, tuple[str, ...]] = field(default_factory=dict)
    source: str | None = None

    @property
    def scale(self) -> float:
        """Froude model scale λ (1 for a full-scale vessel)."""
        return MODEL_SCALE.get(self.vessel.name, 1.0)

    def failure_cases(self, failed: Sequence[str]) -> list[FailureCase]:
        """``intact`` and one case per ``--failed`` entry (``worst`` stays a marker, resolved by Level 1)."""
        names = [t.name for t in self.vessel.thrusters]
        cases = [FailureCase("intact")]
        for i, raw in enumerate(failed):
            text = raw.strip()
            if text == "worst":
                cases.append(FailureCase("worst"))
            elif text in self.groups:
                cases.append(FailureCase(text, self.groups[text]))
            else:
                parts = tuple(p.strip() for p in text.split(",") if p.strip())
                unknown = [p for p in parts if p not in names]
                if not parts or unknown:
                    groups = f"; groups: {', '.join(self.groups)}" if self.groups else ""
                    raise ConfigError(f"--failed[{i}]", f"thruster names of {self.vessel.name} ({', '.join(names)})"
                                      f"{groups}, or 'worst'", text)
                cases.append(FailureCase(",".join(parts), parts))
        return cases

    def single_failures(self) -> list[FailureCase]:
        """Every consequence group and every single thruster: the candidates of the worst single failure."""
        cases = [FailureCase(name, tuple(members)) for name, members in self.groups.items()]
        cases += [FailureCase(t.name, (t.name,)) for t in self.vessel.thrusters]
        return cases


def load_subject(text: str) -> Subject:
    """A built-in vessel name, or a controller configuration file (its vessel, allocation, consequence groups and
    the other controller sections)."""
    if text in BUILTIN_VESSELS:
        return Subject(text, BUILTIN_VESSELS[text], text)
    path = Path(text)
    if not path.exists():
        raise ConfigError("VESSEL_OR_CONFIG", f"a built-in vessel ({', '.join(BUILTIN_VESSELS)}) or a controller "
                          "configuration file", text)
    source, data = read_yaml_file(path, what="a readable controller configuration file")
    config = parse_config(data, file=str(path), text=source)
    assert isinstance(data, Mapping)  # (parse_config refuses anything else)
    controller = {key: copy.deepcopy(data[key]) for key in CONTROLLER_SECTIONS if key in data}
    groups = {g.name: tuple(g.thrusters) for g in config.consequence.groups}
    return Subject(config.vessel.name, config.vessel, copy.deepcopy(data["vessel"]), controller, groups, str(path))


# -- Level 1 ----------------------------------------------------------------------------------------------------
class StaticLoads:
    """Mean environmental loads on a vessel at rest at heading 0 (see the module docstring), full-scale inputs."""

    def __init__(self, vessel: VesselData, current_mps: float, dynamic_allowance: float = 1.0) -> None:
        self.vessel = vessel
        self.model = DpVesselModel(vessel)
        self.scale = MODEL_SCALE.get(vessel.name, 1.0)
        self.current_mps = current_mps
        self.dynamic_allowance = dynamic_allowance

    def wind_b(self, beta_rad: float, wind_mps: float) -> np.ndarray:
        speed = wind_mps / math.sqrt(self.scale)
        return np.array(wind_force_b(self.model.wind, speed, -ssa(beta_rad)))

    def drift_b(self, beta_rad: float, wind_mps: float) -> np.ndarray:
        hs, tp = sea_state_for_wind(wind_mps)
        if hs <= 0.0:
            return np.zeros(3)
        hs /= self.scale
        omega_p = 2.0 * math.pi / (tp / math.sqrt(self.scale))
        edges = frequency_bins(omega_p, 1.0, DRIFT_BINS, "pierson_moskowitz")
        omega = 0.5 * (edges[:-1] + edges[1:])
        a2 = 2.0 * wave_spectrum(omega, hs, omega_p, 1.0, "pierson_moskowitz") * np.diff(edges)
        r = reflection_coefficient(omega, self.model.hull.draft_m)
        mean = 0.5 * self.vessel.water_density_kgpm3 * GRAVITY_MPS2 * self.model.extras.drift_scale * float(
            np.sum(r * r * a2))
        return mean * np.array(drift_direction_factors(ssa(beta_rad + math.pi), self.model.hull))

    def current_b(self, beta_rad: float) -> np.ndarray:
        speed = self.current_mps / math.sqrt(self.scale)
        if speed == 0.0:
            return np.zeros(3)
        toward = beta_rad + math.pi
        rates = self.model.derivative([0.0] * 6, (0.0, 0.0, 0.0), (speed * math.cos(toward),
                                                                  speed * math.sin(toward)))
        return self.model.mass_matrix @ np.array(rates[3:])

    def load_b(self, beta_rad: float, wind_mps: float) -> np.ndarray:
        """Total mean load ``[N, N, N·m]`` (body axes; the thrusters must produce its opposite)."""
        total = self.wind_b(beta_rad, wind_mps) + self.drift_b(beta_rad, wind_mps) + self.current_b(beta_rad)
        return self.dynamic_allowance * total


def level1(subject: Subject, case: FailureCase, directions_deg: Sequence[float], *, current_mps: float,
           dynamic_allowance: float = 1.0, max_wind_mps: float = 40.0) -> dict[str, Any]:
    """Level 1 capability of one case: the curve and the limiting thruster per direction."""
    vessel = subject.vessel
    names = [t.name for t in vessel.thrusters]
    available = np.array([n not in case.failed for n in names])
    kwargs = allocator_kwargs_from_mapping(subject.controller.get("allocation") or {}, vessel.thrusters)
    allocator = ThrustAllocator(vessel.thrusters, STATIC_SAMPLE_TIME_S, **kwargs)
    initial = allocator.state_dict()
    loads = StaticLoads(vessel, current_mps, dynamic_allowance)
    rating = np.array([t.max_thrust_n for t in vessel.thrusters])
    reverse = np.array([max(-t.min_thrust_n, 1e-9) for t in vessel.thrusters])

    def held(beta: float, wind: float) -> bool:
        load = loads.load_b(beta, wind)
        return any(_holds_from(allocator, start, load, available) for start in _starts(allocator, initial, load,
                                                                                       available))

    winds, limiting, at_limit = [], [], []
    for deg in directions_deg:
        beta = math.radians(deg)
        lo, hi = 0.0, max_wind_mps
        if held(beta, hi):
            lo = hi
        elif not held(beta, 0.0):
            hi = 0.0
        while hi - lo > WIND_RESOLUTION_MPS:
            mid = 0.5 * (lo + hi)
            if held(beta, mid):
                lo = mid
            else:
                hi = mid
        load = loads.load_b(beta, lo)
        for start in _starts(allocator, initial, load, available):  # the first start that holds (or the last)
            if _holds_from(allocator, start, load, available):
                break
        allocator.load_state_dict(start)
        result = static_allocation(allocator, -load, available)
        share = np.abs(result.thrust_n) / np.where(result.thrust_n >= 0.0, rating, reverse)
        share[~available] = -1.0
        winds.append(round(lo, 3))
        limiting.append(names[int(np.argmax(share))] if available.any() else None)
        at_limit.append(lo >= max_wind_mps)
    return {"case": case.name, "failed": list(case.failed), "max_wind_mps": winds, "limiting_thruster": limiting,
            "held_at_search_limit": at_limit}


def _starts(allocator: ThrustAllocator, initial: Mapping[str, Any], load_b: np.ndarray, available: np.ndarray
            ) -> list[dict[str, Any]]:
    """Where a static allocation starts from: the allocator's initial state, and every azimuth turned to the
    direction the unconstrained (pseudo-inverse) allocation of the demand wants of it.

    The QP linearises each azimuth's thrust circle around its previous angle, so a static allocation (a few QP
    passes) can settle on a polygon vertex far from the best direction and report saturation where the thrusters
    could hold (measured: the shuttle tanker at 140°, bow azimuth stuck at 165° from 0° while 172° holds; an
    intact layout then held less than the same layout with a tunnel lost). Holding from *any* start is a valid
    answer — the allocation found meets the demand within every limit — so more starts only remove false
    "saturated" results.
    """
    geometry = allocator.geometry
    if not geometry.azimuth_index.size:
        return [dict(initial)]
    f = allocator.unconstrained(-load_b, available)
    angles = list(initial["azimuth_rad"])
    for i in geometry.azimuth_index:
        j = int(geometry.first_variable[i])
        if f[j] != 0.0 or f[j + 1] != 0.0:
            angles[int(i)] = math.atan2(f[j + 1], f[j])
    return [dict(initial), {**initial, "azimuth_rad": angles}]


def _holds_from(allocator: ThrustAllocator, start: Mapping[str, Any], load_b: np.ndarray, available: np.ndarray
                ) -> bool:
    allocator.load_state_dict(start)  # every check from a stated start: no history across directions and speeds
    return holds(allocator, load_b, available)


def polar_area(winds: Sequence[float]) -> float:
    """∝ the area inside a capability curve (Σ V²): what "worst" minimises."""
    return float(np.sum(np.square(winds)))


# -- Level 3 ----------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class CapabilityOptions:
    """The command's options (see ``sim-plant capability --help``)."""

    level: int = 1
    directions: int = 36
    failed: tuple[str, ...] = ()
    current_mps: float = 0.5
    dynamic_allowance: float = 1.0
    max_wind_mps: float = 40.0
    max_excursion_m: float = 5.0
    max_heading_deg: float = 3.0
    settle_s: float = 300.0
    window_s: float = 600.0
    iterations: int = 6
    seed: int = 1

    @property
    def directions_deg(self) -> list[float]:
        return [round(360.0 * k / self.directions, 6) for k in range(self.directions)]


def level3_scenario(subject: Subject, case: FailureCase, beta_deg: float, wind_mps: float,
                    options: CapabilityOptions) -> dict[str, Any]:
    """The lockstep scenario of one Level 3 point (model-scaled for a model-scale vessel)."""
    lam = subject.scale
    root = math.sqrt(lam)
    hs, tp = sea_state_for_wind(wind_mps)
    controller = copy.deepcopy(subject.controller)
    controller.setdefault("loop", {})
    if isinstance(controller["loop"], dict):
        controller["loop"].setdefault("auto_engage_s", round(10.0 / root, 3))
    scenario: dict[str, Any] = {
        "name": f"capability-{subject.name}-{case.name}-{beta_deg:g}deg-{wind_mps:.2f}mps",
        "vessel": copy.deepcopy(subject.vessel_entry),
        "duration_s": round((options.settle_s + options.window_s) / root, 3),
        "seed": options.seed,
        "controller": controller,
        "wind": {"speed_mps": wind_mps / root, "direction_deg": beta_deg},
        "current": {"speed_mps": options.current_mps / root, "direction_deg": (beta_deg + 180.0) % 360.0},
        "setpoints": [{"t_s": 0.0, "north_m": 0.0, "east_m": 0.0, "heading_deg": 0.0}],
        "faults": [{"t_s": 0.0, "kind": "thruster_not_ready", "thruster": name} for name in case.failed],
    }
    if hs > 0.0:
        scenario["sea_states"] = [{"t_s": 0.0, "spectrum": "pierson_moskowitz", "hs_m": hs / lam,
                                   "tp_s": tp / root, "direction_deg": beta_deg}]
    return scenario


def level3(subject: Subject, case: FailureCase, level1_winds: Sequence[float], options: CapabilityOptions,
           engine: Any, *, progress: bool = False) -> dict[str, Any]:
    """Level 3 capability of one case by bisection (see the module docstring)."""
    lam = subject.scale
    directions = options.directions_deg
    lo = [0.0] * len(directions)
    hi = [max(LEVEL3_SEARCH_FACTOR * w, 1.0) for w in level1_winds]
    hi = [min(h, options.max_wind_mps) for h in hi]
    points: list[list[dict[str, Any]]] = [[] for _ in directions]
    settle = options.settle_s / math.sqrt(lam)
    limit_m = options.max_excursion_m / lam
    for step in range(options.iterations):
        runs: list[Run] = []
        for k, beta in enumerate(directions):
            wind = 0.5 * (lo[k] + hi[k])
            scenario = level3_scenario(subject, case, beta, wind, options)
            duration = float(scenario["duration_s"])
            runs.append(Run(len(runs), k, options.seed, {"direction_deg": beta, "wind_mps": wind}, {}, scenario,
                            duration, settle, run_key(scenario, duration, settle), {"direction": k, "wind": wind}))
        outcome: dict[int, dict[str, Any]] = {}

        def on_result(run: Run, result: dict[str, Any], outcome: dict[int, dict[str, Any]] = outcome) -> None:
            outcome[run.tags["direction"]] = result

        if not engine.run(runs, on_result, progress=progress,
                          description=f"level 3 {case.name} step {step + 1}/{options.iterations}"):
            raise KeyboardInterrupt
        for run in runs:
            k, wind = run.tags["direction"], run.tags["wind"]
            result = outcome[k]
            metrics = result.get("summary", {}).get("metrics", {}) if result.get("status") == "ok" else {}
            position = metrics.get("position_error_max_after_settle_m")
            heading = metrics.get("heading_error_max_after_settle_deg")
            ok = position is not None and heading is not None and position <= limit_m \
                and heading <= options.max_heading_deg
            points[k].append({"wind_mps": round(wind, 3), "held": ok, "status": result.get("status"),
                              "position_error_max_m": None if position is None else round(position * lam, 4),
                              "heading_error_max_deg": heading, "error": result.get("error")})
            if ok:
                lo[k] = wind
            else:
                hi[k] = wind
    return {"case": case.name, "failed": list(case.failed), "max_wind_mps": [round(w, 3) for w in lo],
            "bracket_high_mps": [round(h, 3) for h in hi], "runs": points}


# -- the command ------------------------------------------------------------------------------------------------
def run_capability(subject: Subject, cases: list[FailureCase], options: CapabilityOptions, out_dir: Path, *,
                   workers: int | None = None, scheduler: str | None = None, progress: bool = False,
                   engine: Any = None) -> dict[str, Any]:
    """Compute the cases, write ``capability.json`` and ``capability.png`` into ``out_dir``; returns the document.

    The top-level fields (``level``, ``vessel``, ``failed``, ``current_mps``, ``directions_deg``, ``max_wind_mps``,
    ``limiting_thruster``) describe the first failure case asked (the intact case when none); ``cases`` has every
    case, the intact one first.
    """
    directions = options.directions_deg
    common = {"current_mps": options.current_mps, "dynamic_allowance": options.dynamic_allowance,
              "max_wind_mps": options.max_wind_mps}
    level1_cases: list[dict[str, Any]] = []
    for case in cases:
        if case.name == "worst":
            candidates = [level1(subject, c, directions, **common) for c in subject.single_failures()]
            worst = dict(min(candidates, key=lambda c: polar_area(c["max_wind_mps"])))
            worst["case"] = f"worst single failure: {worst['case']}"
            worst["candidates"] = {c["case"]: round(polar_area(c["max_wind_mps"]) / max(
                polar_area(level1_cases[0]["max_wind_mps"]), 1e-9), 4) for c in candidates}
            level1_cases.append(worst)
        else:
            level1_cases.append(level1(subject, case, directions, **common))
    document: dict[str, Any] = {"level": options.level, "vessel": subject.vessel.name, "source": subject.source,
                                "model_scale": subject.scale, "current_mps": options.current_mps,
                                "directions_deg": directions, "wind_wave_relation": "DNV-ST-0111 Table 2-1",
                                "dynamic_allowance": options.dynamic_allowance,
                                "search_limit_mps": options.max_wind_mps}
    if options.level == 1:
        result_cases = level1_cases
    else:
        document.update(max_excursion_m=options.max_excursion_m, max_heading_deg=options.max_heading_deg,
                        settle_s=options.settle_s, window_s=options.window_s, iterations=options.iterations,
                        seed=options.seed)
        result_cases = []
        own = engine is None
        if own:
            from sim_plant.campaign.engine import Engine  # noqa: PLC0415

            engine = Engine(workers, scheduler).__enter__()
        try:
            for l1 in level1_cases:
                case = FailureCase(l1["case"], tuple(l1["failed"]))
                l3 = level3(subject, case, l1["max_wind_mps"], options, engine, progress=progress)
                l3["level1_max_wind_mps"] = l1["max_wind_mps"]
                l3["limiting_thruster"] = l1["limiting_thruster"]
                result_cases.append(l3)
        finally:
            if own:
                engine.close()
    main = result_cases[1] if len(result_cases) > 1 else result_cases[0]
    document.update(failed=main["failed"], max_wind_mps=main["max_wind_mps"],
                    limiting_thruster=main["limiting_thruster"], cases=result_cases)
    out_dir.mkdir(parents=True, exist_ok=True)
    (out_dir / "capability.json").write_text(json.dumps(document, indent=1, allow_nan=False) + "\n",
                                             encoding="utf-8")
    write_polar_plot(document, out_dir / "capability.png")
    return document


def write_polar_plot(document: Mapping[str, Any], path: Path) -> Path:
    """The capability plot as DP engineers draw it: wind direction around (0° = head-on at the top, clockwise),
    wind speed radially, one closed curve per case, Beaufort rings of Table 2-1 for reference."""
    import matplotlib  # noqa: PLC0415

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415
    from matplotlib.projections.polar import PolarAxes  # noqa: PLC0415

    directions = np.radians(np.asarray(document["directions_deg"], dtype=float))
    fig, axes = plt.subplots(figsize=(7.2, 7.6), subplot_kw={"projection": "polar"})
    ax = cast(PolarAxes, axes)  # what projection="polar" makes (subplots is typed as returning plain Axes)
    ax.set_theta_zero_location("N")
    ax.set_theta_direction(-1)
    top = 0.0
    for case in document["cases"]:
        winds = np.asarray(case["max_wind_mps"], dtype=float)
        top = max(top, float(winds.max()) if winds.size else 0.0)
        (line,) = ax.plot(np.r_[directions, directions[:1]], np.r_[winds, winds[:1]], lw=2.0, marker="o", ms=3,
                          label=case["case"] if document["level"] == 1 else f"{case['case']} (level 3)")
        if case.get("level1_max_wind_mps"):  # Level 3: its Level 1 curve for comparison (dynamics only cost)
            static = np.asarray(case["level1_max_wind_mps"], dtype=float)
            top = max(top, float(static.max()))
            ax.plot(np.r_[directions, directions[:1]], np.r_[static, static[:1]], lw=1.0, ls=":",
                    color=line.get_color(), label=f"{case['case']} (level 1)")
    searched = float(document.get("search_limit_mps") or 0.0)
    if searched and any(any(case.get("held_at_search_limit") or []) for case in document["cases"]):
        ax.plot(np.linspace(0, 2 * math.pi, 181), np.full(181, searched), color="0.4", lw=0.8, ls="--",
                label=f"search limit {searched:g} m/s (held there)")
    limit = max(5.0, 1.1 * top)
    for bf, (wind, _, _) in enumerate(TABLE_2_1, start=1):
        if wind <= limit:
            ax.plot(np.linspace(0, 2 * math.pi, 181), np.full(181, wind), color="0.8", lw=0.6, zorder=0)
            ax.annotate(f"BF{bf}", (math.radians(45.0), wind), fontsize=6, color="0.5")
    ax.set_ylim(0.0, limit)
    ax.set_rlabel_position(135)
    scale = document.get("model_scale", 1.0)
    extra = f", model 1:{scale:g} (Froude-scaled, full-scale wind)" if scale != 1.0 else ""
    allowance = f", dynamic allowance {document['dynamic_allowance']:g}" if document.get("dynamic_allowance", 1) != 1 \
        else ""
    ax.set_title(f"DP capability level {document['level']} — {document['vessel']}{extra}\n"
                 f"max mean wind [m/s] from each direction; current {document['current_mps']:g} m/s co-linear, "
                 f"sea DNV-ST-0111 Table 2-1{allowance}", fontsize=9)
    ax.legend(loc="lower center", bbox_to_anchor=(0.5, -0.16), fontsize=8, ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
