"""DP wave filters behind one protocol: MMAE bank, fixed-ω0 KF, RPEM, and "raw" (no wave states).

The runtime calls every kind the same way (:class:`WaveFilter`): :meth:`~WaveFilter.reset` on the
first fix, :meth:`~WaveFilter.predicted_measurement` for the sensor hub's prediction test, then one
:meth:`~WaveFilter.step` per control period (correct with the measured channels, then predict with the
force actually delivered), and ``state_dict``/``load_state_dict`` for a bumpless restart.

Vessel-parallel frame (seed 002 eq. (14), seed 001 eqs. (17)–(38))
------------------------------------------------------------------
The linear model lives in vessel-parallel coordinates ``ηp = Rᵀ(ψ_f)η`` about a *frame heading*
ψ_f, taken as the measured heading (seed 001: ``η_y^f = Rᵀ(ψ_y)η_y``), or the predicted total
heading when no heading arrives. When ψ_f changes by Δψ between samples, every vessel-parallel
vector (ηp, bp, and the WF states if they are earth-frame, seed 002) is rotated by ``Rᵀ(Δψ)`` — the
discrete counterpart of the ``ψ̇S`` terms of seed 001 eqs. (30)–(31) — so the estimate in NED,
``η = R(ψ_f)ηp``, is unchanged by the rotation itself: a 90° turn or a position 1 km from the datum
does not corrupt it. Body-frame WF states (seed 001 eq. (34), default) and ν are not rotated.
Yaw innovations are wrapped with ``ssa``; the heading states are kept continuous and shifted
together by whole turns so the MMAE blend of headings never averages across ±π.

Measurement availability
------------------------
North and east are used as a pair (a position fix has both); a lone coordinate, or a value that is
not finite, is dropped and reported in ``WaveFilterOutput.measured``. Each pattern (position ±,
heading ±) has its own precomputed steady-state gains (:func:`~dpcontrol.estimation.kalman.pattern_gains`);
with nothing measured the filter only predicts (dead reckoning).

MMAE weights
------------
By default the models are compared on band-limited, locally whitened and tempered innovations
(:class:`~dpcontrol.estimation.weighting.BandLikelihood`: only the wave band, a scale-free measure,
evidence counted at the rate of independent samples, held while the LF model is in a transient,
position and heading weighted by the share of the WF motion measured in each), and each
model's WF noise intensity gives every model the same WF variance — the remedies for the docs/design.md §5
trap and for the chatter of per-sample likelihoods on a real plant. The per-sample forms
(``likelihood_scale="common"``/``"own"``) remain for design-model data. Weights follow the discrete
Bayes recursion with forgetting and a floor (:mod:`~dpcontrol.estimation.weighting`), or the exactly
integrated DWSG of seed 000 eq. (18).

Timing and outputs
------------------
``step(y_k, τ_k)`` returns the *corrected* estimate at t_k (what the controller uses now) and leaves the
one-step prediction for t_k+1 inside, made with τ_k — the force delivered over the coming period
(the last delivered force is the usual stand-in). Output arrays are preallocated and *reused* every
step (views): copy them to keep them.

Usage::

    config = WaveFilterConfig.from_options(vessel.mass_matrix, vessel.damping_matrix, 0.2, kind="mmae",
                                           omegas_rad_s=[0.3, 0.45, 0.6, 0.75, 0.9, 1.05, 1.2, 1.35],
                                           zeta=0.1, options={}, length_m=vessel.length_m)
    wave_filter = make_wave_filter(config)
    wave_filter.reset(first_fix_ned)
    ...
    y_pred_ned, innovation_var = wave_filter.predicted_measurement()   # sensor hub's jump test
    out = wave_filter.step(y_ned, tau_delivered_b, (pos_ok, pos_ok, heading_ok))
    controller(out.eta_hat_ned, out.nu_hat_b, out.bias_hat_b)
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np

from dpbase.frames import ssa, ssa_array
from dpcontrol.estimation.design_model import DesignModel, StateIndex, dp_design_model
from dpcontrol.estimation.discretize import DiscreteModel, discretize
from dpcontrol.estimation.filter_config import WaveFilterConfig
from dpcontrol.estimation.kalman import KalmanFilter, SteadyStateFilter, is_covariance, pattern_code, pattern_gains
from dpcontrol.estimation.kernels import NO_INDEX, bank_correct, bank_outputs, bank_predict, bank_predicted_measurement
from dpcontrol.estimation.weighting import BandLikelihood, bayes_step, dwsg_step

STATE_DICT_VERSION = 1
_FULL = pattern_code((True, True, True))
_POSITION = pattern_code((True, True, False))
PATTERN_HEADING = pattern_code((False, False, True))
PATTERN_NONE = pattern_code((False, False, False))
_USED_PATTERNS = (_FULL, _POSITION, PATTERN_HEADING, PATTERN_NONE)
PATTERN_MASKS = {code: np.array([code & 1, (code >> 1) & 1, (code >> 2) & 1], dtype=float) for code in _USED_PATTERNS}
PATTERN_MEASURED = {code: (bool(code & 1), bool(code & 2), bool(code & 4)) for code in _USED_PATTERNS}


@dataclass(eq=False)
class WaveFilterOutput:
    """What a wave filter publishes after each step (arrays are reused views, see module docstring).

    Attributes
    ----------
    eta_hat_ned : ndarray, shape (3,)
        LF pose [north_m, east_m, psi_rad] in NED, heading wrapped with ``ssa``.
    nu_hat_b : ndarray, shape (3,)
        LF body velocity [u_mps, v_mps, r_radps].
    bias_hat_b : ndarray, shape (3,)
        Bias force in body axes [N, N, N·m] (vessel-parallel at the current heading).
    eta_wf_hat_ned : ndarray, shape (3,)
        WF motion [north_m, east_m, psi_rad] in NED (zeros for ``raw``).
    covariance_diag : ndarray, shape (n,)
        Diagonal of the estimation-error covariance of the full state (vessel-parallel coordinates,
        state order of :class:`~dpcontrol.estimation.design_model.StateIndex`); for the MMAE the
        mixture covariance ``Σ p_i (P_i + (x_i − x̂)(x_i − x̂)ᵀ)``.
    innovation : ndarray, shape (3,)
        ``y − ŷ⁻`` in NED [m, m, rad] (weight-averaged for the MMAE); 0 on unmeasured channels.
    weights : ndarray, shape (N,) or None
        MMAE model probabilities (None for the other kinds).
    omegas_rad_s : tuple of float
        The configured peak frequencies: the bank's grid (mmae), the fixed ω0 (kf), the initial ω0
        (rpem), empty (raw) [rad/s].
    omega_hat_rad_s : float or None
        Weight-averaged peak frequency (mmae), RPEM estimate, the fixed ω0 (kf), None (raw) [rad/s].
    measured : tuple of 3 bool
        The channels actually used this step.
    """

    eta_hat_ned: np.ndarray
    nu_hat_b: np.ndarray
    bias_hat_b: np.ndarray
    eta_wf_hat_ned: np.ndarray
    covariance_diag: np.ndarray
    innovation: np.ndarray
    weights: np.ndarray | None
    omegas_rad_s: tuple[float, ...]
    omega_hat_rad_s: float | None
    measured: tuple[bool, bool, bool] = (False, False, False)

    @property
    def eta_wf_hat(self) -> np.ndarray:
        """Alias of :attr:`eta_wf_hat_ned` (NED)."""
        return self.eta_wf_hat_ned


@runtime_checkable
class WaveFilter(Protocol):
    """The protocol the runtime calls for every estimator kind.

    ``dead_reckons``: the estimator's model carries the pose through a reference outage (a force input and a
    vessel model: every wave filter). A kinematic filter without one (seed 004's Kalman–Bucy) only extrapolates
    the last velocity, which the runtime does not hold position on (see ``FallbackSettings``).

    ``force_model``: the estimator predicts with the DP vessel model ``M₀ν̇ + Dν = τ + Rᵀb`` (seed 002 eq. (12)),
    so an inertia estimate (the MRAC's, seed 003) can replace ``M₀`` by scaling the force input
    (``MassAdaptiveEstimator``); False for a filter without that model (Kalman–Bucy, the Nomoto autopilot's).
    """

    config: WaveFilterConfig

    @property
    def dead_reckons(self) -> bool: ...

    @property
    def force_model(self) -> bool: ...

    def reset(self, y_ned: np.ndarray) -> None:
        """Initialise on a fix [north_m, east_m, psi_rad]: LF pose = y, everything else 0.

        What was learnt about the sea (MMAE weights, RPEM ω̂0) is kept when the filter was already
        running: a re-initialisation of the pose does not change the sea state.
        """
        ...

    def predicted_measurement(self) -> tuple[np.ndarray, np.ndarray]:
        """(ŷ⁻ (3,) NED predicted for the next step, innovation variance diagonal (3,) in NED)."""
        ...

    def step(self, y_ned: np.ndarray | None, tau_b: np.ndarray,
             measured: tuple[bool, bool, bool] = (True, True, True)) -> WaveFilterOutput:
        """One period: correct with y_ned on the measured channels, then predict with τ_b [N, N, N·m]."""
        ...

    def state_dict(self) -> dict[str, Any]:
        """JSON-able state for a bumpless restart."""
        ...

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore :meth:`state_dict`; raises ValueError (state untouched) if it does not fit."""
        ...


def build_design_model(config: WaveFilterConfig, omega_rad_s: float | None, bias_factor: float = 1.0) -> DesignModel:
    """The design model of ``config`` at ω0 (None: without wave states); ``bias_factor`` multiplies the bias
    intensity Q3 (the start-up learning's model, :meth:`WaveFilterConfig.bias_learning_time`)."""
    return dp_design_model(
        config.mass_matrix, config.damping_matrix, omega_rad_s, zeta=config.zeta,
        wf_intensity=None if omega_rad_s is None else config.wf_intensity(omega_rad_s),
        force_intensity=config.force_intensity(), bias_intensity=bias_factor * config.bias_intensity(),
        bias_time_constants_s=config.bias_time_constants_s)


def _bank_design(config: WaveFilterConfig, omegas: Sequence[float | None], R: np.ndarray, bias_factor: float = 1.0
                 ) -> tuple[list[DesignModel], list[DiscreteModel], list[dict[int, SteadyStateFilter]]]:
    """A bank's design models at ``omegas``, their discretisations and each one's steady-state gains per
    measurement pattern (``bias_factor``: see :func:`build_design_model`)."""
    models = [build_design_model(config, w, bias_factor) for w in omegas]
    discrete = [discretize(m.A, m.B, m.E, m.Qc, config.sample_time_s) for m in models]
    gains = [pattern_gains(d.Phi, m.H, d.Qd, R) for d, m in zip(discrete, models, strict=True)]
    return models, discrete, gains


def _as_floats(value: Any, length: int, what: str) -> list[float]:
    try:
        if len(value) != length:
            raise ValueError
        return [float(v) for v in value]
    except (TypeError, ValueError):
        raise ValueError(f"{what} must be a sequence of {length} numbers, got {value!r}") from None


class FrameFilter:
    """Shared input checking, vessel-parallel frame handling and output for every kind."""

    kind: str
    dead_reckons = True  # the LF vessel model with the force input (see WaveFilter)
    force_model = True

    def __init__(self, config: WaveFilterConfig, index: StateIndex) -> None:
        self.config = config
        self.index = index
        self.dt_s = config.sample_time_s
        pairs = index.horizontal_pairs(rotate_waves=config.wf_frame == "earth")
        self._ia = np.array([a for a, _ in pairs])
        self._ib = np.array([b for _, b in pairs])
        self._psi_frame = 0.0
        self._initialized = False
        self._y = np.zeros(3)
        self._yp = np.zeros(3)
        self._tau = np.zeros(3)
        n = index.n
        self._lf_tail = np.zeros(6)          # [bias (3), ν (3)]: contiguous in the state vector
        self._eta0 = index.eta.start
        self._lf_slice = slice(index.bias.start, index.nu.stop)
        self._wf0 = None if index.xi2 is None else index.xi2.start
        self.output = WaveFilterOutput(
            eta_hat_ned=np.zeros(3), nu_hat_b=self._lf_tail[3:6], bias_hat_b=self._lf_tail[0:3],
            eta_wf_hat_ned=np.zeros(3),
            covariance_diag=np.zeros(n), innovation=np.zeros(3), weights=None, omegas_rad_s=(),
            omega_hat_rad_s=None)
        self.rejected_samples = 0
        # dead reckoning of the bias (see :meth:`_dead_reckoning_bias`)
        drift = config.bias_drift_time()
        self._bias_mean_on = config.dead_reckoning_bias == "mean"
        self._bias_times_s = (drift, config.bias_yaw_drift_time_s)   # the means' times: surge/sway, yaw
        self._bias_grace_s = drift / 500.0
        self._restart_bias_mean()

    # -- dead reckoning of the bias ----------------------------------------------------------
    def _restart_bias_mean(self) -> None:
        self._bias_mean = [0.0, 0.0, 0.0]   # north, east [N], yaw [N·m]
        self._bias_mean_span_s = [0.0, 0.0]  # time each mean has averaged over (surge/sway, yaw) [s]
        self._since_reset_s = 0.0
        self._bias_gap_s = [0.0, 0.0]        # time since the last position / heading correction [s]
        self._bias_period_s = [0.0, 0.0]     # the last interval between two corrections (the sensor's period) [s]

    def _dead_reckoning_bias(self, x: np.ndarray, weights: np.ndarray | None, code: int) -> None:
        """The bias while its measurement is missing (dead reckoning): relaxed to its mean, not held.

        The bias estimate follows the slowly varying wave drift and wind gusts within ~15 s (the bank's slowest
        correction mode on the supply vessel); held as it was when the position was lost, it holds that
        minute's force for the whole dead reckoning, and the thrust with it (the model estimate stays on the
        set-point only with τ = −b̂, whatever the controller). So, per channel — surge/sway with the position,
        yaw with the heading —, the corrected bias (blended over the bank) is averaged while measured, over the
        random-walk bias's drift time T (``bias_drift_time_s``, the time scale of mean current and wind
        changes; ``bias_yaw_drift_time_s`` in yaw; a running mean until it has that much; surge/sway in NED),
        from T/16 after a reset (the bias's own convergence from zero left out). Once the measurement has been
        missing for T_drift/500 (2 s on the supply vessel) and for three of the channel's last sample intervals
        (a sensor's period and a missed sample or two are not dead reckoning: a 1 Hz receiver or heading on a
        vessel whose T_drift/500 is shorter; the interval is not saved with the state), the channel's bias states
        of every model relax to the mean with time constant T/100 (surge/sway 10 s, yaw 1 s on the supply vessel).
        ``x``: the corrected states, (N, n) or (n,), changed in place.
        """
        if not self._bias_mean_on:
            return
        dt = self.dt_s
        self._since_reset_s += dt
        b0 = self.index.bias.start
        c = math.cos(self._psi_frame)
        s = math.sin(self._psi_frame)
        mean = self._bias_mean
        for channel, measured in ((0, code & _POSITION), (1, code & PATTERN_HEADING)):
            time_s = self._bias_times_s[channel]
            if measured:
                gap = self._bias_gap_s[channel] + dt
                self._bias_gap_s[channel] = 0.0
                self._bias_period_s[channel] = gap
                if self._since_reset_s <= time_s / 16.0:
                    continue
                self._bias_mean_span_s[channel] += gap
                w = min(1.0, gap / min(time_s, self._bias_mean_span_s[channel]))
                if channel == 0:
                    if weights is not None:
                        bx, by = float(weights @ x[:, b0]), float(weights @ x[:, b0 + 1])
                    else:
                        bx, by = float(x[b0]), float(x[b0 + 1])
                    mean[0] += w * (c * bx - s * by - mean[0])
                    mean[1] += w * (s * bx + c * by - mean[1])
                else:
                    bn = float(weights @ x[:, b0 + 2]) if weights is not None else float(x[b0 + 2])
                    mean[2] += w * (bn - mean[2])
                continue
            self._bias_gap_s[channel] += dt
            grace = max(self._bias_grace_s, 3.0 * self._bias_period_s[channel])
            if self._bias_mean_span_s[channel] <= 0.0 or self._bias_gap_s[channel] <= grace:
                continue
            k = -math.expm1(-dt / (time_s / 100.0))
            if channel == 0:
                mx = c * mean[0] + s * mean[1]
                my = -s * mean[0] + c * mean[1]
                x[..., b0] += k * (mx - x[..., b0])
                x[..., b0 + 1] += k * (my - x[..., b0 + 1])
            else:
                x[..., b0 + 2] += k * (mean[2] - x[..., b0 + 2])

    # -- inputs -------------------------------------------------------------------------------
    def _read_inputs(self, y_ned: np.ndarray | None, tau_b: np.ndarray,
                     measured: tuple[bool, bool, bool]) -> int:
        """Validate; fill ``self._y``/``self._tau``; return the availability pattern code.

        Raises ValueError (nothing changed) for a malformed τ or ``measured``; measurement values that
        are not finite only drop their channel (a sensor must not crash the loop).
        """
        if not self._initialized:
            raise RuntimeError("wave filter not initialised: call reset(y_ned) on the first fix")
        try:
            t0, t1, t2 = float(tau_b[0]), float(tau_b[1]), float(tau_b[2])
        except (TypeError, ValueError, IndexError):
            raise ValueError(f"tau_b must be 3 numbers [N, N, N·m], got {tau_b!r}") from None
        if not (math.isfinite(t0) and math.isfinite(t1) and math.isfinite(t2)):
            raise ValueError(f"tau_b must be finite [N, N, N·m], got {tau_b!r}")
        if len(measured) != 3:
            raise ValueError(f"measured must be 3 booleans, got {measured!r}")
        tau = self._tau
        tau[0] = t0
        tau[1] = t1
        tau[2] = t2
        if y_ned is None:
            return PATTERN_NONE
        use_pos = bool(measured[0]) and bool(measured[1])
        use_psi = bool(measured[2])
        y = self._y
        try:
            if use_pos:
                north, east = float(y_ned[0]), float(y_ned[1])
                if math.isfinite(north) and math.isfinite(east):
                    y[0] = north
                    y[1] = east
                else:
                    use_pos = False
                    self.rejected_samples += 1
            if use_psi:
                psi = float(y_ned[2])
                if math.isfinite(psi):
                    y[2] = psi
                else:
                    use_psi = False
                    self.rejected_samples += 1
        except (TypeError, ValueError, IndexError):
            self.rejected_samples += 1
            return PATTERN_NONE
        return (_POSITION if use_pos else 0) | (PATTERN_HEADING if use_psi else 0)

    def _check_reset(self, y_ned: np.ndarray) -> list[float]:
        y = _as_floats(y_ned, 3, "y_ned")
        if not all(math.isfinite(v) for v in y):
            raise ValueError(f"reset needs a finite fix [north_m, east_m, psi_rad], got {y_ned!r}")
        return y

    # -- frame ------------------------------------------------------------------------------
    def _rotate_states(self, x: np.ndarray, dpsi: float) -> None:
        """Vessel-parallel vectors ← Rᵀ(Δψ)·(…) for the frame change Δψ (x: (..., n), in place)."""
        c = math.cos(dpsi)
        s = math.sin(dpsi)
        xa = x[..., self._ia]
        xb = x[..., self._ib]
        x[..., self._ia] = c * xa + s * xb
        x[..., self._ib] = c * xb - s * xa

    def _rotation_matrix(self, dpsi: float) -> np.ndarray:
        """T (n, n) with x_new = T x for the frame change Δψ (for covariances: T P Tᵀ)."""
        T = np.eye(self.index.n)
        self._rotate_states(T.T, dpsi)  # rotating the rows of Tᵀ = rotating the columns' images
        return T

    def _to_vessel_parallel(self, code: int) -> None:
        """``y_p = [Rᵀ(ψ_f)·(north, east), ψ]`` for the current frame heading."""
        c = math.cos(self._psi_frame)
        s = math.sin(self._psi_frame)
        y, yp = self._y, self._yp
        if code & _POSITION:
            yp[0] = c * y[0] + s * y[1]
            yp[1] = -s * y[0] + c * y[1]
        else:
            yp[0] = 0.0
            yp[1] = 0.0
        yp[2] = y[2] if code & PATTERN_HEADING else 0.0

    def _write_pose(self, x_hat: np.ndarray) -> None:
        """LF pose, velocity, bias and WF motion from the (blended) state, to NED."""
        out = self.output
        c = math.cos(self._psi_frame)
        s = math.sin(self._psi_frame)
        v = x_hat.tolist()                  # Python floats: cheaper than numpy scalars for a few values
        e0 = self._eta0
        xp, yp = v[e0], v[e0 + 1]
        out.eta_hat_ned[:] = (c * xp - s * yp, s * xp + c * yp, ssa(v[e0 + 2]))
        np.copyto(self._lf_tail, x_hat[self._lf_slice])   # bias_hat_b and nu_hat_b are views
        w0 = self._wf0
        if w0 is not None:
            wx, wy = v[w0], v[w0 + 1]
            out.eta_wf_hat_ned[:] = (c * wx - s * wy, s * wx + c * wy, v[w0 + 2])

    def _write_innovation(self, eps_p: np.ndarray) -> None:
        """Innovation (vessel-parallel) → NED in the output."""
        c = math.cos(self._psi_frame)
        s = math.sin(self._psi_frame)
        e0, e1, e2 = eps_p.tolist()
        self.output.innovation[:] = (c * e0 - s * e1, s * e0 + c * e1, e2)

    def _frame_state(self) -> dict[str, Any]:
        return {"version": STATE_DICT_VERSION, "kind": self.kind, "n_states": self.index.n,
                "sample_time_s": self.dt_s, "initialized": self._initialized,
                "psi_frame_rad": self._psi_frame,
                "bias_mean": [*self._bias_mean, *self._bias_mean_span_s, self._since_reset_s, *self._bias_gap_s]}

    def _check_state(self, state: dict[str, Any]) -> None:
        if not isinstance(state, dict):
            raise ValueError("wave filter state must be a mapping")
        for key, expected in (("version", STATE_DICT_VERSION), ("kind", self.kind), ("n_states", self.index.n)):
            if state.get(key) != expected:
                raise ValueError(f"wave filter state: {key} is {state.get(key)!r}, expected {expected!r}")
        if not math.isclose(float(state.get("sample_time_s", -1.0)), self.dt_s, rel_tol=1e-9):
            raise ValueError(f"wave filter state: sample_time_s {state.get('sample_time_s')!r} != {self.dt_s}")
        psi = float(state.get("psi_frame_rad", math.nan))
        if not math.isfinite(psi):
            raise ValueError("wave filter state: psi_frame_rad must be finite")
        if state.get("bias_mean") is not None:
            mean = finite_array(state["bias_mean"], (8,), "bias_mean")
            if np.any(mean[3:] < 0.0):
                raise ValueError("wave filter state: bias_mean's times must be >= 0")

    def _load_bias_mean(self, state: dict[str, Any]) -> None:
        """The bias mean of :meth:`_dead_reckoning_bias` from a state (checked by :meth:`_check_state`); a state
        saved before it existed restarts it."""
        self._restart_bias_mean()
        if state.get("bias_mean") is not None:
            values = [float(v) for v in state["bias_mean"]]
            self._bias_mean = values[0:3]
            self._bias_mean_span_s = values[3:5]
            self._since_reset_s = values[5]
            self._bias_gap_s = values[6:8]


def finite_array(value: Any, shape: tuple[int, ...], what: str) -> np.ndarray:
    try:
        array = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"wave filter state: {what} is not numeric") from None
    if array.shape != shape or not np.all(np.isfinite(array)):
        raise ValueError(f"wave filter state: {what} must be finite with shape {shape}")
    return array


class BankWaveFilter(FrameFilter):
    """A bank of N steady-state Kalman filters run as one batched computation.

    ``kind="mmae"``: N models at the grid ``omegas_rad_s`` blended by the weights of
    :mod:`~dpcontrol.estimation.weighting` (seed 000 eqs. (16)–(18), seed 001 eqs. (40)–(42));
    ``kind="kf"``: one model at the fixed ω0; ``kind="raw"``: one model without wave states.

    Every per-model quantity is stacked — Φ (N, n, n), gains (4 patterns, N, n, 3) — in preallocated arrays,
    and one step is four compiled kernels over the whole bank (:mod:`~dpcontrol.estimation.kernels`:
    correction, band likelihood, Bayes weights, blend + prediction): about 20 µs for 8 models × 15 states
    where the same arithmetic as ~50 batched numpy calls cost ~140 µs (``benchmarks/bench_estimation.py``).
    """

    def __init__(self, config: WaveFilterConfig) -> None:
        kind = config.kind
        if kind not in ("mmae", "kf", "raw") or (kind == "kf" and config.time_varying):
            raise ValueError(f"BankWaveFilter runs kinds mmae, kf (steady-state) and raw, not {kind!r}")
        self.kind = kind
        omegas: tuple[float | None, ...] = config.omegas_rad_s if kind != "raw" else (None,)
        R = config.measurement_covariance()
        models, discrete, gains = _bank_design(config, omegas, R)
        super().__init__(config, models[0].index)
        self.models = models
        N = len(models)
        n = self.index.n
        self.H = models[0].H
        self.Phi = np.stack([d.Phi for d in discrete])                      # (N, n, n)
        self.Gamma = discrete[0].Gamma                                      # same for every model
        codes = _USED_PATTERNS
        self._code_slot = {code: i for i, code in enumerate(codes)}
        self.K = np.stack([np.stack([g[code].K for g in gains]) for code in codes])           # (4, N, n, 3)
        self.P_post_diag = np.stack([np.stack([np.diag(g[code].P_post) for g in gains]) for code in codes])
        self.S_prior = np.stack([g[_FULL].S for g in gains])                                  # (N, 3, 3)
        self.steady_state = gains
        self.omegas = np.array([w for w in omegas if w is not None], dtype=float)
        # Error-measure weights per pattern: common fixed normalising covariance (minimum energy,
        # rotation-invariant diag(s_pos, s_pos, s_psi)) or each filter's own S_i (seed 000).
        s_mean = np.mean([np.diag(g[_FULL].S) for g in gains], axis=0)
        s_common = np.array([0.5 * (s_mean[0] + s_mean[1])] * 2 + [s_mean[2]])
        self._half_w_common = np.stack([-0.5 * PATTERN_MASKS[code] / s_common for code in codes])  # (4, 3)
        self._half_S_inv_own = np.stack([np.stack([-0.5 * g[code].S_inv for g in gains]) for code in codes])
        self._log_beta_own = np.stack([np.array([-0.5 * g[code].log_det_S for g in gains]) for code in codes])
        self.common_scale = s_common
        self._common = config.likelihood_scale == "common"
        self.band_likelihood: BandLikelihood | None = None
        if kind == "mmae" and config.likelihood_scale == "band":
            wf_std = config.wf_std()
            half_length = 0.5 * config.length_scale_m
            self.band_likelihood = BandLikelihood(
                N, sample_time_s=config.sample_time_s, band_rad_s=config.likelihood_band(),
                scale_time_s=config.likelihood_scale_time_s(), lf_excess_limit=config.lf_excess_limit,
                length_m=config.length_scale_m, noise_var=np.diag(R),
                prior_wf_energy=(2.0 * wf_std[0] ** 2, (half_length * wf_std[2]) ** 2),
                share_time_s=config.forgetting_time_s if math.isfinite(config.forgetting_time_s) else 400.0)
        self._residual = np.zeros(3)          # Σ p_i (ξ2_i + ε_i): y − η̂_LF for the band likelihood's WF share
        self._bayes = config.weighting == "bayes"
        self._forgetting = (1.0 if math.isinf(config.forgetting_time_s)
                            else math.exp(-config.sample_time_s / config.forgetting_time_s))
        self._log_floor = math.log(config.weight_floor) if config.weight_floor > 0.0 else -math.inf
        # Preallocated state and work arrays (C-contiguous: the kernels' signatures).
        self.x = np.zeros((N, n))
        self.p = np.full(N, 1.0 / N)
        self._log_w = np.zeros(N)
        self._x_hat = np.zeros(n)
        self._x_post = np.zeros((N, n))
        self._eps = np.zeros((N, 3))
        self._eps2 = np.zeros((N, 3))
        self._log_l = np.zeros(N)
        self._work = np.zeros(N)
        self._heading = self.index.eta.start + 2
        # The vectors that turn with the frame are whole 3-blocks ([ξ1, ξ2,] ηp, bp) stored contiguously
        # from _rot_start: the kernel rotates the (x, y) components of _rot_blocks of them.
        idx = self.index
        self._rot_start = 0 if (config.wf_frame == "earth" and idx.has_waves) else idx.eta.start
        self._rot_blocks = (idx.bias.stop - self._rot_start) // 3
        self._wf0_k = NO_INDEX if self._wf0 is None else self._wf0
        self._H = np.ascontiguousarray(self.H, dtype=float)
        self._Phi = np.ascontiguousarray(self.Phi, dtype=float)
        self._Gamma = np.ascontiguousarray(self.Gamma, dtype=float)
        self._K_slots = [np.ascontiguousarray(self.K[i]) for i in range(len(codes))]          # (N, n, 3) per pattern
        # Start-up learning of the bias (WaveFilterConfig.bias_learning_time): the gains of the design with Q3 ×
        # bias_learning_factor for T_learn after a reset. Only the gains change: the weights' likelihood, the
        # predicted measurement's variance and the reported covariance stay the bank's own (the learning design's
        # position and heading innovation variances differ from them by little: the bias is not measured).
        self._learning_time_s = config.bias_learning_time()
        self._learning_left_s = 0.0
        self._K_learning: list[np.ndarray] = []
        if self._learning_time_s > 0.0:
            _, _, learning = _bank_design(config, omegas, R, config.bias_learning_factor)
            self._K_learning = [np.ascontiguousarray(np.stack([g[code].K for g in learning])) for code in codes]
        self._P_post_diag_slots = [np.ascontiguousarray(self.P_post_diag[i]) for i in range(len(codes))]
        self._S9 = np.ascontiguousarray(self.S_prior.reshape(N, 9))
        self._omegas_k = np.zeros(N)                  # Σ p_i ω_i in the kernel (zeros for raw: unused)
        self._omegas_k[: self.omegas.size] = self.omegas
        self._pm_mean_ned = np.zeros(3)
        self._pm_var_ned = np.zeros(3)
        self._band_weights = self.band_likelihood is not None
        out = self.output
        out.omegas_rad_s = tuple(float(w) for w in self.omegas)
        out.weights = self.p if kind == "mmae" else None
        out.omega_hat_rad_s = float(self.omegas[0]) if kind == "kf" else None

    # -- protocol ---------------------------------------------------------------------------
    def reset(self, y_ned: np.ndarray) -> None:
        y = self._check_reset(y_ned)
        self._psi_frame = ssa(y[2])
        c, s = math.cos(self._psi_frame), math.sin(self._psi_frame)
        self.x[:] = 0.0
        e0 = self.index.eta.start
        self.x[:, e0] = c * y[0] + s * y[1]
        self.x[:, e0 + 1] = -s * y[0] + c * y[1]
        self.x[:, e0 + 2] = self._psi_frame
        if not self._initialized:
            self.p[:] = 1.0 / self.p.size
            self._log_w[:] = 0.0
        if self.band_likelihood is not None:
            self.band_likelihood.restart()   # the pose jump is no sea-state evidence
        self._initialized = True
        self._restart_bias_mean()
        self._learning_left_s = self._learning_time_s   # the bias starts at zero: learn it
        self._blend_and_write(PATTERN_NONE)
        self.output.innovation[:] = 0.0
        self.output.measured = (False, False, False)

    def predicted_measurement(self) -> tuple[np.ndarray, np.ndarray]:
        """The bank's predicted measurement and its variance, in NED (seed 000 eq. (16) for the mean).

        With the models' predictions ŷ_i (vessel-parallel), their weighted mean m = Σ p_i ŷ_i and
        spread C = Σ p_i (ŷ_i − m)(ŷ_i − m)ᵀ, and S̄ = Σ p_i S_i, the mixture's innovation covariance is
        S̄ + C; in NED its diagonal is diag(R (S̄ + C) Rᵀ) — R rotates the north/east block only
        (:func:`~dpcontrol.estimation.kernels.bank_predicted_measurement`). The two arrays returned are
        reused by the next call.
        """
        if not self._initialized:
            raise RuntimeError("wave filter not initialised: call reset(y_ned) on the first fix")
        psi = self._psi_frame
        bank_predicted_measurement(self.x, self._H, self.p, self._S9, math.cos(psi), math.sin(psi),
                                   self._pm_mean_ned, self._pm_var_ned)
        return self._pm_mean_ned, self._pm_var_ned

    def step(self, y_ned: np.ndarray | None, tau_b: np.ndarray,
             measured: tuple[bool, bool, bool] = (True, True, True)) -> WaveFilterOutput:
        code = self._read_inputs(y_ned, tau_b, measured)
        slot = self._code_slot[code]
        gains = self._K_slots
        if self._learning_left_s > 0.0:  # the start-up learning's gains (see __init__)
            self._learning_left_s = max(0.0, self._learning_left_s - self.dt_s)
            gains = self._K_learning
        # 1.–2. frame heading (the measured heading, else the predicted total heading) and correction with
        # the pattern's steady-state gains, x̂ = x̄ + K ε (seed 002 eq. (51))
        self._psi_frame = bank_correct(code, self._y, self._psi_frame, self._heading, self._wf0_k, self._rot_start,
                                       self._rot_blocks, 1 if self._band_weights else 0, self.x, self._H,
                                       gains[slot], self.p, self._x_post, self._eps, self._residual)
        if code != PATTERN_NONE and self.kind == "mmae":
            self._update_weights(slot, code)
        self._dead_reckoning_bias(self._x_post, self.p, code)
        self._write_outputs(code)
        # 3. prediction (seed 002 eq. (52)) with the delivered force: x̄ = Φ x̂ + Γ τ
        bank_predict(self._x_post, self._Phi, self._Gamma, self._tau, self.x)
        return self.output

    def set_frame_heading(self, psi_rad: float) -> None:
        """Move the vessel-parallel frame to ψ_f = ψ: vectors ← Rᵀ(Δψ)·v (seed 001 ψ̇S terms).

        The NED estimate is unchanged. (:meth:`step` does this inside its kernel.)
        """
        dpsi = ssa(psi_rad - self._psi_frame)
        if dpsi != 0.0:
            self._rotate_states(self.x, dpsi)
        self._psi_frame = psi_rad

    def model_lf_poses_ned(self) -> np.ndarray:
        """LF pose estimate of every model after the last correction, (N, 3) NED [m, m, rad].

        Each row is what that model's steady-state filter alone would output (the filters of the bank
        do not depend on the weights); for diagnostics and monitoring.
        """
        c, s = math.cos(self._psi_frame), math.sin(self._psi_frame)
        e0 = self.index.eta.start
        xp = self._x_post[:, e0]
        yp = self._x_post[:, e0 + 1]
        return np.stack([c * xp - s * yp, s * xp + c * yp, ssa_array(self._x_post[:, e0 + 2])], axis=1)

    def _update_weights(self, slot: int, code: int) -> None:
        """Error measures m_i and the weight update (discrete Bayes or seed 000 eq. (18) DWSG)."""
        eps = self._eps
        band = self.band_likelihood
        forgetting = self._forgetting
        log_l = self._log_l
        if band is not None:
            # band-limited, locally whitened, tempered (weighting.BandLikelihood); the memory runs on
            # evidence time: a gated (invalid) period neither adds evidence nor forgets the old.
            # The residual y − η̂_LF (blended prior) = Σ p_i (ε_i + ξ2_i), the WF motion + noise for the WF
            # share, came from bank_correct.
            if not band.update(eps, (code & _POSITION) == _POSITION, bool(code & PATTERN_HEADING), self._residual):
                return
            log_l = band.log_l
            forgetting = forgetting ** band.gate_max
        elif self._common:
            # log L_i = −½ εᵢᵀ S̄⁻¹ εᵢ with the common diagonal S̄ (minimum-energy criterion).
            np.multiply(eps, eps, out=self._eps2)
            np.matmul(self._eps2, self._half_w_common[slot], out=self._log_l)
        else:
            # log L_i = −½ ln det S_i − ½ εᵢᵀ S_i⁻¹ εᵢ (seed 000: β_i e^{−m_i}).
            np.einsum("ni,nij,nj->n", eps, self._half_S_inv_own[slot], eps, out=self._log_l)
            self._log_l += self._log_beta_own[slot]
        if self._bayes:
            bayes_step(self._log_w, self.p, log_l, forgetting, self._log_floor)
        else:
            config = self.config
            dwsg_step(self.p, log_l, rate_per_s=config.dwsg_rate_per_s, dt_s=self.dt_s,
                      floor=config.weight_floor, work=self._work)

    def _blend_and_write(self, code: int) -> None:
        """Outputs for the current (prior) state, as after reset or a restore (no innovation)."""
        np.copyto(self._x_post, self.x)
        self._eps[...] = 0.0
        self._write_outputs(code)

    def _write_outputs(self, code: int) -> None:
        """Outputs from the blend of ``_x_post`` (seed 000 eq. (16)) and the mixture covariance
        (:func:`~dpcontrol.estimation.kernels.bank_outputs`)."""
        out = self.output
        omega_hat = bank_outputs(self._x_post, self._eps, self.p, self._P_post_diag_slots[self._code_slot[code]],
                                 self._psi_frame, self._eta0, self._wf0_k, self._lf_slice.start, self._omegas_k,
                                 self._x_hat, out.eta_hat_ned, self._lf_tail, out.eta_wf_hat_ned, out.covariance_diag,
                                 out.innovation)
        out.measured = PATTERN_MEASURED[code]
        if self.kind == "mmae":
            out.omega_hat_rad_s = omega_hat

    # -- persistence --------------------------------------------------------------------------
    def state_dict(self) -> dict[str, Any]:
        state = self._frame_state()
        state.update({"omegas_rad_s": [float(w) for w in self.omegas], "x": self.x.tolist(),
                      "weights": self.p.tolist(), "log_weights": self._log_w.tolist(),
                      "bias_learning_left_s": self._learning_left_s})
        if self.band_likelihood is not None:
            state["likelihood"] = self.band_likelihood.state_dict()
        return state

    def load_state_dict(self, state: dict[str, Any]) -> None:
        self._check_state(state)
        omegas = finite_array(state.get("omegas_rad_s"), self.omegas.shape, "omegas_rad_s")
        if not np.allclose(omegas, self.omegas, rtol=1e-12, atol=0.0):
            raise ValueError("wave filter state: omegas_rad_s differ from the configured bank")
        x = finite_array(state.get("x"), self.x.shape, "x")
        p = finite_array(state.get("weights"), self.p.shape, "weights")
        if np.any(p < 0.0) or not math.isclose(float(p.sum()), 1.0, rel_tol=1e-6):
            raise ValueError("wave filter state: weights must be >= 0 and sum to 1")
        log_w = None
        if state.get("log_weights") is not None:
            log_w = finite_array(state.get("log_weights"), self.p.shape, "log_weights")
            implied = np.exp(log_w - log_w.max())
            if not np.allclose(implied / implied.sum(), p / p.sum(), rtol=1e-6, atol=1e-12):
                raise ValueError("wave filter state: log_weights do not match weights")
        learning_left = float(state.get("bias_learning_left_s", 0.0))
        if not math.isfinite(learning_left) or learning_left < 0.0:
            raise ValueError("wave filter state: bias_learning_left_s must be finite and >= 0")
        band = self.band_likelihood
        if band is not None and state.get("likelihood") is not None:
            band.load_state_dict(state["likelihood"])      # ValueError before anything changed
        elif band is not None:
            band.restart()   # an older state: statistics rebuild while the restored weights hold
        self.x[:] = x
        # weights saved by a running bank sum to 1 within rounding: keep them bit for bit (a restart is
        # then exactly the run that did not stop); renormalise only what was not normalised
        total = float(p.sum())
        self.p[:] = p if abs(total - 1.0) <= 1e-12 else p / total
        if log_w is None:
            log_w = np.log(np.maximum(self.p, 1e-300))
            log_w = np.maximum(log_w - log_w.max(), self._log_floor)
        self._log_w[:] = log_w
        self._psi_frame = float(state["psi_frame_rad"])
        self._initialized = bool(state.get("initialized", True))
        self._load_bias_mean(state)
        # (a state saved before the start-up learning existed, or by a bank without it, has learnt: 0)
        self._learning_left_s = min(learning_left, self._learning_time_s)
        self._blend_and_write(PATTERN_NONE)


class TimeVaryingWaveFilter(FrameFilter):
    """One time-varying Joseph-form Kalman filter at a fixed ω0 (``kind="kf"``, ``time_varying=True``).

    Seed 002 eqs. (51)–(54) with the covariance propagated every step; the covariance is rotated with
    the states on a frame change (``P ← T P Tᵀ``).
    """

    kind = "kf"

    def __init__(self, config: WaveFilterConfig) -> None:
        if config.kind != "kf":
            raise ValueError(f"TimeVaryingWaveFilter runs kind kf, not {config.kind!r}")
        omega = config.omegas_rad_s[0]
        model = build_design_model(config, omega)
        super().__init__(config, model.index)
        self.model = model
        self.discrete = discretize(model.A, model.B, model.E, model.Qc, config.sample_time_s)
        self.R = config.measurement_covariance()
        gains = pattern_gains(self.discrete.Phi, model.H, self.discrete.Qd, self.R)
        self._P0 = gains[_FULL].P_prior.copy()
        self.filter = KalmanFilter(self.discrete.Phi, self.discrete.Gamma, model.H, self.discrete.Qd, self.R,
                                   x0=np.zeros(model.n), P0=self._P0)
        self._heading = model.index.eta.start + 2
        self.output.omegas_rad_s = (float(omega),)
        self.output.omega_hat_rad_s = float(omega)

    def reset(self, y_ned: np.ndarray) -> None:
        y = self._check_reset(y_ned)
        self._psi_frame = ssa(y[2])
        c, s = math.cos(self._psi_frame), math.sin(self._psi_frame)
        x = np.zeros(self.index.n)
        e0 = self.index.eta.start
        x[e0] = c * y[0] + s * y[1]
        x[e0 + 1] = -s * y[0] + c * y[1]
        x[e0 + 2] = self._psi_frame
        self.filter.x = x
        self.filter.P = self._P0.copy()
        self._initialized = True
        self._restart_bias_mean()
        self._write(np.zeros(3), PATTERN_NONE)

    def predicted_measurement(self) -> tuple[np.ndarray, np.ndarray]:
        if not self._initialized:
            raise RuntimeError("wave filter not initialised: call reset(y_ned) on the first fix")
        c, s = math.cos(self._psi_frame), math.sin(self._psi_frame)
        rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        yhat = rot @ (self.filter.H @ self.filter.x)
        yhat[2] = ssa(float(yhat[2]))
        return yhat, np.diag(rot @ self.filter.innovation_covariance() @ rot.T).copy()

    def step(self, y_ned: np.ndarray | None, tau_b: np.ndarray,
             measured: tuple[bool, bool, bool] = (True, True, True)) -> WaveFilterOutput:
        code = self._read_inputs(y_ned, tau_b, measured)
        kf = self.filter
        psi_new = ssa(self._y[2]) if code & PATTERN_HEADING else ssa(float(kf.H[2] @ kf.x))
        self.set_frame_heading(psi_new)
        eps_full = np.zeros(3)
        if code != PATTERN_NONE:
            self._to_vessel_parallel(code)
            rows = np.flatnonzero(PATTERN_MASKS[code])
            eps_full = self._yp - kf.H @ kf.x
            eps_full[2] = ssa(float(eps_full[2]))
            eps_full *= PATTERN_MASKS[code]
            kf.correct(eps_full[rows], rows)
        turns = round(float(kf.x[self._heading]) / (2.0 * math.pi))
        if turns:
            kf.x[self._heading] -= turns * 2.0 * math.pi
        self._dead_reckoning_bias(kf.x, None, code)
        self._write(eps_full, code)
        kf.predict(self._tau)
        return self.output

    def set_frame_heading(self, psi_rad: float) -> None:
        """Move the vessel-parallel frame to ψ: x ← T x, P ← T P Tᵀ (NED estimate unchanged)."""
        dpsi = ssa(psi_rad - self._psi_frame)
        if dpsi != 0.0:
            T = self._rotation_matrix(dpsi)
            self.filter.x = T @ self.filter.x
            self.filter.P = T @ self.filter.P @ T.T
        self._psi_frame = psi_rad

    def _write(self, eps_p: np.ndarray, code: int) -> None:
        self._write_pose(self.filter.x)
        self.output.covariance_diag[:] = np.diag(self.filter.P)
        self._write_innovation(eps_p)
        self.output.measured = PATTERN_MEASURED[code]

    def state_dict(self) -> dict[str, Any]:
        state = self._frame_state()
        state.update({"x": self.filter.x.tolist(), "P": self.filter.P.tolist()})
        return state

    def load_state_dict(self, state: dict[str, Any]) -> None:
        self._check_state(state)
        n = self.index.n
        x = finite_array(state.get("x"), (n,), "x")
        P = finite_array(state.get("P"), (n, n), "P")
        if not is_covariance(P):
            raise ValueError("wave filter state: P must be symmetric positive semidefinite")
        self.filter.x = x
        self.filter.P = 0.5 * (P + P.T)
        self._psi_frame = float(state["psi_frame_rad"])
        self._initialized = bool(state.get("initialized", True))
        self._load_bias_mean(state)
        self._write(np.zeros(3), PATTERN_NONE)
