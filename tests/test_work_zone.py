"""The work zone: membership, the grid inside it, and the studies that keep to it."""

from __future__ import annotations

import math
import tomllib
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from allocation import AllocationProblem
from reliability.basics.errors import InputError, MachineDescriptionError
from reliability.first_order.certificate import certified_worst
from reliability.first_order.fosm import error_sigma, fosm, pose_sigma
from reliability.first_order.zone_enclosure import ZoneEnclosure
from reliability.model.machine_file import machine_from_dict, machine_from_toml
from reliability.model.machine_checks import describe, likely_mistakes
from reliability.model.poses import full_grid, random_poses, workspace_grid
from reliability.model.work_zone import WorkZone, inside_zone, tool_points, tool_tilts
from reliability.sampling.grid_experiment import GridExperiment
from reliability.sampling.machine_yield import YieldModel
from studies import cli
from studies.report.zone_section import zone_section
from studies.workflows.zone_comparison import zone_comparison

SWIVEL = Path(__file__).parent / "machines" / "swivel5.toml"
CYLINDER = {"shape": "cylinder", "centre": [0.0, 0.0], "radius": 250.0, "z": [0.0, 300.0],
            "tilt": [0.0, 60.0]}


def swivel_table(zone=None) -> dict:
    table = tomllib.loads(SWIVEL.read_text())
    if zone is not None:
        table["workzone"] = zone
    return table


@pytest.fixture(scope="module")
def swivel():
    return machine_from_dict(swivel_table(), "swivel5")


@pytest.fixture(scope="module")
def zoned():
    """swivel5 with a cylinder r = 250 mm, z 0 … 300 mm on the table, tilt 0 … 60°."""
    return machine_from_dict(swivel_table(CYLINDER), "swivel5 with a zone")


def swivel_tool_point(c, y, x, z, b):
    """swivel5's tool point by hand: the B pivot at (x, y, -120 + 700 + z - 200), the tool
    180 mm down the spindle turned by B about y, the whole turned by the table C."""
    local = np.array([x - 180.0 * np.sin(b), y, 380.0 + z - 180.0 * np.cos(b)])
    turn = np.array([[np.cos(c), -np.sin(c), 0.0], [np.sin(c), np.cos(c), 0.0], [0, 0, 1]])
    return turn @ local


def in_cylinder_by_hand(c, y, x, z, b):
    """The zone of ``zoned`` from the hand-made tool point (the table turns about the
    cylinder's axis, so C does not matter)."""
    px, py, pz = swivel_tool_point(0.0, y, x, z, b)
    return (px * px + py * py <= 250.0 ** 2 + 1e-6 and -1e-6 <= pz <= 300.0 + 1e-6
            and abs(b) <= math.radians(60.0))


# ----- membership ------------------------------------------------------------------
def test_box_holds_points_inside_and_on_its_faces_only():
    box = WorkZone("box", low=(-10.0, 0.0, 5.0), high=(10.0, 20.0, 6.0))
    points = [(0, 10, 5.5), (10, 20, 6), (-10, 0, 5), (10.001, 10, 5.5), (0, -0.001, 5.5),
              (0, 10, 6.01)]
    assert box.contains(points).tolist() == [True, True, True, False, False, False]


def test_cylinder_holds_its_rim_and_not_beyond():
    cylinder = WorkZone("cylinder", centre=(100.0, -50.0), radius=30.0, z=(0.0, 40.0))
    on_rim = (100.0 + 30.0 * math.cos(0.3), -50.0 + 30.0 * math.sin(0.3), 40.0)
    points = [(100, -50, 20), on_rim, (130.01, -50, 20), (100, -50, -0.01), (118, -26, 0)]
    # (18, 24) from the axis is 30 mm away: on the rim, at the bottom face
    assert cylinder.contains(points).tolist() == [True, True, False, False, True]


def test_tilt_range_is_closed_and_needs_tilts():
    zone = WorkZone("box", low=(0, 0, 0), high=(1, 1, 1), tilt=(10.0, 30.0))
    tilts = np.radians([9.99, 10.0, 20.0, 30.0, 30.01])
    assert zone.contains(np.full((5, 3), 0.5), tilts).tolist() == \
        [False, True, True, True, False]
    with pytest.raises(InputError, match="tilts are needed"):
        zone.contains([0.5, 0.5, 0.5])


def test_tool_point_and_tilt_match_the_hand_made_chain(swivel):
    rng = np.random.default_rng(3)
    low = np.array([a.stroke[0] for a in swivel.axis_specs])
    high = np.array([a.stroke[1] for a in swivel.axis_specs])
    poses = low + (high - low) * rng.random((40, 5))
    expected = np.array([swivel_tool_point(*pose) for pose in poses])
    assert np.allclose(tool_points(swivel, poses), expected, rtol=0, atol=1e-9)
    assert np.allclose(tool_tilts(swivel, poses), np.abs(poses[:, 4]), rtol=0, atol=1e-12)


# ----- the machine file ---------------------------------------------------------------
def test_zone_round_trips_through_the_machine_file(zoned):
    assert machine_from_toml(zoned.to_toml()) == zoned
    assert "workzone" not in tomllib.loads(machine_from_dict(swivel_table()).to_toml())
    box = {"shape": "box", "min": [-100, -100, 0], "max": [100, 100, 250]}
    assert machine_from_dict(swivel_table(box)).work_zone.high == (100.0, 100.0, 250.0)


@pytest.mark.parametrize("zone, message", [
    ({"shape": "sphere"}, r"workzone.shape: expected \"box\" or \"cylinder\"; got 'sphere'"),
    ({**CYLINDER, "radius": -1.0}, r"workzone.radius: must be > 0"),
    ({k: v for k, v in CYLINDER.items() if k != "z"}, r"workzone: missing key 'z'"),
    ({**CYLINDER, "min": [0, 0, 0]}, r"workzone \(shape 'cylinder'\): unknown key 'min'"),
    ({**CYLINDER, "z": [300.0, 0.0]}, r"workzone: work zone z: lo = 300 must be < hi = 0"),
    ({**CYLINDER, "tilt": [0.0, 200.0]}, r"workzone: work zone tilt must be \[lo, hi\] "
                                         r"with 0 <= lo <= hi <= 180 degrees"),
    ({"shape": "box", "min": [0, 0, 0], "max": [1, 0, 1]},
     r"work zone y \(min, max\): lo = 0 must be < hi = 0"),
    ({"shape": "box", "min": [0, 0], "max": [1, 1, 1]}, r"workzone.min: expected three"),
])
def test_bad_zones_are_refused_by_key(zone, message):
    with pytest.raises(MachineDescriptionError, match=message):
        machine_from_dict(swivel_table(zone), "swivel5")


def test_check_states_the_zone_and_warns_when_no_grid_pose_is_inside(zoned, swivel):
    assert "105 of the 3125 poses of the 5-point grid inside" in describe(zoned)
    assert "no work zone: every pose of the strokes" in describe(swivel)
    high = machine_from_dict(swivel_table({**CYLINDER, "z": [800.0, 900.0]}))
    assert any("no pose of the 5-point grid lies in the work zone" in text
               for text in likely_mistakes(high))
    with pytest.raises(InputError, match="no pose of the 5-point grid lies in the work zone"):
        workspace_grid(high)


# ----- the grid and the studies -------------------------------------------------------
def test_grid_keeps_the_poses_inside_by_hand(zoned):
    """5 table angles × (9 poses at B = 0 + 6 at each of B = ±55°), all at Z = 0: at B = 0
    the tool points (X, Y) within 250 mm, among them (±200, ±150) on the rim; at B = ±55°
    the tool point moves 147.4 mm along x, keeping X ∈ {0, ±200} on one side."""
    grid = workspace_grid(zoned)
    assert len(grid) == 5 * (9 + 6 + 6) == 105
    whole = full_grid(zoned)
    by_hand = np.array([in_cylinder_by_hand(*pose) for pose in whole])
    assert np.array_equal(grid, whole[by_hand])


def test_machine_without_zone_keeps_the_whole_grid(swivel):
    assert np.array_equal(workspace_grid(swivel), full_grid(swivel))
    assert inside_zone(swivel, full_grid(swivel)).all()
    assert GridExperiment(swivel).n_poses == 5 ** 5


def test_fosm_worst_pose_is_the_worst_inside_the_zone(zoned, swivel):
    whole = full_grid(swivel)
    sigma = fosm(swivel, swivel.initial_allocation, whole).sigma
    by_hand = np.array([in_cylinder_by_hand(*pose) for pose in whole])
    result = fosm(zoned, zoned.initial_allocation, workspace_grid(zoned))
    worst = result.sigma[result.worst_pose, np.arange(6)]
    assert np.allclose(worst, sigma[by_hand].max(axis=0), rtol=1e-12, atol=0)
    assert inside_zone(zoned, result.poses[result.worst_pose]).all()
    assert np.all(worst <= sigma.max(axis=0))


def test_allocation_problem_defaults_to_the_zone(zoned):
    problem = AllocationProblem.build(zoned, side="two_sided")
    assert np.array_equal(problem.poses, workspace_grid(zoned))


def test_grid_experiment_counts_the_zone_poses_only(zoned, swivel):
    """Same draws with and without the zone: the zone's counts are the whole grid's
    values counted at the zone's poses."""
    t = zoned.initial_allocation * 2.0
    whole = GridExperiment(swivel).run(t, repeats=3, rng=5, keep_values="all")
    inside = np.array([in_cylinder_by_hand(*pose) for pose in full_grid(swivel)])
    expected = np.sum(np.abs(whole.values[:, inside]) < swivel.limits, axis=1)
    zone = GridExperiment(zoned).run(t, repeats=3, rng=5)
    assert zone.n_poses == 105
    assert np.array_equal(zone.inside, expected)


def test_yield_in_the_zone_is_the_share_of_machines_within_limits_there(zoned, swivel):
    """Same built machines: each passes in the zone when its largest |y|/I over the zone's
    poses, computed from the whole grid, is below 1."""
    t = zoned.initial_allocation * 1.5
    model, whole = YieldModel(zoned), YieldModel(swivel)
    u = model.draws(60, rng=11)
    inside = np.array([in_cylinder_by_hand(*pose) for pose in full_grid(swivel)])
    values = whole.experiment.evaluate(*whole.errors(u, t))
    expected = np.all(np.abs(values[:, inside]) < swivel.limits, axis=(1, 2))
    assert np.array_equal(model.output_ratios(u, t).max(axis=1) < 1.0, expected)
    assert model.workspace == "5-point grid, 105 of its 3 125 poses in the work zone"


def test_random_poses_lie_in_the_zone(zoned):
    poses = random_poses(zoned, 50, rng=2)
    assert poses.shape == (50, 5)
    assert all(in_cylinder_by_hand(*pose) for pose in poses)


def test_without_zone_is_the_machine_as_before(zoned, swivel):
    assert replace(zoned, work_zone=None) == swivel


# ----- what the commands and the report say ---------------------------------------------
def test_predict_states_the_grid_poses_in_the_zone(tmp_path, capsys, zoned, swivel):
    for machine, words in ((zoned, "5-point grid, 105 of its 3 125 poses inside the work "
                                   "zone cylinder about (0, 0) mm, radius 250 mm"),
                           (swivel, "5-point grid (3 125 poses; no work zone: every pose "
                                    "of the strokes)")):
        path = tmp_path / "machine.toml"
        path.write_text(machine.to_toml())
        assert cli.main(["predict", str(path)]) == 0
        assert words in capsys.readouterr().out


def test_zone_section_compares_the_zone_with_the_strokes(zoned):
    """On the 3-point grid only C at Z = 0, B = 0, X = Y = 0 is inside (3 table angles)."""
    comparison = zone_comparison(zoned, points=3, machines=40, rng=1)
    section = zone_section(comparison)
    assert section.summary["zone_grid_poses"] == 3 and section.summary["grid_poses"] == 243
    assert "**3 of the 243 poses**" in section.text
    costs = comparison.allocations["cost"]
    assert costs["optimum for the zone"] <= costs["optimum for the strokes"] * (1 + 1e-9)
    worst = comparison.worst.loc["zone"]
    assert inside_zone(zoned, worst[list(zoned.axes)].to_numpy(dtype=float)).all()
    assert np.allclose(worst[["x", "y", "z"]].to_numpy(dtype=float), [0.0, 0.0, 200.0],
                       atol=1e-9)
    assert set(section.figures) == {"zone.png"}


# ----- boxes of poses against the zone (for the certificate) ---------------------------
SWIVEL_BOX = {"shape": "box", "min": [-200.0, -150.0, 150.0], "max": [200.0, 150.0, 350.0],
              "tilt": [10.0, 70.0]}


def measures_by_hand(zone, poses) -> np.ndarray:
    """swivel5's (x, y, z, cos tilt) (box) or (r², z, cos tilt) (cylinder) from the
    hand-made tool point; the tilt is |B|."""
    points = np.array([swivel_tool_point(*pose) for pose in poses])
    cos = np.cos(poses[:, 4])
    if zone["shape"] == "box":
        return np.column_stack([points, cos])
    r2 = np.square(points[:, 0] - zone["centre"][0]) + np.square(points[:, 1] - zone["centre"][1])
    return np.column_stack([r2, points[:, 2], cos])


@pytest.mark.parametrize("zone", [CYLINDER, SWIVEL_BOX], ids=["cylinder", "box"])
def test_enclosure_holds_every_pose_and_proves_outside_only_empty_boxes(zone):
    """Random boxes of swivel5's strokes: 100 poses drawn in each have their measures
    inside the enclosure, a box proved outside holds none of the zone and a box proved
    inside nothing else."""
    machine = machine_from_dict(swivel_table(zone))
    enclosure = ZoneEnclosure(machine)
    rng = np.random.default_rng(7)
    low = np.array([a.stroke[0] for a in machine.axis_specs])
    span = np.array([a.stroke[1] for a in machine.axis_specs]) - low
    corner = low + span * rng.random((80, 5)) * 0.9
    width = span * rng.random((80, 5)) * 0.1
    lo, hi = enclosure.ranges(corner, corner + width)
    outside = enclosure.outside(corner, corner + width)
    inside = enclosure.inside(corner, corner + width)
    assert 0 < outside.sum() < len(outside)
    for b in range(len(corner)):
        poses = corner[b] + width[b] * rng.random((100, 5))
        values = measures_by_hand(zone, poses)
        assert np.all((values >= lo[b] - 1e-6) & (values <= hi[b] + 1e-6))
        held = inside_zone(machine, poses)
        assert not (outside[b] and held.any()) and not (inside[b] and not held.all())


def test_enclosure_keeps_a_box_around_a_pose_of_the_zone(zoned):
    pose = np.array([0.3, 0.0, 0.0, 0.0, 0.0])  # tool point (0, 0, 200), tilt 0
    half = np.array([0.01, 1.0, 1.0, 1.0, 0.01])
    assert not ZoneEnclosure(zoned).outside(pose - half, pose + half)[0]
    assert ZoneEnclosure(zoned).inside(pose - half, pose + half)[0]
    far = np.array([0.3, 0.0, 0.0, 450.0, 0.0])  # tool point 650 mm up
    assert ZoneEnclosure(zoned).outside(far - half, far + half)[0]


MILL = Path(__file__).parent / "machines" / "mill3.toml"
MILL_BOX = {"shape": "box", "min": [-200.0, 300.0, -50.0], "max": [100.0, 500.0, 150.0]}


def test_certificate_in_the_zone_lies_between_a_dense_search_and_the_strokes():
    """mill3 with a box cutting its tool points' range (x -325 … 275, y 265 … 665, z -100
    … 250 mm) on every side: the certified σ in the zone is at most the strokes' and, with
    its bound, at least the largest σ of 4000 poses drawn in the zone."""
    table = tomllib.loads(MILL.read_text())
    mill = machine_from_dict(table)
    zoned_mill = machine_from_dict({**table, "workzone": MILL_BOX})
    t, rtol = mill.initial_allocation, 1e-3
    zone = certified_worst(zoned_mill, t, rtol=rtol)
    strokes = certified_worst(mill, t, rtol=rtol)
    poses = random_poses(zoned_mill, 4000, rng=4)
    dense = pose_sigma(zoned_mill, poses, error_sigma(t, 3.0, "normal")).max(axis=0)
    assert zone["certified"].all()
    assert inside_zone(zoned_mill, zone[list(mill.axes)].to_numpy(dtype=float)).all()
    assert np.all(zone["sigma_bound"].to_numpy() >= dense)
    assert np.all(zone["sigma"].to_numpy() <= strokes["sigma_bound"].to_numpy())
    assert np.any(zone["sigma"].to_numpy() < strokes["sigma"].to_numpy() * 0.99)
