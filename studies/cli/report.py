"""``precrel report MACHINE.toml --out DIR``: the whole study of a machine, as a report."""

from __future__ import annotations

from reliability.acceptance.suggested_limits import minimum_machines
from reliability.basics.errors import InputError
from reliability.basics.streams import sensitivity_stream, zone_stream
from reliability.compensation.compensation_plans import read_compensation_plan
from reliability.measured.acceptance_runs import has_run_columns
from studies.report import machine_sections
from studies.report.acceptance_section import BUILT_MACHINES
from studies.report.as_measured_section import as_measured_builder
from studies.report.extras import (EXTRAS, TITLES, acceptance_builder, builders,
                                   catalogue_builder, evaluation_builder, guarded,
                                   not_computed)
from studies.report.life_section import life_builder
from studies.report.sensitivity_section import study_sensitivity_section
from studies.report.writer import REPORT_MARKERS, write_report
from studies.report.zone_section import zone_section
from studies.workflows import machine_study
from studies.workflows.zone_comparison import zone_comparison

from . import compensate, options


def add_parser(subparsers):
    parser = subparsers.add_parser(
        "report", help="full study of a machine into a folder (tables, figures, report)",
        description="The machine yield of the initial allocation and of the certified "
                    "optimum (under --profile; the optimum over the continuous workspace by "
                    "default, --workspace), FOSM, Monte-Carlo verification, CSV tables, "
                    "figures, report.md, a self-contained report.html, summary.json and "
                    "allocation.csv in DIR. An optional section that cannot be computed "
                    "(e.g. a catalogue that cannot meet the targets) says why in its place; "
                    "the report is still written and the command exits 0. --time-limit S stops "
                    "the certification over the continuous workspace after S seconds (or "
                    "at Ctrl-C): the report is written with the best allocation so far, "
                    "not certified, and the command exits 3.")
    options.add_machine(parser)
    options.add_out(parser, "folder", "folder of the report (report.md, report.html, "
                                      "summary.json, allocation.csv, "
                                      "drawing_tolerances.csv, tables and figures)",
                    required=True)
    options.add_monte_carlo(parser)
    options.add_points(parser)
    options.add_study_model(parser)
    options.add_yield_model(parser)
    options.add_side(parser)
    options.add_bounds(parser)
    options.add_workspace(parser)
    options.add_time_limit(parser)
    parser.add_argument("--skip", nargs="+", default=(), choices=EXTRAS, metavar="SECTION",
                        help="leave out optional sections: " + ", ".join(EXTRAS)
                             + " (default: include all)")
    options.add_input_file(parser, "--tests",
                           "add an 'Acceptance tests' section: these tests predicted for "
                           "the initial and the optimal allocation (with --compensation, "
                           "also after compensation; --suggest with them)")
    options.add_suggest(parser)
    options.add_input_file(parser, "--catalogue",
                           "add a 'Component choice' section: the certified cheapest choice "
                           "of one class per component")
    options.add_tolerances(parser)
    parser.add_argument("--sensitivity", action="store_true",
                        help="add a 'What each tolerance buys' section: d yield / d ln t of "
                             "every item at the optimal (else the initial) allocation")
    options.add_as_measured(parser)
    options.add_overwrite(parser)
    options.add_quiet(parser)
    compensate.add_report_option(parser)
    return parser


def run(args) -> int:
    bounds = options.check_bounds(args.bounds)
    limits = options.loop_limits(args, options.workspace(args))
    out = options.destination(args.out, args.overwrite, folder=True, markers=REPORT_MARKERS)
    machine = options.machine(args)
    given, given_text = start_tolerances(args, machine)
    tests = None if args.tests is None else options.read_tests(args.tests, machine)
    if args.suggest is not None:
        _check_suggest(args.suggest, tests)
    included = [name for name in EXTRAS if name not in args.skip]
    extra = builders(included)
    if tests is not None:
        included.append("tests")
        plan = None if args.compensation is None else \
            read_compensation_plan(args.compensation, machine)
        extra.append(guarded("tests", acceptance_builder(tests, suggest=args.suggest,
                                                         plan=plan,
                                                         plan_name=args.compensation)))
    if args.catalogue is not None:
        included.append("catalogue")
        extra.append(guarded("catalogue", catalogue_builder(
            options.read_catalogue(args.catalogue, machine), given, start_text=given_text,
            samples=args.samples)))
    if machine.work_zone is not None:
        extra.append(lambda study: zone_section(zone_comparison(
            machine, points=args.points, side=args.side, bounds=bounds,
            machines=args.machines, rng=zone_stream(args.seed))))
    measured = options.as_measured_identification(args, machine)
    if measured is not None:
        included.append("as_measured")
        extra.append(guarded("as_measured", as_measured_builder(
            measured, tests, source=args.identification or args.measurements)))
    if args.measurements is not None and tests is not None and \
            has_run_columns(args.measurements):
        included.append("evaluation")
        extra.append(guarded("evaluation", evaluation_builder(args.measurements, tests)))
    if args.sensitivity:
        included.append("sensitivity")
        extra.append(guarded("sensitivity", lambda study: study_sensitivity_section(
            study, machines=args.machines, rng=sensitivity_stream(study.seed))))
    if machine.drift is not None:
        included.append("life")
        extra.append(guarded("life", life_builder))
    if args.compensation is not None:
        included.append("compensation")
        extra.append(guarded("compensation", compensate.report_builder(args, machine)))
    study = machine_study.run(machine, points=args.points, side=args.side, bounds=bounds,
                              rng=args.seed, repeats=args.repeats, samples=args.samples,
                              progress=options.say, bar=options.progress_bar,
                              machines=args.machines, workspace=options.workspace(args),
                              rtol=args.rtol, given=given,
                              given_text=given_text.removeprefix("the tolerances of "),
                              **limits)
    options.say("optional sections: " + (", ".join(included) or "none"))
    sections = machine_sections.sections(study, extra=extra)
    missing = not_computed(sections)
    options.say("drawing figures and writing the report")
    written = write_report(out, sections,
                           {**machine_study.summary(study), "not_computed": missing},
                           title=f"Precision allocation and reliability of {machine.name}",
                           overwrite=args.overwrite)
    print(machine_sections.answers(study))
    for name, reason in missing.items():
        print(f"\nsection {TITLES[name]!r} not computed: {reason}")
    print(f"\n{len(written)} files written to {out}/ (open report.html)")
    # a report whose targets are out of reach is still a complete answer (0); one whose
    # certification was stopped is written but not certified (STOPPED)
    return options.stop_code(study.continuous)


def _check_suggest(probability: float, tests) -> None:
    """Refuse ``--suggest`` without ``--tests``, or with a quantile too far out for the
    acceptance section's built machines."""
    if tests is None:
        raise InputError(f"--suggest {probability:g} needs --tests TESTS.toml: it suggests "
                         f"limits for the results of those acceptance tests")
    needed = minimum_machines(probability)
    if needed > BUILT_MACHINES:
        raise InputError(f"--suggest {probability:g} needs at least {needed} built machines "
                         f"to bound the quantile at 95 % confidence; the acceptance section "
                         f"draws {BUILT_MACHINES}: give a P closer to 0.5")


def start_tolerances(args, machine) -> tuple:
    """``--tolerances``: the allocation the report studies in place of an optimum (and,
    with ``--catalogue``, the starting tolerances of the items in no component), and its
    source in words (none and the initial allocation when not given)."""
    if args.tolerances is None:
        return None, "the initial allocation"
    return (options.read_tolerances(args.tolerances, machine),
            f"the tolerances of {args.tolerances} (--tolerances)")
