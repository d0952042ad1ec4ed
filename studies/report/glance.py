"""The report at a glance: the first screen of ``report.html`` and ``report.md``.

The answers as a table of numbers (:func:`glance_table`, every number read from the entry
of ``summary.json`` named beside it in docs/results.md), one figure that tells the
machine's story (:func:`outputs_figure`: each output's worst-pose failure probability over
the one its target allows, initial and optimal allocation), the ranked advice as tables
(:func:`advice_table`), then the modelling choices in one short block linking to their
sections.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from reliability.basics.display import (axis_units, decimals_text, interval_text,
                                        percent_text, pose_text)
from reliability.basics.ties import worst_rows
from reliability.model.machine import OUTPUTS
from reliability.sampling.yield_estimate import yield_text
from studies.workflows.as_measured import holds_text

from . import plots
from .markdown import anchor, details, markdown_table
from .section import Section

TITLE = "Answers"
FIGURE = "answers_outputs.png"
LABELS = {"initial": "initial allocation", "optimum": "certified optimum",
          "optimal": "certified optimum", "given": "given allocation"}


def answers_section(study, rows: list, advice: str, notes: str, choices: str,
                    summary: dict) -> Section:
    """The first section: the table of ``rows`` (question, answer) beside the outputs
    figure, the ``advice`` tables, the modelling ``choices`` and the ``notes`` folded."""
    table = markdown_table(pd.DataFrame(rows, columns=["question", "answer"]), index=False)
    folded = [details("How the advice is ranked", notes)] if notes else []
    text = "\n\n".join(['<div class="glance">', table, f"![{FIGURE}]({FIGURE})", "</div>",
                        advice, choices, *folded])
    return Section(TITLE, text, figures={FIGURE: outputs_figure(study)}, summary=summary)


def glance_rows(study, summary: dict, meets: str) -> list[tuple[str, str]]:
    """The summary table's rows, each (question, answer), from the merged ``summary``:
    the machine yields, the cost, whether the initial allocation meets the targets
    (``meets``), each allocation's worst output, and when the report has them this machine
    as measured, the compensated cost and the acceptance pass rates."""
    rows = [(f"Machine yield, {LABELS.get(name, name)}",
             f"**{yield_text(value)}** {interval_text(*summary['yield_interval'][name])}")
            for name, value in summary["yield"].items() if value is not None]
    if summary["allocation"] == "given":
        rows += [("Allocation beside the initial one", f"given: {summary['given_source']}"),
                 ("Cost of the given allocation against the initial",
                  f"**{summary['given_relative_cost']:.2%}**"),
                 ("Does the given allocation meet the targets?",
                  "**yes**" if summary["given_meets_targets"] else "**no**")]
    if summary["reachable"]:
        certified = "certified" if summary["certified"] else "NOT certified"
        rows.append(("Cost of the certified optimum against the initial",
                     f"**{summary['relative_cost']:.2%}** ({certified})"))
    rows.append(("Does the initial allocation meet the targets?", meets))
    rows += [(f"Worst output, {LABELS[name]}", worst_output_text(study, result))
             for name, result in _fosm_results(study)]
    return rows + measured_rows(summary)


def measured_rows(summary: dict) -> list[tuple[str, str]]:
    """The rows of the optional sections' answers present in ``summary``."""
    rows = []
    if "as_measured" in summary:
        rows.append(("This machine as measured: every limit at every pose",
                     f"**{holds_text(summary['as_measured']['holds'])}**"))
    if "compensation_cost_ratio" in summary:
        rows.append(("Cost with compensation against without",
                     f"**{summary['compensation_cost_ratio']:.2%}**"))
    for label, rates in summary.get("acceptance", {}).items():
        if "all/pass" in rates:
            rows.append((f"Acceptance tests all passed, {LABELS.get(label, label)}",
                         f"**{decimals_text(rates['all/pass'], 2)}** "
                         f"({summary['acceptance_machines']} machines)"))
    verdicts = summary.get("evaluation", {})
    if verdicts:
        failing = [test for test, passes in verdicts.items() if passes is False]
        judged = [passes for passes in verdicts.values() if passes is not None]
        rows.append(("Acceptance runs as measured",
                     f"**{sum(judged)} of {len(judged)}** tests pass"
                     + (f" (fails: {', '.join(failing)})" if failing else "")))
    return rows


def _fosm_results(study) -> list:
    """(name, FOSM result) of the initial and, when reached, the optimal allocation."""
    found = [("initial", study.initial_fosm), ("optimum", study.optimal_fosm),
             ("given", study.given_fosm)]
    return [(name, result) for name, result in found if result is not None]


def failure_ratios(study, result) -> np.ndarray:
    """Each output's failure probability at its worst grid pose over the one its target
    allows, (1 − P_o) / (1 − R_o) (Eqs. 21–23): above 1 the output misses its target."""
    return (1.0 - result.worst(study.side)) / (1.0 - study.machine.targets)


def worst_output_text(study, result) -> str:
    """The output with the largest :func:`failure_ratios`, ties by
    :func:`~reliability.basics.ties.worst_rows` over the outputs' worst poses; its
    probability against its target, and its pose in mm and degrees."""
    machine = study.machine
    poses = result.poses[result.worst_pose]
    index = worst_rows(failure_ratios(study, result), poses)
    probability = result.worst(study.side)[index]
    return (f"**{OUTPUTS[index]}** {percent_text(probability)} (target "
            f"{100 * machine.targets[index]:g} %) at "
            f"{pose_text(poses[index], machine.axes, axis_units(machine))}")


def outputs_figure(study) -> Figure:
    """Each output's :func:`failure_ratios`, initial and optimal allocation, against the
    line its target draws: which outputs miss, which bind, which have room."""
    figure = Figure(figsize=(5.2, 3.4), layout="constrained")
    ratios = {LABELS[name]: failure_ratios(study, result)
              for name, result in _fosm_results(study)}
    plots.plot_output_ratios(ratios, ax=figure.subplots())
    return figure


def advice_table(table: pd.DataFrame, order, rates: pd.Series, ratios: pd.Series,
                 groups: dict, n: int) -> pd.DataFrame:
    """The first ``n`` entries of ``order`` as rows: item, ISO symbol, name, initial →
    allocated in the machine file's units (``table``, the tolerance table indexed by
    error; a group: its members and the change of its root-sum-square), change and what
    the change buys per 1 % of the initial cost."""
    rows = []
    for name in list(order)[:n]:
        if name in groups:
            members = groups[name]
            shown = ", ".join(members[:3]) + (", …" if len(members) > 3 else "")
            rows.append((name, "–", f"{len(members)} items: {shown}",
                         "root-sum-square", f"{rates[name]:+.0%}", f"{ratios[name]:.2g}"))
        else:
            row = table.loc[name]
            rows.append((name, row.iso, row["name"],
                         f"{row.initial:.3g} → {row.allocated:.3g} {row.unit}",
                         f"{rates[name]:+.0%}", f"{ratios[name]:.2g}"))
    return pd.DataFrame(rows, columns=["item", "ISO", "name", "initial → allocated",
                                       "change", "per 1 % of cost"])


def advice_text(tighten: pd.DataFrame, relax: pd.DataFrame, counts: tuple[int, int]) -> str:
    """The two advice tables with their headings, and how many entries each leaves out."""
    parts = []
    for heading, frame, count, what in (
            ("Tighten", tighten, counts[0], "failure probability removed"),
            ("May be relaxed", relax, counts[1], "failure probability added")):
        more = (f"; {count - len(frame)} more: every item in the allocation section"
                if count > len(frame) else "")
        if len(frame):
            parts.append(f"**{heading}** (ranked; last column: {what} per 1 % of the "
                         f"initial cost{more}):\n\n{markdown_table(frame, index=False)}")
        else:
            parts.append(f"**{heading}**: none.")
    return "\n\n".join(parts)


def choices_text(study, frame: str, reading: str, box: str, cost: str) -> str:
    """The modelling choices in one short block, each linking to its section."""
    allocation = ("Given allocation" if study.given is not None else
                  "Cheapest certified allocation" if study.reachable else
                  "Targets out of reach")
    links = {title: f"[{title}](#{anchor(title)})" for title in (
        "Machine and requirements", "FOSM reliability", allocation,
        "Continuous workspace", "Monte-Carlo verification")}
    workspace = (links["Continuous workspace"] if study.continuous is not None
                 else "the grid")
    return (f"**Modelling choices**: outputs in the {frame} "
            f"({links['Machine and requirements']}); t read as {reading} "
            f"({links['FOSM reliability']}); {study.side.replace('_', '-')}, worst case "
            f"over {workspace}; {box}; {cost} ({links[allocation]}); checked by "
            f"{links['Monte-Carlo verification']}.")
