"""Monte-Carlo on the exact chain beside the first-order life reliability, at each
output's worst pose (``precrel life --check N``, docs/over-time.md).

Built machines are drawn with their errors at acceptance normal with ``σ = t/3`` and the
machine's item correlation (or from a given covariance: a compensated machine's residual,
:func:`reliability.life.compensated_life.first_cycle_covariance`), and their drift as
:func:`reliability.life.life_yield.drift_draws` draws it, on a fine age grid of
:data:`CHECK_AGES` ages from 0 to the horizon. Each output is evaluated on the exact chain
(Eq. 18) at its worst pose over the life, and the share of machines within its limit at
every age of the fine grid is the Monte-Carlo estimate of the life probability, with its
binomial standard error. Under the linear model the first-order value is exact up to the
chain's second-order terms, so the two differ only by those and by sampling.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..basics import checks, streams
from ..basics.chunks import chunk_size
from ..basics.pass_rule import passes
from ..model.machine import OUTPUTS
from .life_yield import covariance_factor, drift_draws

#: Ages of the fine grid from 0 to the horizon.
CHECK_AGES = 41


@dataclass(frozen=True)
class LifeCheck:
    """The Monte-Carlo share within each output's limit over the life at its worst pose.

    Attributes
    ----------
    share, standard_error : ndarray (6,)
    machines : int
    """

    share: np.ndarray
    standard_error: np.ndarray
    machines: int


def check_life(machine, tolerances, worst_poses, horizon: float, *, machines: int,
               rng=None, start_covariance=None, memory: int | None = None) -> LifeCheck:
    """Monte-Carlo of the life probability over ``[0, horizon]`` at ``worst_poses``
    ``(6, n_axes)`` (one per output) on the exact chain (module docstring)."""
    machines = checks.positive_int(machines, "machines")
    t = checks.one_allocation(machine, tolerances)
    if start_covariance is None:
        correlation = np.eye(len(t)) if machine.correlation is None else machine.correlation
        start_covariance = np.outer(t / 3, t / 3) * correlation
    root = covariance_factor(start_covariance)
    ages = np.linspace(0.0, float(horizon), CHECK_AGES)
    error_rng, drift_rng = streams.spawn(rng, 2)
    inside = np.zeros(len(OUTPUTS), dtype=np.int64)
    per_machine = 8 * CHECK_AGES * machine.n_errors * (2 + len(OUTPUTS) * 6)
    size = chunk_size(per_machine, memory)
    for start in range(0, machines, size):
        count = min(size, machines - start)
        e0 = error_rng.standard_normal((count, len(t))) @ root.T
        errors = e0[:, None, :] + drift_draws(machine.drift, machine.correlation, ages, count,
                                              drift_rng)
        flat = errors.reshape(-1, machine.n_errors)
        outputs = machine.comprehensive_error(worst_poses[:, None, :], flat[None])
        # (6 poses, machines · ages, 6 outputs): output o read at its own pose
        own = outputs[np.arange(len(OUTPUTS)), :, np.arange(len(OUTPUTS))]
        within = passes(own.reshape(len(OUTPUTS), count, CHECK_AGES),
                        machine.limits[:, None, None])
        inside += within.all(axis=2).sum(axis=1)
    share = inside / machines
    return LifeCheck(share, np.sqrt(share * (1 - share) / machines), machines)
