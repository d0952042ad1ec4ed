"""Pose sets: the workspace grid of Sec. 5.3 and uniform random poses (DESIGN §2)."""

from __future__ import annotations

import numpy as np


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
    if isinstance(points_per_axis, bool) or not isinstance(points_per_axis, (int, np.integer)) \
            or points_per_axis < 2:
        raise ValueError(f"points_per_axis must be an integer >= 2; got {points_per_axis!r}")
    return [axis_grid_points(axis, int(points_per_axis)) for axis in machine.axis_specs]


def workspace_grid(machine, points_per_axis: int = 5) -> np.ndarray:
    """All combinations of the axes' grid points, ``(points_per_axis ** n_axes, n_axes)``.

    Row order is that of ``itertools.product`` over the axes in chain order: the first
    axis varies slowest, the last fastest (5^6 = 15 625 rows for the paper's machine).
    """
    points = grid_axis_points(machine, points_per_axis)
    mesh = np.meshgrid(*points, indexing="ij")  # first axis slowest, as itertools.product
    return np.stack([axis.ravel() for axis in mesh], axis=-1).astype(float)


def random_poses(machine, n: int, rng=None) -> np.ndarray:
    """``n`` poses drawn uniformly over every axis' stroke, ``(n, n_axes)``."""
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"number of poses must be a positive integer; got {n!r}")
    rng = np.random.default_rng(rng)
    low = np.array([a.stroke[0] for a in machine.axis_specs])
    high = np.array([a.stroke[1] for a in machine.axis_specs])
    return low + (high - low) * rng.random((int(n), len(low)))
