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

from dpcontrol.allocation.kernels import (
    AZIMUTH,
    FIXED,
    L_MODE,
    L_VARIABLE,
    RUDDER,
    extended_thrust,
    generalized_force,
)
from dpcontrol.models.thrusters import ThrusterSpec


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
    # what the kernels of extended_from_commands/force_b read (dpcontrol.allocation.kernels): per thruster
    # [mode, first variable], k_L (0 but for rudders), and B — writable copies, as the kernels' signatures take
    _layout: np.ndarray = field(init=False, repr=False)
    _lift: np.ndarray = field(init=False, repr=False)
    _B: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        # build() puts the azimuth pairs first, at (2q, 2q + 1)
        if not np.array_equal(self.first_variable[self.azimuth_index], 2 * np.arange(self.azimuth_index.size)):
            raise ValueError("ThrusterGeometry: the azimuth variables must come first (use build())")
        layout = np.zeros((len(self.specs), 2), dtype=np.int64)
        layout[:, L_MODE] = self.mode
        layout[:, L_VARIABLE] = self.first_variable
        lift = np.zeros(len(self.specs))
        lift[self.rudder_index] = self.rudder_lift_per_rad
        object.__setattr__(self, "_layout", layout)
        object.__setattr__(self, "_lift", lift)
        object.__setattr__(self, "_B", np.array(self.B, dtype=float, order="C"))

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
        f = np.empty(self.n_variables)
        extended_thrust(self._layout, self._lift, self._per_thruster("thrust_n", thrust_n),
                        self._per_thruster("angle_rad", angle_rad), f)
        return f

    def force_b(self, thrust_n: np.ndarray, angle_rad: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """Generalized force ``B f`` ``[N, N, N·m]`` of thrust/angle commands.

        Parameters
        ----------
        thrust_n, angle_rad : array_like, shape (n,)
            As :meth:`extended_from_commands` [N], [rad].
        out : ndarray, shape (3,), optional
            Written in place and returned (C-contiguous float64); default a new array.
        """
        if out is None:
            out = np.empty(3)
        elif not (type(out) is np.ndarray and out.shape == (3,) and out.dtype == np.float64 and out.flags.carray):
            raise ValueError("out must be a writable C-contiguous float64 array of shape (3,)")
        generalized_force(self._layout, self._lift, self._B, self._per_thruster("thrust_n", thrust_n),
                          self._per_thruster("angle_rad", angle_rad), np.empty(self.n_variables), out)
        return out

    def _per_thruster(self, name: str, value: np.ndarray) -> np.ndarray:
        """``value`` as the kernels take it: a C-contiguous writable float64 array of shape (n,)."""
        if not (type(value) is np.ndarray and value.dtype == np.float64 and value.flags.carray):
            value = np.array(value, dtype=float)  # a copy: contiguous and writable
        if value.shape != (len(self.specs),):
            raise ValueError(f"{name} must have one entry per thruster ({len(self.specs)}), got shape {value.shape}")
        return value


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
