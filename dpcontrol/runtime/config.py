"""The daemon's configuration: one YAML file per vessel → frozen dataclasses, validated on load.

Every error names the file, the key path and what was expected; the daemon refuses to start on an
invalid file (``dpcontrol check-config FILE`` runs the same validation). The sections are
documented in the README ("Configuration reference") and exemplified in ``deploy/config/``.
"""

from __future__ import annotations

import hashlib
import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from dpbase.schema import ConfigError, Section, VesselDefault, join, parse_list
from dpbase.yamlfile import load_yaml, read_yaml_file
from dpcontrol.allocation.allocator import allocator_kwargs_from_mapping
from dpcontrol.allocation.consequence import FailureGroup
from dpcontrol.control import CONTROL_KINDS, ControlConfig, DefaultControl, control_config_from_mapping, default_control
from dpcontrol.control.mrac import LOADING_VESSELS
from dpcontrol.estimation import WaveFilterConfig
from dpcontrol.estimation.filter_config import DEFAULT_OMEGA0_RAD_S, DEFAULT_OMEGAS_RAD_S, LengthScaledGrid
from dpcontrol.guidance import ReferenceModelConfig, reference_config_from_mapping
from dpcontrol.models.vessels import BUILTIN_VESSELS, VesselData, vessel_from_config
from dpcontrol.runtime.consequence import ConsequenceSettings
from dpcontrol.runtime.deviation import DeviationSettings, drift_off_horizon_s
from dpcontrol.runtime.hub import HubConfig, SensorConfig, SensorKind
from dpcontrol.runtime.thruster_monitor import ThrusterMonitorSettings
from interfaces.nmea0183.codec import DEFAULT_MAX_SENTENCE_CHARS
from interfaces.recorder import RecorderSettings
from interfaces.zenoh.security import unprotected_endpoints
from interfaces.zenoh.session_config import ZenohConfig

PROTOCOLS = ("nmea0183", "nmea2000", "mavlink")
MODES = ("standby", "auto_heading", "auto_position")
FALLBACKS = ("dead_reckoning", "hold_heading", "zero_surge_sway", "standby")
VESSEL_ID_PATTERN = re.compile(r"^[A-Za-z0-9_\-]{1,64}$")


@dataclass(frozen=True)
class TransportConfig:
    """One physical input: a serial port, a CAN bus or a MAVLink link.

    ``settings`` holds the protocol's own keys: nmea0183 ``port, baud, max_sentence_chars``; nmea2000
    ``interface, channel`` (+ ``bitrate`` etc. passed to python-can; or a gateway: ``interface`` ydwg_tcp,
    ydwg_udp, ngt1_serial with ``channel`` HOST:PORT or the serial device) and ``variation_deg``; mavlink
    ``url`` (+ ``signing_key_hex``). ``in_process``: no device — the bytes are handed over within the process
    (:func:`in_process_transport`); the daemon has no reader for it.
    """

    name: str
    protocol: str
    settings: Mapping[str, Any]
    in_process: bool = False


def in_process_transport(name: str, protocol: str) -> TransportConfig:
    """A transport whose bytes are handed over within the process (the lockstep simulation feeds the plant's
    encoded bytes to the input stage): the protocol's decoding settings at their defaults, no device.

    Raises
    ------
    ValueError
        An unknown protocol.
    """
    decoding: dict[str, dict[str, Any]] = {
        "nmea0183": {"max_sentence_chars": DEFAULT_MAX_SENTENCE_CHARS},
        "nmea2000": {"variation_deg": None},
        "mavlink": {"signing_key_hex": None, "heartbeat_timeout_s": 5.0},
    }
    if protocol not in decoding:
        raise ValueError(f"transport {name}: unknown protocol {protocol!r} (one of {', '.join(PROTOCOLS)})")
    return TransportConfig(name, protocol, decoding[protocol], in_process=True)


@dataclass(frozen=True)
class SensorRoute:
    """How a sensor's messages are picked out of its transport's traffic."""

    sensor: SensorConfig
    transport: str
    talker: str | None = None  # NMEA 0183 talker ID filter (e.g. "GP", "HE")
    sentences: tuple[str, ...] = ()  # NMEA 0183 sentence types used (default per kind)
    source_address: int | None = None  # NMEA 2000 source address filter
    system_id: int | None = None  # MAVLink system ID filter
    source_name: int | None = None  # NMEA 2000 NAME filter (the 64-bit NAME of its 60928 address claim)


ESTIMATOR_KINDS = ("mmae", "kf", "rpem", "pem", "raw", "kalman_bucy", "heading_kf")
#: Estimators that estimate no bias (seed 004's Kalman–Bucy filter: positions and velocities only): an MRAC on
#: them integrates the error itself (``integral_action: integrator``) unless configured otherwise.
ESTIMATORS_WITHOUT_BIAS = ("kalman_bucy",)
#: The sections that set how the controller behaves, as opposed to the installation (vessel_id, transports,
#: sensors, zenoh, recorder, state, loop): what a scenario's ``controller:`` or an example configuration gives.
CONTROLLER_SECTIONS = ("estimator", "control", "guidance", "allocation", "hub", "fallback", "thruster_monitor",
                       "consequence", "deviation")


@dataclass(frozen=True)
class EstimatorSettings:
    """Estimator selection; ``wave_filter`` is the validated core config for the DP wave filters
    (mmae, kf, rpem, raw), ``options`` the keys of the adapters (kalman_bucy, heading_kf)."""

    kind: str
    wave_filter: WaveFilterConfig | None
    options: Mapping[str, Any] = field(default_factory=dict)
    notices: tuple[str, ...] = ()  # deprecated key names read under their new name (see DaemonConfig.notices)


@dataclass(frozen=True)
class ControlSettings:
    """Controller selection with its validated core configuration."""

    kind: str
    config: ControlConfig
    default: DefaultControl | None = None  # the vessel's default controller and why (None: not known)
    configured: bool = True  # the file gives control.kind (False: the vessel's default runs)

    def origin(self, vessel_name: str) -> str:
        """For ``check-config``: the controller, whether the file chose it or it is the vessel's default, and why."""
        if self.default is None:
            return f"control {self.kind}: configured (control.kind)"
        if self.configured:
            return (f"control {self.kind}: configured (control.kind; the default for vessel {vessel_name} is "
                    f"{self.default.describe()})")
        return (f"control {self.default.describe()}: the default for vessel {vessel_name} (no control.kind given) "
                f"— {self.default.reason}")


@dataclass(frozen=True)
class FallbackSettings:
    """What the loop does when references are lost (defaults justified in docs/fault-handling.md).

    While no reference of a kind is in use the estimator dead-reckons it on the model (alarms
    ``position.dead_reckoning`` / ``heading.dead_reckoning`` at once). After ``dead_reckoning_limit_s`` /
    ``heading_loss_limit_s`` the configured fall-back: ``dead_reckoning`` (the default: keep holding on the
    model, the alarm raised again as critical — the operator decides; thrust is never cut because a sensor
    froze), ``hold_heading`` / ``zero_surge_sway`` (``auto_heading``: no surge and sway force) or ``standby``
    (zero thrust). A fall-back that lasted less than ``restore_within_s`` is undone when the references are
    back (the mode it fell back from is entered again, bumplessly, with an event); after that the operator
    decides. An estimator without a vessel model (``kalman_bucy``) cannot dead-reckon position: its loss takes
    the fall-back at once, ``dead_reckoning`` read as ``hold_heading`` (``DpController._position_loss``)."""

    dead_reckoning_limit_s: float = 60.0
    position_loss: str = "dead_reckoning"
    heading_loss_limit_s: float = 60.0
    heading_loss: str = "dead_reckoning"
    restore_within_s: float = 300.0


@dataclass(frozen=True)
class StateSettings:
    """Persisted estimator/controller state for a bumpless restart (docs/installation.md, restarts)."""

    path: str | None = None
    period_s: float = 1.0
    max_age_s: float = 30.0


@dataclass(frozen=True)
class RealtimeSettings:
    """Scheduling of the control loop's thread (``loop.realtime_priority``, ``loop.cpu_affinity``,
    ``loop.deadline_spin_ms``).

    ``priority`` (1–99): SCHED_FIFO at that priority for the loop thread only — the sensor readers
    and Zenoh's threads stay at normal priority, so the loop preempts them (and any other process)
    the moment its deadline comes; None keeps the normal scheduler. ``cpus``: the CPUs the loop
    thread may run on (empty: any). ``spin_s``: the loop sleeps until this long before each
    deadline and spins the rest, with the GIL released (:mod:`dpcontrol.service.spin`), so the
    cycle starts on time instead of a wake-up latency late [s]; 0 sleeps to the deadline.
    """

    priority: int | None = None
    cpus: tuple[int, ...] = ()
    spin_s: float = 0.002


@dataclass(frozen=True)
class ReplicaSettings:
    """The controller replica (``loop.replica_check``, ``loop.replica_lead_ms``;
    :mod:`dpcontrol.service.replica`).

    ``enabled``: keep a second controller one cycle behind that recomputes every command and
    compares. ``lead_s``: how long before each deadline it runs [s] (it also warms the caches for
    the primary's step; it must finish before the deadline, or the cycle starts late).
    """

    enabled: bool = True
    lead_s: float = 0.003


@dataclass(frozen=True)
class DaemonConfig:
    """The whole validated configuration of ``dpcontrol run``."""

    vessel_id: str
    vessel: VesselData
    datum: tuple[float, float] | None
    rate_hz: float
    initial_mode: str
    auto_engage_s: float | None
    transports: tuple[TransportConfig, ...]
    routes: tuple[SensorRoute, ...]
    estimator: EstimatorSettings
    guidance: ReferenceModelConfig
    control: ControlSettings
    allocation: Mapping[str, Any]
    hub: HubConfig
    fallback: FallbackSettings
    thruster_monitor: ThrusterMonitorSettings
    zenoh: ZenohConfig
    recorder: RecorderSettings
    state: StateSettings
    source_text: str = ""
    source_file: str | None = None
    realtime: RealtimeSettings = field(default_factory=RealtimeSettings)
    replica: ReplicaSettings = field(default_factory=ReplicaSettings)
    consequence: ConsequenceSettings = field(default_factory=ConsequenceSettings)
    deviation: DeviationSettings = field(default_factory=DeviationSettings)

    @property
    def sample_time_s(self) -> float:
        return 1.0 / self.rate_hz

    @property
    def notices(self) -> tuple[str, ...]:
        """What the file should change although it is accepted: a key under its old name (read as the new one
        for one release). ``check-config`` prints them, the daemon logs them at start."""
        return self.estimator.notices

    @property
    def sensors(self) -> tuple[SensorConfig, ...]:
        return tuple(route.sensor for route in self.routes)

    @property
    def config_hash(self) -> str:
        """SHA-256 of the configuration text (recorded with every log, published as config)."""
        return hashlib.sha256(self.source_text.encode("utf-8")).hexdigest()


def _parse_transport(section: Section) -> TransportConfig:
    name = section.string("name")
    protocol = section.string("protocol", choices=PROTOCOLS)
    settings: dict[str, Any] = {}
    if protocol == "nmea0183":
        settings["port"] = section.string("port")
        settings["baud"] = section.integer("baud", 4800, minimum=300)
        # longest sentence read; the default takes high-precision receivers (interfaces.nmea0183.codec)
        settings["max_sentence_chars"] = section.integer("max_sentence_chars", DEFAULT_MAX_SENTENCE_CHARS,
                                                         minimum=82, maximum=4096)
    elif protocol == "nmea2000":
        # (imported here: the gateways bring pyserial and python-can, which other configurations never need)
        from interfaces.nmea2000.gateways import GATEWAY_KINDS, GatewayConfig  # noqa: PLC0415

        settings["interface"] = section.string("interface")
        channel = section.raw("channel", None)
        if channel is not None and not isinstance(channel, (str, int)):
            raise ConfigError(f"{section.path}.channel", "a string or integer channel", channel)
        settings["channel"] = channel
        options = section.section("options")
        settings["options"] = dict(options.data)
        options._read.update(options.data)  # passed through to python-can (or the gateway)
        if settings["interface"] in GATEWAY_KINDS:  # a gateway instead of a CAN card: checked now, not at start
            try:
                GatewayConfig(settings["interface"], "" if channel is None else str(channel), settings["options"])
            except ValueError as error:
                raise ConfigError(f"{section.path}.channel", str(error), channel) from None
        # magnetic variation for magnetic headings when the bus sends none (127258)
        variation = section.raw("variation_deg", None)
        if variation is not None and (isinstance(variation, bool) or not isinstance(variation, int | float)
                                      or not -180.0 <= variation <= 180.0):
            raise ConfigError(f"{section.path}.variation_deg", "degrees in [-180, 180], east positive", variation)
        settings["variation_deg"] = variation
    else:
        # (imported here: the MAVLink transport brings pymavlink, which other configurations never need)
        from interfaces.mavlink.transport import parse_udpin  # noqa: PLC0415

        settings["url"] = section.string("url")
        try:
            parse_udpin(settings["url"])  # checked now, not when the daemon starts the reader
        except ValueError as error:
            raise ConfigError(f"{section.path}.url", str(error), settings["url"]) from None
        key_hex = section.raw("signing_key_hex", None)
        if key_hex is not None and (not isinstance(key_hex, str) or not re.fullmatch(r"[0-9a-fA-F]{64}", key_hex)):
            raise ConfigError(f"{section.path}.signing_key_hex", "64 hexadecimal digits (a 32-byte key)", key_hex)
        settings["signing_key_hex"] = key_hex
        settings["heartbeat_timeout_s"] = section.number("heartbeat_timeout_s", 5.0, minimum=0.5)
    section.finish()
    return TransportConfig(name, protocol, settings)


def _parse_route(section: Section, transports: Mapping[str, TransportConfig]) -> SensorRoute:
    name = section.string("name")
    kind = SensorKind(section.string("kind", choices=[k.value for k in SensorKind]))
    transport = section.string("transport", choices=list(transports))
    rate = section.number("rate_hz", 1.0 if kind is SensorKind.POSITION else 10.0, minimum=0.0,
                          exclusive_minimum=True, maximum=100.0)
    velocity_sigma = 0.1
    if kind is SensorKind.POSITION:
        sigma = section.number("sigma_m", 1.0, minimum=0.0, exclusive_minimum=True)
        arm = section.vector("lever_arm_m", 2, [0.0, 0.0])
        lever = (float(arm[0]), float(arm[1]))
        # the receiver's velocity (SOG/COG): its 1-σ per axis, from the data sheet (the velocity check)
        velocity_sigma = section.number("velocity_sigma_mps", 0.1, minimum=0.0, exclusive_minimum=True,
                                        maximum=100.0)
    elif kind is SensorKind.RATE:
        # a rate-of-turn sensor: the white noise of one sample, from its data sheet [°/s]
        sigma = math.radians(section.number("sigma_degps", 0.05, minimum=0.0, exclusive_minimum=True,
                                            maximum=30.0))
        lever = (0.0, 0.0)
    else:
        # (≤ 180°, as the plant's gyro noise: a heading noise beyond half a turn carries no heading)
        sigma = math.radians(section.number("sigma_deg", 0.2, minimum=0.0, exclusive_minimum=True, maximum=180.0))
        lever = (0.0, 0.0)
    protocol = transports[transport].protocol
    talker = section.raw("talker", None)
    if talker is not None and (protocol != "nmea0183" or not isinstance(talker, str) or len(talker) != 2):
        raise ConfigError(f"{section.path}.talker", "a 2-letter NMEA 0183 talker ID on an nmea0183 transport", talker)
    sentences: tuple[str, ...] = ()
    if section.has("sentences"):
        if protocol != "nmea0183":
            raise ConfigError(f"{section.path}.sentences", "sentences only on an nmea0183 transport", protocol)
        sentences = tuple(s for _, s in section.items("sentences", min_items=1))
        known = ("ROT",) if kind is SensorKind.RATE else ("GGA", "GNS", "RMC", "GLL", "VTG", "GST", "HDT", "THS",
                                                          "ROT")
        for where, value in section.items("sentences"):
            if value not in known:
                raise ConfigError(where, "one of " + ", ".join(known), value)
    source_address = None
    if section.has("source_address"):
        if protocol != "nmea2000":
            raise ConfigError(f"{section.path}.source_address", "source_address only on an nmea2000 transport",
                              protocol)
        source_address = section.integer("source_address", minimum=0, maximum=253)
    source_name = None
    if section.has("source_name"):
        text = section.raw("source_name", None)
        if protocol != "nmea2000":
            raise ConfigError(f"{section.path}.source_name", "source_name only on an nmea2000 transport", protocol)
        if not isinstance(text, str) or not re.fullmatch(r"(0x)?[0-9a-fA-F]{16}", text):
            raise ConfigError(f"{section.path}.source_name", "the device's NAME: 16 hexadecimal digits", text)
        source_name = int(text, 16)
    system_id = None
    if section.has("system_id"):
        if protocol != "mavlink":
            raise ConfigError(f"{section.path}.system_id", "system_id only on a mavlink transport", protocol)
        system_id = section.integer("system_id", minimum=1, maximum=255)
    section.finish()
    return SensorRoute(SensorConfig(name, kind, rate, sigma, lever, velocity_sigma), transport, talker, sentences,
                       source_address, system_id, source_name)


def _parse_hub(section: Section) -> HubConfig:
    defaults = HubConfig()
    values: dict[str, float] = {}
    for key, value in vars(defaults).items():
        deg_key = key.replace("_rad", "_deg")
        if deg_key != key and section.has(deg_key):
            values[key] = math.radians(section.number(deg_key, minimum=0.0, exclusive_minimum=True))
        elif section.has(key):
            values[key] = section.number(key, minimum=0.0, exclusive_minimum=True)
        else:
            section.raw(key, None)
            if deg_key != key:
                section.raw(deg_key, None)
            values[key] = value
    section.finish()
    return HubConfig(**values)


def _wave_frequency(omega_rad_s: float, where: str, rate_hz: float) -> float:
    """``omega_rad_s`` if a wave filter sampled at ``rate_hz`` can model it, else a ConfigError at ``where``.

    The highest frequency is the sampling's, not a full-scale sea's (a model basin's waves on a 1:70 hull peak
    at 5-8 rad/s): at least four samples a wave period, ``ω·Δt ≤ π/2``.
    """
    omega_max = math.pi / 2.0 * rate_hz
    if not 0.05 <= omega_rad_s <= omega_max:
        raise ConfigError(where, f"a wave peak frequency in [0.05, {omega_max:.3g}] rad/s (at most a quarter of the "
                          f"{rate_hz:g} Hz sampling)", omega_rad_s)
    return omega_rad_s


def _parse_estimator(section: Section, vessel: VesselData, rate_hz: float,
                     routes: tuple[SensorRoute, ...] = ()) -> EstimatorSettings:
    kind = section.string("kind", "mmae", choices=ESTIMATOR_KINDS)
    options = {k: v for k, v in section.data.items() if k != "kind"}
    section._read.update(options)
    section.finish()
    if kind in ("kalman_bucy", "heading_kf"):
        sub = Section.of(options, section.path)
        clean: dict[str, float] = {}
        if kind == "kalman_bucy":
            clean["process_noise_scale"] = sub.number("process_noise_scale", 0.02, minimum=0.0, exclusive_minimum=True)
        else:
            if vessel.nomoto_gain_per_s is None or vessel.nomoto_time_constant_s is None:
                raise ConfigError(f"{section.path}.kind", "a vessel with a Nomoto model for heading_kf", vessel.name)
            clean["omega0_rad_s"] = _wave_frequency(sub.number("omega0_rad_s", 1.2, minimum=0.05),
                                                    join(section.path, "omega0_rad_s"), rate_hz)
            clean["zeta"] = sub.number("zeta", 0.1, minimum=0.0, exclusive_minimum=True, maximum=1.0)
            for key, default in (("compass_std_deg", 0.5), ("wave_yaw_std_deg", 3.0), ("bias_rudder_deg", 5.0)):
                value = sub.number(key, default, minimum=0.0, exclusive_minimum=key != "wave_yaw_std_deg")
                clean[key.replace("_deg", "_rad")] = math.radians(value)
            clean["bias_time_s"] = sub.number("bias_time_s", 100.0, minimum=0.0, exclusive_minimum=True)
        sub.finish()
        return EstimatorSettings(kind, None, clean)
    notices: list[str] = []
    single_key = "omega0_rad_s"  # one filter frequency (kf, pem, rpem)
    if "omega_rad_s" in options and kind != "mmae":  # kf's ω0 had its own name until this release
        if "omega0_rad_s" in options:
            raise ConfigError(join(section.path, "omega_rad_s"), "omega0_rad_s alone (omega_rad_s is its old name)",
                              options["omega_rad_s"])
        single_key = "omega_rad_s"  # (read under the name the file gives, so that an error names it)
        notices.append(f"{join(section.path, 'omega_rad_s')} is deprecated: write omega0_rad_s (read as it in this "
                       "release)")
    # without a frequency key the default, stated at full scale, is scaled to the vessel by the filter's config
    frequencies = Section.of(options, section.path)
    omegas: tuple[float, ...]
    if kind == "mmae":
        grid = frequencies.vector("omegas_rad_s", None, DEFAULT_OMEGAS_RAD_S)
        omegas = tuple(float(v) for v in grid) if "omegas_rad_s" in options else DEFAULT_OMEGAS_RAD_S
    elif kind in ("kf", "rpem", "pem"):
        omega0 = frequencies.number(single_key, DEFAULT_OMEGA0_RAD_S)
        omegas = (omega0,) if single_key in options else LengthScaledGrid((DEFAULT_OMEGA0_RAD_S,))
    else:
        omegas = ()
    omega_key = "omegas_rad_s" if kind == "mmae" else single_key
    given = omega_key in options
    for i, omega in enumerate(omegas if given else ()):
        _wave_frequency(omega, f"{section.path}.{omega_key}" + (f"[{i}]" if kind == "mmae" else ""), rate_hz)
    zeta = options.get("zeta", 0.1)
    extra = {k: v for k, v in options.items() if k not in (omega_key, "zeta")}  # (another kind's key: refused below)
    # The filter's measurement noise defaults to what the configured sensors claim (the quietest of
    # each kind, since the hub fuses them), instead of the length-based rule.
    position = [r.sensor.sigma for r in routes if r.sensor.kind is SensorKind.POSITION]
    heading = [r.sensor.sigma for r in routes if r.sensor.kind is SensorKind.HEADING]
    if position and "position_noise_std_m" not in extra:
        extra["position_noise_std_m"] = min(position)
    if heading and "heading_noise_std_rad" not in extra:
        extra["heading_noise_std_rad"] = min(heading)
    wave_filter = WaveFilterConfig.from_options(
        vessel.mass_matrix, vessel.damping_matrix, 1.0 / rate_hz, kind=kind, omegas_rad_s=omegas or (0.8,),
        zeta=zeta, options=extra, length_m=vessel.length_m, path=section.path,
        section_keys=(omega_key, "zeta") if omegas else ("zeta",))
    if omegas and not given:   # the default, scaled to this vessel: within what the sampling can model?
        for omega in wave_filter.omegas_rad_s:
            _wave_frequency(omega, f"{section.path}.{omega_key} (the default for a {wave_filter.length_scale_m:g} m "
                            f"vessel, {omegas} rad/s: give it)", rate_hz)
    return EstimatorSettings(kind, wave_filter, {}, tuple(notices))


def _parse_control(section: Section, vessel: VesselData, builtin: str | None, estimator_kind: str) -> ControlSettings:
    """``control:``; without a ``kind`` the controller measured to hold the vessel (:func:`default_control`)."""
    default = default_control(builtin, course_keeping=estimator_kind == "heading_kf")
    given = section.raw("kind", None) is not None
    kind = str(section.string("kind", VesselDefault(default.section["kind"]), choices=CONTROL_KINDS))
    section._read.update(section.data)  # (the kind's own parser reads and checks every key)
    data = dict(section.data) if given else {**default.section, **section.data}  # (the file's keys override)
    if kind == "mrac" and builtin in LOADING_VESSELS:  # (a vessel of its own on a loading tanker's base)
        data.setdefault("mass_changes", True)
    if kind == "mrac" and estimator_kind in ESTIMATORS_WITHOUT_BIAS:
        # no bias estimate to compensate: the MRAC's integral action is its own integrator (MracConfig)
        data.setdefault("integral_action", "integrator")
    if builtin is not None and builtin != vessel.name:  # (a vessel of the file's own, on a built-in's base)
        default = DefaultControl(default.section, f"based on {builtin}: {default.reason}")
    return ControlSettings(kind, control_config_from_mapping(data, vessel, section.path), default, configured=given)


def _builtin_vessel(value: object) -> str | None:
    """The built-in vessel a ``vessel:`` value names or is based on (``base:``), None for one of its own."""
    name = value.get("base") if isinstance(value, Mapping) else value
    return name if isinstance(name, str) and name in BUILTIN_VESSELS else None


def parse_config(mapping: object, *, file: str | None = None, text: str = "",
                 transports: Sequence[TransportConfig] = ()) -> DaemonConfig:
    """Validate a parsed YAML mapping into a :class:`DaemonConfig`.

    ``transports`` are built by the caller (e.g. :func:`in_process_transport`) and come before the mapping's own
    ``transports`` list, which is then optional; the sensors may name either.

    Raises
    ------
    ConfigError
        With the file name, the key path and what was expected.
    """
    try:
        return _parse(mapping, text, file, tuple(transports))
    except ConfigError as error:
        raise error.with_file(file) if file else error from None


def _parse(mapping: object, text: str, file: str | None, given: tuple[TransportConfig, ...]) -> DaemonConfig:
    root = Section.of(mapping)
    vessel_id = root.string("vessel_id")
    if not VESSEL_ID_PATTERN.match(vessel_id):
        raise ConfigError("vessel_id", "letters, digits, '_' or '-' (it is a Zenoh key segment)", vessel_id)
    vessel = vessel_from_config(root.raw("vessel"), "vessel")
    datum = None
    if root.raw("datum", None) is not None:
        section = root.section("datum")
        datum = (section.number("lat_deg", minimum=-90.0, maximum=90.0),
                 section.number("lon_deg", minimum=-180.0, maximum=180.0))
        section.finish()
    loop = root.section("loop")
    rate = loop.number("rate_hz", 10.0, minimum=1.0, maximum=100.0)
    initial_mode = loop.string("initial_mode", "standby", choices=MODES)
    auto_engage = loop.optional_number("auto_engage_s", minimum=0.0)
    priority = None if loop.raw("realtime_priority", None) is None else \
        loop.integer("realtime_priority", minimum=1, maximum=99)
    cpus: tuple[int, ...] = ()
    if loop.raw("cpu_affinity", None) is not None:
        raw_cpus = loop.raw("cpu_affinity")
        if not isinstance(raw_cpus, list) or not raw_cpus or \
                any(isinstance(c, bool) or not isinstance(c, int) or c < 0 for c in raw_cpus):
            raise ConfigError(join(loop.path, "cpu_affinity"), "a non-empty list of CPU numbers (integers >= 0)",
                              raw_cpus)
        cpus = tuple(sorted(set(raw_cpus)))
    # spinning costs its CPU time: a quarter of the period at most, like the replica's lead
    realtime = RealtimeSettings(priority, cpus,
                                loop.number("deadline_spin_ms", 2.0, minimum=0.0, maximum=250.0 / rate) / 1000.0)
    # the replica runs in the last quarter of the period at most: the rest is the cycle's and the readers'
    replica = ReplicaSettings(loop.boolean("replica_check", True),
                              loop.number("replica_lead_ms", 3.0, minimum=0.5, maximum=250.0 / rate) / 1000.0)
    loop.finish()

    transports = [*given, *parse_list(root, "transports", _parse_transport, required=not given,
                                      min_items=0 if given else 1)]
    by_name: dict[str, TransportConfig] = {}
    for index, transport in enumerate(transports):
        if transport.name in by_name:
            raise ConfigError(f"transports[{index - len(given)}].name", "a unique transport name", transport.name)
        by_name[transport.name] = transport
    routes = tuple(_parse_route(Section.of(item, where), by_name)
                   for where, item in root.items("sensors", required=True, min_items=1))
    names = [r.sensor.name for r in routes]
    for index, name in enumerate(names):
        if names.index(name) != index:
            raise ConfigError(f"sensors[{index}].name", "a unique sensor name", name)
    if not any(r.sensor.kind is SensorKind.POSITION for r in routes):
        raise ConfigError("sensors", "at least one sensor of kind position", names)
    if not any(r.sensor.kind is SensorKind.HEADING for r in routes):
        raise ConfigError("sensors", "at least one sensor of kind heading", names)

    estimator = _parse_estimator(root.section("estimator"), vessel, rate, routes)
    guidance = reference_config_from_mapping(root.raw("guidance", None), vessel, "guidance")
    control = _parse_control(root.section("control"), vessel, _builtin_vessel(root.raw("vessel")), estimator.kind)
    if (control.kind == "autopilot") != (estimator.kind == "heading_kf"):
        raise ConfigError("control.kind", "autopilot together with estimator kind heading_kf (course keeping), "
                          "or a DP controller with a DP estimator", control.kind)

    allocation = allocator_kwargs_from_mapping(root.raw("allocation", None), vessel.thrusters, "allocation")

    hub = _parse_hub(root.section("hub"))

    fb = root.section("fallback")
    fallback = FallbackSettings(
        dead_reckoning_limit_s=fb.number("dead_reckoning_limit_s", 60.0, minimum=0.0),
        position_loss=fb.string("position_loss", "dead_reckoning", choices=FALLBACKS),
        heading_loss_limit_s=fb.number("heading_loss_limit_s", 60.0, minimum=0.0),
        heading_loss=fb.string("heading_loss", "dead_reckoning", choices=("dead_reckoning", "standby",
                                                                          "zero_surge_sway")),
        restore_within_s=fb.number("restore_within_s", 300.0, minimum=0.0),
    )
    fb.finish()

    tm = root.section("thruster_monitor")
    monitor = ThrusterMonitorSettings(
        feedback_timeout_s=tm.number("feedback_timeout_s", 2.0, minimum=0.0, exclusive_minimum=True),
        mismatch_fraction=tm.number("mismatch_fraction", 0.25, minimum=0.0, exclusive_minimum=True),
        mismatch_floor_fraction=tm.number("mismatch_floor_fraction", 0.05, minimum=0.0, exclusive_minimum=True),
        mismatch_persist_s=tm.number("mismatch_persist_s", 5.0, minimum=0.0),
        shortfall_fraction=tm.number("shortfall_fraction", 0.1, minimum=0.0, exclusive_minimum=True),
        shortfall_persist_s=tm.number("shortfall_persist_s", 10.0, minimum=0.0),
    )
    tm.finish()

    consequence = _parse_consequence(root.section("consequence"), vessel)
    deviation = _parse_deviation(root.section("deviation"), vessel.length_m)

    zenoh = ZenohConfig.from_mapping(root.raw("zenoh", None), "zenoh")
    _refuse_unprotected(zenoh)

    rs = root.section("recorder")
    recorder = RecorderSettings(
        path=rs.string("path") if rs.raw("path", None) is not None else None,
        max_file_mb=rs.number("max_file_mb", 256.0, minimum=0.01),
        max_total_mb=rs.number("max_total_mb", 4096.0, minimum=0.01),
        rotate_s=rs.number("rotate_s", 3600.0, minimum=1.0),
        flush_s=rs.number("flush_s", 1.0, minimum=0.05, maximum=1.0),
        queue_size=rs.integer("queue_size", 10000, minimum=10),
    )
    rs.finish()

    ss = root.section("state")
    state = StateSettings(
        path=ss.string("path") if ss.raw("path", None) is not None else None,
        period_s=ss.number("period_s", 1.0, minimum=0.05),
        max_age_s=ss.number("max_age_s", 30.0, minimum=0.0),
    )
    ss.finish()
    root.finish()
    return DaemonConfig(vessel_id, vessel, datum, rate, initial_mode, auto_engage, tuple(transports), routes,
                        estimator, guidance, control, allocation, hub, fallback, monitor, zenoh, recorder, state,
                        source_text=text, source_file=file, realtime=realtime, replica=replica,
                        consequence=consequence, deviation=deviation)


def _refuse_unprotected(zenoh: ZenohConfig) -> None:
    """Whoever reaches the daemon's zenoh endpoint can command the vessel unless zenoh authenticates and filters
    them: off loopback, only TLS with mutual authentication and access control by role (``zenoh.tls`` +
    ``zenoh.identities``), or an explicit ``zenoh.insecure: true`` (a standing warning alarm then says so).

    Raises
    ------
    ConfigError
    """
    open_to_all = unprotected_endpoints(zenoh.listen, zenoh.connect, zenoh.security)
    if open_to_all and not (zenoh.security is not None and zenoh.security.insecure):
        raise ConfigError("zenoh", "tls/ endpoints with zenoh.tls and zenoh.identities (mutual TLS and access "
                          "control by role; see docs/security.md) off loopback, or 'insecure: true' to accept "
                          f"that anybody on the network can command the vessel; unprotected: {', '.join(open_to_all)}",
                          show_got=False)


def _parse_deviation(section: Section, length_m: float) -> DeviationSettings:
    """``deviation:``: warning and alarm limits of position [m] and heading [deg], each alarm limit above its
    warning limit, the persistence [s], and the drift-off horizon [s] (default: the vessel's, from its length
    ``length_m`` [m], :func:`dpcontrol.runtime.deviation.drift_off_horizon_s`)."""
    limits = {key: section.number(key, default, minimum=0.0, exclusive_minimum=True)
              for key, default in (("position_warning_m", 3.0), ("position_alarm_m", 5.0),
                                   ("heading_warning_deg", 3.0), ("heading_alarm_deg", 5.0))}
    for quantity, unit in (("position", "m"), ("heading", "deg")):
        warning, alarm = limits[f"{quantity}_warning_{unit}"], limits[f"{quantity}_alarm_{unit}"]
        if alarm <= warning:
            raise ConfigError(join(section.path, f"{quantity}_alarm_{unit}"),
                              f"more than {quantity}_warning_{unit} ({warning:g} {unit})", alarm)
    if limits["heading_alarm_deg"] >= 180.0:
        raise ConfigError(join(section.path, "heading_alarm_deg"), "less than 180 deg", limits["heading_alarm_deg"])
    horizon = section.optional_number("drift_off_horizon_s", minimum=0.0)
    settings = DeviationSettings(
        position_warning_m=limits["position_warning_m"], position_alarm_m=limits["position_alarm_m"],
        heading_warning_rad=math.radians(limits["heading_warning_deg"]),
        heading_alarm_rad=math.radians(limits["heading_alarm_deg"]),
        persist_s=section.number("persist_s", 1.0, minimum=0.0),
        drift_off_horizon_s=horizon if horizon is not None else drift_off_horizon_s(length_m),
        drift_off_persist_s=section.number("drift_off_persist_s", 3.0, minimum=0.0),
    )
    section.finish()
    return settings


def _parse_consequence(section: Section, vessel: VesselData) -> ConsequenceSettings:
    """``consequence:``: failure groups by thruster name (each a non-empty list of the vessel's thrusters, not
    all of them), and the check's timing."""
    names = [spec.name for spec in vessel.thrusters]
    groups: list[FailureGroup] = []
    raw_groups = section.raw("groups", None)
    where = join(section.path, "groups")
    if raw_groups is not None:
        if not isinstance(raw_groups, Mapping) or not raw_groups:
            raise ConfigError(where, "a mapping of failure group name → list of thruster names "
                              "(e.g. {bus_a: [bow_tunnel_1, azimuth_port]})", raw_groups)
        for name, members in raw_groups.items():
            path = join(where, str(name))
            if not isinstance(name, str) or not VESSEL_ID_PATTERN.match(name):
                raise ConfigError(path, "a group name of letters, digits, '_' or '-' (it names an alarm)", name)
            if not isinstance(members, list) or not members:
                raise ConfigError(path, "a non-empty list of thruster names", members)
            for index, member in enumerate(members):
                if member not in names:
                    raise ConfigError(f"{path}[{index}]", f"one of the vessel's thrusters ({', '.join(names)})",
                                      member)
            if len(set(members)) != len(members):
                raise ConfigError(path, "each thruster once", members)
            if set(members) == set(names):
                raise ConfigError(path, "a group that leaves some thrusters (losing them all can never hold)",
                                  members)
            groups.append(FailureGroup(name, tuple(members)))
    settings = ConsequenceSettings(
        groups=tuple(groups),
        period_s=section.number("period_s", 1.0, minimum=0.1),
        averaging_s=section.number("averaging_s", 30.0, minimum=1.0),
        demand_factor=section.number("demand_factor", 1.25, minimum=1.0),
        persist_s=section.number("persist_s", 10.0, minimum=0.0),
        tolerance=section.number("tolerance", 0.002, minimum=0.0, maximum=0.05),
        utilisation_warning=section.optional_number("utilisation_warning", minimum=0.0, maximum=1.0,
                                                    exclusive_minimum=True),
    )
    section.finish()
    return settings


def load_config(path: str | Path) -> DaemonConfig:
    """Read and validate a YAML configuration file.

    Raises
    ------
    ConfigError
        For unreadable files, files that are not UTF-8 text, YAML syntax errors and invalid content
        (naming the file).
    """
    text, mapping = read_yaml_file(path)
    return parse_config(mapping, file=str(path), text=text)


def config_summary(config: DaemonConfig) -> dict[str, Any]:
    """The running configuration as a JSON-able mapping (the ``dp/<vessel>/config`` queryable)."""
    mapping = load_yaml(config.source_text) if config.source_text else {}
    return {"vessel_id": config.vessel_id, "config_sha256": config.config_hash, "file": config.source_file,
            "config": mapping}
