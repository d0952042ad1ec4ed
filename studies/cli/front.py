"""``precrel front MACHINE.toml``: the certified cost–reliability front of a machine.

For each reliability target (the same for all six outputs, at every pose of the grid) the
cheapest allocation is solved to a certified optimum; the classical worst-case stack is
solved beside it. Prints one row per target and the stack; ``--out`` writes the table.
"""

from __future__ import annotations

import argparse

import numpy as np

from allocation import AllocationProblem
from allocation.per_pose.front import cost_reliability_front, front_to_csv
from allocation.per_pose.result_files import gap_bound, gap_text
from reliability.basics.display import target_text
from reliability.basics.errors import InputError
from reliability.model.machine import OUTPUTS
from reliability.model.poses import workspace_grid

from . import options

#: Default span of the targets: 1 − R from 1e−1 to 1e−9, log-spaced.
FAILURE_SPAN = (1e-1, 1e-9)


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Register ``front`` with its options."""
    parser = subparsers.add_parser(
        "front", help="certified cost against reliability target, and the worst-case stack",
        description=__doc__.splitlines()[0].split(": ", 1)[1])
    options.add_machine(parser)
    options.add_side(parser)
    options.add_target(parser, many=True)
    parser.add_argument("--count", type=options.positive_int, default=20, metavar="N",
                        help="number of targets, 1 − R log-spaced from 1e-1 to 1e-9, when "
                             "--target is not given (default: 20)")
    options.add_deprecated(parser, "--targets", "--count", dest="count",
                           type=options.positive_int, metavar="N")
    options.add_bounds(parser)
    options.add_points(parser)
    options.add_study_model(parser)
    options.add_out(parser, "file", "write the table as CSV", metavar="CSV")
    options.add_overwrite(parser)
    return parser


def run(args) -> int:
    """Compute and print the front; write it with ``--out``; exit 2 when the box reaches
    none of the targets."""
    targets = _targets(args)
    bounds = options.check_bounds(args.bounds)
    if args.out is not None:
        options.destination(args.out, args.overwrite)
    machine = options.machine(args)
    poses = workspace_grid(machine, args.points)
    box = options.box_words(machine, bounds)
    options.say(f"front of {machine.name}: {len(targets)} target(s), {args.side}, {box}, "
                f"{args.points}-point grid, outputs in the {machine.frame} frame")
    front = cost_reliability_front(machine, targets, side=args.side, poses=poses,
                                   bounds=bounds)
    if not front["feasible"].any():
        _refuse_unreachable(machine, float(front["target"].min()), args.side, poses, bounds)
    shown = front[["target", "cost", "relative_cost", "relative_gap", "certified",
                   "binding"]].copy()
    shown.insert(1, "failure", 1.0 - shown["target"])
    shown["relative_gap"] = [gap_bound(g) for g in shown["relative_gap"]]
    reached = shown[front["feasible"]]
    print(f"certified front ({args.side}, {box}, every target at every pose of the "
          f"{args.points}-point grid; {options.reading_text(machine)}); failure = 1 − "
          f"target; relative_gap is an upper bound")
    print(reached.to_string(index=False, formatters={
        "target": target_text, "failure": "{:.3g}".format}, float_format="{:.6g}".format))
    missed = front.loc[~front["feasible"], "target"]
    if len(missed):
        print(f"not reachable in the box: {len(missed)} target(s) from "
              f"{target_text(missed.min())} (failure {1 - missed.min():.3g}) up; "
              f"{options.wider_box_advice(machine, bounds).replace(' it', ' them')}")
    print(_stack_line(front.attrs["stack"]))
    seconds = front.attrs["seconds"]
    options.say(f"time: build and row screening {seconds['build']:.2f} s, "
                f"{len(targets)} solves {seconds['solve']:.2f} s")
    if args.out is not None:
        front_to_csv(shown, args.out, overwrite=args.overwrite)
        print(f"written: {args.out}")
    return 0


def _refuse_unreachable(machine, target: float, side: str, poses, bounds) -> None:
    """Raise the allocation's own refusal (blocking output and pose) for the lowest target."""
    problem = AllocationProblem.build(machine, poses, side=side, bounds=bounds,
                                      targets=dict.fromkeys(OUTPUTS, target))
    problem.solve_exact()  # raises TargetUnreachableError naming what blocks
    raise InputError(f"no target of the front is reachable in the "
                     f"{options.box_words(machine, bounds)}")


def _targets(args) -> np.ndarray:
    if args.target is not None:
        return np.asarray(args.target, dtype=float)
    if args.count < 2:
        raise InputError(f"--count must be an integer >= 2 (the number of log-spaced "
                         f"targets); got {args.count}")
    return 1.0 - np.logspace(np.log10(FAILURE_SPAN[0]), np.log10(FAILURE_SPAN[1]),
                             args.count)


def _stack_line(stack) -> str:
    if "error" in stack:
        return f"worst-case stack: not reachable in the box ({stack['error'].split(';')[0]})"
    return (f"worst-case stack: cost {stack['cost']:.6g} = {stack['relative_cost']:.4g} × "
            f"initial allocation, certified {stack['certified']}, relative gap "
            f"{gap_text(stack['relative_gap'])}, binding {stack['binding']}")
