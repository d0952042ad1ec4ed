"""Compensated machines end to end, to check the residual model: each machine drawn, its
plan's readings simulated on the exact chain, its errors identified, its tables written from
the identification and its outputs evaluated, compensated, on the exact chain
(docs/compensation.md).
"""

from __future__ import annotations

import numpy as np

from ..basics import streams
from ..basics.pass_rule import passes
from ..measured.identification import identify
from ..measured.simulated_measurements import simulate_measurements
from ..model.error_draws import psd_factor
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


def residual_model_passes(plan, tolerances, poses, draws: int, rng=None,
                          chunk: int = 256) -> np.ndarray:
    """``(draws,)``: whether machines of the residual model, first order, hold every limit at
    every pose: residual errors drawn from their covariance plus each pose's repeatability
    and reversal; ``chunk`` machines at a time."""
    machine = plan.machine
    rng = streams.generator(rng)
    poses = machine.check_positions(poses)
    factor = psd_factor(plan.residual_covariance(tolerances))
    jac = machine.jacobian(poses, frame=machine.frame)
    out = np.empty(draws, dtype=bool)
    for first in range(0, draws, chunk):
        count = min(chunk, draws - first)
        residual = rng.standard_normal((count, len(factor))) @ factor.T
        residual = residual[:, None, :] + positioning_draws(machine, (count, len(poses)), rng)
        outputs = np.einsum("poi,npi->npo", jac, residual)
        out[first:first + count] = np.all(passes(outputs, machine.limits), axis=(1, 2))
    return out
