"""Error profiles along travel (reliability.model.profiles) and their use by the grid
experiment."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import truncnorm

from reliability.basics.errors import InputError, InputTypeError
from reliability.first_order.fosm import error_sigma, output_sigma
from reliability.model.error_draws import draw_errors
from reliability.model.profiles import (ConstantProfile, GaussianProfile, IndependentProfile,
                                        axis_profiles, cholesky_factor, correlate_along_travel,
                                        profile_model, standard_normals, to_marginal,
                                        travel_factors)
from reliability.sampling.grid_experiment import GridExperiment

#: Inside counts of the grid experiment before profiles existed (hobbing machine, initial
#: allocation, 7 repeats, seed 11, batches of 3): the default must still give them.
PINNED_INSIDE = [[15625, 15625, 15625, 15625, 15625, 15625],
                 [15617, 15625, 15618, 15625, 15625, 15625],
                 [15625, 15625, 15625, 15625, 15625, 15625],
                 [15625, 15625, 15625, 15405, 15398, 14612],
                 [15625, 15625, 15625, 15625, 15619, 15625],
                 [15625, 15625, 15625, 15606, 15625, 15625],
                 [15625, 15625, 15625, 15625, 15622, 15625]]


def _many(machine, profile, n, seed, points=5, k=3.0, distribution="normal", t=None):
    """``n`` experiments' motion errors ``(n, n_axes, P, 6)`` through the three stages."""
    axis_points = GridExperiment(machine, points).axis_points
    factors = travel_factors(machine, axis_profiles(machine, profile), axis_points)
    z = standard_normals(np.random.default_rng(seed), (n, len(axis_points), points, 6))
    t = np.ones((len(axis_points), 6)) if t is None else t
    return to_marginal(correlate_along_travel(z, factors), t[:, None, :], k, distribution)


# ----- the default is the paper's experiment, unchanged --------------------------------
def test_default_reproduces_the_counts_from_before_profiles(hobbing):
    result = GridExperiment(hobbing).run(hobbing.initial_allocation, repeats=7, rng=11,
                                         batch=3, keep_values="none")
    assert result.inside.tolist() == PINNED_INSIDE


@pytest.mark.parametrize("profile", ["independent", IndependentProfile(), {}, {"X": "independent"}])
def test_independent_is_byte_for_byte_the_rejection_draw(mill3, profile):
    t = mill3.initial_allocation * 3
    got = GridExperiment(mill3, 4, profile=profile).run(t, repeats=5, rng=5,
                                                        keep_values="all").values
    experiment = GridExperiment(mill3, 4)
    motion, assembly = [], []
    for child in np.random.default_rng(5).spawn(5):  # the documented stream, rebuilt
        motion_t = np.broadcast_to(t[:18].reshape(3, 1, 6), (3, 4, 6))
        motion.append(draw_errors(motion_t, (), rng=child))
        assembly.append(draw_errors(t[18:].reshape(2, 6), (), rng=child))
    expected = experiment.evaluate(np.stack(motion), np.stack(assembly))
    assert got.tobytes() == expected.tobytes()


# ----- models ----------------------------------------------------------------------------
def test_profile_names_and_models():
    assert isinstance(profile_model("independent"), IndependentProfile)
    assert isinstance(profile_model("constant"), ConstantProfile)
    assert profile_model("gp:200") == GaussianProfile(200.0)
    assert str(profile_model("gp:12.5")) == "gp:12.5"
    model = GaussianProfile(length=50)
    assert profile_model(model) is model


@pytest.mark.parametrize("spec, error", [
    ("smooth", InputError), ("gp:", InputError), ("gp:abc", InputError),
    ("gp:-3", InputError), ("gp:inf", InputError), (3.0, InputTypeError),
    (None, InputTypeError)])
def test_bad_profiles_are_refused(spec, error):
    with pytest.raises(error, match="profile|length"):
        profile_model(spec)


def test_bad_profile_mapping_names_the_axis(hobbing):
    with pytest.raises(InputError, match="'Q'"):
        axis_profiles(hobbing, {"Q": "constant"})
    with pytest.raises(InputError, match="'X'"):
        GridExperiment(hobbing, profile={"X": "gp:zero"})


def test_mapping_leaves_unnamed_axes_independent(hobbing):
    models = axis_profiles(hobbing, {"X": "constant", "C": GaussianProfile(100)})
    assert [str(m) for m in models] == ["gp:100", "constant", "independent", "independent",
                                        "independent", "independent"]


def test_squared_exponential_kernel_on_a_linear_axis(hobbing):
    axis = hobbing.axis_specs[1]  # X, 0 … 400 mm
    points = np.array([0.0, 100.0, 250.0])
    got = GaussianProfile(150.0).correlation(axis, points)
    assert got[0, 1] == pytest.approx(math.exp(-0.5 * (100 / 150) ** 2), rel=1e-14)
    assert got[1, 2] == pytest.approx(math.exp(-0.5 * 1.0), rel=1e-14)
    assert np.allclose(np.diag(got), 1.0)


def test_limited_rotary_axis_uses_arc_length(hobbing):
    axis = hobbing.axis_specs[3]  # A, ±π/4, diameter 1.5 m → radius 750 mm
    got = GaussianProfile(300.0).correlation(axis, np.array([0.0, 0.2]))
    assert got[0, 1] == pytest.approx(math.exp(-0.5 * (750 * 0.2 / 300) ** 2), rel=1e-14)


def test_periodic_kernel_wraps_on_a_full_turn_axis(hobbing):
    axis = hobbing.axis_specs[0]  # C, full turn, diameter 3 m → radius 1500 mm
    model = GaussianProfile(2000.0)
    delta = 0.3
    c = model.correlation(axis, np.array([0.0, delta, 2 * math.pi - delta]))
    assert c[0, 1] == pytest.approx(c[0, 2], rel=1e-12)  # 0 is as close to 2π−δ as to δ
    expected = math.exp(-2 * math.sin(delta / 2) ** 2 / (2000.0 / 1500.0) ** 2)
    assert c[0, 1] == pytest.approx(expected, rel=1e-14)
    # on the grid, the last point (1.6π) neighbours the first as closely as the second does
    grid = GridExperiment(hobbing).axis_points[0]
    on_grid = model.correlation(axis, grid)
    assert on_grid[0, -1] == pytest.approx(on_grid[0, 1], rel=1e-12)
    # small angles: the squared exponential in arc length
    small = model.correlation(axis, np.array([0.0, 1e-3]))[0, 1]
    assert small == pytest.approx(math.exp(-0.5 * (1500 * 1e-3 / 2000) ** 2), rel=1e-9)


def test_lengths_run_from_independent_to_constant(hobbing):
    axis, points = hobbing.axis_specs[1], np.linspace(0, 400, 5)
    assert np.allclose(GaussianProfile(1e-3).correlation(axis, points), np.eye(5))
    assert np.allclose(GaussianProfile(1e7).correlation(axis, points), 1.0, atol=1e-9)


def test_cholesky_factor_keeps_a_unit_diagonal_when_jitter_is_needed():
    ones = np.ones((5, 5))  # singular: plain Cholesky fails
    with pytest.raises(np.linalg.LinAlgError):
        np.linalg.cholesky(ones - 1e-17 * np.eye(5))
    factor = cholesky_factor(ones)
    product = factor @ factor.T
    assert np.allclose(np.diag(product), 1.0, rtol=0, atol=1e-15)
    assert np.allclose(product, ones, atol=1e-6)
    with pytest.raises(InputError, match="positive semi-definite"):
        cholesky_factor(np.array([[1.0, 2.0], [2.0, 1.0]]))


def test_factors_reproduce_the_kernel(hobbing):
    points = GridExperiment(hobbing).axis_points
    models = axis_profiles(hobbing, "gp:300")
    for model, axis, p, factor in zip(models, hobbing.axis_specs, points,
                                      travel_factors(hobbing, models, points)):
        assert np.allclose(factor @ factor.T, model.correlation(axis, p), atol=2e-6)


# ----- draws: marginals kept, correlation as the kernel ----------------------------------
@pytest.mark.parametrize("profile", ["independent", "gp:150", "constant"])
def test_truncated_marginals_are_kept_at_every_point(hobbing, profile):
    n, k = 20_000, 3.0
    t = np.linspace(1.0, 2.0, 36).reshape(6, 6)
    x = _many(hobbing, profile, n, seed=7, k=k, distribution="truncated", t=t)
    scaled = x / (t[:, None, :] / k)  # every value should be N(0, 1) truncated at ±k
    assert np.abs(scaled).max() <= k * (1 + 1e-12)
    sd = error_sigma(1.0, k, "truncated") * k  # truncated N(0,1) standard deviation
    # z = 4.5 over 180 (axis, point, error) cells; SE of the mean sd/√n, of the variance
    # sd² √((m4/sd⁴ − 1)/n) with m4 the truncated fourth moment
    m4 = truncnorm(-k, k).moment(4)
    mean_se, var_se = sd / math.sqrt(n), math.sqrt((m4 - sd ** 4) / n)
    assert np.abs(scaled.mean(axis=0)).max() < 4.5 * mean_se
    assert np.abs(scaled.var(axis=0) - sd ** 2).max() < 4.5 * var_se


def test_normal_marginals_are_kept(hobbing):
    n = 20_000
    x = _many(hobbing, "gp:400", n, seed=8, k=2.0)  # t = 1, σ = 0.5
    # z = 4.5 over 180 cells; SE of a normal variance σ² √(2/n)
    assert np.abs(x.var(axis=0) - 0.25).max() < 4.5 * 0.25 * math.sqrt(2 / n)


def test_truncated_quantile_transform_is_the_truncated_normal_quantile():
    z = np.array([-8.0, -2.0, -0.3, 0.0, 0.5, 3.0, 9.0])
    got = to_marginal(z, 3.0, k=3.0)
    expected = truncnorm(-3, 3).ppf(np.array([1e-15, 0.02275013194817921, 0.3820885778110474,
                                              0.5, 0.6914624612740131, 0.9986501019683699,
                                              1 - 1e-15]))
    assert np.allclose(got[1:-1], expected[1:-1], rtol=1e-9, atol=1e-12)
    assert got[0] == pytest.approx(-3.0, abs=1e-9) and got[-1] == pytest.approx(3.0, abs=1e-9)


def test_correlation_along_travel_matches_the_kernel(hobbing):
    n, length = 20_000, 200.0
    x = _many(hobbing, GaussianProfile(length), n, seed=9)
    axis = 1  # X: grid points 0, 100, 200, 300, 400 mm
    draws = x[:, axis, :, 2]  # X.dz at the five points
    empirical = np.corrcoef(draws.T)
    kernel = GaussianProfile(length).correlation(hobbing.axis_specs[axis],
                                                 np.linspace(0, 400, 5))
    # SE of a sample correlation ≈ (1 − ρ²)/√n; z = 4.5 over the 10 pairs
    se = (1 - kernel ** 2) / math.sqrt(n) + 1e-12
    assert np.all(np.abs(empirical - kernel) <= 4.5 * se + 1e-6)
    # the six errors of one point stay independent of each other
    cross = np.corrcoef(x[:, axis, 2, :].T)
    assert np.abs(cross - np.eye(6)).max() < 4.5 / math.sqrt(n)


def test_constant_profile_is_perfectly_correlated(hobbing):
    x = _many(hobbing, "constant", 50, seed=10, distribution="truncated")
    assert np.all(x == x[:, :, :1, :])
    assert np.unique(x[:, 1, 0, 0]).size == 50  # but differs between machines


def test_grid_experiment_with_profile_draws_constant_errors(mill3):
    experiment = GridExperiment(mill3, 3, profile={"X": "constant"})
    motion, _ = experiment._draw(mill3.initial_allocation, np.random.default_rng(0), 3.0,
                                 "truncated")
    assert np.all(motion[1] == motion[1, :1])
    assert not np.all(motion[0] == motion[0, :1])


# ----- per-pose reliability does not depend on the profile --------------------------------
@pytest.mark.parametrize("profile", ["gp:200", "constant", {"Y": "constant", "Z": "gp:50"}])
def test_per_pose_spread_is_the_fosm_sigma_whatever_the_profile(mill3, profile):
    repeats = 4000
    result = GridExperiment(mill3, 3, profile=profile).run(
        mill3.initial_allocation, repeats=repeats, rng=12, distribution="normal",
        keep_values="all")
    experiment = GridExperiment(mill3, 3)
    sigma = output_sigma(mill3.jacobian(experiment.poses),
                         error_sigma(mill3.initial_allocation, 3.0))
    sd = result.values.std(axis=0)
    # SE of a normal standard deviation σ/√(2R); z = 4.5 over 27 poses × 6 outputs
    assert np.all(np.abs(sd - sigma) < 4.5 * sigma / math.sqrt(2 * repeats))


def test_mean_fraction_is_the_same_for_every_profile(mill3):
    t = mill3.initial_allocation * 2.5  # fractions well below 1
    estimates = [GridExperiment(mill3, 3, profile=p).run(
        t, repeats=3000, rng=13, keep_values="none").reliability()
        for p in ("independent", "gp:300", "constant")]
    base = estimates[0]
    for other in estimates[1:]:
        se = np.hypot(base.standard_error, other.standard_error)
        assert np.all(np.abs(other.estimate - base.estimate) < 4.0 * se)  # z = 4
    # and the profile does change what a machine sees: the spread between experiments
    assert np.all(estimates[2].std[:3] > 1.2 * base.std[:3])
