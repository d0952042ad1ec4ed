"""Tests of the pose sets: the 5^6 workspace grid of Sec. 5.3 and random poses."""

from __future__ import annotations

import math

import numpy as np
import pytest

from reliability.model.poses import grid_axis_points, random_poses, workspace_grid


def test_hobbing_grid_shape_and_axis_points(hobbing):
    grid = workspace_grid(hobbing)
    assert grid.shape == (15625, 6)
    turn = [0.0, 2 * math.pi / 5, 4 * math.pi / 5, 6 * math.pi / 5, 8 * math.pi / 5]
    expected = {
        "C": turn,                                              # one turn, no 2π
        "X": [0.0, 100.0, 200.0, 300.0, 400.0],                 # both ends
        "Z": [100.0, 200.0, 300.0, 400.0, 500.0],
        "A": [-math.pi / 4, -math.pi / 8, 0.0, math.pi / 8, math.pi / 4],
        "Y": [0.0, 50.0, 100.0, 150.0, 200.0],
        "M": turn,
    }
    for column, name in enumerate(hobbing.axes):
        values = np.unique(grid[:, column])
        # linspace reproduces these to a few ulp of 2π.
        np.testing.assert_allclose(values, expected[name], rtol=0, atol=1e-14, err_msg=name)
        assert np.sum(grid[:, column] == values[0]) == 3125
    assert np.isclose(grid[:, 0].max(), 8 * math.pi / 5) and grid[:, 0].max() < 2 * math.pi
    assert len(np.unique(grid, axis=0)) == 15625


def test_grid_order_first_axis_slowest(hobbing):
    grid = workspace_grid(hobbing)
    np.testing.assert_array_equal(grid[0], [0.0, 0.0, 100.0, -math.pi / 4, 0.0, 0.0])
    # The last axis (M) changes every row, the first (C) every 5^5 rows.
    assert grid[1, 5] > grid[0, 5] and np.all(grid[1, :5] == grid[0, :5])
    assert np.all(grid[:3125, 0] == 0.0) and np.all(grid[3125:6250, 0] > 0.0)
    strides = [np.argmax(grid[:, c] != grid[0, c]) for c in range(6)]
    assert strides == [3125, 625, 125, 25, 5, 1]


def test_grid_points(mill3, trunnion5):
    assert workspace_grid(mill3, 3).shape == (27, 3)
    np.testing.assert_array_equal(np.unique(workspace_grid(mill3, 3)[:, 1]), [-300, 0, 300])
    points = grid_axis_points(trunnion5, 4)
    np.testing.assert_allclose(points[0], [0, math.pi / 2, math.pi, 3 * math.pi / 2])
    np.testing.assert_allclose(points[1][[0, -1]], [-2 * math.pi / 3, math.pi / 6])
    assert workspace_grid(trunnion5, np.int64(2)).shape == (32, 5)


@pytest.mark.parametrize("bad", [1, 0, -3, 2.5, "5", True])
def test_grid_refusals(hobbing, bad):
    with pytest.raises((ValueError, TypeError), match="points must be"):
        workspace_grid(hobbing, bad)


def test_random_poses_within_strokes_and_reproducible(any_machine):
    m = any_machine
    q = random_poses(m, 4000, rng=42)
    assert q.shape == (4000, len(m.axes))
    low = np.array([a.stroke[0] for a in m.axis_specs])
    high = np.array([a.stroke[1] for a in m.axis_specs])
    assert np.all(q >= low) and np.all(q < high)
    # Uniform over the stroke: the span is < 99 % of the stroke only if no draw falls in
    # the top or in the bottom 0.5 %, probability ≤ 2·0.995^4000 ≈ 4e-9 per axis.
    assert np.all(q.max(axis=0) - q.min(axis=0) > 0.99 * (high - low))
    # Mean within 5 standard errors of the midpoint (SE = range/√(12·4000)).
    se = (high - low) / math.sqrt(12 * 4000)
    assert np.all(np.abs(q.mean(axis=0) - (low + high) / 2) < 5 * se)
    np.testing.assert_array_equal(q, random_poses(m, 4000, rng=42))
    np.testing.assert_array_equal(q, random_poses(m, 4000, rng=np.random.default_rng(42)))
    assert not np.array_equal(q, random_poses(m, 4000, rng=43))


@pytest.mark.parametrize("bad", [0, -1, 2.0, True])
def test_random_poses_refusals(hobbing, bad):
    with pytest.raises(ValueError, match="number of poses"):
        random_poses(hobbing, bad)
