"""The certified worst pose over the continuous workspace against grids of the strokes.

Run as ``python -m studies.benchmarks.certified [--rtol R] [--allocation initial|optimum]``.
For the paper's machine (``reliability.hobbing_machine()``) and the 5-axis trunnion of the
tests, it prints per output

* the worst σ on the 5-, 9- and 13-point grids and the time of each grid (σ of every pose,
  :func:`reliability.fosm.pose_sigma`, the simple vectorised reference);
* the certified worst σ, its rigorous bound, the boxes evaluated and the time of
  :func:`reliability.worst_case.certified_worst`;

and the ratio of the certificate's time to the 9- and 13-point grids'. A grid gives only a
lower bound of the worst σ; the certificate gives both ends. ``--allocation optimum`` uses
the certified two-sided optimum of the 5-point grid problem instead of the initial
allocation. Nothing is asserted on times.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import pandas as pd

import reliability
from allocation import AllocationProblem
from reliability.fosm import error_sigma, pose_sigma
from reliability.poses import workspace_grid
from reliability.worst_case import certified_worst
from studies.workflows.timing import one_blas_thread

TRUNNION = Path(__file__).resolve().parents[2] / "tests" / "machines" / "trunnion5.toml"
GRIDS = (5, 9, 13)


def grid_worst(machine, tolerances, points: int) -> tuple[np.ndarray, float]:
    """Worst σ per output on the ``points``-point grid of the strokes (both ends of every
    stroke, full turns included) and its time."""
    low = np.array([axis.stroke[0] for axis in machine.axis_specs])
    high = np.array([axis.stroke[1] for axis in machine.axis_specs])
    started = time.perf_counter()
    axes = [np.linspace(lo, hi, points) for lo, hi in zip(low, high)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, len(low))
    sigma = pose_sigma(machine, grid, error_sigma(tolerances, 3.0, machine.distribution))
    return sigma.max(axis=0), time.perf_counter() - started


def allocation(machine, which: str) -> np.ndarray:
    if which == "initial":
        return machine.initial_allocation
    problem = AllocationProblem.build(machine, workspace_grid(machine, 5))
    return problem.solve_exact().tolerances


def compare(machine, tolerances, rtol: float) -> pd.DataFrame:
    """One row per output: grid worst σ and times, certified σ, bound, boxes, time."""
    frame = pd.DataFrame(index=pd.Index(machine.outputs, name="output"))
    times = {}
    for points in GRIDS:
        worst, seconds = grid_worst(machine, tolerances, points)
        frame[f"grid{points}_sigma"] = worst
        times[points] = seconds
    table = certified_worst(machine, tolerances, rtol=rtol)
    frame["certified_sigma"] = table["sigma"]
    frame["sigma_bound"] = table["sigma_bound"]
    frame["certified"] = table["certified"]
    frame["boxes"] = table["calls"]
    frame["seconds"] = table["seconds"]
    frame.attrs["grid_seconds"] = times
    return frame


@one_blas_thread
def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rtol", type=float, default=1e-3)
    parser.add_argument("--allocation", choices=("initial", "optimum"), default="initial")
    parser.add_argument("--machines", nargs="+", default=("hobbing", "trunnion"),
                        choices=("hobbing", "trunnion"))
    args = parser.parse_args(argv)
    machines = {"hobbing": reliability.hobbing_machine,
                "trunnion": lambda: reliability.load_machine(TRUNNION)}
    for name in args.machines:
        machine = machines[name]()
        t = allocation(machine, args.allocation)
        frame = compare(machine, t, args.rtol)
        grid_seconds = frame.attrs["grid_seconds"]
        total = frame["seconds"].sum()
        print(f"\n{machine.name} ({args.allocation} allocation, {machine.distribution} "
              f"reading, rtol {args.rtol:g})")
        print(frame.to_string(float_format="{:.6g}".format))
        print("grid times: " + ", ".join(f"{p} points {s:.2f} s" for p, s in
                                         grid_seconds.items()))
        print(f"certificate: {int(frame['boxes'].sum())} boxes, {total:.2f} s = "
              f"{total / grid_seconds[9]:.2f} × the 9-point grid, "
              f"{total / grid_seconds[13]:.2f} × the 13-point grid")


if __name__ == "__main__":
    main()
