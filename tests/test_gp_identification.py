"""Identification under gp:<mm> profiles along travel, errors at any pose, and Gauss–Newton
re-linearisation on the exact chain."""

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy import stats

import reliability
from reliability.basics.errors import InputError
from reliability.measured.plans import parse_plan
from reliability.measured.simulated_measurements import simulate_measurements
from studies import cli
from test_measured_machine import numeric_rows, setup_matrix

MACHINES = Path(__file__).parent / "machines"
LENGTH = 300.0
SIX = ["dx", "dy", "dz", "ex", "ey", "ez"]


@pytest.fixture(scope="module")
def mill():
    return reliability.load_machine(MACHINES / "mill3.toml")


def laser(name, axis, line, targets):
    return {"name": name, "kind": "line", "axis": axis, "line": line, "targets": targets,
            "quantities": SIX, "u": 0.0005, "u_angle": 1e-6}


def lasers(mill):
    return parse_plan({"tests": [
        laser("laser_X", "X", {"Y": 200.0, "Z": -100.0}, [-300.0, -100.0, 100.0, 300.0]),
        laser("laser_Y", "Y", {"X": 0.0, "Z": -100.0}, [0.0, 130.0, 270.0, 400.0]),
        laser("laser_Z", "Z", {"X": 100.0, "Y": 200.0}, [-350.0, -200.0, -50.0])]}, mill)


def kernel(a, b):
    """docs/profiles.md, linear axis: exp(−d²/(2ℓ²))."""
    return np.exp(-0.5 * ((a[:, None] - b[None, :]) / LENGTH) ** 2)


def dense_gp_posterior(mill, meas, query):
    """Every motion error's values at its axis' read positions and at ``query``'s, and the
    assembly errors, as one Gaussian vector; the posterior by the data-space formulas with
    the set-ups' flat prior projected out (universal kriging)."""
    sigma = mill.initial_allocation / 3.0
    rows = numeric_rows(mill, meas)
    columns, prior_blocks, where = [], [], {}
    for a in range(3):
        points = np.unique(np.append(meas.poses[:, a], query[a]))
        index = np.searchsorted(points, meas.poses[:, a])
        for c in range(6):
            where[(a, c)] = (sum(len(p) for p in prior_blocks), points)
            block = np.zeros((len(meas), len(points)))
            block[np.arange(len(meas)), index] = rows[:, 6 * a + c]
            columns.append(block)
            prior_blocks.append(sigma[6 * a + c] ** 2 * kernel(points, points))
    start = sum(len(p) for p in prior_blocks)
    columns.append(rows[:, 18:])
    prior_blocks.append(np.diag(sigma[18:] ** 2))
    design = np.hstack(columns)
    prior = np.zeros((design.shape[1],) * 2)
    offset = 0
    for block in prior_blocks:
        prior[offset:offset + len(block), offset:offset + len(block)] = block
        offset += len(block)
    b = setup_matrix(mill, meas)
    inverse = np.linalg.inv(design @ prior @ design.T + np.diag(meas.u ** 2))
    projected = inverse - inverse @ b @ np.linalg.solve(b.T @ inverse @ b, b.T @ inverse)
    gain = prior @ design.T @ projected
    return {"mean": gain @ meas.value, "cov": prior - gain @ design @ prior,
            "chi2": meas.value @ projected @ meas.value, "where": where, "assembly": start}


def test_gp_posterior_equals_a_dense_gaussian_process(mill):
    meas = simulate_measurements(mill, lasers(mill), profile=f"gp:{LENGTH:g}",
                                 rng=7).measurements
    query = np.array([55.0, -210.0, -333.0])   # read at no position of any axis
    ref = dense_gp_posterior(mill, meas, query)
    result = reliability.identify(mill, meas, profile=f"gp:{LENGTH:g}")
    sigma = mill.initial_allocation / 3.0
    profiles = result.profiles.set_index(["error", "position"])
    mean_at = result.mean_at(query)
    for (a, c), (start, points) in ref["where"].items():
        name = mill.error_names[6 * a + c]
        sd = np.sqrt(np.diag(ref["cov"])[start:start + len(points)])
        at = np.searchsorted(points, query[a])
        read = np.flatnonzero(points != query[a])
        ours = profiles.loc[name].loc[points[read]]
        np.testing.assert_allclose(ours["posterior_mean"], ref["mean"][start + read],
                                   atol=1e-4 * sigma[6 * a + c])
        np.testing.assert_allclose(ours["posterior_sd"], sd[read], rtol=1e-4)
        assert mean_at[6 * a + c] == pytest.approx(ref["mean"][start + at],
                                                   abs=1e-4 * sigma[6 * a + c])
    np.testing.assert_allclose(mean_at[18:], ref["mean"][ref["assembly"]:],
                               atol=1e-4 * sigma[18:].max())
    assert result.chi2 == pytest.approx(ref["chi2"], rel=1e-5)
    # the six outputs at the query pose: J(q) applied to the errors in force there
    jac = mill.jacobian(query, frame="workpiece")
    pick = np.zeros((18 + len(sigma) - 18, ref["mean"].size))
    for (a, c), (start, points) in ref["where"].items():
        pick[6 * a + c, start + np.searchsorted(points, query[a])] = 1.0
    pick[18:, ref["assembly"]:] = np.eye(len(sigma) - 18)
    mean, sd = result.predict(query)
    np.testing.assert_allclose(mean, jac @ pick @ ref["mean"], atol=1e-4 * 0.001)
    np.testing.assert_allclose(sd, np.sqrt(np.diag(jac @ pick @ ref["cov"] @ pick.T @ jac.T)),
                               rtol=1e-4)


def test_draws_at_poses_follow_the_gp_posterior(mill):
    result = reliability.identify(mill, simulate_measurements(
        mill, lasers(mill), profile="gp:300", rng=3).measurements, profile="gp:300")
    poses = np.array([[55.0, -210.0, -333.0], [55.0, 250.0, -20.0]])
    n = 4000
    draws = result.sample_at(poses, n, np.random.default_rng(11))
    assert draws.shape == (n, 2, mill.n_errors)
    mean = result.mean_at(poses)
    spread = draws.std(axis=0)
    z = 4.0
    assert np.all(np.abs(draws.mean(axis=0) - mean) <= z * spread / np.sqrt(n) + 1e-15)
    # the outputs of the drawn machines against predict (first order, same errors)
    jac = mill.jacobian(poses, frame="workpiece")
    outputs = np.einsum("poi,npi->npo", jac, draws)
    predicted, sd = result.predict(poses)
    np.testing.assert_allclose(outputs.std(axis=0), sd, rtol=z * np.sqrt(0.5 / n))
    # Y moves between the poses, so its errors differ; X does not, so its errors agree
    np.testing.assert_array_equal(draws[:, 0, :6], draws[:, 1, :6])
    assert not np.allclose(draws[:, 0, 6:12], draws[:, 1, 6:12])


def test_gp_intervals_cover_machines_drawn_under_the_same_profile(mill):
    plan = lasers(mill)
    rng = np.random.default_rng(30)
    shares, cdf = [], []
    for _ in range(20):
        drawn = simulate_measurements(mill, plan, profile="gp:300", rng=rng)
        meas = drawn.measurements
        result = reliability.identify(mill, meas, profile="gp:300")
        table = result.profiles
        truth = np.concatenate([drawn.errors[np.unique(meas.poses[:, a], return_index=True)[1],
                                             6 * a:6 * a + 6].T.ravel() for a in range(3)])
        shares.append(np.mean((truth >= table["lower"]) & (truth <= table["upper"])))
        cdf.append(stats.chi2.cdf(result.chi2, result.dof))
    z = 4.0
    # one machine's values share its draw: the unit of replication is the machine
    assert abs(np.mean(shares) - 0.95) <= z * np.std(shares, ddof=1) / np.sqrt(len(shares))
    assert abs(np.mean(cdf) - 0.5) <= z * np.sqrt(1 / 12 / len(cdf))


def test_iterating_on_the_exact_chain_explains_readings_first_order_cannot(mill):
    plan = parse_plan({"tests": [
        laser("laser_X", "X", {"Y": 200.0, "Z": -300.0}, [-300.0, -100.0, 100.0, 300.0]),
        laser("laser_Y", "Y", {"X": -250.0, "Z": -100.0}, [0.0, 130.0, 270.0, 400.0]),
        {"name": "circle_xy", "kind": "circular", "plane": "xy", "radius": 100.0,
         "centre": {"Y": 200.0, "X": 0.0, "Z": -100.0}, "limit": 0.01, "u": 0.0005}]}, mill)
    large = 100.0 * mill.initial_allocation   # second-order terms of many times u
    meas = simulate_measurements(mill, plan, large, rng=5).measurements
    first = reliability.identify(mill, meas, tolerances=large)
    iterated = reliability.identify(mill, meas, tolerances=large, iterate=True)
    assert first.chi2_p_value < 1e-3
    assert iterated.chi2_p_value > 1e-3 and iterated.settled and iterated.iterations >= 2
    assert iterated.change > 0.5
    assert "re-linearised on the exact chain" in iterated.summary()


def test_the_independent_profile_is_refused(mill):
    meas = simulate_measurements(mill, lasers(mill), rng=0).measurements
    with pytest.raises(InputError, match="profile: identification takes 'constant' or"):
        reliability.identify(mill, meas, profile="independent")


def test_identify_writes_profiles_under_gp(mill, tmp_path, capsys):
    from reliability.measured.measurement_files import write_measurements

    drawn = simulate_measurements(mill, lasers(mill), profile="gp:300", rng=1)
    write_measurements(drawn.measurements, mill, tmp_path / "meas.csv")
    assert cli.main(["identify", str(MACHINES / "mill3.toml"), "--measurements",
                     str(tmp_path / "meas.csv"), "--profile", "gp:300", "--out",
                     str(tmp_path / "out")]) == 0
    assert "written errors.csv, profiles.csv" in capsys.readouterr().out
    table = pd.read_csv(tmp_path / "out" / "profiles.csv")
    assert list(table.columns) == ["error", "position", "prior_sd", "posterior_mean",
                                   "posterior_sd", "lower", "upper"]
    assert set(table["error"]) == set(mill.error_names[:18])


def test_an_identification_rebuilt_from_its_error_tables_acts_the_same(mill):
    result = reliability.identify(mill, simulate_measurements(mill, lasers(mill), rng=4)
                                  .measurements)
    kept = ("machine", "profile", "prior_sd", "mean", "covariance", "setup", "rank",
            "condition", "combinations", "prior_like", "residuals", "chi2", "dof")
    rebuilt = reliability.Identification(**{name: getattr(result, name) for name in kept})
    poses = np.array([[100.0, 50.0, -200.0], [300.0, -250.0, -10.0]])
    for ours, theirs in zip(rebuilt.predict(poses), result.predict(poses)):
        np.testing.assert_array_equal(ours, theirs)
    np.testing.assert_array_equal(rebuilt.mean_at(poses), result.mean_at(poses))
    np.testing.assert_array_equal(rebuilt.sample_at(poses, 5, 9), result.sample_at(poses, 5, 9))


def test_what_precise_readings_cannot_tell_apart_is_named_as_for_coarse_ones(mill):
    from dataclasses import replace

    meas = simulate_measurements(mill, lasers(mill), profile="gp:300", rng=0).measurements
    coarse = reliability.identify(mill, meas, profile="gp:300")
    precise = reliability.identify(mill, replace(meas, u=meas.u / 100), profile="gp:300")
    assert precise.combinations == coarse.combinations
    assert "Y.ey - Y-X.ey" in precise.combinations
