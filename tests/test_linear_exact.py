"""The exact probability of the linearised output under truncated-normal errors
(reliability.first_order.linear_exact), against independent computations."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import quad
from scipy.stats import norm, truncnorm

from reliability import OUTPUTS
from reliability.basics.errors import InputError
from reliability.basics.streams import spawn
from reliability.first_order.fosm import fosm
from reliability.first_order.linear_exact import (TAIL_TOLERANCE, _series_sum,
                                                  fast_truncated_normal_cf, linear_two_sided,
                                                  series_terms, truncated_normal_cf,
                                                  truncated_normal_cf_derivative)
from reliability.model.error_draws import draw_errors
from reliability.model.poses import workspace_grid

K = 3.0


@pytest.mark.parametrize("v", [0.0, 0.3, 2.0, 7.5, 40.0, 150.0])
def test_characteristic_function_against_quadrature(v):
    """φ(v) = E cos(vZ) for Z ~ N(0, 1) truncated at ±3, by adaptive quadrature."""
    reference = quad(lambda z: norm.pdf(z) * np.cos(v * z), -K, K, limit=500,
                     epsabs=1e-15)[0] / (2 * norm.cdf(K) - 1)
    assert truncated_normal_cf(v, K) == pytest.approx(reference, abs=1e-14)
    assert fast_truncated_normal_cf(np.array([v]), K)[0] == pytest.approx(reference, abs=1e-13)


def test_derivative_and_spline():
    """The derivative against a central difference; the spline against the Faddeeva form
    on a million random points of its table (the docstring's error bound, 4e-14)."""
    v = np.array([0.5, 3.0, 20.0, 63.0])
    step = 1e-5
    central = (truncated_normal_cf(v + step, K) - truncated_normal_cf(v - step, K)) / (2 * step)
    np.testing.assert_allclose(truncated_normal_cf_derivative(v, K), central, atol=1e-9)
    points = np.random.default_rng(0).uniform(0.0, 64.0, 1_000_000)
    gap = np.abs(fast_truncated_normal_cf(points, K) - truncated_normal_cf(points, K))
    assert gap.max() < 4e-14


@pytest.mark.parametrize("limit, mean", [(0.8, 0.0), (2.0, 0.3), (4.5, -1.1)])
def test_one_term_is_the_truncated_normal_cdf(limit, mean):
    scale = 0.9
    d = truncnorm(-K, K, scale=scale)
    expected = d.cdf(limit - mean) - d.cdf(-limit - mean)
    got = linear_two_sided(limit, [scale, 0.0, 0.0], mean=mean)
    assert got == pytest.approx(expected, abs=1e-14)


@pytest.mark.parametrize("scales, limit, mean", [((1.0, 0.7), 2.0, 0.3),
                                                  ((1.0, 1.0), 1.5, 0.0),
                                                  ((0.4, 1.3), 3.9, -0.8)])
def test_two_terms_against_quadrature_of_the_convolution(scales, limit, mean):
    """P(|μ + y1 + y2| < I) = ∫ f1(y) [F2(I − μ − y) − F2(−I − μ − y)] dy by quadrature."""
    first, second = (truncnorm(-K, K, scale=s) for s in scales)
    reference = quad(lambda y: first.pdf(y) * (second.cdf(limit - mean - y)
                                               - second.cdf(-limit - mean - y)),
                     -K * scales[0], K * scales[0], epsabs=1e-14, epsrel=1e-13, limit=500)[0]
    assert linear_two_sided(limit, scales, mean=mean) == pytest.approx(reference, abs=1e-9)


def test_three_terms_against_quadrature_over_the_third():
    """Three terms: quadrature over the third term of the two-term closed-form-checked
    series, shifted by its value (the mean argument)."""
    scales, limit = np.array([0.5, 0.8, 0.6]), 2.2
    third = truncnorm(-K, K, scale=scales[2])
    reference = quad(lambda y: third.pdf(y) * linear_two_sided(limit, scales[:2], mean=y),
                     -K * scales[2], K * scales[2], epsabs=1e-13, limit=200)[0]
    assert linear_two_sided(limit, scales) == pytest.approx(reference, abs=1e-9)


def test_series_truncation_meets_its_bound():
    """Doubling the series' length changes the result by less than the stated tail bound."""
    rng = np.random.default_rng(3)
    scales = rng.uniform(0.1, 1.0, (20, 12))
    limit = 2.3 * np.sqrt((scales ** 2).sum(axis=-1))
    mean = rng.uniform(-0.5, 0.5, 20)
    terms = series_terms(limit, scales, K, mean)
    short = np.array([_series_sum(limit[[i]], scales[[i]], K, mean[[i]], int(terms[i]))[0]
                      for i in range(20)])
    long = np.array([_series_sum(limit[[i]], scales[[i]], K, mean[[i]], 4 * int(terms[i]))[0]
                     for i in range(20)])
    assert np.abs(short - long).max() <= TAIL_TOLERANCE


def test_against_monte_carlo_of_the_linear_model(hobbing):
    """10⁶ draws of the linear model Σ J_oi x_i with truncated-normal x_i at one pose:
    the binomial standard error bounds the difference (z < 4.5 for each output)."""
    pose = np.array([0.4, 400.0, 500.0, 0.7, 200.0, 3.5])
    t = hobbing.initial_allocation
    jac = hobbing.jacobian(pose)
    exact = linear_two_sided(hobbing.limits, np.abs(jac) * t / K)
    n = 1_000_000
    inside = np.zeros(6)
    for stream in spawn(17, 4):
        x = draw_errors(t, (n // 4,), k=K, distribution="truncated", rng=stream)
        inside += (np.abs(x @ jac.T) < hobbing.limits).sum(axis=0)
    share = inside / n
    z = (share - exact) / np.sqrt(exact * (1 - exact) / n)
    assert np.all(np.abs(z) < 4.5), z


def test_bad_inputs():
    with pytest.raises(InputError, match="scales"):
        linear_two_sided(1.0, [-0.1, 0.5])
    with pytest.raises(InputError, match="limit"):
        linear_two_sided(0.0, [0.1, 0.5])
    with pytest.raises(InputError, match="series terms"):
        linear_two_sided(1.0, [1.0, 1e-9])  # one term dominates by nine orders


def test_fosm_field_under_each_reading(hobbing):
    """Normal: exact_two_sided is the closed form; truncated: the series, per pose and
    output, and its column in to_frame is the worst-pose value."""
    poses = workspace_grid(hobbing, 2)
    t = hobbing.initial_allocation
    normal = fosm(hobbing, t, poses)
    np.testing.assert_array_equal(normal.exact_two_sided, normal.two_sided)
    truncated = fosm(hobbing, t, poses, distribution="truncated")
    jac = hobbing.jacobian(poses)
    expected = linear_two_sided(hobbing.limits, np.abs(jac) * t / K)
    np.testing.assert_allclose(truncated.exact_two_sided, expected, atol=1e-12)
    rows = np.arange(len(OUTPUTS))
    np.testing.assert_array_equal(truncated.to_frame()["exact_two_sided"],
                                  truncated.exact_two_sided[truncated.worst_pose, rows])
