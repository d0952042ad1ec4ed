"""Benchmark of the certified cheapest choice of catalogue classes (allocation.catalogue.discrete).

Run as ``python -m studies.benchmarks.catalogue``. On the paper's machine (5^6 = 15 625
poses, two-sided, the paper's targets) it prints

1. the example catalogue ``docs/examples/paper_catalogue.toml`` (14 components, 820 125 000
   choices): the solve time (best of 3) and that of its row screening, the price, gap,
   rounds of row generation; beside it HiGHS given every screened row at once, and the
   rate of a vectorised enumeration of choices on the same screened rows, measured on a
   sample and extrapolated to every choice;
2. a part of that catalogue small enough to enumerate in full (the screws, the guides and
   the C bearings: 135 000 choices): MILP against full vectorised enumeration, time and
   equality of the answers;
3. random catalogues of 30 components × 6 classes (two items each, 6^30 ≈ 2.2e23 choices)
   for several seeds: the solve time (row generation, gap 1e-9) beside HiGHS given every
   screened row at once, at the same gap and at its default gap 1e-4 (not a certificate),
   whether the prices agree, and the extrapolated enumeration time.

The enumeration reference computes, for a block of 256 choices at once, every screened
row's load as the sum of the chosen classes' precomputed contributions (one gather and add
per component, blocks small enough to stay in cache), keeps the feasible choices and the
cheapest: the simplest vectorised exact method. Nothing is asserted on times.
"""

from __future__ import annotations

import argparse
import itertools
import time
from pathlib import Path

import numpy as np
from scipy.optimize import Bounds, LinearConstraint, milp

import allocation
import reliability
from allocation.catalogue import discrete
from reliability.model.poses import workspace_grid
from studies.workflows.timing import best_time, one_blas_thread

EXAMPLE = Path(__file__).resolve().parents[2] / "docs" / "examples" / "paper_catalogue.toml"
BLOCK = 256  # choices per enumeration block (its loads stay in cache)
SAMPLE = 50_000  # choices timed to extrapolate the enumeration


class Enumeration:
    """Every choice's loads on the catalogue's screened rows, by blocks of choices."""

    def __init__(self, problem, catalogue):
        index = {name: i for i, name in enumerate(problem.names)}
        upper = problem.reference.copy()
        items = [np.array([index[i] for i in c.items]) for c in catalogue.components]
        for columns, component in zip(items, catalogue.components):
            upper[columns] = component.tolerance_matrix().max(axis=0)
        matrix = problem.rows_up_to(upper).matrix
        rest = np.ones(len(upper), bool)
        for columns in items:
            rest[columns] = False
        self.base = matrix[:, rest] @ problem.variable(problem.reference[rest])
        self.parts = [problem.variable(c.tolerance_matrix()) @ matrix[:, columns].T
                      for columns, c in zip(items, catalogue.components)]  # (classes, rows)
        self.prices = [c.prices() for c in catalogue.components]
        self.sizes = [len(c.classes) for c in catalogue.components]

    def block(self, choices):
        """(feasible, price) of an ``(n, n_components)`` block of class indices."""
        load = np.broadcast_to(self.base, (len(choices), len(self.base))).copy()
        price = np.zeros(len(choices))
        for c, part in enumerate(self.parts):
            load += part[choices[:, c]]
            price += self.prices[c][choices[:, c]]
        return load.max(axis=1) <= 1.0 + discrete.LOAD_TOLERANCE, price

    def cheapest(self):
        """The cheapest feasible choice over all choices: (class indices, price)."""
        best, best_price = None, np.inf
        everything = itertools.product(*(range(n) for n in self.sizes))
        while True:
            choices = np.array(list(itertools.islice(everything, BLOCK)))
            if len(choices) == 0:
                return best, best_price
            feasible, price = self.block(choices)
            price[~feasible] = np.inf
            k = int(np.argmin(price))
            if price[k] < best_price:
                best, best_price = choices[k], price[k]

    def rate(self, rng, n=SAMPLE) -> float:
        """Choices per second on random blocks (index generation included)."""
        start = time.perf_counter()
        for _ in range(n // BLOCK):
            self.block(np.column_stack([rng.integers(s, size=BLOCK) for s in self.sizes]))
        return (n // BLOCK) * BLOCK / (time.perf_counter() - start)


def sub_catalogue(catalogue, names):
    return allocation.Catalogue(components=tuple(c for c in catalogue.components
                                                 if c.name in names),
                                currency=catalogue.currency, source=catalogue.source)


def random_catalogue(machine, n_components, n_classes, rng):
    """Two consecutive items per component; classes at factors 0.3–3 of the initial
    allocation with ±20 % spread per item; prices ∝ 1/factor^0.7 with ±10 % spread."""
    factors = np.geomspace(0.3, 3.0, n_classes)
    names = machine.error_names
    components = []
    for c in range(n_components):
        items = names[2 * c:2 * c + 2]
        start = machine.initial_allocation[[machine.error_index(i) for i in items]]
        classes = []
        for j, factor in enumerate(factors):
            spread = rng.uniform(0.8, 1.2, len(items))
            classes.append({"name": f"class {j}",
                            "price": float(100 * factor ** -0.7 * rng.uniform(0.9, 1.1)),
                            "tolerances": dict(zip(items, (start * factor * spread).tolist()))})
        components.append({"name": f"component {c}", "items": list(items),
                           "classes": classes})
    return allocation.Catalogue.from_dict({"components": components})


def all_rows(problem, catalogue, gap=None):
    """HiGHS on every screened row at once (no row generation), at relative gap ``gap``
    (HiGHS's default 1e-4 when None): best-of-3 time and the price found."""
    enumeration = Enumeration(problem, catalogue)
    coefficients = np.vstack(enumeration.parts).T
    prices = np.concatenate(enumeration.prices)
    owner = np.repeat(np.arange(len(enumeration.sizes)), enumeration.sizes)
    one_each = (owner[None, :] == np.arange(len(enumeration.sizes))[:, None]).astype(float)
    constraints = [LinearConstraint(one_each, 1, 1),
                   LinearConstraint(coefficients, -np.inf, 1 - enumeration.base)]
    options = {} if gap is None else {"mip_rel_gap": gap}
    elapsed, solution = best_time(lambda: milp(prices, integrality=np.ones(len(prices)),
                                               bounds=Bounds(0, 1), constraints=constraints,
                                               options=options), 3)
    return elapsed, solution.fun


def split_times(problem, catalogue):
    """(total, screening) seconds of solve_catalogue, best of 3."""
    total, result = best_time(lambda: allocation.solve_catalogue(problem, catalogue), 3)
    upper = problem.reference.copy()
    for component in catalogue.components:
        for i, item in enumerate(component.items):
            upper[problem.names.index(item)] = component.tolerance_matrix()[:, i].max()
    screening, _ = best_time(lambda: problem.rows_up_to(upper), 3)
    return total, screening, result


@one_blas_thread
def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=5, help="random 30 x 6 catalogues")
    args = parser.parse_args(argv)
    rng = np.random.default_rng(0)
    machine = reliability.hobbing_machine()
    t_build, problem = best_time(
        lambda: allocation.AllocationProblem.build(machine, workspace_grid(machine)), 1)
    print(f"Catalogue benchmark: {machine.name}, {len(problem.poses)} poses, two-sided, "
          f"targets {machine.targets[0]:g}; problem build {t_build:.2f} s (not counted below)")

    # ----- 1. the example catalogue ----------------------------------------------------
    catalogue = allocation.load_catalogue(EXAMPLE, machine)
    total, screening, result = split_times(problem, catalogue)
    rate = Enumeration(problem, catalogue).rate(rng)
    print(f"\n1. Example catalogue: {len(catalogue.components)} components, "
          f"{catalogue.n_choices:,} choices, {result.details['rows']['dominance']} screened rows")
    print(f"   solve_catalogue (best of 3)   {total:8.3f} s  (row screening alone, best of 3: "
          f"{screening:.3f} s; {result.details['nodes']} HiGHS nodes)")
    print(f"   price {result.price:g}, relative gap {result.gap:.1e}, certified "
          f"{result.certified}; row generation: {result.details['rounds']} rounds, "
          f"{result.details['active_rows']} of {result.details['rows']['dominance']} rows")
    t_all, price_all = all_rows(problem, catalogue, discrete.MIP_REL_GAP)
    print(f"   HiGHS on all screened rows at once: {t_all:.3f} s for its MILP alone "
          f"({t_all / total:.1f} x solve_catalogue with its screening), price {price_all:g}")
    print(f"   enumeration: {rate:,.0f} choices/s measured -> "
          f"{catalogue.n_choices / rate:,.0f} s for every choice (extrapolated), "
          f"{catalogue.n_choices / rate / total:,.0f} x solve_catalogue")

    # ----- 2. a part small enough to enumerate -------------------------------------------
    names = [c.name for c in catalogue.components
             if "screw" in c.name or "guides" in c.name or c.name.startswith("C worktable")]
    part = sub_catalogue(catalogue, names)
    total, _, chosen = split_times(problem, part)
    enumeration = Enumeration(problem, part)
    t_enumerate, (best, price) = best_time(enumeration.cheapest, 1)
    same = {c.name: c.classes[j].name for c, j in zip(part.components, best)} == chosen.choice
    print(f"\n2. Screws, guides and C bearings: {part.n_choices:,} choices")
    print(f"   solve_catalogue {total:.3f} s, full enumeration {t_enumerate:.3f} s "
          f"({t_enumerate / total:.1f} x); same choice: {'yes' if same else 'NO'}, prices "
          f"{chosen.price:g} and {price:g}")

    # ----- 3. random 30 x 6 catalogues -----------------------------------------------------
    print(f"\n3. Random catalogues, 30 components x 6 classes ({6 ** 30:.2e} choices), "
          f"{args.seeds} seeds")
    print(f"   {'seed':>4} {'solve s':>8} {'gap':>8} {'rounds':>6} {'all rows s':>10} "
          f"{'ratio':>6} {'same price':>10} {'default gap s':>13} "
          f"{'enumeration (extrapolated)':>27}")
    for seed in range(args.seeds):
        random = random_catalogue(machine, 30, 6, np.random.default_rng(seed))
        try:
            total, _, result = split_times(problem, random)
        except allocation.CatalogueInfeasibleError as exc:
            print(f"   {seed:>4} infeasible: {exc}")
            continue
        t_all, price_all = all_rows(problem, random, discrete.MIP_REL_GAP)
        t_default, _ = all_rows(problem, random)
        same = abs(price_all - result.price) <= 1e-9 * result.price
        years = random.n_choices / Enumeration(problem, random).rate(rng, 40 * BLOCK) \
            / 3.15e7
        print(f"   {seed:>4} {total:8.3f} {result.gap:8.1e} {result.details['rounds']:6d} "
              f"{t_all:10.3f} {t_all / total:6.1f} {'yes' if same else 'NO':>10} "
              f"{t_default:13.3f} {years:21.1e} years")


if __name__ == "__main__":
    main()
