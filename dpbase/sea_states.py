"""Sea-state classes by the wave filter's peak frequency (seed 001 Table I, Froude-scaled to a hull).

Shared by the controller's status (the class it reports), the monitor and the console (how they label it).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass


@dataclass(frozen=True, slots=True)
class SeaStateTable:
    """Sea-state classes by wave peak frequency ω₀ (seed 001 Table I by default).

    Seed 001 Table I (for its ~100 m supply vessel): calm ω₀ > 0.79 rad/s, moderate 0.67–0.79,
    high 0.45–0.67. The boundaries only mean something for that vessel class — pass another table
    for another vessel. Each band is ``(lower, upper]``, except the last, which also includes its
    lower bound; frequencies below the last band are ``below``.

    Attributes
    ----------
    bands : tuple of (name, lower_rad_s)
        From the calmest (highest frequency) down; lower bounds strictly decreasing.
    below : str
        Class for ω₀ below the last band.
    """

    bands: tuple[tuple[str, float], ...] = (("calm", 0.79), ("moderate", 0.67), ("high", 0.45))
    below: str = "outside_table"

    def __post_init__(self) -> None:
        if not self.bands:
            raise ValueError("sea-state table needs at least one band")
        lowers = [lower for _, lower in self.bands]
        positive = all(math.isfinite(x) and x > 0.0 for x in lowers)
        if not positive or any(a <= b for a, b in itertools.pairwise(lowers)):
            raise ValueError(f"sea-state band lower bounds must be positive and strictly decreasing, got {lowers}")
        names = [name for name, _ in self.bands] + [self.below]
        if len(set(names)) != len(names):
            raise ValueError(f"sea-state class names must be unique, got {names}")

    @classmethod
    def froude_scaled(cls, length_m: float, reference_length_m: float = 100.0) -> SeaStateTable:
        """Seed 001 Table I carried to a vessel of length ``length_m`` [m] by Froude scaling.

        The table was drawn for "a typical 100 m DP supply vessel" (seed 001, Sec. IV); wave frequencies scale
        as ``sqrt(reference_length_m / length_m)`` between geometrically similar hulls, so a 1:70 model sees a
        sea "calm" above ``0.79 · sqrt(100 / 1.255) ≈ 7.1 rad/s``. Below the last band the sea is longer than
        the table's highest, for this hull: ``long_swell``.
        """
        if not (math.isfinite(length_m) and length_m > 0.0 and math.isfinite(reference_length_m)
                and reference_length_m > 0.0):
            raise ValueError(f"vessel length must be positive, got {length_m} (reference {reference_length_m})")
        factor = math.sqrt(reference_length_m / length_m)
        return cls(bands=tuple((name, lower * factor) for name, lower in cls().bands), below="long_swell")

    def classify(self, omega_rad_s: float | None) -> str | None:
        """Class of peak frequency ``omega_rad_s`` [rad/s]; ``None`` when unknown (None/NaN)."""
        if omega_rad_s is None or not math.isfinite(omega_rad_s):
            return None
        last = len(self.bands) - 1
        for i, (name, lower) in enumerate(self.bands):
            if omega_rad_s > lower or (i == last and omega_rad_s == lower):
                return name
        return self.below


SEA_STATES_SEED001 = SeaStateTable()
