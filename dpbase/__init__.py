"""The shared vocabulary below every other package of the project (docs/design.md §1).

* :mod:`dpbase.frames` — NED and body frames, rotations, the one angle wrap ``ssa``;
* :mod:`dpbase.geodesy` — WGS-84 and the local NED tangent plane of a datum;
* :mod:`dpbase.schema` — configuration sections, their checks and :class:`~dpbase.schema.ConfigError`;
* :mod:`dpbase.yamlfile` — reading YAML files (YAML 1.2 numbers) with errors that name the file;
* :mod:`dpbase.jit` — the compiled-kernel decorator (numba) of the numeric kernels.
* :mod:`dpbase.wind_loads` — the wind-load law (seed 002 eq. (18), Blendermann 1994) and its ship-type table,
  used by the controller's wind feed-forward and the plant's wind.

It imports nothing of ``dpcontrol``, ``interfaces`` or ``sim_plant``; all three import it
(``tests/unit/test_layers.py``).
"""
