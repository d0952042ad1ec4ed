"""One rule for ties: which pose is "the worst" when several are equally bad.

Many poses of a machine are equally bad by symmetry (a rotary axis at 72° and at 144°, a
linear axis whose position does not enter an output). Their computed values then differ only
by summation rounding, which differs between computers (BLAS, SIMD width), so "the largest"
alone names a different pose on a different machine. Every worst pose the toolkit reports
is therefore chosen by :func:`worst_rows`:

    among the candidates whose value is within a relative tolerance ``rtol`` of the worst
    value, the pose that comes first in lexicographic order (first axis first, smallest
    position first).

``rtol`` is :data:`TIE_RTOL` (1e-9) for values computed in closed form (σ, probabilities)
and :data:`SEARCH_RTOL` (1e-7) for values found by a numerical search, whose optimum is
known only to the search's tolerance.
"""

from __future__ import annotations

import numpy as np

#: Relative tolerance within which closed-form values (σ, failure probability) are tied.
TIE_RTOL = 1e-9
#: Relative tolerance within which values found by a local search are tied.
SEARCH_RTOL = 1e-7


def worst_rows(values, poses, *, rtol: float = TIE_RTOL, largest: bool = True) -> np.ndarray:
    """Row of the worst value of each column, ties broken by the first pose.

    Parameters
    ----------
    values : array_like (n_rows,) or (n_rows, n_columns)
        Non-negative scores, e.g. σ or a failure probability; NaN rows never win.
    poses : array_like (n_rows, n_axes)
        The pose of each row; its lexicographic order breaks ties.
    rtol : float
        Values within ``rtol × |worst|`` of the worst are tied.
    largest : bool
        The worst value is the largest (σ, failure probability) or the smallest.

    Returns
    -------
    int or ndarray of int
        The chosen row (an int for one-dimensional ``values``, one per column otherwise).
    """
    values = np.asarray(values, dtype=float)
    single = values.ndim == 1
    values = values.reshape(len(values), -1)
    signed = values if largest else -values
    signed = np.where(np.isnan(signed), -np.inf, signed)
    worst = signed.max(axis=0)
    tied = signed >= worst - rtol * np.abs(worst)
    rank = lexicographic_rank(poses)
    rows = np.where(tied, rank[:, None], len(rank)).argmin(axis=0)
    return int(rows[0]) if single else rows



def decreasing_order(values) -> np.ndarray:
    """Indices of ``values`` from the largest down; values equal to :data:`TIE_RTOL` of the
    largest magnitude (equal but for rounding, e.g. of symmetric items) keep their order.

    Parameters
    ----------
    values : array_like (n,)

    Returns
    -------
    ndarray of int (n,)
    """
    values = np.asarray(values, dtype=float)
    if not len(values):
        return np.arange(0)
    digits = round(-np.log10(TIE_RTOL))
    level = np.round(values / max(float(np.abs(values).max()), 1e-300), digits)
    return np.argsort(-level, kind="stable")


def lexicographic_rank(poses) -> np.ndarray:
    """Rank of each pose in lexicographic order (first axis first, smallest first)."""
    poses = np.asarray(poses, dtype=float).reshape(len(poses), -1)
    order = np.lexsort(poses.T[::-1])
    rank = np.empty(len(poses), dtype=np.int64)
    rank[order] = np.arange(len(poses))
    return rank


def first_of_equal_rows(keys) -> np.ndarray:
    """Index of the first row of each set of rows equal to the resolution of ``keys``.

    Rows equal in exact arithmetic differ by rounding that differs between computers, so
    rounding alone can put two of them on either side of a step and the sets found would
    depend on the computer. Each row is therefore placed on two grids half a step apart,
    and rows sharing a cell on either grid are one set (connected components): two rows
    within rounding of each other share a cell of at least one grid in every entry unless
    two of their entries straddle a step of each grid.

    Parameters
    ----------
    keys : array_like (n_rows, n_columns)
        Rows scaled so that one unit is the resolution (e.g. values divided by 1e-10).

    Returns
    -------
    ndarray of int
        The first row of each set, in increasing order.
    """
    from scipy import sparse
    from scipy.sparse.csgraph import connected_components

    keys = np.asarray(keys, dtype=float).reshape(len(keys), -1)
    n = len(keys)
    if n == 0:
        return np.arange(0)
    cells = [np.unique(np.floor(keys + shift), axis=0, return_inverse=True)[1].ravel()
             for shift in (0.0, 0.5)]
    links = sparse.coo_matrix((np.ones(2 * n), (np.tile(np.arange(n), 2),
                                                np.concatenate([cells[0],
                                                                cells[1] + n]))),
                              shape=(n, 2 * n))
    graph = sparse.bmat([[None, links], [links.T, None]])
    labels = connected_components(graph, directed=False)[1][:n]
    first = np.full(labels.max() + 1, n)
    np.minimum.at(first, labels, np.arange(n))
    return np.sort(first[first < n])
