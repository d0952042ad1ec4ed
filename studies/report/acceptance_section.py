"""Report section: predicted ISO 230 acceptance-test results of built machines, for each
allocation, with each result's distribution against its limit
(:func:`reliability.acceptance.prediction.acceptance`)."""

from __future__ import annotations

import math

import numpy as np
from matplotlib.figure import Figure

from reliability.acceptance.acceptance_result import profile_note
from reliability.acceptance.prediction import DEFAULT_PROFILE, acceptance
from reliability.acceptance.suggested_limits import suggest_limits
from reliability.basics.display import decimals_text, lower_bound_text, upper_bound_text
from reliability.basics.streams import acceptance_stream
from studies.workflows.compensated_acceptance import SUFFIX, comparison_frame

from .markdown import details, markdown_table
from .section import Section

TITLE = "Acceptance tests"
FIGURE = "acceptance.png"
#: Built machines per allocation unless told otherwise.
BUILT_MACHINES = 2000


def acceptance_section(machine, tests, allocations: dict, *, machines: int = BUILT_MACHINES,
                       profile=DEFAULT_PROFILE, suggest=None, seed: int = 0,
                       compensated=None, plan_name: str = "") -> Section:
    """Predicted acceptance-test results of machines built to each allocation.

    Each allocation's numbers are those of ``precrel acceptance --tolerances CSV --profile
    P --machines N --seed S`` for it.

    Parameters
    ----------
    machine : Machine
    tests : sequence of tests
        :func:`reliability.acceptance.definitions.read_tests`.
    allocations : dict
        Label -> tolerances, e.g. ``{"initial": ..., "optimum": ...}``.
    machines : int
        Built machines per allocation.
    profile : str
        Error profile along travel.
    suggest : float, optional
        P: add each result's suggested limit, its P-quantile with its interval
        (:func:`reliability.acceptance.suggested_limits.suggest_limits`).
    seed : int
        Every allocation draws from a fresh
        :func:`reliability.basics.streams.acceptance_stream` of ``seed``.
    compensated : dict or str, optional
        Label -> the results after compensation of machines built to that allocation
        (:func:`studies.workflows.compensated_acceptance.compensated_acceptance`), shown
        beside; or why they could not be computed, said in their place.
    plan_name : str
        The compensation plan, as the reader gave it.
    """
    results = {label: acceptance(machine, tests, t, machines=machines, profile=profile,
                                 rng=acceptance_stream(seed))
               for label, t in allocations.items()}
    first = next(iter(results.values()))
    setting = f"profile {first.profile}, {first.n_machines} machines, seed {seed}"
    text = [f"Machines built to each allocation ({first.n_machines} each, seed {seed}, the "
            f"same draws for every allocation: `precrel acceptance --seed {seed} --machines "
            f"{first.n_machines} --profile {first.profile}` prints the same numbers, given "
            f"`--tolerances allocation.csv` for the optimum) and put through the "
            f"{len(tests)} tests of the test file: {profile_note(first.profile)}; tolerances "
            f"read as {first.distribution} with σ = t/{first.k:g}; geometric "
            f"errors only (no servo, dynamic or thermal effects), plus each linear axis' "
            f"repeatability and reversal in positioning tests. Results in µm; pass "
            f"probabilities with Wilson 95 % intervals; drivers: each error item's share of "
            f"the result's mean square, the item drawn alone."]
    tables, summary = {}, {}
    if compensated is not None:
        text += ["", _compensation_note(compensated, plan_name, seed, first.n_machines)]
    for label, result in results.items():
        suggestion = None if suggest is None else suggest_limits(result, suggest)
        frame = result.to_frame() if suggestion is None else suggestion.to_frame()
        if isinstance(compensated, dict):
            frame = comparison_frame(result, compensated[label], suggest)
        tables[f"acceptance_{label}.csv"] = frame
        text += ["", f"**{label}** ({setting}): all tests passed with probability "
                 f"{_interval(frame.iloc[-1])}{_suggested_pass(suggestion)}"
                 f"{_compensated_pass(frame)}.", "",
                 markdown_table(_shown(result, frame), index=False)]
        summary[label] = {f"{row.test}/{row.quantity}": row.pass_probability
                          for row in frame.itertuples() if not math.isnan(row.pass_probability)}
    text[0] = ("All tests passed, per allocation: " + "; ".join(
        f"{label} **{_interval(tables[f'acceptance_{label}.csv'].iloc[-1])}**"
        for label in results) + f" ({setting}).\n\n"
        + details("How the machines are built and tested", text[0]))
    extra = {} if not isinstance(compensated, dict) else {"acceptance_compensated": {
        label: _pass_summary(tables[f"acceptance_{label}.csv"], SUFFIX) for label in results}}
    return Section(TITLE, "\n".join(text), figures={FIGURE: plot_results(results)},
                   tables=tables, summary={"acceptance": summary,
                                           "acceptance_profile": first.profile,
                                           "acceptance_machines": first.n_machines, **extra})


def _compensation_note(compensated, plan_name: str, seed: int, machines: int) -> str:
    if not isinstance(compensated, dict):
        return (f"**After compensation** (`--compensation {plan_name}`): not computed: "
                f"{compensated}")
    return (f"**After compensation** (`--compensation {plan_name}`): beside each result, "
            f"machines built to the same allocation, measured under the plan and compensated "
            f"(columns \"compensated\"; `precrel acceptance --compensation {plan_name} "
            f"--seed {seed} --machines {machines}` prints the same numbers): residual errors "
            f"drawn correlated from the residual model, each one value along the whole "
            f"travel, repeatability and reversal in positioning tests as before "
            f"(docs/compensation.md).")


def _compensated_pass(frame) -> str:
    if "pass_probability" + SUFFIX not in frame:
        return ""
    return f"; after compensation {_interval(frame.iloc[-1], SUFFIX)}"


def _pass_summary(frame, suffix: str) -> dict:
    return {f"{row['test']}/{row['quantity']}": row["pass_probability" + suffix]
            for _, row in frame.iterrows() if not math.isnan(row["pass_probability" + suffix])}


def _interval(row, suffix: str = "") -> str:
    """A pass probability to four decimals, its interval's ends rounded outward."""
    return (f"{row['pass_probability' + suffix]:.4f} "
            f"[{decimals_text(row['pass_low' + suffix], 4, 'lower')}, "
            f"{decimals_text(row['pass_high' + suffix], 4, 'upper')}]")


def _suggested_text(limit, low, high) -> str:
    """A suggested limit in µm (mm given) to three digits, its interval's ends rounded
    outward."""
    return (f"{1000 * limit:.3g} [{lower_bound_text(1000 * low, 3)}, "
            f"{upper_bound_text(1000 * high, 3)}]")


def _suggested_pass(suggestion) -> str:
    if suggestion is None:
        return ""
    return (f"; with every limit at its suggested value (column \"suggested\": the "
            f"{suggestion.probability:g}-quantile with its 95 % order-statistic interval) "
            f"{_interval(suggestion.joint_pass().iloc[-1])}")


def _shown(result, frame):
    rows = frame[frame["test"] != "all"].copy()
    for column in ("limit", "mean", "q95"):
        rows[column] = [f"{1000 * v:.3g}" if not math.isnan(v) else "-" for v in rows[column]]
    rows["pass"] = [_interval(r) if not math.isnan(r["pass_probability"]) else "-"
                    for _, r in rows.iterrows()]
    rows["drivers"] = [result.top_drivers(r.test, r.quantity) or "-" for r in rows.itertuples()]
    suggested = ["suggested"] if "suggested_limit" in rows else []
    if suggested:
        rows["suggested"] = [_suggested_text(r.suggested_limit, r.suggested_low,
                                             r.suggested_high) for r in rows.itertuples()]
    compensated = _compensated_columns(rows)
    return rows[["test", "quantity", "limit", "mean", "q95", "pass", *suggested, *compensated,
                 "drivers"]].rename(columns={"limit": "limit µm", "mean": "mean µm",
                                             "q95": "q95 µm", "suggested": "suggested µm"})


def _compensated_columns(rows) -> list[str]:
    """Add the results after compensation to the shown rows, when there are any."""
    if "mean" + SUFFIX not in rows:
        return []
    rows["compensated µm (q05–q95)"] = [
        f"{1000 * r['mean' + SUFFIX]:.3g} ({1000 * r['q05' + SUFFIX]:.3g}–"
        f"{1000 * r['q95' + SUFFIX]:.3g})" for _, r in rows.iterrows()]
    rows["compensated pass"] = [_interval(r, SUFFIX) if not math.isnan(
        r["pass_probability" + SUFFIX]) else "-" for _, r in rows.iterrows()]
    shown = ["compensated µm (q05–q95)", "compensated pass"]
    if "suggested_limit" + SUFFIX in rows:
        rows["compensated suggested µm"] = [
            _suggested_text(r["suggested_limit" + SUFFIX], r["suggested_low" + SUFFIX],
                            r["suggested_high" + SUFFIX]) for _, r in rows.iterrows()]
        shown.append("compensated suggested µm")
    return shown


def plot_results(results: dict) -> Figure:
    """One panel per limited result: its distribution (µm) for each allocation, and the
    limit as a vertical line."""
    first = next(iter(results.values()))
    panels = [(test, quantity, limit) for test in first.tests
              for quantity, limit in test.limits.items()]
    columns = min(4, len(panels))
    rows = math.ceil(len(panels) / columns)
    figure = Figure(figsize=(3.2 * columns, 2.6 * rows), layout="constrained")
    axes = figure.subplots(rows, columns, squeeze=False).ravel()
    for ax, (test, quantity, limit) in zip(axes, panels):
        values = {label: 1000 * r.values[(test.name, quantity)].to_numpy()
                  for label, r in results.items()}
        high = max(1000 * limit, *(np.quantile(v, 0.999) for v in values.values())) * 1.05
        bins = np.linspace(0, high, 40)
        for label, v in values.items():
            ax.hist(np.minimum(v, high), bins=bins, histtype="step", density=True,
                    label=label)
        ax.axvline(1000 * limit, color="black", linestyle="--", linewidth=1)
        ax.set_title(f"{test.name}: {quantity}", fontsize=9)
        ax.set_xlabel("µm", fontsize=8)
        ax.set_yticks([])
    for ax in axes[len(panels):]:
        ax.set_visible(False)
    axes[0].legend(fontsize=7)
    figure.suptitle("Predicted test results against their limits (dashed)")
    return figure
