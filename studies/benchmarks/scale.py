"""Scaling benchmark: time and peak memory against the grid size, and sweep parallelism.

Run as ``python -m studies.benchmarks.scale``. It prints

1. for the paper's machine and 5, 7, 9, 11 points per axis (15 625 to 1 771 561 poses):
   the time and peak memory of FOSM over the grid, and of the certified allocation
   (problem build with row screening, plus the exact solve), each next to a simple
   vectorised reference computed in the same run — FOSM on the whole-array Jacobian, and
   the allocation with whole-array rows and the all-pairs dominance screen — with their
   ratios. Every measurement runs in its own subprocess (BLAS pinned to one thread), so
   peaks are separate; peak memory is the subprocess' maximum resident set size
   (interpreter and libraries included). A subprocess that exceeds ``--memory-limit`` or
   ``--timeout`` is reported as such;
2. a sweep of ``--sweep-tasks`` allocate-and-verify tasks run serially, on a 2-process
   pool and on a 2-worker Dask LocalCluster: wall times, the parallel efficiency
   ``serial / (2 × parallel)``, and whether the three results.csv are byte-identical.

``--code DIR`` runs the scaling measurements against another copy of the toolkit (for
example an older commit checked out in DIR), for before/after tables. Nothing is asserted
on times; the machine's load makes them noisy.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parents[2]
SWEEP_MACHINES = ("hobbing",)


# ----- measurements (run in a subprocess each) -----------------------------------------
def measure(name: str, points: int) -> dict:
    """Time one computation on the paper's machine; the caller reads the peak memory."""
    import numpy as np

    import reliability
    from reliability.model.poses import workspace_grid

    machine = reliability.hobbing_machine()
    grid = workspace_grid(machine, points)
    t = machine.initial_allocation
    start = time.perf_counter()
    if name == "fosm":
        result = reliability.fosm(machine, t, grid)
        summary = float(result.worst().min())
    elif name == "fosm_reference":
        summary = float(_reference_fosm(machine, t, grid).min())
    elif name == "allocation":
        import allocation

        problem = allocation.AllocationProblem.build(machine, grid, side="one_sided")
        best = problem.solve_exact()
        summary = float(best.cost)
    else:
        summary = float(_reference_allocation(machine, grid))
    elapsed = time.perf_counter() - start
    return {"time": elapsed, "poses": len(grid), "summary": summary,
            "checksum": float(np.round(summary, 6))}


def _reference_fosm(machine, t, grid):
    """Worst two-sided probability per output from the whole-array Jacobian (Eq. 20)."""
    from reliability.first_order.fosm import error_sigma, output_sigma, two_sided_probability

    sigma = output_sigma(machine.jacobian(grid), error_sigma(t))
    return two_sided_probability(machine.limits, sigma).min(axis=0)


def _reference_allocation(machine, grid):
    """Certified optimum with whole-array rows and the all-pairs dominance screen."""
    import numpy as np

    from allocation.solvers.convex import solve_convex_allocation
    from allocation.cost.cost import CostModel
    from reliability.first_order.fosm import required_index

    reference = machine.initial_allocation
    lower, upper = 0.25 * reference ** 2, 2.25 * reference ** 2  # box [0.5, 1.5] in u = t²
    allowed = machine.limits / required_index(machine.targets, "one_sided")
    rows = np.square(machine.jacobian(grid) / 3.0) / np.square(allowed)[:, None]
    kept = []
    for output in range(6):
        matrix = rows[:, output, :]
        matrix = matrix[matrix @ upper > 1.0]
        matrix = np.unique(matrix, axis=0)
        dominated = np.zeros(len(matrix), dtype=bool)
        for start in range(0, len(matrix), 256):
            block = matrix[start:start + 256]
            covers = np.all(matrix[None, :, :] >= block[:, None, :], axis=-1)
            covers[np.arange(len(block)), np.arange(start, start + len(block))] = False
            dominated[start:start + len(block)] = covers.any(axis=1)
        kept.append(matrix[~dominated])
    weights = CostModel.from_machine(machine).weights
    solution = solve_convex_allocation(weights, np.concatenate(kept), lower, upper)
    return CostModel.from_machine(machine).total(solution.t)


def _child(name: str, points: int, memory_limit: float) -> None:
    """Subprocess entry: limit memory, measure, print JSON with the peak RSS."""
    limit = int(memory_limit * 2 ** 30)
    resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
    try:
        out = measure(name, points)
    except MemoryError:
        out = {"error": f"out of memory (> {memory_limit:g} GB)"}
    out["peak_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(json.dumps(out))


def run_measurement(name, points, code: Path, timeout: float, memory_limit: float) -> dict:
    """One measurement in a fresh interpreter importing the toolkit from ``code``."""
    env = dict(os.environ, PYTHONPATH=str(code))
    command = [sys.executable, "-c",
               "import runpy, sys; sys.path.insert(0, sys.argv[1]); "
               "runpy.run_path(sys.argv[2], run_name='measurement')['_child']"
               f"({name!r}, {points}, {memory_limit})", str(code), __file__]
    try:
        done = subprocess.run(command, capture_output=True, text=True, timeout=timeout,
                              env=env, cwd=code)
    except subprocess.TimeoutExpired:
        return {"error": f"timeout (> {timeout:g} s)"}
    lines = [line for line in done.stdout.splitlines() if line.startswith("{")]
    if not lines:
        tail = (done.stderr.strip().splitlines() or ["no output"])[-1]
        return {"error": "out of memory" if "MemoryError" in done.stderr else tail[:60]}
    return json.loads(lines[-1])


def _cell(result: dict) -> str:
    if "error" in result:
        return f"{result['error']:>24}"
    return f"{result['time']:9.2f} s {result['peak_mb']:8.0f} MB"


def scaling_table(points_list, code, timeout, memory_limit) -> None:
    print(f"1. Scaling on the paper's machine (toolkit from {code})")
    print(f"   {'points':>6} {'poses':>9}  {'computation':<11} {'toolkit':>24} "
          f"{'whole-array reference':>24} {'time ratio':>10} {'memory ratio':>12}")
    for points in points_list:
        for what in ("fosm", "allocation"):
            ours = run_measurement(what, points, code, timeout, memory_limit)
            ref = run_measurement(f"{what}_reference", points, code, timeout, memory_limit)
            both = "error" not in ours and "error" not in ref
            ratio = f"{'-':>10} {'-':>12}"
            if both:
                ratio = (f"{ref['time'] / ours['time']:10.2f} "
                         f"{ref['peak_mb'] / ours['peak_mb']:12.2f}")
            print(f"   {points:>6} {points ** 6:>9}  {what:<11} {_cell(ours)} {_cell(ref)} "
                  f"{ratio}", flush=True)
    print("   (ratios: reference / chunked, above 1 means the chunked code is faster or "
          "smaller)")


# ----- sweep parallel efficiency ---------------------------------------------------------
def sweep_efficiency(n_tasks: int, workers: int = 2) -> None:
    from concurrent.futures import ProcessPoolExecutor

    from studies.workflows.sweep import SweepSpec, clear_caches, run_sweep

    seeds = max(1, n_tasks // 4)
    spec = SweepSpec(machines=SWEEP_MACHINES, sides=("one_sided", "two_sided"),
                     targets=(0.99, 0.995), seeds=tuple(range(seeds)), repeats=(20,))
    total = len(spec.tasks())
    print(f"\n2. Sweep of {total} tasks (paper's machine, 5-point grid, 20 experiments "
          f"each), {workers} workers")
    with tempfile.TemporaryDirectory() as folder:
        folder = Path(folder)
        times = {}
        start = time.perf_counter()
        run_sweep(spec, folder / "serial")
        times["serial"] = time.perf_counter() - start
        clear_caches()  # forked workers must not inherit the serial run's allocations
        start = time.perf_counter()
        with ProcessPoolExecutor(workers) as pool:
            run_sweep(spec, folder / "processes", executor=pool)
        times["processes"] = time.perf_counter() - start
        from distributed import Client, LocalCluster

        start = time.perf_counter()
        with LocalCluster(n_workers=workers, threads_per_worker=1,
                          dashboard_address=None) as cluster, Client(cluster) as client:
            run_sweep(spec, folder / "dask", executor=client)
        times["dask"] = time.perf_counter() - start
        text = (folder / "serial" / "results.csv").read_bytes()
        same = all((folder / name / "results.csv").read_bytes() == text
                   for name in ("processes", "dask"))
    for name, elapsed in times.items():
        efficiency = "" if name == "serial" else \
            f"   parallel efficiency {times['serial'] / (workers * elapsed):5.2f}"
        print(f"   {name:<10} {elapsed:8.1f} s{efficiency}")
    print(f"   results.csv byte-identical across the three: {'yes' if same else 'NO'}")
    print("   (parallel times include starting the workers; each worker process solves "
          "the allocations it meets once)")


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, nargs="*", default=[5, 7, 9, 11],
                        help="points per axis of the scaling table (none: skip it)")
    parser.add_argument("--code", type=Path, default=HERE,
                        help="folder of the toolkit copy to measure (default: this one)")
    parser.add_argument("--timeout", type=float, default=600.0, help="s per measurement")
    parser.add_argument("--memory-limit", type=float, default=8.0,
                        help="GB of address space per measurement")
    parser.add_argument("--sweep-tasks", type=int, default=200,
                        help="tasks of the sweep (0: skip the sweep)")
    args = parser.parse_args(argv)
    # The measurements run this file in subprocesses that may import an older copy of the
    # toolkit (--code): nothing of studies/ is imported at module level, and BLAS is pinned
    # through the environment the subprocesses inherit.
    from studies.workflows.timing import limit_blas_threads

    limit_blas_threads()
    print(f"BLAS threads: {os.environ['OPENBLAS_NUM_THREADS']}; CPUs: {os.cpu_count()}")
    if args.points:
        scaling_table(args.points, args.code.resolve(), args.timeout, args.memory_limit)
    if args.sweep_tasks:
        sweep_efficiency(args.sweep_tasks)


if __name__ == "__main__":
    main()
