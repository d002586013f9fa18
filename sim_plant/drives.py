"""Thruster drives of the plant: response, limits, failures, command timeout, generalized force.

Each drive (one per :class:`~dpcontrol.models.thrusters.ThrusterSpec`) follows its command like a
real variable-speed drive:

* thrust: first-order response with the spec's ``time_constant_s``, the rate of change limited to
  ``thrust_rate_limit_nps`` and the command saturated to [``min_thrust_n``, ``max_thrust_n``];
  integrated exactly over each plant substep (T ← T + clip((T_c − T)(1 − e^{−h/τ}), ±ṫ_max h));
* azimuth (``azimuth`` kind): slews the short way round at ``azimuth_rate_limit_radps``;
  rudder (``propeller_rudder``): slews at the same rate, limited to ±``rudder_max_angle_rad``;
  tunnels and plain propellers keep their fixed ``angle_rad``;
* a command older than ``timeout_s`` (default 1 s), a disabled command, or :meth:`command_lost`
  (liveliness of the controller lost) makes the drive ramp its thrust to zero through the same
  dynamics and rate limit, the azimuth holding where it is, until a fresh command arrives;
* failures injected by the scenario: ``stuck`` (thrust and angle frozen at the onset values),
  ``zero`` (no thrust delivered, e.g. a lost propeller; the drive looks ready), ``wrong_sign``
  (the delivered force is reversed, feedback shows the negative thrust), ``not_ready`` (drive
  tripped: ``ready`` false, thrust spins down to zero, commands ignored).

Forces in body axes (x forward, y starboard, at (x_m, y_m)): F = T (cos α, sin α) with α the fixed
angle or the azimuth; a ``propeller_rudder`` gives F = (T, T · rudder_lift_per_rad · δ) for T > 0 and
(T, 0) astern; moment N = x F_y − y F_x. τ_act_b is the sum.

The drive states and constants are rows of small arrays, so that the plant's substep kernel
(:func:`sim_plant.kernels.plant_substep`) moves them together with the vessel in one call; the
arithmetic is in :func:`~sim_plant.kernels.drives_update` and :func:`~sim_plant.kernels.drives_force`.
Commands are validated here, in Python.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import cast

import numpy as np

from dpbase.frames import ssa
from dpcontrol.models.thrusters import ThrusterSpec
from sim_plant.kernels import (
    AZIMUTH,
    B_ALPHA_H,
    B_LOST,
    B_TIMEOUT,
    COMMAND_OK,
    DRIVE_BANK,
    DRIVE_CODES,
    DRIVE_CONSTANTS,
    DRIVE_STATE,
    K_FAILURE,
    K_KIND,
    NO_DRIVE,
    NO_FAILURE,
    NOT_READY,
    PROPELLER,
    RUDDER,
    S_ANGLE,
    S_COMMAND_TIME,
    S_TARGET_ANGLE,
    S_TARGET_THRUST,
    S_THRUST,
    STUCK,
    TUNNEL,
    WRONG_SIGN,
    ZERO,
    drives_command,
    drives_feedback,
    drives_force,
    drives_update,
)

FAILURES: tuple[str, ...] = ("stuck", "zero", "wrong_sign", "not_ready")


class CommandError(ValueError):
    """A thruster command was rejected (nothing of it was applied)."""


@dataclass(frozen=True, slots=True)
class ThrusterCommand:
    """Command to one drive.

    Attributes
    ----------
    thrust_n : float
        Demanded thrust along the force direction [N] (saturated by the drive).
    azimuth_rad : float or None
        Azimuth (``azimuth``) or rudder angle (``propeller_rudder``) [rad]; ignored for tunnels
        and plain propellers; None keeps the previous angle command.
    enabled : bool
        False commands zero thrust.
    """

    thrust_n: float
    azimuth_rad: float | None = None
    enabled: bool = True


@dataclass(frozen=True, slots=True)
class DriveReport:
    """What a drive reports (``dp/<vessel>/thrusters/feedback``).

    Attributes
    ----------
    name : str
    thrust_n : float
        Delivered thrust [N] (negative for a ``wrong_sign`` failure, 0 for ``zero``).
    azimuth_rad : float
        Actual azimuth / rudder angle / fixed force angle [rad], wrapped to (−π, π].
    ready : bool
        False when the drive is tripped (``not_ready`` failure).
    """

    name: str
    thrust_n: float
    azimuth_rad: float
    ready: bool


_KIND = {"tunnel": TUNNEL, "azimuth": AZIMUTH, "propeller": PROPELLER, "propeller_rudder": RUDDER}
_FAILURE_CODE = {None: NO_FAILURE, "stuck": STUCK, "zero": ZERO, "wrong_sign": WRONG_SIGN, "not_ready": NOT_READY}


def _finite_number(value: object) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def _float_view(array: np.ndarray) -> memoryview[float]:
    """A memoryview of a contiguous float64 array (items are Python floats; writes go to the array)."""
    # numpy types ndarray.data as a memoryview of ints whatever the dtype; memoryview(array) would be the
    # same view, but numpy's stubs give ndarray the buffer protocol only from Python 3.12
    return cast("memoryview[float]", array.data)


class ThrusterDrives:
    """The bank of drives of one vessel.

    Parameters
    ----------
    specs : sequence of ThrusterSpec
    timeout_s : float
        Command age after which a drive ramps to zero [s] (> 0).
    """

    def __init__(self, specs: Sequence[ThrusterSpec], timeout_s: float = 1.0) -> None:
        if not timeout_s > 0.0:
            raise ValueError("thruster timeout_s must be > 0")
        self.specs = tuple(specs)
        self.names = tuple(s.name for s in self.specs)
        self._index = {name: i for i, name in enumerate(self.names)}
        self.timeout_s = timeout_s
        n = len(self.specs)
        self._kind = [_KIND[s.kind] for s in self.specs]
        self._max = [float(s.max_thrust_n) for s in self.specs]
        self._min = [float(s.min_thrust_n) for s in self.specs]
        self._rudder_max = [math.inf if s.rudder_max_angle_rad is None else float(s.rudder_max_angle_rad)
                            for s in self.specs]
        # The kernels' arrays (layouts in sim_plant.kernels): constants, state, integer codes, bank scalars
        const = np.empty((len(DRIVE_CONSTANTS), n))
        const[:] = [[s.x_m for s in self.specs], [s.y_m for s in self.specs],
                    [math.cos(s.angle_rad) for s in self.specs], [math.sin(s.angle_rad) for s in self.specs],
                    [s.rudder_lift_per_rad for s in self.specs], [s.time_constant_s for s in self.specs],
                    [s.thrust_rate_limit_nps for s in self.specs],
                    [math.inf if s.azimuth_rate_limit_radps is None else s.azimuth_rate_limit_radps
                     for s in self.specs]]
        self._const = const
        self._state = np.zeros((len(DRIVE_STATE), n))
        self._codes = np.zeros((len(DRIVE_CODES), n), dtype=np.int64)
        self._codes[K_KIND] = self._kind
        self._limits = np.array([self._min, self._max, self._rudder_max])  # DRIVE_LIMITS rows (drives_command)
        self._bank = np.zeros(len(DRIVE_BANK))  # not lost
        self._bank[B_ALPHA_H] = -1.0  # no substep yet
        self._bank[B_TIMEOUT] = timeout_s
        self.thrust = self._state[S_THRUST]  # drive state (what the drive produces before failures) [N]
        self.angle = self._state[S_ANGLE]  # actual azimuth / rudder / fixed angle [rad]
        self.angle[:] = [s.angle_rad if _KIND[s.kind] in (TUNNEL, PROPELLER) else 0.0 for s in self.specs]
        self._state[S_TARGET_ANGLE] = self.angle
        self._state[S_COMMAND_TIME] = -math.inf  # no command yet: ramp to (stay at) zero
        self.failure: list[str | None] = [None] * n
        self._ready = [True] * n
        self._feedback = np.empty((2, n))
        self.arrays = (self._const, self._state, self._codes, self._bank)
        """The kernels' drive arguments ``(const, state, codes, bank)`` (state and bank change in place)."""
        # memoryviews for the writes of command(): a float item write costs half a numpy one
        self._command_rows = tuple(_float_view(self._state[row])
                                   for row in (S_TARGET_THRUST, S_TARGET_ANGLE, S_COMMAND_TIME))
        self._bank_view = _float_view(self._bank)

    @property
    def _target_thrust(self) -> list[float]:
        """Saturated thrust commands [N] (a copy)."""
        return self._state[S_TARGET_THRUST].tolist()

    # -- inputs ----------------------------------------------------------------------------------
    def command(self, t_s: float, commands: Mapping[str, ThrusterCommand]) -> None:
        """Apply commands (all or nothing); thrusters not named keep their previous command.

        Raises
        ------
        CommandError
            Unknown thruster name, non-finite or non-numeric thrust/azimuth, non-bool ``enabled``;
            nothing is applied then.
        """
        if not isinstance(t_s, (int, float)) or isinstance(t_s, bool) or not math.isfinite(t_s):
            raise CommandError(f"command time must be a finite number, got {t_s!r}")
        problems = []
        checked: list[tuple[int, float, float | None, bool]] = []
        index = self._index
        isfinite = math.isfinite
        for name, cmd in commands.items():
            i = index.get(name)
            if i is not None and type(cmd) is ThrusterCommand:
                thrust, az, enabled = cmd.thrust_n, cmd.azimuth_rad, cmd.enabled
                # exact float / bool types are the common case; anything else gets the full check
                if (type(thrust) is float and isfinite(thrust) and type(enabled) is bool
                        and (az is None or (type(az) is float and isfinite(az)))):
                    checked.append((i, thrust, az, enabled))
                    continue
            problem = self._problem(name, cmd)
            if problem is not None:
                problems.append(problem)
            else:  # other number types (int, numpy floats)
                az = cmd.azimuth_rad
                checked.append((index[name], float(cmd.thrust_n), None if az is None else float(az), cmd.enabled))
        if problems:
            raise CommandError("thruster command rejected: " + "; ".join(problems))
        target_thrust, target_angle, command_time = self._command_rows
        low, high, kinds, rudder_max = self._min, self._max, self._kind, self._rudder_max
        t = float(t_s)
        for i, thrust, az, enabled in checked:
            target_thrust[i] = min(high[i], max(low[i], thrust)) if enabled else 0.0
            if az is not None:
                kind = kinds[i]
                if kind == AZIMUTH:
                    target_angle[i] = ssa(az)
                elif kind == RUDDER:
                    target_angle[i] = min(rudder_max[i], max(-rudder_max[i], az))
            command_time[i] = t
        self._bank_view[B_LOST] = 0.0

    def command_arrays(self, t_s: float, order: np.ndarray, thrust_n: np.ndarray, azimuth_rad: np.ndarray,
                       enabled: np.ndarray) -> None:
        """:meth:`command` from per-drive arrays: entry ``j`` commands drive ``order[j]``.

        The same as ``command(t_s, {names[order[j]]: ThrusterCommand(thrust_n[j], azimuth_rad[j], enabled[j])})``
        (with the values as Python floats and bools), in one kernel call (:func:`sim_plant.kernels.drives_command`)
        instead of a command object and a Python check per drive: the lockstep loop commands every drive every
        step from the controller's arrays. Anything the kernel does not take (a non-finite value, arrays of
        other types or lengths) goes through :meth:`command` itself, so what is rejected, and the message, stay
        the same.

        Parameters
        ----------
        t_s : float
        order : ndarray of int64, shape (m,)
            Drive index (into :attr:`names`) of each entry.
        thrust_n, azimuth_rad : ndarray of float64, shape (m,)
        enabled : ndarray of bool, shape (m,)

        Raises
        ------
        CommandError
            As :meth:`command`; nothing is applied then.
        """
        if type(t_s) is float and math.isfinite(t_s):
            try:
                done = drives_command(self._state, self._limits, self._codes, order, thrust_n, azimuth_rad, enabled,
                                      t_s) == COMMAND_OK
            except TypeError:  # not arrays of the kernel's types: the general path converts or rejects them
                done = False
            if done:
                self._bank_view[B_LOST] = 0.0
                return
        names = self.names
        self.command(t_s, {names[i]: ThrusterCommand(thrust, azimuth, on) for i, thrust, azimuth, on in
                           zip(np.asarray(order).tolist(), np.asarray(thrust_n).tolist(),
                               np.asarray(azimuth_rad).tolist(), np.asarray(enabled).tolist(), strict=True)})

    def _problem(self, name: str, cmd: object) -> str | None:
        """What is wrong with one thruster's command (None: nothing)."""
        if name not in self._index:
            return f"unknown thruster {name!r} (known: {', '.join(self.names)})"
        if type(cmd) is not ThrusterCommand:
            return f"{name}: expected a ThrusterCommand, got {type(cmd).__name__}"
        if not _finite_number(cmd.thrust_n):
            return f"{name}: thrust_n must be a finite number, got {cmd.thrust_n!r}"
        if cmd.azimuth_rad is not None and not _finite_number(cmd.azimuth_rad):
            return f"{name}: azimuth_rad must be a finite number or None, got {cmd.azimuth_rad!r}"
        if type(cmd.enabled) is not bool:
            return f"{name}: enabled must be true or false, got {cmd.enabled!r}"
        return None

    def command_lost(self, t_s: float) -> None:
        """The controller disappeared (liveliness lost): every drive ramps to zero until the next
        :meth:`command`."""
        del t_s
        self._bank_view[B_LOST] = 1.0

    def set_failure(self, name: str, failure: str | None) -> None:
        """Inject (``failure`` in :data:`FAILURES`) or clear (None) a failure on one drive."""
        if failure is not None and failure not in FAILURES:
            raise ValueError(f"unknown thruster failure {failure!r}")
        i = self._index[name]
        self.failure[i] = failure
        self._codes[K_FAILURE, i] = _FAILURE_CODE[failure]
        self._ready[i] = failure != "not_ready"

    # -- dynamics --------------------------------------------------------------------------------
    def update(self, t_s: float, h_s: float) -> None:
        """Advance every drive over the substep [t_s, t_s + h_s] (:func:`sim_plant.kernels.drives_update`;
        the plant's substep kernel calls it with the vessel step)."""
        drives_update(self._const, self._state, self._codes, self._bank, t_s, h_s)

    def delivered_thrust(self, i: int) -> float:
        """Thrust actually delivered by drive ``i`` after failures [N]."""
        failure = self.failure[i]
        if failure == "zero":
            return 0.0
        thrust = float(self.thrust[i])
        return -thrust if failure == "wrong_sign" else thrust

    def force_b(self, skip: int = NO_DRIVE) -> tuple[float, float, float]:
        """τ_act_b = Σ forces and moments of the delivered thrusts [N, N, N·m]
        (:func:`sim_plant.kernels.drives_force`).

        ``skip`` leaves one drive out (the mariner's rudder, whose force the manoeuvring model
        takes from its hydrodynamic derivatives).
        """
        return drives_force(self._const, self._state, self._codes, skip)

    def feedback(self) -> list[DriveReport]:
        """Per-drive feedback (delivered thrust, actual angle, ready)."""
        thrusts, angles, ready = self.feedback_values()
        return [DriveReport(name, thrust, angle, ok)
                for name, thrust, angle, ok in zip(self.names, thrusts, angles, ready, strict=True)]

    def feedback_values(self) -> tuple[list[float], list[float], list[bool]]:
        """What :meth:`feedback` reports, as three lists in :attr:`names` order: delivered thrust [N], actual
        angle [rad], ready (for a caller that builds its own feedback objects: no intermediate one per drive).

        The lists are new, except ``ready``, which is the drives' own (read it, do not change it).
        """
        out = self._feedback
        drives_feedback(self._state, self._codes, out)
        thrusts, angles = out.tolist()
        return thrusts, angles, self._ready

    def index(self, name: str) -> int:
        return self._index[name]
