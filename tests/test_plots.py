"""Tests for studies.report.plots: artists drawn, limit lines, refusals; and for every
figure of the report and of the paper's case study: a title, and a legend that covers no
data and stays inside the picture."""

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
import pytest  # noqa: E402
from matplotlib.axes import Axes  # noqa: E402
from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: E402
from matplotlib.collections import LineCollection  # noqa: E402
from matplotlib.colors import to_rgba  # noqa: E402

from reliability.basics.statistics import between_experiment_interval
from studies.report.correlation_section import plot_cost_against_correlation  # noqa: E402
from studies.report.plots import (  # noqa: E402
    plot_allocation_comparison,
    plot_comprehensive_error_scatter,
    plot_convergence,
    plot_front,
    plot_reliability_comparison,
    plot_repeats,
)
from studies.report.profiles_section import plot_yield_against_length  # noqa: E402

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


# --------------------------------------------------------------------------- legends
def _drawn(ax):
    """Lay the figure out and draw it, as saving a PNG does; return the renderer."""
    if not hasattr(ax.figure.canvas, "get_renderer"):  # a bare Figure(): as savefig would
        FigureCanvasAgg(ax.figure)
    ax.figure.canvas.draw()
    return ax.figure.canvas.get_renderer()


def _data_covered_by(ax, box, renderer):
    """The data artists of ``ax`` of which some part lies in the display box ``box``:
    bars (their rectangles), lines (their drawn segments, or their markers when no line
    joins them), scatter points and error-bar segments."""
    covered = [patch for patch in ax.patches if patch.get_window_extent(renderer).overlaps(box)]
    for line in ax.lines:
        path = line.get_transform().transform_path(line.get_path())
        if line.get_linestyle() in ("None", "", " "):
            hit = box.count_contains(path.vertices) > 0
        else:
            hit = path.intersects_bbox(box, filled=False)
        covered += [line] if hit else []
    for collection in ax.collections:
        if isinstance(collection, LineCollection):
            transform = collection.get_transform()
            hit = any(transform.transform_path(p).intersects_bbox(box, filled=False)
                      for p in collection.get_paths())
        else:
            offsets = collection.get_offsets()
            hit = len(offsets) > 0 and box.count_contains(
                collection.get_offset_transform().transform(offsets)) > 0
        covered += [collection] if hit else []
    return covered


def _inside(inner, outer, slack=0.5):
    """Is the display box ``inner`` inside ``outer`` (to ``slack`` pixels)?"""
    return (inner.x0 >= outer.x0 - slack and inner.y0 >= outer.y0 - slack
            and inner.x1 <= outer.x1 + slack and inner.y1 <= outer.y1 + slack)


def assert_readable(figure):
    """Every axes of ``figure`` has a title (or the figure a suptitle) inside the picture;
    every legend lies inside the picture and over none of the data of any axes."""
    renderer = _drawn(figure.axes[0])
    suptitle = figure._suptitle.get_text() if figure._suptitle is not None else ""
    for ax in figure.axes:
        if not (ax.get_title() or suptitle):
            raise AssertionError(f"axes {ax.get_ylabel()!r} has no title")
        if ax.get_title():
            assert _inside(ax.title.get_window_extent(renderer), figure.bbox), ax.get_title()
        legend = ax.get_legend()
        if legend is None:
            continue
        box = legend.get_window_extent(renderer)
        assert _inside(box, figure.bbox), f"legend of {ax.get_title()!r} leaves the picture"
        for other in figure.axes:
            covered = _data_covered_by(other, box, renderer)
            assert not covered, f"legend of {ax.get_title()!r} covers {covered}"


ITEMS = [f"{axis}.{c}" for axis in "CAYXZ" for c in ("dx", "dy", "dz", "ex", "ey", "ez")]


def _crowded_allocation():
    """Looser and tighter bars alternating across the whole axes: no empty corner."""
    return plot_allocation_comparison(np.ones(30), np.tile([0.5, 1.5], 15), names=ITEMS)


def _crowded_scatter():
    """Points spread evenly over ±1.1 limit at every pose index: no empty corner."""
    values = np.random.default_rng(0).permutation(np.linspace(-0.022, 0.022, 3000))
    return plot_comprehensive_error_scatter(values, 0.02, output_label="dx")


def _front_frame():
    target = 1.0 - np.logspace(-1, -6, 12)
    frame = pd.DataFrame({"target": target, "feasible": True,
                          "relative_cost": 0.6 + 0.5 * np.arange(12)})
    frame.attrs.update(side="two_sided", stack={"relative_cost": 7.0})
    return frame


def _yield_frame():
    rows = [{"allocation": a, "profile": p, "repeats": 200, "length_mm": length,
             "yield": y, "yield_lower": y - 0.05, "yield_upper": min(y + 0.05, 1.0)}
            for a, base in (("initial", 0.1), ("optimum", 0.55))
            for p, length, y in (("independent", 0.0, base), ("gp:100", 100.0, base + 0.1),
                                 ("gp:1000", 1000.0, base + 0.35),
                                 ("constant", np.inf, base + 0.4))]
    return pd.DataFrame(rows)


FIGURES = {
    "allocation": _crowded_allocation,
    "allocation, four allocations": lambda: plot_allocation_comparison(
        {"initial": INITIAL, "paper": OPTIMISED, "gwo": OPTIMISED * 1.1,
         "exact": OPTIMISED * 0.9}, names=NAMES),
    "scatter": _crowded_scatter,
    "convergence": lambda: plot_convergence(_history(), optimum=9.0e9),
    "reliability": lambda: plot_reliability_comparison(_reliability_frame(), target=0.99,
                                                       interval="95% Wilson"),
    "repeats": lambda: plot_repeats(_repeats()),
    "front": lambda: plot_front(_front_frame(), marks={"initial": (0.95, 1.0),
                                                       "optimum": (0.99, 1.4)}),
    "yield against correlation length": lambda: plot_yield_against_length(_yield_frame()),
}


@pytest.mark.parametrize("draw", FIGURES.values(), ids=FIGURES.keys())
def test_legend_covers_no_data_and_every_figure_has_a_title(draw):
    assert_readable(draw().figure)


def test_the_check_finds_a_legend_over_data():
    ax = _crowded_scatter()
    ax.legend(loc="upper right")
    with pytest.raises(AssertionError, match="covers"):
        assert_readable(ax.figure)


def test_correlation_figure_has_a_title():
    sweep = pd.DataFrame({"cost_vs_rho0": [1.02, 1.0, 0.98]},
                         index=pd.Index([-0.5, 0.0, 0.5], name="rho"))
    assert_readable(plot_cost_against_correlation(sweep, ("X.dx", "Y.dy")).figure)


# --------------------------------------------------------------------------- allocation
def test_allocation_bars_are_ratios_drawn_from_one_on_a_log_axis():
    ax = plot_allocation_comparison(INITIAL, OPTIMISED, names=NAMES)
    assert isinstance(ax, Axes)
    bars = ax.patches
    assert len(bars) == len(NAMES)
    tops = np.array([b.get_y() + b.get_height() for b in bars])
    np.testing.assert_allclose([b.get_y() for b in bars], 1.0)
    np.testing.assert_allclose(tops, OPTIMISED / INITIAL)
    assert ax.get_yscale() == "log"
    assert 1.0 in _horizontal_lines(ax)
    assert ax.get_ylabel() == "optimised / reference (log scale)"
    assert [t.get_text() for t in ax.get_xticklabels()] == NAMES
    legend = [t.get_text() for t in ax.get_legend().get_texts()]
    assert legend == ["reference = 1", "optimised"]
    assert ax.get_title()


def test_allocation_axis_is_symmetric_about_one_with_plain_ticks():
    ax = plot_allocation_comparison(np.ones(4), [0.5, 0.8, 1.0, 1.25], names=NAMES[:4])
    low, high = ax.get_ylim()
    assert low * high == pytest.approx(1.0)  # halving and doubling: bars of equal length
    assert low < 0.5 and high > 2.0
    ticks = ax.get_yticks()
    assert 1.0 in ticks and np.all((ticks >= low) & (ticks <= high))
    _drawn(ax)
    labels = {t.get_text() for t in ax.get_yticklabels()}
    assert {"0.5", "1", "2"} <= labels
    # An unchanged allocation still has an axis around 1 (zero-height bars).
    flat = plot_allocation_comparison(np.ones(3), np.ones(3), names=NAMES[:3])
    assert flat.get_ylim()[0] < 1.0 < flat.get_ylim()[1]


def test_allocation_mapping_draws_one_bar_group_per_non_reference_allocation():
    allocations = {"initial": INITIAL, "paper": OPTIMISED, "gwo": OPTIMISED * 1.1,
                   "exact": OPTIMISED * 0.9}
    ax = plot_allocation_comparison(allocations, names=NAMES, title="Fig. 8")
    assert len(ax.patches) == 3 * len(NAMES)
    tops = np.array([b.get_y() + b.get_height() for b in ax.patches]).reshape(3, -1)
    np.testing.assert_allclose(tops, [OPTIMISED / INITIAL, 1.1 * OPTIMISED / INITIAL,
                                      0.9 * OPTIMISED / INITIAL])
    assert ax.get_ylabel() == "allocation / initial (log scale)"
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
    frame = pd.DataFrame({
        "output": ["dx", "dy", "dz", "ex", "ey", "ez"],
        "fosm_one_sided": [0.995, 0.999, 0.999, 0.996, 0.995, 0.993],
        "fosm_two_sided": [0.990, 0.998, 0.998, 0.992, 0.990, 0.986],
        "mc_estimate": [0.9996, 1.0, 0.9998, 0.9995, 0.9992, 0.9983],
        "mc_lower": [0.9992, 1.0, 0.9995, 0.9990, 0.9985, 0.9971],
        "mc_upper": [1.0, 1.0, 1.0001, 0.9999, 0.9998, 0.9995],
    })
    frame.attrs["mc_interval"] = "95% Wilson score interval on Kish's effective sample size"
    return frame


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
    assert ax.get_ylabel() == "probability within limit (%)"


def _legend_texts(ax):
    return [" ".join(t.get_text().split()) for t in ax.get_legend().get_texts()]


def test_reliability_comparison_names_the_interval_it_draws():
    frame = _reliability_frame()
    named = _legend_texts(plot_reliability_comparison(frame))
    assert ("Monte Carlo mean, 95% Wilson score interval on Kish's effective sample size"
            in named)
    given = _legend_texts(plot_reliability_comparison(frame, interval="95% Clopper-Pearson"))
    assert "Monte Carlo mean, 95% Clopper-Pearson" in given
    frame.attrs.clear()
    with pytest.raises(ValueError, match="name the interval of mc_lower and mc_upper"):
        plot_reliability_comparison(frame)


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
    from reliability.sampling.grid_experiment import GridExperiment
    result = GridExperiment(hobbing, points=2).run(
        hobbing.initial_allocation, repeats=3, rng=0)
    ax = plot_repeats(result.table9())
    # One point per experiment and output: 3 x 6, none for Avg/Min/Max.
    points = sum(len(c.get_offsets()) for c in ax.collections)
    assert points == 3 * 6
    plt.close(ax.figure)


# --------------------------------------------------------------------------- saved figures
def _errorbar_bounds(ax):
    """(lower, upper) ends of the error bars drawn on ``ax``."""
    (bars,) = ax.containers
    return np.array([s[:, 1] for s in bars.lines[2][0].get_segments()]).T


def test_every_report_figure_is_readable_and_draws_the_tables_interval(mill3):
    from studies.report import machine_sections
    from studies.report.extras import EXTRAS, builders
    from studies.workflows import machine_study
    study = machine_study.run(mill3, points=3, repeats=4, samples=500, rng=0)
    sections = machine_sections.sections(study, extra=builders(EXTRAS))
    figures = {name: figure for section in sections
               for name, figure in section.figures.items()}
    assert {"allocation_motion.png", "fosm_vs_mc.png", "front.png", "scatter_dx.png",
            "grid_repeats.png", "profiles_yield.png"} <= set(figures)
    for name, figure in figures.items():
        try:
            assert_readable(figure)
        except AssertionError as error:
            raise AssertionError(f"{name}: {error}") from error
    (verification,) = [s for s in sections if "fosm_vs_mc.png" in s.figures]
    table = verification.tables["fosm_vs_mc.csv"]
    for ax, (name, check) in zip(figures["fosm_vs_mc.png"].axes, study.checks.items()):
        # The figure's bars are the table's interval: Wilson on Kish's effective size,
        # recomputed here from the experiments' fractions.
        kish = between_experiment_interval(check.grid.fractions, names=OUTPUTS,
                                           poses=check.grid.n_poses)
        np.testing.assert_allclose(_errorbar_bounds(ax), [kish.lower, kish.upper],
                                   rtol=1e-12)
        np.testing.assert_allclose(_errorbar_bounds(ax),
                                   table.loc[name, ["mc_lower", "mc_upper"]].to_numpy().T,
                                   rtol=1e-12)
        assert any("Wilson" in text and "Kish" in text for text in _legend_texts(ax))
        assert "t-interval" not in ax.get_title()
    motion = figures["allocation_motion.png"].axes[0]
    assert motion.get_yscale() == "log"
    assert motion.get_ylabel() == "certified optimum / initial (log scale)"
    ratio = study.allocated[:18] / study.problem.reference[:18]  # as written to the CSV
    np.testing.assert_allclose([b.get_y() + b.get_height() for b in motion.patches], ratio)


@pytest.mark.xdist_group("small_paper_study")
def test_every_figure_of_the_paper_study_is_readable(small_paper_study):
    from studies.paper import reproduce
    study = small_paper_study
    figures = reproduce.figures(study, reproduce.tables(study))
    assert {f"fig{n:02d}.png" for n in range(8, 16)} <= set(figures)
    for name, figure in figures.items():
        try:
            assert_readable(figure)
        except AssertionError as error:
            raise AssertionError(f"{name}: {error}") from error
