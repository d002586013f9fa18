"""Batch prediction-error identification of the wave model (seed 002 eqs. (46)–(50)), and the filter that uses it.

Seed 002 §"Kalman filter tuning" describes the commercial practice: record the motion while the vessel keeps
station, detrend it to an estimate of the wave-induced motion η̂_pw(k), and fit the wave model in the directly
parameterised innovations form ::

    ξ̂(k+1) = A_w(θ) ξ̂(k) + L_w(θ) ε(k, θ)                                  seed 002 eq. (50)
    ε(k, θ) = η̂_pw(k) − C_w(θ) ξ̂(k)                                        seed 002 eq. (49)
    θ̂ = arg min_θ det Σ_k ε(k, θ) ε(k, θ)ᵀ                                 seed 002 eq. (48)

re-estimated "at regular time intervals of 20 min, which is the time period for which the sea state can be
considered to be stationary"; then ``Q1 = Q̂_P``, the covariance of the identified innovations.

Here each degree of freedom j has the oscillator of seed 002 eq. (27), ``A_w`` its exact discretisation at
(ω0, ζ) shared by the three DOFs (one sea), ``C_w = [0 1]``, and its own free ``L_w`` (2 numbers). A 2-state
innovations model is the ARMA(2, 2) ``a(q) y = c(q) ε`` with ``a`` the oscillator's characteristic polynomial
and ``c`` = det(qI − A + L C) monic and free; the predictor is stable when ``c`` is, so ``c`` is parameterised
by two reflection coefficients in (−1, 1) (Ljung 1999 §4.2: a stable predictor for every θ). The prediction
errors are then one ``scipy.signal.lfilter`` call per channel, and the criterion eq. (48) is the log-determinant of
their 3×3 sample covariance, minimised over (log ω0, ζ, reflection coefficients) by L-BFGS-B within bounds.

The data are the measured position (body axes: the WF model of seed 001 eq. (34) is body-fixed) and heading
minus the running filter's LF estimate — the detrending of the paper, by the LF model instead of a first-order
high-pass — low-pass filtered and decimated to ≈ 0.5 s (:func:`scipy.signal.decimate`, zero phase), so a
20-min record is ≈ 2400 samples whatever the control rate; to ≈ π/(2·ω_max) instead when the search range's
upper end ω_max lies above π rad/s (a model's Froude-scaled seas: CyberShip II's default range ends at 15.6 rad/s,
so its record keeps the 0.1 s control period).

:class:`PemWaveFilter` (``kind="pem"``) is the steady-state Kalman filter of
:class:`~dpcontrol.estimation.wave_filter.BankWaveFilter` at the current (ω̂0, ζ̂, σ̂_wf), rebuilt after each
identification with the state carried over. It keeps no clock: the record and the schedule count control steps.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import minimize
from scipy.signal import decimate, lfilter, welch

from dpbase.frames import ssa
from dpcontrol.estimation.filter_config import WaveFilterConfig
from dpcontrol.estimation.wave_filter import BankWaveFilter, WaveFilterOutput

#: target sample time of the identification data [s] (wave periods ≥ 3 s: ≥ 6 samples a period), shortened to
#: π/(2·ω_max) when the ω0 search range reaches higher (a model's Froude-scaled seas)
IDENTIFICATION_SAMPLE_TIME_S = 0.5
_MIN_SAMPLES = 256


@dataclass(frozen=True)
class WaveModelEstimate:
    """Result of :func:`identify_wave_model`.

    Attributes
    ----------
    omega_rad_s : float
        Identified WF peak (natural) frequency ω0 [rad/s].
    zeta : float
        Identified relative damping ζ [-].
    wf_std : ndarray, shape (3,)
        Standard deviation of the detrended WF motion, measurement noise removed [m, m, rad] (NaN where a
        channel had no data): the σ_wf that gives the model the measured WF variance (seed 002: Q1 = Q̂_P).
    criterion : float
        log det of the prediction-error covariance at the optimum (seed 002 eq. (48)).
    samples : int
        Decimated samples used.
    """

    omega_rad_s: float
    zeta: float
    wf_std: np.ndarray
    criterion: float
    samples: int


def oscillator_polynomial(omega_rad_s: float, zeta: float, h_s: float) -> np.ndarray:
    """``[1, a1, a2]``: characteristic polynomial of the exact discretisation (step h) of seed 002 eq. (27).

    The poles of ``s² + 2ζω0 s + ω0²`` map to ``exp(s h)``: ``a1 = −2 e^{−ζω0h} cos(ω0 h √(1−ζ²))``,
    ``a2 = e^{−2ζω0h}`` (ζ < 1).
    """
    decay = math.exp(-zeta * omega_rad_s * h_s)
    return np.array([1.0, -2.0 * decay * math.cos(omega_rad_s * h_s * math.sqrt(1.0 - zeta * zeta)), decay * decay])


def _reflection_polynomial(k1: float, k2: float) -> np.ndarray:
    """Monic stable ``[1, c1, c2]`` from reflection coefficients in (−1, 1) (Schur–Cohn / Levinson step-up)."""
    return np.array([1.0, k1 * (1.0 + k2), k2])


def identify_wave_model(residual: np.ndarray, sample_time_s: float, *, omega_range_rad_s: tuple[float, float],
                        zeta_range: tuple[float, float] = (0.02, 0.6), noise_var: np.ndarray | None = None,
                        zeta_fixed: float | None = None) -> WaveModelEstimate | None:
    """Seed 002 eqs. (46)–(50): (ω0, ζ) shared by the channels of ``residual`` by prediction-error minimisation.

    Parameters
    ----------
    residual : ndarray, shape (N, 3)
        Detrended WF motion η̂_pw (body x [m], body y [m], heading [rad]) at ``sample_time_s``, oldest first;
        NaN rows (no measurement) are filled by linear interpolation, a channel with fewer than half its
        samples is left out.
    sample_time_s : float
        Sample time of ``residual`` [s].
    omega_range_rad_s : (float, float)
        Search range of ω0 [rad/s]; the data are decimated to ≈ min(0.5 s, π/(2·ω_max)), ω_max its upper end.
    zeta_range : (float, float)
        Search range of ζ [-].
    noise_var : ndarray, shape (3,), optional
        Measurement noise variance per channel per sample [m², m², rad²], removed from σ̂_wf.
    zeta_fixed : float, optional
        Fix ζ (seed 002: "fixing the damping … to a value in the range 0.01 to 0.1") and identify ω0 only.

    Returns
    -------
    WaveModelEstimate or None
        None when the data do not carry a wave record: too short, or no channel whose variance is at least
        twice its measurement noise's (after the decimation's low-pass).
    """
    data = np.asarray(residual, dtype=float)
    if data.ndim != 2 or data.shape[1] != 3:
        raise ValueError(f"residual must have shape (N, 3), got {data.shape}")
    # at least four samples a period of the highest frequency searched (a model's seas peak at up to 10 rad/s)
    target = min(IDENTIFICATION_SAMPLE_TIME_S, 0.5 * math.pi / omega_range_rad_s[1])
    factor = max(1, round(target / sample_time_s))
    h = factor * sample_time_s
    channels: list[int] = []
    series: list[np.ndarray] = []
    for j in range(3):
        x = data[:, j]
        finite = np.isfinite(x)
        if finite.sum() < max(0.5 * x.size, _MIN_SAMPLES * factor):
            continue
        index = np.arange(x.size)
        x = np.interp(index, index[finite], x[finite])
        if factor > 1:
            x = decimate(x, factor, ftype="fir", zero_phase=True)
        x = x - x.mean()
        if not np.any(x):
            continue
        if noise_var is not None and float(np.var(x)) < 2.0 * float(noise_var[j]) / factor:
            continue        # the channel's wave motion is below its measurement noise: nothing to identify
        channels.append(j)
        series.append(x)
    if not series:
        return None
    y = np.stack(series)                                   # (m, K)
    scale = y.std(axis=1, keepdims=True)
    y = y / scale                                          # the criterion is scale-free; this conditions it
    m, samples = y.shape
    low, high = omega_range_rad_s
    high = min(high, 0.8 * math.pi / h)
    # start: the peak of the channels' summed normalised spectra within the range
    freq_hz, psd = welch(y, fs=1.0 / h, nperseg=min(samples, 512), axis=1)
    omega = 2.0 * math.pi * freq_hz
    inside = (omega >= low) & (omega <= high)
    if not np.any(inside):
        return None
    omega0 = float(omega[inside][np.argmax(psd.sum(axis=0)[inside])])
    zeta0 = zeta_fixed if zeta_fixed is not None else 0.1
    covariance = np.empty((m, m))

    def unpack(theta: np.ndarray) -> tuple[float, float]:
        return math.exp(theta[0]), zeta_fixed if zeta_fixed is not None else float(theta[1])

    def criterion(theta: np.ndarray) -> float:
        w0, z = unpack(theta)
        a = oscillator_polynomial(w0, z, h)
        offset = 1 if zeta_fixed is not None else 2
        eps = np.empty_like(y)
        for i in range(m):
            k1, k2 = np.tanh(theta[offset + 2 * i: offset + 2 * i + 2])
            eps[i] = lfilter(a, _reflection_polynomial(k1, k2), y[i])       # ε = (a/c) y, eqs. (49)–(50)
        np.matmul(eps, eps.T, out=covariance)
        sign, logdet = np.linalg.slogdet(covariance / samples)                # eq. (48)
        return logdet if sign > 0 else math.inf

    theta0 = [math.log(omega0)] + ([] if zeta_fixed is not None else [zeta0]) + [0.0] * (2 * m)
    bounds = [(math.log(low), math.log(high))] + ([] if zeta_fixed is not None else [zeta_range]) \
        + [(-3.0, 3.0)] * (2 * m)
    result = minimize(criterion, np.array(theta0), method="L-BFGS-B", bounds=bounds,
                      options={"maxiter": 200})
    if not math.isfinite(result.fun):
        return None
    w_hat, z_hat = unpack(result.x)
    wf_std = np.full(3, np.nan)
    for i, j in enumerate(channels):
        var = float(scale[i, 0] ** 2)
        if noise_var is not None:
            # the decimation's low-pass keeps ≈ 1/factor of white noise's variance
            var -= float(noise_var[j]) / factor
        wf_std[j] = math.sqrt(max(var, 0.0))
    return WaveModelEstimate(omega_rad_s=w_hat, zeta=z_hat, wf_std=wf_std, criterion=float(result.fun),
                             samples=samples)


class PemWaveFilter:
    """Steady-state wave filter whose WF model is re-identified every ``pem_interval_s`` (``kind="pem"``).

    Between identifications this is :class:`~dpcontrol.estimation.wave_filter.BankWaveFilter` with one model
    (seed 002 eqs. (51)–(54) in steady state). Every step appends the detrended WF motion (measured position in
    body axes and heading, minus the LF estimate) to a record of the last ``pem_window_s``; the first
    identification runs once ``pem_first_s`` of record exist, then one every ``pem_interval_s`` (seed 002:
    20 min). A successful identification rebuilds the filter at (ω̂0, ζ̂) with the identified WF standard
    deviation (the equal-variance rule of :mod:`~dpcontrol.estimation.filter_config` with σ_wf = σ̂_wf, seed 002's
    ``Q1 = Q̂_P``), carrying the state over (the LF estimate does not jump).

    The output publishes ω̂0 like the MMAE's ω̂ (``omega_hat_rad_s``, and ``omegas_rad_s = (ω̂0,)`` with the
    weight 1) and ζ̂ in :attr:`zeta_hat`; :attr:`identifications` counts the successful ones.
    """

    kind = "pem"

    dead_reckons = True  # the LF vessel model with the force input (see WaveFilter)
    force_model = True

    def __init__(self, config: WaveFilterConfig) -> None:
        if config.kind != "pem":
            raise ValueError(f"PemWaveFilter runs kind pem, not {config.kind!r}")
        self.config = config
        self.dt_s = config.sample_time_s
        self.omega_hat = float(config.omegas_rad_s[0])
        self.zeta_hat = float(config.zeta)
        self.wf_std = config.wf_std()
        self.inner = BankWaveFilter(self._inner_config())
        self.index = self.inner.index
        self._window = max(1, round(config.pem_window_s / self.dt_s))
        self._record = np.full((self._window, 3), np.nan)
        self._count = 0                                   # samples written into the record (ring position)
        self._steps_to_next = max(1, round(config.pem_first_s / self.dt_s))
        self._interval = max(1, round(config.pem_interval_s / self.dt_s))
        self._noise_var = np.diag(config.measurement_covariance()).copy()
        self.identifications = 0
        self.last_estimate: WaveModelEstimate | None = None
        self._weights = np.ones(1)
        self._sync_output()

    def _inner_config(self) -> WaveFilterConfig:
        return dataclasses.replace(self.config, kind="kf", omegas_rad_s=(self.omega_hat,), zeta=self.zeta_hat,
                                   wf_position_std_m=float(self.wf_std[0]), wf_heading_std_rad=float(self.wf_std[2]))

    def _sync_output(self) -> None:
        out = self.inner.output
        out.omega_hat_rad_s = self.omega_hat
        out.omegas_rad_s = (self.omega_hat,)
        out.weights = self._weights

    @property
    def output(self) -> WaveFilterOutput:
        """The output of the last step (reused arrays)."""
        return self.inner.output

    @property
    def rejected_samples(self) -> int:
        return self.inner.rejected_samples

    # -- protocol ---------------------------------------------------------------------------
    def reset(self, y_ned: np.ndarray) -> None:
        self.inner.reset(y_ned)
        self._sync_output()

    def predicted_measurement(self) -> tuple[np.ndarray, np.ndarray]:
        return self.inner.predicted_measurement()

    def set_frame_heading(self, psi_rad: float) -> None:
        self.inner.set_frame_heading(psi_rad)

    def step(self, y_ned: np.ndarray | None, tau_b: np.ndarray,
             measured: tuple[bool, bool, bool] = (True, True, True)) -> WaveFilterOutput:
        out = self.inner.step(y_ned, tau_b, measured)
        self._append(y_ned, out)
        self._steps_to_next -= 1
        if self._steps_to_next <= 0:
            self._steps_to_next = self._interval
            self.identify()
        self._sync_output()
        return self.inner.output

    def _append(self, y_ned: np.ndarray | None, out: WaveFilterOutput) -> None:
        """Record ``y − η̂_LF`` in body axes at the measured heading (NaN on unmeasured channels)."""
        row = self._record[self._count % self._window]
        row[:] = np.nan
        pos, _, psi_ok = out.measured
        if y_ned is not None and psi_ok:
            psi = float(self.inner._y[2])                 # the validated measurement of this step
            row[2] = ssa(psi - float(out.eta_hat_ned[2]))
        if y_ned is not None and pos:
            c, s = math.cos(float(out.eta_hat_ned[2])), math.sin(float(out.eta_hat_ned[2]))
            dn = float(self.inner._y[0]) - float(out.eta_hat_ned[0])
            de = float(self.inner._y[1]) - float(out.eta_hat_ned[1])
            row[0] = c * dn + s * de
            row[1] = -s * dn + c * de
        self._count += 1

    def recorded(self) -> np.ndarray:
        """The record, oldest first, shape (min(count, window), 3) (a new array)."""
        n = min(self._count, self._window)
        start = self._count - n
        order = (np.arange(start, self._count) % self._window)
        return self._record[order]

    def identify(self) -> WaveModelEstimate | None:
        """Identify (ω0, ζ, σ_wf) on the record and rebuild the filter; None (nothing changed) if it fails."""
        config = self.config
        estimate = identify_wave_model(
            self.recorded(), self.dt_s, omega_range_rad_s=(config.rpem_omega_min_rad_s, config.rpem_omega_max_rad_s),
            zeta_range=(config.pem_zeta_min, config.pem_zeta_max), noise_var=self._noise_var,
            zeta_fixed=None if config.pem_identify_zeta else config.zeta)
        if estimate is None:
            return None
        wf_std = self.wf_std.copy()
        floor = config.wf_std() * config.pem_wf_std_floor
        for j in (0, 1, 2):
            if math.isfinite(float(estimate.wf_std[j])):
                wf_std[j] = max(float(estimate.wf_std[j]), float(floor[j]))
        wf_std[0] = wf_std[1] = max(wf_std[0], wf_std[1])   # surge and sway share σ (rotation invariance)
        self.omega_hat, self.zeta_hat, self.wf_std = estimate.omega_rad_s, estimate.zeta, wf_std
        state = self.inner.state_dict()
        self.inner = BankWaveFilter(self._inner_config())
        state["omegas_rad_s"] = [self.omega_hat]
        self.inner.load_state_dict(state)
        self.identifications += 1
        self.last_estimate = estimate
        return estimate

    def state_dict(self) -> dict[str, Any]:
        state = self.inner.state_dict()
        state.update({"kind": "pem", "omega_hat_rad_s": self.omega_hat, "zeta_hat": self.zeta_hat,
                      "wf_std": self.wf_std.tolist(), "identifications": self.identifications})
        return state

    def load_state_dict(self, state: dict[str, Any]) -> None:
        try:
            omega = float(state["omega_hat_rad_s"])
            zeta = float(state["zeta_hat"])
            wf_std = np.array(state["wf_std"], dtype=float)
        except (KeyError, TypeError, ValueError):
            raise ValueError("wave filter state: pem needs omega_hat_rad_s, zeta_hat and wf_std") from None
        config = self.config
        if not (config.rpem_omega_min_rad_s <= omega <= config.rpem_omega_max_rad_s and 0.0 < zeta < 1.0
                and wf_std.shape == (3,) and np.all(np.isfinite(wf_std)) and np.all(wf_std > 0.0)):
            raise ValueError("wave filter state: pem parameters out of range")
        saved = (self.omega_hat, self.zeta_hat, self.wf_std)
        self.omega_hat, self.zeta_hat, self.wf_std = omega, zeta, wf_std
        inner = BankWaveFilter(self._inner_config())
        try:
            inner.load_state_dict({**state, "kind": "kf"})
        except ValueError:
            self.omega_hat, self.zeta_hat, self.wf_std = saved
            raise
        self.inner = inner
        self.identifications = int(state.get("identifications", 0))
        self._sync_output()
