"""The composed plant: vessel, environment, drives and sensors of one scenario.

Used the same way by the lockstep runner and by the real-time emulator::

    plant = Plant(load_scenario(path))          # seeded from scenario.seed: deterministic
    plant.command(t_s, {"bow_tunnel": ThrusterCommand(1.0e4)})
    plant.advance(t_s_end)                      # RK4 substeps at the plant rate
    truth = plant.truth                         # LF / total pose, WF motion, forces, peaks, mass
    feedback = plant.feedback()
    samples = plant.sensor_samples(t_s_end)     # every sample due up to t_s_end, in time order

Time grid: RK4 substeps end on the fixed grid k·h (h = 1/``plant.rate_hz``) and, additionally, at
every sensor sample time, thruster-fault boundary and at the requested end time, so each sample
sees the exact state at its own time and a lockstep run whose end times are on the grid does not
depend on how ``advance`` was chunked. Inputs are held over a substep (zero-order hold): thruster
force, wind, wave drift, current and the mass factor are taken at the substep start; the drives
then move over the substep with their exact first-order response. The slowly varying environment
(wind with gusts, wave drift, current) is refreshed every ``ENV_PERIOD_S`` = 0.1 s (or every substep
if the plant rate is lower): the drift's difference frequencies and the gust spectrum have periods
of seconds to minutes.

Environment forces act on the LF model; the first-order wave motion is an output disturbance in
body axes (seed 001 eq. (15)): total position = LF position + R(ψ)·(x_w, y_w), total heading =
ψ + ψ_w. Sensors see the total motion.
"""

from __future__ import annotations

import math
import zlib
from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from dpbase.frames import ssa
from dpbase.geodesy import LocalFrame
from sim_plant.drives import DriveReport, ThrusterCommand, ThrusterDrives
from sim_plant.environment.current import CurrentModel
from sim_plant.environment.waves import CALM, SpectrumPeaks, WaveEnvironment, WaveSample
from sim_plant.environment.wind import WindModel
from sim_plant.faults import THRUSTER_FAULTS, Fault
from sim_plant.kernels import NO_DRIVE, plant_substep
from sim_plant.scenario import Scenario
from sim_plant.sensors import GnssSensor, GnssSpec, GyroSensor, GyroSpec, RotSensor, SensorSample
from sim_plant.vessel import DpVesselModel, ManoeuvringVesselModel, vessel_model

_TOL_S = 1e-9
MASS_STEP = 1e-4  # relative change of the mass factor that triggers a rebuild of the mass matrices
ENV_PERIOD_S = 0.1  # wind gusts, wave drift and current are refreshed at 10 Hz (held in between)
_FAILURE_OF = {"thruster_stuck": "stuck", "thruster_zero": "zero", "thruster_wrong_sign": "wrong_sign",
               "thruster_not_ready": "not_ready"}
# random streams (first key after the seed), so adding e.g. a sensor never changes the waves
_STREAM_WAVES, _STREAM_CURRENT, _STREAM_WIND, _STREAM_SENSOR = 1, 2, 3, 4
# what Plant.record_values returns: 15 floats, the two wave peaks (None in calm water), 2 floats
RecordValues = tuple[float, float, float, float, float, float, float, float, float, float, float, float, float,
                     float | None, float | None, float, float]


@dataclass(frozen=True, slots=True)
class PlantTruth:
    """The true state of the plant at ``t_s`` (what a run is judged against).

    Attributes
    ----------
    t_s : float
    north_m, east_m, heading_rad : float
        LF pose (NED, heading wrapped to (−π, π]).
    north_total_m, east_total_m, heading_total_rad : float
        Total pose = LF + WF (what a perfect sensor at the control origin sees).
    surge_mps, sway_mps, yaw_rate_radps : float
        LF body velocity over ground.
    wf_surge_m, wf_sway_m, wf_yaw_rad : float
        First-order WF motion in body axes.
    yaw_rate_total_radps : float
        LF + WF yaw rate.
    tau_act_b : tuple of float
        Force delivered by the thrusters (X, Y, N) [N, N, N·m]; for the mariner the rudder's is
        Y_δ δ, N_δ δ.
    tau_env_b : tuple of float
        Wind + wave drift (X, Y, N) [N, N, N·m] (current acts through the damping, not here).
    current_north_mps, current_east_mps : float
        Current velocity over ground.
    wind_speed_mps, wind_direction_rad : float
        True wind speed (with gust) and the direction it comes from.
    omega_peak_rad_s : float or None
        Wave spectrum peak ωp of the sea state in force (None in calm water).
    motion_peak_rad_s : float or None
        Peak of |RAO|²S of the dominant DOF (encounter frequency when moving) — judge the wave
        filter's ω̂ against this (docs/design.md §5, trap 3).
    motion_peaks_rad_s : tuple or None
        Surge, sway, yaw motion peaks (None entries where a DOF does not move).
    mass_factor : float
        Rigid-body mass / the vessel's ballast mass.
    mass_kg : float
        Rigid-body mass.
    surge_mass_kg : float
        M11 = m − X_u̇, the surge mass an adaptive controller estimates.
    """

    t_s: float
    north_m: float
    east_m: float
    heading_rad: float
    north_total_m: float
    east_total_m: float
    heading_total_rad: float
    surge_mps: float
    sway_mps: float
    yaw_rate_radps: float
    wf_surge_m: float
    wf_sway_m: float
    wf_yaw_rad: float
    yaw_rate_total_radps: float
    tau_act_b: tuple[float, float, float]
    tau_env_b: tuple[float, float, float]
    current_north_mps: float
    current_east_mps: float
    wind_speed_mps: float
    wind_direction_rad: float
    omega_peak_rad_s: float | None
    motion_peak_rad_s: float | None
    motion_peaks_rad_s: tuple[float | None, float | None, float | None] | None
    mass_factor: float
    mass_kg: float
    surge_mass_kg: float

    def columns(self) -> dict[str, float | None]:
        """The truth columns of ``sim-plant run``'s timeseries.csv (docs/design.md §4.3), plus
        ``motion_peak_rad_s``."""
        return {
            "t_s": self.t_s,
            "north_m": self.north_m, "east_m": self.east_m, "heading_rad": self.heading_rad,
            "north_total_m": self.north_total_m, "east_total_m": self.east_total_m,
            "heading_total_rad": self.heading_total_rad,
            "surge_mps": self.surge_mps, "sway_mps": self.sway_mps, "yaw_rate_radps": self.yaw_rate_radps,
            "tau_act_x_n": self.tau_act_b[0], "tau_act_y_n": self.tau_act_b[1], "tau_act_n_nm": self.tau_act_b[2],
            "omega_peak_rad_s": self.omega_peak_rad_s, "motion_peak_rad_s": self.motion_peak_rad_s,
            "mass_factor": self.mass_factor,
        }


def _total_pose(north_m: float, east_m: float, psi_rad: float, wave: WaveSample) -> tuple[float, float, float]:
    """LF pose plus the WF motion (body axes, seed 001) rotated to NED: what a sensor sees [m, m, rad]."""
    c = math.cos(psi_rad)
    s = math.sin(psi_rad)
    return (north_m + c * wave.surge_m - s * wave.sway_m, east_m + s * wave.surge_m + c * wave.sway_m,
            ssa(psi_rad + wave.yaw_rad))


class PlantDivergedError(ArithmeticError):
    """The integrated state became infinite or NaN (a scenario far outside the models' range)."""


class Plant:
    """The plant of one scenario (see the module docstring).

    Parameters
    ----------
    scenario : Scenario
    """

    def __init__(self, scenario: Scenario) -> None:
        self.scenario = scenario
        vessel = scenario.vessel
        seed = scenario.seed
        init = scenario.initial
        self.model: DpVesselModel | ManoeuvringVesselModel = vessel_model(vessel, init.surge_mps or None)
        self.course_keeping = isinstance(self.model, ManoeuvringVesselModel)
        self._h = 1.0 / scenario.plant.rate_hz
        self.drives = ThrusterDrives(vessel.thrusters, scenario.plant.thruster_timeout_s)
        self._rudder = NO_DRIVE
        if self.course_keeping:
            rudders = [i for i, t in enumerate(vessel.thrusters) if t.kind == "propeller_rudder"]
            self._rudder = rudders[0] if rudders else NO_DRIVE

        def rng(*keys: int) -> np.random.Generator:
            return np.random.default_rng([seed, *keys])

        self._mass_varies = len({p.factor for p in scenario.mass_schedule}) > 1
        self._final_mass = scenario.mass_schedule[-1].factor if scenario.mass_schedule else 1.0
        self.model.set_mass_factor(scenario.mass_factor_at(0.0))
        self._mass_t = math.nan
        self._hull_draft = self.model.hull.draft_m
        self.waves = WaveEnvironment(scenario.sea_states, self.model.hull, lambda i: rng(_STREAM_WAVES, i),
                                     water_density_kgpm3=vessel.water_density_kgpm3,
                                     drift_scale=self.model.extras.drift_scale,
                                     dominant_dof=2 if self.course_keeping else None)
        cur = scenario.current
        self.current = CurrentModel(cur.speed_mps, cur.direction_rad, rng(_STREAM_CURRENT),
                                    speed_std_mps=cur.speed_std_mps, direction_std_rad=cur.direction_std_rad,
                                    time_constant_s=cur.time_constant_s)
        wind = scenario.wind
        self.wind = WindModel(wind.speed_mps, wind.direction_rad, self.model.wind, rng(_STREAM_WIND),
                              gusts=wind.gusts, height_m=wind.height_m)
        self.frame = LocalFrame(scenario.datum.lat_deg, scenario.datum.lon_deg)
        self.sensors: list[GnssSensor | GyroSensor | RotSensor] = []
        for spec in scenario.sensors:
            stream = rng(_STREAM_SENSOR, zlib.crc32(spec.name.encode()))
            if isinstance(spec, GnssSpec):
                self.sensors.append(GnssSensor(spec, self.frame, stream, scenario.faults, scenario.utc_start_s))
            elif isinstance(spec, GyroSpec):
                self.sensors.append(GyroSensor(spec, stream, scenario.faults, scenario.utc_start_s))
            else:
                self.sensors.append(RotSensor(spec, stream, scenario.faults, scenario.utc_start_s))

        cn, ce = self.current.velocity_ned(0.0)
        c, s = math.cos(init.heading_rad), math.sin(init.heading_rad)
        u0 = init.surge_mps
        if self.course_keeping:
            u0 = init.surge_mps + c * cn + s * ce  # speed through the water is u0
        # the LF state [north_m, east_m, psi_rad, u_mps, v_mps, r_radps], advanced in place by the substep kernel
        self._x = np.array([init.north_m, init.east_m, ssa(init.heading_rad), u0, init.sway_mps,
                            init.yaw_rate_radps], dtype=float)
        self._t = 0.0
        self._k = 0
        self._thruster_faults: list[Fault] = [f for f in scenario.faults if f.kind in THRUSTER_FAULTS]
        boundaries = sorted({f.t_s for f in self._thruster_faults} | {f.end_s for f in self._thruster_faults})
        self._fault_times = deque(b for b in boundaries if math.isfinite(b))
        self._samples: deque[SensorSample] = deque()
        self._wave_cache_t = math.nan
        self._wave_cache: WaveSample = CALM
        self._tau_env = (0.0, 0.0, 0.0)
        self._current_ned = (cn, ce)
        self._env_period = max(self._h, ENV_PERIOD_S)
        self._env_next = 0.0
        self._truth_cache: PlantTruth | None = None
        self._surge_mass_factor = math.nan  # the mass factor self._surge_mass is M11 of (record_values)
        self._surge_mass = math.nan
        self._next_event = math.inf
        self._process_events(0.0)

    # -- inputs ----------------------------------------------------------------------------------
    @property
    def t_s(self) -> float:
        """Current plant time [s]."""
        return self._t

    def command(self, t_s: float, commands: Mapping[str, ThrusterCommand]) -> None:
        """Thruster commands from the controller, stamped ``t_s`` (age for the drive timeout).

        Raises
        ------
        sim_plant.drives.CommandError
            Nothing of an invalid command is applied.
        """
        self.drives.command(t_s, commands)
        self._truth_cache = None

    def command_arrays(self, t_s: float, order: np.ndarray, thrust_n: np.ndarray, azimuth_rad: np.ndarray,
                       enabled: np.ndarray) -> None:
        """:meth:`command` from per-drive arrays, entry ``j`` for drive ``order[j]`` (an index into
        ``drives.names``): see :meth:`sim_plant.drives.ThrusterDrives.command_arrays`.

        Raises
        ------
        sim_plant.drives.CommandError
            Nothing of an invalid command is applied.
        """
        self.drives.command_arrays(t_s, order, thrust_n, azimuth_rad, enabled)
        self._truth_cache = None

    def command_lost(self, t_s: float) -> None:
        """The controller's liveliness disappeared: drives ramp to zero until the next command."""
        self.drives.command_lost(t_s)

    # -- time --------------------------------------------------------------------------------------
    def advance(self, t_s_end: float) -> None:
        """Integrate the truth up to ``t_s_end`` [s] (no-op if already there).

        Raises
        ------
        ValueError
            ``t_s_end`` is not finite or lies in the past.
        """
        if not isinstance(t_s_end, (int, float)) or not math.isfinite(t_s_end):
            raise ValueError(f"advance: t_s_end must be a finite number, got {t_s_end!r}")
        if t_s_end < self._t - _TOL_S:
            raise ValueError(f"advance: t_s_end {t_s_end} is before the plant time {self._t}")
        h = self._h
        try:
            while self._t < t_s_end - _TOL_S:
                t = self._t
                grid_next = (self._k + 1) * h
                t_next = min(t_s_end, grid_next, self._next_event)
                if abs(t_next - grid_next) <= _TOL_S:
                    t_next = grid_next
                self._substep(t, t_next - t)
                self._t = t_next
                if t_next == grid_next:
                    self._k += 1
                if self._next_event <= t_next + _TOL_S:
                    self._process_events(t_next)
        except (ValueError, OverflowError, ZeroDivisionError) as error:
            if self._state_finite():
                raise
            raise self._diverged() from error
        if not self._state_finite():  # (one check per call: a few hundred ns)
            raise self._diverged()
        if self._mass_varies:
            self._update_mass(self._t)  # the truth reports the mass the next substep will use
        self._truth_cache = None

    def _state_finite(self) -> bool:
        return math.isfinite(math.fsum(self._x.tolist()))  # NaN and ±inf both propagate into the sum

    def _diverged(self) -> PlantDivergedError:
        north, east, _, u, v, r = self._x.tolist()
        return PlantDivergedError(
            f"the vessel's motion left the model's range at t = {self._t:.2f} s (surge {u:.3g} m/s, sway "
            f"{v:.3g} m/s, yaw rate {r:.3g} rad/s, at {north:.3g} m N, {east:.3g} m E): a value of the scenario "
            "(forces, current, wind, the vessel's data) is far outside what the vessel can meet")

    def _substep(self, t: float, h: float) -> None:
        if self._mass_varies:
            self._update_mass(t)
        if t >= self._env_next - _TOL_S:
            # wind gusts, wave drift and current vary slowly: refresh them on their own grid
            wave = self._waves_at(t)
            _, _, psi, u, v, _ = self._x.tolist()
            wx, wy, wn = self.wind.force_b(t, psi, u, v)
            dx, dy, dn = wave.drift_b
            self._tau_env = (wx + dx, wy + dy, wn + dn)
            self._current_ned = self.current.velocity_ned(t)
            self._env_next = (math.floor(t / self._env_period + _TOL_S) + 1) * self._env_period
        ex, ey, en = self._tau_env
        cn, ce = self._current_ned
        model = self.model
        # thruster force at t, RK4 step of the vessel, drives over [t, t + h]: one kernel call
        plant_substep(self._x, model.kind, model.params, t, h, ex, ey, en, cn, ce, *self.drives.arrays,
                      self._rudder)
        self._wave_cache_t = math.nan

    def _update_mass(self, t: float) -> None:
        if t == self._mass_t:
            return  # the end of one advance() and the start of the next substep ask for the same time
        self._mass_t = t
        model = self.model
        factor = self.scenario.mass_factor_at(t)
        # rebuilding the matrices costs ~50 µs: follow the schedule in steps of 1e-4 (relative)
        if abs(factor - model.mass_factor) > MASS_STEP * factor or factor == self._final_mass:
            model.set_mass_factor(factor)
            if abs(model.hull.draft_m - self._hull_draft) > 0.05:
                self.waves.set_hull(model.hull)
                self._hull_draft = model.hull.draft_m
                self._wave_cache_t = math.nan

    def _waves_at(self, t: float) -> WaveSample:
        if t != self._wave_cache_t:
            north, east, psi, u, v, _ = self._x.tolist()
            c = math.cos(psi)
            s = math.sin(psi)
            self._wave_cache = self.waves.evaluate(t, north, east, psi, north_rate_mps=c * u - s * v,
                                                   east_rate_mps=s * u + c * v)
            self._wave_cache_t = t
        return self._wave_cache

    def _find_next_event(self) -> float:
        """The next sensor sample time or thruster-fault boundary (they change only in _process_events,
        which caches this as ``_next_event``)."""
        nxt = self._fault_times[0] if self._fault_times else math.inf
        for sensor in self.sensors:
            nxt = min(nxt, sensor.next_time_s)
        return nxt

    def _process_events(self, t: float) -> None:
        changed = False
        while self._fault_times and self._fault_times[0] <= t + _TOL_S:
            self._fault_times.popleft()
            changed = True
        if changed or t == 0.0:
            for name in self.drives.names:
                active = [f for f in self._thruster_faults if f.target == name and f.active(t + _TOL_S)]
                failure = _FAILURE_OF[max(active, key=lambda f: f.t_s).kind] if active else None
                self.drives.set_failure(name, failure)
        due = [s for s in self.sensors if s.next_time_s <= t + _TOL_S]
        if not due:
            self._next_event = self._find_next_event()
            return
        north, east, psi, _, _, r = self._x.tolist()
        wave = self._waves_at(t)
        north_total, east_total, heading_total = _total_pose(north, east, psi, wave)
        rate_total = r + wave.yaw_rate_radps
        for sensor in due:
            while sensor.next_time_s <= t + _TOL_S:
                if isinstance(sensor, GnssSensor):
                    self._samples.extend(sensor.sample(t, north_total, east_total, heading_total))
                else:
                    self._samples.extend(sensor.sample(t, heading_total, rate_total))
        self._next_event = self._find_next_event()

    # -- outputs -----------------------------------------------------------------------------------
    @property
    def truth(self) -> PlantTruth:
        """The true state at the current plant time (see :class:`PlantTruth`)."""
        if self._truth_cache is not None:
            return self._truth_cache
        t = self._t
        x = self._x.tolist()
        wave = self._waves_at(t)
        psi = x[2]
        tau = self._tau_act()
        wind_env = self.wind.force_b(t, psi, x[3], x[4])
        drift = wave.drift_b
        cn, ce = self.current.velocity_ned(t)
        peaks = self._peaks(t, psi, x[3], x[4])
        model = self.model
        north_total, east_total, heading_total = _total_pose(x[0], x[1], psi, wave)
        truth = PlantTruth(
            t_s=t,
            north_m=x[0], east_m=x[1], heading_rad=ssa(psi),
            north_total_m=north_total, east_total_m=east_total, heading_total_rad=heading_total,
            surge_mps=x[3], sway_mps=x[4], yaw_rate_radps=x[5],
            wf_surge_m=wave.surge_m, wf_sway_m=wave.sway_m, wf_yaw_rad=wave.yaw_rad,
            yaw_rate_total_radps=x[5] + wave.yaw_rate_radps,
            tau_act_b=tau,
            tau_env_b=(wind_env[0] + drift[0], wind_env[1] + drift[1], wind_env[2] + drift[2]),
            current_north_mps=cn, current_east_mps=ce,
            wind_speed_mps=self.wind.speed_at(t), wind_direction_rad=self.wind.direction_from_rad,
            omega_peak_rad_s=peaks.omega_peak_rad_s, motion_peak_rad_s=peaks.motion_peak_rad_s,
            motion_peaks_rad_s=peaks.motion_peaks_rad_s,
            mass_factor=model.mass_factor, mass_kg=model.mass_kg, surge_mass_kg=model.surge_mass_kg,
        )
        self._truth_cache = truth
        return truth

    def record_values(self) -> RecordValues:
        """The fields of :attr:`truth` a lockstep time-series row keeps, computed alone (the same numbers).

        Returns
        -------
        RecordValues
            ``t_s, north_m, east_m, heading_rad, north_total_m, east_total_m, heading_total_rad, surge_mps,
            sway_mps, yaw_rate_radps, tau_act_b[0], tau_act_b[1], tau_act_b[2], omega_peak_rad_s,
            motion_peak_rad_s, mass_factor, surge_mass_kg`` (the peaks None in calm water).

        Notes
        -----
        Called once per control step, it skips what a row does not keep (wind force, current, wind speed,
        the WF motion fields) and the :class:`PlantTruth` object, and reads the surge mass from a cache that
        follows the mass factor (M11 changes only with it; reading it from the mass matrix costs a numpy
        item per step).
        """
        truth = self._truth_cache
        if truth is not None:  # built already this step: the same values
            tau = truth.tau_act_b
            return (truth.t_s, truth.north_m, truth.east_m, truth.heading_rad, truth.north_total_m,
                    truth.east_total_m, truth.heading_total_rad, truth.surge_mps, truth.sway_mps,
                    truth.yaw_rate_radps, tau[0], tau[1], tau[2], truth.omega_peak_rad_s, truth.motion_peak_rad_s,
                    truth.mass_factor, truth.surge_mass_kg)
        t = self._t
        north, east, psi, u, v, r = self._x.tolist()
        wave = self._waves_at(t)
        tx, ty, tn = self._tau_act()
        peaks = self._peaks(t, psi, u, v)
        model = self.model
        factor = model.mass_factor
        if factor != self._surge_mass_factor:
            self._surge_mass = model.surge_mass_kg
            self._surge_mass_factor = factor
        return (t, north, east, ssa(psi), *_total_pose(north, east, psi, wave), u, v, r, tx, ty, tn,
                peaks.omega_peak_rad_s, peaks.motion_peak_rad_s, factor, self._surge_mass)

    def _tau_act(self) -> tuple[float, float, float]:
        """Force delivered by the thrusters (with the mariner's rudder force from its derivatives)."""
        tau = self.drives.force_b(self._rudder)
        if self._rudder >= 0:
            rudder = float(self.drives.angle[self._rudder])
            dv = self.model.derivatives  # type: ignore[union-attr]
            length = self.scenario.vessel.length_m
            speed2 = self.model.surge_speed_mps ** 2  # type: ignore[union-attr]
            q = 0.5 * self.scenario.vessel.water_density_kgpm3 * length**2 * speed2
            y_d = q * dv.y_d * rudder
            n_d = q * length * dv.n_d * rudder
            tau = (tau[0] + self.drives.delivered_thrust(self._rudder), tau[1] + y_d, tau[2] + n_d)
        return tau

    def _peaks(self, t: float, psi: float, u: float, v: float) -> SpectrumPeaks:
        """Wave and motion peaks for heading ``psi`` and LF velocity ``u, v`` at ``t``."""
        c = math.cos(psi)
        s = math.sin(psi)
        return self.waves.peaks_for_velocity(t, psi, c * u - s * v, s * u + c * v)

    def feedback(self) -> list[DriveReport]:
        """Per-thruster feedback: delivered thrust, actual azimuth/rudder angle, ready."""
        return self.drives.feedback()

    def feedback_values(self) -> tuple[list[float], list[float], list[bool]]:
        """:meth:`feedback` as three lists in ``drives.names`` order (delivered thrust, angle, ready; see
        :meth:`sim_plant.drives.ThrusterDrives.feedback_values`)."""
        return self.drives.feedback_values()

    def sensor_samples(self, t_s_end: float) -> list[SensorSample]:
        """All sensor samples due up to and including ``t_s_end``, in time order (advancing the plant
        to ``t_s_end`` first if needed). Each sample is returned once."""
        if t_s_end > self._t:
            self.advance(t_s_end)
        out = []
        queue = self._samples
        while queue and queue[0].t_s <= t_s_end + _TOL_S:
            out.append(queue.popleft())
        return out

    def state(self) -> tuple[float, float, float, float, float, float]:
        """Raw LF state (north_m, east_m, psi_rad, u_mps, v_mps, r_radps)."""
        north, east, psi, u, v, r = self._x.tolist()
        return north, east, psi, u, v, r
