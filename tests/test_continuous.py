"""Allocations certified over the continuous workspace (allocation.per_pose.continuous,
docs/continuous-allocation.md): the loop's optimum against independent checks, its
refusals and its plain "not certified", its searched-only mode and
``solve_over_workspace`` (pose cutting planes from the local search alone), the command
line and the study's summary."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from allocation import AllocationProblem, solve_over_workspace
from allocation.per_pose.continuous import certificate_table, check_continuous, solve_continuous
from reliability import OUTPUTS, workspace_grid
from reliability.basics.errors import InputError
from reliability.first_order.fosm import error_sigma
from reliability.first_order.workspace_search import continuous_worst
from reliability.model.kinematics import output_variance
from studies import cli
from studies.report.extras import EXTRAS
from studies.workflows.sweep import SweepSpec

MILL = str(Path(__file__).parent / "machines" / "mill3.toml")
QUICK = ["--repeats", "2", "--samples", "500", "--points", "3", "--machines", "400"]
BOX = (0.05, 1.5)  # wide enough below that a common rescaling stays inside it


def strokes(machine):
    low = np.array([axis.stroke[0] for axis in machine.axis_specs])
    high = np.array([axis.stroke[1] for axis in machine.axis_specs])
    return low, high


def interior_poses(machine):
    """The 3-point grid shrunk to the middle half of every stroke: it misses every stroke
    end, where the worst poses of these machines lie, so the loop must add poses."""
    grid = workspace_grid(machine, 3)
    low, high = strokes(machine)
    lo, hi = grid.min(axis=0), grid.max(axis=0)
    return low + (high - low) * (0.25 + 0.5 * (grid - lo) / np.where(hi > lo, hi - lo, 1))


def vertices(machine):
    """Every corner of the stroke box (the 2-point grid of the linear machine)."""
    low, high = strokes(machine)
    corners = np.stack(np.meshgrid(*zip(low, high), indexing="ij"), axis=-1)
    return corners.reshape(-1, len(low))


def dense_sigma_ratio(problem, tolerances, n=20_000, seed=3):
    """Largest σ / allowed σ per output over random poses and the stroke box's corners:
    an independent check of the certificate (plain FOSM, Eq. 20)."""
    machine = problem.machine
    low, high = strokes(machine)
    poses = np.vstack([low + (high - low) * np.random.default_rng(seed).random(
        (n, len(low))), vertices(machine)])
    variance = np.square(error_sigma(tolerances, problem.k, problem.distribution))
    sigma = np.sqrt(output_variance(machine, poses, variance))
    return sigma.max(axis=0) / problem.allowed_sigma


# ----- the linear mill: σ² is convex in the positions, so its maximum is at a corner ------
@pytest.fixture(scope="module")
def mill_interior(mill3):
    return AllocationProblem.build(mill3, interior_poses(mill3), bounds=BOX)


@pytest.fixture(scope="module")
def mill_continuous(mill_interior):
    return solve_continuous(mill_interior, rtol=1e-3)


def test_mill_continuous_optimum_is_the_corner_optimum(mill3, mill_interior, mill_continuous):
    """On an all-linear machine every J entry is affine in the positions, so σ² is convex
    and the worst pose of the continuous workspace is a corner: the continuous optimum is
    the optimum on the corners, computed independently."""
    result = mill_continuous
    assert result.certified and result.workspace == "continuous"
    assert result.statement == "certified over the continuous workspace to 0.001 in σ"
    assert len(result.added) > 0 and result.solves >= 2
    corners = AllocationProblem.build(mill3, vertices(mill3), bounds=BOX).solve_exact()
    np.testing.assert_allclose(result.cost, corners.cost, rtol=1e-6)
    # the interior grid is a relaxation: its optimum is cheaper
    assert result.grid.cost <= result.cost * (1 + 1e-9)
    assert result.cost_ratio > 1.01
    assert np.all(dense_sigma_ratio(mill_interior, result.tolerances) <= 1 + 1e-3)
    table = result.certificate
    assert np.all(table["sigma_bound"] <= table["allowed"] * (1 + 1e-3))
    assert list(table.index) == list(OUTPUTS) and table.attrs["current"]


def test_added_poses_are_readable(mill3, mill_continuous):
    added = mill_continuous.added
    assert list(added.columns) == ["solve", "source", "output", "Y_mm", "X_mm", "Z_mm",
                                   "ratio"]
    assert np.all(added["ratio"] > 1) and set(added["source"]) <= {"search", "certificate"}
    text = mill_continuous.summary()
    assert "workspace: continuous" in text and "certificate call(s)" in text


def test_rescaled_grid_optimum_costs_more(mill_interior, mill_continuous):
    """The interior grid's optimum scaled by one common factor until its certified bound
    meets every target is feasible over the continuous workspace, so it costs at least the
    continuous optimum (σ is proportional to a common factor on the tolerances)."""
    grid = mill_continuous.grid
    bound = certificate_table(mill_interior, grid.tolerances)
    factor = float((bound["allowed"] / bound["sigma_bound"]).min())
    assert factor < 1
    rescaled = factor * grid.tolerances
    assert np.all(rescaled >= mill_interior.lower) and np.all(rescaled <= mill_interior.upper)
    assert np.all(certificate_table(mill_interior, rescaled)["excess"] <= 1e-9)
    cost = float(mill_interior.cost.total(rescaled))
    assert cost >= mill_continuous.cost * (1 - 1e-9)


def test_truncated_reading_constrains_the_truncated_sigma(mill3):
    """Under the truncated reading the target's σ is met by the truncated σ (smaller than
    t/3), so the continuous optimum allows wider tolerances and costs less."""
    normal = AllocationProblem.build(mill3, interior_poses(mill3), bounds=BOX)
    truncated = AllocationProblem.build(mill3, interior_poses(mill3), bounds=BOX,
                                        distribution="truncated")
    first = solve_continuous(normal, rtol=1e-3)
    second = solve_continuous(truncated, rtol=1e-3)
    assert second.certified and second.cost < first.cost
    assert second.certificate.attrs["distribution"] == "truncated"
    assert np.all(dense_sigma_ratio(truncated, second.tolerances) <= 1 + 1e-3)
    assert np.any(dense_sigma_ratio(normal, second.tolerances) > 1 + 1e-3)


def test_iteration_cap_is_not_certified(mill_interior):
    capped = solve_continuous(mill_interior, rtol=1e-3, max_solves=1)
    assert not capped.certified
    assert capped.statement.startswith("NOT certified over the continuous workspace")
    assert "stopped after 1 solves" in capped.reason


# ----- the 5-axis trunnion machine, with the real certificate ----------------------------
@pytest.fixture(scope="module")
def trunnion_continuous(trunnion5):
    problem = AllocationProblem.build(trunnion5, interior_poses(trunnion5), bounds=BOX)
    return problem, solve_continuous(problem, rtol=5e-2)


def test_trunnion_continuous_optimum(trunnion5, trunnion_continuous):
    """Certified to rtol = 0.05 (loose, to keep the test quick): the certified bound meets
    every target within rtol, 20 000 random poses and the corners never exceed the target's
    σ by more than rtol, and the interior grid's optimum is cheaper (a relaxation)."""
    problem, result = trunnion_continuous
    assert result.certified, result.reason
    table = result.certificate
    assert np.all(table["sigma_bound"] <= table["allowed"] * (1 + 5e-2))
    assert np.all(dense_sigma_ratio(problem, result.tolerances) <= 1 + 5e-2)
    assert dense_sigma_ratio(problem, result.grid.tolerances).max() > 1 + 5e-2
    assert result.grid.cost <= result.cost * (1 + 1e-9) and len(result.added) > 0


def test_uncertified_certificate_says_so(trunnion5):
    """A certificate stopped after one box evaluation has a bound far above σ: no pose to
    cut, and the result says plainly that it is not certified, with the gap."""
    problem = AllocationProblem.build(trunnion5, workspace_grid(trunnion5, 3))
    result = solve_continuous(problem, rtol=1e-3, max_calls=1, search=False)
    assert not result.certified
    assert "NOT certified" in result.statement and "stopped at gap" in result.reason
    assert result.certificate_calls == 1 and result.solves == 1


# ----- the stack reading ----------------------------------------------------------------
def test_stack_reading_reaches_the_corner_optimum(mill3):
    """The loop under the stack reading: on an all-linear machine every |J_oi| is convex in
    the positions, so the worst-case stack is largest at a corner of the strokes and the
    optimum over the corners (computed independently) is the continuous optimum."""
    problem = AllocationProblem.build(mill3, interior_poses(mill3), side="stack", bounds=BOX)
    result = solve_continuous(problem, rtol=1e-3)
    assert result.certified and result.quantity == "the worst-case stack"
    assert result.statement.endswith("in the worst-case stack")
    corners = AllocationProblem.build(mill3, vertices(mill3), side="stack",
                                      bounds=BOX).solve_exact()
    np.testing.assert_allclose(result.cost, corners.cost, rtol=1e-6)
    assert result.grid.cost < result.cost and result.searches == 0


# ----- searched only: the loop without the certificate, and solve_over_workspace --------
TOLERANCE = 1e-6  # solve_over_workspace's default shortfall in β
SEARCHED_RTOL = TOLERANCE / (1 - TOLERANCE)  # the same shortfall as σ over the allowed σ


@pytest.mark.parametrize("name", ["mill3", "trunnion5"])
def test_searched_only_mode_is_solve_over_workspace(name, request):
    """From poses that miss every stroke end, the searched-only loop and
    ``solve_over_workspace`` add the same poses and reach the same allocation, which an
    independent check finds short nowhere: σ over what the target allows at 20 000 random
    poses and the stroke box's corners never exceeds 1 + the tolerance (the grid optimum
    exceeds it by far). On the all-linear mill the optimum is the corner optimum."""
    machine = request.getfixturevalue(name)
    problem = AllocationProblem.build(machine, interior_poses(machine), bounds=BOX)
    searched = solve_continuous(problem, rtol=SEARCHED_RTOL, certify=False)
    assert searched.searched_only and not searched.certified and not searched.capped
    assert searched.statement.startswith("not certified: searched only")
    assert searched.certificate is None and searched.certificate_calls == 0
    assert len(searched.added) > 0 and set(searched.added["source"]) == {"search"}
    result, added = solve_over_workspace(problem)
    np.testing.assert_array_equal(result.tolerances, searched.tolerances)
    np.testing.assert_array_equal(added, searched.result.problem.poses[len(problem.poses):])
    assert result.certificate["certified"]
    assert np.all(dense_sigma_ratio(problem, result.tolerances) <= 1 + TOLERANCE)
    assert dense_sigma_ratio(problem, searched.grid.tolerances).max() > 1.1
    if name == "mill3":
        corners = AllocationProblem.build(machine, vertices(machine), bounds=BOX).solve_exact()
        np.testing.assert_allclose(result.cost, corners.cost, rtol=1e-6)


def test_searched_only_cap_raises_in_solve_over_workspace(mill_interior):
    capped = solve_continuous(mill_interior, rtol=SEARCHED_RTOL, certify=False, max_solves=1)
    assert capped.capped and capped.searched_only and not capped.certified
    assert capped.statement.startswith("NOT certified") and "stopped after 1 solves" \
        in capped.reason
    with pytest.raises(RuntimeError, match="after 1 rounds"):
        solve_over_workspace(mill_interior, max_rounds=1)


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


def test_searched_only_refusals_and_the_workpiece_frame(mill3):
    """Searched only needs the search (σ readings, ``search=True``); a workpiece-frame
    study runs searched only and certified."""
    stack = AllocationProblem.build(mill3, workspace_grid(mill3, 2), side="stack")
    with pytest.raises(InputError, match="stack reading"):
        solve_continuous(stack, certify=False)
    problem = AllocationProblem.build(mill3, workspace_grid(mill3, 2))
    with pytest.raises(InputError, match="search=True"):
        solve_continuous(problem, certify=False, search=False)
    with pytest.raises(InputError, match="rtol"):
        solve_continuous(problem, certify=False, rtol=-1e-3)
    workpiece = AllocationProblem.build(mill3, interior_poses(mill3), bounds=BOX,
                                        frame="workpiece")
    assert solve_continuous(workpiece).certified
    result, added = solve_over_workspace(workpiece)
    assert len(added) > 0
    assert workpiece.with_poses(added).meets_targets(result.tolerances)


# ----- refusals ---------------------------------------------------------------------------
def test_refusals_name_the_workspace(mill3):
    with pytest.raises(InputError, match="correlated.*--workspace grid"):
        check_continuous(mill3.with_correlation({("X.dx", "Y.dx"): 0.5}))
    mean = AllocationProblem.build(mill3, workspace_grid(mill3, 2), workspace="mean")
    with pytest.raises(InputError, match="worst-case reading"):
        solve_continuous(mean)
    problem = AllocationProblem.build(mill3, workspace_grid(mill3, 2))
    with pytest.raises(InputError, match="rtol"):
        solve_continuous(problem, rtol=0)


# ----- command line, study and sweep ------------------------------------------------------
def test_allocate_names_the_workspace(tmp_path, capsys):
    out = tmp_path / "a.csv"
    assert cli.main(["allocate", MILL, "--out", str(out), "--points", "3"]) == 0
    printed = capsys.readouterr().out
    assert "workspace: continuous — certified over the continuous workspace to 0.001" \
           in printed
    assert cli.main(["allocate", MILL, "--out", str(out), "--points", "3", "--overwrite",
                     "--workspace", "grid", "--rtol", "0.01"]) == 0
    assert "workspace: grid — the targets hold at the 27 poses" in capsys.readouterr().out
    for extra, words in ((["--method", "gwo"], "--workspace grid"),
                         (["--workspace", "plane"], "plane")):
        code = cli.main(["allocate", MILL, "--out", str(tmp_path / "b.csv"), "--drawing",
                         str(tmp_path / "b_drawing.csv"), *extra])
        assert code == 2 and words in capsys.readouterr().err
    assert not (tmp_path / "b.csv").exists()
    # another --out in the same folder: its own drawing file, no collision with a.csv's
    assert cli.main(["allocate", MILL, "--out", str(tmp_path / "c.csv"), "--points", "3",
                     "--workspace", "grid", "--frame", "workpiece"]) == 0
    assert (tmp_path / "c.drawing.csv").exists() and (tmp_path / "a.drawing.csv").exists()
    assert cli.main(["allocate", MILL, "--out", str(tmp_path / "d.csv"), "--points", "3",
                     "--workspace", "grid", "--frame", "workpiece", "--drawing",
                     str(tmp_path / "d_drawing.csv")]) == 0
    assert (tmp_path / "d_drawing.csv").exists() and not (tmp_path / "d.drawing.csv").exists()


@pytest.mark.xdist_group("lean_mill_report")
def test_report_summary_names_the_workspace(lean_mill_report, tmp_path):
    continuous, grid = lean_mill_report.folder, tmp_path / "g"  # the default workspace
    assert cli.main(["report", MILL, "--out", str(grid), *QUICK, "--workspace", "grid",
                     "--skip", *EXTRAS]) == 0
    assert "certified over the continuous workspace to 0.001" in lean_mill_report.printed
    first = json.loads((continuous / "summary.json").read_text())
    second = json.loads((grid / "summary.json").read_text())
    assert first["workspace"] == "continuous" and first["workspace_certified"] is True
    assert second["workspace"] == "grid" and "workspace_certified" not in second
    assert (continuous / "workspace_certificate.csv").exists()
    assert "Continuous workspace" in (continuous / "report.md").read_text()


def test_verify_certify_samples_the_certified_worst_poses(tmp_path, capsys):
    out = tmp_path / "a.csv"
    assert cli.main(["allocate", MILL, "--out", str(out), "--points", "3"]) == 0
    capsys.readouterr()
    assert cli.main(["verify", MILL, "--tolerances", str(out), "--repeats", "2",
                     "--samples", "2000", "--points", "3", "--certify",
                     "--distribution", "truncated"]) == 0
    printed = capsys.readouterr().out
    assert "certified (continuous workspace, rtol 0.001) worst pose" in printed
    assert "truncated at +-t" in printed
    assert ("interval reaches the target" in printed
            or "significantly below target" in printed)


def test_sweep_workspace_key():
    plain = SweepSpec.from_dict({"machines": [MILL]}).tasks()[0]
    grid = SweepSpec.from_dict({"machines": [MILL], "workspace": "grid"}).tasks()[0]
    chosen = SweepSpec.from_dict({"machines": [MILL], "workspace": "continuous"}).tasks()[0]
    assert "workspace" not in plain.parameters()  # old stores keep their hashes
    assert grid.parameters() == plain.parameters()
    assert chosen.parameters()["workspace"] == "continuous"
    with pytest.raises(InputError, match="workspace"):
        SweepSpec.from_dict({"machines": [MILL], "workspace": "plane"})
