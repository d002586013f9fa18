"""Irregular long-crested waves: first-order WF motion through RAOs, second-order drift forces,
piecewise-constant sea states with cross-fades.

One :class:`WaveField` is one sea state realised as ``n`` regular waves (see
:mod:`sim_plant.environment.spectra`) acting on one hull. Phases are taken at the vessel's LF
position, φ_i(t) = ω_i t − k_i d(t) + ε_i with d the position along the propagation direction, so a
moving vessel (the mariner at 7.7 m/s) sees the encounter frequency ω_e = ω − k·U cos β without any
special case. The WF motion lives in body axes (seed 001 eqs. (8)–(11), (34)):

    x_w = Σ a_i X(ω_i, β) sin φ_i,   y_w = Σ a_i Y(ω_i, β) sin φ_i,   ψ_w = −Σ a_i Ψ(ω_i, β) cos φ_i

with the RAOs of :mod:`sim_plant.environment.rao` and β the propagation direction relative to the
LF heading; the plant adds R(ψ)·(x_w, y_w) to the LF position and ψ_w to the heading (seed 001
eq. (15)).

The slowly varying drift force uses Newman's approximation in envelope form: with
b_i = √(½ρg)·R(ω_i)·a_i, the force per unit length is |Σ b_i e^{iφ_i}|², whose mean is
Σ ½ρg R_i² a_i² ∝ Hs² and whose fluctuation contains only difference frequencies ω_i − ω_j.

A sea state is one wave system (a wind sea) or two (a wind sea and a swell from its own direction, each with its
own spectrum): the systems are independent realisations, so their motions add and so do their drift forces
(the envelopes of independent systems do not interfere in the mean). A change of sea state regenerates the
components; during ``fade_s`` after the change the output is
cos(πs/2)·old + sin(πs/2)·new with s a smoothstep of time, which keeps the WF motion and its rate
continuous and, for independent realisations, the variance between the two states.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import NamedTuple

import numpy as np

from dpbase.frames import ssa
from sim_plant.environment.rao import HullDimensions, drift_direction_factors, motion_raos, reflection_coefficient
from sim_plant.environment.spectra import GRAVITY_MPS2, SPECTRA, WaveComponents, realise_waves, wave_spectrum
from sim_plant.kernels import W_B, W_PSI, W_X, WAVE_WEIGHTS, wave_sums

_BETA_STEPS = 360
_BETA_STEP_RAD = 2.0 * math.pi / _BETA_STEPS
_BETA_REFRESH_RAD = 1e-3  # re-interpolate the RAO vectors when β moved more than this (0.06°)
_BETA_GRID = -math.pi + _BETA_STEP_RAD * np.arange(_BETA_STEPS + 1)  # the RAO table's β [rad]


@dataclass(frozen=True)
class WaveSystem:
    """One wave system of a sea state: a swell beside the wind sea (scenario ``sea_states[i].swell``).

    Attributes
    ----------
    hs_m : float
        Significant wave height of this system [m].
    omega_peak_rad_s : float
        Its spectrum peak frequency [rad/s].
    direction_rad : float
        Direction it comes FROM, NED, clockwise from north [rad].
    spectrum : {"jonswap", "pierson_moskowitz"}
    gamma : float
        JONSWAP peak enhancement (a swell's narrow spectrum: 3–10).
    components : int
        Number of regular wave components.
    """

    hs_m: float
    omega_peak_rad_s: float
    direction_rad: float = 0.0
    spectrum: str = "jonswap"
    gamma: float = 3.3
    components: int = 200

    def __post_init__(self) -> None:
        if self.spectrum not in SPECTRA:
            raise ValueError(f"unknown spectrum {self.spectrum!r}")
        if self.hs_m < 0.0 or self.omega_peak_rad_s <= 0.0 or self.components < 1:
            raise ValueError(f"invalid wave system {self}")


@dataclass(frozen=True)
class SeaState:
    """One sea state, in force from ``t_s`` on (scenario ``sea_states`` entry).

    Attributes
    ----------
    t_s : float
        Start time [s].
    hs_m : float
        Significant wave height [m] (0 = calm).
    omega_peak_rad_s : float
        Spectrum peak frequency ωp [rad/s] (seed 001 Table I: calm > 0.79, moderate 0.67–0.79,
        high 0.45–0.67).
    direction_rad : float
        Direction the waves come FROM, NED, clockwise from north [rad] (like wind).
    spectrum : {"jonswap", "pierson_moskowitz"}
    gamma : float
        JONSWAP peak enhancement (3.3 typical; 1 = Pierson–Moskowitz).
    components : int
        Number of regular wave components (≥ 100 in scenarios).
    fade_s : float
        Cross-fade time from the previous sea state [s].
    swell : WaveSystem or None
        A second wave system with its own spectrum and direction (None: the wind sea alone).
    """

    t_s: float
    hs_m: float
    omega_peak_rad_s: float
    direction_rad: float = 0.0
    spectrum: str = "jonswap"
    gamma: float = 3.3
    components: int = 200
    fade_s: float = 30.0
    swell: WaveSystem | None = None

    def __post_init__(self) -> None:
        if self.fade_s < 0.0:
            raise ValueError(f"invalid sea state {self}: fade_s < 0")
        self.wind_sea()  # (its own checks: spectrum, height, peak, components)

    @property
    def calm(self) -> bool:
        return not self.systems()

    def wind_sea(self) -> WaveSystem:
        """This state's own wave system (its fields but ``t_s``, ``fade_s`` and ``swell``)."""
        return WaveSystem(self.hs_m, self.omega_peak_rad_s, self.direction_rad, self.spectrum, self.gamma,
                          self.components)

    def systems(self) -> tuple[WaveSystem, ...]:
        """The systems with waves, the wind sea first, then the swell."""
        return tuple(s for s in (self.wind_sea(), self.swell) if s is not None and s.hs_m > 0.0)


class WaveSample(NamedTuple):
    """Wave effects at one instant (immutable; a named tuple: the plant evaluates the waves once per substep,
    and a tuple costs a quarter of a frozen dataclass to build).

    Attributes
    ----------
    surge_m, sway_m, yaw_rad : float
        First-order WF motion in body axes [m, m, rad].
    yaw_rate_radps : float
        Time derivative of ``yaw_rad`` at the vessel (encounter frequency) [rad/s].
    drift_b : tuple of float
        Second-order drift force (X, Y, N) in body axes [N, N, N·m].
    """

    surge_m: float
    sway_m: float
    yaw_rad: float
    yaw_rate_radps: float
    drift_b: tuple[float, float, float]


CALM = WaveSample(0.0, 0.0, 0.0, 0.0, (0.0, 0.0, 0.0))


class WaveField:
    """One realised sea state acting on one hull.

    Parameters
    ----------
    components : WaveComponents
    direction_from_rad : float
        Direction the waves come from (NED) [rad].
    hull : HullDimensions
    water_density_kgpm3 : float
    drift_scale : float
        Multiplier on the thin-wall drift coefficient (see :mod:`sim_plant.environment.rao`).
    """

    def __init__(self, components: WaveComponents, direction_from_rad: float, hull: HullDimensions,
                 water_density_kgpm3: float = 1025.0, drift_scale: float = 1.0) -> None:
        self.components = components
        self.direction_from_rad = direction_from_rad
        chi = direction_from_rad + math.pi  # propagation direction
        self.propagation_rad = ssa(chi)
        self._cos_chi = math.cos(chi)
        self._sin_chi = math.sin(chi)
        # C-contiguous float64: the layout of the kernel's arguments
        self._omega = np.ascontiguousarray(components.omega_rad_s, dtype=float)
        self._k = np.ascontiguousarray(components.wavenumber_radpm, dtype=float)
        self._eps = np.ascontiguousarray(components.phase_rad, dtype=float)
        self._a = components.amplitude_m
        self._rho = water_density_kgpm3
        self._drift_scale = drift_scale
        # The weights of the sums over the components (rows: sim_plant.kernels.WAVE_WEIGHTS): the RAOs
        # times the amplitudes at the current β (interpolated in _refresh) and the drift amplitudes.
        self._weights = np.zeros((len(WAVE_WEIGHTS), self._omega.size))
        self._beta_cached = math.inf
        self._drift_factors = (0.0, 0.0, 0.0)
        self.set_hull(hull)

    # -- hull-dependent tables ------------------------------------------------------------------
    def set_hull(self, hull: HullDimensions) -> None:
        """(Re)build the RAO table over β (1° grid) and the drift coefficients for ``hull``.

        The table's rows are computed when first needed (:meth:`_rao_row`): a vessel on station uses
        two or three of the 361, and the draft of a tanker being loaded changes the hull ~200 times.
        """
        self.hull = hull
        self._rao_rows: dict[int, np.ndarray] = {}
        r = reflection_coefficient(self._omega, hull.draft_m)
        self._b = math.sqrt(0.5 * self._rho * GRAVITY_MPS2 * self._drift_scale) * r * self._a
        self._weights[W_B] = self._b
        self._beta_cached = math.inf

    def _rao_row(self, j: int) -> np.ndarray:
        """Row ``j`` of the RAO table, shape (3, n): a_i X, a_i Y, a_i Ψ at β_j [m, m, rad]."""
        row = self._rao_rows.get(j)
        if row is None:
            rx, ry, rpsi = motion_raos(self._omega[None, :], _BETA_GRID[j:j + 1, None], self.hull)
            row = self._rao_rows[j] = np.concatenate((rx, ry, rpsi)) * self._a
        return row

    def _refresh(self, beta: float) -> None:
        if abs(beta - self._beta_cached) <= _BETA_REFRESH_RAD:
            return
        pos = (beta + math.pi) / _BETA_STEP_RAD
        j = min(int(pos), _BETA_STEPS - 1)
        w = pos - j
        target = self._weights[W_X:W_PSI + 1]  # the rows a X, a Y, a Ψ: linear in β between the grid rows
        np.multiply(self._rao_row(j), 1.0 - w, out=target)
        np.add(target, w * self._rao_row(j + 1), out=target)
        self._beta_cached = beta
        self._drift_factors = drift_direction_factors(beta, self.hull)

    def relative_direction(self, heading_rad: float) -> float:
        """β = propagation direction relative to the bow, wrapped (−π, π] [rad]."""
        return ssa(self.propagation_rad - heading_rad)

    # -- evaluation -------------------------------------------------------------------------------
    def evaluate(self, t_s: float, north_m: float, east_m: float, heading_rad: float, *,
                 north_rate_mps: float = 0.0, east_rate_mps: float = 0.0, weight: float = 1.0
                 ) -> tuple[float, float, float, float, float, float]:
        """WF motion, its yaw rate and the drift envelope at one instant (:func:`sim_plant.kernels.wave_sums`).

        Parameters
        ----------
        t_s : float
        north_m, east_m, heading_rad : float
            LF pose of the vessel (phase reference and relative direction).
        north_rate_mps, east_rate_mps : float
            LF velocity in NED (Doppler term of the WF yaw rate).
        weight : float
            Cross-fade weight applied to every output.

        Returns
        -------
        tuple
            (x_w [m], y_w [m], ψ_w [rad], ψ̇_w [rad/s], Re A, Im A) with A = Σ b_i e^{iφ_i} [√(N/m)]
            (weighted).
        """
        beta = self.relative_direction(heading_rad)
        self._refresh(beta)
        d = north_m * self._cos_chi + east_m * self._sin_chi
        d_rate = north_rate_mps * self._cos_chi + east_rate_mps * self._sin_chi
        return wave_sums(t_s, d, d_rate, weight, self._omega, self._k, self._eps, self._weights)

    def drift_factors(self) -> tuple[float, float, float]:
        """Direction factors (l_x, l_y, l_ψ) for the β of the last :meth:`evaluate`."""
        return self._drift_factors

    def motion_series(self, t_s: np.ndarray, heading_rad: float, north_m: float = 0.0, east_m: float = 0.0
                      ) -> np.ndarray:
        """WF body motion for many times at a fixed pose, with the exact RAOs (tests, plots).

        Returns
        -------
        ndarray, shape (len(t_s), 3)
            Columns x_w [m], y_w [m], ψ_w [rad].
        """
        beta = self.relative_direction(heading_rad)
        rx, ry, rpsi = motion_raos(self._omega, beta, self.hull)
        d = north_m * self._cos_chi + east_m * self._sin_chi
        phi = np.multiply.outer(np.asarray(t_s, dtype=float), self._omega) - self._k * d + self._eps
        s = np.sin(phi)
        return np.column_stack((s @ (self._a * rx), s @ (self._a * ry), -(np.cos(phi) @ (self._a * rpsi))))

    def mean_drift_b(self, heading_rad: float) -> tuple[float, float, float]:
        """Mean drift force Σ b_i² · (l_x, l_y, l_ψ) in body axes [N, N, N·m] (∝ Hs²)."""
        mean = float(np.dot(self._b, self._b))
        lx, ly, ln = drift_direction_factors(self.relative_direction(heading_rad), self.hull)
        return mean * lx, mean * ly, mean * ln


#: A peak-finding grid: ω [rad/s] and each wave system's spectrum on it [m²·s/rad]
PeakGrid = tuple[np.ndarray, tuple[np.ndarray, ...]]


def _systems_or_unit(state: SeaState) -> tuple[WaveSystem, ...]:
    """The state's wave systems, or for a calm state the wind sea's shape at unit Hs (its peaks are still asked)."""
    return state.systems() or (replace(state.wind_sea(), hs_m=1.0),)


def _peak_grid(state: SeaState) -> PeakGrid:
    """600 points per wave system over [0.3·min ωp, 5·max ωp], and each system's spectrum on them."""
    systems = _systems_or_unit(state)
    low = min(s.omega_peak_rad_s for s in systems)
    high = max(s.omega_peak_rad_s for s in systems)
    w = np.linspace(0.3 * low, 5.0 * high, 600 * len(systems))
    return w, tuple(wave_spectrum(w, s.hs_m, s.omega_peak_rad_s, s.gamma, s.spectrum) for s in systems)


def _system_encounters(state: SeaState, beta_rad: float, speed_along_mps: float, speed_across_mps: float
                       ) -> list[tuple[float, float]]:
    """Per wave system: (β relative to the bow [rad], the vessel's speed along its propagation [m/s]).

    ``beta_rad`` and the speeds are those of the state's own direction (the wind sea's); a system from a
    direction Δ further clockwise is met at β + Δ, and the speed along it is U_along·cos Δ + U_across·sin Δ
    (``speed_across_mps``: the velocity component 90° clockwise of the wind sea's propagation).
    """
    out = []
    for system in _systems_or_unit(state):
        delta = system.direction_rad - state.direction_rad
        if delta == 0.0:
            out.append((beta_rad, speed_along_mps))
        else:
            out.append((ssa(beta_rad + delta),
                        speed_along_mps * math.cos(delta) + speed_across_mps * math.sin(delta)))
    return out


def motion_peaks(state: SeaState, hull: HullDimensions, beta_rad: float, speed_along_mps: float = 0.0,
                 grid: PeakGrid | None = None, *, speed_across_mps: float = 0.0
                 ) -> tuple[float | None, float | None, float | None]:
    """Peak frequencies of the continuous motion spectra Σ_k |RAO_i(ω, β_k)|² S_k(ω) (surge, sway, yaw).

    With the vessel moving at ``speed_along_mps`` along the wave propagation direction, the spectra
    are mapped to the encounter frequency ω_e = ω − ω²U/g (density divided by |dω_e/dω|, clipped
    near the following-sea singularity), since that is what a filter on board sees; with a swell, each system
    with its own β_k and speed along it (:func:`_system_encounters`), and the peak's ω mapped with the speed
    along the system that contributes most there. The maximum is found on a 600-point grid per system over
    [0.3, 5]·ωp and refined by a parabola through the three points around it (error ≪ 0.1 % of ωp).

    Returns
    -------
    tuple of (float or None)
        ω of the maxima [rad/s] (encounter frequency when moving); None for a DOF the waves do not
        move (e.g. yaw in exact head seas).
    """
    w, spectra = grid if grid is not None else _peak_grid(state)
    systems = []  # per system: (RAOs (surge, sway, yaw), its spectrum as the filter sees it, speed along)
    encounters = _system_encounters(state, beta_rad, speed_along_mps, speed_across_mps)
    for spectrum, (beta, along) in zip(spectra, encounters, strict=True):
        seen = spectrum if along == 0.0 else \
            spectrum / np.maximum(np.abs(1.0 - 2.0 * w * along / GRAVITY_MPS2), 0.05)
        systems.append((motion_raos(w, beta, hull), seen, along))
    peaks: list[float | None] = []
    for dof in range(3):
        # a DOF whose RAO is zero up to rounding (sway in exact head seas: sin π ≈ 1e-16) has no peak
        if all(np.max(np.abs(raos[dof])) <= 1e-9 for raos, _, _ in systems):
            peaks.append(None)
            continue
        parts = [raos[dof] * raos[dof] * spectrum for raos, spectrum, _ in systems]
        density = parts[0] if len(parts) == 1 else np.sum(parts, axis=0)
        j = min(max(int(np.argmax(density)), 1), w.size - 2)
        y0, y1, y2 = density[j - 1], density[j], density[j + 1]
        curvature = y0 - 2.0 * y1 + y2
        shift = 0.5 * (y0 - y2) / curvature if curvature < 0.0 else 0.0
        omega = float(w[j] + shift * (w[1] - w[0]))
        along = systems[int(np.argmax([part[j] for part in parts]))][2]
        peaks.append(abs(omega - omega * omega * along / GRAVITY_MPS2))
    return peaks[0], peaks[1], peaks[2]


def motion_variances(state: SeaState, hull: HullDimensions, beta_rad: float,
                     grid: PeakGrid | None = None) -> tuple[float, float, float]:
    """Σ_k ∫|RAO_i(ω, β_k)|² S_k dω for surge [m²], sway [m²], yaw [rad²] (which DOF dominates)."""
    w, spectra = grid if grid is not None else _peak_grid(state)
    total = [0.0, 0.0, 0.0]
    for spectrum, (beta, _) in zip(spectra, _system_encounters(state, beta_rad, 0.0, 0.0), strict=True):
        for dof, rao in enumerate(motion_raos(w, beta, hull)):
            total[dof] += float(np.trapezoid(rao * rao * spectrum, w))
    return total[0], total[1], total[2]


def spectrum_peak(state: SeaState) -> float:
    """The wave spectrum's peak ω [rad/s]: the wind sea's ωp, or the swell's where the summed spectrum is
    higher at the swell's peak than at the wind sea's."""
    systems = _systems_or_unit(state)
    if len(systems) == 1:
        return systems[0].omega_peak_rad_s

    def total(omega: float) -> float:
        at = np.array([omega])
        return sum(float(wave_spectrum(at, s.hs_m, s.omega_peak_rad_s, s.gamma, s.spectrum)[0]) for s in systems)

    return max((s.omega_peak_rad_s for s in systems), key=total)


@dataclass(frozen=True, slots=True)
class SpectrumPeaks:
    """Peaks that judge a wave filter (docs/design.md §5, trap 3).

    Attributes
    ----------
    omega_peak_rad_s : float or None
        Wave spectrum peak ωp (None in calm water) [rad/s].
    motion_peak_rad_s : float or None
        Peak of |RAO|²S of the dominant DOF [rad/s].
    motion_peaks_rad_s : tuple of (float or None), or None
        Peaks for surge, sway, yaw [rad/s] (None for a DOF without WF motion).
    dominant_dof : int or None
        0 surge, 1 sway, 2 yaw.
    """

    omega_peak_rad_s: float | None
    motion_peak_rad_s: float | None
    motion_peaks_rad_s: tuple[float | None, float | None, float | None] | None
    dominant_dof: int | None


NO_PEAKS = SpectrumPeaks(None, None, None, None)


class WaveEnvironment:
    """Piecewise-constant sea states with cross-fades, for one vessel.

    Parameters
    ----------
    sea_states : sequence of SeaState
        Sorted by ``t_s``; before the first one the sea is calm. Consecutive changes must be at
        least the later one's ``fade_s`` apart (checked by the scenario schema).
    hull : HullDimensions
    rng_for : callable
        ``rng_for(index) -> numpy.random.Generator``: an independent seeded stream per sea state,
        so that adding a sea state does not change the earlier ones.
    water_density_kgpm3, drift_scale : float
    dominant_dof : int or None
        Force the DOF whose motion peak is reported (2 = yaw for a heading autopilot); None picks
        the largest of surge, sway and yaw·L/2.
    """

    def __init__(self, sea_states: Sequence[SeaState], hull: HullDimensions,
                 rng_for: Callable[[int], np.random.Generator], *, water_density_kgpm3: float = 1025.0,
                 drift_scale: float = 1.0, dominant_dof: int | None = None) -> None:
        self.sea_states = tuple(sea_states)
        for earlier, later in zip(self.sea_states, self.sea_states[1:], strict=False):
            if later.t_s < earlier.t_s + later.fade_s:
                raise ValueError(f"sea state at {later.t_s} s starts before the fade from {earlier.t_s} s ends")
        self._starts = [s.t_s for s in self.sea_states]
        self.hull = hull
        self._rng_for = rng_for
        self._rho = water_density_kgpm3
        self._drift_scale = drift_scale
        self._dominant = dominant_dof
        self._fields: dict[int, tuple[WaveField, ...]] = {}  # per sea state, one field per wave system
        self._peak_cache: dict[tuple[int, int, int, int], SpectrumPeaks] = {}
        self._peak_grids: dict[int, PeakGrid] = {}

    def set_hull(self, hull: HullDimensions) -> None:
        """Change the hull (draft during loading): RAO and drift tables are rebuilt."""
        self.hull = hull
        for fields in self._fields.values():
            for field in fields:
                field.set_hull(hull)
        self._peak_cache.clear()

    def _fields_of(self, index: int) -> tuple[WaveField, ...]:
        """The realised wave systems of sea state ``index`` (none in calm water)."""
        if index not in self._fields:
            systems = self.sea_states[index].systems()
            fields = []
            if systems:
                rng = self._rng_for(index)  # the wind sea first: a state without a swell draws as before
                for system in systems:
                    comps = realise_waves(system.hs_m, system.omega_peak_rad_s, system.gamma, system.spectrum,
                                          system.components, rng=rng)
                    fields.append(WaveField(comps, system.direction_rad, self.hull, self._rho, self._drift_scale))
            self._fields[index] = tuple(fields)
            # fields two changes back can never be needed again (times only move forward)
            for old in [i for i in self._fields if i < index - 1]:
                del self._fields[old]
        return self._fields[index]

    def index_at(self, t_s: float) -> int:
        """Index of the sea state in force at ``t_s`` (−1 before the first)."""
        starts = self._starts
        i = len(starts) - 1
        while i >= 0 and starts[i] > t_s:
            i -= 1
        return i

    def evaluate(self, t_s: float, north_m: float, east_m: float, heading_rad: float, *,
                 north_rate_mps: float = 0.0, east_rate_mps: float = 0.0) -> WaveSample:
        """WF motion and drift force at ``t_s`` for the vessel's LF pose and velocity."""
        i = self.index_at(t_s)
        if i < 0:
            return CALM
        state = self.sea_states[i]
        new = self._fields_of(i)
        fading = i > 0 and state.fade_s > 0.0 and t_s < state.t_s + state.fade_s
        if not fading:
            if not new:
                return CALM
            if len(new) == 1:  # (most sea states: one system, no sums)
                x, y, p, r, ac, as_ = new[0].evaluate(t_s, north_m, east_m, heading_rad,
                                                      north_rate_mps=north_rate_mps, east_rate_mps=east_rate_mps)
                lx, ly, ln = new[0].drift_factors()
                f = ac * ac + as_ * as_
                return WaveSample(x, y, p, r, (f * lx, f * ly, f * ln))
            weighted = [(field, 1.0) for field in new]
        else:
            u = (t_s - state.t_s) / state.fade_s
            s = u * u * (3.0 - 2.0 * u)
            w_new = math.sin(0.5 * math.pi * s)
            w_old = math.cos(0.5 * math.pi * s)
            weighted = [(field, w_old) for field in self._fields_of(i - 1)] + [(field, w_new) for field in new]
        total = [0.0, 0.0, 0.0, 0.0]
        drift = [0.0, 0.0, 0.0]
        for field, weight in weighted:
            x, y, p, r, ac, as_ = field.evaluate(t_s, north_m, east_m, heading_rad, north_rate_mps=north_rate_mps,
                                                 east_rate_mps=east_rate_mps, weight=weight)
            total[0] += x
            total[1] += y
            total[2] += p
            total[3] += r
            # Envelopes of independent fields (two sea states, or a wind sea and a swell) do not interfere in
            # the mean: sum the forces.
            lx, ly, ln = field.drift_factors()
            f = ac * ac + as_ * as_
            drift[0] += f * lx
            drift[1] += f * ly
            drift[2] += f * ln
        return WaveSample(total[0], total[1], total[2], total[3], (drift[0], drift[1], drift[2]))

    def peaks(self, t_s: float, heading_rad: float, speed_along_mps: float = 0.0) -> SpectrumPeaks:
        """Wave and motion spectrum peaks of the sea state in force at ``t_s`` (the new one during
        a fade), for the given heading and vessel speed along the wave direction."""
        i = self.index_at(t_s)
        if i < 0 or self.sea_states[i].calm:
            return NO_PEAKS
        return self._peaks(i, heading_rad, speed_along_mps, 0.0)

    def peaks_for_velocity(self, t_s: float, heading_rad: float, north_rate_mps: float,
                           east_rate_mps: float) -> SpectrumPeaks:
        """:meth:`peaks` for a vessel velocity over ground in NED: the speed along the wave direction is
        ``north_rate·cos χ + east_rate·sin χ`` with χ = :meth:`propagation_rad` (0 before the first sea state).

        The same result as ``peaks(t_s, heading_rad, speed)`` with that speed, with one look-up of the sea
        state in force instead of two (the plant's truth asks every control step).
        """
        i = self.index_at(t_s)
        if i < 0 or self.sea_states[i].calm:
            return NO_PEAKS
        prop = ssa(self.sea_states[i].direction_rad + math.pi)  # propagation_rad(t_s)
        c, s = math.cos(prop), math.sin(prop)
        return self._peaks(i, heading_rad, north_rate_mps * c + east_rate_mps * s,
                           east_rate_mps * c - north_rate_mps * s)

    def _peaks(self, i: int, heading_rad: float, speed_along_mps: float, speed_across_mps: float) -> SpectrumPeaks:
        """:meth:`peaks` of sea state ``i`` (in force, not calm); ``speed_across_mps`` (90° clockwise of the
        propagation) matters only to a swell from another direction."""
        state = self.sea_states[i]
        beta = ssa(state.direction_rad + math.pi - heading_rad)
        across = round(speed_across_mps * 10.0) if state.swell is not None else 0
        key = (i, round(math.degrees(beta)), round(speed_along_mps * 10.0), across)
        cached = self._peak_cache.get(key)
        if cached is not None:
            return cached
        beta_q = math.radians(key[1])
        speed_q = key[2] / 10.0
        grid = self._peak_grids.get(i)
        if grid is None:
            grid = self._peak_grids[i] = _peak_grid(state)
        peaks = motion_peaks(state, self.hull, beta_q, speed_q, grid, speed_across_mps=across / 10.0)
        if self._dominant is not None:
            dominant = self._dominant
        else:
            vx, vy, vpsi = motion_variances(state, self.hull, beta_q, grid)
            scaled = (vx, vy, vpsi * (0.5 * self.hull.length_m) ** 2)
            dominant = int(np.argmax(scaled))
        if peaks[dominant] is None:  # e.g. yaw in exact head seas: report the largest that moves
            moving = [d for d in range(3) if peaks[d] is not None]
            dominant = moving[0] if moving else dominant
        result = SpectrumPeaks(spectrum_peak(state), peaks[dominant], peaks, dominant)
        if len(self._peak_cache) > 4096:
            self._peak_cache.clear()
        self._peak_cache[key] = result
        return result

    def propagation_rad(self, t_s: float) -> float | None:
        """Propagation direction (NED) of the sea state in force, None before the first."""
        i = self.index_at(t_s)
        return None if i < 0 else ssa(self.sea_states[i].direction_rad + math.pi)
