"""Tolerances for a service life beside those for acceptance, on the same options: the
workflow behind ``precrel allocate MACHINE.toml --life T`` (docs/life-allocation.md).

One problem (grid, reading, box, locks, costs) is solved twice: for the targets at
acceptance (Eq. 34, the plain ``allocate``) and for the life target of
:mod:`allocation.per_pose.life` (every output within its limit at every pose and every age
of ``[0, T]`` under the machine's linear ``[drift]``), each over the continuous workspace
(certified, :func:`allocation.per_pose.continuous.solve_continuous`) or on the grid. The
life target is stricter at every pose (its probability is at most the acceptance
probability), so the life allocation costs at least the acceptance allocation of the same
pose set.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from allocation.per_pose.continuous import DEFAULT_RTOL, ContinuousAllocation, \
    solve_continuous
from allocation.per_pose.life import checked_life, life_loads, life_problem
from reliability.basics.errors import InputError


@dataclass(frozen=True, eq=False)
class LifeAllocationRun:
    """The life allocation and the acceptance allocation of one problem.

    Attributes
    ----------
    years : float
        The service life ``T``.
    drift : Drift
        The machine's drift (``kind`` 'linear').
    workspace : {'continuous', 'grid'}
    acceptance, life : ContinuousAllocation or AllocationResult
        The loop's result over the continuous workspace, or the grid optimum.
    seconds : (float, float)
        Wall time of the acceptance and of the life allocation (the life's includes
        building its rows and bounding the drift).
    """

    years: float
    drift: object
    workspace: str
    acceptance: object
    life: object
    seconds: tuple

    @property
    def life_result(self):
        """The life allocation's :class:`~allocation.AllocationResult`."""
        return _allocation(self.life)

    @property
    def acceptance_result(self):
        """The acceptance allocation's :class:`~allocation.AllocationResult`."""
        return _allocation(self.acceptance)

    @property
    def cost_ratio(self) -> float:
        """Cost of the life allocation over the acceptance allocation's."""
        return self.life_result.cost / self.acceptance_result.cost

    @property
    def certified(self) -> bool | None:
        """Both allocations certified over the continuous workspace (None on the grid)."""
        if self.workspace == "grid":
            return None
        return bool(self.acceptance.certified and self.life.certified)

    def worst_life_load(self, tolerances=None) -> np.ndarray:
        """Per output, the largest ``σ0² / A`` over the life problem's poses (grid and
        added) at ``tolerances`` (default the life allocation): ≤ 1 where the life target
        holds at all of them."""
        result = self.life_result
        tolerances = result.tolerances if tolerances is None else tolerances
        return life_loads(result.problem, tolerances).max(axis=0)

    def fields(self) -> dict:
        """The run's summary as plain values (``life_years`` first)."""
        rates = " ".join(f"{v:g}" for v in np.unique(self.drift.rate))
        return {"life_years": self.years, "drift_kind": self.drift.kind,
                "drift_rates_per_year": rates,
                "workspace": self.workspace, "certified": self.certified,
                "life_cost": float(self.life_result.cost),
                "acceptance_cost": float(self.acceptance_result.cost),
                "life_over_acceptance_cost": float(self.cost_ratio),
                "life_seconds": float(self.seconds[1]),
                "acceptance_seconds": float(self.seconds[0])}


def run(problem, years, *, workspace: str = "continuous", rtol: float = DEFAULT_RTOL,
        progress=None, time_limit: float | None = None) -> LifeAllocationRun:
    """The acceptance and the life allocation of ``problem``.

    Parameters
    ----------
    problem : AllocationProblem
        Two-sided, worst case (the acceptance problem).
    years : float
        The service life ``T`` > 0.
    workspace : {'continuous', 'grid'}
    rtol : float
        Relative tolerance of the certificate (continuous).
    progress : callable, optional
        ``progress(text)``: a line per step of each loop, prefixed by which allocation.
    time_limit : float, optional
        Seconds each of the two loops may take (continuous only).

    Returns
    -------
    LifeAllocationRun
    """
    if workspace not in ("continuous", "grid"):
        raise InputError(f"workspace must be 'continuous' or 'grid'; got {workspace!r}")
    say = progress or (lambda text: None)
    drift = problem.machine.drift
    checked_life(problem.machine, years)
    started = time.perf_counter()
    acceptance = _solve(problem, workspace, rtol, time_limit,
                        lambda text: say(f"acceptance: {text}"))
    middle = time.perf_counter()
    say(f"life {years:g} years: building the rows (one root per pose and output)"
        + (" and bounding the drift over the strokes" if workspace == "continuous" else ""))
    life = _solve(life_problem(problem, years, bound_drift=workspace == "continuous"),
                  workspace, rtol, time_limit, lambda text: say(f"life: {text}"))
    return LifeAllocationRun(years=float(years), drift=drift, workspace=workspace,
                             acceptance=acceptance, life=life,
                             seconds=(middle - started, time.perf_counter() - middle))


def _solve(problem, workspace, rtol, time_limit, progress):
    """The continuous loop's result, or the grid optimum."""
    if workspace == "grid":
        return problem.solve_exact()
    limits = {} if time_limit is None else {"time_limit": time_limit}
    return solve_continuous(problem, rtol=rtol, progress=progress, **limits)


def _allocation(result):
    """The AllocationResult of a loop's result or of a grid optimum."""
    return result.result if isinstance(result, ContinuousAllocation) else result
