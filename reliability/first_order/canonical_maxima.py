"""Worst poses that are a function of the inputs, not of the order a search visited them.

Many machines are symmetric: the hob axis of the paper's machine at two angles 180° apart
gives the same σ of an output, a table axis a quarter turn apart another output's. A
branch and bound (:mod:`reliability.first_order.certificate`) visits such twins in an order
set by the last bits of its bounds, which differ between computers (BLAS kernels, SIMD
width), and a local search polishes the first candidate it holds; reporting "the best found"
would then name one twin on one computer and the other elsewhere. This module makes the
answer canonical:

1. :class:`NearCandidates` keeps every candidate the search met whose value is within a
   tolerance of the best so far (a twin's region is refined as deep as the best one's, so
   its candidates come as close);
2. :func:`representatives` picks one candidate per region (regions apart by more than
   :data:`REGION_SPAN` of a stroke on some axis), the best first, at most
   :data:`MAX_REGIONS`; each is polished by the local search, so every twin ends at its own
   local maximum;
3. :func:`snap_positions` rounds a polished pose to :data:`POSE_RESOLUTION` of each stroke
   (a local search fixes a smooth maximum's position only to about the square root of its
   tolerance, so the digits beyond differ between computers), and the tie rule
   (:func:`reliability.basics.ties.worst_rows`, within
   :data:`reliability.basics.ties.SEARCH_RTOL`) names the first twin in lexicographic order.
"""

from __future__ import annotations

import numpy as np

from ..basics.ties import lexicographic_rank

#: Resolution of a searched pose, as a fraction of each axis' stroke.
POSE_RESOLUTION = 1e-4
#: Candidates kept (the best by value) while the search runs.
POOL_SIZE = 4096
#: Two candidates farther apart than this fraction of a stroke on some axis lie in
#: different regions, each polished on its own.
REGION_SPAN = 0.05
#: Regions polished at most, the best first.
MAX_REGIONS = 8
#: Stopping tolerances of the bounded local search (L-BFGS-B) on an objective scaled to
#: about 1: far below :data:`POSE_RESOLUTION`'s effect, so that the search ends at the same
#: resolution step on every computer (SciPy's defaults stop about 1e-4 of a stroke short).
POLISH_OPTIONS = {"ftol": 1e-15, "gtol": 1e-12, "maxiter": 1000}


class NearCandidates:
    """The candidates within a relative tolerance of the best value met so far.

    Parameters
    ----------
    tolerance : float
        Relative tolerance (in the search's function) within which a candidate is kept.
    n_axes : int
    """

    def __init__(self, tolerance: float, n_axes: int):
        self.tolerance = float(tolerance)
        self.points = np.empty((0, n_axes))
        self.values = np.empty(0)

    def add(self, points, values, best: float) -> None:
        """Keep ``points`` (``(b, n_axes)``) whose ``values`` are near ``best``, drop kept
        ones no longer near it, and keep at most :data:`POOL_SIZE` (the best)."""
        points = np.vstack([self.points, points])
        values = np.concatenate([self.values, values])
        near = values >= best * (1 - self.tolerance)
        points, values = points[near], values[near]
        if len(values) > POOL_SIZE:
            order = _best_first(values, points)[:POOL_SIZE]
            points, values = points[order], values[order]
        self.points, self.values = points, values


def representatives(points, values, span) -> np.ndarray:
    """One candidate per region, the best first, at most :data:`MAX_REGIONS`.

    Parameters
    ----------
    points : ndarray (n, n_axes)
    values : ndarray (n,)
        Larger is worse; ties broken by the first point in lexicographic order.
    span : ndarray (n_axes,)
        Each axis' stroke (zero for a fixed axis).

    Returns
    -------
    ndarray (n_regions, n_axes)
        Candidates no two of which lie within :data:`REGION_SPAN` of a stroke on every axis.
    """
    points = np.asarray(points, dtype=float)
    if not len(points):
        return points
    scale = np.where(span > 0, span, 1.0)
    ordered = points[_best_first(np.asarray(values, dtype=float), points)] / scale
    free = np.ones(len(ordered), dtype=bool)
    chosen = []
    while free.any() and len(chosen) < MAX_REGIONS:
        first = int(np.argmax(free))
        chosen.append(first)
        free &= np.abs(ordered - ordered[first]).max(axis=1) > REGION_SPAN
    return ordered[chosen] * scale


def snap_positions(points, low, high) -> np.ndarray:
    """Positions rounded to :data:`POSE_RESOLUTION` of each stroke ``[low, high]``, measured
    from ``low`` and kept within the stroke; an axis without a stroke keeps its position."""
    points = np.asarray(points, dtype=float)
    step = POSE_RESOLUTION * (np.asarray(high, dtype=float) - low)
    safe = np.where(step > 0, step, 1.0)
    snapped = np.clip(low + np.round((points - low) / safe) * safe, low, high)
    return np.where(step > 0, snapped, points)


def _best_first(values, points) -> np.ndarray:
    """Rows by decreasing value, equal values in lexicographic order of their points."""
    return np.lexsort((lexicographic_rank(points), -values))
