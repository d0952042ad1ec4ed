"""``precrel allocate MACHINE.toml --out CSV``: the cheapest allocation meeting the targets,
and beside it the tolerances to write on drawings (``--drawing``, default
``drawing_tolerances.csv`` in the folder of ``--out``); with ``--catalogue CAT.toml`` the
cheapest choice of catalogue classes; with ``--yield Y`` the cheapest allocation found
whose machine yield reaches Y, with its cost bracket."""

from __future__ import annotations

import contextlib
import dataclasses
from pathlib import Path

import numpy as np
import pandas as pd

from allocation import AllocationProblem, allocate_for_yield, solve_catalogue
from allocation.continuous import check_continuous, solve_continuous
from allocation.elasticity import requirement_table
from allocation.result_files import (DRAWING_FILE, DRAWING_RESOLUTION, allocation_to_csv,
                                     cost_shares_text, cost_units_text, drawing_check_text,
                                     drawing_to_csv, gap_text, nearly_free_text,
                                     written_cost_text)
from allocation.yield_dual import log_concave_bound, not_log_concave
from reliability.basics import display
from reliability.basics.errors import InputError
from reliability.model.poses import workspace_grid
from studies.report.machine_sections import shown_tolerance_table, tolerance_table
from studies.report.writer import SIGNIFICANT

from . import compensate, options

#: Where ``--yield`` simulates its built machines.
YIELD_EXECUTORS = ("serial", "dask")
YIELD_EXECUTOR_OPTIONS = ("--executor", "--workers", "--scheduler")
#: Options of --yield only, beside the executor's.
YIELD_ONLY_OPTIONS = ("--convex-steps", "--convex-machines", "--bound-machines")


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
                    "columns component, class, price. With --yield Y: the cheapest allocation "
                    "found whose machine yield (share of built machines within every limit at "
                    "every grid pose, under --profile) reaches Y, verified on fresh machines, "
                    "between a certified lower bound on the cost and the naive method "
                    "(docs/yield-allocation.md); --scheduler ADDRESS simulates the built "
                    "machines on a running Dask cluster, with the same result.")
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
                        help="random seed of GWO, or of the built machines with --yield "
                             "(default 0)")
    parser.add_argument("--yield", dest="yield_target", type=options.probability,
                        metavar="Y",
                        help="allocate for a machine yield Y in (0, 1) instead of per-pose "
                             "targets (with --profile, --machines, --scheduler; not with "
                             "--target, --side one_sided, --lock, --method gwo or "
                             "--catalogue)")
    options.add_yield_model(parser)
    add_yield_executor(parser)
    add_yield_bracket(parser)
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
    parser.add_argument("--drawing", metavar="CSV",
                        help=f"tolerances to write on drawings (columns error, iso, name, "
                             f"tolerance, unit; µm and arcsec, rounded down to the "
                             f"resolution; --tolerances reads it as it is); default "
                             f"{DRAWING_FILE} in the folder of --out; not with --catalogue")
    parser.add_argument("--drawing-resolution", nargs=2, type=float, metavar=("UM", "ARCSEC"),
                        default=DRAWING_RESOLUTION,
                        help="resolution of the drawing tolerances in µm and arcsec "
                             "(default 0.1 0.1)")
    parser.add_argument("--overwrite", action="store_true",
                        help="replace existing --out / --drawing / --tolerances-out files")
    compensate.add_allocation_option(parser)
    return parser


def run(args) -> int:
    if args.yield_target is None:
        for option in YIELD_EXECUTOR_OPTIONS:
            if getattr(args, option[2:]) is not None:
                raise InputError(f"{option} is used with --yield only: it says where the "
                                 f"built machines of the machine yield are simulated")
        for option in YIELD_ONLY_OPTIONS:
            if getattr(args, option[2:].replace("-", "_")) is not None:
                raise InputError(f"{option} is used with --yield only")
    if args.compensation is not None:
        return compensate.run_allocation(args)
    if args.yield_target is not None:
        return run_yield(args)
    if args.profile is not None:
        raise InputError("--profile is used with --yield only")
    if args.catalogue is not None:
        return run_catalogue(args)
    for option, value in (("--tolerances", args.tolerances),
                          ("--tolerances-out", args.tolerances_out)):
        if value is not None:
            raise InputError(f"{option} is used with --catalogue only")
    bounds = options.check_bounds(args.bounds)
    out = options.destination(args.out, args.overwrite)
    drawing = drawing_destination(args, out)
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
    print(changes_text(result))
    write_files(args, result, out, drawing)
    return 0


def drawing_destination(args, out: Path) -> Path:
    """Where the drawing file goes (``--drawing``, else beside ``--out``), checked before
    any work: it must differ from ``--out``."""
    path = Path(args.drawing) if args.drawing is not None else out.parent / DRAWING_FILE
    try:
        drawing = options.destination(path, args.overwrite, "--drawing")
    except InputError as error:
        if args.drawing is not None:
            raise
        raise InputError(f"{error} (the drawing file of an earlier allocation in this "
                         f"folder?), or name this one with --drawing CSV") from None
    if drawing.resolve() == out.resolve():
        raise InputError(f"--drawing {drawing} is also --out; give the drawing file another "
                         f"name")
    return drawing


def write_files(args, result, out: Path, drawing: Path, *, targets: bool = True) -> None:
    """The allocation CSV and the drawing file, each with a line on what it holds (with
    ``targets``, whether the drawing meets the per-pose targets of the result's problem)."""
    allocation_to_csv(result, out, args.overwrite, significant=SIGNIFICANT)
    print(f"\nallocation written to {out}, {written_cost_text(result)}")
    resolution = tuple(args.drawing_resolution)
    drawing_to_csv(result.problem.machine, result.tolerances, drawing, args.overwrite,
                   resolution=resolution)
    print(f"drawing tolerances written to {drawing}, "
          f"{drawing_check_text(result, resolution, targets=targets)}")


def changes_text(result, top: int = 10) -> str:
    """The ``top`` largest changes from the initial allocation, in the machine file's
    units with ISO 230-1 symbols and plain names."""
    problem = result.problem
    table = tolerance_table(problem.machine, problem.reference, result.tolerances)
    order = table["change"].abs().sort_values(ascending=False, kind="stable").index[:top]
    shown = shown_tolerance_table(problem.machine, problem.reference,
                                  result.tolerances).loc[order]
    return (f"\nlargest changes from the initial allocation ({top} of {len(table)}; "
            f"tolerances in the machine file's units):\n{shown.to_string(index=False)}")


def run_catalogue(args) -> int:
    """``--catalogue``: everything checked first, then the certified cheapest choice."""
    for option, given in (("--bounds", args.bounds is not None), ("--lock", bool(args.lock)),
                          ("--method gwo", args.method != "exact"),
                          ("--workspace continuous", args.workspace == "continuous"),
                          ("--drawing", args.drawing is not None)):
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
    catalogue = options.read_catalogue(args.catalogue, machine)
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


def run_yield(args) -> int:
    """``--yield Y``: everything checked first, then :func:`allocation.allocate_for_yield`."""
    for option, given in (("--target", args.target is not None),
                          ("--side one_sided", args.side != "two_sided"),
                          ("--lock", bool(args.lock)), ("--method gwo", args.method != "exact"),
                          ("--catalogue", args.catalogue is not None),
                          ("--tolerances", args.tolerances is not None),
                          ("--tolerances-out", args.tolerances_out is not None)):
        if given:
            raise InputError(f"{option} does not apply with --yield: the machine yield is "
                             f"the share of built machines with every output inside its "
                             f"limit (two-sided) at every pose, and the per-output targets "
                             f"are chosen by the search")
    if args.workspace == "continuous":
        raise InputError("--workspace continuous does not apply with --yield: the machine "
                         "yield is simulated on the --points grid (--workspace grid, the "
                         "default with --yield)")
    bounds = options.check_bounds(args.bounds)
    out = options.destination(args.out, args.overwrite)
    drawing = drawing_destination(args, out)
    executor, where = yield_executor(args)
    machine = options.machine(args)
    why = not_log_concave(machine, machine.profile, machine.distribution)
    if args.bound_machines is not None and why is not None:
        raise InputError(f"--bound-machines: {why}; the lower bound rests on the yield's "
                         f"log-concavity, which holds for independent normal errors "
                         f"constant along travel")
    if args.convex_machines is not None and args.convex_steps is None:
        raise InputError("--convex-machines sizes the gradient of --convex-steps: give "
                         "--convex-steps too")
    with executor as client:
        options.say(f"allocating for machine yield {args.yield_target:g} on the "
                    f"{args.points}-point grid, {options.box_words(machine, bounds)}, profile "
                    f"{machine.profile}, {args.machines:,} built machines per sample (design, "
                    f"calibration and verification), simulated {where}")
        result = allocate_for_yield(machine, args.yield_target, points=args.points,
                                    bounds=bounds, machines=args.machines, seed=args.seed,
                                    executor=client, convex_steps=args.convex_steps or 0,
                                    convex_machines=args.convex_machines)
    print(describe_yield(result))
    print(changes_text(result))
    write_files(args, result, out, drawing, targets=False)
    if args.bound_machines is not None:
        options.say(f"the log-concave lower bound on {args.bound_machines:,} machines")
        bound = log_concave_bound(result, machines=args.bound_machines, steps=1,
                                  seed=args.seed)
        print(f"\n{bound.text(result.initial_cost)}: gap "
              f"{display.percentage_text(1 - bound.bound / result.cost, bound='upper')} "
              f"of the cost")
    return 0


def add_yield_bracket(parser) -> None:
    """``--convex-steps``, ``--convex-machines`` and ``--bound-machines``: the convex steps
    of ``--yield``'s search and its lower bound at 95 % confidence."""
    parser.add_argument("--convex-steps", type=options.positive_int, default=None,
                        metavar="S",
                        help="with --yield: S steps of the convex problem from the search's "
                             "allocation (normal reading, no item correlation, profile "
                             "constant; docs/yield-allocation.md), kept when cheaper once "
                             "calibrated (default none)")
    parser.add_argument("--convex-machines", type=options.positive_int, default=None,
                        metavar="N",
                        help="with --convex-steps: machines of their gradient (default 5 × "
                             "--machines)")
    parser.add_argument("--bound-machines", type=options.positive_int, default=None,
                        metavar="N",
                        help="with --yield: also the lower bound at 95%% confidence from "
                             "the yield's log-concavity, on N machines (e.g. 50000; same "
                             "conditions as --convex-steps)")


def add_yield_executor(parser) -> None:
    """``--executor``, ``--workers`` and ``--scheduler``: where ``--yield`` simulates its
    built machines (as ``precrel sweep`` runs its tasks)."""
    parser.add_argument("--executor", choices=YIELD_EXECUTORS, default=None,
                        help="with --yield: simulate the built machines here (serial, the "
                             "default) or on Dask (dask: a local cluster of --workers "
                             "workers, or the scheduler at --scheduler); the result printed "
                             "and written is the same")
    parser.add_argument("--workers", type=options.positive_int, default=None, metavar="N",
                        help="with --executor dask: workers of the local Dask cluster "
                             "(default 2)")
    parser.add_argument("--scheduler", default=None, metavar="ADDRESS",
                        help="with --yield: simulate the built machines on the running Dask "
                             "scheduler at ADDRESS, e.g. tcp://10.0.0.5:8786 (--executor "
                             "dask implied)")


def yield_executor(args):
    """The context of ``--yield``'s Dask client (None: here) and where it simulates, in
    words, after checking that ``--executor``, ``--workers`` and ``--scheduler`` go
    together."""
    dask = args.executor == "dask" or (args.executor is None and args.scheduler is not None)
    if args.scheduler is not None and not dask:
        raise InputError(f"--scheduler needs --executor dask (or no --executor); got "
                         f"--executor {args.executor}")
    if args.workers is not None and not dask:
        raise InputError("--workers needs --executor dask: it sizes the local Dask cluster")
    if args.workers is not None and args.scheduler is not None:
        raise InputError(f"--workers sizes a local Dask cluster; the scheduler at --scheduler "
                         f"{args.scheduler} has its own workers: give one of the two")
    if not dask:
        return contextlib.nullcontext(), "here"
    if args.scheduler is not None:
        return (options.dask_client(args.scheduler, option="--scheduler"),
                f"on the Dask scheduler at {args.scheduler}")
    return (options.dask_client(workers=args.workers),
            f"on a local Dask cluster of {args.workers or options.DASK_WORKERS} workers")


def describe_yield(result) -> str:
    """The model (profile, reading, grid, box), the result's findings
    (:meth:`allocation.YieldAllocation.finding_lines`) and the search's size."""
    return "\n".join([
        f"machine yield target {result.yield_target:g}: profile {result.profile}; "
        f"{options.reading_text(result.problem.machine)}; workspace: the {result.points}-point "
        f"grid ({len(result.problem.poses):,} poses); box {result.problem.box_text()}",
        *result.finding_lines(),
        f"search: {result.evaluations} candidates on {result.machines:,} design machines "
        f"(aimed at yield {result.design_yield_target:.4f} there), seed {result.seed}"])


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
             f"{display.percentage_text(result.cost / initial)} of the initial allocation "
             f"({initial:.6g}); "
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
                  display.ratio_columns(requirement_table(result)).to_string()]
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
