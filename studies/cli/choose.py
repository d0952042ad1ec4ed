"""``precrel choose MACHINE.toml --catalogue CAT.toml --out choice.csv``: the certified
cheapest choice of one catalogue class per component, and beside it the tolerances that
follow from it (``choice.tolerances.csv``, or ``--tolerances-out``). When no choice can
meet the targets, the rows that block it go beside ``--out`` instead
(``choice.blocking.csv``: output, pose as axis positions, load)."""

from __future__ import annotations

import dataclasses

import numpy as np

from allocation import AllocationProblem, CatalogueInfeasibleError, solve_catalogue
from allocation.per_pose.result_files import allocation_to_csv
from reliability.basics.display import axis_units, with_positions
from reliability.basics.errors import InputError
from reliability.basics.files import write_csv
from reliability.model.poses import workspace_grid
from studies.report.writer import SIGNIFICANT

from . import options


def add_parser(subparsers):
    parser = subparsers.add_parser(
        "choose", help="cheapest choice of catalogue classes meeting the targets",
        description="The certified cheapest choice of one class per component of a "
                    "catalogue (docs/catalogue.md) meeting the targets at the --points grid "
                    "poses; items in no component keep their starting tolerances "
                    "(--tolerances, else the initial allocation). Writes the choice (columns "
                    "component, class, price) and beside it the tolerances that follow from "
                    "it (columns error, reference, allocated): choice.csv -> "
                    "choice.tolerances.csv.")
    options.add_machine(parser)
    options.add_input_file(parser, "--catalogue", "the classes to choose among",
                           required=True)
    options.add_out(parser, "file", "choice CSV to write (columns component, class, price); "
                                    "the tolerances go beside it, STEM.tolerances.csv",
                    metavar="CSV", required=True)
    options.add_tolerances(parser)
    add_tolerances_out(parser)
    options.add_side(parser)
    options.add_target(parser)
    options.add_points(parser)
    options.add_study_model(parser)
    options.add_overwrite(parser)
    return parser


def add_tolerances_out(parser) -> None:
    """``--tolerances-out CSV``: where the tolerances of the choice go instead of beside
    ``--out``."""
    parser.add_argument("--tolerances-out", metavar="CSV",
                        help="the tolerances that follow from the choice (columns error, "
                             "reference, allocated) instead of STEM.tolerances.csv beside "
                             "--out")


def run(args) -> int:
    """Everything checked first, then the certified cheapest choice."""
    out = options.destination(args.out, args.overwrite)
    tolerances_out = options.beside_destination(out, "tolerances", args.overwrite,
                                                override=args.tolerances_out,
                                                option="--tolerances-out")
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
    try:
        result = solve_catalogue(problem, catalogue)
    except CatalogueInfeasibleError as error:
        raise InputError(blocked_text(error, problem, options.beside(out, "blocking"),
                                      args.overwrite)) from None
    print(result.summary())
    print(f"workspace: grid — the choice meets the targets at the {len(problem.poses)} poses "
          f"of the {args.points}-point grid (a catalogue choice is made on the grid only)")
    result.to_csv(out, args.overwrite, significant=SIGNIFICANT)
    print(f"\nchoice written to {out}")
    allocation_to_csv(result, tolerances_out, args.overwrite)  # all digits
    print(f"tolerances written to {tolerances_out}")
    return 0


def blocked_text(error, problem, path, overwrite: bool) -> str:
    """The refusal of an infeasible catalogue, its blocking rows written to ``path`` (output,
    pose as axis positions, load) unless an earlier file is there without ``overwrite``."""
    if error.blocking.empty:
        return str(error)
    machine = problem.machine
    table = with_positions(error.blocking, machine.axes, axis_units(machine))
    if path.exists() and not overwrite:
        return f"{error} (not written: {path} exists; pass --overwrite)"
    write_csv(table, path, overwrite, index=False, float_format=f"%.{SIGNIFICANT}g")
    return f"{error} (listed in {path})"
