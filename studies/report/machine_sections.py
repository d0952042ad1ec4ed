"""The sections of a machine report, made from a
:class:`~studies.workflows.machine_study.MachineStudy`.

The answers first, then the machine yield (the share of built machines within every limit
everywhere) and what decides it, the machine and its requirements, FOSM of the initial and the
optimal allocation, the allocation with what binds, and the Monte-Carlo verification, each a
:class:`~studies.report.section.Section` that :func:`studies.report.writer.write_report`
lays out.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from matplotlib.figure import Figure
from scipy.stats import norm

from allocation.per_pose.elasticity import requirement_table, requirement_text
from allocation.per_pose.result_files import (DRAWING_FILE, MULTIPLIER_DIGITS, allocation_frame,
                                     cost_shares_text, cost_units_text, drawing_check_text,
                                     drawing_frame, gap_text, nearly_free_text,
                                     written_cost_text, written_tolerances)
from reliability.basics.display import (OUTPUT_UNITS, axis_units, error_units, in_units,
                                        output_people_units, percentage_text, pose_frame,
                                        shown_positions, tolerance_numbers,
                                        top_contributors, unit_symbol, with_positions)
from reliability.basics.files import SIGNIFICANT, as_written, rounded_up
from reliability.model.identifiability import EQUAL_RTOL, indistinguishable_groups
from reliability.model.iso_names import plain_names
from reliability.model.machine import OUTPUTS
from studies.workflows.machine_study import UNCHANGED, MachineStudy, summary

from . import glance, plots
from .markdown import (details, interval_formats, markdown_table, percent_bound,
                       significant_bound)
from .section import Section
from .writer import merged_summary
from .yield_section import yield_section, yield_sentence

PERCENT = "{:.3%}".format
#: How the advice names a group of errors that cannot be told apart.
GROUP_WORD = "group"
#: Each allocation of a study in words.
ALLOCATION_WORDS = {"initial": "initial allocation", "optimum": "certified optimum",
                    "given": "given allocation"}
#: Entries of each advice list shown before "and K more".
ADVICE_SHOWN = 10


def answers(study: MachineStudy) -> str:
    """The designer's questions answered in a few markdown bullets (what ``precrel report``
    prints; the report's first section is :func:`answers_section`)."""
    held = "the optimum's targets hold" if study.given is None else "worst poses sought"
    choices = (f"Choices behind every number below: outputs in the {_frame_text(study)}; a "
               f"tolerance t read as {_reading(study.machine.distribution)} by FOSM and the "
               f"allocation (distribution '{study.machine.distribution}') and drawn as "
               f"{_reading(next(iter(study.checks.values())).distribution)} by the "
               f"Monte-Carlo; {_grid_reading(study)}; workspace: {held} "
               f"{study.workspace_text()}; {box_text(study)}; cost Eq. 28, "
               f"{cost_units_text(study.problem.cost)}.\n")
    meets = f"- Does the initial allocation meet the targets? {meets_text(study)}."
    if study.given is not None:
        return "\n".join([choices, yield_sentence(study), meets, f"- {given_sentence(study)}"])
    if not study.reachable:
        return "\n".join([choices, yield_sentence(study), meets, unreachable_text(study)])
    tighten, relax = advice(study, study.optimum.nearly_free())
    before, after = _advice_notes(study, tighten + relax)
    return "\n".join([choices, yield_sentence(study), meets, f"- {cost_sentence(study)}",
                      *before, f"- Tighten: {tighten or 'none'}.",
                      f"- May be relaxed: {relax or 'none'}.", *after])


def answers_section(study: MachineStudy, later) -> Section:
    """The report's first screen (:mod:`studies.report.glance`): the answers as a table of
    numbers beside the outputs figure, the advice as tables, the modelling choices with
    links to the ``later`` sections, whose summary entries the table reads too."""
    info = summary(study)
    rows = glance.glance_rows(study, merged_summary(info, later), meets_text(study))
    choices = glance.choices_text(study, _frame_text(study),
                                  _reading(study.machine.distribution),
                                  box_text(study), cost_units_text(study.problem.cost))
    if study.given is not None:
        return glance.answers_section(study, rows, given_sentence(study), "", choices, info)
    if not study.reachable:
        return glance.answers_section(study, rows, unreachable_text(study)[2:], "",
                                      choices, info)
    free = study.optimum.nearly_free()
    tighten, relax, rates, ratios, groups = _advice_orders(study, free)
    table = tolerance_table(study.machine, study.problem.reference,
                            study.optimum.tolerances).set_index("error")
    tables = [glance.advice_table(table, order, rates, ratios, groups, ADVICE_SHOWN)
              for order in (tighten, relax)]
    before, after = _advice_notes(study, " ".join(
        " ".join(frame["item"]) for frame in tables))
    notes = "\n".join([f"- {cost_sentence(study)}", *before, *after])
    return glance.answers_section(
        study, rows, glance.advice_text(*tables, (len(tighten), len(relax))), notes,
        choices, info)


def meets_text(study: MachineStudy) -> str:
    """Whether the initial allocation meets the targets: ``**yes**: every output meets its
    target``, or ``**no**: dx 98.680% < 99 %; …``."""
    worst = study.initial_fosm.worst(study.side)
    short = [f"{o} {PERCENT(p)} < {100 * t:g} %"
             for o, p, t in zip(OUTPUTS, worst, study.machine.targets) if p < t]
    return ("**yes**: every output meets its target" if not short else
            f"**no**: {'; '.join(short)}")


def given_sentence(study: MachineStudy) -> str:
    """What the given allocation is, what it costs and whether it meets the targets."""
    info = summary(study)
    meets = "meets" if info["given_meets_targets"] else "does **not** meet"
    return (f"The report studies **the given allocation** ({study.given}) beside the "
            f"initial one, not an optimum: it costs **{info['given_relative_cost']:.2%}** "
            f"of the initial allocation and {meets} every target at every grid pose.")


def cost_sentence(study: MachineStudy) -> str:
    """What the cheapest allocation in the box costs, and its certificate."""
    info = summary(study)
    certified = "certified optimal" if info["certified"] else "NOT certified"
    return (f"The cheapest allocation meeting them within the box costs "
            f"**{info['relative_cost']:.2%}** of the initial allocation ({certified}, "
            f"relative duality gap {gap_text(study.optimum.certificate['relative_gap'])}).")


def _frame_text(study: MachineStudy) -> str:
    return ("tool frame (Eq. 18, turning with the rotary axes)"
            if study.machine.frame == "tool" else "workpiece frame (δ_w = R δ_t, ε_w = R ε_t)")


def _grid_reading(study: MachineStudy) -> str:
    return (f"{study.side.replace('_', '-')} probability, worst case over the "
            f"{study.points}-point grid of {len(study.problem.poses)} poses")


def _advice_notes(study: MachineStudy, advised: str) -> tuple[list[str], list[str]]:
    """The bullets before the advice (the Monte-Carlo verdict, the nearly free items) and
    after it (how the advice is ranked and, when ``advised`` names a group, what a group
    is)."""
    machine, free = study.machine, study.optimum.nearly_free()
    mc = study.checks["optimum"].worst_poses
    below = mc[mc["mc_upper"] < machine.targets]
    verdict = ("every output's Monte-Carlo interval at its worst pose reaches its target"
               if below.empty else
               "Monte-Carlo at the worst pose is significantly below target for "
               + ", ".join(below["output"]))
    notes = [f"- Monte-Carlo of that allocation ({summary(study)['samples']} samples at each "
             f"output's {_sampled_pose(study)}, Wilson 95 %): {verdict}; "
             + ", ".join(f"{row.output} {PERCENT(row.mc_estimate)}"
                         for row in mc.itertuples()) + "."]
    if free:
        notes.append(
            f"- {len(free)} items sit at a bound carrying under 0.1 % of the cost each "
            f"(nearly free with t in {' and '.join(study.problem.cost.units or ('mm', 'rad'))}"
            f" inside the cost): their tolerance is decided by the box, not by cost, so "
            f"they are left out of the advice below.")
    after = [RANKING_NOTE]
    if GROUP_WORD in advised:
        after.append("- A group is a set of errors that cannot be told apart (the allocation "
                     "section's table): only their summed variance matters, so none of them "
                     "can be changed alone; the cost decides how the group's variance is "
                     "shared.")
    return notes, after


RANKING_NOTE = (
    "- Ranked by what each change buys at the initial allocation (FOSM at each output's "
    "worst grid pose, initial tolerances → optimum in the machine file's units): the "
    "failure probability, summed over the six outputs, removed per 1 % of the initial cost "
    "spent tightening the item (tighten: largest first), or added per 1 % saved relaxing "
    "it (relax: smallest first); the first ten of each list are shown.")


def _sampled_pose(study: MachineStudy) -> str:
    """Which worst pose the optimum's Monte-Carlo samples."""
    if study.continuous is not None and study.continuous.certificate is not None:
        return "certified worst pose over the continuous workspace"
    return f"worst pose of the {study.points}-point grid"


def box_text(study: MachineStudy) -> str:
    """The search box and where it comes from, e.g. ``search box [0.5, 1.5] × the initial
    allocation (the default; the machine file has no [bounds])``."""
    source = {"machine file": "",
              "factors of the initial allocation": " (the default; the machine file has no "
                                                   "[bounds])",
              "given": " (from --bounds)"}[study.problem.bounds_source]
    return f"search box {study.problem.box_text()}{source}"


def unreachable_text(study: MachineStudy) -> str:
    """Why no allocation in the box meets the targets, and the box that would."""
    factor = study.problem.reaching_factor()
    return (f"- **No allocation inside the box ({study.problem.box_text()}) meets the "
            f"targets**: {study.unreachable}. The largest "
            f"lower-bound factor that reaches them is **{factor:.4g}** (all tolerances at "
            f"{factor:.4g} × the initial allocation just meet every target): rerun with "
            f"`--bounds LO HI` and LO ≤ {factor:.4g}.")


def unreachable_section(study: MachineStudy) -> Section:
    """What blocks the targets: every blocked (output, pose), worst first."""
    machine = study.machine
    blocking = shown_poses(machine, study.unreachable.blocking)
    text = (f"{unreachable_text(study)[2:]}\n\nBlocked requirements with every tolerance "
            f"at the box's lower bound (σ in mm or rad, the output's unit; poses in mm and "
            f"degrees), worst first; {len(blocking)} in all, the first 20 shown:\n\n"
            f"{markdown_table(blocking.head(20), index=False)}")
    return Section("Targets out of reach", text, tables={"blocking.csv": blocking})


def advice(study: MachineStudy, free=(), n: int = ADVICE_SHOWN) -> tuple[str, str]:
    """The tighten and the relax advice of the answers, ranked by what each change buys,
    e.g. ``"X.ex (EAX X roll, 2.9 → 1.2 arcsec, -57%; 0.0031 per 1 % of cost); the dz group
    1 (9 items: C.dz, Y.dz, X.dz, …; +58% in root-sum-square; 2e-06 per 1 % of cost); …
    and K more"``.

    Errors that cannot be told apart (:func:`groups_table`) are one entry, changed by the
    root-sum-square of their tolerances, since only their summed variance reaches the
    outputs; errors in ``free`` are left out. Entries change by more than
    :data:`~studies.workflows.machine_study.UNCHANGED`. Tightening is ranked by
    :func:`buy_ratios` largest first (the most failure probability removed per unit of
    cost), relaxing smallest first (the most cost saved per unit of failure probability
    added); the first ``n`` of each are shown.
    """
    tighten, relax, rates, ratios, groups = _advice_orders(study, free)
    return (_changes_text(study, tighten, rates, ratios, groups, n),
            _changes_text(study, relax, rates, ratios, groups, n))


def _advice_orders(study: MachineStudy, free) -> tuple:
    """The tighten and the relax entries in rank order (see :func:`advice`), with every
    entry's relative change, :func:`buy_ratios` and the groups by name."""
    rates, groups = _advice_rates(study, free)
    ratios = buy_ratios(study, groups).reindex(rates.index)
    tighten = ratios[rates < -UNCHANGED].sort_values(ascending=False, kind="stable")
    relax = ratios[rates > UNCHANGED].sort_values(kind="stable")
    return tighten.index, relax.index, rates, ratios, groups


def buy_ratios(study: MachineStudy, groups: dict) -> pd.Series:
    """What changing each error (or group, scaled together) buys at the initial
    allocation: the failure probability, summed over the six outputs at their worst grid
    poses (FOSM), removed per 1 % of the initial cost spent on tightening it.

    With σ_o² = Σ_i (J_oi t_i / 3)², ``∂σ_o/∂ln t_i = σ_o s_oi`` (``s_oi`` the item's share
    of the variance), so ``∂(1 − P_o)/∂ln t_i = c φ(β_o) β_o s_oi`` (``c`` = 2 two-sided, 1
    one-sided), while the cost ``w_i/t_i²`` changes by ``−2 w_i/t_i²``. The same ratio read
    the other way is the failure probability added per 1 % of cost saved by relaxing.
    """
    initial = study.initial_fosm
    beta = initial.to_frame()["beta"].to_numpy()
    sides = 2.0 if study.side == "two_sided" else 1.0
    shares = initial.contributions[list(OUTPUTS)].to_numpy() / 100.0
    gain = pd.Series(sides * shares @ (norm.pdf(beta) * beta), index=study.machine.error_names)
    costs = pd.Series(study.problem.cost.item_costs(study.problem.reference),
                      index=study.machine.error_names)
    per_percent = study.problem.cost.total(study.problem.reference) / 100.0
    for name, members in groups.items():
        gain[name], costs[name] = gain[members].sum(), costs[members].sum()
    return gain / (2.0 * costs) * per_percent


def _advice_rates(study: MachineStudy, free) -> tuple[pd.Series, dict]:
    """Relative change (allocated / initial − 1) of every single error and of every group
    of errors that cannot be told apart (of the root-sum-square), and each group's
    members by its name (``"the dz group 1"``)."""
    names = study.machine.error_names
    allocated = pd.Series(study.optimum.tolerances, index=names).drop(free, errors="ignore")
    initial = pd.Series(study.problem.reference, index=names)[allocated.index]
    rates, groups = {}, {}
    for row in groups_table(study.machine, study.problem.poses).itertuples():
        members = [name for name in row.errors.split() if name in allocated.index]
        if len(members) > 1:
            name = _group_name(row.group, members)
            groups[name] = members
            rss = np.sqrt(np.sum(allocated[members] ** 2) / np.sum(initial[members] ** 2))
            rates[name] = rss - 1.0
    grouped = [member for members in groups.values() for member in members]
    for name in allocated.index.difference(grouped, sort=False):
        rates[name] = allocated[name] / initial[name] - 1.0
    return pd.Series(rates, dtype=float), groups


def _group_name(number: int, members) -> str:
    """``"the dz group 1"`` when every member is a dz error, else ``"group 1"``."""
    kinds = {name.rsplit(".", 1)[-1] for name in members}
    kind = f"the {kinds.pop()} " if len(kinds) == 1 else ""
    return f"{kind}{GROUP_WORD} {number}"


def _changes_text(study: MachineStudy, order, rates: pd.Series, ratios: pd.Series,
                  groups: dict, n: int) -> str:
    """The first ``n`` entries of ``order`` as ``"X.ex (EAX X roll, 2.9 → 1.2 arcsec,
    -57%; 0.0031 per 1 % of cost); the dz group 1 (9 items: C.dz, Y.dz, X.dz, …; +58% in
    root-sum-square; 2e-06 per 1 % of cost)"``, and how many more."""
    table = tolerance_table(study.machine, study.problem.reference,
                            study.optimum.tolerances).set_index("error")
    entries = []
    for name in list(order)[:n]:
        buys = f"{ratios[name]:.2g} per 1 % of cost"
        if name in groups:
            members = groups[name]
            shown = ", ".join(members[:3]) + (", …" if len(members) > 3 else "")
            entries.append(f"{name} ({len(members)} items: {shown}; {rates[name]:+.0%} in "
                           f"root-sum-square; {buys})")
        else:
            row = table.loc[name]
            entries.append(f"{name} ({row.iso} {row['name']}, {row.initial:.3g} → "
                           f"{row.allocated:.3g} {row.unit}, {rates[name]:+.0%}; {buys})")
    more = f" and {len(order) - n} more" if len(order) > n else ""
    return "; ".join(entries) + more


def tolerance_table(machine, reference, tolerances) -> pd.DataFrame:
    """Tolerances for people: error, ISO 230-1 symbol, plain name, unit (the machine
    file's: :func:`~reliability.basics.display.people_units`), the reference and the given
    tolerance in that unit, and the relative change (``change`` = tolerance / reference −
    1)."""
    names = machine.error_names
    units = error_units(names, machine.cost_coefficients.units)
    return pd.DataFrame({"error": names, "iso": machine.iso_names,
                         "name": plain_names(machine),
                         "unit": [unit_symbol(u) for u in units],
                         "initial": in_units(reference, units),
                         "allocated": in_units(tolerances, units),
                         "change": np.asarray(tolerances) / np.asarray(reference) - 1.0})


def shown_tolerance_table(machine, reference, tolerances) -> pd.DataFrame:
    """:func:`tolerance_table` as printed (of the tolerances as written to the allocation
    file, :func:`~allocation.per_pose.result_files.written_tolerances`, so that an item on a
    bound shows the bound): the tolerances cut to 0.001 µm or 0.001 arcsec
    in their unit (:func:`~reliability.basics.display.tolerance_numbers`), the change in
    per cent to 0.01 % with its sign (:func:`~reliability.basics.display.percentage_text`)."""
    table = tolerance_table(machine, reference, tolerances)
    units = error_units(machine.error_names, machine.cost_coefficients.units)
    return table.assign(initial=tolerance_numbers(reference, units),
                        allocated=tolerance_numbers(tolerances, units),
                        change=[("+" if v > 0 else "") + percentage_text(v)
                                for v in table["change"]])


def sections(study: MachineStudy, extra=()) -> list[Section]:
    """The report's sections, answers first.

    Parameters
    ----------
    study : MachineStudy
    extra : iterable of callables
        ``extra_section(study) -> Section``, appended after the standard sections (e.g. the
        cost–reliability front or rare-event estimates).
    """
    allocation = (allocation_section(study) if study.reachable else
                  given_section(study) if study.given is not None else
                  unreachable_section(study))
    workspace = [workspace_section(study)] if study.continuous is not None else []
    later = [yield_section(study), machine_section(study), fosm_section(study), allocation,
             *workspace, verification_section(study), *(make(study) for make in extra)]
    return [answers_section(study, later), *later]


def workspace_section(study: MachineStudy) -> Section:
    """How the optimum was certified over the continuous workspace: the statement, the
    poses added to the grid, the certificate per output (docs/continuous-allocation.md)."""
    continuous = study.continuous
    machine = study.machine
    answer = (f"The optimum over the continuous workspace costs "
              f"**{continuous.cost_ratio:.6g} ×** the grid optimum's; "
              f"{continuous.statement}.")
    method = (f"Starting from the {study.points}-point grid, the worst pose of every output "
              f"short of its target (found by a local search, then by the certificate's "
              f"branch and bound over the whole stroke box) was added as a constraint and the "
              f"problem solved again: {continuous.solves} convex solve(s), "
              f"{len(continuous.added)} pose(s) added, {continuous.certificate_calls} "
              f"certificate call(s).")
    text = answer
    tables = {}
    if len(continuous.added):
        tables["workspace_added_poses.csv"] = continuous.added
        text += ("\n\nPoses added (mm, rotary axes in degrees; `ratio` is σ there over "
                 "the σ the target allows, at the solve before it was added):\n\n"
                 + markdown_table(continuous.added, index=False))
    if continuous.certificate is not None:
        table = continuous.certificate.reset_index()
        poses = pose_frame(table[list(machine.axes)].to_numpy(dtype=float), machine.axes,
                           axis_units(machine), style="csv")
        value, bound = ("stack", "stack_bound") if study.side == "stack" else \
            ("sigma", "sigma_bound")
        shown = pd.concat([table[["output"]], poses,
                           table[[value, bound, "allowed", "excess", "gap", "certified",
                                  "calls"]]], axis=1)
        shown.insert(1, "unit", list(OUTPUT_UNITS))
        # the certified bound is written rounded up, so the file's bound still bounds
        tables["workspace_certificate.csv"] = shown.assign(
            **{bound: rounded_up(shown[bound].to_numpy(dtype=float), SIGNIFICANT)})
        text += ("\n\nThe certificate at the optimum (`allowed`: the σ the target allows; "
                 "`excess`: bound / allowed − 1; `gap`: the certificate's own bound / σ − 1):"
                 "\n\n" + markdown_table(shown, interval_formats(
                     significant_bound(5), upper=(bound, "excess", "gap")), index=False))
    text += "\n\n" + details("How it is certified", method)
    entries = {"workspace_certified": continuous.certified, "workspace_rtol": continuous.rtol,
               "workspace_solves": continuous.solves,
               "workspace_certificate_calls": continuous.certificate_calls,
               "workspace_cost_ratio": continuous.cost_ratio}
    return Section("Continuous workspace", text, tables=tables, summary=entries)


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
            f"\n\n{markdown_table(in_people_units(machine, requirements, 'limit'), index=False)}")
    return Section("Machine and requirements", text,
                   tables={"axes.csv": axes, "requirements.csv": requirements})


def fosm_table(machine, result, side: str) -> pd.DataFrame:
    """Per output: worst pose as axis positions (columns ``<axis>_mm``, ``<axis>_deg``), σ
    with its unit, β, probabilities, top contributors."""
    frame = result.to_frame()
    rows = np.arange(len(OUTPUTS))
    table = pd.DataFrame({"output": list(OUTPUTS), "frame": result.frame,
                          "unit": list(OUTPUT_UNITS)})
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
    tables = {"fosm_initial.csv": fosm_table(study.machine, study.initial_fosm, study.side)}
    if study.reachable:
        tables["fosm_optimum.csv"] = fosm_table(study.machine, study.optimal_fosm, study.side)
    if study.given is not None:
        tables["fosm_given.csv"] = fosm_table(study.machine, study.given_fosm, study.side)
    formats = {"beta": "{:.4f}".format, "worst_one_sided": PERCENT,
               "worst_two_sided": PERCENT}
    method = (f"First-order second-moment reliability (Eqs. 19–23; tolerances read as "
              f"{_reading(study.machine.distribution)}) at each "
              f"output's worst pose of the {study.points}-point grid, given as axis "
              f"positions (mm, rotary axes in degrees); `sigma` in the output's `unit` (the "
              f"machine file's units here, mm and rad in the CSV files); "
              f"`top_contributors` are the errors with the largest share of the output's "
              f"variance there.")
    text = f"{fosm_sentence(tables)}\n\n" + details("What the columns are", method)
    for name, heading in (("fosm_initial.csv", "Initial allocation"),
                          ("fosm_optimum.csv", "Cheapest certified allocation"),
                          ("fosm_given.csv", "Given allocation")):
        if name in tables:
            shown = in_people_units(study.machine, tables[name], "sigma")
            text += f"\n\n### {heading}\n\n{markdown_table(shown, formats, index=False)}"
    return Section("FOSM reliability", text, tables=tables)


def fosm_sentence(tables: dict) -> str:
    """How many outputs each allocation's FOSM table finds short of their targets at their
    worst grid pose, and which."""
    names = {"fosm_initial.csv": "initial", "fosm_optimum.csv": "certified optimum",
             "fosm_given.csv": "given"}
    parts = []
    for name, table in tables.items():
        short = list(table.loc[~table["meets"].astype(bool), "output"])
        parts.append(f"{names[name]} allocation **{len(short)} of 6**"
                     + (f" ({', '.join(short)})" if short else ""))
    return "Outputs short of their targets at their worst grid pose: " + "; ".join(parts) + "."


def allocation_section(study: MachineStudy) -> Section:
    optimum, machine = study.optimum, study.machine
    groups = groups_table(machine, study.problem.poses)
    written = written_tolerances(optimum)
    detail = optimum.to_frame().reset_index()
    # the rate of the tolerance as written: a solve fixes a tolerance's sixth digit, not
    # the sixth digit of its change
    detail["allocated"] = written
    detail["rate"] = written / study.problem.reference - 1.0
    people = shown_tolerance_table(machine, study.problem.reference, written)
    people["status"] = detail["status"].to_numpy()
    requirements = requirement_table(optimum).reset_index()
    for column in requirements.columns[requirements.columns.str.startswith("dlncost/")]:
        requirements[column] = as_written(requirements[column], MULTIPLIER_DIGITS)
    info = summary(study)
    method = (f"The cheapest allocation (cost model Eq. 28, k1 = k2 = k3 = 1) meeting every "
              f"target at every grid pose (Eq. 34), tolerances within the box "
              f"({box_text(study)}). Cost {optimum.cost:.6g} against "
              f"{info['initial_cost']:.6g} initially; relative duality gap "
              f"{gap_text(optimum.certificate['relative_gap'])}.\n\n"
              f"`dlncost/dln_limit` is the "
              f"relative cost change per relative change of the limit (from the Lagrange "
              f"multipliers; {MULTIPLIER_DIGITS} significant digits, what the dual solve "
              f"fixes), `dlncost/dln_target` the same for the target probability. Where "
              f"outputs bind together (equal or dependent constraint gradients, e.g. at "
              f"symmetric poses) only "
              f"their joint change is determined: such an output shows the cost's change "
              f"when its limit alone is relaxed and when it is tightened, `bound_with` names "
              f"the group and `dlncost/dln_group_limit` gives relaxing the group's limits "
              f"together (docs/non-unique.md; all in `requirements_elasticity.csv`).")
    text = "\n\n".join([
        cost_sentence(study).replace("The cheapest allocation meeting them",
                                     "The cheapest allocation meeting the targets"),
        f"Allocation in the machine file's units (`change` = allocated / initial − 1; "
        f"`status` says which bound holds; `allocation.csv` and `allocation_detail.csv` "
        f"hold mm and rad):", markdown_table(people, index=False),
        "Which requirements bind, and what they cost:",
        markdown_table(requirement_text(optimum).reset_index(), index=False),
        details("How the allocation is found and what the columns mean", method),
        cost_text(study), drawing_text(study),
        details("Errors that cannot be told apart", groups_text(machine, groups))])
    figures = allocation_figures(machine, {"initial": study.problem.reference,
                                           "certified optimum": study.allocated})
    return Section("Cheapest certified allocation", text, figures=figures,
                   tables={"allocation.csv": allocation_frame(optimum, SIGNIFICANT),
                           "allocation_detail.csv": detail,
                           "requirements_elasticity.csv": requirements,
                           "indistinguishable_groups.csv": groups,
                           DRAWING_FILE: drawing_frame(machine, optimum.tolerances)})


def allocation_figures(machine, shown: dict) -> dict:
    """The motion and the assembly errors' tolerances of ``shown`` (label -> tolerances,
    the initial allocation first) relative to the initial ones (the paper's Figs. 8–9)."""
    figures, n_motion = {}, 6 * len(machine.axes)
    for name, part, what in (("allocation_motion.png", slice(0, n_motion), "motion"),
                             ("allocation_assembly.png", slice(n_motion, None), "assembly")):
        figure = Figure(figsize=(max(8, 0.35 * n_motion), 4.5), layout="constrained")
        plots.plot_allocation_comparison({k: v[part] for k, v in shown.items()},
                                         names=machine.error_names[part], ax=figure.subplots(),
                                         title=f"{machine.name}: {what}-error tolerances "
                                               f"relative to the initial allocation")
        figures[name] = figure
    return figures


def given_section(study: MachineStudy) -> Section:
    """The given allocation (``--tolerances``) studied in the optimum's place: its cost
    against the initial one, whether it meets the targets, every item beside the initial
    tolerance, and the figures of the allocation section."""
    machine, info = study.machine, summary(study)
    given = study.given_tolerances
    meets = "meets" if info["given_meets_targets"] else "does **not** meet"
    people = shown_tolerance_table(machine, study.problem.reference, given)
    text = "\n\n".join([
        f"The allocation of {study.given} costs **{info['given_relative_cost']:.2%}** of "
        f"the initial allocation (cost Eq. 28, {cost_units_text(study.problem.cost)}) and "
        f"{meets} every target at every grid pose (FOSM). No allocation was sought: this "
        f"report studies the given one beside the initial one.",
        "Allocation in the machine file's units (`change` = given / initial − 1; "
        "`given_allocation.csv` holds mm and rad):", markdown_table(people, index=False)])
    frame = pd.DataFrame({"error": machine.error_names, "reference": study.problem.reference,
                          "allocated": given})
    return Section("Given allocation", text,
                   figures=allocation_figures(machine, {"initial": study.problem.reference,
                                                        "given": given}),
                   tables={"given_allocation.csv": frame})


def drawing_text(study: MachineStudy) -> str:
    """What ``drawing_tolerances.csv`` holds and how it was checked."""
    return (f"**Tolerances for drawings**: `{DRAWING_FILE}` gives every item with its ISO "
            f"230-1 symbol and plain name in µm or arcsec, "
            f"{drawing_check_text(study.optimum)}. `precrel predict`, `verify` and "
            f"`--tolerances` read it as it is.")


def in_people_units(machine, table: pd.DataFrame, column: str) -> pd.DataFrame:
    """A copy of a per-output table (one row per output, a ``unit`` column in mm or rad)
    with ``column`` and ``unit`` in the machine file's units."""
    units = output_people_units(machine.cost_coefficients.units)
    shown = table.copy()
    shown[column] = in_units(table[column].to_numpy(dtype=float), units)
    shown["unit"] = [unit_symbol(unit) for unit in units]
    return shown


def cost_text(study: MachineStudy) -> str:
    """The cost units, each group's share of the cost, and the nearly free items."""
    cost = study.problem.cost
    free = nearly_free_text(study.optimum)
    return (f"**Cost units**: {cost_units_text(cost)}. Cost shares at the initial "
            f"allocation: {cost_shares_text(cost, study.problem.reference)}; at the optimum: "
            f"{cost_shares_text(cost, study.optimum.tolerances)}."
            + (f" **{free}**." if free else "")
            + f" `allocation.csv`: {written_cost_text(study.optimum)}.")


def groups_table(machine, poses) -> pd.DataFrame:
    """The errors that cannot be told apart on ``poses``, one row per group."""
    groups = indistinguishable_groups(machine, poses)
    return pd.DataFrame({"group": np.arange(1, len(groups) + 1),
                         "size": [len(g) for g in groups],
                         "errors": [" ".join(g) for g in groups]})


def groups_text(machine, table: pd.DataFrame) -> str:
    """The report's note on :func:`groups_table`."""
    members = int(table["size"].sum())
    return (
        f"**Errors that cannot be told apart**: {members} of {machine.n_errors} errors fall "
        f"into {len(table)} groups whose sensitivities are equal at every grid pose (to "
        f"{EQUAL_RTOL:g} of the largest). Only each group's summed variance enters the "
        f"outputs, so within a group the cost alone decides how it is shared; a tolerance "
        f"set for one member can be traded for another's at no loss of reliability."
        + (f"\n\n{markdown_table(table, index=False)}" if len(table) else ""))


def verification_section(study: MachineStudy) -> Section:
    machine = study.machine
    grid = pd.concat({name: check.grid_comparison.set_index("output")
                      for name, check in study.checks.items()}, names=["allocation"])
    random = pd.concat({name: check.random_poses.set_index("output")
                        for name, check in study.checks.items()}, names=["allocation"])
    worst = pd.concat({name: shown_poses(machine, check.worst_poses).set_index("output")
                       for name, check in study.checks.items()}, names=["allocation"])
    repeats = pd.concat(
        [pd.DataFrame(check.grid.fractions, columns=list(OUTPUTS))
         .assign(allocation=name, repeat=np.arange(1, check.grid.repeats + 1))
         for name, check in study.checks.items()])[["allocation", "repeat", *OUTPUTS]]
    percent = {c: PERCENT for c in ("fosm_two_sided", "mc_estimate", "fosm_worst_two_sided",
                                    "estimate")} | interval_formats(
        percent_bound(3), lower=("mc_lower", "lower"), upper=("mc_upper", "upper"))
    check = study.checks[_last_checked(study)]
    text = "\n\n".join([
        verification_sentence(study, grid),
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


def verification_sentence(study: MachineStudy, grid: pd.DataFrame) -> str:
    """The verification's answer for the last allocation checked: for how many outputs
    the Monte-Carlo interval at the worst pose reaches the target, and for how many the
    grid mean of FOSM lies inside the grid experiments' interval (``grid``: the
    ``fosm_vs_mc.csv`` table)."""
    name = _last_checked(study)
    worst = study.checks[name].worst_poses
    reach = int((worst["mc_upper"].to_numpy() >= study.machine.targets).sum())
    own = grid.loc[name]
    inside = int(own["fosm_two_sided"].between(own["mc_lower"], own["mc_upper"]).sum())
    return (f"For the {ALLOCATION_WORDS[name]}, the Monte-Carlo interval at each output's "
            f"worst pose reaches its target for **{reach} of 6** outputs, and the grid mean "
            f"of FOSM lies inside the grid experiments' 95 % interval for **{inside} of 6**.")


def _last_checked(study: MachineStudy) -> str:
    """The optimum or the given allocation when there is one, else the initial one."""
    return next((name for name in ("optimum", "given") if name in study.checks), "initial")


def pose_columns_of(machine) -> list[str]:
    """The CSV column names of a pose of ``machine``: ``X_mm``, ``A_deg``, …"""
    return list(pose_frame(np.zeros((1, len(machine.axes))), machine.axes,
                           axis_units(machine), style="csv").columns)


def shown_poses(machine, frame: pd.DataFrame) -> pd.DataFrame:
    """:func:`~reliability.basics.display.with_positions` for ``machine``'s axes."""
    return with_positions(frame, machine.axes, axis_units(machine))


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
                                          target=float(machine.targets.min()), ax=ax,
                                          output_colours=plots.OUTPUT_COLOURS)
        ax.set_title(f"{name} allocation: grid-mean FOSM vs\n"
                     f"{study.checks[name].grid.repeats} grid experiments")
    figures["fosm_vs_mc.png"] = figure
    figure = Figure(figsize=(11, 4.5), layout="constrained")
    plots.plot_repeats(repeats, by="allocation", target=float(machine.targets.min()),
                       ax=figure.subplots(), output_colours=plots.OUTPUT_COLOURS)
    figures["grid_repeats.png"] = figure
    last = _last_checked(study)
    label = ALLOCATION_WORDS[last]
    values = study.checks[last].grid.values[0]
    for index, output in enumerate(OUTPUTS):
        figure = Figure(figsize=(9, 4.5), layout="constrained")
        ax = figure.subplots()
        plots.plot_comprehensive_error_scatter(values[:, index], machine.limits[index],
                                               output_label=output, ax=ax,
                                               colour=plots.OUTPUT_COLOURS[output])
        ax.set_title(f"{ax.get_title()}\n{machine.name}, {label}, grid experiment 1")
        figures[f"scatter_{output}.png"] = figure
    return figures
