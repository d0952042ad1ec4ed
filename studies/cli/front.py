"""``precrel front MACHINE.toml``: the certified cost–reliability front of a machine.

For each reliability target (the same for all six outputs, at every pose of the grid) the
cheapest allocation is solved to a certified optimum; the classical worst-case stack is
solved beside it. Prints one row per target and the stack; ``--out`` writes the table.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from allocation.front import FRONT_SIDES, cost_reliability_front
from reliability.errors import InputError
from reliability.files import write_csv
from reliability.machine import load_machine
from reliability.poses import workspace_grid

from . import options

#: Default span of the targets: 1 − R from 1e−1 to 1e−9, log-spaced.
FAILURE_SPAN = (1e-1, 1e-9)


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Register ``front`` with its options."""
    parser = subparsers.add_parser(
        "front", help="certified cost against reliability target, and the worst-case stack",
        description=__doc__.splitlines()[0].split(": ", 1)[1])
    parser.add_argument("machine", type=Path, help="machine description (TOML)")
    parser.add_argument("--side", choices=FRONT_SIDES, default="two_sided",
                        help="reading of the reliability requirement (default: two_sided)")
    parser.add_argument("--targets", type=options.probability, nargs="+", default=None, metavar="R",
                        help="reliability targets in (0, 1) (default: --points targets "
                             "with 1 − R log-spaced from 1e-1 to 1e-9)")
    parser.add_argument("--points", type=options.positive_int, default=20,
                        help="number of log-spaced targets when --targets is not given "
                             "(default: 20)")
    parser.add_argument("--bounds", type=options.positive_float, nargs=2, default=(0.5, 1.5),
                        metavar=("LO", "HI"),
                        help="tolerance box as factors of the initial allocation "
                             "(default: 0.5 1.5; high targets and the stack usually need "
                             "a lower LO, e.g. 0.001)")
    parser.add_argument("--grid", type=options.grid_points, default=5,
                        help="grid points per axis (default: 5)")
    parser.add_argument("--out", type=Path, default=None, help="write the table as CSV")
    parser.add_argument("--overwrite", action="store_true",
                        help="replace an existing --out file")
    return parser


def run(args) -> int:
    """Compute and print the front; write it with ``--out``."""
    targets = _targets(args)
    if args.grid < 2:
        raise InputError(f"--grid must be an integer >= 2; got {args.grid}")
    if args.out is not None:
        options.destination(args.out, args.overwrite)
    machine = load_machine(args.machine)
    print(f"front of {machine.name}: {len(targets)} target(s), {args.side}, box "
          f"{args.bounds[0]:g}–{args.bounds[1]:g} × initial allocation", file=sys.stderr)
    front = cost_reliability_front(machine, targets, side=args.side,
                                   poses=workspace_grid(machine, args.grid),
                                   bounds=tuple(args.bounds))
    shown = front[["target", "cost", "relative_cost", "relative_gap", "certified",
                   "feasible", "binding"]].copy()
    shown.insert(1, "failure", 1.0 - shown["target"])  # 1 − R, readable where R rounds to 1
    print(shown.to_string(float_format=lambda v: f"{v:.6g}"))
    print(_stack_line(front.attrs["stack"]))
    seconds = front.attrs["seconds"]
    print(f"time: build and row screening {seconds['build']:.2f} s, "
          f"{len(targets)} solves {seconds['solve']:.2f} s", file=sys.stderr)
    if args.out is not None:
        write_csv(shown, args.out, overwrite=args.overwrite)
        print(f"written: {args.out}")
    return 0


def _targets(args) -> np.ndarray:
    if args.targets is not None:
        return np.asarray(args.targets, dtype=float)
    if args.points < 2:
        raise InputError(f"--points must be an integer >= 2; got {args.points}")
    return 1.0 - np.logspace(np.log10(FAILURE_SPAN[0]), np.log10(FAILURE_SPAN[1]),
                             args.points)


def _stack_line(stack) -> str:
    if "error" in stack:
        return f"worst-case stack: not reachable in the box ({stack['error'].split(';')[0]})"
    return (f"worst-case stack: cost {stack['cost']:.6g} = {stack['relative_cost']:.4g} × "
            f"initial allocation, certified {stack['certified']}, relative gap "
            f"{stack['relative_gap']:.2g}, binding {stack['binding']}")
