"""``precrel check MACHINE.toml``: validate a machine file, summarise it, warn of mistakes."""

from __future__ import annotations

from allocation import CostModel
from reliability.machine_checks import describe, likely_mistakes

from . import options


def add_parser(subparsers):
    parser = subparsers.add_parser(
        "check", help="validate and summarise a machine file",
        description="Load a machine file, print its axes (strokes with units), number of "
                    "errors, requirements and the cost of the initial allocation, and warn "
                    "about likely mistakes.")
    options.add_machine(parser)
    return parser


def run(args) -> int:
    machine = options.machine(args)
    cost = CostModel.from_machine(machine).total(machine.initial_allocation)
    print(describe(machine))
    print(f"initial allocation cost (Eq. 28, k1 = k2 = k3 = 1): {cost:.6g}")
    warnings = likely_mistakes(machine)
    print(f"\nwarnings ({len(warnings)}):" if warnings else "\nno warnings")
    for text in warnings:
        print(f"  - {text}")
    return 0
