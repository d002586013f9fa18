"""The shared vocabulary below every other package of the project (docs/design.md §1).

* :mod:`dpbase.frames` — NED and body frames, rotations, the one angle wrap ``ssa``;
* :mod:`dpbase.geodesy` — WGS-84 and the local NED tangent plane of a datum;
* :mod:`dpbase.schema` — configuration sections, their checks and :class:`~dpbase.schema.ConfigError`;
* :mod:`dpbase.yamlfile` — reading YAML files (YAML 1.2 numbers) with errors that name the file;
* :mod:`dpbase.jit` — the compiled-kernel decorator (numba) of the numeric kernels.

It imports nothing of ``dpcontrol``, ``interfaces`` or ``sim_plant``; all three import it
(``tests/unit/test_layers.py``).
"""
