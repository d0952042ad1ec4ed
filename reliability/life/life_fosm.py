"""First-order reliability of each output at an age and over a service life, pose by pose.

At a pose ``q`` an output read to first order is ``y(τ) = J(q)·e(τ)``: at acceptance
``y(0) ~ N(0, σ0²)`` with ``σ0² = J Σ0 Jᵀ`` (Eq. 20, with the machine's item correlation,
:func:`reliability.first_order.fosm.pose_sigma`), and its drift ``d(τ) = J·(e(τ) − e(0))``
has mean ``J·Drift.mean(τ)`` and variance ``J·Drift.covariance(τ)·Jᵀ``
(:mod:`reliability.model.drift`). Two probabilities per output, pose and age:

* **at the age**: ``P(|y(τ)| < I)``; under the linear model ``y(τ)`` is normal with
  ``σ² = σ0² + τ² s1²`` (``s1²`` the variance of one year's drift); under wear the normal
  of the same mean ``τ J μ`` and variance ``σ0² + τ J² v`` (a two-moment approximation:
  the gamma increments are skewed).
* **over the life**: ``P(|y(t)| < I for every t in [0, τ])``. Under the linear model
  ``y(t)`` is linear in ``t``, so this is the exact
  :func:`reliability.life.first_passage.first_passage_within` of ``y(0)`` and
  ``d(τ)``. Under wear it is Monte-Carlo of the gamma paths at the ages of the grid
  (:mod:`reliability.life.wear_paths`), at each output's most likely failing poses of the
  normal approximation, with the out-crossing (Rice) approximation as a check.

The worst pose of each output at each age is the pose of the lowest life probability
(ties by :func:`reliability.basics.ties.worst_rows`), on the grid only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..basics import streams
from ..basics.chunks import chunks, jacobian_bytes
from ..basics.errors import InputError
from ..basics.ties import worst_rows
from ..first_order.fosm import error_sigma, pose_sigma, two_sided_failure
from ..model.machine import OUTPUTS
from .first_passage import FIRST_PASSAGE_BYTES, first_passage_within
from .wear_paths import rice_life_failure, wear_life_probability

#: Poses per output at which the wear model's life probability is sampled besides each
#: age's worst (those of the largest failure of the normal approximation at the last age).
WEAR_CANDIDATES = 3
#: A pose is skipped by the linear model's quadrature only when another pose has both a
#: larger σ0 and a larger drift sd, by more than this relative margin.
PRUNE_RTOL = 1e-6
#: Gamma paths drawn per candidate pose by default (wear).
DEFAULT_PATHS = 20_000


@dataclass(frozen=True)
class LifeReliability:
    """Each output's reliability at its worst grid pose, at each age and over the life.

    Attributes
    ----------
    ages : ndarray (A,)
        Years, from 0, increasing.
    poses : ndarray (n_poses, n_axes)
    at_age : ndarray (A, 6)
        The lowest ``P(|y(τ)| < I)`` over the poses.
    life : ndarray (A, 6)
        ``P(|y(t)| < I for all t ≤ τ)`` at the worst pose of each age.
    worst_pose : ndarray (A, 6) of int
        The pose (row of ``poses``) of ``life``.
    life_se : ndarray (A, 6)
        Monte-Carlo standard error of ``life`` (0 where exact: the linear model).
    rice : ndarray (A, 6) or None
        Wear only: the out-crossing approximation of ``life`` at the same poses.
    kind : str
        The drift model (``'linear'`` or ``'wear'``).
    method : str
        How ``life`` was computed, in words.
    """

    ages: np.ndarray
    poses: np.ndarray
    at_age: np.ndarray
    life: np.ndarray
    worst_pose: np.ndarray
    life_se: np.ndarray
    rice: np.ndarray | None
    kind: str
    method: str


def checked_ages(ages) -> np.ndarray:
    """``ages`` as a float array starting at 0 and increasing, or an InputError naming it."""
    array = np.atleast_1d(np.asarray(ages, dtype=float))
    if array.ndim != 1 or len(array) < 1 or not np.isfinite(array).all():
        raise InputError(f"ages must be a one-dimensional list of finite years; got {ages!r}")
    if array[0] != 0 or np.any(np.diff(array) <= 0):
        raise InputError(f"ages must start at 0 and increase; got {array.tolist()}")
    return array


def age_grid(until, step) -> np.ndarray:
    """``0, step, 2·step, …`` up to ``until`` (included, the last step shortened)."""
    until, step = float(until), float(step)
    if not (np.isfinite(until) and until > 0):
        raise InputError(f"until must be a number of years > 0; got {until!r}")
    if not (np.isfinite(step) and 0 < step <= until):
        raise InputError(f"step must be a number of years in (0, until={until:g}]; "
                         f"got {step!r}")
    count = int(np.ceil(until / step - 1e-9))
    return np.append(np.arange(count) * step, until)


def output_moments(machine, poses, tolerances=None, *, k: float = 3.0,
                   distribution: str = "normal", start_covariance=None,
                   memory: int | None = None):
    """σ0 of each output at acceptance and its drift's moments per year, ``(n_poses, 6)``.

    Returns
    -------
    sigma0 : ndarray
        ``sqrt(J Σ0 Jᵀ)`` (Eq. 20; ``Σ0`` of ``tolerances`` read as ±kσ, or
        ``start_covariance`` when given, e.g. a compensated machine's residual).
    slope : ndarray
        ``J·μ``: the drift's mean per year (0 under the linear model).
    unit_sd : ndarray
        Linear: ``sqrt(J D R D Jᵀ)``, the sd of one year's drift (it scales with ``τ``);
        wear: ``sqrt(J² v)``, whose square scales with ``τ``.
    """
    drift = machine.drift
    if drift is None:
        raise InputError(f"machine {machine.name!r} has no [drift] table: nothing changes "
                         f"with age")
    slope = np.zeros((len(poses), len(OUTPUTS)))
    unit_variance = np.zeros_like(slope)
    sigma0 = np.zeros_like(slope)
    for part in chunks(len(poses), jacobian_bytes(machine), memory):
        jac = machine.jacobian(poses[part])
        if start_covariance is not None:
            sigma0[part] = np.sqrt(np.einsum("poi,ij,poj->po", jac, start_covariance, jac))
        if drift.kind == "wear":
            slope[part] = jac @ drift.rate
            unit_variance[part] = np.square(jac) @ np.square(drift.spread)
    if start_covariance is None:
        sigma0 = pose_sigma(machine, poses, error_sigma(tolerances, k, distribution),
                            memory=memory)
    if drift.kind == "linear":
        return sigma0, slope, pose_sigma(machine, poses, drift.rate, memory=memory)
    return sigma0, slope, np.sqrt(unit_variance)


def at_age_failure(limits, sigma0, slope, unit_sd, age: float, kind: str) -> np.ndarray:
    """``P(|y(age)| ≥ I)`` of the normal of the output's mean and variance at ``age``."""
    spread = age * unit_sd if kind == "linear" else np.sqrt(age) * unit_sd
    return two_sided_failure(limits, np.sqrt(sigma0 ** 2 + spread ** 2), age * slope)


def life_reliability(machine, tolerances, poses, ages, *, k: float = 3.0,
                     distribution: str = "normal", start_covariance=None, rng=None,
                     paths: int = DEFAULT_PATHS, memory: int | None = None
                     ) -> LifeReliability:
    """Each output's reliability at an age and over ``[0, age]`` at its worst grid pose.

    Parameters
    ----------
    machine : Machine
        With a ``[drift]`` table (``machine.drift``).
    tolerances : array_like
        ``(n_errors,)`` read as ±kσ under ``distribution``.
    poses : ndarray (n_poses, n_axes)
    ages : array_like
        Years from 0, increasing (:func:`age_grid`).
    start_covariance : ndarray (n_errors, n_errors), optional
        The errors' covariance at age 0 instead of the tolerances' (a compensated
        machine's residual, :mod:`reliability.life.recalibration`).
    rng : seed or Generator
        Wear only: the gamma paths.
    paths : int
        Wear only: paths per candidate pose.
    memory : int, optional
        Bytes of temporary arrays per chunk of poses.

    Returns
    -------
    LifeReliability
    """
    ages = checked_ages(ages)
    poses = np.atleast_2d(machine.check_positions(poses))
    sigma0, slope, unit_sd = output_moments(machine, poses, tolerances, k=k,
                                            distribution=distribution,
                                            start_covariance=start_covariance,
                                            memory=memory)
    kind, limits = machine.drift.kind, machine.limits
    age_column = ages[:, None, None]
    at_age = 1.0 - at_age_failure(limits, sigma0, slope, unit_sd, age_column, kind)
    if kind == "linear":
        life, worst = _linear_life(limits, sigma0, unit_sd, ages, poses, memory)
        return LifeReliability(ages, poses, at_age.min(axis=1), life, worst,
                               np.zeros_like(life), None, kind,
                               "first passage exact to first order (linear drift)")
    return _wear_life(machine, limits, sigma0, slope, unit_sd, ages, poses,
                      at_age.min(axis=1), streams.generator(rng), paths, memory)


def _linear_life(limits, sigma0, unit_sd, ages, poses, memory):
    """The exact first-order life probability at each age's worst pose and output.

    ``(y(0), y(τ))`` is a centred normal whose covariance grows (in the Loewner order)
    with ``σ0`` and with the drift's sd, and the square ``|y(0)|, |y(τ)| < I`` is convex and
    symmetric, so by Anderson's inequality the life probability falls with both. A pose
    whose ``σ0`` and one year's drift sd are both strictly below another pose's (by more
    than :data:`PRUNE_RTOL`) is never the worst at any age; the quadrature runs on the
    others (:func:`undominated`), once per distinct pair of the two."""
    failure = np.full((len(poses), len(ages), len(OUTPUTS)), -np.inf)
    pose, output = np.nonzero(undominated(sigma0, unit_sd))
    # poses of equal σ0 and drift sd (symmetry) share one quadrature
    keys = np.column_stack([output, *_rounded(sigma0[pose, output]),
                            *_rounded(unit_sd[pose, output])])
    _, first, inverse = np.unique(keys, axis=0, return_index=True, return_inverse=True)
    distinct = np.empty((len(first), len(ages)))
    pair = np.repeat(np.arange(len(first)), len(ages))
    age = np.tile(np.arange(len(ages)), len(first))
    for part in chunks(len(pair), FIRST_PASSAGE_BYTES, memory):
        p, o = pose[first[pair[part]]], output[first[pair[part]]]
        distinct[pair[part], age[part]] = 1.0 - first_passage_within(
            limits[o], sigma0[p, o], ages[age[part]] * unit_sd[p, o])
    failure[pose, :, output] = distinct[inverse.ravel()]
    worst = worst_rows(failure.reshape(len(poses), -1), poses).reshape(len(ages), -1)
    life = 1.0 - np.take_along_axis(failure, worst[None], axis=0)[0]
    return life, worst


def _rounded(values):
    """Exponent and mantissa rounded to 40 bits: equal keys for values equal to about
    1e-12 relative."""
    mantissa, exponent = np.frexp(values)
    return exponent, np.round(mantissa * 2.0 ** 40)


def undominated(sigma0, unit_sd, rtol: float | None = None) -> np.ndarray:
    """``(n_poses, 6)`` bool: the poses of each output that no other pose exceeds in both
    ``σ0`` and ``unit_sd`` by more than ``rtol`` (relative; :data:`PRUNE_RTOL`)."""
    rtol = PRUNE_RTOL if rtol is None else rtol
    order = np.argsort(-sigma0, axis=0, kind="stable")
    s_sorted = np.take_along_axis(sigma0, order, axis=0)
    u_sorted = np.take_along_axis(unit_sd, order, axis=0)
    running = np.maximum.accumulate(u_sorted, axis=0)
    kept = np.ones(sigma0.shape, dtype=bool)
    for o in range(sigma0.shape[1]):
        # poses with σ0 > s(1 + rtol) are a prefix of the descending order
        above = np.searchsorted(-s_sorted[:, o], -sigma0[:, o] * (1 + rtol), side="left")
        best = np.where(above > 0, running[np.maximum(above - 1, 0), o], -np.inf)
        kept[:, o] = ~(best > unit_sd[:, o] * (1 + rtol))
    return kept


def _wear_life(machine, limits, sigma0, slope, unit_sd, ages, poses, at_age, rng, paths,
               memory):
    """Monte-Carlo of the gamma paths at each output's candidate poses (the largest
    normal-approximation failure at the last age), the worst of them per age."""
    failure = at_age_failure(limits, sigma0, slope, unit_sd, ages[:, None, None], "wear")
    top = np.argsort(-failure[-1], axis=0, kind="stable")[:WEAR_CANDIDATES]
    candidates = np.vstack([top, worst_rows(failure.transpose(1, 0, 2).reshape(
        len(poses), -1), poses).reshape(len(ages), -1)])  # (C, 6)
    count = len(candidates)
    outputs = np.broadcast_to(np.arange(len(OUTPUTS)), candidates.shape)
    rows = machine.jacobian(poses[candidates.ravel()])[np.arange(candidates.size),
                                                         outputs.ravel()]
    probability, se = wear_life_probability(
        machine.drift, rows, sigma0[candidates, outputs].ravel(),
        np.tile(limits, count), ages, rng, paths, memory)
    probability = probability.reshape(len(ages), count, len(OUTPUTS))
    se = se.reshape(probability.shape)
    chosen = np.column_stack([worst_rows(1.0 - probability[:, :, o].T,
                                         poses[candidates[:, o]])
                              for o in range(len(OUTPUTS))])  # (A, 6)
    pick = np.arange(len(OUTPUTS))
    rice = 1.0 - rice_life_failure(limits, sigma0[candidates, outputs],
                                   slope[candidates, outputs],
                                   unit_sd[candidates, outputs], ages)
    take = (np.arange(len(ages))[:, None], chosen, pick)
    return LifeReliability(
        ages, poses, at_age, probability[take], candidates[chosen, pick], se[take],
        rice[take], "wear",
        f"Monte-Carlo of {paths:,} gamma wear paths at the ages of the grid, at each "
        f"output's worst grid pose of each age and its {WEAR_CANDIDATES} most likely "
        f"failing at the last age (normal approximation of y(age))")
