"""``precrel measure MACHINE.toml --plan PLAN.toml --out meas.csv``: what a plan's runs would
read on one machine drawn to an allocation; the drawn truth goes beside it,
``meas.truth.csv`` (or ``--truth``)."""

from __future__ import annotations

from reliability.basics.files import SIGNIFICANT, write_csv
from reliability.basics.streams import generator
from reliability.measured.measurement_files import write_measurements
from reliability.measured.plans import read_plan
from reliability.measured.simulated_measurements import simulate_measurements

from . import options


def add_parser(subparsers):
    parser = subparsers.add_parser(
        "measure", help="simulated measurements of one drawn machine (a plan's runs)",
        description="Draw one machine built to an allocation (errors along travel under the "
                    "profile, tolerances read as the machine file says) and write what the "
                    "runs of PLAN.toml would read on its exact chain, each with its own "
                    "set-up and noise of standard deviation u, as a measurement file "
                    "(docs/measurements.md); the drawn errors and set-ups go beside it: "
                    "meas.csv -> meas.truth.csv.")
    options.add_machine(parser)
    parser.add_argument("--plan", required=True, metavar="PLAN.toml",
                        help="a test file whose tests carry u and u_angle, plus line runs")
    options.add_out(parser, "file", "the measurement file to write; the drawn truth goes "
                                    "beside it, STEM.truth.csv", metavar="meas.csv",
                    required=True)
    parser.add_argument("--truth", metavar="truth.csv",
                        help="the drawn errors and set-ups (item, position, value) instead "
                             "of STEM.truth.csv beside --out")
    options.add_tolerances(parser)
    options.add_profile(parser)
    options.add_seed(parser)
    options.add_overwrite(parser)
    return parser


def run(args) -> int:
    out = options.destination(args.out, args.overwrite)
    truth = options.beside_destination(out, "truth", args.overwrite, override=args.truth,
                                       option="--truth")
    machine = options.machine(args)
    plan = read_plan(args.plan, machine)
    tolerances = None if args.tolerances is None else \
        options.read_tolerances(args.tolerances, machine)
    drawn = simulate_measurements(machine, plan, tolerances, profile=machine.profile,
                                  rng=generator(args.seed))
    write_measurements(drawn.measurements, machine, out, overwrite=args.overwrite)
    write_csv(drawn.truth, truth, overwrite=args.overwrite, index=False,
              float_format=f"%.{SIGNIFICANT + 4}g")
    print(f"{len(drawn.measurements)} readings of {len(plan)} runs on one machine of "
          f"{machine.name!r}, profile {machine.profile}, seed {args.seed}; "
          f"{options.reading_text(machine)}")
    print(f"written {out}\nwritten {truth}")
    return 0
