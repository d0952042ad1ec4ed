"""Allocation for a machine-yield target against the naive method (one common target).

Run as ``python -m studies.benchmarks.yield_allocation [--yield 0.95] [--machines 2000 4000]
[--seeds 2023 2024 2025 2026 2027] [--at-target] [--only paper trunnion swivel]``. For the paper's machine
(``reliability/machines/hobbing.toml``), the 5-axis trunnion mill of the tests
(``tests/machines/trunnion5.toml``) and the 5-axis machine with a C table and a B swivel
head (``tests/machines/swivel5.toml``), under the ``constant`` error profile and each file's
reading of a tolerance, on the 5-point grid and each file's box (its ``[bounds]`` table, else
the default [0.5, 1.5] × the initial allocation), for every sample size and
seed it prints

1. the cost bracket of :func:`allocation.allocate_for_yield`: the certified lower bound
   (the larger of the row bound and the pose-chain bound,
   :mod:`allocation.machine_yield.yield_bound`), the feasible cost (and the search's before its
   calibration) and the gap, all relative to the initial allocation's cost;
2. the verified yield interval of the allocation found (95 % Clopper–Pearson, from a fresh
   sample of built machines, the count stated), and the naive method's cost and verified
   yield;
3. the margin at equal yield on a third, independent sample shared by both methods
   (:func:`allocation.machine_yield.yield_margin.equal_yield_margin`): each method's cost at the
   design yield both were tuned to (``--at-target``: at Y itself), and their difference with its
   bootstrap standard error (paired over machines);
4. the wall and CPU time of ``allocate_for_yield`` and its peak traced memory
   (:mod:`tracemalloc`, numpy's arrays included);

and per machine and sample size the mean margin over the seeds with its standard error
(the spread of the margins across seeds over the square root of their count), which
counts the noise of the design samples the searches ran on as well.

Nothing is asserted on times.
"""

from __future__ import annotations

import argparse
import time
import tracemalloc
from pathlib import Path

import numpy as np

import allocation
import reliability
from allocation.machine_yield.yield_margin import equal_yield_margin
from reliability.model.poses import workspace_grid
from studies.workflows.timing import one_blas_thread

ROOT = Path(__file__).resolve().parents[2]
#: The search whose numbers docs/yield-allocation.md ("Numbers") quotes: the share of
#: machines passing, no convex step, no log-concave bound (the defaults before the bracket
#: by default, which :mod:`studies.benchmarks.yield_bracket` measures).
SHARE_PATH = dict(estimator="share", convex_steps=0, bound_machines=0)
MACHINES = {"paper": ("paper (hobbing.toml)",
                      ROOT / "reliability" / "machines" / "hobbing.toml"),
            "trunnion": ("5-axis trunnion (trunnion5.toml)",
                         ROOT / "tests" / "machines" / "trunnion5.toml"),
            "swivel": ("5-axis swivel head (swivel5.toml)",
                       ROOT / "tests" / "machines" / "swivel5.toml")}


def box_words(machine) -> str:
    """The box the allocation searches, as its problem states it."""
    return allocation.AllocationProblem.build(machine, workspace_grid(machine, 2)[:1]).box_text()


def timed_allocation(machine, yield_target, machines, seed):
    """The allocation, its wall and CPU seconds and its peak traced bytes."""
    tracemalloc.start()
    wall, cpu = time.perf_counter(), time.process_time()
    result = allocation.allocate_for_yield(machine, yield_target, profile="constant",
                                           machines=machines, rng=seed, **SHARE_PATH)
    seconds = (time.perf_counter() - wall, time.process_time() - cpu)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return result, seconds, peak


def show(machine, yield_target, machines, seed, at_target) -> float:
    """One run's lines; returns its margin (naive − found at equal yield, relative to the
    initial cost)."""
    result, (wall, cpu), peak = timed_allocation(machine, yield_target, machines, seed)
    initial = result.initial_cost
    v, n = result.verified_yield, result.naive.verified_yield
    margin = equal_yield_margin(result, level=yield_target if at_target else None)
    print(f"  N {machines}, seed {seed}: bracket [{result.lower_bound / initial:.2%}, "
          f"{result.cost / initial:.2%}] of the initial cost, gap {result.relative_gap:.1%} "
          f"of the feasible cost ({result.method}, {result.search_cost / initial:.2%} "
          f"before calibration); verified {v.estimate:.4f} "
          f"[{v.lower:.4f}, {v.upper:.4f}] {'verified' if result.verified else 'NOT verified'}"
          f"; naive {result.naive.cost / initial:.2%}, verified {n.estimate:.4f} "
          f"[{n.lower:.4f}, {n.upper:.4f}]")
    print(f"    margin at equal yield {margin['level']:.4f}: {margin['margin']:.2%} ± "
          f"{margin['margin_error']:.2%} of the initial cost (paired bootstrap s.e.); "
          f"time {wall:.1f} s wall, {cpu:.1f} s CPU ({result.evaluations} candidates; "
          f"build {result.seconds['build']:.1f} s, bound {result.seconds['bound']:.1f} s, "
          f"targets {result.seconds['targets']:.1f} s, "
          f"shape {result.seconds['shape']:.1f} s, calibration "
          f"{result.seconds['calibration']:.1f} s, verification "
          f"{result.seconds['verify']:.1f} s); peak memory {peak / 2 ** 20:.0f} MiB")
    return margin["margin"]


@one_blas_thread
def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--yield", dest="yield_target", type=float, default=0.95)
    parser.add_argument("--machines", type=int, nargs="+", default=[2000, 4000])
    parser.add_argument("--seeds", type=int, nargs="+", default=[2023, 2024, 2025, 2026, 2027])
    parser.add_argument("--at-target", action="store_true",
                        help="compare the costs at yield Y instead of the design yield")
    parser.add_argument("--only", nargs="+", choices=list(MACHINES), default=list(MACHINES),
                        help="the machines to run (all three by default)")
    args = parser.parse_args(argv)
    for label, path in (MACHINES[name] for name in args.only):
        machine = reliability.load_machine(path)
        print(f"\n== {label}: yield {args.yield_target:g}, profile constant, distribution "
              f"{machine.distribution}, 5-point grid, box {box_words(machine)}")
        for machines in args.machines:
            margins = []
            for seed in args.seeds:
                try:
                    margins.append(show(machine, args.yield_target, machines, seed,
                                        args.at_target))
                except allocation.YieldUnreachableError as unreachable:
                    print(f"  N {machines}, seed {seed}: {unreachable}")
            if not margins:
                continue
            if len(margins) == 1:
                print(f"  N {machines}: margin over the naive method {margins[0]:.2%} of the "
                      f"initial cost (one seed: no spread across seeds)")
                continue
            error = np.std(margins, ddof=1) / np.sqrt(len(margins))
            print(f"  N {machines}: margin over the naive method {np.mean(margins):.2%} ± "
                  f"{error:.2%} of the initial cost (mean ± s.e. over {len(margins)} seeds)")


if __name__ == "__main__":
    main()
