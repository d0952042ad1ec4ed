"""``precrel check MACHINE.toml``: validate a machine file, summarise it, warn of mistakes."""

from __future__ import annotations

from allocation import CostModel
from allocation.per_pose.result_files import cost_shares_text, cost_units_text
from reliability.model.identifiability import EQUAL_RTOL, indistinguishable_groups
from reliability.model.machine_checks import describe, likely_mistakes

from . import options


def add_parser(subparsers):
    parser = subparsers.add_parser(
        "check", help="validate and summarise a machine file",
        description="Load a machine file, print its axes (strokes with units), number of "
                    "errors, requirements and the cost of the initial allocation, list the "
                    "groups of errors that cannot be told apart, and warn about likely "
                    "mistakes.")
    options.add_machine(parser)
    return parser


def run(args) -> int:
    machine = options.machine(args, warn=False)
    cost = CostModel.from_machine(machine).total(machine.initial_allocation)
    print(describe(machine))
    model = CostModel.from_machine(machine)
    print(f"initial allocation cost (Eq. 28, k1 = k2 = k3 = 1; {cost_units_text(model)}): "
          f"{cost:.6g}")
    print(f"cost shares of the initial allocation: "
          f"{cost_shares_text(model, machine.initial_allocation)}")
    print(groups_text(machine, indistinguishable_groups(machine)))
    warnings = likely_mistakes(machine)
    print(f"\nwarnings ({len(warnings)}):" if warnings else "\nno warnings")
    for text in warnings:
        print(f"  - {text}")
    return 0


def groups_text(machine, groups) -> str:
    """The groups of errors with equal sensitivities at every pose of the 5-point grid."""
    members = sum(len(g) for g in groups)
    lines = [f"\nerrors that cannot be told apart ({members} of {machine.n_errors} errors in "
             f"{len(groups)} groups; sensitivities equal at every pose of the 5-point grid to "
             f"{EQUAL_RTOL:g} of the largest; only each group's summed variance matters, "
             f"and the cost alone decides how it is shared):"]
    lines += [f"  - {', '.join(group)}" for group in groups]
    return "\n".join(lines) if groups else "\nevery error can be told apart from the others"
