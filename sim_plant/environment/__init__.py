"""Plant environment: waves (spectra, RAOs, WF motion, drift), current and wind (numpy; the per-step
sums over wave and gust components are kernels of :mod:`sim_plant.kernels`).

Modules: :mod:`.spectra` (JONSWAP / Pierson–Moskowitz, NORSOK gusts, sums of sinusoids),
:mod:`.rao` (parametric motion RAOs and drift coefficients from the hull dimensions),
:mod:`.waves` (sea states, cross-fades, WF motion and drift force), :mod:`.current`,
:mod:`.wind` (gusts; the force by the shared law of :mod:`dpbase.wind_loads`).
"""

from sim_plant.environment.current import CurrentModel
from sim_plant.environment.rao import HullDimensions, motion_raos, reflection_coefficient
from sim_plant.environment.spectra import SPECTRA, SpectralProcess, realise_waves, wave_spectrum
from sim_plant.environment.waves import (
    CALM,
    NO_PEAKS,
    SeaState,
    SpectrumPeaks,
    WaveEnvironment,
    WaveField,
    WaveSample,
    WaveSystem,
    motion_peaks,
)
from sim_plant.environment.wind import WindModel, wind_force_b

__all__ = [
    "CALM",
    "NO_PEAKS",
    "SPECTRA",
    "CurrentModel",
    "HullDimensions",
    "SeaState",
    "SpectralProcess",
    "SpectrumPeaks",
    "WaveEnvironment",
    "WaveField",
    "WaveSample",
    "WaveSystem",
    "WindModel",
    "motion_peaks",
    "motion_raos",
    "realise_waves",
    "reflection_coefficient",
    "wave_spectrum",
    "wind_force_b",
]
