"""The measurement plan as a design choice: the cost of the cheapest allocation after
compensation against variants of the plan.

Run as ``python -m studies.benchmarks.compensation_plans [--grid P] [--out DIR]
[--bounds LO HI]`` (the box as factors of the initial allocation; default the machine file's). For the
test 5-axis machine (tests/machines/swivel5.toml) and the paper's machine, each with its
example plan (docs/examples/*_plan.toml), and for variants of the plan (laser runs only,
no laser runs, an instrument ten times noisier, the table's spacing five times wider), it
prints and writes (``plans.csv``, ``plans.png`` in ``--out``) the cost after compensation
over the certified cost without, with the certified lower bound, and the items kept tight.

Nothing is asserted; the numbers are the result.
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

import numpy as np
import pandas as pd

import reliability
from allocation import AllocationProblem
from allocation.per_pose.compensated import allocate_compensated
from reliability.compensation.compensation_plans import (CompensationPlan,
                                                         read_compensation_plan)
from reliability.measured.identification import plan_information
from reliability.model.poses import workspace_grid
from studies.workflows.timing import one_blas_thread

MACHINES = {"swivel5": ("tests/machines/swivel5.toml", "docs/examples/swivel5_plan.toml"),
            "paper": (None, "docs/examples/paper_plan.toml")}
#: Factor of the noisier instrument's ``u`` and of the wider spacing.
NOISIER = 10.0
WIDER = 5.0


def variants(plan: CompensationPlan) -> dict:
    """The plan and its variants, by name."""
    lines = tuple(run for run in plan.runs if run.centre is None and len(run.quantities) > 3)
    others = tuple(run for run in plan.runs if run not in lines)
    noisy = tuple(dataclasses.replace(run, u=run.u * NOISIER) for run in plan.runs)
    out = {"as planned": plan}
    for name, runs in (("laser runs only", lines), ("no laser runs", others),
                       (f"instrument {NOISIER:g} × noisier", noisy)):
        out[name] = dataclasses.replace(plan, runs=runs,
                                        information=plan_information(plan.machine, runs))
    out[f"spacing {WIDER:g} × wider"] = dataclasses.replace(
        plan, spacing_mm=plan.spacing_mm * WIDER, spacing_deg=plan.spacing_deg * WIDER)
    return out


def study(name: str, grid: int, bounds=None) -> pd.DataFrame:
    machine_path, plan_path = MACHINES[name]
    machine = reliability.hobbing_machine() if machine_path is None else \
        reliability.load_machine(machine_path)
    base = read_compensation_plan(plan_path, machine)
    problem = AllocationProblem.build(machine, workspace_grid(machine, grid), side="two_sided",
                                      bounds=bounds)
    without = problem.solve_exact()
    rows = []
    for variant, plan in variants(base).items():
        found = allocate_compensated(problem, plan, without=without)
        rows.append({"machine": name, "plan": variant, "runs": len(plan.runs),
                     "cost_ratio": found.cost / found.cost_without,
                     "lower_bound_ratio": found.lower_bound / found.cost_without,
                     "tight_items": len(found.tight()), "feasible": found.feasible})
    return pd.DataFrame(rows)


def figure(table: pd.DataFrame, path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    machines = list(dict.fromkeys(table["machine"]))
    fig, axes = plt.subplots(1, len(machines), figsize=(5 * len(machines), 3.6), sharey=True)
    for ax, name in zip(np.atleast_1d(axes), machines):
        part = table[table["machine"] == name]
        ax.barh(part["plan"], part["cost_ratio"], color="tab:blue", label="allocation found")
        ax.scatter(part["lower_bound_ratio"], part["plan"], color="black", marker="|", s=200,
                   label="certified lower bound")
        ax.set_title(name)
        ax.set_xlabel("cost after compensation / cost without")
        ax.invert_yaxis()
    np.atleast_1d(axes)[0].legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


@one_blas_thread
def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--grid", type=int, default=3)
    parser.add_argument("--out", default="compensation-plans")
    parser.add_argument("--bounds", type=float, nargs=2, metavar=("LO", "HI"))
    args = parser.parse_args(argv)
    out = Path(args.out)
    out.mkdir(exist_ok=True)
    table = pd.concat([study(name, args.grid, args.bounds) for name in MACHINES],
                      ignore_index=True)
    table.to_csv(out / "plans.csv", index=False, float_format="%.6g")
    figure(table, out / "plans.png")
    print(table.to_string(index=False, float_format=lambda v: f"{v:.4g}"))
    print(f"\nwritten plans.csv and plans.png into {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
