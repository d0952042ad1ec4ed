"""``precrel compensate MACHINE.toml --identification DIR --out DIR``: compensation tables of a
measured machine (one CSV per axis and ``assembly.csv``, docs/compensation.md), and what the
machine keeps after compensation."""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd

from allocation import AllocationProblem
from allocation.per_pose.compensated import allocate_compensated
from allocation.per_pose.result_files import allocation_to_csv
from reliability.basics import display
from reliability.basics.errors import InputError
from reliability.basics.statistics import binomial_interval
from reliability.basics.streams import extra_stream
from reliability.compensation.compensation_plans import read_compensation_plan
from reliability.compensation.compensation_files import table_file_names, write_compensation
from reliability.compensation.residual import measured_residual
from reliability.compensation.tables import (DEFAULT_SPACING_DEG, DEFAULT_SPACING_MM,
                                             compensation_tables)
from reliability.model.poses import workspace_grid
from studies.report.compensation_section import compensation_section
from studies.report.writer import SIGNIFICANT
from studies.workflows.compensation_verification import verify_compensation

from . import options

#: Grid of the residual printed for a machine identified here.
RESIDUAL_GRID = 3


def add_parser(subparsers):
    parser = subparsers.add_parser(
        "compensate", help="compensation tables of a measured machine",
        description="Write the compensation tables of a measured machine: per axis a CSV "
                    "with position_mm or position_deg at the spacing over the stroke and "
                    "one column per motion error named by its ISO 230-1 symbol (mm, rad), "
                    "and assembly.csv (error, iso, value) of the constant errors; each value "
                    "is the identified error, the correction its negative "
                    "(docs/compensation.md). From --identification DIR (the folder of "
                    "precrel identify --out) or --measurements meas.csv (identified here); "
                    "prints this machine's outputs before and after compensation.")
    options.add_machine(parser)
    options.add_as_measured(parser, required=True)
    options.add_tolerances(parser)
    options.add_profile(parser)
    options.add_out(parser, "folder", "folder of the tables (one CSV per axis and "
                                      "assembly.csv)", required=True)
    parser.add_argument("--spacing-mm", type=float, default=DEFAULT_SPACING_MM, metavar="H",
                        help=f"spacing along linear axes (default {DEFAULT_SPACING_MM:g} mm)")
    parser.add_argument("--spacing-deg", type=float, default=DEFAULT_SPACING_DEG,
                        metavar="H",
                        help=f"spacing about rotary axes (default {DEFAULT_SPACING_DEG:g} "
                             f"degrees)")
    parser.add_argument("--items", nargs="+", metavar="NAME",
                        help="errors to table (names or ISO symbols; default all)")
    parser.add_argument("--max-correction-mm", type=float, metavar="X",
                        help="the table's range for translations (mm)")
    parser.add_argument("--max-correction-rad", type=float, metavar="X",
                        help="the table's range for rotations (rad)")
    options.add_overwrite(parser)
    return parser


def run(args) -> int:
    machine = options.machine(args)
    out = options.destination(args.out, args.overwrite, folder=True,
                              markers=table_file_names(machine))
    for option, given in (("--tolerances", args.tolerances), ("--profile", args.profile)):
        if given is not None and args.measurements is None:
            raise InputError(f"{option} is used with --measurements only (an identification "
                             f"folder already holds its prior and profile)")
    identification = _identification(args, machine)
    tables = compensation_tables(identification, spacing_mm=args.spacing_mm,
                                 spacing_deg=args.spacing_deg, items=args.items,
                                 max_correction_mm=args.max_correction_mm,
                                 max_correction_rad=args.max_correction_rad)
    write_compensation(tables, out, args.overwrite)
    print(f"compensation tables of {machine.name!r}: {len(tables.items)} of "
          f"{machine.n_errors} errors tabled, every {args.spacing_mm:g} mm and "
          f"{args.spacing_deg:g} degrees; written {', '.join(table_file_names(machine))} "
          f"into {out}")
    print("\n" + residual_text(identification, tables))
    return 0


def _identification(args, machine):
    tolerances = None if args.tolerances is None else \
        options.read_tolerances(args.tolerances, machine)
    return options.as_measured_identification(args, machine, tolerances)


def residual_text(identification, tables) -> str:
    """Worst mean and σ of each output before and after compensation on the grid, in the
    machine file's units (mm and rad when it states none), to three significant digits; a
    mean zero to rounding (:func:`~reliability.basics.display.resolved_text`, against the
    sd before) as 0."""
    machine = identification.machine
    poses = workspace_grid(machine, RESIDUAL_GRID)
    before, before_sd = identification.predict(poses, frame=machine.frame)
    mean, sigma = measured_residual(identification, tables, poses)
    units = display.output_people_units(machine.cost_coefficients.units)
    scale = display.in_units(before_sd.max(axis=0), units)
    columns = {"|mean| before": np.abs(before).max(axis=0), "sd before": before_sd.max(axis=0),
               "|mean| after": np.abs(mean).max(axis=0), "sd after": sigma.max(axis=0)}
    frame = pd.DataFrame({"unit": [display.unit_symbol(u) for u in units],
                          "limit": display.tolerance_numbers(machine.limits, units)} | {
        name: [display.resolved_text(v, s, digits=3) for v, s in
               zip(display.in_units(values, units), scale)]
        for name, values in columns.items()}, index=pd.Index(machine.outputs, name="output"))
    return (f"this machine's outputs ({machine.frame} frame) on the {RESIDUAL_GRID}-point "
            f"grid, worst over the poses: posterior mean and sd before compensation, and "
            f"what the tables leave (the sd after adds repeatability and reversal)\n"
            f"{frame.to_string()}")


def add_allocation_option(parser) -> None:
    """``precrel allocate --compensation PLAN.toml``."""
    options.add_input_file(parser, "--compensation",
                           "allocate for machines measured under this plan and compensated, "
                           "on the --points grid; prints the cost with and without "
                           "compensation, its bracket and the items that stay tight (not "
                           "with --yield, --method gwo or --workspace continuous)")


def run_allocation(args) -> int:
    """``allocate --compensation``: the cheapest allocation found after compensation, with
    its certified bracket, written as the allocation CSV (the options checked by
    :func:`studies.cli.allocate.check_mode`)."""
    bounds = options.check_bounds(args.bounds)
    out = options.destination(args.out, args.overwrite)
    machine = options.machine(args)
    if args.target is not None:
        machine = dataclasses.replace(machine, targets=np.full(6, args.target))
    plan = read_compensation_plan(args.compensation, machine)
    options.say(f"building the problem on the {args.points}-point grid, "
                f"{options.box_words(machine, bounds)}")
    problem = AllocationProblem.build(machine, workspace_grid(machine, args.points),
                                      side=args.side, bounds=bounds, locked=tuple(args.lock))
    found = allocate_compensated(problem, plan)
    print(f"allocation for {machine.name!r} measured under {args.compensation} "
          f"({len(plan.runs)} runs) and compensated ({int(plan.tabled.sum())} items tabled, "
          f"every {plan.spacing_mm:g} mm and {plan.spacing_deg:g} degrees); targets at the "
          f"{len(problem.poses)} poses of the {args.points}-point grid, {args.side}\n")
    print(found.summary())
    allocation_to_csv(found.result, out, args.overwrite, significant=SIGNIFICANT)
    print(f"\nallocation written to {out} (no drawing file: its check is of the machine "
          f"without compensation)")
    return 0


#: Extra stream of the compensated machines of ``verify --compensation``.
VERIFY_STREAM = 7
#: Machines of the residual model behind the predicted yield after compensation.
MODEL_MACHINES = 20_000


def add_verification_option(parser) -> None:
    """``precrel verify --compensation PLAN.toml [--compensated-machines N]``."""
    options.add_input_file(parser, "--compensation",
                           "also the results after compensation, for machines measured "
                           "under this plan and compensated: FOSM beside FOSM before, on the "
                           "--points grid, and the yield predicted by the residual model "
                           "beside the yield of --compensated-machines machines measured, "
                           "identified and compensated on the exact chain")
    parser.add_argument("--compensated-machines", type=options.positive_int, default=100,
                        metavar="N",
                        help="machines simulated end to end with --compensation (default 100)")


def verification_text(machine, tolerances, args) -> str:
    """``verify --compensation``: per output the worst FOSM before and after compensation on
    the grid, and the machine yield after compensation, predicted and simulated."""
    plan = read_compensation_plan(args.compensation, machine)
    poses = workspace_grid(machine, args.points)
    rng = extra_stream(args.seed, VERIFY_STREAM)
    options.say(f"{args.compensated_machines} machines measured under {args.compensation}, "
                f"identified and compensated")
    check = verify_compensation(plan, tolerances, poses, args.compensated_machines,
                                MODEL_MACHINES, rng)
    rows = [_yield_line("predicted by the residual model", check.predicted),
            _yield_line("simulated end to end on the exact chain", check.simulated)]
    return (f"after compensation ({args.compensation}: {len(plan.runs)} runs, "
            f"{int(plan.tabled.sum())} items tabled; repeatability and reversal included), "
            f"two-sided, worst over the {len(poses)} poses of the {args.points}-point grid "
            f"(simulated: at the worst pose after compensation, {len(check.simulated)} "
            f"machines)\n"
            f"{check.table.to_string(float_format=lambda v: f'{v:.6g}')}\n"
            f"machine yield after compensation:\n" + "\n".join(rows))


def _yield_line(what, passes) -> str:
    low, high = binomial_interval(int(passes.sum()), len(passes))
    return (f"  {what}: {passes.mean():.4f} "
            f"[{display.probability_bound_text(float(low), upper=False)}, "
            f"{display.probability_bound_text(float(high), upper=True)}] "
            f"({len(passes)} machines)")


def add_report_option(parser) -> None:
    """``precrel report --compensation PLAN.toml``."""
    options.add_input_file(parser, "--compensation",
                           "add an 'After compensation' section: the cheapest allocation for "
                           "machines measured under this plan and compensated, beside the "
                           "one without, what compensation relaxes and what it cannot")


def report_builder(args, machine):
    """The builder of the report's section of ``--compensation`` (the plan read now, so a
    bad plan is refused before any work)."""
    plan = read_compensation_plan(args.compensation, machine)
    return lambda study: compensation_section(study, plan, args.compensation)
