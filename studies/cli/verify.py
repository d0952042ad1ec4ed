"""``precrel verify MACHINE.toml --tolerances CSV``: Monte-Carlo beside FOSM; ``--out DIR``
writes its three tables (:data:`TABLE_FILES`)."""

from __future__ import annotations

import numpy as np
import pandas as pd

from reliability.basics import display
from reliability.basics.errors import InputError
from reliability.basics.files import SIGNIFICANT, write_csv
from reliability.basics.streams import extra_stream
from reliability.sampling.pose_sampling import EVENTS, sample_at_poses
from reliability.sampling.verification import rare_event_table, reachable_events, verify
from studies.workflows.as_measured import AS_MEASURED_STREAM, as_measured

from . import compensate, options

#: The tables ``--out DIR`` holds: the verification's attribute of each.
TABLE_FILES = {"grid_experiments.csv": "grid_comparison", "random_poses.csv": "random_poses",
               "worst_poses.csv": "worst_poses"}


def add_parser(subparsers):
    parser = subparsers.add_parser(
        "verify", help="Monte-Carlo verification of an allocation, FOSM beside it",
        description="The machine yield (the share of built machines within every limit at "
                    "every grid pose, under --profile), then repeated grid experiments "
                    "(Wilson interval on the effective sample size "
                    "from the spread between experiments), "
                    "random poses (Wilson interval) and Monte-Carlo at each output's worst "
                    "pose (Wilson interval; certified over the continuous workspace unless "
                    "--workspace grid, as the report samples it), each beside the FOSM "
                    "prediction. Errors are drawn under the study's reading of a tolerance "
                    "(--distribution).")
    options.add_machine(parser)
    options.add_tolerances(parser, required=True)
    options.add_monte_carlo(parser)
    parser.add_argument("--precision", type=options.probability, metavar="P",
                        help="also sample each output's worst pose adaptively until the "
                             "interval's relative half-width on the failure probability is "
                             "at most P (e.g. 0.1), or --max-samples is reached")
    parser.add_argument("--max-samples", type=options.positive_int, default=2_000_000,
                        metavar="N", help="sample cap of --precision (default 2000000)")
    parser.add_argument("--rare", action="store_true",
                        help="also estimate each output's and the system's failure "
                             "probability at its worst pose by importance sampling (or "
                             "--rare-method subset) on the exact model")
    parser.add_argument("--rare-method", choices=("importance", "subset"),
                        default="importance", help="rare-event method (default importance)")
    parser.add_argument("--target-cov", type=options.probability, default=0.1, metavar="C",
                        help="coefficient of variation --rare stops at (default 0.1)")
    parser.add_argument("--max-evaluations", type=options.positive_int, default=20_000,
                        metavar="N", help="exact-model evaluations --rare may use "
                                          "(default 20000)")
    options.add_points(parser)
    options.add_study_model(parser)
    options.add_yield_model(parser)
    options.add_workspace(parser)
    options.add_deprecated(parser, "--certify", "--workspace continuous", dest="certify",
                           nargs=0, const=True, default=False)
    options.add_as_measured(parser)
    options.add_input_file(parser, "--tests",
                           "with --identification or --measurements: each test's predicted "
                           "result for this machine, beside machines built to the "
                           "allocation")
    compensate.add_verification_option(parser)
    options.add_out(parser, "folder", f"write {', '.join(TABLE_FILES)} into DIR")
    options.add_overwrite(parser)
    return parser


def workspace(args) -> str:
    """Where the worst poses are sought: ``--workspace``, ``'continuous'`` by default (and
    under ``--certify``); ``--certify`` with ``--workspace grid`` is refused."""
    if args.certify and args.workspace == "grid":
        raise InputError("--certify asks for the continuous workspace and --workspace grid "
                         "for the grid; pass one of them")
    return "continuous" if args.workspace is None else args.workspace


def run(args) -> int:
    out = None if args.out is None else options.destination(
        args.out, args.overwrite, folder=True, markers=tuple(TABLE_FILES))
    machine = options.machine(args)
    continuous = workspace(args) == "continuous"
    if continuous:
        options.check_certifiable(machine, "--workspace continuous (the default)",
                                  "pass --workspace grid to sample at the worst grid poses")
    t = options.read_tolerances(args.tolerances, machine)
    measured = options.as_measured_identification(args, machine, t)
    tests = as_measured_tests(args, machine, measured)
    result = verify(machine, t, points=args.points, repeats=args.repeats,
                    samples=args.samples, rng=args.seed, progress=options.say,
                    bar=options.progress_bar, machines=args.machines,
                    workspace="continuous" if continuous else "grid", rtol=args.rtol)
    print(f"Monte-Carlo verification of {args.tolerances} on {machine.name!r} "
          f"(seed {args.seed}); outputs in the {machine.frame} frame; two-sided "
          f"probabilities in %; Monte-Carlo and FOSM with {options.reading_text(machine)}\n")
    print(result.machine_yield.summary() + "\n")
    where = f"certified (continuous workspace, rtol {args.rtol:g})" if continuous else "grid"
    print(report_tables(machine, result, where))
    worst = result.worst_poses
    short = worst.loc[~worst["reaches_target"], "output"].tolist()
    print(f"\nat every output's {where} worst pose the Monte-Carlo interval reaches the "
          f"target" if not short else
          f"\nMonte-Carlo significantly below target at the {where} worst pose: "
          f"{', '.join(short)}")
    if args.precision is not None:
        options.say(f"adaptive Monte-Carlo at the worst poses to relative precision "
                    f"{args.precision:g}")
        print("\n" + precision_text(machine, t, args.precision, args.max_samples,
                                    rng=extra_stream(args.seed, 0)))
    if args.rare:
        options.say(f"rare-event estimates at the worst poses ({args.rare_method})")
        print("\n" + rare_text(machine, t, args, rng=extra_stream(args.seed, 1)))
    if measured is not None:
        options.say("this machine as measured: posterior draws through the exact chain")
        print("\n" + as_measured_text(machine, measured, t, result, tests, args, where))
    if args.compensation is not None:
        print("\n" + compensate.verification_text(machine, t, args))
    if out is not None:
        write_tables(result, out, args.overwrite)
    return 0


def write_tables(result, out, overwrite: bool) -> None:
    """The verification's tables into the folder ``out`` (:data:`TABLE_FILES`)."""
    out.mkdir(exist_ok=True)
    for name, attribute in TABLE_FILES.items():
        write_csv(getattr(result, attribute), out / name, overwrite=overwrite, index=False,
                  float_format=f"%.{SIGNIFICANT}g")
    print(f"\nwritten {', '.join(TABLE_FILES)} into {out}")


def as_measured_tests(args, machine, measured):
    """``--tests``, read; refused without ``--identification`` or ``--measurements``."""
    if args.tests is None:
        return None
    if measured is None:
        raise InputError("--tests predicts acceptance tests for a measured machine; give "
                         "--identification DIR or --measurements CSV with it")
    return options.read_tests(args.tests, machine)


def as_measured_text(machine, identification, tolerances, result, tests, args, where) -> str:
    """This machine's reliability at the grid and the verification's worst poses, beside
    the design's (the design-time yield when the identification's prior is the allocation
    verified)."""
    same = np.allclose(3.0 * identification.coefficients.prior_sd, tolerances, rtol=1e-5,
                       atol=0.0)
    found = as_measured(machine, identification, points=args.points,
                        poses=result.worst_poses[list(machine.axes)].to_numpy(dtype=float),
                        draws=args.machines, tests=tests,
                        design_yield=result.machine_yield if same else None,
                        rng=extra_stream(args.seed, AS_MEASURED_STREAM))
    note = "" if same else (f"\nnote: the identification's prior is not {args.tolerances}; "
                            f"the design-time numbers above are of its own allocation "
                            f"(t = 3 x prior sd)")
    return (f"{found.summary()}\n(the further poses: each output's {where} worst pose of "
            f"the design){note}")


def precision_text(machine, tolerances, precision: float, max_samples: int, *, rng) -> str:
    """``--precision P``: adaptive Monte-Carlo at the worst poses of the events crude
    sampling can resolve within ``max_samples``; the others are named, for ``--rare``."""
    events = reachable_events(machine, tolerances, precision, max_samples)
    skipped = [e for e in EVENTS if e not in events]
    note = (f"\nNot sampled (failure probability too small for {max_samples} samples to reach "
            f"the precision; use --rare): {', '.join(skipped)}" if skipped else "")
    if not events:
        return note.lstrip("\n")
    result = sample_at_poses(machine, tolerances, precision=precision,
                             max_samples=max_samples, events=events, rng=rng,
                             distribution=machine.distribution)
    return result.summary() + note


def rare_text(machine, tolerances, args, *, rng) -> str:
    """``--rare``: failure probabilities at each event's worst grid pose."""
    table = rare_event_table(machine, tolerances, method=args.rare_method,
                             target_cov=args.target_cov,
                             max_evaluations=args.max_evaluations, rng=rng)
    shown = table.drop(columns=["distribution"]).assign(
        lower=[display.lower_bound_text(v, 4) for v in table["lower"]],
        upper=[display.upper_bound_text(v, 4) for v in table["upper"]])
    return (f"Failure probability at each event's worst grid pose ({args.rare_method}, exact "
            f"model, {machine.distribution} errors):\n"
            + shown.to_string(float_format="{:.4g}".format))


def report_tables(machine, result, where: str = "grid") -> str:
    """The three comparisons as text tables; ``where`` names the worst poses sampled."""
    grid = result.grid_comparison
    grid_table = pd.DataFrame({
        "FOSM grid mean": _pct(grid["fosm_two_sided"]),
        "MC mean": _pct(grid["mc_estimate"]),
        "95% Wilson (Kish n_eff)": _interval(grid["mc_lower"], grid["mc_upper"]),
        "FOSM worst pose": _pct(grid["fosm_worst_two_sided"]),
    }, index=pd.Index(grid["output"], name="output"))
    random = result.random_poses
    random_table = pd.DataFrame({
        "FOSM": _pct(random["fosm_two_sided"]),
        "MC": _pct(random["estimate"]),
        "95% Wilson": _interval(random["lower"], random["upper"]),
    }, index=pd.Index(random["output"], name="output"))
    worst = result.worst_poses
    worst_table = pd.DataFrame({
        "worst pose": [options.pose_text(machine, row) for row in
                       worst[list(machine.axes)].to_numpy()],
        "FOSM": _pct(worst["fosm_two_sided"]),
        "exact linear": _pct(worst["exact_linear"]),
        "MC": _pct(worst["mc_estimate"]),
        "95% Wilson": _interval(worst["mc_lower"], worst["mc_upper"]),
        "target": [f"{100 * v:g}" for v in worst["target"]],
        "reaches target": ["yes" if v else "NO" for v in worst["reaches_target"]],
    }, index=pd.Index(worst["output"], name="output"))
    return "\n\n".join([
        f"grid experiments ({result.grid.repeats} x {result.grid.n_poses} poses), two-sided:",
        grid_table.to_string(),
        f"random poses ({int(random['n'].iloc[0])} independent samples), two-sided:",
        random_table.to_string(),
        f"at each output's {where} worst pose ({int(worst['samples'].iloc[0])} samples):",
        worst_table.to_string()])


def _pct(values) -> list[str]:
    return [f"{100 * v:.3f}" for v in values]


def _interval(lower, upper) -> list[str]:
    """Intervals in per cent to 0.001 %, their ends rounded outward."""
    return [f"[{display.percent_number(lo, 'lower', 3)}, "
            f"{display.percent_number(hi, 'upper', 3)}]" for lo, hi in zip(lower, upper)]
