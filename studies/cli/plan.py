"""``precrel plan MACHINE.toml --candidates PLAN.toml --budget B``: the candidate runs that
best pin down each output's σ at its worst pose, within a budget."""

from __future__ import annotations

import pandas as pd

from reliability.basics.display import UNIT_SCALES, output_people_units, unit_symbol
from reliability.basics.files import atomic_write_text
from reliability.measured.planning import plan_measurements, read_candidates

from . import options


def add_parser(subparsers):
    parser = subparsers.add_parser(
        "plan", help="choose the measurement runs that pin down the limits, within a budget",
        description="From the candidate runs of a plan file (docs/measurements.md; each "
                    "test may carry a cost, default 1) choose, within --budget, the runs "
                    "that most reduce the sum over the six outputs of (posterior sd / "
                    "limit)^2 at each output's worst grid pose: the posterior covariance "
                    "of the identification depends only on where the runs read and their "
                    "u, so no readings are needed. Greedy by gain per cost with lazy "
                    "evaluation, and every affordable subset when there are at most 12 "
                    "candidates; prints what each chosen run adds.")
    options.add_machine(parser)
    parser.add_argument("--candidates", required=True, metavar="PLAN.toml",
                        help="the candidate runs: a plan file whose tests may carry cost")
    parser.add_argument("--budget", required=True, type=options.positive_float, metavar="B",
                        help="total cost the chosen runs may take")
    options.add_tolerances(parser)
    options.add_points(parser)
    options.add_out(parser, "file", "write the chosen runs as a plan file",
                    metavar="CHOSEN.toml")
    options.add_overwrite(parser)
    return parser


def run(args) -> int:
    out = None if args.out is None else options.destination(args.out, args.overwrite)
    machine = options.machine(args)
    candidates = read_candidates(args.candidates, machine)
    tolerances = None if args.tolerances is None else \
        options.read_tolerances(args.tolerances, machine)
    plan = plan_measurements(machine, candidates, args.budget, tolerances=tolerances,
                             points=args.points)
    source = "initial allocation" if args.tolerances is None else args.tolerances
    print(f"Measurement plan for {machine.name!r} from {args.candidates}, prior sigma = t/3 "
          f"of the {source}; worst poses on the {args.points}-point grid, outputs in the "
          f"{machine.frame} frame.\n")
    print(plan.summary())
    print("\ncandidates (alone: share of V with no run that the run removes alone):")
    print(plan.candidate_table().to_string(index=False, float_format="{:.3g}".format))
    print("\neach output's sd at its worst pose:")
    print(output_table(machine, plan).to_string(index=False))
    if out is not None:
        atomic_write_text(out, plan.to_toml(args.candidates), args.overwrite)
        print(f"\nwritten {out}")
    return 0


def output_table(machine, plan) -> pd.DataFrame:
    """Each output's worst pose and its sd with no run, the chosen runs and every
    candidate, in the machine file's units (mm and rad when it states none)."""
    rows = []
    units = output_people_units(machine.cost_coefficients.units)
    for (output, row), unit in zip(plan.outputs.iterrows(), units):
        scale, unit = UNIT_SCALES[unit], unit_symbol(unit)
        rows.append({"output": output, "limit": f"{scale * row['limit']:.4g} {unit}",
                     "worst pose": options.pose_text(machine, row["worst_pose"]),
                     **{name: f"{scale * row[column]:.3g} {unit}" for name, column in
                        (("no run", "prior_sd"), ("chosen", "chosen_sd"),
                         ("every candidate", "all_sd"))}})
    return pd.DataFrame(rows)
