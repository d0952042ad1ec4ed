"""The certified cost–reliability front: the cheapest machine for every reliability target.

The paper's argument (Sec. 4) is that holding every error "completely within the allowable
range" is too expensive and that a reliability target buys a cheaper machine at a tolerable
risk. :func:`cost_reliability_front` measures it: for each target R (the same for all six
outputs, at every pose) it solves the allocation problem of Eq. (34) to a certified
optimum, and it solves the classical worst-case stack (``side='stack'``) beside it.

All targets share one set of constraint rows: with a common target every FOSM row is
``J² / (k² (I/z)²)``, so going from target R to R' multiplies all rows by
``(z'/z)²``. The problem is built and its rows screened once, for the most demanding
target (a row the screening drops there can never bind at a smaller target, and
duplicate and dominance screening do not depend on the scale). Each target's solve
starts from the neighbouring target's multipliers scaled by the same factor (warm start;
only the speed depends on it), so after the screening a target costs milliseconds.
"""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np
import pandas as pd

from reliability.basics.errors import InputError
from reliability.basics.files import SIGNIFICANT, probability_text, write_csv
from reliability.first_order.fosm import required_index
from reliability.model.machine import OUTPUTS

from ..solvers.convex import InfeasibleAllocationError
from .common_target import CommonTargetSolver
from .problem import AllocationProblem, ScreenedRows
from .solve import TargetUnreachableError, solve_exact

FRONT_SIDES = ("one_sided", "two_sided")


def cost_reliability_front(machine, targets, *, side: str = "two_sided", stack: bool = True,
                           gap_tol: float = 1e-6, **build_options) -> pd.DataFrame:
    """Certified optimal cost for each reliability target, and the worst-case stack.

    Parameters
    ----------
    machine : Machine
    targets : array_like of float
        Reliability targets in (0, 1), applied to all six outputs at every pose.
    side : {'one_sided', 'two_sided'}
        Reading of the reliability requirement (see :class:`AllocationProblem`).
    stack : bool
        Also solve the classical worst-case stack (``frame.attrs['stack']``).
    gap_tol : float
        Relative duality gap accepted as certified.
    **build_options
        Passed to :meth:`AllocationProblem.build` (``poses``, ``bounds``, ``lower``,
        ``upper``, ``locked``, ``reference``, ``k``, ``cost_factors``, ``limits``);
        ``targets``, ``side`` and ``workspace`` are set here.

    Returns
    -------
    pandas.DataFrame
        One row per target, in the order given: ``target``, ``required_index`` (z),
        ``cost`` (Eq. 28), ``relative_cost`` (to the reference allocation, Table 4 by
        default), ``dual_bound``, ``relative_gap``, ``certified``, ``feasible`` (False
        where the box cannot hold the target; cost is then NaN) and ``binding`` (the
        outputs with a binding row, comma-separated). ``frame.attrs`` holds
        ``reference_cost``, ``side``, ``tolerances`` (n_targets, n_errors; NaN rows
        where infeasible), ``seconds`` (wall time of the build with its row screening,
        and of all the solves) and ``stack``: a dict with the stack allocation's ``cost``,
        ``relative_cost``, ``relative_gap``, ``certified``, ``binding`` and
        ``tolerances`` — the limiting point of the front (every error anywhere in its
        tolerance) — or ``{'error': message}`` when the box cannot hold it.
    """
    targets = _check_targets(targets)
    if side not in FRONT_SIDES:
        raise InputError(f"side must be one of {FRONT_SIDES} for the front; got {side!r}")
    for name in ("targets", "workspace", "side"):
        if name in build_options:
            raise InputError(f"{name!r} is set by cost_reliability_front; do not pass it")
    order = np.argsort(targets, kind="stable")
    highest = float(targets[order[-1]])
    started = time.perf_counter()
    problem = AllocationProblem.build(machine, side=side, workspace="worst",
                                      targets=dict.fromkeys(OUTPUTS, highest),
                                      **build_options)
    z = required_index(targets, side)
    records = [None] * len(targets)
    tolerances = np.full((len(targets), problem.machine.n_errors), np.nan)
    solve = CommonTargetSolver(problem, gap_tol)
    built = time.perf_counter()
    for i in order:
        try:
            solution = solve(targets[i])
        except InfeasibleAllocationError:
            records[i] = _infeasible_record(targets[i], z[i])
            continue
        tolerances[i] = solution.t
        records[i] = _record(problem, solution, targets[i], z[i])
    solved = time.perf_counter()
    frame = pd.DataFrame.from_records(records)
    frame.index.name = "point"
    frame.attrs.update(reference_cost=_reference_cost(problem), side=side,
                       tolerances=tolerances,
                       seconds={"build": built - started, "solve": solved - built},
                       stack=_stack(machine, problem, build_options, gap_tol) if stack
                       else None)
    return frame


def allocation_point(machine, tolerances, *, side: str = "two_sided", **build_options):
    """Where an allocation sits in the front's plane: (worst reliability, relative cost).

    The worst reliability is the lowest probability of the chosen side over the six
    outputs and the poses; the cost is relative to the reference allocation.
    """
    # the mean reading skips the row screening, which a probability does not need
    problem = AllocationProblem.build(machine, side=side, workspace="mean", **build_options)
    t = machine.check_tolerances(tolerances)
    worst = float(problem.probability(t).min())
    return worst, float(problem.cost.total(t) / _reference_cost(problem))


def front_file_table(table: pd.DataFrame) -> pd.DataFrame:
    """A front table as its CSV file holds it: the ``target`` column as text that keeps
    both R and 1 − R to :data:`~reliability.basics.files.SIGNIFICANT` digits
    (``0.999999999``, never a rounded ``1``); the other numbers are written to that many
    digits by the writer."""
    return table.assign(target=[probability_text(r) for r in table["target"]])


def front_to_csv(table: pd.DataFrame, path, overwrite: bool = False):
    """Write a front table (columns from :func:`cost_reliability_front`, at least
    ``target``) as CSV without its index; returns the path."""
    return write_csv(front_file_table(table), path, overwrite, index=False,
                     float_format=f"%.{SIGNIFICANT}g")


def _check_targets(targets) -> np.ndarray:
    values = np.atleast_1d(np.asarray(targets, dtype=float))
    if values.ndim != 1 or values.size == 0:
        raise InputError(f"targets must be a non-empty 1-D sequence; got shape {values.shape}")
    bad = np.flatnonzero(~((values > 0) & (values < 1)))
    if bad.size:
        raise InputError(f"targets[{bad[0]}] = {values[bad[0]]!r}; targets must lie in (0, 1)")
    return values


def _reference_cost(problem) -> float:
    return float(problem.cost.total(problem.reference))


def _record(problem, solution, target, z) -> dict:
    outputs = np.unique(problem.rows.output[solution.active])  # active rows, not λ > 0:
    # where outputs bind together their λ split, and so λ > 0, is not unique
    return {"target": float(target), "required_index": float(z), "cost": solution.fun,
            "relative_cost": solution.fun / _reference_cost(problem),
            "dual_bound": solution.dual_bound, "relative_gap": solution.relative_gap,
            "certified": bool(solution.success), "feasible": True,
            "binding": ",".join(OUTPUTS[o] for o in outputs)}


def _infeasible_record(target, z) -> dict:
    return {"target": float(target), "required_index": float(z), "cost": np.nan,
            "relative_cost": np.nan, "dual_bound": np.nan, "relative_gap": np.nan,
            "certified": False, "feasible": False, "binding": ""}


def _stack(machine, fosm_problem, build_options, gap_tol) -> dict:
    """The worst-case stack allocation, the front's limiting point."""
    problem = _stack_problem(machine, fosm_problem, build_options)
    try:
        result = solve_exact(problem, gap_tol=gap_tol)
    except TargetUnreachableError as exc:
        return {"error": str(exc)}
    binding = result.requirements.index[result.requirements["binding_rows"] > 0]
    return {"cost": result.cost, "relative_cost": result.cost / _reference_cost(problem),
            "relative_gap": result.certificate["relative_gap"],
            "certified": result.certificate["certified"], "binding": ",".join(binding),
            "tolerances": result.tolerances}


def _stack_problem(machine, fosm_problem, build_options):
    """The stack problem, reusing the FOSM problem's screening where that is exact.

    A stack row ``|J|/I`` and a FOSM row ``J² z²/(k² I²)`` of the same output and pose
    are equal, or one entrywise above another, exactly when the other reading's are: the
    duplicate and dominance screening is the same for both. When the FOSM box step kept
    every row, its survivors, box-screened for the stack, are the stack's screened rows.
    """
    counts = fosm_problem.rows.counts
    if counts["box"] != counts["candidates"]:
        return AllocationProblem.build(machine, side="stack", **build_options)
    rows = fosm_problem.rows
    problem = replace(fosm_problem, machine=machine, side="stack", rows=None)
    if problem.jacobian is None:  # not kept (memory budget): only the screened rows' poses
        sensitivity = machine.jacobian(problem.poses[rows.pose])[np.arange(len(rows.pose)),
                                                                 rows.output]
    else:
        sensitivity = problem.jacobian[rows.pose, rows.output]
    matrix = np.abs(sensitivity) / machine.limits[rows.output][:, None]
    keep = matrix @ problem.upper > 1.0
    stack_counts = dict(counts, box=int(keep.sum()), duplicates=int(keep.sum()),
                        dominance=int(keep.sum()))
    return replace(problem, rows=ScreenedRows(matrix=matrix[keep], pose=rows.pose[keep],
                                              output=rows.output[keep], counts=stack_counts))
