"""The bracket of the allocation for a machine-yield target with the log-concave lower bound.

Run as ``python -m studies.benchmarks.yield_bracket [--yield 0.95] [--machines 4000 20000]
[--convex-machines 20000] [--bound-machines 50000] [--seed 2023] [--confidence 0.95]
[--only paper trunnion swivel]``. For each machine (as
:mod:`studies.benchmarks.yield_allocation`: ``constant`` profile, 5-point grid, the machine
file's box) and each sample size N:

1. the feasible side: :func:`allocation.allocate_for_yield` with N machines per sample and
   one convex step (:func:`allocation.machine_yield.yield_dual.tangent_step`, its gradient on
   ``--convex-machines`` machines), calibrated and verified on fresh samples of N; its
   verified yield with the Clopper–Pearson interval;
2. the lower side: the certified bound of the relaxations (deterministic, FOSM), and
   :func:`allocation.machine_yield.yield_dual.log_concave_bound` at ``--confidence`` (one step
   from the result, then the bound on a fresh sample of ``--bound-machines``);
3. the gap, (feasible − lower bound) / feasible, for each lower bound, and the seconds.

The design margin of the feasible side falls as ``1/√N``, so the gap does too: the larger N
shows how much of the gap the margin is. Nothing is asserted.
"""

from __future__ import annotations

import argparse
import time

import allocation
import reliability
from allocation.machine_yield.yield_dual import log_concave_bound
from studies.benchmarks.yield_allocation import MACHINES
from studies.workflows.timing import one_blas_thread


def bracket_lines(machine, yield_target, machines, args) -> list[str]:
    """The lines of one machine at one sample size."""
    started = time.perf_counter()
    result = allocation.allocate_for_yield(machine, yield_target, profile="constant",
                                           machines=machines, rng=args.seed,
                                           convex_steps=1,
                                           convex_machines=args.convex_machines)
    searched = time.perf_counter() - started
    started = time.perf_counter()
    bound = log_concave_bound(result, machines=args.bound_machines, steps=1,
                              confidence=args.confidence, rng=args.seed)
    bounded = time.perf_counter() - started
    initial = result.initial_cost
    v = result.verified_yield
    verdict = "verified" if result.verified else "NOT verified"
    return [
        f"  N {machines:,}: feasible {result.cost / initial:.2%} of the initial cost "
        f"({result.method}; search {result.search_calibrated_cost / initial:.2%} "
        f"calibrated), verified {v.estimate:.4f} [{v.lower:.4f}, {v.upper:.4f}] {verdict}; "
        f"{searched:.0f} s",
        f"    certified lower bound {result.lower_bound / initial:.2%}: gap "
        f"{result.relative_gap:.1%} of the feasible cost",
        f"    log-concave lower bound at {bound.confidence:.0%} {bound.bound / initial:.2%} "
        f"(estimate {bound.point_estimate / initial:.2%}; tangent at "
        f"{bound.point_cost / initial:.2%}, yield {bound.point_yield:.4f} on "
        f"{bound.machines:,} machines): gap {1 - bound.bound / result.cost:.1%} of the "
        f"feasible cost; {bounded:.0f} s"]


@one_blas_thread
def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--yield", dest="yield_target", type=float, default=0.95)
    parser.add_argument("--machines", type=int, nargs="+", default=[4000, 20000])
    parser.add_argument("--convex-machines", type=int, default=20000)
    parser.add_argument("--bound-machines", type=int, default=50000)
    parser.add_argument("--seed", type=int, default=2023)
    parser.add_argument("--confidence", type=float, default=0.95)
    parser.add_argument("--only", nargs="+", choices=list(MACHINES), default=list(MACHINES))
    args = parser.parse_args(argv)
    for label, path in (MACHINES[name] for name in args.only):
        machine = reliability.load_machine(path)
        print(f"\n== {label}: yield {args.yield_target:g}, seed {args.seed}", flush=True)
        for machines in args.machines:
            print("\n".join(bracket_lines(machine, args.yield_target, machines, args)),
                  flush=True)


if __name__ == "__main__":
    main()
