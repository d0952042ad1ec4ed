"""What the cost units do to the paper's case: the optimum in mm/rad and in µm/arcsec.

    python -m studies.paper.units_study

The cost of an item is w / t² with t in the units ``[cost] units`` names (docs/cost-units.md).
For each choice of units and each reading of Eq. (34) this prints the certified optimum's
cost relative to Table 4, the items at a bound, the items nearly free (at a bound, under
0.1 % of the cost), the share of the initial cost carried by translational items, and how
the optimum's direction of change agrees with the paper's Table 6 (share of items moving the
same way, and the correlation of the log ratios optimum/initial and Table 6/initial).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd

import reliability
from allocation import AllocationProblem
from studies.workflows.timing import one_blas_thread

from .tables import TABLE6

#: The units compared: the paper's (its Table 7 needs them) and two designer's choices.
UNITS = (("mm", "rad"), ("um", "arcsec"), ("um", "urad"))


def units_table(sides=("one_sided", "two_sided")) -> pd.DataFrame:
    """One row per (units, side), the columns described in the module docstring."""
    machine = reliability.hobbing_machine()
    paper = machine.error_vector(TABLE6, default=None)
    rows = []
    for units in UNITS:
        costs = dataclasses.replace(machine.cost_coefficients, units=units)
        priced = dataclasses.replace(machine, cost_coefficients=costs)
        for side in sides:
            problem = AllocationProblem.build(priced, side=side)
            result = problem.solve_exact()
            status = result.to_frame()["status"]
            rows.append({"units": "/".join(units), "side": side,
                         "relative_cost": result.cost / problem.cost.total(problem.reference),
                         "at_bound": int(status.isin(["lower", "upper"]).sum()),
                         "at_lower": int((status == "lower").sum()),
                         "nearly_free": len(result.nearly_free()),
                         "translational_share": float(
                             problem.cost.shares(problem.reference)["translational"].sum()),
                         **_agreement(result.tolerances, paper, problem.reference)})
    return pd.DataFrame(rows)


def _agreement(optimum, paper, reference) -> dict:
    """Share of items moving the same way as Table 6 (unchanged counts as a direction, to
    1e-6), and the correlation of the log ratios to the reference."""
    ours = np.sign(np.round(optimum / reference - 1.0, 6))
    theirs = np.sign(np.round(paper / reference - 1.0, 6))
    correlation = np.corrcoef(np.log(optimum / reference), np.log(paper / reference))[0, 1]
    return {"same_direction_as_table6": float(np.mean(ours == theirs)),
            "log_ratio_correlation": float(correlation)}


@one_blas_thread
def main() -> int:
    print(units_table().to_string(index=False, float_format="{:.4g}".format))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
