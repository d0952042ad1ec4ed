"""``precrel allocate MACHINE.toml --out CSV``: the cheapest allocation meeting the targets."""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd

from allocation import AllocationProblem
from allocation.elasticity import requirement_table
from allocation.result_files import allocation_to_csv, gap_text
from reliability.errors import InputError
from reliability.poses import workspace_grid
from studies.report.writer import SIGNIFICANT

from . import options


def add_parser(subparsers):
    parser = subparsers.add_parser(
        "allocate", help="cheapest allocation meeting the targets (Eq. 34)",
        description="Solve the allocation problem of Eq. (34) at every pose of the grid: "
                    "the certified optimum (exact) or the Grey Wolf Optimiser (gwo). Prints "
                    "the cost relative to the initial allocation, what binds and the "
                    "elasticity of each requirement; writes CSV columns error, reference, "
                    "allocated.")
    options.add_machine(parser)
    parser.add_argument("--out", required=True, metavar="CSV",
                        help="allocation file to write (columns error, reference, allocated)")
    options.add_side(parser)
    parser.add_argument("--target", type=options.probability, metavar="R",
                        help="one reliability target for every output (default: the file's)")
    options.add_points(parser)
    options.add_bounds(parser)
    options.add_distribution(parser)
    parser.add_argument("--lock", nargs="+", default=(), metavar="NAME",
                        help="errors held at their initial tolerance (e.g. X.dx)")
    parser.add_argument("--method", choices=("exact", "gwo"), default="exact",
                        help="certified convex optimum (default) or the paper's GWO")
    parser.add_argument("--seed", type=options.seed, default=0,
                        help="random seed of GWO (default 0)")
    parser.add_argument("--overwrite", action="store_true", help="replace an existing --out")
    return parser


def run(args) -> int:
    bounds = options.check_bounds(args.bounds)
    out = options.destination(args.out, args.overwrite)
    machine = options.machine(args)
    for name in args.lock:
        if name not in machine.error_names:
            raise InputError(f"--lock: unknown error {name!r}; the machine's errors are "
                             f"named like {machine.error_names[0]!r}")
    if args.target is not None:
        machine = dataclasses.replace(machine, targets=np.full(6, args.target))
    options.say(f"building the problem on the {args.points}-point grid")
    problem = AllocationProblem.build(machine, workspace_grid(machine, args.points),
                                      side=args.side, bounds=bounds, locked=tuple(args.lock))
    result = solve(problem, args.method, args.seed)
    print(describe(result))
    allocation_to_csv(result, out, args.overwrite, significant=SIGNIFICANT)
    print(f"\nallocation written to {out}")
    return 0


def solve(problem, method: str, seed: int = 0):
    """The exact optimum, or GWO (100 wolves, 500 iterations) with a progress bar."""
    if method == "exact":
        options.say("solving the convex problem (certified optimum)")
        return problem.solve_exact()
    iterations = 500
    with options.progress_bar(iterations, "GWO") as bar:
        return problem.solve_gwo(n_wolves=100, n_iterations=iterations, rng=seed,
                                 progress=lambda *_: bar.update())


def describe(result) -> str:
    """Cost relative to the initial allocation, feasibility, what binds, elasticities."""
    problem = result.problem
    initial = problem.cost.total(problem.reference)
    lines = [f"method: {result.method}; cost {result.cost:.6g} = "
             f"{result.cost / initial:.4%} of the initial allocation ({initial:.6g}); "
             f"{options.reading_text(problem.machine)}"]
    if result.method == "exact":
        certificate = result.certificate
        lines.append(f"certified optimum: {'yes' if certificate['certified'] else 'NO'} "
                     f"(relative duality gap {gap_text(certificate['relative_gap'])})")
    else:
        lines.append("feasible: yes" if result.feasible else
                     f"NOT FEASIBLE: the best wolf violates the constraints by "
                     f"{result.certificate['violation']:.3g}")
    frame = result.to_frame()
    counts = frame["status"].value_counts()
    lines.append("items: " + ", ".join(f"{counts.get(s, 0)} {s}"
                                        for s in ("lower", "upper", "free", "locked")))
    if result.requirements is not None:
        lines += ["", "requirements (elasticities from the Lagrange multipliers):",
                  requirement_table(result).to_string()]
    elif len(result.active):
        lines += ["", "binding (output, pose) constraints: "
                  + ", ".join(sorted(set(result.active["output"])))]
    if problem.distribution == "truncated" and problem.side != "stack":
        lines += ["", exact_linear_text(problem, result.tolerances)]
    return "\n".join(lines)


def exact_linear_text(problem, tolerances) -> str:
    """Under the truncated reading: at each output's worst grid pose, the normal
    approximation the constraint holds (FOSM with the truncated σ) beside the exact
    probability of the linearised output, and how far apart they are."""
    frame = problem.evaluate(tolerances)
    table = pd.DataFrame({
        "P two-sided, normal approximation": [options.percent(v) for v in
                                              frame["worst_two_sided"]],
        "P exact linear (truncated errors)": [options.percent(v) for v in
                                              frame["exact_two_sided"]],
        "exact − normal": [f"{v:+.3g}" for v in
                           frame["exact_two_sided"] - frame["worst_two_sided"]],
    }, index=frame.index)
    return ("at each output's worst grid pose, the constrained normal approximation and the "
            "exact probability of the linearised output:\n" + table.to_string())
