"""The equal-yield margin: the costs of the naive method and of an allocation for a
machine-yield target at one yield, measured on one fresh sample shared by both (paired).
"""

from __future__ import annotations

import numpy as np

from reliability.basics import checks, streams
from reliability.basics.renamed import renamed
from reliability.first_order.fosm import required_index

from .yield_search import SearchPoint, YieldSearch
from .yield_target import YieldAllocation


@renamed("seed", "rng")
def equal_yield_margin(result: YieldAllocation, *, level: float | None = None,
                       spacing: float = 0.04,
                       machines: int | None = None, rng: int | None = None,
                       resamples: int = 2000) -> dict:
    """Cost of the naive method and of the result at one yield, and their difference with
    its error bar, measured on one fresh sample shared by both (paired).

    ``level`` is the yield compared at: by default the design yield ``Y_d`` both methods
    were tuned to (their allocations' yields); ``yield_target`` gives the comparison at Y.

    Each method is a family of allocations along a common shift of its required indices
    (naive: the common target, or the share of the way to the lower bounds when its start
    was moved there; the result: its six targets, or, when the error-shape stage
    gave it, its tolerances scaled by ``z/(z + shift)`` inside the box with ``z`` the naive
    required index). On a fresh sample (common
    random numbers for every allocation) each family is moved from shift 0 outwards in
    doubling steps of ``spacing`` until its yields bracket the level, the bracket is bisected
    four times, one shift is added beyond each end, and its cost at the level is
    interpolated linearly between the shifts whose yields bracket it.
    The error bar is the bootstrap standard error over the sample's machines (Poisson
    weights, the same resample for both families, so the difference is paired). The shared
    sample and the weights draw from the second and the fourth stream of
    :func:`reliability.basics.streams.yield_allocation_streams` of the integer seed ``rng``
    (None: ``result.seed + 1``; a Generator is refused with an InputTypeError naming
    ``rng``, as the named streams derive from an integer seed; ``seed=`` is the deprecated
    spelling, :mod:`reliability.basics.renamed`), and the machines are judged by the engine
    of the search.

    Returns
    -------
    dict
        ``level``: the yield compared at; ``naive`` and ``result``: cost there relative
        to the initial cost; ``margin``: their difference (naive − result, relative to
        the initial cost); ``*_error``: the bootstrap standard errors; ``saving``: the
        margin over the naive cost; ``machines``; ``shifts``, ``yields`` and ``costs`` of
        each family; ``evaluations``.
    """
    spacing = checks.finite_float(spacing, "spacing", 0.0, low_open=True)
    machines = result.machines if machines is None else checks.positive_int(machines,
                                                                            "machines")
    seed = result.seed + 1 if rng is None else streams.integer_seed(rng)
    resamples = checks.positive_int(resamples, "resamples")
    target = result.design_yield_target if level is None else checks.probability(level, "level")
    search = YieldSearch(result.problem.machine, result.points, None, machines, seed, 0.0,
                     problem=result.search_problem)
    sample = search.verification_verdicts()
    z_naive = np.full(6, required_index(result.naive.target, "two_sided"))
    families = {"naive": _naive_family(result, search, z_naive),
                "result": _result_family(result, search, float(z_naive[0]))}
    shifts, costs, passes = {}, {}, {}
    for name, allocate in families.items():
        shifts[name], costs[name], passes[name] = _family(allocate, sample, spacing, target)
        costs[name] = costs[name] / result.initial_cost
    weights = search.streams[3].poisson(1.0, (resamples, machines))
    at_y = {name: _cost_at_yield(costs[name], passes[name], target, weights)
            for name in families}
    point = {name: float(_cost_at_yield(costs[name], passes[name], target,
                                        np.ones((1, machines)))[0]) for name in families}
    margin = at_y["naive"] - at_y["result"]
    return {"level": target, "naive": point["naive"], "result": point["result"],
            "margin": point["naive"] - point["result"],
            "naive_error": float(np.nanstd(at_y["naive"], ddof=1)),
            "result_error": float(np.nanstd(at_y["result"], ddof=1)),
            "margin_error": float(np.nanstd(margin, ddof=1)),
            "saving": (point["naive"] - point["result"]) / point["naive"],
            "machines": machines, "shifts": shifts, "costs": costs,
            "yields": {name: passes[name].mean(axis=1) for name in families},
            "evaluations": sum(len(s) for s in shifts.values())}


def _naive_family(result, search, z):
    """The naive allocation at a shift: its common target shifted, or, when it was moved
    towards the box's lower bounds, that share shifted: past the most precise target (share
    0) the common target falls, past the lower bounds (share 1) nothing moves."""
    if result.naive.toward_lower == 0.0:
        return lambda shift: search.solve(z + shift)
    cap, lower = search.solve(z), np.asarray(result.search_problem.lower)

    def moved(shift):
        share = result.naive.toward_lower + shift
        if share <= 0.0:
            return search.solve(z + share)
        t = cap.t + min(share, 1.0) * (lower - cap.t)
        return SearchPoint(z=z, t=t, cost=float(result.search_problem.cost.total(t)))
    return moved


def _result_family(result, search, z):
    """The result's allocation at a shift: its six targets shifted (the per-output stage),
    its tolerances scaled by ``z/(z + shift)`` inside the box (the error-shape stage), or the
    naive family (the naive start kept: no margin)."""
    if result.method == "naive start":
        return _naive_family(result, search, z)
    if result.method == "per-output targets":
        z_result = required_index(result.output_targets, "two_sided")
        return lambda shift: search.solve(z_result + shift)
    problem = result.search_problem

    def scaled(shift):
        t = np.clip(result.tolerances * z / (z + shift), problem.lower, problem.upper)
        return SearchPoint(z=np.full(6, z + shift), t=t, cost=float(problem.cost.total(t)))
    return scaled


def _family(allocate, sample, spacing, target, doublings: int = 10, steps: int = 4):
    """Shifts, costs and per-machine verdicts on ``sample`` around yield ``target`` of the
    allocations ``allocate(shift)``: from shift 0 outwards in doubling steps until the
    yields bracket it, then ``steps`` bisections of the bracket, and one shift beyond each
    end of it."""
    found = {}

    def meets(shift):
        if shift not in found:
            point = allocate(shift)
            found[shift] = (point.cost, sample(point.t))
        return found[shift][1].mean() >= target

    low = high = 0.0
    outward = -1.0 if meets(0.0) else 1.0
    for i in range(doublings):
        shift = outward * spacing * 2 ** i
        if meets(shift) != (outward < 0):
            break
    low, high = sorted((shift, shift / 2 if i else 0.0))
    for _ in range(steps):
        middle = 0.5 * (low + high)
        low, high = (low, middle) if meets(middle) else (middle, high)
    meets(low - spacing)
    meets(high + spacing)
    order = sorted(found)
    return (np.array(order), np.array([found[s][0] for s in order]),
            np.stack([found[s][1] for s in order]))


def _cost_at_yield(costs, passes, target, weights) -> np.ndarray:
    """Cost at yield ``target`` for each row of machine weights, linear in the yield
    between the first offset reaching it and the one before (NaN when not bracketed)."""
    yields = weights @ passes.T / weights.sum(axis=1, keepdims=True)  # (B, offsets)
    yields = np.maximum.accumulate(yields, axis=1)  # a more precise family never loses
    reach = yields >= target
    first = np.argmax(reach, axis=1)
    ok = reach.any(axis=1) & (first > 0)
    k = np.where(ok, first, 1)
    rows = np.arange(len(yields))
    y0, y1 = yields[rows, k - 1], yields[rows, k]
    share = np.where(y1 > y0, (target - y0) / np.where(y1 > y0, y1 - y0, 1.0), 1.0)
    out = costs[k - 1] + share * (costs[k] - costs[k - 1])
    return np.where(ok, out, np.nan)
