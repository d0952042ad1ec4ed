"""Benchmark: do the identification's 95 % posterior intervals cover simulated machines?

Run as ``python -m studies.benchmarks.identification_coverage [--machines N] [--poses P]
[--profile P ...] [--machine paper swivel5] [--seed S]``. For the paper's machine with
``docs/examples/paper_plan.toml`` and ``tests/machines/swivel5.toml`` with
``docs/examples/swivel5_plan.toml``, under each profile (default ``constant`` and
``gp:300``), it draws ``N`` machines (default 200) with ``precrel measure``'s machinery
(:func:`reliability.measured.simulated_measurements.simulate_measurements`, the same
profile), identifies each under that profile and counts

- **errors**: the drawn truth inside the 95 % interval of every row of ``errors.csv`` (under
  ``gp`` a motion error's row is its mean over the stroke; the truth's is the trapezoid
  mean of the drawn profile at :data:`LEVELS` levels of the stroke);
- **profiles** (``gp``): every motion error at every position read, against ``profiles.csv``;
- **outputs**: the six outputs of the exact chain at ``P`` random poses (default 1 000, each
  axis at one of its :data:`LEVELS` levels) inside the 95 % interval of ``predict``;
- **χ²**: the statistic's distribution against χ²(dof): the Kolmogorov–Smirnov p-value of
  its CDF values against the uniform, and its mean and variance against ``dof`` and
  ``2 dof``.

The truth at the random poses and levels is drawn with the machine, jointly with what the
plan reads: they are one more run of the plan whose readings are dropped before the
identification. Coverage is a share over machines; its standard error is the spread of the
per-machine shares between machines over √N (the readings of one machine share its draw).
It also prints, per machine and profile, the rank, the condition and the combinations that
cannot be told apart.
"""

from __future__ import annotations

import argparse
import math
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
from scipy import stats

import reliability
from reliability.basics.streams import generator
from reliability.measured.identification import Z95
from reliability.measured.plans import PlannedRun, read_plan
from reliability.measured.simulated_measurements import simulate_measurements
from studies.workflows.timing import one_blas_thread

ROOT = Path(__file__).resolve().parents[2]
MACHINES = {"paper": (None, ROOT / "docs" / "examples" / "paper_plan.toml"),
            "swivel5": (ROOT / "tests" / "machines" / "swivel5.toml",
                        ROOT / "docs" / "examples" / "swivel5_plan.toml")}
#: Levels of every axis' stroke for the truth: the random poses and the mean over the stroke.
LEVELS = 101
#: Name of the run that carries the truth's poses through the simulation.
TRUTH_RUN = "__truth__"


def levels(axis) -> tuple[np.ndarray, np.ndarray]:
    """The axis' levels and the weights of the mean over its stroke (trapezoid; equal
    weights around a full turn)."""
    if axis.full_turn:
        return np.arange(LEVELS) * (2 * math.pi / LEVELS), np.full(LEVELS, 1.0 / LEVELS)
    points = np.linspace(*axis.stroke, LEVELS)
    weights = np.full(LEVELS, 1.0)
    weights[[0, -1]] = 0.5
    return points, weights / weights.sum()


def truth_poses(machine, n_poses, rng) -> tuple[np.ndarray, int]:
    """``n_poses`` random poses at the levels, then each axis swept over its levels with the
    others at their middle level; and the index where the sweeps start."""
    grids = [levels(axis)[0] for axis in machine.axis_specs]
    random = np.column_stack([rng.choice(grid, n_poses) for grid in grids])
    middle = np.array([grid[LEVELS // 2] for grid in grids])
    sweeps = []
    for a, grid in enumerate(grids):
        sweep = np.tile(middle, (LEVELS, 1))
        sweep[:, a] = grid
        sweeps.append(sweep)
    return np.concatenate([random, *sweeps]), n_poses


def one_machine(machine, plan, profile, n_poses, rng) -> dict:
    """Draw, identify and count one machine."""
    poses, start = truth_poses(machine, n_poses, rng)
    extra = PlannedRun(TRUTH_RUN, poses, ("dx",), np.ones(1))
    drawn = simulate_measurements(machine, (*plan, extra), profile=profile, rng=rng)
    meas = drawn.measurements
    keep = meas.run != TRUTH_RUN
    measured = replace(meas, **{name: getattr(meas, name)[keep] for name in
                                ("run", "poses", "quantity", "centre", "value", "u")})
    truth = drawn.errors[~keep]
    result = reliability.identify(machine, measured, profile=profile)
    out = {"errors": _errors_inside(machine, result, truth, start),
           "outputs": _outputs_inside(machine, result, poses[:start], truth[:start]),
           "chi2": result.chi2, "dof": result.dof, "result": result}
    if result.coefficients.varies:
        out["profiles"] = _profiles_inside(result, measured.poses, drawn.errors[keep])
    return out


def _errors_inside(machine, result, truth, start) -> np.ndarray:
    value = truth[start].copy()
    for a, axis in enumerate(machine.axis_specs):
        sweep = truth[start + a * LEVELS:start + (a + 1) * LEVELS, 6 * a:6 * a + 6]
        value[6 * a:6 * a + 6] = levels(axis)[1] @ sweep
    table = result.errors
    return (value >= table["lower"].to_numpy()) & (value <= table["upper"].to_numpy())


def _outputs_inside(machine, result, poses, truth) -> np.ndarray:
    mean, sd = result.predict(poses)
    exact = machine.comprehensive_error(poses, truth, frame="workpiece")
    return np.abs(exact - mean) <= Z95 * sd


def _profiles_inside(result, poses, truth) -> np.ndarray:
    table = result.profiles
    values = []
    for a, positions in enumerate(result.positions):
        _, first = np.unique(poses[:, a], return_index=True)
        values.append(truth[first, 6 * a:6 * a + 6].T.ravel())
    value = np.concatenate(values)
    return (value >= table["lower"].to_numpy()) & (value <= table["upper"].to_numpy())


def coverage_text(shares) -> str:
    """Mean share over machines, its standard error and how far from 0.95 in standard
    errors."""
    shares = np.asarray(shares, dtype=float)
    mean = shares.mean()
    se = shares.std(ddof=1) / math.sqrt(len(shares))
    return f"{mean:.4f} ± {se:.4f} (z = {(mean - 0.95) / se:+.1f})"


def chi2_text(chi2, dof) -> str:
    """KS p-value of the χ² CDF values, mean and variance against dof and 2 dof."""
    chi2, dof = np.asarray(chi2), np.asarray(dof)
    cdf = stats.chi2.cdf(chi2, dof)
    ks = stats.kstest(cdf, "uniform").pvalue
    excess = chi2 - dof
    z_mean = excess.mean() / math.sqrt(2 * dof.mean() / len(chi2))
    return (f"KS p = {ks:.3g}; mean - dof = {excess.mean():+.1f} (z = {z_mean:+.2f}); "
            f"var / (2 dof) = {excess.var(ddof=1) / (2 * dof.mean()):.3f}")


def run(name, profile, n_machines, n_poses, seed) -> None:
    """Print the coverage of one machine under one profile."""
    path, plan_path = MACHINES[name]
    machine = reliability.hobbing_machine() if path is None else reliability.load_machine(path)
    plan = read_plan(plan_path, machine)
    rng = generator(seed)
    started = time.perf_counter()
    counts = [one_machine(machine, plan, profile, n_poses, rng) for _ in range(n_machines)]
    first = counts[0]["result"]
    print(f"\n## {name}, profile {profile}: {n_machines} machines, {len(first.residuals)} "
          f"readings each, {n_poses} random poses ({time.perf_counter() - started:.0f} s)")
    print(first.summary())
    print(f"errors:  {coverage_text([c['errors'].mean() for c in counts])} over "
          f"{first.machine.n_errors} rows")
    if "profiles" in counts[0]:
        print(f"profiles at read positions: "
              f"{coverage_text([c['profiles'].mean() for c in counts])} over "
              f"{counts[0]['profiles'].size} values")
    print(f"outputs: {coverage_text([c['outputs'].mean() for c in counts])}")
    print(f"chi2:    {chi2_text([c['chi2'] for c in counts], [c['dof'] for c in counts])}")


@one_blas_thread
def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--machines", type=int, default=200, help="machines drawn per case")
    parser.add_argument("--poses", type=int, default=1000, help="random poses per machine")
    parser.add_argument("--profile", nargs="+", default=["constant", "gp:300"])
    parser.add_argument("--machine", nargs="+", choices=sorted(MACHINES),
                        default=["paper", "swivel5"])
    parser.add_argument("--seed", type=int, default=2026)
    args = parser.parse_args(argv)
    for name in args.machine:
        for profile in args.profile:
            run(name, profile, args.machines, args.poses, args.seed)


if __name__ == "__main__":
    main()
