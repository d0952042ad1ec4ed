"""``precrel sensitivity MACHINE.toml``: Sobol indices of each output at a pose and, with
``--yield-gradient``, what each tolerance buys in machine yield (docs/sensitivity.md)."""

from __future__ import annotations

import numpy as np

from reliability.basics.errors import InputError
from reliability.basics.files import write_csv
from reliability.basics.streams import sensitivity_stream, spawn
from reliability.sampling.machine_yield import YieldModel
from reliability.sampling.sobol import DEFAULT_SAMPLES, sobol_indices
from reliability.sampling.yield_sensitivity import yield_sensitivity

from . import options

#: Files of ``--out``; an earlier one marks an earlier result.
OUTPUT_FILES = ("sobol.csv", "yield_sensitivity.csv")


def add_parser(subparsers):
    parser = subparsers.add_parser(
        "sensitivity", help="Sobol indices at a pose, and d yield / d ln t of every item",
        description="Sobol first-order and total indices of each output on the exact chain "
                    "(at --pose, else at each output's worst grid pose) beside the FOSM "
                    "variance shares; with --yield-gradient, the change of the machine yield per "
                    "unit of ln t of every item and group of indistinguishable items.")
    options.add_machine(parser)
    options.add_tolerances(parser)
    parser.add_argument("--pose", metavar="AXIS=V,...", default=None,
                        help="one pose for every output, each axis as NAME=VALUE in mm or "
                             "degrees, e.g. C=0,X=400,Z=-100 (default: each output's worst "
                             "pose of the --points grid)")
    parser.add_argument("--yield-gradient", dest="with_yield", action="store_true",
                        help="also d yield / d ln t of every item (score function on the "
                             "yield's draws; central differences under the truncated "
                             "reading)")
    options.add_deprecated(parser, "--yield", "--yield-gradient", dest="with_yield",
                           nargs=0, const=True)
    options.add_yield_model(parser)
    parser.add_argument("--sobol-samples", dest="samples", type=options.positive_int,
                        default=DEFAULT_SAMPLES, metavar="N",
                        help=f"rows of each Sobol sample (default {DEFAULT_SAMPLES})")
    options.add_deprecated(parser, "--samples", "--sobol-samples", dest="samples",
                           type=options.positive_int, metavar="N")
    options.add_points(parser)
    options.add_seed(parser)
    options.add_out(parser, "folder", "write sobol.csv (and with --yield-gradient "
                                      "yield_sensitivity.csv) into DIR")
    options.add_overwrite(parser)
    return parser


def run(args) -> int:
    out = None if args.out is None else options.destination(
        args.out, args.overwrite, folder=True, markers=OUTPUT_FILES)
    machine = options.machine(args)
    t = machine.initial_allocation if args.tolerances is None else \
        options.read_tolerances(args.tolerances, machine)
    pose = None if args.pose is None else parse_pose(machine, args.pose)
    sobol_rng, yield_rng = spawn(args.seed, 1)[0], sensitivity_stream(args.seed)
    options.say("Sobol indices on the exact chain")
    sobol = sobol_indices(machine, t, pose, samples=args.samples,
                          points=args.points, rng=sobol_rng)
    where = "at " + options.pose_text(machine, pose) if pose is not None else \
        f"at each output's worst pose of the {args.points}-point grid"
    print(f"{machine.name!r} {where}; {options.reading_text(machine)}")
    print(sobol.summary())
    written = {"sobol.csv": sobol.to_frame()}
    if args.with_yield:
        options.say(f"d yield / d ln t on {args.machines} built machines")
        model = YieldModel(machine, points=args.points)
        result = yield_sensitivity(model, t, machines=args.machines, rng=yield_rng)
        print(f"\nmachine yield under profile {model.profile}, {model.workspace}")
        print(result.summary())
        written["yield_sensitivity.csv"] = result.to_frame()
    if out is not None:
        out.mkdir(exist_ok=True)
        for name, frame in written.items():
            write_csv(frame, out / name, overwrite=args.overwrite, index=False)
        for name in set(OUTPUT_FILES) - set(written):  # an earlier run's, not this one's
            (out / name).unlink(missing_ok=True)
        print(f"\n{', '.join(written)} written to {out}/")
    return 0


def parse_pose(machine, text: str) -> np.ndarray:
    """``--pose NAME=VALUE,...``: every axis once, linear axes in mm, rotary in degrees;
    returned in mm and rad."""
    values = {}
    for part in text.split(","):
        name, _, value = part.partition("=")
        name = name.strip()
        if name not in machine.axes or name in values:
            raise InputError(f"--pose {text!r}: {name!r} is not an axis of the machine or is "
                             f"given twice; expected each of {', '.join(machine.axes)} once")
        try:
            values[name] = float(value)
        except ValueError:
            raise InputError(f"--pose {text!r}: axis {name} needs a number; got "
                             f"{value!r}") from None
    missing = [axis for axis in machine.axes if axis not in values]
    if missing:
        raise InputError(f"--pose {text!r}: missing axes {', '.join(missing)}")
    return np.array([np.radians(values[axis.name]) if axis.kind == "rotary"
                     else values[axis.name] for axis in machine.axis_specs])
