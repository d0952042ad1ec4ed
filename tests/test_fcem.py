"""Tests of the fuzzy comprehensive evaluation (Eqs. 29-30, example Eqs. 36-39)."""

import numpy as np
import pytest

from allocation.cost.fuzzy_evaluation import FcemResult, fcem_coefficient

A_PAPER = [0.4, 0.2, 0.1, 0.3]  # Eq. (36)
R_PAPER = [  # Eq. (37)
    [0, 0, 0.2, 0.2, 0.6],
    [0, 0, 0.2, 0.4, 0.4],
    [0, 0, 0.6, 0.4, 0],
    [0, 0.2, 0.2, 0.4, 0.2],
]


def test_paper_example_gives_b_of_eq38_and_a_of_eq39():
    result = fcem_coefficient(A_PAPER, R_PAPER)
    assert isinstance(result, FcemResult)
    np.testing.assert_allclose(result.b, [0, 0.06, 0.24, 0.32, 0.38], atol=1e-15)
    assert result.value == pytest.approx(1.98, abs=1e-14)


def test_custom_scores_and_frame():
    result = fcem_coefficient([1.0], [[0.5, 0.5]], scores=[10, 2])
    assert result.value == pytest.approx(6.0)
    frame = result.to_frame()
    assert list(frame.index) == [1, 2]
    assert list(frame.columns) == ["membership", "score"]
    assert frame["membership"].sum() == pytest.approx(1.0)


def test_result_is_frozen():
    result = fcem_coefficient(A_PAPER, R_PAPER)
    with pytest.raises(AttributeError):
        result.value = 2.0
    with pytest.raises(ValueError):
        result.b[0] = 1.0


@pytest.mark.parametrize(
    "weights, match",
    [
        ([[0.5, 0.5]], r"weights must be a non-empty 1-D vector, got shape \(1, 2\)"),
        ([], r"weights must be a non-empty 1-D vector"),
        ([0.5, -0.1, 0.6], r"weights\[1\] = -0.1 must be finite and non-negative"),
        ([0.5, np.nan, 0.5], r"weights\[1\] = nan must be finite"),
        ([0.4, 0.4], r"weights must sum to 1, they sum to 0.8"),
    ],
)
def test_bad_weights_are_refused(weights, match):
    membership = np.full((np.size(weights), 5), 0.2)
    with pytest.raises(ValueError, match=match):
        fcem_coefficient(weights, membership)


def test_weights_within_tolerance_are_accepted():
    result = fcem_coefficient([0.5, 0.5 + 5e-10], np.full((2, 5), 0.2))
    assert result.value == pytest.approx(3.0)


def test_membership_of_wrong_shape_is_refused():
    with pytest.raises(
        ValueError, match=r"shape \(len\(weights\), len\(scores\)\) = \(4, 5\), got \(4, 4\)"
    ):
        fcem_coefficient(A_PAPER, np.full((4, 4), 0.25))


def test_negative_or_non_finite_membership_is_refused():
    bad = np.array(R_PAPER, dtype=float)
    bad[2, 3] = -0.4
    bad[2, 4] = 0.4 + 0.4
    with pytest.raises(
        ValueError, match=r"membership\[2, 3\] = -0.4 must be finite and non-negative"
    ):
        fcem_coefficient(A_PAPER, bad)
    bad[2, 3] = np.inf
    with pytest.raises(ValueError, match=r"membership\[2, 3\] = inf"):
        fcem_coefficient(A_PAPER, bad)


def test_membership_row_not_summing_to_one_names_the_row():
    bad = np.array(R_PAPER, dtype=float)
    bad[3, 0] = 0.1
    with pytest.raises(ValueError, match=r"membership row 3 must sum to 1, it sums to 1.1"):
        fcem_coefficient(A_PAPER, bad)


@pytest.mark.parametrize(
    "scores, match",
    [
        ([5, 4, np.nan, 2, 1], r"scores\[2\] = nan is not finite"),
        ([[5, 4, 3, 2, 1]], r"scores must be a non-empty 1-D vector, got shape \(1, 5\)"),
    ],
)
def test_bad_scores_are_refused(scores, match):
    with pytest.raises(ValueError, match=match):
        fcem_coefficient(A_PAPER, R_PAPER, scores=scores)
