"""Pose sets: the workspace grid of Sec. 5.3 and uniform random poses (docs/model.md).

On a machine with a work zone (:mod:`reliability.model.work_zone`) both keep the poses
inside it only; without one they cover the whole stroke box.
"""

from __future__ import annotations

import numpy as np

from ..basics import checks, streams
from ..basics.errors import InputError
from ..basics.renamed import renamed
from .work_zone import inside_zone, zone_text

#: Random poses drawn per accepted pose, at most, before a work zone is judged too small.
MOST_DRAWS_PER_POSE = 10_000


def axis_grid_points(axis, points: int) -> np.ndarray:
    """Equidistant points over one axis' stroke (Sec. 5.3: five per axis).

    Linear axes and limited rotary axes include both ends; a full-turn rotary axis is
    sampled over one revolution without repeating 0 = 2π.
    """
    low, high = axis.stroke
    if axis.full_turn:
        return np.linspace(low, high, points, endpoint=False)
    return np.linspace(low, high, points)


def grid_axis_points(machine, points: int = 5) -> list[np.ndarray]:
    """The grid points of every axis, in chain order."""
    points = checks.positive_int(points, "points", 2)
    return [axis_grid_points(axis, int(points)) for axis in machine.axis_specs]


@renamed("points_per_axis", "points")
def workspace_grid(machine, points: int = 5, *, budget: int | None = None) -> np.ndarray:
    """The grid's poses in the workspace: all combinations of the axes' grid points, or on
    a machine with a work zone those inside it.

    Row order is that of ``itertools.product`` over the axes in chain order: the first
    axis varies slowest, the last fastest (5^6 = 15 625 rows for the paper's machine).
    The ``P^n`` rows must fit in ``budget`` bytes (default
    :data:`reliability.basics.checks.DEFAULT_BUDGET`), checked before any is built.

    Parameters
    ----------
    machine : Machine
    points : int
        Grid points per axis, ``P >= 2`` (``points_per_axis=`` is its deprecated spelling,
        :mod:`reliability.basics.renamed`).
    budget : int, optional
        Bytes the grid may take.

    Returns
    -------
    numpy.ndarray
        ``(P^n, n_axes)``, or ``(n_inside, n_axes)`` with a work zone.

    Raises
    ------
    InputError
        When the machine has a work zone and no grid pose lies inside it.
    """
    grid = full_grid(machine, points, budget=budget)
    if machine.work_zone is None:
        return grid
    return grid[grid_inside_zone(machine, grid, points)]


def grid_inside_zone(machine, grid, points: int) -> np.ndarray:
    """Which rows of a full grid lie in the machine's work zone, ``(P^n,)`` bool; an
    InputError when none does."""
    inside = inside_zone(machine, grid)
    if not inside.any():
        raise InputError(f"no pose of the {points}-point grid lies in the "
                         f"{zone_text(machine)}; use more points per axis or check the "
                         f"zone against the strokes and the tool_offset")
    return inside


def full_grid(machine, points: int = 5, *, budget: int | None = None) -> np.ndarray:
    """All combinations of the axes' grid points, ``(P^n, n_axes)``, whatever the work
    zone (row order as :func:`workspace_grid`)."""
    axis_points = grid_axis_points(machine, points)
    n_axes = len(axis_points)
    # the meshes and the stacked rows take 16 n bytes per pose
    checks.require_size(len(axis_points[0]) ** n_axes, 16 * n_axes, budget,
                        f"a {len(axis_points[0])}-point grid on {n_axes} axes",
                        "use fewer points per axis, pass an explicit pose set, or draw "
                        "random poses")
    mesh = np.meshgrid(*axis_points, indexing="ij")  # first axis slowest, as itertools.product
    return np.stack([axis.ravel() for axis in mesh], axis=-1).astype(float)


def random_poses(machine, n: int, rng=None, *, budget: int | None = None) -> np.ndarray:
    """``n`` poses drawn uniformly over every axis' stroke, ``(n, n_axes)``; on a machine
    with a work zone, uniformly over the strokes' poses inside it (by rejection, at most
    :data:`MOST_DRAWS_PER_POSE` draws per pose)."""
    n = checks.positive_int(n, "number of poses n")
    rng = streams.generator(rng)
    checks.require_size(n, 8 * len(machine.axis_specs), budget, f"{n:,} random poses",
                        "draw fewer poses per call (in chunks)")
    if machine.work_zone is None:
        return _uniform_poses(machine, n, rng)
    return _poses_in_zone(machine, n, rng)


def _uniform_poses(machine, n: int, rng) -> np.ndarray:
    low = np.array([a.stroke[0] for a in machine.axis_specs])
    high = np.array([a.stroke[1] for a in machine.axis_specs])
    return low + (high - low) * rng.random((int(n), len(low)))


def _poses_in_zone(machine, n: int, rng) -> np.ndarray:
    """``n`` uniform poses inside the work zone, drawn in rounds of ``n`` candidates."""
    kept, count, drawn = [], 0, 0
    while count < n:
        if drawn >= MOST_DRAWS_PER_POSE * n:
            raise InputError(f"random poses: {count} of {drawn:,} uniform poses of the "
                             f"strokes lie in the {zone_text(machine)}; the zone holds too "
                             f"small a share of the strokes to draw {n:,} poses")
        candidates = _uniform_poses(machine, n, rng)
        drawn += n
        kept.append(candidates[inside_zone(machine, candidates)])
        count += len(kept[-1])
    return np.concatenate(kept)[:n]
