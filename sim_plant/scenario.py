"""Scenario files (docs/design.md §4.2): YAML → validated, frozen :class:`Scenario`.

Every error names the file, the key path and what was expected, and a misspelt key is rejected
by name (``dpbase.schema.Section.finish``)::

    sim_plant/scenarios/demo.yaml: sea_states[1].omega_peak_rads: expected a known key (valid keys here: ...)

Keys (all times in seconds from the start; angles in degrees in the file, radians inside):

``name`` (str), ``description`` (str, optional), ``vessel`` (built-in name or inline mapping, see
:func:`dpcontrol.models.vessels.vessel_from_config`), ``duration_s`` (> 0), ``seed`` (int ≥ 0, 0),
``controller`` (opaque mapping for the controller side; only checked to be a mapping),
``datum`` {``lat_deg``, ``lon_deg``} (origin of the NED frame), ``utc_start_s`` (UTC seconds of day at
t = 0, 36000), ``plant`` {``rate_hz`` (RK4 substep rate; per-vessel default), ``thruster_timeout_s`` (1.0)},
``initial`` {``north_m``, ``east_m``, ``heading_deg``, ``surge_mps`` (service speed for the mariner),
``sway_mps``, ``yaw_rate_degps``},
``sea_states`` [{``t_s``, ``spectrum`` (jonswap | pierson_moskowitz), ``hs_m``, ``omega_peak_rad_s`` or
``tp_s``, ``gamma`` (jonswap, 3.3), ``direction_deg`` (waves come FROM), ``components`` (≥ 100, 200),
``fade_s`` (30), ``swell`` (optional: a second wave system beside the wind sea, {``hs_m``, ``omega_peak_rad_s`` or
``tp_s``, ``direction_deg``, ``spectrum``, ``gamma``, ``components``})}] (calm before the first; changes at least
``fade_s`` apart),
``current`` {``speed_mps``, ``direction_deg`` (flows TOWARD), ``variation`` {``speed_std_mps``,
``direction_std_deg``, ``time_constant_s``}},
``wind`` {``speed_mps`` (1-h mean at 10 m), ``direction_deg`` (comes FROM), ``gusts`` (true), ``height_m``},
``setpoints`` [{``t_s``, ``north_m``, ``east_m``, ``heading_deg``}] (position and/or heading; a
heading-only setpoint is an autopilot course),
``mass_schedule`` [{``t_s``, ``factor``}] (linear in between, constant outside),
``faults`` [{``t_s``, ``kind``, ``duration_s`` (optional: to the end), ``sensor`` | ``thruster`` |
``target``, and per kind: ``gnss_jump`` ``offset_m``, ``direction_deg``; ``gnss_drift`` ``rate_mps``,
``direction_deg``; ``gnss_noise`` ``factor``; ``gyro_offset`` ``offset_deg``; ``gyro_drift``
``rate_degps``; ``rot_offset`` ``rate_degps``; ``malformed_burst`` ``count``}],
``sensors`` [{``name``, ``kind`` gnss | gyro | rot, ``protocol`` nmea0183 | nmea2000 | mavlink, ``rate_hz``,
``offset_s``; gnss: ``noise_m``, ``markov_m``, ``markov_time_constant_s``, ``lever_arm_m`` [x, y],
``quality``, ``satellites``, ``hdop``, ``antenna_height_m``, ``gst``, ``velocity`` (SOG/COG, true),
``velocity_noise_mps`` (0.02); gyro: ``noise_deg``, ``bias_deg``,
``markov_deg``, ``markov_time_constant_s``, ``rate_of_turn``, ``rot_noise_degps``; rot (a rate-of-turn sensor
independent of the gyros): ``noise_degps`` (0.01), ``bias_degps`` (0.03)}] (default: one GNSS
``gnss1`` and one gyro ``gyro1`` on nmea0183 with the vessel's default noise).

Values past the range of the plant's models are refused as typos: ``hs_m`` ≤ 30, current ``speed_mps``
and ``speed_std_mps`` ≤ 10, wind ``speed_mps`` ≤ 80, initial ``surge_mps``/``sway_mps`` within ±30 and
``yaw_rate_degps`` within ±30; GNSS ``noise_m``, ``markov_m`` ≤ 1000 and ``antenna_height_m`` within
±1000, ``hdop`` < 100; gyro ``noise_deg``, ``markov_deg`` ≤ 180, ``rot_noise_degps`` ≤ 30; rot ``noise_degps`` ≤ 30
and ``bias_degps`` within ±30. A run that still
drives the vessel's state to overflow (inline vessel data far from any ship) stops with
:class:`sim_plant.plant.PlantDivergedError`, naming the time.
"""

from __future__ import annotations

import bisect
import copy
import itertools
import math
import operator
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

from dpbase.schema import ConfigError, Section, join
from dpbase.yamlfile import read_yaml_file
from dpcontrol.models.vessels import VesselData, vessel_from_config
from interfaces.messages import FixQuality
from sim_plant.environment.spectra import SPECTRA
from sim_plant.environment.waves import SeaState, WaveSystem
from sim_plant.faults import FAULT_KINDS, GNSS_FAULTS, GYRO_FAULTS, ROT_FAULTS, THRUSTER_FAULTS, Fault
from sim_plant.sensors import PROTOCOLS, SENSOR_KINDS, GnssSpec, GyroSpec, RotSpec, SensorSpec
from sim_plant.vessel_data import extras_for

# The range of the plant's models, beyond any sea a vessel keeps station in (a value past it is a typo, and
# would drive the integration to overflow): the highest waves recorded are below 30 m Hs, ocean currents
# below 3 m/s (tidal races 7 m/s), 10-min mean winds of a category-5 hurricane about 70 m/s.
MAX_HS_M = 30.0
MAX_CURRENT_MPS = 10.0
MAX_WIND_MPS = 80.0
MAX_SPEED_MPS = 30.0
MAX_YAW_RATE_DEGPS = 30.0
MAX_GNSS_ERROR_M = 1000.0  # noise, slow error and antenna height: far beyond any receiver a DP system uses

DEFAULT_DATUM_DEG = (63.4305, 10.3951)  # Trondheim fjord, home of CyberShip II
DEFAULT_UTC_START_S = 36000.0
MIN_WAVE_COMPONENTS = 100
QUALITIES: dict[str, FixQuality] = {q.name.lower(): q for q in FixQuality if q is not FixQuality.INVALID}


class ReadOnlyMapping(Mapping[str, Any]):
    """A read-only view of a (deep-copied) mapping; unlike ``types.MappingProxyType`` it pickles,
    so a :class:`Scenario` can be sent to another process."""

    __slots__ = ("_data",)

    def __init__(self, data: Mapping[str, Any]) -> None:
        self._data = copy.deepcopy(dict(data))

    def __getitem__(self, key: str) -> Any:
        return self._data[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self._data)

    def __len__(self) -> int:
        return len(self._data)

    def __repr__(self) -> str:
        return f"ReadOnlyMapping({self._data!r})"

    def to_dict(self) -> dict[str, Any]:
        """A deep, mutable copy."""
        return copy.deepcopy(self._data)

    def __reduce__(self) -> tuple[Any, ...]:
        return (ReadOnlyMapping, (self._data,))


_POINT_TIME = operator.attrgetter("t_s")  # the time of a schedule point (MassPoint)


@dataclass(frozen=True)
class Datum:
    """Origin of the plant's NED frame (WGS-84) [deg]."""

    lat_deg: float
    lon_deg: float


@dataclass(frozen=True)
class PlantSettings:
    """Integration rate [Hz] and drive command timeout [s]."""

    rate_hz: float
    thruster_timeout_s: float = 1.0


@dataclass(frozen=True)
class InitialState:
    """Initial LF pose (NED) and body velocity."""

    north_m: float = 0.0
    east_m: float = 0.0
    heading_rad: float = 0.0
    surge_mps: float = 0.0
    sway_mps: float = 0.0
    yaw_rate_radps: float = 0.0


@dataclass(frozen=True)
class CurrentSpec:
    """Current: speed, direction it flows toward (NED) and optional slow variation."""

    speed_mps: float = 0.0
    direction_rad: float = 0.0
    speed_std_mps: float = 0.0
    direction_std_rad: float = 0.0
    time_constant_s: float = 600.0


@dataclass(frozen=True)
class WindSpec:
    """Wind: 1-h mean speed at ``height_m``, direction it comes from (NED), gusts on/off."""

    speed_mps: float = 0.0
    direction_rad: float = 0.0
    gusts: bool = True
    height_m: float = 10.0


@dataclass(frozen=True)
class Setpoint:
    """Operator setpoint from ``t_s`` on; ``north_m``/``east_m`` None = heading only (autopilot)."""

    t_s: float
    north_m: float | None
    east_m: float | None
    heading_rad: float | None


@dataclass(frozen=True)
class MassPoint:
    """Mass factor (rigid-body mass / the vessel's) at ``t_s``."""

    t_s: float
    factor: float


@dataclass(frozen=True, eq=False)
class Scenario:
    """A validated scenario (see the module docstring for the file format).

    ``controller`` is a read-only copy of the ``controller:`` mapping (nested values as in the
    file; ``.to_dict()`` for a mutable copy), for the controller side to validate.
    """

    name: str
    vessel: VesselData
    duration_s: float
    seed: int
    controller: Mapping[str, Any]
    datum: Datum
    utc_start_s: float
    plant: PlantSettings
    initial: InitialState
    sea_states: tuple[SeaState, ...]
    current: CurrentSpec
    wind: WindSpec
    setpoints: tuple[Setpoint, ...]
    mass_schedule: tuple[MassPoint, ...]
    faults: tuple[Fault, ...]
    sensors: tuple[SensorSpec, ...]
    description: str = ""
    source: str | None = None

    def sea_state_at(self, t_s: float) -> SeaState | None:
        """The sea state in force at ``t_s`` (None = calm, before the first)."""
        i = bisect.bisect_right([s.t_s for s in self.sea_states], t_s) - 1
        return None if i < 0 else self.sea_states[i]

    def setpoint_at(self, t_s: float) -> Setpoint | None:
        """The setpoint in force at ``t_s`` (None before the first)."""
        i = bisect.bisect_right([s.t_s for s in self.setpoints], t_s) - 1
        return None if i < 0 else self.setpoints[i]

    def mass_factor_at(self, t_s: float) -> float:
        """Mass factor at ``t_s``: linear between schedule points, constant outside (1 if none)."""
        points = self.mass_schedule
        if not points:
            return 1.0
        if t_s <= points[0].t_s:
            return points[0].factor
        if t_s >= points[-1].t_s:
            return points[-1].factor
        # (bisect on the points' times directly: the plant asks every substep, a list of the times costs more)
        i = bisect.bisect_right(points, t_s, key=_POINT_TIME)
        a, b = points[i - 1], points[i]
        return a.factor + (b.factor - a.factor) * (t_s - a.t_s) / (b.t_s - a.t_s)

    def sensor(self, name: str) -> SensorSpec:
        """The sensor spec called ``name`` (KeyError if none)."""
        for spec in self.sensors:
            if spec.name == name:
                return spec
        raise KeyError(name)


# -- loading --------------------------------------------------------------------------------------
def load_scenario(path: str | Path) -> Scenario:
    """Read and validate a scenario YAML file.

    Raises
    ------
    ConfigError
        An unreadable file, not UTF-8 text, invalid YAML or content (the message names the file and the
        key path).
    """
    _, data = read_yaml_file(path, what="a readable scenario file")
    return parse_scenario(data, file=str(path))


def builtin_scenario_names() -> list[str]:
    """Names of the scenarios shipped in ``sim_plant/scenarios`` (without ``.yaml``)."""
    folder = resources.files("sim_plant") / "scenarios"
    return sorted(p.name[: -len(".yaml")] for p in folder.iterdir() if p.name.endswith(".yaml"))


def builtin_fault_scenario_names() -> list[str]:
    """Names of the fault scenarios shipped in ``sim_plant/scenarios/faults``, as ``faults/<name>``."""
    folder = resources.files("sim_plant") / "scenarios" / "faults"
    return sorted(f"faults/{p.name[: -len('.yaml')]}" for p in folder.iterdir() if p.name.endswith(".yaml"))


def builtin_scenario_path(name: str) -> Path:
    """Path of a shipped scenario (``demo``, ``cs2-seed000`` ..., or a fault scenario ``faults/01-gnss-freeze``).

    Raises
    ------
    KeyError
        Unknown name (the message lists the known ones).
    """
    names = builtin_scenario_names()
    faults = builtin_fault_scenario_names()
    if name not in names and name not in faults:
        raise KeyError(f"unknown built-in scenario {name!r} (known: {', '.join(names)}; fault scenarios: "
                       f"{', '.join(faults)}), and no file of that name")
    return Path(str(resources.files("sim_plant") / "scenarios" / f"{name}.yaml"))


def parse_scenario(data: object, file: str | None = None) -> Scenario:
    """Validate an already-parsed mapping into a :class:`Scenario`.

    Raises
    ------
    ConfigError
        Naming ``file`` (when given), the key path and what was expected.
    """
    try:
        return _parse(data, file)
    except ConfigError as error:
        raise (error.with_file(file) if file else error) from None


def _parse(data: object, file: str | None) -> Scenario:
    root = Section.of(data, "")
    name = root.string("name")
    description = root.string("description", "") if root.has("description") else ""
    vessel = vessel_from_config(root.raw("vessel"), "vessel")
    extras = extras_for(vessel)
    duration = root.number("duration_s", minimum=0.0, exclusive_minimum=True)
    seed = root.integer("seed", 0, minimum=0)
    controller_raw = root.raw("controller", {})
    if controller_raw is None:
        controller_raw = {}
    if not isinstance(controller_raw, Mapping):
        raise ConfigError("controller", "a mapping (passed to the controller side)", controller_raw)
    controller = ReadOnlyMapping(controller_raw)

    datum_sec = root.section("datum")
    datum = Datum(datum_sec.number("lat_deg", DEFAULT_DATUM_DEG[0], minimum=-90.0, maximum=90.0),
                  datum_sec.number("lon_deg", DEFAULT_DATUM_DEG[1], minimum=-180.0, maximum=180.0))
    datum_sec.finish()
    utc_start = root.number("utc_start_s", DEFAULT_UTC_START_S, minimum=0.0)
    if utc_start >= 86400.0:
        raise ConfigError("utc_start_s", "seconds of day in [0, 86400)", utc_start)

    plant_sec = root.section("plant")
    plant = PlantSettings(
        rate_hz=plant_sec.number("rate_hz", extras.default_plant_rate_hz, minimum=0.0, exclusive_minimum=True,
                                 maximum=1000.0),
        thruster_timeout_s=plant_sec.number("thruster_timeout_s", 1.0, minimum=0.0, exclusive_minimum=True),
    )
    plant_sec.finish()

    init_sec = root.section("initial")
    initial = InitialState(
        north_m=init_sec.number("north_m", 0.0),
        east_m=init_sec.number("east_m", 0.0),
        heading_rad=math.radians(init_sec.number("heading_deg", 0.0)),
        surge_mps=init_sec.number("surge_mps", vessel.service_speed_mps, minimum=-MAX_SPEED_MPS,
                                  maximum=MAX_SPEED_MPS),
        sway_mps=init_sec.number("sway_mps", 0.0, minimum=-MAX_SPEED_MPS, maximum=MAX_SPEED_MPS),
        yaw_rate_radps=math.radians(init_sec.number("yaw_rate_degps", 0.0, minimum=-MAX_YAW_RATE_DEGPS,
                                                    maximum=MAX_YAW_RATE_DEGPS)),
    )
    init_sec.finish()
    if extras.manoeuvring is not None and not initial.surge_mps > 0.0:
        raise ConfigError("initial.surge_mps", f"a forward speed > 0 for the course-keeping vessel {vessel.name}",
                          initial.surge_mps)

    sea_states = _sea_states(root)
    current = _current(root.section("current"))
    wind = _wind(root.section("wind"))
    setpoints = _setpoints(root)
    mass_schedule = _mass_schedule(root)
    sensors = _sensors(root, extras.default_gnss_noise_m, extras.default_gyro_noise_deg)
    faults = _faults(root, sensors, vessel)
    root.finish()
    return Scenario(name=name, vessel=vessel, duration_s=duration, seed=seed, controller=controller, datum=datum,
                    utc_start_s=utc_start, plant=plant, initial=initial, sea_states=sea_states, current=current,
                    wind=wind, setpoints=setpoints, mass_schedule=mass_schedule, faults=faults, sensors=sensors,
                    description=description, source=file)


def _increasing(times: list[tuple[str, float]], what: str) -> None:
    for (_, earlier), (where, later) in itertools.pairwise(times):
        if later <= earlier:
            raise ConfigError(where, f"{what} times in increasing order (after {earlier:g} s)", later)


def _wave_system(sec: Section, where: str) -> WaveSystem:
    """The spectrum keys of a sea state or of its swell: ``hs_m``, ``omega_peak_rad_s`` or ``tp_s``, ``spectrum``,
    ``gamma``, ``direction_deg``, ``components``."""
    spectrum = sec.string("spectrum", "jonswap", choices=SPECTRA)
    hs = sec.number("hs_m", minimum=0.0, maximum=MAX_HS_M)
    if sec.has("omega_peak_rad_s") == sec.has("tp_s"):
        raise ConfigError(join(where, "omega_peak_rad_s"), "exactly one of omega_peak_rad_s or tp_s",
                          show_got=False)
    if sec.has("tp_s"):
        omega = 2.0 * math.pi / sec.number("tp_s", minimum=0.0, exclusive_minimum=True)
    else:
        omega = sec.number("omega_peak_rad_s", minimum=0.0, exclusive_minimum=True)
    if spectrum == "jonswap":
        gamma = sec.number("gamma", 3.3, minimum=1.0, maximum=20.0)
    elif sec.has("gamma"):
        raise ConfigError(join(where, "gamma"), "no gamma for spectrum pierson_moskowitz (it is jonswap's)",
                          show_got=False)
    else:
        gamma = 1.0
    return WaveSystem(hs_m=hs, omega_peak_rad_s=omega, direction_rad=math.radians(sec.number("direction_deg", 0.0)),
                      spectrum=spectrum, gamma=gamma,
                      components=sec.integer("components", 200, minimum=MIN_WAVE_COMPONENTS, maximum=5000))


def _sea_states(root: Section) -> tuple[SeaState, ...]:
    states: list[SeaState] = []
    times: list[tuple[str, float]] = []
    for where, item in root.items("sea_states"):
        sec = Section.of(item, where)
        t = sec.number("t_s", minimum=0.0)
        wind_sea = _wave_system(sec, where)
        swell = None
        if sec.has("swell"):
            swell_sec = sec.section("swell")
            swell = _wave_system(swell_sec, swell_sec.path)
            swell_sec.finish()
        state = SeaState(
            t_s=t, hs_m=wind_sea.hs_m, omega_peak_rad_s=wind_sea.omega_peak_rad_s,
            direction_rad=wind_sea.direction_rad, spectrum=wind_sea.spectrum, gamma=wind_sea.gamma,
            components=wind_sea.components, fade_s=sec.number("fade_s", 30.0, minimum=0.0), swell=swell,
        )
        sec.finish()
        if states and state.t_s < states[-1].t_s + state.fade_s:
            raise ConfigError(join(where, "t_s"),
                              f"a start at least fade_s = {state.fade_s:g} s after the previous sea state "
                              f"({states[-1].t_s:g} s)", state.t_s)
        times.append((join(where, "t_s"), t))
        states.append(state)
    _increasing(times, "sea state")
    return tuple(states)


def _current(sec: Section) -> CurrentSpec:
    var = sec.section("variation")
    spec = CurrentSpec(
        speed_mps=sec.number("speed_mps", 0.0, minimum=0.0, maximum=MAX_CURRENT_MPS),
        direction_rad=math.radians(sec.number("direction_deg", 0.0)),
        speed_std_mps=var.number("speed_std_mps", 0.0, minimum=0.0, maximum=MAX_CURRENT_MPS),
        direction_std_rad=math.radians(var.number("direction_std_deg", 0.0, minimum=0.0)),
        time_constant_s=var.number("time_constant_s", 600.0, minimum=0.0, exclusive_minimum=True),
    )
    var.finish()
    sec.finish()
    return spec


def _wind(sec: Section) -> WindSpec:
    spec = WindSpec(
        speed_mps=sec.number("speed_mps", 0.0, minimum=0.0, maximum=MAX_WIND_MPS),
        direction_rad=math.radians(sec.number("direction_deg", 0.0)),
        gusts=sec.boolean("gusts", True),
        height_m=sec.number("height_m", 10.0, minimum=0.0, exclusive_minimum=True),
    )
    sec.finish()
    return spec


def _setpoints(root: Section) -> tuple[Setpoint, ...]:
    points: list[Setpoint] = []
    times: list[tuple[str, float]] = []
    for where, item in root.items("setpoints"):
        sec = Section.of(item, where)
        t = sec.number("t_s", minimum=0.0)
        north = sec.optional_number("north_m")
        east = sec.optional_number("east_m")
        heading = sec.optional_number("heading_deg")
        sec.finish()
        if (north is None) != (east is None):
            raise ConfigError(join(where, "north_m" if north is None else "east_m"),
                              "north_m and east_m together (or neither, for a heading-only setpoint)",
                              show_got=False)
        if north is None and heading is None:
            raise ConfigError(join(where, "heading_deg"), "a position (north_m, east_m) and/or heading_deg",
                              show_got=False)
        times.append((join(where, "t_s"), t))
        points.append(Setpoint(t, north, east, None if heading is None else math.radians(heading)))
    _increasing(times, "setpoint")
    return tuple(points)


def _mass_schedule(root: Section) -> tuple[MassPoint, ...]:
    points: list[MassPoint] = []
    times: list[tuple[str, float]] = []
    for where, item in root.items("mass_schedule"):
        sec = Section.of(item, where)
        point = MassPoint(sec.number("t_s", minimum=0.0),
                          sec.number("factor", minimum=0.0, exclusive_minimum=True, maximum=10.0))
        sec.finish()
        times.append((join(where, "t_s"), point.t_s))
        points.append(point)
    _increasing(times, "mass schedule")
    return tuple(points)


def _sensors(root: Section, gnss_noise_m: float, gyro_noise_deg: float) -> tuple[SensorSpec, ...]:
    if not root.has("sensors") or root.raw("sensors", None) is None:
        root.raw("sensors", None)
        return (GnssSpec("gnss1", noise_m=gnss_noise_m),
                GyroSpec("gyro1", noise_rad=math.radians(gyro_noise_deg)))
    specs: list[SensorSpec] = []
    names: set[str] = set()
    for where, item in root.items("sensors"):  # an explicit [] means no sensors
        sec = Section.of(item, where)
        name = sec.string("name")
        if name in names:
            raise ConfigError(join(where, "name"), "a sensor name not used before", name)
        names.add(name)
        kind = sec.string("kind", choices=SENSOR_KINDS)
        protocol = sec.string("protocol", "nmea0183", choices=PROTOCOLS)
        offset = sec.number("offset_s", 0.0, minimum=0.0)
        spec: SensorSpec
        if kind == "gnss":
            lever = sec.vector("lever_arm_m", 2, [0.0, 0.0])
            quality = sec.string("quality", "dgps", choices=QUALITIES)
            spec = GnssSpec(
                name=name, protocol=protocol,
                rate_hz=sec.number("rate_hz", 5.0, minimum=0.0, exclusive_minimum=True, maximum=100.0),
                noise_m=sec.number("noise_m", gnss_noise_m, minimum=0.0, maximum=MAX_GNSS_ERROR_M),
                markov_m=sec.number("markov_m", 0.0, minimum=0.0, maximum=MAX_GNSS_ERROR_M),
                markov_time_constant_s=sec.number("markov_time_constant_s", 300.0, minimum=0.0,
                                                  exclusive_minimum=True),
                lever_arm_m=(float(lever[0]), float(lever[1])),
                quality=QUALITIES[quality],
                satellites=sec.integer("satellites", 12, minimum=0, maximum=99),
                hdop=sec.number("hdop", 0.8, minimum=0.0, maximum=99.99),  # (GGA's field: 2 decimals, < 100)
                antenna_height_m=sec.number("antenna_height_m", 0.0, minimum=-MAX_GNSS_ERROR_M,
                                            maximum=MAX_GNSS_ERROR_M),
                gst=sec.boolean("gst", True),
                offset_s=offset,
                velocity=sec.boolean("velocity", True),
                velocity_noise_mps=sec.number("velocity_noise_mps", 0.02, minimum=0.0, maximum=100.0),
            )
        elif kind == "rot":
            spec = RotSpec(
                name=name, protocol=protocol,
                rate_hz=sec.number("rate_hz", 10.0, minimum=0.0, exclusive_minimum=True, maximum=200.0),
                noise_radps=math.radians(sec.number("noise_degps", 0.01, minimum=0.0, maximum=MAX_YAW_RATE_DEGPS)),
                bias_radps=math.radians(sec.number("bias_degps", 0.03, minimum=-MAX_YAW_RATE_DEGPS,
                                                   maximum=MAX_YAW_RATE_DEGPS)),
                offset_s=offset,
            )
        else:
            spec = GyroSpec(
                name=name, protocol=protocol,
                rate_hz=sec.number("rate_hz", 10.0, minimum=0.0, exclusive_minimum=True, maximum=200.0),
                noise_rad=math.radians(sec.number("noise_deg", gyro_noise_deg, minimum=0.0, maximum=180.0)),
                bias_rad=math.radians(sec.number("bias_deg", 0.0)),
                markov_rad=math.radians(sec.number("markov_deg", 0.0, minimum=0.0, maximum=180.0)),
                markov_time_constant_s=sec.number("markov_time_constant_s", 600.0, minimum=0.0,
                                                  exclusive_minimum=True),
                rate_of_turn=sec.boolean("rate_of_turn", True),
                rot_noise_radps=math.radians(sec.number("rot_noise_degps", 0.02, minimum=0.0,
                                                        maximum=MAX_YAW_RATE_DEGPS)),
                offset_s=offset,
            )
        sec.finish()
        specs.append(spec)
    return tuple(specs)


_FAULT_PARAMS: dict[str, tuple[str, ...]] = {
    "gnss_jump": ("offset_m", "direction_deg"),
    "gnss_drift": ("rate_mps", "direction_deg"),
    "gnss_noise": ("factor",),
    "gyro_offset": ("offset_deg",),
    "gyro_drift": ("rate_degps",),
    "rot_offset": ("rate_degps",),
    "malformed_burst": ("count",),
}


def _faults(root: Section, sensors: tuple[SensorSpec, ...], vessel: VesselData) -> tuple[Fault, ...]:
    by_name = {s.name: s for s in sensors}
    thrusters = [t.name for t in vessel.thrusters]
    faults: list[Fault] = []
    for where, item in root.items("faults"):
        sec = Section.of(item, where)
        t = sec.number("t_s", minimum=0.0)
        kind = sec.string("kind", choices=FAULT_KINDS)
        duration = sec.optional_number("duration_s", minimum=0.0, exclusive_minimum=True)
        target_keys = [k for k in ("sensor", "thruster", "target") if sec.has(k)]
        if len(target_keys) != 1:
            raise ConfigError(join(where, "sensor"), "exactly one of sensor, thruster or target", show_got=False)
        key = target_keys[0]
        target = sec.string(key)
        key_path = join(where, key)
        if kind in THRUSTER_FAULTS:
            if key == "sensor" or target not in thrusters:
                raise ConfigError(key_path, f"a thruster of {vessel.name} ({', '.join(thrusters)})", target)
        else:
            if key == "thruster" or target not in by_name:
                raise ConfigError(key_path, f"a sensor name ({', '.join(by_name)})", target)
            spec = by_name[target]
            if kind in GNSS_FAULTS and spec.kind != "gnss":
                raise ConfigError(key_path, f"a gnss sensor for {kind}", target)
            if kind in GYRO_FAULTS and spec.kind != "gyro":
                raise ConfigError(key_path, f"a gyro sensor for {kind}", target)
            if kind in ROT_FAULTS and spec.kind != "rot":
                raise ConfigError(key_path, f"a rot (rate-of-turn) sensor for {kind}", target)
            if kind == "serial_unplug" and spec.protocol != "nmea0183":
                raise ConfigError(key_path, "a sensor on a serial line (protocol nmea0183) for serial_unplug", target)
            if kind == "heartbeat_loss" and spec.protocol != "mavlink":
                raise ConfigError(key_path, "a sensor on MAVLink (which has heartbeats) for heartbeat_loss", target)
        params = _FAULT_PARAMS.get(kind, ())
        values: dict[str, Any] = {}
        if "offset_m" in params:
            values["offset_m"] = sec.number("offset_m", minimum=0.0)
        if "direction_deg" in params:
            values["direction_rad"] = math.radians(sec.number("direction_deg", 0.0))
        if "rate_mps" in params:
            values["rate_mps"] = sec.number("rate_mps", minimum=0.0)
        if "factor" in params:
            values["factor"] = sec.number("factor", minimum=0.0)
        if "offset_deg" in params:
            values["offset_rad"] = math.radians(sec.number("offset_deg"))
        if "rate_degps" in params:
            values["rate_radps"] = math.radians(sec.number("rate_degps"))
        if "count" in params:
            values["count"] = sec.integer("count", 10, minimum=1, maximum=100000)
        sec.finish()
        faults.append(Fault(t_s=t, kind=kind, target=target, duration_s=duration, **values))
    return tuple(sorted(faults, key=lambda f: f.t_s))
