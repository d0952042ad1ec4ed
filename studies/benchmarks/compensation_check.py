"""Monte-Carlo check of the residual model of compensated machines, end to end.

Run as ``python -m studies.benchmarks.compensation_check [--machine swivel5|paper|PATH]
[--plan PLAN.toml] [--machines N] [--grid P] [--seed S] [--bounds LO HI]``. The machine's
cheapest allocation after compensation (two-sided targets of its file, on the ``P``-point
grid, box of the file or ``LO``–``HI`` × the initial allocation) is found; ``N`` machines are built to it, each measured under the plan (its readings simulated
on the exact chain with their set-ups and noise), identified, given its compensation tables,
and evaluated compensated on the exact chain at every grid pose, each approach drawing its
repeatability and reversal. Printed beside each other:

1. the machine yield (every output within its limit at every grid pose): predicted by the
   residual model (first order, Gaussian, 20 000 draws) and simulated, with 95 % intervals;
2. at the worst (pose, output) pairs of the FOSM after compensation: its probability against
   the share of simulated machines within the limit there, with a 95 % interval.

Nothing is asserted; the numbers are the result.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import pandas as pd

import reliability
from allocation import AllocationProblem
from allocation.per_pose.compensated import allocate_compensated
from reliability.basics.pass_rule import passes
from reliability.basics.statistics import binomial_interval
from reliability.basics.streams import spawn
from reliability.compensation.compensated_machines import (residual_model_passes,
                                                           simulate_compensated)
from reliability.compensation.compensation_plans import read_compensation_plan
from reliability.model.poses import workspace_grid
from studies.workflows.timing import one_blas_thread

MACHINES = {"swivel5": ("tests/machines/swivel5.toml", "docs/examples/swivel5_plan.toml"),
            "paper": (None, "docs/examples/paper_plan.toml")}
#: Draws of the residual model behind the predicted yield.
MODEL_DRAWS = 20_000
#: Worst (pose, output) pairs shown.
WORST = 5


def load(name: str, plan_path: str | None):
    """The machine and its compensation plan."""
    machine_path, default_plan = MACHINES.get(name, (name, None))
    machine = reliability.hobbing_machine() if machine_path is None else \
        reliability.load_machine(machine_path)
    return machine, read_compensation_plan(plan_path or default_plan, machine)


def check(machine, plan, *, machines: int, grid: int, seed: int, bounds=None) -> dict:
    """The allocation, the predicted and simulated yield and the worst pairs."""
    poses = workspace_grid(machine, grid)
    problem = AllocationProblem.build(machine, poses, side="two_sided", bounds=bounds)
    allocation = allocate_compensated(problem, plan)
    t = allocation.tolerances
    streams = spawn(seed, 2)
    started = time.perf_counter()
    simulated = simulate_compensated(plan, t, poses, machines, streams[0])
    seconds = time.perf_counter() - started
    predicted = residual_model_passes(plan, t, poses, MODEL_DRAWS, streams[1])
    inside = passes(simulated, machine.limits)
    return {"allocation": allocation, "seconds": seconds,
            "yield": yield_rows(inside, predicted),
            "worst": worst_rows(machine, plan.probability(t, poses), inside, poses)}


def yield_rows(inside, predicted) -> pd.DataFrame:
    rows = []
    for name, passes in (("residual model", predicted), ("simulated", inside)):
        count = int(passes.reshape(len(passes), -1).all(axis=1).sum())
        low, high = binomial_interval(count, len(passes))
        rows.append((name, len(passes), count / len(passes), float(low), float(high)))
    return pd.DataFrame(rows, columns=["yield of", "machines", "yield", "lower", "upper"])


def worst_rows(machine, probability, inside, poses) -> pd.DataFrame:
    order = np.argsort(probability, axis=None, kind="stable")[:WORST]
    rows = []
    for flat in order:
        pose, output = np.unravel_index(flat, probability.shape)
        count = int(inside[:, pose, output].sum())
        low, high = binomial_interval(count, len(inside))
        rows.append((machine.outputs[output], np.array2string(poses[pose], precision=4),
                     float(probability[pose, output]), count / len(inside), float(low),
                     float(high)))
    return pd.DataFrame(rows, columns=["output", "pose", "fosm", "simulated", "lower",
                                       "upper"])


@one_blas_thread
def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--machine", default="swivel5")
    parser.add_argument("--plan")
    parser.add_argument("--machines", type=int, default=200)
    parser.add_argument("--grid", type=int, default=3)
    parser.add_argument("--seed", type=int, default=2026)
    parser.add_argument("--bounds", type=float, nargs=2, metavar=("LO", "HI"))
    args = parser.parse_args(argv)
    machine, plan = load(args.machine, args.plan)
    result = check(machine, plan, machines=args.machines, grid=args.grid, seed=args.seed,
                   bounds=args.bounds)
    print(f"{machine.name}: {args.machines} machines built to the cheapest allocation after "
          f"compensation, measured, identified, compensated, on the {args.grid}-point grid "
          f"({result['seconds']:.0f} s)\n")
    print(result["allocation"].summary() + "\n")
    print(result["yield"].to_string(index=False) + "\n")
    print(result["worst"].to_string(index=False))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
