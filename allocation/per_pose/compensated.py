"""Allocation for compensated machines: the cheapest allocation in the box whose machines,
measured under a plan and compensated, meet the targets (docs/compensation.md).

With ``u = t²`` and ``σ = t/3`` the residual variance of an output after compensation is
``V(u) = jᵀ Cov(r) j + jᵀ diag(v_R) j``, ``Cov(r)`` from
:func:`reliability.compensation.residual.residual_covariance` and ``v_R`` the repeatability
and reversal. It is concave in ``u`` when every item the plan informs is tabled (``P(Σ)`` is
operator concave). Held at the table's rule of the current point ``u_k``, the residual
variance is linear in ``u`` (``fixed_rule_terms``) and, since the posterior mean at ``u`` is
at least as good a rule as the one of ``u_k``, bounds ``V(u)`` from above and touches it at
``u_k``. So each convex solve of :func:`allocation.solvers.convex.solve_convex_allocation` on these
rows gives an allocation that meets the targets after compensation, at a cost no higher
than the one before: a sequence of feasible iterates, decreasing in cost.

The lower bound of the bracket comes from a relaxation: ``P`` is non-decreasing in ``Σ``,
so on the box ``V(u) ≥ jₛᵀ P(Σ_lo) jₛ + Σ_{i unseen} j_i² u_i / 9 + jᵀ diag(v_R) j`` (the
items the plan does not inform keep their prior, linear in ``u``; the others are bounded by
their posterior at the tightest tolerances); the dual bound of that convex problem is below
the cost of every allocation that meets the targets after compensation.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import pandas as pd

from reliability.basics.display import error_units
from reliability.basics.saved_fields import Array, Flag, Frame, Number, read_fields, write_fields
from reliability.basics.saved_results import load_payload, save_payload
from reliability.basics.display import (lower_bound_text, percentage_text,
                                        tolerance_text)
from reliability.compensation.compensation_plans import K
from reliability.compensation.residual import (fixed_rule_terms, positioning_variance,
                                               posterior_covariance)

from ..solvers.convex import solve_convex_allocation
from .problem import screen_rows
from .solve import AllocationResult, TargetUnreachableError

#: Rounds of linearisation stop when the cost falls by less than this fraction.
ROUND_TOLERANCE = 1e-6
#: At most this many rounds.
MAX_ROUNDS = 30


@dataclass(frozen=True, eq=False)
class CompensatedAllocation:
    """The cheapest allocation found for compensated machines, with its bracket.

    Attributes
    ----------
    result : AllocationResult
        The allocation (method ``'compensated'``) on the problem's poses and box.
    plan : CompensationPlan
    upper : ndarray
        The box's upper bounds with the table's range: a tabled item is not allowed a
        tolerance beyond its ``max_correction``.
    lower_bound : float
        Certified lower bound on the cost of every allocation in the box that meets the
        targets after compensation.
    cost_without : float
        The certified optimum without compensation on the same poses and box.
    rounds : DataFrame
        ``round, cost`` of the linearisations.
    feasible : bool
        The allocation meets every target after compensation at every pose (the exact
        residual covariance, not its linear bound).
    """

    result: AllocationResult
    plan: object
    upper: np.ndarray
    lower_bound: float
    cost_without: float
    rounds: pd.DataFrame
    feasible: bool

    @property
    def tolerances(self) -> np.ndarray:
        return self.result.tolerances

    @property
    def cost(self) -> float:
        return self.result.cost

    def items(self) -> pd.DataFrame:
        """Per item: allocated, its bounds, where it sits and what the plan leaves of its
        prior σ (``posterior_share``), with why an item below its upper bound stays there."""
        problem, plan = self.result.problem, self.plan
        t = self.tolerances
        share = np.sqrt(np.diag(posterior_covariance(t / K, plan.information))) / (t / K)
        capped = self.upper < problem.upper
        at_upper = np.isclose(t, self.upper, rtol=1e-6)
        at_lower = np.isclose(t, problem.lower, rtol=1e-6) & ~at_upper
        reason = np.where(at_upper & capped, "table range",
                          np.where(at_upper, "box", np.where(at_lower, "lower bound",
                                                             "targets")))
        return pd.DataFrame({"error": problem.names, "iso": problem.machine.iso_names,
                             "allocated": t, "lower": problem.lower, "upper": self.upper,
                             "tabled": plan.tabled, "seen": plan.seen,
                             "posterior_share": share, "limited_by": reason})

    def tight(self) -> pd.DataFrame:
        """The items kept below their upper bound, with why."""
        table = self.items()
        return table[table["limited_by"].isin(("targets", "lower bound"))]

    def summary(self) -> str:
        """Cost with and without compensation, the bracket and what stays tight."""
        tight = self.tight()
        gap = percentage_text(self.cost / self.lower_bound - 1, bound="upper")
        lines = [f"cost after compensation {self.cost:.6g} (certified lower bound "
                 f"{lower_bound_text(self.lower_bound)}, gap {gap}); "
                 f"without compensation {self.cost_without:.6g}: ratio "
                 f"{self.cost / self.cost_without:.4f}",
                 f"{len(self.rounds)} linearisations; meets every target after compensation "
                 f"at every pose: {'yes' if self.feasible else 'NO'}",
                 f"{len(self.items()) - len(tight)} of {len(self.items())} items at an "
                 f"upper bound (the box or the table's range)"]
        if len(tight):
            lines.append("items kept tight:")
            units = error_units(tight["error"], self.result.problem.machine.cost_coefficients.units)
            lines += [f"  {row.error} ({row.iso}): {tolerance_text(row.allocated, unit)} of "
                      f"up to {tolerance_text(row.upper, unit)}, posterior σ "
                      f"{row.posterior_share:.2f} of prior, "
                      f"{'seen' if row.seen else 'not seen'} by the plan"
                      for row, unit in zip(tight.itertuples(), units)]
        return "\n".join(lines)

    def to_frame(self) -> pd.DataFrame:
        """Per item, the allocation and what limits it: :meth:`items`."""
        return self.items()

    def save(self, path, overwrite: bool = False):
        """Save as JSON (tag :data:`SAVED_FORMAT`): the allocation (as
        :meth:`AllocationResult.save` writes it) and :data:`SAVED_FIELDS`; the plan is not
        saved. An existing file is kept unless ``overwrite``. Returns the path."""
        payload = write_fields(self, SAVED_FIELDS)
        payload["result"] = self.result.payload()
        return save_payload(path, SAVED_FORMAT, payload, overwrite)

    @classmethod
    def load(cls, path, problem, plan) -> "CompensatedAllocation":
        """Reload an allocation written by :meth:`save` with its ``problem`` (checked to be
        the saved allocation's in the box the table's range leaves) and compensation
        ``plan`` (re-attached), every field checked: the table's upper bounds lie within the
        problem's box and the allocation within them, so the bracket and the verdict are the saved ones. A damaged field
        raises :class:`~reliability.basics.errors.SavedResultError` naming the file and
        field."""
        data = load_payload(path, SAVED_FORMAT)
        values = read_fields(data, SAVED_FIELDS)
        upper = values["upper"]
        if upper.shape != problem.upper.shape or np.any(upper > problem.upper):
            raise data.error("upper", "expected one bound per error within the problem's box")
        result = AllocationResult.from_payload(data.table("result"),
                                               replace(problem, upper=upper))
        if values["lower_bound"] > result.cost * (1 + 1e-9):
            raise data.error("lower_bound", "exceeds the allocation's cost")
        return cls(result=result, plan=plan, **values)


SAVED_FORMAT = "precrel.compensated_allocation"
SAVED_FIELDS = (Array("upper", (None,), positive=True), Number("lower_bound", positive=True),
                Number("cost_without", positive=True), Frame("rounds", ("round", "cost")),
                Flag("feasible"))


def allocate_compensated(problem, plan, *, without=None, max_rounds: int = MAX_ROUNDS,
                         tolerance: float = ROUND_TOLERANCE) -> CompensatedAllocation:
    """The cheapest allocation found whose machines meet the targets after compensation.

    Parameters
    ----------
    problem : AllocationProblem
        Poses, box, costs and targets (``side='two_sided'`` or ``'one_sided'``, worst case).
    plan : CompensationPlan
        How the machines will be measured and compensated.
    without : AllocationResult, optional
        The problem's certified optimum without compensation, when already solved.
    max_rounds : int
    tolerance : float
        Stop when a round lowers the cost by less than this fraction.

    Returns
    -------
    CompensatedAllocation
    """
    without = problem.solve_exact() if without is None else without
    upper = np.where(plan.tabled, np.minimum(problem.upper, plan.max_correction),
                     problem.upper)
    upper = np.maximum(upper, problem.lower)
    model = _Residual(problem, plan)
    t = _start(model, without.tolerances, problem.lower, upper)
    history = [(0, float(problem.cost.total(t)))]
    for index in range(1, max_rounds + 1):
        t = _round(model, t, problem.lower, upper)
        history.append((index, float(problem.cost.total(t))))
        if history[-2][1] - history[-1][1] <= tolerance * history[-1][1]:
            break
    result = AllocationResult(problem=replace(problem, upper=upper), method="compensated",
                              tolerances=t, cost=float(problem.cost.total(t)),
                              feasible=model.meets(t), certificate={},
                              active=pd.DataFrame())
    return CompensatedAllocation(result=result, plan=plan, upper=upper,
                                 lower_bound=_lower_bound(model, problem.lower, upper),
                                 cost_without=without.cost,
                                 rounds=pd.DataFrame(history, columns=["round", "cost"]),
                                 feasible=result.feasible)


class _Residual:
    """The residual variance's pieces on the problem's poses."""

    def __init__(self, problem, plan):
        self.problem, self.plan = problem, plan
        self.jacobian = np.concatenate([block for _, block in problem.jacobian_chunks()])
        self.allowed = np.square(problem.allowed_sigma)
        self.floor = np.square(self.jacobian) @ positioning_variance(problem.machine)

    def rows(self, gain, noise):
        """Coefficients ``(n_poses, 6, n)`` of ``u`` in the residual variance with the rule
        held fixed (``gain``, ``noise``), and the variance left for them ``(n_poses, 6)``."""
        coefficients = np.square(self.jacobian @ gain / K)
        constant = np.einsum("poi,ij,poj->po", self.jacobian, noise, self.jacobian)
        room = self.allowed - constant - self.floor
        return coefficients, room

    def variance(self, t) -> np.ndarray:
        gain, noise = fixed_rule_terms(t / K, self.plan.information, self.plan.tabled)
        coefficients, room = self.rows(gain, noise)
        return coefficients @ np.square(t) + (self.allowed - room)

    def meets(self, t) -> bool:
        return bool(np.all(self.variance(t) <= self.allowed * (1.0 + 1e-9)))

    def unreachable(self, t) -> TargetUnreachableError:
        load = self.variance(t) / self.allowed
        pose, output = np.unravel_index(int(np.argmax(load)), load.shape)
        name = self.problem.machine.outputs[output]
        return TargetUnreachableError(
            f"after compensation {name} at pose {pose} (of {len(load)}) needs "
            f"{np.sqrt(load[pose, output]):.4g} × its allowed σ even at the tightest "
            f"tolerances", pd.DataFrame({"output": [name], "pose": [int(pose)]}))


def _start(model, candidate, lower, upper) -> np.ndarray:
    """A feasible start: the allocation without compensation held in the box, else the
    tightest allocation."""
    start = np.clip(candidate, lower, upper)
    if model.meets(start):
        return start
    if model.meets(lower):
        return lower.copy()
    raise model.unreachable(lower)


def _round(model, t, lower, upper) -> np.ndarray:
    """One convex solve on the rows linearised at ``t``; ``t`` is feasible for them. When no
    row can bind in the box, the box's upper bounds are the optimum."""
    gain, noise = fixed_rule_terms(t / K, model.plan.information, model.plan.tabled)
    coefficients, room = model.rows(gain, noise)
    solved = _solve(model.problem, coefficients, room, lower, upper)
    return upper.copy() if solved is None else solved.t


def _solve(problem, coefficients, room, lower, upper):
    """The convex solve on ``coefficients @ u ≤ room``, or None when no row can bind."""
    if np.any(room <= 0):
        raise TargetUnreachableError(
            "after compensation what no tolerance changes (measurement noise, repeatability "
            "and reversal) alone exceeds an allowed σ", pd.DataFrame())
    rows = screen_rows(coefficients / room[..., None], np.square(upper))
    if len(rows.matrix) == 0:
        return None
    return solve_convex_allocation(problem.cost.weights, rows.matrix, np.square(lower),
                                   np.square(upper))


def _lower_bound(model, lower, upper) -> float:
    """Dual bound of the relaxation: informed items at their posterior of the tightest
    tolerances, the others exactly."""
    plan = model.plan
    seen = plan.seen
    posterior = posterior_covariance(np.where(seen, lower / K, 0.0), plan.information)
    gain = np.diag((~seen).astype(float))
    coefficients, room = model.rows(gain, posterior)
    solved = _solve(model.problem, coefficients, room, lower, upper)
    if solved is None:
        return float(model.problem.cost.total(upper))
    return float(solved.dual_bound)
