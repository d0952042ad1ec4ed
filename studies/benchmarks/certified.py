"""The certified worst pose over the continuous workspace against grids of the strokes.

Run as ``python -m studies.benchmarks.certified [--rtol R] [--reading sigma|stack]
[--machines hobbing trunnion swivel gantry] [--allocations initial table6 optimum]
[--frame tool|workpiece] [--frames]``. For the paper's machine
(``reliability.hobbing_machine()``: its initial allocation, the paper's Table 6 and the
certified two-sided optimum of the 5-point grid problem), the 5-axis trunnion and the C-table,
B-head swivel machine of the tests and the example gantry (initial allocation and its
two-sided optimum), with the outputs read in ``--frame`` (default: each machine's own), it
prints per output

* the worst σ (or worst-case stack ``Σ|J| t``) on the 5-, 9- and 13-point grids of the
  workspace (:func:`reliability.model.poses.workspace_grid`: full turns without repeating 0 = 2π)
  and the time of each grid, evaluated in slices of the first axis by the simple vectorised
  reference (:func:`reliability.first_order.fosm.pose_sigma`, or the Jacobian in chunks);
* the certified worst value, its rigorous bound, the gap, the boxes evaluated and the
  time of :func:`reliability.first_order.workspace_search.certified_worst`;
* ``miss13``: how much larger the certified worst value is than the 13-point grid's;

and the ratio of the certificate's time to each grid's. A grid gives only a lower bound of
the worst value; the certificate gives both ends. With ``--frames`` it prints instead, per
machine and allocation, the certificate's time with the outputs in the tool frame and in the
workpiece frame (the least of :data:`REPEATS` runs, wall and processor time) and their
ratio. Nothing is asserted on times.
"""

from __future__ import annotations

import argparse
import dataclasses
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

ROOT = Path(__file__).resolve().parents[2]
GRIDS = (5, 9, 13)
MACHINES = {"hobbing": reliability.hobbing_machine,
            "trunnion": lambda: reliability.load_machine(ROOT / "tests/machines/trunnion5.toml"),
            "swivel": lambda: reliability.load_machine(ROOT / "tests/machines/swivel5.toml"),
            "gantry": lambda: reliability.load_machine(ROOT / "docs/examples/gantry5.toml")}
#: Runs of each certificate in the frame comparison; the least time is reported.
REPEATS = 3


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


def frame_times(machine, tolerances, rtol: float, reading: str) -> pd.DataFrame:
    """The certificate's least wall and processor time over :data:`REPEATS` runs and its
    boxes, with the outputs in the tool and in the workpiece frame."""
    rows = {}
    for frame in ("tool", "workpiece"):
        framed = dataclasses.replace(machine, frame=frame)
        wall, processor = [], []
        for _ in range(REPEATS):
            started, used = time.perf_counter(), time.process_time()
            table = certified_worst(framed, tolerances, rtol=rtol, reading=reading)
            wall.append(time.perf_counter() - started)
            processor.append(time.process_time() - used)
        rows[frame] = {"seconds": min(wall), "cpu_seconds": min(processor),
                       "boxes": int(table["calls"].sum()),
                       "certified": bool(table["certified"].all())}
    return pd.DataFrame(rows).T


def print_frames(machine, label: str, tolerances, rtol: float, reading: str) -> None:
    times = frame_times(machine, tolerances, rtol, reading)
    ratio = times.loc["workpiece"] / times.loc["tool"]
    print(f"{machine.name}, {label}: " + "; ".join(
        f"{frame} {row.seconds:.2f} s (cpu {row.cpu_seconds:.2f} s, {row.boxes:,} boxes"
        f"{'' if row.certified else ', NOT certified'})" for frame, row in times.iterrows())
        + f"; workpiece / tool {ratio['seconds']:.2f} (cpu {ratio['cpu_seconds']:.2f})")


@one_blas_thread
def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rtol", type=float, default=1e-3)
    parser.add_argument("--reading", choices=("sigma", "stack"), default="sigma")
    parser.add_argument("--machines", nargs="+", default=("hobbing", "trunnion"),
                        choices=tuple(MACHINES))
    parser.add_argument("--allocations", nargs="+", default=("initial", "table6", "optimum"),
                        choices=("initial", "table6", "optimum"))
    parser.add_argument("--frame", choices=("tool", "workpiece"), default=None,
                        help="frame of the outputs (default: each machine's own)")
    parser.add_argument("--frames", action="store_true",
                        help="time the certificate in both frames instead of the grids")
    args = parser.parse_args(argv)
    for name in args.machines:
        machine = MACHINES[name]()
        if args.frame is not None:
            machine = dataclasses.replace(machine, frame=args.frame)
        for label, t in allocations(machine, name, args.allocations).items():
            if args.frames:
                print_frames(machine, label, t, args.rtol, args.reading)
                continue
            frame = compare(machine, t, args.rtol, args.reading)
            grid_seconds = frame.attrs["grid_seconds"]
            total = frame["seconds"].sum()
            reading = (f"sigma reading ({machine.distribution} errors, k = 3)"
                       if args.reading == "sigma" else "worst-case stack reading (Σ|J| t)")
            print(f"\n{machine.name}: {label} allocation, {reading}, rtol {args.rtol:g}, "
                  f"outputs in the {machine.frame} frame")
            print(frame.to_string(float_format="{:.6g}".format))
            sizes = {p: np.prod([len(a) for a in grid_axis_points(machine, p)]) for p in GRIDS}
            print("grid times: " + ", ".join(f"{p} points ({sizes[p]:,} poses) {s:.2f} s"
                                             for p, s in grid_seconds.items()))
            print(f"certificate: {int(frame['calls'].sum()):,} boxes, {total:.2f} s = "
                  + ", ".join(f"{total / grid_seconds[p]:.2f} × the {p}-point grid"
                              for p in GRIDS))


if __name__ == "__main__":
    main()
