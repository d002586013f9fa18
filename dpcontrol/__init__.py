"""dpcontrol — dynamic positioning controller service.

Layers (imports point down only, see ``docs/design.md`` §1):

* :mod:`dpbase` (below every package): frames, geodesy, configuration schema, YAML, compiled-kernel helper;
* numeric core: :mod:`dpcontrol.models`, :mod:`dpcontrol.estimation`,
  :mod:`dpcontrol.guidance`, :mod:`dpcontrol.control`, :mod:`dpcontrol.allocation`
  — numpy/scipy only, no clock, no I/O;
* :mod:`dpcontrol.runtime` — control loop, sensor hub, modes, alarms;
* :mod:`dpcontrol.cli` — composition.
"""

__version__ = "0.1.0"
