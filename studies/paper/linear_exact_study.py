"""The exact probability of the linearised output under truncated errors, checked by sampling.

Run as ``python -m studies.paper.linear_exact_study [--draws N] [--seed S]``. On the paper's
machine at its certified two-sided optimum (5-point grid, truncated reading) it takes three poses
(the worst grid poses of dx and of ex, and a pose drawn at random) and prints per output: the
normal approximation of FOSM (truncated σ), the exact probability of the linear model ``Σ J_oi
x_i`` with truncated-normal ``x_i`` (:mod:`reliability.first_order.linear_exact`), the Monte-Carlo
estimate of the same linear model from ``--draws`` draws (default 10⁷) and the z-score of the exact
value against it (binomial standard error).
"""

from __future__ import annotations

import argparse
import dataclasses

import numpy as np
import pandas as pd

import reliability
from allocation import AllocationProblem
from reliability.basics.display import axis_units, pose_text
from reliability.basics.pass_rule import passes
from reliability.basics.streams import generator, spawn
from reliability.first_order.fosm import fosm
from reliability.first_order.linear_exact import linear_two_sided
from reliability.model.error_draws import draw_errors
from reliability.model.poses import workspace_grid
from studies.workflows.timing import one_blas_thread

CHUNK = 500_000


def linear_monte_carlo(machine, tolerances, pose, draws: int, rng) -> np.ndarray:
    """Share of ``draws`` truncated-normal error vectors with |J x| < I, per output."""
    jac = machine.jacobian(pose)
    inside = np.zeros(6)
    rng = generator(rng)
    for start in range(0, draws, CHUNK):
        size = min(CHUNK, draws - start)
        x = draw_errors(tolerances, (size,), distribution="truncated", rng=rng)
        inside += passes(x @ jac.T, machine.limits).sum(axis=0)
    return inside / draws


def study(draws: int, seed: int) -> list[tuple[np.ndarray, pd.DataFrame]]:
    machine = dataclasses.replace(reliability.hobbing_machine(), distribution="truncated")
    grid = workspace_grid(machine, 5)
    problem = AllocationProblem.build(machine, grid)
    t = problem.solve_exact().tolerances
    on_grid = fosm(machine, t, grid, distribution="truncated")
    pose_stream, *draw_streams = spawn(seed, 4)
    low = np.array([axis.stroke[0] for axis in machine.axis_specs])
    high = np.array([axis.stroke[1] for axis in machine.axis_specs])
    poses = [grid[on_grid.worst_pose[0]], grid[on_grid.worst_pose[3]],
             low + (high - low) * generator(pose_stream).random(len(low))]
    out = []
    for pose, stream in zip(poses, draw_streams):
        jac = machine.jacobian(pose)
        exact = linear_two_sided(machine.limits, np.abs(jac) * t / 3.0)
        normal = fosm(machine, t, pose[None], distribution="truncated").two_sided[0]
        sampled = linear_monte_carlo(machine, t, pose, draws, stream)
        z = (sampled - exact) / np.sqrt(exact * (1 - exact) / draws)
        out.append((pose, pd.DataFrame({
            "normal_approx": normal, "exact_linear": exact, "mc_linear": sampled,
            "z_exact": z, "exact_minus_normal": exact - normal},
            index=pd.Index(machine.outputs, name="output"))))
    return out


@one_blas_thread
def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--draws", type=int, default=10_000_000)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    machine = reliability.hobbing_machine()
    print(f"paper's machine, certified two-sided optimum of the 5-point grid problem, "
          f"errors normal σ = t/3 truncated at ±t; {args.draws} draws of the linear model "
          f"per pose (seed {args.seed})")
    for pose, frame in study(args.draws, args.seed):
        print(f"\npose {pose_text(pose, machine.axes, axis_units(machine), 6)}")
        print(frame.to_string(float_format="{:.7f}".format))


if __name__ == "__main__":
    main()
