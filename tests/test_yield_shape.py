"""The error-shape stage of the yield allocation and the pieces it rests on."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from allocation import AllocationProblem
from allocation.machine_yield.yield_shape import scaled_to_yield, shape_search
from reliability import load_machine, workspace_grid
from reliability.sampling.machine_yield import YieldModel

TRUNNION = Path(__file__).parent / "machines" / "trunnion5.toml"


@pytest.fixture(scope="module")
def setting():
    machine = load_machine(TRUNNION)
    model = YieldModel(machine, points=3)
    u = np.random.default_rng(4).standard_normal((400, model.dimension))
    return machine, model, u


@pytest.mark.parametrize("profile", ["constant", "gp:300"])
def test_contributions_sum_to_the_chains_worst_row(profile):
    """Σ_i J_ri x_i at each machine's worst row is the exact chain's value there to first
    order: at a tenth of the tolerances the relative difference is below 1e-4."""
    machine = load_machine(TRUNNION)
    model = YieldModel(machine, profile=profile, points=3)
    u = np.random.default_rng(1).standard_normal((50, model.dimension))
    t = 0.1 * machine.initial_allocation
    ratio, worst = model.worst_ratios(u, t)
    terms = model.row_contributions(u, t, worst)
    limits = np.tile(machine.limits, model.experiment.n_poses)[worst]
    np.testing.assert_allclose(np.abs(terms.sum(axis=1)) / limits, ratio, rtol=1e-4)


def test_worst_ratio_is_homogeneous_to_first_order(setting):
    """g(c t) = c g(t) up to the chain's second-order terms (what the quantile scaling uses)."""
    machine, model, u = setting
    t = machine.initial_allocation
    base = model.worst_ratios(u, t)[0]
    np.testing.assert_allclose(model.worst_ratios(u, 0.5 * t)[0], 0.5 * base, rtol=1e-4)


def test_shape_search_meets_the_design_yield_in_the_box(setting):
    """The result, checked independently on the same draws, reaches the design yield, lies
    in the box, and costs no more than the start scaled onto the same yield."""
    machine, model, u = setting
    problem = AllocationProblem.build(machine, workspace_grid(machine, 3))
    lower, upper = np.asarray(problem.lower), np.asarray(problem.upper)
    start = problem.solve_exact().tolerances
    found = shape_search(model, problem.cost, lower, upper, start, 0.9, u, iterations=8)
    assert np.mean(model.worst_ratios(u, found.tolerances)[0] < 1.0) >= 0.9
    assert found.design_yield >= 0.9
    assert np.all(found.tolerances >= lower) and np.all(found.tolerances <= upper)
    first = shape_search(model, problem.cost, lower, upper, start, 0.9, u, iterations=1)
    assert first.steps == 0 and found.cost <= first.cost
    assert found.cost == pytest.approx(problem.cost.total(found.tolerances))


def test_scaling_to_a_yield_finds_the_largest_scale_when_lower_bounds_hold_items():
    """Half the tolerances may tighten by 10 % only, so the quantile's fixed-point steps
    stall; the scale found is then bisected: its yield reaches the target on the sample, a
    scale 1 % larger misses it, and the allocation is the clipped multiple of the shape."""
    machine = load_machine(Path(__file__).parent / "machines" / "trunnion5.toml")
    model = YieldModel(machine, profile="constant", points=3)
    u = model.draws(300, 4)
    shape = np.asarray(machine.initial_allocation, dtype=float)
    lower, upper = 0.2 * shape, 10.0 * shape
    lower[::2] = 0.9 * shape[::2]
    found = scaled_to_yield(model, lower, upper, shape, 0.95, u)
    assert found["passes"].mean() >= 0.95
    np.testing.assert_array_equal(found["t"], np.clip(found["scale"] * shape, lower, upper))
    looser = np.clip(1.01 * found["scale"] * shape, lower, upper)
    assert (model.output_ratios(u, looser) < 1.0).all(axis=1).mean() < 0.95
    assert scaled_to_yield(model, lower, upper, shape, 0.999, u) is None
