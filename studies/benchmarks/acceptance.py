"""Benchmark: built machines through a file of acceptance tests, against a simple reference.

Run as ``python -m studies.benchmarks.acceptance [--machines N] [--reference N]``. On the
paper's machine and ``docs/examples/paper_tests.toml`` (6 tests: two circles, three
positioning tests, one rotary test; gp:300 profiles) it times

1. :func:`reliability.acceptance.prediction.acceptance` for ``N`` built machines (default 10 000),
   in full (with the drivers, each error item drawn alone on 200 machines) and results only;
2. the simple vectorised reference, on fewer machines (default 1 000): every motion error
   drawn at each position its axis visits (a Cholesky factor per axis), gathered to every
   pose, the exact model of Eq. (18) batched over machines and poses, rotated into the
   workpiece frame, an algebraic circle fit, the same ISO 230-2 statistics;
3. the same reference with the toolkit's first-order model (``R(q) J_δ(q) x`` per pose and
   machine) instead of the exact product, the like-for-like comparison;

and prints the time per 10 000 machines of each, their ratio, and both answers' means.
Nothing is asserted on times; the ratio is the result.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

import reliability
from reliability.acceptance.definitions import read_tests
from reliability.acceptance.iso_statistics import positioning_statistics
from reliability.acceptance.iso_tests import (CircularTest, PositioningTest, build_path,
                                              deviation_weights, ideal_chain)
from reliability.acceptance.prediction import acceptance
from reliability.basics.chunks import chunks
from reliability.basics.streams import generator
from reliability.model.profiles import GaussianProfile
from studies.workflows.timing import best_time, one_blas_thread

TESTS = Path(__file__).resolve().parents[2] / "docs" / "examples" / "paper_tests.toml"
LENGTH = 300.0  # mm, the default gp:300 profile


def reference(machine, tests, tolerances, n, rng, exact: bool = True) -> dict:
    """The simple reference: errors at every visited pose, the exact model (or with
    ``exact=False`` the same first-order model as the toolkit, per pose), plain fits."""
    rng = generator(rng)
    paths = [build_path(machine, test) for test in tests]
    poses = np.concatenate([p.poses for p in paths])
    rotation = ideal_chain(machine, poses)[:, :3, :3]
    weights = None if exact else deviation_weights(machine, poses)
    sigma = tolerances / 3.0
    n_axes = len(machine.axes)
    deviations = np.empty((n, len(poses), 3))
    for part in chunks(n, 8 * len(poses) * machine.n_errors * 4):
        m = part.stop - part.start
        x = np.empty((m, len(poses), machine.n_errors))
        for a, axis in enumerate(machine.axis_specs):
            visited, at = np.unique(np.round(poses[:, a], 9), return_inverse=True)
            factor = GaussianProfile(LENGTH).factor(axis, visited)   # Cholesky, with jitter
            z = rng.standard_normal((m, len(visited), 6))
            values = np.einsum("pq,mqc->mpc", factor, z) * sigma[6 * a:6 * a + 6]
            x[:, :, 6 * a:6 * a + 6] = values[:, at.reshape(-1)]
        x[:, :, 6 * n_axes:] = (rng.standard_normal((m, machine.n_errors - 6 * n_axes))
                                * sigma[6 * n_axes:])[:, None, :]
        if exact:
            delta = machine.comprehensive_error(poses, x)[..., :3]
            deviations[part] = np.einsum("pij,mpj->mpi", rotation, delta)
        else:
            deviations[part] = np.einsum("poi,mpi->mpo", weights, x)
    results, start = {}, 0
    for path in paths:
        d = deviations[:, start:start + len(path.poses)] @ path.directions.T
        start += len(path.poses)
        if isinstance(path.test, CircularTest):
            results[(path.test.name, "G")] = _kasa_g(path.nominal + d)
        elif isinstance(path.test, PositioningTest):
            noise = rng.standard_normal((n, path.test.runs, 2, len(path.poses)))
            axis = machine.axis_specs[machine.axes.index(path.test.axis)]
            runs = d[:, None, None, :, 0] + axis.reversal * np.array([[0.5], [-0.5]]) \
                + axis.repeatability * noise
            stats = positioning_statistics(runs)
            results.update({(path.test.name, q): stats[q] for q in "EARB"})
        else:
            for i, q in enumerate(path.test.quantities):
                results[(path.test.name, q)] = np.ptp(d[..., i], axis=1)
    return results


def _kasa_g(points) -> np.ndarray:
    """G about the algebraic (Kåsa) least-squares circle centre."""
    x, y = points[..., 0], points[..., 1]
    design = np.stack([x, y, np.ones_like(x)], -1)
    coef = np.linalg.solve(np.einsum("npi,npj->nij", design, design),
                           np.einsum("npi,np->ni", design, x ** 2 + y ** 2)[..., None])[..., 0]
    radial = np.hypot(x - coef[:, :1] / 2, y - coef[:, 1:2] / 2)
    return radial.max(axis=1) - radial.min(axis=1)


@one_blas_thread
def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--machines", type=int, default=10_000)
    parser.add_argument("--reference", type=int, default=1_000)
    parser.add_argument("--repeats", type=int, default=2)
    args = parser.parse_args(argv)
    machine = reliability.hobbing_machine()
    tests = read_tests(TESTS, machine)
    t = machine.initial_allocation
    poses = sum(len(build_path(machine, test).poses) for test in tests)
    print(f"{machine.name}: {len(tests)} tests, {poses} poses per machine, gp:{LENGTH:g}")
    full, ours = best_time(lambda: acceptance(machine, tests, t, machines=args.machines,
                                              rng=1), args.repeats)
    bare, _ = best_time(lambda: acceptance(machine, tests, t, machines=args.machines,
                                           driver_machines=1, rng=1), args.repeats)
    simple, theirs = best_time(lambda: reference(machine, tests, t, args.reference, 2), 1)
    linear, _ = best_time(lambda: reference(machine, tests, t, args.reference, 2, False), 1)
    per = 10_000 / args.machines
    reference_10k = simple * 10_000 / args.reference
    linear_10k = linear * 10_000 / args.reference
    print(f"toolkit, {args.machines} machines: {full:.2f} s with drivers, {bare:.2f} s "
          f"results only ({full * per:.2f} s and {bare * per:.2f} s per 10 000)")
    print(f"simple reference, {args.reference} machines: {simple:.2f} s "
          f"({reference_10k:.1f} s per 10 000)")
    print(f"simple reference on the first-order model, {args.reference} machines: "
          f"{linear:.2f} s ({linear_10k:.1f} s per 10 000)")
    for label, time in (("exact", reference_10k), ("first-order", linear_10k)):
        print(f"ratio {label} reference / toolkit per machine: {time / (full * per):.1f} "
              f"(with drivers), {time / (bare * per):.1f} (results only)")
    print(f"\n{'test':<16}{'quantity':<10}{'toolkit mean µm':>17}{'reference mean µm':>19}")
    for key, values in theirs.items():
        print(f"{key[0]:<16}{key[1]:<10}{1000 * ours.values[key].mean():>17.3f}"
              f"{1000 * values.mean():>19.3f}")


if __name__ == "__main__":
    main()
