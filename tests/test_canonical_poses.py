"""Worst poses that are a function of the inputs: symmetric twins are resolved by the tie rule
(reliability.first_order.canonical_maxima), not by the order a search met them."""

from __future__ import annotations

import numpy as np
import pytest

from reliability.first_order.canonical_maxima import (MAX_REGIONS, POSE_RESOLUTION,
                                                      NearCandidates, representatives,
                                                      snap_positions)
from reliability.first_order.certificate import certified_worst
from reliability.first_order.fosm import error_sigma, pose_sigma

#: Relative perturbations of the allocation far below anything printed: the last bits a
#: processor's kernel changes, which reorder the boxes of a branch and bound.
PERTURBATIONS = (0.0, 3e-15, -7e-15)


@pytest.fixture(scope="module")
def hob_axis_twins(hobbing):
    """The paper's machine at an allocation where dx and dz are worst with the hob axis M at
    either of two angles 180° apart, certified under three perturbations of the
    allocation."""
    t = hobbing.initial_allocation.copy()
    tables = [certified_worst(hobbing, t * (1 + e)) for e in PERTURBATIONS]
    return hobbing, t, tables


def _with_m_turned(machine, pose, turn):
    """The pose with the hob axis M turned by ``turn`` rad, back into its stroke."""
    m = list(machine.axes).index("M")
    low, high = machine.axis_specs[m].stroke
    turned = np.array(pose, dtype=float)
    turned[m] = low + np.mod(turned[m] + turn - low, high - low)
    return turned


def test_the_twin_180_degrees_away_is_as_bad_and_comes_later(hob_axis_twins):
    """At the reported worst pose of dx and dz, the pose with M turned by 180° has the same
    σ (to the tie tolerance of a search), and the reported one is the first of the two in
    lexicographic order: the tie rule's choice, whichever the search met first."""
    machine, t, tables = hob_axis_twins
    sigma_x = error_sigma(t, 3.0, machine.distribution)
    for output, o in (("dx", 0), ("dz", 2)):
        pose = tables[0].loc[output, list(machine.axes)].to_numpy(dtype=float)
        twin = _with_m_turned(machine, pose, np.pi)
        both = pose_sigma(machine, np.vstack([pose, twin]), sigma_x)[:, o]
        assert both[1] == pytest.approx(both[0], rel=1e-6), output
        m = list(machine.axes).index("M")
        assert pose[m] < twin[m], output


def test_the_reported_poses_do_not_change_with_the_last_bits(hob_axis_twins):
    machine, _, tables = hob_axis_twins
    axes = list(machine.axes)
    for table in tables[1:]:
        np.testing.assert_array_equal(table[axes].to_numpy(), tables[0][axes].to_numpy())


def test_reported_positions_lie_on_the_resolution_grid(hob_axis_twins):
    machine, _, tables = hob_axis_twins
    low = np.array([a.stroke[0] for a in machine.axis_specs])
    high = np.array([a.stroke[1] for a in machine.axis_specs])
    steps = (tables[0][list(machine.axes)].to_numpy(dtype=float) - low) / \
        (POSE_RESOLUTION * (high - low))
    np.testing.assert_allclose(steps, np.round(steps), atol=1e-6)


def test_one_representative_per_region_best_first_ties_in_lexicographic_order():
    span = np.array([10.0, 10.0])
    points = np.array([[9.0, 1.0], [1.0, 1.0], [1.2, 1.1], [5.0, 5.0]])
    values = np.array([2.0, 2.0, 1.9, 1.0])
    chosen = representatives(points, values, span)
    # [1, 1] and [9, 1] tie: [1, 1] first; [1.2, 1.1] lies in [1, 1]'s region
    np.testing.assert_array_equal(chosen, [[1.0, 1.0], [9.0, 1.0], [5.0, 5.0]])
    many = np.column_stack([np.arange(20.0), np.zeros(20)])
    assert len(representatives(many, np.ones(20), np.array([20.0, 1.0]))) == MAX_REGIONS


def test_near_candidates_keep_only_what_is_near_the_best():
    near = NearCandidates(0.01, 1)
    near.add(np.array([[0.0], [1.0]]), np.array([1.0, 0.995]), best=1.0)
    near.add(np.array([[2.0]]), np.array([1.002]), best=1.002)
    assert sorted(near.points.ravel().tolist()) == [0.0, 1.0, 2.0]
    near.add(np.array([[3.0]]), np.array([1.2]), best=1.2)
    assert near.points.ravel().tolist() == [3.0]


def test_snap_keeps_the_strokes_and_axes_without_one():
    low, high = np.array([0.0, 5.0]), np.array([360.0, 5.0])
    snapped = snap_positions(np.array([[359.99999, 5.0], [51.2183, 5.0]]), low, high)
    np.testing.assert_allclose(snapped[:, 1], 5.0)
    assert snapped[0, 0] == 360.0
    assert snapped[1, 0] == pytest.approx(0.036 * round(51.2183 / 0.036))
