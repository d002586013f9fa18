"""Estimator construction for the runtime, and adapters to the one :class:`WaveFilter` protocol.

The DP wave filters (mmae, kf, rpem, raw) implement the protocol directly. Two estimators of the
seeds do not, and are adapted here so the same control step runs them:

* ``kalman_bucy`` — seed 004's Kalman–Bucy filter on the 3-DOF kinematic model (positions and
  earth-frame rates, no wave model, no bias): LF pose = its position states, body velocity by
  seed 004 eq. (60);
* ``heading_kf`` — seed 002's course-keeping filter (eqs. (69)–(81)) for a heading autopilot: only
  the heading is filtered (LF + WF yaw), position passes through (a course-keeping ship does not
  control its position).
"""

from __future__ import annotations

import copy
import math
from typing import Any

import numpy as np

from dpbase.frames import ned_to_body, ssa
from dpcontrol.estimation import WaveFilter, WaveFilterConfig, WaveFilterOutput, make_wave_filter
from dpcontrol.estimation.heading import HeadingKalmanFilter, HeadingModel, heading_model
from dpcontrol.estimation.kalman_bucy import POSITION, VELOCITY, KalmanBucyFilter, blue_lady_model
from dpcontrol.models.vessels import VesselData

_NO_WEIGHTS: tuple[float, ...] = ()


def _output(n_states: int) -> WaveFilterOutput:
    return WaveFilterOutput(eta_hat_ned=np.zeros(3), nu_hat_b=np.zeros(3), bias_hat_b=np.zeros(3),
                            eta_wf_hat_ned=np.zeros(3), covariance_diag=np.zeros(n_states), innovation=np.zeros(3),
                            weights=None, omegas_rad_s=_NO_WEIGHTS, omega_hat_rad_s=None,
                            measured=(False, False, False))


class KalmanBucyEstimator:
    """Seed 004 Kalman–Bucy filter behind the :class:`WaveFilter` protocol.

    The model is seed 004's (eqs. (53)–(62): three double integrators, positions measured, no
    force input, no wave states), integrated over one control period per step with the sample
    held (seed 004 eq. (32)) and ``R = R_k Δt`` (eq. (35)). Two things are added for a DP loop:

    * **Unmeasured channels are not corrected.** A channel without a fresh sample this period
      (the GNSS at 5 Hz in a 10 Hz loop) has its rows of ``Cᵀ R⁻¹`` zeroed for the period (one
      precomputed set per availability pattern): the filter predicts there and its covariance
      grows, instead of treating a held or predicted value as new information. With that, every
      fresh sample is used over exactly one period with intensity ``R_k Δt`` — the information of
      one sample of variance ``R_k``, whatever the sensor's rate.
    * **Process noise matched to the vessel** (``process_noise_scale`` × seed 004's ``Q``). The
      seed's ``Q_x = 0.1`` is an acceleration intensity of 0.1 m²/s³: the velocity may wander by
      0.3 m/s within a second, while the Blue Lady's thrusters accelerate her 23 t by at most
      ≈ 0.02 m/s². A filter that fast passes the GNSS noise into the velocity (seed 004 itself finds
      the velocity estimates "burdened with a noise of relatively high level" needing "additional
      smoothing"), and in a DP loop the PID's derivative turns it into thrust noise beyond the
      thrusters' capacity. Accelerations of σ_a ≈ 0.01 m/s² correlated over ≈ 10 s are a white-noise
      intensity ``2σ_a²τ ≈ 2·10⁻³`` m²/s³ = 0.02 × the seed's: the default scale. Measured on the
      seed 004 scenario (``tests/closed_loop/test_seed004.py``): velocity error 0.11 → 0.02 m/s rms,
      station-keeping error 0.24 → 0.06 m rms, commanded-force noise 4× lower. ``1.0`` gives the
      seed's filter.

    Parameters
    ----------
    sample_time_s : float
        Control period Δt [s] (the filter integrates one period per step).
    process_noise_scale : float
        Factor on seed 004's process-noise intensity ``Q`` (> 0; 1 = the seed's tuning).
    """

    kind = "kalman_bucy"
    dead_reckons = False  # no force input: the last velocity, extrapolated (see WaveFilter)
    force_model = False

    def __init__(self, sample_time_s: float, *, process_noise_scale: float = 0.02) -> None:
        for name, value in (("sample_time_s", sample_time_s), ("process_noise_scale", process_noise_scale)):
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"{name} must be a finite number > 0, got {value!r}")
        self._model = blue_lady_model()
        self._q = self._model.Q * process_noise_scale
        self._dt = sample_time_s
        self._filter: KalmanBucyFilter | None = None
        self._out = _output(6)
        # Cᵀ R⁻¹ and Cᵀ R⁻¹ C per availability pattern (measured channels as bits), built on reset
        self._gains: dict[tuple[bool, bool, bool], tuple[np.ndarray, np.ndarray]] = {}

    @property
    def process_noise_intensity(self) -> np.ndarray:
        """The ``Q`` the filter runs with (shape (6, 6), seed 004 units converted to SI)."""
        return self._q.copy()

    def reset(self, y_ned: np.ndarray) -> None:
        x0 = np.zeros(6)
        x0[POSITION] = y_ned
        x0[POSITION[2]] = ssa(float(y_ned[2]))
        model = self._model
        # P0 (seed 004 eq. (46) gives no value): the positions come from one sample, so its variance; the
        # rates are unknown at a reset, 1 m/s and 2 °/s (1σ). P0 = I (1 rad² of heading against a 0.1 deg²
        # sample) made the Riccati equation so stiff that the first seconds needed ~800 RK4 substeps a
        # period: 0.1 s of CPU per 0.1 s cycle after every reset.
        p0 = np.empty(6)
        p0[POSITION] = np.diag(model.R_sample)
        p0[VELOCITY] = (1.0, 1.0, math.radians(2.0) ** 2)
        f = KalmanBucyFilter(model.A, model.B, model.C, model.G, self._q, R=model.intensity_R(self._dt),
                             dt_s=self._dt, x0=x0, P0=np.diag(p0))
        full = f.Ct_Rinv.copy()
        self._gains = {}
        for pattern in ((n, e, h) for n in (True, False) for e in (True, False) for h in (True, False)):
            ct_rinv = full * np.array(pattern, dtype=float)[None, :]
            self._gains[pattern] = (ct_rinv, ct_rinv @ model.C)
        self._filter = f

    def predicted_measurement(self) -> tuple[np.ndarray, np.ndarray]:
        f = self._require()
        x_next = f.x[POSITION] + self._dt * f.x[VELOCITY]
        variance = np.diag(f.P)[POSITION] + np.diag(self._model.R_sample)
        return x_next, variance

    def step(self, y_ned: np.ndarray | None, tau_b: np.ndarray,
             measured: tuple[bool, bool, bool] = (True, True, True)) -> WaveFilterOutput:
        """One period: correct the measured channels of ``y_ned`` continuously, predict the others."""
        del tau_b  # kinematic model: no force input (seed 004 eqs. (53)–(58) with X = Y = N = 0)
        f = self._require()
        pattern = (False, False, False) if y_ned is None else (bool(measured[0]), bool(measured[1]), bool(measured[2]))
        y = f.x[POSITION].copy()
        if y_ned is not None:
            for i in range(3):
                if pattern[i]:
                    y[i] = float(y_ned[i])
            y[2] = f.x[POSITION][2] + ssa(y[2] - f.x[POSITION][2])  # continuous heading next to the state
        innovation = y - f.x[POSITION]
        # The filter object exposes Cᵀ R⁻¹ (and Cᵀ R⁻¹ C) as attributes; swapping them per pattern is
        # the Kalman–Bucy equations with C restricted to the measured rows (no KB class per pattern).
        f.Ct_Rinv, f.Ct_Rinv_C = self._gains[pattern]
        f.step(y)
        out = self._out
        pose = f.x[POSITION]
        out.eta_hat_ned[:] = (pose[0], pose[1], ssa(pose[2]))
        out.nu_hat_b[:] = ned_to_body(f.x[VELOCITY], pose[2])  # seed 004 eq. (60)
        out.covariance_diag[:] = np.diag(f.P)
        out.innovation[:] = innovation
        out.measured = pattern
        return out

    def _require(self) -> KalmanBucyFilter:
        if self._filter is None:
            raise RuntimeError("reset() first")
        return self._filter

    def state_dict(self) -> dict[str, Any]:
        f = self._require()
        return {"kind": self.kind, "x": f.x.tolist(), "P": f.P.tolist()}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        if state.get("kind") != self.kind:
            raise ValueError("state of another estimator kind")
        x = np.array(state["x"], dtype=float)
        self.reset(x[POSITION])
        f = self._require()
        f.x = x
        f.P = np.array(state["P"], dtype=float)


class CourseKeepingEstimator:
    """Seed 002 heading filter (eqs. (69)–(81)) behind the :class:`WaveFilter` protocol.

    The rudder input of the model is the autopilot's rudder angle in the Nomoto sign convention
    (positive δ → positive yaw rate); the runtime passes it as ``tau_b[2]`` (see
    :meth:`step`), since a course-keeping ship's only control is the rudder. The bias ``b`` of
    eq. (72) [rad/s²] is published as the yaw moment ``m b̂`` [N·m] in ``bias_hat_b[2]`` (the
    unit of the protocol, ``m = I_z − N_ṙ``), ready for the autopilot to compensate.

    Parameters
    ----------
    vessel : VesselData
        Needs the Nomoto ``K``, ``T`` and the yaw inertia ``M[2, 2]``.
    sample_time_s : float
        Filter period h [s].
    omega0_rad_s, zeta : float
        Wave-model peak (encounter) frequency [rad/s] and relative damping (seed 002: 1.2, 0.1).
    compass_std_rad : float
        Compass noise standard deviation [rad] (seed 002: 0.5°).
    wave_yaw_std_rad : float
        Design standard deviation of the WF yaw σ_w [rad]; the intensity of w1 in eq. (70) is
        ``4ζω0 σ_w²`` (the stationary variance of ``s/(s² + 2ζω0 s + ω0²)`` driven by white noise
        is ``q/(4ζω0)``). 0 turns wave filtering off: the model keeps no WF motion, so the WF yaw
        reaches the autopilot (the "filter off" comparison of seed 002 Fig. 7 / Fig. 9).
    bias_rudder_rad, bias_time_s : float
        Bias random walk (w3): one standard deviation of drift equals the yaw acceleration
        ``(K/T)·bias_rudder_rad`` of a rudder offset within ``bias_time_s``, i.e. an intensity
        ``((K/T)·δ_b)² / t_b`` [rad²/s⁵].

    Notes
    -----
    Defaults (seed 002 leaves w2, w3 open and its σ_w1 = √300 is ambiguous, see
    :mod:`dpcontrol.estimation.heading`):

    * ``σ_w = 3°``. Read in degrees, the seed's √300 is a WF yaw of 25° standard deviation — a
      model that attributes nearly every heading change to waves: on the seed 002 scenario (real
      WF yaw 0.27°, motion peak 1.1 rad/s) the LF estimate then lags the true heading by up to
      2° and the heading error grows by 70 %. With 3° the notch at ω0 is still deep (rudder WF
      content about 5× below the unfiltered case, measured in ``tests/closed_loop/test_seed002.py``)
      while the LF estimate follows the turns.
    * bias: a 5° rudder equivalent within 100 s. The slowly varying yaw moment of the waves changes
      with the heading relative to the waves, i.e. at every course change; in the seed 002 sea it is
      worth ≈ 5° of rudder (measured on the plant). The former (1°, 600 s) took ≈ 700 s to learn it,
      during which the ship drifted off course by several degrees.
    * w2 (LF yaw acceleration noise): the yaw rate would wander with 0.05°/s standard deviation
      (``q2 = 2σ_r²/T``).
    """

    kind = "heading_kf"

    dead_reckons = True  # the Nomoto model with the rudder input carries the heading
    force_model = False  # the Nomoto model, not the DP vessel model

    def __init__(self, vessel: VesselData, sample_time_s: float, *, omega0_rad_s: float = 1.2, zeta: float = 0.1,
                 compass_std_rad: float = math.radians(0.5), wave_yaw_std_rad: float = math.radians(3.0),
                 bias_rudder_rad: float = math.radians(5.0), bias_time_s: float = 100.0) -> None:
        if vessel.nomoto_gain_per_s is None or vessel.nomoto_time_constant_s is None:
            raise ValueError(f"vessel {vessel.name} has no Nomoto model for a heading filter")
        for name, value in (("omega0_rad_s", omega0_rad_s), ("zeta", zeta), ("compass_std_rad", compass_std_rad),
                            ("bias_rudder_rad", bias_rudder_rad), ("bias_time_s", bias_time_s),
                            ("sample_time_s", sample_time_s)):
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"{name} must be a finite number > 0, got {value!r}")
        if not (math.isfinite(wave_yaw_std_rad) and wave_yaw_std_rad >= 0.0):
            raise ValueError(f"wave_yaw_std_rad must be a finite number >= 0, got {wave_yaw_std_rad!r}")
        gain = vessel.nomoto_gain_per_s
        period = vessel.nomoto_time_constant_s
        self._inertia = float(vessel.mass_matrix[2, 2])
        self._model = heading_model(
            gain_per_s=gain, time_constant_s=period, omega0_rad_s=omega0_rad_s, zeta=zeta,
            wave_intensity=4.0 * zeta * omega0_rad_s * wave_yaw_std_rad**2,
            yaw_accel_intensity=2.0 * math.radians(0.05) ** 2 / period,
            bias_intensity=(gain / period * bias_rudder_rad) ** 2 / bias_time_s, compass_std_rad=compass_std_rad)
        self._dt = sample_time_s
        # Built once here so that settings with no steady-state filter (no stabilising Riccati solution) are
        # refused with the configuration, not at the first heading, every cycle; reset builds it on the heading.
        HeadingKalmanFilter(self._model, self._dt, 0.0)
        self._filter: HeadingKalmanFilter | None = None
        self._position = np.zeros(2)
        self._out = _output(5)
        self._out.omega_hat_rad_s = omega0_rad_s if wave_yaw_std_rad > 0.0 else None

    @property
    def model(self) -> HeadingModel:
        """The continuous model (seed 002 eqs. (75)–(81)) the filter runs on."""
        return self._model

    def reset(self, y_ned: np.ndarray) -> None:
        self._filter = HeadingKalmanFilter(self._model, self._dt, float(y_ned[2]))
        self._position[:] = y_ned[:2]

    def predicted_measurement(self) -> tuple[np.ndarray, np.ndarray]:
        f = self._require().filter
        psi = float(f.H[0] @ f.x)
        variance = float(f.H[0] @ f.P @ f.H[0]) + float(self._model.R[0, 0])
        return np.array([self._position[0], self._position[1], ssa(psi)]), np.array([25.0, 25.0, variance])

    def step(self, y_ned: np.ndarray | None, tau_b: np.ndarray,
             measured: tuple[bool, bool, bool] = (True, True, True)) -> WaveFilterOutput:
        """Filter the heading; ``tau_b[2]`` carries the rudder angle [rad] (Nomoto sign)."""
        f = self._require()
        heading = None if y_ned is None or not measured[2] else float(y_ned[2])
        if y_ned is not None and measured[0] and measured[1]:
            self._position[:] = y_ned[:2]
        estimate = f.step(heading, float(tau_b[2]))
        out = self._out
        out.eta_hat_ned[:] = (self._position[0], self._position[1], estimate.psi_hat_rad)
        out.nu_hat_b[:] = (0.0, 0.0, estimate.r_hat_radps)
        out.eta_wf_hat_ned[:] = (0.0, 0.0, estimate.psi_wf_hat_rad)
        out.bias_hat_b[:] = (0.0, 0.0, self._inertia * estimate.bias_hat_radps2)  # m b̂ [N·m]
        out.covariance_diag[:] = np.diag(f.filter.P)
        out.measured = (False, False, heading is not None)
        return out

    def _require(self) -> HeadingKalmanFilter:
        if self._filter is None:
            raise RuntimeError("reset() first")
        return self._filter

    def state_dict(self) -> dict[str, Any]:
        f = self._require().filter
        return {"kind": self.kind, "x": f.x.tolist(), "P": f.P.tolist(), "position": self._position.tolist()}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        if state.get("kind") != self.kind:
            raise ValueError("state of another estimator kind")
        x = np.array(state["x"], dtype=float)
        position = np.array(state["position"], dtype=float)
        self.reset(np.array([position[0], position[1], x[2]]))
        f = self._require().filter
        f.x = x
        f.P = np.array(state["P"], dtype=float)


class MassAdaptiveEstimator:
    """A DP wave filter whose model inertia follows the MRAC's mass estimate between set-point moves.

    The wave filters are built on the vessel's nominal inertia ``M₀`` (the shuttle tanker's: ballast).
    During seed 003's 12 h offloading the true surge inertia grows 2.66×, and a filter on ``M₀``
    predicts accelerations up to 2.66× too large: its LF estimate and bias are distorted during every
    move, and the MRAC, which learns from that estimate, is led astray (measured on the plant: â₂ 47 %
    above the true mass after 12 h). Seed 003's single-DOF study gives the filter the true mass
    (:mod:`sim_plant.bench.offloading_case`); on a vessel the best model available is the MRAC's.

    With ``M̂ = diag(â₂)`` the filter is fed ``τ' = M₀ M̂⁻¹ τ``: its model ``M₀ ν̇ + D₀ν = τ' + b'``
    becomes ``M̂ ν̇ + D₀ M̂ M₀⁻¹ ν = τ + M̂ M₀⁻¹ b'``, the true dynamics when ``M̂ = M`` and the damping
    scales with the inertia (as the tanker's ``D = M/1000, M/100, M/80``; what does not scale is
    slowly varying and ends in the bias). The bias is published in physical units,
    ``b̂ = M̂ M₀⁻¹ b̂'``. With ``M̂ = M₀`` the wrapper is the inner filter exactly.

    The model is updated only while the MRAC is **not** adapting (its gate closed in every DOF: the
    reference model at rest, between moves): updating it during a move closes a fast loop — a mass
    estimate too high makes the filter predict too little motion, the estimate lags, and the MRAC
    raises the mass further — which diverged on the plant (â₂ > 3× the true mass within 3 h). Held
    over each move, the filter's mass and the MRAC's estimate converge together from move to move
    (within ±8 % of the true mass over the 12 h, see ``tests/closed_loop/test_seed003.py``).

    Parameters
    ----------
    inner : WaveFilter
        A DP wave filter (mmae, kf, rpem, raw) built on ``M₀``.
    mass_nominal : array_like, shape (3,)
        ``diag(M₀)`` [kg, kg, kg·m²].
    """

    @property
    def dead_reckons(self) -> bool:
        return self.inner.dead_reckons

    @property
    def force_model(self) -> bool:
        return self.inner.force_model

    def __init__(self, inner: WaveFilter, mass_nominal: np.ndarray) -> None:
        nominal = np.array(mass_nominal, dtype=float)
        if nominal.shape != (3,) or not np.all(np.isfinite(nominal)) or np.any(nominal <= 0.0):
            raise ValueError(f"mass_nominal must be 3 finite numbers > 0, got {mass_nominal!r}")
        self.inner = inner
        self._nominal = nominal
        self._ratio = np.ones(3)  # diag(M̂ M₀⁻¹) in use
        self._tau = np.zeros(3)
        self._bias = np.zeros(3)
        self._out: WaveFilterOutput | None = None

    def __getattr__(self, name: str) -> Any:
        if name == "inner":  # not set yet (copy/unpickle): no recursion
            raise AttributeError(name)
        return getattr(self.inner, name)  # kind, config, set_frame_heading, ... of the inner filter

    @property
    def mass_ratio(self) -> np.ndarray:
        """``diag(M̂ M₀⁻¹)`` in use (new array)."""
        return self._ratio.copy()

    def set_mass_estimate(self, mass_hat: np.ndarray) -> None:
        """Use ``diag(M̂)`` [kg, kg, kg·m²] from the next step on (call between moves, see the class
        docstring); non-finite or non-positive entries are ignored."""
        mass = np.asarray(mass_hat, dtype=float)
        if mass.shape != (3,):
            raise ValueError(f"mass_hat must have shape (3,), got {mass.shape}")
        good = np.isfinite(mass) & (mass > 0.0)
        self._ratio[good] = mass[good] / self._nominal[good]

    def reset(self, y_ned: np.ndarray) -> None:
        self.inner.reset(y_ned)

    def predicted_measurement(self) -> tuple[np.ndarray, np.ndarray]:
        return self.inner.predicted_measurement()

    def step(self, y_ned: np.ndarray | None, tau_b: np.ndarray,
             measured: tuple[bool, bool, bool] = (True, True, True)) -> WaveFilterOutput:
        """The inner step with ``τ' = M₀ M̂⁻¹ τ``; the output's bias in physical units (own array)."""
        np.divide(tau_b, self._ratio, out=self._tau)
        inner = self.inner.step(y_ned, self._tau, measured)
        # one output object reused (as the inner filter's): its fields are the inner's (the same arrays)
        # but its own bias — a dict update instead of copy.copy of a new object every step
        out = self._out
        if out is None:
            out = self._out = copy.copy(inner)
        else:
            vars(out).update(vars(inner))
        np.multiply(inner.bias_hat_b, self._ratio, out=self._bias)
        out.bias_hat_b = self._bias
        return out

    def state_dict(self) -> dict[str, Any]:
        return {**self.inner.state_dict(), "mass_ratio": self._ratio.tolist()}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        ratio = state.get("mass_ratio")
        if ratio is not None:
            values = np.array(ratio, dtype=float)
            if values.shape != (3,) or not np.all(np.isfinite(values)) or np.any(values <= 0.0):
                raise ValueError(f"invalid mass_ratio in the estimator state: {ratio!r}")
        self.inner.load_state_dict({k: v for k, v in state.items() if k != "mass_ratio"})
        if ratio is not None:
            self._ratio[:] = values


WAVE_FILTER_KINDS = ("mmae", "kf", "rpem", "pem", "raw")
ESTIMATOR_KINDS = (*WAVE_FILTER_KINDS, "kalman_bucy", "heading_kf")


def make_estimator(kind: str, wave_filter: WaveFilterConfig | None, vessel: VesselData, sample_time_s: float,
                   options: dict[str, Any] | None = None) -> WaveFilter:
    """The estimator of ``kind`` (a DP wave filter, or one of the adapters above)."""
    if kind in WAVE_FILTER_KINDS:
        if wave_filter is None:
            raise ValueError(f"estimator {kind} needs a WaveFilterConfig")
        return make_wave_filter(wave_filter)
    if kind == "kalman_bucy":
        return KalmanBucyEstimator(sample_time_s, **dict(options or {}))  # type: ignore[return-value]
    if kind == "heading_kf":
        opts = dict(options or {})
        return CourseKeepingEstimator(vessel, sample_time_s, **opts)  # type: ignore[return-value]
    raise ValueError(f"unknown estimator kind {kind!r}")
