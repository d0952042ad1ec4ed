"""The certified worst pose over the continuous workspace against grids of the strokes.

Run as ``python -m studies.benchmarks.certified [--rtol R] [--reading sigma|stack]
[--machines hobbing trunnion] [--allocations initial table6 optimum]``. For the paper's
machine (``reliability.hobbing_machine()``: its initial allocation, the paper's Table 6 and
the certified two-sided optimum of the 5-point grid problem) and the 5-axis trunnion of the
tests (initial allocation and its two-sided optimum), it prints per output

* the worst σ (or worst-case stack ``Σ|J| t``) on the 5-, 9- and 13-point grids of the
  workspace (:func:`reliability.model.poses.workspace_grid`: full turns without repeating 0 = 2π)
  and the time of each grid, evaluated in slices of the first axis by the simple vectorised
  reference (:func:`reliability.first_order.fosm.pose_sigma`, or the Jacobian in chunks);
* the certified worst value, its rigorous bound, the gap, the boxes evaluated and the
  time of :func:`reliability.first_order.workspace_search.certified_worst`;
* ``miss13``: how much larger the certified worst value is than the 13-point grid's;

and the ratio of the certificate's time to each grid's. A grid gives only a lower bound of
the worst value; the certificate gives both ends. Nothing is asserted on times.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import pandas as pd

import reliability
from allocation import AllocationProblem
from reliability.basics.chunks import chunks, jacobian_bytes
from reliability.first_order.fosm import error_sigma, pose_sigma
from reliability.first_order.workspace_search import certified_worst
from reliability.model.poses import grid_axis_points, workspace_grid
from studies.paper.tables import TABLE6
from studies.workflows.timing import one_blas_thread

TRUNNION = Path(__file__).resolve().parents[2] / "tests" / "machines" / "trunnion5.toml"
GRIDS = (5, 9, 13)
MACHINES = {"hobbing": reliability.hobbing_machine,
            "trunnion": lambda: reliability.load_machine(TRUNNION)}


def grid_worst(machine, tolerances, points: int, reading: str) -> tuple[np.ndarray, float]:
    """Worst value per output on the ``points``-point workspace grid and its time, one
    slice of the first axis at a time (the whole 13-point grid of six axes would not fit
    in memory at once)."""
    started = time.perf_counter()
    axes = grid_axis_points(machine, points)
    rest = np.stack(np.meshgrid(*axes[1:], indexing="ij"), axis=-1).reshape(-1, len(axes) - 1)
    worst = np.zeros(len(machine.outputs))
    for first in axes[0]:
        poses = np.column_stack([np.full(len(rest), first), rest])
        worst = np.maximum(worst, _values(machine, tolerances, poses, reading).max(axis=0))
    return worst, time.perf_counter() - started


def _values(machine, tolerances, poses, reading):
    if reading == "sigma":
        return pose_sigma(machine, poses, error_sigma(tolerances, 3.0, machine.distribution))
    out = np.empty((len(poses), len(machine.outputs)))
    for part in chunks(len(poses), jacobian_bytes(machine)):
        out[part] = np.abs(machine.jacobian(poses[part])) @ tolerances
    return out


def allocations(machine, name: str, wanted) -> dict:
    """The allocations compared on a machine: ``initial``, ``table6`` (the paper's
    machine only) and ``optimum`` (the certified two-sided optimum of the 5-point grid)."""
    out = {}
    if "initial" in wanted:
        out["initial"] = machine.initial_allocation
    if "table6" in wanted and name == "hobbing":
        out["table6"] = machine.error_vector(TABLE6, default=None)
    if "optimum" in wanted:
        problem = AllocationProblem.build(machine, workspace_grid(machine, 5))
        out["optimum"] = problem.solve_exact().tolerances
    return out


def compare(machine, tolerances, rtol: float, reading: str) -> pd.DataFrame:
    """One row per output: grid worst values and times, the certificate and its cost."""
    frame = pd.DataFrame(index=pd.Index(machine.outputs, name="output"))
    times = {}
    for points in GRIDS:
        worst, seconds = grid_worst(machine, tolerances, points, reading)
        frame[f"grid{points}"] = worst
        times[points] = seconds
    table = certified_worst(machine, tolerances, rtol=rtol, reading=reading)
    frame["certified"] = table[reading]
    frame["bound"] = table[f"{reading}_bound"]
    frame["gap"] = table["gap"]
    frame["ok"] = table["certified"]
    frame["miss13"] = table[reading] / frame["grid13"] - 1.0
    frame["calls"] = table["calls"]
    frame["seconds"] = table["seconds"]
    frame.attrs["grid_seconds"] = times
    return frame


@one_blas_thread
def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rtol", type=float, default=1e-3)
    parser.add_argument("--reading", choices=("sigma", "stack"), default="sigma")
    parser.add_argument("--machines", nargs="+", default=("hobbing", "trunnion"),
                        choices=tuple(MACHINES))
    parser.add_argument("--allocations", nargs="+", default=("initial", "table6", "optimum"),
                        choices=("initial", "table6", "optimum"))
    args = parser.parse_args(argv)
    for name in args.machines:
        machine = MACHINES[name]()
        for label, t in allocations(machine, name, args.allocations).items():
            frame = compare(machine, t, args.rtol, args.reading)
            grid_seconds = frame.attrs["grid_seconds"]
            total = frame["seconds"].sum()
            reading = (f"sigma reading ({machine.distribution} errors, k = 3)"
                       if args.reading == "sigma" else "worst-case stack reading (Σ|J| t)")
            print(f"\n{machine.name}: {label} allocation, {reading}, rtol {args.rtol:g}")
            print(frame.to_string(float_format="{:.6g}".format))
            sizes = {p: np.prod([len(a) for a in grid_axis_points(machine, p)]) for p in GRIDS}
            print("grid times: " + ", ".join(f"{p} points ({sizes[p]:,} poses) {s:.2f} s"
                                             for p, s in grid_seconds.items()))
            print(f"certificate: {int(frame['calls'].sum()):,} boxes, {total:.2f} s = "
                  + ", ".join(f"{total / grid_seconds[p]:.2f} × the {p}-point grid"
                              for p in GRIDS))


if __name__ == "__main__":
    main()
