"""One BLAS thread for the computations whose answer must not depend on the thread count.

A matrix product sums in an order that depends on how many threads share it, so its last
bits do. Most results do not notice. A search that decides on sampled verdicts does: a built
machine whose worst ratio is 1 − 1e-15 passes or fails by those bits, and the search then
takes another path (the allocation for a machine yield on the paper's machine, seed 2023,
4 000 machines: 124.41 % of the initial cost on one thread, 124.77 % on two). Such functions
run under :func:`one_blas_thread`, so that the same inputs give the same answer in a
script, a notebook and the command line, whatever ``OPENBLAS_NUM_THREADS`` says.
"""

from __future__ import annotations

import functools


def one_blas_thread(function):
    """Decorate ``function``: while it runs, the BLAS libraries loaded use one thread
    (:func:`threadpoolctl.threadpool_limits`), and the caller's setting is restored after."""
    @functools.wraps(function)
    def pinned(*args, **kwargs):
        from threadpoolctl import threadpool_limits

        with threadpool_limits(limits=1, user_api="blas"):
            return function(*args, **kwargs)
    return pinned
