"""Course-keeping (heading autopilot) Kalman filter, seed 002 eqs. (69)–(81).

Model for the wave filter of a heading autopilot, state ``x = [ξ_w, ψ_w, ψ, r, b]`` (seed 002 eq. (77))::

    ξ̇_w = ψ_w                                   (69)
    ψ̇_w = −ω0² ξ_w − 2ζω0 ψ_w + w1               (70)   2nd-order WF yaw
    ψ̇   = r                                     (71)
    ṙ   = −r/T + (K/T) δ + b + w2               (72)   first-order Nomoto, τ_N = m(K/T)δ (63)
    ḃ   = w3                                    (73)
    y   = ψ + ψ_w + v                           (74)

i.e. ``A`` and ``E`` of eqs. (80)–(81) and ``hᵀ = [0, 1, 1, 0, 0]``; the input is the rudder angle δ
[rad] (the ``b = [0, 0, 0, 1/m, 0]ᵀ`` of eq. (80) times τ_N = m(K/T)δ). The bias b [rad/s²] takes the
rudder offset and the slowly varying environmental moment. Discretised exactly (Van Loan) at the
period h and run as a Joseph-form Kalman filter (:class:`~dpcontrol.estimation.kalman.KalmanFilter`);
the heading innovation is wrapped with ``ssa``.

Mariner case (seed 002, "Example Kalman Filter Design for Course-Keeping Autopilot"): K = 0.185 1/s,
T = 107.3 s, h = 0.5 s, σ_compass = 0.5°, ζ = 0.1, ω0 = 1.2 rad/s, σ_w1 = √300. Units assumed for the
last one: the paper prints "rad/s", but read literally as a noise intensity in rad²/s³ the WF yaw of
eq. (70) would have a standard deviation of √(300/(4ζω0)) = 25 *rad*. It is read here in degrees:
``σ_w1² = 300 deg²/s³`` → 0.0914 rad²/s³, a WF yaw of 25° standard deviation (a large wave-induced yaw,
as in the paper's rough-weather illustration). The paper gives no intensities for w2 and w3; the
defaults are documented on :func:`mariner_heading_filter`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from dpbase.frames import ssa
from dpcontrol.estimation.discretize import discretize
from dpcontrol.estimation.kalman import KalmanFilter, steady_state_filter

MARINER_K_PER_S = 0.185
MARINER_T_S = 107.3
MARINER_SAMPLE_TIME_S = 0.5
MARINER_COMPASS_STD_RAD = math.radians(0.5)
MARINER_ZETA = 0.1
MARINER_OMEGA0_RAD_S = 1.2
#: σ_w1² = 300 deg²/s³ converted to rad²/s³ (see the module docstring).
MARINER_WAVE_INTENSITY = 300.0 * (math.pi / 180.0) ** 2


@dataclass(frozen=True, eq=False)
class HeadingModel:
    """Continuous heading model of seed 002 eqs. (75)–(81).

    Attributes
    ----------
    A : ndarray, shape (5, 5)
    B : ndarray, shape (5, 1)
        Rudder input (K/T in the r row).
    E : ndarray, shape (5, 3)
    H : ndarray, shape (1, 5)
    Qc : ndarray, shape (3, 3)
        Intensities of w1 [rad²/s³], w2 [rad²/s³], w3 [rad²/s⁵].
    R : ndarray, shape (1, 1)
        Compass variance per sample [rad²].
    """

    A: np.ndarray
    B: np.ndarray
    E: np.ndarray
    H: np.ndarray
    Qc: np.ndarray
    R: np.ndarray


def heading_model(*, gain_per_s: float, time_constant_s: float, omega0_rad_s: float, zeta: float,
                  wave_intensity: float, yaw_accel_intensity: float, bias_intensity: float,
                  compass_std_rad: float) -> HeadingModel:
    """Build A, B, E, H (seed 002 eqs. (80)–(81)) and the noise matrices."""
    if not (gain_per_s > 0.0 and time_constant_s > 0.0 and omega0_rad_s > 0.0 and zeta > 0.0
            and compass_std_rad > 0.0):
        raise ValueError("heading model needs K, T, ω0, ζ and the compass std > 0")
    if min(wave_intensity, yaw_accel_intensity, bias_intensity) < 0.0:
        raise ValueError("noise intensities must be >= 0")
    A = np.zeros((5, 5))
    A[0, 1] = 1.0
    A[1, 0] = -(omega0_rad_s**2)
    A[1, 1] = -2.0 * zeta * omega0_rad_s
    A[2, 3] = 1.0
    A[3, 3] = -1.0 / time_constant_s
    A[3, 4] = 1.0
    B = np.zeros((5, 1))
    B[3, 0] = gain_per_s / time_constant_s
    E = np.zeros((5, 3))
    E[1, 0] = 1.0
    E[3, 1] = 1.0
    E[4, 2] = 1.0
    H = np.array([[0.0, 1.0, 1.0, 0.0, 0.0]])
    Qc = np.diag([wave_intensity, yaw_accel_intensity, bias_intensity])
    return HeadingModel(A=A, B=B, E=E, H=H, Qc=Qc, R=np.array([[compass_std_rad**2]]))


@dataclass
class HeadingEstimate:
    """Output of :meth:`HeadingKalmanFilter.step`.

    Attributes
    ----------
    psi_hat_rad : float
        LF heading ψ̂, wrapped with ssa [rad].
    r_hat_radps : float
        LF yaw rate [rad/s].
    psi_wf_hat_rad : float
        WF heading ψ̂_w [rad].
    bias_hat_radps2 : float
        Bias b̂ [rad/s²].
    variance_psi_rad2 : float
        Error variance of ψ̂ [rad²].
    """

    psi_hat_rad: float
    r_hat_radps: float
    psi_wf_hat_rad: float
    bias_hat_radps2: float
    variance_psi_rad2: float


class HeadingKalmanFilter:
    """Wave-filtering heading observer of seed 002 eqs. (69)–(81), Joseph-form time-varying KF.

    Parameters
    ----------
    model : HeadingModel
    sample_time_s : float
        h [s].
    psi0_rad : float
        Initial heading (from the first compass sample) [rad].
    """

    def __init__(self, model: HeadingModel, sample_time_s: float, psi0_rad: float = 0.0) -> None:
        self.model = model
        d = discretize(model.A, model.B, model.E, model.Qc, sample_time_s)
        self.discrete = d
        self.steady = steady_state_filter(d.Phi, model.H, d.Qd, model.R)
        x0 = np.zeros(5)
        x0[2] = ssa(psi0_rad)
        self.filter = KalmanFilter(d.Phi, d.Gamma, model.H, d.Qd, model.R, x0=x0, P0=self.steady.P_prior)

    def step(self, psi_measured_rad: float | None, rudder_rad: float) -> HeadingEstimate:
        """Correct with the compass sample (None or non-finite: predict only), then predict with δ."""
        if not math.isfinite(rudder_rad):
            raise ValueError(f"rudder angle must be finite, got {rudder_rad!r}")
        kf = self.filter
        if psi_measured_rad is not None and math.isfinite(psi_measured_rad):
            innovation = ssa(psi_measured_rad - float(kf.H[0] @ kf.x))
            kf.correct(np.array([innovation]))
        x = kf.x
        estimate = HeadingEstimate(psi_hat_rad=ssa(float(x[2])), r_hat_radps=float(x[3]),
                                   psi_wf_hat_rad=float(x[1]), bias_hat_radps2=float(x[4]),
                                   variance_psi_rad2=float(kf.P[2, 2]))
        turns = round(float(x[2]) / (2.0 * math.pi))
        if turns:
            kf.x = x.copy()
            kf.x[2] -= turns * 2.0 * math.pi
        kf.predict(np.array([rudder_rad]))
        return estimate


def mariner_heading_filter(*, yaw_accel_intensity: float = 2.0 * (math.radians(0.05)) ** 2 / MARINER_T_S,
                           bias_intensity: float = (MARINER_K_PER_S / MARINER_T_S * math.radians(1.0)) ** 2 / 600.0,
                           psi0_rad: float = 0.0) -> HeadingKalmanFilter:
    """The seed 002 mariner course-keeping filter (K = 0.185 1/s, T = 107.3 s, h = 0.5 s, …).

    Defaults for the noises the paper leaves open: w2 such that alone it would make the yaw rate
    wander with 0.05°/s standard deviation (``q2 = 2σ_r²/T``); w3 such that the bias can drift by the
    effect of a 1° rudder offset (K/T·1°) in 600 s.
    """
    model = heading_model(gain_per_s=MARINER_K_PER_S, time_constant_s=MARINER_T_S,
                          omega0_rad_s=MARINER_OMEGA0_RAD_S, zeta=MARINER_ZETA,
                          wave_intensity=MARINER_WAVE_INTENSITY, yaw_accel_intensity=yaw_accel_intensity,
                          bias_intensity=bias_intensity, compass_std_rad=MARINER_COMPASS_STD_RAD)
    return HeadingKalmanFilter(model, MARINER_SAMPLE_TIME_S, psi0_rad)
