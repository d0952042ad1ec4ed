"""Wall time and BLAS threads of the scripts: best-of-n timing, one BLAS thread.

Small matrix products suffer from OpenBLAS threading on a busy 2-core machine (tens of times
slower at random), which would make measured ratios meaningless; every script's ``main()``
therefore runs under :func:`one_blas_thread`. Nothing here runs at import, and the module
imports no numpy, so that the command line can pin the threads before numpy is loaded.
"""

from __future__ import annotations

import functools
import os
import time

BLAS_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


def limit_blas_threads() -> None:
    """One BLAS thread, unless the user set otherwise, for numpy loaded after this call and
    for every child process started after it (environment variables)."""
    for variable in BLAS_VARIABLES:
        os.environ.setdefault(variable, "1")


def one_blas_thread(main):
    """Decorate a script's ``main``: while it runs, BLAS uses one thread (threadpoolctl, for
    the libraries already loaded) and so do the processes it starts
    (:func:`limit_blas_threads`)."""
    @functools.wraps(main)
    def pinned(*args, **kwargs):
        from threadpoolctl import threadpool_limits

        limit_blas_threads()
        with threadpool_limits(limits=1):
            return main(*args, **kwargs)
    return pinned


def best_time(function, repeats: int):
    """Smallest wall time of ``repeats`` calls, and the last call's result."""
    best, result = float("inf"), None
    for _ in range(repeats):
        start = time.perf_counter()
        result = function()
        best = min(best, time.perf_counter() - start)
    return best, result
