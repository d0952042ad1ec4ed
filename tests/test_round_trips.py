"""Every file the toolkit writes and reads again gives back the same verdicts.

One test per writer: write, read back, and compare what a reader decides from the file
(meets its targets or not, the same targets, the same estimates and intervals) with what
was decided from memory.
"""

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import reliability
from allocation import AllocationProblem, AllocationResult, load_catalogue, solve_catalogue
from allocation.per_pose.front import cost_reliability_front, front_to_csv
from allocation.per_pose.result_files import (allocation_to_csv, read_allocation_csv,
                                              written_tolerances)
from reliability import FosmResult, GridExperiment, GridExperimentResult, fosm, workspace_grid
from reliability.basics.files import SIGNIFICANT, probability_text, rounded_down
from reliability.sampling.experiment_results import RandomPoseResult
from reliability.sampling.machine_yield import machine_yield
from reliability.sampling.pose_sampling import sample_random_poses
from studies.report import writer
from studies.report.machine_sections import fosm_section
from studies.workflows import machine_study
from studies.workflows.sweep import SweepSpec, run_sweep

HERE = Path(__file__).parent
#: Targets whose failure probability a six-digit number of R would lose.
NEAR_ONE = 0.999999999


@pytest.fixture(scope="module")
def swivel5():
    return reliability.load_machine(HERE / "machines" / "swivel5.toml")


@pytest.fixture(scope="module")
def study(swivel5):
    """The report's study of the swivel-head machine on the 3-point grid, small samples;
    its certified optimum sits on its targets, where a nearest six-digit rounding of the
    tolerances misses three of them."""
    return machine_study.run(swivel5, points=3, workspace="grid", repeats=2, samples=200,
                             machines=50, rng=3)


@pytest.fixture(scope="module")
def mill_optimum(mill3):
    problem = AllocationProblem.build(mill3, workspace_grid(mill3, 3))
    return problem.solve_exact()


# ----- the digits -----------------------------------------------------------------------
def test_rounded_down_reads_back_never_above_and_within_one_step():
    values = 10 ** np.random.default_rng(4).uniform(-9, 3, 2000)
    values = np.concatenate([values, [0.0015, 0.7, 3.0, 0.000999999949, 1.2345678e-5]])
    cut = rounded_down(values)
    read = np.array([float(f"{v:.{SIGNIFICANT}g}") for v in cut])
    np.testing.assert_array_equal(read, cut)
    assert np.all(cut <= values)
    assert np.all(values - cut < 1e-5 * values)
    np.testing.assert_array_equal(cut[-5:], [0.0015, 0.7, 3.0, 0.000999999, 1.23456e-5])


@pytest.mark.parametrize("value, text", [(0.99, "0.99"), (NEAR_ONE, "0.999999999"),
                                         (1 - 1.23456789e-7, "0.999999876543"),
                                         (1 / 3, "0.333333"), (1e-7, "0.0000001"),
                                         (1.0, "1"), (0.0, "0")])
def test_a_probability_keeps_its_distance_from_1(value, text):
    assert probability_text(value) == text


# ----- allocations -----------------------------------------------------------------------
def test_an_allocation_csv_meets_the_targets_its_optimum_meets(study, swivel5, tmp_path):
    optimum = study.optimum
    assert fosm(swivel5, optimum.tolerances, optimum.problem.poses).meets_targets().all()
    path = optimum.to_csv(tmp_path / "allocation.csv", significant=SIGNIFICANT)
    written = read_allocation_csv(path, swivel5)
    np.testing.assert_array_equal(written, written_tolerances(optimum))
    assert fosm(swivel5, written, optimum.problem.poses).meets_targets().all()
    assert optimum.problem.meets_targets(written)
    on_bound = np.isclose(optimum.tolerances, optimum.problem.lower, rtol=1e-12) | \
        np.isclose(optimum.tolerances, optimum.problem.upper, rtol=1e-12)
    assert np.all(written[~on_bound] <= optimum.tolerances[~on_bound])


def test_the_report_says_its_own_optimum_meets_its_targets(study, tmp_path):
    out = tmp_path / "report"
    writer.write_report(out, [fosm_section(study)], machine_study.summary(study),
                        title="round trip")
    table = pd.read_csv(out / "fosm_optimum.csv")
    assert table["meets"].all()
    summary = json.loads((out / "summary.json").read_text())
    assert summary["optimal_meets_targets"] is True
    assert summary["initial_meets_targets"] == bool(
        study.initial_fosm.meets_targets(study.side).all())


def test_the_yield_of_the_written_allocation_is_the_yield_in_memory(study, swivel5,
                                                                     tmp_path):
    path = study.optimum.to_csv(tmp_path / "allocation.csv", significant=SIGNIFICANT)
    options = {"points": 3, "machines": 400, "rng": 11, "method": "crude"}
    computed = machine_yield(swivel5, study.optimum.tolerances, **options)
    read = machine_yield(swivel5, read_allocation_csv(path, swivel5), **options)
    # the same built machines, each tolerance at most 1e-5 tighter: the same count, or one
    # machine on a limit's edge, inside the interval either way
    assert abs(read.estimate - computed.estimate) <= 1 / 400
    assert computed.lower <= read.estimate <= computed.upper


def test_an_allocation_result_file_reads_back_with_its_verdicts(mill_optimum, mill3,
                                                                tmp_path):
    again = AllocationResult.load(mill_optimum.save(tmp_path / "allocation.json"))
    np.testing.assert_array_equal(again.tolerances, mill_optimum.tolerances)
    assert again.feasible is mill_optimum.feasible is True
    assert again.cost == mill_optimum.cost
    assert mill_optimum.problem.meets_targets(again.tolerances)


def test_a_catalogue_choice_and_its_tolerances_read_back(mill3, tmp_path):
    catalogue = load_catalogue(HERE / "catalogues" / "mill3.toml", mill3)
    problem = AllocationProblem.build(mill3, workspace_grid(mill3, 3))
    choice = solve_catalogue(problem, catalogue)
    path = choice.to_csv(tmp_path / "choice.csv", significant=SIGNIFICANT)
    read = pd.read_csv(path)
    assert dict(zip(read["component"], read["class"])) == dict(choice.choice)
    assert read["price"].sum() == pytest.approx(choice.to_frame()["price"].sum(), rel=1e-6)
    written = read_allocation_csv(allocation_to_csv(choice, tmp_path / "t.csv",
                                                    significant=SIGNIFICANT), mill3)
    assert problem.meets_targets(written)


# ----- targets near 1 --------------------------------------------------------------------
def test_a_front_file_keeps_its_targets_short_of_1(mill3, tmp_path):
    targets = [0.9, 0.99999, NEAR_ONE]
    front = cost_reliability_front(mill3, targets, poses=workspace_grid(mill3, 3),
                                   stack=False)
    read = pd.read_csv(front_to_csv(front, tmp_path / "front.csv"))
    np.testing.assert_allclose(1 - read["target"], 1 - np.array(targets), rtol=1e-6)
    assert (read["target"] < 1).all()
    np.testing.assert_array_equal(read["feasible"], front["feasible"])
    np.testing.assert_allclose(read["cost"], front["cost"], rtol=5e-6)


def test_a_sweep_results_file_keeps_its_targets_short_of_1(tmp_path):
    spec = SweepSpec(machines=(str(HERE / "machines" / "mill3.toml"),), sides=("two_sided",),
                     targets=(NEAR_ONE,), seeds=(0,), repeats=(1,), points=3)
    result = run_sweep(spec, tmp_path / "store")  # out of reach in the box: no sampling
    read = pd.read_csv(result.path)
    assert read["target"].iloc[0] < 1
    assert 1 - read["target"].iloc[0] == pytest.approx(1 - NEAR_ONE, rel=1e-6)


# ----- first-order and Monte-Carlo results ---------------------------------------------
def test_a_fosm_file_reads_back_with_its_verdicts(mill3, tmp_path):
    result = fosm(mill3, mill3.initial_allocation, workspace_grid(mill3, 3))
    again = FosmResult.load(result.save(tmp_path / "fosm.json"))
    for side in ("one_sided", "two_sided"):
        np.testing.assert_array_equal(again.meets_targets(side), result.meets_targets(side))
        np.testing.assert_array_equal(again.worst(side), result.worst(side))
    np.testing.assert_array_equal(again.targets, result.targets)


def test_a_grid_experiment_file_reads_back_with_its_estimates(mill_optimum, tmp_path):
    experiment = GridExperiment(mill_optimum.problem.machine, 3)
    runs = experiment.run(mill_optimum.tolerances, repeats=3, rng=5)
    again = GridExperimentResult.load(runs.save(tmp_path / "runs.csv"))
    pd.testing.assert_frame_equal(again.reliability().to_frame(),
                                  runs.reliability().to_frame())
    pd.testing.assert_frame_equal(again.all_inside_share().to_frame(),
                                  runs.all_inside_share().to_frame())


def test_a_checkpointed_grid_experiment_resumes_to_the_same_counts(mill_optimum, tmp_path):
    experiment = GridExperiment(mill_optimum.problem.machine, 3)
    first = experiment.run(mill_optimum.tolerances, repeats=2, rng=7,
                           checkpoint=tmp_path / "store")
    assert list((tmp_path / "store").glob("*.json"))
    resumed = experiment.run(mill_optimum.tolerances, repeats=2, rng=7,
                             checkpoint=tmp_path / "store")
    pd.testing.assert_frame_equal(resumed.to_frame(), first.to_frame())


def test_a_random_pose_file_reads_back_with_its_intervals(mill_optimum, tmp_path):
    sampled = sample_random_poses(mill_optimum.problem.machine, mill_optimum.tolerances,
                                  300, rng=2)
    again = RandomPoseResult.load(sampled.save(tmp_path / "random.csv"))
    pd.testing.assert_frame_equal(again.to_frame(), sampled.to_frame())


def test_a_machine_file_reads_back_with_its_verdicts(swivel5, tmp_path):
    again = reliability.machine_from_toml(swivel5.to_toml())
    assert again == swivel5
    poses = workspace_grid(swivel5, 3)
    np.testing.assert_array_equal(
        fosm(again, again.initial_allocation, poses).meets_targets(),
        fosm(swivel5, swivel5.initial_allocation, poses).meets_targets())
