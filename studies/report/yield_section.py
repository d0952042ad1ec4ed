"""The report's first answer: the machine yield of each allocation, and what decides it.

The yield (:func:`reliability.sampling.machine_yield.machine_yield`) is the share of built machines
that keep all six outputs within their limits at every grid pose, under the study's error
profile and reading of a tolerance; the failure shares say which requirement (output and
pose region) fails first in the machines that fail.
"""

from __future__ import annotations

import textwrap

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from reliability.sampling.yield_estimate import yield_text
from reliability.basics.display import interval_text

from .markdown import (details, interval_formats, markdown_table, percent_bound,
                       probability_bound)
from .plots import OUTPUT_COLOURS
from .section import Section

#: Regions drawn per allocation in the failure-share figure (largest shares).
PLOTTED_SHARES = 10
#: Rows of each allocation's failure-share table in the report text (the CSV has all).
TABLED_SHARES = 10
LABELS = {"initial": "initial", "optimum": "optimal", "given": "given"}
#: Characters per line of a failure region's label: longer ones wrap, so the bars keep
#: most of the figure's width.
LABEL_WIDTH = 34


def yield_table(study) -> pd.DataFrame:
    """One row per allocation: the yield, its interval, the failure probability's CoV,
    the method, the machines simulated and the first-order bounds."""
    rows = []
    for name, check in study.checks.items():
        y = check.machine_yield
        rows.append({"allocation": LABELS.get(name, name), "yield": y.estimate,
                     "lower": y.lower, "upper": y.upper,
                     "failure_probability": y.failure_probability, "cov": y.cov,
                     "method": y.method, "machines": y.machines, "failing": y.failures,
                     "first_order_lower": y.first_order_lower,
                     "first_order_upper": y.first_order_upper, "profile": y.profile,
                     "distribution": y.distribution, "workspace": y.workspace})
    return pd.DataFrame(rows)


def share_table(study) -> pd.DataFrame:
    """Every allocation's failure shares, one row per (allocation, output, region)."""
    frames = [check.machine_yield.failure_shares.assign(allocation=LABELS.get(name, name))
              for name, check in study.checks.items()]
    frame = pd.concat(frames, ignore_index=True)
    return frame[["allocation", *frames[0].columns]] if len(frame) else \
        pd.DataFrame(columns=["allocation", *frames[0].columns])


def yield_sentence(study) -> str:
    """The yields in one markdown line, for the Answers."""
    parts = [f"{LABELS.get(name, name)} **{yield_text(c.machine_yield.estimate)}** "
             f"{interval_text(c.machine_yield.lower, c.machine_yield.upper)}"
             for name, c in study.checks.items()]
    first = next(iter(study.checks.values())).machine_yield
    return (f"- Machine yield (share of built machines with all six outputs within their "
            f"limits at every pose of the {first.workspace}; profile {first.profile}, "
            f"{first.confidence:.0%} interval): " + "; ".join(parts) + ".")


def yield_section(study) -> Section:
    """The yield table, each allocation's failure shares and the failure-share figure."""
    first = next(iter(study.checks.values())).machine_yield
    table = yield_table(study)
    shares = share_table(study)
    shown = table[["allocation", "yield", "lower", "upper", "failure_probability", "cov",
                   "method", "machines", "failing", "first_order_lower",
                   "first_order_upper"]]
    formats = {"yield": yield_text, "failure_probability": "{:.3g}".format,
               "cov": "{:.3g}".format} | interval_formats(
        probability_bound, lower=("lower", "first_order_lower"),
        upper=("upper", "first_order_upper"))
    method = (
        f"The share of built machines that keep all six outputs within their limits at "
        f"every pose of the {first.workspace} at once, under the error profile "
        f"**{first.profile}** ({_profile_words(first.profile)}) and the reading "
        f"'{first.distribution}'. This is what a manufacturer sees; the per-output, "
        f"per-pose reliability of the sections below does not give it. `lower`/`upper`: "
        f"the {first.confidence:.0%} interval (Clopper–Pearson for crude sampling, "
        f"`p ± z·se` on the failure probability for importance sampling); `cov`: the "
        f"failure probability's coefficient of variation; `first_order_*`: bounds on the "
        f"yield of the linearised model (union bound over every pose and output; the best "
        f"single one). Why each method: "
        + "; ".join(f"{LABELS.get(n, n)}: {c.machine_yield.method_reason}"
                    for n, c in study.checks.items()) + ".")
    parts = [
        yield_sentence(study)[2:], markdown_table(shown, formats, index=False),
        details("How the yield is estimated", method),
        "What fails first in the machines that fail: the output and pose region with the "
        "largest |y|/I over the grid (regions: the worst pose's third of the stroke along "
        "the axes that change that output's spread most; mm and degrees). `share`: of the "
        "failing machines (weighted under importance sampling), with its Wilson "
        "interval on the effective number of failing machines; `failures`: failing "
        "machines sampled there."]
    for name, check in study.checks.items():
        own = check.machine_yield.failure_shares
        label = LABELS.get(name, name)
        if own.empty:
            parts.append(f"{label.capitalize()} allocation: no failing machine was sampled.")
            continue
        more = (f" (the {TABLED_SHARES} largest of {len(own)}; all in failure_shares.csv)"
                if len(own) > TABLED_SHARES else "")
        parts += [f"{label.capitalize()} allocation{more}:",
                  markdown_table(own.head(TABLED_SHARES),
                                 {"share": "{:.1%}".format} | interval_formats(
                                     percent_bound(1), lower=("lower",), upper=("upper",)),
                                 index=False)]
    figures = {} if shares.empty else {"failure_shares.png": failure_share_figure(study)}
    return Section("Machine yield", "\n\n".join(parts), figures=figures,
                   tables={"machine_yield.csv": table.set_index("allocation"),
                           "failure_shares.csv": shares.set_index("allocation")})


def failure_share_figure(study) -> Figure:
    """One panel per allocation: its largest failure shares with their intervals."""
    checks = {n: c for n, c in study.checks.items() if not c.machine_yield.failure_shares.empty}
    figure = Figure(figsize=(11, 1.2 + 0.45 * PLOTTED_SHARES * len(checks)),
                    layout="constrained")
    axes = figure.subplots(len(checks), 1, squeeze=False).ravel()
    for ax, (name, check) in zip(axes, checks.items()):
        plot_failure_shares(check.machine_yield, ax=ax,
                            title=f"{LABELS.get(name, name)} allocation")
    first = next(iter(checks.values())).machine_yield
    figure.suptitle(f"{study.machine.name}: what fails first in failing built machines "
                    f"(profile {first.profile}, reading '{first.distribution}', "
                    f"{first.workspace})")
    return figure


def plot_failure_shares(estimate, *, ax=None, title: str = "", count: int = PLOTTED_SHARES):
    """Horizontal bars of the largest failure shares of a
    :class:`~reliability.sampling.yield_estimate.YieldEstimate`, with their intervals.

    Returns
    -------
    matplotlib.axes.Axes
    """
    if ax is None:
        ax = Figure(figsize=(10, 5), layout="constrained").subplots()
    shares = estimate.failure_shares.head(count).iloc[::-1]
    labels = [textwrap.fill(f"{row.output}: {row.region}", LABEL_WIDTH,
                            break_long_words=False) for row in shares.itertuples()]
    share = 100 * shares["share"].to_numpy(dtype=float)
    error = np.vstack([share - 100 * shares["lower"].to_numpy(dtype=float),
                       100 * shares["upper"].to_numpy(dtype=float) - share])
    ax.barh(np.arange(len(shares)), share, xerr=error, capsize=3,
            color=[OUTPUT_COLOURS[o] for o in shares["output"]], alpha=0.85)
    ax.set_yticks(np.arange(len(shares)), labels, fontsize=8)
    ax.set_xlabel(f"share of failing machines [%] ({estimate.confidence:.0%} interval)")
    ax.set_xlim(0, 100)
    ax.set_title(f"{title}: yield {yield_text(estimate.estimate)} "
                 f"{interval_text(estimate.lower, estimate.upper)}, "
                 f"{estimate.method}, {estimate.machines:,} machines, {estimate.failures:,} "
                 f"failing", fontsize=10)
    return ax


def _profile_words(profile: str) -> str:
    if profile == "constant":
        return "each error one value per built machine along its whole travel"
    if profile == "independent":
        return "a fresh draw at every grid point, the paper's grid experiment"
    if profile.startswith("gp:"):
        return (f"a Gaussian process along travel with correlation length "
                f"{profile[3:]} mm")
    return "per axis"
