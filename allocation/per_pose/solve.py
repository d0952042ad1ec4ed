"""Solving an :class:`~allocation.per_pose.problem.AllocationProblem`: exactly and by GWO.

``solve_exact`` returns the certified global optimum of the worst-case problem (a convex
problem in ``u = t²``, :mod:`allocation.solvers.convex`) with its duality gap, the active
constraints (which output at which pose) and their Lagrange multipliers. For the
workspace-mean reading the constraint ``mean_p P(β_p) ≥ R`` is not linear in ``u``; it is
concave — so the problem convex — wherever every β ≥ √3 (P ≥ 0.92 two-sided). It is
solved by supporting-hyperplane cuts on the same convex solver, whose dual bound is a
certificate where that concavity holds (the result says whether it does).

``solve_gwo`` runs the Grey Wolf Optimiser (:mod:`allocation.solvers.gwo`) on the same problem,
over the free items, with Deb's feasibility rules, as the paper does.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from scipy.stats import norm

from reliability.basics import checks, streams
from reliability.basics.display import OUTPUT_UNITS, axis_units, pose_text
from reliability.basics.errors import InputError
from reliability.basics.ties import worst_rows
from reliability.first_order.fosm import probability
from reliability.model.machine import OUTPUTS

from ..solvers.convex import InfeasibleAllocationError, largest_fraction, solve_convex_allocation
from ..solvers.gwo import grey_wolf
from .elasticity import requirement_multipliers
from .result_files import (NEARLY_FREE_SHARE, allocation_from_payload, allocation_payload,
                           allocation_summary, allocation_to_csv, load_allocation,
                           save_allocation)

CONVEX_BETA = np.sqrt(3.0)  # Φ(β) and 2Φ(β)−1 are concave in σ² for β ≥ √3


class TargetUnreachableError(InfeasibleAllocationError):
    """No allocation inside the bounds meets a target.

    Attributes
    ----------
    blocking : DataFrame
        What blocks, worst first: for the worst-case reading every (output, pose) whose σ
        exceeds the allowed σ even with every tolerance at its lower bound (with the pose's
        positions, ``allowed_sigma`` and ``sigma_at_lower``; for the stack ``limit`` and
        ``stack_at_lower``); for the mean reading every
        output whose mean probability at the lower bounds is short of its target.
    rows, loads
        As in :class:`InfeasibleAllocationError` (screened rows; empty for the mean reading).
    """

    def __init__(self, message: str, blocking: pd.DataFrame, rows=(), loads=()):
        ValueError.__init__(self, message)
        self.blocking = blocking
        self.rows = tuple(int(row) for row in rows)
        self.loads = np.asarray(loads, dtype=float)


def unreachable_worst(problem, rows=(), loads=()) -> TargetUnreachableError:
    """The error for the worst-case reading, listing every blocked (output, pose).

    Parameters
    ----------
    problem : AllocationProblem
        A problem with ``workspace='worst'`` whose rows the box cannot hold: some
        (output, pose) pair misses its requirement with every tolerance at its lower bound.
    rows, loads : sequence, optional
        The rows and loads of the solver's :class:`InfeasibleAllocationError`, kept on the
        error.

    Returns
    -------
    TargetUnreachableError
        Its message names the worst blocked pair and counts the others; its ``blocking``
        frame lists every blocked pair (output, pose, the pose's axes, what is needed and
        what the lower bounds give), the worst first.
    """
    at_lower = problem.loads(problem.variable(problem.lower))  # (n_poses, 6)
    pose, output = np.nonzero(at_lower > 1.0)
    order = np.argsort(-at_lower[pose, output], kind="stable")
    pose, output = pose[order], output[order]
    first = worst_rows(at_lower[pose, output], problem.poses[pose]) if len(pose) else 0
    order = np.r_[first, np.delete(np.arange(len(pose)), first)]
    pose, output = pose[order], output[order]
    frame = pd.DataFrame({"output": np.array(OUTPUTS)[output], "pose": pose})
    for i, axis in enumerate(problem.machine.axes):
        frame[axis] = problem.poses[pose, i]
    if problem.side == "stack":  # the load is Σ|J| t / I
        frame["limit"] = problem.machine.limits[output]
        frame["stack_at_lower"] = frame["limit"] * at_lower[pose, output]
        need, have, what = "limit", "stack_at_lower", "worst-case stack"
        verb = "must stay within"
    else:  # the load is σ² / allowed σ²
        frame["allowed_sigma"] = (problem.allowed_sigma[output] if problem.life is None
                                  else _life_allowed_sigma(problem, pose, output))
        frame["sigma_at_lower"] = frame["allowed_sigma"] * np.sqrt(at_lower[pose, output])
        need, have, what, verb = "allowed_sigma", "sigma_at_lower", "target", "needs σ ≤"
    first = frame.iloc[0]
    machine = problem.machine
    positions = pose_text(first[list(machine.axes)].to_numpy(dtype=float), machine.axes,
                          axis_units(machine), digits=6)
    unit = OUTPUT_UNITS[OUTPUTS.index(first["output"])]
    message = (f"{what} unreachable inside the bounds: {first['output']} at "
               f"{positions} {verb} {first[need]:.4g} {unit} "
               f"but the tightest allowed tolerances give {first[have]:.4g} {unit}; "
               f"{len(frame)} (output, pose) pair(s) blocked in all")
    return TargetUnreachableError(message, frame, rows, loads)


def _life_allowed_sigma(problem, pose, output) -> np.ndarray:
    """The largest σ0 the life target allows at each (pose, output) of a life problem
    (:meth:`allocation.per_pose.life.LifeRequirement.allowed_variance`)."""
    allowed = problem.life.allowed_variance(problem.machine.jacobian(problem.poses[pose]))
    return np.sqrt(allowed[np.arange(len(pose)), output])


def _unreachable_mean(problem, shortfall) -> TargetUnreachableError:
    """The error for the workspace-mean reading, naming the outputs that fall short."""
    short = np.flatnonzero(shortfall < 0)
    short = short[np.argsort(shortfall[short])]
    frame = pd.DataFrame({"output": np.array(OUTPUTS)[short],
                          "target": problem.machine.targets[short],
                          "mean_probability_at_lower":
                              problem.machine.targets[short] + shortfall[short]})
    first = frame.iloc[0]
    message = (f"workspace-mean target unreachable inside the bounds: {first['output']} "
               f"reaches {first['mean_probability_at_lower']:.6g} at the tightest allowed "
               f"tolerances, short of {first['target']:.6g}")
    return TargetUnreachableError(message, frame)


@dataclass(frozen=True, eq=False)
class AllocationResult:
    """An allocation found for a problem, with what is known about its optimality.

    Attributes
    ----------
    method : str
        ``'exact'`` or ``'gwo'``.
    tolerances : ndarray (n_errors,)
    cost : float
        Eq. (28) at ``tolerances``.
    feasible : bool
        Meets every constraint of the problem (checked at all poses).
    certificate : dict
        Exact: ``dual_bound``, ``relative_gap``, KKT residuals. GWO: ``violation``.
    active : DataFrame
        Binding constraints: output, pose index and positions (the exact solver: every
        row active at the optimum), and for the exact solver the multiplier λ that
        certifies the dual bound and its ``elasticity = −2λ/F``. These per-row values are
        the solver's own split: where several binding rows are alike any split is
        optimal, so they are part of the certificate, not results (docs/non-unique.md);
        :attr:`requirements` gives what the problem determines.
    history : DataFrame or None
        GWO convergence (best cost and violation per iteration).
    requirements : DataFrame or None
        Exact solver: per output, the number of binding rows and what the cost does when
        the limit I moves (:func:`allocation.per_pose.elasticity.requirement_multipliers`):
        ``multiplier_min``/``multiplier_max``, the range of the summed multiplier Σλ over
        all optimal multipliers; ``elasticity_relax`` and ``elasticity_tighten``, the
        one-sided ``d ln F / d ln I`` (``−2 min Σλ/F`` and ``−2 max Σλ/F``; relaxing I by
        1 % changes the cost by about ``elasticity_relax`` %, a saving); ``multiplier`` and
        ``elasticity`` where the two agree, NaN where the problem does not determine them
        (outputs binding together at symmetric poses: ``bound_with`` names them,
        ``group_elasticity`` is relaxing them together). For the stack, whose rows scale
        as 1/I, the factor 2 is 1. The toolkit uses this one sign everywhere it prints
        an elasticity.

    ``summary()`` (and ``repr``) prints the cost relative to the reference allocation and
    what binds, opening with "NOT FEASIBLE" when the allocation misses a target;
    ``save(path)`` / ``AllocationResult.load(path)`` keep it as JSON and ``to_csv(path)``
    writes the columns ``error, reference, allocated``.
    """

    problem: object = field(repr=False)
    method: str
    tolerances: np.ndarray
    cost: float
    feasible: bool
    certificate: dict
    active: pd.DataFrame
    history: pd.DataFrame | None = None
    requirements: pd.DataFrame | None = None

    def to_frame(self) -> pd.DataFrame:
        """Table 6 view: reference and allocated tolerance, optimisation rate, status."""
        problem = self.problem
        rate = self.tolerances / problem.reference - 1.0
        status = np.full(len(rate), "free", dtype=object)
        close = 1e-6 * problem.reference
        status[np.abs(self.tolerances - problem.lower) <= close] = "lower"
        status[np.abs(self.tolerances - problem.upper) <= close] = "upper"
        status[problem.locked] = "locked"
        return pd.DataFrame({"reference": problem.reference, "allocated": self.tolerances,
                             "rate": rate, "status": status},
                            index=pd.Index(problem.names, name="error"))

    def nearly_free(self, share: float = NEARLY_FREE_SHARE) -> list[str]:
        """Items at a bound that carry less than ``share`` of the cost: nearly free, so
        their tolerance is decided by the bound, not by the cost (often a sign that the
        cost units make one kind of item negligible, docs/cost-units.md)."""
        frame = self.to_frame()
        costs = np.asarray(self.problem.cost.item_costs(self.tolerances), dtype=float)
        cheap = costs / costs.sum() < share
        at_bound = frame["status"].isin(["lower", "upper"]).to_numpy()
        return [name for name, flag in zip(frame.index, cheap & at_bound) if flag]

    def breakdown(self) -> pd.DataFrame:
        """Where the cost goes, item by item (:meth:`CostModel.breakdown`)."""
        return self.problem.cost.breakdown(self.tolerances)

    def summary(self, top: int = 5) -> str:
        """Feasibility, cost relative to the reference, what binds, the largest changes."""
        return allocation_summary(self, top)

    def __repr__(self) -> str:
        return self.summary()

    def to_csv(self, path, overwrite: bool = False, *, significant: int | None = None):
        """Write the allocation CSV (columns ``error, reference, allocated``, one row per
        error) with all digits or ``significant`` digits; returns the path
        (:func:`allocation.per_pose.result_files.allocation_to_csv`)."""
        return allocation_to_csv(self, path, overwrite, significant=significant)

    def save(self, path, overwrite: bool = False):
        """Save as JSON with its metadata (:mod:`reliability.basics.saved_results`); returns
        the path."""
        return save_allocation(self, path, overwrite)

    @classmethod
    def load(cls, path, problem=None) -> "AllocationResult":
        """Reload a result written by :meth:`save`, verifying every field. Without
        ``problem`` the result carries a :class:`~allocation.per_pose.result_files.SavedProblem`;
        a given problem is checked to be the saved one."""
        return load_allocation(cls, path, problem)

    def payload(self) -> dict:
        """The JSON-ready fields :meth:`save` writes, for saving inside another result
        (:func:`allocation.per_pose.result_files.allocation_payload`)."""
        return allocation_payload(self)

    @classmethod
    def from_payload(cls, data, problem=None) -> "AllocationResult":
        """The result :meth:`payload` wrote, read through ``data`` and checked as
        :meth:`load` says."""
        return allocation_from_payload(cls, data, problem)


def solve_exact(problem, *, gap_tol: float = 1e-6) -> AllocationResult:
    """The optimum of Eq. (34) with a certificate.

    Raises
    ------
    TargetUnreachableError
        When some output at some pose cannot meet its target even with every tolerance at
        its lower bound; the message names the output and the pose.
    """
    gap_tol = checks.finite_float(gap_tol, "gap_tol", 0.0, low_open=True)
    if problem.workspace == "mean":
        return _solve_mean(problem)
    w = problem.cost.weights
    try:
        solution = solve_convex_allocation(w, problem.rows.matrix,
                                           problem.variable(problem.lower),
                                           problem.variable(problem.upper), gap_tol=gap_tol,
                                           power=problem.variable_power)
    except InfeasibleAllocationError as exc:
        raise unreachable_worst(problem, exc.rows, exc.loads) from None
    active = _row_frame(problem, solution.active)
    active["multiplier"] = solution.multipliers[solution.active]
    scale = 2.0 / problem.variable_power  # rows scale as 1/I² (FOSM) or 1/I (stack)
    active["elasticity"] = -scale * active["multiplier"] / solution.fun
    certificate = {"dual_bound": solution.dual_bound, "duality_gap": solution.duality_gap,
                   "relative_gap": solution.relative_gap,
                   "stationarity": solution.kkt.stationarity,
                   "primal_feasibility": solution.kkt.primal_feasibility,
                   "complementary_slackness": solution.kkt.complementary_slackness,
                   "certified": bool(solution.success), "rows": problem.rows.counts}
    return AllocationResult(problem=problem, method="exact", tolerances=solution.t,
                            cost=float(problem.cost.total(solution.t)),
                            feasible=problem.meets_targets(solution.t),
                            certificate=certificate, active=active,
                            requirements=requirement_multipliers(problem, solution))


def solve_gwo(problem, *, n_wolves: int = 100, n_iterations: int = 500, rng=None,
              initial=None, progress=None) -> AllocationResult:
    """Grey Wolf Optimiser on the problem's free items (paper: 500 iterations, 100 wolves).

    Parameters
    ----------
    problem : AllocationProblem
    n_wolves, n_iterations : int
    rng : None, int or numpy.random.Generator
    initial : array_like, optional
        ``(m, n_errors)`` starting allocations placed in the pack (e.g. the reference).
    progress : callable, optional
        ``progress(iteration, best_cost, best_violation)`` after each iteration.
    """
    free = ~problem.locked
    if not free.any():
        raise InputError("solve_gwo: every item of the problem is locked (lower == upper), so "
                         "there is nothing to optimise; evaluate problem.lower instead")
    rng = streams.generator(rng)
    checks.callback(progress, "progress")

    def full(x):
        t = np.broadcast_to(problem.lower, x.shape[:-1] + problem.lower.shape).copy()
        t[..., free] = x
        return t

    start = None if initial is None else \
        np.atleast_2d(problem.machine.check_tolerances(initial))[:, free]
    run = grey_wolf(lambda x: problem.cost.total(full(x)), problem.lower[free],
                    problem.upper[free], violation=lambda x: problem.violation(full(x)),
                    n_wolves=n_wolves, n_iterations=n_iterations, rng=rng, initial=start,
                    progress=progress)
    t = full(run.x)
    history = run.history.rename(columns={"fun": "cost"})
    history.index.name = "iteration"
    return AllocationResult(problem=problem, method="gwo", tolerances=t, cost=float(run.fun),
                            feasible=problem.meets_targets(t),
                            certificate={"violation": run.violation,
                                         "evaluations": run.n_evaluations},
                            active=_active_rows(problem, t), history=history)


def _row_frame(problem, rows) -> pd.DataFrame:
    """Output name, pose index and axis positions of screened constraint rows."""
    pose = problem.rows.pose[rows]
    frame = pd.DataFrame({"output": np.array(OUTPUTS)[problem.rows.output[rows]],
                          "pose": pose})
    for i, axis in enumerate(problem.machine.axes):
        frame[axis] = problem.poses[pose, i]
    return frame


def _active_rows(problem, t, tol: float = 1e-6) -> pd.DataFrame:
    """Worst-case rows within ``tol`` of binding at ``t`` (no multipliers)."""
    if problem.rows is None:
        return pd.DataFrame()
    load = problem.rows.matrix @ problem.variable(t)
    return _row_frame(problem, np.flatnonzero(load >= 1.0 - tol))


# ----- workspace-mean reading ----------------------------------------------------------
MEAN_TOLERANCE = 1e-10  # shortfall of the mean probability that counts as violated
MAX_CUTS_ROUNDS = 200
#: Slack of a mean constraint within which it is active at the end (tangent cut added).
MEAN_TANGENT = 1e-7


def _solve_mean(problem) -> AllocationResult:
    """Kelley's cutting planes for ``mean_p P_o(u) ≥ R_o`` (workspace-mean reading).

    Where every β ≥ √3 the mean probability ``h_o(u)`` is concave in ``u = t²``, so the
    feasible set is convex and a tangent plane at a point of its boundary supports it
    (Veinott's supporting hyperplanes). Each round solves the certified convex problem
    with all cuts so far (:func:`solve_convex_allocation`); for every output still short
    at the relaxed optimum ``u`` it finds the boundary point between the lower bounds
    (feasible, checked first) and ``u`` and cuts there. The last
    relaxation's dual bound is a lower bound on the optimum wherever the concavity holds,
    i.e. globally when β ≥ √3 at every pose even with every tolerance at its upper bound
    (``certificate['global']``).
    """
    model = _MeanConstraint(problem)
    w, lo, hi = problem.cost.weights, problem.lower ** 2, problem.upper ** 2
    at_lower = model.slack(lo)
    if np.any(at_lower < 0):
        raise _unreachable_mean(problem, at_lower)
    u, cuts, relaxed, tangent = hi.copy(), [], None, False
    for rounds in range(1, MAX_CUTS_ROUNDS + 1):
        shortfall = model.slack(u) < -MEAN_TOLERANCE
        if not shortfall.any():
            if tangent or relaxed is None:
                break
            # the cuts met at u were taken elsewhere: one more round with the tangents at
            # u itself, so that u is stationary for the mean constraints, not the cuts
            shortfall, tangent = model.slack(u) <= MEAN_TANGENT, True
        cuts.extend(model.cut(lo, u, output) for output in np.flatnonzero(shortfall))
        relaxed = solve_convex_allocation(w, np.array(cuts), lo, hi)
        u = relaxed.u
    u = _restore_mean_feasibility(model, u, lo)
    t = np.sqrt(u)
    cost = float(problem.cost.total(t))
    bound = cost if relaxed is None else relaxed.dual_bound  # None: the upper bounds are optimal
    certificate = {"dual_bound": bound, "relative_gap": (cost - bound) / cost,
                   "primal_feasibility": float(max(0.0, -model.slack(u).min())),
                   "rounds": rounds, "cuts": len(cuts),
                   "min_beta_at_upper": float(model.beta(hi).min()),
                   "global": bool(model.beta(hi).min() >= CONVEX_BETA)}
    certificate["certified"] = bool(certificate["global"]
                                    and (relaxed is None or relaxed.success))
    active = np.flatnonzero(model.slack(u) <= 1e-7)
    return AllocationResult(problem=problem, method="exact", tolerances=t, cost=cost,
                            feasible=problem.meets_targets(t), certificate=certificate,
                            active=pd.DataFrame({"output": np.array(OUTPUTS)[active]}))


def _restore_mean_feasibility(model, u, lo):
    """Shrink ``u`` towards ``lo`` by bisection until every mean constraint holds."""
    if model.slack(u).min() >= 0:
        return u
    rho = largest_fraction(lambda rho: model.slack(np.maximum(lo, rho * u)).min() >= 0)
    return np.maximum(lo, rho * u)


class _MeanConstraint:
    """``h_o(u) = mean_p P_o(β_p) − R_o`` with ``β_p = I_o/√(a_p·u)``, and its cuts."""

    def __init__(self, problem):
        self.a = np.square(problem.jacobian / problem.k * problem.spread)  # σ² = a @ u
        self.limits = problem.machine.limits
        self.targets = problem.machine.targets
        self.side = problem.side

    def beta(self, u) -> np.ndarray:
        return self.limits / np.sqrt(self.a @ u)

    def slack(self, u, output=slice(None)):
        """``h(u)`` for every output, or for one when ``output`` is an index."""
        sigma = np.sqrt(self.a[:, output, :] @ u)
        mean = probability(self.limits[output], sigma, self.side).mean(axis=0)
        return mean - self.targets[output]

    def gradient(self, u) -> np.ndarray:
        """``∂h_o/∂u_i``, ``(6, n)``: dP/dβ · dβ/dσ² · a."""
        beta = self.beta(u)
        density = (2 if self.side == "two_sided" else 1) * norm.pdf(beta)
        dp_dsigma2 = -density * beta ** 3 / (2 * self.limits ** 2)
        return np.einsum("po,pon->on", dp_dsigma2, self.a) / beta.shape[0]

    def cut(self, lo, u, output) -> np.ndarray:
        """Row ``r`` of the supporting cut ``r @ u' ≤ 1`` for ``output``.

        The cut touches the boundary ``h_o = 0`` on the segment from ``lo`` (where
        ``h_o ≥ 0``) to ``u`` (where ``h_o < 0``), found by bisection; there
        ``h_o(u') ≥ 0`` implies ``−∇h_o·u' ≤ −∇h_o·u_b``, and the right-hand side is > 0.
        """
        s = largest_fraction(lambda s: self.slack(lo + s * (u - lo), output) >= 0,
                             steps=45)  # 2^-45 of the segment: far below the tolerances
        boundary = lo + s * (u - lo)
        g = self.gradient(boundary)[output]
        return -g / (-g @ boundary)
