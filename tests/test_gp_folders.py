"""An identification under a Gaussian-process profile read back from its folder, and what
reads it: verify and report's as-measured machine and the compensation tables."""

import json
import shutil
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

import reliability
from reliability.basics.errors import InputError
from reliability.compensation.tables import read_compensation
from reliability.compensation.residual import measured_residual, positioning_variance
from reliability.measured.identification_files import COEFFICIENTS_FILE
from reliability.measured.measurement_files import write_measurements
from reliability.measured.plans import parse_plan
from reliability.measured.simulated_measurements import simulate_measurements
from studies.cli import options
from studies.cli.program import main
from studies.report.as_measured_section import prior_allocation
from studies.workflows.as_measured import as_measured

MILL = Path(__file__).parent / "machines" / "mill3.toml"
PROFILE = "gp:300"
SIX = ["dx", "dy", "dz", "ex", "ey", "ez"]
#: Spacing of the compensation tables in the tests (mm).
SPACING = 100.0


def laser(name, axis, line, targets):
    return {"name": name, "kind": "line", "axis": axis, "line": line, "targets": targets,
            "quantities": SIX, "u": 0.0005, "u_angle": 1e-6}


@pytest.fixture(scope="module")
def mill():
    return reliability.load_machine(MILL)


@pytest.fixture(scope="module")
def readings(mill):
    plan = parse_plan({"tests": [
        laser("laser_X", "X", {"Y": 200.0, "Z": -100.0}, [-300.0, -100.0, 100.0, 300.0]),
        laser("laser_Y", "Y", {"X": 0.0, "Z": -100.0}, [0.0, 130.0, 270.0, 400.0])]}, mill)
    return simulate_measurements(mill, plan, profile=PROFILE, rng=7).measurements


@pytest.fixture(scope="module")
def folder(mill, readings, tmp_path_factory):
    where = tmp_path_factory.mktemp("gp")
    write_measurements(readings, mill, where / "meas.csv")
    assert main(["identify", str(MILL), "--measurements", str(where / "meas.csv"),
                 "--profile", PROFILE, "--out", str(where / "id")]) == 0
    return where


@pytest.fixture(scope="module")
def direct(mill, folder):
    """The identification the folder holds, made here from the same file."""
    return reliability.identify(mill, reliability.read_measurements(folder / "meas.csv", mill),
                                profile=PROFILE)


def random_poses(machine, count, seed):
    low, high = np.array([axis.stroke for axis in machine.axis_specs]).T
    return low + (high - low) * np.random.default_rng(seed).random((count, len(low)))


def test_a_gp_folder_reads_back_the_same_identification(mill, folder, direct):
    back = reliability.read_identification(folder / "id", mill)
    poses = random_poses(mill, 9, seed=1)
    assert back.profile == PROFILE and back.coefficients.size == direct.coefficients.size
    np.testing.assert_array_equal(back.mean_at(poses), direct.mean_at(poses))
    for read, original in zip(back.predict(poses), direct.predict(poses)):
        np.testing.assert_array_equal(read, original)
    np.testing.assert_array_equal(back.sample_at(poses, 4, rng=3),
                                  direct.sample_at(poses, 4, rng=3))
    assert back.profiles.equals(direct.profiles)
    np.testing.assert_array_equal(back.prior_sd, direct.prior_sd)


def _edit_arrays(folder, change):
    path = folder / COEFFICIENTS_FILE
    with np.load(path) as loaded:
        arrays = {key: loaded[key] for key in loaded.files}
    change(arrays)
    np.savez(path, **arrays)


def _edit_summary(folder, profile):
    path = folder / "summary.json"
    summary = json.loads(path.read_text())
    path.write_text(json.dumps({**summary, "profile": profile}))


@pytest.mark.parametrize("spoil, message", [
    (lambda f: (f / COEFFICIENTS_FILE).unlink(), "coefficients.npz: missing"),
    (lambda f: _edit_arrays(f, lambda a: a.update(loadings_1=1.02 * a["loadings_1"])),
     "'loadings_1': not a basis of profile gp:300 along axis 'X'"),
    (lambda f: _edit_arrays(f, lambda a: a.update(theta=a["theta"] + 0.1)),
     "errors.csv says .*not of one identification"),
    (lambda f: _edit_arrays(f, lambda a: a["theta_covariance"].__setitem__((0, 1), 1.0)),
     "'theta_covariance' is not symmetric"),
    (lambda f: _edit_arrays(f, lambda a: a.pop("positions_2")), "missing array 'positions_2'"),
    (lambda f: _edit_summary(f, "gp:250"), r"'points_0': expected a float array of shape"),
    (lambda f: _edit_summary(f, "independent"), "summary.json: .*cannot be identified"),
])
def test_a_damaged_gp_folder_is_refused(mill, folder, tmp_path, spoil, message):
    copy = shutil.copytree(folder / "id", tmp_path / "id")
    spoil(copy)
    with pytest.raises(InputError, match=message):
        reliability.read_identification(copy, mill)


def test_compensation_tables_of_a_gp_folder_vary_along_travel(mill, folder, direct,
                                                              tmp_path):
    assert main(["compensate", str(MILL), "--identification", str(folder / "id"),
                 "--out", str(tmp_path / "tables"), "--spacing-mm", str(SPACING)]) == 0
    tables = read_compensation(tmp_path / "tables", mill)
    for a, axis in enumerate(mill.axis_specs[:2]):
        table = tables.axes[axis.name]
        poses = np.tile(random_poses(mill, 1, seed=2), (len(table), 1))
        poses[:, a] = table["position_mm"]
        expected = direct.mean_at(poses)[:, 6 * a:6 * a + 6]
        written = table[[mill.iso_names[i] for i in range(6 * a, 6 * a + 6)]].to_numpy()
        np.testing.assert_allclose(written, expected, rtol=1e-5, atol=0.0)
        prior = direct.coefficients.prior_sd[6 * a:6 * a + 6]
        assert np.all(np.ptp(written, axis=0) > 0.05 * prior), axis.name


def test_compensate_identifies_measurements_under_its_profile(mill, folder, tmp_path):
    meas = str(folder / "meas.csv")
    assert main(["compensate", str(MILL), "--measurements", meas, "--profile", PROFILE,
                 "--out", str(tmp_path / "gp"), "--spacing-mm", str(SPACING)]) == 0
    assert main(["compensate", str(MILL), "--identification", str(folder / "id"),
                 "--profile", PROFILE, "--out", str(tmp_path / "no")]) == 2
    along = read_compensation(tmp_path / "gp", mill).axes["X"]
    assert np.ptp(along["EXX"]) > 0


def test_verify_and_report_identify_measurements_under_the_profile(mill, folder):
    args = SimpleNamespace(identification=None, measurements=str(folder / "meas.csv"))
    found = options.as_measured_identification(args, replace(mill, profile=PROFILE))
    assert found.profile == PROFILE and found.coefficients.varies
    with pytest.raises(InputError, match="profile 'independent'.*cannot be identified"):
        options.as_measured_identification(args, replace(mill, profile="independent"))
    read = options.as_measured_identification(
        SimpleNamespace(identification=str(folder / "id"), measurements=None), mill)
    assert read.profile == PROFILE


def test_the_design_allocation_of_a_gp_identification_is_its_prior(mill, direct):
    study = SimpleNamespace(machine=mill, reachable=False, compared=None)
    assert prior_allocation(study, direct) == "initial"
    found = as_measured(mill, direct, points=2, draws=8, rng=0)
    np.testing.assert_allclose(found.tolerances, mill.initial_allocation, rtol=1e-12)


def test_a_compensated_gp_machine_keeps_its_posterior_sd_at_each_pose(mill, direct):
    assert not positioning_variance(mill).any()
    poses = random_poses(mill, 5, seed=4)
    tables = reliability.compensation_tables(direct, spacing_mm=SPACING)
    _, sigma = measured_residual(direct, tables, poses, frame="workpiece")
    np.testing.assert_allclose(sigma, direct.predict(poses)[1], rtol=1e-9)
