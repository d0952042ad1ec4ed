"""The sections of a machine report, made from a
:class:`~studies.workflows.machine_study.MachineStudy`.

The answers first, then the machine and its requirements, FOSM of the initial and the
optimal allocation, the allocation with what binds, and the Monte-Carlo verification, each a
:class:`~studies.report.section.Section` that :func:`studies.report.writer.write_report`
lays out.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from allocation.elasticity import requirement_table
from allocation.result_files import MULTIPLIER_DIGITS, allocation_frame, gap_text
from reliability.display import (OUTPUT_UNITS, axis_units, pose_frame, shown_positions,
                                 top_contributors)
from reliability.files import as_written
from reliability.machine import OUTPUTS
from studies.workflows.machine_study import MachineStudy, summary, tolerance_changes

from . import plots
from .markdown import markdown_table
from .section import Section

PERCENT = "{:.3%}".format


def answers(study: MachineStudy) -> str:
    """The designer's questions answered in a few markdown bullets."""
    machine, side = study.machine, study.side
    reading = f"{side.replace('_', '-')} probability, worst case over the " \
              f"{study.points}-point grid of {len(study.problem.poses)} poses"
    worst = study.initial_fosm.worst(side)
    short = [f"{o} {PERCENT(p)} < {100 * t:g} %" for o, p, t in zip(OUTPUTS, worst, machine.targets)
             if p < t]
    meets = ("**yes**: every output meets its target" if not short else
             f"**no**: {'; '.join(short)}")
    info = summary(study)
    certified = "certified optimal" if info["certified"] else "NOT certified"
    mc = study.checks["optimum"].worst_poses
    below = mc[mc["mc_upper"] < machine.targets]
    verdict = ("every output's Monte-Carlo interval at its worst pose reaches its target"
               if below.empty else
               "Monte-Carlo at the worst pose is significantly below target for "
               + ", ".join(below["output"]))
    tighten, relax = (_changes_text(changes) for changes in tolerance_changes(study))
    return "\n".join([
        f"Choices behind every number below: outputs in the tool frame (Eq. 18); a "
        f"tolerance t read as {_reading(study.machine.distribution)} by FOSM and the "
        f"allocation (distribution '{study.machine.distribution}'), and drawn as "
        f"{_reading(study.checks['optimum'].distribution)} by the Monte-Carlo; {reading}; "
        f"workspace: the {study.points}-point grid; search box "
        f"[{study.bounds[0]:g}, {study.bounds[1]:g}] × the initial allocation; cost Eq. 28 "
        f"with t in mm and rad.\n",
        f"- Does the initial allocation meet the targets? {meets}.",
        f"- The cheapest allocation meeting them within the box [{study.bounds[0]:g}, "
        f"{study.bounds[1]:g}] × initial costs **{info['relative_cost']:.2%}** of the "
        f"initial allocation ({certified}, relative duality gap "
        f"{gap_text(study.optimum.certificate['relative_gap'])}).",
        f"- Monte-Carlo of that allocation ({info['samples']} samples at each output's "
        f"worst pose, Wilson 95 %): {verdict}; "
        + ", ".join(f"{row.output} {PERCENT(row.mc_estimate)}" for row in mc.itertuples())
        + ".",
        f"- Tighten: {tighten or 'none'}.",
        f"- May be relaxed: {relax or 'none'}.",
    ])


def _changes_text(changes: pd.Series, n: int = 6) -> str:
    """The first ``n`` relative changes as ``"X.dx (-50%), ..."``, and how many more."""
    shown = ", ".join(f"{name} ({value:+.0%})" for name, value in changes.head(n).items())
    return shown + (f" and {len(changes) - n} more" if len(changes) > n else "")


def sections(study: MachineStudy, extra=()) -> list[Section]:
    """The report's sections, answers first.

    Parameters
    ----------
    study : MachineStudy
    extra : iterable of callables
        ``extra_section(study) -> Section``, appended after the standard sections (e.g. the
        cost–reliability front or rare-event estimates).
    """
    return [Section("Answers", answers(study), summary=summary(study)),
            machine_section(study), fosm_section(study), allocation_section(study),
            verification_section(study), *(make(study) for make in extra)]


def machine_section(study: MachineStudy) -> Section:
    machine = study.machine
    strokes, units = shown_positions(np.array([a.stroke for a in machine.axis_specs]).T,
                                     axis_units(machine))
    axes = pd.DataFrame({
        "axis": [a.name for a in machine.axis_specs],
        "kind": [a.kind for a in machine.axis_specs],
        "direction": [a.direction for a in machine.axis_specs],
        "stroke_low": strokes[0], "stroke_high": strokes[1], "stroke_unit": list(units),
        "size_m": [a.size for a in machine.axis_specs]})
    requirements = pd.DataFrame({"output": list(OUTPUTS), "limit": machine.limits,
                                 "unit": list(OUTPUT_UNITS),
                                 "target": machine.targets})
    text = (f"Axes in chain order, workpiece to tool; {machine.n_errors} errors "
            f"({6 * len(machine.axes)} motion, {machine.n_errors - 6 * len(machine.axes)} "
            f"assembly).\n\n{markdown_table(axes, index=False)}\n\nRequirements: "
            f"|output| < limit with probability ≥ target, {study.side.replace('_', '-')}."
            f"\n\n{markdown_table(requirements, index=False)}")
    return Section("Machine and requirements", text,
                   tables={"axes.csv": axes, "requirements.csv": requirements})


def fosm_table(machine, result, side: str) -> pd.DataFrame:
    """Per output: worst pose as axis positions (columns ``<axis>_mm``, ``<axis>_deg``), σ
    with its unit, β, probabilities, top contributors."""
    frame = result.to_frame()
    rows = np.arange(len(OUTPUTS))
    table = pd.DataFrame({"output": list(OUTPUTS), "unit": list(OUTPUT_UNITS)})
    poses = pose_frame(result.poses[result.worst_pose], machine.axes, axis_units(machine),
                       style="csv")
    for column in poses:
        table[column] = poses[column].to_numpy()
    table["sigma"] = result.sigma[result.worst_pose, rows]
    table["beta"] = frame["beta"].to_numpy()
    table["worst_one_sided"] = frame["worst_one_sided"].to_numpy()
    table["worst_two_sided"] = frame["worst_two_sided"].to_numpy()
    table["target"] = machine.targets
    table["meets"] = frame[f"meets_{side}"].to_numpy()
    table["top_contributors"] = [top_contributors(result.contributions, o)
                                 for o in OUTPUTS]
    return table


def fosm_section(study: MachineStudy) -> Section:
    tables = {"fosm_initial.csv": fosm_table(study.machine, study.initial_fosm, study.side),
              "fosm_optimum.csv": fosm_table(study.machine, study.optimal_fosm, study.side)}
    formats = {"beta": "{:.4f}".format, "worst_one_sided": PERCENT,
               "worst_two_sided": PERCENT}
    text = (f"First-order second-moment reliability (Eqs. 19–23; tolerances read as "
            f"{_reading(study.machine.distribution)}) at each "
            f"output's worst pose of the {study.points}-point grid, given as axis positions "
            f"(mm, rotary axes in degrees); `sigma` in the output's `unit`; "
            f"`top_contributors` are the errors with the largest share of the output's "
            f"variance there.\n\n### Initial allocation\n\n"
            f"{markdown_table(tables['fosm_initial.csv'], formats, index=False)}\n\n"
            f"### Cheapest certified allocation\n\n"
            f"{markdown_table(tables['fosm_optimum.csv'], formats, index=False)}")
    return Section("FOSM reliability", text, tables=tables)


def allocation_section(study: MachineStudy) -> Section:
    optimum, machine = study.optimum, study.machine
    detail = optimum.to_frame().reset_index()
    requirements = requirement_table(optimum).reset_index()
    for column in ("dlncost/dln_limit", "dlncost/dln_target"):
        requirements[column] = as_written(requirements[column], MULTIPLIER_DIGITS)
    info = summary(study)
    text = (f"The cheapest allocation (cost model Eq. 28, k1 = k2 = k3 = 1) meeting every "
            f"target at every grid pose (Eq. 34), tolerances within [{study.bounds[0]:g}, "
            f"{study.bounds[1]:g}] × the initial allocation. Cost {optimum.cost:.6g} against "
            f"{info['initial_cost']:.6g} initially ({info['relative_cost']:.2%}); "
            f"{'certified' if info['certified'] else 'not certified'} optimum, relative "
            f"duality gap {gap_text(optimum.certificate['relative_gap'])}.\n\n"
            f"Which requirements bind, and what they cost: `dlncost/dln_limit` is the "
            f"relative cost change per relative change of the limit (from the Lagrange "
            f"multipliers; {MULTIPLIER_DIGITS} significant digits, what the dual solve "
            f"fixes), `dlncost/dln_target` the same for the target probability.\n\n"
            f"{markdown_table(requirements, index=False)}\n\n"
            f"Allocation (`rate` = allocated / initial − 1; `status` says which bound "
            f"holds):\n\n{markdown_table(detail, {'rate': '{:+.1%}'.format}, index=False)}")
    figures = {}
    n_motion = 6 * len(machine.axes)
    shown = {"initial": study.problem.reference, "certified optimum": study.allocated}
    for name, part, what in (("allocation_motion.png", slice(0, n_motion), "motion"),
                             ("allocation_assembly.png", slice(n_motion, None), "assembly")):
        figure = Figure(figsize=(max(8, 0.35 * n_motion), 4.5), layout="constrained")
        plots.plot_allocation_comparison({k: v[part] for k, v in shown.items()},
                                         names=machine.error_names[part], ax=figure.subplots(),
                                         title=f"{machine.name}: {what}-error tolerances "
                                               f"relative to the initial allocation")
        figures[name] = figure
    return Section("Cheapest certified allocation", text, figures=figures,
                   tables={"allocation.csv": allocation_frame(optimum),
                           "allocation_detail.csv": detail,
                           "requirements_elasticity.csv": requirements})


def verification_section(study: MachineStudy) -> Section:
    machine = study.machine
    grid = pd.concat({name: check.grid_comparison.set_index("output")
                      for name, check in study.checks.items()}, names=["allocation"])
    random = pd.concat({name: check.random_poses.set_index("output")
                        for name, check in study.checks.items()}, names=["allocation"])
    worst = pd.concat({name: _shown_poses(machine, check.worst_poses).set_index("output")
                       for name, check in study.checks.items()}, names=["allocation"])
    repeats = pd.concat(
        [pd.DataFrame(check.grid.fractions, columns=list(OUTPUTS))
         .assign(allocation=name, repeat=np.arange(1, check.grid.repeats + 1))
         for name, check in study.checks.items()])[["allocation", "repeat", *OUTPUTS]]
    percent = {c: PERCENT for c in ("fosm_two_sided", "mc_estimate", "mc_lower", "mc_upper",
                                    "fosm_worst_two_sided", "estimate", "lower", "upper")}
    check = study.checks["optimum"]
    text = "\n\n".join([
        f"Errors drawn as {_reading(check.distribution)}; FOSM beside them with the same "
        f"reading. Three checks of the FOSM prediction, each with a 95 % interval:",
        f"Grid experiments ({check.grid.repeats} per allocation, {check.grid.n_poses} poses "
        f"each; one error draw per experiment shared by its poses): mean share of poses in "
        f"tolerance, Wilson interval on the effective sample size from the spread between "
        f"experiments, beside the grid mean of the "
        f"FOSM two-sided probability.",
        markdown_table(grid.reset_index()[["allocation", "output", "fosm_two_sided",
                                           "mc_estimate", "mc_lower", "mc_upper",
                                           "fosm_worst_two_sided"]], percent, index=False),
        "Random poses (independent: a uniform pose and fresh errors per sample), Wilson "
        "interval, beside FOSM averaged over the same poses:",
        markdown_table(random.reset_index()[["allocation", "output", "fosm_two_sided",
                                             "estimate", "lower", "upper"]], percent,
                       index=False),
        "At each output's FOSM worst grid pose (mm, rotary axes in degrees), Wilson "
        "interval, beside FOSM and the exact probability of the linearised output "
        "(`exact_linear`; equal to FOSM under the normal reading):",
        markdown_table(worst.reset_index()[["allocation", "output", *pose_columns_of(machine),
                                            "fosm_two_sided", "exact_linear", "mc_estimate",
                                            "mc_lower", "mc_upper"]],
                       {**percent, "exact_linear": PERCENT}, index=False)])
    return Section("Monte-Carlo verification", text,
                   figures=_verification_figures(study, grid, repeats),
                   tables={"fosm_vs_mc.csv": grid, "random_pose.csv": random,
                           "worst_pose_mc.csv": worst,
                           "grid_repeats.csv": repeats.set_index(["allocation", "repeat"])})


def pose_columns_of(machine) -> list[str]:
    """The CSV column names of a pose of ``machine``: ``X_mm``, ``A_deg``, …"""
    return list(pose_frame(np.zeros((1, len(machine.axes))), machine.axes,
                           axis_units(machine), style="csv").columns)


def _shown_poses(machine, frame: pd.DataFrame) -> pd.DataFrame:
    """``frame`` with its axis columns (model units) replaced by ``X_mm``, ``A_deg``, …"""
    shown = pose_frame(frame[list(machine.axes)].to_numpy(), machine.axes,
                       axis_units(machine), style="csv")
    out = frame.drop(columns=list(machine.axes))
    for i, column in enumerate(shown):
        out.insert(1 + i, column, shown[column].to_numpy())
    return out


def _reading(distribution: str) -> str:
    """A reading of a tolerance t, in words."""
    return ("a normal error with σ = t/3 truncated at ±t" if distribution == "truncated"
            else "a normal error with σ = t/3")


def _verification_figures(study, grid, repeats) -> dict:
    machine, figures = study.machine, {}
    figure = Figure(figsize=(7 * len(study.checks), 4.5), layout="constrained")
    axes = figure.subplots(1, len(study.checks), sharey=True, squeeze=False).ravel()
    for ax, name in zip(axes, study.checks):
        plots.plot_reliability_comparison(grid.loc[name].reset_index(),
                                          target=float(machine.targets.min()), ax=ax)
        ax.set_title(f"{name} allocation: grid-mean FOSM vs\n"
                     f"{study.checks[name].grid.repeats} grid experiments")
    figures["fosm_vs_mc.png"] = figure
    figure = Figure(figsize=(11, 4.5), layout="constrained")
    plots.plot_repeats(repeats, by="allocation", target=float(machine.targets.min()),
                       ax=figure.subplots())
    figures["grid_repeats.png"] = figure
    values = study.checks["optimum"].grid.values[0]
    for index, output in enumerate(OUTPUTS):
        figure = Figure(figsize=(9, 4.5), layout="constrained")
        ax = figure.subplots()
        plots.plot_comprehensive_error_scatter(values[:, index], machine.limits[index],
                                               output_label=output, ax=ax)
        ax.set_title(f"{ax.get_title()}\n{machine.name}, certified optimum, grid "
                     f"experiment 1")
        figures[f"scatter_{output}.png"] = figure
    return figures
