"""Compiled numeric kernels: numba's settings in one place, for the numeric core and the plant.

Why compiled kernels: the control step works on small arrays (8 models × 15 states, 3-vectors,
6–8 thrusters), where a numpy call costs 0.5–2 µs of Python dispatch for a few nanoseconds of
arithmetic. A step written as ~50 such calls spends almost all of its time in dispatch; the same
arithmetic as loops in one numba kernel costs one call. numba compiles the Python source of a
kernel, so the equations stay readable next to their references and the same code runs (slowly)
as plain Python with ``NUMBA_DISABLE_JIT=1`` for debugging.

Settings, and why:

* **eager compilation** — every kernel is declared with its signature and compiled (or loaded from
  the cache) when its module is imported, i.e. before the control loop starts: a controller must not
  stop for a second to compile the first time it engages DP;
* ``cache=True`` — compiled code is kept on disk and reused while the source is unchanged (numba
  stamps it with the source file's hash). The cache lives next to the source (``__pycache__``) or,
  where that is read-only (a service under ``ProtectSystem=strict``), in ``NUMBA_CACHE_DIR``
  (``deploy/dpcontrol.service`` sets it to the unit's ``CacheDirectory``). Where no cache directory is
  writable the kernels are compiled at every start instead of failing;
  One limit of numba's cache: a kernel that calls a kernel of *another* file (``ssa_compiled`` of
  :mod:`dpbase.frames`) is cached together with it, and is not recompiled when only that
  other file changes — after editing a shared kernel, delete the ``__pycache__`` folders (a fresh
  install or checkout has none);
* ``fastmath=False`` — IEEE arithmetic: no reassociation, so a run is reproducible and a recording
  replays exactly;
* ``error_model="numpy"`` — a division by zero gives ±inf/NaN as in numpy (the callers check for
  finite results) instead of raising inside the loop;
* ``nogil=True`` — the daemon's sensor reader threads keep running while a kernel computes;
* ``boundscheck=False`` — the callers own the array shapes (checked at construction).

Kernels take preallocated arrays and write their results into them (no allocation per call).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar

import numba

F = TypeVar("F", bound=Callable[..., Any])

# Types for kernel signatures (C-contiguous arrays, the layout of every preallocated buffer)
f8 = numba.float64
i8 = numba.int64
b1 = numba.boolean
void = numba.void
f8_1d = numba.float64[::1]
f8_2d = numba.float64[:, ::1]
f8_3d = numba.float64[:, :, ::1]
f8_4d = numba.float64[:, :, :, ::1]
b1_1d = numba.boolean[::1]
i8_1d = numba.int64[::1]
UniTuple = numba.types.UniTuple
Tuple = numba.types.Tuple

_OPTIONS: dict[str, Any] = {"nogil": True, "fastmath": False, "error_model": "numpy", "boundscheck": False}


def kernel(signature: Any) -> Callable[[F], F]:
    """Decorator: compile ``function`` for ``signature`` now (from the on-disk cache when it is there).

    Parameters
    ----------
    signature : numba signature
        e.g. ``void(f8_2d, f8_1d)`` or ``f8(f8_1d)``; one signature per kernel.
    """
    def decorate(function: F) -> F:
        try:
            return numba.njit(signature, cache=True, **_OPTIONS)(function)  # type: ignore[no-any-return]
        except RuntimeError as error:  # no writable cache directory (numba: "no locator available")
            if "locator" not in str(error):
                raise
            return numba.njit(signature, cache=False, **_OPTIONS)(function)  # type: ignore[no-any-return]
    return decorate
