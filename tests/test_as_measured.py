"""This machine as measured: the identification's folder read back, its reliability and its
acceptance results from posterior draws."""

import shutil
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

import reliability
from reliability.acceptance.definitions import read_tests
from reliability.acceptance.iso_statistics import circular_deviation
from reliability.acceptance.iso_tests import build_path
from reliability.basics.errors import InputError
from reliability.measured.identification_files import COVARIANCE_FILE
from reliability.measured.measurement_files import write_measurements
from reliability.measured.plans import parse_plan
from reliability.measured.simulated_measurements import simulate_measurements
from reliability.model.poses import workspace_grid
from studies.cli.program import main
from studies.report.as_measured_section import as_measured_builder
from studies.report.extras import guarded
from studies.workflows.as_measured import as_measured

HERE = Path(__file__).parent
SIX = ["dx", "dy", "dz", "ex", "ey", "ez"]


@pytest.fixture(scope="module")
def mill():
    return reliability.load_machine(HERE / "machines" / "mill3.toml")


@pytest.fixture(scope="module")
def swivel():
    return reliability.load_machine(HERE / "machines" / "swivel5.toml")


def laser(name, axis, line, targets):
    return {"name": name, "kind": "line", "axis": axis, "line": line, "targets": targets,
            "quantities": SIX, "u": 0.0005, "u_angle": 1e-6}


@pytest.fixture(scope="module")
def mill_readings(mill):
    plan = parse_plan({"tests": [
        laser("laser_X", "X", {"Y": 200.0, "Z": -100.0}, [-300.0, -100.0, 100.0, 300.0]),
        laser("laser_Y", "Y", {"X": 0.0, "Z": -100.0}, [0.0, 130.0, 270.0, 400.0])]}, mill)
    return simulate_measurements(mill, plan, rng=4)


@pytest.fixture(scope="module")
def identified_folder(mill, mill_readings, tmp_path_factory):
    folder = tmp_path_factory.mktemp("identified")
    write_measurements(mill_readings.measurements, mill, folder / "meas.csv")
    assert main(["identify", str(HERE / "machines" / "mill3.toml"), "--measurements",
                 str(folder / "meas.csv"), "--out", str(folder / "id")]) == 0
    return folder


def test_an_identification_folder_reads_back(mill, mill_readings, identified_folder):
    direct = reliability.identify(mill, mill_readings.measurements)
    back = reliability.read_identification(identified_folder / "id", mill)
    np.testing.assert_array_equal(back.covariance, direct.covariance)
    np.testing.assert_allclose(back.mean, direct.mean, rtol=1e-5, atol=1e-12)
    assert (back.rank, back.dof, back.combinations) == (direct.rank, direct.dof,
                                                        direct.combinations)


def _spoil_covariance(folder, change):
    path = folder / COVARIANCE_FILE
    np.save(path, change(np.load(path)))


@pytest.mark.parametrize("spoil, message", [
    (lambda f: _spoil_covariance(f, lambda c: c + np.triu(np.full_like(c, 1e-6), 1)),
     "not symmetric"),
    (lambda f: _spoil_covariance(f, lambda c: c - 2 * np.outer(*[np.sqrt(np.diag(c))] * 2)),
     "not positive semi-definite"),
    (lambda f: _spoil_covariance(f, lambda c: 4 * c), "not of one identification"),
    (lambda f: _spoil_covariance(f, lambda c: c[:-1, :-1]), r"expected a \(30, 30\)"),
    (lambda f: (f / COVARIANCE_FILE).unlink(), "covariance.npy: missing"),
])
def test_a_damaged_identification_folder_is_refused(mill, identified_folder, tmp_path, spoil,
                                                    message):
    folder = shutil.copytree(identified_folder / "id", tmp_path / "id")
    spoil(folder)
    with pytest.raises(InputError, match=message):
        reliability.read_identification(folder, mill)


def test_an_identification_of_another_machine_is_refused(swivel, identified_folder):
    with pytest.raises(InputError, match="error .C.dx. of the machine is missing"):
        reliability.read_identification(identified_folder / "id", swivel)


def test_a_machine_known_exactly_gets_the_exact_chains_verdict(swivel):
    """With the posterior a point at x, every draw is x: each output holds everywhere iff
    the exact chain keeps it inside at every grid pose, and the mean at its worst pose is the
    exact output there."""
    truth = 1.2 * swivel.initial_allocation * np.random.default_rng(8).choice(
        [-1.0, 1.0], swivel.n_errors)
    known = replace(reliability.identify(swivel, simulate_measurements(
        swivel, parse_plan({"tests": [laser("laser_X", "X", {"C": 0.0, "Y": 0.0, "Z": 250.0,
                                                             "B": 0.0},
                                            [-400.0, 0.0, 400.0])]}, swivel),
        rng=1).measurements), mean=truth, covariance=np.zeros((swivel.n_errors,) * 2))
    grid = workspace_grid(swivel, 3)
    exact = swivel.comprehensive_error(grid, truth)
    found = as_measured(swivel, known, points=3, draws=2, rng=0)
    holds = np.all(np.abs(exact) < swivel.limits, axis=0)
    assert holds.any() and not holds.all()
    np.testing.assert_array_equal(found.outputs["holds"].to_numpy(), holds.astype(float))
    assert found.holds["estimate"] == float(holds.all())
    for o, (pose, mean) in enumerate(zip(found.outputs["worst_pose"], found.outputs["mean"])):
        row = int(np.flatnonzero(np.all(np.isclose(grid, pose), axis=1))[0])
        assert mean == pytest.approx(exact[row, o], rel=1e-9, abs=1e-15)


def test_a_machine_known_exactly_gets_its_circle(mill, mill_readings):
    """G of the circle for a point posterior against the exact chain's path fitted by
    ISO 230-4's least-squares circle."""
    tests = read_tests(HERE / "acceptance_tests" / "mill3.toml", mill)
    truth = mill.initial_allocation * np.random.default_rng(3).standard_normal(mill.n_errors)
    known = replace(reliability.identify(mill, mill_readings.measurements), mean=truth,
                    covariance=np.zeros((mill.n_errors,) * 2))
    found = as_measured(mill, known, points=2, draws=2, tests=tests, rng=0)
    circle = build_path(mill, tests[0])
    deviation = mill.comprehensive_error(circle.poses, truth, frame="workpiece")[:, :3]
    expected = circular_deviation(circle.nominal + deviation @ circle.directions.T)
    row = found.acceptance.set_index(["test", "quantity"]).loc[("circle_xy_r100", "G")]
    assert row["mean"] == pytest.approx(expected, abs=1e-6)
    assert row["pass_probability"] == float(expected <= tests[0].limit)
    passes = found.summary_dict()["acceptance_pass"]
    assert "circle_xy_r100.G" in passes and "position_X.R" not in passes


def test_verify_prints_this_machine_beside_the_design(mill, identified_folder, tmp_path,
                                                     capsys):
    tolerances = tmp_path / "t.csv"
    tolerances.write_text("error,allocated\n" + "".join(
        f"{name},{float(t)!r}\n" for name, t in zip(mill.error_names, mill.initial_allocation)))
    common = ["verify", str(HERE / "machines" / "mill3.toml"), "--tolerances", str(tolerances),
              "--tests", str(HERE / "acceptance_tests" / "mill3.toml")]
    assert main(common) == 2
    assert "--tests predicts acceptance tests for a measured machine" in capsys.readouterr().err
    small = ["--points", "2", "--repeats", "2", "--samples", "200", "--machines", "200",
             "--workspace", "grid"]
    assert main([*common, *small, "--measurements", str(identified_folder / "meas.csv")]) == 0
    printed = capsys.readouterr().out
    assert "probability that it holds every limit at every pose" in printed
    assert "design-time machine yield of the allocation" in printed
    assert "circle_xy_r100" in printed.split("This machine as measured")[1]


def _study(machine, tolerances):
    worst = pd.DataFrame(workspace_grid(machine, 2)[:6], columns=list(machine.axes))
    check = SimpleNamespace(worst_poses=worst, machine_yield=None)
    return SimpleNamespace(machine=machine, checks={"initial": check, "optimum": check},
                           reachable=True, allocated=tolerances,
                           compared=("optimum", tolerances), points=2, machines=50, seed=0)


def test_the_as_measured_section_names_the_prior_allocation(mill, mill_readings):
    identified = reliability.identify(mill, mill_readings.measurements,
                                      tolerances=0.5 * mill.initial_allocation)
    section = guarded("as_measured", as_measured_builder(identified, source="m.csv"))(
        _study(mill, 0.5 * mill.initial_allocation))
    assert section.title == "As measured"
    assert "prior is the optimum allocation" in section.text
    assert set(section.tables["as_measured_outputs.csv"].index) == set(mill.outputs)


def test_an_as_measured_section_that_fails_leaves_the_report_whole(mill, swivel,
                                                                     mill_readings):
    identified = reliability.identify(mill, mill_readings.measurements)
    section = guarded("as_measured", as_measured_builder(identified, source="m.csv"))(
        _study(swivel, swivel.initial_allocation))
    assert section.title == "As measured"
    assert "as_measured" in section.summary["not_computed"]
    assert "--identification or --measurements" in section.text
