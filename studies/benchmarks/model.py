"""Benchmark and sanity report of the machine model on the paper's 5^6 grid.

Run as ``python -m studies.benchmarks.model``. It prints

1. the time of the batched FOSM (``m.jacobian(grid)`` + ``fosm(..., jacobian=J)``) for one
   allocation against a plain reference that loops over the 15 625 poses in Python, both
   measured in this run (best of a few repeats, ``time.perf_counter``), their ratio, and the
   largest difference between the two sets of numbers;
2. the largest relative residual of the linear model against the exact Eq. (18) at the
   Table 4 tolerances (errors = +t, and random ±t draws);
3. worst-pose β and P (one- and two-sided) per output for the initial allocation (Table 4)
   and the paper's optimised allocation (Table 6), and which meets the 99 % target.

Nothing is asserted on times; the ratio is the result.
"""

from __future__ import annotations

import argparse

import numpy as np
from scipy.special import ndtr

import reliability
from reliability.basics.streams import generator
from reliability.first_order.fosm import fosm
from reliability.model.poses import workspace_grid
from studies.paper.tables import TABLE6
from studies.workflows.timing import best_time, one_blas_thread



def batched(machine, tolerances, grid):
    """The toolkit's path: one batched Jacobian, one FOSM call."""
    jac = machine.jacobian(grid)
    result = fosm(machine, tolerances, grid, jacobian=jac)
    return np.stack([result.sigma, result.beta, result.one_sided, result.two_sided])


def per_pose_reference(machine, tolerances, poses):
    """The simple reference: a Python loop over poses, σ, β and P pose by pose."""
    sigma_x2 = (np.asarray(tolerances) / 3.0) ** 2
    limits = machine.limits
    out = np.empty((4, len(poses), 6))
    for p, q in enumerate(poses):
        jac = machine.jacobian(q)                      # (6, n_errors)
        sigma = np.sqrt((jac * jac) @ sigma_x2)        # Eq. (20)
        beta = limits / sigma                          # Eq. (21), zero mean
        out[0, p], out[1, p] = sigma, beta
        out[2, p] = ndtr(beta)                         # Eq. (22)
        out[3, p] = ndtr(beta) - ndtr(-beta)           # P(|y| < I)
    return out


def largest_relative_residual(machine, tolerances, grid, jac, n_random=20, seed=0):
    """max over draws and poses of |y_exact − J x|, per output.

    Returned relative to the output's largest linear value over the grid (its size there)
    and relative to its design limit.
    """
    rng = generator(seed)
    draws = [tolerances] + [tolerances * rng.choice([-1.0, 1.0], size=tolerances.shape)
                            for _ in range(n_random)]
    to_size, to_limit = np.zeros(6), np.zeros(6)
    for x in draws:
        linear = jac @ x
        residual = np.abs(machine.comprehensive_error(grid, x) - linear).max(axis=0)
        to_size = np.maximum(to_size, residual / np.abs(linear).max(axis=0))
        to_limit = np.maximum(to_limit, residual / machine.limits)
    return to_size, to_limit, len(draws)


def reliability_table(machine, allocations, grid, jac):
    """Worst-pose β and probabilities per output and allocation, printed."""
    outputs = machine.outputs
    header = f"{'allocation':<12}{'':<14}" + "".join(f"{o:>10}" for o in outputs)
    print(header)
    print("-" * len(header))
    verdicts = {}
    for label, tolerances in allocations.items():
        result = fosm(machine, tolerances, grid, jacobian=jac)
        beta_worst = result.beta.min(axis=0)
        rows = [("worst beta", beta_worst, "{:10.4f}"),
                ("P one-sided", result.worst("one_sided"), "{:10.5f}"),
                ("P two-sided", result.worst("two_sided"), "{:10.5f}")]
        for i, (name, values, fmt) in enumerate(rows):
            lead = label if i == 0 else ""
            print(f"{lead:<12}{name:<14}" + "".join(fmt.format(v) for v in values))
        verdicts[label] = (result.meets_targets("one_sided"), result.meets_targets("two_sided"))
        print()
    target = machine.targets
    print(f"Target: P >= {target[0]:.2f} at every grid pose for every output "
          f"(one-sided: beta >= 2.3263; two-sided: beta >= 2.5758).")
    for label, (one, two) in verdicts.items():
        fails_one = [o for o, ok in zip(outputs, one) if not ok]
        fails_two = [o for o, ok in zip(outputs, two) if not ok]
        print(f"  {label:<10} one-sided (paper, Eq. 22): "
              f"{'MEETS' if one.all() else 'fails ' + ', '.join(fails_one)};"
              f"  two-sided (exact): {'MEETS' if two.all() else 'fails ' + ', '.join(fails_two)}")


@one_blas_thread
def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3, help="timing repeats (best of)")
    parser.add_argument("--reference-poses", type=int, default=None,
                        help="poses for the per-pose loop (default: all; fewer are scaled)")
    args = parser.parse_args(argv)

    m = reliability.hobbing_machine()
    grid = workspace_grid(m)
    n_poses = len(grid)
    t4 = m.initial_allocation
    print(f"Machine: {m.name}; grid {grid.shape[0]} poses × {grid.shape[1]} axes, "
          f"{m.n_errors} errors\n")

    # 1. batched versus per-pose reference -------------------------------------------------
    print("1. FOSM on the grid, Table 4 allocation")
    batch_time, batch = best_time(lambda: batched(m, t4, grid), args.repeats)
    n_ref = n_poses if args.reference_poses is None else min(args.reference_poses, n_poses)
    ref_poses = grid[:n_ref]
    ref_repeats = max(1, min(args.repeats, 2))
    ref_time, ref = best_time(lambda: per_pose_reference(m, t4, ref_poses), ref_repeats)
    scaled = ref_time * n_poses / n_ref
    print(f"   batched  jacobian(grid) + fosm(jacobian=J): {batch_time * 1e3:9.1f} ms "
          f"(best of {args.repeats})")
    if n_ref == n_poses:
        print(f"   per-pose Python loop over {n_ref} poses:       {ref_time * 1e3:9.1f} ms "
              f"(best of {ref_repeats})")
    else:
        print(f"   per-pose Python loop over {n_ref} of {n_poses} poses: "
              f"{ref_time * 1e3:.1f} ms, scaled to all poses: {scaled * 1e3:.1f} ms "
              f"(best of {ref_repeats})")
    print(f"   speed-up (per-pose / batched): {scaled / batch_time:.1f}x")
    names = ("sigma", "beta", "P one-sided", "P two-sided")
    diffs = [np.abs(batch[i, :n_ref] - ref[i]).max() for i in range(4)]
    rel = [np.abs(batch[i, :n_ref] / ref[i] - 1).max() for i in range(2)]
    print("   same numbers? max |batched - reference|: "
          + ", ".join(f"{n} {d:.2e}" for n, d in zip(names, diffs))
          + f"  (relative: sigma {rel[0]:.1e}, beta {rel[1]:.1e})")
    agree = np.allclose(batch[:, :n_ref], ref, rtol=1e-12, atol=0)
    print(f"   agree to rtol 1e-12: {agree}\n")

    # 2. exact versus linear ---------------------------------------------------------------
    jac = m.jacobian(grid)
    to_size, to_limit, n_draws = largest_relative_residual(m, t4, grid, jac)
    print("2. Exact Eq. (18) minus linear J·x on the grid, Table 4 tolerances "
          f"(x = +t and {n_draws - 1} random ±t draws)")
    print("   " + "".join(f"{o:>10}" for o in m.outputs))
    print("   " + "".join(f"{v:10.2e}" for v in to_size)
          + "   max|residual| / max_grid|J x|")
    print("   " + "".join(f"{v:10.2e}" for v in to_limit) + "   max|residual| / limit")
    print(f"   largest relative residual: {to_size.max():.2e} (of the output's size), "
          f"{to_limit.max():.2e} (of its limit)\n")

    # 3. reliability of the paper's allocations ---------------------------------------------
    print("3. Worst grid pose, FOSM (sigma = t/3, zero mean)")
    allocations = {"Table 4": t4, "Table 6": m.error_vector(TABLE6, default=None)}
    reliability_table(m, allocations, grid, jac)


if __name__ == "__main__":
    main()
