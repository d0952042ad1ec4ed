"""Allocations certified over the continuous workspace (allocation.continuous,
docs/continuous-allocation.md): the loop's optimum against independent checks, its
refusals and its plain "not certified", the command line and the study's summary."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from allocation import AllocationProblem
from allocation.continuous import certify, check_continuous, solve_continuous
from reliability import OUTPUTS, workspace_grid
from reliability.basics.errors import InputError
from reliability.first_order.fosm import error_sigma
from reliability.model.kinematics import output_variance
from studies import cli
from studies.report.extras import EXTRAS
from studies.workflows.sweep import SweepSpec

MILL = str(Path(__file__).parent / "machines" / "mill3.toml")
QUICK = ["--repeats", "2", "--samples", "500", "--points", "3"]
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
    bound = certify(mill_interior, grid.tolerances)
    factor = float((bound["allowed"] / bound["sigma_bound"]).min())
    assert factor < 1
    rescaled = factor * grid.tolerances
    assert np.all(rescaled >= mill_interior.lower) and np.all(rescaled <= mill_interior.upper)
    assert np.all(certify(mill_interior, rescaled)["excess"] <= 1e-9)
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


# ----- refusals ---------------------------------------------------------------------------
def test_refusals_name_the_workspace(mill3):
    with pytest.raises(InputError, match="'workpiece' frame.*--workspace grid"):
        check_continuous(dataclasses.replace(mill3, frame="workpiece"))
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
    for extra, words in ((["--frame", "workpiece"], "--workspace grid"),
                         (["--method", "gwo"], "--workspace grid"),
                         (["--workspace", "plane"], "plane")):
        code = cli.main(["allocate", MILL, "--out", str(tmp_path / "b.csv"), *extra])
        assert code == 2 and words in capsys.readouterr().err
    assert not (tmp_path / "b.csv").exists()
    assert cli.main(["allocate", MILL, "--out", str(tmp_path / "c.csv"), "--points", "3",
                     "--workspace", "grid", "--frame", "workpiece"]) == 0


def test_report_summary_names_the_workspace(tmp_path, capsys):
    continuous, grid = tmp_path / "c", tmp_path / "g"
    assert cli.main(["report", MILL, "--out", str(continuous), *QUICK,
                     "--skip", *EXTRAS]) == 0
    assert cli.main(["report", MILL, "--out", str(grid), *QUICK, "--workspace", "grid",
                     "--skip", *EXTRAS]) == 0
    printed = capsys.readouterr().out
    assert "certified over the continuous workspace to 0.001" in printed
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
