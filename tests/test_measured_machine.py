"""The machine as measured: measurement files, simulated readings and identification."""

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

import reliability
from reliability.acceptance.iso_tests import tool_point
from reliability.basics.errors import InputError
from reliability.measured.measurement_files import write_measurements
from reliability.measured.plans import parse_plan
from reliability.measured.simulated_measurements import simulate_measurements

MACHINES = Path(__file__).parent / "machines"
TRANSLATIONS = ("dx", "dy", "dz")


@pytest.fixture(scope="module")
def mill():
    return reliability.load_machine(MACHINES / "mill3.toml")


def line_run(name, axis, line, targets, quantities):
    return {"name": name, "kind": "line", "axis": axis, "line": line, "targets": targets,
            "quantities": quantities, "u": 0.0005, "u_angle": 1e-6}


def mill_plan(mill, circle=False):
    six = ["dx", "dy", "dz", "ex", "ey", "ez"]
    tests = [line_run("laser_X", "X", {"Y": 200.0, "Z": -100.0}, [-300.0, -100.0, 100.0, 300.0],
                      six),
             line_run("laser_Y", "Y", {"X": 0.0, "Z": -100.0}, [0.0, 130.0, 270.0, 400.0], six)]
    if circle:
        tests.append({"name": "circle_xy", "kind": "circular", "plane": "xy", "radius": 100.0,
                      "centre": {"Y": 200.0, "X": 0.0, "Z": -100.0}, "limit": 0.01,
                      "u": 0.0005})
    return parse_plan({"tests": tests}, mill)


# ----- measurement files ----------------------------------------------------------------
GOOD_ROWS = ["r1,100,0,-100,dx,,,,0.001,0.0005", "r1,200,0,-100,dx,,,,0.002,0.0005"]
HEADER = "run,Y_mm,X_mm,Z_mm,quantity,cx_mm,cy_mm,cz_mm,value,u"


@pytest.mark.parametrize("header, rows, where", [
    (HEADER, ["r1,100,0,-100,dq,,,,0.001,0.0005"], "row 1, column 'quantity'"),
    (HEADER, [GOOD_ROWS[0], "r1,500,0,-100,dx,,,,0.002,0.0005"], "row 2, column 'Y_mm'"),
    (HEADER, [GOOD_ROWS[0], "r1,200,0,-100,dx,,,,0.002,0"], "row 2, column 'u'"),
    (HEADER, [GOOD_ROWS[0], "r1,200,0,-100,dx,,,,0.002,"], "row 2, column 'u'"),
    (HEADER, [GOOD_ROWS[0], "r1,200,zero,-100,dx,,,,0.002,0.0005"], "row 2, column 'X_mm'"),
    (HEADER, [*GOOD_ROWS, "r1,300,0,-100,dy,,,,0.002,0.0005"], "row 3, column 'quantity'"),
    (HEADER, [*GOOD_ROWS[:1], "r1,200,0,-100,dx,1,2,3,0.002,0.0005"], "row 2, column 'cx_mm'"),
    (HEADER.replace("Y_mm", "W_mm"), GOOD_ROWS, "column 'W_mm'"),
])
def test_bad_files_are_refused_naming_row_and_column(mill, tmp_path, header, rows, where):
    path = tmp_path / "meas.csv"
    path.write_text("\n".join([header, *rows]) + "\n")
    with pytest.raises(InputError, match=where.replace("(", r"\(")):
        reliability.read_measurements(path, mill)


def test_written_readings_read_back(mill, tmp_path):
    drawn = simulate_measurements(mill, mill_plan(mill, circle=True), rng=1)
    write_measurements(drawn.measurements, mill, tmp_path / "meas.csv")
    back = reliability.read_measurements(tmp_path / "meas.csv", mill)
    np.testing.assert_allclose(back.value, drawn.measurements.value, rtol=1e-11)
    np.testing.assert_allclose(back.poses, drawn.measurements.poses, rtol=1e-11, atol=1e-12)


# ----- identification -------------------------------------------------------------------
def numeric_rows(machine, measurements, step=1e-7):
    """Each reading's sensitivity to every error by central differences of the exact chain
    (the ballbar's length change for radial readings)."""
    q, c = measurements.poses, measurements.centre
    names = list(TRANSLATIONS) + ["ex", "ey", "ez"]

    def readings(x):
        deviation = machine.comprehensive_error(q, x, frame="workpiece")
        index = [names.index(k) if k != "radial" else 0 for k in measurements.quantity]
        out = deviation[np.arange(len(q)), index]
        radial = measurements.quantity == "radial"
        arm = tool_point(machine, q[radial]) - c[radial]
        out[radial] = np.linalg.norm(arm + deviation[radial, :3], axis=1) - \
            np.linalg.norm(arm, axis=1)
        return out

    eye = np.eye(machine.n_errors) * step
    return np.stack([(readings(e) - readings(-e)) / (2 * step) for e in eye], axis=1)


def setup_matrix(machine, measurements):
    """One column per (run, quantity) zero; two per ballbar run, its centre moved along x
    and along y (the circles here lie in the xy plane), each reading's length change being
    minus the move along the unit vector from the centre to the tool point."""
    columns = []
    for run in dict.fromkeys(measurements.run):
        rows = measurements.run == run
        if "radial" in measurements.quantity[rows]:
            arm = tool_point(machine, measurements.poses) - measurements.centre
            unit = arm / np.linalg.norm(arm, axis=1, keepdims=True)
            columns += [np.where(rows, -unit[:, 0], 0.0), np.where(rows, -unit[:, 1], 0.0)]
            continue
        for quantity in dict.fromkeys(measurements.quantity[rows]):
            columns.append((rows & (measurements.quantity == quantity)) * 1.0)
    return np.column_stack(columns)


def test_posterior_equals_a_dense_joint_computation(mill):
    drawn = simulate_measurements(mill, mill_plan(mill, circle=True), rng=4)
    meas = drawn.measurements
    result = reliability.identify(mill, meas)
    a = numeric_rows(mill, meas)
    b = setup_matrix(mill, meas)
    prior_var = (mill.initial_allocation / 3.0) ** 2
    weight = 1.0 / meas.u ** 2
    design = np.hstack([a, b])
    precision = design.T @ (design * weight[:, None])
    precision[:mill.n_errors, :mill.n_errors] += np.diag(1.0 / prior_var)
    joint = np.linalg.inv(precision)
    mean = joint @ (design.T @ (weight * meas.value))
    p = mill.n_errors
    np.testing.assert_allclose(result.mean, mean[:p], rtol=1e-5,
                               atol=1e-6 * np.sqrt(prior_var).max())
    np.testing.assert_allclose(result.covariance, joint[:p, :p], rtol=1e-5,
                               atol=1e-8 * prior_var.max())
    spread = a @ (a * prior_var).T + np.diag(meas.u ** 2)
    inverse = np.linalg.inv(spread)
    projected = inverse - inverse @ b @ np.linalg.solve(b.T @ inverse @ b, b.T @ inverse)
    assert result.chi2 == pytest.approx(meas.value @ projected @ meas.value, rel=1e-6)
    assert result.dof == len(meas) - b.shape[1]


def test_the_null_space_names_what_the_readings_cannot_tell_apart(mill):
    result = reliability.identify(mill, simulate_measurements(mill, mill_plan(mill), rng=0)
                                  .measurements)
    # constant offsets are taken by each run's instrument zeros
    for name in mill.error_names:
        if name.endswith(TRANSLATIONS):
            assert name in result.combinations
    # equal sensitivity columns at every pose (reliability.model.identifiability)
    assert "Y.ey - Y-X.ey" in result.combinations
    # a straight line under constant errors shows two slopes: the two deviations across it
    assert result.rank == 4
    assert len(result.combinations) == mill.n_errors - result.rank


def test_posterior_intervals_cover_the_drawn_machines(mill):
    plan = mill_plan(mill, circle=True)
    rng = np.random.default_rng(30)
    inside, chi2 = [], []
    for _ in range(50):
        drawn = simulate_measurements(mill, plan, rng=rng)
        result = reliability.identify(mill, drawn.measurements)
        table = result.errors
        truth = drawn.errors[0]
        inside.append((truth >= table["lower"]) & (truth <= table["upper"]))
        chi2.append(stats.chi2.cdf(result.chi2, result.dof))
    coverage = np.mean(inside)
    count = np.size(inside)
    z = 4.0
    assert abs(coverage - 0.95) <= z * np.sqrt(0.95 * 0.05 / count)
    # the χ² statistic's probability is uniform under the model: mean 1/2, sd sqrt(1/12)/√50
    assert abs(np.mean(chi2) - 0.5) <= z * np.sqrt(1 / 12 / len(chi2))


def test_predict_and_sample_agree(mill):
    result = reliability.identify(mill, simulate_measurements(mill, mill_plan(mill), rng=2)
                                  .measurements)
    poses = np.array([[100.0, 50.0, -200.0], [300.0, -250.0, -10.0]])
    mean, sd = result.predict(poses)
    draws = result.sample(20000, np.random.default_rng(5))
    outputs = np.einsum("poi,ni->npo", mill.jacobian(poses, frame="workpiece"), draws)
    z = 4.0
    assert np.all(np.abs(outputs.mean(axis=0) - mean) <= z * sd / np.sqrt(20000) + 1e-15)
    np.testing.assert_allclose(outputs.std(axis=0), sd, rtol=z * np.sqrt(0.5 / 20000))


def test_identify_refuses_readings_not_read_from_a_file(mill):
    with pytest.raises(InputError, match="measurements"):
        reliability.identify(mill, {"value": [1.0]})


def test_a_reading_the_model_cannot_explain_is_named(mill):
    meas = simulate_measurements(mill, mill_plan(mill, circle=True), rng=3).measurements
    value = meas.value.copy()
    value[17] += 40 * meas.u[17]
    result = reliability.identify(mill, replace(meas, value=value))
    assert result.chi2_p_value < 1e-3
    assert f"run {meas.run[17]!r}, row 18" in result.summary()


def test_errors_at_poses_agree_with_the_posterior(mill):
    result = reliability.identify(mill, simulate_measurements(mill, mill_plan(mill), rng=2)
                                  .measurements)
    poses = np.array([[[100.0, 50.0, -200.0], [300.0, -250.0, -10.0], [0.0, 0.0, -50.0]]])
    np.testing.assert_array_equal(result.mean_at(poses)[0, 1], result.mean)
    draws = result.sample_at(poses, 4000, np.random.default_rng(5))
    assert draws.shape == (4000, 1, 3, mill.n_errors)
    z, sd = 4.0, result.errors["posterior_sd"].to_numpy()
    assert np.all(np.abs(draws[:, 0, 2].mean(axis=0) - result.mean) <= z * sd / np.sqrt(4000)
                  + 1e-15)
    np.testing.assert_array_equal(draws[:, 0, 0], draws[:, 0, 1])
