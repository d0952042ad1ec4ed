"""Report section: the certified optimal cost as one error correlation varies."""

from __future__ import annotations

from matplotlib.figure import Figure

from allocation.per_pose.result_files import gap_text
from studies.workflows.correlation_sweep import VALUES, correlation_sweep

from .markdown import markdown_table
from .section import Section


def plot_cost_against_correlation(sweep, pair, ax=None):
    """Optimal cost relative to the uncorrelated pair against ρ; returns the axes."""
    if ax is None:
        ax = Figure(figsize=(5.5, 3.5)).add_subplot()
    ax.plot(sweep.index, sweep["cost_vs_rho0"], "o-", color="C0")
    ax.axhline(1.0, color="0.6", lw=0.8)
    ax.set_xlabel(f"correlation ρ of {pair[0]} and {pair[1]}")
    ax.set_ylabel("optimal cost / cost at ρ = 0")
    ax.set_title("Certified optimal cost against one correlation")
    return ax


def correlation_section(machine, pair, values=VALUES, *, side: str = "two_sided",
                        sweep=None) -> Section:
    """A report :class:`~studies.report.section.Section` on one correlated pair of errors.

    Parameters
    ----------
    machine : Machine
    pair : (str, str)
        The correlated errors (paper names or ISO 230-1 symbols).
    values : sequence of float
        Correlation coefficients.
    side : {'one_sided', 'two_sided'}
    sweep : DataFrame, optional
        A precomputed :func:`studies.workflows.correlation_sweep.correlation_sweep` table.
    """
    if sweep is None:
        sweep = correlation_sweep(machine, pair, values, side=side)
    index = [machine.error_index(n) for n in pair]
    names = [f"{machine.error_names[i]} ({machine.iso_names[i]})" for i in index]
    ax = plot_cost_against_correlation(sweep, pair)
    low, high = sweep.index.min(), sweep.index.max()
    worst_ignored = sweep["rho0_optimum_worst_P"].min()
    text = (
        f"Errors {names[0]} and {names[1]} are given a correlation ρ "
        f"from {low:g} to {high:g}; for each value the worst-case allocation problem "
        f"({side.replace('_', '-')} reading, workspace grid) is solved to a certified "
        f"optimum (largest relative duality gap {gap_text(sweep['relative_gap'].max())}). The "
        f"optimal cost moves from {sweep['cost_vs_rho0'].loc[low]:.4f} to "
        f"{sweep['cost_vs_rho0'].loc[high]:.4f} times its value at ρ = 0. The allocation "
        f"designed for uncorrelated errors keeps a worst-pose reliability of at least "
        f"{worst_ignored:.5f} over this range (target {machine.targets.min():g}).\n\n"
        + markdown_table(sweep, {"cost": "{:.6e}".format, "dual_bound": "{:.6e}".format,
                                 "relative_gap": "{:.1e}".format,
                                 "cost_vs_rho0": "{:.5f}".format,
                                 "rho0_optimum_worst_P": "{:.5f}".format}) + "\n")
    return Section(
        title="Correlated errors and the optimal cost",
        text=text,
        figures={"correlation_cost.png": ax.figure},
        tables={"correlation_cost.csv": sweep.reset_index()},
        summary={"correlation_pair": list(pair),
                 "correlation_cost_ratio": {f"{rho:g}": float(r)
                                            for rho, r in sweep["cost_vs_rho0"].items()},
                 "correlation_max_relative_gap": float(sweep["relative_gap"].max()),
                 "correlation_rho0_optimum_worst_P": float(worst_ignored)})
