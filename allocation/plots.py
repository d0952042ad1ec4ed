"""Figures of the allocation results (each takes ``ax=None`` and returns the axes)."""

from __future__ import annotations

import numpy as np


def plot_front(front, *, marks=None, ax=None):
    """Relative cost against the failure probability 1 − R (log axis), with the stack.

    Parameters
    ----------
    front : pandas.DataFrame
        From :func:`allocation.front.cost_reliability_front`.
    marks : mapping, optional
        ``{label: (reliability, relative_cost)}`` of allocations to mark, e.g. the initial
        allocation and the paper's Table 6 from :func:`allocation.front.allocation_point`.
    ax : matplotlib.axes.Axes, optional

    Returns
    -------
    matplotlib.axes.Axes
    """
    if ax is None:
        import matplotlib.pyplot as plt

        _, ax = plt.subplots(figsize=(6.4, 4.2))
    feasible = front[front["feasible"]].sort_values("target")
    failure = 1.0 - feasible["target"].to_numpy()
    ax.plot(failure, feasible["relative_cost"], "o-", ms=3,
            label=f"certified optimum ({front.attrs.get('side', '')})")
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
    ax.set_xlabel("1 − R (worst output, worst pose)")
    ax.set_ylabel("cost relative to the reference allocation")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize="small")
    return ax
