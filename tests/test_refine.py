"""allocation.refine: pose cutting planes make the target hold between grid points."""

import numpy as np
import pytest

from allocation.problem import AllocationProblem
from allocation.refine import solve_over_workspace
from reliability.model.poses import workspace_grid
from reliability.first_order.workspace_search import continuous_worst


@pytest.fixture(scope="module")
def coarse_problem(hobbing):
    """Two-sided worst case on a 3-point grid: coarse, so the gaps are wide."""
    return AllocationProblem.build(hobbing, workspace_grid(hobbing, 3), side="two_sided")


def test_refined_optimum_holds_between_grid_points(hobbing, coarse_problem):
    grid_optimum = coarse_problem.solve_exact()
    before = continuous_worst(hobbing, grid_optimum.tolerances, coarse_problem.poses)
    assert np.any(before["beta"] < coarse_problem.required_index * (1 - 1e-4))
    refined, added = solve_over_workspace(coarse_problem)
    assert len(added) > 0
    required = coarse_problem.required_index
    # From the same starts as the refinement's last check (grid and added poses): met.
    starts = np.vstack([coarse_problem.poses, added])
    after = continuous_worst(hobbing, refined.tolerances, starts)
    assert np.all(after["beta"] >= required * (1 - 1e-6))
    # The search is local: from the bare grid it may land on a neighbouring local worst,
    # which still misses the target by far less than the grid optimum did.
    from_grid = continuous_worst(hobbing, refined.tolerances, coarse_problem.poses)
    assert np.all(from_grid["beta"] >= required * (1 - 1e-4))
    assert refined.certificate["certified"]
    assert refined.cost >= grid_optimum.cost  # more poses can only cost more


def test_with_poses_appends_rows_for_new_poses(hobbing, coarse_problem):
    extra = np.array([[0.1, 10.0, 150.0, 0.2, 20.0, 0.3]])
    bigger = coarse_problem.with_poses(extra)
    assert len(bigger.poses) == len(coarse_problem.poses) + 1
    assert len(bigger.rows.matrix) == len(coarse_problem.rows.matrix) + 6
    np.testing.assert_allclose(bigger.rows.matrix[-6:],
                               bigger.row_matrix(hobbing.jacobian(extra))[0])
    assert bigger.rows.counts["added"] == 6


def test_mean_reading_refused(hobbing):
    problem = AllocationProblem.build(hobbing, workspace_grid(hobbing, 2), workspace="mean")
    with pytest.raises(ValueError, match="worst-case"):
        solve_over_workspace(problem)
