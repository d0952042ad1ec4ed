"""Measured error profiles (reliability.model.measured_profiles): reading, checks, FOSM and
Monte-Carlo means."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy.stats import norm

from reliability.basics.errors import InputError, InputTypeError
from reliability.first_order.fosm import fosm
from reliability.model.measured_profiles import (MeasuredProfile, SystematicErrors,
                                                 measured_profile, read_profile_csv)
from reliability.model.poses import grid_axis_points, workspace_grid
from reliability.sampling.grid_experiment import GridExperiment

EXAMPLE = Path(__file__).resolve().parent.parent / "docs" / "examples" / \
    "x_vertical_straightness.csv"


def _write(tmp_path, text, name="profile.csv"):
    path = tmp_path / name
    path.write_text(text)
    return path


# ----- reading and checks ----------------------------------------------------------------
def test_example_file_reads_and_interpolates(hobbing):
    profile = read_profile_csv(EXAMPLE, hobbing, "X.dz")
    assert profile.axis == 1 and profile.component == 2
    assert profile.positions[0] == 0.0 and profile.positions[-1] == 400.0
    assert np.abs(profile.values).max() < 0.005  # a few µm
    # linear interpolation halfway between two measured points
    middle = 0.5 * (profile.values[3] + profile.values[4])
    assert profile(87.5) == pytest.approx(middle, rel=1e-12)


def test_csv_with_comments_and_spaces(tmp_path, mill3):
    path = _write(tmp_path, "# a comment\nposition, value\n-300, 0.001\n0, 0.002\n300, 0.0\n")
    profile = read_profile_csv(path, mill3, "X.dy")
    assert profile(-150.0) == pytest.approx(0.0015)


@pytest.mark.parametrize("text, match", [
    ("pos,value\n0,1\n400,1\n", "columns must be exactly position,value"),
    ("position,value,extra\n0,1,2\n400,1,2\n", "columns"),
    ("position,value\n0,a\n400,1\n", "'value' must hold numbers"),
    ("position,value\n", "at least 2 rows"),
    ("position,value\n0,1\n", "at least 2 rows"),
])
def test_bad_files_are_refused(tmp_path, mill3, text, match):
    with pytest.raises(InputError, match=match):
        read_profile_csv(_write(tmp_path, text), mill3, "Y.dx")


def test_missing_file_is_refused(tmp_path, mill3):
    with pytest.raises(InputError, match="cannot read"):
        read_profile_csv(tmp_path / "absent.csv", mill3, "Y.dx")


def test_unsorted_positions_are_refused_unless_sort(mill3):
    positions, values = [0.0, 400.0, 200.0], [0.0, 2.0, 1.0]
    with pytest.raises(InputError, match=r"row 2 \(200\) is smaller"):
        measured_profile(mill3, "Y.dx", positions, values)
    profile = measured_profile(mill3, "Y.dx", positions, values, sort=True)
    assert profile.positions.tolist() == [0.0, 200.0, 400.0]
    assert profile.values.tolist() == [0.0, 1.0, 2.0]


def test_repeated_positions_and_non_finite_values_are_refused(mill3):
    with pytest.raises(InputError, match="repeats"):
        measured_profile(mill3, "Y.dx", [0.0, 200.0, 200.0, 400.0], [0, 1, 1, 0])
    with pytest.raises(InputError, match=r"values\[1\]"):
        measured_profile(mill3, "Y.dx", [0.0, 200.0, 400.0], [0, np.nan, 0])


def test_error_names_must_be_motion_errors(mill3):
    with pytest.raises(InputError, match="'Y-X.dx' is not a motion error"):
        measured_profile(mill3, "Y-X.dx", [0, 400], [0, 0])
    with pytest.raises(InputError, match="'Y.qq'"):
        measured_profile(mill3, "Y.qq", [0, 400], [0, 0])
    with pytest.raises(InputTypeError):
        measured_profile(mill3, 3, [0, 400], [0, 0])


def test_coverage_policy(mill3):
    with pytest.raises(InputError, match=r"covers \[50, 400\] but axis 'Y' travels \[0, 400\]"):
        measured_profile(mill3, "Y.dx", [50.0, 400.0], [1.0, 2.0])
    held = measured_profile(mill3, "Y.dx", [50.0, 400.0], [1.0, 2.0], outside="hold")
    assert held(0.0) == 1.0 and held(400.0) == 2.0
    covered = measured_profile(mill3, "Y.dx", [0.0, 400.0], [1.0, 2.0])
    with pytest.raises(InputError, match="outside the measured range"):
        covered(410.0)
    with pytest.raises(InputError, match="outside must be"):
        measured_profile(mill3, "Y.dx", [0.0, 400.0], [1.0, 2.0], outside="extend")


def test_full_turn_axis_interpolates_periodically(hobbing):
    positions = np.array([0.0, 0.5 * math.pi, math.pi, 1.5 * math.pi])
    profile = measured_profile(hobbing, "C.ez", positions, [1.0, 2.0, 3.0, 4.0])
    assert profile.periodic
    # between 1.5π (4) and 2π ≡ 0 (1): halfway is 2.5
    assert profile(1.75 * math.pi) == pytest.approx(2.5)
    assert profile(2 * math.pi) == pytest.approx(1.0)
    with pytest.raises(InputError, match=r"must lie in \[0, 2π\)"):
        measured_profile(hobbing, "C.ez", [0.0, 2 * math.pi], [1.0, 1.0])


def test_systematic_errors_checks(mill3, hobbing):
    a = measured_profile(mill3, "Y.dx", [0.0, 400.0], [1.0, 2.0])
    with pytest.raises(InputError, match="more than one measured profile"):
        SystematicErrors(mill3, (a, a))
    with pytest.raises(InputTypeError):
        SystematicErrors(mill3, ("Y.dx",))
    other = measured_profile(hobbing, "X.dz", [0.0, 400.0], [1.0, 2.0])
    with pytest.raises(InputError, match="another machine"):
        SystematicErrors(mill3, (other,))


def test_means_and_grid_means_agree(mill3):
    profile = measured_profile(mill3, "X.dz", [-300.0, 0.0, 300.0], [0.002, -0.001, 0.003])
    systematic = SystematicErrors(mill3, (profile,))
    poses = workspace_grid(mill3, 3)
    means = systematic.means(poses)
    column = mill3.error_index("X.dz")
    assert np.count_nonzero(means[:, np.arange(mill3.n_errors) != column]) == 0
    assert np.allclose(means[:, column], np.interp(poses[:, 1], profile.positions,
                                                   profile.values))
    grid = systematic.at_grid(grid_axis_points(mill3, 3))
    assert grid.shape == (3, 3, 6)
    assert grid[1, :, 2].tolist() == [0.002, -0.001, 0.003]
    assert np.count_nonzero(grid) == 3
    frame = systematic.to_frame()
    assert frame.columns.tolist() == ["error", "position", "value"] and len(frame) == 3


# ----- FOSM with means -------------------------------------------------------------------
def test_fosm_with_measured_means_matches_the_closed_form(mill3):
    """Translational means only: the output mean is exactly J μ_x, and
    P(|y| ≤ I) = Φ((I − μ)/σ) − Φ((−I − μ)/σ)."""
    systematic = SystematicErrors(mill3, (
        measured_profile(mill3, "X.dy", [-300.0, 300.0], [-0.004, 0.006]),
        measured_profile(mill3, "Z.dx", [-350.0, 0.0], [0.003, 0.0]),
    ))
    poses = workspace_grid(mill3, 4)
    t = mill3.initial_allocation
    result = fosm(mill3, t, poses, means=systematic.means(poses))
    jacobian = mill3.jacobian(poses)
    mu = np.einsum("poe,pe->po", jacobian, systematic.means(poses))
    sigma = np.sqrt(np.einsum("poe,e->po", jacobian ** 2, (t / 3.0) ** 2))
    limit = mill3.limits
    expected = norm.cdf((limit - mu) / sigma) - norm.cdf((-limit - mu) / sigma)
    assert np.allclose(result.mean, mu, rtol=1e-9, atol=1e-15)
    assert np.allclose(result.two_sided, expected, rtol=1e-9, atol=1e-15)
    assert np.any(np.abs(mu) > 1e-3)  # the means do shift the outputs
    zero = fosm(mill3, t, poses)
    assert np.all(result.worst("two_sided")[:2] < zero.worst("two_sided")[:2])  # dx, dy


def test_monte_carlo_with_means_agrees_with_fosm_with_means(mill3):
    systematic = SystematicErrors(mill3, (
        measured_profile(mill3, "X.dy", [-300.0, 300.0], [-0.006, 0.006]),
        measured_profile(mill3, "Y.dz", [0.0, 200.0, 400.0], [0.004, -0.004, 0.004]),
    ))
    t = mill3.initial_allocation * 1.5
    poses = workspace_grid(mill3, 3)
    prediction = fosm(mill3, t, poses, means=systematic.means(poses)).workspace_mean()
    result = GridExperiment(mill3, 3, systematic=systematic).run(
        t, repeats=4000, rng=21, distribution="normal", keep_values="none").reliability()
    # z = 4 on the between-experiment SE (the model is linear to ~1e-7 at these errors)
    assert np.all(np.abs(result.estimate - prediction) < 4.0 * result.standard_error + 1e-6)
    plain = GridExperiment(mill3, 3).run(t, repeats=4000, rng=21, distribution="normal",
                                         keep_values="none").reliability()
    assert np.all(result.estimate[:3] < plain.estimate[:3])  # the means cost reliability


def test_profile_object_is_frozen(mill3):
    profile = measured_profile(mill3, "Y.dx", [0.0, 400.0], [1.0, 2.0])
    assert isinstance(profile, MeasuredProfile)
    with pytest.raises(AttributeError):
        profile.error = "X.dx"


def test_grid_experiment_refuses_foreign_or_wrong_systematic(mill3, hobbing):
    other = SystematicErrors(hobbing, (measured_profile(hobbing, "X.dz", [0.0, 400.0],
                                                        [0.0, 0.001]),))
    with pytest.raises(InputError, match="other axes"):
        GridExperiment(mill3, 3, systematic=other)
    with pytest.raises(InputTypeError, match="systematic"):
        GridExperiment(mill3, 3, systematic={"X.dz": 0.001})
