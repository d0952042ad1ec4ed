"""Tests of the Monte-Carlo result objects, :mod:`reliability.sampling.experiment_results` (Tables
8 and 9).

Everything is checked on small results built by hand, whose Table 8/9 entries, intervals
and yields are computed here independently (``statistics.mean``, ``scipy.stats.t``,
``scipy.stats.binomtest``, the Wilson formula written out).
"""

from __future__ import annotations

import math
import statistics

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from reliability import OUTPUTS
from reliability.sampling.experiment_results import (FRAME_COLUMNS, METADATA_COLUMNS,
                                                     GridExperimentResult, RandomPoseResult)

LIMITS = np.array([0.02, 0.02, 0.02, 4.8e-5, 4.8e-5, 4.8e-5])
# Four experiments of 100 poses; every column varies, experiment 3 is entirely inside.
INSIDE = np.array([[100, 99, 98, 100, 97, 100],
                   [95, 100, 100, 99, 100, 100],
                   [100, 100, 100, 100, 100, 100],
                   [90, 100, 99, 100, 96, 98]])
N_POSES = 100


@pytest.fixture
def result():
    return GridExperimentResult(limits=LIMITS.copy(), inside=INSIDE.copy(), n_poses=N_POSES,
                                distribution="normal", k=2.5, points=3)


def test_fractions_and_all_inside(result):
    assert result.repeats == 4
    np.testing.assert_array_equal(result.fractions, INSIDE / 100)
    np.testing.assert_array_equal(result.all_inside, [False, False, True, False])


def test_table8(result):
    table = result.table8(3)
    assert list(table.index) == list(OUTPUTS) and table.index.name == "output"
    assert list(table.columns) == ["limit", "inside", "outside", "fraction"]
    np.testing.assert_array_equal(table["limit"], LIMITS)
    np.testing.assert_array_equal(table["inside"], [90, 100, 99, 100, 96, 98])
    np.testing.assert_array_equal(table["outside"], [10, 0, 1, 0, 4, 2])
    np.testing.assert_allclose(table["fraction"], [0.90, 1.0, 0.99, 1.0, 0.96, 0.98],
                               rtol=1e-15)
    np.testing.assert_array_equal(result.table8()["inside"], INSIDE[0])
    for bad in (4, -1):
        with pytest.raises(IndexError, match=str(bad)):
            result.table8(bad)


def test_table9_rows_and_summary(result):
    table = result.table9()
    assert list(table.index) == [1, 2, 3, 4, "Avg", "Min", "Max"]
    assert list(table.columns) == list(OUTPUTS)
    np.testing.assert_allclose(table.loc[[1, 2, 3, 4]].to_numpy(), INSIDE / 100, rtol=1e-15)
    for j, output in enumerate(OUTPUTS):
        column = [row[j] / 100 for row in INSIDE.tolist()]
        assert table.loc["Avg", output] == pytest.approx(statistics.mean(column), rel=1e-14)
        assert table.loc["Min", output] == min(column)
        assert table.loc["Max", output] == max(column)
    # A few entries spelled out: dx 0.9625 on average, min 0.90; ey min 0.96.
    assert table.loc["Avg", "dx"] == pytest.approx(0.9625, rel=1e-14)
    assert table.loc["Min", "dx"] == 0.90 and table.loc["Min", "ey"] == 0.96


def test_all_inside_share_is_clopper_pearson_over_experiments(result):
    estimate = result.all_inside_share()
    exact = stats.binomtest(1, 4).proportion_ci(confidence_level=0.95, method="exact")
    assert estimate.estimate == 0.25 and estimate.n == 4
    assert estimate.method == "clopper-pearson"
    assert estimate.lower == pytest.approx(exact.low, rel=1e-10)
    assert estimate.upper == pytest.approx(exact.high, rel=1e-10)
    narrower = result.all_inside_share(0.8)
    assert narrower.lower > estimate.lower and narrower.upper < estimate.upper


def test_reliability_is_wilson_on_the_kish_effective_size(result):
    estimate = result.reliability()
    assert estimate.n == 4 and estimate.method == "wilson-kish" and estimate.names == OUTPUTS
    z = stats.norm.ppf(0.975)
    for j in range(6):
        column = INSIDE[:, j] / 100
        mean, se = column.mean(), statistics.stdev(column.tolist()) / 2.0
        n_eff = min(mean * (1 - mean) / se**2, 4 * N_POSES) if se > 0 else 4 * N_POSES
        assert estimate.estimate[j] == pytest.approx(mean, rel=1e-14)
        assert estimate.standard_error[j] == pytest.approx(se, rel=1e-12)
        assert estimate.effective_n[j] == pytest.approx(n_eff, rel=1e-12)
        for bound in (estimate.lower[j], estimate.upper[j]):
            if bound < 1.0:
                assert (mean - bound) ** 2 == pytest.approx(
                    z**2 * bound * (1 - bound) / n_eff, rel=1e-9)
        assert estimate.minimum[j] == column.min() and estimate.maximum[j] == column.max()
    assert np.all((0 <= estimate.lower) & (estimate.upper <= 1))
    wide = result.reliability(0.99)
    assert np.all(wide.upper - wide.lower > estimate.upper - estimate.lower)


def test_reliability_needs_two_experiments():
    single = GridExperimentResult(limits=LIMITS, inside=INSIDE[:1], n_poses=N_POSES)
    with pytest.raises(ValueError, match="2 experiments"):
        single.reliability()


def test_to_frame(result):
    frame = result.to_frame()
    assert tuple(frame.columns) == FRAME_COLUMNS + METADATA_COLUMNS
    assert len(frame) == 4 * 6
    assert set(frame["distribution"]) == {"normal"} and set(frame["k"]) == {2.5}
    assert set(frame["points"]) == {3}
    np.testing.assert_array_equal(frame["repeat"], np.repeat([1, 2, 3, 4], 6))
    assert list(frame["output"]) == list(OUTPUTS) * 4
    np.testing.assert_array_equal(frame["limit"], np.tile(LIMITS, 4))
    np.testing.assert_array_equal(frame["inside"], INSIDE.ravel())
    np.testing.assert_array_equal(frame["outside"], 100 - INSIDE.ravel())
    np.testing.assert_allclose(frame["fraction"], INSIDE.ravel() / 100, rtol=1e-15)
    row = frame[(frame["repeat"] == 4) & (frame["output"] == "ey")]
    assert row["inside"].item() == 96 and row["outside"].item() == 4


def _same(a, b):
    np.testing.assert_array_equal(a.inside, b.inside)
    np.testing.assert_array_equal(a.limits, b.limits)
    assert a.n_poses == b.n_poses
    assert a.inside.dtype.kind == "i"


def test_from_frame_round_trip_in_any_row_order(result):
    frame = result.to_frame()
    back = GridExperimentResult.from_frame(frame)  # how it was drawn travels with it
    _same(back, result)
    assert (back.distribution, back.k, back.points) == ("normal", 2.5, 3)
    assert back.values is None
    shuffled = frame.sample(frac=1.0, random_state=0).reset_index(drop=True)
    _same(GridExperimentResult.from_frame(shuffled), result)


def test_save_and_load_round_trip(result, tmp_path):
    path = tmp_path / "table9.csv"
    written = result.save(path)
    assert written == path and path.exists()
    back = GridExperimentResult.load(path)
    _same(back, result)
    assert (back.distribution, back.k, back.points) == ("normal", 2.5, 3)
    pd.testing.assert_frame_equal(pd.read_csv(path), result.to_frame(), check_dtype=False)


def test_save_refuses_to_overwrite(result, tmp_path):
    path = tmp_path / "table9.csv"
    result.save(path)
    before = path.read_text()
    other = GridExperimentResult(limits=LIMITS, inside=np.full((2, 6), 7), n_poses=N_POSES)
    with pytest.raises(FileExistsError, match="overwrite"):
        other.save(path)
    assert path.read_text() == before
    other.save(path, overwrite=True)
    _same(GridExperimentResult.load(path), other)


@pytest.mark.parametrize("column", FRAME_COLUMNS + METADATA_COLUMNS)
def test_from_frame_refuses_missing_column(result, column):
    # 'fraction' is derived and not needed to rebuild, but the table is refused without
    # it: the saved format has all six columns.
    frame = result.to_frame().drop(columns=column)
    with pytest.raises(ValueError, match=repr(column)):
        GridExperimentResult.from_frame(frame)


def test_from_frame_refuses_wrong_outputs(result):
    frame = result.to_frame()
    renamed = frame.assign(output=frame["output"].replace({"ez": "ew"}))
    with pytest.raises(ValueError, match="outputs"):
        GridExperimentResult.from_frame(renamed)
    missing = frame[frame["output"] != "dz"]
    with pytest.raises(ValueError, match="outputs"):
        GridExperimentResult.from_frame(missing)
    extra = pd.concat([frame, frame[frame["output"] == "dx"].assign(output="dw")])
    with pytest.raises(ValueError, match="outputs"):
        GridExperimentResult.from_frame(extra)


def test_from_frame_refuses_mixed_pose_counts(result):
    frame = result.to_frame()
    frame.loc[3, "outside"] += 1
    with pytest.raises(ValueError, match="pose counts"):
        GridExperimentResult.from_frame(frame)


# ------------------------------------------------------------------ RandomPoseResult
def _wilson(k, n, z):
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z / (1 + z * z / n) * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
    return centre - half, centre + half


def test_random_pose_result_to_frame():
    inside = np.array([990, 1000, 975, 900, 999, 950])
    one, two = np.linspace(0.90, 0.95, 6), np.linspace(0.80, 0.85, 6)
    r = RandomPoseResult(limits=LIMITS, inside=inside, n_samples=1000, fosm_one_sided=one,
                         fosm_two_sided=two, distribution="normal", k=3.0)
    frame = r.to_frame()
    assert list(frame.index) == list(OUTPUTS)
    for column in ("limit", "inside", "estimate", "lower", "upper", "standard_error",
                   "fosm_one_sided", "fosm_two_sided"):
        assert column in frame.columns
    assert list(frame.columns[:2]) == ["limit", "inside"]
    np.testing.assert_array_equal(frame["limit"], LIMITS)
    np.testing.assert_array_equal(frame["inside"], inside)
    np.testing.assert_allclose(frame["estimate"], inside / 1000, rtol=1e-15)
    np.testing.assert_array_equal(frame["fosm_one_sided"], one)
    np.testing.assert_array_equal(frame["fosm_two_sided"], two)
    z = stats.norm.ppf(0.975)
    for j, k in enumerate(inside):
        low, high = _wilson(k, 1000, z)
        assert frame["lower"].iloc[j] == pytest.approx(low, abs=1e-12)
        assert frame["upper"].iloc[j] == pytest.approx(high, abs=1e-12)
        p = k / 1000
        assert frame["standard_error"].iloc[j] == pytest.approx(math.sqrt(p * (1 - p) / 1000))
    exact = r.reliability(method="clopper-pearson")
    ci = stats.binomtest(900, 1000).proportion_ci(method="exact")
    assert exact.lower[3] == pytest.approx(ci.low, rel=1e-10)
    assert exact.upper[3] == pytest.approx(ci.high, rel=1e-10)


def test_sampling_results_print_readable_summaries(mill3):
    from reliability import GridExperiment, sample_random_poses

    grid = GridExperiment(mill3, 3).run(mill3.initial_allocation, repeats=4, rng=3)
    text = repr(grid)
    entirely = int((grid.inside == grid.n_poses).all(axis=1).sum())
    assert f"{entirely} of 4 experiments entirely within every limit" in text
    assert "0.01 mm" in text and "3e-05 rad" in text and "27 poses" in text
    assert "array(" not in text
    random = sample_random_poses(mill3, mill3.initial_allocation, 500, rng=3)
    text = repr(random)
    assert "500 random poses" in text and "Wilson" in text and "array(" not in text
    share = 100 * random.inside[0] / 500
    assert f"{share:.3f}" in text
