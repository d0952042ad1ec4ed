"""``precrel life MACHINE.toml --until YEARS --out DIR``: accuracy over time for a machine
file with a ``[drift]`` table (docs/over-time.md). Writes :data:`FILES` into ``DIR``."""

from __future__ import annotations

import time

from reliability.basics.errors import InputError
from reliability.basics.files import SIGNIFICANT, write_csv
from reliability.compensation.compensation_plans import read_compensation_plan
from reliability.life.life_yield import DEFAULT_LIFE_MACHINES
from studies.report.life_section import life_figure
from studies.workflows.life_study import LifeStudy, life_study

from . import options

#: What ``--out DIR`` holds.
FILES = ("life.csv", "life_summary.json", "life.png")


def add_parser(subparsers):
    parser = subparsers.add_parser(
        "life", help="reliability and machine yield over a service life ([drift] table)",
        description="Each output's probability of staying within its limit at every age up "
                    "to each one, at its worst grid pose (first order), the machine yield "
                    "over the life (built machines with drawn drift on the exact chain) "
                    "and the recalibration interval: the age at which that yield falls "
                    "below --yield.")
    options.add_machine(parser)
    options.add_tolerances(parser)
    parser.add_argument("--until", type=options.positive_float, required=True,
                        metavar="YEARS", help="the horizon in years")
    parser.add_argument("--step", type=options.positive_float, default=0.5,
                        metavar="YEARS", help="the age grid's step (default %(default)s)")
    options.add_yield(parser, "level", "the level below which the machine is recalibrated "
                                       "(default: the smallest of the machine file's "
                                       "targets)")
    options.add_input_file(parser, "--compensation", "a compensation plan (docs/compensation.md): "
                           "also the intervals between recalibrations of machines re-measured "
                           "and re-compensated under it")
    parser.add_argument("--check", type=options.positive_int, default=None, metavar="N",
                        help="also N built machines on the exact chain at each output's "
                             "worst pose over the whole life, beside the first-order life "
                             "reliability (and after compensation, with --compensation)")
    options.add_points(parser)
    options.add_machines(parser, DEFAULT_LIFE_MACHINES)
    options.add_seed(parser)
    options.add_out(parser, "folder", "write " + ", ".join(FILES) + " into this folder",
                    required=True)
    options.add_overwrite(parser)
    options.add_quiet(parser)
    return parser


def run(args) -> int:
    if args.step > args.until:
        raise InputError(f"--step {args.step:g}: must not exceed --until {args.until:g}")
    out = options.destination(args.out, args.overwrite, folder=True, markers=FILES)
    machine = options.machine(args)
    if machine.drift is None:
        raise InputError(f"{args.machine}: no [drift] table; life needs one (how the errors "
                         f"change with age, docs/over-time.md)")
    t = machine.initial_allocation if args.tolerances is None else \
        options.read_tolerances(args.tolerances, machine)
    plan = None if args.compensation is None else \
        read_compensation_plan(args.compensation, machine)
    options.say(f"life of {machine.name!r} to {args.until:g} years: first order at every "
                f"grid pose, then {args.machines:,} built machines on the exact chain")
    start = time.perf_counter()
    study = life_study(machine, t, until=args.until, step=args.step, level=args.level,
                       points=args.points, machines=args.machines, seed=args.seed,
                       plan=plan, check=args.check or 0)
    seconds = time.perf_counter() - start
    out.mkdir(exist_ok=True)
    write_csv(study.to_frame(), out / "life.csv", args.overwrite,
              float_format=f"%.{SIGNIFICANT}g", index=False)
    study.save(out / "life_summary.json", overwrite=args.overwrite)
    LifeStudy.load(out / "life_summary.json")
    _save_figure(life_figure(study), out / "life.png", args.overwrite)
    source = "the initial allocation" if args.tolerances is None else \
        f"the tolerances of {args.tolerances}"
    print(f"Life of {source}; {options.reading_text(machine)}\n")
    print(study.summary())
    print(f"\nwritten {', '.join(FILES)} to {out}/ ({seconds:.1f} s)")
    return 0


def _save_figure(figure, path, overwrite: bool) -> None:
    import matplotlib.pyplot as plt

    if path.exists() and not overwrite:
        raise InputError(f"--out: {path} exists; pass --overwrite to replace it")
    figure.savefig(path, dpi=120)
    plt.close(figure)
