"""Allocations whose target holds between grid points too (pose cutting planes).

The allocation problem holds the target at the poses of a grid (docs/model.md), but Eq. (35) asks
for the whole stroke of every axis, and an optimum certified on the grid can fall slightly short
between its points (:mod:`reliability.first_order.workspace_search`). Here the grid optimum is
checked by a continuous search; every pose where an output falls short is added to the pose set and
the problem is solved again, until no such pose is found.
"""

from __future__ import annotations

import numpy as np

from reliability.basics import checks
from reliability.basics.errors import InputError
from reliability.first_order.workspace_search import continuous_worst


def solve_over_workspace(problem, *, max_rounds: int = 20, tolerance: float = 1e-6,
                         log=lambda message: None):
    """Exact optimum of a worst-case problem, refined until it holds between grid points.

    Parameters
    ----------
    problem : AllocationProblem
        A worst-case problem (``workspace='worst'``).
    max_rounds : int
        Solves at most; an error is raised if the continuous search still finds a pose
        short of its target after the last one.
    tolerance : float
        Relative shortfall of β below the required index that counts as short.
    log : callable
        Called with a line per round.

    Returns
    -------
    result : AllocationResult
        Exact optimum on the grid plus the added poses.
    added : ndarray (n_added, n_axes)
        The poses added to the grid.
    """
    max_rounds = checks.positive_int(max_rounds, "max_rounds")
    tolerance = checks.finite_float(tolerance, "tolerance", 0.0, 1.0, high_open=True)
    checks.callback(log, "log")
    if problem.workspace != "worst":
        raise InputError("pose refinement applies to the worst-case reading only")
    grid_size = len(problem.poses)
    for round_ in range(1, max_rounds + 1):
        result = problem.solve_exact()
        worst = continuous_worst(problem.machine, result.tolerances, problem.poses,
                                 k=problem.k, grid_sigma=problem.sigma(result.tolerances))
        short = worst["beta"].to_numpy() < problem.required_index * (1 - tolerance)
        shortfall = float(np.max(1 - worst["beta"].to_numpy() / problem.required_index))
        log(f"round {round_}: cost {result.cost:.6g}; {int(short.sum())} output(s) short "
            f"between grid points, worst β {100 * max(shortfall, 0):.3g} % below target")
        if not short.any():
            return result, problem.poses[grid_size:]
        problem = problem.with_poses(worst.loc[short, list(problem.machine.axes)].to_numpy())
    raise RuntimeError(f"continuous search still finds poses short of the target after "
                       f"{max_rounds} rounds")
