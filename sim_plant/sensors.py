"""Sensor models: GNSS receivers and gyrocompasses producing the typed messages of
:mod:`interfaces.messages`, each at its own rate, tagged with the protocol it is sent over.

GNSS (per horizontal axis, NED): reported antenna position = total position + R(ψ_tot)·lever arm
+ Gauss–Markov error (σ_gm, T_gm: the slow multipath/atmosphere wander of a DGPS) + white noise σ,
converted to WGS-84 with :meth:`dpbase.geodesy.LocalFrame.surface_to_geodetic`. Each fix is a
:class:`~interfaces.messages.PositionFix` (with quality, satellites, HDOP, UTC time), optionally
followed by a :class:`~interfaces.messages.PositionErrorStats` (GST: 1-σ = √(σ² + σ_gm²) times the
noise factor of an active ``gnss_noise`` fault), and a
:class:`~interfaces.messages.CourseOverGround` (SOG/COG: the receiver's Doppler velocity) unless ``velocity`` is
off: the antenna's true velocity over ground at the epoch — the three-point backward derivative of the true
antenna position at this sample and the two before (exact for a quadratic; the mean over the last epoch with the
second fix), LF + WF motion, lever arm included: the wave motion and r × lever arm are real motion — plus white
noise ``velocity_noise_mps`` per axis (× the ``gnss_noise`` factor), from a stream of its own (the
position noise is the same with or without it). None with a receiver's first fix. Its errors are the Doppler's,
not the position's: ``gnss_jump``, ``gnss_drift`` and the Gauss–Markov wander (multipath, a correction) move the
position only; ``gnss_freeze`` repeats both; ``gnss_invalid`` and ``gnss_dropout`` send neither.

Gyrocompass: heading = ψ_tot + bias + Gauss–Markov error + white noise, wrapped to [0, 2π) as sent,
as :class:`~interfaces.messages.Heading`; optionally a :class:`~interfaces.messages.RateOfTurn`
(true total yaw rate + white noise).

Rate-of-turn sensor (``kind: rot``, a rate gyro / ROT indicator: its own device, independent of the
gyrocompass): rate = total yaw rate + bias + white noise, as :class:`~interfaces.messages.RateOfTurn`
(NMEA 0183 ``$TIROT``, NMEA 2000 PGN 127251, MAVLink ATTITUDE ``yawspeed``); its faults ``rot_*``
never touch a gyro's output, nor a gyro's faults its own.

Faults (:mod:`sim_plant.faults`), evaluated at each sample time:
``*_dropout`` no output; ``*_invalid`` an :class:`InvalidFix` instead of the message (the emulator
encodes it as GGA quality 0 / RMC status V / PGN 129029 "no GNSS" / THS mode V / N2K NA);
``*_freeze`` the last value repeated (with a running UTC time); ``gnss_jump`` a constant offset;
``gnss_drift`` an offset growing at ``rate_mps``; ``gnss_noise`` white noise × ``factor``;
``gyro_offset`` / ``gyro_drift`` a constant / growing heading error; ``rot_offset`` a constant rate error
(``rot_freeze``, ``rot_dropout``, ``rot_invalid`` as for the others). The random processes keep
running through faults, so a run is the same whatever the faults.

Sample times are exact: t_k = offset_s + k / rate_hz.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from dpbase.frames import TWO_PI, ssa
from dpbase.geodesy import LocalFrame, lever_arm_ned
from interfaces.messages import (
    CourseOverGround,
    FixQuality,
    Heading,
    PositionErrorStats,
    PositionFix,
    RateOfTurn,
    SensorMessage,
)
from sim_plant.faults import Fault

PROTOCOLS: tuple[str, ...] = ("nmea0183", "nmea2000", "mavlink")
SENSOR_KINDS: tuple[str, ...] = ("gnss", "gyro", "rot")
SECONDS_PER_DAY = 86400.0


@dataclass(frozen=True, slots=True)
class InvalidFix:
    """A sample the sensor flagged invalid (emulator: GGA quality 0, RMC V, N2K NA, THS V ...).

    Attributes
    ----------
    kind : {"position", "heading", "rate"}
    reason : str
        The fault that caused it (``gnss_invalid``, ``gyro_invalid``, ``rot_invalid``).
    utc_time_s : float or None
        Seconds since midnight UTC.
    lat_deg, lon_deg : float or None
        The position the receiver would have reported (some receivers still send it with quality
        0; a decoder must check validity before values). None for headings.
    heading_rad : float or None
        Likewise for a gyro.
    """

    kind: str
    reason: str
    utc_time_s: float | None = None
    lat_deg: float | None = None
    lon_deg: float | None = None
    heading_rad: float | None = None


class SensorSample(NamedTuple):
    """One output of one sensor (immutable; a named tuple: every sensor builds one or two per sample, and a
    tuple costs a quarter of a frozen dataclass to build).

    Attributes
    ----------
    t_s : float
        Measurement time on the plant clock [s].
    sensor : str
        Configured sensor name (``gnss1``, ``gyro1`` ...).
    protocol : {"nmea0183", "nmea2000", "mavlink"}
    message : SensorMessage or InvalidFix
    """

    t_s: float
    sensor: str
    protocol: str
    message: SensorMessage | InvalidFix

    @property
    def valid(self) -> bool:
        return not isinstance(self.message, InvalidFix)


@dataclass(frozen=True)
class GnssSpec:
    """A GNSS receiver (scenario ``sensors`` entry, ``kind: gnss``).

    Attributes
    ----------
    name, protocol : str
    rate_hz : float
        Fix rate (1–10 Hz typical).
    noise_m : float
        White noise 1-σ per horizontal axis [m].
    markov_m, markov_time_constant_s : float
        Gauss–Markov error 1-σ per axis [m] and correlation time [s].
    lever_arm_m : tuple of float
        Antenna position in body axes (x forward, y starboard) [m].
    quality : FixQuality
    satellites : int
    hdop : float
    antenna_height_m : float
        Reported altitude [m].
    gst : bool
        Emit PositionErrorStats with each fix.
    offset_s : float
        Time of the first sample [s].
    velocity : bool
        Emit CourseOverGround (SOG/COG) with each fix.
    velocity_noise_mps : float
        White noise 1-σ of the velocity per horizontal axis [m/s] (a DGPS receiver's Doppler: 0.02–0.05).
    """

    name: str
    protocol: str = "nmea0183"
    rate_hz: float = 5.0
    noise_m: float = 0.3
    markov_m: float = 0.0
    markov_time_constant_s: float = 300.0
    lever_arm_m: tuple[float, float] = (0.0, 0.0)
    quality: FixQuality = FixQuality.DGPS
    satellites: int = 12
    hdop: float = 0.8
    antenna_height_m: float = 0.0
    gst: bool = True
    offset_s: float = 0.0
    velocity: bool = True
    velocity_noise_mps: float = 0.02

    kind = "gnss"


@dataclass(frozen=True)
class GyroSpec:
    """A gyrocompass (scenario ``sensors`` entry, ``kind: gyro``); angles in rad.

    Attributes
    ----------
    name, protocol : str
    rate_hz : float
        Output rate (5–20 Hz typical).
    noise_rad : float
        White noise 1-σ [rad].
    bias_rad : float
        Constant offset [rad].
    markov_rad, markov_time_constant_s : float
        Gauss–Markov error 1-σ [rad] and correlation time [s].
    rate_of_turn : bool
        Also emit RateOfTurn.
    rot_noise_radps : float
        White noise on the rate of turn [rad/s].
    offset_s : float
    """

    name: str
    protocol: str = "nmea0183"
    rate_hz: float = 10.0
    noise_rad: float = math.radians(0.05)
    bias_rad: float = 0.0
    markov_rad: float = 0.0
    markov_time_constant_s: float = 600.0
    rate_of_turn: bool = True
    rot_noise_radps: float = math.radians(0.02)
    offset_s: float = 0.0

    kind = "gyro"


@dataclass(frozen=True)
class RotSpec:
    """A rate-of-turn sensor (scenario ``sensors`` entry, ``kind: rot``): a rate gyro with its own
    electronics, independent of the gyrocompass; rates in rad/s.

    The defaults are of a marine MEMS/FOG rate sensor's data sheet (e.g. a ROT indicator's rate
    gyro): white noise 0.01 °/s 1-σ per sample at 10 Hz, a turn-on bias of a few 0.01 °/s.

    Attributes
    ----------
    name, protocol : str
    rate_hz : float
        Output rate (10 Hz typical).
    noise_radps : float
        White noise 1-σ of one sample [rad/s].
    bias_radps : float
        Constant bias [rad/s] (what the controller estimates against the gyrocompass).
    offset_s : float
    """

    name: str
    protocol: str = "nmea0183"
    rate_hz: float = 10.0
    noise_radps: float = math.radians(0.01)
    bias_radps: float = math.radians(0.03)
    offset_s: float = 0.0

    kind = "rot"


SensorSpec = GnssSpec | GyroSpec | RotSpec


class _Sensor:
    """Shared scheduling and fault look-up."""

    def __init__(self, spec: SensorSpec, rng: np.random.Generator, faults: Sequence[Fault],
                 utc_start_s: float) -> None:
        if spec.protocol not in PROTOCOLS:
            raise ValueError(f"sensor {spec.name}: unknown protocol {spec.protocol!r}")
        if not spec.rate_hz > 0.0:
            raise ValueError(f"sensor {spec.name}: rate_hz must be > 0")
        self.spec = spec
        self.name = spec.name
        self.protocol = spec.protocol
        self._rng = rng
        self._faults = tuple(f for f in faults if f.target == spec.name)
        self._utc_start_s = utc_start_s
        self._index = 0
        self._period = 1.0 / spec.rate_hz
        self.next_time_s = spec.offset_s
        self._gm_time_s: float | None = None
        self._block: list[float] = []
        self._used = 0

    def _normals(self, k: int) -> list[float]:
        """The next ``k`` standard normal draws of this sensor's stream (drawn in blocks: one numpy
        call per 1024 samples instead of one per sample; kept as Python floats, which is what every
        use of them needs)."""
        if self._used + k > len(self._block):
            self._block = self._rng.standard_normal(2048).tolist()
            self._used = 0
        out = self._block[self._used:self._used + k]
        self._used += k
        return out

    def _advance_schedule(self) -> None:
        self._index += 1
        self.next_time_s = self.spec.offset_s + self._index * self._period

    def _active(self, t_s: float) -> list[Fault]:
        if not self._faults:
            return []
        return [f for f in self._faults if f.active(t_s)]

    def _utc(self, t_s: float) -> float:
        return math.fmod(self._utc_start_s + t_s, SECONDS_PER_DAY)

    def _gm_step(self, state: list[float], sigma: float, tau: float, t_s: float) -> None:
        """Exact discrete Gauss–Markov update of ``state`` to time ``t_s`` (stationary start), in place."""
        if sigma <= 0.0:
            return
        draws = self._normals(len(state))
        if self._gm_time_s is None:
            state[:] = [sigma * w for w in draws]
        else:
            phi = math.exp(-(t_s - self._gm_time_s) / tau)
            gain = sigma * math.sqrt(max(0.0, 1.0 - phi * phi))
            state[:] = [x * phi + gain * w for x, w in zip(state, draws, strict=True)]


class GnssSensor(_Sensor):
    """A GNSS receiver (see the module docstring).

    Parameters
    ----------
    spec : GnssSpec
    frame : LocalFrame
        Datum of the plant's NED frame.
    rng : numpy.random.Generator
        This sensor's own stream.
    faults : sequence of Fault
        All scenario faults (those targeting this sensor are used).
    utc_start_s : float
        UTC seconds of day at t = 0.
    """

    def __init__(self, spec: GnssSpec, frame: LocalFrame, rng: np.random.Generator, faults: Sequence[Fault] = (),
                 utc_start_s: float = 0.0) -> None:
        super().__init__(spec, rng, faults, utc_start_s)
        self.gnss = spec
        self._frame = frame
        self._gm = [0.0, 0.0]
        self._last_latlon: tuple[float, float] | None = None
        # the velocity's noise: a stream of its own (spawned: the position's stream is not advanced)
        self._velocity_rng = np.random.default_rng(rng.bit_generator.seed_seq.spawn(1)[0])  # type: ignore[attr-defined]
        self._velocity_block: list[float] = []
        self._velocity_used = 0
        # the true antenna positions (t_s, north_m, east_m) of the last two samples, the older first
        self._previous_antenna: list[tuple[float, float, float]] = []
        self._last_velocity: CourseOverGround | None = None

    def _velocity_normals(self) -> tuple[float, float]:
        if self._velocity_used + 2 > len(self._velocity_block):
            self._velocity_block = self._velocity_rng.standard_normal(2048).tolist()
            self._velocity_used = 0
        i = self._velocity_used
        self._velocity_used += 2
        return self._velocity_block[i], self._velocity_block[i + 1]

    def _velocity(self, t_s: float, north_m: float, east_m: float, factor: float) -> CourseOverGround | None:
        """SOG/COG at ``t_s`` from the true antenna position (module docstring); None without a previous one."""
        history = self._previous_antenna
        white_north, white_east = self._velocity_normals()  # drawn every sample: faults do not shift the stream
        if len(history) == 2:
            (t0, n0, e0), (t1, n1, e1) = history
            h1, h2 = t1 - t0, t_s - t1  # (> 0: samples are scheduled forward)
            c0 = h2 / (h1 * (h1 + h2))
            c1 = -(h1 + h2) / (h1 * h2)
            c2 = (h1 + 2.0 * h2) / (h2 * (h1 + h2))
            v_north = c0 * n0 + c1 * n1 + c2 * north_m
            v_east = c0 * e0 + c1 * e1 + c2 * east_m
            history.pop(0)
        elif history:
            t1, n1, e1 = history[0]
            v_north = (north_m - n1) / (t_s - t1)
            v_east = (east_m - e1) / (t_s - t1)
        else:
            history.append((t_s, north_m, east_m))
            return None
        history.append((t_s, north_m, east_m))
        sigma = factor * self.gnss.velocity_noise_mps
        v_north += sigma * white_north
        v_east += sigma * white_east
        return CourseOverGround(math.atan2(v_east, v_north) % TWO_PI, math.hypot(v_north, v_east))

    def sample(self, t_s: float, north_m: float, east_m: float, heading_rad: float) -> list[SensorSample]:
        """Samples at ``t_s`` from the vessel's TOTAL pose (LF + WF), then schedule the next.

        Parameters
        ----------
        t_s : float
            Must equal :attr:`next_time_s`.
        north_m, east_m, heading_rad : float
            Total position of the control origin and total heading.
        """
        spec = self.gnss
        self._advance_schedule()
        self._gm_step(self._gm, spec.markov_m, spec.markov_time_constant_s, t_s)
        self._gm_time_s = t_s
        white_north, white_east = self._normals(2)  # drawn every sample: faults do not shift the stream
        active = self._active(t_s)
        kinds = {f.kind for f in active} if active else ()
        if "gnss_dropout" in kinds:
            return []
        factor = 1.0
        off_north = off_east = 0.0
        for f in active:
            if f.kind == "gnss_noise":
                factor *= f.factor
            elif f.kind == "gnss_jump":
                off_north += f.offset_m * math.cos(f.direction_rad)
                off_east += f.offset_m * math.sin(f.direction_rad)
            elif f.kind == "gnss_drift":
                grown = f.rate_mps * (t_s - f.t_s)
                off_north += grown * math.cos(f.direction_rad)
                off_east += grown * math.sin(f.direction_rad)
        dn, de = lever_arm_ned(spec.lever_arm_m[0], spec.lever_arm_m[1], heading_rad)
        gm = self._gm
        n = north_m + dn + gm[0] + factor * spec.noise_m * white_north + off_north
        e = east_m + de + gm[1] + factor * spec.noise_m * white_east + off_east
        velocity = self._velocity(t_s, north_m + dn, east_m + de, factor) if spec.velocity else None
        utc = self._utc(t_s)
        if "gnss_freeze" in kinds and self._last_latlon is not None:
            lat, lon = self._last_latlon
            velocity = self._last_velocity
        else:
            lat, lon = self._frame.surface_to_geodetic(n, e, spec.antenna_height_m)
        if "gnss_invalid" in kinds:
            return [SensorSample(t_s, self.name, self.protocol,
                                 InvalidFix("position", "gnss_invalid", utc, lat, lon))]
        self._last_latlon = (lat, lon)
        self._last_velocity = velocity
        out = [SensorSample(t_s, self.name, self.protocol,
                            PositionFix(lat, lon, spec.quality, utc, spec.satellites, spec.hdop,
                                        spec.antenna_height_m))]
        if velocity is not None:
            out.append(SensorSample(t_s, self.name, self.protocol, velocity))
        if spec.gst:
            sigma = math.hypot(factor * spec.noise_m, spec.markov_m)
            out.append(SensorSample(t_s, self.name, self.protocol,
                                    PositionErrorStats(sigma, sigma, 2.0 * sigma, sigma, utc)))
        return out


class GyroSensor(_Sensor):
    """A gyrocompass (see the module docstring)."""

    def __init__(self, spec: GyroSpec, rng: np.random.Generator, faults: Sequence[Fault] = (),
                 utc_start_s: float = 0.0) -> None:
        super().__init__(spec, rng, faults, utc_start_s)
        self.gyro = spec
        self._gm = [0.0]
        self._last: tuple[float, float] | None = None

    def sample(self, t_s: float, heading_rad: float, yaw_rate_radps: float) -> list[SensorSample]:
        """Samples at ``t_s`` from the TOTAL heading and yaw rate, then schedule the next."""
        spec = self.gyro
        self._advance_schedule()
        self._gm_step(self._gm, spec.markov_rad, spec.markov_time_constant_s, t_s)
        self._gm_time_s = t_s
        white_h, white_r = self._normals(2)
        active = self._active(t_s)
        kinds = {f.kind for f in active} if active else ()
        if "gyro_dropout" in kinds:
            return []
        offset = 0.0
        rate_error = 0.0
        for f in active:
            if f.kind == "gyro_offset":
                offset += f.offset_rad
            elif f.kind == "gyro_drift":
                offset += f.rate_radps * (t_s - f.t_s)
                rate_error += f.rate_radps
        heading = ssa(heading_rad + spec.bias_rad + self._gm[0] + spec.noise_rad * white_h + offset)
        if heading < 0.0:
            heading += TWO_PI
            if heading >= TWO_PI:  # −1e-17 + 2π rounds to 2π
                heading = 0.0
        rate = yaw_rate_radps + spec.rot_noise_radps * white_r + rate_error
        if "gyro_freeze" in kinds and self._last is not None:
            heading, rate = self._last
        utc = self._utc(t_s)
        if "gyro_invalid" in kinds:
            return [SensorSample(t_s, self.name, self.protocol,
                                 InvalidFix("heading", "gyro_invalid", utc, heading_rad=heading))]
        self._last = (heading, rate)
        out = [SensorSample(t_s, self.name, self.protocol, Heading(heading, "A", utc))]
        if spec.rate_of_turn:
            out.append(SensorSample(t_s, self.name, self.protocol, RateOfTurn(rate)))
        return out


class RotSensor(_Sensor):
    """A rate-of-turn sensor (see the module docstring): its own noise stream and faults."""

    def __init__(self, spec: RotSpec, rng: np.random.Generator, faults: Sequence[Fault] = (),
                 utc_start_s: float = 0.0) -> None:
        super().__init__(spec, rng, faults, utc_start_s)
        self.rot = spec
        self._last: float | None = None

    def sample(self, t_s: float, heading_rad: float, yaw_rate_radps: float) -> list[SensorSample]:
        """Samples at ``t_s`` from the TOTAL yaw rate [rad/s] (``heading_rad`` unused: the gyro's signature, so
        the plant samples both alike), then schedule the next."""
        del heading_rad
        spec = self.rot
        self._advance_schedule()
        (white,) = self._normals(1)  # drawn every sample: faults do not shift the stream
        active = self._active(t_s)
        kinds = {f.kind for f in active} if active else ()
        if "rot_dropout" in kinds:
            return []
        error = 0.0
        for f in active:
            if f.kind == "rot_offset":
                error += f.rate_radps
        rate = yaw_rate_radps + spec.bias_radps + spec.noise_radps * white + error
        if "rot_freeze" in kinds and self._last is not None:
            rate = self._last
        if "rot_invalid" in kinds:
            return [SensorSample(t_s, self.name, self.protocol, InvalidFix("rate", "rot_invalid", self._utc(t_s)))]
        self._last = rate
        return [SensorSample(t_s, self.name, self.protocol, RateOfTurn(rate))]
