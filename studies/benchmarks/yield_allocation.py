"""Allocation for a machine-yield target against the naive method (one common target).

Run as ``python -m studies.benchmarks.yield_allocation [--yield 0.95] [--machines 2000]
[--seed 2023] [--at-target]``. For the paper's machine
(``reliability/machines/hobbing.toml``) and the 5-axis trunnion mill of the tests
(``tests/machines/trunnion5.toml``), under the ``constant`` error profile and each file's
reading of a tolerance, on the 5-point grid and the default box, it prints

1. the cost bracket of :func:`allocation.allocate_for_yield`: the certified lower bound
   (every row at FOSM probability Y), the feasible cost and the gap, all relative to the
   initial allocation's cost;
2. the verified yield interval of the allocation found (95 % Clopper–Pearson, from a fresh
   sample of built machines, the count stated) and the per-output targets;
3. the naive method (the simple reference: one common per-pose target raised until the
   yield is reached) with its cost and verified yield, and the ratio of the two costs;
4. the margin at equal yield on a third, independent sample shared by both methods
   (:func:`allocation.yield_target.equal_yield_margin`): each method's cost at the design
   yield both were tuned to (``--at-target``: at Y itself), and their difference with its
   bootstrap standard error (paired over machines);
5. times: the search, the verification, one convex solve and one yield estimate.

Nothing is asserted on times.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

import allocation
import reliability
from allocation.yield_target import _Search, equal_yield_margin
from reliability.model.machine import OUTPUTS
from studies.workflows.timing import one_blas_thread

ROOT = Path(__file__).resolve().parents[2]
MACHINES = {"5-axis (trunnion5.toml)": ROOT / "tests" / "machines" / "trunnion5.toml",
            "paper (hobbing.toml)": ROOT / "reliability" / "machines" / "hobbing.toml"}


def show(label, path, yield_target, machines, seed, at_target):
    machine = reliability.load_machine(path)
    started = time.perf_counter()
    result = allocation.allocate_for_yield(machine, yield_target, profile="constant",
                                           machines=machines, seed=seed)
    elapsed = time.perf_counter() - started
    initial = result.initial_cost
    v, n = result.verified_yield, result.naive.verified_yield
    print(f"\n== {label}: yield {yield_target:g}, profile {result.profile}, distribution "
          f"{result.distribution}, {result.points}-point grid ({len(result.problem.poses):,} "
          f"poses), {result.problem.box_text()}")
    print(f"lower bound   {result.lower_bound / initial:9.4%} of the initial cost (every row "
          f"at FOSM probability {yield_target:g}, certified)")
    print(f"feasible cost {result.cost / initial:9.4%}   gap {result.gap / initial:.4%} of the "
          f"initial cost ({result.relative_gap:.1%} of the feasible cost)")
    print(f"verified yield {v.estimate:.4f} [{v.lower:.4f}, {v.upper:.4f}] from {v.n:,} fresh "
          f"machines: {'verified' if result.verified else 'NOT verified'} "
          f"(design yield aimed at {result.design_yield_target:.4f})")
    print(f"found by the {result.method} stage; per-output per-pose targets of the first "
          f"stage: " + ", ".join(f"{name} {r:.5f}"
                                 for name, r in zip(OUTPUTS, result.output_targets)))
    print(f"naive method: common target {result.naive.target:.5f}, cost "
          f"{result.naive.cost / initial:.4%}, verified yield {n.estimate:.4f} "
          f"[{n.lower:.4f}, {n.upper:.4f}]; cost ratio found/naive "
          f"{result.cost / result.naive.cost:.4f}")
    margin = equal_yield_margin(result, level=yield_target if at_target else None)
    print(f"at equal yield {margin['level']:.4f} ({margin['machines']:,} fresh machines "
              f"shared, {margin['evaluations']} allocations): naive "
              f"{margin['naive']:.4%} ± {margin['naive_error']:.4%}, found "
              f"{margin['result']:.4%} ± {margin['result_error']:.4%}; margin "
              f"{margin['margin']:.4%} ± {margin['margin_error']:.4%} of the initial cost "
          f"({margin['saving']:.2%} of the naive cost; paired bootstrap s.e.)")
    print(f"times: allocate_for_yield {elapsed:.1f} s ({result.evaluations} candidates on "
          f"the design sample; build {result.seconds['build']:.1f} s, per-output targets "
          f"{result.seconds['targets']:.1f} s, error shape {result.seconds['shape']:.1f} s, "
          f"verification {result.seconds['verify']:.1f} s)"
          f"; {one_solve_and_yield(result)}")


def one_solve_and_yield(result) -> str:
    """Time of one convex solve (cold) and of one yield estimate on the design sample."""
    search = _Search(result.problem.machine, result.points, None, result.machines,
                     result.seed, 0.0, problem=result.problem)
    z = np.full(6, 3.0)
    started = time.perf_counter()
    point = search.solve(z)
    solved = time.perf_counter()
    search.verification_sample()(point.t)
    sampled = time.perf_counter()
    return (f"one cold solve {1e3 * (solved - started):.0f} ms, one yield estimate "
            f"{sampled - solved:.2f} s ({1e3 * (sampled - solved) / result.machines:.2f} ms "
            f"per machine)")


@one_blas_thread
def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--yield", dest="yield_target", type=float, default=0.95)
    parser.add_argument("--machines", type=int, default=2000)
    parser.add_argument("--seed", type=int, default=2023)
    parser.add_argument("--at-target", action="store_true",
                        help="compare the costs at yield Y instead of the design yield")
    args = parser.parse_args(argv)
    for label, path in MACHINES.items():
        show(label, path, args.yield_target, args.machines, args.seed, args.at_target)


if __name__ == "__main__":
    main()
