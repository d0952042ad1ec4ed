"""How the certified optimal cost moves as one error correlation varies, for any machine.

For each coefficient the worst-case problem on the 5-point grid is solved to a certified
optimum by :func:`allocation.per_pose.correlated.solve_correlated`; the table also gives the
worst-pose reliability that the optimum designed for an uncorrelated pair actually has under
that correlation. The report section is :mod:`studies.report.correlation_section`.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from allocation.per_pose.correlated import solve_correlated
from reliability.first_order.fosm import fosm
from reliability.model.poses import workspace_grid

#: Correlation coefficients swept by default: −0.8 to 0.8 by 0.2.
VALUES = tuple(np.round(np.linspace(-0.8, 0.8, 9), 10))


def correlation_sweep(machine, pair, values=VALUES, *, side: str = "two_sided",
                      progress=None) -> pd.DataFrame:
    """Certified optimal cost of ``machine`` for each correlation of ``pair``.

    Parameters
    ----------
    machine : Machine
        Its own correlations are kept, ``pair`` is set on top.
    pair : (str, str)
        Two error names (paper names or ISO 230-1 symbols).
    values : sequence of float
        Correlation coefficients in [-1, 1].
    side : {'one_sided', 'two_sided'}
    progress : callable, optional
        ``progress(done, total)`` after each solve.

    Returns
    -------
    DataFrame
        Indexed by ``rho``: ``cost``, ``cost_vs_rho0`` (ratio to the optimum with the pair
        uncorrelated), ``dual_bound``, ``relative_gap``, ``certified``,
        ``rho0_optimum_worst_P`` (lowest worst-pose probability over the six outputs of
        the uncorrelated pair's optimum when the pair has this correlation: what ignoring
        the correlation costs in reliability).
    """
    values = [float(v) for v in values]
    poses = workspace_grid(machine)
    jacobian = machine.jacobian(poses)
    results = {}
    for done, rho in enumerate(values, 1):
        results[rho] = solve_correlated(machine.with_correlation({tuple(pair): rho}), poses,
                                        side=side)
        if progress is not None:
            progress(done, len(values))
    baseline = results[0.0] if 0.0 in results else solve_correlated(
        machine.with_correlation({tuple(pair): 0.0}), poses, side=side)
    rows = []
    for rho, result in results.items():
        check = fosm(machine.with_correlation({tuple(pair): rho}), baseline.tolerances, poses,
                     jacobian=jacobian)
        rows.append({"rho": rho, "cost": result.cost,
                     "cost_vs_rho0": result.cost / baseline.cost,
                     "dual_bound": result.dual_bound, "relative_gap": result.relative_gap,
                     "certified": result.certified,
                     "rho0_optimum_worst_P": float(check.worst(side).min())})
    return pd.DataFrame(rows).set_index("rho")
