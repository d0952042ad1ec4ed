"""How much cheaper is a reliable machine than a worst-case-stacked one? (paper's machine)

Run as ``python -m studies.paper.tradeoff_study``. On the paper's machine (5^6 = 15 625 poses,
worst case over the grid, k1 = k2 = k3 = 1, costs relative to Table 4) it prints

1. the certified classical worst-case stack allocation (``Σ|∂y/∂x| t ≤ I`` at every pose)
   and its cost relative to Table 4, in the box [0.001, 1.5] × Table 4 (the default
   [0.5, 1.5] cannot hold it: the refusal is printed too);
2. the certified two-sided front for 50 targets from 0.9 to 1 − 1e−9 in the same box, the
   ratio stack cost / 99 % cost, and where the front would meet the stack cost if the
   z² law of an unbounded optimum went on;
3. the system reliability (all six outputs inside at once) at the worst pose for the
   initial (Table 4), the paper's (Table 6) and the two-sided optimal allocation, beside
   the product of the marginals, the Bonferroni bound and the least marginal, with a
   Monte-Carlo check of the linear model at that pose;
4. the certified bracket of the cheapest allocation whose system reliability is 0.99 at
   every pose (default box);
5. the time of the 50-point front: row screening and solves, and the solves against
   cold-started solves of the same rows (the simple reference) in the same run.

Nothing is asserted on times. BLAS is limited to one thread unless set otherwise.
"""

from __future__ import annotations

import numpy as np
from scipy.stats import norm

import allocation
import reliability
from allocation.solvers.convex import solve_convex_allocation
from allocation.per_pose.result_files import gap_text
from reliability.basics.display import axis_units, bound_text, pose_text
from reliability.basics.pass_rule import passes
from reliability.basics.streams import spawn
from reliability.first_order.fosm import required_index
from reliability.first_order.system_reliability import worst_system_reliability
from reliability.model.machine import OUTPUTS
from reliability.model.poses import workspace_grid
from studies.workflows.timing import best_time, one_blas_thread

from .tables import TABLE6

BOUNDS = (0.001, 1.5)  # × Table 4; wide enough that no item of the stack sits at a bound
TARGETS = 1.0 - np.logspace(-1, -9, 50)
SEED = 2023
MC_SAMPLES = 1_000_000
Z = 4.0  # standard errors accepted in the Monte-Carlo check


def stack_numbers(machine):
    """Print the certified stack allocation, and the default box's refusal."""
    print("1. Classical worst-case stack allocation (Σ|∂y/∂x| t ≤ I at every grid pose)")
    table4 = machine.initial_allocation
    problem = allocation.AllocationProblem.build(machine, side="stack", bounds=BOUNDS)
    worst = (problem.stack(table4) / machine.limits).max(axis=0)
    print("   stack / limit at the Table 4 tolerances: " +
          ", ".join(f"{o} {v:.2f}" for o, v in zip(OUTPUTS, worst)))
    try:
        allocation.AllocationProblem.build(machine, side="stack").solve_exact()
    except allocation.TargetUnreachableError as exc:
        print(f"   default box [0.5, 1.5]: {str(exc).split(';')[0]}")
    result = problem.solve_exact()
    reference = problem.cost.total(table4)
    status = result.to_frame()["status"].value_counts().to_dict()
    binding = result.requirements.index[result.requirements["binding_rows"] > 0]
    print(f"   box {BOUNDS} × Table 4: cost {result.cost:.6g} = "
          f"{result.cost / reference:.4f} × Table 4 (certified "
          f"{result.certificate['certified']}, relative duality gap "
          f"{gap_text(result.certificate['relative_gap'])}); items {status}; binding outputs "
          f"{', '.join(binding)}")
    return result.cost / reference


def front_numbers(machine, stack_relative):
    """Print the 50-point two-sided front and the stack/99 % ratio."""
    print("\n2. Certified two-sided front, worst case over the grid, box "
          f"{BOUNDS} × Table 4")
    front = allocation.cost_reliability_front(machine, TARGETS, bounds=BOUNDS)
    shown = front[["target", "required_index", "relative_cost", "relative_gap", "certified",
                   "binding"]].copy()
    shown.insert(1, "1-R", 1.0 - shown.pop("target"))
    print(shown.to_string(float_format=lambda v: f"{v:.4g}"))
    print(f"   all certified: {bool(front['certified'].all())}; stack: "
          f"{front.attrs['stack']['relative_cost']:.4f} × Table 4")
    at99 = allocation.cost_reliability_front(machine, [0.99], bounds=BOUNDS, stack=False)
    ratio = stack_relative / at99["relative_cost"][0]
    print(f"   R = 0.99: {at99['relative_cost'][0]:.4f} × Table 4; stack / 99 % cost = "
          f"{ratio:.2f}")
    last = front.iloc[-1]
    z_equal = last["required_index"] * np.sqrt(stack_relative / last["relative_cost"])
    print(f"   if cost kept growing as z² beyond 1 − 1e−9, it would reach the stack cost at "
          f"z = {z_equal:.2f}, i.e. 1 − R = {2 * norm.sf(z_equal):.2g}")
    return front


def system_numbers(machine, rng):
    """Print the worst-pose system reliability of three allocations, with a MC check."""
    print("\n3. System reliability (all six outputs inside at once), worst pose of the grid")
    poses = workspace_grid(machine)
    jacobian = machine.jacobian(poses)
    optimum = allocation.AllocationProblem.build(machine).solve_exact()
    allocations = {"initial (Table 4)": machine.initial_allocation,
                   "paper (Table 6)": machine.error_vector(TABLE6, default=None),
                   "two-sided optimum": optimum.tolerances}
    children = rng.spawn(2 * len(allocations))
    for i, (name, t) in enumerate(allocations.items()):
        result = worst_system_reliability(machine, t, poses, rng=children[2 * i],
                                          jacobian=jacobian, n_points=4096)
        w = result.worst
        pose = int(result.index[w])
        x = children[2 * i + 1].normal(size=(MC_SAMPLES, machine.n_errors)) * (t / 3)
        inside = np.all(passes(x @ jacobian[pose].T, machine.limits), axis=1).mean()
        se = np.sqrt(inside * (1 - inside) / MC_SAMPLES)
        z = (inside - result.probability[w]) / np.hypot(se, result.error[w])
        where = pose_text(poses[pose], machine.axes, axis_units(machine), 6)
        print(f"   {name:18s} at {where}: system {result.probability[w]:.6f} ± "
              f"{result.error[w]:.1g}; product {result.product[w]:.6f}; Bonferroni "
              f"{bound_text(result.bonferroni[w])}; least output {result.min_marginal[w]:.6f}; "
              f"{len(result.index)} poses evaluated exactly")
        print(f"   {'':18s} Monte-Carlo of the linear model ({MC_SAMPLES} draws): "
              f"{inside:.6f} ± {se:.1g}, z = {z:+.2f} (|z| ≤ {Z:g}: "
              f"{'agrees' if abs(z) <= Z else 'DISAGREES'})")


def bracket_numbers(machine, rng):
    """Print the certified bracket of the system-target allocation at R = 0.99."""
    print("\n4. Cheapest allocation with system reliability 0.99 at every pose (box [0.5, 1.5])")
    result = allocation.system_allocation(machine, 0.99, rng=rng)
    c = result.certificate
    reference = result.problem.cost.total(machine.initial_allocation)
    print(f"   lower bound (each output alone at 0.99): {c['lower_bound'] / reference:.4f} "
          "× Table 4")
    print(f"   Bonferroni point (each output at {1 - 0.01 / 6:.6f}): "
          f"{c['bonferroni_cost'] / reference:.4f} × Table 4")
    print(f"   tightened feasible allocation (each output at {c['output_target']:.6f}): "
          f"{result.cost / reference:.4f} × Table 4; worst system probability "
          f"{c['system_probability']:.6f} ± {c['system_error']:.1g} at pose "
          f"{c['worst_pose']} (checked with a {c['z']:g}-standard-error margin)")
    print(f"   gap: {c['relative_gap']:.1%} of the feasible cost; certified {c['certified']}, "
          f"feasible {result.feasible}")


def timing_numbers(machine):
    """Print the time of a 50-point front, and warm against cold solves of the same rows."""
    print("\n5. Time of the 50-point front")
    seconds, front = best_time(lambda: allocation.cost_reliability_front(
        machine, TARGETS, bounds=BOUNDS, stack=False), 1)
    split = front.attrs["seconds"]
    print(f"   total {seconds:.2f} s: build + row screening {split['build']:.2f} s, "
          f"50 warm-started certified solves {split['solve']:.2f} s")
    problem = allocation.AllocationProblem.build(
        machine, bounds=BOUNDS, targets=dict.fromkeys(OUTPUTS, TARGETS[-1]))
    z = required_index(TARGETS)

    def cold():
        for value in z:
            solve_convex_allocation(problem.cost.weights,
                                    problem.rows.matrix * (value / z[-1]) ** 2,
                                    problem.lower ** 2, problem.upper ** 2)

    cold_seconds, _ = best_time(cold, 1)
    print(f"   the same 50 solves cold-started: {cold_seconds:.2f} s "
          f"(warm start {cold_seconds / split['solve']:.1f}× faster)")


@one_blas_thread
def main() -> int:
    machine = reliability.hobbing_machine()
    children = spawn(SEED, 2)
    stack_relative = stack_numbers(machine)
    front_numbers(machine, stack_relative)
    system_numbers(machine, children[0])
    bracket_numbers(machine, children[1])
    timing_numbers(machine)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
