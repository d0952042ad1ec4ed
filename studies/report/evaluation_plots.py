"""Figures of a measured machine's acceptance runs (``precrel evaluate``): each positioning
run's mean deviations per direction with ±2s bands (ISO 230-2), each circle's radial
deviation in polar form (ISO 230-4). Each figure is a :class:`matplotlib.figure.Figure`
made without pyplot, so nothing here picks a backend; labels carry units, titles say what is
shown.
"""

from __future__ import annotations

import re

import numpy as np
from matplotlib.figure import Figure

UM = 1000.0
#: Figures are named ``evaluation_<run>.png`` (characters other than letters, digits,
#: ``_ . -`` in the run's name as ``_``).
FIGURE_PREFIX = "evaluation_"
COLOURS = {"+": "tab:blue", "-": "tab:orange"}
NAMES = {"+": "+ direction (↑)", "-": "− direction (↓)"}


def run_figures(runs) -> dict[str, Figure]:
    """File name -> figure of every positioning run and circle of ``runs``
    (:class:`~reliability.measured.acceptance_runs.AcceptanceRuns`), in file order."""
    out = {}
    for run in runs.runs:
        draw = {"positioning": positioning_figure, "circular": circle_figure}.get(run.kind)
        if draw is not None:
            out[f"{FIGURE_PREFIX}{re.sub(r'[^A-Za-z0-9_.-]', '_', run.name)}.png"] = draw(run)
    return out


def positioning_figure(run) -> Figure:
    """Mean positional deviation ``x̄_i↑``, ``x̄_i↓`` at each target, each with its band
    ``x̄ ± 2 s`` (µm), of a :class:`~reliability.measured.acceptance_runs.PositioningRun`."""
    table = run.table()
    figure = Figure(figsize=(7.5, 4.5), layout="constrained")
    ax = figure.add_subplot()
    for sign, mean, s in (("+", "x_up", "s_up"), ("-", "x_down", "s_down")):
        centre, band = UM * table[mean], 2.0 * UM * table[s]
        ax.plot(table["target"], centre, marker="o", color=COLOURS[sign],
                label=f"mean, {NAMES[sign]}")
        ax.fill_between(table["target"], centre - band, centre + band, alpha=0.2,
                        color=COLOURS[sign], label=f"± 2s, {NAMES[sign]}")
    values = run.values()
    ax.set_xlabel(f"target position of {run.axis} (mm)")
    ax.set_ylabel(f"positional deviation {run.quantity} (µm)")
    ax.set_title(f"{run.name}: ISO 230-2 positioning of {run.axis}, "
                 f"{run.deviations.shape[0]} cycles\nE = {UM * values['E']:.3g} µm, "
                 f"A = {UM * values['A']:.3g} µm, R = {UM * values['R']:.3g} µm, "
                 f"B = {UM * values['B']:.3g} µm", fontsize="medium")
    ax.axhline(0.0, color="0.6", linewidth=0.8)
    ax.grid(True, alpha=0.3)
    ax.legend(loc="center left", bbox_to_anchor=(1.02, 0.5), fontsize="small")
    return figure


def circle_figure(run) -> Figure:
    """Radial deviation ``F`` (µm) of each direction of a
    :class:`~reliability.measured.acceptance_runs.CircularRun` about the least-squares
    centre, in polar form (angle: the position on the circle)."""
    deviations = run.deviations()
    figure = Figure(figsize=(6.5, 5.5), layout="constrained")
    ax = figure.add_subplot(projection="polar")
    every = UM * np.concatenate(list(deviations.values()))
    span = max(every.max() - every.min(), 1e-6)
    low, high = every.min() - 0.2 * span, every.max() + 0.2 * span
    for sign, values in deviations.items():
        order = np.argsort(np.mod(run.angles[sign], 2.0 * np.pi))
        theta = np.append(run.angles[sign][order], run.angles[sign][order][0])
        radius = UM * np.append(values[order], values[order][0])
        ax.plot(theta, radius, color=COLOURS[sign], label=NAMES[sign].replace("direction",
                                                                            "travel"))
    ax.set_rorigin(low - span)
    ax.set_rlim(low, high)
    ax.set_rlabel_position(100)
    values = run.values()
    shown = ", ".join(f"{q} = {UM * values[q]:.3g} µm" for q in ("G", "H") if q in values)
    ax.set_title(f"{run.name}: ISO 230-4 circle in {run.axes[0]}–{run.axes[1]}, radius "
                 f"{run.radius:.6g} mm\nradial deviation F (µm) about the least-squares "
                 f"centre; {shown or 'one direction'}", fontsize="medium")
    ax.set_xlabel(f"angle from +{run.axes[0]} towards +{run.axes[1]}")
    ax.legend(loc="center left", bbox_to_anchor=(1.08, 0.5), fontsize="small")
    return figure
