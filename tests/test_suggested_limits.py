"""Acceptance limits from the design (reliability.acceptance.suggested_limits, precrel
acceptance --suggest): the order-statistic interval against closed forms and its coverage,
and suggested limits against fresh built machines.

Statistical checks use z = 4 on the estimator's standard error, with fixed seeds."""

from __future__ import annotations

import math
import tomllib
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from reliability import machine_from_dict
from reliability.acceptance.iso_tests import PositioningTest
from reliability.acceptance.prediction import acceptance
from reliability.acceptance.suggested_limits import (
    minimum_machines,
    quantile_interval,
    quantile_ranks,
    suggest_limits,
)
from reliability.basics.errors import InputError
from studies import cli

MACHINES = Path(__file__).parent / "machines"
Z = 4.0
P = 0.95


@pytest.fixture(scope="module")
def mill():
    """mill3 with a repeatability and a reversal on X, so R and B vary between machines."""
    data = tomllib.loads((MACHINES / "mill3.toml").read_text())
    data["axes"][1].update(repeatability=0.001, reversal=0.002)
    return machine_from_dict(data)


@pytest.fixture(scope="module")
def position_x():
    return PositioningTest("position_X", "X", {"Y": 200.0, "Z": -175.0},
                           {"E": 0.01, "A": 0.02, "R": 0.01, "B": 0.01})


def test_median_of_a_hundred_draws_is_bounded_by_the_40th_and_61st():
    # the classical table of distribution-free intervals for the median, n = 100, 95 %
    lower, upper, coverage = quantile_ranks(100, 0.5)
    assert (lower, upper) == (40, 61)
    # P(40 <= K <= 60) for K ~ binomial(100, 1/2)
    assert coverage == pytest.approx(sum(math.comb(100, k) for k in range(40, 61)) / 2 ** 100,
                                     rel=1e-12)


def test_minimum_machines_is_where_the_extreme_order_statistics_first_bound_p():
    # 0.95^72 = 0.0249 <= 0.025 < 0.95^71 = 0.0262
    assert minimum_machines(0.95) == 72
    assert quantile_ranks(72, 0.95)[1] == 72
    with pytest.raises(InputError, match=r"machines must be at least 72 .*0\.95-quantile.*71"):
        quantile_ranks(71, 0.95)
    with pytest.raises(InputError, match=r"probability must be a number in \(0, 1\); got 1"):
        minimum_machines(1)


def test_interval_covers_the_quantile_at_its_stated_coverage():
    rng = np.random.default_rng(5)
    repeats, n, p = 4000, 150, 0.9
    draws = rng.exponential(size=(repeats, n))
    quantile = -math.log(1 - p)
    _, low, high = quantile_interval(draws.T, p)
    covered = np.mean((low <= quantile) & (quantile <= high))
    coverage = quantile_ranks(n, p)[2]
    assert coverage >= 0.95
    assert abs(covered - coverage) <= Z * math.sqrt(coverage * (1 - coverage) / repeats)


def test_suggested_limit_is_just_above_the_order_statistic_at_n_p(mill, position_x):
    """x₍ₖ₎, k = ⌈nP⌉, moved to the next float: the machine at x₍ₖ₎ passes by |v| < limit."""
    result = acceptance(mill, [position_x], machines=400, driver_machines=1, rng=2)
    limits = suggest_limits(result, 0.9).limits.set_index(["test", "quantity"])
    for quantity in position_x.quantities:
        values = np.sort(result.values[("position_X", quantity)].to_numpy())
        limit = limits.loc[("position_X", quantity), "suggested_limit"]
        assert limit == np.nextafter(values[359], np.inf)
        assert np.mean(values < limit) >= 0.9
        assert np.mean(values < values[359]) < 0.9


def test_suggested_limits_are_met_by_a_share_p_of_fresh_machines(mill, position_x):
    design, fresh = (acceptance(mill, [position_x], machines=n, driver_machines=1, rng=seed)
                     for n, seed in ((2000, 11), (10_000, 12)))
    suggestion = suggest_limits(design, P)
    # the limit's true share has sd √(P(1−P)/n), the fresh machines add √(P(1−P)/N)
    spread = math.sqrt(P * (1 - P) * (1 / 2000 + 1 / 10_000))
    within = np.ones(10_000, dtype=bool)
    for row in suggestion.limits.itertuples():
        ok = fresh.values[(row.test, row.quantity)].to_numpy() < row.suggested_limit
        assert abs(ok.mean() - P) <= Z * spread, row.quantity
        within &= ok
    # E and A move together, R and B with the repeatability: all four at once is rarer
    joint = suggestion.joint_pass().set_index("test")
    one_machine = math.sqrt(P * (1 - P) / 10_000)
    assert within.mean() < P - Z * one_machine
    assert joint.loc["position_X", "pass_high"] < P
    assert joint.loc["position_X", "quantities"] == "E, A, R, B"


def test_command_adds_the_suggested_columns_and_the_joint_pass(tmp_path, capsys):
    tests = tmp_path / "tests.toml"
    tests.write_text('[[tests]]\nname = "position_X"\nkind = "positioning"\naxis = "X"\n'
                     'line = { Y = 200.0, Z = -175.0 }\nlimit = { E = 0.015, A = 0.02 }\n')
    machine = str(MACHINES / "mill3.toml")
    assert cli.main(["acceptance", machine, "--tests", str(tests), "--machines", "200",
                     "--seed", "4", "--suggest", "0.9", "--out", str(tmp_path / "acc.csv")]) == 0
    printed = capsys.readouterr().out
    assert "suggested limits: the 0.9-quantile" in printed
    assert "position_X (E, A): " in printed
    written = pd.read_csv(tmp_path / "acc.csv")
    assert list(written.columns[-3:]) == ["suggested_limit", "suggested_low", "suggested_high"]
    assert written.iloc[-1][["suggested_limit", "suggested_low", "suggested_high"]].isna().all()
    rows = written.iloc[:-1]
    assert (rows["suggested_low"] <= rows["suggested_limit"]).all()
    assert (rows["suggested_limit"] <= rows["suggested_high"]).all()
    assert cli.main(["acceptance", machine, "--tests", str(tests), "--machines", "50",
                     "--suggest", "0.95"]) == 2
    assert "--machines must be at least 72" in capsys.readouterr().err


def test_report_refuses_a_suggestion_without_tests(tmp_path, capsys):
    assert cli.main(["report", str(MACHINES / "mill3.toml"), "--out", str(tmp_path / "r"),
                     "--suggest", "0.95"]) == 2
    assert "--suggest 0.95 needs --tests" in capsys.readouterr().err
    assert not (tmp_path / "r").exists()


def test_report_section_shows_the_suggested_limits(mill, position_x):
    from studies.report.acceptance_section import acceptance_section
    section = acceptance_section(mill, [position_x], {"initial": mill.initial_allocation},
                                 machines=100, suggest=0.9, seed=3)
    assert "suggested µm" in section.text and "0.9-quantile" in section.text
    assert "suggested_limit" in section.tables["acceptance_initial.csv"]
