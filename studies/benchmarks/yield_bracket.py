"""The bracket of ``allocate --yield`` at its default settings: one lower bound, one gap.

Run as ``python -m studies.benchmarks.yield_bracket [--yield 0.95] [--machines 4000]
[--seed 2023] [--seeds 2023 2024 2025 2026 2027] [--code PATH] [--only paper trunnion
swivel]``. For each machine (``constant`` profile, 5-point grid, the machine file's box):

1. **after**: ``precrel allocate MACHINE --yield Y --machines N --seed S`` run as a command
   (its defaults: one convex step, the calibration and the verification by the radial
   control variate, the log-concave bound at 95 % where it holds): the lower bound and its
   kind, the verified cost, the verified yield and its interval, the gap over the verified
   cost, the wall seconds and the peak resident memory of the process;
2. **before**: the same command from the checkout at ``--code PATH`` (e.g. a checkout of
   an earlier version), when given;
3. the **estimator**: at the allocation found, the per-ray variance of the directional
   estimator against the binomial ``Y (1 − Y)`` of crude machines at equal count, and the
   standard error of the control variate (N machines, 10 N rays) against the binomial one
   of N machines, with the yield and the machines that the exact chain and the linearised
   rows judge differently; the gradient's standard error on N crude machines (conditional
   Monte Carlo) and on N rays;
4. the **margin over the naive method** across ``--seeds``: the naive method's cost over
   the result's, both calibrated to the same criterion on the same sample, and both
   verified yields.

Timings share the machine with whatever else runs on it; the counts and ratios do not.
Nothing is asserted.
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import time
from pathlib import Path
from tempfile import TemporaryDirectory

import numpy as np

import allocation
import reliability
from allocation.machine_yield.yield_controlled import RAYS_FACTOR, ray_sample
from allocation.machine_yield.yield_dual import scaled_rows, yield_and_gradient
from allocation.machine_yield.yield_search import YieldSearch
from reliability.sampling.machine_yield import YieldModel
from reliability.sampling.radial_yield import as_directions, radial_gradient
from studies.benchmarks.yield_allocation import MACHINES
from studies.workflows.timing import one_blas_thread

ROOT = Path(__file__).resolve().parents[2]
#: The lines of the command's output quoted.
QUOTED = ("lower bound", "cost", "gap", "verified yield")
#: Runs ``python -m studies`` with the arguments after ``-c``'s and prints the process's
#: peak resident memory (kB, ``VmHWM`` of ``/proc/self/status``: the ``ru_maxrss`` of
#: ``getrusage`` would carry the benchmark's own across the fork) and its CPU seconds (user
#: + system) to standard error last.
RUN_WITH_PEAK = ("import re, resource, runpy, sys\n"
                 "sys.argv = ['studies', *sys.argv[1:]]\n"
                 "try:\n    runpy.run_module('studies', run_name='__main__')\n"
                 "finally:\n    used = resource.getrusage(resource.RUSAGE_SELF)\n"
                 "    status = open('/proc/self/status').read()\n"
                 "    peak = re.search(r'VmHWM:\\s+(\\d+)', status).group(1)\n"
                 "    print('peak', peak, used.ru_utime + used.ru_stime, file=sys.stderr)")


def command_lines(code: Path, machine: Path, args) -> list[str]:
    """``allocate --yield`` from the checkout ``code`` as a command: its quoted lines, wall
    and CPU seconds and the process's peak resident memory."""
    with TemporaryDirectory() as folder:
        started = time.perf_counter()
        done = subprocess.run(
            [sys.executable, "-c", RUN_WITH_PEAK, "allocate", str(machine), "--yield",
             str(args.yield_target), "--machines", str(args.machines), "--seed",
             str(args.seed), "--profile", "constant", "--out", str(Path(folder) / "a.csv")],
            cwd=code, env={**os.environ, "PYTHONPATH": str(code),
                           "PYTHONDONTWRITEBYTECODE": "1"}, capture_output=True,
            text=True, check=False)
        seconds = time.perf_counter() - started
    used = re.search(r"^peak (\d+) ([\d.]+)$", done.stderr, re.MULTILINE)
    if done.returncode != 0 or used is None:
        return [f"    exit {done.returncode}: {done.stderr.strip()[-300:]}"]
    peak, cpu = int(used.group(1)) / 1024, float(used.group(2))
    lines = [f"    {line}" for line in done.stdout.splitlines()
             if line.startswith(QUOTED)]
    return lines + [f"    {seconds:.0f} s wall ({cpu:.0f} s CPU), peak resident memory "
                    f"{peak:.0f} MB"]


def estimator_lines(machine, args) -> list[str]:
    """The directional and control-variate estimators at the default result's allocation
    against crude sampling at equal count."""
    result = allocation.allocate_for_yield(machine, args.yield_target, profile="constant",
                                           machines=args.machines, rng=args.seed)
    search = YieldSearch(result.problem.machine, result.points, None, args.machines,
                         args.seed, 0.0, problem=result.search_problem,
                         yield_target=args.yield_target)
    found = ray_sample(search, "verification", args.seed).judge(result.tolerances)
    estimate = found.estimate()
    terms = found.rays.terms()
    binomial = estimate.estimate * (1 - estimate.estimate)
    crude_error = np.sqrt(binomial / args.machines)
    return [f"    estimator at the result: yield {estimate.estimate:.4f}; per ray, variance "
            f"{terms.var(ddof=1):.3g} against the binomial {binomial:.3g} of one machine "
            f"(ratio {binomial / terms.var(ddof=1):.2f}); control variate on "
            f"{args.machines:,} machines and {RAYS_FACTOR * args.machines:,} rays: standard "
            f"error {estimate.standard_error:.2g} against {crude_error:.2g} crude "
            f"(variance ratio {(crude_error / estimate.standard_error) ** 2:.1f}); "
            f"{estimate.disagreements} of {args.machines:,} machines judged differently by "
            f"the exact chain and the linearised rows",
            *gradient_lines(machine, result.tolerances, args.machines, args.seed)]


def gradient_lines(machine, tolerances, draws: int, seed: int) -> list[str]:
    """The yield's gradient in the log-tolerances at ``tolerances`` on ``draws`` crude
    machines (conditional Monte Carlo,
    :func:`allocation.machine_yield.yield_dual.yield_and_gradient`) and on as many rays
    (:func:`reliability.sampling.radial_yield.radial_gradient`): their mean standard errors
    and seconds."""
    model = YieldModel(machine, profile="constant", points=5)
    rows = scaled_rows(machine, model.deciding_poses)
    z = np.random.default_rng(seed).standard_normal((draws, len(tolerances)))
    started = time.perf_counter()
    _, _, crude_error = yield_and_gradient(rows, tolerances, z)
    crude_seconds = time.perf_counter() - started
    started = time.perf_counter()
    *_, radial_error = radial_gradient(rows, tolerances, as_directions(z))
    radial_seconds = time.perf_counter() - started
    return [f"    gradient on {draws:,} draws: mean standard error {crude_error.mean():.3g} "
            f"by conditional Monte Carlo ({crude_seconds:.1f} s), {radial_error.mean():.3g} "
            f"along rays ({radial_seconds:.1f} s)"]


def margin_lines(machine, args) -> list[str]:
    """The naive method's cost over the result's, and both verified yields, per seed."""
    lines, ratios = [], []
    for seed in args.seeds:
        result = allocation.allocate_for_yield(machine, args.yield_target,
                                               profile="constant", machines=args.machines,
                                               rng=seed)
        ratio = result.naive.cost / result.cost
        ratios.append(ratio)
        v, n = result.verified_yield, result.naive.verified_yield
        lines.append(f"    seed {seed}: naive/result {ratio:.4f}; result "
                     f"{result.cost / result.initial_cost:.2%} ({result.method}), verified "
                     f"{v.estimate:.4f} [{v.lower:.4f}, {v.upper:.4f}]; naive "
                     f"{result.naive.cost / result.initial_cost:.2%}, verified "
                     f"{n.estimate:.4f} [{n.lower:.4f}, {n.upper:.4f}]; gap "
                     f"{result.gap_of_cost:.2%}")
    spread = np.std(ratios, ddof=1) / np.sqrt(len(ratios)) if len(ratios) > 1 else 0.0
    return lines + [f"    margin over the naive method: naive/result {np.mean(ratios):.4f} ± "
                    f"{spread:.4f} (mean ± its standard error over {len(ratios)} seeds)"]


@one_blas_thread
def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--yield", dest="yield_target", type=float, default=0.95)
    parser.add_argument("--machines", type=int, default=4000)
    parser.add_argument("--seed", type=int, default=2023)
    parser.add_argument("--seeds", type=int, nargs="*", default=[2023, 2024, 2025, 2026,
                                                                 2027])
    parser.add_argument("--code", type=Path, default=None,
                        help="a checkout of an earlier version, run as 'before'")
    parser.add_argument("--only", nargs="+", choices=list(MACHINES), default=list(MACHINES))
    args = parser.parse_args(argv)
    for label, path in (MACHINES[name] for name in args.only):
        machine = reliability.load_machine(path)
        print(f"\n== {label}: yield {args.yield_target:g}, {args.machines:,} machines, seed "
              f"{args.seed}", flush=True)
        print("  after (this checkout, default settings):", flush=True)
        print("\n".join(command_lines(ROOT, path, args)), flush=True)
        if args.code is not None:
            print(f"  before ({args.code}):", flush=True)
            print("\n".join(command_lines(args.code, path, args)), flush=True)
        print("\n".join(estimator_lines(machine, args)), flush=True)
        if args.seeds:
            print("\n".join(margin_lines(machine, args)), flush=True)


if __name__ == "__main__":
    main()
