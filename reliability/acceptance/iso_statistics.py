"""ISO 230 statistics of measured or simulated test paths: the circular deviation of
ISO 230-4, the positioning statistics of ISO 230-2 and its target spacing.
"""

from __future__ import annotations

import math

import numpy as np

from ..basics.errors import InputError

#: ISO 230-2 target spacing: at least this many targets per metre of travel, and at least
#: :data:`MIN_TARGETS` in all.
TARGETS_PER_METRE = 5
MIN_TARGETS = 5
#: Relative size of the deterministic irregular shift of interior default targets (ISO
#: 230-2 shifts targets off a uniform spacing so that periodic errors are sampled).
TARGET_SHIFT = 0.2


def circular_deviation(points, iterations: int = 2) -> np.ndarray:
    """ISO 230-4 circular deviation ``G``: radial range about the least-squares circle centre.

    Parameters
    ----------
    points : array_like
        ``(..., P, 2)`` actual path in the plane of the test (mm).
    iterations : int
        Gauss–Newton steps of :func:`least_squares_centre`.

    Returns
    -------
    numpy.ndarray
        ``(...)`` G = max_j |p_j − c| − min_j |p_j − c| (mm).
    """
    p = np.asarray(points, dtype=float)
    radial = np.linalg.norm(p - least_squares_centre(p, iterations), axis=-1)
    return radial.max(axis=-1) - radial.min(axis=-1)


def least_squares_centre(points, iterations: int = 2) -> np.ndarray:
    """Centre of the least-squares circle of a path (ISO 230-4).

    The centre and radius minimise ``Σ (|p_j − c| − ρ)²``; found by Gauss–Newton steps from
    the centroid, which converge in one or two steps for a path within micrometres of a
    circle.

    Parameters
    ----------
    points : array_like
        ``(..., P, 2)`` path in the plane of the test (mm).
    iterations : int
        Gauss–Newton steps.

    Returns
    -------
    numpy.ndarray
        ``(..., 1, 2)`` the centre c (mm).
    """
    p = np.asarray(points, dtype=float)
    centre = p.mean(axis=-2, keepdims=True)
    for _ in range(iterations):
        offset = p - centre
        distance = np.linalg.norm(offset, axis=-1)
        unit = offset / distance[..., None]
        # residual_j = |p_j − c| − ρ; its gradient is (−u_j, −1): the normal equations
        basis = np.concatenate([unit, np.ones(distance.shape + (1,))], axis=-1)
        normal = np.einsum("...pi,...pj->...ij", basis, basis)
        right = np.einsum("...pi,...p->...i", basis, distance)
        step = np.linalg.solve(normal, right[..., None])[..., 0]
        # distance ≈ ρ + u·Δc  →  the centre moves by Δc, ρ is step[..., 2]
        centre = centre + step[..., None, :2]
    return centre


def positioning_statistics(deviations) -> dict[str, np.ndarray]:
    """ISO 230-2 (2014, clause 3) statistics of bidirectional positioning runs.

    Parameters
    ----------
    deviations : array_like
        ``(..., runs, 2, targets)`` positioning deviations ``x_ij = P_ij − P_i`` (mm);
        direction 0 approaches every target from below (↑), 1 from above (↓). At least two
        runs.

    Returns
    -------
    dict of ndarray
        ``E``, ``A``, ``R``, ``B`` (bidirectional systematic positioning error, accuracy,
        repeatability and reversal value of the axis) and ``E_up``, ``E_down``, ``R_up``,
        ``R_down``, ``A_up``, ``A_down``, ``M`` (unidirectional values and the range of the
        mean bidirectional positional deviation), each ``(...)``.
    """
    x = np.asarray(deviations, dtype=float)
    if x.ndim < 3 or x.shape[-2] != 2 or x.shape[-3] < 2:
        raise InputError(f"deviations must have shape (..., runs >= 2, 2, targets); "
                         f"got {x.shape}")
    first = x[..., :1, :, :]             # runs taken from the first, so equal runs give s = 0
    mean = first[..., 0, :, :] + (x - first).mean(axis=-3)  # x̄_i↑, x̄_i↓
    s = (x - first).std(axis=-3, ddof=1)  # s_i↑, s_i↓: estimators of the standard uncertainty
    up, down = mean[..., 0, :], mean[..., 1, :]
    s_up, s_down = s[..., 0, :], s[..., 1, :]
    reversal_i = up - down               # B_i = x̄_i↑ − x̄_i↓
    r_up, r_down = 4.0 * s_up, 4.0 * s_down   # R_i↑ = 4 s_i↑, R_i↓ = 4 s_i↓
    r_i = np.maximum(2.0 * s_up + 2.0 * s_down + np.abs(reversal_i),
                     np.maximum(r_up, r_down))  # bidirectional R_i
    bidirectional = (up + down) / 2.0    # x̄_i
    return {
        "E": _range(mean, axis=(-2, -1)),                       # max(x̄↑, x̄↓) − min(x̄↑, x̄↓)
        "A": (mean + 2.0 * s).max(axis=(-2, -1)) - (mean - 2.0 * s).min(axis=(-2, -1)),
        "R": r_i.max(axis=-1),
        "B": np.abs(reversal_i).max(axis=-1),
        "E_up": _range(up), "E_down": _range(down),
        "R_up": r_up.max(axis=-1), "R_down": r_down.max(axis=-1),
        "A_up": (up + 2.0 * s_up).max(axis=-1) - (up - 2.0 * s_up).min(axis=-1),
        "A_down": (down + 2.0 * s_down).max(axis=-1) - (down - 2.0 * s_down).min(axis=-1),
        "M": _range(bidirectional),
    }


def _range(values, axis=-1) -> np.ndarray:
    return values.max(axis=axis) - values.min(axis=axis)


def default_targets(stroke, per_metre: int = TARGETS_PER_METRE,
                    minimum: int = MIN_TARGETS) -> np.ndarray:
    """Target positions by ISO 230-2's spacing rule (its test conditions, target positions).

    At least ``per_metre`` targets per metre of travel and at least ``minimum`` in all,
    ``P_i = (i − 1) p + r_i`` over the stroke with ``p`` the uniform spacing and ``r_i`` a
    shift that differs from target to target so that periodic errors are sampled. The
    standard draws ``r_i`` at random; here it is the deterministic
    ``r_i = TARGET_SHIFT · p · (2 frac(i φ) − 1)`` (φ the golden ratio), so that the same
    file gives the same targets, and the two end targets sit at the stroke ends.

    Parameters
    ----------
    stroke : (float, float)
        mm.

    Returns
    -------
    numpy.ndarray
        Increasing targets (mm).
    """
    low, high = (float(v) for v in stroke)
    count = max(minimum, math.ceil(per_metre * (high - low) / 1000.0))
    spacing = (high - low) / (count - 1)
    index = np.arange(count)
    golden = (1.0 + math.sqrt(5.0)) / 2.0
    shift = TARGET_SHIFT * spacing * (2.0 * np.mod(index * golden, 1.0) - 1.0)
    shift[[0, -1]] = 0.0
    return low + index * spacing + shift
