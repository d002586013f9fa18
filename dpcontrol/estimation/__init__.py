"""Wave-filtering estimators of the numeric core.

* :mod:`~dpcontrol.estimation.design_model` — the DP design model (seed 002 eqs. (30)–(39), seed 001
  eqs. (33)–(38)), one builder parameterised by ω0 and ζ;
* :mod:`~dpcontrol.estimation.discretize` — exact discretisation with Van Loan process noise;
* :mod:`~dpcontrol.estimation.kalman` — Joseph-form Kalman filter, DARE steady-state gains;
* :mod:`~dpcontrol.estimation.weighting` — MMAE weights: exact DWSG (seed 000 eq. (18)) and Bayes;
* :mod:`~dpcontrol.estimation.wave_filter` — the runtime protocol and the MMAE/KF/raw filters;
* :mod:`~dpcontrol.estimation.rpem` — RPEM adaptive-frequency filter (seed 003);
* :mod:`~dpcontrol.estimation.kalman_bucy` — Kalman–Bucy filter, Blue Lady (seed 004);
* :mod:`~dpcontrol.estimation.heading` — course-keeping heading filter (seed 002 eqs. (69)–(81));
* :mod:`~dpcontrol.estimation.filter_config` — :class:`WaveFilterConfig` and the default tuning rule;
* :mod:`~dpcontrol.estimation.factory` — :func:`make_wave_filter`, the filter of a configuration's kind.
"""

from dpcontrol.estimation.factory import make_wave_filter
from dpcontrol.estimation.filter_config import WaveFilterConfig
from dpcontrol.estimation.rpem import RpemWaveFilter
from dpcontrol.estimation.wave_filter import (
    BankWaveFilter,
    TimeVaryingWaveFilter,
    WaveFilter,
    WaveFilterOutput,
)

__all__ = [
    "BankWaveFilter",
    "RpemWaveFilter",
    "TimeVaryingWaveFilter",
    "WaveFilter",
    "WaveFilterConfig",
    "WaveFilterOutput",
    "make_wave_filter",
]
