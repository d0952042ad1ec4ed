"""``precrel acceptance MACHINE.toml --tests TESTS.toml``: will built machines pass their
ISO 230 acceptance tests? ``--out FILE`` writes the table (a folder, the old spelling,
still gets its ``acceptance.csv`` for one release)."""

from __future__ import annotations

from pathlib import Path

from reliability.acceptance.acceptance_result import profile_note
from reliability.acceptance.prediction import acceptance, path_profile
from reliability.acceptance.suggested_limits import check_machines, suggest_limits
from reliability.basics.errors import InputError
from reliability.basics.files import SIGNIFICANT, write_csv
from reliability.basics.streams import acceptance_stream, compensated_acceptance_stream
from reliability.compensation.compensation_plans import read_compensation_plan
from studies.workflows.compensated_acceptance import (compensated_acceptance,
                                                      comparison_frame, comparison_text)

from . import options

#: The result file written into a folder given as ``--out`` (deprecated).
RESULT_FILE = "acceptance.csv"


def add_parser(subparsers):
    parser = subparsers.add_parser(
        "acceptance", help="predicted ISO 230 acceptance-test results and pass probabilities",
        description="Draw machines built to an allocation (geometric errors along travel "
                    "as an error profile, plus each linear axis' repeatability and reversal) "
                    "and evaluate every test of TESTS.toml on each: circular deviation G "
                    "(ISO 230-4), E, A, R, B (ISO 230-2) and rotary-axis ranges. Prints each "
                    "result's mean and 95 % quantile, the pass probability with its Wilson "
                    "95 % interval and the error items that drive it.")
    options.add_machine(parser)
    options.add_input_file(parser, "--tests", "the tests to predict", required=True)
    options.add_tolerances(parser)
    options.add_machines(parser, default=2000)
    options.add_profile(parser)
    options.add_seed(parser)
    options.add_suggest(parser)
    options.add_input_file(parser, "--compensation",
                           "also each result after compensation, beside the result before: "
                           "machines built to the allocation, measured under this plan and "
                           "compensated, drawn from the residual model; adds columns ending "
                           "in _compensated to the --out table")
    options.add_out(parser, "file", "write the table of results as CSV", metavar="CSV")
    options.add_overwrite(parser)
    return parser


def run(args) -> int:
    out = None if args.out is None else out_file(args)
    machine = options.machine(args)
    tests = options.read_tests(args.tests, machine)
    tolerances = None if args.tolerances is None else \
        options.read_tolerances(args.tolerances, machine)
    chosen = profile_source(args)
    try:
        path_profile(machine.profile, tests)
    except InputError as error:
        raise InputError(f"{chosen}: {error} (give it with --profile)") from None
    if args.suggest is not None:
        check_machines(args.machines, args.suggest, name="--machines")
    plan = None if args.compensation is None else \
        read_compensation_plan(args.compensation, machine)
    options.say(f"{len(tests)} tests on {args.machines} built machines")
    result = acceptance(machine, tests, tolerances, machines=args.machines,
                        profile=machine.profile, rng=acceptance_stream(args.seed))
    source = "initial allocation" if args.tolerances is None else args.tolerances
    print(f"Acceptance tests of {machine.name!r}, {source}: {result.n_machines} built "
          f"machines, seed {args.seed}; {profile_note(result.profile)} ({chosen}); "
          f"tolerances read as "
          f"{result.distribution} with σ = t/{result.k:g}; geometric errors only (no servo, "
          f"dynamic or thermal effects), plus each linear axis' repeatability and reversal "
          f"in positioning tests.\n")
    print(result.results_text())
    suggestion = None if args.suggest is None else suggest_limits(result, args.suggest)
    if suggestion is not None:
        print(f"\n{suggestion.summary()}")
    table = result.to_frame() if suggestion is None else suggestion.to_frame()
    if plan is not None:
        table = _compensated(args, plan, tests, tolerances, result)
    if out is not None:
        path = write_csv(table, out, overwrite=args.overwrite,
                         index=False, float_format=f"%.{SIGNIFICANT}g")
        print(f"\nwritten {path}")
    return 0


def _compensated(args, plan, tests, tolerances, before):
    """Print the results after compensation beside those before; the table with both."""
    options.say(f"{args.machines} machines measured under {args.compensation} and "
                f"compensated")
    after = compensated_acceptance(plan, tests, tolerances, machines=args.machines,
                                   rng=compensated_acceptance_stream(args.seed))
    frame = comparison_frame(before, after, args.suggest)
    print(f"\nafter compensation ({args.compensation}: {len(plan.runs)} runs, "
          f"{int(plan.tabled.sum())} items tabled), {after.n_machines} machines of the "
          f"residual model, extra stream 8 of seed {args.seed}: residual errors drawn "
          f"correlated, each one value along the whole travel (the constant profile, the one "
          f"an identification holds), repeatability and reversal in positioning tests as "
          f"before; results in µm, mean (5–95 %), pass probability (Wilson 95 %)"
          + ("" if args.suggest is None else
             f", suggested limit (the {args.suggest:g}-quantile)") + "\n")
    print(comparison_text(frame))
    return frame


def out_file(args):
    """``--out``: the table's file, checked before any work; a folder (the old meaning)
    still gets its ``acceptance.csv``, with a warning."""
    if not Path(args.out).is_dir():
        return options.destination(args.out, args.overwrite)
    path = Path(args.out) / RESULT_FILE
    options.warn_deprecated("--out DIR (a folder) in acceptance", f"--out {path}")
    return options.destination(path, args.overwrite)


def profile_source(args) -> str:
    """Where the error profile comes from, in words: ``--profile`` or the machine file."""
    if args.profile is not None:
        return "--profile"
    return "the machine file's profile"
