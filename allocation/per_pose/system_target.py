"""Allocation for a system target: all six outputs inside their limits at once.

The allocation problem of Eq. (34) puts a target on each output separately. A machine whose every
output meets R at a pose can still fail the workpiece more often than 1 − R, because any of six
outputs may leave its limit. :func:`system_allocation` finds the cheapest allocation (within the
problem's family) whose *system* reliability — the six-dimensional normal rectangle probability of
:mod:`reliability.first_order.system_reliability` — reaches R at every pose, and brackets the true
optimum with certified bounds:

* **lower bound.** The system event is contained in each output's event, so any
  allocation meeting R for the system meets R for every output. The certified dual bound
  of the per-output problem at target R is therefore a lower bound on the system optimum.
* **feasible side.** With every output at ``1 − (1 − R)/6`` the Bonferroni inequality
  guarantees the system target. A common per-output target ``r`` between R and that
  value is then lowered by bisection as long as the exact system probability, checked at
  every pose (screened with Šidák's bound, :func:`worst_system_reliability`), still
  reaches R with a margin of ``z`` standard errors. The allocation returned is optimal
  for its per-output target ``r`` and verified for the system; the gap to the lower bound
  says how much any other allocation could still save.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pandas as pd

from reliability.basics import streams
from reliability.basics.errors import InputError
from reliability.first_order.fosm import required_index
from reliability.first_order.system_reliability import worst_system_reliability
from reliability.model.machine import OUTPUTS

from ..solvers.convex import InfeasibleAllocationError
from .common_target import CommonTargetSolver
from .problem import AllocationProblem, ScreenedRows, with_requirements
from .solve import AllocationResult, unreachable_worst

#: Standard errors of the exact system probability kept as a safety margin.
SYSTEM_MARGIN_Z = 3.0


def system_allocation(machine, target: float, *, steps: int = 12, n_points: int = 1024,
                      rng=None, gap_tol: float = 1e-6, **build_options) -> AllocationResult:
    """Cheapest allocation whose system reliability reaches ``target`` at every pose.

    Parameters
    ----------
    machine : Machine
    target : float
        System reliability R in (0, 1): probability that all six outputs are inside
        their limits at once (two-sided, linearised Gaussian model).
    steps : int
        Bisection steps on the common per-output target.
    n_points : int
        Sobol' points per batch of the exact system probability.
    rng : None, int or numpy.random.Generator
        For the scrambled points of the system probability.
    gap_tol : float
        Relative duality gap accepted by the convex solves.
    **build_options
        Passed to :meth:`AllocationProblem.build` (``poses``, ``bounds``, ``lower``,
        ``upper``, ``locked``, ``reference``, ``k``, ``cost_factors``, ``limits``).

    Returns
    -------
    AllocationResult
        ``method='system'``; ``feasible`` says whether the exact system check passed at
        every pose. ``certificate`` holds ``lower_bound`` (certified), ``gap`` and
        ``relative_gap`` (to the lower bound), ``output_target`` (the common per-output
        target used), ``bonferroni_cost`` (cost at ``1 − (1 − R)/6``),
        ``system_probability``, ``system_error`` and ``worst_pose`` (the worst pose's
        exact probability, its standard error and index), ``certified`` (every convex
        solve certified) and ``z`` (the safety margin in standard errors).

    Raises
    ------
    TargetUnreachableError
        When even the per-output target R cannot be met inside the box, or the
        Bonferroni point cannot.
    """
    target = _check_target(target)
    for name in ("targets", "workspace", "side"):
        if name in build_options:
            raise InputError(f"{name!r} is set by system_allocation; do not pass it")
    if not (isinstance(steps, (int, np.integer)) and steps >= 0):
        raise InputError(f"steps must be an integer >= 0; got {steps!r}")
    bonferroni = 1.0 - (1.0 - target) / len(OUTPUTS)
    problem = AllocationProblem.build(machine, side="two_sided", workspace="worst",
                                      targets=dict.fromkeys(OUTPUTS, bonferroni),
                                      **build_options)
    generator = streams.generator(rng)
    solver = CommonTargetSolver(problem, gap_tol)
    certified = []

    def solve(value):
        try:
            solution = solver(value)
        except InfeasibleAllocationError as exc:
            raise unreachable_worst(_at_target(problem, value), exc.rows, exc.loads) from None
        certified.append(bool(solution.success))
        return solution

    lower = solve(target)
    upper = solve(bonferroni)
    check = _system_check(problem, upper.t, target, n_points, generator)
    best, best_target, best_check = upper, bonferroni, check
    low, high = target, bonferroni
    for _ in range(steps if check[0] else 0):
        middle = 0.5 * (low + high)
        candidate = solve(middle)
        candidate_check = _system_check(problem, candidate.t, target, n_points, generator)
        if candidate_check[0]:
            best, best_target, best_check, high = candidate, middle, candidate_check, middle
        else:
            low = middle
    return _result(problem, best, best_target, best_check, lower, upper, all(certified))


def _at_target(problem, target):
    """The problem with every output's target set to ``target`` (rows rescaled)."""
    machine = with_requirements(problem.machine, targets=dict.fromkeys(OUTPUTS, target))
    rescaled = replace(problem, machine=machine)
    rows = problem.rows
    scale = (required_index(target, "two_sided")
             / required_index(problem.machine.targets[0], "two_sided")) ** 2
    return replace(rescaled, rows=ScreenedRows(matrix=rows.matrix * scale, pose=rows.pose,
                                               output=rows.output, counts=rows.counts))


def _system_check(problem, t, target, n_points, generator):
    """(passes, worst probability, its standard error, worst pose index)."""
    result = worst_system_reliability(problem.machine, t, problem.poses, k=problem.k,
                                      n_points=n_points, rng=generator.spawn(1)[0],
                                      jacobian=problem.jacobian)
    w = result.worst
    probability, error = float(result.probability[w]), float(result.error[w])
    return (probability - SYSTEM_MARGIN_Z * error >= target, probability, error,
            int(result.index[w]))


def _result(problem, best, output_target, check, lower, bonferroni, certified):
    chosen = _at_target(problem, output_target)
    t = np.asarray(best.t)
    cost = float(problem.cost.total(t))
    bound = float(lower.dual_bound)
    binding = best.active  # every active row: which carry λ > 0 is not unique
    active = pd.DataFrame({"output": np.array(OUTPUTS)[problem.rows.output[binding]],
                           "pose": problem.rows.pose[binding]})
    certificate = {"lower_bound": bound, "gap": cost - bound,
                   "relative_gap": (cost - bound) / cost,
                   "output_target": float(output_target),
                   "bonferroni_cost": float(bonferroni.fun),
                   "system_probability": check[1], "system_error": check[2],
                   "worst_pose": check[3], "z": SYSTEM_MARGIN_Z,
                   "certified": bool(certified)}
    return AllocationResult(problem=chosen, method="system", tolerances=t, cost=cost,
                            feasible=bool(check[0]), certificate=certificate, active=active)


def _check_target(target) -> float:
    if isinstance(target, bool) or not isinstance(target, (int, float, np.number)):
        raise InputError(f"target must be a number in (0, 1); got {target!r}")
    target = float(target)
    if not 0.0 < target < 1.0:
        raise InputError(f"target must lie in (0, 1); got {target!r}")
    return target
