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
    w_n = const[K_OMEGA]
    w_e = const[K_OMEGA + 1]
    w_p = const[K_OMEGA + 2]
    z_n = const[K_ZETA]
    z_e = const[K_ZETA + 1]
    z_p = const[K_ZETA + 2]
    vmax = const[K_SPEED]
    amax = const[K_ACCEL]
    rmax = const[K_YAW_RATE]
    rdotmax = const[K_YAW_ACCEL]
    steps = math.ceil(dt * const[K_RATE] / STEP_ACCURACY)
    substeps = steps if steps > 1 else 1
    h = dt / substeps
    r_n = r[0]
    r_e = r[1]
    r_psi = ssa(r[2])
    rf_n, rf_e, rf_p = state[S_PREFILTER, 0], state[S_PREFILTER, 1], state[S_PREFILTER, 2]
    x_n, x_e, x_p = state[S_ETA, 0], state[S_ETA, 1], state[S_ETA, 2]
    v_n, v_e, v_p = state[S_VELOCITY, 0], state[S_VELOCITY, 1], state[S_VELOCITY, 2]
    a_n = a_e = a_p = 0.0
    for _ in range(substeps):
        # first-order pre-filter (heading error by ssa: the short way round)
        rf_n += h * w_n * (r_n - rf_n)
        rf_e += h * w_e * (r_e - rf_e)
        rf_p = ssa(rf_p + h * w_p * ssa(r_psi - rf_p))
        # commanded velocity of the mass–spring–damper, limited by speed and braking distance
        e_n = rf_n - x_n
        e_e = rf_e - x_e
        e_p = ssa(rf_p - x_p)
        vc_n = w_n / (2.0 * z_n) * e_n
        vc_e = w_e / (2.0 * z_e) * e_e
        speed = math.hypot(vc_n, vc_e)
        limit = _py_min(vmax, math.sqrt(amax * math.hypot(e_n, e_e)))
        if speed > limit:
            scale = limit / speed
            vc_n *= scale
            vc_e *= scale
        vc_p = w_p / (2.0 * z_p) * e_p
        limit = _py_min(rmax, math.sqrt(rdotmax * abs(e_p)))
        if abs(vc_p) > limit:
            vc_p = math.copysign(limit, vc_p)
        # acceleration, limited (horizontal as a vector)
        a_n = 2.0 * z_n * w_n * (vc_n - v_n)
        a_e = 2.0 * z_e * w_e * (vc_e - v_e)
        accel = math.hypot(a_n, a_e)
        if accel > amax:
            scale = amax / accel
            a_n *= scale
            a_e *= scale
        a_p = 2.0 * z_p * w_p * (vc_p - v_p)
        if abs(a_p) > rdotmax:
            a_p = math.copysign(rdotmax, a_p)
        # semi-implicit Euler
        v_n += h * a_n
        v_e += h * a_e
        v_p += h * a_p
        x_n += h * v_n
        x_e += h * v_e
        x_p = ssa(x_p + h * v_p)
    state[S_PREFILTER, 0] = rf_n
    state[S_PREFILTER, 1] = rf_e
    state[S_PREFILTER, 2] = rf_p
    state[S_ETA, 0] = x_n
    state[S_ETA, 1] = x_e
    state[S_ETA, 2] = x_p
    state[S_VELOCITY, 0] = v_n
    state[S_VELOCITY, 1] = v_e
    state[S_VELOCITY, 2] = v_p
    state[S_ACCEL, 0] = a_n
    state[S_ACCEL, 1] = a_e
    state[S_ACCEL, 2] = a_p
    return True
