"""Tests of :func:`reliability.sampling.fosm_comparison.fosm_versus_monte_carlo`."""

from __future__ import annotations

import numpy as np
import pytest

import reliability
from reliability import OUTPUTS
from reliability.first_order.fosm import fosm
from reliability.sampling.experiment_results import GridExperimentResult
from reliability.sampling.fosm_comparison import fosm_versus_monte_carlo
from reliability.sampling.grid_experiment import GridExperiment

COLUMNS = ["output", "limit", "fosm_worst_one_sided", "fosm_worst_two_sided",
           "fosm_one_sided", "fosm_two_sided", "mc_estimate", "mc_lower", "mc_upper",
           "mc_min", "mc_max", "two_sided_within"]


@pytest.fixture(scope="module")
def setting():
    m = reliability.hobbing_machine()
    g = GridExperiment(m, 3)
    t = 2 * m.initial_allocation
    return m, fosm(m, t, g.poses, distribution="truncated"), g.run(t, repeats=30, rng=3)


def test_columns_and_values(setting):
    m, f, grid = setting
    frame = fosm_versus_monte_carlo(f, grid)
    assert list(frame.columns) == COLUMNS
    assert list(frame["output"]) == list(OUTPUTS)
    np.testing.assert_array_equal(frame["limit"], m.limits)
    np.testing.assert_array_equal(frame["fosm_two_sided"], f.workspace_mean("two_sided"))
    np.testing.assert_array_equal(frame["fosm_one_sided"], f.workspace_mean("one_sided"))
    np.testing.assert_array_equal(frame["fosm_worst_two_sided"], f.two_sided.min(axis=0))
    np.testing.assert_array_equal(frame["fosm_worst_one_sided"], f.one_sided.min(axis=0))
    fractions = grid.inside / grid.n_poses
    np.testing.assert_allclose(frame["mc_estimate"], fractions.mean(axis=0), rtol=1e-14)
    np.testing.assert_array_equal(frame["mc_min"], fractions.min(axis=0))
    np.testing.assert_array_equal(frame["mc_max"], fractions.max(axis=0))
    interval = grid.reliability()
    np.testing.assert_array_equal(frame["mc_lower"], interval.lower)
    np.testing.assert_array_equal(frame["mc_upper"], interval.upper)
    within = (frame["mc_lower"] <= frame["fosm_two_sided"]) & \
             (frame["fosm_two_sided"] <= frame["mc_upper"])
    np.testing.assert_array_equal(frame["two_sided_within"], within)
    assert frame["two_sided_within"].dtype == bool
    # The one-sided mean is above the two-sided one: 1 − P halves.
    np.testing.assert_allclose(1 - frame["fosm_one_sided"], (1 - frame["fosm_two_sided"]) / 2,
                               rtol=1e-9)


def test_confidence_widens_the_interval(setting):
    _, f, grid = setting
    narrow = fosm_versus_monte_carlo(f, grid, confidence=0.8)
    wide = fosm_versus_monte_carlo(f, grid, confidence=0.99)
    assert np.all(wide["mc_upper"] - wide["mc_lower"] > narrow["mc_upper"] - narrow["mc_lower"])


def test_within_flag_on_a_hand_built_result(setting):
    """Two experiments with fractions 0.9 and 1.0: p = 0.95, se = 0.05, n_eff = 19."""
    m, f, _ = setting
    inside = np.vstack([np.full(6, 0.9 * 729), np.full(6, 729)]).round().astype(int)
    grid = GridExperimentResult(limits=m.limits, inside=inside, n_poses=729)
    frame = fosm_versus_monte_carlo(f, grid)
    fraction = inside / 729
    p = fraction.mean(axis=0)
    n_eff = p * (1 - p) / (fraction.std(axis=0, ddof=1) / np.sqrt(2)) ** 2
    np.testing.assert_allclose(n_eff, 19.0, rtol=2e-3)  # 0.9 * 729 rounds to 656
    z = 1.959963984540054
    centre = (p + z**2 / (2 * n_eff)) / (1 + z**2 / n_eff)
    half = z / (1 + z**2 / n_eff) * np.sqrt(p * (1 - p) / n_eff + z**2 / (4 * n_eff**2))
    np.testing.assert_allclose(frame["mc_lower"], centre - half, rtol=1e-12)
    np.testing.assert_allclose(frame["mc_upper"], centre + half, rtol=1e-12)
    assert frame["two_sided_within"].all()
    assert "Wilson" in frame.attrs["mc_interval"]
    tight = GridExperimentResult(limits=m.limits, inside=np.full((2, 6), 729), n_poses=729)
    assert not fosm_versus_monte_carlo(f, tight)["two_sided_within"].any()


@pytest.mark.parametrize("scale", [0.5, 0.7])
def test_fosm_and_monte_carlo_both_at_one_agree(setting, scale):
    """Every pose inside in every experiment, FOSM at 1 − 1e-9: within, not 'not within'.

    The interval keeps the width of the 2 × 729 poses evaluated, [N / (N + z²), 1]."""
    m, _, _ = setting
    f = fosm(m, scale * m.initial_allocation, GridExperiment(m, 3).poses,
             distribution="truncated")
    assert np.all(f.workspace_mean("two_sided") > 1 - 1e-4)
    everything = GridExperimentResult(limits=m.limits, inside=np.full((2, 6), 729),
                                      n_poses=729)
    frame = fosm_versus_monte_carlo(f, everything)
    assert frame["two_sided_within"].all()
    np.testing.assert_allclose(frame["mc_lower"], 1458 / (1458 + 1.959963984540054**2),
                               rtol=1e-12)
    np.testing.assert_array_equal(frame["mc_upper"], 1.0)


def test_pose_count_mismatch_is_refused(setting):
    _, f, _ = setting
    other = GridExperimentResult(limits=f.limits, inside=np.full((3, 6), 15_000),
                                 n_poses=15_625)
    with pytest.raises(ValueError, match="729.*15625"):
        fosm_versus_monte_carlo(f, other)
