"""The wave filter of a configuration: one factory over the kinds (mmae, kf, rpem, pem, raw).

Apart from the filters themselves so that :mod:`~dpcontrol.estimation.rpem` and :mod:`~dpcontrol.estimation.pem`,
built on :mod:`~dpcontrol.estimation.wave_filter`, are not imported back by it (no import cycle).
"""

from __future__ import annotations

from dpcontrol.estimation.filter_config import WaveFilterConfig
from dpcontrol.estimation.pem import PemWaveFilter
from dpcontrol.estimation.rpem import RpemWaveFilter
from dpcontrol.estimation.wave_filter import BankWaveFilter, TimeVaryingWaveFilter, WaveFilter


def make_wave_filter(config: WaveFilterConfig) -> WaveFilter:
    """The wave filter for ``config.kind`` (mmae, kf, rpem, pem, raw)."""
    if config.kind == "pem":
        return PemWaveFilter(config)  # type: ignore[return-value]
    if config.kind == "rpem":
        return RpemWaveFilter(config)
    if config.kind == "kf" and config.time_varying:
        return TimeVaryingWaveFilter(config)
    return BankWaveFilter(config)
