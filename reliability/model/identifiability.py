"""Errors that cannot be told apart: equal sensitivities at every pose.

Two errors whose sensitivity columns ``J[:, :, i]`` and ``J[:, :, j]`` (Eq. 19) are equal at
every pose move every output in the same way: only the sum of their values matters, so
FOSM (Eq. 20) sees only the sum of their variances, and within such a group only the cost
decides how that variance is shared between its members. On the paper's machine the
position errors of consecutive axes along the same direction form such groups (X.dx with
C-X.dx and C.dx, …).

Columns are compared over a pose set (the workspace grid by default) to a relative
tolerance of the column's largest entry; groups are whole (every member within the
tolerance of the group's first member at every pose), found by partition refinement chunk by
chunk, so the Jacobian of all poses is never held at once.
"""

from __future__ import annotations

import numpy as np

from ..basics.chunks import chunks, jacobian_bytes
from .poses import workspace_grid

#: Two sensitivity columns are equal when they differ by at most this fraction of the
#: column's largest entry at every pose.
EQUAL_RTOL = 1e-12


def indistinguishable_groups(machine, poses=None, *, rtol: float = EQUAL_RTOL,
                             memory: int | None = None) -> list[tuple[str, ...]]:
    """Groups of two or more errors whose sensitivity columns are equal at every pose.

    Parameters
    ----------
    machine : Machine
    poses : array_like (n_poses, n_axes), optional
        Where to compare; the 5-point workspace grid by default.
    rtol : float
        Relative tolerance, a fraction of each column's largest absolute entry.
    memory : int, optional
        Bytes of temporary arrays (Jacobian chunks).

    Returns
    -------
    list of tuple of str
        Each group's error names in the machine's order; groups ordered by their first
        member. Errors with no effect on any output at any pose form a group of their own
        when there are two or more.
    """
    poses = workspace_grid(machine) if poses is None else np.atleast_2d(
        machine.check_positions(poses))
    scale = np.zeros(machine.n_errors)
    for part in chunks(len(poses), jacobian_bytes(machine), memory):
        block = np.abs(machine.jacobian(poses[part]))
        scale = np.maximum(scale, block.max(axis=(0, 1)))
    labels = _refine(np.zeros(machine.n_errors, dtype=np.int64), scale[None, :],
                     rtol * np.maximum(scale, 1e-300))
    for part in chunks(len(poses), jacobian_bytes(machine), memory):
        block = machine.jacobian(poses[part]).reshape(-1, machine.n_errors)
        labels = _refine(labels, block, rtol * scale)
    groups = {}
    for index, label in enumerate(labels):
        groups.setdefault(int(label), []).append(machine.error_names[index])
    return sorted((tuple(g) for g in groups.values() if len(g) > 1),
                  key=lambda g: machine.error_index(g[0]))


def _refine(labels, block, tolerance) -> np.ndarray:
    """Split every class of ``labels`` so that each member's column of ``block`` is within
    ``tolerance`` (per column) of its class representative's (the first member)."""
    refined = np.empty_like(labels)
    count = 0
    for label in np.unique(labels):
        remaining = np.flatnonzero(labels == label)
        while remaining.size:
            first = remaining[0]
            gap = np.abs(block[:, remaining] - block[:, [first]]).max(axis=0)
            close = gap <= tolerance[remaining]
            refined[remaining[close]] = count
            count += 1
            remaining = remaining[~close]
    return refined
