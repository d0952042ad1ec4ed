"""Figures for precision allocation and precision reliability (the paper's Figs. 8-15) and
the cost–reliability front.

Every function draws onto a given :class:`matplotlib.axes.Axes` (or a new figure when
``ax=None``), labels titles, axes (with units) and legends so the figure reads without the
code, and returns the axes. Nothing here opens a window or picks a backend.

Legends stand to the right of the axes, outside the plotted area, so that they never cover
data. A figure made here uses the constrained layout, which keeps them inside the saved
image; on axes of a figure without a layout engine, save with ``bbox_inches="tight"``.
"""

from __future__ import annotations

import textwrap
from collections.abc import Mapping

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.ticker import FixedLocator, FuncFormatter, NullLocator, PercentFormatter

from reliability.basics.errors import InputError, InputTypeError
from reliability.basics.pass_rule import passes
from reliability.basics.streams import generator

__all__ = [
    "plot_allocation_comparison",
    "plot_output_ratios",
    "plot_comprehensive_error_scatter",
    "plot_convergence",
    "plot_front",
    "plot_reliability_comparison",
    "plot_repeats",
]

#: Units of the six comprehensive errors, by the design's component names.
UNITS = {"dx": "mm", "dy": "mm", "dz": "mm", "ex": "rad", "ey": "rad", "ez": "rad"}
INSIDE_COLOR, OUTSIDE_COLOR = "tab:blue", "tab:red"
#: One colour per output, the same in every report figure that tells outputs apart.
OUTPUT_COLOURS = {"dx": "tab:blue", "dy": "tab:orange", "dz": "tab:green",
                  "ex": "tab:purple", "ey": "tab:brown", "ez": "tab:pink"}
#: Fill of each allocation in a figure that sets allocations side by side by output:
#: the first light and hatched, the next solid.
ALLOCATION_FILLS = ({"alpha": 0.35, "hatch": "//"}, {"alpha": 0.95, "hatch": ""})


# --------------------------------------------------------------------------- titles
def fit_titles(figure) -> None:
    """Wrap the figure's suptitle and every axes' title that is wider than the room it has
    (:data:`TITLE_ROOM` of the figure's width, or its axes' width) onto more lines, and fit
    the layout again (the layout only: nothing is drawn). Figures whose titles take less than
    :data:`CROWDED` of the room their axes have before the layout are left alone."""
    renderer = figure._get_renderer()
    if not _crowded(figure, renderer):
        return
    engine = figure.get_layout_engine()
    for _ in range(3):
        if engine is not None:
            engine.execute(figure)
        texts = [(ax.title, ax.get_window_extent(renderer).width) for ax in figure.axes]
        if figure._suptitle is not None:
            texts.append((figure._suptitle, TITLE_ROOM * figure.bbox.width))
        wrapped = [_wrap(text, room, renderer) for text, room in texts if text.get_text()]
        if not any(wrapped):
            return


#: Share of the room a title may take, judged before the layout, below which it surely fits.
CROWDED = 0.8


def _crowded(figure, renderer) -> bool:
    """Whether any title may be too wide: wider than :data:`CROWDED` of its axes' width as
    placed before the layout (or of :data:`TITLE_ROOM` of the figure's, for the suptitle)."""
    width = figure.bbox.width
    texts = [(ax.title, ax.get_position().width * width) for ax in figure.axes]
    if figure._suptitle is not None:
        texts.append((figure._suptitle, TITLE_ROOM * width))
    return any(text.get_window_extent(renderer).width > CROWDED * room
               for text, room in texts if text.get_text())


#: Share of the figure's width a suptitle may take.
TITLE_ROOM = 0.96


def _wrap(text, room: float, renderer) -> bool:
    """Wrap ``text`` (a matplotlib Text) to fit ``room`` pixels; whether it changed."""
    width = text.get_window_extent(renderer).width
    if width <= room:
        return False
    lines = text.get_text().split("\n")
    longest = max(len(line) for line in lines)
    characters = max(12, int(longest * room / width) - 2)
    text.set_text("\n".join(textwrap.fill(line, characters, break_long_words=False)
                            for line in lines))
    return True


# --------------------------------------------------------------------------- helpers
def _axes(ax, figsize):
    """Return ``ax``, or the axes of a new figure of ``figsize`` inches."""
    if ax is None:
        _, ax = plt.subplots(figsize=figsize, layout="constrained")
    return ax


def _finite_1d(name, values):
    """Return ``values`` as a finite 1-d float array."""
    x = np.asarray(values, dtype=float)
    if x.ndim != 1:
        raise InputError(f"{name} must be 1-dimensional; got shape {x.shape}")
    bad = np.flatnonzero(~np.isfinite(x))
    if bad.size:
        raise InputError(f"{name} must be finite; {name}[{bad[0]}] = {x[bad[0]]}")
    return x


def _positive(name, value):
    """Return ``value`` as a finite positive float."""
    v = float(value)
    if not (np.isfinite(v) and v > 0):
        raise InputError(f"{name} must be finite and positive; got {value!r}")
    return v


def _require_columns(frame, columns):
    """Refuse a frame that lacks any of ``columns``, naming the missing ones."""
    missing = [c for c in columns if c not in frame.columns]
    if missing:
        raise InputError(f"frame lacks column(s) {missing}; it has {list(frame.columns)}")


def _legend_beside(ax, **options):
    """Draw the legend to the right of the axes, outside the plotted area."""
    return ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0,
                     fontsize="small", **options)


def _target_line(ax, target):
    """Draw a horizontal target-probability line, if a target is given."""
    if target is None:
        return
    if not 0.0 < target < 1.0:
        raise InputError(f"target must lie in (0, 1); got {target!r}")
    ax.axhline(target, color="k", ls=":", lw=1.2, label=f"target {100 * target:g} %")


# --------------------------------------------------------------------------- Figs. 8-9
def _allocations(before, after, labels):
    """Return the allocations as an ordered dict label -> values, reference first."""
    if isinstance(before, Mapping):
        if after is not None:
            raise InputTypeError("give either a mapping label -> values, or before and after")
        allocations = dict(before)
    else:
        if after is None:
            raise InputTypeError("after is required unless before is a mapping label -> values")
        if len(labels) != 2:
            raise InputError(f"labels must hold 2 labels for before/after; got {labels!r}")
        allocations = dict(zip(labels, (before, after)))
    if len(allocations) < 2:
        raise InputError(f"need at least 2 allocations to compare; got {list(allocations)}")
    return allocations


def _tolerances(label, values, names):
    """Return one allocation as a positive finite array aligned with ``names``."""
    t = np.asarray(values, dtype=float)
    if t.shape != (len(names),):
        raise InputError(
            f"allocation {label!r} has shape {t.shape}; expected ({len(names)},) to match names"
        )
    bad = np.flatnonzero(~(np.isfinite(t) & (t > 0)))
    if bad.size:
        i = bad[0]
        raise InputError(f"allocation {label!r}: tolerance of {names[i]!r} is {t[i]}")
    return t


def _group_separators(ax, names):
    """Faint vertical lines between items of different axes or joints ("X" in "X.dx")."""
    groups = [name.split(".")[0] for name in names]
    for i in range(1, len(groups)):
        if groups[i] != groups[i - 1]:
            ax.axvline(i - 0.5, color="0.85", lw=0.8, zorder=0)


#: Mantissas of the tick values of a ratio axis, per decade.
RATIO_TICK_MANTISSAS = (1, 1.2, 1.5, 2, 3, 4, 5, 6, 7, 8, 9)
#: The fewest mantissas, used when the full set would crowd the axis.
SPARSE_TICK_MANTISSAS = (1, 2, 5)
#: At most this many labelled ticks on a ratio axis.
MAX_RATIO_TICKS = 9


def _ratio_limits(ratios):
    """Y limits of a log ratio axis: symmetric about 1, the largest change and 8 % more
    (in log).

    Symmetric limits draw a halving and a doubling as bars of the same length. The smallest
    span is ×/÷ 1.2, so that a figure of unchanged tolerances still has an axis.
    """
    reach = 1.08 * max(float(np.max(np.abs(np.log(ratios)))), np.log(1.2))
    return np.exp(-reach), np.exp(reach)


def _ratio_ticks(low, high):
    """Readable tick values in ``[low, high]`` on a log axis, 1 always among them."""
    decades = range(int(np.floor(np.log10(low))), int(np.ceil(np.log10(high))) + 1)
    for mantissas in (RATIO_TICK_MANTISSAS, SPARSE_TICK_MANTISSAS, (1,)):
        ticks = [m * 10.0 ** k for k in decades for m in mantissas
                 if low <= m * 10.0 ** k <= high]
        if len(ticks) <= MAX_RATIO_TICKS:
            break
    return ticks


def _ratio_axis(ax, ratios):
    """A log y axis for ratios: symmetric limits about 1, plain-number ticks, no minor ones."""
    ax.set_yscale("log")
    low, high = _ratio_limits(ratios)
    ax.set_ylim(low, high)
    ax.yaxis.set_major_locator(FixedLocator(_ratio_ticks(low, high)))
    ax.yaxis.set_major_formatter(FuncFormatter(lambda value, _: f"{value:g}"))
    ax.yaxis.set_minor_locator(NullLocator())


def plot_allocation_comparison(
    before,
    after=None,
    *,
    names,
    ax=None,
    title=None,
    labels=("reference", "optimised"),
):
    """Grouped bars comparing tolerance allocations item by item (Figs. 8 and 9).

    Translational tolerances (mm) and angular ones (rad) differ by about 200 times, so
    the bars show each allocation **relative to the reference** (the first allocation):
    a bar from the reference line at 1 to the ratio ``t / t_reference``, on a logarithmic
    axis, so that halving and doubling a tolerance are bars of the same length, downwards
    (tighter, dearer) and upwards (looser, cheaper). A bar reaching 1.5 is Table 6's
    "optimisation rate" of +50 %.

    Parameters
    ----------
    before : array_like or Mapping[str, array_like]
        Reference tolerances, one per name; or a mapping label -> tolerances holding
        two or more allocations (e.g. initial, paper, gwo, exact), the first of which
        is the reference.
    after : array_like, optional
        Compared tolerances; required unless `before` is a mapping.
    names : sequence of str
        Error-item names in the design's notation (``"X.dx"``, ``"C-X.ez"``).
    ax : matplotlib.axes.Axes, optional
        Axes to draw on; a new figure if None.
    title : str, optional
        Title; a description of the comparison if None.
    labels : tuple of 2 str
        Legend labels of `before` and `after` (ignored for a mapping).

    Returns
    -------
    matplotlib.axes.Axes

    Raises
    ------
    InputTypeError
        If `after` is missing for array input, or given together with a mapping.
    InputError
        If an allocation's length differs from `names`, or a tolerance is non-positive or
        non-finite (allocation and item named).
    """
    names = [str(n) for n in names]
    allocations = {
        label: _tolerances(label, values, names)
        for label, values in _allocations(before, after, labels).items()
    }
    (ref_label, ref), *others = allocations.items()
    ratios = np.array([t / ref for _, t in others])
    ax = _axes(ax, (max(6.0, 0.3 * len(names) + 2), 4.5))
    x = np.arange(len(names))
    width = 0.8 / len(others)
    for j, ((label, _), ratio) in enumerate(zip(others, ratios)):
        offset = (j - (len(others) - 1) / 2) * width
        ax.bar(x + offset, ratio - 1.0, width, bottom=1.0, label=label)
    ax.axhline(1.0, color="k", lw=1.0, label=f"{ref_label} = 1")
    _group_separators(ax, names)
    _ratio_axis(ax, ratios)
    ax.set_xticks(x, names, rotation=90)
    ax.set_xlim(-0.6, len(names) - 0.4)
    ax.set_xlabel("error item (axis.component or joint.component)")
    compared = others[0][0] if len(others) == 1 else "allocation"
    ax.set_ylabel(f"{compared} / {ref_label} (log scale)")
    ax.set_title(title or f"Tolerance allocation relative to {ref_label} ({len(names)} items)")
    _legend_beside(ax)
    return ax


def plot_output_ratios(ratios: Mapping, *, ax=None, title=None):
    """Each output's failure probability at its worst pose over the one its target allows,
    ``(1 − P_o) / (1 − R_o)`` (Eqs. 21–23), one bar per allocation in the output's colour
    (:data:`OUTPUT_COLOURS`), on a logarithmic axis with the target at 1: a bar above the
    line misses the target, one on it binds, one below has room.

    Parameters
    ----------
    ratios : Mapping[str, array_like (6,)]
        Allocation label -> the six ratios (dx, dy, dz, ex, ey, ez), at most two labels.
    ax : matplotlib.axes.Axes, optional
    title : str, optional

    Returns
    -------
    matplotlib.axes.Axes
    """
    if not 1 <= len(ratios) <= len(ALLOCATION_FILLS):
        raise InputError(f"ratios must hold 1 or {len(ALLOCATION_FILLS)} allocations; got "
                         f"{list(ratios)}")
    outputs = list(OUTPUT_COLOURS)
    values = {label: _finite_1d(f"ratios[{label!r}]", v) for label, v in ratios.items()}
    ax = _axes(ax, (6.0, 3.4))
    x, width = np.arange(len(outputs)), 0.8 / len(values)
    colours = [OUTPUT_COLOURS[o] for o in outputs]
    for j, (label, value) in enumerate(values.items()):
        offset = (j - (len(values) - 1) / 2) * width
        ax.bar(x + offset, value, width, color=colours, edgecolor=colours,
               label=label, **ALLOCATION_FILLS[j])
    ax.axhline(1.0, color="k", ls=":", lw=1.2, label="target")
    ax.set_yscale("log")
    shown = np.concatenate(list(values.values()))
    shown = shown[shown > 0]
    if shown.size:  # room below the smallest bar, so every bar shows its length
        ax.set_ylim(min(shown.min(), 1.0) / 3.0, max(shown.max(), 1.0) * 3.0)
    ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    ax.set_xticks(x, outputs)
    ax.set_xlabel("output (above 1: misses its target; at 1: binds)")
    ax.set_ylabel("(1 − P) / (1 − target)")
    ax.set_title(title or "Worst-pose failure probability over the target's",
                 fontsize=10)
    handles = [plt.Rectangle((0, 0), 1, 1, facecolor="0.4", edgecolor="0.4", **fill)
               for fill in ALLOCATION_FILLS[:len(values)]]
    ax.legend([*handles, ax.get_lines()[-1]], [*values, "target"], fontsize="small",
              loc="lower center", bbox_to_anchor=(0.5, 1.08), ncols=3, frameon=False)
    return ax


# --------------------------------------------------------------------------- Figs. 10-15
def _unit(output_label, unit):
    """Return the unit to print, from `unit` or the component name in `output_label`."""
    if unit is not None:
        return unit
    if output_label in UNITS:
        return UNITS[output_label]
    raise InputError(
        f"cannot infer the unit of {output_label!r}; pass unit= (e.g. 'mm' or 'rad')"
    )


def _shown_inside(outside, max_points, rng):
    """Indices of inside points to draw: all, or a random subset so the total fits.

    Outside points are never dropped, so the subset holds ``max_points - n_outside``
    inside points (none if the outside points alone exceed `max_points`).
    """
    inside = np.flatnonzero(~outside)
    if max_points is None:
        return inside
    if int(max_points) != max_points or max_points < 1:
        raise InputError(f"max_points must be a positive integer; got {max_points!r}")
    keep = max(int(max_points) - int(outside.sum()), 0)
    if keep >= inside.size:
        return inside
    return np.sort(generator(rng).choice(inside, size=keep, replace=False))


def plot_comprehensive_error_scatter(
    values, limit, *, output_label, unit=None, ax=None, max_points=None, rng=None,
    colour=None
):
    """Scatter of one comprehensive error over the poses of a grid experiment (Figs. 10-15).

    Points that fail their limit (``|value| >= limit``, the rule of
    :func:`reliability.basics.pass_rule.passes`) are red, the others blue; dashed lines mark
    ``+-limit``. The legend and title count the poses outside, over all of `values` even
    when only a subset is drawn.

    Parameters
    ----------
    values : array_like, shape (n_poses,)
        The comprehensive error at each pose (e.g. 15 625 for 5 points on six axes).
    limit : float
        Design limit ``I`` of this error, > 0 (e.g. 0.02 mm, 4.8e-5 rad; Eq. 35).
    output_label : str
        Name of the error, printed on the axes (``"dx"`` ... ``"ez"`` or e.g. ``"δx"``).
    unit : str, optional
        Unit of `values` and `limit`; inferred for the names ``dx dy dz`` (mm) and
        ``ex ey ez`` (rad), required otherwise.
    ax : matplotlib.axes.Axes, optional
        Axes to draw on; a new figure if None.
    max_points : int, optional
        Draw at most this many points: all outside points, plus a random subset of the
        inside ones. All points if None.
    rng : None, int or numpy.random.Generator
        Seed or generator for that subset (through :func:`reliability.basics.streams.generator`).
    colour : str, optional
        Colour of the points within the limit, e.g. the output's in
        :data:`OUTPUT_COLOURS`; the points outside are then red crosses, told apart by
        shape from any output's colour. Blue dots within, red dots outside if None.

    Returns
    -------
    matplotlib.axes.Axes

    Raises
    ------
    InputError
        If `values` is not a finite 1-d array, `limit` is not positive, `max_points` is
        not a positive integer, or the unit cannot be inferred.
    """
    values = _finite_1d("values", values)
    limit = _positive("limit", limit)
    unit = _unit(output_label, unit)
    outside = ~passes(values, limit)
    n_out, n_in = int(outside.sum()), int((~outside).sum())
    inside = _shown_inside(outside, max_points, rng)
    shown = "" if inside.size == n_in else f", {inside.size} drawn"
    ax = _axes(ax, (8.0, 4.0))
    ax.scatter(inside, values[inside], s=3, color=colour or INSIDE_COLOR, linewidths=0,
               label=f"within limit: {n_in} poses{shown}")
    out_idx = np.flatnonzero(outside)
    crosses = {} if colour is None else {"marker": "x", "linewidths": 0.8, "s": 12}
    ax.scatter(out_idx, values[out_idx], **({"s": 8, "linewidths": 0} | crosses),
               color=OUTSIDE_COLOR, label=f"outside limit: {n_out} poses")
    ax.axhline(limit, color="k", ls="--", lw=1.0, label=f"limit ±{limit:g} {unit}")
    ax.axhline(-limit, color="k", ls="--", lw=1.0)
    span = 1.15 * max(limit, float(np.abs(values).max()))
    ax.set_ylim(-span, span)  # both limit lines in view, symmetric about zero
    ax.set_xlabel("pose index in the grid experiment")
    ax.set_ylabel(f"{output_label} ({unit})")
    ax.set_title(f"Comprehensive error {output_label}: {n_out} of {values.size} poses "
                 f"outside ±{limit:g} {unit}")
    _legend_beside(ax, markerscale=2)
    return ax


# --------------------------------------------------------------------------- convergence
def _yscale(yscale, values):
    """Resolve ``"auto"`` to log when positive values span more than two decades."""
    if yscale not in ("auto", "linear", "log"):
        raise InputError(f"unknown yscale {yscale!r}; choose 'auto', 'linear' or 'log'")
    if yscale != "auto":
        return yscale
    positive = np.all(values > 0)
    return "log" if positive and values.max() / values.min() > 100 else "linear"


def plot_convergence(history, *, optimum=None, ax=None, yscale="auto"):
    """Best objective per GWO iteration, against the certified optimum.

    Parameters
    ----------
    history : pandas.DataFrame
        One row per iteration, indexed by iteration, with column ``best_objective`` (or
        ``cost``, as in the history of :func:`allocation.solve_gwo`) and
        optionally a boolean column ``feasible`` (is the best wolf feasible); infeasible
        iterations are marked with red crosses.
    optimum : float, optional
        Certified global optimum (the exact convex solution), drawn as a dashed line
        with its value in the legend; the final relative gap goes in the title.
    ax : matplotlib.axes.Axes, optional
        Axes to draw on; a new figure if None.
    yscale : {"auto", "linear", "log"}
        ``"auto"`` uses a log scale when the positive values span more than a factor 100.

    Returns
    -------
    matplotlib.axes.Axes

    Raises
    ------
    InputError
        If the column ``best_objective`` is missing, empty or non-finite, if ``feasible``
        is not boolean, or if `yscale` is unknown.
    """
    if "best_objective" not in history.columns and "cost" in history.columns:
        history = history.rename(columns={"cost": "best_objective"})  # solve_gwo's history
    _require_columns(history, ["best_objective"])
    best = _finite_1d("best_objective", history["best_objective"])
    if best.size == 0:
        raise InputError("history has no iterations")
    it = history.index.to_numpy()
    ax = _axes(ax, (7.0, 4.0))
    ax.plot(it, best, color="tab:blue", lw=1.5, label="GWO best objective")
    if "feasible" in history.columns:
        feasible = history["feasible"].to_numpy()
        if feasible.dtype != bool:
            raise InputError(f"column 'feasible' must be boolean; got dtype {feasible.dtype}")
        ax.plot(it[~feasible], best[~feasible], "x", color=OUTSIDE_COLOR, ms=4,
                label=f"best infeasible ({int((~feasible).sum())} iterations)")
    title = "GWO convergence"
    scaled = best
    if optimum is not None:
        optimum = float(optimum)
        ax.axhline(optimum, color="k", ls="--", lw=1.0, label=f"certified optimum = {optimum:.6g}")
        title += f": final gap {100 * (best[-1] - optimum) / abs(optimum):.3g} %"
        scaled = np.append(best, optimum)
    ax.set_yscale(_yscale(yscale, scaled))
    ax.set_xlabel("iteration")
    ax.set_ylabel("best objective (manufacturing cost, Eq. 28)")
    ax.set_title(title)
    _legend_beside(ax)
    return ax


# --------------------------------------------------------------------------- FOSM vs MC
RELIABILITY_COLUMNS = ("output", "fosm_one_sided", "fosm_two_sided", "mc_estimate",
                       "mc_lower", "mc_upper")


def _check_reliability_frame(frame):
    """Refuse missing columns, probabilities outside [0, 1] and inverted intervals."""
    _require_columns(frame, RELIABILITY_COLUMNS)
    for column in RELIABILITY_COLUMNS[1:]:
        _finite_1d(column, frame[column])
    for column in RELIABILITY_COLUMNS[1:4]:
        bad = frame[(frame[column] < 0) | (frame[column] > 1)]
        if len(bad):
            output, value = bad["output"].iloc[0], bad[column].iloc[0]
            raise InputError(f"{column} must lie in [0, 1]; output {output!r} has {value}")
    est = frame["mc_estimate"]
    inverted = frame.loc[(frame["mc_lower"] > est) | (est > frame["mc_upper"]), "output"]
    if len(inverted):
        raise InputError(
            f"mc_lower <= mc_estimate <= mc_upper fails for output {inverted.iloc[0]!r}"
        )


def _interval_name(frame, interval):
    """The name of the frame's Monte-Carlo interval: `interval`, else the frame's own."""
    name = interval if interval is not None else frame.attrs.get("mc_interval")
    if not name:
        raise InputError("name the interval of mc_lower and mc_upper: pass interval= (e.g. "
                         "\"95% Wilson score interval\") or give the frame "
                         "attrs['mc_interval'], as fosm_versus_monte_carlo does")
    return str(name)


def plot_reliability_comparison(frame, *, target=None, ax=None, interval=None,
                                output_colours=None):
    """Per output: FOSM-predicted probabilities beside the Monte-Carlo estimate.

    The FOSM values (Eqs. 19-23) are drawn as markers, one-sided ``Φ(I/σ)`` as in the
    paper and two-sided ``P(|y| < I)``; the Monte-Carlo estimate carries its interval as
    an error bar. For a like-with-like comparison the FOSM columns should be computed on
    the same poses as the Monte-Carlo estimate (e.g. averaged over the grid).

    Parameters
    ----------
    frame : pandas.DataFrame
        One row per output with columns ``output``, ``fosm_one_sided``, ``fosm_two_sided``,
        ``mc_estimate``, ``mc_lower``, ``mc_upper``, as
        :func:`reliability.sampling.fosm_comparison.fosm_versus_monte_carlo` returns. The bounds
        are drawn as given, so the figure shows the interval of the frame's table.
    target : float, optional
        Reliability target (e.g. 0.99), drawn as a dotted line.
    ax : matplotlib.axes.Axes, optional
        Axes to draw on; a new figure if None.
    interval : str, optional
        Name of the interval ``mc_lower``–``mc_upper``, printed in the legend; by default
        ``frame.attrs["mc_interval"]`` (95 % Wilson score interval on Kish's effective
        sample size for :func:`~reliability.sampling.fosm_comparison.fosm_versus_monte_carlo`).
    output_colours : mapping, optional
        Output -> colour (:data:`OUTPUT_COLOURS`): each output's Monte-Carlo estimate and
        tick label in its colour, the FOSM markers in black and grey (told apart by shape).
        One colour per method if None.

    Returns
    -------
    matplotlib.axes.Axes

    Raises
    ------
    InputError
        If a column is missing, a probability is outside [0, 1] or non-finite, an interval
        does not contain its estimate (the output is named), `target` is outside (0, 1),
        or the interval has no name.
    """
    _check_reliability_frame(frame)
    interval = _interval_name(frame, interval)
    x = np.arange(len(frame))
    est = frame["mc_estimate"].to_numpy(float)
    yerr = np.vstack([est - frame["mc_lower"], frame["mc_upper"] - est])
    ax = _axes(ax, (7.0, 4.0))
    methods = (("tab:orange", "tab:green") if output_colours is None else ("0.55", "k"))
    ax.plot(x - 0.2, frame["fosm_one_sided"], "v", color=methods[0],
            label="FOSM one-sided Φ(I/σ) (paper)")
    ax.plot(x, frame["fosm_two_sided"], "^", color=methods[1],
            label="FOSM two-sided P(|y| < I)")
    label = textwrap.fill(f"Monte Carlo mean, {interval}", 34, break_on_hyphens=False)
    if output_colours is None:
        ax.errorbar(x + 0.2, est, yerr=yerr, fmt="o", color=INSIDE_COLOR, capsize=3,
                    label=label)
    else:
        _coloured_estimates(ax, x + 0.2, est, yerr, frame["output"], output_colours, label)
    _target_line(ax, target)
    ax.set_xticks(x, frame["output"].astype(str))
    _colour_ticks(ax, output_colours)
    ax.set_xlabel("comprehensive error")
    ax.set_ylabel("probability within limit (%)")
    ax.yaxis.set_major_formatter(PercentFormatter(xmax=1.0))
    ax.set_title("Precision reliability: FOSM prediction vs Monte Carlo")
    _legend_beside(ax)
    return ax


def _coloured_estimates(ax, x, est, yerr, outputs, colours, label) -> None:
    """The estimates with their intervals, one error-bar container, each output's point
    and bar in its colour (caps and the legend entry grey)."""
    shown = [colours[o] for o in outputs]
    bars = ax.errorbar(x, est, yerr=yerr, fmt="none", ecolor="0.4", capsize=3, label=label)
    bars.lines[2][0].set_color(shown)
    ax.scatter(x, est, c=shown, zorder=3)


# --------------------------------------------------------------------------- Table 9
def _repeat_groups(frame, outputs, by):
    """Validate the repeats frame; return (outputs, [(group label, sub-frame), ...])."""
    frame = frame[~frame.index.isin(SUMMARY_ROWS)]
    if by is not None:
        _require_columns(frame, [by])
    if outputs is None:
        outputs = [c for c in frame.columns if c not in (by, "repeat")]
    outputs = list(outputs)
    if not outputs:
        raise InputError("no output columns to plot")
    _require_columns(frame, outputs)
    for column in outputs:
        f = _finite_1d(column, frame[column])
        bad = np.flatnonzero((f < 0) | (f > 1))
        if bad.size:
            raise InputError(f"fractions must lie in [0, 1]; {column}[{bad[0]}] = {f[bad[0]]}")
    groups = list(frame.groupby(by, sort=False)) if by is not None else [(None, frame)]
    return outputs, groups


#: Markers of the groups of :func:`plot_repeats` when the colours tell the outputs apart.
GROUP_MARKERS = ("o", "s", "^", "D")


def _colour_ticks(ax, output_colours) -> None:
    """Each x tick label (an output's name) in its colour, when colours are given."""
    if output_colours is None:
        return
    for tick in ax.get_xticklabels():
        tick.set_color(output_colours.get(tick.get_text(), "k"))


#: Summary rows of :meth:`GridExperimentResult.table9`, which are not experiments.
SUMMARY_ROWS = ("Avg", "Min", "Max")


def plot_repeats(frame, *, outputs=None, by=None, target=0.99, ax=None,
                 output_colours=None):
    """Per-experiment fractions within limit, per output (the paper's Table 9 as a figure).

    For each output a box (quartiles, whiskers to the extremes) summarises the repeated
    grid experiments, and every experiment is drawn as a point, spread sideways in
    experiment order so that equal values (many experiments sit at exactly 100 %) stay
    visible.

    Parameters
    ----------
    frame : pandas.DataFrame
        One row per experiment, one column per output, values in [0, 1] (e.g. the rows of
        ``table9_repeats.csv``, or :meth:`GridExperimentResult.table9`, whose rows
        labelled Avg, Min and Max are left out).
    outputs : sequence of str, optional
        Columns to plot; by default every column except `by` and ``"repeat"``.
    by : str, optional
        Column splitting the rows into groups drawn side by side (e.g. ``"allocation"``).
    target : float or None, default 0.99
        Reliability target drawn as a dotted line; None for no line.
    ax : matplotlib.axes.Axes, optional
        Axes to draw on; a new figure if None.
    output_colours : mapping, optional
        Output -> colour (:data:`OUTPUT_COLOURS`): each output's points and tick label in
        its colour, the groups told apart by marker shape (legend in grey). One colour per
        group if None.

    Returns
    -------
    matplotlib.axes.Axes

    Raises
    ------
    InputError
        If a named column is missing, a fraction is non-finite or outside [0, 1] (column
        and row named), or `target` is outside (0, 1).
    """
    outputs, groups = _repeat_groups(frame, outputs, by)
    ax = _axes(ax, (max(6.0, 0.7 * len(outputs) * len(groups) + 2), 4.0))
    width = 0.8 / len(groups)
    x = np.arange(len(outputs))
    for j, (label, sub) in enumerate(groups):
        pos = x + (j - (len(groups) - 1) / 2) * width
        data = [sub[c].to_numpy(float) for c in outputs]
        ax.boxplot(data, positions=pos, widths=0.8 * width, whis=(0, 100),
                   manage_ticks=False, medianprops={"color": "k"})
        spread = np.linspace(-0.3, 0.3, len(sub)) * width
        xs = np.concatenate([p + spread for p in pos])
        ys = np.concatenate(data)
        name = "one grid experiment" if label is None else f"{label} (n = {len(sub)})"
        if output_colours is None:
            ax.scatter(xs, ys, s=12, alpha=0.7, color=f"C{j}", linewidths=0, label=name,
                       zorder=3)
        else:
            marker = GROUP_MARKERS[j % len(GROUP_MARKERS)]
            colours = np.repeat([output_colours[c] for c in outputs], len(sub))
            ax.scatter(xs, ys, s=12, alpha=0.7, c=colours, marker=marker, linewidths=0,
                       zorder=3)
            ax.scatter([], [], s=12, color="0.4", marker=marker, label=name)
    _target_line(ax, target)
    ax.set_xticks(x, outputs)
    _colour_ticks(ax, output_colours)
    ax.set_xlabel("comprehensive error")
    ax.set_ylabel("fraction of poses within limit (%)")
    ax.yaxis.set_major_formatter(PercentFormatter(xmax=1.0))
    ax.set_title("Fraction within limit, per repeated grid experiment")
    _legend_beside(ax)
    return ax


def plot_front(front, *, marks=None, ax=None, title=None):
    """Relative cost against the failure probability 1 − R (log axis), with the stack.

    The certified optimal cost of holding one target for all six outputs at every pose,
    against that target's failure probability; the worst-case stack as a dashed line.

    Parameters
    ----------
    front : pandas.DataFrame
        From :func:`allocation.per_pose.front.cost_reliability_front`.
    marks : mapping, optional
        ``{label: (reliability, relative_cost)}`` of allocations to mark, e.g. the initial
        allocation and the paper's Table 6 from :func:`allocation.per_pose.front.allocation_point`.
    ax : matplotlib.axes.Axes, optional
        Axes to draw on; a new figure if None.
    title : str, optional
        Title; a description of the front (with its probability reading) if None.

    Returns
    -------
    matplotlib.axes.Axes
    """
    ax = _axes(ax, (7.6, 4.2))
    feasible = front[front["feasible"]].sort_values("target")
    failure = 1.0 - feasible["target"].to_numpy()
    side = str(front.attrs.get("side", "")).replace("_", "-")
    reading = f", {side} reading" if side else ""
    ax.plot(failure, feasible["relative_cost"], "o-", ms=3, label="certified optimum")
    stack = front.attrs.get("stack") or {}
    if "relative_cost" in stack:
        ax.axhline(stack["relative_cost"], color="k", ls="--",
                   label=f"worst-case stack ({stack['relative_cost']:.3g}×)")
    for (label, (reliability, cost)), marker in zip((marks or {}).items(), "s^vD"):
        ax.plot([max(1.0 - reliability, np.finfo(float).tiny)], [cost], marker, ms=8,
                label=f"{label} (worst R = {reliability:.6g})")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.invert_xaxis()
    ax.set_xlabel("failure probability 1 − R (worst output, worst pose; log scale)")
    ax.set_ylabel("cost / reference allocation's cost (log scale)")
    ax.set_title(title or f"Cost of reliability: certified optimal cost\nagainst the "
                          f"failure probability{reading}")
    ax.grid(True, which="both", alpha=0.3)
    _legend_beside(ax)
    return ax
