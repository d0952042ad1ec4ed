"""System reliability (all six outputs at once) and the allocation for a system target."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import multivariate_normal, norm

from allocation import AllocationProblem, system_allocation
from reliability import system_reliability, worst_system_reliability
from reliability.basics.errors import InputError
from reliability.first_order.system_reliability import rectangle_probability
from reliability.model.poses import workspace_grid

Z = 4.0  # standard errors allowed in every statistical comparison below


def test_independent_outputs_give_the_product():
    # diagonal covariance: the rectangle probability is Π (2Φ(b/σ) − 1), and Genz's
    # integrand is constant, so the estimate is exact
    sd = np.array([[1.0, 2.0, 0.5, 1.5, 1.0, 3.0]])
    limits = np.array([2.0, 3.0, 1.0, 2.5, 1.2, 4.0])
    estimates = rectangle_probability(np.einsum("pi,ij->pij", sd ** 2, np.eye(6)), limits,
                                      n_points=64, rng=0)
    exact = np.prod(2 * norm.cdf(limits / sd[0]) - 1)
    np.testing.assert_allclose(estimates, exact, rtol=1e-12)


def test_bivariate_rectangle_against_scipy():
    covariance = np.array([[1.0, 0.8], [0.8, 2.0]])
    limits = np.array([1.0, 1.5])
    estimates = rectangle_probability(covariance[None], limits, n_points=4096, rng=1)
    value = estimates.mean()
    error = estimates.std(ddof=1) / np.sqrt(len(estimates))
    reference = multivariate_normal.cdf(limits, mean=np.zeros(2), cov=covariance,
                                        lower_limit=-limits, rng=0)
    assert abs(value - reference) <= Z * error + 1e-5  # scipy's default abseps is 1e-5


def test_degenerate_covariance_repeated_output():
    # y2 = y1 exactly: P(|y1| < 1, |y2| < 2) = P(|y1| < 1), with a zero pivot in Cholesky
    covariance = np.ones((1, 2, 2))
    estimates = rectangle_probability(covariance, np.array([1.0, 2.0]), n_points=256, rng=2)
    np.testing.assert_allclose(estimates, 2 * norm.cdf(1.0) - 1, rtol=1e-12)


@pytest.fixture(scope="module")
def grid(hobbing):
    return workspace_grid(hobbing, 3)


@pytest.fixture(scope="module")
def initial(hobbing, grid):
    return system_reliability(hobbing, hobbing.initial_allocation, grid, rng=3)


def test_bounds_bracket_the_exact_probability(initial):
    # Bonferroni ≤ product (Šidák) ≤ exact ≤ least marginal
    slack = Z * initial.error
    assert np.all(initial.bonferroni <= initial.product + 1e-15)
    assert np.all(initial.product <= initial.probability + slack)
    assert np.all(initial.probability <= initial.min_marginal + slack)
    assert np.all(initial.error > 0) and np.all(initial.error < 1e-4)


def test_monte_carlo_of_the_linear_model_agrees(hobbing, grid, initial):
    w = initial.worst
    jacobian = hobbing.jacobian(grid[initial.index[w]])
    n = 400_000
    x = np.random.default_rng(4).normal(size=(n, hobbing.n_errors)) * \
        (hobbing.initial_allocation / 3)
    inside = np.all(np.abs(x @ jacobian.T) < hobbing.limits, axis=1).mean()
    p = initial.probability[w]
    standard_error = np.sqrt(p * (1 - p) / n)
    assert abs(inside - p) <= Z * np.hypot(standard_error, initial.error[w])
    # the outputs are correlated enough that the exact value is off the product
    assert p - initial.product[w] > Z * np.hypot(standard_error, initial.error[w])


def test_screened_worst_pose_is_the_worst(hobbing, grid, initial):
    screened = worst_system_reliability(hobbing, hobbing.initial_allocation, grid, rng=5,
                                        batch=16)
    assert len(screened.probability) < len(grid)
    assert screened.worst_probability == pytest.approx(
        initial.worst_probability,
        abs=Z * np.hypot(initial.error[initial.worst], screened.error[screened.worst]))
    # every pose left out has a product (lower bound) above the worst found
    left_out = np.setdiff1d(np.arange(len(grid)), screened.index)
    assert np.all(initial.product[left_out] >= screened.worst_probability)


def test_frame_summary_and_determinism(hobbing, grid, initial):
    frame = initial.to_frame()
    assert list(frame.columns[:6]) == list(hobbing.axes)
    assert {"probability", "error", "product", "bonferroni", "min_marginal"} <= set(frame)
    assert frame.index.name == "pose" and len(frame) == len(grid)
    assert "worst pose" in initial.summary() and "Šidák" in initial.summary()
    np.testing.assert_array_equal(initial.worst_pose, grid[initial.index[initial.worst]])
    first = system_reliability(hobbing, hobbing.initial_allocation, grid[:20], rng=8)
    again = system_reliability(hobbing, hobbing.initial_allocation, grid[:20], rng=8)
    np.testing.assert_array_equal(again.probability, first.probability)


@pytest.mark.parametrize("options, match", [
    ({"n_points": 1000}, "power of 2"),
    ({"n_batches": 1}, "n_batches"),
    ({"k": 0.0}, "k must be"),
])
def test_bad_input_is_refused(hobbing, grid, options, match):
    with pytest.raises(InputError, match=match):
        system_reliability(hobbing, hobbing.initial_allocation, grid[:2], **options)


def test_bad_tolerance_is_refused(hobbing, grid):
    t = hobbing.initial_allocation.copy()
    t[3] = -1
    with pytest.raises(ValueError, match="C.ex"):
        system_reliability(hobbing, t, grid[:2])


# ----- allocation for a system target ----------------------------------------------------
@pytest.fixture(scope="module")
def system_result(hobbing, grid):
    return system_allocation(hobbing, 0.99, poses=grid, rng=6, steps=8)


def test_system_bracket(hobbing, grid, system_result):
    result = system_result
    certificate = result.certificate
    assert result.feasible and certificate["certified"]
    # the lower bound is the per-output optimum at R, solved independently
    per_output = AllocationProblem.build(hobbing, grid,
                                         targets=dict.fromkeys(hobbing.outputs, 0.99))
    assert certificate["lower_bound"] == pytest.approx(per_output.solve_exact().cost,
                                                       rel=1e-6)
    assert certificate["lower_bound"] <= result.cost <= certificate["bonferroni_cost"]
    assert 0.99 <= certificate["output_target"] <= 1 - 0.01 / 6
    assert certificate["relative_gap"] == pytest.approx(
        1 - certificate["lower_bound"] / result.cost)


def test_system_allocation_meets_the_target_everywhere(hobbing, grid, system_result):
    check = system_reliability(hobbing, system_result.tolerances, grid, rng=7)
    lowest = check.worst
    assert check.probability[lowest] + Z * check.error[lowest] >= 0.99
    # and it is not wasteful: the per-output target could not be much lower
    assert check.worst_probability < 0.995


def test_system_allocation_refuses_bad_target(hobbing, grid):
    with pytest.raises(InputError, match="target"):
        system_allocation(hobbing, 1.0, poses=grid)
    with pytest.raises(InputError, match="targets"):
        system_allocation(hobbing, 0.9, poses=grid, targets={"dx": 0.9})


def test_system_section(mill3):
    from studies.report.tradeoff_sections import system_section

    poses = workspace_grid(mill3, 3)
    section = system_section(mill3, {"initial": mill3.initial_allocation}, poses=poses,
                             rng=9)
    table = section.tables["system_reliability.csv"]
    row = table.loc["initial"]
    assert row["bonferroni"] <= row["product"] <= row["system"] + Z * row["error"]
    assert row["system"] <= row["least_output"] + Z * row["error"]
    assert section.summary["system_worst_initial"] == row["system"]
    assert "| initial |" in section.text
