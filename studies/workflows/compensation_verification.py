"""Compensation verified: per output, the FOSM before and after compensation and the share of
simulated compensated machines within the limit, and the machine yield after compensation
predicted by the residual model beside the yield simulated end to end on the exact chain
(docs/compensation.md).

A simulated machine's output passes where :func:`reliability.basics.pass_rule.passes` says so;
the machine passes when every output passes at every pose.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from reliability.basics import checks, streams
from reliability.basics.pass_rule import passes
from reliability.compensation.compensated_machines import (residual_model_passes,
                                                           simulate_compensated)
from reliability.first_order.fosm import fosm


@dataclass(frozen=True)
class CompensationVerification:
    """Results of :func:`verify_compensation`.

    Attributes
    ----------
    table : pandas.DataFrame
        Per output (index ``output``): ``target``; ``FOSM before``, the worst two-sided FOSM
        probability over the poses before compensation; ``FOSM after``, the same after
        compensation; ``simulated after``, the share of simulated machines whose output
        passes at the pose of ``FOSM after``.
    predicted : numpy.ndarray of bool
        ``(model_machines,)``: residual-model machines holding every limit at every pose.
    simulated : numpy.ndarray of bool
        ``(machines,)``: simulated compensated machines holding every limit at every pose.
    """

    table: pd.DataFrame
    predicted: np.ndarray
    simulated: np.ndarray


def verify_compensation(plan, tolerances, poses, machines: int, model_machines: int,
                        rng=None) -> CompensationVerification:
    """Compensation under ``plan`` verified at ``poses``, first order and end to end.

    Parameters
    ----------
    plan : CompensationPlan
    tolerances : array_like
        ``(n_errors,)`` allocation the machines are built to (mm, rad).
    poses : array_like
        ``(n_poses, n_axes)`` poses where every output is judged.
    machines : int
        Machines built, measured, identified and compensated on the exact chain.
    model_machines : int
        Machines drawn from the residual model for the predicted yield.
    rng : None, int or numpy.random.Generator
        Draws the simulated machines, then the residual model's machines.

    Returns
    -------
    CompensationVerification
    """
    machine = plan.machine
    machines = checks.positive_int(machines, "machines")
    model_machines = checks.positive_int(model_machines, "model_machines")
    rng = streams.generator(rng)
    simulated = simulate_compensated(plan, tolerances, poses, machines, rng)
    predicted = residual_model_passes(plan, tolerances, poses, model_machines, rng)
    inside = passes(simulated, machine.limits)
    after = plan.probability(tolerances, poses)
    worst = np.argmin(after, axis=0)
    table = pd.DataFrame(
        {"target": machine.targets,
         "FOSM before": fosm(machine, tolerances, poses).to_frame()["worst_two_sided"].to_numpy(),
         "FOSM after": after.min(axis=0),
         "simulated after": inside.mean(axis=0)[worst, np.arange(len(machine.outputs))]},
        index=pd.Index(machine.outputs, name="output"))
    return CompensationVerification(table=table, predicted=predicted,
                                    simulated=inside.all(axis=(1, 2)))
