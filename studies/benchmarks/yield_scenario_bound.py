"""A lower bound over every allocation, from single built machines: the scenario quantile bound.

Run as ``python -m studies.benchmarks.yield_scenario_bound [--yield 0.95] [--machines 1000]
[--allocation-machines 4000] [--seed 2023] [--confidence 0.95] [--only paper trunnion
swivel]``. For each machine (as
:mod:`studies.benchmarks.yield_allocation`: ``constant`` profile, 5-point grid, default box):

1. draw N built machines (:meth:`reliability.sampling.machine_yield.YieldModel.draws`, the
   third stream of :func:`reliability.basics.streams.yield_allocation_streams` of
   ``seed + 2``, which no search uses), and read each one's standard normal per error
   (:func:`allocation.machine_yield.yield_dual.unit_draws`);
2. for each machine ``k``, bound from below ``v_k``: the cheapest allocation in the box
   (Eq. 28) under which machine ``k`` alone keeps all six linearised outputs ``J(pose)·e``
   (Eq. 19) within their limits at every pose of the grid. The outputs of one built
   machine are affine along a linear axis under ``constant``, so the stroke ends of those
   axes stand for the grid
   (:attr:`reliability.sampling.machine_yield.YieldModel.deciding_poses`).
   The constraints are linear in the tolerances; each convex cost term ``w_i/t_i²`` is
   replaced by the largest of 24 of its tangents, a linear programme (HiGHS) whose optimum
   is at most ``v_k``;
3. any allocation whose yield is at least Y is passed by all but at most ``K`` of the N
   machines with probability at least the confidence (``K`` as in
   :func:`studies.benchmarks.yield_gap_sources.allowed_failures`), so its cost is at least
   the ``(K + 1)``-th largest ``v_k``: a lower bound over every shape, not one ray, at that
   confidence (the quantile bound of the sampled chance-constrained problem: Ahmed,
   Luedtke, Song & Xie, *Math. Program.* 162, 2017; Pagnoncelli, Ahmed & Shapiro 2009 for
   the confidence).

It prints that bound beside the certified lower bound and the feasible cost of
:func:`allocation.allocate_for_yield` (``--allocation-machines`` per sample, ``seed``),
relative to the initial cost.
Each ``v_k`` exploits its own machine's draws (errors that happen to be small are left
loose), which is why the bound is weak: it is a check on whether a bound of this kind could
close the gap, not a product feature. One linear programme per machine (no vectorised
solver does them together); about 0.1–0.3 s each.

Nothing is asserted.
"""

from __future__ import annotations

import time

import numpy as np
from scipy import sparse
from scipy.optimize import linprog

import allocation
from allocation.machine_yield.yield_dual import scaled_rows, unit_draws
from reliability.basics import streams
from reliability.sampling.machine_yield import YieldModel
from studies.benchmarks.yield_allocation import SHARE_PATH
from studies.benchmarks.yield_gap_sources import (allowed_failures, bound_parser,
                                                  each_machine)
from studies.workflows.timing import one_blas_thread

#: Grid points per axis, and tangents of each cost term in the linear programme.
POINTS = 5
TANGENTS = 24


class TangentProgram:
    """``min Σ w_i/t_i²`` over the box with ``|A t| ≤ 1``, bounded from below by a linear
    programme in ``x = t/t_ref`` and one epigraph variable per term (cost relative to the
    reference allocation's)."""

    def __init__(self, problem):
        reference = np.asarray(problem.reference, dtype=float)
        self.reference = reference
        self.weights = problem.cost.weights / reference**2 / problem.cost.total(reference)
        self.lower = np.asarray(problem.lower) / reference
        self.upper = np.asarray(problem.upper) / reference
        n = len(reference)
        taus = np.exp(np.linspace(np.log(self.lower), np.log(self.upper), TANGENTS))
        value, slope = self.weights / taus**2, -2.0 * self.weights / taus**3
        # s_i ≥ f(τ) + f'(τ)(x_i − τ)  ⇔  f'(τ) x_i − s_i ≤ f'(τ) τ − f(τ)
        rows = np.arange(TANGENTS * n)
        columns = np.tile(np.arange(n), TANGENTS)
        self.tangents = sparse.csr_matrix(
            (np.r_[slope.ravel(), -np.ones(TANGENTS * n)],
             (np.r_[rows, rows], np.r_[columns, columns + n])), shape=(TANGENTS * n, 2 * n))
        self.tangent_bounds = (slope * taus - value).ravel()
        self.objective = np.r_[np.zeros(n), np.ones(n)]
        self.bounds = list(zip(self.lower, self.upper)) + [(0.0, None)] * n

    def lowest_cost(self, rows) -> float:
        """The programme's optimum for constraint rows ``|rows · t| ≤ 1`` (``rows`` on
        tolerances), ``inf`` when no allocation in the box meets them."""
        scaled = rows * self.reference
        scaled = scaled[np.abs(scaled) @ self.upper > 1.0]  # rows that can bind in the box
        if not len(scaled):
            return float(self.weights @ (1.0 / self.upper**2))
        padded = sparse.hstack([sparse.csr_matrix(np.vstack([scaled, -scaled])),
                                sparse.csr_matrix((2 * len(scaled), len(self.reference)))])
        found = linprog(self.objective, A_ub=sparse.vstack([self.tangents, padded]),
                        b_ub=np.r_[self.tangent_bounds, np.ones(2 * len(scaled))],
                        bounds=self.bounds, method="highs")
        if found.status == 2:
            return float("inf")
        if found.status != 0:
            raise RuntimeError(f"HiGHS: {found.message}")
        return float(found.fun)


def scenario_report(machine, yield_target, machines, seed, confidence,
                    allocation_machines) -> list[str]:
    """The lines of one machine."""
    started = time.perf_counter()
    result = allocation.allocate_for_yield(machine, yield_target, profile="constant",
                                           points=POINTS, machines=allocation_machines,
                                           rng=seed, **SHARE_PATH)
    searched = time.perf_counter() - started
    model = YieldModel(result.problem.machine, points=POINTS)
    draws = unit_draws(model, model.draws(machines,
                                          streams.yield_allocation_streams(seed + 2)[2]))
    poses = model.deciding_poses
    rows = scaled_rows(result.problem.machine, poses)
    program = TangentProgram(result.problem)
    started = time.perf_counter()
    costs = np.sort([program.lowest_cost(rows * z) for z in draws])[::-1]
    allowed = allowed_failures(machines, yield_target, confidence)
    bound = costs[allowed]
    feasible = result.cost / result.initial_cost
    certified = result.lower_bound / result.initial_cost
    return [f"  feasible {feasible:.2%} of the initial cost (verified "
            f"{result.verified_yield.estimate:.4f}), certified lower bound {certified:.2%} "
            f"(gap {result.relative_gap:.1%}); {searched:.0f} s",
            f"  scenario quantile bound {bound:.2%} at confidence {confidence:g} (rank "
            f"{allowed + 1} from the dearest of {machines} single machines, {len(poses)} "
            f"poses each; median {np.median(costs):.2%}, {np.isinf(costs).sum()} machines no "
            f"allocation in the box passes): gap {1 - bound / feasible:.1%} of the feasible "
            f"cost; {time.perf_counter() - started:.0f} s"]


@one_blas_thread
def main(argv=None):
    parser = bound_parser(__doc__.splitlines()[0], 1000)
    parser.add_argument("--allocation-machines", type=int, default=4000)
    args = parser.parse_args(argv)
    for machine in each_machine(args):
        print("\n".join(scenario_report(machine, args.yield_target, args.machines, args.seed,
                                        args.confidence, args.allocation_machines)),
              flush=True)


if __name__ == "__main__":
    main()
