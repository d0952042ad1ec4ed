"""``precrel allocate MACHINE.toml --out a.csv``: the cheapest allocation meeting the targets,
and beside it the tolerances to write on drawings (``a.drawing.csv``, or ``--drawing``);
with ``--yield Y`` the cheapest allocation found whose machine yield reaches Y, with its
cost bracket; with ``--compensation PLAN.toml`` the cheapest after compensation. Which
options go with which of these modes is declared once, :data:`MODE_OPTIONS`."""

from __future__ import annotations

import argparse
import contextlib
from pathlib import Path

import pandas as pd

from allocation import AllocationProblem, allocate_for_yield
from allocation.per_pose.continuous import check_continuous, solve_continuous
from allocation.per_pose.elasticity import requirement_text
from allocation.per_pose.result_files import (DRAWING_RESOLUTION, allocation_to_csv, cost_shares_text, cost_units_text,
                                     drawing_check_text, drawing_to_csv, gap_text,
                                     nearly_free_text, written_cost_text,
                                     written_tolerances)
from allocation.machine_yield.yield_dual import not_log_concave
from reliability.basics import display
from reliability.basics.errors import InputError
from reliability.model.poses import workspace_grid
from reliability.model.work_zone import grid_text
from studies.report.machine_sections import shown_tolerance_table, tolerance_table
from studies.report.writer import SIGNIFICANT

from . import allocate_life, choose, compensate, options

#: The modes of ``allocate``: per-pose targets (the default), ``--yield``,
#: ``--compensation`` and the deprecated ``--catalogue`` (now ``precrel choose``).
TARGETS, YIELD, COMPENSATION, CATALOGUE = ("per-pose targets", "--yield", "--compensation",
                                           "--catalogue")


def _given(dest: str):
    return lambda args: getattr(args, dest) is not None


#: Which options go with which mode: (the option as its refusal names it, whether it is
#: given, the modes it goes with). Options not listed go with every mode.
MODE_OPTIONS = (
    ("--yield", _given("yield_target"), (YIELD,)),
    ("--life", _given("life"), (TARGETS,)),
    ("--catalogue", _given("catalogue"), (CATALOGUE,)),
    ("--target", _given("target"), (TARGETS, COMPENSATION, CATALOGUE)),
    ("--side one_sided", lambda args: args.side == "one_sided",
     (TARGETS, COMPENSATION, CATALOGUE)),
    ("--lock", lambda args: bool(args.lock), (TARGETS, COMPENSATION)),
    ("--method gwo", lambda args: args.method == "gwo", (TARGETS,)),
    ("--workspace continuous", lambda args: args.workspace == "continuous", (TARGETS,)),
    ("--time-limit", _given("time_limit"), (TARGETS,)),
    ("--bounds", _given("bounds"), (TARGETS, YIELD, COMPENSATION)),
    ("--profile", _given("profile"), (YIELD,)),
    ("--executor", _given("executor"), (YIELD,)),
    ("--workers", _given("workers"), (YIELD,)),
    ("--scheduler", _given("scheduler"), (YIELD,)),
    ("--convex-steps", _given("convex_steps"), (YIELD,)),
    ("--convex-machines", _given("convex_machines"), (YIELD,)),
    ("--bound-machines", _given("bound_machines"), (YIELD,)),
    ("--verbose", lambda args: args.verbose, (YIELD,)),
    ("--drawing", _given("drawing"), (TARGETS, YIELD)),
    ("--tolerances", _given("tolerances"), (CATALOGUE,)),
    ("--tolerances-out", _given("tolerances_out"), (CATALOGUE,)),
)
#: Why the options of other modes do not apply in a mode, said in the refusal.
MODE_REASONS = {
    YIELD: "the machine yield is the share of built machines with every output inside its "
           "limit (two-sided) at every pose of the --points grid, and the per-output "
           "targets are chosen by the search",
    COMPENSATION: "the allocation after compensation meets the per-pose targets (the "
                  "machine file's, or --target) at the --points grid poses",
    CATALOGUE: "classes are used as given, items in no component keep their starting "
               "tolerances and the choice holds on the grid poses",
}
#: Where to go instead, for an option refused in a mode.
MODE_INSTEAD = {("--yield", COMPENSATION): "; an allocation's machine yield after "
                "compensation is printed by verify MACHINE.toml --tolerances CSV "
                "--compensation PLAN.toml"}


def add_parser(subparsers):
    parser = subparsers.add_parser(
        "allocate", help="cheapest allocation meeting the targets (Eq. 34)",
        description="Solve the allocation problem of Eq. (34) over the continuous "
                    "workspace (default: the grid's optimum with the certificate's worst "
                    "poses added until every output is certified, docs/continuous-"
                    "allocation.md) or at every pose of the grid (--workspace grid): "
                    "the certified optimum (exact) or, on the grid, the Grey Wolf Optimiser "
                    "(gwo). Prints the cost relative to the initial allocation, what binds "
                    "and the elasticity of each requirement; writes the allocation CSV "
                    "(columns error, reference, allocated) and beside it the drawing file "
                    "(a.csv -> a.drawing.csv). With --yield Y: the cheapest allocation "
                    "found whose machine yield (share of built machines within every limit "
                    "at every grid pose, under --profile) reaches Y, verified on fresh "
                    "machines, between a certified lower bound on the cost and the naive "
                    "method (docs/yield-allocation.md); --scheduler ADDRESS simulates the "
                    "built machines on a running Dask cluster, with the same result. The "
                    "cheapest choice of catalogue classes is 'precrel choose'.")
    options.add_machine(parser)
    options.add_out(parser, "file", "allocation CSV to write (columns error, reference, "
                                    "allocated); the drawing file goes beside it, "
                                    "STEM.drawing.csv", metavar="CSV", required=True)
    options.add_side(parser)
    options.add_target(parser)
    options.add_points(parser)
    options.add_study_model(parser)
    options.add_bounds(parser)
    options.add_workspace(parser)
    options.add_time_limit(parser)
    parser.add_argument("--lock", nargs="+", default=(), metavar="NAME",
                        help="errors held at their initial tolerance (e.g. X.dx)")
    parser.add_argument("--method", choices=("exact", "gwo"), default="exact",
                        help="certified convex optimum (default) or the paper's GWO")
    options.add_seed(parser)
    parser.add_argument("--life", type=options.positive_float, metavar="T",
                        help="tolerances for a service life of T years (> 0): every output "
                             "within its limit at every pose and every age of [0, T] under "
                             "the machine file's [drift] (kind linear), beside the cost for "
                             "acceptance only; writes STEM.life.csv too "
                             "(docs/life-allocation.md)")
    options.add_yield(parser, "yield_target", "allocate for it instead of per-pose targets "
                                              "(with --profile, --machines, --executor)")
    options.add_yield_model(parser)
    options.add_executor(parser)
    add_yield_bracket(parser)
    options.add_deprecated(parser, "--catalogue", "precrel choose", dest="catalogue",
                           metavar=options.INPUT_FILES["--catalogue"][0])
    options.add_tolerances(parser)
    choose.add_tolerances_out(parser)
    parser.add_argument("--drawing", metavar="CSV",
                        help="tolerances to write on drawings (columns error, iso, name, "
                             "tolerance, unit; µm and arcsec, rounded down to the "
                             "resolution; --tolerances reads it as it is) instead of "
                             "STEM.drawing.csv beside --out")
    parser.add_argument("--drawing-resolution", nargs=2, type=float, metavar=("UM", "ARCSEC"),
                        default=DRAWING_RESOLUTION,
                        help="resolution of the drawing tolerances in µm and arcsec "
                             "(default 0.1 0.1)")
    options.add_overwrite(parser)
    options.add_quiet(parser)
    compensate.add_allocation_option(parser)
    return parser


def mode(args) -> str:
    """The mode the options ask for (``--compensation`` before ``--yield`` before the
    deprecated ``--catalogue``)."""
    if args.compensation is not None:
        return COMPENSATION
    if args.yield_target is not None:
        return YIELD
    return CATALOGUE if args.catalogue is not None else TARGETS


def check_mode(args) -> str:
    """The mode, after refusing (before any work) every option of :data:`MODE_OPTIONS`
    given that does not go with it; the refusal names the option and the mode."""
    chosen = mode(args)
    for option, given, modes in MODE_OPTIONS:
        if chosen in modes or not given(args):
            continue
        if chosen == TARGETS:
            raise InputError(f"{option} is used with {' or '.join(modes)} only")
        raise InputError(f"{option} does not apply with {chosen}: {MODE_REASONS[chosen]}"
                         f"{MODE_INSTEAD.get((option, chosen), '')}")
    return chosen


def run(args) -> int:
    chosen = check_mode(args)
    if chosen == COMPENSATION:
        return compensate.run_allocation(args)
    if chosen == YIELD:
        return run_yield(args)
    if chosen == CATALOGUE:
        return choose.run(args)
    if args.life is not None:
        return allocate_life.run(args)
    bounds = options.check_bounds(args.bounds)
    out = options.destination(args.out, args.overwrite)
    drawing = options.beside_destination(out, "drawing", args.overwrite,
                                         override=args.drawing, option="--drawing")
    machine = options.allocation_machine(args)
    workspace = options.workspace(args)
    limits = options.loop_limits(args, workspace)
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
    if workspace != "continuous":
        result = solve(problem, args.method, args.seed)
        print(describe(result, f"workspace: grid — the targets hold at the "
                               f"{len(problem.poses)} poses of the {args.points}-point grid "
                               f"(not certified between them)"))
        print(changes_text(result))
        write_files(args, result, out, drawing)
        return 0
    options.say(f"certifying over the continuous workspace (rtol {args.rtol:g}"
                + (f", time limit {args.time_limit:g} s" if limits else "") + ")")
    continuous = solve_continuous(problem, rtol=args.rtol,
                                  progress=lambda text: options.say(f"  {text}"), **limits)
    print(describe(continuous.result, continuous.summary()))
    print(changes_text(continuous.result))
    write_files(args, continuous.result, out, drawing,
                verdict=None if continuous.certified else continuous.reason)
    return options.stop_code(continuous)


def write_files(args, result, out: Path, drawing: Path, *, targets: bool = True,
                verdict: str | None = None) -> None:
    """The allocation CSV and the drawing file, each with a line on what it holds (with
    ``targets``, whether the drawing meets the per-pose targets of the result's problem).

    ``verdict``: why an allocation of the continuous workspace is not certified
    (:func:`~allocation.per_pose.result_files.allocation_to_csv`'s ``not_certified``)."""
    allocation_to_csv(result, out, args.overwrite, significant=SIGNIFICANT,
                      not_certified=verdict)
    print(f"\nallocation written to {out}"
          + ("" if verdict is None else " (NOT certified: see its columns certified, reason)")
          + f", {written_cost_text(result)}")
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
                                  written_tolerances(result)).loc[order]
    return (f"\nlargest changes from the initial allocation ({top} of {len(table)}; "
            f"tolerances in the machine file's units):\n{shown.to_string(index=False)}")


def run_yield(args) -> int:
    """``--yield Y``: everything checked first, then :func:`allocation.allocate_for_yield`
    (one convex step and the log-concave bound by default where the theorem holds); prints
    one lower bound and one gap (every bound and stage with ``--verbose``) and writes the
    allocation, the drawing and the saved result (``a.summary.json`` beside ``a.csv``)."""
    bounds = options.check_bounds(args.bounds)
    out = options.destination(args.out, args.overwrite)
    drawing = options.beside_destination(out, "drawing", args.overwrite,
                                         override=args.drawing, option="--drawing")
    summary = options.destination(summary_path(out), args.overwrite)
    executor, where = yield_executor(args)
    machine = options.machine(args)
    why = not_log_concave(machine, machine.profile, machine.distribution)
    if args.bound_machines is not None and why is not None:
        raise InputError(f"--bound-machines: {why}; the lower bound rests on the yield's "
                         f"log-concavity, which holds for independent normal errors, each "
                         f"scaled by its own tolerance")
    if args.convex_machines is not None and args.convex_steps == 0:
        raise InputError("--convex-machines sizes the gradient of the convex steps: not "
                         "with --convex-steps 0")
    with executor as client:
        options.say(f"allocating for machine yield {args.yield_target:g} on the "
                    f"{args.points}-point grid, {options.box_words(machine, bounds)}, profile "
                    f"{machine.profile}, {args.machines:,} built machines per sample (design, "
                    f"calibration and verification), simulated {where}")
        result = allocate_for_yield(machine, args.yield_target, points=args.points,
                                    bounds=bounds, machines=args.machines, rng=args.seed,
                                    executor=client,
                                    convex_steps=args.convex_steps,
                                    convex_machines=args.convex_machines,
                                    bound_machines=args.bound_machines)
    print(describe_yield(result, args.verbose))
    print(changes_text(result))
    write_files(args, result, out, drawing, targets=False)
    result.save(summary, overwrite=args.overwrite)
    print(f"result written to {summary}: lower bound ({result.lower_bound_kind}), gap "
          f"{display.percentage_text(result.gap_of_cost, bound='upper')} of the cost")
    return 0


def summary_path(out: Path) -> Path:
    """The saved result beside the ``--out`` file: ``a.csv`` -> ``a.summary.json``."""
    return out.with_name(f"{out.stem}.summary.json")


def steps(text: str) -> int:
    """An integer >= 0."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected an integer >= 0, got {text!r}")
    return value


def add_yield_bracket(parser) -> None:
    """``--convex-steps``, ``--convex-machines``, ``--bound-machines`` and ``--verbose``:
    the convex steps of ``--yield``'s search, its lower bound at 95 % confidence and how
    much of the bracket is printed."""
    parser.add_argument("--convex-steps", type=steps, default=None, metavar="S",
                        help="with --yield: S steps of the convex problem from the search's "
                             "allocation (normal reading, no item correlation; "
                             "docs/yield-allocation.md), kept when cheaper once calibrated "
                             "(default 1 under profile constant, 0 under the others; 0: "
                             "none)")
    parser.add_argument("--convex-machines", type=options.positive_int, default=None,
                        metavar="N",
                        help="with --yield: rays of the convex steps' gradient (default 5 × "
                             "--machines)")
    parser.add_argument("--bound-machines", type=options.positive_int, default=None,
                        metavar="N",
                        help="with --yield: rays (crude machines under the profiles "
                             "independent and gp) of each sample of the lower bound at 95%% "
                             "confidence from the yield's log-concavity (default 10 × "
                             "--machines under profile constant, none under the others; "
                             "same conditions as --convex-steps)")
    parser.add_argument("--verbose", action="store_true",
                        help="with --yield: also every other bound (row, pose chain, the "
                             "log-concave estimate) and every stage's cost")


def yield_executor(args):
    """The context of ``--yield``'s Dask client (None: here) and where it simulates, in
    words (:func:`options.executor_kind`; no process pool)."""
    kind = options.executor_kind(args, ("serial", "dask"), " with --yield")
    if kind == "serial":
        return contextlib.nullcontext(), "here"
    if args.scheduler is not None:
        return (options.dask_client(args.scheduler, option="--scheduler"),
                f"on the Dask scheduler at {args.scheduler}")
    return (options.dask_client(workers=args.workers),
            f"on a local Dask cluster of {args.workers or options.DASK_WORKERS} workers")


def describe_yield(result, verbose: bool = False) -> str:
    """The model (profile, reading, grid, box), the result's findings
    (:meth:`allocation.YieldAllocation.finding_lines`, every bound and stage with
    ``verbose``) and the search's size."""
    return "\n".join([
        f"machine yield target {result.yield_target:g}: profile {result.profile}; "
        f"{options.reading_text(result.problem.machine)}; outputs in the "
        f"{result.problem.machine.frame} frame; workspace: the "
        f"{grid_text(result.problem.machine, result.points, len(result.problem.poses))}; box "
        f"{result.problem.box_text()}",
        *result.finding_lines(verbose),
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
                  requirement_text(result).to_string()]
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
