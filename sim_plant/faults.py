"""Fault injections of a scenario (``faults:`` entries), shared by the sensors, drives and emulator.

Physical and sensor faults are implemented by the pure plant (:mod:`sim_plant.sensors`,
:mod:`sim_plant.drives`); protocol-level faults (``malformed_burst``, ``serial_unplug``,
``heartbeat_loss``) are parsed and validated here and carried out by the emulator.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

GNSS_FAULTS: tuple[str, ...] = ("gnss_freeze", "gnss_jump", "gnss_drift", "gnss_noise", "gnss_dropout",
                                "gnss_invalid")
GYRO_FAULTS: tuple[str, ...] = ("gyro_freeze", "gyro_offset", "gyro_drift", "gyro_dropout", "gyro_invalid")
ROT_FAULTS: tuple[str, ...] = ("rot_freeze", "rot_offset", "rot_dropout", "rot_invalid")  # rate-of-turn sensors
THRUSTER_FAULTS: tuple[str, ...] = ("thruster_stuck", "thruster_zero", "thruster_wrong_sign", "thruster_not_ready")
PROTOCOL_FAULTS: tuple[str, ...] = ("malformed_burst", "serial_unplug", "heartbeat_loss")
FAULT_KINDS: tuple[str, ...] = GNSS_FAULTS + GYRO_FAULTS + ROT_FAULTS + THRUSTER_FAULTS + PROTOCOL_FAULTS


@dataclass(frozen=True)
class Fault:
    """One injected fault, active for ``t_s ≤ t < t_s + duration_s``.

    Attributes
    ----------
    t_s : float
        Start [s].
    kind : str
        One of :data:`FAULT_KINDS`.
    target : str
        Sensor or thruster name.
    duration_s : float or None
        Length [s]; None = until the end of the run.
    offset_m, direction_rad : float
        ``gnss_jump``: offset size [m] and its NED direction [rad] (``gnss_drift`` uses the
        direction too).
    rate_mps : float
        ``gnss_drift``: drift speed of the reported position [m/s].
    factor : float
        ``gnss_noise``: multiplier of the white noise [-].
    offset_rad : float
        ``gyro_offset``: heading offset [rad].
    rate_radps : float
        ``gyro_drift``: heading drift rate [rad/s]; ``rot_offset``: rate error [rad/s].
    count : int
        ``malformed_burst``: number of malformed sentences/frames (emulator).
    """

    t_s: float
    kind: str
    target: str
    duration_s: float | None = None
    offset_m: float = 0.0
    direction_rad: float = 0.0
    rate_mps: float = 0.0
    factor: float = 1.0
    offset_rad: float = 0.0
    rate_radps: float = 0.0
    count: int = 0

    def __post_init__(self) -> None:
        if self.kind not in FAULT_KINDS:
            raise ValueError(f"unknown fault kind {self.kind!r}")
        if self.duration_s is not None and self.duration_s <= 0.0:
            raise ValueError("fault duration_s must be > 0")

    @property
    def end_s(self) -> float:
        """End time [s] (inf when it lasts to the end)."""
        return math.inf if self.duration_s is None else self.t_s + self.duration_s

    def active(self, t_s: float) -> bool:
        return self.t_s <= t_s < self.end_s
