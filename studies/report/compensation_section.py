"""The report's "After compensation" section: the cheapest allocation for machines measured
under a plan and compensated, beside the one without compensation; what compensation lets
the designer relax and what it cannot, and why (docs/compensation.md)."""

from __future__ import annotations

from allocation.per_pose.compensated import allocate_compensated
from reliability.basics.display import error_units, unit_symbol
from reliability.basics.display import (decimals_text, percentage_text,
                                        tolerance_numbers)
from reliability.model.iso_names import plain_names

from .markdown import details, markdown_table
from .section import Section

TITLE = "After compensation"
#: Rows of the relaxed and tight tables in the report text (the CSV holds every item).
SHOWN_ROWS = 12


def compensation_section(study, plan, plan_name: str) -> Section:
    """The section of ``plan`` on the study's poses, box and side."""
    found = allocate_compensated(study.problem, plan)
    items = found.items()
    without = found.result.problem.solve_exact().tolerances if study.optimum is None else \
        study.optimum.tolerances
    items.insert(3, "without compensation", without)
    items["change"] = items["allocated"] / items["without compensation"] - 1.0
    table = items[["error", "iso", "without compensation", "allocated", "upper", "change",
                   "seen", "posterior_share", "limited_by"]]
    shown = _for_people(table, study.problem.machine)
    relaxed = shown[table["change"] > 1e-6].sort_values("change", ascending=False,
                                                       kind="stable")
    tight = shown[table["limited_by"].isin(("targets", "lower bound"))]
    formats = {"posterior_share": "{:.4g}".format, "change": percentage_text}
    text = "\n\n".join([
        _answer(found),
        f"**What compensation lets you relax** ({len(relaxed)} items; the largest; "
        f"tolerances in the machine file's units, `compensation.csv` in mm and rad):",
        markdown_table(relaxed.head(SHOWN_ROWS), formats, index=False),
        _tight_text(tight), markdown_table(tight.head(SHOWN_ROWS), formats, index=False)
        if len(tight) else "",
        details("How it is computed", _method(found, plan, plan_name,
                                              len(study.problem.poses)) + " " + _model_text())])
    return Section(TITLE, text, tables={"compensation.csv": table},
                   summary={"compensation_cost_ratio": found.cost / found.cost_without,
                            "compensation_lower_bound_ratio":
                                found.lower_bound / found.cost_without,
                            "compensation_feasible": bool(found.feasible)})


def _for_people(table, machine):
    """The items with their plain names and the unit of each tolerance (the machine file's,
    :func:`~reliability.basics.display.people_units`), tolerances shown in it
    (:func:`~reliability.basics.display.tolerance_numbers`)."""
    units = error_units(table["error"], machine.cost_coefficients.units)
    shown = table.copy()
    for column in ("without compensation", "allocated", "upper"):
        shown[column] = tolerance_numbers(table[column], units)
    shown.insert(2, "name", plain_names(machine))
    shown.insert(3, "unit", [unit_symbol(u) for u in units])
    return shown


def _answer(found) -> str:
    return (f"After compensation the cheapest allocation found costs "
            f"**{found.cost / found.cost_without:.4f} ×** the certified optimum without "
            f"compensation, and meets every target at every pose: "
            f"{'yes' if found.feasible else 'NO'}.")


def _method(found, plan, plan_name, poses) -> str:
    return (f"Machines measured under `{plan_name}` ({len(plan.runs)} runs), identified and "
            f"compensated ({int(plan.tabled.sum())} of {len(plan.tabled)} items tabled, every "
            f"{plan.spacing_mm:g} mm and {plan.spacing_deg:g} degrees); both allocations on "
            f"the same {poses} poses and box, with a certified lower bound of "
            f"{decimals_text(found.lower_bound / found.cost_without, 4, 'lower')} × on the "
            f"cost ratio.")


def _tight_text(tight) -> str:
    if not len(tight):
        return ("**What compensation cannot relax:** nothing stays below its upper bound; the "
                "box (and the table's range) is what limits every item.")
    unseen = int((~tight["seen"]).sum())
    seen = (f"; the other {len(tight) - unseen} are seen, but only in combinations or through "
            f"noise that leaves them part of their prior (`posterior_share`: posterior σ over "
            f"prior σ at the allocation)") if unseen < len(tight) else ""
    return (f"**What stays tight** ({len(tight)} items kept below their upper bound): "
            f"{unseen} of them are not seen by the plan at all — every run has its own "
            f"instrument zeros, so an error that moves or turns the tool by the same amount at "
            f"every pose of a run (a constant translation the rotary axes do not turn) is "
            f"never identified and no table holds it; it keeps its prior{seen}.")


def _model_text() -> str:
    return ("The residual error is the posterior error of the identification, plus what lies "
            "between table points and beyond the table's range, plus each linear axis' "
            "repeatability and reversal (σ_R² + B²/4 on its positioning error), which no "
            "table removes; the numbers without compensation carry neither. The bracket's "
            "lower end relaxes the informed items to their posterior at the tightest "
            "tolerances. See docs/compensation.md.")
