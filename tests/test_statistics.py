"""Tests for reliability.basics.statistics: intervals against scipy, coverage, refusals."""

import numpy as np
import pandas as pd
import pytest
from scipy import integrate, special, stats

from reliability.basics.statistics import (ProportionEstimate, all_within_share,
                                           between_experiment_interval, binomial_interval,
                                           proportion)

# Statistical checks allow Z standard errors of the Monte-Carlo estimate (two-sided
# false-alarm rate 0.27 % per check for a correct implementation; seeds are fixed).
Z = 3.0
CASES = [(0, 1), (1, 1), (0, 10), (3, 10), (10, 10), (0, 500), (495, 500), (500, 500),
         (15568, 15625), (7, 20)]
SCIPY_NAME = {"wilson": "wilson", "clopper-pearson": "exact"}


# --------------------------------------------------------------------------- intervals
@pytest.mark.parametrize("method", ["wilson", "clopper-pearson"])
@pytest.mark.parametrize("confidence", [0.9, 0.95, 0.99])
def test_binomial_interval_matches_scipy_binomtest(method, confidence):
    k, n = np.array(CASES).T
    lower, upper = binomial_interval(k, n, confidence, method)
    for i, (ki, ni) in enumerate(CASES):
        ref = stats.binomtest(ki, ni).proportion_ci(confidence, SCIPY_NAME[method])
        assert lower[i] == pytest.approx(ref.low, abs=1e-10), (ki, ni)
        assert upper[i] == pytest.approx(ref.high, abs=1e-10), (ki, ni)


@pytest.mark.parametrize("method", ["wilson", "clopper-pearson"])
def test_interval_is_exactly_zero_or_one_at_the_ends(method):
    lower, upper = binomial_interval([0, 20], 20, method=method)
    assert lower[0] == 0.0 and upper[1] == 1.0
    assert 0.0 < upper[0] < 1.0 and 0.0 < lower[1] < 1.0


def test_binomial_interval_broadcasts_and_returns_scalars_for_scalars():
    lower, upper = binomial_interval(np.array([[1], [2]]), np.array([10, 20, 30]))
    assert lower.shape == upper.shape == (2, 3)
    lo, hi = binomial_interval(3, 10)
    assert isinstance(lo, float) and isinstance(hi, float)


def _exact_coverage(p, n, confidence, method):
    """Coverage of the interval for Binomial(n, p), summed over every possible k."""
    k = np.arange(n + 1)
    lower, upper = binomial_interval(k, n, confidence, method)
    return stats.binom.pmf(k, n, p)[(lower <= p) & (p <= upper)].sum()


@pytest.mark.parametrize("method", ["wilson", "clopper-pearson"])
def test_coverage_by_simulation(method):
    """2000 replications at p = 0.99, n = 500, z = 3 on the coverage estimate."""
    p, n, reps, confidence = 0.99, 500, 2000, 0.95
    k = np.random.default_rng(20230201).binomial(n, p, size=reps)
    lower, upper = binomial_interval(k, n, confidence, method)
    observed = np.mean((lower <= p) & (p <= upper))
    exact = _exact_coverage(p, n, confidence, method)
    se = np.sqrt(exact * (1 - exact) / reps)
    assert abs(observed - exact) <= Z * se
    # Undercoverage is the dangerous failure: not more than Z standard errors below nominal.
    assert observed >= confidence - Z * np.sqrt(confidence * (1 - confidence) / reps)


@pytest.mark.parametrize("n", [20, 100, 500])
def test_clopper_pearson_never_undercovers(n):
    for p in (0.5, 0.9, 0.99, 0.999):
        assert _exact_coverage(p, n, 0.95, "clopper-pearson") >= 0.95 - 1e-12


# --------------------------------------------------------------------------- proportion
def test_proportion_fields_and_frame():
    est = proportion([15568, 15625, 15528], 15625, names=("dx", "dy", "ez"))
    assert isinstance(est, ProportionEstimate)
    np.testing.assert_allclose(est.estimate, [15568 / 15625, 1.0, 15528 / 15625])
    p = est.estimate
    np.testing.assert_allclose(est.standard_error, np.sqrt(p * (1 - p) / 15625))
    frame = est.to_frame()
    assert list(frame.index) == ["dx", "dy", "ez"]
    assert frame.loc["dy", "upper"] == 1.0 and frame.loc["dy", "n"] == 15625
    assert set(est.as_dict()) >= {"estimate", "lower", "upper", "standard_error", "n"}


def test_results_are_frozen():
    est = proportion([1, 2], 10)
    with pytest.raises(AttributeError):
        est.estimate = 0.5
    with pytest.raises(ValueError, match="read-only"):
        est.lower[0] = 0.0


# --------------------------------------------------------------------------- between experiments
def test_between_experiment_interval_is_wilson_on_kish_effective_size():
    f = np.random.default_rng(1).uniform(0.99, 1.0, size=(20, 6))
    est = between_experiment_interval(f, confidence=0.9, names=list("abcdef"))
    p, se = f.mean(axis=0), f.std(axis=0, ddof=1) / np.sqrt(20)
    n_eff = p * (1 - p) / se**2  # Kish: pooled size over the design effect
    np.testing.assert_allclose(est.effective_n, n_eff, rtol=1e-12)
    # Wilson bounds are the roots pi of (p - pi)^2 = z^2 pi (1 - pi) / n_eff.
    z = stats.norm.ppf(0.95)
    for bound in (est.lower, est.upper):
        np.testing.assert_allclose((p - bound) ** 2, z**2 * bound * (1 - bound) / n_eff,
                                   rtol=1e-9)
    assert np.all(est.lower < p) and np.all(p < est.upper)
    np.testing.assert_allclose(est.standard_error, se)
    np.testing.assert_array_equal(est.minimum, f.min(axis=0))
    np.testing.assert_array_equal(est.maximum, f.max(axis=0))
    assert est.n == 20 and est.method == "wilson-kish"
    assert list(est.to_frame().index) == list("abcdef")


def test_between_experiment_interval_stays_inside_zero_one():
    """Where a Student-t interval reaches above 1 (0.995 + 12.7 * 0.005), Wilson does not."""
    est = between_experiment_interval([[1.0, 0.0], [0.99, 0.01]])
    assert 0.0 <= est.lower[0] and est.upper[0] <= 1.0
    assert 0.0 <= est.lower[1] and est.upper[1] <= 1.0
    assert est.upper[0] < 1.0 and est.lower[1] > 0.0


def test_agreeing_experiments_keep_an_interval_of_the_poses_evaluated():
    """All experiments at 1: n_eff = n * poses and the Wilson lower bound N / (N + z^2)."""
    est = between_experiment_interval(np.ones((4, 2)), poses=100)
    z = stats.norm.ppf(0.975)
    np.testing.assert_allclose(est.lower, 400 / (400 + z**2), rtol=1e-12)
    np.testing.assert_array_equal(est.upper, 1.0)
    np.testing.assert_array_equal(est.effective_n, 400.0)
    capped = between_experiment_interval([[0.5], [0.6]], poses=3)
    assert capped.effective_n[0] == 6.0  # p(1-p)/se^2 = 99 exceeds the 6 poses
    without = between_experiment_interval(np.ones((4, 2)))
    np.testing.assert_allclose(without.lower, 4 / (4 + z**2), rtol=1e-12)
    with pytest.raises(ValueError, match="poses"):
        between_experiment_interval(np.ones((4, 2)), poses=0)


def test_between_experiment_interval_coverage_for_normal_fractions():
    """Near-nominal coverage for normal fractions: 2000 replications, z = 3."""
    reps, mean, sd = 2000, 0.995, 0.001
    f = np.random.default_rng(7).normal(mean, sd, size=(20, reps))
    est = between_experiment_interval(f)
    observed = np.mean((est.lower <= mean) & (mean <= est.upper))
    assert abs(observed - 0.95) <= Z * np.sqrt(0.95 * 0.05 / reps)


def test_pooling_correlated_poses_undercovers_but_experiments_do_not():
    """Poses sharing an experiment's errors: the pooled binomial interval is too narrow.

    Each experiment has its own in-tolerance probability (logit-normal random effect); its
    15 625 poses are drawn with that probability. The pooled Wilson interval treats the
    312 500 poses as independent.
    """
    reps, n_exp, poses, mu, tau = 400, 20, 15625, special.logit(0.998), 1.0
    rng = np.random.default_rng(11)
    p_exp = special.expit(mu + tau * rng.standard_normal((n_exp, reps)))
    k = rng.binomial(poses, p_exp)
    truth = integrate.quad(lambda z: special.expit(mu + tau * z) * stats.norm.pdf(z),
                           -12, 12)[0]
    lo, hi = binomial_interval(k.sum(axis=0), n_exp * poses)
    pooled = np.mean((lo <= truth) & (truth <= hi))
    est = between_experiment_interval(k / poses)
    replicated = np.mean((est.lower <= truth) & (truth <= est.upper))
    # Seeds 11-13 give pooled coverage 0.16-0.18 and replicated 0.85 (below the nominal
    # 0.95 because these fractions are skewed; see the Notes of the function). With 400
    # replications the coverage standard error is about 0.018; bounds leave Z = 3 of it.
    assert pooled < 0.3
    assert replicated > 0.8


# --------------------------------------------------------------------------- all-within share
def test_all_within_share_reduces_trailing_axes():
    ok = np.ones((20, 15, 6), dtype=bool)
    ok[3, 7, 5] = False
    ok[8, 0, 0] = False
    est = all_within_share(ok)
    assert est.estimate == 18 / 20 and est.n == 20 and est.method == "clopper-pearson"
    ref = stats.binomtest(18, 20).proportion_ci(0.95, "exact")
    assert (est.lower, est.upper) == pytest.approx((ref.low, ref.high), abs=1e-10)


def test_all_within_share_from_counts_equals_boolean_input():
    by_count = all_within_share(17, trials=20)
    by_bool = all_within_share(np.arange(20) < 17)
    pd.testing.assert_frame_equal(by_count.to_frame(), by_bool.to_frame())


# --------------------------------------------------------------------------- refusals
@pytest.mark.parametrize(
    "args, kwargs, match",
    [
        ((3, 0), {}, r"trials must be positive; trials = 0"),
        (([1, 2], [10, -4]), {}, r"trials\[1\] = -4"),
        ((11, 10), {}, r"successes = 11"),
        (([0, -1], 10), {}, r"successes\[1\] = -1"),
        ((2.5, 10), {}, r"whole numbers; successes = 2.5"),
        ((2, np.nan), {}, r"whole numbers; trials = nan"),
        ((2, 10), {"confidence": 1.0}, r"confidence must lie in \(0, 1\); got 1.0"),
        ((2, 10), {"confidence": 0}, r"confidence must lie in \(0, 1\)"),
        ((2, 10), {"method": "wald"}, r"unknown interval method 'wald'"),
        (([1, 2, 3], [10, 10]), {}, r"do not broadcast"),
    ],
)
def test_binomial_interval_refusals(args, kwargs, match):
    with pytest.raises(ValueError, match=match):
        binomial_interval(*args, **kwargs)


def test_proportion_refuses_wrong_number_of_names():
    with pytest.raises(ValueError, match="got 2 names for 3 outputs"):
        proportion([1, 2, 3], 10, names=("dx", "dy"))


@pytest.mark.parametrize(
    "fractions, match",
    [
        ([[0.99, 1.0]], r"at least 2 experiments.*got 1"),
        (0.99, r"at least 2 experiments.*got 0"),
        ([[0.99, 1.0], [1.2, 1.0]], r"fractions\[1, 0\] = 1.2"),
        ([[0.99, -0.1], [0.99, 1.0]], r"fractions\[0, 1\] = -0.1"),
        ([[0.99, np.inf], [0.99, 1.0]], r"finite.*fractions\[0, 1\] = inf"),
        ([0.99, np.nan, 1.0], r"fractions\[1\] = nan"),
    ],
)
def test_between_experiment_interval_refusals(fractions, match):
    with pytest.raises(ValueError, match=match):
        between_experiment_interval(fractions)


def test_to_frame_refuses_multidimensional_estimates():
    est = between_experiment_interval(np.full((3, 2, 2), 0.5) + np.arange(3)[:, None, None] / 10)
    with pytest.raises(ValueError, match=r"0-d or 1-d estimate; got shape \(2, 2\)"):
        est.to_frame()


def test_all_within_share_refusals():
    with pytest.raises(TypeError, match="boolean array.*trials="):
        all_within_share(np.array([1, 0, 1]))
    with pytest.raises(ValueError, match="trials must be positive"):
        all_within_share(np.zeros((0, 5), dtype=bool))
    with pytest.raises(ValueError, match="unknown interval method 'exact'"):
        all_within_share(np.ones(5, dtype=bool), method="exact")


def test_scalar_frame_has_one_row():
    frame = all_within_share(np.ones(20, dtype=bool)).to_frame()
    assert isinstance(frame, pd.DataFrame) and len(frame) == 1
    assert frame["upper"].iloc[0] == 1.0
