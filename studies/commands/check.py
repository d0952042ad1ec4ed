"""``precrel check MACHINE.toml``: validate a machine file, summarise it, warn of mistakes."""

from __future__ import annotations

import math

from allocation import CostModel

from . import _common

RATE_NOTE = "rotary strokes wider than 2*pi rad look like degrees given for radians"


def add_parser(subparsers):
    parser = subparsers.add_parser(
        "check", help="validate and summarise a machine file",
        description="Load a machine file, print its axes (strokes with units), number of "
                    "errors, requirements and the cost of the initial allocation, and warn "
                    "about likely mistakes.")
    _common.add_machine(parser)
    return parser


def run(args) -> int:
    machine = _common.machine(args)
    print(_summary(machine))
    warnings = _warnings(machine)
    print(f"\nwarnings ({len(warnings)}):" if warnings else "\nno warnings")
    for text in warnings:
        print(f"  - {text}")
    return 0


def _summary(machine) -> str:
    cost = CostModel.from_machine(machine).total(machine.initial_allocation)
    cost_line = f"initial allocation cost (Eq. 28, k1 = k2 = k3 = 1): {cost:.6g}"
    described = _checks_module()
    if described is not None and hasattr(described, "describe"):
        return f"{described.describe(machine)}\n{cost_line}"
    lines = [f"machine: {machine.name}",
             f"axes ({len(machine.axis_specs)}, chain workpiece -> tool):"]
    for axis in machine.axis_specs:
        unit = _common.axis_unit(axis)
        stroke = "full turn" if axis.full_turn else \
            f"stroke [{axis.stroke[0]:g}, {axis.stroke[1]:g}] {unit}"
        lines.append(f"  {axis.name:<6} {axis.kind:<7} along/about {axis.direction}  "
                     f"{stroke}  size {axis.size:g} m")
    lines.append(f"errors: {machine.n_errors} ({6 * len(machine.axis_specs)} motion, "
                 f"{machine.n_errors - 6 * len(machine.axis_specs)} assembly)")
    lines.append("requirements:")
    for output, limit, target in zip(_common.outputs(), machine.limits, machine.targets):
        lines.append(f"  {output}  |{output}| < {limit:g} {_common.OUTPUT_UNITS[output]} "
                     f"with probability >= {target:g}")
    lines.append(cost_line)
    return "\n".join(lines)


def _warnings(machine) -> list[str]:
    described = _checks_module()
    if described is not None and hasattr(described, "likely_mistakes"):
        return [str(w) for w in described.likely_mistakes(machine)]
    warnings = []
    first = machine.axis_specs[0]
    if any(first.offset):
        warnings.append(f"axis {first.name}: the first axis' offset cancels in the "
                        f"comprehensive error (Eq. 18) and has no effect")
    for axis in machine.axis_specs:
        if axis.kind == "rotary" and not axis.full_turn and \
                axis.stroke[1] - axis.stroke[0] > 2 * math.pi:
            warnings.append(f"axis {axis.name}: stroke of {axis.stroke[1] - axis.stroke[0]:g}"
                            f" rad; {RATE_NOTE}")
        if axis.size > 50:
            warnings.append(f"axis {axis.name}: size {axis.size:g} m looks like "
                            f"millimetres; the cost model expects metres")
    return warnings


def _checks_module():
    try:
        from reliability import machine_checks
    except ImportError:
        return None
    return machine_checks
