"""Compiled per-step kernel of the reference model (:mod:`dpcontrol.guidance.reference_model`).

Why a kernel (see :mod:`dpbase.jit`): a step of the third-order model with its speed, braking and
acceleration limits is ~60 floating-point operations and four angle wraps per integration sub-step;
as Python floats, with the checks and the output arrays around it, that is ~500 bytecodes per control
period. Here it is one call on the model's state array.

:func:`reference_step` is the Python loop it replaced, with the same operations in the same order.
Python's ``min``, ``max`` and ``math.hypot`` are spelled out or compiled: ``min``/``max`` as the
builtins (:func:`_py_min`, which differs from a plain comparison only on NaN), ``hypot`` as the C
library's, which may differ from CPython's own algorithm in the last bit.

Data layout (C-contiguous float64):

* ``const`` (``K_SIZE``,): ``K_OMEGA`` ω per DOF (north, east, heading) [rad/s], ``K_ZETA`` ζ [-],
  ``K_RATE`` the fastest rate max(2ζω, ω) [1/s] (it sets the sub-steps), ``K_SPEED`` [m/s], ``K_ACCEL``
  [m/s²], ``K_YAW_RATE`` [rad/s] and ``K_YAW_ACCEL`` [rad/s²] limits;
* ``state`` (``S_ROWS``, 3), per DOF along the last axis: ``S_PREFILTER`` r_f, ``S_ETA`` η_d,
  ``S_VELOCITY`` η̇_d, ``S_ACCEL`` η̈_d (NED; headings wrapped to (−π, π]).
"""

from __future__ import annotations

import math

import numpy as np

from dpbase.frames import ssa_compiled as ssa
from dpbase.jit import b1, f8, f8_1d, f8_2d, kernel

K_OMEGA, K_ZETA, K_RATE, K_SPEED, K_ACCEL, K_YAW_RATE, K_YAW_ACCEL = 0, 3, 6, 7, 8, 9, 10
K_SIZE = 11
S_PREFILTER, S_ETA, S_VELOCITY, S_ACCEL = range(4)
S_ROWS = 4
STEP_ACCURACY = 0.2  # largest 2ζω·h (and ω·h) per integration sub-step


@kernel(f8(f8, f8))
def _py_min(a: float, b: float) -> float:
    """Python's ``min(a, b)``."""
    return b if b < a else a


@kernel(b1(f8, f8_1d, f8_1d, f8_2d))
def reference_step(dt: float, r: np.ndarray, const: np.ndarray, state: np.ndarray) -> bool:
    """Advance the model by ``dt`` towards the set-point ``r`` (semi-implicit Euler sub-steps).

    Parameters
    ----------
    dt : float
        Sample time [s] (> 0, checked by the caller).
    r : ndarray, shape (3,)
        Set-point ``[north_m, east_m, psi_rad]`` (heading any wrap).
    const, state : ndarray
        See the module docstring; ``state`` is updated.

    Returns
    -------
    bool
        False (and nothing changed) when ``r`` is not 3 finite numbers.
    """
    if r.size != 3 or not (math.isfinite(r[0]) and math.isfinite(r[1]) and math.isfinite(r[2])):
        return False
    omega_north = const[K_OMEGA]
    omega_east = const[K_OMEGA + 1]
    omega_psi = const[K_OMEGA + 2]
    zeta_north = const[K_ZETA]
    zeta_east = const[K_ZETA + 1]
    zeta_psi = const[K_ZETA + 2]
    vmax = const[K_SPEED]
    amax = const[K_ACCEL]
    rmax = const[K_YAW_RATE]
    rdotmax = const[K_YAW_ACCEL]
    steps = math.ceil(dt * const[K_RATE] / STEP_ACCURACY)
    substeps = steps if steps > 1 else 1
    h = dt / substeps
    r_north = r[0]
    r_east = r[1]
    r_psi = ssa(r[2])
    rf_north, rf_east, rf_psi = state[S_PREFILTER, 0], state[S_PREFILTER, 1], state[S_PREFILTER, 2]
    x_north, x_east, x_psi = state[S_ETA, 0], state[S_ETA, 1], state[S_ETA, 2]
    v_north, v_east, v_psi = state[S_VELOCITY, 0], state[S_VELOCITY, 1], state[S_VELOCITY, 2]
    a_north = a_east = a_psi = 0.0
    for _ in range(substeps):
        # first-order pre-filter (heading error by ssa: the short way round)
        rf_north += h * omega_north * (r_north - rf_north)
        rf_east += h * omega_east * (r_east - rf_east)
        rf_psi = ssa(rf_psi + h * omega_psi * ssa(r_psi - rf_psi))
        # commanded velocity of the mass–spring–damper, limited by speed and braking distance
        e_north = rf_north - x_north
        e_east = rf_east - x_east
        e_psi = ssa(rf_psi - x_psi)
        vc_north = omega_north / (2.0 * zeta_north) * e_north
        vc_east = omega_east / (2.0 * zeta_east) * e_east
        speed = math.hypot(vc_north, vc_east)
        limit = _py_min(vmax, math.sqrt(amax * math.hypot(e_north, e_east)))
        if speed > limit:
            scale = limit / speed
            vc_north *= scale
            vc_east *= scale
        vc_psi = omega_psi / (2.0 * zeta_psi) * e_psi
        limit = _py_min(rmax, math.sqrt(rdotmax * abs(e_psi)))
        if abs(vc_psi) > limit:
            vc_psi = math.copysign(limit, vc_psi)
        # acceleration, limited (horizontal as a vector)
        a_north = 2.0 * zeta_north * omega_north * (vc_north - v_north)
        a_east = 2.0 * zeta_east * omega_east * (vc_east - v_east)
        accel = math.hypot(a_north, a_east)
        if accel > amax:
            scale = amax / accel
            a_north *= scale
            a_east *= scale
        a_psi = 2.0 * zeta_psi * omega_psi * (vc_psi - v_psi)
        if abs(a_psi) > rdotmax:
            a_psi = math.copysign(rdotmax, a_psi)
        # semi-implicit Euler
        v_north += h * a_north
        v_east += h * a_east
        v_psi += h * a_psi
        x_north += h * v_north
        x_east += h * v_east
        x_psi = ssa(x_psi + h * v_psi)
    state[S_PREFILTER, 0] = rf_north
    state[S_PREFILTER, 1] = rf_east
    state[S_PREFILTER, 2] = rf_psi
    state[S_ETA, 0] = x_north
    state[S_ETA, 1] = x_east
    state[S_ETA, 2] = x_psi
    state[S_VELOCITY, 0] = v_north
    state[S_VELOCITY, 1] = v_east
    state[S_VELOCITY, 2] = v_psi
    state[S_ACCEL, 0] = a_north
    state[S_ACCEL, 1] = a_east
    state[S_ACCEL, 2] = a_psi
    return True
