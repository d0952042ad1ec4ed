"""A machine with a work zone beside the same machine without it: the worst poses, the cost
of the cheapest allocation on the grid and the machine yield, each in the zone and over the
whole strokes (docs/machine-file.md, ``[workzone]``).

The allocation is solved on the grid (workspace 'grid') in both workspaces, in the same box,
so that the two costs differ by the workspace alone.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import pandas as pd

from allocation import AllocationProblem, TargetUnreachableError
from allocation.per_pose.result_files import written_tolerances
from reliability.basics import checks
from reliability.basics.errors import InputError
from reliability.basics.streams import spawn
from reliability.first_order.fosm import fosm
from reliability.model.machine import OUTPUTS
from reliability.model.poses import full_grid, workspace_grid
from reliability.model.work_zone import tool_frames, tilt_of_axes
from reliability.sampling.machine_yield import DEFAULT_MACHINES, machine_yield

@dataclass(frozen=True)
class ZoneComparison:
    """What the work zone changes (see :func:`zone_comparison`).

    Attributes
    ----------
    machine : Machine
        With its work zone.
    points : int
        Grid points per axis.
    grid_poses : int
        Poses of the whole grid (``points ** n_axes``).
    zone_poses : ndarray (n_inside, n_axes)
        The grid poses inside the zone.
    whole_points : ndarray (grid_poses, 3)
        Tool points of every grid pose, mm, workpiece frame.
    worst : DataFrame
        Per workspace and output: the initial allocation's worst grid pose (one column per
        axis), its tool point ``x``, ``y``, ``z`` (mm), ``tilt`` (rad) and ``sigma``.
    allocations : DataFrame
        Per allocation (initial, the optimum for each workspace): ``cost`` relative to the
        initial allocation's, and the machine yield and its interval in each workspace.
    """

    machine: object
    points: int
    grid_poses: int
    zone_poses: np.ndarray
    whole_points: np.ndarray
    worst: pd.DataFrame
    allocations: pd.DataFrame


def zone_comparison(machine, *, points: int = 5, side: str = "two_sided", bounds=None,
                    machines: int = DEFAULT_MACHINES, rng=None) -> ZoneComparison:
    """The machine in its work zone beside the same machine over the whole strokes.

    Parameters
    ----------
    machine : Machine
        With a work zone.
    points : int
        Grid points per axis.
    side : {'two_sided', 'one_sided'}
        Reading of the targets.
    bounds : (float, float), optional
        Tolerance box as factors of the initial allocation (default the machine file's
        ``[bounds]``, else [0.5, 1.5]), the same in both workspaces.
    machines : int
        Built machines per machine yield: the same built machines for every allocation and
        workspace, so that a machine failing in the zone fails over the strokes too.
    rng : None, int or numpy.random.Generator

    Returns
    -------
    ZoneComparison
    """
    if machine.work_zone is None:
        raise InputError("machine: it has no work zone ([workzone] in the machine "
                                "file) to compare with the whole strokes")
    points = checks.positive_int(points, "points", 2)
    strokes = replace(machine, work_zone=None)
    spaces = {"zone": machine, "strokes": strokes}
    problems = {name: AllocationProblem.build(m, workspace_grid(m, points), side=side,
                                              bounds=bounds)
                for name, m in spaces.items()}
    shown = {"initial": machine.initial_allocation}
    for name, problem in problems.items():
        try:
            shown[f"optimum for the {name}"] = written_tolerances(problem.solve_exact())
        except TargetUnreachableError:
            continue
    grid = full_grid(machine, points)
    return ZoneComparison(
        machine=machine, points=points, grid_poses=len(grid),
        zone_poses=problems["zone"].poses, whole_points=tool_frames(machine, grid)[0],
        worst=_worst_table(spaces, problems, machine.initial_allocation),
        allocations=_allocation_table(spaces, problems["zone"], shown, points, machines,
                                      rng))


def _worst_table(spaces, problems, tolerances) -> pd.DataFrame:
    rows = []
    for name, m in spaces.items():
        problem = problems[name]
        result = fosm(m, tolerances, problem.poses, jacobian=problem.jacobian,
                      distribution=m.distribution)
        poses = result.poses[result.worst_pose]
        points, axes = tool_frames(m, poses)
        for o, output in enumerate(OUTPUTS):
            rows.append({"workspace": name, "output": output,
                         **dict(zip(m.axes, poses[o])),
                         "x": points[o, 0], "y": points[o, 1], "z": points[o, 2],
                         "tilt": tilt_of_axes(axes[o]),
                         "sigma": result.sigma[result.worst_pose[o], o]})
    return pd.DataFrame(rows).set_index(["workspace", "output"])


def _allocation_table(spaces, zone_problem, shown, points, machines, rng) -> pd.DataFrame:
    initial_cost = zone_problem.cost.total(zone_problem.reference)
    draws = spawn(rng, 1)[0].bit_generator.seed_seq  # the same built machines every time
    rows = []
    for label, t in shown.items():
        row = {"allocation": label, "cost": zone_problem.cost.total(t) / initial_cost}
        for name, m in spaces.items():
            estimate = machine_yield(m, t, points=points, machines=machines,
                                     rng=draws)
            row.update({f"yield {name}": estimate.estimate,
                        f"yield {name} low": estimate.lower,
                        f"yield {name} high": estimate.upper})
        rows.append(row)
    return pd.DataFrame(rows).set_index("allocation")
