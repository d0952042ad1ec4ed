"""Is a measured machine's percentile among the predicted machines uniform when the machine
is drawn from the design? ``python -m studies.benchmarks.evaluation_uniformity``.

Draws ``--machines`` machines of ``tests/machines/swivel5.toml`` as ``precrel measure``
does (the runs of ``docs/examples/swivel5_acceptance_plan.toml``), evaluates each as
``precrel evaluate`` does, and places every limited result of
``tests/acceptance_tests/swivel5.toml`` among ``--predicted`` machines of the acceptance
prediction (``acceptance_stream(0)``). Prints per result the mean percentile with its
standard error (1/√12/√n), its z against 1/2 and the Kolmogorov–Smirnov p-value against the
uniform. ``--profile gp:300`` draws and predicts under a profile along travel.
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

import numpy as np
from scipy import stats

import reliability
from reliability.acceptance.definitions import read_tests
from reliability.basics.streams import acceptance_stream
from reliability.measured.acceptance_runs import acceptance_runs_from_frame
from reliability.measured.plans import read_plan
from reliability.measured.simulated_measurements import simulate_measurements
from studies.workflows.acceptance_evaluation import evaluate_against_design

ROOT = Path(__file__).resolve().parents[2]
MACHINE = ROOT / "tests" / "machines" / "swivel5.toml"
TESTS = ROOT / "tests" / "acceptance_tests" / "swivel5.toml"
PLAN = ROOT / "docs" / "examples" / "swivel5_acceptance_plan.toml"


def percentiles(machines: int, predicted: int, seed: int, profile: str | None = None):
    """``(keys, (machines, len(keys)))``: each drawn machine's percentile per result, the
    machines drawn and predicted under ``profile`` (the machine file's by default)."""
    machine = reliability.load_machine(MACHINE)
    if profile is not None:
        machine = replace(machine, profile=profile)
    plan, tests = read_plan(PLAN, machine), read_tests(TESTS, machine)
    rng = np.random.default_rng(seed)
    rows, result, keys = [], None, None
    for _ in range(machines):
        drawn = simulate_measurements(machine, plan, profile=machine.profile, rng=rng)
        runs = acceptance_runs_from_frame(drawn.measurements.to_frame(machine).astype(str))
        if result is None:
            table, result, _ = evaluate_against_design(runs, machine, tests,
                                                       machines=predicted,
                                                       rng=acceptance_stream(0))
            compared = table.dropna(subset=["percentile"])
            keys = list(zip(compared["run"], compared["quantity"]))
        values = runs.evaluation_frame().set_index(["run", "quantity"])["value"]
        rows.append([np.mean(result.values[key].to_numpy() <= values[key]) for key in keys])
    return keys, np.array(rows)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--machines", type=int, default=200)
    parser.add_argument("--predicted", type=int, default=2000)
    parser.add_argument("--seed", type=int, default=2026)
    parser.add_argument("--profile", default=None,
                        help="error profile along travel (default: the machine file's)")
    args = parser.parse_args(argv)
    keys, values = percentiles(args.machines, args.predicted, args.seed, args.profile)
    error = np.sqrt(1.0 / 12.0 / args.machines)
    print(f"{args.machines} machines drawn (seed {args.seed}, profile "
          f"{args.profile or 'of the machine file'}), each among {args.predicted} predicted "
          f"machines; mean percentile ± its standard error {error:.4f}")
    for (run, quantity), column in zip(keys, values.T):
        z = (column.mean() - 0.5) / error
        print(f"  {run} {quantity}: mean {column.mean():.3f} (z {z:+.1f}), KS p "
              f"{stats.kstest(column, 'uniform').pvalue:.2f}")


if __name__ == "__main__":
    main()
