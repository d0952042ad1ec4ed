"""Each event's worst grid pose: one function, reading the tolerances as the machine does."""

import dataclasses

import numpy as np
import pytest
from scipy.stats import norm, truncnorm

import reliability
from reliability.basics.errors import InputError
from reliability.first_order.worst_grid_pose import EVENTS, worst_grid_poses
from reliability.model.machine import OUTPUTS
from reliability.model.poses import workspace_grid
from reliability.sampling.pose_sampling import sample_at_poses
from reliability.sampling.sobol import sobol_indices

K = 3.0


def independent_worst(machine, t, distribution, points):
    """Each event's worst pose from the Jacobian and scipy's σ of an error, ties (within
    1e-9 of the worst) to the lexicographically first pose."""
    grid = workspace_grid(machine, points)
    sigma_x = (truncnorm(-K, K, scale=t / K).std() if distribution == "truncated"
               else t / K)
    sigma = np.sqrt(np.einsum("pon,n->po", np.square(machine.jacobian(grid)),
                              np.square(sigma_x)))
    system = (2 * norm.sf(machine.limits / sigma)).sum(axis=1)
    scores = np.column_stack([sigma, system])
    chosen = []
    for column in scores.T:
        tied = np.flatnonzero(column >= column.max() * (1 - 1e-9))
        chosen.append(min(tied, key=lambda row: tuple(grid[row])))
    return grid[chosen]


@pytest.fixture(scope="module")
def competing(hobbing):
    """An allocation whose system worst pose on the 3-point grid moves with σ's scale:
    linear errors at half, angular errors at 1.6 times the initial allocation."""
    angular = np.array([".e" in name for name in hobbing.error_names])
    return hobbing.initial_allocation * np.where(angular, 1.6, 0.5)


@pytest.mark.parametrize("distribution", ["normal", "truncated"])
def test_poses_match_an_independent_computation(hobbing, competing, distribution):
    ours = worst_grid_poses(hobbing, competing, EVENTS, points=3, distribution=distribution)
    np.testing.assert_array_equal(ours, independent_worst(hobbing, competing, distribution, 3))


def test_the_system_pose_follows_the_reading_of_a_tolerance(hobbing, competing):
    normal = worst_grid_poses(hobbing, competing, ("system",), points=3, distribution="normal")
    truncated = worst_grid_poses(hobbing, competing, ("system",), points=3,
                                 distribution="truncated")
    assert not np.array_equal(normal, truncated)
    np.testing.assert_array_equal(
        truncated, independent_worst(hobbing, competing, "truncated", 3)[[-1]])


def test_the_machine_reading_is_the_default(hobbing, competing):
    truncated_machine = dataclasses.replace(hobbing, distribution="truncated")
    np.testing.assert_array_equal(
        worst_grid_poses(truncated_machine, competing, EVENTS, points=3),
        worst_grid_poses(hobbing, competing, EVENTS, points=3, distribution="truncated"))
    np.testing.assert_array_equal(
        worst_grid_poses(hobbing, competing, EVENTS, points=3),
        worst_grid_poses(hobbing, competing, EVENTS, points=3, distribution="normal"))


def test_every_entry_point_returns_the_same_poses_on_the_paper_machine():
    machine = reliability.hobbing_machine()
    t = machine.initial_allocation
    ours = worst_grid_poses(machine, t, EVENTS)
    for row, event in enumerate(EVENTS):
        np.testing.assert_array_equal(reliability.rare.worst_grid_pose(machine, t, event),
                                      ours[row])
    np.testing.assert_array_equal(reliability.rare.worst_grid_poses(machine, t, EVENTS), ours)
    sampled = sample_at_poses(machine, t, samples=10, rng=0, fosm=False)
    np.testing.assert_array_equal(sampled.poses, ours[:len(OUTPUTS)])
    indices = sobol_indices(machine, t, samples=16, resamples=10, rng=0)
    np.testing.assert_array_equal(indices.poses, ours[:len(OUTPUTS)])


@pytest.mark.parametrize("events, match", [("dx", "events"), (("dx", "dq"), "events"),
                                           ((), "events")])
def test_bad_events_are_refused(hobbing, events, match):
    with pytest.raises(InputError, match=match):
        worst_grid_poses(hobbing, hobbing.initial_allocation, events, points=2)


def test_an_unknown_reading_is_refused(hobbing):
    with pytest.raises(InputError, match="distribution"):
        worst_grid_poses(hobbing, hobbing.initial_allocation, points=2, distribution="uniform")
