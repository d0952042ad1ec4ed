"""The shape of an allocation for a machine-yield target, moved error by error.

The per-output search of :mod:`allocation.machine_yield.yield_target` moves six targets; this
stage moves all ``n`` tolerances. It rests on one property of the machine yield: a built
machine's worst ratio ``g(t) = max_r |y_r|/I_r`` over every (pose, output) row is, to first
order, homogeneous of degree one in the tolerances (every error is ``(t_i/k)`` times a draw that
does not depend on ``t``, under either reading). So on a fixed sample of built machines the
yield of ``t̂/s`` is the share of machines with ``g(t̂) < s``, and the cheapest scale of a
*shape* ``t̂`` that reaches a yield ``Y_d`` is ``s = q_{Y_d}(t̂)``, the ``Y_d``-quantile of
``g(t̂)``. The constrained problem becomes the unconstrained one

    minimise  F(v) = c(e^v / q(e^v))    over v = log t̂,

whose gradient follows from the quantile's sensitivity ``∂q/∂θ = E[∂g/∂θ | g = q]``
(Hong 2009, "Estimating quantile sensitivities") and Euler's relation for the homogeneous
``g``: ``∂ log g/∂ log t_i`` is error i's share ``s_i = J_ri x_i / y_r`` of the linearised
worst row (the shares sum to one). With the cost ``c = Σ w_i/t_i²`` (Eq. 28),

    ∂F/∂v_i = −2 c (κ_i − s̄_i),   κ_i = (w_i/t_i²)/c (error i's share of the cost),

``s̄`` the mean share of the machines whose ``g`` lies near the quantile. At the cheapest
shape every error's share of the cost equals its share of the failures at the margin; an
error whose cost share is larger is loosened, one whose failure share is larger is
tightened. The search takes steps along ``κ − s̄`` in ``log t``, rescales by the quantile,
keeps the tolerances inside the box (those held at a bound do not scale, so the scale is
found by a few fixed-point steps), and halves the step when the cost does not fall. Every
candidate is evaluated on the exact chain (:meth:`reliability.sampling.machine_yield.YieldModel.
worst_ratios`) with common random numbers at its final scale, so it meets the design yield
on the design sample exactly, not only to first order.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Share of the design machines, on each side of the quantile, whose shares are averaged.
BAND = 0.05
#: Largest change of one log-tolerance in the first step.
FIRST_STEP = 0.3
#: The search stops when the step falls below this.
SMALLEST_STEP = 0.004
#: A candidate may meet the design yield with its sample quantile of worst ratios this far
#: below 1 (it is rescaled otherwise) ...
SLACK = 1e-3
#: ... within this many rescalings.
RESCALES = 6
#: Bisections on the scale when the rescalings are held up by tolerances at their bounds.
BISECTIONS = 10


@dataclass(frozen=True)
class ShapeResult:
    """The cheapest allocation the shape search found.

    Attributes
    ----------
    tolerances : ndarray (n_errors,)
    cost : float
    design_yield : float
        Its yield on the design sample (exact chain).
    evaluations : int
        Candidates evaluated on the design sample (each one to a few chain evaluations).
    steps : int
        Steps accepted.
    """

    tolerances: np.ndarray
    cost: float
    design_yield: float
    evaluations: int
    steps: int


def shape_search(model, cost, lower, upper, start, design_target, u, *,
                 iterations: int = 20, worst_ratios=None) -> ShapeResult:
    """Move every tolerance of ``start`` towards equal cost and failure shares.

    Parameters
    ----------
    model : reliability.sampling.machine_yield.YieldModel
        The machine, its grid, profile and reading.
    cost : allocation.cost.cost.CostModel
    lower, upper : ndarray (n_errors,)
        The box.
    start : ndarray (n_errors,)
        A starting allocation (e.g. the per-output search's).
    design_target : float
        Yield every candidate must reach on the design sample.
    u : ndarray (machines, model.dimension)
        The design sample's standard normal draws (common random numbers).
    iterations : int
        Candidates evaluated at most.
    worst_ratios : callable, optional
        ``t -> (ratio, row)`` per machine of ``u``; ``model.worst_ratios(u, t)`` (the
        whole grid) by default, or an evaluation on fewer poses that is exact where it
        matters.

    Returns
    -------
    ShapeResult or None
        None when no scale of ``start`` inside the box meets the design yield.
    """
    judge = _judge(model, design_target, u, worst_ratios)
    current = _scaled(judge, cost, lower, upper, np.asarray(start, dtype=float))
    if current is None:
        return None
    step, steps, evaluations = FIRST_STEP, 0, 1
    while evaluations < iterations and step >= SMALLEST_STEP:
        cost_share, failure_share = current["cost_share"], current["failure_share"]
        imbalance = (cost_share - failure_share) / (cost_share + np.abs(failure_share))
        direction = _projected(imbalance, current["t"], lower, upper)
        if not direction.any():
            break
        move = step * direction
        trial = _scaled(judge, cost, lower, upper, current["t"] * np.exp(move))
        evaluations += 1
        if trial is not None and trial["cost"] < current["cost"]:
            current, steps = trial, steps + 1
        else:
            step *= 0.5
    return ShapeResult(tolerances=current["t"], cost=current["cost"],
                       design_yield=current["design_yield"], evaluations=evaluations,
                       steps=steps)


def scaled_to_yield(model, lower, upper, shape, target, u) -> dict | None:
    """``clip(s · shape, box)`` with the largest scale ``s`` at which its yield on the
    sample ``u`` reaches ``target``, judged on the whole grid of the exact chain.

    The scale comes from the fixed-point steps ``s ← s (1 − SLACK/2) / q(s)`` (``q`` the
    sample quantile of the worst ratios that must lie below 1): one step when nothing is
    held at a bound (the ratios are homogeneous in the tolerances), a few otherwise, until
    ``q`` lies within :data:`SLACK` below 1. When tolerances held at their lower bounds
    keep the steps from reaching ``target``, :data:`BISECTIONS` bisections in ``log s``
    between the last scale and the one that puts every tolerance at its lower bound find
    the largest scale that does.

    Returns
    -------
    dict or None
        ``t``, ``scale`` and ``passes`` (per machine of ``u``: it holds every limit at
        every pose; their share is at least ``target``); None when not even every
        tolerance at its lower bound reaches ``target``.
    """
    level = _passing_rank(target, len(u))
    shape = np.asarray(shape, dtype=float)

    def judged(scale):
        t = np.clip(scale * shape, lower, upper)
        ratio = model.worst_ratios(u, t)[0]
        return t, ratio, np.partition(ratio, level)[level]

    scale = 1.0
    for attempt in range(RESCALES):
        t, ratio, quantile = judged(scale)
        if 1.0 - SLACK <= quantile < 1.0:
            break
        following = scale * (1.0 - 0.5 * SLACK) / quantile
        if np.array_equal(np.clip(following * shape, lower, upper), t) \
                or attempt == RESCALES - 1:
            break
        scale = following
    if quantile >= 1.0:
        found = bisected_scale(judged, scale, float(np.min(lower / shape)))
        if found is None:
            return None
        scale, (t, ratio, quantile) = found
    return {"t": t, "scale": scale, "passes": ratio < 1.0}


def bisected_scale(judged, failing, lowest):
    """The largest scale between ``lowest`` (every tolerance at its lower bound) and the
    ``failing`` one whose quantile is below 1, with what ``judged`` says of it; None when
    not even ``lowest`` gives one. ``judged(scale)`` returns a tuple whose third item is the
    quantile of the worst ratios that must lie below 1."""
    at_lowest = judged(lowest)
    if at_lowest[2] >= 1.0:
        return None
    low, high, best = np.log(lowest), np.log(failing), (lowest, at_lowest)
    for _ in range(BISECTIONS):
        middle = 0.5 * (low + high)
        trial = judged(np.exp(middle))
        if trial[2] < 1.0:
            low, best = middle, (np.exp(middle), trial)
        else:
            high = middle
    return best


def _passing_rank(target, machines) -> int:
    """Rank of the worst ratio that must lie below 1 for a yield of ``target`` among
    ``machines`` (the machines ranked below it pass too)."""
    return int(np.ceil(target * machines)) - 1


def _judge(model, target, u, worst_ratios):
    """The model, the evaluation of the worst ratios (the whole grid's by default), the
    draws, the rank of the quantile that must lie below 1 and the band's half-width."""
    level = _passing_rank(target, len(u))
    band = max(1, int(BAND * len(u)))
    if worst_ratios is None:
        def worst_ratios(t):
            return model.worst_ratios(u, t)
    return model, worst_ratios, u, level, band


def _projected(direction, t, lower, upper) -> np.ndarray:
    """``direction`` without the components that would push a tolerance held at a bound
    further out of the box."""
    held = ((t <= lower) & (direction < 0)) | ((t >= upper) & (direction > 0))
    return np.where(held, 0.0, direction)


def _scaled(judge, cost, lower, upper, shape) -> dict | None:
    """The shape scaled into the box until the exact chain meets the design yield on the
    design sample with at most :data:`SLACK` to spare, with its cost, its cost shares and
    the mean failure shares of the machines at the margin (None when the box cannot).

    Tolerances held at a bound do not scale, so the scale is found by a few fixed-point
    steps ``t ← clip(t (1 − SLACK/2) / q(t))`` with ``q`` the sample quantile of the worst
    ratios (one step when no tolerance meets a bound: the ratios are homogeneous in t).
    Machines below the quantile pass (their ratio is below 1), so ``q < 1`` means the
    design yield is met on the design sample. ``judge`` is the model, the evaluation of
    the worst ratios, the design draws, the quantile's rank and the band's half-width."""
    model, worst_ratios, u, level, band = judge
    t = np.clip(shape, lower, upper)
    for attempt in range(RESCALES):
        ratio, worst = worst_ratios(t)
        order = np.argsort(ratio)
        quantile = ratio[order[level]]
        if 1.0 - SLACK <= quantile < 1.0:
            break
        scaled = np.clip(t * (1.0 - 0.5 * SLACK) / quantile, lower, upper)
        if np.array_equal(scaled, t) or attempt == RESCALES - 1:
            break
        t = scaled
    if quantile >= 1.0:
        return None
    margin = order[max(0, level - band):level + band + 1]
    terms = model.row_contributions(u[margin], t, worst[margin])
    shares = terms / terms.sum(axis=1, keepdims=True)
    items = cost.item_costs(t)
    return {"t": t, "cost": float(items.sum()), "cost_share": items / items.sum(),
            "failure_share": shares.mean(axis=0),
            "design_yield": float(np.mean(ratio < 1.0))}
