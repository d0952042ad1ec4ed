"""The certificate over a work zone: its bound against closed forms and dense searches of the
zone, the Lagrangian bound of boxes across the boundary, and the zone's tests in chunks."""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest

from reliability.first_order import box_models, certificate
from reliability.first_order.certificate import certified_worst
from reliability.first_order.fosm import error_sigma, pose_sigma
from reliability.first_order.pose_expansion import jacobian_expansion, variance_expansion
from reliability.first_order.zone_bound import ZoneConstraints
from reliability.first_order.zone_enclosure import ZoneEnclosure
from reliability.model.machine_file import machine_from_dict
from reliability.model.poses import random_poses
from reliability.model.work_zone import inside_zone

MACHINES = Path(__file__).parent / "machines"
MILL = tomllib.loads((MACHINES / "mill3.toml").read_text())
#: mill3's tool point is (X − 25, Y + 265, Z + 250) mm: the chain's offsets summed, each
#: axis moving the tool along its own direction.
MILL_TOOL = np.array([-25.0, 265.0, 250.0])
MILL_BOX = {"shape": "box", "min": [-200.0, 300.0, -50.0], "max": [100.0, 500.0, 150.0]}
MILL_CYLINDER = {"shape": "cylinder", "centre": [-50.0, 450.0], "radius": 150.0,
                 "z": [-50.0, 150.0]}


def mill(zone) -> object:
    return machine_from_dict({**MILL, "workzone": zone}, "mill3 with a zone")


def test_box_zone_certificate_is_the_largest_sigma_at_the_zone_corners():
    """A box zone of mill3 is the box of poses X, Y, Z = the zone's corners minus the tool
    offset; σ² is a sum of squares of functions affine in each axis, so convex along each,
    and its largest value over the box is at one of the box's eight corners."""
    machine = mill(MILL_BOX)
    t, rtol = machine.initial_allocation, 1e-3
    low = np.array(MILL_BOX["min"]) - MILL_TOOL
    high = np.array(MILL_BOX["max"]) - MILL_TOOL
    corners = np.array([[lo_hi[i][a] for a, i in enumerate(bits)]
                        for bits in np.ndindex(2, 2, 2) for lo_hi in [(low, high)]])
    poses = corners[:, [1, 0, 2]]  # mill3's axes are Y, X, Z
    assert inside_zone(machine, poses).all()
    exact = pose_sigma(machine, poses, error_sigma(t, 3.0, "normal")).max(axis=0)
    table = certified_worst(machine, t, rtol=rtol)
    assert table["certified"].all()
    assert np.all(table["sigma_bound"].to_numpy() >= exact * (1 - 1e-12))
    assert np.all(table["sigma"].to_numpy() <= exact * (1 + 1e-8))  # the zone's rounding
    assert np.all(table["sigma"].to_numpy() >= exact / (1 + rtol))


def test_cylinder_zone_certificate_holds_against_a_dense_search():
    """A cylinder whose rim cuts mill3's strokes: boxes whose poses are all outside are
    dropped until none is left, the search ends certified, and the bound is at least the
    largest σ of 1500 poses drawn in the zone."""
    machine = mill(MILL_CYLINDER)
    t, rtol = machine.initial_allocation, 1e-3
    table = certified_worst(machine, t, rtol=rtol)
    poses = random_poses(machine, 1500, rng=6)
    dense = pose_sigma(machine, poses, error_sigma(t, 3.0, "normal")).max(axis=0)
    assert table["certified"].all()
    assert inside_zone(machine, table[list(machine.axes)].to_numpy(dtype=float)).all()
    assert np.all(table["sigma_bound"].to_numpy() >= dense)
    assert np.all(table["sigma"].to_numpy() >= dense / (1 + rtol) ** 2)


SWIVEL = tomllib.loads((MACHINES / "swivel5.toml").read_text())
SWIVEL_CYLINDER = {"shape": "cylinder", "centre": [0.0, 0.0], "radius": 250.0,
                   "z": [0.0, 300.0], "tilt": [0.0, 60.0]}


def swivel_boundary(reading="sigma"):
    """swivel5 with a cylinder zone, the model of its δx σ² (or stack), the zone's
    enclosure and a boundary object of the search over the zone."""
    machine = machine_from_dict({**SWIVEL, "workzone": SWIVEL_CYLINDER})
    t = machine.initial_allocation
    if reading == "sigma":
        variance = np.square(error_sigma(t, 3.0, "normal"))
        model = box_models.SigmaModel(variance_expansion(machine, variance, machine.frame)
                                      .restricted(0))
    else:
        model = box_models.StackModel(jacobian_expansion(machine, t, machine.frame)
                                      .restricted(0))
    enclosure = ZoneEnclosure(machine)
    low, high = model.local_strokes(machine)
    boundary = certificate._ZoneBoundary.for_model(
        model, enclosure, low, high, lambda x: enclosure.contains(model.expansion.pose(x)))
    return machine, model, enclosure, boundary


@pytest.mark.parametrize("reading", ["sigma", "stack"])
def test_lagrangian_bound_holds_over_the_zone_part_of_boxes_across_it(reading):
    """Random small boxes of swivel5's poses across its cylinder's boundary, with
    multipliers at the local maximum on the rim and fitted to each box: the Lagrangian
    bound of σ² (or of the stack) is at least its value at 400 poses of the box that lie
    in the zone, and below the whole-box bound for many boxes."""
    machine, model, enclosure, boundary = swivel_boundary(reading)
    start = model.expansion.local(np.array([1.5, 0.0, -100.0, 20.0, 0.98]))
    rim = boundary.search(start[None])[0]
    boundary.multipliers = boundary.constraints.multipliers(
        certificate._point_slope(model, rim)[1], rim, boundary.low, boundary.high)[None]
    assert np.all(boundary.multipliers >= 0) and boundary.multipliers.any()
    rng = np.random.default_rng(12)
    span = boundary.high - boundary.low
    centre = np.clip(rim + span * 0.05 * rng.standard_normal((60, 5)), boundary.low,
                     boundary.high)
    half = span * 0.02 * rng.random((60, 5))
    low = np.maximum(centre - half, boundary.low)
    high = np.minimum(centre + half, boundary.high)
    outside, inside = enclosure.classify(model.expansion.pose(low), model.expansion.pose(high))
    across = ~outside & ~inside
    low, high = low[across], high[across]
    lagrangian = boundary._lagrangian_bounds(low, high)
    lagrangian = lagrangian[0] if reading == "sigma" else lagrangian
    whole = certificate._evaluate(model, low, high, None)[0]
    checked = 0
    for b in range(len(low)):
        points = low[b] + (high[b] - low[b]) * rng.random((400, 5))
        held = enclosure.contains(model.expansion.pose(points))
        if held.any():
            assert lagrangian[b] >= model.values(points[held]).max()
            checked += 1
    assert checked >= 10
    assert np.mean(lagrangian < whole) > 0.3


def test_fitted_multipliers_level_the_lagrangian_on_one_constraint():
    """One constraint whose gradient is parallel to f's: the fitted multiplier is their
    ratio, and a constraint the box cannot pass gets none."""
    gradient = np.array([[2.0, -4.0]])
    g = np.array([[0.0, -10.0]])
    g_gradient = np.array([[[1.0, -2.0], [1.0, 0.0]]])
    zeros = np.zeros((1, 2, 2, 2))
    fitted = certificate._fitted_multipliers(gradient, g, g_gradient, zeros, zeros,
                                             np.array([[0.1, 0.1]]))
    assert np.allclose(fitted, [[2.0, 0.0]], rtol=1e-12, atol=0)


def test_zone_tests_of_many_boxes_run_in_chunks(monkeypatch):
    """The enclosure of 500 boxes within a budget of 40 boxes' temporaries is computed 40
    boxes at a time, with the same answer as in one piece."""
    machine, model, enclosure, _ = swivel_boundary()
    rng = np.random.default_rng(3)
    low = np.array([a.stroke[0] for a in machine.axis_specs])
    span = np.array([a.stroke[1] for a in machine.axis_specs]) - low
    corner = low + span * rng.random((500, 5)) * 0.9
    width = span * rng.random((500, 5)) * 0.1
    whole = enclosure.classify(corner, corner + width, memory=2 ** 40)
    sizes = []
    ranges = enclosure.ranges
    monkeypatch.setattr(enclosure, "ranges",
                        lambda lo, hi: sizes.append(len(lo)) or ranges(lo, hi))
    chunked = enclosure.classify(corner, corner + width,
                                 memory=40 * enclosure._bytes_per_box(0))
    assert max(sizes) == 40 and sum(sizes) == 500
    assert all(np.array_equal(a, b) for a, b in zip(whole, chunked))
    assert ZoneConstraints(enclosure).count == 4  # r², bottom, top, tilt ≤ 60°


def test_swivel_zone_certificate_of_dz_closes_on_the_rim_within_a_few_thousand_boxes():
    """swivel5's δz in its cylinder: the worst pose lies on the zone's top with σ larger
    just outside. Boxes across the boundary bounded by the Lagrangian close within 3000
    boxes (the whole-box bound left a gap of 1.7e-3 after 100 000), and the bound holds
    against 2000 poses drawn in the zone."""
    machine = machine_from_dict({**SWIVEL, "workzone": SWIVEL_CYLINDER})
    t = machine.initial_allocation
    variance = np.square(error_sigma(t, 3.0, "normal"))
    model = box_models.SigmaModel(variance_expansion(machine, variance, machine.frame)
                                  .restricted(2))
    low, high = model.local_strokes(machine)
    tied, bound, calls, _ = certificate.branch_and_bound(model, low, high, 1e-3, 3000,
                                                         zone=ZoneEnclosure(machine))
    value = float(model.values(tied).max())
    assert bound <= value * (1 + 1e-3) ** 2 and calls <= 3000
    poses = random_poses(machine, 2000, rng=8)
    dense = pose_sigma(machine, poses, error_sigma(t, 3.0, "normal"))[:, 2].max()
    assert np.sqrt(bound) >= dense
