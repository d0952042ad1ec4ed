"""Bounded memory: chunked computations equal the whole-array ones, and the fast screen
keeps the optimum of the unscreened problem.

Chunks are forced with tiny memory budgets, so that a 729-pose grid is processed in many
pieces; each result is compared with the same quantity computed on whole arrays (the
previous implementation) or from first principles (finite differences, brute force).
"""

from __future__ import annotations

import itertools
import json

import numpy as np
import pytest

from allocation import AllocationProblem, screen_rows, solve_convex_allocation
from reliability.basics.chunks import chunks
from reliability.basics.errors import InputError, SavedResultError
from reliability.first_order.fosm import error_sigma, fosm
from reliability.first_order.workspace_search import _negative_sigma_and_gradient, continuous_worst
from reliability.model.kinematics import jacobian_and_derivative
from reliability.model.poses import grid_axis_points, random_poses, workspace_grid
from reliability.sampling.grid_experiment import GridExperiment

TINY = 40_000  # bytes: about 25 hobbing poses per chunk


@pytest.fixture(scope="module")
def grid3(hobbing):
    return workspace_grid(hobbing, 3)


def test_chunks_cover_every_item_once_within_the_budget():
    parts = chunks(1000, 24, memory=240)
    assert [p.stop - p.start for p in parts] == [10] * 100
    assert chunks(5, 10 ** 9, memory=1) == [slice(0, 1), slice(1, 2), slice(2, 3),
                                             slice(3, 4), slice(4, 5)]
    with pytest.raises(InputError, match="memory"):
        chunks(10, 8, memory=0)


def test_workspace_grid_is_the_product_of_the_axis_points(trunnion5):
    points = grid_axis_points(trunnion5, 4)
    expected = np.array(list(itertools.product(*points)))
    np.testing.assert_array_equal(workspace_grid(trunnion5, 4), expected)


@pytest.mark.parametrize("means", [False, True])
def test_chunked_fosm_equals_fosm_on_the_whole_jacobian(hobbing, grid3, means):
    t = hobbing.initial_allocation
    mu = 0.2 * t if means else None
    whole = fosm(hobbing, t, grid3, jacobian=hobbing.jacobian(grid3), means=mu)
    chunked = fosm(hobbing, t, grid3, memory=TINY, means=mu)
    for name in ("mean", "sigma", "beta", "one_sided", "two_sided"):
        np.testing.assert_allclose(getattr(chunked, name), getattr(whole, name),
                                   rtol=1e-13, atol=0)
    np.testing.assert_array_equal(chunked.worst_pose, whole.worst_pose)
    np.testing.assert_allclose(chunked.contributions, whole.contributions, rtol=1e-12)
    # and σ from first principles, Eq. (20), on the whole Jacobian
    jac = hobbing.jacobian(grid3)
    sigma = np.sqrt(np.einsum("pon,n->po", jac ** 2, error_sigma(t) ** 2))
    np.testing.assert_allclose(chunked.sigma, sigma, rtol=1e-13)
    if means:
        np.testing.assert_allclose(chunked.mean, hobbing.comprehensive_error(grid3, mu),
                                   rtol=1e-13, atol=1e-18)


def brute_force_undominated(matrix):
    """Rows not ≤ another row in every entry: the definition, pair by pair."""
    keep = []
    for i, row in enumerate(matrix):
        others = np.delete(matrix, i, axis=0)
        if not np.any(np.all(others >= row, axis=1)):
            keep.append(i)
    return np.array(keep, dtype=int)


def old_screen(rows, upper_u):
    """The previous screen: box, duplicates, then every row against every other (entries
    equal but for rounding taken as equal)."""
    from allocation.per_pose.problem import _equal_entries_equal, _unique_rows

    kept = []
    for output in range(rows.shape[1]):
        matrix = rows[:, output, :]
        pose = np.flatnonzero(matrix @ upper_u > 1.0)
        pose = pose[_unique_rows(matrix[pose])]
        pose = pose[brute_force_undominated(_equal_entries_equal(matrix[pose]))]
        kept.extend((int(p), output) for p in pose)
    return sorted(kept)


def test_undominated_equals_the_definition_on_random_rows():
    rng = np.random.default_rng(3)
    # few distinct values, a constant column and a duplicated column: many ties
    matrix = rng.integers(0, 4, size=(600, 6)).astype(float)
    matrix[:, 2] = 1.5
    matrix[:, 5] = matrix[:, 0]
    matrix = np.unique(matrix, axis=0)[rng.permutation(len(np.unique(matrix, axis=0)))]
    from allocation.per_pose.problem import _undominated

    np.testing.assert_array_equal(_undominated(matrix, block=16),
                                  brute_force_undominated(matrix))


@pytest.mark.parametrize("side", ["one_sided", "two_sided"])
def test_screen_keeps_the_rows_of_the_old_screen(hobbing, grid3, side):
    problem = AllocationProblem.build(hobbing, grid3, side=side)
    rows = problem.row_matrix()
    upper_u = problem.upper ** 2
    new = screen_rows(rows, upper_u)
    assert sorted(zip(new.pose.tolist(), new.output.tolist())) == old_screen(rows, upper_u)


@pytest.mark.parametrize("side", ["one_sided", "two_sided"])
def test_screened_optimum_equals_the_unscreened_optimum(hobbing, grid3, side):
    problem = AllocationProblem.build(hobbing, grid3, side=side)
    all_rows = problem.row_matrix().reshape(-1, hobbing.n_errors)
    w, lo, hi = problem.cost.weights, problem.lower ** 2, problem.upper ** 2
    unscreened = solve_convex_allocation(w, all_rows, lo, hi)
    screened = solve_convex_allocation(w, problem.rows.matrix, lo, hi)
    assert unscreened.success and screened.success
    # each optimum lies in [dual_bound, fun]; the intervals overlap (to the 1e-9 of
    # rows merged as duplicates to 10 digits)
    assert screened.dual_bound <= unscreened.fun * (1 + 1e-9)
    assert unscreened.dual_bound <= screened.fun * (1 + 1e-9)
    assert np.max(all_rows @ screened.u) <= 1 + 1e-9  # feasible for every unscreened row


def test_chunked_problem_equals_the_whole_array_problem(hobbing, grid3):
    whole = AllocationProblem.build(hobbing, grid3, side="two_sided")
    chunked = AllocationProblem.build(hobbing, grid3, side="two_sided", memory=TINY)
    assert whole.jacobian is not None and chunked.jacobian is None
    assert chunked.rows.counts == whole.rows.counts
    np.testing.assert_array_equal(chunked.rows.pose, whole.rows.pose)
    np.testing.assert_array_equal(chunked.rows.output, whole.rows.output)
    np.testing.assert_allclose(chunked.rows.matrix, whole.rows.matrix, rtol=1e-14)
    t = hobbing.initial_allocation
    np.testing.assert_allclose(chunked.sigma(t), whole.sigma(t), rtol=1e-13)
    np.testing.assert_allclose(chunked.loads(t ** 2),
                               whole.row_matrix() @ t ** 2, rtol=1e-13)
    a, b = whole.solve_exact(), chunked.solve_exact()
    assert b.cost == pytest.approx(a.cost, rel=1e-12)
    assert b.feasible and b.certificate["certified"]


def test_unreachable_target_is_reported_from_chunks(hobbing_dict, grid3):
    from reliability.model.machine_file import machine_from_dict
    from allocation.per_pose.solve import TargetUnreachableError

    hobbing_dict["requirements"]["dx"]["limit"] = 1e-4  # far below any reachable σ
    machine = machine_from_dict(hobbing_dict)
    whole = AllocationProblem.build(machine, grid3)
    chunked = AllocationProblem.build(machine, grid3, memory=TINY)
    with pytest.raises(TargetUnreachableError) as expected:
        whole.solve_exact()
    with pytest.raises(TargetUnreachableError) as got:
        chunked.solve_exact()
    assert str(got.value) == str(expected.value)


@pytest.mark.parametrize("start,side", [("two_sided", "one_sided"),
                                        ("one_sided", "two_sided")])
def test_with_reading_solves_like_a_fresh_build(hobbing, grid3, start, side):
    shared = AllocationProblem.build(hobbing, grid3, side=start).with_reading(side)
    fresh = AllocationProblem.build(hobbing, grid3, side=side)
    assert shared.side == side and shared.jacobian is not None
    if side == "one_sided":  # looser: derived from the two-sided rows, not rescreened
        assert "shared" in shared.rows.counts
    else:  # tighter: screened afresh, exactly as a fresh build
        assert shared.rows.counts == fresh.rows.counts
    assert shared.solve_exact().cost == pytest.approx(fresh.solve_exact().cost, rel=1e-9)


def test_jacobian_derivative_matches_central_differences(any_machine):
    machine = any_machine
    q = random_poses(machine, 5, rng=11)
    _, derivative = jacobian_and_derivative(machine, q)
    h = 1e-5  # mm or rad; central differences err by O(h²)
    for a in range(len(machine.axis_specs)):
        step = np.zeros(len(machine.axis_specs))
        step[a] = h
        numeric = (machine.jacobian(q + step) - machine.jacobian(q - step)) / (2 * h)
        scale = np.abs(numeric).max()
        np.testing.assert_allclose(derivative[:, a], numeric, atol=1e-7 * scale)


def test_sigma_gradient_matches_central_differences(hobbing):
    sigma_x = error_sigma(hobbing.initial_allocation)
    q = random_poses(hobbing, 1, rng=5)[0]
    h = 1e-5
    for output in range(6):
        value, gradient = _negative_sigma_and_gradient(hobbing, q, sigma_x, output)
        numeric = np.empty_like(q)
        for a in range(len(q)):
            step = np.zeros_like(q)
            step[a] = h
            plus = _negative_sigma_and_gradient(hobbing, q + step, sigma_x, output)[0]
            minus = _negative_sigma_and_gradient(hobbing, q - step, sigma_x, output)[0]
            numeric[a] = (plus - minus) / (2 * h)
        # central differences of σ ~ 1e-3 carry rounding of about 1e-16 / h
        np.testing.assert_allclose(gradient, numeric, rtol=1e-5, atol=1e-9 * abs(value))


def test_continuous_worst_reuses_the_given_grid_sigma(hobbing, grid3):
    t = hobbing.initial_allocation
    problem = AllocationProblem.build(hobbing, grid3)
    given = continuous_worst(hobbing, t, grid3, grid_sigma=problem.sigma(t))
    computed = continuous_worst(hobbing, t, grid3, memory=TINY)
    # poses may differ where σ ties (outputs that do not depend on some axes)
    columns = ["grid_beta", "beta", "grid_two_sided", "two_sided"]
    np.testing.assert_allclose(given[columns].to_numpy(), computed[columns].to_numpy(),
                               rtol=1e-9)
    with pytest.raises(ValueError, match="grid_sigma must have shape"):
        continuous_worst(hobbing, t, grid3, grid_sigma=np.ones((3, 6)))


def test_grid_experiment_batches_within_memory_give_the_same_counts(trunnion5):
    experiment = GridExperiment(trunnion5, 3)
    t = trunnion5.initial_allocation
    one_at_a_time = experiment.run(t, repeats=5, rng=4, memory=1, keep_values="none")
    together = experiment.run(t, repeats=5, rng=4, batch=50)
    np.testing.assert_array_equal(one_at_a_time.inside, together.inside)


def test_grid_experiment_checkpoint_resumes_without_recomputing(trunnion5, tmp_path,
                                                               monkeypatch):
    experiment = GridExperiment(trunnion5, 3)
    t = trunnion5.initial_allocation
    first = experiment.run(t, repeats=6, rng=9, batch=2, checkpoint=tmp_path,
                           keep_values="none")
    assert len(list(tmp_path.glob("*.json"))) == 3
    calls = []
    original = GridExperiment.evaluate
    monkeypatch.setattr(GridExperiment, "evaluate",
                        lambda self, *a: calls.append(1) or original(self, *a))
    again = experiment.run(t, repeats=6, rng=9, batch=2, checkpoint=tmp_path,
                           keep_values="none")
    np.testing.assert_array_equal(again.inside, first.inside)
    assert calls == []
    other_seed = experiment.run(t, repeats=6, rng=10, batch=2, checkpoint=tmp_path,
                                keep_values="none")
    assert len(calls) == 3 and not np.array_equal(other_seed.inside, first.inside)
    damaged = sorted(tmp_path.glob("*.json"))[0]
    record = json.loads(damaged.read_text())
    record["result"][0][0] += 1
    damaged.write_text(json.dumps(record))
    with pytest.raises(SavedResultError, match="checksum"):
        for seed in (9, 10):  # the damaged batch belongs to one of the two runs
            experiment.run(t, repeats=6, rng=seed, batch=2, checkpoint=tmp_path,
                           keep_values="none")


def test_output_variance_equals_the_squared_jacobian_sum(any_machine):
    from reliability.model.kinematics import output_variance

    q = random_poses(any_machine, 50, rng=2)
    variance = error_sigma(any_machine.initial_allocation) ** 2
    expected = np.einsum("pon,n->po", any_machine.jacobian(q) ** 2, variance)  # Eq. (20)
    np.testing.assert_allclose(output_variance(any_machine, q, variance), expected,
                               rtol=1e-13)


def test_rows_equal_up_to_rounding_are_one_row_across_a_rounding_step():
    """Two rows equal but for last-bit rounding, with an entry right at a step of the
    10-digit rounding (so that rounding alone puts them in different cells), are screened
    as one row, and rows differing in the 9th digit stay two."""
    rng = np.random.default_rng(3)
    base = rng.uniform(0.1, 1.0, (4, 6))
    twin = base.copy()
    base[0, 2] = 0.3 + 5e-11  # halfway between two 10-digit steps of the row's scale
    twin[0, 2] = np.nextafter(base[0, 2], 0.0)
    twin[1:] = base[1:] * (1 + 4e-16)
    apart = base[:1] * (1 + 1e-8)
    rows = np.stack([np.vstack([base, twin, apart])] * 6, axis=1)  # (9 poses, 6, 6 items)
    screened = screen_rows(rows, np.full(6, 10.0))
    assert screened.counts["duplicates"] == 6 * 5


def test_entries_equal_but_for_rounding_are_equal_in_the_dominance_screen():
    """A row whose entries equal another's but for last bits on either side is dominated
    by it (and the other way round only one of them is kept); an entry apart by 1e-9 is
    not equal."""
    from allocation.per_pose.problem import _equal_entries_equal, _undominated

    base = np.array([[0.5, 0.25, 0.125], [0.1, 0.9, 0.3]])
    noisy = np.array([[np.nextafter(0.5, 1.0), np.nextafter(0.25, 0.0), 0.125]])
    apart = np.array([[0.5 * (1 + 1e-9), 0.2, 0.1]])
    matrix = np.vstack([base, noisy, apart])
    canonical = _equal_entries_equal(matrix)
    assert canonical[0, 0] == canonical[2, 0] == 0.5
    assert canonical[0, 1] == canonical[2, 1] == np.nextafter(0.25, 0.0)
    assert canonical[3, 0] == matrix[3, 0]
    assert _undominated(matrix).tolist() == [1, 2, 3] or \
        _undominated(matrix).tolist() == [0, 1, 3]
