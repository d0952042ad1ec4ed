"""``precrel evaluate RUNS.csv --out DIR``: a measured machine's ISO 230-2, ISO 230-4 and
ISO 10791-6 values from its acceptance runs; with ``--machine`` and ``--tests`` also its
limits, pass or fail, and where it sits among the machines the design predicted."""

from __future__ import annotations

import pandas as pd

from reliability.acceptance.acceptance_result import profile_note
from reliability.acceptance.prediction import path_profile
from reliability.basics.errors import InputError
from reliability.basics.files import SIGNIFICANT, write_csv
from reliability.basics.streams import acceptance_stream
from reliability.measured.acceptance_runs import read_acceptance_runs
from studies.report.evaluation_plots import FIGURE_PREFIX, run_figures
from studies.workflows.acceptance_evaluation import (evaluate_against_design,
                                                     printed_table, verdicts_by_test,
                                                     worst_sentences)

from . import options

#: The table files written into ``--out DIR``; figures are ``evaluation_<run>.png``.
TABLE_FILE, POSITIONS_FILE = "evaluation.csv", "positions.csv"


def add_parser(subparsers):
    parser = subparsers.add_parser(
        "evaluate", help="a measured machine's ISO 230 acceptance values (and against the "
                         "design)",
        description="Read the acceptance runs of a measurement file (positioning runs with "
                    "cycle and direction, ballbar runs with direction, rotary runs; "
                    "docs/measurements.md) and write their ISO 230-2 (E, M, R, B, A and "
                    "their one-direction values), ISO 230-4 (G per direction, G, H, F) and "
                    "ISO 10791-6 (ranges) values, the per-target table and figures. With "
                    "--machine and --tests: each test's limit, pass or fail, and the "
                    "measured value's percentile among machines built to the allocation.")
    parser.add_argument("runs", metavar="RUNS.csv", help="measurement file of the runs")
    parser.add_argument("--machine", metavar="MACHINE.toml",
                        help="the machine file: check the runs against it and, with "
                             "--tests, compare with the machines the design predicts")
    options.add_input_file(parser, "--tests", "the limits of the runs of the same names, "
                                              "and the predicted machines' results "
                                              "(with --machine)")
    options.add_tolerances(parser)
    options.add_machines(parser, default=2000)
    options.add_profile(parser)
    options.add_seed(parser)
    options.add_out(parser, "folder", f"write {TABLE_FILE}, {POSITIONS_FILE} and a figure per "
                                      f"positioning run and circle into DIR", required=True)
    options.add_overwrite(parser)
    return parser


def run(args) -> int:
    _check_options(args)
    out = options.destination(args.out, args.overwrite, folder=True,
                              markers=(TABLE_FILE, POSITIONS_FILE))
    machine = None if args.machine is None else options.machine(args)
    tests = None if args.tests is None else options.read_tests(args.tests, machine)
    tolerances = None if args.tolerances is None else \
        options.read_tolerances(args.tolerances, machine)
    if tests is not None:
        path_profile(machine.profile, tests)
    runs = read_acceptance_runs(args.runs, machine)
    options.print_warnings(runs.warnings)
    table = runs.evaluation_frame()
    count = f"{len(runs.runs)} run{'s' if len(runs.runs) > 1 else ''}"
    print(f"Acceptance runs of {args.runs}: {count}; values in µm to 3 significant digits "
          f"({TABLE_FILE}: mm, {SIGNIFICANT} significant digits)")
    for sentence in runs.left_out:
        print(f"  left out: {sentence}")
    if tests is not None:
        options.say(f"predicting {args.machines} machines through the tests of {args.tests} "
                    f"that have a run")
        table, result, matched = evaluate_against_design(
            runs, machine, tests, tolerances, machines=args.machines,
            rng=acceptance_stream(args.seed))
        _print_design(args, table, result, matched)
        unmatched = [test.name for test in tests if test not in matched]
        if unmatched:
            print(f"  tests without a run of their name (not evaluated): "
                  f"{', '.join(unmatched)}")
    else:
        print(f"\n{printed_table(table).to_string(index=False)}")
    _write(out, args.overwrite, runs, table)
    return 0


def _check_options(args) -> None:
    given = [name for name, value in (("--tests", args.tests), ("--tolerances",
                                                                args.tolerances),
                                      ("--profile", args.profile)) if value is not None]
    if given and args.machine is None:
        raise InputError(f"{given[0]} needs --machine MACHINE.toml")
    if args.machine is not None and args.tests is None and \
            (args.tolerances is not None or args.profile is not None):
        raise InputError(f"{given[0]} is used with --tests only")


def _print_design(args, table, result, tests) -> None:
    source = "initial allocation" if args.tolerances is None else args.tolerances
    print(f"\nagainst {args.tests} and {result.n_machines} machines built to the {source} "
          f"(the acceptance prediction's stream, seed {args.seed}; "
          f"{profile_note(result.profile)}); percentile: the share of predicted machines "
          f"whose value is <= the measured one\n")
    print(printed_table(table).to_string(index=False))
    print()
    for row in verdicts_by_test(table, tests).itertuples():
        verdict = "no limit" if pd.isna(row.passes) else "passes" if row.passes else "FAILS"
        print(f"  {row.test}: {verdict}")
    for sentence in worst_sentences(table, result, tests):
        print(f"  {sentence}")


def _write(out, overwrite, runs, table) -> None:
    """The tables and figures; with ``overwrite`` an earlier run's figures and per-target
    table are removed first, so the folder holds one evaluation."""
    out.mkdir(exist_ok=True)
    if overwrite:
        for earlier in [*out.glob(f"{FIGURE_PREFIX}*.png"), out / POSITIONS_FILE]:
            earlier.unlink(missing_ok=True)
    written = [write_csv(table, out / TABLE_FILE, overwrite=overwrite, index=False,
                         float_format=f"%.{SIGNIFICANT}g")]
    positions = runs.positions_frame()
    if len(positions):
        written.append(write_csv(positions, out / POSITIONS_FILE, overwrite=overwrite,
                                 index=False, float_format=f"%.{SIGNIFICANT}g"))
    for name, figure in run_figures(runs).items():
        figure.savefig(out / name, dpi=120)
        written.append(out / name)
    print(f"\nwritten {', '.join(p.name for p in written)} into {out}")
