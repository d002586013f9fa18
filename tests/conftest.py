"""Test-wide settings.

One BLAS thread for the whole suite (as the Makefile and the systemd units set it): the numeric
core works on small matrices, where a threaded BLAS on a loaded 2-core machine costs ~100×.
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
