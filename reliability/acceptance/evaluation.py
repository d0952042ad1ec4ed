"""ISO 230-2, ISO 230-4 and ISO 10791-6 values of a built machine, from its readings.

The prediction (:mod:`reliability.acceptance.prediction`) gives what machines built to an
allocation will show; this module gives what one measured machine shows, by the same
definitions, from the deviations read in acceptance runs (read and checked by
:mod:`reliability.measured.acceptance_runs`). Every value is in mm.

**ISO 230-2:2014, clause 3 (terms and definitions), positioning of a linear axis.** At
target ``i`` (``m`` targets) the ``j``-th of ``n`` cycles reads the positional deviation
``x_ij = P_ij − P_i`` approaching in the ``+`` direction (↑) and in the ``−`` direction (↓):

- mean unidirectional positional deviation at a target: the mean over the **cycles**,
  ``x̄_i↑ = (1/n) Σ_j x_ij↑`` (likewise ↓), and the mean bidirectional positional deviation
  ``x̄_i = (x̄_i↑ + x̄_i↓) / 2``;
- estimator of the unidirectional standard uncertainty of positioning at a target,
  ``s_i↑ = √(Σ_j (x_ij↑ − x̄_i↑)² / (n − 1))``;
- reversal value at a target ``B_i = x̄_i↑ − x̄_i↓``; of the axis ``B = max |B_i|``; mean
  reversal value ``B̄ = (1/m) Σ_i B_i``;
- unidirectional repeatability at a target ``R_i↑ = 4 s_i↑``; bidirectional
  ``R_i = max(2 s_i↑ + 2 s_i↓ + |B_i|, R_i↑, R_i↓)``; of the axis ``R↑ = max R_i↑``,
  ``R = max R_i``;
- unidirectional systematic positioning error ``E↑ = max x̄_i↑ − min x̄_i↑``; bidirectional
  ``E = max(x̄_i↑, x̄_i↓) − min(x̄_i↑, x̄_i↓)``; range of the mean bidirectional positional
  deviation ``M = max x̄_i − min x̄_i``;
- unidirectional accuracy ``A↑ = max(x̄_i↑ + 2 s_i↑) − min(x̄_i↑ − 2 s_i↑)``; bidirectional
  ``A = max(x̄_i↑ + 2 s_i↑, x̄_i↓ + 2 s_i↓) − min(x̄_i↑ − 2 s_i↑, x̄_i↓ − 2 s_i↓)``.

**ISO 230-4:2005, clause 3 (terms and definitions), circular tests.** A ballbar of nominal
length ``r`` reads the change ``v_j`` of its length at the nominal angle ``θ_j``, so the
actual path is ``p_j = (r + v_j)(cos θ_j, sin θ_j)`` about the ballbar's centre:

- circular deviation ``G(+)``, ``G(−)``: the range of ``|p_j − c|`` over one direction's
  path, ``c`` the centre of that path's least-squares circle (the minimum radial separation
  of two circles about that centre enclosing the path);
- bidirectional circular deviation ``G``: the same over both paths together, about the
  centre of the least-squares circle of both;
- circular hysteresis ``H``: the largest radial difference between the two paths, both
  about that common centre, the ``−`` path interpolated (periodically, linearly in the
  angle) at the angles of the ``+`` path;
- radial deviation ``F``: ``|p_j − c| − r``, the actual path against the nominal one
  centred on the least-squares centre of both paths; ``F_max`` and ``F_min`` its largest and
  smallest (signed) values.

**ISO 10791-6:2014 (test conditions for machining centres, accuracy of speeds and
interpolations), its tests of a rotary axis turning while the linear axes hold the tool
point**: the range (max − min) of the tool point's deviation in x, y and z of the workpiece
frame over the sweep, ``range_x``, ``range_y``, ``range_z``; an instrument zero per direction
does not change a range. The prediction computes the same ranges
(:mod:`reliability.acceptance.prediction`).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..basics.errors import InputError
from .iso_statistics import circular_deviation, least_squares_centre, positioning_statistics

#: ISO 230-2 results of a positioning run, in the order :func:`positioning_values` gives them.
POSITIONING_QUANTITIES = ("E", "E_up", "E_down", "M", "R", "R_up", "R_down", "B", "B_mean",
                          "A", "A_up", "A_down")
#: ISO 230-4 results of a circular run (``G`` and ``H`` need both directions).
CIRCULAR_QUANTITIES = ("G_plus", "G_minus", "G", "H", "F_max", "F_min")
#: ISO 10791-6 results of a rotary run.
ROTARY_QUANTITIES = ("range_x", "range_y", "range_z")
#: Columns of the per-target table (:func:`positioning_table`), all in mm.
TARGET_COLUMNS = ("target", "x_up", "x_down", "x_mean", "s_up", "s_down", "B_i", "R_up_i",
                  "R_down_i", "R_i")
#: ISO 230-2 needs at least two cycles for a standard uncertainty; it asks for five.
MIN_CYCLES, ISO_CYCLES = 2, 5
DIRECTIONS = ("+", "-")


def positioning_values(deviations) -> dict[str, float]:
    """ISO 230-2 values of one bidirectional positioning run (module docstring).

    Parameters
    ----------
    deviations : array_like
        ``(n, 2, m)`` positional deviations ``x_ij`` (mm): ``n >= 2`` cycles, direction 0
        ``+`` (↑) and 1 ``−`` (↓), ``m`` targets.

    Returns
    -------
    dict of float
        :data:`POSITIONING_QUANTITIES` (mm).
    """
    x = _positioning_array(deviations)
    stats = positioning_statistics(x)
    mean = x.mean(axis=0)                       # (2, m): x̄_i↑, x̄_i↓
    stats["B_mean"] = np.mean(mean[0] - mean[1])
    return {quantity: float(stats[quantity]) for quantity in POSITIONING_QUANTITIES}


def positioning_table(targets, deviations) -> pd.DataFrame:
    """The per-target ISO 230-2 table of one run: :data:`TARGET_COLUMNS` (mm).

    Parameters
    ----------
    targets : array_like
        ``(m,)`` target positions (mm).
    deviations : array_like
        ``(n, 2, m)`` as :func:`positioning_values`.

    Returns
    -------
    pandas.DataFrame
        One row per target: ``x̄_i↑``, ``x̄_i↓``, ``x̄_i``, ``s_i↑``, ``s_i↓``, ``B_i``,
        ``R_i↑``, ``R_i↓``, ``R_i``.
    """
    x = _positioning_array(deviations)
    mean = x.mean(axis=0)                       # (2, m): the mean over the cycles
    s = x.std(axis=0, ddof=1)
    reversal = mean[0] - mean[1]
    return pd.DataFrame({
        "target": np.asarray(targets, dtype=float), "x_up": mean[0], "x_down": mean[1],
        "x_mean": mean.mean(axis=0), "s_up": s[0], "s_down": s[1], "B_i": reversal,
        "R_up_i": 4.0 * s[0], "R_down_i": 4.0 * s[1],
        "R_i": np.maximum(2.0 * s[0] + 2.0 * s[1] + np.abs(reversal), 4.0 * s.max(axis=0))},
        columns=list(TARGET_COLUMNS))


def _positioning_array(deviations) -> np.ndarray:
    x = np.asarray(deviations, dtype=float)
    if x.ndim != 3 or x.shape[1] != 2 or x.shape[0] < MIN_CYCLES or x.shape[2] < 2:
        raise InputError(f"deviations must have shape (cycles >= {MIN_CYCLES}, 2, "
                         f"targets >= 2); got {x.shape}")
    if not np.all(np.isfinite(x)):
        raise InputError("deviations must be finite numbers (mm)")
    return x


def circular_values(angles, radial, radius: float) -> dict[str, float]:
    """ISO 230-4 values of a ballbar run in one or both directions (module docstring).

    Parameters
    ----------
    angles, radial : Mapping[str, array_like]
        By direction ``'+'``, ``'-'`` (either or both): the nominal angles ``θ_j`` (rad) of
        the readings and the ballbar's length changes ``v_j`` (mm).
    radius : float
        The ballbar's nominal length ``r`` (mm).

    Returns
    -------
    dict of float
        ``G_plus`` and/or ``G_minus`` (each direction given), ``G`` and ``H`` (both
        given), ``F_max``, ``F_min`` (mm).
    """
    paths, distance = _paths_about_common_centre(angles, radial, radius)
    every = np.concatenate(list(distance.values()))
    out = {f"G_{name}": float(circular_deviation(paths[d]))
           for d, name in zip(DIRECTIONS, ("plus", "minus")) if d in paths}
    if len(paths) == 2:
        out["G"] = float(every.max() - every.min())
        order = np.argsort(np.mod(angles["-"], 2.0 * np.pi))
        minus = np.interp(np.mod(angles["+"], 2.0 * np.pi),
                          np.mod(angles["-"], 2.0 * np.pi)[order], distance["-"][order],
                          period=2.0 * np.pi)
        out["H"] = float(np.abs(distance["+"] - minus).max())
    out["F_max"], out["F_min"] = float(every.max() - radius), float(every.min() - radius)
    return {quantity: out[quantity] for quantity in CIRCULAR_QUANTITIES if quantity in out}


def radial_deviations(angles, radial, radius: float) -> dict[str, np.ndarray]:
    """ISO 230-4 radial deviation ``F_j = |p_j − c| − r`` of every reading, by direction,
    ``c`` the least-squares centre of every path given (mm; arguments as
    :func:`circular_values`)."""
    _, distance = _paths_about_common_centre(angles, radial, radius)
    return {d: values - radius for d, values in distance.items()}


def _paths_about_common_centre(angles, radial, radius):
    """Each direction's path ``p_j`` and its distances ``|p_j − c|`` from the least-squares
    centre of all of them."""
    if not angles or set(angles) - set(DIRECTIONS) or set(angles) != set(radial):
        raise InputError(f"angles and radial must be given for the same directions among "
                         f"{DIRECTIONS}; got {sorted(angles)} and {sorted(radial)}")
    if not np.isfinite(radius) or radius <= 0:
        raise InputError(f"radius must be a finite number > 0 mm; got {radius!r}")
    paths = {d: _path(angles[d], radial[d], radius) for d in DIRECTIONS if d in angles}
    centre = least_squares_centre(np.concatenate(list(paths.values())))
    return paths, {d: np.linalg.norm(p - centre, axis=-1) for d, p in paths.items()}


def _path(angles, radial, radius) -> np.ndarray:
    theta, value = np.asarray(angles, dtype=float), np.asarray(radial, dtype=float)
    if theta.ndim != 1 or theta.shape != value.shape or len(theta) < 4:
        raise InputError(f"each direction needs matching angles and radial readings, at "
                         f"least 4; got shapes {theta.shape} and {value.shape}")
    if not (np.all(np.isfinite(theta)) and np.all(np.isfinite(value))):
        raise InputError("angles and radial readings must be finite numbers")
    return (radius + value)[:, None] * np.stack([np.cos(theta), np.sin(theta)], axis=-1)


def rotary_values(deviations) -> dict[str, float]:
    """ISO 10791-6 ranges of a rotary run: the range of each direction's readings.

    Parameters
    ----------
    deviations : Mapping[str, array_like]
        By quantity ``'dx'``, ``'dy'``, ``'dz'`` (any of them): the tool point's deviation
        read along the sweep (mm).

    Returns
    -------
    dict of float
        ``range_x``, ``range_y``, ``range_z`` for the quantities given (mm).
    """
    out = {}
    for quantity, name in zip(("dx", "dy", "dz"), ROTARY_QUANTITIES):
        if quantity in deviations:
            values = np.asarray(deviations[quantity], dtype=float)
            if values.ndim != 1 or len(values) < 2 or not np.all(np.isfinite(values)):
                raise InputError(f"deviations[{quantity!r}] must be two or more finite "
                                 f"numbers (mm)")
            out[name] = float(values.max() - values.min())
    if not out:
        raise InputError("deviations: give any of 'dx', 'dy', 'dz'")
    return out
