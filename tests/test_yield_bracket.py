"""The machine yield judged on each machine's own poses, and the search's check of it."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy.stats import norm

import reliability
from allocation.per_pose.common_target import CommonTargetSolver
from allocation.per_pose.problem import AllocationProblem
from allocation.machine_yield.yield_bound import ChainLog, _greedy_chain, pose_chain_bound
from allocation.machine_yield.yield_search import YieldSearch
from reliability.model.poses import workspace_grid
from reliability.sampling.machine_yield import YieldModel, _largest_over_poses

MACHINE_DIR = Path(__file__).parent / "machines"


@pytest.fixture(scope="module")
def swivel_model():
    """A workpiece-frame machine whose motion errors differ at every grid point."""
    machine = reliability.load_machine(MACHINE_DIR / "swivel5.toml")
    return YieldModel(replace(machine, profile="independent"), points=3)


def test_ratios_at_the_grid_worst_poses_are_the_grid_ratios(swivel_model):
    u = swivel_model.draws(40, 1)
    t = swivel_model.machine.initial_allocation
    full, where = swivel_model.output_ratios(u, t, with_poses=True)
    ratios, found = swivel_model.ratios_at(u, t, where)
    np.testing.assert_allclose(ratios, full, rtol=1e-12)
    np.testing.assert_array_equal(found, where)


def test_ratios_at_other_poses_never_exceed_the_grid(swivel_model):
    u = swivel_model.draws(40, 2)
    t = swivel_model.machine.initial_allocation
    full = swivel_model.output_ratios(u, t)
    poses = np.random.default_rng(3).integers(0, swivel_model.experiment.n_poses, (40, 4))
    ratios, found = swivel_model.ratios_at(u, t, poses)
    assert np.all(ratios <= full * (1 + 1e-12))
    assert all(np.isin(found[m], poses[m]).all() for m in range(40))


@pytest.mark.parametrize("count", [1, 2, 5, 15625])
def test_largest_over_poses_is_the_maximum(count):
    rows = np.random.default_rng(count).standard_normal((3, count, 6))
    np.testing.assert_array_equal(_largest_over_poses(rows.copy()), rows.max(axis=1))


def test_search_checks_its_screen_on_the_whole_grid(trunnion5):
    """A screen that misses the worst poses is caught, widened, and then agrees with the
    grid; every screened verdict is at least as lenient as the grid's."""
    search = YieldSearch(trunnion5, 3, None, 60, 4, 0.0)
    t = trunnion5.initial_allocation
    grid = search.model.output_ratios(search.draws("design"), t) < 1.0
    np.testing.assert_array_equal(search.verdicts(t, "design"), grid)
    search._poses["design"] = np.zeros((60, 1), dtype=np.intp)
    screened = search.verdicts(t, "design")
    assert np.all(screened[grid])
    assert not np.array_equal(screened, grid)
    assert not search.confirm(t, "design")
    assert search._poses["design"].shape == (60, 7)
    assert search.confirm(t, "design")
    np.testing.assert_array_equal(search.verdicts(t, "design"), grid)


def test_ratios_at_skips_missing_poses(swivel_model):
    """A negative pose is no pose: each machine's ratios are those of its other poses, and a
    machine without any pose holds every output (ratio 0, pose -1)."""
    u = swivel_model.draws(30, 5)
    t = swivel_model.machine.initial_allocation
    poses = np.random.default_rng(4).integers(0, swivel_model.experiment.n_poses, (30, 3))
    holes = poses.copy()
    holes[::3, 1] = -1
    holes[1] = -1
    ratios, found = swivel_model.ratios_at(u, t, holes)
    for m in range(30):
        kept = holes[m][holes[m] >= 0]
        if len(kept) == 0:
            assert np.all(ratios[m] == 0) and np.all(found[m] == -1)
            continue
        alone, at = swivel_model.ratios_at(u[m:m + 1], t, kept[None, :])
        np.testing.assert_array_equal(ratios[m], alone[0])
        np.testing.assert_array_equal(found[m], at[0])


def test_a_failed_check_evaluates_the_grid_once(trunnion5, monkeypatch):
    """The check that catches a screen missing the worst poses takes the grid's verdicts and
    its worst poses from one evaluation of the whole grid."""
    search = YieldSearch(trunnion5, 3, None, 60, 4, 0.0)
    t = trunnion5.initial_allocation
    search.verdicts(t, "design")
    search._poses["design"] = np.zeros((60, 1), dtype=np.intp)
    calls = []
    whole_grid = search.model.output_ratios

    def counted(*args, **kwargs):
        calls.append(kwargs)
        return whole_grid(*args, **kwargs)
    monkeypatch.setattr(search.model, "output_ratios", counted)
    assert not search.confirm(t, "design")
    assert len(calls) == 1


@pytest.mark.parametrize("yield_target", [0.5, 0.95])
def test_chain_log_is_concave_and_above_the_log_probability(yield_target):
    """ĥ lies on or above h(v) = log(2Φ(1/√v) − 1) on [0, 1/z_Y²] and is concave there
    (second differences on a fine grid); at Y = 0.95 (z_Y above β_c) it is h itself."""
    z = norm.ppf((1 + yield_target) / 2)
    chain_log = ChainLog(z ** -2)
    v = np.linspace(1e-3, z ** -2, 4001)
    h = np.log(2 * norm.cdf(1 / np.sqrt(v)) - 1)
    upper = chain_log(v)
    assert np.all(upper >= h - 1e-12)
    assert np.all(np.diff(upper, 2) <= 1e-12)
    if yield_target == 0.95:
        np.testing.assert_allclose(upper, h, rtol=1e-12)


def test_joint_probability_at_a_pose_is_below_the_fresh_product(trunnion5):
    """The chain inequality, measured: 100 000 draws of the linearised outputs at one pose
    hold all six limits no more often than the product of the fresh rows' probabilities
    allows (at most Z = 4 standard errors above it), for loose tolerances."""
    machine = trunnion5
    pose = workspace_grid(machine, 3)[[40]]
    t = 2.5 * machine.initial_allocation
    sigma = t / 3.0
    coefficient = np.square(machine.jacobian(pose)) * np.square(sigma / machine.limits[:, None])
    support = coefficient > 1e-24 * coefficient.max(axis=2, keepdims=True)
    _, fresh, _ = _greedy_chain(coefficient, support, np.ones(len(t)), ChainLog(1e9))
    variance = fresh[0].sum(axis=1)
    bound = np.prod(1 - 2 * norm.sf(1 / np.sqrt(np.maximum(variance, 1e-300))))
    x = np.random.default_rng(8).standard_normal((100_000, len(t))) * sigma
    inside = np.all(np.abs(x @ machine.jacobian(pose)[0].T) < machine.limits, axis=1)
    share = inside.mean()
    assert 0.2 < bound < 0.9  # the event is neither sure nor impossible
    assert share <= bound + 4 * np.sqrt(bound * (1 - bound) / len(x))
    assert bound < (2 * norm.cdf(1 / np.sqrt(coefficient[0].sum(axis=1))) - 1).min()


def test_chain_bound_is_below_every_allocation_reaching_the_yield(trunnion5):
    """Validity: random shapes in the box, each scaled to the least precise allocation whose
    linearised machine yield on 1 500 normal draws is at least Y plus 4 standard errors,
    cost at least the bound; the bound is above the row bound, and certified to within
    1e-5 of its relaxation's solution."""
    machine = replace(trunnion5, profile="constant")
    problem = AllocationProblem.build(machine, workspace_grid(machine, 3), side="two_sided",
                                      workspace="worst")
    solver = CommonTargetSolver(problem)
    y = 0.9
    row = solver(y)
    chain = pose_chain_bound(problem, y, row.t)
    assert chain.bound > row.dual_bound * 1.01
    assert chain.bound <= problem.cost.total(chain.tolerances) * (1 + 1e-9)
    assert chain.bound >= problem.cost.total(chain.tolerances) * (1 - 1e-5)
    jacobian = machine.jacobian(problem.poses)  # (P, 6, n)
    rng = np.random.default_rng(9)
    draws = rng.standard_normal((1500, machine.n_errors))
    needed = y + 4 * np.sqrt(y * (1 - y) / len(draws))

    rows = jacobian.reshape(-1, machine.n_errors).T
    limits = np.tile(machine.limits, len(problem.poses))

    def linear_yield(t):
        return np.all(np.abs((draws * t / 3.0) @ rows) < limits, axis=1).mean()
    met = 0
    for shape in problem.lower + rng.random((4, machine.n_errors)) * (problem.upper
                                                                        - problem.lower):
        low, high = 0.0, 1.0  # scale of shape - lower
        for _ in range(6):
            middle = 0.5 * (low + high)
            t = problem.lower + middle * (shape - problem.lower)
            low, high = (middle, high) if linear_yield(t) >= needed else (low, middle)
        t = problem.lower + low * (shape - problem.lower)
        if linear_yield(t) >= needed:
            met += 1
            assert problem.cost.total(t) >= chain.bound
    assert met > 0


def test_no_chain_bound_where_the_loosest_corner_meets_every_pose(trunnion5):
    """At a yield the box's loosest corner reaches at every pose, the row optimum is that
    corner and no chain adds to the row bound."""
    problem = AllocationProblem.build(trunnion5, workspace_grid(trunnion5, 3),
                                      side="two_sided", workspace="worst")
    assert pose_chain_bound(problem, 0.05, problem.upper) is None
