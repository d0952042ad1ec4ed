"""Benchmark of the rare-event estimators against crude Monte-Carlo.

Run as ``python -m studies.benchmarks.rare_events``. At the worst pose of the δx error of the
paper's machine, the Table 4 allocation is scaled so that the linear two-sided failure
probability of δx is 1e−4, 1e−6 and 1e−9. For each level and each method
(importance sampling, subset simulation), ``--repeats`` independent runs on the exact model
(Eq. 18) give: the exact-model evaluations used, the CoV reached, an estimate and its 95 %
interval, the mean estimate over the exact linear answer ``2Φ(−β)`` and the share of
intervals containing it (the model's non-linearity is below 2e−4 of the output spread, so
the linear answer is the reference), and the evaluations crude Monte-Carlo would need for
the same CoV, ``(1 − p)/(p · CoV²)``, with the ratio, and the time that would take
(extrapolated from a vectorised crude run of 200 000 samples timed in the same run) over
the estimator's time.
Nothing is asserted; the numbers are the result.
"""

from __future__ import annotations

import argparse

import numpy as np
import pandas as pd
from scipy.stats import norm

import reliability
from reliability.basics.pass_rule import passes
from reliability.basics.streams import generator, spawn
from reliability.sampling.rare_events import failure_probability, worst_grid_pose
from studies.workflows.timing import best_time, one_blas_thread

LEVELS = (1e-4, 1e-6, 1e-9)


def scaled_tolerances(machine, probability, pose, output: int = 0):
    """Table 4 tolerances scaled so that ``output`` fails with ``probability`` (linear,
    two-sided) at ``pose``."""
    t = machine.initial_allocation
    sigma = np.sqrt(np.square(machine.jacobian(pose)[output]) @ np.square(t / 3))  # Eq. (20)
    beta = -norm.ppf(probability / 2)
    return t * machine.limits[output] / (beta * sigma)


def crude_seconds_per_evaluation(machine, pose, samples: int = 200_000,
                                 seed: int = 0) -> float:
    """Wall time of one crude Monte-Carlo sample (draw, exact model, count), vectorised over
    ``samples`` draws at ``pose``: the simple reference."""
    rng = generator(seed)
    t = machine.initial_allocation

    def crude():
        y = machine.comprehensive_error(pose, rng.standard_normal((samples, t.size)) * t / 3)
        return int(np.sum(~passes(y[:, 0], machine.limits[0])))

    seconds, _ = best_time(crude, 3)
    return seconds / samples


def benchmark(levels=LEVELS, methods=("importance", "subset"), *, seed: int = 2023,
              repeats: int = 20, target_cov: float = 0.1,
              max_evaluations: int = 20_000) -> pd.DataFrame:
    """One row per (level, method), over ``repeats`` independent runs: mean evaluations and
    CoV, the first run's estimate and interval, the mean estimate over the exact answer,
    the share of intervals containing it, crude Monte-Carlo's evaluations for the same
    CoV with the ratio to the evaluations used, and the time crude Monte-Carlo would take
    (extrapolated from a vectorised crude run timed here) over the estimator's time."""
    machine = reliability.hobbing_machine()
    pose = worst_grid_pose(machine, machine.initial_allocation, "dx")
    per_sample = crude_seconds_per_evaluation(machine, pose)
    rows = []
    for level, level_stream in zip(levels, spawn(seed, len(levels))):
        t = scaled_tolerances(machine, level, pose)
        for method, method_stream in zip(methods, level_stream.spawn(len(methods))):
            def runs(method=method, method_stream=method_stream):
                return [failure_probability(machine, t, pose, event="dx", method=method,
                                            target_cov=target_cov,
                                            max_evaluations=max_evaluations,
                                            rng=run_stream)
                        for run_stream in method_stream.spawn(repeats)]
            seconds, results = best_time(runs, 1)
            evaluations = np.mean([r.n_evaluations for r in results])
            cov = np.mean([r.cov for r in results])
            crude = (1 - level) / (level * cov ** 2)
            first = results[0]
            rows.append({"exact_linear": level, "method": method,
                         "evaluations": evaluations, "cov": cov,
                         "estimate": first.probability, "lower": first.interval[0],
                         "upper": first.interval[1],
                         "mean_estimate/exact": np.mean([r.probability for r in results])
                         / level,
                         "covered": np.mean([r.interval[0] <= level <= r.interval[1]
                                             for r in results]),
                         "crude_mc_evaluations": crude, "crude/used": crude / evaluations,
                         "seconds_per_run": seconds / repeats,
                         "crude_seconds": crude * per_sample,
                         "time_ratio": crude * per_sample / (seconds / repeats)})
    return pd.DataFrame(rows)


@one_blas_thread
def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=2023)
    parser.add_argument("--repeats", type=int, default=20, help="independent runs per row")
    parser.add_argument("--target-cov", type=float, default=0.1)
    parser.add_argument("--max-evaluations", type=int, default=20_000)
    args = parser.parse_args(argv)
    machine = reliability.hobbing_machine()
    pose = worst_grid_pose(machine, machine.initial_allocation, "dx")
    print("Rare-event failure probability of dx at its worst grid pose "
          + ", ".join(f"{a}={v:.4g}" for a, v in zip(machine.axes, pose))
          + f"; target CoV {args.target_cov}, budget {args.max_evaluations} evaluations,"
          f" seed {args.seed}, {args.repeats} runs per row (estimate and interval: the first"
          " run; evaluations and cov: means).")
    frame = benchmark(seed=args.seed, repeats=args.repeats, target_cov=args.target_cov,
                      max_evaluations=args.max_evaluations)
    print(frame.to_string(index=False, float_format="{:.3g}".format))


if __name__ == "__main__":
    main()
