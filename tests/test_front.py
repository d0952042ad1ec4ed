"""The certified cost–reliability front and its figure."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
import pytest  # noqa: E402

from allocation import AllocationProblem, allocation_point, cost_reliability_front  # noqa: E402
from reliability.basics.errors import InputError
from reliability.first_order.fosm import required_index
from reliability.model.poses import workspace_grid
from studies.paper.tables import TABLE6  # noqa: E402
from studies.report.plots import plot_front  # noqa: E402

TARGETS = np.array([0.999, 0.9, 0.99, 1 - 1e-6, 0.95])  # deliberately unsorted


@pytest.fixture(scope="module")
def grid(hobbing):
    return workspace_grid(hobbing, 3)


@pytest.fixture(scope="module")
def front(hobbing, grid):
    return cost_reliability_front(hobbing, TARGETS, poses=grid, bounds=(1e-3, 1.5))


def test_rows_follow_the_given_targets_and_are_certified(front):
    np.testing.assert_array_equal(front["target"], TARGETS)
    assert front["certified"].all() and front["feasible"].all()
    assert (front["relative_gap"] <= 1e-6).all()
    assert {"target", "cost", "relative_cost", "certified", "binding"} <= set(front)


def test_cost_rises_with_the_target(front):
    ordered = front.sort_values("target")
    assert np.all(np.diff(ordered["cost"]) > 0)


def test_each_point_matches_an_independent_solve(hobbing, grid, front):
    for target in (0.9, 0.999):
        problem = AllocationProblem.build(hobbing, grid, bounds=(1e-3, 1.5),
                                          targets=dict.fromkeys(hobbing.outputs, target))
        result = problem.solve_exact()
        row = front[front["target"] == target].iloc[0]
        assert row["cost"] == pytest.approx(result.cost, rel=1e-6)
        binding = result.requirements.index[result.requirements["binding_rows"] > 0]
        assert row["binding"] == ",".join(binding)


def test_cost_scales_as_z_squared_without_active_bounds(hobbing, grid):
    # with no item at a bound the optimum is u(z) = u(z0) (z0/z)², so F ∝ z²
    targets = [0.99, 0.9999]
    front = cost_reliability_front(hobbing, targets, poses=grid, bounds=(1e-4, 1e4),
                                   stack=False)
    z = required_index(np.array(targets))
    assert front["cost"][1] / front["cost"][0] == pytest.approx((z[1] / z[0]) ** 2,
                                                                rel=1e-6)


def test_stack_is_the_limiting_point(hobbing, grid, front):
    stack = front.attrs["stack"]
    problem = AllocationProblem.build(hobbing, grid, side="stack", bounds=(1e-3, 1.5))
    assert stack["cost"] == pytest.approx(problem.solve_exact().cost, rel=1e-6)
    assert stack["certified"]
    assert stack["relative_cost"] > front["relative_cost"].max()
    assert front.attrs["reference_cost"] == pytest.approx(
        problem.cost.total(hobbing.initial_allocation))


def test_targets_the_box_cannot_hold_are_marked(hobbing, grid):
    front = cost_reliability_front(hobbing, [0.99, 1 - 1e-9], poses=grid)  # default box
    assert front["feasible"].tolist() == [True, False]
    assert np.isnan(front["cost"][1]) and not front["certified"][1]
    assert "error" in front.attrs["stack"]


@pytest.mark.parametrize("targets, options, match", [
    ([0.9, 1.0], {}, r"targets\[1\]"),
    ([], {}, "non-empty"),
    ([0.9], {"side": "stack"}, "side"),
    ([0.9], {"workspace": "mean"}, "'workspace' is set"),
])
def test_bad_input_is_refused(hobbing, grid, targets, options, match):
    with pytest.raises(InputError, match=match):
        cost_reliability_front(hobbing, targets, poses=grid, **options)


def test_figure(hobbing, grid, front):
    marks = {"initial": allocation_point(hobbing, hobbing.initial_allocation, poses=grid),
             "Table 6": allocation_point(hobbing, hobbing.error_vector(TABLE6, default=None),
                                         poses=grid)}
    assert marks["initial"][1] == pytest.approx(1.0)
    ax = plot_front(front, marks=marks)
    assert ax.get_xscale() == "log"
    labels = [text.get_text() for text in ax.get_legend().get_texts()]
    assert any("stack" in label for label in labels)
    assert any("Table 6" in label for label in labels)
    plt.close(ax.figure)


# ----- precrel front ---------------------------------------------------------------------
def _parse(argv):
    import argparse

    from studies.cli import front as command

    parser = argparse.ArgumentParser()
    command.add_parser(parser.add_subparsers(dest="command"))
    return command, parser.parse_args(["front", *argv])


MILL = str(Path(__file__).parent / "machines" / "mill3.toml")


def test_command_prints_and_writes_the_front(tmp_path, capsys):
    out = tmp_path / "front.csv"
    command, args = _parse([MILL, "--target", "0.9", "0.999", "--bounds", "0.001", "1.5",
                            "--points", "3", "--out", str(out)])
    assert command.run(args) == 0
    printed = capsys.readouterr().out
    assert "worst-case stack: cost" in printed and f"written: {out}" in printed
    table = pd.read_csv(out)
    assert table["target"].tolist() == [0.9, 0.999]
    assert table["certified"].all()
    assert table["relative_cost"].is_monotonic_increasing
    # the file is not replaced without --overwrite
    with pytest.raises(InputError, match="exists"):
        command.run(args)


def test_command_refuses_too_few_targets():
    command, args = _parse([MILL, "--points", "2", "--count", "1"])
    with pytest.raises(InputError, match="--count"):
        command.run(args)


def test_command_still_reads_the_old_targets_spelling(capsys):
    """``--targets N``, the old spelling of ``--count N``, works with a warning."""
    _, args = _parse([MILL, "--targets", "3"])
    assert args.count == 3
    assert "precrel: warning: --targets is deprecated; use --count" in capsys.readouterr().err


@pytest.mark.parametrize("argv, words", [
    (["--points", "1"], ["--points", "'1'"]),
    (["--target", "1.5"], ["--target", "'1.5'"]),
    (["--count", "0.5"], ["--count", "'0.5'"]),
    (["--targets", "0.5"], ["--targets", "'0.5'"]),
    (["--bounds", "1.5", "0.5"], ["--bounds", "LO"]),
])
def test_command_refuses_bad_options_before_any_work(argv, words, capsys):
    from studies import cli

    assert cli.main(["front", MILL, *argv]) == 2
    last = capsys.readouterr().err.strip().splitlines()[-1]
    assert all(word in last for word in words), last


def test_front_section(mill3):
    from studies.report.tradeoff_sections import front_section

    section = front_section(mill3, targets=[0.9, 0.999], poses=workspace_grid(mill3, 3))
    summary = section.summary
    assert summary["front_points"] == 3  # 0.99 is added for the comparison
    assert summary["stack_over_target_cost"] == pytest.approx(
        summary["stack_relative_cost"] / summary["relative_cost_at_0.99"])
    assert "times** as expensive" in section.text
    assert set(section.figures) == {"front.png"} and set(section.tables) == {"front.csv"}
    plt.close(section.figures["front.png"])
