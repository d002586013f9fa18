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

import math
from typing import Any

import numpy as np

from dpcontrol.estimation import WaveFilter, WaveFilterConfig, WaveFilterOutput, make_wave_filter
from dpcontrol.estimation.heading import HeadingKalmanFilter, heading_model
from dpcontrol.estimation.kalman_bucy import POSITION, VELOCITY, KalmanBucyFilter, blue_lady_model
from dpcontrol.models.frames import ned_to_body, ssa
from dpcontrol.models.vessels import VesselData

_NO_WEIGHTS: tuple[float, ...] = ()


def _output(n_states: int) -> WaveFilterOutput:
    return WaveFilterOutput(eta_hat_n=np.zeros(3), nu_hat_b=np.zeros(3), bias_hat_b=np.zeros(3),
                            eta_wf_hat_n=np.zeros(3), covariance_diag=np.zeros(n_states), innovation=np.zeros(3),
                            weights=None, omegas_rad_s=_NO_WEIGHTS, omega_hat_rad_s=None,
                            measured=(False, False, False))


class KalmanBucyEstimator:
    """Seed 004 Kalman–Bucy filter behind the :class:`WaveFilter` protocol.

    Parameters
    ----------
    sample_time_s : float
        Control period [s] (the filter integrates one period per step, measurement held).
    """

    kind = "kalman_bucy"

    def __init__(self, sample_time_s: float) -> None:
        self._model = blue_lady_model()
        self._dt = sample_time_s
        self._filter: KalmanBucyFilter | None = None
        self._out = _output(6)
        self._turns = 0.0

    def reset(self, y_n: np.ndarray) -> None:
        x0 = np.zeros(6)
        x0[POSITION] = y_n
        model = self._model
        self._filter = KalmanBucyFilter(model.A, model.B, model.C, model.G, model.Q, R=model.intensity_R(self._dt),
                                        dt_s=self._dt, x0=x0, P0=np.eye(6))

    def predicted_measurement(self) -> tuple[np.ndarray, np.ndarray]:
        f = self._require()
        x_next = f.x[POSITION] + self._dt * f.x[VELOCITY]
        variance = np.diag(f.P)[POSITION] + np.diag(self._model.R_sample)
        return x_next, variance

    def step(self, y_n: np.ndarray | None, tau_b: np.ndarray,
             measured: tuple[bool, bool, bool] = (True, True, True)) -> WaveFilterOutput:
        del tau_b  # kinematic model: no force input (seed 004 eqs. (53)–(58) with X = Y = N = 0)
        f = self._require()
        y = f.x[POSITION].copy() if y_n is None else np.array(y_n, dtype=float)
        if y_n is not None:
            y[2] = f.x[POSITION][2] + ssa(y[2] - f.x[POSITION][2])  # continuous heading
        for i in range(3):
            if not measured[i]:  # unmeasured channel: hold the prediction (no correction)
                y[i] = f.x[POSITION][i]
        innovation = y - f.x[POSITION]
        f.step(y)
        out = self._out
        pose = f.x[POSITION]
        out.eta_hat_n[:] = (pose[0], pose[1], ssa(pose[2]))
        out.nu_hat_b[:] = ned_to_body(f.x[VELOCITY], pose[2])
        out.covariance_diag[:] = np.diag(f.P)
        out.innovation[:] = innovation
        out.measured = tuple(measured)  # type: ignore[assignment]
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
    :meth:`step`), since a course-keeping ship's only control is the rudder.
    """

    kind = "heading_kf"

    def __init__(self, vessel: VesselData, sample_time_s: float, *, omega0_rad_s: float = 1.2, zeta: float = 0.1,
                 compass_std_rad: float = math.radians(0.5),
                 wave_intensity: float = 300.0 * (math.pi / 180) ** 2) -> None:
        if vessel.nomoto_gain_per_s is None or vessel.nomoto_time_constant_s is None:
            raise ValueError(f"vessel {vessel.name} has no Nomoto model for a heading filter")
        gain = vessel.nomoto_gain_per_s
        period = vessel.nomoto_time_constant_s
        self._model = heading_model(
            gain_per_s=gain, time_constant_s=period, omega0_rad_s=omega0_rad_s, zeta=zeta,
            wave_intensity=wave_intensity, yaw_accel_intensity=2.0 * math.radians(0.05) ** 2 / period,
            bias_intensity=(gain / period * math.radians(1.0)) ** 2 / 600.0, compass_std_rad=compass_std_rad)
        self._dt = sample_time_s
        self._filter: HeadingKalmanFilter | None = None
        self._position = np.zeros(2)
        self._out = _output(5)
        self._out.omega_hat_rad_s = omega0_rad_s

    def reset(self, y_n: np.ndarray) -> None:
        self._filter = HeadingKalmanFilter(self._model, self._dt, float(y_n[2]))
        self._position[:] = y_n[:2]

    def predicted_measurement(self) -> tuple[np.ndarray, np.ndarray]:
        f = self._require().filter
        psi = float(f.H[0] @ f.x)
        variance = float(f.H[0] @ f.P @ f.H[0]) + float(self._model.R[0, 0])
        return np.array([self._position[0], self._position[1], ssa(psi)]), np.array([25.0, 25.0, variance])

    def step(self, y_n: np.ndarray | None, tau_b: np.ndarray,
             measured: tuple[bool, bool, bool] = (True, True, True)) -> WaveFilterOutput:
        """Filter the heading; ``tau_b[2]`` carries the rudder angle [rad] (Nomoto sign)."""
        f = self._require()
        heading = None if y_n is None or not measured[2] else float(y_n[2])
        if y_n is not None and measured[0] and measured[1]:
            self._position[:] = y_n[:2]
        estimate = f.step(heading, float(tau_b[2]))
        out = self._out
        out.eta_hat_n[:] = (self._position[0], self._position[1], estimate.psi_hat_rad)
        out.nu_hat_b[:] = (0.0, 0.0, estimate.r_hat_radps)
        out.eta_wf_hat_n[:] = (0.0, 0.0, estimate.psi_wf_hat_rad)
        out.bias_hat_b[:] = (0.0, 0.0, estimate.bias_hat_radps2)
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


WAVE_FILTER_KINDS = ("mmae", "kf", "rpem", "raw")
ESTIMATOR_KINDS = (*WAVE_FILTER_KINDS, "kalman_bucy", "heading_kf")


def make_estimator(kind: str, wave_filter: WaveFilterConfig | None, vessel: VesselData, sample_time_s: float,
                   options: dict[str, Any] | None = None) -> WaveFilter:
    """The estimator of ``kind`` (a DP wave filter, or one of the adapters above)."""
    if kind in WAVE_FILTER_KINDS:
        if wave_filter is None:
            raise ValueError(f"estimator {kind} needs a WaveFilterConfig")
        return make_wave_filter(wave_filter)
    if kind == "kalman_bucy":
        return KalmanBucyEstimator(sample_time_s)  # type: ignore[return-value]
    if kind == "heading_kf":
        opts = dict(options or {})
        return CourseKeepingEstimator(vessel, sample_time_s, **opts)  # type: ignore[return-value]
    raise ValueError(f"unknown estimator kind {kind!r}")
