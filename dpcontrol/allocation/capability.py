"""Simplified DP capability: the largest wind each direction a thruster layout can hold.

In the spirit of a DNV-ST-0111 level-1 capability plot (static balance, wind, waves and current
collinear), with deliberately simple load models — this checks a thruster *layout*, it is not a
class analysis:

* wind: :class:`~dpcontrol.control.wind.WindFeedforward` with the vessel's Blendermann
  coefficients (seed 002 eq. (18));
* current ``V_c = current_per_wind · V_w`` from the same direction: quadratic cross-flow drag
  with the vessel's ``quadratic_damping`` (``X = X_|u|u |u_c| u_c``, ``Y = Y_|v|v |v_c| v_c``) and the
  Munk moment ``N = (A₁₁ − A₂₂) u_c v_c`` of the added masses;
* waves: a fully developed sea ``H_s = 0.21 V_w²/g`` (Pierson–Moskowitz) and a mean drift force
  ``F = C_r ρ g H_s² / 16`` per metre of the projected hull (beam ahead, length abeam),
  ``C_r = 0.5`` (partial reflection), with a yaw moment ``0.05 L F_y cos β``.

Model-scale vessels are checked at the Froude-scaled environment (speeds ÷ √λ, wave height ÷ λ).
Directions ``β`` are where the weather comes *from*, relative to the bow, clockwise.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import numpy as np

from dpcontrol.allocation.allocator import AllocationResult, ThrustAllocator
from dpcontrol.control.wind import WindFeedforward
from dpcontrol.models.vessels import GRAVITY_MPS2, VesselData

#: Time a static allocation may move the thrusters over [s]: long enough that no rate limit binds.
STATIC_SAMPLE_TIME_S = 1.0e3
#: Allocation calls of a static allocation: later calls start from the azimuths the earlier ones chose.
STATIC_PASSES = 3

# Model scales of the built-in model-scale vessels (CyberShip II: 1:70 supply vessel; Blue Lady: 1:24 VLCC).
MODEL_SCALE = {"cybership2": 70.0, "blue_lady": 24.0}


@dataclasses.dataclass(frozen=True)
class Environment:
    """Collinear environment of the capability check (full-scale values)."""

    current_per_wind: float = 0.05       # 0.5 m/s of current at 10 m/s of wind [s⁻¹·s]
    drift_reflection: float = 0.5        # C_r of the mean wave drift
    wave_yaw_arm_per_length: float = 0.05


def environment_load_b(vessel: VesselData, wind_from_rad: float, wind_speed_mps: float,
                       environment: Environment | None = None) -> np.ndarray:
    """Environmental load on the vessel at heading 0 ``[N, N, N·m]`` (body axes).

    Parameters
    ----------
    vessel : VesselData
    wind_from_rad : float
        Direction the weather comes from relative to the bow, clockwise [rad].
    wind_speed_mps : float
        Full-scale wind speed [m/s] (scaled down for model-scale vessels).
    """
    env = environment or Environment()
    scale = MODEL_SCALE.get(vessel.name, 1.0)
    wind = WindFeedforward.for_vessel(vessel)
    speed = wind_speed_mps / math.sqrt(scale)
    tau = np.zeros(3) if wind is None else wind.force_b(speed, wind_from_rad, 0.0)
    # current flows away from where it comes from
    current = env.current_per_wind * speed
    u_c = -current * math.cos(wind_from_rad)
    v_c = -current * math.sin(wind_from_rad)
    x_uu, y_vv, _ = vessel.quadratic_damping
    added = vessel.added_mass_matrix
    tau += np.array([x_uu * abs(u_c) * u_c, y_vv * abs(v_c) * v_c, (added[0, 0] - added[1, 1]) * u_c * v_c])
    hs = 0.21 * wind_speed_mps**2 / GRAVITY_MPS2 / scale
    drift = env.drift_reflection * vessel.water_density_kgpm3 * GRAVITY_MPS2 * hs**2 / 16.0
    f_x = -drift * vessel.beam_m * math.cos(wind_from_rad)
    f_y = -drift * vessel.length_m * math.sin(wind_from_rad)
    tau += np.array([f_x, f_y, env.wave_yaw_arm_per_length * vessel.length_m * f_y * math.cos(wind_from_rad)])
    return tau


def static_allocation(allocator: ThrustAllocator, demand_b: np.ndarray,
                      available: np.ndarray | None = None) -> AllocationResult:
    """``demand_b`` ``[N, N, N·m]`` allocated to the (available) thrusters as they could settle to it: an
    allocator built with :data:`STATIC_SAMPLE_TIME_S` (no rate limit binds), :data:`STATIC_PASSES` calls (later
    calls start from the azimuths the earlier ones chose)."""
    result = allocator.allocate(demand_b, available)
    for _ in range(STATIC_PASSES - 1):
        result = allocator.allocate(demand_b, available)
    return result


def holds(allocator: ThrustAllocator, load_b: np.ndarray, available: np.ndarray | None = None) -> bool:
    """Whether the (available) thrusters can balance ``load_b`` (:func:`static_allocation` of ``−load_b``; use
    an allocator built with :data:`STATIC_SAMPLE_TIME_S`)."""
    return not static_allocation(allocator, -load_b, available).saturated


def capability_mps(vessel: VesselData, directions_rad: Sequence[float], *, max_wind_mps: float = 40.0,
                   iterations: int = 20, environment: Environment | None = None,
                   available: np.ndarray | None = None) -> np.ndarray:
    """Largest full-scale wind speed held from each direction (bisection to ``max_wind_mps / 2^iterations``) [m/s].

    Parameters
    ----------
    available : array of bool, optional
        Thrusters in use (default all) — e.g. a failure case.
    """
    allocator = ThrustAllocator(vessel.thrusters, STATIC_SAMPLE_TIME_S)
    out = np.zeros(len(directions_rad))
    for k, beta in enumerate(directions_rad):
        lo, hi = 0.0, max_wind_mps
        for _ in range(iterations):
            mid = 0.5 * (lo + hi)
            if holds(allocator, environment_load_b(vessel, beta, mid, environment), available):
                lo = mid
            else:
                hi = mid
        out[k] = lo
    return out
