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

Plain floats in lists, no numpy: with ≤ 8 drives this is faster than array calls and allocates
nothing per substep.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from dpcontrol.models.frames import ssa
from dpcontrol.models.thrusters import ThrusterSpec

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
class ThrusterFeedback:
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


_TUNNEL, _AZIMUTH, _PROPELLER, _RUDDER = 0, 1, 2, 3


def _finite_number(value: object) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
_KIND = {"tunnel": _TUNNEL, "azimuth": _AZIMUTH, "propeller": _PROPELLER, "propeller_rudder": _RUDDER}


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
        self._tau = [s.time_constant_s for s in self.specs]
        self._rate = [s.thrust_rate_limit_nps for s in self.specs]
        self._max = [s.max_thrust_n for s in self.specs]
        self._min = [s.min_thrust_n for s in self.specs]
        self._az_rate = [math.inf if s.azimuth_rate_limit_radps is None else s.azimuth_rate_limit_radps
                         for s in self.specs]
        self._rudder_max = [math.inf if s.rudder_max_angle_rad is None else s.rudder_max_angle_rad
                            for s in self.specs]
        # state
        self.thrust = [0.0] * n  # drive state (what the drive produces before failures)
        self.angle = [s.angle_rad if _KIND[s.kind] in (_TUNNEL, _PROPELLER) else 0.0 for s in self.specs]
        self._target_thrust = [0.0] * n
        self._target_angle = list(self.angle)
        self._t_cmd = [-math.inf] * n  # no command yet: ramp to (stay at) zero
        self._lost = False
        self.failure: list[str | None] = [None] * n
        self._alpha_h = -1.0
        self._alpha = [0.0] * n
        self._any_failure = False  # no failure anywhere: delivered thrust = drive thrust (the usual case)
        # per drive, the constants of force_b in one tuple (one unpacking instead of five list look-ups)
        self._geometry = [(i, _KIND[s.kind], s.x_m, s.y_m, math.cos(s.angle_rad), math.sin(s.angle_rad),
                           s.rudder_lift_per_rad) for i, s in enumerate(self.specs)]

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
        for name, cmd in commands.items():
            i = index.get(name)
            if i is None:
                problems.append(f"unknown thruster {name!r} (known: {', '.join(self.names)})")
                continue
            if type(cmd) is not ThrusterCommand:
                problems.append(f"{name}: expected a ThrusterCommand, got {type(cmd).__name__}")
                continue
            thrust = cmd.thrust_n
            az = cmd.azimuth_rad
            # exact float / bool types are the common case; anything else gets the full check
            if not (type(thrust) is float and math.isfinite(thrust)) and not _finite_number(thrust):
                problems.append(f"{name}: thrust_n must be a finite number, got {thrust!r}")
                continue
            if az is not None and not (type(az) is float and math.isfinite(az)) and not _finite_number(az):
                problems.append(f"{name}: azimuth_rad must be a finite number or None, got {az!r}")
                continue
            if type(cmd.enabled) is not bool:
                problems.append(f"{name}: enabled must be true or false, got {cmd.enabled!r}")
                continue
            checked.append((i, float(thrust), None if az is None else float(az), cmd.enabled))
        if problems:
            raise CommandError("thruster command rejected: " + "; ".join(problems))
        for i, thrust, az, enabled in checked:
            self._target_thrust[i] = min(self._max[i], max(self._min[i], thrust)) if enabled else 0.0
            kind = self._kind[i]
            if az is not None and kind == _AZIMUTH:
                self._target_angle[i] = ssa(az)
            elif az is not None and kind == _RUDDER:
                self._target_angle[i] = min(self._rudder_max[i], max(-self._rudder_max[i], az))
            self._t_cmd[i] = t_s
        self._lost = False

    def command_lost(self, t_s: float) -> None:
        """The controller disappeared (liveliness lost): every drive ramps to zero until the next
        :meth:`command`."""
        del t_s
        self._lost = True

    def set_failure(self, name: str, failure: str | None) -> None:
        """Inject (``failure`` in :data:`FAILURES`) or clear (None) a failure on one drive."""
        if failure is not None and failure not in FAILURES:
            raise ValueError(f"unknown thruster failure {failure!r}")
        self.failure[self._index[name]] = failure
        self._any_failure = any(f is not None for f in self.failure)

    # -- dynamics --------------------------------------------------------------------------------
    def update(self, t_s: float, h_s: float) -> None:
        """Advance every drive over the substep [t_s, t_s + h_s]."""
        if abs(h_s - self._alpha_h) > 1e-12 * h_s:  # substeps differ only by rounding most of the time
            self._alpha = [-math.expm1(-h_s / tau) for tau in self._tau]
            self._alpha_h = h_s
        lost = self._lost
        timeout = self.timeout_s
        for i in range(len(self._kind)):
            failure = self.failure[i]
            if failure == "stuck":
                continue
            thrust = self.thrust[i]
            if failure == "not_ready" or lost or t_s - self._t_cmd[i] > timeout:
                target = 0.0
                hold_angle = True
            else:
                target = self._target_thrust[i]
                hold_angle = False
            delta = (target - thrust) * self._alpha[i]
            limit = self._rate[i] * h_s
            if delta > limit:
                delta = limit
            elif delta < -limit:
                delta = -limit
            self.thrust[i] = thrust + delta
            kind = self._kind[i]
            if hold_angle or kind in (_TUNNEL, _PROPELLER):
                continue
            angle = self.angle[i]
            err = ssa(self._target_angle[i] - angle) if kind == _AZIMUTH else self._target_angle[i] - angle
            step = self._az_rate[i] * h_s
            if err > step:
                err = step
            elif err < -step:
                err = -step
            self.angle[i] = ssa(angle + err) if kind == _AZIMUTH else angle + err

    def delivered_thrust(self, i: int) -> float:
        """Thrust actually delivered by drive ``i`` after failures [N]."""
        failure = self.failure[i]
        if failure == "zero":
            return 0.0
        if failure == "wrong_sign":
            return -self.thrust[i]
        return self.thrust[i]

    def force_b(self, skip: int = -1) -> tuple[float, float, float]:
        """τ_act_b = Σ forces and moments of the delivered thrusts [N, N, N·m].

        ``skip`` leaves one drive out (the mariner's rudder, whose force the manoeuvring model
        takes from its hydrodynamic derivatives).
        """
        fx_sum = fy_sum = n_sum = 0.0
        thrusts = self.thrust
        angles = self.angle
        failed = self._any_failure
        for i, kind, x, y, fixed_cos, fixed_sin, lift in self._geometry:
            if i == skip:
                continue
            t = self.delivered_thrust(i) if failed else thrusts[i]
            if t == 0.0:
                continue
            if kind == _AZIMUTH:
                a = angles[i]
                fx = t * math.cos(a)
                fy = t * math.sin(a)
            elif kind == _RUDDER:
                fx = t
                fy = t * lift * angles[i] if t > 0.0 else 0.0
            else:
                fx = t * fixed_cos
                fy = t * fixed_sin
            fx_sum += fx
            fy_sum += fy
            n_sum += x * fy - y * fx
        return fx_sum, fy_sum, n_sum

    def feedback(self) -> list[ThrusterFeedback]:
        """Per-drive feedback (delivered thrust, actual angle, ready)."""
        if not self._any_failure:
            angles = self.angle
            return [ThrusterFeedback(name, thrust, ssa(angles[i]), True)
                    for i, (name, thrust) in enumerate(zip(self.names, self.thrust, strict=True))]
        return [ThrusterFeedback(name, self.delivered_thrust(i), ssa(self.angle[i]), self.failure[i] != "not_ready")
                for i, name in enumerate(self.names)]

    def index(self, name: str) -> int:
        return self._index[name]
