"""``precrel report MACHINE.toml --out DIR``: the whole study of a machine, as a report."""

from __future__ import annotations

from studies.report_extras import EXTRAS

from . import _common


def add_parser(subparsers):
    parser = subparsers.add_parser(
        "report", help="full study of a machine into a folder (tables, figures, report)",
        description="FOSM of the initial allocation, the certified optimum, Monte-Carlo "
                    "verification, CSV tables, figures, report.md, a self-contained "
                    "report.html, summary.json and allocation.csv in DIR.")
    _common.add_machine(parser)
    parser.add_argument("--out", required=True, metavar="DIR", help="output folder")
    _common.add_monte_carlo(parser)
    _common.add_points(parser)
    _common.add_side(parser)
    _common.add_bounds(parser)
    parser.add_argument("--skip", nargs="+", default=(), choices=EXTRAS, metavar="SECTION",
                        help="leave out optional sections: " + ", ".join(EXTRAS)
                             + " (default: include all)")
    parser.add_argument("--overwrite", action="store_true",
                        help="replace an earlier report in DIR (other files are left alone)")
    return parser


def run(args) -> int:
    from studies import pipeline
    from studies.machine_report import check_output_folder, write_report
    from studies.report_extras import builders
    bounds = _common.check_bounds(args.bounds)
    out = check_output_folder(args.out, args.overwrite)
    machine = _common.machine(args)
    study = pipeline.run(machine, points=args.points, side=args.side, bounds=bounds,
                         seed=args.seed,
                         repeats=args.repeats, samples=args.samples, progress=_common.say,
                         bar=_common.progress_bar)
    extra = builders([name for name in EXTRAS if name not in args.skip])
    _common.say("optional sections: " + (", ".join(n for n in EXTRAS if n not in args.skip)
                                          or "none"))
    sections = pipeline.sections(study, extra=extra)
    _common.say("drawing figures and writing the report")
    written = write_report(out, sections, pipeline.summary(study),
                           title=f"Precision allocation and reliability of {machine.name}",
                           overwrite=args.overwrite)
    print(pipeline.answers(study))
    print(f"\n{len(written)} files written to {out}/ (open report.html)")
    return 0
