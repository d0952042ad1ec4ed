"""Benchmark: time and peak memory of identification for 10 000 and 100 000 readings.

Run as ``python -m studies.benchmarks.identification_speed [--readings N ...] [--profile P
...] [--machine paper swivel5] [--iterate-up-to N]``. The plan of each machine
(``docs/examples/paper_plan.toml``, ``docs/examples/swivel5_plan.toml``: laser runs along
each linear axis, three ballbar circles, a test of each rotary axis; hundreds of distinct
positions per axis) is repeated, each repeat a run of its own with its own set-up, until it
gives at least ``N`` readings (default 10 000 and 100 000) of one machine drawn under the
profile. For each profile (default ``constant`` and ``gp:300``) it prints the readings, the
distinct positions per axis, the coefficients, the wall and CPU time of one
:func:`reliability.measured.identification.identify` (BLAS on one thread; on a busy
machine the CPU time is the one to read) and its peak memory:
the largest memory numpy and Python held during the call above what they held before it
(``tracemalloc``, a second run), and with ``--iterate`` on the smaller sets (up to
``--iterate-up-to`` readings, default 20 000) the same for the Gauss–Newton re-linearisation.
"""

from __future__ import annotations

import argparse
import math
import time
import tracemalloc
from dataclasses import replace

import numpy as np

import reliability
from reliability.measured.plans import read_plan
from reliability.measured.simulated_measurements import simulate_measurements
from studies.benchmarks.identification_coverage import MACHINES
from studies.workflows.timing import one_blas_thread


def repeated_plan(plan, readings: int) -> tuple:
    """The plan's runs repeated, each repeat renamed, until they give ``readings``."""
    per_plan = sum(len(run.poses) * len(run.quantities) for run in plan)
    copies = math.ceil(readings / per_plan)
    return tuple(replace(run, name=f"{run.name}#{i}") for i in range(copies) for run in plan)


def measure(machine, measurements, profile, iterate) -> tuple[float, float, float]:
    """Wall and CPU seconds of one identification, and its peak traced memory in MB (a
    second run)."""
    started, cpu = time.perf_counter(), time.process_time()
    reliability.identify(machine, measurements, profile=profile, iterate=iterate)
    seconds, cpu = time.perf_counter() - started, time.process_time() - cpu
    tracemalloc.start()
    before = tracemalloc.get_traced_memory()[0]
    reliability.identify(machine, measurements, profile=profile, iterate=iterate)
    peak = tracemalloc.get_traced_memory()[1] - before
    tracemalloc.stop()
    return seconds, cpu, peak / 2 ** 20


def run(name, readings, profiles, iterate_up_to, seed) -> None:
    """Print one machine's rows."""
    path, plan_path = MACHINES[name]
    machine = reliability.hobbing_machine() if path is None else reliability.load_machine(path)
    plan = read_plan(plan_path, machine)
    for count in readings:
        for profile in profiles:
            drawn = simulate_measurements(machine, repeated_plan(plan, count),
                                          profile=profile, rng=seed)
            meas = drawn.measurements
            positions = [len(np.unique(column)) for column in meas.poses.T]
            coefficients = reliability.identify(machine, meas, profile=profile) \
                .coefficients.size
            for iterate in (False, True) if len(meas) <= iterate_up_to else (False,):
                seconds, cpu, peak = measure(machine, meas, profile, iterate)
                print(f"| {name} | {profile} | {'yes' if iterate else 'no'} | {len(meas)} | "
                      f"{' '.join(map(str, positions))} | {coefficients} | {seconds:.2f} | "
                      f"{cpu:.2f} | {peak:.0f} |", flush=True)


@one_blas_thread
def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--readings", type=int, nargs="+", default=[10_000, 100_000])
    parser.add_argument("--profile", nargs="+", default=["constant", "gp:300"])
    parser.add_argument("--machine", nargs="+", choices=sorted(MACHINES),
                        default=["paper", "swivel5"])
    parser.add_argument("--iterate-up-to", type=int, default=20_000)
    parser.add_argument("--seed", type=int, default=2026)
    args = parser.parse_args(argv)
    print("| machine | profile | iterate | readings | positions per axis | coefficients | "
          "wall (s) | CPU (s) | peak (MB) |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for name in args.machine:
        run(name, args.readings, args.profile, args.iterate_up_to, args.seed)


if __name__ == "__main__":
    main()
