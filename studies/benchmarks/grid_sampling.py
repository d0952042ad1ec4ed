"""Benchmark of the grid-experiment engine (Sec. 5.3) against the per-pose exact model.

Run as ``python -m studies.benchmarks.grid_sampling``. For the hobbing machine and the paper's
Table 6 allocation it draws the errors of 20 grid experiments once (each from its own
generator spawned from the seed, exactly as ``GridExperiment.run`` does), then times, in
this run and on the same draws (best of ``--rounds`` calls, ``time.perf_counter``):

(a) ``GridExperiment.evaluate`` on all 20 experiments at once (head/tail factorisation);
(b) ``GridExperiment.reference_evaluate``: the straightforward batched per-pose product,
    ``machine.comprehensive_error`` on all 20 × 15 625 pose/error combinations;

and prints both times, their ratio (target ≥ 20×) and the largest difference between the
two relative to each output's largest |value| (target ≤ 1e-12). It also times a full
``GridExperiment(m).run(t, repeats=20)`` (drawing, evaluating and counting, end to end).
Nothing is asserted; the numbers are the result.

BLAS threads. ``evaluate`` spends its time in one batched product of small matrices
(20 × (125 × 12) · (12 × 750)); a multi-threaded OpenBLAS on a shared machine can make
that call tens of times slower than on one thread (measured here: 0.3 s instead of 5 ms
on 2 busy cores). As in ``studies.benchmarks.allocation_solvers``, BLAS is limited to one thread
unless ``OPENBLAS_NUM_THREADS`` (or ``OMP_NUM_THREADS``) is set; then, unless
``--no-thread-comparison``, the same timings are repeated in a child process with as many
BLAS threads as CPUs (numpy's default), so the difference is visible.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time

import numpy as np

import reliability
from reliability import OUTPUTS
from reliability.basics.pass_rule import passes
from reliability.basics.streams import spawn
from reliability.sampling.grid_experiment import GridExperiment
from studies.paper.tables import TABLE6
from studies.workflows.timing import best_time, limit_blas_threads


def draw_repeats(experiment, tolerances, repeats, seed):
    """The errors of ``repeats`` experiments, drawn as ``GridExperiment.run`` draws them."""
    children = spawn(seed, repeats)
    draws = [experiment._draw(tolerances, child, 3.0, "truncated") for child in children]
    return np.stack([d[0] for d in draws]), np.stack([d[1] for d in draws])


def main(argv=None):
    """Parse the options and measure with ``--blas-threads`` BLAS threads (default 1)."""
    args = parse_arguments(argv)
    from threadpoolctl import threadpool_limits

    if args.blas_threads == 1:
        limit_blas_threads()
    with threadpool_limits(limits=args.blas_threads):
        measure(args)


def parse_arguments(argv=None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=20, help="experiments (default 20)")
    parser.add_argument("--points", type=int, default=5, help="points per axis (default 5)")
    parser.add_argument("--rounds", type=int, default=3, help="timing rounds, best kept")
    parser.add_argument("--seed", type=int, default=2023)
    parser.add_argument("--no-thread-comparison", action="store_true",
                        help="skip the child run with numpy's default BLAS threads")
    parser.add_argument("--blas-threads", type=int, default=1,
                        help="BLAS threads of this run (default 1)")
    return parser.parse_args(argv)


def measure(args) -> None:
    """Time the engine against the reference and print the comparison."""
    machine = reliability.hobbing_machine()
    tolerances = machine.error_vector(TABLE6, default=None)
    start = time.perf_counter()
    experiment = GridExperiment(machine, args.points)
    setup = time.perf_counter() - start
    motion, assembly = draw_repeats(experiment, tolerances, args.repeats, args.seed)
    print(f"machine: {machine.name}")
    print(f"allocation: Table 6; {args.repeats} experiments × {experiment.n_poses} poses "
          f"({args.points} points on {len(machine.axes)} axes); seed {args.seed}; "
          f"best of {args.rounds}; BLAS threads: {os.environ['OPENBLAS_NUM_THREADS']}")
    print(f"GridExperiment set-up (transports, once per machine and grid): {setup:.4f} s")

    fast_time, fast = best_time(lambda: experiment.evaluate(motion, assembly), args.rounds)
    slow_time, slow = best_time(lambda: experiment.reference_evaluate(motion, assembly),
                                args.rounds)
    size = np.abs(slow).max(axis=(0, 1))
    relative = np.abs(fast - slow).max(axis=(0, 1)) / size
    print()
    print(f"(a) GridExperiment.evaluate, all {args.repeats} at once: {fast_time:9.4f} s")
    print(f"(b) reference_evaluate (per-pose exact product):  {slow_time:9.4f} s")
    print(f"    ratio (b)/(a): {slow_time / fast_time:.1f}×   (target ≥ 20×)")
    print("    largest |(a) − (b)| / max|(b)| per output (target ≤ 1e-12):")
    for output, value, scale in zip(OUTPUTS, relative, size):
        print(f"      {output}: {value:.2e}   (max |value| {scale:.3e})")
    print(f"    worst: {relative.max():.2e}")

    run_time, result = best_time(
        lambda: GridExperiment(machine, args.points).run(tolerances, repeats=args.repeats,
                                                         rng=args.seed, keep_values="none"),
        args.rounds)
    print()
    print(f"end to end: GridExperiment(m, {args.points}).run(t, repeats={args.repeats}) "
          f"(set-up, drawing, evaluating, counting): {run_time:.4f} s")
    fractions = result.fractions.mean(axis=0)
    print("    mean fraction in tolerance: "
          + "  ".join(f"{o} {f:.5f}" for o, f in zip(OUTPUTS, fractions)))
    counts = np.sum(passes(fast, machine.limits), axis=1)
    print(f"    counts of run() equal counts of the pre-drawn errors: "
          f"{np.array_equal(counts, result.inside)}")

    if not args.no_thread_comparison:
        threads = str(os.cpu_count() or 1)
        env = dict(os.environ, OPENBLAS_NUM_THREADS=threads, OMP_NUM_THREADS=threads,
                   MKL_NUM_THREADS=threads)
        command = [sys.executable, "-m", "studies.benchmarks.grid_sampling",
                   "--no-thread-comparison", "--blas-threads", threads,
                   "--repeats", str(args.repeats), "--points", str(args.points),
                   "--rounds", str(args.rounds), "--seed", str(args.seed)]
        child = subprocess.run(command, env=env, capture_output=True, text=True, check=True)
        keep = ("(a)", "(b)", "ratio", "worst", "end to end", "allocation")
        print()
        print(f"the same in a child process with {threads} BLAS threads (numpy's default):")
        for line in child.stdout.splitlines():
            if line.strip().startswith(keep):
                print("  " + line.strip())


if __name__ == "__main__":
    main()
