"""Monte-Carlo at poses: default worst poses, Wilson coverage by repetition, adaptive stopping.

Coverage: over R seeded runs the share of 95 % intervals containing the true failure
probability is binomial with SE = sqrt(0.95 · 0.05 / R); accepted within 3 SE (z = 3).
The true probability is the linear-Gaussian one: on the exact model the non-linear part of
the outputs is below 2e−4 of their spread at these tolerances (checked below), far below
what a few hundred runs can resolve.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import multivariate_normal, norm

from reliability import fosm, workspace_grid
from reliability.basics.errors import InputError
from reliability.first_order.worst_grid_pose import worst_grid_poses
from reliability.sampling.pose_sampling import EVENTS, linear_failure, sample_at_poses

Z = 3.0


def band(runs, level=0.95):
    half = Z * np.sqrt(level * (1 - level) / runs)
    return level - half, level + half


@pytest.fixture(scope="module")
def setup(hobbing):
    """Tolerances giving dx a 5 % two-sided failure probability at its worst pose."""
    t0 = hobbing.initial_allocation
    pose = worst_grid_poses(hobbing, t0)[0]
    jacobian = hobbing.jacobian(pose)
    sigma = np.sqrt(np.square(jacobian[0]) @ np.square(t0 / 3))
    t = t0 * hobbing.limits[0] / (-norm.ppf(0.025) * sigma)
    a = jacobian * (t / 3)
    cov = a @ a.T
    sd = np.sqrt(np.diag(cov))
    system = 1 - multivariate_normal(np.zeros(6), cov / np.outer(sd, sd), abseps=1e-8,
                                     releps=1e-6, maxpts=500_000, seed=2).cdf(hobbing.limits / sd,
                                                 lower_limit=-hobbing.limits / sd)
    return t, pose, system


def test_non_linearity_is_negligible_here(hobbing, setup):
    t, pose, _ = setup
    x = np.random.default_rng(0).standard_normal((2000, t.size)) * t / 3
    y = hobbing.comprehensive_error(pose, x)
    linear = x @ hobbing.jacobian(pose).T
    assert np.all(np.abs(y - linear).max(axis=0) < 2e-4 * linear.std(axis=0))


def test_default_poses_are_fosm_worst_poses(hobbing):
    t = hobbing.initial_allocation
    result = sample_at_poses(hobbing, t, samples=2000, rng=1, fosm=False)
    grid_sigma = fosm(hobbing, t, workspace_grid(hobbing)).sigma.max(axis=0)
    at_poses = fosm(hobbing, t, result.poses).sigma  # (6 poses, 6 outputs)
    np.testing.assert_allclose(np.diag(at_poses), grid_sigma, rtol=1e-12)  # ties allowed
    frame = result.to_frame()
    assert len(frame) == 12  # each output at its own worst pose, the system at all six
    assert list(frame["event"][:2]) == ["dx", "system"]
    assert {"C (deg)", "X (mm)", "mc_failure", "lower", "upper", "fosm_failure"} <= set(frame)
    np.testing.assert_allclose(frame["C (deg)"].iloc[0], np.degrees(result.poses[0, 0]))
    assert "Wilson" in result.summary()


def test_fixed_sample_wilson_coverage(hobbing, setup):
    t, pose, system = setup
    runs, n = 300, 1000
    seeds = np.random.SeedSequence(31).spawn(runs)
    hits = np.zeros(2)
    for s in seeds:
        est = sample_at_poses(hobbing, t, pose[None], samples=n, batch=n,
                              rng=np.random.default_rng(s), fosm=False).estimate
        lower, upper = np.asarray(est.lower)[0, [0, 6]], np.asarray(est.upper)[0, [0, 6]]
        truth = np.array([0.05, system])
        hits += (lower <= truth) & (truth <= upper)
    low, high = band(runs)
    assert np.all((low <= hits / runs) & (hits / runs <= high))


def test_adaptive_stopping_coverage_and_sample_count(hobbing, setup):
    t, pose, _ = setup
    runs, precision = 300, 0.3
    seeds = np.random.SeedSequence(32).spawn(runs)
    hits, used = 0, []
    for s in seeds:
        result = sample_at_poses(hobbing, t, pose[None], precision=precision, batch=250,
                                 max_samples=20_000, rng=np.random.default_rng(s),
                                 events=("dx", "system"), fosm=False)
        est = result.estimate
        assert result.reached
        assert np.all(result.relative_half_width()[0, [0, 6]] <= precision)
        hits += est.lower[0, 0] <= 0.05 <= est.upper[0, 0]
        used.append(result.n_samples)
    low, high = band(runs)
    assert low <= hits / runs <= high
    # fixed-n answer: 1.96² (1 − p)/(p · precision²) ≈ 811 samples for dx at p = 0.05
    assert 500 <= np.median(used) <= 1200


def test_adaptive_cap_is_reported(hobbing, setup):
    t, pose, _ = setup
    result = sample_at_poses(hobbing, t, pose[None], precision=0.01, batch=500,
                             max_samples=1500, rng=3, fosm=False)
    assert result.reached is False and result.n_samples == 1500
    assert "NOT reached" in result.summary()


def test_fosm_column_matches_closed_forms(hobbing, setup):
    t, pose, system = setup
    linear = linear_failure(hobbing, t, pose[None])
    assert linear[0, 0] == pytest.approx(0.05, rel=1e-9)
    assert linear[0, 6] == pytest.approx(system, rel=1e-5)
    assert len(EVENTS) == linear.shape[1]


def test_same_seed_same_numbers(hobbing, setup):
    t, pose, _ = setup
    a = sample_at_poses(hobbing, t, pose[None], samples=3000, batch=1000, rng=9, fosm=False)
    b = sample_at_poses(hobbing, t, pose[None], samples=3000, batch=1000, rng=9, fosm=False)
    np.testing.assert_array_equal(a.failures, b.failures)


@pytest.mark.parametrize("kwargs, match", [
    ({"samples": 0}, "samples"), ({"precision": -0.1}, "precision"),
    ({"batch": 1.5}, "batch"), ({"distribution": "uniform"}, "distribution"),
    ({"poses": np.zeros((2, 5))}, "positions|poses"),
])
def test_bad_input_is_refused(hobbing, kwargs, match):
    with pytest.raises(ValueError, match=match):
        sample_at_poses(hobbing, hobbing.initial_allocation, **kwargs)


def test_bad_input_names_the_argument(hobbing):
    with pytest.raises(InputError, match="max_samples"):
        sample_at_poses(hobbing, hobbing.initial_allocation, precision=0.1, max_samples=-1)


def test_clopper_pearson_interval_is_wider_and_named(hobbing, setup):
    t, pose, _ = setup
    wilson = sample_at_poses(hobbing, t, pose[None], samples=2000, rng=4, fosm=False)
    exact = sample_at_poses(hobbing, t, pose[None], samples=2000, rng=4, fosm=False,
                            interval="clopper-pearson")
    np.testing.assert_array_equal(wilson.failures, exact.failures)
    assert np.all(np.asarray(exact.estimate.upper) - np.asarray(exact.estimate.lower)
                  >= np.asarray(wilson.estimate.upper) - np.asarray(wilson.estimate.lower))
    assert "Clopper–Pearson" in exact.summary()
    with pytest.raises(InputError, match="interval"):
        sample_at_poses(hobbing, t, pose[None], samples=10, interval="agresti")


def test_events_select_rows_and_unknown_event_is_refused(hobbing):
    t = hobbing.initial_allocation
    result = sample_at_poses(hobbing, t, samples=500, rng=5, fosm=False, events=("ez",))
    frame = result.to_frame()
    assert list(frame["event"]) == ["ez"] and list(frame["pose"]) == ["worst ez"]
    with pytest.raises(InputError, match="events"):
        sample_at_poses(hobbing, t, samples=500, events=("dq",))
