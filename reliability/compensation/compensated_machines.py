"""Compensated machines end to end, to check the residual model: each machine drawn, its
plan's readings simulated on the exact chain, its errors identified, its tables written from
the identification and its outputs evaluated, compensated, on the exact chain
(docs/compensation.md).
"""

from __future__ import annotations

import numpy as np

from ..basics import streams
from ..measured.identification import identify
from ..measured.simulated_measurements import simulate_measurements
from .residual import compensated_deviation, positioning_draws


def simulate_compensated(plan, tolerances, poses, machines: int, rng=None) -> np.ndarray:
    """``(machines, n_poses, 6)``: exact outputs of built, measured and compensated machines.

    Parameters
    ----------
    plan : CompensationPlan
    tolerances : array_like
        The allocation the machines are built to; the identification's prior.
    poses : array_like (n_poses, n_axes)
    machines : int
    rng : None, int or numpy.random.Generator
    """
    machine = plan.machine
    rng = streams.generator(rng)
    t = machine.check_tolerances(tolerances)
    poses = machine.check_positions(poses)
    out = np.empty((machines, len(poses), 6))
    for index in range(machines):
        built = simulate_measurements(machine, plan.runs, t, rng=rng)
        identification = identify(machine, built.measurements, tolerances=t)
        out[index] = compensated_deviation(machine, poses, built.errors[0],
                                           plan.tables(identification), rng)
    return out


def linear_residual_draws(plan, tolerances, poses, draws: int, rng=None) -> np.ndarray:
    """``(draws, n_poses, 6)``: outputs of the residual model, first order: residual errors
    drawn from their covariance plus each pose's repeatability and reversal."""
    machine = plan.machine
    rng = streams.generator(rng)
    poses = machine.check_positions(poses)
    covariance = plan.residual_covariance(tolerances)
    values, vectors = np.linalg.eigh(covariance)
    factor = vectors * np.sqrt(np.maximum(values, 0.0))
    residual = rng.standard_normal((draws, len(covariance))) @ factor.T
    residual = residual[:, None, :] + positioning_draws(machine, (draws, len(poses)), rng)
    jac = machine.jacobian(poses, frame=machine.frame)
    return np.einsum("poi,npi->npo", jac, residual)
