"""``precrel identify MACHINE.toml --measurements meas.csv``: a built machine's errors from its
measurements, with their posterior uncertainty."""

from __future__ import annotations

from reliability.measured.identification import identify
from reliability.measured.identification_files import IDENTIFICATION_FILES
from reliability.measured.measurement_files import read_measurements

from . import options

#: The files written into ``--out DIR``.
RESULT_FILES = IDENTIFICATION_FILES


def add_parser(subparsers):
    parser = subparsers.add_parser(
        "identify", help="identify a built machine's errors from its measurements",
        description="A linear-Gaussian Bayesian update of every geometric error (prior mean "
                    "0, sigma = t/3 of the allocation in force) from the readings of a "
                    "measurement file (docs/measurements.md), each run's set-up estimated "
                    "with a flat prior. Prints the rank and condition of the information "
                    "about the errors, the combinations the readings cannot tell apart and "
                    "a chi2 check of the readings against the model.")
    options.add_machine(parser)
    options.add_measurements(parser, required=True)
    options.add_tolerances(parser)
    options.add_profile(parser)
    parser.add_argument("--iterate", action="store_true",
                        help="re-linearise at the posterior mean on the exact chain "
                             "(Gauss-Newton) and say how much that changed")
    options.add_out(parser, "folder", f"write {', '.join(RESULT_FILES)} into DIR (profiles.csv "
                                      f"and coefficients.npz under a gp profile)")
    options.add_overwrite(parser)
    return parser


def run(args) -> int:
    out = None if args.out is None else options.destination(
        args.out, args.overwrite, folder=True, markers=RESULT_FILES)
    machine = options.machine(args)
    measurements = read_measurements(args.measurements, machine)
    tolerances = None if args.tolerances is None else \
        options.read_tolerances(args.tolerances, machine)
    result = identify(machine, measurements, tolerances=tolerances,
                      profile=options.identified_profile(machine), iterate=args.iterate)
    source = "initial allocation" if args.tolerances is None else args.tolerances
    model = "on the exact chain at the posterior mean" if args.iterate else \
        "first order at zero errors"
    print(f"Identification of {machine.name!r} from {args.measurements}, prior sigma = t/3 "
          f"of the {source}; {model}.\n")
    print(result.summary())
    if out is not None:
        written = result.save(out, overwrite=args.overwrite)
        print(f"\nwritten {', '.join(written)} into {out}")
    return 0
