"""Report section: how error profiles along travel change the spread and the yield."""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np

from .markdown import details, markdown_table
from .section import Section

TITLE = "Errors along travel: independent, smooth or constant"


def plot_yield_against_length(comparison, *, repeats=None, ax=None):
    """Machine-level yield against correlation length, with Clopper-Pearson intervals.

    Independent profiles are drawn at the left edge and constant ones at the right edge
    of the logarithmic length axis, one line per allocation.

    Parameters
    ----------
    comparison : pandas.DataFrame
        :func:`studies.workflows.profile_comparison.profile_comparison`'s table.
    repeats : int, optional
        Which number of experiments to show; the largest by default.
    ax : matplotlib.axes.Axes, optional

    Returns
    -------
    matplotlib.axes.Axes
    """
    if ax is None:
        _, ax = plt.subplots(figsize=(7.8, 4.0), layout="constrained")
    repeats = comparison["repeats"].max() if repeats is None else repeats
    rows = comparison[comparison["repeats"] == repeats]
    finite = rows["length_mm"][np.isfinite(rows["length_mm"]) & (rows["length_mm"] > 0)]
    low, high = finite.min() / 4, finite.max() * 4
    for label, group in rows.groupby("allocation", sort=False):
        x = group["length_mm"].replace({0.0: low, np.inf: high}).to_numpy()
        y = group["yield"].to_numpy()
        error = np.vstack([y - group["yield_lower"], group["yield_upper"] - y])
        ax.errorbar(x, y, yerr=error, marker="o", capsize=3, label=label)
    ax.set_xscale("log")
    ticks = [low, *sorted(finite.unique()), high]
    ax.set_xticks(ticks, ["indep."] + [f"{v:g}" for v in sorted(finite.unique())] + ["const."])
    ax.minorticks_off()
    ax.set_xlabel("correlation length along travel (mm)")
    ax.set_ylabel("machine-level yield (all poses within every limit)")
    ax.set_ylim(0, 1)
    ax.set_title(f"Yield against correlation length ({repeats} experiments, 95 % intervals)")
    ax.legend(title="allocation", loc="upper left", bbox_to_anchor=(1.02, 1.0),
              borderaxespad=0.0)  # beside the axes: never over the data
    return ax


def profiles_section(study) -> Section:
    """The profile study as a report section (text, tables, figure, summary).

    Parameters
    ----------
    study : studies.workflows.profile_comparison.ProfilesStudy
    """
    comparison = study.comparison
    longest = int(comparison["repeats"].max())
    figure = plot_yield_against_length(comparison).figure
    tables = {"profiles_comparison.csv": comparison}
    text = [_comparison_text(comparison, longest, study.study_profile)]
    rows = comparison[comparison["repeats"] == longest]
    summary = {"profiles_yield": {f"{a}/{p}": float(y) for a, p, y
                                  in zip(rows["allocation"], rows["profile"], rows["yield"])},
               "profiles_experiments": longest}
    if study.paper_check is not None:
        tables["profiles_paper_check.csv"] = study.paper_check
        verdict = consistent_profiles(study.paper_check)
        text.append(_paper_text(study.paper_check, verdict))
        summary["table9_consistent_with"] = verdict
    if study.systematic is not None:
        tables["systematic_profile.csv"] = study.systematic
        text.append(_systematic_text(study.systematic))
        worst = study.systematic.groupby(level="allocation", sort=False)
        summary["systematic_worst_two_sided"] = {
            label: {"without": float(g["worst_without"].min()),
                    "with": float(g["worst_with"].min())} for label, g in worst}
    return Section(title=TITLE, text="\n\n".join(text),
                   figures={"profiles_yield.png": figure}, tables=tables, summary=summary)


def consistent_profiles(check) -> list[str]:
    """Profiles under which every paper quantity lies in the central 95 % of the blocks."""
    inside = check.groupby("profile", sort=False)["paper_inside"].all()
    return [profile for profile, ok in inside.items() if ok]


def _comparison_text(comparison, longest, study_profile=None) -> str:
    rows = comparison[comparison["repeats"] == longest]
    columns = ["allocation", "profile", "yield", "yield_lower", "yield_upper",
               *(["machines"] if "machines" in rows else []),
               "std_dx", "std_ex", "std_ey", "mean_dx", "mean_ex", "mean_ey"]
    low, high = rows["yield"].idxmin(), rows["yield"].idxmax()
    answer = (f"The machine-level yield ranges from **{rows.loc[low, 'yield']:.3f}** "
              f"({rows.loc[low, 'allocation']}, {rows.loc[low, 'profile']} errors) to "
              f"**{rows.loc[high, 'yield']:.3f}** ({rows.loc[high, 'allocation']}, "
              f"{rows.loc[high, 'profile']} errors) over the error profiles along travel.")
    method = (
        "The paper's grid experiment draws each axis' motion errors independently at each "
        "of its grid points. Real motion errors are smooth along travel. Here they are also "
        "drawn as Gaussian-process profiles of a given correlation length, and as constant "
        "along travel, with the same marginal distribution at every point. The per-pose "
        "reliability (the mean fractions) does not change; the machine-level yield and the "
        f"spread between experiments do. {longest} experiments per row"
        + _study_rows_text(study_profile, longest) + ".")
    return "\n\n".join([answer, markdown_table(rows[columns], index=False), _findings(rows),
                         details("How the profiles are drawn", method)])


def _study_rows_text(study_profile, longest) -> str:
    """What the rows of a report's own profile hold, when there is one."""
    if study_profile is None:
        return ""
    return (f"; the yield of the rows under **{study_profile}**, the study's profile, is "
            f"the study's machine yield (section \"Machine yield\": the same estimate, "
            f"stream and `machines`), the other rows' yield the share of their {longest} "
            f"experiments entirely within every limit (`machines` = experiments), and the "
            f"spread and mean fractions of every row come from its {longest} experiments")


def _findings(rows) -> str:
    """One sentence per allocation on the yield, and one on the unchanged mean fractions."""
    lines = []
    for label, group in rows.groupby("allocation", sort=False):
        ends = group.set_index("profile")["yield"]
        lines.append(f"- {label}: machine-level yield {ends.iloc[0]:.3f} with "
                     f"{ends.index[0]} errors, {ends.iloc[-1]:.3f} with {ends.index[-1]} "
                     f"ones (largest {ends.max():.3f}, smallest {ends.min():.3f}).")
        base = group.iloc[0]
        z = max(abs(r[f"mean_{o}"] - base[f"mean_{o}"])
                / np.hypot(r[f"se_{o}"], base[f"se_{o}"]) if r[f"se_{o}"] + base[f"se_{o}"]
                else 0.0 for _, r in group.iterrows() for o in ("dx", "ex", "ey"))
        verdict = "as expected, per-pose reliability does not depend on the profile" \
            if z < 3.0 else "more than 3 standard errors: check the run"
        lines.append(f"- {label}: mean fractions of every profile within {z:.1f} standard "
                     f"errors of the {group['profile'].iloc[0]} ones ({verdict}).")
    return "\n".join(lines)


def _paper_text(check, verdict) -> str:
    table = check[["profile", "quantity", "q025", "median", "q975", "paper",
                   "paper_percentile", "paper_inside"]]
    if verdict:
        conclusion = ("The paper's Table 9 lies inside the central 95 % range of every "
                      "quantity for: " + ", ".join(verdict) + ".")
    else:
        conclusion = ("No profile model puts every quantity of the paper's Table 9 inside its "
                      "central 95 % range.")
    return ("Table 9 of the paper (20 experiments, Table 6 allocation) against blocks of 20 "
            "experiments of each model: spread of the δx, εx, εy fractions and the number of "
            "experiments entirely within every limit, with the paper's percentile among the "
            "blocks.\n\n"
            + markdown_table(table, index=False) + "\n\n" + conclusion + " The spreads of "
            "20 experiments vary over an order of magnitude under every model and grow with "
            "the share of poses out of tolerance, which is smaller in the paper's Table 9 "
            "than in these runs of the same allocation; the number of experiments entirely "
            "within every limit is the sharper test, and longer correlation lengths predict "
            "more such experiments.")


def _systematic_text(effect) -> str:
    worst = effect[["limit", "worst_without", "worst_with", "largest_output_mean",
                    "mean_with", "mc_mean_with", "mc_se_with"]]
    return ("A measured straightness profile is a systematic error: its mean shifts the "
            "comprehensive errors pose by pose, and the allocated tolerance remains the random "
            "part around it. Two-sided FOSM reliability on the grid without and with the "
            "profile, and the grid experiment with the profile added (limits and output "
            "means in mm or rad):\n\n"
            + markdown_table(worst))
