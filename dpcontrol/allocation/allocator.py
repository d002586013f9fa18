"""Constrained thrust allocation as a small dense QP (daqp), with rate limits and forbidden sectors.

Formulation (Fossen 2021 ch. 11; Johansen, Fossen & Berge 2004, "Constrained nonlinear control
allocation with singularity avoidance using sequential quadratic programming", IEEE TCST 12(1)),
in the extended-thrust variables ``f`` of :mod:`dpcontrol.allocation.geometry` (``τ = B f``)::

    minimise    Σᵢ wᵢ Tᵢ²/Tmaxᵢ  +  ρ·‖s‖₁ + sᵀ Q s      (power-like cost + heavily weighted slack)
    subject to  B f + s = τ
                thrust limits ∩ thrust-rate limits (from the previous command over dt)
                azimuth-rate limits, forbidden azimuth sectors, rudder-angle and rudder-rate limits
                thrusters marked unavailable: f = 0

* Cost: for thrusters of one technology the power ∝ T^{3/2}/D with Tmax ∝ D², so the optimal
  split of a force is ``Tᵢ ∝ Tmaxᵢ`` (equal loading); the quadratic ``T²/Tmax`` has the same
  optimality condition and keeps the QP convex. ``thrust_weights`` multiply it per thruster;
  the rudder lift ``F_l`` gets ``rudder_lift_weight`` (lift costs drag, not propeller power).
* Azimuths (extended thrust ``(F_x, F_y)``): the circle ``|F| ≤ r`` is an inscribed polygon
  (24 sides over the full circle, sides ≤ 15° inside a sector; one vertex always at the previous
  azimuth so that holding the last command stays feasible), with ``r = min(Tmax, T_prev + Ṫ dt)``.
  The azimuth rate limit is linearised as in Johansen et al.: the force must lie in the sector
  ``[α_prev − α̇ dt, α_prev + α̇ dt]`` (two half-planes, convex while the sector is < 180°;
  wider windows — no rate limit, long dt — are cut to 171° centred towards the unconstrained
  direction). Forbidden sectors shrink that window to the allowed arc around ``α_prev``; when
  the demand cannot be met and the short way to the direction the unconstrained allocation wants
  crosses a forbidden sector, the QP is solved again with the window opened only the long way
  round; a thruster with (almost) zero thrust is slewed towards the wanted direction at the rate
  limit. The lower thrust-rate limit is the half-plane ``F·u(α_prev) ≥ T_prev − Ṫ dt``
  (conservative). Azimuths are commanded with ``T ≥ 0`` (a reversible azimuth is used forward
  only).
* Main propeller with rudder: ahead, ``(F_a, F_l)`` in the wedge ``δ_lo k_L F_a ≤ F_l ≤ δ_hi k_L F_a``
  with ``[δ_lo, δ_hi]`` the rudder-angle window reachable at the rudder rate; astern ``F_l = 0``.
  Which of the two convex pieces is used in a step follows the sign the unconstrained allocation
  wants, among those the thrust-rate limit allows; if both are allowed (thrust near zero) and that
  guess cannot meet the demand, the other combinations are solved too and the smallest shortfall
  kept. Without lift (no thrust, or astern) the rudder slews towards the angle the
  unconstrained allocation wants.
* Slack: ``s = s⁺ − s⁻`` (``s± ≥ 0``) absorbs what cannot be produced, weighted by an exact
  penalty ``ρ(s⁺ + s⁻)`` plus ``Q(s⁺² + s⁻²)`` (ρ = Q = 10⁴ in normalised units, ≫ the
  multipliers of any feasible allocation): a feasible demand is met exactly (to the solver
  tolerance, ≈ 10⁻⁹ relative), an infeasible one gives the best feasible force (the quadratic
  part spreads the shortfall over the DOFs), reported as ``shortfall_b``. A pure quadratic
  slack needs a weight ≈ 10⁸ for 10⁻⁸ accuracy, and that makes the multipliers of saturated
  allocations so large that the active-set solvers fail (daqp cycles, quadprog reports
  inconsistent constraints) — measured on this problem.

Variables are normalised by each thruster's largest thrust and the equality rows by the
capability per DOF, so the QP is well scaled for a 1 m model and a 260 m tanker alike.

Solver: daqp (dual active set for small dense QPs; one ``daqp.Model`` set up once, updated in
place every step and warm-started from the previous working set). Compared on this problem —
5000 QPs captured from an 8-azimuth allocator (16 thrust + 6 slack variables, 91 rows) under a
smooth random demand, ``benchmarks/bench_control.py --compare-solvers``, 2-core machine shared with
other jobs: daqp warm 9.5 µs median / 14 µs p99 (cold 14 / 50 µs); quadprog (dense Goldfarb–Idnani,
no warm start) 71 / 139 µs, same solutions to 6·10⁻¹³; OSQP (ADMM, warm-started, fixed sparsity,
ε = 10⁻⁷, polished) 144 µs median but 16.9 ms p99 and solutions up to 2·10⁻² away (normalised
units) — an active-set method is exact and far faster on problems this small, hence daqp (already
the project dependency). On ≈ 0.1 % of the steps daqp's warm start returns a non-finite point
(exit flag 1); the step is then solved again from an empty working set (``cold_restarts``).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import daqp
import numpy as np

from dpcontrol.allocation.geometry import AZIMUTH, FIXED, ThrusterGeometry, weighted_pseudo_inverse
from dpcontrol.models.frames import ssa, ssa_array
from dpcontrol.models.schema import ConfigError, Section, check_vector
from dpcontrol.models.thrusters import ThrusterSpec

TWO_PI = 2.0 * math.pi
_EPS_ANGLE = 1e-9
_MAX_WINDOW = 0.95 * math.pi    # largest convex azimuth window
_MIN_WINDOW = 1e-7              # narrower windows are treated as a fixed direction
_ZERO_THRUST = 1e-9             # |F|/Tmax below which a direction (azimuth, rudder) is not defined by F
_SATURATION_TOLERANCE = 1e-6    # shortfall / capability per DOF above which the demand is "saturated"
_INACTIVE = 1.0                 # bound of unused (all-zero) constraint rows
_MAX_RUDDER_ENUMERATION = 3     # ahead/astern combinations tried for at most this many rudders
_SUM = np.add.reduce            # the C reduction behind ndarray.sum, without its Python-level wrapper


@dataclass(frozen=True, eq=False)
class AllocationResult:
    """One allocation.

    Attributes
    ----------
    thrust_n : ndarray, shape (n,)
        Thrust command per thruster [N] (>= 0 for azimuths).
    azimuth_rad : ndarray, shape (n,)
        Azimuth for azimuths, rudder angle for ``propeller_rudder``, the fixed ``angle_rad`` for
        tunnels and propellers [rad].
    tau_achieved_b : ndarray, shape (3,)
        Generalized force of these commands ``[N, N, N·m]``.
    shortfall_b : ndarray, shape (3,)
        ``τ_demand − τ_achieved``.
    saturated : bool
        The demand could not be met (shortfall above 10⁻⁶ of the capability in some DOF).
    solver_status : str
        ``optimal``, or ``fallback`` (solver failure: previous commands held within the limits).
    iterations : int
        Active-set iterations.
    """

    thrust_n: np.ndarray
    azimuth_rad: np.ndarray
    tau_achieved_b: np.ndarray
    shortfall_b: np.ndarray
    saturated: bool
    solver_status: str
    iterations: int


class ThrustAllocator:
    """Constrained QP thrust allocation for a set of thrusters (see module docstring).

    Parameters
    ----------
    thrusters : sequence of ThrusterSpec
        The layout (order = order of the commands).
    sample_time_s : float
        Default time between allocations for the rate limits [s].
    thrust_weights : sequence of float, optional
        Cost multipliers per thruster (default 1).
    rudder_lift_weight : float
        Cost multiplier of the rudder lift relative to the propeller thrust.
    slack_weight : float or 3 floats
        ``Q`` in normalised units (default 1e4).
    slack_penalty : float or 3 floats
        ``ρ`` in normalised units (default 1e4).
    polygon_sides : int
        Sides of the inscribed polygon over a full circle (>= 8).

    Notes
    -----
    The matrices of the QP are allocated once; every call updates them in place and re-solves
    the same ``daqp.Model`` (warm start from the previous working set). The last command is the
    state (:meth:`state_dict`): rate limits continue from it unless feedback is given.

    Per call, the work around the solver is written for small thruster counts: the constraint rows
    are updated with a few numpy calls on preallocated arrays and views (no per-call allocation of
    the QP data), and the commands are extracted on Python floats (see :meth:`_commands`) — about
    half the cost of the earlier fully vectorised form (shuttle tanker 100 → 45 µs, six azimuths
    78 → 40 µs per call, same results bit for bit).
    """

    def __init__(self, thrusters: Sequence[ThrusterSpec], sample_time_s: float, *,
                 thrust_weights: Sequence[float] | None = None, rudder_lift_weight: float = 0.5,
                 slack_weight: float | Sequence[float] = 1e4, slack_penalty: float | Sequence[float] = 1e4,
                 polygon_sides: int = 24) -> None:
        if not (isinstance(sample_time_s, (int, float)) and math.isfinite(sample_time_s) and sample_time_s > 0.0):
            raise ValueError(f"sample_time_s must be finite and > 0, got {sample_time_s!r}")
        if not isinstance(polygon_sides, int) or polygon_sides < 8:
            raise ValueError("polygon_sides must be an integer >= 8")
        geo = ThrusterGeometry.build(thrusters)
        self._geo = geo
        self._specs = geo.specs
        n = self._n = len(geo.specs)
        nf = self._nf = geo.n_variables
        self._dt = float(sample_time_s)
        self._sides = polygon_sides

        weights = np.ones(n) if thrust_weights is None else np.asarray(thrust_weights, dtype=float)
        if weights.shape != (n,) or not np.all(np.isfinite(weights)) or np.any(weights <= 0.0):
            raise ValueError(f"thrust_weights must be {n} finite numbers > 0")
        if not (math.isfinite(rudder_lift_weight) and rudder_lift_weight > 0.0):
            raise ValueError("rudder_lift_weight must be > 0")
        slack = np.broadcast_to(np.asarray(slack_weight, dtype=float), (3,)).copy()
        penalty = np.broadcast_to(np.asarray(slack_penalty, dtype=float), (3,)).copy()
        if not (np.all(np.isfinite(slack)) and np.all(slack > 0.0) and np.all(np.isfinite(penalty))
                and np.all(penalty >= 0.0)):
            raise ValueError("slack_weight must be > 0 and slack_penalty >= 0")

        # --- per-thruster data
        specs = self._specs
        self._thrust_max = np.array([s.max_thrust_n for s in specs])
        # azimuths are commanded forward only (T >= 0)
        self._thrust_min = np.array([0.0 if geo.mode[i] == AZIMUTH else s.min_thrust_n for i, s in enumerate(specs)])
        self._thrust_rate = np.array([s.thrust_rate_limit_nps for s in specs])
        self._angle_rate = np.array([math.inf if s.azimuth_rate_limit_radps is None else s.azimuth_rate_limit_radps
                                     for s in specs])
        self._fixed_angle = np.array([s.angle_rad for s in specs])

        # --- scaling: variables by thruster size, equality rows by capability per DOF
        self._var_scale = geo.scale_n[geo.variable_thruster].astype(float)
        capability = np.abs(geo.B) @ self._var_scale
        self._tau_scale = np.where(capability > 0.0, capability, 1.0)
        w_var = weights[geo.variable_thruster] * self._var_scale / float(np.mean(geo.scale_n))
        w_var[geo.first_variable[geo.rudder_index] + 1] *= rudder_lift_weight
        # physical weights for the pseudo-inverse: Σ w T²/Tmax = Σ (w_var/scale²) f²
        self._w_phys = w_var / self._var_scale**2
        self._pinv_cache: dict[bytes, np.ndarray] = {}

        # --- index sets
        self._fix = geo.fixed_index
        self._fix_var = geo.first_variable[self._fix]
        self._rud = geo.rudder_index
        self._rud_var = geo.first_variable[self._rud]
        self._az = geo.azimuth_index
        self._az_x = geo.first_variable[self._az]
        self._az_y = self._az_x + 1
        self._az_scale = self._var_scale[self._az_x]
        self._sectors = [self._normalise_sectors(specs[i]) for i in self._az]
        self._sector_azimuths = [q for q, sectors in enumerate(self._sectors) if sectors]

        # --- constraint rows: 3 equalities, then per azimuth a contiguous block [chords, cone low
        # edge, cone high edge, lower thrust rate], then 2 wedge rows per rudder. The number of
        # chords per azimuth is what the widest window at up to twice the sample time needs (at
        # least 8; P + 2 when some azimuth has no rate limit or forbidden sectors): a narrow
        # rate window needs one chord either side of the previous azimuth.
        n_az = self._az.size
        side = TWO_PI / polygon_sides
        need = 8
        for i in self._az:
            spec = specs[i]
            if spec.azimuth_rate_limit_radps is None or spec.forbidden_sectors_rad:
                need = polygon_sides + 2
            else:
                need = max(need, 2 * math.ceil(2.0 * spec.azimuth_rate_limit_radps * self._dt / side))
        chords = self._chords = min(need, polygon_sides + 2)
        block = chords + 3
        self._az_rows = 3 + np.arange(n_az * block).reshape(n_az, block)
        row = 3 + n_az * block
        self._rud_rows = row + 2 * np.arange(self._rud.size)
        m = row + 2 * self._rud.size
        self._vertex = np.arange(chords + 1)[None, :].astype(float)
        self._inv_side = 1.0 / side
        self._az_rate = self._angle_rate[self._az]
        self._az_eps2 = (_ZERO_THRUST * self._az_scale) ** 2
        self._az_tmax = self._thrust_max[self._az]

        nv = self._nv = nf + 6  # f, s⁺, s⁻
        self._A = np.zeros((m, nv))
        self._A[:3, :nf] = geo.B * self._var_scale[None, :] / self._tau_scale[:, None]
        self._A[:3, nf:nf + 3] = np.eye(3)
        self._A[:3, nf + 3:] = -np.eye(3)
        self._H = np.diag(np.concatenate([2.0 * w_var, 2.0 * slack, 2.0 * slack]))
        self._linear = np.concatenate([np.zeros(nf), penalty, penalty])
        self._upper = np.full(nv + m, _INACTIVE)
        self._lower = np.full(nv + m, -_INACTIVE)
        self._upper[nf:nv] = np.inf
        self._lower[nf:nv] = 0.0
        sense = np.zeros(nv + m, dtype=np.int32)
        sense[nv:nv + 3] = 5  # equality rows B f + s⁺ − s⁻ = τ
        self._sense = sense
        self.cold_restarts = 0  # diagnostics: solves repeated without warm start
        self._upper[nv:nv + 3] = 0.0
        self._lower[nv:nv + 3] = 0.0
        # writable strided views of the azimuth blocks: element (q, r) is row r of azimuth q's
        # block in the column of its F_x (F_y) variable, which is 2q (2q + 1)
        stride_row, stride_col = self._A.strides
        view_shape = (n_az, block)
        view_strides = (block * stride_row + 2 * stride_col, stride_row)
        self._blk_x = np.lib.stride_tricks.as_strided(self._A[3:, 0:], view_shape, view_strides, writeable=True)
        self._blk_y = np.lib.stride_tricks.as_strided(self._A[3:, 1:], view_shape, view_strides, writeable=True)
        self._blk_u = self._upper[nv + 3:nv + 3 + n_az * block].reshape(view_shape)
        self._blk_l = self._lower[nv + 3:nv + 3 + n_az * block].reshape(view_shape)
        self._az_bounds_u = self._upper[:2 * n_az].reshape(n_az, 2)
        self._az_bounds_l = self._lower[:2 * n_az].reshape(n_az, 2)
        self._model = daqp.Model()
        self._model.settings = {"primal_tol": 1e-9, "iter_limit": 2000}
        status, _ = self._model.setup(self._H, self._linear, self._A, self._upper, self._lower, sense)
        if status < 0:
            raise RuntimeError(f"daqp setup failed (status {status})")

        # --- per-step working arrays (thrust window, azimuth windows, rudder windows)
        self._t_lo = np.zeros(n)
        self._t_hi = np.zeros(n)
        self._az_lo = np.zeros(n_az)
        self._az_hi = np.zeros(n_az)
        self._az_full = np.zeros(n_az, dtype=bool)
        self._az_blocked = np.zeros(n_az, dtype=bool)
        self._az_target: np.ndarray | None = np.full(n_az, np.nan)
        self._az_arc_lo = np.full(n_az, -np.inf)
        self._az_arc_hi = np.full(n_az, np.inf)
        self._no_arc_lo = np.full(n_az, -np.inf)
        self._no_arc_hi = np.full(n_az, np.inf)
        self._no_block = np.zeros(n_az, dtype=bool)
        self._az_long_way = np.zeros(n_az, dtype=bool)
        self._narrow_dt = -1.0
        self._narrow_ok = False
        self._narrow_layout = False
        self._narrow_offsets = np.zeros((n_az, 5))
        self._narrow_cos_half = np.ones(n_az)
        self._unused = np.zeros((n_az, self._chords + 3), dtype=bool)
        self._rud_window = [(0.0, 0.0)] * self._rud.size   # (δ_lo, δ_hi) per rudder, Python floats
        self._rud_ahead = np.ones(self._rud.size, dtype=bool)
        self._rud_ambiguous = np.zeros(self._rud.size, dtype=bool)
        # per rudder, the constants of _rudder_constraints/_commands as Python floats and ints (numpy
        # scalar reads and spec attribute look-ups cost more than the arithmetic they feed)
        self._rud_data = [
            (int(i), int(j), int(row), float(self._var_scale[j]), specs[i].rudder_lift_per_rad,
             float(specs[i].rudder_max_angle_rad or 0.0), float(self._angle_rate[i]), specs[i].max_thrust_n,
             specs[i].min_thrust_n, _ZERO_THRUST * float(self._var_scale[j]))
            for i, j, row in zip(self._rud, self._rud_var, self._rud_rows, strict=True)]

        # --- the per-step work of allocate() on preallocated arrays (each numpy call on these small
        # arrays costs about as much as its arithmetic on a thousand elements: few calls, no allocation)
        self._eq_upper = self._upper[nv:nv + 3]          # the equality rows B f + s⁺ − s⁻ = τ
        self._eq_lower = self._lower[nv:nv + 3]
        self._tau_scale_list = self._tau_scale.tolist()
        self._saturation_limit = (_SATURATION_TOLERANCE * self._tau_scale).tolist()
        self._all_true = np.ones(n, dtype=bool)
        self._all_true.setflags(write=False)
        self._all_on_key = self._all_true.tobytes()
        self._prev_t_buf = np.zeros(n)                   # previous thrust clamped to the limits
        self._low_all = np.zeros(n)                      # T_prev − Ṫ dt
        self._high_all = np.zeros(n)                     # T_prev + Ṫ dt
        self._step_dt = math.nan                         # dt of _step_all (recomputed when dt changes)
        self._step_all = np.zeros(n)                     # Ṫ dt
        # the fixed thrusters' variables are contiguous, last (geometry orders them so)
        fix_start = nf - self._fix.size
        if not np.array_equal(self._fix_var, np.arange(fix_start, nf)):
            raise RuntimeError("internal: fixed-thruster variables must be the last, contiguous ones")
        self._fix_lower = self._lower[fix_start:nf]
        self._fix_upper = self._upper[fix_start:nf]
        self._fix_scale = self._var_scale[fix_start:nf]
        self._fix_work = np.zeros(self._fix.size)
        # per thruster, the constants of _commands as Python numbers
        self._fix_data = [(int(i), int(j), float(self._fixed_angle[i])) for i, j in zip(self._fix, self._fix_var,
                                                                                       strict=True)]
        self._az_data = [(int(i), float(eps), float(rate)) for i, eps, rate in
                         zip(self._az, _ZERO_THRUST * self._az_scale, self._angle_rate[self._az], strict=True)]
        self._az_eps2_list = self._az_eps2.tolist()
        self._B = geo.B
        # narrow azimuth windows: the ten trigonometric values of each block [cos of (chord mid left,
        # chord mid right, window low edge, window high edge, α_prev), sin of the same] go into A with
        # one put; these are their flat positions and signs (rows of _azimuth_constraints_narrow)
        c = chords
        block_rows = 3 + np.arange(n_az)[:, None] * block
        col_x = 2 * np.arange(n_az)[:, None]
        rows_cos = block_rows + np.array([0, 1, c, c + 1, c + 2])[None, :]
        cols_cos = col_x + np.array([0, 0, 1, 1, 0])[None, :]     # cos → X, X, Y, Y, X
        cols_sin = col_x + np.array([1, 1, 0, 0, 1])[None, :]     # sin → Y, Y, X, X, Y
        self._narrow_put = np.concatenate([rows_cos * nv + cols_cos, rows_cos * nv + cols_sin], axis=1)
        self._narrow_sign = np.tile(np.array([1.0, 1.0, -1.0, 1.0, 1.0, 1.0, 1.0, 1.0, -1.0, 1.0]), (n_az, 1))
        self._narrow_angles = np.zeros((n_az, 5))
        self._narrow_trig = np.zeros((n_az, 10))
        self._narrow_cos_half2 = np.ones((n_az, 2))
        self._az_a = np.zeros(n_az)                      # α_prev of the azimuths
        self._az_t_lo = np.zeros(n_az)                   # their thrust window this step
        self._az_t_hi = np.zeros(n_az)
        self._az_r = np.zeros(n_az)                      # normalised radius
        self._az_low = np.zeros(n_az)
        self._az_flag = np.zeros(n_az, dtype=bool)
        # views of the arrays above that _azimuth_constraints_narrow writes every step (a view costs as
        # much to create as the operation on it)
        self._az_a_col = self._az_a[:, None]
        self._az_r_col = self._az_r[:, None]
        self._narrow_cos = self._narrow_trig[:, :5]
        self._narrow_sin = self._narrow_trig[:, 5:]
        self._narrow_u01 = self._blk_u[:, 0:2]
        self._narrow_lower_rate = self._blk_l[:, chords + 2]
        self._narrow_lo = self._narrow_angles[:, 2]
        self._narrow_hi = self._narrow_angles[:, 3]

        # --- inputs of the current step (set by allocate)
        self._c_mask = np.ones(n, dtype=bool)
        self._c_all_on = True
        self._c_prev_t = np.zeros(n)
        self._c_prev_a = np.zeros(n)
        self._c_f_star = np.zeros(nf)
        self._c_step = np.zeros(n)
        self._c_dt = self._dt

        # --- last command (the rate limits continue from it)
        self._thrust = np.zeros(n)
        self._thrust_in_limits = True  # within [T_min, T_max]: every command of allocate() is
        self._angle = np.where(geo.mode == FIXED, self._fixed_angle, 0.0)

    # ------------------------------------------------------------------ properties
    @property
    def thrusters(self) -> tuple[ThrusterSpec, ...]:
        return self._specs

    @property
    def geometry(self) -> ThrusterGeometry:
        return self._geo

    @property
    def sample_time_s(self) -> float:
        return self._dt

    @property
    def capability_scale(self) -> np.ndarray:
        """Per-DOF scale of the generalized force (Σ |B| · Tmax) ``[N, N, N·m]`` (copy)."""
        return self._tau_scale.copy()

    @property
    def last_command(self) -> tuple[np.ndarray, np.ndarray]:
        """``(thrust_n, azimuth_rad)`` of the last command (copies)."""
        return self._thrust.copy(), self._angle.copy()

    def pseudo_inverse(self, available: np.ndarray | None = None) -> np.ndarray:
        """Weighted pseudo-inverse ``(n_f, 3)`` over the available thrusters (same weights as the QP)."""
        mask = self._available(available)
        return self._pinv(mask, mask.tobytes())

    def _pinv(self, mask: np.ndarray, key: bytes) -> np.ndarray:
        """:meth:`pseudo_inverse` of a checked mask and its bytes (cached per mask)."""
        cached = self._pinv_cache.get(key)
        if cached is None:
            cols = self._geo.variables_of(mask)
            cached = np.zeros((self._nf, 3))
            if cols.any():
                cached[cols] = weighted_pseudo_inverse(self._geo.B[:, cols], self._w_phys[cols])
            cached.setflags(write=False)
            self._pinv_cache[key] = cached
        return cached

    def unconstrained(self, tau_b: np.ndarray, available: np.ndarray | None = None) -> np.ndarray:
        """Extended thrust ``f`` (n_f,) of the weighted pseudo-inverse (no limits)."""
        return self.pseudo_inverse(available) @ _vector3("tau_b", tau_b)

    def qp_snapshot(self) -> dict[str, np.ndarray]:
        """Copies of the last QP (``H, f, A, bupper, blower, sense``; daqp conventions) — for diagnostics
        and solver comparisons."""
        sense = np.zeros(self._upper.size, dtype=np.int32)
        sense[self._nv:self._nv + 3] = 5
        return {"H": self._H.copy(), "f": self._linear.copy(), "A": self._A.copy(),
                "bupper": self._upper.copy(), "blower": self._lower.copy(), "sense": sense,
                "n_variables": np.array(self._nf)}

    # ------------------------------------------------------------------ allocation
    def allocate(self, tau_b: np.ndarray, available: np.ndarray | None = None,
                 previous_thrust_n: np.ndarray | None = None, previous_azimuth_rad: np.ndarray | None = None,
                 dt_s: float | None = None) -> AllocationResult:
        """Allocate a generalized force to the thrusters.

        Parameters
        ----------
        tau_b : array_like, shape (3,)
            Demanded force ``[N, N, N·m]`` in body axes.
        available : array_like of bool, shape (n,), optional
            False marks a thruster unavailable (commanded 0; default all available).
        previous_thrust_n, previous_azimuth_rad : array_like, shape (n,), optional
            Feedback of the delivered thrust and azimuth/rudder angle; non-finite entries fall
            back to the last command. Default: the last command.
        dt_s : float, optional
            Time over which the rate limits apply (default ``sample_time_s``).

        Returns
        -------
        AllocationResult

        Raises
        ------
        ValueError
            On a malformed or non-finite demand, mask, feedback shape or dt (state unchanged).
        """
        tau = _vector3("tau_b", tau_b)
        mask = self._available(available)
        dt = self._dt if dt_s is None else dt_s
        if not (isinstance(dt, (int, float)) and math.isfinite(dt) and dt > 0.0):
            raise ValueError(f"dt_s must be finite and > 0, got {dt_s!r}")
        # the previous thrust clamped to the limits; the last command of allocate() is within them already
        # (the last command arrays are replaced, never modified in place, and prev_t is only read)
        if previous_thrust_n is None and self._thrust_in_limits:
            prev_t = self._thrust
        else:  # minimum/maximum with out= is np.clip without its Python-level wrapper
            prev_t = self._prev_t_buf
            np.maximum(self._feedback("previous_thrust_n", previous_thrust_n, self._thrust), self._thrust_min,
                       out=prev_t)
            np.minimum(prev_t, self._thrust_max, out=prev_t)
        prev_a = self._feedback("previous_azimuth_rad", previous_azimuth_rad, self._angle)
        key = mask.tobytes()
        all_on = key == self._all_on_key
        f_star = self._pinv(mask, key) @ tau
        if dt != self._step_dt:
            np.multiply(self._thrust_rate, dt, out=self._step_all)
            self._step_dt = dt
        step = self._step_all
        # the thrust window every thruster type starts from: [max(T_min, T_prev − Ṫdt), min(T_max, T_prev + Ṫdt)],
        # zero for an unavailable thruster (the rudders' own windows are set by _rudder_constraints)
        np.subtract(prev_t, step, out=self._low_all)
        np.add(prev_t, step, out=self._high_all)
        np.maximum(self._thrust_min, self._low_all, out=self._t_lo)
        np.minimum(self._thrust_max, self._high_all, out=self._t_hi)
        if not all_on:
            off = ~mask
            self._t_lo[off] = 0.0
            self._t_hi[off] = 0.0
        # the inputs of this step, read by the per-thruster-type methods below
        self._c_mask, self._c_all_on, self._c_prev_t, self._c_prev_a = mask, all_on, prev_t, prev_a
        self._c_f_star, self._c_step, self._c_dt = f_star, step, dt

        np.divide(tau, self._tau_scale, out=self._eq_upper)
        np.copyto(self._eq_lower, self._eq_upper)
        if self._fix.size:
            self._fixed_constraints()
        for q in range(self._rud.size):
            self._rudder_constraints(q)
        if self._az.size:
            self._azimuth_constraints()
        best = self._solve(tau)
        if best[3] > 0.0 and self._rud.size:
            ambiguous = np.flatnonzero(self._rud_ambiguous)
            if 0 < ambiguous.size <= _MAX_RUDDER_ENUMERATION:
                # ahead/astern of a propeller with rudder near zero thrust is a binary choice (the
                # union of two convex pieces): when the first guess cannot meet the demand, try the
                # other combinations and keep the smallest shortfall
                first = tuple(bool(v) for v in self._rud_ahead[ambiguous])
                chosen = first
                for combination in itertools.product((True, False), repeat=ambiguous.size):
                    if combination == first:
                        continue
                    self._set_rudder_modes(ambiguous, combination)
                    candidate = self._solve(tau)
                    if candidate[3] < best[3]:
                        best, chosen = candidate, combination
                self._set_rudder_modes(ambiguous, chosen)
        if best[3] > 0.0 and self._az_long_way.any():
            # the demand cannot be met this step and the short way of some azimuth to the direction
            # it is wanted in crosses a forbidden sector: open its window only the long way round
            # (otherwise it would sit at the sector edge for ever)
            self._azimuth_constraints(long_way=True)
            best = self._solve(tau)
        thrust, angle, achieved, _, status, iterations = best
        shortfall = tau - achieved
        # |shortfall| > 10⁻⁶ · capability in some DOF, on Python floats (three numpy reductions cost more)
        s0, s1, s2 = shortfall.tolist()
        l0, l1, l2 = self._saturation_limit
        saturated = abs(s0) > l0 or abs(s1) > l1 or abs(s2) > l2
        self._thrust = thrust
        self._thrust_in_limits = True
        self._angle = angle
        return AllocationResult(thrust_n=thrust.copy(), azimuth_rad=angle.copy(), tau_achieved_b=achieved,
                                shortfall_b=shortfall, saturated=saturated, solver_status=status,
                                iterations=iterations)

    def _set_rudder_modes(self, rudders: np.ndarray, ahead: tuple[bool, ...]) -> None:
        for q, mode in zip(rudders, ahead, strict=True):
            self._rudder_constraints(int(q), mode)

    def _solve(self, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, str, int]:
        """Solve the QP as set up; ``(thrust, angle, achieved, normalised shortfall, status, iterations)``."""
        self._model.update(A=self._A, bupper=self._upper, blower=self._lower)
        x, _, exitflag, info = self._model.solve()
        iterations = int(info.get("iterations", 0))
        # finite solution: one C-level reduction (x are normalised values, their sum cannot overflow;
        # a NaN or an infinity makes it non-finite)
        ok = exitflag >= 1 and math.isfinite(_SUM(x))
        if not ok:
            # the warm start can fail when rows of the previous working set changed structure (a
            # chord row now unused, a layout switch): solve again from an empty working set
            self._model.update(A=self._A, bupper=self._upper, blower=self._lower, sense=self._sense)
            x, _, exitflag, info = self._model.solve()
            iterations += int(info.get("iterations", 0))
            self.cold_restarts += 1
            ok = exitflag >= 1 and math.isfinite(_SUM(x))
        if ok:
            f = np.asarray(x[: self._nf]) * self._var_scale
            status = "optimal"
        else:  # not seen in testing: every constraint set contains the held previous command
            f = None
            status = "fallback"
        thrust, angle, f_cmd = self._commands(f)
        achieved = self._B @ f_cmd
        # Σ|τ − τ_achieved|/capability if some DOF misses by more than 10⁻⁶ (Python floats: 3 values)
        t0, t1, t2 = tau.tolist()
        a0, a1, a2 = achieved.tolist()
        c0, c1, c2 = self._tau_scale_list
        e0, e1, e2 = abs(t0 - a0) / c0, abs(t1 - a1) / c1, abs(t2 - a2) / c2
        tol = _SATURATION_TOLERANCE
        score = e0 + e1 + e2 if (e0 > tol or e1 > tol or e2 > tol) else 0.0
        return thrust, angle, achieved, score, status, iterations

    # ------------------------------------------------------------------ constraints per thruster type
    def _fixed_constraints(self) -> None:
        """Bounds of the fixed-direction thrusters: their window of allocate(), normalised."""
        work = self._fix_work
        self._t_lo.take(self._fix, out=work)
        np.divide(work, self._fix_scale, out=self._fix_lower)
        self._t_hi.take(self._fix, out=work)
        np.divide(work, self._fix_scale, out=self._fix_upper)

    def _rudder_constraints(self, q: int, force_ahead: bool | None = None) -> None:
        i, j, row, scale, k_lift, delta_max, angle_rate, max_thrust, min_thrust, _ = self._rud_data[q]
        A, upper, lower = self._A, self._upper, self._lower
        r0 = self._nv + row
        # scalar writes: cheaper than slice assignments for two elements
        A[row, j] = A[row, j + 1] = A[row + 1, j] = A[row + 1, j + 1] = 0.0
        upper[r0] = upper[r0 + 1] = _INACTIVE
        lower[r0] = lower[r0 + 1] = -_INACTIVE
        delta_prev = min(max(float(self._c_prev_a[i]), -delta_max), delta_max)
        step_delta = angle_rate * self._c_dt
        d_lo = max(-delta_max, delta_prev - step_delta)
        d_hi = min(delta_max, delta_prev + step_delta)
        self._rud_window[q] = (d_lo, d_hi)
        if not self._c_mask[i]:
            self._t_lo[i] = self._t_hi[i] = 0.0
            self._rud_ahead[q] = True
            self._rud_ambiguous[q] = False
            lower[j] = lower[j + 1] = upper[j] = upper[j + 1] = 0.0
            return
        t_prev = float(self._c_prev_t[i])
        step = float(self._c_step[i])
        ahead_lo = max(0.0, t_prev - step)
        ahead_hi = min(max_thrust, t_prev + step)
        astern_lo = max(min_thrust, t_prev - step)
        astern_hi = min(0.0, t_prev + step)
        ahead_ok = ahead_lo <= ahead_hi
        astern_ok = astern_lo <= astern_hi and min_thrust < 0.0
        self._rud_ambiguous[q] = ahead_ok and astern_ok
        if force_ahead is not None and ahead_ok and astern_ok:
            ahead = force_ahead
        else:
            ahead = ahead_ok and (not astern_ok or self._c_f_star[j] >= 0.0)
        self._rud_ahead[q] = ahead
        if ahead:
            self._t_lo[i], self._t_hi[i] = ahead_lo, ahead_hi
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
            upper[r0] = upper[r0 + 1] = 0.0
            lower[r0] = lower[r0 + 1] = -np.inf
        else:
            self._t_lo[i], self._t_hi[i] = astern_lo, astern_hi
            lower[j] = astern_lo / scale
            upper[j] = astern_hi / scale
            lower[j + 1] = upper[j + 1] = 0.0

    def _azimuth_constraints(self, long_way: bool = False) -> None:
        mask, prev_t, prev_a = self._c_mask, self._c_prev_t, self._c_prev_a
        f_star, step, dt = self._c_f_star, self._c_step, self._c_dt
        if not self._sector_azimuths and self._narrow_windows(dt):
            self._azimuth_constraints_narrow()
            return
        if self._narrow_layout:
            self._model.update(sense=self._sense)  # rows change structure: no stale working set
            self._narrow_layout = False  # the general path rewrites every row of the blocks
        az = self._az
        n2 = 2 * az.size
        a = prev_a[az]
        fx = f_star[0:n2:2]
        fy = f_star[1:n2:2]
        target = a + ssa_array(np.arctan2(fy, fx) - a)
        target[fx * fx + fy * fy <= self._az_eps2] = np.nan  # no wanted direction
        delta = self._az_rate * dt
        lo = a - delta
        hi = a + delta
        if self._sector_azimuths:
            arc_lo = np.full(az.size, -np.inf)
            arc_hi = np.full(az.size, np.inf)
            blocked = np.zeros(az.size, dtype=bool)
            side = np.zeros(az.size)
            for q in self._sector_azimuths:
                wanted = None if math.isnan(target[q]) else float(target[q])
                blocked[q], arc_lo[q], arc_hi[q], target[q], side[q] = self._sector_window(
                    float(a[q]), self._sectors[q], wanted)
            np.maximum(lo, arc_lo, out=lo)
            np.minimum(hi, arc_hi, out=hi)
        else:
            arc_lo, arc_hi, blocked, side = self._no_arc_lo, self._no_arc_hi, self._no_block, None
        full = (hi - lo) >= TWO_PI
        wide = ~full & (hi - lo > _MAX_WINDOW)
        if wide.any():
            # a window of 171° towards the wanted direction, containing the previous azimuth
            half = 0.5 * _MAX_WINDOW
            centre = np.clip(np.where(np.isnan(target), a, target), lo + half, hi - half)
            centre = np.clip(centre, a - half, a + half)
            lo = np.where(wide, centre - half, lo)
            hi = np.where(wide, centre + half, hi)
        if side is not None:
            narrow = ~full & ~wide
            self._az_long_way = narrow & (side != 0.0)
            if long_way:
                lo = np.where(self._az_long_way & (side > 0.0), a, lo)
                hi = np.where(self._az_long_way & (side < 0.0), a, hi)
            lo = np.where(blocked, a, lo)
            hi = np.where(blocked, a, hi)
        self._az_lo, self._az_hi, self._az_full, self._az_blocked = lo, hi, full, blocked
        self._az_target, self._az_arc_lo, self._az_arc_hi = target, arc_lo, arc_hi

        # thrust window and simple bounds
        t_prev = prev_t[az]
        radius = np.minimum(self._az_tmax, t_prev + step[az])
        low = t_prev - step[az]
        active = mask[az] & (radius > 0.0)
        if side is not None:
            active &= ~blocked
        self._t_lo[az] = np.where(active, np.maximum(low, 0.0), 0.0)
        self._t_hi[az] = np.where(active, radius, 0.0)
        self._t_lo.take(az, out=self._az_t_lo)   # what _azimuth_commands reads
        self._t_hi.take(az, out=self._az_t_hi)
        self._az_a[:] = a
        r = np.where(active, radius / self._az_scale, 0.0)
        self._az_bounds_u[:] = r[:, None]
        np.negative(self._az_bounds_u, out=self._az_bounds_l)

        # inscribed polygon: vertices from lo to hi with one at the previous azimuth (full circle: P sides)
        if full.any():
            lo = np.where(full, a - TWO_PI, lo)
            hi = np.where(full, a, hi)
        tiny = hi - lo < _MIN_WINDOW
        if tiny.any():
            lo = np.where(tiny, a - 0.5 * _MIN_WINDOW, lo)
            hi = np.where(tiny, a + 0.5 * _MIN_WINDOW, hi)
        left = a - lo
        right = hi - a
        k1 = np.ceil(left * self._inv_side - 1e-9)
        k2 = np.ceil(right * self._inv_side - 1e-9)
        c = self._chords
        over = k1 + k2 > c
        if over.any():  # a window wider than the rows were sized for: fewer, longer chords
            share = np.clip(np.round(c * left / (left + right)), k1 > 0, c - (k2 > 0))
            k1 = np.where(over, share, k1)
            k2 = np.where(over, c - share, k2)
        m = self._vertex
        k1c = k1[:, None]
        vertices = np.where(m <= k1c, lo[:, None] + left[:, None] * (m / np.maximum(k1c, 1.0)),
                            a[:, None] + right[:, None] * ((m - k1c) / np.maximum(k2[:, None], 1.0)))
        X, Y, U, L = self._blk_x, self._blk_y, self._blk_u, self._blk_l
        mid = vertices[:, 1:] + vertices[:, :-1]
        mid *= 0.5
        np.cos(mid, out=X[:, :c])
        np.sin(mid, out=Y[:, :c])
        half_angle = vertices[:, 1:] - vertices[:, :-1]
        half_angle *= 0.5
        np.cos(half_angle, out=U[:, :c])
        U[:, :c] *= r[:, None]
        L[:, :c] = -np.inf
        # the force direction φ within [lo, hi]: sin(φ − lo) ≥ 0 and sin(hi − φ) ≥ 0
        np.sin(lo, out=X[:, c])
        np.cos(lo, out=Y[:, c])
        Y[:, c] *= -1.0
        np.sin(hi, out=X[:, c + 1])
        X[:, c + 1] *= -1.0
        np.cos(hi, out=Y[:, c + 1])
        U[:, c:c + 2] = 0.0
        L[:, c:c + 2] = -np.inf
        # lower thrust-rate limit: F·u(α_prev) ≥ T_prev − Ṫ dt
        np.cos(a, out=X[:, c + 2])
        np.sin(a, out=Y[:, c + 2])
        U[:, c + 2] = np.inf
        np.divide(low, self._az_scale, out=L[:, c + 2])
        # rows not in use this step become 0·f ∈ [−1, 1]
        unused = self._unused
        np.greater_equal(m[:, :-1], (k1 + k2)[:, None], out=unused[:, :c])
        unused[:, c] = full
        unused[:, c + 1] = full
        np.less_equal(low, 0.0, out=unused[:, c + 2])
        unused |= ~active[:, None]
        X[unused] = 0.0
        Y[unused] = 0.0
        U[unused] = _INACTIVE
        L[unused] = -_INACTIVE

    def _narrow_windows(self, dt: float) -> bool:
        """Whether every azimuth's window this step is the plain rate window ``α_prev ± α̇ dt`` with
        one chord either side (rate-limited, ``α̇ dt`` ≤ one polygon side, no sectors) — the usual
        case at a DP sample rate, handled by :meth:`_azimuth_constraints_narrow`."""
        if abs(dt - self._narrow_dt) > 1e-9 * dt:  # recompute only when dt really changes
            delta = self._az_rate * dt
            self._narrow_ok = bool(np.all(np.isfinite(delta)) and np.all(delta * self._inv_side <= 1.0)
                                   and np.all(delta >= _MIN_WINDOW))
            if self._narrow_ok:
                # angles of [chord mid left, chord mid right, window low edge, window high edge, α_prev]
                self._narrow_offsets = np.stack([-0.5 * delta, 0.5 * delta, -delta, delta,
                                                 np.zeros_like(delta)], axis=1)
                self._narrow_cos_half = np.cos(0.5 * delta)
                self._narrow_cos_half2[:] = self._narrow_cos_half[:, None]
            self._narrow_dt = dt
        return self._narrow_ok

    def _azimuth_constraints_narrow(self) -> None:
        """The constraints of :meth:`_azimuth_constraints` for narrow rate windows, in few numpy calls.

        The block layout is fixed here (two chords, two cone edges, the lower-rate row; the other
        chord rows unused), so only the angles and bounds change from step to step; an unavailable
        thruster only needs its variables bounded to zero (every row holds at F = 0). The rows are::

            chords       [cos m, sin m]·F ≤ r cos(α̇dt/2),  m = α_prev ∓ α̇dt/2
            φ ≥ α_prev − α̇dt:  [sin lo, −cos lo]·F ≤ 0;    φ ≤ α_prev + α̇dt:  [−sin hi, cos hi]·F ≤ 0
            lower thrust rate  [cos α_prev, sin α_prev]·F ≥ (T_prev − Ṫdt)/T_max   (only if > 0)
        """
        c = self._chords
        if not self._narrow_layout:
            X, Y, U, L = self._blk_x, self._blk_y, self._blk_u, self._blk_l
            self._model.update(sense=self._sense)  # rows change structure: no stale working set
            X[:, 2:c] = 0.0
            Y[:, 2:c] = 0.0
            U[:, 2:c] = _INACTIVE
            L[:, 2:c] = -_INACTIVE
            L[:, :2] = -np.inf
            U[:, c:c + 2] = 0.0
            L[:, c:c + 2] = -np.inf
            U[:, c + 2] = np.inf
            self._narrow_layout = True
        az = self._az
        self._c_prev_a.take(az, out=self._az_a)
        np.add(self._az_a_col, self._narrow_offsets, out=self._narrow_angles)
        trig = self._narrow_trig
        np.cos(self._narrow_angles, out=self._narrow_cos)
        np.sin(self._narrow_angles, out=self._narrow_sin)
        trig *= self._narrow_sign           # −cos lo and −sin hi (× −1.0 is exact)
        self._A.put(self._narrow_put, trig)
        # thrust window (allocate() zeroed it for an unavailable thruster): radius min(T_max, T_prev + Ṫdt)
        self._t_hi.take(az, out=self._az_t_hi)
        self._t_lo.take(az, out=self._az_t_lo)
        r = self._az_r
        np.divide(self._az_t_hi, self._az_scale, out=r)
        np.multiply(self._az_r_col, self._narrow_cos_half2, out=self._narrow_u01)
        # lower thrust-rate limit, inactive (−∞) unless T_prev − Ṫdt > 0 on an available thruster
        low = self._az_low
        self._low_all.take(az, out=low)
        lower_rate = self._narrow_lower_rate
        np.divide(low, self._az_scale, out=lower_rate)
        off = self._az_flag
        np.less_equal(low, 0.0, out=off)
        if not self._c_all_on:
            off |= ~self._c_mask[az]
        np.copyto(lower_rate, -np.inf, where=off)
        np.copyto(self._az_bounds_u, self._az_r_col)
        np.negative(self._az_bounds_u, out=self._az_bounds_l)
        self._az_lo = self._narrow_lo
        self._az_hi = self._narrow_hi
        self._az_full = self._no_block
        self._az_blocked = self._no_block
        self._az_target = None  # computed by the commands only if some azimuth is idle
        self._az_arc_lo = self._no_arc_lo
        self._az_arc_hi = self._no_arc_hi

    @staticmethod
    def _normalise_sectors(spec: ThrusterSpec) -> list[tuple[float, float]]:
        """Forbidden sectors as ``(start, width)`` with width in (0, 2π)."""
        out = []
        for start, end in spec.forbidden_sectors_rad:
            width = (end - start) % TWO_PI
            if width > _EPS_ANGLE:
                out.append((start % TWO_PI, width))
        return out

    @staticmethod
    def _sector_window(a: float, sectors: list[tuple[float, float]], wanted: float | None
                       ) -> tuple[bool, float, float, float, float]:
        """Allowed arc around ``a`` and the target in it: ``(blocked, arc_lo, arc_hi, target, side)``.

        ``side`` is +1/−1 when the short way to the wanted direction is blocked and the window
        must open only the long way round (0 otherwise); ``target`` is NaN without a wanted
        direction.
        """
        arc_lo, arc_hi = -math.inf, math.inf
        for start, width in sectors:
            offset = (a - start) % TWO_PI
            if _EPS_ANGLE < offset < width - _EPS_ANGLE:
                # inside a forbidden sector: no thrust; slew out towards the nearer edge
                edge = a - offset if offset <= 0.5 * width else a + (width - offset)
                return True, a, a, edge, 0.0
            up = (start - a) % TWO_PI
            if up > TWO_PI - _EPS_ANGLE:
                up = 0.0
            down = (a - (start + width)) % TWO_PI
            if down > TWO_PI - _EPS_ANGLE:
                down = 0.0
            arc_hi = min(arc_hi, a + up)
            arc_lo = max(arc_lo, a - down)
        if wanted is None:
            return False, arc_lo, arc_hi, math.nan, 0.0
        short = a + ssa(wanted - a)
        target = None
        for candidate in (short, short - TWO_PI, short + TWO_PI):
            if arc_lo - _EPS_ANGLE <= candidate <= arc_hi + _EPS_ANGLE:
                target = min(max(candidate, arc_lo), arc_hi)
                break
        if target is None:  # the wanted direction is forbidden: aim at the nearer edge
            target = arc_lo if abs(ssa(wanted - arc_lo)) <= abs(ssa(wanted - arc_hi)) else arc_hi
            return False, arc_lo, arc_hi, target, 0.0
        side = 0.0
        if abs(target - short) > _EPS_ANGLE and abs(target - a) > _EPS_ANGLE:
            side = 1.0 if target > a else -1.0
        return False, arc_lo, arc_hi, target, side

    # ------------------------------------------------------------------ commands from the solution
    def _commands(self, f: np.ndarray | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Thrust and angle commands from the QP solution ``f`` (None: hold the previous command), and
        the extended thrust of those commands (``τ_achieved = B f_cmd``).

        One pass over the thrusters on Python floats: for the handful of thrusters of a vessel this is
        cheaper than the thirty-odd numpy calls of the vectorised form (commands and achieved force
        measured at 10 µs instead of 27 µs for the shuttle tanker, 12 µs instead of 25 µs for six
        azimuths). The values are the same bit for bit.
        """
        n = self._n
        prev_t = self._c_prev_t.tolist()
        t_lo = self._t_lo.tolist()
        t_hi = self._t_hi.tolist()
        fl = None if f is None else f.tolist()
        thrust = [0.0] * n
        angle = [0.0] * n
        ext = [0.0] * self._nf
        # fixed direction thrusters: the solution clamped to the window
        for i, j, fixed_angle in self._fix_data:
            t = min(max(prev_t[i] if fl is None else fl[j], t_lo[i]), t_hi[i])
            thrust[i] = t
            angle[i] = fixed_angle
            ext[j] = t
        # propellers with rudder
        if self._rud_data:
            prev_a = self._c_prev_a.tolist()
            f_star = self._c_f_star.tolist()
            for q, (i, j, _, _, k_lift, limit, _, _, _, eps) in enumerate(self._rud_data):
                d_lo, d_hi = self._rud_window[q]
                t = min(max(prev_t[i] if fl is None else fl[j], t_lo[i]), t_hi[i])
                if fl is None:
                    delta = prev_a[i]
                elif self._rud_ahead[q] and t > eps:
                    delta = fl[j + 1] / (k_lift * t)
                else:
                    # no lift this step (no thrust, or astern): slew towards the rudder angle the
                    # unconstrained allocation wants, so that lift is available when thrust returns
                    delta = prev_a[i]
                    if f_star[j] > eps:
                        delta = min(max(f_star[j + 1] / (k_lift * f_star[j]), -limit), limit)
                delta = min(max(delta, d_lo), d_hi)
                thrust[i] = t
                angle[i] = delta
                ext[j] = t
                ext[j + 1] = t * k_lift * delta if t > 0.0 else 0.0  # lift only ahead
        if self._az_data:
            self._azimuth_commands(f, prev_t, thrust, angle, ext)
        return np.array(thrust), np.array(angle), np.array(ext)

    def _azimuth_commands(self, f: np.ndarray | None, prev_t: list[float], thrust: list[float],
                          angle: list[float], ext: list[float]) -> None:
        """T = |F| and α = atan2(F_y, F_x) (the short way from α_prev) inside the step's windows; an idle
        azimuth (no thrust) slews towards the direction the unconstrained allocation wants.

        The transcendental functions run vectorised (numpy's, so that the commands do not depend on
        which implementation of atan2/cos/sin a code path happens to use), the rest on Python floats.
        """
        n2 = 2 * len(self._az_data)
        if f is not None:
            norm = np.hypot(f[0:n2:2], f[1:n2:2]).tolist()
            atan = np.arctan2(f[1:n2:2], f[0:n2:2]).tolist()
        a_prev = self._az_a.tolist()
        t_lo = self._az_t_lo.tolist()
        t_hi = self._az_t_hi.tolist()
        lo = self._az_lo.tolist()
        hi = self._az_hi.tolist()
        full = None if self._az_full is self._no_block else self._az_full.tolist()
        blocked = None if self._az_blocked is self._no_block else self._az_blocked.tolist()
        mask = None if self._c_all_on else self._c_mask.tolist()
        target: list[float] | None = None
        directions = []
        for q, (i, eps, rate) in enumerate(self._az_data):
            a = a_prev[q]
            if f is None:
                t = prev_t[i]
                direction = a
            else:
                t = norm[q]
                direction = a + ((atan[q] - a + math.pi) % TWO_PI - math.pi)   # % is np.remainder's floor mod
            t = min(max(t, t_lo[q]), t_hi[q])
            on = mask is None or mask[i]
            is_blocked = blocked is not None and blocked[q]
            if full is None or not full[q]:
                direction = min(max(direction, lo[q]), hi[q])
            if not on or is_blocked or (t <= eps and t_lo[q] <= eps):
                # idle: slew towards the wanted direction at the rate limit, inside the allowed arc
                t = 0.0
                if on:
                    if target is None:
                        target = self._azimuth_targets(a_prev)
                    wanted = target[q]
                    step = rate * self._c_dt
                    direction = a + min(max(0.0 if math.isnan(wanted) else wanted - a, -step), step)
                    if not is_blocked:
                        direction = min(max(direction, float(self._az_arc_lo[q])), float(self._az_arc_hi[q]))
                else:
                    direction = a
            direction = ssa(direction)
            thrust[i] = t
            angle[i] = direction
            directions.append(direction)
        # extended thrust of the commands: (T cos α, T sin α)
        wrapped = np.array(directions)
        cos = np.cos(wrapped).tolist()
        sin = np.sin(wrapped).tolist()
        for q, (i, _, _) in enumerate(self._az_data):
            t = thrust[i]
            ext[2 * q] = t * cos[q]
            ext[2 * q + 1] = t * sin[q]

    def _azimuth_targets(self, a_prev: list[float]) -> list[float]:
        """The direction the unconstrained allocation wants per azimuth, the short way from α_prev (NaN
        without one); the general constraint path has computed it already."""
        if self._az_target is not None:
            return self._az_target.tolist()
        n2 = 2 * len(self._az_data)
        fx = self._c_f_star[0:n2:2]
        fy = self._c_f_star[1:n2:2]
        atan = np.arctan2(fy, fx).tolist()
        fx_l, fy_l = fx.tolist(), fy.tolist()
        return [math.nan if fx_l[q] * fx_l[q] + fy_l[q] * fy_l[q] <= self._az_eps2_list[q] else a + ssa(atan[q] - a)
                for q, a in enumerate(a_prev)]

    # ------------------------------------------------------------------ input checks and state
    def _available(self, available: np.ndarray | None) -> np.ndarray:
        if available is None:
            return self._all_true  # read-only: the mask is never written
        if type(available) is np.ndarray and available.dtype == bool and available.shape == (self._n,):
            return available  # the runtime's case: nothing to convert
        mask = np.asarray(available)
        if mask.shape != (self._n,):
            raise ValueError(f"available must have one entry per thruster ({self._n}), got shape {mask.shape}")
        if mask.dtype != bool:
            if mask.dtype == object or not np.all(np.isin(mask, (0, 1))):
                raise ValueError(f"available must be booleans, got {available!r}")
            mask = mask.astype(bool)
        return mask

    def _feedback(self, name: str, value: np.ndarray | None, fallback: np.ndarray) -> np.ndarray:
        if value is None:
            return fallback  # the last command arrays are replaced, never modified in place
        try:
            array = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            raise ValueError(f"{name} must be numbers, got {value!r}") from None
        if array.shape != (self._n,):
            raise ValueError(f"{name} must have one entry per thruster ({self._n}), got shape {array.shape}")
        return np.where(np.isfinite(array), array, fallback)

    def state_dict(self) -> dict[str, Any]:
        """JSON-able state: the last command (the rate limits continue from it after a restart)."""
        return {
            "names": [s.name for s in self._specs],
            "thrust_n": self._thrust.tolist(),
            "azimuth_rad": self._angle.tolist(),
        }

    def load_state_dict(self, state: Mapping[str, Any]) -> None:
        """Restore :meth:`state_dict` output (validated: same thruster names, finite values)."""
        try:
            names = list(state["names"])
            thrust = np.asarray(state["thrust_n"], dtype=float)
            angle = np.asarray(state["azimuth_rad"], dtype=float)
        except (KeyError, TypeError, ValueError) as error:
            raise ValueError(f"invalid allocator state: {error}") from None
        if names != [s.name for s in self._specs]:
            raise ValueError(f"allocator state is for thrusters {names}, not {[s.name for s in self._specs]}")
        if thrust.shape != (self._n,) or angle.shape != (self._n,) or not (
                np.all(np.isfinite(thrust)) and np.all(np.isfinite(angle))):
            raise ValueError("allocator state needs finite thrust_n and azimuth_rad per thruster")
        self._thrust = thrust.copy()
        self._thrust_in_limits = False  # a restored command is clamped to the limits at the next step
        self._angle = angle.copy()


def _vector3(name: str, value: Any) -> np.ndarray:
    if type(value) is np.ndarray and value.shape == (3,) and value.dtype == np.float64:
        a, b, c = value.tolist()  # three float checks are cheaper than np.isfinite(...).all()
        if math.isfinite(a) and math.isfinite(b) and math.isfinite(c):
            return value
        raise ValueError(f"{name} must be 3 finite numbers, got {value!r}")
    try:
        array = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be 3 finite numbers, got {value!r}") from None
    if array.shape != (3,) or not np.all(np.isfinite(array)):
        raise ValueError(f"{name} must be 3 finite numbers, got {value!r}")
    return array


def allocator_kwargs_from_mapping(value: object, thrusters: Sequence[ThrusterSpec],
                                  path: str = "allocation") -> dict[str, Any]:
    """Validate an ``allocation:`` config mapping into keyword arguments of :class:`ThrustAllocator`.

    Keys (all optional): ``thrust_weights`` (mapping thruster name → weight > 0; unnamed thrusters
    weigh 1), ``rudder_lift_weight`` (> 0), ``slack_weight`` and ``slack_penalty`` (number or 3
    numbers, normalised units), ``polygon_sides`` (integer >= 8).

    Raises
    ------
    ConfigError
        Naming the key path and what was expected.
    """
    section = Section.of(value, path)
    kwargs: dict[str, Any] = {}
    weights = section.section("thrust_weights")
    if weights.data:
        names = [t.name for t in thrusters]
        for name in weights.data:
            if name not in names:
                raise ConfigError(f"{weights.path}.{name}", "a thruster name (" + ", ".join(names) + ")",
                                  show_got=False)
        kwargs["thrust_weights"] = [weights.number(name, 1.0, minimum=0.0, exclusive_minimum=True)
                                    for name in names]
        weights.finish()
    if section.has("rudder_lift_weight"):
        kwargs["rudder_lift_weight"] = section.number("rudder_lift_weight", minimum=0.0, exclusive_minimum=True)
    for key, minimum, exclusive in (("slack_weight", 0.0, True), ("slack_penalty", 0.0, False)):
        raw = section.raw(key, None)
        if raw is None:
            continue
        if isinstance(raw, (int, float)) and not isinstance(raw, bool):
            kwargs[key] = section.number(key, minimum=minimum, exclusive_minimum=exclusive)
        else:
            vector = check_vector(raw, f"{section.path}.{key}", 3)
            if np.any(vector < minimum) or (exclusive and np.any(vector == minimum)):
                raise ConfigError(f"{section.path}.{key}", f"numbers {'>' if exclusive else '>='} {minimum:g}", raw)
            kwargs[key] = vector.tolist()
    if section.has("polygon_sides"):
        kwargs["polygon_sides"] = section.integer("polygon_sides", minimum=8)
    section.finish()
    return kwargs
