"""Sobol indices on the exact chain, d yield / d ln t and ``precrel sensitivity``."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from reliability.basics.errors import InputError
from reliability.sampling.machine_yield import YieldModel
from reliability.sampling.sobol import SOBOL_COLUMNS, fosm_shares, sobol_indices
from reliability.sampling.yield_sensitivity import item_scores, yield_sensitivity
from studies.cli import main

#: Standard errors allowed between two estimates that should agree, with about a hundred
#: comparisons per test (two-sided 1e-4 each).
Z_MANY = 3.9
#: ... and with a handful of comparisons.
Z_FEW = 3.0
MILL = "tests/machines/mill3.toml"


def test_sobol_indices_of_a_nearly_linear_chain_are_its_fosm_variance_shares(mill3):
    result = sobol_indices(mill3, samples=1000, points=3, rng=5)
    shares = fosm_shares(mill3, mill3.initial_allocation, result.poses)
    moving = np.isfinite(shares)
    # the bootstrap half-width is z = 1.96 standard errors
    for estimate, half_width in ((result.S1, result.S1_conf), (result.ST, result.ST_conf)):
        se = half_width / 1.96
        gap = np.abs(estimate - shares)[moving]
        assert np.all(gap <= Z_MANY * se[moving] + 1e-9), gap.max()  # 1e-9: rounding
    assert np.allclose(result.analytic, shares, equal_nan=True)
    assert np.nanmax(shares) > 2.5 * np.nanmin(shares[shares > 0])  # not all equal
    assert list(result.to_frame().columns) == list(SOBOL_COLUMNS)


def test_sobol_indices_refuse_correlated_errors(mill3):
    with pytest.raises(InputError, match="independent errors"):
        sobol_indices(mill3.with_correlation({("X.dx", "Y.dx"): 0.5}), samples=10)


@pytest.mark.parametrize("profile", ["constant", "independent"])
def test_the_yield_score_function_agrees_with_central_differences(mill3, profile):
    model = YieldModel(mill3, profile=profile, points=3)
    t = mill3.initial_allocation
    draws = model.draws(2000, rng=11)
    score = yield_sensitivity(model, t, draws=draws)
    top = [name for name in score.ranked()["error"] if "+" not in name][:3]
    check = yield_sensitivity(model, t, draws=draws, method="difference", errors=top,
                              groups=[])
    ours = score.to_frame().set_index("error").loc[top]
    theirs = check.to_frame().set_index("error")
    gap = np.abs(ours["dyield_dlnt"] - theirs["dyield_dlnt"])
    assert np.all(gap <= Z_FEW * np.hypot(ours["se"], theirs["se"])), gap
    assert np.all(ours["dyield_dlnt"] < -2 * ours["se"])  # they matter, and lower the yield
    assert score.method == "score" and check.method == "difference"


def test_item_scores_have_mean_zero_under_correlation_and_a_travel_profile(mill3):
    machine = mill3.with_correlation({("X.ey", "X.dz"): 0.6, ("Y-X.dx", "X-Z.dy"): -0.4})
    model = YieldModel(machine, profile="gp:200", points=3)
    scores = item_scores(model, model.draws(4000, rng=3))
    se = scores.std(axis=0, ddof=1) / np.sqrt(len(scores))
    assert np.all(np.abs(scores.mean(axis=0)) <= Z_MANY * se)


def test_the_score_function_refuses_the_truncated_reading(mill3):
    model = YieldModel(mill3, distribution="truncated", points=2)
    with pytest.raises(InputError, match="method 'difference'"):
        yield_sensitivity(model, mill3.initial_allocation, machines=10, method="score")
    auto = yield_sensitivity(model, mill3.initial_allocation, machines=20, rng=1,
                             errors=["X.dx"])
    assert auto.method == "difference"


def test_precrel_sensitivity_writes_both_files(tmp_path, capsys):
    out = tmp_path / "sens"
    code = main(["sensitivity", MILL, "--pose", "Y=200,X=0,Z=-100", "--yield-gradient",
                 "--machines", "200", "--points", "2", "--sobol-samples", "100",
                 "--out", str(out)])
    assert code == 0
    sobol = pd.read_csv(out / "sobol.csv")
    assert list(sobol.columns) == ["output", "error", "S1", "S1_conf", "ST", "ST_conf"]
    frame = pd.read_csv(out / "yield_sensitivity.csv")
    assert list(frame.columns) == ["error", "dyield_dlnt", "se"]
    assert "d yield / d ln t" in capsys.readouterr().out
    (out / "notes.txt").write_text("mine")
    # rewritten without --yield-gradient: the folder holds this run's files only
    assert main(["sensitivity", MILL, "--pose", "Y=200,X=0,Z=-100", "--points", "2",
                 "--sobol-samples", "100", "--out", str(out), "--overwrite"]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["notes.txt", "sobol.csv"]


@pytest.mark.parametrize("pose, message", [("Y=200,X=0", "missing axes Z"),
                                           ("Y=200,X=0,Z=a", "needs a number"),
                                           ("Y=1,X=0,Z=0,W=1", "not an axis")])
def test_precrel_sensitivity_names_a_bad_pose(pose, message, capsys):
    assert main(["sensitivity", MILL, "--pose", pose, "--sobol-samples", "10"]) == 2
    assert message in capsys.readouterr().err
