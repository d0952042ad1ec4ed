"""Recalibration with a compensation plan: the intervals between recalibrations of machines
that are re-measured and re-compensated (docs/over-time.md, docs/compensation.md).

At a recalibration at age ``T`` the plan measures the machine and the table is rewritten
from the identification, with the rule ``precrel compensate`` uses (the posterior mean of
the tabled items under the allocation's prior, gain held fixed,
:func:`reliability.compensation.residual.fixed_rule_terms`): what the machine keeps right
after is ``M e(T) − ν`` with ``M = I − S P₀ F`` and the rule's noise ``ν ~ N(0, N)``,
``N = S P₀ F P₀ S``, drawn afresh at every recalibration. From then on the errors drift
again, so at age ``t ≥ T`` the residual is

    r(t) = M e(T) − ν + (e(t) − e(T)).

What the plan identifies is reset at each recalibration; what it cannot see keeps the
drift accumulated since acceptance, so the intervals shrink when unseen errors drift.

The intervals are found on the exact chain: built machines with one value per error along
the whole travel (the compensated machines' model of docs/compensation.md; the machine
file's profile along travel is not used here), errors at acceptance normal with
``σ = t/3`` (the identification's reading) and the item correlation, drift drawn as for
:func:`reliability.life.life_yield.life_yield`. Cycle ``k`` starts at recalibration age
``T_k`` (``T_0 = 0``: compensated at acceptance); its yield is the share of machines within
every limit at every grid pose and every grid age from ``T_k`` on, and its interval
``Δ_k`` the age after ``T_k`` at which that yield falls below the level. The next
recalibration is at the last grid age at or before ``T_k + Δ_k`` (at least one step
later).
Repeatability and reversal are left out (they do not drift).

The first cycle is also given to first order (:func:`first_cycle_covariance`): right after
compensation at acceptance the residual is independent of the drift to come, so its
first passage is exact (:func:`reliability.life.first_passage.first_passage_within`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..basics import checks, streams
from ..basics.chunks import chunk_size
from ..basics.pass_rule import passes
from ..basics.statistics import binomial_interval
from ..compensation.residual import fixed_rule_terms
from ..model.machine import OUTPUTS
from ..sampling.machine_yield import YieldModel
from .life_fosm import checked_ages
from .life_yield import covariance_factor, deciding_experiment, drift_draws, drifted_ratios
from .recalibration import crossing_interval

#: Reading of a tolerance by the identification: σ = t / K.
K = 3.0


@dataclass(frozen=True)
class CompensatedLife:
    """The recalibrations of compensated machines over a horizon.

    Attributes
    ----------
    starts : ndarray (C,)
        Age of each recalibration (0: compensated at acceptance).
    intervals : ndarray (C, 3)
        Per cycle ``[earliest, interval, latest]`` in years after its start (NaN: the
        yield stays above the level until the horizon).
    first_yield, first_lower, first_upper : ndarray (A,)
        The first cycle's yield from acceptance at every grid age and its interval.
    machines : int
    """

    starts: np.ndarray
    intervals: np.ndarray
    first_yield: np.ndarray
    first_lower: np.ndarray
    first_upper: np.ndarray
    machines: int


def first_cycle_covariance(machine, plan, tolerances) -> np.ndarray:
    """The covariance of the residual right after compensation at acceptance,
    ``M Σ0 Mᵀ + N`` with ``Σ0 = D R D`` (``D = diag(t/3)``, ``R`` the item correlation)."""
    sigma = np.asarray(tolerances, dtype=float) / K
    rule, noise = fixed_rule_terms(sigma, plan.information, plan.tabled)
    start = np.outer(sigma, sigma) * (np.eye(len(sigma)) if machine.correlation is None
                                      else machine.correlation)
    return rule @ start @ rule.T + noise


def compensated_life(machine, plan, tolerances, ages, level: float, *, points: int = 5,
                     machines: int = 1000, rng=None, confidence: float = 0.95,
                     memory: int | None = None) -> CompensatedLife:
    """The intervals between recalibrations of machines compensated under ``plan``
    (module docstring).

    Parameters
    ----------
    machine : Machine
        With a ``[drift]`` table.
    plan : CompensationPlan
    tolerances : array_like
    ages : array_like
        The age grid from 0.
    level : float
        The yield below which a machine is recalibrated.
    points, machines, rng, confidence, memory
        The grid, the built machines, the seed (split into the errors at acceptance, the
        drift and the rule's noise), the intervals' level and the batch memory.
    """
    ages = checked_ages(ages)
    t = checks.one_allocation(machine, tolerances)
    sigma = t / K
    rule, noise = fixed_rule_terms(sigma, plan.information, plan.tabled)
    error_rng, drift_rng, noise_rng = streams.spawn(rng, 3)
    root = sigma[:, None] * (np.eye(len(t)) if machine.correlation is None
                             else covariance_factor(machine.correlation))
    e0 = error_rng.standard_normal((machines, len(t))) @ root.T
    change = drift_draws(machine.drift, machine.correlation, ages, machines, drift_rng)
    model = YieldModel(machine, profile="constant", points=points, memory=memory)
    experiment = deciding_experiment(model, "constant")
    starts, intervals, first = [0], [], None
    while True:
        k = starts[-1]
        ratios = _cycle_ratios(machine, experiment, model.experiment.points, rule,
                               covariance_factor(noise), e0, change, k, noise_rng, memory)
        passed = passes(np.maximum.accumulate(ratios, axis=1), 1.0).all(axis=2).sum(axis=0)
        lower, upper = binomial_interval(passed, machines, confidence, "clopper-pearson")
        offsets = ages[k:] - ages[k]
        if first is None:
            first = (passed / machines, np.asarray(lower), np.asarray(upper))
        intervals.append(crossing_interval(offsets, lower, passed / machines, upper, level)
                         if len(offsets) > 1 else np.full(3, np.nan))
        due = intervals[-1][1]
        if np.isnan(due) or due == 0:
            break
        following = max(k + 1, int(np.searchsorted(ages, ages[k] + due, side="right")) - 1)
        if following >= len(ages) - 1:
            break
        starts.append(following)
    return CompensatedLife(ages[np.array(starts)], np.array(intervals), *first, machines)


def _cycle_ratios(machine, experiment, points, rule, noise_root, e0, change, k, rng,
                  memory):
    """``(R, A − k, 6)``: the largest ratios at every grid age from ``ages[k]`` of machines
    recalibrated at ``ages[k]``, in batches of machines."""
    n = len(machine.axis_specs)
    out = np.empty((len(e0), change.shape[1] - k, len(OUTPUTS)))
    size = chunk_size(8 * change.shape[1] * e0.shape[1] * 4, memory)
    for start in range(0, len(e0), size):
        part = slice(start, min(start + size, len(e0)))
        at_start = e0[part] + change[part, k]
        base = at_start @ rule.T - rng.standard_normal(at_start.shape) @ noise_root.T
        motion = np.repeat(base[:, None, :6 * n].reshape(-1, n, 1, 6), points, axis=2)
        assembly = base[:, 6 * n:].reshape(-1, n - 1, 6)
        later = change[part, k:] - change[part, k:k + 1]
        out[part] = drifted_ratios(experiment, machine, motion, assembly, later, memory)
    return out
