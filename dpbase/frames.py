"""Reference frames and angle helpers (Fossen/SNAME conventions).

Earth-fixed frame: local NED tangent plane at a datum, ``eta_ned = [north_m, east_m, psi_rad]``,
heading ``psi`` 0 = north, positive clockwise seen from above. Body frame: surge (forward),
sway (starboard), yaw (clockwise), ``nu_b = [u_mps, v_mps, r_radps]``.

This module is the one place angles are wrapped (``ssa``); every other module calls it.
"""

from __future__ import annotations

import math

import numpy as np

from dpbase.jit import f8, kernel

TWO_PI = 2.0 * math.pi


def ssa(angle_rad: float) -> float:
    """Smallest signed angle: wrap an angle to the interval (−π, π].

    Parameters
    ----------
    angle_rad : float
        Any angle [rad].

    Returns
    -------
    float
        The same direction expressed in (−π, π] [rad].
    """
    # Python's float % is fmod plus a sign correction (CPython's float_rem), so this is the fmod-based
    # wrap bit for bit; numba compiles % (not math.fmod) with the same semantics for ssa_compiled.
    wrapped = (angle_rad + math.pi) % TWO_PI
    if wrapped <= 0.0:
        wrapped += TWO_PI
    return wrapped - math.pi


ssa_compiled = kernel(f8(f8))(ssa)
""":func:`ssa` compiled, for calls from inside compiled kernels (the same source and results)."""


def ssa_array(angle_rad: np.ndarray) -> np.ndarray:
    """Vectorised :func:`ssa` for arrays [rad] → (−π, π] [rad]."""
    wrapped = np.mod(np.asarray(angle_rad, dtype=float) + math.pi, TWO_PI)
    wrapped = np.where(wrapped <= 0.0, wrapped + TWO_PI, wrapped)
    return wrapped - math.pi


def rotation_nb(psi_rad: float) -> np.ndarray:
    """Yaw rotation matrix ``R_nb(ψ)`` mapping body-frame vectors to NED (seed 002 eq. (3)).

    Returns
    -------
    numpy.ndarray, shape (3, 3)
        ``[[cos ψ, −sin ψ, 0], [sin ψ, cos ψ, 0], [0, 0, 1]]``; ``R⁻¹ = Rᵀ``.
    """
    c = math.cos(psi_rad)
    s = math.sin(psi_rad)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def body_to_ned(vector_b: np.ndarray, psi_rad: float) -> np.ndarray:
    """Rotate a 3-DOF body vector (surge, sway, yaw) to NED: ``R_nb(ψ) · v_b``."""
    c = math.cos(psi_rad)
    s = math.sin(psi_rad)
    x, y, z = float(vector_b[0]), float(vector_b[1]), float(vector_b[2])
    return np.array([c * x - s * y, s * x + c * y, z])


def ned_to_body(vector_ned: np.ndarray, psi_rad: float) -> np.ndarray:
    """Rotate a 3-DOF NED vector to body axes: ``R_nb(ψ)ᵀ · v_n`` (vessel-parallel, seed 002 eq. (14))."""
    c = math.cos(psi_rad)
    s = math.sin(psi_rad)
    x, y, z = float(vector_ned[0]), float(vector_ned[1]), float(vector_ned[2])
    return np.array([c * x + s * y, -s * x + c * y, z])
