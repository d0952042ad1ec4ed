"""How the certified optimal cost answers each requirement: elasticities of the cost.

At the optimum of Eq. (34) the worst-case rows read ``σ² (z/I)² <= 1`` with ``z`` the
required index of the target (Eq. 23). The Lagrange multipliers λ of an output's binding rows
give ``d ln F / d ln z = 2Σλ/F``; the limit ``I`` acts with the opposite sign
(``d ln F / d ln I = −2Σλ/F``, the ``elasticity`` of
:attr:`allocation.AllocationResult.requirements`), and the chain rule through ``R = Φ(z)``
(one-sided) or ``R = 2Φ(z) − 1`` (two-sided) gives the target's elasticity. One sign
convention throughout: an elasticity is ``d ln cost / d ln (requirement)``.

The per-output sums Σλ are not always determined by the problem: where rows of two
outputs have equal (or linearly dependent) gradients at the optimum — e.g. ``dx`` and
``dz`` binding at symmetric poses — any split of their multipliers is optimal
(:mod:`allocation.solvers.dual_face`). Each output's sum is therefore given as its range
``[min, max]`` over all optimal multipliers, which is what the cost does (Eq. F2 there):
relaxing the limit ``I`` changes the cost at ``elasticity_relax = −2 min Σλ / F``,
tightening it at ``elasticity_tighten = −2 max Σλ / F``. Where the two agree (to
:data:`UNIQUE_WIDTH`) the derivative exists and is ``elasticity``; where not,
``elasticity`` is NaN and ``bound_with`` names the outputs whose multipliers trade with
this one's (``"dx+dz"``); ``group_elasticity`` is the unique elasticity of relaxing all
of them together, when it exists.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from scipy.stats import norm

from reliability.basics.display import significant_text
from reliability.first_order.fosm import required_index
from reliability.model.machine import OUTPUTS

from ..solvers.dual_face import dual_face

#: An elasticity range narrower than this times (1 + |its largest end|) is one number: the
#: dual face is imposed to 1e-6 (:data:`allocation.solvers.dual_face.SLACK_FLOOR`), which
#: widens a determined range to about 1e-5; three significant digits are printed.
UNIQUE_WIDTH = 1e-4
#: Columns of :attr:`AllocationResult.requirements`.
REQUIREMENT_COLUMNS = ("binding_rows", "multiplier", "multiplier_min", "multiplier_max",
                       "elasticity", "elasticity_relax", "elasticity_tighten", "bound_with",
                       "group_elasticity")


def requirement_multipliers(problem, solution) -> pd.DataFrame:
    """Per output: binding rows, the range of Σλ over all optimal multipliers, elasticities.

    Parameters
    ----------
    problem : AllocationProblem
        A worst-case problem (its ``rows`` gave the solver's constraints).
    solution : ConvexSolution
        Its certified optimum.

    Returns
    -------
    DataFrame
        Indexed by output (all six), columns :data:`REQUIREMENT_COLUMNS`: ``binding_rows``
        (active rows), ``multiplier_min``/``multiplier_max`` (range of Σλ, Eq. F2 of
        :mod:`allocation.solvers.dual_face`), ``multiplier`` (Σλ where the range is one
        number, else NaN), ``elasticity_relax = −s·min/F``,
        ``elasticity_tighten = −s·max/F`` and ``elasticity`` (their common value, else NaN)
        with ``s = 2/p`` (2 for FOSM rows, 1 for stack rows), ``bound_with`` (the outputs
        whose multipliers trade with this one's, joined by ``+``; empty when unique) and
        ``group_elasticity`` (``−s Σ_group λ / F`` where that is unique, else NaN).
    """
    scale = 2.0 / problem.variable_power
    face = dual_face(problem.cost.weights, problem.rows.matrix, solution.u,
                     problem.variable(problem.lower), problem.variable(problem.upper),
                     solution.active, power=problem.variable_power)
    output = problem.rows.output[face.rows]
    to_elasticity = -scale / solution.fun
    width = UNIQUE_WIDTH / scale * solution.fun  # UNIQUE_WIDTH in multiplier units

    def narrow(low, high):
        return bool(np.isfinite(high)
                    and high - low <= width * (1.0 + scale * high / solution.fun))

    def members(outputs):
        return np.isin(output, outputs)

    ranges = np.array([face.sum_range(members([o])) for o in range(len(OUTPUTS))])
    loose = np.flatnonzero([not narrow(low, high) for low, high in ranges])
    groups = _groups(face, members, ranges, loose, width)
    frame = pd.DataFrame({"binding_rows": np.bincount(output, minlength=len(OUTPUTS)),
                          "multiplier_min": ranges[:, 0], "multiplier_max": ranges[:, 1]},
                         index=pd.Index(OUTPUTS, name="output"))
    unique = np.ones(len(OUTPUTS), dtype=bool)
    unique[loose] = False
    frame["multiplier"] = np.where(unique, ranges.mean(axis=1), np.nan)
    frame["elasticity"] = to_elasticity * frame["multiplier"] + 0.0
    frame["elasticity_relax"] = to_elasticity * frame["multiplier_min"] + 0.0
    frame["elasticity_tighten"] = to_elasticity * frame["multiplier_max"] + 0.0
    frame["bound_with"] = ""
    frame["group_elasticity"] = frame["elasticity"]
    for group in groups:
        low, high = face.sum_range(members(group))
        names = [OUTPUTS[o] for o in group]
        frame.loc[names, "bound_with"] = "+".join(names) if len(group) > 1 else ""
        frame.loc[names, "group_elasticity"] = \
            to_elasticity * 0.5 * (low + high) + 0.0 if narrow(low, high) else np.nan
    return frame[list(REQUIREMENT_COLUMNS)]


def _groups(face, members, ranges, loose, width) -> list[list[int]]:
    """The non-unique outputs joined into groups: two outputs are joined when the range of
    their summed multipliers is narrower than the two ranges together (they trade). An
    output that cannot be tightened at all (an infinite range) stays alone."""
    parent = {o: o for o in loose}
    finite = [o for o in loose if np.isfinite(ranges[o, 1])]
    for i, a in enumerate(finite):
        for b in finite[i + 1:]:
            low, high = face.sum_range(members([a, b]))
            spread = ranges[a, 1] - ranges[a, 0] + ranges[b, 1] - ranges[b, 0]
            if high - low < spread - width:
                parent[_root(parent, b)] = _root(parent, a)
    groups: dict[int, list[int]] = {}
    for o in loose:
        groups.setdefault(_root(parent, o), []).append(int(o))
    return list(groups.values())


def _root(parent, o):
    while parent[o] != o:
        o = parent[o]
    return o


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
        ``dlncost/dln_limit`` (negative: a looser limit is cheaper; NaN where the problem
        does not determine it), ``dlncost/dln_target`` (positive: a higher target costs
        more; NaN likewise), the one-sided values that always exist:
        ``dlncost/dln_limit_relax`` and ``_tighten`` (a limit raised or lowered),
        ``dlncost/dln_target_lower`` and ``_raise`` (a target lowered or raised), and
        ``bound_with`` and ``dlncost/dln_group_limit`` (see :func:`requirement_multipliers`).
        Files saved before the one-sided columns existed give them equal to the two-sided
        value.
    """
    problem = result.problem
    requirements = result.requirements
    limit = requirements["elasticity"].to_numpy(dtype=float)
    relax = _column(requirements, "elasticity_relax", limit)
    tighten = _column(requirements, "elasticity_tighten", limit)
    target = problem.machine.targets
    z = required_index(target, problem.side)
    slope = norm.pdf(z) * (2.0 if problem.side == "two_sided" else 1.0)  # dR/dz
    to_target = -target / (z * slope)  # a raised target is a tightened limit
    binding = requirements["binding_rows"].to_numpy() > 0
    return pd.DataFrame({
        "binding_rows": requirements["binding_rows"].to_numpy(),
        "binds": np.where(binding, "yes", "no"),
        "dlncost/dln_limit": limit + 0.0,
        "dlncost/dln_target": limit * to_target + 0.0,
        "dlncost/dln_limit_relax": relax + 0.0,
        "dlncost/dln_limit_tighten": tighten + 0.0,
        "dlncost/dln_target_lower": relax * to_target + 0.0,
        "dlncost/dln_target_raise": tighten * to_target + 0.0,
        "bound_with": requirements["bound_with"].to_numpy() if "bound_with" in requirements
        else "",
        "dlncost/dln_group_limit": _column(requirements, "group_elasticity", limit) + 0.0,
    }, index=requirements.index)


def _column(requirements, name, default) -> np.ndarray:
    return requirements[name].to_numpy(dtype=float) if name in requirements else default


def requirement_text(result) -> pd.DataFrame:
    """:func:`requirement_table` for people: three significant digits, and where the
    problem does not determine an elasticity its two one-sided values, e.g.
    ``"0 relaxed / -0.371 tightened"``, with ``bound_with`` and the group's elasticity.

    Parameters
    ----------
    result : AllocationResult
        An exact result.

    Returns
    -------
    DataFrame of str
        Indexed by output, columns ``binding_rows``, ``binds``, ``dlncost/dln_limit``,
        ``dlncost/dln_target``, ``bound_with``, ``dlncost/dln_group_limit``.
    """
    table = requirement_table(result)
    shown = one_or_two_sided
    group = table["dlncost/dln_group_limit"]
    return pd.DataFrame({
        "binding_rows": table["binding_rows"].astype(str), "binds": table["binds"],
        "dlncost/dln_limit": shown(*(table[f"dlncost/dln_limit{end}"]
                                     for end in ("", "_relax", "_tighten")),
                                   ("relaxed", "tightened")),
        "dlncost/dln_target": shown(*(table[f"dlncost/dln_target{end}"]
                                      for end in ("", "_lower", "_raise")),
                                    ("lowered", "raised")),
        "bound_with": table["bound_with"],
        "dlncost/dln_group_limit": [significant_text(v) if b and np.isfinite(v) else
                                    "" if not b else "not determined"
                                    for v, b in zip(group, table["bound_with"])],
    }, index=table.index)


def one_or_two_sided(values, lows, highs, words=("relaxed", "tightened")) -> list[str]:
    """Each elasticity to three significant digits, or where it is NaN (not determined by
    the problem) its two one-sided values: ``"0 relaxed / -0.371 tightened"``."""
    return [significant_text(value) if np.isfinite(value) else
            f"{significant_text(low)} {words[0]} / {significant_text(high)} {words[1]}"
            for value, low, high in zip(values, lows, highs)]


def limit_texts(requirements) -> list[str]:
    """The ``d ln cost / d ln limit`` of each row of a ``requirements`` table for people
    (:func:`one_or_two_sided`); tables saved before the one-sided columns existed hold
    only ``elasticity``."""
    limit = requirements["elasticity"].to_numpy(dtype=float)
    return one_or_two_sided(limit, _column(requirements, "elasticity_relax", limit),
                            _column(requirements, "elasticity_tighten", limit))
