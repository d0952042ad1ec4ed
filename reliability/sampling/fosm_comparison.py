"""FOSM prediction beside Monte-Carlo reliability.

What FOSM predicts for a grid experiment. The share of the grid's poses within the limit
in one experiment has, by linearity of expectation, the mean over the poses of each pose's
probability. So the like-with-like prediction of the Monte-Carlo mean fraction is the FOSM
probability *averaged over the same poses*; the worst-pose value is what the allocation
constraint (Eq. 35) holds, and is reported beside it.

Where the paper's one-sided FOSM is optimistic. ``Φ(β)`` counts one tail of ``|y| > I``;
the exact two-sided probability is ``2Φ(β) − 1`` at zero mean, so the one-sided reading
halves the failure probability: a pose it rates at 99 % is really at 98 %, and the paper's
99 % target corresponds to β = 2.326 where the honest target needs β = 2.576.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..basics import checks
from ..basics.errors import InputError
from ..first_order.fosm import FosmResult
from ..model.machine import OUTPUTS
from .experiment_results import GridExperimentResult


def fosm_versus_monte_carlo(fosm_result, grid_result, confidence: float = 0.95
                            ) -> pd.DataFrame:
    """Per output: FOSM (worst pose and grid mean, both sides) and the grid Monte-Carlo.

    Parameters
    ----------
    fosm_result : FosmResult
        FOSM of the allocation on the grid poses of the experiment.
    grid_result : GridExperimentResult
        Repeated grid experiments of the same allocation.
    confidence : float
        Level of the Monte-Carlo interval.

    Returns
    -------
    pandas.DataFrame
        Columns ``output, limit, fosm_worst_one_sided, fosm_worst_two_sided,
        fosm_one_sided, fosm_two_sided`` (grid means), ``mc_estimate, mc_lower, mc_upper``
        (mean over experiments and its Wilson score interval on Kish's effective sample
        size, :meth:`GridExperimentResult.reliability`; always inside [0, 1], and of
        non-zero width even when every experiment is entirely in tolerance),
        ``mc_min, mc_max`` and ``two_sided_within`` (the grid-mean two-sided FOSM lies in
        the interval). ``frame.attrs["mc_interval"]`` names the interval.
    """
    checks.instance(fosm_result, "fosm_result", FosmResult)
    checks.instance(grid_result, "grid_result", GridExperimentResult)
    if len(fosm_result.poses) != grid_result.n_poses:
        raise InputError(f"FOSM was computed on {len(fosm_result.poses)} poses but the grid "
                         f"experiment has {grid_result.n_poses}")
    if not np.array_equal(fosm_result.limits, grid_result.limits):
        raise InputError(f"FOSM limits {fosm_result.limits} differ from the grid "
                         f"experiment's {grid_result.limits}")
    mc = grid_result.reliability(confidence)
    frame = pd.DataFrame({
        "output": list(OUTPUTS),
        "limit": fosm_result.limits,
        "fosm_worst_one_sided": fosm_result.worst("one_sided"),
        "fosm_worst_two_sided": fosm_result.worst("two_sided"),
        "fosm_one_sided": fosm_result.workspace_mean("one_sided"),
        "fosm_two_sided": fosm_result.workspace_mean("two_sided"),
        "mc_estimate": mc.estimate,
        "mc_lower": mc.lower,
        "mc_upper": mc.upper,
        "mc_min": mc.minimum,
        "mc_max": mc.maximum,
    })
    frame["two_sided_within"] = frame["fosm_two_sided"].between(frame["mc_lower"],
                                                                 frame["mc_upper"])
    frame.attrs["mc_interval"] = (f"{confidence:.0%} Wilson score interval on Kish's "
                                  f"effective sample size")
    return frame
