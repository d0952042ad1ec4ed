"""Gamma wear paths and the life probability of an output that wears.

Under the ``"wear"`` model (:mod:`reliability.model.drift`) error ``i`` gains a gamma
process ``W_i(t)`` with mean ``μ_i t`` and variance ``v_i t``: its increment over a step
``Δ`` is gamma with shape ``μ_i² Δ / v_i`` and scale ``v_i / μ_i`` (mean ``μ_i Δ``,
variance ``v_i Δ``), independent between steps and errors; with ``v_i = 0`` the wear is
the constant rate ``μ_i Δ``. An output read to first order at a pose is
``y(t) = y(0) + j·W(t)``, ``y(0) ~ N(0, σ0²)``.

:func:`wear_life_probability` samples the paths at the ages of a grid and counts the paths
inside ``±I`` at every age up to each one (the first passage on the grid: a crossing and
return between two grid ages is not seen). :func:`rice_life_failure` is the out-crossing
(Rice) approximation used as a check: ``P(|y(0)| ≥ I) + ∫₀^τ ν(t) dt`` with the rate of
crossings driven by the mean wear, ``ν(t) = (j·μ)⁺ f_t(I) + (j·μ)⁻ f_t(−I)``, ``f_t`` the
normal density of ``y(t)`` (mean ``t j·μ``, variance ``σ0² + t j²·v``). It ignores the
crossings the fluctuation of the wear makes by itself and double-counts paths that cross
twice, so it is an approximation, not a bound; it agrees with the sampled paths when the
mean wear dominates its spread.
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import cumulative_trapezoid

from ..basics.pass_rule import passes
from ..basics.chunks import chunks
from ..basics.errors import InputError
from ..first_order.fosm import two_sided_failure

#: Points of the fine age grid of the out-crossing integral.
RICE_POINTS = 2001


def gamma_increments(drift, steps, size: int, rng) -> np.ndarray:
    """``(size, len(steps), n_errors)`` wear increments over consecutive ``steps``
    (years), each gamma with mean ``μ Δ`` and variance ``v Δ`` (module docstring)."""
    mean, variance = drift.rate, np.square(drift.spread)
    bad = np.flatnonzero((mean == 0) & (variance > 0))
    if len(bad):
        raise InputError(f"drift: error {bad[0]} has a wear spread but no mean wear; a gamma "
                         f"wear with mean 0 is 0 (set its sd to 0 or give a mean)")
    random = variance > 0
    shape = np.where(random, np.square(mean) / np.where(random, variance, 1.0), 0.0)
    scale = np.where(random, variance / np.where(mean > 0, mean, 1.0), 0.0)
    steps = np.asarray(steps, dtype=float)[:, None]
    drawn = rng.gamma(shape * steps, scale, size=(size, len(steps), len(mean)))
    return np.where(random, drawn, mean * steps)


def wear_paths(drift, ages, size: int, rng) -> np.ndarray:
    """``(size, len(ages), n_errors)``: the wear ``W(t)`` of every error at each age
    (``ages[0] = 0``, where it is 0)."""
    increments = gamma_increments(drift, np.diff(ages), size, rng)
    return np.concatenate([np.zeros((size, 1, len(drift.rate))),
                           np.cumsum(increments, axis=1)], axis=1)


def wear_life_probability(drift, rows, sigma0, limits, ages, rng, paths: int,
                          memory: int | None = None):
    """The share of sampled paths of ``y(t) = y(0) + j·W(t)`` inside ``±I`` at every grid
    age up to each one, for several outputs at once.

    Parameters
    ----------
    drift : Drift
        Of kind ``'wear'``.
    rows : ndarray (M, n_errors)
        The Jacobian row ``j`` of each output (at its pose).
    sigma0, limits : ndarray (M,)
        σ of ``y(0)`` and the limit ``I`` of each.
    ages : ndarray (A,)
        From 0, increasing.
    rng : numpy.random.Generator
    paths : int
        Paths drawn (the same paths for every row: common random numbers).
    memory : int, optional
        Bytes of temporary arrays per chunk of paths.

    Returns
    -------
    probability, standard_error : ndarray (A, M)
    """
    rows = np.atleast_2d(rows)
    inside = np.zeros((len(ages), len(rows)))
    per_path = 8 * len(ages) * (2 * drift.rate.size + 4 * len(rows))
    for part in chunks(paths, per_path, memory):
        size = part.stop - part.start
        drift_out = wear_paths(drift, ages, size, rng) @ rows.T  # (size, A, M)
        start = rng.standard_normal((size, 1, len(rows))) * sigma0
        within = passes(start + drift_out, limits)
        inside += np.logical_and.accumulate(within, axis=1).sum(axis=0)
    probability = inside / paths
    return probability, np.sqrt(probability * (1.0 - probability) / paths)


def rice_life_failure(limits, sigma0, slope, unit_sd, ages) -> np.ndarray:
    """The out-crossing approximation of ``P(|y(t)| ≥ I for some t ≤ τ)`` at each age,
    ``(A, ...)`` for outputs of shape ``(...)`` (module docstring).

    ``slope`` is ``j·μ`` and ``unit_sd`` is ``sqrt(j²·v)`` of each output.
    """
    fine = np.union1d(ages, np.linspace(0.0, ages[-1], RICE_POINTS))
    t = fine.reshape((-1,) + (1,) * np.ndim(sigma0))
    mean = t * slope
    sd = np.sqrt(sigma0 ** 2 + t * unit_sd ** 2)
    density = (np.maximum(slope, 0) * _normal_density(limits, mean, sd)
               + np.maximum(-slope, 0) * _normal_density(-limits, mean, sd))
    crossings = cumulative_trapezoid(density, fine, axis=0, initial=0.0)
    at_start = two_sided_failure(limits, sigma0)
    return np.minimum(at_start + crossings[np.searchsorted(fine, ages)], 1.0)


def _normal_density(x, mean, sd):
    return np.exp(-0.5 * ((x - mean) / sd) ** 2) / (np.sqrt(2 * np.pi) * sd)
