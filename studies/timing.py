"""Shared by the benchmark scripts: best-of-n wall time, and BLAS limited to one thread.

Imports no numpy, so that :func:`limit_blas_threads` can run before numpy is loaded.
"""

from __future__ import annotations

import os
import time

BLAS_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


def limit_blas_threads() -> None:
    """One BLAS thread unless the user set otherwise; call before numpy is imported.

    Small matrix products suffer from OpenBLAS threading on a busy 2-core machine (tens of
    times slower at random), which would make the measured ratios meaningless.
    """
    for variable in BLAS_VARIABLES:
        os.environ.setdefault(variable, "1")


def best_time(function, repeats: int):
    """Smallest wall time of ``repeats`` calls, and the last call's result."""
    best, result = float("inf"), None
    for _ in range(repeats):
        start = time.perf_counter()
        result = function()
        best = min(best, time.perf_counter() - start)
    return best, result
