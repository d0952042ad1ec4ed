"""Correlated errors: validation, FOSM with jᵀΣj, the Gaussian copula, the correlated solver."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import reliability
from scipy.stats import norm

from allocation import AllocationProblem
from allocation.per_pose.correlated import solve_correlated
from reliability.basics.errors import InputError, MachineDescriptionError
from reliability.first_order.fosm import error_sigma, fosm
from reliability.first_order.output_covariance import output_covariance
from reliability.model.correlation import (check_correlation_matrix, correlation_pairs,
                                           correlation_to_toml)
from reliability.model.error_draws import (correlate_items, correlation_factor, draw_correlated,
                                           draw_grid_errors, grid_factors, normal_to_marginal)
from reliability.model.machine_file import machine_from_dict
from reliability.model.poses import workspace_grid
from reliability.sampling.grid_experiment import GridExperiment
from reliability.sampling.pose_sampling import sample_random_poses

Z = 4.0  # statistical tests: |estimate − truth| ≤ Z standard errors


# ----- validation ------------------------------------------------------------------------
def test_pairs_from_the_machine_file_by_paper_or_iso_name(hobbing_dict):
    hobbing_dict["correlation"] = [{"errors": ["X.ey", "EZX"], "coefficient": 0.6},
                                   {"errors": ["EB0X", "C-X.dz"], "coefficient": -0.3}]
    machine = machine_from_dict(hobbing_dict)
    R = machine.correlation
    i, j = machine.error_index("X.ey"), machine.error_index("X.dz")
    assert R[i, j] == R[j, i] == 0.6
    a, b = machine.error_index("C-X.ey"), machine.error_index("C-X.dz")
    assert R[a, b] == R[b, a] == -0.3
    assert np.count_nonzero(R - np.eye(machine.n_errors)) == 4
    assert not R.flags.writeable


def test_no_correlation_table_means_none(hobbing):
    assert hobbing.correlation is None


@pytest.mark.parametrize("entry, match", [
    ({"errors": ["X.ey", "X.nope"], "coefficient": 0.5}, "X.nope"),
    ({"errors": ["X.ey", "EBX"], "coefficient": 0.5}, "same error"),
    ({"errors": ["X.ey", "X.dz"], "coefficient": 1.2}, r"\[-1, 1\]"),
    ({"errors": ["X.ey", "X.dz"], "coefficient": True}, r"\[-1, 1\]"),
    ({"errors": ["X.ey"], "coefficient": 0.5}, "two error names"),
    ({"errors": ["X.ey", "X.dz"], "rho": 0.5}, "'coefficient'"),
])
def test_bad_pairs_are_refused_naming_them(hobbing_dict, entry, match):
    hobbing_dict["correlation"] = [entry]
    with pytest.raises(MachineDescriptionError, match=match):
        machine_from_dict(hobbing_dict)


def test_a_pair_given_twice_is_refused_even_under_its_iso_names(hobbing_dict):
    hobbing_dict["correlation"] = [{"errors": ["X.ey", "X.dz"], "coefficient": 0.5},
                                   {"errors": ["EZX", "EBX"], "coefficient": 0.4}]
    with pytest.raises(MachineDescriptionError, match="already given"):
        machine_from_dict(hobbing_dict)


def test_pairs_that_no_distribution_has_are_refused_with_the_eigenvalue(hobbing):
    # ρ_ab = ρ_ac = 0.9, ρ_bc = −0.9: eigenvalue 1 − 0.9 − 0.9 = −0.8 (closed form)
    pairs = [("X.ey", "X.dz", 0.9), ("X.ey", "X.dx", 0.9), ("X.dz", "X.dx", -0.9)]
    with pytest.raises(MachineDescriptionError, match=r"eigenvalue -0\.8 .*'X\."):
        hobbing.with_correlation(pairs)


@pytest.mark.parametrize("change, match", [
    (lambda R: R.__setitem__((0, 1), 0.3), "not symmetric"),
    (lambda R: R.__setitem__((2, 2), 0.9), "with itself"),
    (lambda R: R.__setitem__((3, 3), np.nan), "not finite"),
])
def test_matrix_checks_name_the_entry(hobbing, change, match):
    R = np.eye(hobbing.n_errors)
    change(R)
    with pytest.raises(MachineDescriptionError, match=match):
        check_correlation_matrix(R, hobbing.error_names)


def test_pairs_write_back_and_load_equal(hobbing, hobbing_dict):
    machine = hobbing.with_correlation({("X.ey", "X.dz"): 0.6, ("EA0Z", "EB0Z"): -0.25})
    tables = correlation_to_toml(machine)
    assert len(tables) == 2 and len(correlation_pairs(machine)) == 2
    hobbing_dict["correlation"] = tables
    assert np.array_equal(machine_from_dict(hobbing_dict).correlation, machine.correlation)


def test_to_toml_writes_the_correlation_when_the_machine_can_write_toml(hobbing):
    if not hasattr(hobbing, "to_toml"):
        pytest.skip("Machine.to_toml is not available in this build")
    import tomllib

    machine = hobbing.with_correlation({("X.ey", "X.dz"): 0.6})
    again = machine_from_dict(tomllib.loads(machine.to_toml()))
    assert np.array_equal(again.correlation, machine.correlation)


# ----- FOSM --------------------------------------------------------------------------------
def _explicit_sigma(J, t, R, k=3.0):
    """σ_y² = jᵀ D R D j built from the explicit covariance matrix."""
    D = np.diag(t / k)
    return np.sqrt(np.einsum("...i,ij,...j->...", J, D @ R @ D, J))


def test_fosm_sigma_is_the_quadratic_form(hobbing):
    machine = hobbing.with_correlation({("X.ey", "X.dz"): 0.7, ("Z.ex", "Z.dy"): -0.5,
                                        ("C-X.dx", "X-Z.dy"): 0.4})
    poses = workspace_grid(machine, 3)
    t = machine.initial_allocation * np.linspace(0.6, 1.4, machine.n_errors)
    result = fosm(machine, t, poses)
    J = machine.jacobian(poses)
    assert np.allclose(result.sigma, _explicit_sigma(J, t, machine.correlation), rtol=1e-12)
    cov = output_covariance(J, t, machine.correlation)
    assert np.allclose(np.sqrt(np.diagonal(cov, axis1=-2, axis2=-1)), result.sigma,
                       rtol=1e-12)
    assert np.allclose(cov, np.swapaxes(cov, -1, -2))


def test_identity_correlation_gives_the_paper_fosm(hobbing):
    poses = workspace_grid(hobbing, 3)
    plain = fosm(hobbing, hobbing.initial_allocation, poses)
    same = fosm(dataclasses.replace(hobbing, correlation=np.eye(hobbing.n_errors)),
                hobbing.initial_allocation, poses)
    assert np.allclose(plain.sigma, same.sigma, rtol=1e-13)
    assert np.allclose(plain.contributions, same.contributions, rtol=1e-10)


def test_contributions_are_euler_shares(hobbing):
    rho = 0.8
    machine = hobbing.with_correlation({("X.ey", "X.dz"): rho})
    result = fosm(machine, machine.initial_allocation, workspace_grid(machine, 3))
    share = result.contributions
    assert np.allclose(share.sum(axis=0), 100.0)
    # two-error closed form at the δz worst pose: a_i² + ρ a_i a_j for each of the pair
    pose = result.poses[result.worst_pose[2]]
    J = machine.jacobian(pose)[2]
    a = J * machine.initial_allocation / 3.0
    i, j = machine.error_index("X.ey"), machine.error_index("X.dz")
    sigma2 = np.sum(a ** 2) + 2 * rho * a[i] * a[j]
    assert share.loc["X.ey", "dz"] == pytest.approx(100 * (a[i] ** 2 + rho * a[i] * a[j])
                                                    / sigma2, rel=1e-10)


def test_monte_carlo_output_variance_matches_the_quadratic_form(hobbing):
    machine = hobbing.with_correlation({("X.ey", "X.dz"): 0.8, ("X.ey", "X.dx"): -0.5})
    pose = np.array([1.0, 300.0, 450.0, 0.5, 150.0, 2.0])
    t = machine.initial_allocation
    n = 40_000
    x = draw_correlated(t, (n,), correlation_factor(machine.correlation), k=3.0,
                        distribution="normal", rng=12)
    y = machine.comprehensive_error(pose, x)
    predicted = _explicit_sigma(machine.jacobian(pose), t, machine.correlation) ** 2
    se = predicted * np.sqrt(2.0 / (n - 1))  # normal variance estimator
    assert np.all(np.abs(y.var(axis=0, ddof=1) - predicted) <= Z * se)
    # the whole output covariance: SE of a covariance estimate is √((σ_a²σ_b² + c²)/n)
    cov = output_covariance(machine.jacobian(pose), t, machine.correlation)
    se_cov = np.sqrt((np.outer(np.diag(cov), np.diag(cov)) + cov ** 2) / n)
    assert np.all(np.abs(np.cov(y.T) - cov) <= Z * se_cov)
    assert np.any(np.abs(cov - np.diag(np.diag(cov))) > Z * se_cov)  # cross terms seen


def test_random_pose_sampling_agrees_with_correlated_fosm(hobbing):
    machine = hobbing.with_correlation({("X.ey", "X.dz"): 0.8})
    t = 2.5 * machine.initial_allocation  # P well below 1, so the test has power
    n = 20_000
    result = sample_random_poses(machine, t, n, rng=5, distribution="normal")
    fraction = result.inside / n
    se = np.sqrt(result.fosm_two_sided * (1 - result.fosm_two_sided) / n)
    assert np.all(np.abs(fraction - result.fosm_two_sided) <= Z * se)  # binomial SE
    plain = sample_random_poses(hobbing, t, n, rng=5, distribution="normal")
    assert not np.allclose(plain.fosm_two_sided, result.fosm_two_sided)


# ----- the copula --------------------------------------------------------------------------
def test_correlate_items_gives_the_correlation():
    R = np.array([[1.0, 0.6, -0.3], [0.6, 1.0, 0.0], [-0.3, 0.0, 1.0]])
    n = 100_000
    z = correlate_items(np.random.default_rng(3).standard_normal((n, 3)),
                        correlation_factor(R))
    sample = np.corrcoef(z.T)
    se = (1 - R ** 2) / np.sqrt(n)  # standard error of a Pearson coefficient
    assert np.all(np.abs(sample - R) <= Z * se + 1e-12)


def test_singular_correlation_has_a_factor():
    R = np.array([[1.0, 1.0], [1.0, 1.0]])
    L = correlation_factor(R)
    assert np.allclose(L @ L.T, R)


def test_copula_keeps_truncated_marginals():
    k = 3.0
    n = 200_000
    R = np.array([[1.0, -0.8], [-0.8, 1.0]])
    t = np.array([0.003, 1.5e-5])
    x = draw_correlated(t, (n,), correlation_factor(R), k=k, rng=7)
    assert np.all(np.abs(x) <= t)
    # truncated-normal marginal: standard deviation and tail mass beyond 2σ (closed forms)
    sd = error_sigma(t, k, "truncated")
    se_sd = sd / np.sqrt(2 * n) * 1.2  # kurtosis of the truncated normal is below 3
    assert np.all(np.abs(x.std(axis=0) - sd) <= Z * se_sd)
    beyond = (2 * norm.cdf(-2) - 2 * norm.cdf(-k)) / (2 * norm.cdf(k) - 1)
    observed = np.mean(np.abs(x) > 2 * t / k, axis=0)
    assert np.all(np.abs(observed - beyond) <= Z * np.sqrt(beyond * (1 - beyond) / n))
    assert np.corrcoef(x.T)[0, 1] == pytest.approx(-0.8, abs=0.01)


def test_marginal_transform_is_the_truncated_quantile():
    k = 3.0
    z = np.array([-8.0, -1.0, 0.0, 0.5, 2.0, 8.0])
    expected = norm.ppf(norm.cdf(-k) + norm.cdf(z) * (2 * norm.cdf(k) - 1))
    assert np.allclose(normal_to_marginal(z, k), expected, atol=1e-9)
    assert np.array_equal(normal_to_marginal(z, k, "normal"), z)


def test_grid_experiment_draws_correlated_motion_errors(hobbing):
    machine = hobbing.with_correlation({("X.ey", "X.dz"): 0.7, ("C-X.dx", "Z-A.ey"): -0.6})
    t = machine.initial_allocation
    draws = [draw_grid_errors(machine, t, 5, rng=seed, distribution="normal")
             for seed in range(4000)]
    motion = np.stack([d[0] for d in draws])  # (R, n_axes, P, 6)
    x = machine.axes.index("X")
    r = np.corrcoef(motion[:, x, :, 4].ravel(), motion[:, x, :, 2].ravel())[0, 1]
    n = motion[:, x, :, 4].size
    assert abs(r - 0.7) <= Z * (1 - 0.49) / np.sqrt(n)
    # different grid points of one axis stay independent (the paper's profile)
    r_points = np.corrcoef(motion[:, x, 0, 4], motion[:, x, 1, 2])[0, 1]
    assert abs(r_points) <= Z / np.sqrt(len(draws))
    assembly = np.stack([d[1] for d in draws])
    r_joint = np.corrcoef(assembly[:, 0, 0], assembly[:, 2, 4])[0, 1]
    assert abs(r_joint + 0.6) <= Z * (1 - 0.36) / np.sqrt(len(draws))
    result = GridExperiment(machine, 3).run(t, repeats=2, rng=1)
    assert result.inside.shape == (2, 6)


def test_grid_experiment_refuses_pairs_across_axes(hobbing):
    machine = hobbing.with_correlation({("X.ey", "Z.dx"): 0.5})
    with pytest.raises(InputError, match="'X.ey' and 'Z.dx'"):
        grid_factors(machine)


# ----- allocation --------------------------------------------------------------------------
def test_independent_problem_refuses_a_correlated_machine(hobbing):
    with pytest.raises(InputError, match="solve_correlated"):
        AllocationProblem.build(hobbing.with_correlation({("X.ey", "X.dz"): 0.5}))


@pytest.fixture(scope="module")
def independent_optimum(hobbing):
    return AllocationProblem.build(hobbing).solve_exact()


def test_correlated_solver_at_zero_agrees_with_the_independent_solver(hobbing,
                                                                      independent_optimum):
    result = solve_correlated(hobbing.with_correlation({("X.ey", "X.dz"): 0.0}))
    assert result.certified and result.relative_gap <= 1e-6
    assert result.dual_bound <= result.cost
    assert result.cost == pytest.approx(independent_optimum.cost, rel=1e-7)
    assert np.allclose(result.tolerances, independent_optimum.tolerances, rtol=1e-3)


@pytest.fixture(scope="module")
def mill_sweep(mill3):
    pair = ("X.dx", "X.ey")  # positioning and pitch: the Abbe pair, binding on this mill
    h = 1e-3
    return {rho: solve_correlated(mill3.with_correlation({pair: rho}))
            for rho in (0.5 - h, 0.5, 0.5 + h, -0.5)}, h


def test_correlated_optimum_is_certified_and_feasible(mill3, mill_sweep):
    results, _ = mill_sweep
    for rho, result in results.items():
        assert result.certified, result.message
        assert result.dual_bound <= result.cost * (1 + 1e-12)
        machine = mill3.with_correlation({("X.dx", "X.ey"): rho})
        check = fosm(machine, result.tolerances, workspace_grid(machine))
        assert np.all(check.worst("two_sided") >= machine.targets * (1 - 1e-9))


def test_cost_derivative_matches_finite_difference(mill3, mill_sweep):
    results, h = mill_sweep
    a, b = mill3.error_index("X.dx"), mill3.error_index("X.ey")
    slope = (results[0.5 + h].cost - results[0.5 - h].cost) / (2 * h)
    assert slope != 0
    assert results[0.5].sensitivity(a, b) == pytest.approx(slope, rel=1e-3)


# ----- study and report section ------------------------------------------------------------
def test_sweep_and_section_on_the_test_mill(mill3, mill_sweep):
    from studies.report.correlation_section import correlation_section
    from studies.workflows.correlation_sweep import correlation_sweep

    results, _ = mill_sweep
    sweep = correlation_sweep(mill3, ("EXX", "EBX"), [-0.5, 0.0, 0.5])
    assert sweep.loc[0.0, "cost_vs_rho0"] == pytest.approx(1.0, rel=1e-9)
    assert sweep.loc[0.5, "cost"] == pytest.approx(results[0.5].cost, rel=1e-9)
    assert sweep["certified"].all()
    section = correlation_section(mill3, ("EXX", "EBX"), sweep=sweep)
    assert "EXX" in section.text and "| rho |" in section.text
    assert set(section.figures) == {"correlation_cost.png"}
    assert section.tables["correlation_cost.csv"].shape[0] == 3
    assert section.summary["correlation_pair"] == ["EXX", "EBX"]


def test_result_table_names_errors_both_ways(mill3, mill_sweep):
    results, _ = mill_sweep
    frame = results[0.5].to_frame()
    assert list(frame.index) == list(mill3.error_names)
    assert list(frame["iso"]) == list(mill3.iso_names)
    assert np.array_equal(frame["tolerance"], results[0.5].tolerances)
    assert "certified" in results[0.5].summary()


def test_same_seed_same_correlated_draws(hobbing):
    machine = hobbing.with_correlation({("X.ey", "X.dz"): 0.7})
    t = machine.initial_allocation
    one = draw_grid_errors(machine, t, 5, rng=42)
    two = draw_grid_errors(machine, t, 5, rng=42)
    assert all(np.array_equal(a, b) for a, b in zip(one, two))
    first = GridExperiment(machine, 3).run(t, repeats=3, rng=9, batch=1)
    again = GridExperiment(machine, 3).run(t, repeats=3, rng=9, batch=3)
    assert np.array_equal(first.inside, again.inside)


def test_with_correlation_takes_a_full_matrix(hobbing):
    R = np.eye(hobbing.n_errors)
    i, j = hobbing.error_index("EBX"), hobbing.error_index("EZX")
    R[i, j] = R[j, i] = -0.4
    assert np.array_equal(hobbing.with_correlation(R).correlation, R)
    R[i, j] = 0.5  # no longer symmetric
    with pytest.raises(MachineDescriptionError, match="'X.dz' and 'X.ey'|'X.ey' and 'X.dz'"):
        hobbing.with_correlation(R)


def test_continuous_worst_pose_search_uses_the_correlation(mill3):
    """The continuous search's σ at its pose equals correlated FOSM there."""
    from reliability.first_order.workspace_search import continuous_worst
    correlated = mill3.with_correlation({("X.ey", "X.dz"): 0.7})
    grid = reliability.workspace_grid(correlated, 3)
    table = continuous_worst(correlated, correlated.initial_allocation, grid, starts=2)
    for output in ("dx", "dz"):
        pose = table.loc[output, list(correlated.axes)].to_numpy(dtype=float)
        at = reliability.fosm(correlated, correlated.initial_allocation, pose[None, :])
        o = correlated.outputs.index(output)
        assert table.loc[output, "beta"] == pytest.approx(
            correlated.limits[o] / at.sigma[0, o], rel=1e-9)
