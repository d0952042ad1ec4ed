"""The report's "What each tolerance buys" section: ``∂ yield / ∂ ln t`` of every item and
group at an allocation, as the change of the yield and of the cost when it is tightened by
10 % (docs/sensitivity.md)."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from allocation.cost.cost import CostModel
from reliability.sampling.machine_yield import DEFAULT_MACHINES, YieldModel
from reliability.sampling.yield_sensitivity import yield_sensitivity

from .extras import allocations
from .markdown import details, markdown_table
from .section import Section

#: The tightening the table speaks of: every tolerance of the row times this factor.
TIGHTENING = 0.9
#: Rows of the ranked table in the report text (the CSV holds them all).
SHOWN_ROWS = 15


def tightening_table(result, machine, tolerances) -> pd.DataFrame:
    """One row per item and group, by decreasing effect on the yield: the yield change in
    percentage points when its tolerances are tightened by 10 % (first order in ``ln t``),
    its standard error, and the relative cost change of the machine (exact, Eq. 28)."""
    costs = CostModel.from_machine(machine).item_costs(tolerances)
    step = math.log(TIGHTENING)
    index = [[machine.error_index(name) for name in row] for row in result.members]
    group_cost = np.array([costs[row].sum() for row in index])
    frame = pd.DataFrame({
        "tighten by 10 %": list(result.errors),
        "yield change [%]": 100 * step * result.dyield_dlnt,
        "se [%]": 100 * abs(step) * result.se,
        "cost change [%]": 100 * group_cost * (TIGHTENING ** -2 - 1.0) / costs.sum()})
    order = np.argsort(-np.abs(result.dyield_dlnt), kind="stable")
    return frame.iloc[order].reset_index(drop=True)


def sensitivity_section(machine, tolerances, *, label: str, points: int = 5,
                        machines: int = DEFAULT_MACHINES, rng=None) -> Section:
    """The ranked table "tighten this by 10 % → yield +x %, cost +y %" of one allocation."""
    model = YieldModel(machine, points=points)
    result = yield_sensitivity(model, tolerances, machines=machines, rng=rng)
    table = tightening_table(result, machine, tolerances)
    formats = {"yield change [%]": "{:+.3f}".format, "se [%]": "{:.3f}".format,
               "cost change [%]": "{:+.2f}".format}
    how = ("the score function on the yield's own draws" if result.method == "score" else
           "central differences on common random numbers")
    top = table.iloc[0]
    answer = (f"Tightening **{top['tighten by 10 %']}** by 10 % changes the machine yield "
              f"most at the {label} allocation: **{formats['yield change [%]'](top['yield change [%]'])} "
              f"%** (se {formats['se [%]'](top['se [%]'])} %), for "
              f"{formats['cost change [%]'](top['cost change [%]'])} % of cost.")
    method = (f"The change of the machine yield (profile {model.profile}, {model.workspace}, "
              f"{result.machines} built machines, yield {result.yield_estimate:.4f}) when the "
              f"tolerances of one item, or of a group of items no pose tells apart, are "
              f"tightened by 10 %, to first order in ln t ({how}), beside the change of the "
              f"machine's cost (Eq. 28). `se`: the standard error of the yield change. Items "
              f"whose yield change is within about two standard errors of 0 buy nothing "
              f"measurable at this number of machines.")
    text = "\n\n".join([answer, markdown_table(table.head(SHOWN_ROWS), formats, index=False),
                         details("How it is computed", method)])
    return Section(title="What each tolerance buys", text=text,
                   tables={"yield_sensitivity.csv": result.to_frame()},
                   summary={"yield_sensitivity": {"allocation": label,
                                                  "machines": result.machines,
                                                  "method": result.method}})


def study_sensitivity_section(study, *, machines: int = DEFAULT_MACHINES, rng=None) -> Section:
    """:func:`sensitivity_section` of a machine study's optimal allocation (of the initial
    one when the targets are out of reach), on the study's grid."""
    label, tolerances = list(allocations(study).items())[-1]
    return sensitivity_section(study.machine, tolerances, label=label, points=study.points,
                               machines=machines, rng=rng)
