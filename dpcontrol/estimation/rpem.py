"""RPEM adaptive-frequency Kalman filter (seed 003 eqs. (10)–(14)): one filter that tracks ω0.

The alternative to the MMAE bank: a time-varying Kalman filter on the design model at the current
estimate ω̂0 (Joseph form, :class:`~dpcontrol.estimation.kalman.KalmanFilter` equations), plus the
recursive prediction-error method (Ljung 1987) on the innovations ε = y − H x̄::

    ω̂0[k] = ω̂0[k−1] + P[k−1] ψᵀ W ε / (λ + P[k−1] ψᵀ W ψ)                 seed 003 eq. (11)
    P[k]   = (P[k−1] − P[k−1]² ψᵀ W ψ / (λ + P[k−1] ψᵀ W ψ)) / λ
    ψ[k]   = −∂ε/∂ω0 = H ∂x̄[k]/∂ω0                                        seed 003 eqs. (12), (14)
    ∂x̄[k+1]/∂ω0 = Φ̂ (I − K H) ∂x̄[k]/∂ω0 + (∂Φ̂/∂ω0) x̂[k]                seed 003 eq. (13)

(∂K/∂ω0 neglected, as in the paper). Seed 003 treats one degree of freedom; here ε and ψ have the
three channels and ``W = diag(1/Λ̂)`` normalises them by a running estimate Λ̂ of the innovation
variances (Ljung's multi-output RPEM), so no channel dominates by its units.

∂Φ/∂ω0 is exact: the Fréchet derivative of the matrix exponential (the block-triangular exponential
``exp([[A, ∂A], [0, A]]h)``, :func:`~dpcontrol.estimation.discretize.transition_derivative`), here in
the closed form of :func:`~dpcontrol.estimation.discretize.oscillator_discretization` (the tests
check one against the other): only the WF block of Φ and Qd depends on ω0 and the three degrees of
freedom share ω0 and ζ, so one 2×2 block is re-discretised whenever ω̂0 moves. ω̂0 is projected
onto ``[rpem_omega_min_rad_s, rpem_omega_max_rad_s]``; the adaptation starts after a warm-up of two
periods of the initial ω0, when the sensitivity has built up.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from dpbase.frames import ssa
from dpcontrol.estimation.discretize import discretize, oscillator_discretization
from dpcontrol.estimation.filter_config import WaveFilterConfig
from dpcontrol.estimation.kalman import KalmanFilter, is_covariance, solve_prior_covariance
from dpcontrol.estimation.wave_filter import (
    PATTERN_HEADING,
    PATTERN_MASKS,
    PATTERN_MEASURED,
    PATTERN_NONE,
    FrameFilter,
    WaveFilterOutput,
    build_design_model,
    finite_array,
)

_MIN_VARIANCE = 1e-300


class RpemWaveFilter(FrameFilter):
    """Adaptive wave filter with RPEM peak-frequency tracking (``kind="rpem"``), seed 003.

    Exposes ``omega_hat_rad_s`` (the current ω̂0) besides the common :class:`WaveFilterOutput`.
    """

    kind = "rpem"

    def __init__(self, config: WaveFilterConfig) -> None:
        if config.kind != "rpem":
            raise ValueError(f"RpemWaveFilter runs kind rpem, not {config.kind!r}")
        self.omega0 = float(config.omegas_rad_s[0])
        model = build_design_model(config, self.omega0)
        super().__init__(config, model.index)
        self.model = model
        self.R = config.measurement_covariance()
        discrete = discretize(model.A, model.B, model.E, model.Qc, config.sample_time_s)
        self._P0 = solve_prior_covariance(discrete.Phi, model.H, discrete.Qd, self.R)
        self.filter = KalmanFilter(discrete.Phi, discrete.Gamma, model.H, discrete.Qd, self.R,
                                   x0=np.zeros(model.n), P0=self._P0)
        # _set_omega rewrites the WF blocks of the filter's own Φ and Qd in place.
        self._Phi = self.filter.Phi
        self._Qd = self.filter.Qd
        self._dPhi = np.zeros_like(self._Phi)
        self._lam = config.rpem_forgetting
        self._omega_min = config.rpem_omega_min_rad_s
        self._omega_max = config.rpem_omega_max_rad_s
        self._warmup_steps = math.ceil(2.0 * (2.0 * math.pi / self.omega0) / config.sample_time_s)
        self._heading = model.index.eta.start + 2
        # (ξ1_j, ξ2_j) block of degree of freedom j in the 15-state vector.
        self._wave_blocks = [np.ix_([j, j + 3], [j, j + 3]) for j in range(3)]
        self.output.omegas_rad_s = (self.omega0,)
        self._init_adaptation()

    def _init_adaptation(self, keep_estimate: bool = False) -> None:
        """Start the RPEM recursion; ``keep_estimate`` keeps ω̂0 and its P (re-initialised pose)."""
        if not keep_estimate:
            self.omega_hat = self.omega0
            initial = self.config.rpem_initial_variance
            self.p_omega = (initial if initial is not None
                            else (0.3 * self.omega0) ** 2 * (1.0 - self._lam))
        self.dx = np.zeros(self.index.n)                 # ∂x̄/∂ω0 (prior)
        self.innovation_variance = np.diag(self.R).copy() + np.diag(self.model.H @ self._P0 @ self.model.H.T)
        self.steps = 0
        self._set_omega(self.omega_hat)

    # -- model at ω̂0 ---------------------------------------------------------------------------
    def _set_omega(self, omega: float) -> None:
        """Φ, ∂Φ/∂ω0 and Qd of the WF block at ω (the LF block is constant)."""
        phi2, dphi2, q2 = oscillator_discretization(omega, self.config.zeta, self.dt_s)
        q1 = self.config.wf_intensity(omega)
        for j in range(3):
            ij = self._wave_blocks[j]
            self._Phi[ij] = phi2
            self._dPhi[ij] = dphi2
            self._Qd[ij] = q1[j] * q2
        self.omega_hat = omega

    # -- protocol ---------------------------------------------------------------------------
    def reset(self, y_ned: np.ndarray) -> None:
        y = self._check_reset(y_ned)
        self._psi_frame = ssa(y[2])
        c, s = math.cos(self._psi_frame), math.sin(self._psi_frame)
        x = np.zeros(self.index.n)
        e0 = self.index.eta.start
        x[e0] = c * y[0] + s * y[1]
        x[e0 + 1] = -s * y[0] + c * y[1]
        x[e0 + 2] = self._psi_frame
        self._init_adaptation(keep_estimate=self._initialized)
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
        H = kf.H
        psi_new = ssa(self._y[2]) if code & PATTERN_HEADING else ssa(float(H[2] @ kf.x))
        self.set_frame_heading(psi_new)
        eps = np.zeros(3)
        if code != PATTERN_NONE:
            self._to_vessel_parallel(code)
            mask = PATTERN_MASKS[code]
            rows = np.flatnonzero(mask)
            eps = self._yp - H @ kf.x
            eps[2] = ssa(float(eps[2]))
            eps *= mask
            self._adapt(eps, H @ self.dx, mask)
            kf.correct(eps[rows], rows)
            # Posterior sensitivity ∂x̂/∂ω0 = (I − K H) ∂x̄/∂ω0 (∂K/∂ω0 neglected, seed 003 eq. (13)).
            self.dx = self.dx - kf.K @ (H[rows] @ self.dx)
        turns = round(float(kf.x[self._heading]) / (2.0 * math.pi))
        if turns:
            kf.x[self._heading] -= turns * 2.0 * math.pi
        self._dead_reckoning_bias(kf.x, None, code)
        self._write(eps, code)
        # Prediction at the (possibly new) ω̂0, and the sensitivity recursion seed 003 eq. (13).
        x_post = kf.x
        kf.predict(self._tau)
        self.dx = self._Phi @ self.dx + self._dPhi @ x_post
        self.steps += 1
        return self.output

    def set_frame_heading(self, psi_rad: float) -> None:
        """Move the vessel-parallel frame to ψ: x, ∂x̄/∂ω0 ← T·(…), P ← T P Tᵀ (NED estimate unchanged)."""
        dpsi = ssa(psi_rad - self._psi_frame)
        if dpsi != 0.0:
            T = self._rotation_matrix(dpsi)
            self.filter.x = T @ self.filter.x
            self.filter.P = T @ self.filter.P @ T.T
            self.dx = T @ self.dx
        self._psi_frame = psi_rad

    def _adapt(self, eps: np.ndarray, psi: np.ndarray, mask: np.ndarray) -> None:
        """Seed 003 eq. (11) with channel weights W = diag(1/Λ̂) and projection onto the range."""
        lam = self._lam
        var = self.innovation_variance
        var += (1.0 - lam) * mask * (eps * eps - var)
        np.maximum(var, _MIN_VARIANCE, out=var)
        if self.steps < self._warmup_steps:
            return
        w = mask / var
        g = float(psi @ (w * psi))
        denom = lam + self.p_omega * g
        omega = self.omega_hat + self.p_omega * float(psi @ (w * eps)) / denom
        self.p_omega = (self.p_omega - self.p_omega**2 * g / denom) / lam
        omega = min(max(omega, self._omega_min), self._omega_max)
        if omega != self.omega_hat:
            self._set_omega(omega)

    def _write(self, eps_p: np.ndarray, code: int) -> None:
        self._write_pose(self.filter.x)
        self.output.covariance_diag[:] = np.diag(self.filter.P)
        self._write_innovation(eps_p)
        self.output.measured = PATTERN_MEASURED[code]
        self.output.omega_hat_rad_s = self.omega_hat

    # -- persistence --------------------------------------------------------------------------
    def state_dict(self) -> dict[str, Any]:
        state = self._frame_state()
        state.update({"x": self.filter.x.tolist(), "P": self.filter.P.tolist(), "omega_hat_rad_s": self.omega_hat,
                      "p_omega": self.p_omega, "dx_domega": self.dx.tolist(),
                      "innovation_variance": self.innovation_variance.tolist(), "steps": self.steps})
        return state

    def load_state_dict(self, state: dict[str, Any]) -> None:
        self._check_state(state)
        n = self.index.n
        x = finite_array(state.get("x"), (n,), "x")
        P = finite_array(state.get("P"), (n, n), "P")
        dx = finite_array(state.get("dx_domega"), (n,), "dx_domega")
        var = finite_array(state.get("innovation_variance"), (3,), "innovation_variance")
        omega = float(finite_array(state.get("omega_hat_rad_s"), (), "omega_hat_rad_s"))
        p_omega = float(finite_array(state.get("p_omega"), (), "p_omega"))
        steps = state.get("steps", 0)
        if not self._omega_min <= omega <= self._omega_max:
            raise ValueError("wave filter state: omega_hat_rad_s outside the RPEM range")
        if p_omega <= 0.0 or np.any(var <= 0.0) or not isinstance(steps, int) or steps < 0:
            raise ValueError("wave filter state: p_omega, innovation_variance must be > 0, steps an int >= 0")
        if not is_covariance(P):
            raise ValueError("wave filter state: P must be symmetric positive semidefinite")
        self._set_omega(omega)
        self.filter.x = x
        self.filter.P = 0.5 * (P + P.T)
        self.dx = dx
        self.innovation_variance = var
        self.p_omega = p_omega
        self.steps = steps
        self._psi_frame = float(state["psi_frame_rad"])
        self._initialized = bool(state.get("initialized", True))
        self._load_bias_mean(state)
        self._write(np.zeros(3), PATTERN_NONE)
