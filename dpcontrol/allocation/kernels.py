"""Compiled per-step kernels of the thrust allocation: the extended-thrust map, the QP's rows, the commands.

Why kernels (see :mod:`dpbase.jit`): a vessel has 3–20 allocation variables, so the per-step work
around the QP solver — thrust windows, rudder wedges, azimuth polygons and rate cones, the commands
from the solution — is a few hundred floating-point operations spread over a hundred numpy or Python
calls. Here each stage is one loop over the thrusters in one compiled call:

* :func:`extended_thrust` / :func:`generalized_force` — the nonlinear map ``(T, α) → f`` of
  :mod:`dpcontrol.allocation.geometry` and ``τ = B f``;
* :func:`allocation_constraints` — every per-step row and bound of the QP of
  :class:`~dpcontrol.allocation.allocator.ThrustAllocator` (module docstring there: thrust and
  thrust-rate windows, the rudder wedge ``δ_lo k_L F_a ≤ F_l ≤ δ_hi k_L F_a``, the azimuth polygon,
  rate cone and forbidden sectors);
* :func:`allocation_commands` — thrust and angle commands from the QP solution (or the held previous
  command), their generalized force and the normalised shortfall (:func:`all_finite` first tells
  whether the solver's point is a solution).

The allocator keeps the configuration, the checks of its inputs, the daqp calls and the decisions
between solves (rudder ahead/astern enumeration, the long way round a forbidden sector) in Python.

The functions are the numpy and Python code they replaced, written as loops: the same operations in the
same order, so that the QP and the commands are the same to the last bit except where a sum's order
changed (``pinv @ τ`` and ``B @ f``, here plain loops instead of BLAS's machine-dependent kernels) and in
the narrow azimuth rows, which now take this step's dt (the numpy code kept the ``α̇ dt`` of the dt at
which it last checked the layout: a last-bit difference when the measured period jitters). ``min`` and
``max`` are spelled out as Python's builtins (:func:`_clamp`, :func:`_py_max`, :func:`_py_min`) or
numpy's ufuncs (:func:`_maximum`, :func:`_minimum`), whichever the replaced code used (they differ only
on NaN and on the sign of a zero).

Data layout (per thruster ``i``; arrays built once by the allocator, C-contiguous):

* ``layout`` (n, 5) int: ``L_MODE`` (``FIXED``/``AZIMUTH``/``RUDDER``), ``L_VARIABLE`` (first
  extended-thrust variable), ``L_ROW`` (first constraint row of its block), ``L_SECTOR_FIRST`` and
  ``L_SECTOR_COUNT`` (its rows of ``sectors``, forbidden sectors as ``(start, width)`` [rad]); the
  geometry's own table is the first two columns;
* ``spec`` (n, 9) float: constants (``S_*``: thrust window [N], rates [N/s, rad/s], variable scale [N],
  fixed angle [rad], rudder lift [1/rad] and limit [rad], the "no thrust" level [N]);
* ``window`` (n, 8) float and ``state`` (n, 5) int: what :func:`allocation_constraints` decided this
  step (thrust window [N], ``T_prev − Ṫ dt`` [N], azimuth or rudder window [rad], wanted direction
  and allowed arc [rad]; window full, blocked by a sector, long way open, rudder ahead, ahead/astern
  ambiguous) for :func:`allocation_commands` and the allocator.

QP layout (daqp): variables ``x = [f / scale, s⁺, s⁻]`` (``nv`` columns of ``A``), bounds of variable
``k`` at ``upper[k]``/``lower[k]``, of row ``r`` of ``A`` at ``upper[nv + r]``/``lower[nv + r]``.
"""

from __future__ import annotations

import math

import numpy as np

from dpbase.frames import ssa_compiled as ssa
from dpbase.jit import UniTuple, b1, b1_1d, f8, f8_1d, f8_2d, i8, i8_1d, kernel, void

i8_2d = i8[:, ::1]  # C-contiguous int64 2-D (an index table)

TWO_PI = 2.0 * math.pi

# Thruster modes (ThrusterGeometry.mode)
FIXED = 0
AZIMUTH = 1
RUDDER = 2

EPS_ANGLE = 1e-9
MAX_WINDOW = 0.95 * math.pi    # largest convex azimuth window [rad]
MIN_WINDOW = 1e-7              # narrower windows are treated as a fixed direction [rad]
ZERO_THRUST = 1e-9             # |F|/Tmax below which a direction (azimuth, rudder) is not defined by F
SATURATION_TOLERANCE = 1e-6    # shortfall / capability per DOF above which the demand is "saturated"
INACTIVE = 1.0                 # bound of unused (all-zero) constraint rows

# Columns of layout (int, per thruster)
L_MODE, L_VARIABLE, L_ROW, L_SECTOR_FIRST, L_SECTOR_COUNT = range(5)
LAYOUT_COLUMNS = 5
# Columns of spec (float, per thruster)
S_T_MIN, S_T_MAX, S_T_RATE, S_A_RATE, S_SCALE, S_ANGLE, S_K_LIFT, S_DELTA_MAX, S_EPS = range(9)
SPEC_COLUMNS = 9
# Columns of window (float, per thruster, per step)
W_T_LO, W_T_HI, W_LOW, W_LO, W_HI, W_TARGET, W_ARC_LO, W_ARC_HI = range(8)
WINDOW_COLUMNS = 8
# Columns of state (int 0/1, per thruster, per step)
F_FULL, F_BLOCKED, F_LONG_WAY, F_AHEAD, F_AMBIGUOUS = range(5)
STATE_COLUMNS = 5

# Rudder modes of allocation_constraints: the allocation's guess, or forced
RUDDER_GUESS = -1
RUDDER_ASTERN = 0
RUDDER_AHEAD = 1


# ---------------------------------------------------------------------- min/max as the replaced code had them
@kernel(f8(f8, f8))
def _py_max(a: float, b: float) -> float:
    """Python's ``max(a, b)``."""
    return b if b > a else a


@kernel(f8(f8, f8))
def _py_min(a: float, b: float) -> float:
    """Python's ``min(a, b)``."""
    return b if b < a else a


@kernel(f8(f8, f8, f8))
def _clamp(x: float, lo: float, hi: float) -> float:
    """Python's ``min(max(x, lo), hi)``."""
    y = lo if lo > x else x
    return hi if hi < y else y


@kernel(f8(f8, f8))
def _maximum(a: float, b: float) -> float:
    """``numpy.maximum(a, b)`` (NaN propagates)."""
    return a if (a >= b or math.isnan(a)) else b


@kernel(f8(f8, f8))
def _minimum(a: float, b: float) -> float:
    """``numpy.minimum(a, b)`` (NaN propagates)."""
    return a if (a <= b or math.isnan(a)) else b


# ---------------------------------------------------------------------- geometry: (T, α) → f → τ
@kernel(UniTuple(f8, 2)(i8, f8, f8, f8))
def _extended_pair(mode: int, k_lift: float, thrust: float, angle: float) -> tuple[float, float]:
    """A thruster's extended thrust (geometry module docstring): azimuth ``(T cos α, T sin α)``;
    propeller with rudder ``(T, T k_L δ)`` ahead, ``(T, 0)`` astern; fixed direction ``(T, ·)``."""
    if mode == AZIMUTH:
        return thrust * math.cos(angle), thrust * math.sin(angle)
    if mode == RUDDER:
        return thrust, (thrust * k_lift * angle if thrust > 0.0 else 0.0)   # lift only ahead
    return thrust, 0.0


@kernel(void(i8_2d, f8_1d, f8_1d, f8_1d, f8_1d))
def extended_thrust(layout: np.ndarray, lift: np.ndarray, thrust_n: np.ndarray, angle_rad: np.ndarray,
                    f: np.ndarray) -> None:
    """Extended thrust ``f`` of thrust/angle commands (Fossen 2021 §11.2; geometry module docstring).

    Parameters
    ----------
    layout : (n, ≥2) int — ``L_MODE``, ``L_VARIABLE`` per thruster
    lift : (n,) — rudder lift ``k_L`` [1/rad] (read for rudders only)
    thrust_n : (n,) [N]; angle_rad : (n,) azimuth / rudder angle [rad] (ignored for fixed thrusters)
    f : (n_f,) out — [N]
    """
    for i in range(layout.shape[0]):
        mode = layout[i, L_MODE]
        j = layout[i, L_VARIABLE]
        first, second = _extended_pair(mode, lift[i], thrust_n[i], angle_rad[i])
        f[j] = first
        if mode != FIXED:
            f[j + 1] = second


@kernel(void(f8_2d, f8_1d, f8_1d))
def _configuration_product(B: np.ndarray, f: np.ndarray, tau: np.ndarray) -> None:
    """``τ = B f`` for the (3, n_f) configuration matrix."""
    for k in range(3):
        total = 0.0
        for j in range(f.size):
            total += B[k, j] * f[j]
        tau[k] = total


@kernel(void(i8_2d, f8_1d, f8_2d, f8_1d, f8_1d, f8_1d, f8_1d))
def generalized_force(layout: np.ndarray, lift: np.ndarray, B: np.ndarray, thrust_n: np.ndarray,
                      angle_rad: np.ndarray, f: np.ndarray, tau_b: np.ndarray) -> None:
    """Generalized force ``τ_b = B f(T, α)`` ``[N, N, N·m]`` of thrust/angle commands.

    Parameters as :func:`extended_thrust`; ``B`` (3, n_f) the configuration matrix, ``f`` (n_f,) work
    (the extended thrust on return), ``tau_b`` (3,) out.
    """
    extended_thrust(layout, lift, thrust_n, angle_rad, f)
    _configuration_product(B, f, tau_b)


# ---------------------------------------------------------------------- constraint rows per thruster type
@kernel(void(i8, f8, f8, i8_2d, f8_2d, f8_1d, f8_1d))
def _fixed_bounds(i: int, t_lo: float, t_hi: float, layout: np.ndarray, spec: np.ndarray, upper: np.ndarray,
                  lower: np.ndarray) -> None:
    """Bounds of a fixed-direction thruster's variable: its thrust window, normalised."""
    j = layout[i, L_VARIABLE]
    scale = spec[i, S_SCALE]
    lower[j] = t_lo / scale
    upper[j] = t_hi / scale


@kernel(void(i8, i8, f8, f8, b1, f8, f8, i8_2d, f8_2d, f8_2d, i8_2d, f8_2d, f8_1d, f8_1d))
def _rudder_rows(i: int, mode: int, t_prev: float, a_prev: float, on: bool, f_axial_star: float, dt: float,
                 layout: np.ndarray, spec: np.ndarray, window: np.ndarray, state: np.ndarray, A: np.ndarray,
                 upper: np.ndarray, lower: np.ndarray) -> None:
    """Bounds and wedge rows of a propeller with rudder (allocator module docstring).

    Ahead ``(F_a, F_l)`` lies in the wedge ``δ_lo k_L F_a ≤ F_l ≤ δ_hi k_L F_a`` with ``[δ_lo, δ_hi]`` the
    rudder angles reachable at the rudder rate; astern ``F_l = 0``. Which piece: ``mode`` (``RUDDER_AHEAD``
    / ``RUDDER_ASTERN``) when both are allowed by the thrust-rate limit, else (and for ``RUDDER_GUESS``) the
    sign of the unconstrained allocation's axial force ``f_axial_star``.
    """
    j = layout[i, L_VARIABLE]
    row = layout[i, L_ROW]
    r0 = A.shape[1] + row
    scale = spec[i, S_SCALE]
    k_lift = spec[i, S_K_LIFT]
    delta_max = spec[i, S_DELTA_MAX]
    A[row, j] = 0.0
    A[row, j + 1] = 0.0
    A[row + 1, j] = 0.0
    A[row + 1, j + 1] = 0.0
    upper[r0] = INACTIVE
    upper[r0 + 1] = INACTIVE
    lower[r0] = -INACTIVE
    lower[r0 + 1] = -INACTIVE
    delta_prev = _clamp(a_prev, -delta_max, delta_max)
    step_delta = spec[i, S_A_RATE] * dt
    d_lo = _py_max(-delta_max, delta_prev - step_delta)
    d_hi = _py_min(delta_max, delta_prev + step_delta)
    window[i, W_LO] = d_lo
    window[i, W_HI] = d_hi
    if not on:
        window[i, W_T_LO] = 0.0
        window[i, W_T_HI] = 0.0
        state[i, F_AHEAD] = 1
        state[i, F_AMBIGUOUS] = 0
        lower[j] = 0.0
        lower[j + 1] = 0.0
        upper[j] = 0.0
        upper[j + 1] = 0.0
        return
    step = spec[i, S_T_RATE] * dt
    min_thrust = spec[i, S_T_MIN]
    ahead_lo = _py_max(0.0, t_prev - step)
    ahead_hi = _py_min(spec[i, S_T_MAX], t_prev + step)
    astern_lo = _py_max(min_thrust, t_prev - step)
    astern_hi = _py_min(0.0, t_prev + step)
    ahead_ok = ahead_lo <= ahead_hi
    astern_ok = astern_lo <= astern_hi and min_thrust < 0.0
    ambiguous = ahead_ok and astern_ok
    state[i, F_AMBIGUOUS] = 1 if ambiguous else 0
    if mode != RUDDER_GUESS and ambiguous:
        ahead = mode == RUDDER_AHEAD
    else:
        ahead = ahead_ok and (not astern_ok or f_axial_star >= 0.0)
    state[i, F_AHEAD] = 1 if ahead else 0
    if ahead:
        window[i, W_T_LO] = ahead_lo
        window[i, W_T_HI] = ahead_hi
        lower[j] = ahead_lo / scale
        upper[j] = ahead_hi / scale
        lift = k_lift * delta_max * ahead_hi / scale
        lower[j + 1] = -lift
        upper[j + 1] = lift
        # wedge k δ_lo F_a ≤ F_l ≤ k δ_hi F_a
        A[row, j] = -k_lift * d_hi
        A[row, j + 1] = 1.0
        A[row + 1, j] = k_lift * d_lo
        A[row + 1, j + 1] = -1.0
        upper[r0] = 0.0
        upper[r0 + 1] = 0.0
        lower[r0] = -np.inf
        lower[r0 + 1] = -np.inf
    else:
        window[i, W_T_LO] = astern_lo
        window[i, W_T_HI] = astern_hi
        lower[j] = astern_lo / scale
        upper[j] = astern_hi / scale
        lower[j + 1] = 0.0
        upper[j + 1] = 0.0


@kernel(void(i8, i8, f8, f8, f8, f8, f8_2d, f8_1d, f8_1d))
def _set_row(row: int, j: int, x: float, y: float, up: float, low: float, A: np.ndarray, upper: np.ndarray,
             lower: np.ndarray) -> None:
    """Row ``row`` of an azimuth block: ``low ≤ x F_x + y F_y ≤ up`` (F_x, F_y: variables j, j + 1)."""
    A[row, j] = x
    A[row, j + 1] = y
    upper[A.shape[1] + row] = up
    lower[A.shape[1] + row] = low


@kernel(void(i8, i8, f8_2d, f8_1d, f8_1d))
def _unused_row(row: int, j: int, A: np.ndarray, upper: np.ndarray, lower: np.ndarray) -> None:
    """An azimuth row not in use this step: ``0·F ∈ [−1, 1]``."""
    _set_row(row, j, 0.0, 0.0, INACTIVE, -INACTIVE, A, upper, lower)


@kernel(void(i8, f8, f8, b1, i8, i8_2d, f8_2d, f8_2d, f8_2d, f8_1d, f8_1d))
def _azimuth_rows_narrow(i: int, a: float, dt: float, on: bool, chords: int, layout: np.ndarray,
                         spec: np.ndarray, window: np.ndarray, A: np.ndarray, upper: np.ndarray,
                         lower: np.ndarray) -> None:
    """An azimuth's rows for a narrow rate window (``α̇ dt`` ≤ one polygon side, no sectors)::

        chords       [cos m, sin m]·F ≤ r cos(α̇dt/2),  m = α_prev ∓ α̇dt/2
        φ ≥ α_prev − α̇dt:  [sin lo, −cos lo]·F ≤ 0;    φ ≤ α_prev + α̇dt:  [−sin hi, cos hi]·F ≤ 0
        lower thrust rate  [cos α_prev, sin α_prev]·F ≥ (T_prev − Ṫdt)/T_max   (only if > 0)

    with ``r = min(T_max, T_prev + Ṫdt)/T_max`` (0 for an unavailable thruster: its variables are bounded to
    zero, and every row holds at F = 0); the other chord rows are unused. The thrust window is the one
    :func:`allocation_constraints` set for every thruster.
    """
    j = layout[i, L_VARIABLE]
    row = layout[i, L_ROW]
    scale = spec[i, S_SCALE]
    delta = spec[i, S_A_RATE] * dt
    lo = a + -delta
    hi = a + delta
    r = window[i, W_T_HI] / scale
    chord_bound = r * math.cos(0.5 * delta)
    m_left = a + -0.5 * delta
    m_right = a + 0.5 * delta
    _set_row(row, j, math.cos(m_left), math.sin(m_left), chord_bound, -np.inf, A, upper, lower)
    _set_row(row + 1, j, math.cos(m_right), math.sin(m_right), chord_bound, -np.inf, A, upper, lower)
    for k in range(2, chords):
        _unused_row(row + k, j, A, upper, lower)
    _set_row(row + chords, j, math.sin(lo), -math.cos(lo), 0.0, -np.inf, A, upper, lower)
    _set_row(row + chords + 1, j, -math.sin(hi), math.cos(hi), 0.0, -np.inf, A, upper, lower)
    low = window[i, W_LOW]
    along = a + 0.0
    _set_row(row + chords + 2, j, math.cos(along), math.sin(along), np.inf,
             -np.inf if (low <= 0.0 or not on) else low / scale, A, upper, lower)
    upper[j] = r
    upper[j + 1] = r
    lower[j] = -r
    lower[j + 1] = -r
    window[i, W_LO] = lo
    window[i, W_HI] = hi


@kernel(UniTuple(f8, 5)(f8, f8_2d, i8, i8, f8))
def _sector_window(a: float, sectors: np.ndarray, first: int, count: int, wanted: float
                   ) -> tuple[float, float, float, float, float]:
    """Allowed arc around ``a`` and the target in it: ``(blocked, arc_lo, arc_hi, target, side)`` [rad].

    ``blocked`` is 1.0 when ``a`` is inside a forbidden sector (no thrust; slew out towards the nearer
    edge, the target); ``side`` is +1/−1 when the short way to the wanted direction is blocked and the
    window must open only the long way round (0 otherwise); ``target`` is NaN without a wanted
    direction (``wanted`` NaN).
    """
    arc_lo = -np.inf
    arc_hi = np.inf
    for k in range(first, first + count):
        start = sectors[k, 0]
        width = sectors[k, 1]
        offset = (a - start) % TWO_PI
        if EPS_ANGLE < offset < width - EPS_ANGLE:
            # inside a forbidden sector: no thrust; slew out towards the nearer edge
            edge = a - offset if offset <= 0.5 * width else a + (width - offset)
            return 1.0, a, a, edge, 0.0
        up = (start - a) % TWO_PI
        if up > TWO_PI - EPS_ANGLE:
            up = 0.0
        down = (a - (start + width)) % TWO_PI
        if down > TWO_PI - EPS_ANGLE:
            down = 0.0
        arc_hi = _py_min(arc_hi, a + up)
        arc_lo = _py_max(arc_lo, a - down)
    if math.isnan(wanted):
        return 0.0, arc_lo, arc_hi, np.nan, 0.0
    short = a + ssa(wanted - a)
    for shift in (0.0, -TWO_PI, TWO_PI):
        candidate = short + shift
        if arc_lo - EPS_ANGLE <= candidate <= arc_hi + EPS_ANGLE:
            target = _clamp(candidate, arc_lo, arc_hi)
            side = 0.0
            if abs(target - short) > EPS_ANGLE and abs(target - a) > EPS_ANGLE:
                side = 1.0 if target > a else -1.0
            return 0.0, arc_lo, arc_hi, target, side
    # the wanted direction is forbidden: aim at the nearer edge
    target = arc_lo if abs(ssa(wanted - arc_lo)) <= abs(ssa(wanted - arc_hi)) else arc_hi
    return 0.0, arc_lo, arc_hi, target, 0.0


@kernel(void(i8, b1, f8, f8, b1, f8, i8, f8, i8_2d, f8_2d, f8_2d, f8_2d, i8_2d, f8_2d, f8_1d, f8_1d))
def _azimuth_rows_general(i: int, long_way: bool, t_prev: float, a: float, on: bool, dt: float, chords: int,
                          inv_side: float, layout: np.ndarray, spec: np.ndarray, sectors: np.ndarray,
                          window: np.ndarray, state: np.ndarray, A: np.ndarray, upper: np.ndarray,
                          lower: np.ndarray) -> None:
    """An azimuth's bounds and rows in general (allocator module docstring; Johansen et al. 2004).

    The window of force directions is the rate window ``α_prev ± α̇ dt`` cut to the allowed arc of the
    forbidden sectors (or, blocked inside one, just ``α_prev``); wider than 171° it is cut to 171° centred
    towards the wanted direction ``window[i, W_TARGET]`` (set by the caller); ``long_way`` opens it only
    the long way round where that was decided. The circle ``|F| ≤ r`` is an inscribed polygon from the
    window's low edge to its high edge with a vertex at ``α_prev`` (full circle: ``P`` sides), then the two
    cone edges and the lower thrust-rate row; rows not in use are ``0·F ∈ [−1, 1]``.
    """
    j = layout[i, L_VARIABLE]
    row = layout[i, L_ROW]
    count = layout[i, L_SECTOR_COUNT]
    scale = spec[i, S_SCALE]
    target = window[i, W_TARGET]
    delta = spec[i, S_A_RATE] * dt
    lo = a - delta
    hi = a + delta
    blocked = False
    side = 0.0
    arc_lo = -np.inf
    arc_hi = np.inf
    if count > 0:
        blocked_flag, arc_lo, arc_hi, target, side = _sector_window(a, sectors, layout[i, L_SECTOR_FIRST], count,
                                                                    target)
        blocked = blocked_flag != 0.0
        lo = _maximum(lo, arc_lo)
        hi = _minimum(hi, arc_hi)
    full = (hi - lo) >= TWO_PI
    wide = not full and (hi - lo > MAX_WINDOW)
    if wide:
        # a window of 171° towards the wanted direction, containing the previous azimuth
        half = 0.5 * MAX_WINDOW
        centre = a if math.isnan(target) else target
        centre = _minimum(_maximum(centre, lo + half), hi - half)
        centre = _minimum(_maximum(centre, a - half), a + half)
        lo = centre - half
        hi = centre + half
    way = not full and not wide and side != 0.0
    if long_way and way:
        if side > 0.0:
            lo = a
        if side < 0.0:
            hi = a
    if blocked:
        lo = a
        hi = a
    window[i, W_LO] = lo
    window[i, W_HI] = hi
    window[i, W_TARGET] = target
    window[i, W_ARC_LO] = arc_lo
    window[i, W_ARC_HI] = arc_hi
    state[i, F_FULL] = 1 if full else 0
    state[i, F_BLOCKED] = 1 if blocked else 0
    state[i, F_LONG_WAY] = 1 if way else 0

    # thrust window and simple bounds
    step = spec[i, S_T_RATE] * dt
    radius = _minimum(spec[i, S_T_MAX], t_prev + step)
    low = t_prev - step
    active = on and radius > 0.0 and not blocked
    window[i, W_T_LO] = _maximum(low, 0.0) if active else 0.0
    window[i, W_T_HI] = radius if active else 0.0
    r = radius / scale if active else 0.0
    upper[j] = r
    upper[j + 1] = r
    lower[j] = -r
    lower[j + 1] = -r

    if not active:
        for k in range(chords + 3):
            _unused_row(row + k, j, A, upper, lower)
        return
    # inscribed polygon: vertices from lo to hi with one at the previous azimuth (full circle: P sides)
    if full:
        lo = a - TWO_PI
        hi = a
    if hi - lo < MIN_WINDOW:
        lo = a - 0.5 * MIN_WINDOW
        hi = a + 0.5 * MIN_WINDOW
    left = a - lo
    right = hi - a
    k1 = np.ceil(left * inv_side - 1e-9)
    k2 = np.ceil(right * inv_side - 1e-9)
    if k1 + k2 > chords:  # a window wider than the rows were sized for: fewer, longer chords
        share = np.rint(chords * left / (left + right))
        share = _minimum(_maximum(share, 1.0 if k1 > 0 else 0.0), chords - (1.0 if k2 > 0 else 0.0))
        k1 = share
        k2 = chords - share
    used = k1 + k2
    den1 = _maximum(k1, 1.0)
    den2 = _maximum(k2, 1.0)
    previous = lo + left * (0.0 / den1)   # vertex 0
    for k in range(chords):
        m = k + 1.0
        vertex = lo + left * (m / den1) if m <= k1 else a + right * ((m - k1) / den2)
        if k >= used:
            _unused_row(row + k, j, A, upper, lower)
        else:
            mid = (vertex + previous) * 0.5
            half_angle = (vertex - previous) * 0.5
            _set_row(row + k, j, math.cos(mid), math.sin(mid), math.cos(half_angle) * r, -np.inf, A, upper, lower)
        previous = vertex
    # the force direction φ within [lo, hi]: sin(φ − lo) ≥ 0 and sin(hi − φ) ≥ 0
    if full:
        _unused_row(row + chords, j, A, upper, lower)
        _unused_row(row + chords + 1, j, A, upper, lower)
    else:
        _set_row(row + chords, j, math.sin(lo), -math.cos(lo), 0.0, -np.inf, A, upper, lower)
        _set_row(row + chords + 1, j, -math.sin(hi), math.cos(hi), 0.0, -np.inf, A, upper, lower)
    # lower thrust-rate limit: F·u(α_prev) ≥ T_prev − Ṫ dt
    if low <= 0.0:
        _unused_row(row + chords + 2, j, A, upper, lower)
    else:
        _set_row(row + chords + 2, j, math.cos(a), math.sin(a), np.inf, low / scale, A, upper, lower)


@kernel(void(f8_1d, f8_2d, f8_1d, f8_1d, b1_1d, f8, i8_1d, b1, b1, i8, f8, i8_2d, f8_2d, f8_2d, f8_1d, f8_1d,
             f8_2d, i8_2d, f8_2d, f8_1d, f8_1d))
def allocation_constraints(tau_b: np.ndarray, pinv: np.ndarray, prev_t: np.ndarray, prev_a: np.ndarray,
                           mask: np.ndarray, dt: float, rudder_mode: np.ndarray, narrow: bool, long_way: bool,
                           chords: int, inv_side: float, layout: np.ndarray, spec: np.ndarray,
                           sectors: np.ndarray, tau_scale: np.ndarray, f_star: np.ndarray, window: np.ndarray,
                           state: np.ndarray, A: np.ndarray, upper: np.ndarray, lower: np.ndarray) -> None:
    """Every per-step row and bound of the allocation QP (allocator module docstring).

    Sets the unconstrained allocation ``f* = B_W⁺ τ`` (Fossen 2021 §11.2.2), the equality rows
    ``B f + s⁺ − s⁻ = τ`` (normalised by the capability per DOF), each thruster's thrust window
    ``[max(T_min, T_prev − Ṫdt), min(T_max, T_prev + Ṫdt)]`` (zero when unavailable), and per thruster type
    the bounds and rows: fixed direction — the window; rudder — :func:`_rudder_rows`; azimuth — its wanted
    direction (that of ``f*``, the short way from α_prev; NaN below ``ZERO_THRUST``) and
    :func:`_azimuth_rows_narrow` when ``narrow`` (every azimuth's rate window is narrow, no sectors) else
    :func:`_azimuth_rows_general`.

    Parameters
    ----------
    tau_b : (3,) demand [N, N, N·m]; pinv : (n_f, 3) weighted pseudo-inverse of the available thrusters
    prev_t, prev_a : (n,) previous thrust [N] (within the limits) and angle [rad]
    mask : (n,) available; dt : time of the rate limits [s]
    rudder_mode : (n,) ``RUDDER_GUESS``/``RUDDER_AHEAD``/``RUDDER_ASTERN`` (read for rudders)
    narrow : use the narrow azimuth rows; long_way : open the windows marked ``F_LONG_WAY`` the long way
    chords : chord rows per azimuth block; inv_side : 1 / polygon side [1/rad]
    layout, spec, sectors : the thruster tables (module docstring); tau_scale : (3,) capability per DOF
    f_star : (n_f,) out [N]; window, state : out (module docstring); A, upper, lower : the QP, updated
    """
    n_f = f_star.size
    t0 = tau_b[0]
    t1 = tau_b[1]
    t2 = tau_b[2]
    for j in range(n_f):
        f_star[j] = pinv[j, 0] * t0 + pinv[j, 1] * t1 + pinv[j, 2] * t2
    nv = A.shape[1]
    for k in range(3):
        upper[nv + k] = tau_b[k] / tau_scale[k]
        lower[nv + k] = upper[nv + k]
    for i in range(layout.shape[0]):
        mode = layout[i, L_MODE]
        j = layout[i, L_VARIABLE]
        t_prev = prev_t[i]
        on = mask[i]
        step = spec[i, S_T_RATE] * dt
        low = t_prev - step
        window[i, W_LOW] = low
        t_lo = _maximum(spec[i, S_T_MIN], low)
        t_hi = _minimum(spec[i, S_T_MAX], t_prev + step)
        if not on:
            t_lo = 0.0
            t_hi = 0.0
        window[i, W_T_LO] = t_lo
        window[i, W_T_HI] = t_hi
        if mode == FIXED:
            _fixed_bounds(i, t_lo, t_hi, layout, spec, upper, lower)
        elif mode == RUDDER:
            _rudder_rows(i, rudder_mode[i], t_prev, prev_a[i], on, f_star[j], dt, layout, spec, window, state, A,
                         upper, lower)
        else:
            a = prev_a[i]
            fx = f_star[j]
            fy = f_star[j + 1]
            eps = spec[i, S_EPS]
            window[i, W_TARGET] = np.nan if fx * fx + fy * fy <= eps * eps else a + ssa(math.atan2(fy, fx) - a)
            if narrow:
                window[i, W_ARC_LO] = -np.inf
                window[i, W_ARC_HI] = np.inf
                state[i, F_FULL] = 0
                state[i, F_BLOCKED] = 0
                state[i, F_LONG_WAY] = 0
                _azimuth_rows_narrow(i, a, dt, on, chords, layout, spec, window, A, upper, lower)
            else:
                _azimuth_rows_general(i, long_way, t_prev, a, on, dt, chords, inv_side, layout, spec, sectors,
                                      window, state, A, upper, lower)


# ---------------------------------------------------------------------- commands from the solution
@kernel(b1(f8_1d))
def all_finite(x: np.ndarray) -> bool:
    """Whether every entry of ``x`` is finite (a solver's point is a solution only then)."""
    finite = True
    for k in range(x.size):
        finite &= math.isfinite(x[k])
    return finite


@kernel(f8(f8_1d, b1, f8_1d, f8_1d, b1_1d, f8_1d, f8, i8_2d, f8_2d, f8_2d, i8_2d, f8_2d, f8_1d, f8_1d, f8_1d,
           f8_1d, f8_1d, f8_1d))
def allocation_commands(x: np.ndarray, solved: bool, prev_t: np.ndarray, prev_a: np.ndarray, mask: np.ndarray,
                        f_star: np.ndarray, dt: float, layout: np.ndarray, spec: np.ndarray, window: np.ndarray,
                        state: np.ndarray, B: np.ndarray, tau_b: np.ndarray, tau_scale: np.ndarray,
                        thrust_n: np.ndarray, angle_rad: np.ndarray, f: np.ndarray, achieved_b: np.ndarray
                        ) -> float:
    """Thrust and angle commands from the QP solution (or, ``solved`` false, the previous command held),
    inside the windows :func:`allocation_constraints` set; their force ``τ_achieved = B f(T, α)``.

    Fixed direction: the thrust clamped to the window. Rudder: the angle ``δ = F_l/(k_L F_a)`` ahead; without
    lift (no thrust, or astern) it slews towards the angle the unconstrained allocation wants. Azimuth:
    ``T = |F|``, ``α = atan2(F_y, F_x)`` the short way from α_prev, inside the window; an idle azimuth (no
    thrust, unavailable or blocked) slews towards the wanted direction at the rate limit, inside the allowed
    arc.

    Parameters
    ----------
    x : (≥ n_f,) the QP solution (normalised: ``f = x · scale``); solved : whether x is one
    prev_t, prev_a, mask, f_star, dt, layout, spec, window, state : as :func:`allocation_constraints`
    B : (3, n_f) configuration matrix; tau_b : (3,) demand; tau_scale : (3,) capability per DOF
    thrust_n, angle_rad : (n,) out — the commands [N], [rad]; f : (n_f,) work; achieved_b : (3,) out

    Returns
    -------
    float
        ``Σ |τ − τ_achieved| / capability`` if some DOF misses by more than ``SATURATION_TOLERANCE``, else 0.
    """
    for i in range(layout.shape[0]):
        mode = layout[i, L_MODE]
        j = layout[i, L_VARIABLE]
        scale = spec[i, S_SCALE]
        t_lo = window[i, W_T_LO]
        t_hi = window[i, W_T_HI]
        if mode == FIXED:
            t = _clamp(x[j] * scale if solved else prev_t[i], t_lo, t_hi)
            direction = spec[i, S_ANGLE]
        elif mode == RUDDER:
            eps = spec[i, S_EPS]
            k_lift = spec[i, S_K_LIFT]
            t = _clamp(x[j] * scale if solved else prev_t[i], t_lo, t_hi)
            if not solved:
                direction = prev_a[i]
            elif state[i, F_AHEAD] != 0 and t > eps:
                direction = x[j + 1] * scale / (k_lift * t)
            else:
                # no lift this step (no thrust, or astern): slew towards the rudder angle the unconstrained
                # allocation wants, so that lift is available when thrust returns
                direction = prev_a[i]
                if f_star[j] > eps:
                    limit = spec[i, S_DELTA_MAX]
                    direction = _clamp(f_star[j + 1] / (k_lift * f_star[j]), -limit, limit)
            direction = _clamp(direction, window[i, W_LO], window[i, W_HI])
        else:
            a = prev_a[i]
            if solved:
                fx = x[j] * scale
                fy = x[j + 1] * scale
                t = math.hypot(fx, fy)
                direction = a + ((math.atan2(fy, fx) - a + math.pi) % TWO_PI - math.pi)
            else:
                t = prev_t[i]
                direction = a
            t = _clamp(t, t_lo, t_hi)
            on = mask[i]
            blocked = state[i, F_BLOCKED] != 0
            if state[i, F_FULL] == 0:
                direction = _clamp(direction, window[i, W_LO], window[i, W_HI])
            eps = spec[i, S_EPS]
            if not on or blocked or (t <= eps and t_lo <= eps):
                # idle: slew towards the wanted direction at the rate limit, inside the allowed arc
                t = 0.0
                if on:
                    wanted = window[i, W_TARGET]
                    step = spec[i, S_A_RATE] * dt
                    direction = a + _clamp(0.0 if math.isnan(wanted) else wanted - a, -step, step)
                    if not blocked:
                        direction = _clamp(direction, window[i, W_ARC_LO], window[i, W_ARC_HI])
                else:
                    direction = a
            direction = ssa(direction)
        thrust_n[i] = t
        angle_rad[i] = direction
    # the force of the commands, from the commands themselves (the nonlinear map)
    for i in range(layout.shape[0]):
        mode = layout[i, L_MODE]
        j = layout[i, L_VARIABLE]
        first, second = _extended_pair(mode, spec[i, S_K_LIFT], thrust_n[i], angle_rad[i])
        f[j] = first
        if mode != FIXED:
            f[j + 1] = second
    _configuration_product(B, f, achieved_b)
    score = 0.0
    missed = False
    for k in range(3):
        error = abs(tau_b[k] - achieved_b[k]) / tau_scale[k]
        score += error
        missed = missed or error > SATURATION_TOLERANCE
    return score if missed else 0.0
