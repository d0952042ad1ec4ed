"""The report's work-zone section: the zone drawn with the tool points of the grid poses it
holds, the worst poses in the zone and over the whole strokes (positions and tool points),
and the cost and machine yield with and without the zone
(:func:`studies.workflows.zone_comparison.zone_comparison`).
"""

from __future__ import annotations

import math

import pandas as pd
from matplotlib.figure import Figure
from matplotlib.patches import Circle, Rectangle

from reliability.basics.display import (OUTPUT_UNITS, axis_units, interval_text, pose_text,
                                        with_unit)
from reliability.model.work_zone import tool_frames
from reliability.sampling.yield_estimate import yield_text

from .markdown import details, markdown_table
from .section import Section

WORKSPACE_WORDS = {"zone": "in the work zone", "strokes": "over the whole strokes"}


def zone_section(comparison) -> Section:
    """The section of a :class:`~studies.workflows.zone_comparison.ZoneComparison`."""
    machine = comparison.machine
    inside = len(comparison.zone_poses)
    rows = allocation_rows(comparison)
    answer = (f"**{inside} of the {comparison.grid_poses} poses** of the "
              f"{comparison.points}-point grid lie in the work zone; " + _zone_cost(rows))
    method = (f"Workspace: the {machine.work_zone.text()} (tool point and tilt in the "
              f"workpiece frame). FOSM, the allocation, the grid experiment and the machine "
              f"yield of this report use the poses inside only. The table sets the same "
              f"machine without its zone (every pose of the strokes) beside it; both optima "
              f"are solved on the grid poses of their workspace, in the same box. The worst "
              f"poses are the initial allocation's, with the tool point (mm, workpiece frame) "
              f"and tool tilt.")
    text = "\n\n".join([
        answer, markdown_table(rows, index=False),
        "Worst pose of each output for the initial allocation:",
        markdown_table(worst_rows(comparison), index=False),
        details("How the zone is used", method)])
    return Section(
        title="The work zone", text=text, figures={"zone.png": zone_figure(comparison)},
        tables={"zone_allocations.csv": comparison.allocations,
                "zone_worst_poses.csv": comparison.worst},
        summary={"work_zone": machine.work_zone.to_dict(), "zone_grid_poses": inside,
                 "grid_poses": comparison.grid_poses,
                 "zone_yield": comparison.allocations["yield zone"].to_dict(),
                 "strokes_yield": comparison.allocations["yield strokes"].to_dict(),
                 "zone_relative_cost": comparison.allocations["cost"].to_dict()})


def _zone_cost(rows: pd.DataFrame) -> str:
    """The cost of the optimum for the zone as :func:`allocation_rows` shows it."""
    zone = rows[rows["allocation"] == "optimum for the zone"]
    if not len(zone):
        return "no allocation in the box meets the targets there."
    return (f"the optimum for the zone costs **{zone['cost (× initial)'].iloc[0]} ×** the "
            f"initial allocation.")


def allocation_rows(comparison) -> pd.DataFrame:
    """Cost and yield (with its interval) of each allocation in each workspace."""
    rows = []
    for label, row in comparison.allocations.iterrows():
        rows.append({"allocation": label, "cost (× initial)": f"{row['cost']:.4g}",
                     **{f"yield {WORKSPACE_WORDS[name]}":
                        f"{yield_text(row[f'yield {name}'])} "
                        f"{interval_text(row[f'yield {name} low'], row[f'yield {name} high'])}"
                        for name in WORKSPACE_WORDS}})
    return pd.DataFrame(rows)


def worst_rows(comparison) -> pd.DataFrame:
    """Each output's worst pose in each workspace, its tool point, tilt and σ."""
    machine = comparison.machine
    rows = []
    for (name, output), row in comparison.worst.iterrows():
        unit = OUTPUT_UNITS[machine.outputs.index(output)]
        rows.append({"output": output, "workspace": WORKSPACE_WORDS[name],
                     "worst pose": pose_text(row[list(machine.axes)].to_numpy(dtype=float),
                                             machine.axes, axis_units(machine)),
                     "tool point [mm]": f"({row['x']:.1f}, {row['y']:.1f}, {row['z']:.1f})",
                     "tilt [deg]": f"{math.degrees(row['tilt']):.1f}",
                     "sigma": with_unit(row["sigma"], unit, 4)})
    return pd.DataFrame(rows).sort_values("output", kind="stable")


def zone_figure(comparison) -> Figure:
    """Top (x–y) and side (x–z) views of the zone, the tool points of the whole grid
    (grey) and of the poses inside (blue), and the initial allocation's worst poses."""
    figure = Figure(figsize=(10, 4.5))
    views = (("x", "y", 0, 1), ("x", "z", 0, 2))
    inside = tool_frames(comparison.machine, comparison.zone_poses)[0]
    for position, (first, second, i, j) in enumerate(views):
        ax = figure.add_subplot(1, 2, position + 1)
        ax.scatter(comparison.whole_points[:, i], comparison.whole_points[:, j], s=4,
                   color="0.8", label="tool points of the grid")
        ax.scatter(inside[:, i], inside[:, j], s=10, color="tab:blue",
                   label="tool points in the zone")
        for name, style in (("zone", {"facecolors": "none", "edgecolors": "tab:red"}),
                            ("strokes", {"marker": "x", "color": "tab:orange"})):
            worst = comparison.worst.loc[name]
            ax.scatter(worst[first], worst[second], s=60, **style,
                       label=f"worst poses {WORKSPACE_WORDS[name]}")
        ax.add_patch(_outline(comparison.machine.work_zone, i, j))
        ax.set_xlabel(f"{first} [mm]")
        ax.set_ylabel(f"{second} [mm]")
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_title("top view" if second == "y" else "side view")
    figure.axes[0].legend(fontsize=7, loc="upper left")
    figure.suptitle("Work zone (workpiece frame) and the tool points of the grid poses")
    return figure


def _outline(zone, i: int, j: int):
    """The zone's outline in the view of coordinates ``i`` (horizontal) and ``j``."""
    low, high = zone.bounding_box()
    style = {"fill": False, "edgecolor": "tab:green", "linewidth": 1.5}
    if zone.shape == "cylinder" and (i, j) == (0, 1):
        return Circle(zone.centre, zone.radius, **style)
    return Rectangle((low[i], low[j]), high[i] - low[i], high[j] - low[j], **style)
