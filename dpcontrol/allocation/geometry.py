"""Thruster geometry: extended-thrust variables, configuration matrix, weighted pseudo-inverse.

Each thruster contributes one or two *extended thrust* variables (Fossen 2021 §11.2; Johansen,
Fossen & Berge 2004), chosen so that the generalized force is linear in them,
``τ_b = B f`` with a constant configuration matrix ``B`` (3 × n_f):

* ``tunnel`` / ``propeller`` (and a ``propeller_rudder`` without a rudder): one variable, the
  thrust ``T`` along the fixed direction ``angle_rad``;
* ``azimuth``: two variables, the body-frame force components ``(F_x, F_y)``; thrust
  ``T = |F|`` and azimuth ``α = atan2(F_y, F_x)``;
* ``propeller_rudder``: two variables, the axial propeller force ``F_a = T`` along ``angle_rad``
  and the rudder lift ``F_l = T · k_L · δ`` (``k_L = rudder_lift_per_rad``, positive δ pushes to
  starboard) perpendicular to it, acting at the thruster position. For ``T > 0`` the rudder angle
  is ``δ = F_l/(k_L F_a)``, and ``|δ| ≤ δ_max`` is the wedge ``|F_l| ≤ k_L δ_max F_a`` — linear
  in ``(F_a, F_l)``; astern (``T < 0``) the rudder gives no lift (``F_l = 0``).

A force ``(F_x, F_y)`` at ``(x, y)`` gives ``[F_x, F_y, x F_y − y F_x]`` (surge, sway, yaw moment).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from dpcontrol.models.thrusters import ThrusterSpec

FIXED = 0
AZIMUTH = 1
RUDDER = 2


def _frozen(array: np.ndarray) -> np.ndarray:
    array.setflags(write=False)
    return array


@dataclass(frozen=True, eq=False)
class ThrusterGeometry:
    """Variable layout and configuration matrix of a thruster set (build with :meth:`build`).

    Attributes
    ----------
    specs : tuple of ThrusterSpec
    mode : ndarray of int, shape (n,)
        ``FIXED``, ``AZIMUTH`` or ``RUDDER`` per thruster.
    first_variable : ndarray of int, shape (n,)
        Index of each thruster's first extended-thrust variable (azimuth variables come first:
        azimuth q has ``(F_x, F_y)`` at ``(2q, 2q + 1)``, then rudders, then fixed thrusters).
    n_variables : int
        ``n_f``.
    B : ndarray, shape (3, n_f)
        Configuration matrix [1, 1, m] (``τ_b = B f``).
    variable_thruster : ndarray of int, shape (n_f,)
        Thruster index of each variable.
    scale_n : ndarray, shape (n,)
        Largest thrust magnitude per thruster ``max(max_thrust_n, −min_thrust_n)`` [N].
    fixed_index, azimuth_index, rudder_index : ndarray of int
        Thruster indices of each mode.
    rudder_lift_per_rad : ndarray, shape (n_rudder,)
        ``k_L`` of the rudder thrusters.
    """

    specs: tuple[ThrusterSpec, ...]
    mode: np.ndarray
    first_variable: np.ndarray
    n_variables: int
    B: np.ndarray
    variable_thruster: np.ndarray
    scale_n: np.ndarray
    fixed_index: np.ndarray
    azimuth_index: np.ndarray
    rudder_index: np.ndarray
    rudder_lift_per_rad: np.ndarray
    # (thruster, variable[, k_L]) of the rudders and fixed thrusters for extended_from_commands
    _rudders: tuple[tuple[int, int, float], ...] = field(init=False, repr=False)
    _fixed: tuple[tuple[int, int], ...] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        # build() puts the azimuth pairs first, at (2q, 2q + 1)
        if not np.array_equal(self.first_variable[self.azimuth_index], 2 * np.arange(self.azimuth_index.size)):
            raise ValueError("ThrusterGeometry: the azimuth variables must come first (use build())")
        first = self.first_variable.tolist()
        object.__setattr__(self, "_rudders", tuple(
            (i, first[i], float(k)) for i, k in zip(self.rudder_index.tolist(), self.rudder_lift_per_rad, strict=True)))
        object.__setattr__(self, "_fixed", tuple((i, first[i]) for i in self.fixed_index.tolist()))

    @staticmethod
    def build(specs: Sequence[ThrusterSpec]) -> ThrusterGeometry:
        """Geometry of ``specs`` (at least one thruster)."""
        specs = tuple(specs)
        if not specs:
            raise ValueError("thrust allocation needs at least one thruster")
        mode = np.zeros(len(specs), dtype=int)
        for i, spec in enumerate(specs):
            if not isinstance(spec, ThrusterSpec):
                raise TypeError(f"thruster {i} is not a ThrusterSpec: {spec!r}")
            if spec.kind == "azimuth":
                mode[i] = AZIMUTH
            elif spec.kind == "propeller_rudder" and rudder_slope(spec) > 0.0:
                mode[i] = RUDDER
            else:
                mode[i] = FIXED
        # variables ordered by mode — all azimuths first, (F_x, F_y) pairs at even/odd indices,
        # then the rudder pairs, then the fixed thrusters — so that the allocator can address the
        # azimuth variables as strided views
        first = np.zeros(len(specs), dtype=int)
        columns: list[tuple[float, float, float]] = []
        owner: list[int] = []
        for wanted in (AZIMUTH, RUDDER, FIXED):
            for i, spec in enumerate(specs):
                if mode[i] != wanted:
                    continue
                first[i] = len(columns)
                if wanted == AZIMUTH:
                    columns.append(_column(spec.x_m, spec.y_m, 0.0))
                    columns.append(_column(spec.x_m, spec.y_m, 0.5 * math.pi))
                elif wanted == RUDDER:
                    columns.append(_column(spec.x_m, spec.y_m, spec.angle_rad))
                    columns.append(_column(spec.x_m, spec.y_m, spec.angle_rad + 0.5 * math.pi))
                else:
                    columns.append(_column(spec.x_m, spec.y_m, spec.angle_rad))
                owner.extend([i] * (len(columns) - len(owner)))
        rudder = np.flatnonzero(mode == RUDDER)
        return ThrusterGeometry(
            specs=specs,
            mode=_frozen(mode),
            first_variable=_frozen(first),
            n_variables=len(columns),
            B=_frozen(np.array(columns).T),
            variable_thruster=_frozen(np.array(owner, dtype=int)),
            scale_n=_frozen(np.array([max(s.max_thrust_n, -s.min_thrust_n) for s in specs])),
            fixed_index=_frozen(np.flatnonzero(mode == FIXED)),
            azimuth_index=_frozen(np.flatnonzero(mode == AZIMUTH)),
            rudder_index=_frozen(rudder),
            rudder_lift_per_rad=_frozen(np.array([specs[i].rudder_lift_per_rad for i in rudder], dtype=float)),
        )

    def variables_of(self, available: np.ndarray) -> np.ndarray:
        """Boolean mask over the variables of the available thrusters."""
        return np.asarray(available, dtype=bool)[self.variable_thruster]

    def extended_from_commands(self, thrust_n: np.ndarray, angle_rad: np.ndarray) -> np.ndarray:
        """Extended thrust ``f`` (n_f,) of thrust/angle commands (the nonlinear map).

        ``angle_rad`` is the azimuth for azimuths, the rudder angle for ``propeller_rudder``
        (lift only for positive thrust) and ignored (the spec's ``angle_rad``) otherwise.
        """
        thrust = np.asarray(thrust_n, dtype=float)
        angle = np.asarray(angle_rad, dtype=float)
        # Python floats for the handful of thrusters (a numpy call per thruster type costs more than the
        # arithmetic); the azimuths' cos/sin stay numpy's, the same values as a vectorised evaluation
        t = thrust.tolist()
        f = [0.0] * self.n_variables
        if self.azimuth_index.size:
            a = angle[self.azimuth_index]
            for q, (i, c, s) in enumerate(zip(self.azimuth_index.tolist(), np.cos(a).tolist(), np.sin(a).tolist(),
                                              strict=True)):
                f[2 * q] = t[i] * c
                f[2 * q + 1] = t[i] * s
        if self.rudder_index.size:
            delta = angle.tolist()
            for i, j, k_lift in self._rudders:
                f[j] = t[i]
                f[j + 1] = t[i] * k_lift * delta[i] if t[i] > 0.0 else 0.0   # lift only ahead
        for i, j in self._fixed:
            f[j] = t[i]
        return np.array(f)

    def force_b(self, thrust_n: np.ndarray, angle_rad: np.ndarray) -> np.ndarray:
        """Generalized force ``B f`` ``[N, N, N·m]`` of thrust/angle commands."""
        return self.B @ self.extended_from_commands(thrust_n, angle_rad)


def rudder_slope(spec: ThrusterSpec) -> float:
    """``k_L · δ_max``: the largest ratio ``|F_l| / F_a`` of a propeller with rudder (0 without)."""
    if spec.kind != "propeller_rudder" or spec.rudder_max_angle_rad is None:
        return 0.0
    return spec.rudder_lift_per_rad * spec.rudder_max_angle_rad


def _column(x: float, y: float, angle: float) -> tuple[float, float, float]:
    c = math.cos(angle)
    s = math.sin(angle)
    return (c, s, x * s - y * c)


def weighted_pseudo_inverse(B: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """Weighted pseudo-inverse ``B_W⁺ = W⁻¹Bᵀ(BW⁻¹Bᵀ)⁻¹`` (Fossen 2021 §11.2.2).

    Minimises ``fᵀWf`` subject to ``Bf = τ`` (no limits). Computed as
    ``W^{-1/2} (B W^{-1/2})⁺`` with the Moore–Penrose inverse, so a rank-deficient ``B`` (e.g.
    thrusters unavailable) gives the least-squares allocation instead of failing.

    Parameters
    ----------
    B : ndarray, shape (3, n_f)
    weights : ndarray, shape (n_f,)
        Positive diagonal of W.

    Returns
    -------
    ndarray, shape (n_f, 3)
    """
    w = np.asarray(weights, dtype=float)
    if np.any(w <= 0.0):
        raise ValueError("pseudo-inverse weights must be > 0")
    root = 1.0 / np.sqrt(w)
    return root[:, None] * np.linalg.pinv(B * root[None, :])
