"""Pose sets: the workspace grid of Sec. 5.3 and uniform random poses (docs/model.md)."""

from __future__ import annotations

import numpy as np

from ..basics import checks, streams


def axis_grid_points(axis, points: int) -> np.ndarray:
    """Equidistant points over one axis' stroke (Sec. 5.3: five per axis).

    Linear axes and limited rotary axes include both ends; a full-turn rotary axis is
    sampled over one revolution without repeating 0 = 2π.
    """
    low, high = axis.stroke
    if axis.full_turn:
        return np.linspace(low, high, points, endpoint=False)
    return np.linspace(low, high, points)


def grid_axis_points(machine, points_per_axis: int = 5) -> list[np.ndarray]:
    """The grid points of every axis, in chain order."""
    points_per_axis = checks.positive_int(points_per_axis, "points_per_axis", 2)
    return [axis_grid_points(axis, int(points_per_axis)) for axis in machine.axis_specs]


def workspace_grid(machine, points_per_axis: int = 5, *, budget: int | None = None
                   ) -> np.ndarray:
    """All combinations of the axes' grid points, ``(points_per_axis ** n_axes, n_axes)``.

    Row order is that of ``itertools.product`` over the axes in chain order: the first
    axis varies slowest, the last fastest (5^6 = 15 625 rows for the paper's machine).
    The ``P^n`` rows must fit in ``budget`` bytes (default
    :data:`reliability.basics.checks.DEFAULT_BUDGET`), checked before any is built.
    """
    points = grid_axis_points(machine, points_per_axis)
    n_axes = len(points)
    # the meshes and the stacked rows take 16 n bytes per pose
    checks.require_size(len(points[0]) ** n_axes, 16 * n_axes, budget,
                        f"a {len(points[0])}-point grid on {n_axes} axes",
                        "use fewer points per axis, pass an explicit pose set, or draw "
                        "random poses")
    mesh = np.meshgrid(*points, indexing="ij")  # first axis slowest, as itertools.product
    return np.stack([axis.ravel() for axis in mesh], axis=-1).astype(float)


def random_poses(machine, n: int, rng=None, *, budget: int | None = None) -> np.ndarray:
    """``n`` poses drawn uniformly over every axis' stroke, ``(n, n_axes)``."""
    n = checks.positive_int(n, "number of poses n")
    rng = streams.generator(rng)
    checks.require_size(n, 8 * len(machine.axis_specs), budget, f"{n:,} random poses",
                        "draw fewer poses per call (in chunks)")
    low = np.array([a.stroke[0] for a in machine.axis_specs])
    high = np.array([a.stroke[1] for a in machine.axis_specs])
    return low + (high - low) * rng.random((int(n), len(low)))
