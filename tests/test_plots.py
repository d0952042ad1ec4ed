"""Tests for studies.report.plots: artists drawn, limit lines, refusals."""

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
import pytest  # noqa: E402
from matplotlib.axes import Axes  # noqa: E402
from matplotlib.colors import to_rgba  # noqa: E402

from studies.report.plots import (  # noqa: E402
    plot_allocation_comparison,
    plot_comprehensive_error_scatter,
    plot_convergence,
    plot_reliability_comparison,
    plot_repeats,
)

NAMES = ["X.dx", "X.dy", "X.ez", "C-X.dx", "C-X.ez"]
INITIAL = np.array([0.003, 0.003, 1.45e-5, 0.003, 1.45e-5])
OPTIMISED = np.array([0.0036, 0.0027, 1.45e-5, 0.0031, 1.27e-5])


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plt.close("all")


def _horizontal_lines(ax):
    """y values of the horizontal lines drawn with axhline."""
    return sorted(
        line.get_ydata()[0] for line in ax.lines
        if len(set(line.get_ydata())) == 1 and tuple(line.get_xdata()) == (0, 1)
    )


def _collection(ax, prefix):
    """The scatter collection whose label starts with ``prefix``."""
    (found,) = [c for c in ax.collections if c.get_label().startswith(prefix)]
    return found


# --------------------------------------------------------------------------- allocation
def test_allocation_bars_are_ratios_drawn_from_one():
    ax = plot_allocation_comparison(INITIAL, OPTIMISED, names=NAMES)
    assert isinstance(ax, Axes)
    bars = ax.patches
    assert len(bars) == len(NAMES)
    tops = np.array([b.get_y() + b.get_height() for b in bars])
    np.testing.assert_allclose([b.get_y() for b in bars], 1.0)
    np.testing.assert_allclose(tops, OPTIMISED / INITIAL)
    assert 1.0 in _horizontal_lines(ax)
    assert [t.get_text() for t in ax.get_xticklabels()] == NAMES
    legend = [t.get_text() for t in ax.get_legend().get_texts()]
    assert legend == ["reference = 1", "optimised"]
    assert ax.get_title() and ax.get_ylabel()


def test_allocation_mapping_draws_one_bar_group_per_non_reference_allocation():
    allocations = {"initial": INITIAL, "paper": OPTIMISED, "gwo": OPTIMISED * 1.1,
                   "exact": OPTIMISED * 0.9}
    ax = plot_allocation_comparison(allocations, names=NAMES, title="Fig. 8")
    assert len(ax.patches) == 3 * len(NAMES)
    assert ax.get_title() == "Fig. 8"
    # Two groups ("X", "C-X") -> one separator at x = 2.5.
    assert [ln.get_xdata()[0] for ln in ax.lines if tuple(ln.get_ydata()) == (0, 1)] == [2.5]


def test_allocation_draws_on_given_axes():
    _, given = plt.subplots()
    assert plot_allocation_comparison(INITIAL, OPTIMISED, names=NAMES, ax=given) is given


@pytest.mark.parametrize(
    "before, after, kwargs, error, match",
    [
        (INITIAL, OPTIMISED[:4], {}, ValueError, r"'optimised' has shape \(4,\); expected \(5,\)"),
        (INITIAL, np.r_[OPTIMISED[:2], 0.0, OPTIMISED[3:]], {}, ValueError,
         r"'optimised': tolerance of 'X.ez' is 0.0"),
        (np.r_[np.nan, INITIAL[1:]], OPTIMISED, {}, ValueError,
         r"'reference': tolerance of 'X.dx' is nan"),
        (INITIAL, None, {}, TypeError, "after is required"),
        ({"a": INITIAL, "b": OPTIMISED}, OPTIMISED, {}, TypeError, "either a mapping"),
        ({"a": INITIAL}, None, {}, ValueError, "at least 2 allocations"),
        (INITIAL, OPTIMISED, {"labels": ("a", "b", "c")}, ValueError, "2 labels"),
        (INITIAL, OPTIMISED, {"colour": "red"}, TypeError, "colour"),
    ],
)
def test_allocation_refusals(before, after, kwargs, error, match):
    with pytest.raises(error, match=match):
        plot_allocation_comparison(before, after, names=NAMES, **kwargs)


# --------------------------------------------------------------------------- scatter
def _grid_values(seed=3, n=15625, scale=0.007):
    return np.random.default_rng(seed).normal(0.0, scale, n)


def test_scatter_colours_points_by_limit_and_draws_limit_lines():
    values, limit = _grid_values(), 0.02
    n_out = int(np.sum(np.abs(values) > limit))
    assert 0 < n_out < 100
    ax = plot_comprehensive_error_scatter(values, limit, output_label="dx")
    red, blue = _collection(ax, "outside"), _collection(ax, "within")
    assert len(red.get_offsets()) == n_out
    assert len(blue.get_offsets()) == values.size - n_out
    np.testing.assert_allclose(red.get_facecolor()[0], to_rgba("tab:red"))
    np.testing.assert_allclose(blue.get_facecolor()[0], to_rgba("tab:blue"))
    assert np.all(np.abs(red.get_offsets()[:, 1]) > limit)
    assert _horizontal_lines(ax) == [-limit, limit]
    assert f"{n_out} of 15625" in ax.get_title()
    assert ax.get_ylabel() == "dx (mm)"
    assert f"outside limit: {n_out} poses" in [t.get_text() for t in ax.get_legend().get_texts()]


def test_scatter_with_no_point_outside_has_empty_red_collection():
    ax = plot_comprehensive_error_scatter(np.full(10, 1e-6), 4.8e-5, output_label="ez")
    assert len(_collection(ax, "outside").get_offsets()) == 0
    assert ax.get_ylabel() == "ez (rad)"


def test_scatter_subsample_keeps_every_outside_point_and_is_reproducible():
    values, limit = _grid_values(), 0.02
    n_out = int(np.sum(np.abs(values) > limit))
    ax = plot_comprehensive_error_scatter(values, limit, output_label="δx", unit="mm",
                                          max_points=1000, rng=5)
    assert len(_collection(ax, "outside").get_offsets()) == n_out
    drawn = _collection(ax, "within").get_offsets()
    assert len(drawn) == 1000 - n_out
    again = plot_comprehensive_error_scatter(values, limit, output_label="δx", unit="mm",
                                             max_points=1000, rng=5)
    np.testing.assert_array_equal(drawn, _collection(again, "within").get_offsets())
    assert "drawn" in _collection(ax, "within").get_label()


@pytest.mark.parametrize(
    "values, limit, kwargs, match",
    [
        (np.zeros(5), 0.0, {}, "limit must be finite and positive"),
        (np.zeros(5), -0.02, {}, "limit must be finite and positive"),
        (np.zeros((5, 2)), 0.02, {}, r"values must be 1-dimensional; got shape \(5, 2\)"),
        (np.array([0.0, np.inf]), 0.02, {}, r"values\[1\] = inf"),
        (np.zeros(5), 0.02, {"output_label": "δx"}, "cannot infer the unit of 'δx'"),
        (np.zeros(5), 0.02, {"max_points": 0}, "max_points must be a positive integer"),
        (np.zeros(5), 0.02, {"max_points": 2.5}, "max_points must be a positive integer"),
    ],
)
def test_scatter_refusals(values, limit, kwargs, match):
    kwargs = {"output_label": "dx", **kwargs}
    with pytest.raises(ValueError, match=match):
        plot_comprehensive_error_scatter(values, limit, **kwargs)


# --------------------------------------------------------------------------- convergence
def _history(n=50):
    best = 9.0e9 + 1.0e9 * np.exp(-np.arange(n) / 8)
    return pd.DataFrame({"best_objective": best, "feasible": np.arange(n) >= 3})


def test_convergence_draws_history_optimum_and_infeasible_marks():
    ax = plot_convergence(_history(), optimum=9.0e9)
    assert isinstance(ax, Axes)
    curve, crosses = ax.lines[0], ax.lines[1]
    assert len(curve.get_xdata()) == 50 and len(crosses.get_xdata()) == 3
    assert _horizontal_lines(ax) == [9.0e9]
    legend = [t.get_text() for t in ax.get_legend().get_texts()]
    assert "certified optimum = 9e+09" in legend
    assert ax.get_yscale() == "linear"
    assert "final gap" in ax.get_title()


def test_convergence_auto_log_scale_over_many_decades():
    history = pd.DataFrame({"best_objective": np.logspace(6, 2, 40)})
    assert plot_convergence(history).get_yscale() == "log"
    assert plot_convergence(history, yscale="linear").get_yscale() == "linear"


@pytest.mark.parametrize(
    "history, kwargs, match",
    [
        (pd.DataFrame({"fun": [1.0, 2.0]}), {}, r"lacks column\(s\) \['best_objective'\]"),
        (pd.DataFrame({"best_objective": []}, dtype=float), {}, "no iterations"),
        (pd.DataFrame({"best_objective": [1.0, np.nan]}), {}, r"best_objective\[1\] = nan"),
        (pd.DataFrame({"best_objective": [1.0], "feasible": [1]}), {}, "must be boolean"),
        (pd.DataFrame({"best_objective": [1.0]}), {"yscale": "symlog"}, "unknown yscale"),
    ],
)
def test_convergence_refusals(history, kwargs, match):
    with pytest.raises(ValueError, match=match):
        plot_convergence(history, **kwargs)


# --------------------------------------------------------------------------- reliability
def _reliability_frame():
    return pd.DataFrame({
        "output": ["dx", "dy", "dz", "ex", "ey", "ez"],
        "fosm_one_sided": [0.995, 0.999, 0.999, 0.996, 0.995, 0.993],
        "fosm_two_sided": [0.990, 0.998, 0.998, 0.992, 0.990, 0.986],
        "mc_estimate": [0.9996, 1.0, 0.9998, 0.9995, 0.9992, 0.9983],
        "mc_lower": [0.9992, 1.0, 0.9995, 0.9990, 0.9985, 0.9971],
        "mc_upper": [1.0, 1.0, 1.0001, 0.9999, 0.9998, 0.9995],
    })


def test_reliability_comparison_draws_three_series_per_output():
    frame = _reliability_frame()
    ax = plot_reliability_comparison(frame, target=0.99)
    one, two = ax.lines[0], ax.lines[1]
    np.testing.assert_allclose(one.get_ydata(), frame.fosm_one_sided)
    np.testing.assert_allclose(two.get_ydata(), frame.fosm_two_sided)
    (bars,) = ax.containers
    np.testing.assert_allclose(bars.lines[0].get_ydata(), frame.mc_estimate)
    segments = bars.lines[2][0].get_segments()
    np.testing.assert_allclose([s[:, 1] for s in segments], frame[["mc_lower", "mc_upper"]])
    assert 0.99 in _horizontal_lines(ax)
    assert [t.get_text() for t in ax.get_xticklabels()] == list(frame.output)


@pytest.mark.parametrize(
    "change, match",
    [
        (lambda f: f.drop(columns="mc_upper"), r"lacks column\(s\) \['mc_upper'\]"),
        (lambda f: f.assign(mc_lower=f.mc_estimate + 1e-4), "fails for output 'dx'"),
        (lambda f: f.assign(fosm_two_sided=np.where(f.output == "dy", 1.2, f.fosm_two_sided)),
         r"fosm_two_sided must lie in \[0, 1\]; output 'dy' has 1.2"),
        (lambda f: f.assign(mc_estimate=np.nan), r"mc_estimate\[0\] = nan"),
    ],
)
def test_reliability_comparison_refusals(change, match):
    with pytest.raises(ValueError, match=match):
        plot_reliability_comparison(change(_reliability_frame()))


def test_reliability_comparison_refuses_target_outside_unit_interval():
    with pytest.raises(ValueError, match="target must lie in"):
        plot_reliability_comparison(_reliability_frame(), target=99)


# --------------------------------------------------------------------------- repeats
OUTPUTS = ["dx", "dy", "dz", "ex", "ey", "ez"]


def _repeats(seed=0, n=20):
    rng = np.random.default_rng(seed)
    values = np.minimum(1.0, 1.0 - np.abs(rng.normal(0, 0.002, (n, 6))))
    frame = pd.DataFrame(values, columns=OUTPUTS)
    frame.insert(0, "repeat", np.arange(1, n + 1))
    return frame


def test_repeats_draws_every_experiment_and_the_target():
    frame = _repeats()
    ax = plot_repeats(frame)
    (points,) = ax.collections
    offsets = points.get_offsets()
    assert len(offsets) == 20 * 6
    np.testing.assert_allclose(offsets[:, 1], frame[OUTPUTS].to_numpy().T.ravel())
    assert 0.99 in _horizontal_lines(ax)
    assert [t.get_text() for t in ax.get_xticklabels()] == OUTPUTS


def test_repeats_by_group_draws_one_point_set_per_group():
    frame = pd.concat([_repeats(1).assign(allocation="paper"),
                       _repeats(2).assign(allocation="exact")])
    ax = plot_repeats(frame, by="allocation", outputs=["dx", "ez"], target=None)
    assert [len(c.get_offsets()) for c in ax.collections] == [40, 40]
    assert [c.get_label() for c in ax.collections] == ["paper (n = 20)", "exact (n = 20)"]
    assert _horizontal_lines(ax) == []


@pytest.mark.parametrize(
    "frame, kwargs, match",
    [
        (_repeats(), {"outputs": ["dx", "qq"]}, r"lacks column\(s\) \['qq'\]"),
        (_repeats(), {"by": "allocation"}, r"lacks column\(s\) \['allocation'\]"),
        (_repeats().assign(ey=1.5), {}, r"fractions must lie in \[0, 1\]; ey\[0\] = 1.5"),
        (_repeats(), {"target": 1.0}, "target must lie in"),
        (_repeats()[["repeat"]], {}, "no output columns"),
    ],
)
def test_repeats_refusals(frame, kwargs, match):
    with pytest.raises(ValueError, match=match):
        plot_repeats(frame, **kwargs)


def test_convergence_takes_the_history_solve_gwo_returns(mill3):
    import allocation
    from reliability import workspace_grid
    problem = allocation.AllocationProblem.build(mill3, workspace_grid(mill3, 2))
    result = problem.solve_gwo(n_wolves=8, n_iterations=5, rng=0)
    ax = plot_convergence(result.history)
    np.testing.assert_array_equal(ax.lines[0].get_ydata(), result.history["cost"])
    plt.close(ax.figure)


def test_repeats_leaves_out_table9_summary_rows(hobbing):
    from reliability.sampling import GridExperiment
    result = GridExperiment(hobbing, points_per_axis=2).run(
        hobbing.initial_allocation, repeats=3, rng=0)
    ax = plot_repeats(result.table9())
    # One point per experiment and output: 3 x 6, none for Avg/Min/Max.
    points = sum(len(c.get_offsets()) for c in ax.collections)
    assert points == 3 * 6
    plt.close(ax.figure)
