"""Ocean current: an irrotational velocity field uniform in space, in NED.

The mean is a speed and the direction the current flows TOWARD (oceanographic "set", NED,
clockwise from north). An optional slow variation of speed and direction is realised as the sum of
sinusoids with the spectrum of a first-order Gauss–Markov process (std and time constant
configurable) — stateless in time, so any query order gives the same current. The vessel feels the
current through the velocity relative to the water, ν_r = ν − ν_c (seed 002 eqs. (6)–(8)); see
:mod:`sim_plant.vessel`.
"""

from __future__ import annotations

import math

import numpy as np

from sim_plant.environment.spectra import SpectralProcess, gauss_markov_process


class CurrentModel:
    """Current velocity over ground.

    Parameters
    ----------
    speed_mps : float
        Mean speed [m/s] (≥ 0).
    direction_to_rad : float
        Direction the current flows toward (NED) [rad].
    rng : numpy.random.Generator
        Seeds the slow variation (unused when both stds are 0).
    speed_std_mps, direction_std_rad : float
        Standard deviations of the slow variation of speed [m/s] and direction [rad].
    time_constant_s : float
        Correlation time of the variation [s].
    """

    def __init__(self, speed_mps: float, direction_to_rad: float, rng: np.random.Generator, *,
                 speed_std_mps: float = 0.0, direction_std_rad: float = 0.0, time_constant_s: float = 600.0
                 ) -> None:
        if speed_mps < 0.0 or speed_std_mps < 0.0 or direction_std_rad < 0.0 or time_constant_s <= 0.0:
            raise ValueError("current: speeds, stds and time constant must be non-negative (time constant > 0)")
        self.mean_speed_mps = speed_mps
        self.direction_to_rad = direction_to_rad
        self._speed_var: SpectralProcess | None = None
        self._dir_var: SpectralProcess | None = None
        if speed_std_mps > 0.0:
            self._speed_var = gauss_markov_process(speed_std_mps, time_constant_s, rng)
        if direction_std_rad > 0.0:
            self._dir_var = gauss_markov_process(direction_std_rad, time_constant_s, rng)
        self._constant = self._speed_var is None and self._dir_var is None
        self._vn = speed_mps * math.cos(direction_to_rad)
        self._ve = speed_mps * math.sin(direction_to_rad)

    @property
    def varies(self) -> bool:
        return not self._constant

    def speed_direction(self, t_s: float) -> tuple[float, float]:
        """(speed [m/s] ≥ 0, direction toward [rad]) at ``t_s``."""
        speed = self.mean_speed_mps
        direction = self.direction_to_rad
        if self._speed_var is not None:
            speed = max(0.0, speed + self._speed_var.value(t_s))
        if self._dir_var is not None:
            direction += self._dir_var.value(t_s)
        return speed, direction

    def velocity_ned(self, t_s: float) -> tuple[float, float]:
        """Current velocity (north, east) [m/s] at ``t_s``."""
        if self._constant:
            return self._vn, self._ve
        speed, direction = self.speed_direction(t_s)
        return speed * math.cos(direction), speed * math.sin(direction)
