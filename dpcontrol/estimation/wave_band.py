"""How much wave-frequency motion reaches the controller: running wave-band standard deviations.

:class:`WaveBandMeter` band-passes a few signals — the commanded force (surge, sway, yaw) and the LF pose
estimate's north, east and heading — over the wave band and keeps an exponentially weighted mean square of
each, so the status and the record can say, at any time, how large the wave-frequency part of what the
controller commands (and of what it is fed) is: a wave filter doing its job keeps both small (seed 002 Fig. 7:
the thrusters should not work against every wave).

The band-pass is a 2nd-order Butterworth band-pass (``scipy.signal.butter``) over ``[ω_low, ω_high]``: the
configured band until the estimator has a peak frequency ω̂, then ``[ω̂/2, 3ω̂]`` (:meth:`follow_peak`, what the
campaign benchmark measures offline with a Welch PSD around the motion's peak), run as one transposed
direct-form-II biquad on all six signals at once; the mean square has the time constant ``averaging_time_s``
(default ten periods of the lowest band edge).
No clock: one :meth:`update` per control period.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.signal import butter

#: signals metered, in the order of :meth:`WaveBandMeter.update`'s arrays
SIGNALS = ("force_x_n", "force_y_n", "moment_n_nm", "lf_north_m", "lf_east_m", "lf_heading_rad")


class WaveBandMeter:
    """Running wave-band standard deviation of the commanded force and of the LF pose estimate.

    Parameters
    ----------
    sample_time_s : float
        Control period [s].
    band_rad_s : (float, float)
        Wave band [rad/s], below the Nyquist frequency.
    averaging_time_s : float, optional
        Time constant of the mean square [s] (None: ten periods of the lower band edge).
    """

    def __init__(self, sample_time_s: float, band_rad_s: tuple[float, float],
                 averaging_time_s: float | None = None) -> None:
        low, high = float(band_rad_s[0]), float(band_rad_s[1])
        nyquist = math.pi / sample_time_s
        if not (sample_time_s > 0.0 and 0.0 < low < high):
            raise ValueError(f"need a period > 0 and a band 0 < low < high, got {sample_time_s}, {band_rad_s}")
        high = min(high, 0.95 * nyquist)
        if low >= high:
            raise ValueError(f"wave band {band_rad_s} rad/s is not below the Nyquist frequency {nyquist:g} rad/s")
        self._nyquist = nyquist
        self._design(low, high)
        tau = averaging_time_s if averaging_time_s is not None else 10.0 * 2.0 * math.pi / low
        self._alpha = 1.0 - math.exp(-sample_time_s / tau)
        self._z1 = np.zeros(6)
        self._z2 = np.zeros(6)
        self._x = np.zeros(6)
        self._y = np.zeros(6)
        self._mean_square = np.zeros(6)
        self._unwrap_heading: float | None = None
        self.steps = 0

    def _design(self, low: float, high: float) -> None:
        b, a = butter(1, [low / self._nyquist, high / self._nyquist], btype="bandpass")   # 2nd order: one biquad
        self.band_rad_s = (low, high)
        self._b = [float(v) for v in b]
        self._a = [float(v) for v in a]

    def follow_peak(self, omega_rad_s: float | None) -> None:
        """Centre the band on the estimator's peak frequency: ``[ω̂/2, 3ω̂]`` (the campaign's band), redesigned
        only when ω̂ moved by more than 10 % from the band's (the filter state is kept)."""
        if omega_rad_s is None or not math.isfinite(omega_rad_s) or omega_rad_s <= 0.0:
            return
        low = 0.5 * omega_rad_s
        if abs(low / self.band_rad_s[0] - 1.0) <= 0.1:
            return
        high = min(3.0 * omega_rad_s, 0.95 * self._nyquist)
        if low < high:
            self._design(low, high)

    def reset(self) -> None:
        """Forget everything (a new engagement: its transient is no wave motion)."""
        self._z1[:] = 0.0
        self._z2[:] = 0.0
        self._mean_square[:] = 0.0
        self._unwrap_heading = None
        self.steps = 0

    def update(self, tau_b: np.ndarray, eta_hat_ned: np.ndarray) -> None:
        """One period: commanded force [N, N, N·m] and LF pose estimate [m, m, rad] (NED)."""
        x = self._x
        x[0:3] = tau_b
        x[3:5] = eta_hat_ned[0:2]
        psi = float(eta_hat_ned[2])
        if self._unwrap_heading is not None:   # continuous heading: a ±π wrap is no wave
            psi = self._unwrap_heading + math.remainder(psi - self._unwrap_heading, 2.0 * math.pi)
        self._unwrap_heading = psi
        x[5] = psi
        if not np.all(np.isfinite(x)):
            return
        if self.steps == 0:
            # start in the steady state of a constant input (output 0; b0 + b1 + b2 = 0 for a band-pass),
            # not with a step from zero
            self._z2[:] = self._b[2] * x
            self._z1[:] = (self._b[1] + self._b[2]) * x
        b0, b1, b2 = self._b
        _, a1, a2 = self._a
        y = self._y
        np.multiply(x, b0, out=y)
        y += self._z1
        self._z1[:] = b1 * x - a1 * y + self._z2
        self._z2[:] = b2 * x - a2 * y
        self._mean_square += self._alpha * (y * y - self._mean_square)
        self.steps += 1

    @property
    def std(self) -> np.ndarray:
        """Wave-band standard deviation of each signal of :data:`SIGNALS` (new array)."""
        return np.sqrt(self._mean_square)

    def summary(self) -> dict[str, float] | None:
        """``{"force_n", "moment_nm", "lf_position_m", "lf_heading_rad"}``: horizontal force and position
        together (√(σx² + σy²)); None before the first full averaging time."""
        if self.steps * self._alpha < 1.0:
            return None
        ms = self._mean_square
        return {"force_n": math.sqrt(ms[0] + ms[1]), "moment_nm": math.sqrt(ms[2]),
                "lf_position_m": math.sqrt(ms[3] + ms[4]), "lf_heading_rad": math.sqrt(ms[5])}
