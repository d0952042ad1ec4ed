"""The worst pose between grid points: a continuous search of the workspace.

Eq. (35) asks the reliability target to hold over the whole stroke of every axis; the paper (and
the allocation problem, docs/model.md) checks it on a grid of five points per axis. FOSM's σ varies
smoothly with the pose, so the grid can miss a slightly worse pose between its points.
:func:`searched_worst` is the toolkit's one local search of the worst pose: a bounded L-BFGS-B
on σ over the strokes from each output's worst grid poses, its poses rounded to a resolution
and its ties broken by one rule. :func:`continuous_worst` reports its result as reliability
indices (how much worse the continuous workspace is), and the continuous allocation loop
(:mod:`allocation.per_pose.continuous`) cuts the poses it finds. :func:`certified_worst`
(:mod:`reliability.first_order.certificate`) bounds σ over the whole stroke box rigorously instead
(docs/certified-workspace.md). The search uses the analytic gradient of σ
(:func:`reliability.model.kinematics.jacobian_and_derivative`), and σ over the grid can be passed
in when the caller already has it, so the grid is not evaluated again.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from scipy.optimize import minimize

from ..basics import checks
from ..basics.errors import InputError
from ..basics.ties import SEARCH_RTOL, worst_rows
from ..model.kinematics import jacobian_and_derivative
from ..model.machine import OUTPUTS
from ..model.work_zone import inside_zone
from .canonical_maxima import POLISH_OPTIONS, snap_positions
from .certificate import certified_worst
from .fosm import error_sigma, one_sided_probability, pose_sigma, two_sided_probability

__all__ = ["certified_worst", "continuous_worst", "searched_worst", "snap_to_resolution",
           "worst_first"]


def continuous_worst(machine, tolerances, grid, *, k: float = 3.0, starts: int = 3,
                     grid_sigma=None, memory: int | None = None,
                     distribution: str = "normal") -> pd.DataFrame:
    """Largest σ of each output over the continuous workspace, from the grid's worst poses,
    as reliability indices and probabilities (the table of :func:`searched_worst`).

    Parameters
    ----------
    machine : Machine
    tolerances : array_like
        ``(n_errors,)`` allocation, read as ±kσ.
    grid : array_like
        ``(n_poses, n_axes)`` poses to start from (e.g. the workspace grid).
    k : float
        Coverage factor.
    starts : int
        Local searches per output, from its ``starts`` worst grid poses.
    grid_sigma : ndarray (n_poses, 6), optional
        σ of every output at the grid poses for this allocation (e.g. from
        ``AllocationProblem.sigma``); computed in chunks of poses otherwise.
    memory : int, optional
        Bytes of temporary arrays when σ over the grid is computed here.
    distribution : {'normal', 'truncated'}
        How a tolerance is read (:func:`reliability.first_order.fosm.error_sigma`).

    Returns
    -------
    pandas.DataFrame
        Per output: ``grid_beta`` and ``beta`` (continuous), the two-sided and one-sided
        probabilities at each, and the continuous worst pose (one column per axis),
        rounded to :data:`reliability.first_order.canonical_maxima.POSE_RESOLUTION` of each
        stroke (:func:`snap_to_resolution`);
        poses whose σ is within :data:`reliability.basics.ties.SEARCH_RTOL` of the largest are
        tied and the first in lexicographic order is reported
        (:func:`reliability.basics.ties.worst_rows`). The search is local, so ``beta`` is an
        upper bound on the true continuous worst β.
    """
    found = searched_worst(machine, tolerances, grid, k=k, distribution=distribution,
                           starts=starts, grid_sigma=grid_sigma, memory=memory)
    rows = [_row(machine, o, found["grid_sigma"].iloc[o], found["sigma"].iloc[o],
                 found[list(machine.axes)].iloc[o].to_numpy())
            for o in range(len(OUTPUTS))]
    return pd.DataFrame(rows, index=pd.Index(OUTPUTS, name="output"))


def searched_worst(machine, tolerances, grid, *, k: float = 3.0,
                   distribution: str = "normal", scale=None, starts: int = 3,
                   grid_sigma=None, memory: int | None = None) -> pd.DataFrame:
    """The worst pose of each output found by a bounded local search, and σ there.

    The one local search of the worst pose: L-BFGS-B maximises ``σ_o(q) / scale_o`` (Eq.
    20, with σ of every error under the reading ``distribution`` of a tolerance and the
    machine's correlation, if any) with its analytic gradient
    (:func:`reliability.model.kinematics.jacobian_and_derivative`, in ``machine.frame``)
    over the strokes, from the ``starts`` poses of ``grid`` where the output is largest
    (chosen by the tie rule, :func:`worst_first`), with stopping tolerances far below
    the resolution (:data:`reliability.first_order.canonical_maxima.POLISH_OPTIONS`). The
    poses found are rounded to
    :data:`reliability.first_order.canonical_maxima.POSE_RESOLUTION` of each stroke
    (:func:`snap_to_resolution`), σ is evaluated there, and the reported pose is, among
    the worst grid pose and the poses found, the first in lexicographic order among those
    within :data:`reliability.basics.ties.SEARCH_RTOL` of the largest σ
    (:func:`reliability.basics.ties.worst_rows`), so that the same inputs give the same pose
    on every computer and under every SciPy version that finds the same maximum. On a machine
    with a work zone, poses found outside it are dropped. Local: it
    proves nothing (:func:`certified_worst` bounds σ over the strokes rigorously).

    Parameters
    ----------
    machine : Machine
    tolerances : array_like
        ``(n_errors,)`` allocation, read as ±kσ.
    grid : array_like
        ``(n_poses, n_axes)`` poses to start from (a workspace grid, or the poses of an
        allocation problem).
    k : float
        Coverage factor.
    distribution : {'normal', 'truncated'}
        How a tolerance is read (:func:`reliability.first_order.fosm.error_sigma`).
    scale : array_like (6,), optional
        What each output's σ is divided by in the objective, e.g. the σ its target allows
        (``AllocationProblem.allowed_sigma``): L-BFGS-B's stopping tolerances are absolute
        in the objective's units, so an objective of order 1 is searched alike for outputs
        in mm and in rad. Default 1 (σ itself).
    starts : int
        Local searches per output.
    grid_sigma : ndarray (n_poses, 6), optional
        σ of every output at the grid poses under the same reading (e.g. from
        ``AllocationProblem.sigma``); computed in chunks of poses otherwise.
    memory : int, optional
        Bytes of temporary arrays when σ over the grid is computed here.

    Returns
    -------
    pandas.DataFrame
        Per output (index ``output``): the reported pose (one column per axis), ``sigma``
        there and ``grid_sigma``, the largest σ over ``grid``.
    """
    starts = checks.positive_int(starts, "starts")
    t = machine.check_tolerances(tolerances)
    if t.ndim != 1:
        raise InputError(f"tolerances must be one allocation of shape ({machine.n_errors},); "
                         f"got {t.shape}")
    sigma_x = error_sigma(t, k, distribution)
    grid = np.atleast_2d(machine.check_positions(grid))
    if grid.ndim != 2 or len(grid) == 0:
        raise InputError(f"grid must have shape (n_poses, {len(machine.axes)}) with at least "
                         f"one pose; got {grid.shape}")
    checks.poses_in_strokes(machine, grid, "grid")
    if grid_sigma is None:
        grid_sigma = pose_sigma(machine, grid, sigma_x, memory=memory)
    grid_sigma = np.asarray(grid_sigma, dtype=float)
    if grid_sigma.shape != (len(grid), len(OUTPUTS)):
        raise InputError(f"grid_sigma must have shape ({len(grid)}, {len(OUTPUTS)}); "
                         f"got {grid_sigma.shape}")
    if scale is None:
        scale = np.ones(len(OUTPUTS))
    scale = checks.numeric_array(scale, "scale")
    if scale.shape != (len(OUTPUTS),) or not np.all(np.isfinite(scale) & (scale > 0)):
        raise InputError(f"scale must hold {len(OUTPUTS)} finite positive numbers, one per "
                         f"output; got {scale}")
    bounds = [axis.stroke for axis in machine.axis_specs]
    poses = np.empty((len(OUTPUTS), len(machine.axes)))
    sigma = np.empty(len(OUTPUTS))
    for o in range(len(OUTPUTS)):
        def negative(q, o=o):
            value, gradient = _negative_sigma_and_gradient(machine, q, sigma_x, o)
            return value / scale[o], gradient / scale[o]

        found = [minimize(negative, start, jac=True, method="L-BFGS-B", bounds=bounds,
                          options=POLISH_OPTIONS).x
                 for start in grid[worst_first(grid_sigma[:, o], grid, starts)]]
        found = snap_to_resolution(machine, np.array(found))
        found = found[inside_zone(machine, found)]
        found_sigma = -np.array([_negative_sigma_and_gradient(machine, q, sigma_x, o)[0]
                                 for q in found])
        best = grid_sigma[:, o].max()
        candidates = np.vstack([grid[worst_rows(grid_sigma[:, o], grid)], found])
        values = np.concatenate([[best], found_sigma])
        choice = worst_rows(values, candidates, rtol=SEARCH_RTOL)
        poses[o], sigma[o] = candidates[choice], values[choice]
    table = pd.DataFrame(poses, columns=list(machine.axes),
                         index=pd.Index(OUTPUTS, name="output"))
    table["sigma"] = sigma
    table["grid_sigma"] = grid_sigma.max(axis=0)
    return table


def worst_first(values, poses, count: int) -> list[int]:
    """The ``count`` rows of largest value, each chosen by the tie rule among the rest."""
    remaining = np.array(values, dtype=float)
    rows = []
    for _ in range(min(count, len(remaining))):
        rows.append(worst_rows(remaining, poses))
        remaining[rows[-1]] = np.nan
    return rows


def snap_to_resolution(machine, poses) -> np.ndarray:
    """Poses found by a search, rounded to
    :data:`reliability.first_order.canonical_maxima.POSE_RESOLUTION` of each stroke's span.

    A local search fixes the position of a smooth maximum only to about the square root of
    its tolerance, so the digits beyond this resolution differ between computers; σ at the
    rounded pose differs from σ at the found one only to second order.
    """
    low = np.array([axis.stroke[0] for axis in machine.axis_specs])
    high = np.array([axis.stroke[1] for axis in machine.axis_specs])
    return snap_positions(poses, low, high)


def _negative_sigma_and_gradient(machine, q, sigma_x, output: int):
    """``−σ_o(q)`` and its gradient over the axis positions, analytically.

    ``σ_o² = jᵀ Σ j`` with ``Σ = D R D`` (Eq. 20 for R = I: ``Σ_i J_oi² σ_i²``), so
    ``∂σ_o/∂q_a = (∂j/∂q_a)ᵀ Σ j / σ_o``; R is ``machine.correlation`` or the identity.
    """
    jac, derivative = jacobian_and_derivative(machine, q, machine.frame)
    if machine.correlation is None:
        weighted = jac[output] * np.square(sigma_x)  # Σ j, (n_errors,)
    else:
        weighted = sigma_x * (machine.correlation @ (sigma_x * jac[output]))
    sigma = np.sqrt(weighted @ jac[output])  # Eq. (20)
    gradient = derivative[:, output, :] @ weighted / sigma
    return -sigma, -gradient


def _row(machine, output: int, grid_sigma: float, sigma: float, pose) -> dict:
    limit = machine.limits[output]
    row = {"grid_beta": limit / grid_sigma, "beta": limit / sigma,
           "grid_two_sided": two_sided_probability(limit, grid_sigma),
           "two_sided": two_sided_probability(limit, sigma),
           "grid_one_sided": one_sided_probability(limit, grid_sigma),
           "one_sided": one_sided_probability(limit, sigma)}
    row.update(dict(zip(machine.axes, pose)))
    return row
