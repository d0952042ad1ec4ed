"""Where the gap of an allocation for a machine-yield target comes from, along its own ray.

Run as ``python -m studies.benchmarks.yield_gap_sources [--yield 0.95] [--machines 4000]
[--seed 2023] [--confidence 0.95] [--only paper trunnion swivel]``. For each machine (as
:mod:`studies.benchmarks.yield_allocation`: ``constant`` profile, 5-point grid, default box)
it finds the allocation ``t`` of :func:`allocation.allocate_for_yield` and scales it,
``clip(s·t, box)``, judging every scale on one fresh sample of built machines (the second
stream of :func:`reliability.basics.streams.yield_allocation_streams` of ``seed + 2``, which
no search or margin uses). It prints the cost, relative to the initial allocation's, at
which that sample's yield is

1. the design yield ``Y_d`` the search had to reach (the feasible side's own margin),
2. ``Y`` itself,
3. ``1 − K/N`` with ``K`` the largest count of failures among ``N`` machines that a
   sampled lower bound at this confidence must allow: ``K`` is the smallest count with
   ``P(Binomial(N, 1 − Y) ≤ K) ≥ confidence``, since the bound must keep every allocation of
   yield ``Y`` feasible for its sample with that probability (the sample-average
   approximation bound of Nemirovski & Shapiro 2006 and Pagnoncelli, Ahmed & Shapiro 2009,
   one replication);
4. what the linear programming relaxation of that sampled problem (each failure allowed
   as ``(g_j − 1)/M_j`` with ``M_j`` the machine's largest excess on the ray) allows on
   this ray.

Along one ray the shape is held: a bound over every allocation can only be lower, so each
line is an upper limit on what a lower bound of that kind could prove here. The costs are
found by bisection on the scale (16 steps).

Nothing is asserted.
"""

from __future__ import annotations

import argparse

import numpy as np
from scipy.stats import binom

import allocation
import reliability
from reliability.basics import streams
from reliability.sampling.machine_yield import YieldModel
from studies.benchmarks.yield_allocation import MACHINES, SHARE_PATH
from studies.workflows.timing import one_blas_thread

STEPS = 16


def allowed_failures(machines: int, yield_target: float, confidence: float) -> int:
    """Smallest ``K`` with ``P(Binomial(machines, 1 − yield_target) ≤ K) ≥ confidence``."""
    return int(binom.ppf(confidence, machines, 1.0 - yield_target))


def scale_at(worst, level, low, high) -> float:
    """Largest scale in ``[low, high]`` whose sample yield (``worst(s) < 1``) is at least
    ``level``, by bisection (the yield falls as the scale grows)."""
    for _ in range(STEPS):
        middle = 0.5 * (low + high)
        low, high = (middle, high) if np.mean(worst(middle) < 1.0) >= level else (low, middle)
    return low


def ray_report(machine, yield_target, machines, seed, confidence) -> list[str]:
    """The lines of one machine."""
    result = allocation.allocate_for_yield(machine, yield_target, profile="constant",
                                           machines=machines, rng=seed, **SHARE_PATH)
    problem = result.problem
    lower, upper = np.asarray(problem.lower), np.asarray(problem.upper)
    model = YieldModel(problem.machine, points=result.points)
    u = model.draws(machines, streams.yield_allocation_streams(seed + 2)[1])

    def allocation_at(s):
        return np.clip(s * result.tolerances, lower, upper)

    def worst(s):
        return model.output_ratios(u, allocation_at(s)).max(axis=1)

    def cost(s):
        return problem.cost.total(allocation_at(s)) / result.initial_cost

    s_max = float(np.max(upper / result.tolerances))
    allowed = allowed_failures(machines, yield_target, confidence)
    at = {"design yield": scale_at(worst, result.design_yield_target, 0.5, s_max),
          "yield Y": scale_at(worst, yield_target, 0.5, s_max),
          "sampled bound": scale_at(worst, 1.0 - allowed / machines, 0.5, s_max)}
    at["its LP relaxation"] = relaxed_scale(worst(1.0), worst(s_max) / s_max, allowed, s_max)
    feasible = result.cost / result.initial_cost
    lines = [f"  found {feasible:.2%} of the initial cost ({result.method}), verified yield "
             f"{result.verified_yield.estimate:.4f}; yield of the fresh sample at s = 1: "
             f"{np.mean(worst(1.0) < 1.0):.4f}; lower bound {result.lower_bound / result.initial_cost:.2%}"
             f" (gap {result.relative_gap:.1%})"]
    for name, s in at.items():
        lines.append(f"  {name:>18}: scale {s:.4f}, cost {cost(s):.2%}, below the found cost "
                     f"by {1 - cost(s) / feasible:.1%} of it")
    lines.append(f"  (K = {allowed} of {machines} machines may fail in a sampled bound at "
                 f"confidence {confidence:g}; the expected count at Y is "
                 f"{machines * (1 - yield_target):.0f})")
    return lines


def relaxed_scale(ratio_at_one, slope, allowed, s_max) -> float:
    """Largest scale ``s ≤ s_max`` with ``Σ_j (s g_j − 1)_+ / M_j ≤ K`` for the linearised
    worst ratios ``g_j(s) = s·g_j(1)`` (homogeneous to first order), ``M_j`` the machine's
    largest excess on the ray (at ``s_max``)."""
    excess = np.maximum(slope * s_max - 1.0, 1e-12)
    low, high = 0.5, s_max
    for _ in range(STEPS):
        middle = 0.5 * (low + high)
        used = np.sum(np.maximum(middle * ratio_at_one - 1.0, 0.0) / excess)
        low, high = (middle, high) if used <= allowed else (low, middle)
    return low


def bound_parser(description: str, machines: int) -> argparse.ArgumentParser:
    """The options of a benchmark on the yield allocation's lower side: yield, machines
    (default ``machines``), seed, confidence and the machines of the benchmark to run."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--yield", dest="yield_target", type=float, default=0.95)
    parser.add_argument("--machines", type=int, default=machines)
    parser.add_argument("--seed", type=int, default=2023)
    parser.add_argument("--confidence", type=float, default=0.95)
    parser.add_argument("--only", nargs="+", choices=list(MACHINES), default=list(MACHINES))
    return parser


def each_machine(args):
    """The machines of ``args.only``, each after its heading is printed."""
    for label, path in (MACHINES[name] for name in args.only):
        print(f"\n== {label}: yield {args.yield_target:g}, {args.machines} machines, "
              f"seed {args.seed}", flush=True)
        yield reliability.load_machine(path)


@one_blas_thread
def main(argv=None):
    args = bound_parser(__doc__.splitlines()[0], 4000).parse_args(argv)
    for machine in each_machine(args):
        print("\n".join(ray_report(machine, args.yield_target, args.machines, args.seed,
                                   args.confidence)))


if __name__ == "__main__":
    main()
