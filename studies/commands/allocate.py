"""``precrel allocate MACHINE.toml --out CSV``: the cheapest allocation meeting the targets."""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd
from scipy.stats import norm

from allocation import AllocationProblem
from reliability.errors import InputError
from reliability.fosm import required_index
from reliability.poses import workspace_grid

from . import _common


def add_parser(subparsers):
    parser = subparsers.add_parser(
        "allocate", help="cheapest allocation meeting the targets (Eq. 34)",
        description="Solve the allocation problem of Eq. (34) at every pose of the grid: "
                    "the certified optimum (exact) or the Grey Wolf Optimiser (gwo). Prints "
                    "the cost relative to the initial allocation, what binds and the "
                    "elasticity of each requirement; writes CSV columns error, reference, "
                    "allocated.")
    _common.add_machine(parser)
    parser.add_argument("--out", required=True, metavar="CSV",
                        help="allocation file to write (columns error, reference, allocated)")
    _common.add_side(parser)
    parser.add_argument("--target", type=_common.probability, metavar="R",
                        help="one reliability target for every output (default: the file's)")
    _common.add_points(parser)
    _common.add_bounds(parser)
    parser.add_argument("--lock", nargs="+", default=(), metavar="NAME",
                        help="errors held at their initial tolerance (e.g. X.dx)")
    parser.add_argument("--method", choices=("exact", "gwo"), default="exact",
                        help="certified convex optimum (default) or the paper's GWO")
    parser.add_argument("--seed", type=_common.seed, default=0,
                        help="random seed of GWO (default 0)")
    parser.add_argument("--overwrite", action="store_true", help="replace an existing --out")
    return parser


def run(args) -> int:
    bounds = _common.check_bounds(args.bounds)
    out = _common.check_new_file(args.out, args.overwrite)
    machine = _common.machine(args)
    for name in args.lock:
        if name not in machine.error_names:
            raise InputError(f"--lock: unknown error {name!r}; the machine's errors are "
                             f"named like {machine.error_names[0]!r}")
    if args.target is not None:
        machine = dataclasses.replace(machine, targets=np.full(6, args.target))
    _common.say(f"building the problem on the {args.points}-point grid")
    problem = AllocationProblem.build(machine, workspace_grid(machine, args.points),
                                      side=args.side, bounds=bounds, locked=tuple(args.lock))
    result = solve(problem, args.method, args.seed)
    print(describe(result))
    write_allocation(result, out, args.overwrite)
    print(f"\nallocation written to {out}")
    return 0


def solve(problem, method: str, seed: int = 0):
    """The exact optimum, or GWO (100 wolves, 500 iterations) with a progress bar."""
    if method == "exact":
        _common.say("solving the convex problem (certified optimum)")
        return problem.solve_exact()
    iterations = 500
    with _common.progress_bar(iterations, "GWO") as bar:
        return problem.solve_gwo(n_wolves=100, n_iterations=iterations, rng=seed,
                                 progress=lambda *_: bar.update())


def describe(result) -> str:
    """Cost relative to the initial allocation, feasibility, what binds, elasticities."""
    problem = result.problem
    initial = problem.cost.total(problem.reference)
    lines = [f"method: {result.method}; cost {result.cost:.6g} = "
             f"{result.cost / initial:.4%} of the initial allocation ({initial:.6g})"]
    if result.method == "exact":
        certificate = result.certificate
        lines.append(f"certified optimum: {'yes' if certificate['certified'] else 'NO'} "
                     f"(relative duality gap {certificate['relative_gap']:.1e})")
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
    return "\n".join(lines)


def requirement_table(result) -> pd.DataFrame:
    """Per output: binding rows, ``d ln cost / d ln limit`` and ``d ln cost / d ln target``.

    The worst-case rows are ``σ² (z/I)² <= 1`` with ``z`` the required index of the target
    (Eq. 23), so relaxing the limit ``I`` by 1 % changes the cost by ``−2Σλ/F`` % and
    raising ``z`` by 1 % by ``+2Σλ/F`` %; the chain rule through ``R = Φ(z)`` (one-sided)
    or ``R = 2Φ(z) − 1`` (two-sided) gives the target's elasticity.
    """
    problem = result.problem
    requirements = result.requirements
    limit_elasticity = -requirements["elasticity"].to_numpy()
    target = problem.machine.targets
    z = required_index(target, problem.side)
    slope = norm.pdf(z) * (2.0 if problem.side == "two_sided" else 1.0)  # dR/dz
    target_elasticity = requirements["elasticity"].to_numpy() * target / (z * slope)
    binding = requirements["binding_rows"].to_numpy() > 0
    return pd.DataFrame({
        "binding_rows": requirements["binding_rows"].to_numpy(),
        "binds": np.where(binding, "yes", "no"),
        "dlncost/dln_limit": np.round(limit_elasticity, 4) + 0.0,
        "dlncost/dln_target": np.round(target_elasticity, 4),
    }, index=requirements.index)


def allocation_frame(result) -> pd.DataFrame:
    """The allocation CSV contract: columns ``error, reference, allocated``."""
    frame = result.to_frame()
    return pd.DataFrame({"error": list(frame.index),
                         "reference": frame["reference"].to_numpy(),
                         "allocated": frame["allocated"].to_numpy()})


def write_allocation(result, path, overwrite: bool) -> None:
    """Write :func:`allocation_frame` with 6 significant digits."""
    from reliability.files import write_csv
    write_csv(allocation_frame(result), path, overwrite=overwrite, index=False,
              float_format="%.6g")
