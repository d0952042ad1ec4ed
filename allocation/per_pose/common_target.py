"""Certified solves of the per-pose problem at one target common to all six outputs, for
a sequence of targets: the cost-reliability front, the system target and the lower bound of
the machine-yield allocation solve it target after target.
"""

from __future__ import annotations

import numpy as np

from reliability.first_order.fosm import required_index

from ..solvers.convex import solve_convex_allocation


class CommonTargetSolver:
    """Certified solves of a worst-case FOSM problem with one target for all outputs.

    ``problem`` must give every output the same target, at least as high as any target
    asked for: its rows, multiplied by ``(z/z_problem)²``, are the rows at target z
    (Eq. 20 with σ ≤ I/z), and a row screened out at the highest target cannot bind at a
    lower one. Each call starts from the last solve's multipliers, scaled the same way.

    Parameters
    ----------
    problem : AllocationProblem
        The worst-case FOSM problem built at the highest target asked for.
    gap_tol : float
        Relative duality gap accepted by the convex solves.
    """

    def __init__(self, problem, gap_tol: float = 1e-6):
        self.problem = problem
        self.gap_tol = gap_tol
        self.z_problem = float(problem.required_index[0])
        self.start, self.z_start = None, None

    def __call__(self, target):
        """:class:`ConvexSolution` at ``target``; raises InfeasibleAllocationError."""
        problem = self.problem
        z = float(required_index(target, problem.side))
        start = None if self.start is None else self.start * (z / self.z_start) ** 2
        solution = solve_convex_allocation(
            problem.cost.weights, problem.rows.matrix * (z / self.z_problem) ** 2,
            problem.lower ** 2, problem.upper ** 2, gap_tol=self.gap_tol, start=start)
        self.start, self.z_start = np.array(solution.multipliers), z
        return solution
