"""How the certified optimal cost answers each requirement: elasticities of the cost.

At the optimum of Eq. (34) the worst-case rows read ``σ² (z/I)² <= 1`` with ``z`` the
required index of the target (Eq. 23). The Lagrange multipliers λ of an output's binding rows
give ``d ln F / d ln z = 2Σλ/F``; the limit ``I`` acts with the opposite sign
(``d ln F / d ln I = −2Σλ/F``, the ``elasticity`` of
:attr:`allocation.AllocationResult.requirements`), and the chain rule through ``R = Φ(z)``
(one-sided) or ``R = 2Φ(z) − 1`` (two-sided) gives the target's elasticity. One sign
convention throughout: an elasticity is ``d ln cost / d ln (requirement)``.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from scipy.stats import norm

from reliability.first_order.fosm import required_index


def requirement_table(result) -> pd.DataFrame:
    """Per output: binding rows, ``d ln cost / d ln limit`` and ``d ln cost / d ln target``.

    Parameters
    ----------
    result : AllocationResult
        An exact result (its ``requirements`` table holds the multipliers' elasticities).

    Returns
    -------
    DataFrame
        Indexed by output, columns ``binding_rows``, ``binds`` (yes/no),
        ``dlncost/dln_limit`` (negative: a looser limit is cheaper) and
        ``dlncost/dln_target`` (positive: a higher target costs more).
    """
    problem = result.problem
    requirements = result.requirements
    limit_elasticity = requirements["elasticity"].to_numpy()
    target = problem.machine.targets
    z = required_index(target, problem.side)
    slope = norm.pdf(z) * (2.0 if problem.side == "two_sided" else 1.0)  # dR/dz
    target_elasticity = -limit_elasticity * target / (z * slope)
    binding = requirements["binding_rows"].to_numpy() > 0
    return pd.DataFrame({
        "binding_rows": requirements["binding_rows"].to_numpy(),
        "binds": np.where(binding, "yes", "no"),
        "dlncost/dln_limit": limit_elasticity + 0.0,
        "dlncost/dln_target": target_elasticity + 0.0,
    }, index=requirements.index)
