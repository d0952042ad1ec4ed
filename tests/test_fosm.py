"""Tests of FOSM precision reliability (Eqs. 19-23), one- and two-sided."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
from scipy.stats import norm, truncnorm

from reliability import OUTPUTS
from reliability.first_order.fosm import (FosmResult, error_sigma, fosm, one_sided_probability,
                                          reliability_index, required_index, two_sided_probability)
from reliability.model.poses import workspace_grid

T_LIN, T_ANG = 0.003, 1.45e-5          # Table 4
Q0 = np.array([0.0, 0.0, 100.0, 0.0, 0.0, 0.0])  # C X Z A Y M: no rotation, Z = 100


@pytest.fixture(scope="module")
def grid(hobbing):
    return workspace_grid(hobbing)


@pytest.fixture(scope="module")
def grid_jacobian(hobbing, grid):
    return hobbing.jacobian(grid)


@pytest.fixture(scope="module")
def table4(hobbing, grid, grid_jacobian):
    return fosm(hobbing, hobbing.initial_allocation, grid, jacobian=grid_jacobian)


# ----- σ by hand --------------------------------------------------------------------------
def test_sigma_hand_case(hobbing):
    """At Q0 every chain rotation is the identity, so each error's frame is the tool's.

    εx: the 11 angular errors about x (6 axes + 5 joints) add with coefficient 1:
    σ = √11·t/3. δz: the 11 δz add with coefficient 1 (ε×p has no z part for p along z).
    δx: 11 δx plus the εy of the 5 frames that still see Z's 100 mm of travel (C, C-X, X,
    X-Z and Z itself, whose error precedes its motion): δx += εy·100.
    """
    result = fosm(hobbing, hobbing.initial_allocation, Q0)
    s_lin, s_ang = T_LIN / 3, T_ANG / 3
    expected = [
        math.sqrt(11 * s_lin**2 + 5 * (100 * s_ang) ** 2),  # δx
        math.sqrt(11 * s_lin**2 + 5 * (100 * s_ang) ** 2),  # δy: εx·100 with the same 5
        math.sqrt(11) * s_lin,                              # δz
        math.sqrt(11) * s_ang, math.sqrt(11) * s_ang, math.sqrt(11) * s_ang,
    ]
    assert result.sigma.shape == (1, 6)
    np.testing.assert_allclose(result.sigma[0], expected, rtol=1e-13)
    np.testing.assert_allclose(result.beta[0], hobbing.limits / np.array(expected), rtol=1e-13)

    contributions = result.contributions
    assert isinstance(contributions, pd.DataFrame)
    assert contributions.shape == (66, 6)
    angular_x = [n for n in hobbing.error_names if n.endswith(".ex")]
    np.testing.assert_allclose(contributions.loc[angular_x, "ex"], 100 / 11, rtol=1e-12)
    assert contributions["ex"].drop(angular_x).abs().max() == 0.0
    var_dx = expected[0] ** 2
    assert contributions.loc["X.dx", "dx"] == pytest.approx(100 * s_lin**2 / var_dx, rel=1e-12)
    assert contributions.loc["X-Z.ey", "dx"] == pytest.approx(
        100 * (100 * s_ang) ** 2 / var_dx, rel=1e-12)
    assert contributions.loc["Z-A.ey", "dx"] == 0.0  # after Z's travel: no lever arm


def test_contributions_sum_to_100(table4, hobbing):
    c = table4.contributions
    assert list(c.index) == list(hobbing.error_names) and list(c.columns) == list(OUTPUTS)
    np.testing.assert_allclose(c.sum(axis=0), 100.0, rtol=1e-12)
    assert (c.to_numpy() >= 0).all()


# ----- probabilities ------------------------------------------------------------------------
def test_one_and_two_sided_at_zero_mean(table4):
    beta = table4.beta
    np.testing.assert_allclose(table4.one_sided, norm.cdf(beta), rtol=1e-14)
    np.testing.assert_allclose(table4.two_sided, 2 * norm.cdf(beta) - 1, rtol=0, atol=1e-14)
    np.testing.assert_array_equal(table4.mean, 0.0)
    np.testing.assert_allclose(beta, table4.limits / table4.sigma, rtol=1e-15)


def test_scalar_probability_functions():
    assert reliability_index(0.02, 0.01) == 2.0
    assert reliability_index(0.02, 0.01, mean=-0.005) == pytest.approx(1.5)
    assert one_sided_probability(0.02, 0.01) == pytest.approx(norm.cdf(2.0), rel=1e-15)
    assert two_sided_probability(0.02, 0.01) == pytest.approx(2 * norm.cdf(2) - 1, rel=1e-15)
    # β = 2.326 gives 99 % one-sided but 98 % two-sided (the fosm module's remark).
    beta99 = required_index(0.99, "one_sided")
    assert beta99 == pytest.approx(2.3263478740, rel=1e-9)
    assert two_sided_probability(beta99, 1.0) == pytest.approx(0.98, rel=1e-12)
    assert required_index(0.99, "two_sided") == pytest.approx(norm.ppf(0.995), rel=1e-15)
    assert required_index(0.99) == required_index(0.99, "two_sided")


def test_nonzero_mean(hobbing):
    means = hobbing.error_vector({"X.dx": 0.005, "C.ez": 1e-5})
    result = fosm(hobbing, hobbing.initial_allocation, Q0, means=means)
    # Exact model at the means (Eq. 20): at Q0 all rotations are I, X.dx passes through,
    # C.ez with the tool at (0, 0, 100) adds ε×p = 0 to δ and 1e-5 to εz, and the exact
    # product adds the second-order [ε_C]×δ_X = 1e-5 ẑ × 0.005 x̂ = 5e-8 ŷ.
    np.testing.assert_allclose(result.mean[0], [0.005, 5e-8, 0, 0, 0, 1e-5],
                               rtol=1e-12, atol=1e-20)
    mu, sigma, limit = result.mean[0], result.sigma[0], hobbing.limits
    np.testing.assert_allclose(
        result.two_sided[0],
        norm.cdf((limit - mu) / sigma) - norm.cdf((-limit - mu) / sigma), rtol=1e-14)
    np.testing.assert_allclose(result.one_sided[0], norm.cdf((limit - np.abs(mu)) / sigma),
                               rtol=1e-14)
    assert result.two_sided[0, 0] < 2 * norm.cdf(limit[0] / sigma[0]) - 1  # a mean costs
    # The sign of the mean does not matter.
    flipped = fosm(hobbing, hobbing.initial_allocation, Q0, means=-means)
    np.testing.assert_allclose(flipped.two_sided, result.two_sided, rtol=1e-14)
    np.testing.assert_allclose(flipped.sigma, result.sigma, rtol=0)


def test_fosm_against_monte_carlo_of_linear_model(hobbing, table4, grid_jacobian):
    """P(|J x| < I) by simulation at each output's worst pose versus FOSM.

    The linear model with normal errors has a normal output, so the two-sided FOSM is
    exact for it; the simulated fraction is binomial with SE = √(P(1−P)/n). Accept within
    z = 4 SE (n = 200 000, fixed seed). With tolerances scaled so the worst β is 2 for the
    output under test, the one-sided Φ(2) = 0.977 exceeds the true 0.954 by 0.023, about
    50 SE: it must fall outside the band.
    """
    rows = np.arange(6)
    jac_worst = grid_jacobian[table4.worst_pose, rows]  # (6, 66): each output's worst pose
    sigma_x = hobbing.initial_allocation / 3
    rng = np.random.default_rng(20230217)
    n, chunk = 200_000, 50_000
    y = np.concatenate([(rng.standard_normal((chunk, 66)) * sigma_x) @ jac_worst.T
                        for _ in range(n // chunk)])
    z = 4.0
    # (a) the Table 4 allocation itself
    inside = (np.abs(y) < hobbing.limits).mean(axis=0)
    p_two = table4.two_sided[table4.worst_pose, rows]
    se = np.sqrt(p_two * (1 - p_two) / n)
    assert np.all(np.abs(inside - p_two) < z * se), (inside, p_two, se)
    # (b) tolerances scaled by c_o so that output o's worst β is 2 (σ scales with c_o)
    beta_worst = table4.beta[table4.worst_pose, rows]
    scale = beta_worst / 2.0
    inside = (np.abs(y * scale) < hobbing.limits).mean(axis=0)
    for o in range(6):
        scaled = fosm(hobbing, hobbing.initial_allocation * scale[o],
                      table4.poses[table4.worst_pose[o]])
        assert scaled.beta[0, o] == pytest.approx(2.0, rel=1e-12)
        two, one = scaled.two_sided[0, o], scaled.one_sided[0, o]
        se = math.sqrt(two * (1 - two) / n)
        assert abs(inside[o] - two) < z * se, (OUTPUTS[o], inside[o], two, se)
        assert abs(inside[o] - one) > z * se, (OUTPUTS[o], inside[o], one, se)


# ----- σ from tolerance ------------------------------------------------------------------
def test_truncated_sigma(hobbing):
    ratio = truncnorm(-3, 3).std()
    assert ratio == pytest.approx(0.986578, abs=1e-6)  # the brief's 0.98657, truncated
    t = hobbing.initial_allocation
    np.testing.assert_allclose(error_sigma(t, 3, "truncated"), t / 3 * ratio, rtol=1e-12)
    np.testing.assert_allclose(error_sigma(t, 2.5, "truncated"),
                               t / 2.5 * truncnorm(-2.5, 2.5).std(), rtol=1e-12)
    normal = fosm(hobbing, t, Q0)
    truncated = fosm(hobbing, t, Q0, distribution="truncated")
    # Every σ_i scales by the same factor, so every output σ does too.
    np.testing.assert_allclose(truncated.sigma / normal.sigma, ratio, rtol=1e-12)


def test_coverage_factor(hobbing):
    t = hobbing.initial_allocation
    np.testing.assert_array_equal(error_sigma(t, 2.0), t / 2)
    a, b = fosm(hobbing, t, Q0, k=3.0), fosm(hobbing, t, Q0, k=6.0)
    np.testing.assert_allclose(b.sigma, a.sigma / 2, rtol=1e-14)
    np.testing.assert_allclose(b.beta, 2 * a.beta, rtol=1e-14)


# ----- worst pose, verdicts, frame ----------------------------------------------------------
def test_worst_pose_minimises_two_sided(table4):
    rows = np.arange(6)
    at_worst = table4.two_sided[table4.worst_pose, rows]
    np.testing.assert_array_equal(at_worst, table4.two_sided.min(axis=0))
    np.testing.assert_array_equal(table4.worst("two_sided"), at_worst)
    np.testing.assert_array_equal(table4.worst("one_sided"), table4.one_sided.min(axis=0))
    # δx is worst where every lever arm is longest: X = 400, Z = 500, A = ±π/4, Y = 200.
    q = table4.poses[table4.worst_pose[0]]
    assert (q[1], q[2], q[4]) == (400.0, 500.0, 200.0)
    assert q[3] == pytest.approx(math.pi / 4)  # +π/4 puts Y's travel along +z: longest lever
    assert table4.poses.shape == (15625, 6) and table4.sigma.shape == (15625, 6)


def test_meets_targets_and_frame(table4):
    np.testing.assert_array_equal(table4.meets_targets("one_sided"), [True] * 6)
    np.testing.assert_array_equal(table4.meets_targets("two_sided"),
                                  [False, True, False, True, True, True])
    np.testing.assert_array_equal(table4.meets_targets("two_sided", workspace="mean"),
                                  [True] * 6)
    np.testing.assert_allclose(table4.workspace_mean("one_sided"),
                               table4.one_sided.mean(axis=0), rtol=1e-15)
    frame = table4.to_frame()
    assert list(frame.index) == list(OUTPUTS)
    np.testing.assert_array_equal(frame["beta"], table4.beta[table4.worst_pose, np.arange(6)])
    np.testing.assert_array_equal(frame["meets_two_sided"],
                                  [False, True, False, True, True, True])
    assert isinstance(table4, FosmResult)


def test_paper_initial_allocation_meets_one_sided_target_only(table4):
    """Table 4 meets the paper's 99 % (one-sided, Eq. 22) at every grid pose.

    The worst δx has β = 2.3347 ≥ Φ⁻¹(0.99) = 2.3263, so Φ(β) = 0.9902; its exact two-sided
    probability is 2Φ(β) − 1 = 0.9804 < 0.99.
    """
    assert np.all(table4.worst("one_sided") >= 0.99)
    assert table4.worst("two_sided")[0] < 0.99
    beta_dx = table4.beta[:, 0].min()
    assert 2.3263 <= beta_dx <= 2.345
    assert beta_dx == pytest.approx(2.334657, abs=5e-6)  # regression value of this model
    # εx, εy, εz: σ = √11·t/3 at every pose (rotations keep row norms), β = 2.9943.
    np.testing.assert_allclose(table4.beta[:, 3:],
                               4.8e-5 / (math.sqrt(11) * T_ANG / 3), rtol=1e-12)


# ----- refusals -----------------------------------------------------------------------------
def test_refusals(hobbing, table4):
    t = hobbing.initial_allocation
    with pytest.raises(ValueError, match="unknown side"):
        table4.worst("both")
    with pytest.raises(ValueError, match="unknown side"):
        table4.meets_targets("upper")
    with pytest.raises(ValueError, match="unknown side"):
        required_index(0.99, "left")
    with pytest.raises(ValueError, match="workspace"):
        table4.meets_targets("two_sided", workspace="median")
    for k in (0.0, -3.0, np.nan, np.inf):
        with pytest.raises(ValueError, match="coverage factor"):
            fosm(hobbing, t, Q0, k=k)
    with pytest.raises(ValueError, match="unknown distribution"):
        fosm(hobbing, t, Q0, distribution="uniform")
    with pytest.raises(ValueError, match="jacobian must have shape"):
        fosm(hobbing, t, np.vstack([Q0, Q0]), jacobian=hobbing.jacobian(Q0[None]))
    with pytest.raises(ValueError, match="jacobian must have shape"):
        fosm(hobbing, t, Q0, jacobian=np.zeros((1, 6, 65)))
    bad = t.copy()
    bad[hobbing.error_index("M.ey")] = -1e-5
    with pytest.raises(ValueError, match="M.ey"):
        fosm(hobbing, bad, Q0)
    with pytest.raises(ValueError, match="66"):
        fosm(hobbing, t[:-1], Q0)
    with pytest.raises(ValueError, match="one allocation"):
        fosm(hobbing, np.vstack([t, t]), Q0)
    for target in (0.0, 1.0, 1.2, -0.5):
        with pytest.raises(ValueError, match=r"\(0, 1\)"):
            required_index(target)
    with pytest.raises(ValueError, match="positions"):
        fosm(hobbing, t, Q0[:5])


def test_poses_with_more_than_two_dimensions_refused_clearly(hobbing):
    # FosmResult is defined for (n_poses, n_axes); a (5, 3125, 6) batch currently fails
    # deep inside pandas ("Must pass 2-d input") instead of naming the poses' shape
    # (wrong shapes get a clear exception).
    poses = workspace_grid(hobbing).reshape(5, 3125, 6)
    with pytest.raises(ValueError, match=r"poses.*\(5, 3125, 6\)"):
        fosm(hobbing, hobbing.initial_allocation, poses)
