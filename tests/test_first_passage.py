"""The first-passage probability of a linearly drifting output
(reliability.life.first_passage), against independent computations."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from reliability.life.first_passage import first_passage_within

CASES = [(s0, sd, m0, md) for s0 in (0.05, 0.3, 0.5) for sd in (1e-4, 0.01, 0.1, 0.3, 1.0, 5.0)
         for m0, md in ((0.0, 0.0), (0.1, 0.05), (-0.2, 0.3))]


@pytest.mark.parametrize("s0, sd, m0, md", CASES)
def test_it_is_the_bivariate_normal_rectangle(s0, sd, m0, md):
    """(y(0), y(τ)) is bivariate normal with covariance [[s0², s0²], [s0², s0² + sd²]]:
    scipy's rectangle probability (Genz's algorithm) is an independent computation."""
    limit = 1.0
    rectangle = stats.multivariate_normal(
        [m0, m0 + md], [[s0 ** 2, s0 ** 2], [s0 ** 2, s0 ** 2 + sd ** 2]]).cdf(
        [limit, limit], lower_limit=[-limit, -limit])
    assert first_passage_within(limit, s0, sd, m0, md) == pytest.approx(rectangle, abs=1e-7)


@pytest.mark.parametrize("m0, md", [(0.0, 0.0), (0.1, 0.05), (0.2, -0.5)])
def test_without_drift_spread_it_is_one_interval(m0, md):
    """sd = 0: y(τ) = y(0) + md, so y(0) must lie in (max(−I, −I − md), min(I, I − md))."""
    low, high = max(-1.0, -1.0 - md), min(1.0, 1.0 - md)
    expected = stats.norm.cdf(high, m0, 0.3) - stats.norm.cdf(low, m0, 0.3)
    assert first_passage_within(1.0, 0.3, 0.0, m0, md) == pytest.approx(expected, abs=1e-14)


def test_monte_carlo_of_linear_paths_on_a_fine_age_grid():
    """Paths y(t) = y0 + r t judged at 201 ages of [0, 1]: the share within ±I at every age
    agrees with the closed form within 4 standard errors (z = 4, 200 000 paths)."""
    rng = np.random.default_rng(11)
    y0 = rng.normal(0.05, 0.3, 200_000)
    rate = rng.normal(0.1, 0.4, 200_000)
    ages = np.linspace(0.0, 1.0, 201)
    within = np.all(np.abs(y0[:, None] + rate[:, None] * ages) < 1.0, axis=1)
    expected = first_passage_within(1.0, 0.3, 0.4, 0.05, 0.1)
    error = np.sqrt(expected * (1 - expected) / len(y0))
    assert abs(within.mean() - expected) < 4 * error


def test_broadcasts_and_falls_with_the_drift():
    """One value per (pose, output) of broadcast arguments; more drift never helps."""
    value = first_passage_within(np.ones((3, 1)), np.array([[0.2], [0.3], [0.4]]),
                                 np.linspace(0.0, 1.0, 5))
    assert value.shape == (3, 5)
    assert np.all(np.diff(value, axis=1) < 0) and np.all(np.diff(value, axis=0) < 0)
