"""Report sections on the cost–reliability trade-off of a machine.

:func:`front_section` answers "how much cheaper is a 99 % machine than a
worst-case-stacked one?" with the certified front and the stack allocation;
:func:`system_section` reports the probability that all six outputs are inside at once
(the machine's real yield at a pose) for some allocations, beside the per-output view.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from allocation.per_pose.front import allocation_point, cost_reliability_front, front_file_table
from allocation.per_pose.result_files import gap_bound, gap_text
from reliability.basics.display import axis_units, bound_text, pose_frame, pose_text
from reliability.basics.display import (decimals_text)
from reliability.basics.streams import spawn
from reliability.first_order.system_reliability import worst_system_reliability
from reliability.model.poses import workspace_grid

from .markdown import details
from .plots import plot_front
from .section import Section

#: Front targets: 1 − R log-spaced from 1e−1 to 1e−9.
DEFAULT_TARGETS = 1.0 - np.logspace(-1, -9, 25)
#: A box wide enough for the stack and the highest targets on the paper's machine.
WIDE_BOUNDS = (0.001, 1.5)


def front_section(machine, *, targets=DEFAULT_TARGETS, reliability: float = 0.99,
                  bounds=WIDE_BOUNDS, box=None, box_text=None, poses=None,
                  marks=None) -> Section:
    """The certified two-sided front, the stack, and the stack / ``reliability`` ratio.

    Parameters
    ----------
    machine : Machine
    targets : array_like
        Targets of the front.
    reliability : float
        The target compared with the stack in the text ("a 99 % machine").
    bounds : (float, float)
        Box as factors of the initial allocation, for the front and the stack alike.
    box : dict, optional
        Explicit ``{"lower": ..., "upper": ...}`` tolerance bounds instead of ``bounds``
        (e.g. a report's own box), described by ``box_text``.
    box_text : str, optional
        The box in words; default ``"LO–HI × the initial allocation"``.
    poses : array_like, optional
        Default: the 5-point workspace grid.
    marks : mapping, optional
        ``{label: tolerances}`` marked on the figure; the initial allocation always is.
    """
    poses = workspace_grid(machine) if poses is None else poses
    all_targets = np.union1d(np.asarray(targets, dtype=float), [reliability])
    front = cost_reliability_front(machine, all_targets, poses=poses,
                                   **({"bounds": bounds} if box is None else box))
    stack = front.attrs["stack"]
    at = front[np.isclose(front["target"], reliability)].iloc[0]
    allocations = {"initial": machine.initial_allocation, **(marks or {})}
    points = {label: allocation_point(machine, t, poses=poses)
              for label, t in allocations.items()}
    ax = plot_front(front, marks=points)
    table = front_file_table(front[["target", "required_index", "cost", "relative_cost",
                                    "relative_gap", "certified", "feasible", "binding"]].assign(
        relative_gap=[gap_bound(g) for g in front["relative_gap"]]))
    reached = int(front["feasible"].sum())
    words = f"box {bounds[0]:g}–{bounds[1]:g} × the initial allocation" if box_text is None \
        else f"box {box_text}"
    summary = {"front_points": int(len(front)), "front_reached": reached,
               "front_certified": bool(front.loc[front["feasible"], "certified"].all()),
               f"relative_cost_at_{reliability:g}":
                   float(at["relative_cost"]) if at["feasible"] else None}
    stack_text = (f"The worst-case stack (every output inside its limit for every "
                  f"combination of errors within their tolerances, Σ|∂y/∂x| t ≤ I at every "
                  f"pose)")
    if "error" in stack:
        answer = ((f"The cheapest allocation meeting {reliability:g} two-sided at every "
                   f"pose costs **{at['relative_cost']:.3g} ×** the initial allocation; "
                   if at["feasible"] else "") +
                  f"the worst-case stack cannot be held in the {words}: "
                  f"{stack['error'].split(';')[0]}.")
        answer = answer[0].upper() + answer[1:]
        method = f"{stack_text} has no allocation in this box."
    elif not at["feasible"]:
        answer = (f"{reliability:g} two-sided at every pose is not reachable in the {words}; "
                  f"the worst-case stack costs **{stack['relative_cost']:.3g} ×** the "
                  f"initial allocation.")
        method = (f"{stack_text} is a certified optimum, relative duality gap "
                  f"{gap_text(stack['relative_gap'])}.")
    else:
        ratio = stack["relative_cost"] / at["relative_cost"]
        summary.update(stack_relative_cost=float(stack["relative_cost"]),
                       stack_certified=bool(stack["certified"]),
                       stack_over_target_cost=float(ratio))
        answer = (f"The worst-case machine is **{ratio:.3g} times** as expensive as the "
                  f"cheapest one meeting {reliability:g} two-sided at every pose "
                  f"({stack['relative_cost']:.3g} against {at['relative_cost']:.3g} × the "
                  f"initial allocation, in the {words}).")
        method = (f"{stack_text} costs {stack['relative_cost']:.3g} × the initial allocation "
                  f"(certified optimum, relative duality gap "
                  f"{gap_text(stack['relative_gap'])}); the cheapest allocation meeting "
                  f"{reliability:g} two-sided at every pose costs {at['relative_cost']:.3g} ×.")
    method += (f" The front gives the certified optimal cost for the {reached} of "
               f"{len(front)} targets this box can reach (the same target for all six "
               f"outputs at every pose; `relative_gap` in `front.csv` is an upper bound); "
               f"the dashed line is the stack. Marked allocations sit at their worst "
               f"reliability over outputs and poses.")
    text = f"{answer}\n\n" + details("How the front is computed", method)
    return Section(title="Cost against reliability", text=text,
                   figures={"front.png": ax.figure}, tables={"front.csv": table},
                   summary=summary)


def system_section(machine, allocations, *, poses=None, rng=None) -> Section:
    """Worst-pose system reliability of each allocation, with the per-output bounds.

    Parameters
    ----------
    machine : Machine
    allocations : mapping
        ``{label: tolerances}``.
    poses : array_like, optional
        Default: the 5-point workspace grid.
    rng : None, int or numpy.random.Generator
    """
    poses = workspace_grid(machine) if poses is None else poses
    jacobian = machine.jacobian(poses)
    children = spawn(rng, len(allocations))
    units = axis_units(machine)
    rows, where = [], {}
    for child, (label, t) in zip(children, allocations.items()):
        result = worst_system_reliability(machine, t, poses, rng=child, jacobian=jacobian)
        w = result.worst
        where[label] = pose_text(result.poses[w], machine.axes, units, digits=6)
        rows.append({"allocation": label,
                     **pose_frame(result.poses[w], machine.axes, units,
                                  style="csv").iloc[0].to_dict(),
                     "system": result.probability[w], "error": result.error[w],
                     "product": result.product[w], "bonferroni": result.bonferroni[w],
                     "least_output": result.min_marginal[w]})
    table = pd.DataFrame(rows).set_index("allocation")
    lines = [f"| {label} | {where[label]} | {row['system']:.6f} ± {row['error']:.1g} | "
             f"{decimals_text(row['product'], 6, 'lower')} | "
             f"{bound_text(row['bonferroni'])} | "
             f"{decimals_text(row['least_output'], 6, 'upper')} |"
             for label, row in table.iterrows()]
    answer = "All six outputs inside at once at the worst grid pose: " + ", ".join(
        f"**{row['system']:.6f}** ({label})" for label, row in table.iterrows()) + "."
    method = ("A part is good only when all six outputs are inside their limits at once. "
              "For the linearised model this is a six-dimensional normal rectangle "
              "probability, computed exactly up to the stated numerical standard error; "
              "the product of the per-output probabilities is a lower bound (Šidák), "
              "Bonferroni a weaker one, and the least reliable output an upper bound. "
              "The worst pose of the grid is given as axis positions.")
    text = (f"{answer}\n\n"
            "| allocation | worst pose | all six inside | product | Bonferroni | least output |\n"
            "|---|---|---|---|---|---|\n" + "\n".join(lines) + "\n\n"
            + details("How it is computed", method))
    summary = {f"system_worst_{label}": float(value) for label, value in table["system"].items()}
    return Section(title="System reliability", text=text,
                   tables={"system_reliability.csv": table}, summary=summary)

