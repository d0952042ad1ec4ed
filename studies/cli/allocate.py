"""``precrel allocate MACHINE.toml --out CSV``: the cheapest allocation meeting the targets;
with ``--catalogue CAT.toml`` the cheapest choice of catalogue classes."""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd

from allocation import AllocationProblem, load_catalogue, solve_catalogue
from allocation.continuous import check_continuous, solve_continuous
from allocation.elasticity import requirement_table
from allocation.result_files import (allocation_to_csv, cost_shares_text, cost_units_text, gap_text,
                                     nearly_free_text)
from reliability.errors import InputError
from reliability.poses import workspace_grid
from studies.report.writer import SIGNIFICANT

from . import options


def add_parser(subparsers):
    parser = subparsers.add_parser(
        "allocate", help="cheapest allocation meeting the targets (Eq. 34)",
        description="Solve the allocation problem of Eq. (34) over the continuous "
                    "workspace (default: the grid's optimum with the certificate's worst "
                    "poses added until every output is certified, docs/continuous-"
                    "allocation.md) or at every pose of the grid (--workspace grid): "
                    "the certified optimum (exact) or, on the grid, the Grey Wolf Optimiser "
                    "(gwo). Prints "
                    "the cost relative to the initial allocation, what binds and the "
                    "elasticity of each requirement; writes CSV columns error, reference, "
                    "allocated. With --catalogue: the certified cheapest choice of one class "
                    "per component of a catalogue (docs/catalogue.md), written as CSV "
                    "columns component, class, price.")
    options.add_machine(parser)
    parser.add_argument("--out", required=True, metavar="CSV",
                        help="allocation file to write (columns error, reference, allocated);"
                             " with --catalogue the choice (columns component, class, price)")
    options.add_side(parser)
    parser.add_argument("--target", type=options.probability, metavar="R",
                        help="one reliability target for every output (default: the file's)")
    options.add_points(parser)
    options.add_study_model(parser)
    options.add_bounds(parser)
    options.add_workspace(parser)
    parser.add_argument("--lock", nargs="+", default=(), metavar="NAME",
                        help="errors held at their initial tolerance (e.g. X.dx)")
    parser.add_argument("--method", choices=("exact", "gwo"), default="exact",
                        help="certified convex optimum (default) or the paper's GWO")
    parser.add_argument("--seed", type=options.seed, default=0,
                        help="random seed of GWO (default 0)")
    parser.add_argument("--catalogue", metavar="CAT.toml",
                        help="choose one class per component of this catalogue instead of "
                             "continuous tolerances, on the grid poses (no --bounds, --lock, "
                             "--method gwo or --workspace continuous)")
    parser.add_argument("--tolerances", metavar="CSV",
                        help="with --catalogue: tolerances of the items in no component "
                             "(default the initial allocation)")
    parser.add_argument("--tolerances-out", metavar="CSV",
                        help="with --catalogue: write the tolerances that follow from the "
                             "choice (columns error, reference, allocated)")
    parser.add_argument("--overwrite", action="store_true",
                        help="replace existing --out / --tolerances-out files")
    return parser


def run(args) -> int:
    if args.catalogue is not None:
        return run_catalogue(args)
    for option, value in (("--tolerances", args.tolerances),
                          ("--tolerances-out", args.tolerances_out)):
        if value is not None:
            raise InputError(f"{option} is used with --catalogue only")
    bounds = options.check_bounds(args.bounds)
    out = options.destination(args.out, args.overwrite)
    machine = options.machine(args)
    for name in args.lock:
        if name not in machine.error_names:
            raise InputError(f"--lock: unknown error {name!r}; the machine's errors are "
                             f"named like {machine.error_names[0]!r}")
    if args.target is not None:
        machine = dataclasses.replace(machine, targets=np.full(6, args.target))
    workspace = options.workspace(args)
    if workspace == "continuous":
        if args.method != "exact":
            raise InputError("--method gwo searches the grid problem only; use --workspace "
                             "grid with it (the continuous workspace needs the certified "
                             "optimum, --method exact)")
        check_continuous(machine, args.side)
    options.say(f"building the problem on the {args.points}-point grid, "
                f"{options.box_words(machine, bounds)}")
    problem = AllocationProblem.build(machine, workspace_grid(machine, args.points),
                                      side=args.side, bounds=bounds, locked=tuple(args.lock))
    if workspace == "continuous":
        options.say(f"certifying over the continuous workspace (rtol {args.rtol:g})")
        continuous = solve_continuous(problem, rtol=args.rtol, progress=options.say)
        result = continuous.result
        print(describe(result, continuous.summary()))
    else:
        result = solve(problem, args.method, args.seed)
        print(describe(result, f"workspace: grid — the targets hold at the "
                               f"{len(problem.poses)} poses of the {args.points}-point grid "
                               f"(not certified between them)"))
    allocation_to_csv(result, out, args.overwrite, significant=SIGNIFICANT)
    print(f"\nallocation written to {out}")
    return 0


def run_catalogue(args) -> int:
    """``--catalogue``: everything checked first, then the certified cheapest choice."""
    for option, given in (("--bounds", args.bounds is not None), ("--lock", bool(args.lock)),
                          ("--method gwo", args.method != "exact"),
                          ("--workspace continuous", args.workspace == "continuous")):
        if given:
            raise InputError(f"{option} does not apply with --catalogue: classes are used "
                             f"as given, items in no component keep their starting "
                             f"tolerances and the choice holds on the grid poses")
    out = options.destination(args.out, args.overwrite)
    tolerances_out = None if args.tolerances_out is None else \
        options.destination(args.tolerances_out, args.overwrite, "--tolerances-out")
    if tolerances_out is not None and tolerances_out.resolve() == out.resolve():
        raise InputError("--tolerances-out must differ from --out")
    machine = options.machine(args)
    catalogue = load_catalogue(args.catalogue, machine)
    start = None if args.tolerances is None else \
        options.read_tolerances(args.tolerances, machine)
    if args.target is not None:
        machine = dataclasses.replace(machine, targets=np.full(6, args.target))
    options.say(f"building the problem on the {args.points}-point grid")
    problem = AllocationProblem.build(machine, workspace_grid(machine, args.points),
                                      side=args.side, reference=start)
    options.say(f"choosing among {catalogue.n_choices:,} combinations of classes (HiGHS)")
    result = solve_catalogue(problem, catalogue)
    print(result.summary())
    print(f"workspace: grid — the choice meets the targets at the {len(problem.poses)} poses "
          f"of the {args.points}-point grid (a catalogue choice is made on the grid only)")
    result.to_csv(out, args.overwrite, significant=SIGNIFICANT)
    print(f"\nchoice written to {out}")
    if tolerances_out is not None:
        allocation_to_csv(result, tolerances_out, args.overwrite)  # all digits
        print(f"tolerances written to {tolerances_out}")
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


def describe(result, workspace: str) -> str:
    """Cost relative to the initial allocation, feasibility, what binds, elasticities;
    ``workspace`` is the text that says where the targets hold."""
    problem = result.problem
    initial = problem.cost.total(problem.reference)
    lines = [f"method: {result.method}; cost {result.cost:.6g} = "
             f"{result.cost / initial:.4%} of the initial allocation ({initial:.6g}); "
             f"{options.reading_text(problem.machine)}", workspace]
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
    lines.append(f"{cost_units_text(problem.cost)}; cost shares at the initial allocation: "
                 f"{cost_shares_text(problem.cost, problem.reference)}")
    if nearly_free_text(result):
        lines.append(nearly_free_text(result))
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
