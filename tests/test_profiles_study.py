"""The profile study and its report section, on a small run."""

from __future__ import annotations

import math

import matplotlib

matplotlib.use("Agg")
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from reliability.model.measured_profiles import SystematicErrors, measured_profile
from studies.paper.profiles_study import main, paper_spread_check  # noqa: E402
from studies.paper.tables import TABLE6  # noqa: E402
from studies.report.profiles_section import (  # noqa: E402
    consistent_profiles, plot_yield_against_length, profiles_section)
from studies.workflows.profile_comparison import (  # noqa: E402
    ProfilesStudy, profile_comparison, profile_length, systematic_effect)


@pytest.fixture(scope="module")
def small(hobbing):
    kept = {}
    allocations = {"table6": hobbing.error_vector(TABLE6, default=None),
                   "wide": hobbing.initial_allocation * 1.3}
    frame = profile_comparison(hobbing, allocations, ("independent", "gp:200", "constant"),
                               (4, 40), rng=1, keep=kept)
    return frame, kept


def test_profile_lengths():
    assert profile_length("independent") == 0.0
    assert profile_length("gp:250") == 250.0
    assert math.isinf(profile_length("constant"))


def test_comparison_rows_and_yield_intervals(small):
    frame, kept = small
    assert len(frame) == 2 * 3 * 2
    assert set(frame["repeats"]) == {4, 40}
    assert np.all((frame["yield_lower"] <= frame["yield"]) & (frame["yield"] <= frame["yield_upper"]))
    result = kept[("table6", "constant", 40)]
    row = frame[(frame.allocation == "table6") & (frame.profile == "constant")
                & (frame.repeats == 40)].iloc[0]
    assert row["yield"] == result.all_inside.mean()
    assert row["std_ex"] == pytest.approx(result.fractions[:, 3].std(ddof=1))


def test_paper_check_quantiles_and_percentile(small):
    _, kept = small
    check = paper_spread_check({p: kept[("table6", p, 40)]
                                for p in ("independent", "constant")}, "table6")
    assert set(check["quantity"]) == {"std_dx", "std_ex", "std_ey", "all_inside"}
    assert np.all(check["blocks"] == 2)
    assert np.all((check["q025"] <= check["median"]) & (check["median"] <= check["q975"]))
    assert np.all((check["paper_percentile"] >= 0) & (check["paper_percentile"] <= 100))
    inside = (check["q025"] <= check["paper"]) & (check["paper"] <= check["q975"])
    assert np.array_equal(check["paper_inside"], inside)
    verdict = consistent_profiles(check)
    assert all(check[check.profile == p]["paper_inside"].all() for p in verdict)


def test_systematic_effect_lowers_the_worst_pose(hobbing):
    bow = measured_profile(hobbing, "X.dz", [0.0, 200.0, 400.0], [0.006, -0.003, 0.006])
    effect = systematic_effect(hobbing, hobbing.error_vector(TABLE6, default=None),
                               SystematicErrors(hobbing, (bow,)), repeats=6, rng=3,
                               points=3)
    assert effect.loc["dz", "worst_with"] < effect.loc["dz", "worst_without"]
    assert effect.loc["ex", "worst_with"] == effect.loc["ex", "worst_without"]
    assert effect.loc["dz", "largest_output_mean"] == pytest.approx(0.006, rel=1e-6)


def test_section_and_figure(small):
    frame, _ = small
    ax = plot_yield_against_length(frame)
    assert len(ax.containers) == 2  # one error-bar line per allocation
    section = profiles_section(ProfilesStudy(comparison=frame))
    assert "profiles_yield.png" in section.figures
    assert "profiles_comparison.csv" in section.tables
    assert set(section.summary["profiles_yield"]) == {
        f"{a}/{p}" for a in ("table6", "wide") for p in ("independent", "gp:200", "constant")}
    assert "| allocation | profile |" in section.text


def test_command_refuses_too_few_repeats(capsys):
    assert main(["--repeats", "1"]) == 2
    assert "--repeats" in capsys.readouterr().err


def test_documentation_examples_run(monkeypatch):
    import re
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    blocks = re.findall(r"```python\n(.*?)```", (root / "docs" / "profiles.md").read_text(),
                        flags=re.S)
    assert len(blocks) == 2
    monkeypatch.chdir(root)
    namespace = {}
    for block in blocks:  # the second block continues the first
        exec(compile(block, "docs/profiles.md", "exec"), namespace)
    assert namespace["mc"].repeats == 200
    worst = namespace["with_bow"].worst("two_sided")
    assert worst[2] < namespace["fosm"](namespace["machine"], namespace["t"],
                                        namespace["poses"]).worst("two_sided")[2]
