"""Benchmark of the machine yield on the paper's machine.

Run as ``python -m studies.benchmarks.machine_yield [--machines N] [--seed S]
[--distribution normal|truncated]``. Prints:

1. the machine yield (all six outputs within their limits at every pose of the 5-point grid,
   15 625 poses) of the initial (Table 4), the paper's (Table 6) and the optimal (certified
   two-sided 99 % grid optimum) allocations under the ``independent``, ``constant`` and
   ``gp:300`` profiles, with intervals, the method ``auto`` chose and the first-order bounds
   of the linearised model; the machine file's reading of a tolerance (``normal``) unless
   ``--distribution`` names another (``truncated`` is the paper's Monte-Carlo draw);
2. a yield near 1 − 1e−4: the optimum's tolerances scaled down until the linearised model
   fails with probability 1e−4 (:meth:`YieldModel.linear_failure`, by bisection; the
   first-order union bound is far looser when rows fail together, as under ``constant``),
   estimated by importance sampling on the exact chain to a CoV
   of 0.1, with the machines it evaluated against the ``(1 − p)/(p · CoV²)`` crude sampling
   would need, and both times;
3. timings: our crude estimator against the simple vectorised reference, the grid experiment
   (:meth:`reliability.sampling.grid_experiment.GridExperiment.run`, one generator per machine) on
   the same number of machines, in the same run.

Nothing is asserted; the numbers are the result.
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np
import pandas as pd

import reliability
from allocation import AllocationProblem
from reliability.model.poses import workspace_grid
from reliability.sampling.grid_experiment import GridExperiment
from reliability.sampling.machine_yield import DEFAULT_MACHINES, YieldModel
from reliability.sampling.yield_estimate import yield_text
from studies.paper.tables import TABLE6
from studies.workflows.timing import one_blas_thread

PROFILES = ("independent", "constant", "gp:300")
#: The linearised model's failure probability of the rare case.
RARE_FAILURE = 1e-4


def allocations(machine) -> dict:
    """Initial (Table 4), paper (Table 6) and the certified two-sided 99 % grid optimum."""
    problem = AllocationProblem.build(machine, workspace_grid(machine, 5), side="two_sided")
    return {"initial": machine.initial_allocation,
            "paper": machine.error_vector(TABLE6, default=None),
            "optimal": problem.solve_exact().tolerances}


def yield_table(machine, named, machines: int, seed: int) -> pd.DataFrame:
    """Every allocation under every profile, ``method='auto'``."""
    rows = []
    for profile in PROFILES:
        model = YieldModel(machine, profile=profile)
        for name, t in named.items():
            start = time.perf_counter()
            y = model.estimate(t, machines=machines, rng=seed)
            rows.append({"allocation": name, "profile": profile,
                         "yield": yield_text(y.estimate),
                         "95% interval": f"[{yield_text(y.lower)}, {yield_text(y.upper)}]",
                         "method": y.method, "machines": y.machines,
                         "first-order bounds": f"[{yield_text(y.first_order_lower)}, "
                                               f"{yield_text(y.first_order_upper)}]",
                         "seconds": round(time.perf_counter() - start, 1)})
    return pd.DataFrame(rows)


def rare_scale(model, tolerances, seed: int) -> float:
    """The factor c (to 0.1 %) for which the linearised model of c·t fails with probability
    :data:`RARE_FAILURE`, by bisection in log c."""
    low, high = np.log(0.1), 0.0
    while high - low > 1e-3:
        middle = 0.5 * (low + high)
        failure = model.linear_failure(np.exp(middle) * tolerances, rng=seed)
        low, high = (middle, high) if failure < RARE_FAILURE else (low, middle)
    return float(np.exp(0.5 * (low + high)))


def crude_timing(machine, t, profile, machines: int, seed: int) -> dict:
    """Seconds per machine of our crude estimator and of the grid experiment."""
    model = YieldModel(machine, profile=profile)
    start = time.perf_counter()
    ours = model.estimate(t, machines=machines, rng=seed, method="crude")
    mine = (time.perf_counter() - start) / machines
    experiment = GridExperiment(machine, 5, profile)
    start = time.perf_counter()
    reference = experiment.run(t, repeats=machines, rng=seed + 1, keep_values="none",
                               distribution=machine.distribution).all_inside_share()
    theirs = (time.perf_counter() - start) / machines
    return {"profile": profile, "machines": machines,
            "ours yield": yield_text(ours.estimate),
            "reference yield": yield_text(float(reference.estimate)),
            "ours ms/machine": round(1e3 * mine, 3),
            "reference ms/machine": round(1e3 * theirs, 3),
            "reference/ours": round(theirs / mine, 2)}


@one_blas_thread
def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--machines", type=int, default=DEFAULT_MACHINES)
    parser.add_argument("--seed", type=int, default=2023)
    parser.add_argument("--distribution", choices=("normal", "truncated"), default=None)
    args = parser.parse_args(argv)
    machine = reliability.hobbing_machine()
    if args.distribution is not None:
        machine = dataclasses.replace(machine, distribution=args.distribution)
    named = allocations(machine)
    print(f"{machine.name}: machine yield over the 5-point grid (15 625 poses), reading "
          f"'{machine.distribution}', up to {args.machines} built machines each, seed "
          f"{args.seed}; first-order bounds of the linearised model (union bound, best "
          f"single row)\n")
    print(yield_table(machine, named, args.machines, args.seed).to_string(index=False))

    model = YieldModel(machine, profile="constant")
    scale = rare_scale(model, named["optimal"], args.seed)
    t = scale * named["optimal"]
    linear = model.linear_failure(t, rng=args.seed)
    start = time.perf_counter()
    rare = model.estimate(t, machines=50_000, rng=args.seed, method="importance",
                          target_cov=0.1)
    seconds = time.perf_counter() - start
    timing = crude_timing(machine, named["optimal"], "constant", 1000, args.seed)
    crude_seconds = rare.crude_equivalent * timing["ours ms/machine"] / 1e3
    lower, upper = rare.first_order_lower, rare.first_order_upper
    print(f"\nA yield near 1 − 1e-4: the optimum × {scale:.4f} (the linearised model fails "
          f"with {linear:.3g}), profile constant:")
    print(f"  importance sampling: yield {yield_text(rare.estimate)} (95 % "
          f"[{yield_text(rare.lower)}, {yield_text(rare.upper)}]), failure probability "
          f"{rare.failure_probability:.3g}, CoV {rare.cov:.3f}, {rare.machines:,} machine "
          f"evaluations, {seconds:.1f} s")
    print(f"  first-order bounds {yield_text(lower)} ≤ yield ≤ {yield_text(upper)}")
    fewer = rare.crude_equivalent / rare.machines
    print(f"  crude sampling for the same CoV: (1 − p)/(p·CoV²) = "
          f"{rare.crude_equivalent:,.0f} machine evaluations ({fewer:,.0f} × more), "
          f"about {crude_seconds:,.0f} s at "
          f"{timing['ours ms/machine']} ms per machine "
          f"({crude_seconds / seconds:,.0f} × the importance sampler's time)")

    print("\nCrude sampling against the simple vectorised reference (GridExperiment.run, "
          "the optimum, same number of machines):")
    rows = [timing] + [crude_timing(machine, named["optimal"], p, 1000, args.seed)
                       for p in ("independent", "gp:300")]
    print(pd.DataFrame(rows).to_string(index=False))


if __name__ == "__main__":
    main()
