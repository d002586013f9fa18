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
  penalty ``ρ(s⁺ + s⁻)`` plus ``Q(s⁺² + s⁻²)`` (ρ = Q = 10⁴ in normalised units, 10⁵ for yaw, ≫ the
  multipliers of any feasible allocation): a feasible demand is met exactly (to the solver
  tolerance, ≈ 10⁻⁹ relative), an infeasible one gives the best feasible force (the quadratic
  part spreads the shortfall over the DOFs), reported as ``shortfall_b``. A pure quadratic
  slack needs a weight ≈ 10⁸ for 10⁻⁸ accuracy, and that makes the multipliers of saturated
  allocations so large that the active-set solvers fail (daqp cycles, quadprog reports
  inconsistent constraints) — measured on this problem.
* **Heading priority**: the yaw row's ρ and Q are ten times the surge and sway rows' (:data:`DEFAULT_SLACK`), so
  when the thrusters cannot meet the whole demand the shortfall goes to position, not heading — the practice of
  commercial DP systems (heading priority), because a vessel that loses heading turns her side to the weather
  and the environmental load grows beyond what any allocation can meet. Found on the Blue Lady in a 0.22 m/s
  current 27° off the bow: with equal weights the allocator gave up the yaw moment for sway force and she fell
  77° off heading and 9.7 m off position; with heading priority 1.2° rms and 1.4 m (docs/fault-handling.md).
  Ten, not more: the multipliers grow with the weights (see above).

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

from dpbase.schema import ConfigError, Section, check_vector
from dpcontrol.allocation.geometry import AZIMUTH, FIXED, ThrusterGeometry, weighted_pseudo_inverse
from dpcontrol.allocation.kernels import (
    EPS_ANGLE,
    F_AHEAD,
    F_AMBIGUOUS,
    F_LONG_WAY,
    INACTIVE,
    L_MODE,
    L_ROW,
    L_SECTOR_COUNT,
    L_SECTOR_FIRST,
    L_VARIABLE,
    LAYOUT_COLUMNS,
    MIN_WINDOW,
    RUDDER_AHEAD,
    RUDDER_ASTERN,
    RUDDER_GUESS,
    S_A_RATE,
    S_ANGLE,
    S_DELTA_MAX,
    S_EPS,
    S_K_LIFT,
    S_SCALE,
    S_T_MAX,
    S_T_MIN,
    S_T_RATE,
    SATURATION_TOLERANCE,
    SPEC_COLUMNS,
    STATE_COLUMNS,
    TWO_PI,
    WINDOW_COLUMNS,
    ZERO_THRUST,
    all_finite,
    allocation_commands,
    allocation_constraints,
)
from dpcontrol.models.thrusters import ThrusterSpec

_MAX_RUDDER_ENUMERATION = 3     # ahead/astern combinations tried for at most this many rudders
HEADING_PRIORITY = 10.0
"""How much more a shortfall of yaw moment costs than one of surge or sway force (normalised units)."""
DEFAULT_SLACK = (1e4, 1e4, HEADING_PRIORITY * 1e4)
"""Default ``ρ`` and ``Q`` of the slack per DOF (surge, sway, yaw), normalised units: heading priority."""


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


def _result(*, thrust_n: np.ndarray, azimuth_rad: np.ndarray, tau_achieved_b: np.ndarray, shortfall_b: np.ndarray,
            saturated: bool, solver_status: str, iterations: int) -> AllocationResult:
    """An :class:`AllocationResult` of these fields (the same object as its constructor builds).

    The frozen dataclass's ``__init__`` sets each of its seven fields through ``object.__setattr__``
    (~3 µs per allocation on the development machine, once per control cycle); the instance dictionary
    is filled in one call instead. Frozen-ness is unchanged: ``__setattr__`` still raises.
    """
    result = object.__new__(AllocationResult)
    result.__dict__.update(thrust_n=thrust_n, azimuth_rad=azimuth_rad, tau_achieved_b=tau_achieved_b,
                           shortfall_b=shortfall_b, saturated=saturated, solver_status=solver_status,
                           iterations=iterations)
    return result


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
        ``Q`` in normalised units (default :data:`DEFAULT_SLACK`: heading priority).
    slack_penalty : float or 3 floats
        ``ρ`` in normalised units (default :data:`DEFAULT_SLACK`).
    polygon_sides : int
        Sides of the inscribed polygon over a full circle (>= 8).

    Notes
    -----
    The matrices of the QP are allocated once; every call updates them in place and re-solves
    the same ``daqp.Model`` (warm start from the previous working set). The last command is the
    state (:meth:`state_dict`): rate limits continue from it unless feedback is given.

    Per call, the work around the solver is two compiled kernels (:mod:`dpcontrol.allocation.kernels`):
    :func:`~dpcontrol.allocation.kernels.allocation_constraints` writes every row and bound that changes
    from step to step, :func:`~dpcontrol.allocation.kernels.allocation_commands` turns the solution into
    commands and their force. The thrusters are described to them once, as tables (``_layout``,
    ``_spec``, ``_sectors``); what a step decides (windows, flags) is in ``_window`` and ``_state``.
    Measured with ``benchmarks/bench_control.py`` on the shared 2-core development machine (medians of nine
    runs), against the numpy calls per thruster type and Python floats it replaced: six azimuths 116 → 53 µs
    per call, eight 144 → 58 µs, shuttle tanker 138 → 34 µs; the daqp update and solve are now about half
    of what remains.
    """

    def __init__(self, thrusters: Sequence[ThrusterSpec], sample_time_s: float, *,  # noqa: PLR0915 - every allocation constant is validated and precomputed here once (geometry, limits, QP matrices), off the per-step path
                 thrust_weights: Sequence[float] | None = None, rudder_lift_weight: float = 0.5,
                 slack_weight: float | Sequence[float] = DEFAULT_SLACK,
                 slack_penalty: float | Sequence[float] = DEFAULT_SLACK,
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
        self._thrust_max = np.array([s.max_thrust_n for s in specs], dtype=float)
        # azimuths are commanded forward only (T >= 0)
        self._thrust_min = np.array([0.0 if geo.mode[i] == AZIMUTH else s.min_thrust_n for i, s in enumerate(specs)],
                                    dtype=float)
        angle_rate = np.array([math.inf if s.azimuth_rate_limit_radps is None else s.azimuth_rate_limit_radps
                               for s in specs], dtype=float)
        fixed_angle = np.array([s.angle_rad for s in specs], dtype=float)

        # --- scaling: variables by thruster size, equality rows by capability per DOF
        self._var_scale = geo.scale_n[geo.variable_thruster].astype(float)
        capability = np.abs(geo.B) @ self._var_scale
        self._tau_scale = np.where(capability > 0.0, capability, 1.0)
        w_var = weights[geo.variable_thruster] * self._var_scale / float(np.mean(geo.scale_n))
        w_var[geo.first_variable[geo.rudder_index] + 1] *= rudder_lift_weight
        # physical weights for the pseudo-inverse: Σ w T²/Tmax = Σ (w_var/scale²) f²
        self._w_phys = w_var / self._var_scale**2
        self._pinv_cache: dict[bytes, np.ndarray] = {}

        # --- constraint rows: 3 equalities, then per azimuth a contiguous block [chords, cone low
        # edge, cone high edge, lower thrust rate], then 2 wedge rows per rudder. The number of
        # chords per azimuth is what the widest window at up to twice the sample time needs (at
        # least 8; P + 2 when some azimuth has no rate limit or forbidden sectors): a narrow
        # rate window needs one chord either side of the previous azimuth.
        az = self._az = geo.azimuth_index
        rud = geo.rudder_index
        n_az = az.size
        side = TWO_PI / polygon_sides
        need = 8
        for i in az:
            spec = specs[i]
            if spec.azimuth_rate_limit_radps is None or spec.forbidden_sectors_rad:
                need = polygon_sides + 2
            else:
                need = max(need, 2 * math.ceil(2.0 * spec.azimuth_rate_limit_radps * self._dt / side))
        chords = self._chords = min(need, polygon_sides + 2)
        block = chords + 3
        m = 3 + n_az * block + 2 * rud.size
        self._inv_side = 1.0 / side
        self._az_rate = angle_rate[az]

        # --- the thrusters as the kernels read them (dpcontrol.allocation.kernels, module docstring)
        layout = np.zeros((n, LAYOUT_COLUMNS), dtype=np.int64)
        layout[:, L_MODE] = geo.mode
        layout[:, L_VARIABLE] = geo.first_variable
        layout[az, L_ROW] = 3 + block * np.arange(n_az)
        layout[rud, L_ROW] = 3 + n_az * block + 2 * np.arange(rud.size)
        sectors: list[tuple[float, float]] = []
        for i in az:
            own = self._normalise_sectors(specs[i])
            layout[i, L_SECTOR_FIRST] = len(sectors)
            layout[i, L_SECTOR_COUNT] = len(own)
            sectors.extend(own)
        self._has_sectors = bool(sectors)
        self._sectors = np.array(sectors if sectors else [(0.0, 0.0)], dtype=float)  # one unused row if none
        self._layout = layout
        table = np.zeros((n, SPEC_COLUMNS))
        table[:, S_T_MIN] = self._thrust_min
        table[:, S_T_MAX] = self._thrust_max
        table[:, S_T_RATE] = [s.thrust_rate_limit_nps for s in specs]
        table[:, S_A_RATE] = angle_rate
        table[:, S_SCALE] = geo.scale_n
        table[:, S_ANGLE] = fixed_angle
        table[:, S_K_LIFT] = [s.rudder_lift_per_rad for s in specs]
        table[:, S_DELTA_MAX] = [s.rudder_max_angle_rad or 0.0 for s in specs]
        table[:, S_EPS] = ZERO_THRUST * table[:, S_SCALE]
        self._spec = table
        self._B = np.array(geo.B, order="C")  # writable C-contiguous copy: the kernels' signatures take writable arrays

        nv = self._nv = nf + 6  # f, s⁺, s⁻
        self._A = np.zeros((m, nv))
        self._A[:3, :nf] = geo.B * self._var_scale[None, :] / self._tau_scale[:, None]
        self._A[:3, nf:nf + 3] = np.eye(3)
        self._A[:3, nf + 3:] = -np.eye(3)
        self._H = np.diag(np.concatenate([2.0 * w_var, 2.0 * slack, 2.0 * slack]))
        self._linear = np.concatenate([np.zeros(nf), penalty, penalty])
        self._upper = np.full(nv + m, INACTIVE)
        self._lower = np.full(nv + m, -INACTIVE)
        self._upper[nf:nv] = np.inf
        self._lower[nf:nv] = 0.0
        sense = np.zeros(nv + m, dtype=np.int32)
        sense[nv:nv + 3] = 5  # equality rows B f + s⁺ − s⁻ = τ
        self._sense = sense
        self.cold_restarts = 0  # diagnostics: solves repeated without warm start
        self._upper[nv:nv + 3] = 0.0
        self._lower[nv:nv + 3] = 0.0
        self._model = daqp.Model()
        self._model.settings = {"primal_tol": 1e-9, "iter_limit": 2000}
        status, _ = self._model.setup(self._H, self._linear, self._A, self._upper, self._lower, sense)
        if status < 0:
            raise RuntimeError(f"daqp setup failed (status {status})")

        # --- per-step arrays: what allocation_constraints decides, the unconstrained allocation, work
        self._window = np.zeros((n, WINDOW_COLUMNS))
        self._state = np.zeros((n, STATE_COLUMNS), dtype=np.int64)
        self._rudder_mode = np.full(n, RUDDER_GUESS, dtype=np.int64)
        self._rudder_list = rud.tolist()
        self._f_star = np.zeros(nf)
        self._f_work = np.zeros(nf)
        self._narrow_dt = -1.0
        self._narrow_ok = False
        self._narrow_layout = False
        self._saturation_limit = (SATURATION_TOLERANCE * self._tau_scale).tolist()
        self._all_true = np.ones(n, dtype=bool)  # never written (writable: the kernels' signature)
        self._prev_t_buf = np.zeros(n)                   # previous thrust clamped to the limits

        # --- inputs of the current step (set by allocate, read again by the re-solves)
        self._c_tau = np.zeros(3)
        self._c_pinv = np.zeros((nf, 3))
        self._c_mask = self._all_true
        self._c_prev_t = np.zeros(n)
        self._c_prev_a = np.zeros(n)
        self._c_dt = self._dt
        self._c_narrow = False

        # --- last command (the rate limits continue from it)
        self._thrust = np.zeros(n)
        self._thrust_in_limits = True  # within [T_min, T_max]: every command of allocate() is
        self._angle = np.where(geo.mode == FIXED, fixed_angle, 0.0)

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
        """Weighted pseudo-inverse ``(n_f, 3)`` over the available thrusters (same weights as the QP; read-only)."""
        mask = self._available(available)
        view = self._pinv(mask, mask.tobytes()).view()
        view.setflags(write=False)
        return view

    def _pinv(self, mask: np.ndarray, key: bytes) -> np.ndarray:
        """:meth:`pseudo_inverse` of a checked mask and its bytes (cached per mask; the cached array is
        writable because the kernels' signatures take writable arrays, and only they read it)."""
        cached = self._pinv_cache.get(key)
        if cached is None:
            cols = self._geo.variables_of(mask)
            cached = np.zeros((self._nf, 3))
            if cols.any():
                cached[cols] = weighted_pseudo_inverse(self._geo.B[:, cols], self._w_phys[cols])
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
        narrow = False
        if self._az.size:
            narrow = not self._has_sectors and self._narrow_windows(dt)
            if narrow != self._narrow_layout:
                self._model.update(sense=self._sense)  # rows change structure: no stale working set
                self._narrow_layout = narrow
        # the inputs of this step, read again by the re-solves below
        self._c_tau, self._c_pinv, self._c_mask = tau, self._pinv(mask, mask.tobytes()), mask
        self._c_prev_t, self._c_prev_a, self._c_dt, self._c_narrow = prev_t, prev_a, float(dt), narrow

        self._constraints(long_way=False)
        best = self._solve()
        rudders_forced = False
        if best[3] > 0.0 and self._rudder_list:
            state = self._state
            ambiguous = [i for i in self._rudder_list if state[i, F_AMBIGUOUS]]
            if 0 < len(ambiguous) <= _MAX_RUDDER_ENUMERATION:
                # ahead/astern of a propeller with rudder near zero thrust is a binary choice (the
                # union of two convex pieces): when the first guess cannot meet the demand, try the
                # other combinations and keep the smallest shortfall
                first = tuple(bool(state[i, F_AHEAD]) for i in ambiguous)
                chosen = first
                rudders_forced = True
                for combination in itertools.product((True, False), repeat=len(ambiguous)):
                    if combination == first:
                        continue
                    self._set_rudder_modes(ambiguous, combination)
                    candidate = self._solve()
                    if candidate[3] < best[3]:
                        best, chosen = candidate, combination
                self._set_rudder_modes(ambiguous, chosen)
        # (a basic column slice: F_LONG_WAY is only ever set on azimuth rows, and the fancy index over
        # self._az cost ~4× as much on the 28 % of tanker steps with a shortfall)
        if best[3] > 0.0 and self._state[:, F_LONG_WAY].any():
            # the demand cannot be met this step and the short way of some azimuth to the direction
            # it is wanted in crosses a forbidden sector: open its window only the long way round
            # (otherwise it would sit at the sector edge for ever)
            self._constraints(long_way=True)
            best = self._solve()
        if rudders_forced:
            self._rudder_mode.fill(RUDDER_GUESS)
        thrust, angle, achieved, _, status, iterations = best
        shortfall = tau - achieved
        # |shortfall| > 10⁻⁶ · capability in some DOF, on Python floats (three numpy reductions cost more)
        s0, s1, s2 = shortfall.tolist()
        l0, l1, l2 = self._saturation_limit
        saturated = abs(s0) > l0 or abs(s1) > l1 or abs(s2) > l2
        self._thrust = thrust
        self._thrust_in_limits = True
        self._angle = angle
        return _result(thrust_n=thrust.copy(), azimuth_rad=angle.copy(), tau_achieved_b=achieved, shortfall_b=shortfall,
                       saturated=saturated, solver_status=status, iterations=iterations)

    def _constraints(self, long_way: bool) -> None:
        """Rows and bounds of this step's QP (:func:`~dpcontrol.allocation.kernels.allocation_constraints`)."""
        allocation_constraints(self._c_tau, self._c_pinv, self._c_prev_t, self._c_prev_a, self._c_mask, self._c_dt,
                               self._rudder_mode, self._c_narrow, long_way, self._chords, self._inv_side,
                               self._layout, self._spec, self._sectors, self._tau_scale, self._f_star, self._window,
                               self._state, self._A, self._upper, self._lower)

    def _set_rudder_modes(self, rudders: list[int], ahead: tuple[bool, ...]) -> None:
        """Force the ahead/astern piece of these (ambiguous) rudders and rebuild the rows (only theirs change)."""
        for i, mode in zip(rudders, ahead, strict=True):
            self._rudder_mode[i] = RUDDER_AHEAD if mode else RUDDER_ASTERN
        self._constraints(long_way=False)

    def _solve(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, str, int]:
        """Solve the QP as set up; ``(thrust, angle, achieved, normalised shortfall, status, iterations)``."""
        self._model.update(A=self._A, bupper=self._upper, blower=self._lower)
        x, _, exitflag, info = self._model.solve()
        iterations = int(info.get("iterations", 0))
        ok = exitflag >= 1 and all_finite(x)
        if not ok:
            # the warm start can fail when rows of the previous working set changed structure (a
            # chord row now unused, a layout switch): solve again from an empty working set
            self._model.update(A=self._A, bupper=self._upper, blower=self._lower, sense=self._sense)
            x, _, exitflag, info = self._model.solve()
            iterations += int(info.get("iterations", 0))
            self.cold_restarts += 1
            ok = exitflag >= 1 and all_finite(x)
        # not ok — not seen in testing: every constraint set contains the held previous command
        thrust = np.empty(self._n)
        angle = np.empty(self._n)
        achieved = np.empty(3)
        score = allocation_commands(x, ok, self._c_prev_t, self._c_prev_a, self._c_mask, self._f_star, self._c_dt,
                                    self._layout, self._spec, self._window, self._state, self._B, self._c_tau,
                                    self._tau_scale, thrust, angle, self._f_work, achieved)
        return thrust, angle, achieved, score, "optimal" if ok else "fallback", iterations

    def _narrow_windows(self, dt: float) -> bool:
        """Whether every azimuth's window this step is the plain rate window ``α_prev ± α̇ dt`` with
        one chord either side (rate-limited, ``α̇ dt`` ≤ one polygon side, no sectors) — the usual
        case at a DP sample rate, with the fixed block layout of the narrow rows."""
        if abs(dt - self._narrow_dt) > 1e-9 * dt:  # recompute only when dt really changes
            delta = self._az_rate * dt
            self._narrow_ok = bool(np.all(np.isfinite(delta)) and np.all(delta * self._inv_side <= 1.0)
                                   and np.all(delta >= MIN_WINDOW))
            self._narrow_dt = dt
        return self._narrow_ok

    @staticmethod
    def _normalise_sectors(spec: ThrusterSpec) -> list[tuple[float, float]]:
        """Forbidden sectors as ``(start, width)`` with width in (0, 2π)."""
        out = []
        for start, end in spec.forbidden_sectors_rad:
            width = (end - start) % TWO_PI
            if width > EPS_ANGLE:
                out.append((start % TWO_PI, width))
        return out


    # ------------------------------------------------------------------ input checks and state
    def _available(self, available: np.ndarray | None) -> np.ndarray:
        """The availability mask as the kernels take it: a C-contiguous, writable (never written) bool array."""
        if available is None:
            return self._all_true
        if (type(available) is np.ndarray and available.dtype == bool and available.shape == (self._n,)
                and available.flags.carray):
            return available  # the runtime's case: nothing to convert
        mask = np.asarray(available)
        if mask.shape != (self._n,):
            raise ValueError(f"available must have one entry per thruster ({self._n}), got shape {mask.shape}")
        if mask.dtype != bool and (mask.dtype == object or not np.all(np.isin(mask, (0, 1)))):
            raise ValueError(f"available must be booleans, got {available!r}")
        return np.array(mask, dtype=bool)  # a copy: contiguous and writable whatever the input was

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
    """``value`` checked as 3 finite numbers, as a C-contiguous writable float64 array (the kernels' type)."""
    if type(value) is np.ndarray and value.shape == (3,) and value.dtype == np.float64 and value.flags.carray:
        a, b, c = value.tolist()  # three float checks are cheaper than np.isfinite(...).all()
        if math.isfinite(a) and math.isfinite(b) and math.isfinite(c):
            return value
        raise ValueError(f"{name} must be 3 finite numbers, got {value!r}")
    try:
        array = np.array(value, dtype=float)  # a copy: contiguous and writable
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
