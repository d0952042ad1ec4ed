"""The machine yield over a service life: the share of built machines that hold every limit
at every grid pose at every age up to ``τ``.

Built machines are drawn as for the machine yield at acceptance
(:class:`reliability.sampling.machine_yield.YieldModel`: the error profile along travel,
the reading of a tolerance, the item correlation), and each gets its own drift
(:mod:`reliability.model.drift`), the same amount added to an error at every point of its
axis' travel:

* ``'linear'``: a rate per error, normal with mean 0 and covariance ``D R D``
  (``D = diag(rate)``, ``R`` the machine's item correlation), the errors at age ``t`` being
  ``e(0) + r t``;
* ``'wear'``: gamma increments per error between the ages of the grid
  (:func:`reliability.life.wear_paths.wear_paths`).

Each machine is judged on the exact chain (Eq. 18) at every grid pose and every age of the
grid, machines and ages evaluated together in batches within a memory budget (no Python
loop over machines, poses or ages); it holds over ``[0, τ]`` when ``|y| < I`` at every
pose and age up to ``τ`` (first passage on the age grid: under the linear model a pose's
output is close to linear in age, so between grid ages it stays within its limit when it
is within at both ends, up to the chain's second-order terms; under wear, a crossing and
return between two grid ages is not seen). The yield at each age comes with its
Clopper–Pearson interval.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..basics import checks, streams
from ..basics.chunks import chunk_size
from ..basics.errors import InputError
from ..basics.pass_rule import passes
from ..basics.statistics import binomial_interval
from ..model.machine import OUTPUTS
from ..sampling.grid_experiment import GridExperiment
from ..sampling.machine_yield import YieldModel, deciding_points
from .life_fosm import checked_ages
from .wear_paths import wear_paths

#: Built machines simulated over a life when not told otherwise (each is judged at every
#: age of the grid).
DEFAULT_LIFE_MACHINES = 1000


@dataclass(frozen=True)
class LifeYield:
    """The machine yield at every age of a grid, first passage from age 0.

    Attributes
    ----------
    ages : ndarray (A,)
    machines : int
        Built machines simulated.
    passed : ndarray (A,) of int
        Machines within every limit at every pose and every grid age up to each age.
    output_passed : ndarray (A, 6) of int
        The same per output.
    lower, upper : ndarray (A,)
        Clopper–Pearson interval of the yield at ``confidence``.
    confidence : float
    """

    ages: np.ndarray
    machines: int
    passed: np.ndarray
    output_passed: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    confidence: float

    @property
    def estimate(self) -> np.ndarray:
        """The yield at each age, ``passed / machines``."""
        return self.passed / self.machines


def drift_draws(drift, correlation, ages, size: int, rng) -> np.ndarray:
    """``(size, A, n_errors)``: each built machine's change of every error at each age."""
    if drift.kind == "wear":
        return wear_paths(drift, ages, size, rng)
    root = np.eye(len(drift.rate)) if correlation is None else covariance_factor(correlation)
    rates = (rng.standard_normal((size, len(drift.rate))) @ root.T) * drift.rate
    return np.asarray(ages)[None, :, None] * rates[:, None, :]


def covariance_factor(matrix) -> np.ndarray:
    """A factor ``L`` with ``L Lᵀ = matrix`` for a positive semi-definite matrix."""
    values, vectors = np.linalg.eigh(np.asarray(matrix, dtype=float))
    return vectors * np.sqrt(np.maximum(values, 0.0))


def deciding_experiment(model: YieldModel, profile) -> GridExperiment:
    """The grid experiment at the poses where a built machine's largest ratio can be
    reached (:func:`reliability.sampling.machine_yield.deciding_points`); the argument
    holds with drift too: the drift adds the same amount at every point of an axis."""
    kept = deciding_points(model.machine, model.profiles, model.experiment.points)
    if kept is None:
        return model.experiment
    return GridExperiment(model.machine, model.experiment.points, profile, kept_points=kept)


def drifted_ratios(experiment, machine, motion, assembly, change, memory=None) -> np.ndarray:
    """``(R, A, 6)``: each machine's largest ``|y_o|/I_o`` over the grid at each age, its
    errors at age ``a`` being the drawn ``motion (R, n, P, 6)`` and ``assembly
    (R, n − 1, 6)`` plus ``change[:, a] (R, A, n_errors)`` (the same at every point of an
    axis' travel); machines and ages evaluated together in batches within ``memory``."""
    n, n_ages = motion.shape[1], change.shape[1]
    per_machine = n_ages * 4 * 6 * 8 * experiment.n_grid
    size = chunk_size(per_machine, memory)
    out = np.empty((len(motion), n_ages, len(OUTPUTS)))
    for start in range(0, len(motion), size):
        part = slice(start, min(start + size, len(motion)))
        count = part.stop - part.start
        moved = (motion[part, None] + change[part, :, :6 * n].reshape(count, n_ages, n, 1, 6))
        fixed = (assembly[part, None]
                 + change[part, :, 6 * n:].reshape(count, n_ages, n - 1, 6))
        values = experiment.evaluate(moved.reshape((-1,) + motion.shape[1:]),
                                     fixed.reshape((-1,) + assembly.shape[1:]))
        np.abs(values, out=values)
        values /= machine.limits
        out[part] = values.max(axis=1).reshape(count, n_ages, len(OUTPUTS))
    return out


def life_yield(machine, tolerances, ages, *, profile=None, distribution=None,
               points: int = 5, machines: int = DEFAULT_LIFE_MACHINES, rng=None,
               k: float = 3.0, confidence: float = 0.95, memory: int | None = None,
               model: YieldModel | None = None) -> LifeYield:
    """The machine yield over ``[0, age]`` at every age of ``ages`` (module docstring).

    Parameters
    ----------
    machine : Machine
        With a ``[drift]`` table.
    tolerances : array_like
        ``(n_errors,)``, read as ±kσ.
    ages : array_like
        Years from 0, increasing.
    profile, distribution, points, k
        As for :class:`~reliability.sampling.machine_yield.YieldModel`.
    machines : int
        Built machines simulated.
    rng : seed or Generator
        Split into the stream of the errors at acceptance and that of the drift.
    confidence : float
        Level of the Clopper–Pearson intervals.
    memory : int, optional
        Bytes of temporary arrays per batch of (machine, age) pairs.
    model : YieldModel, optional
        A model built for this machine and these options, to reuse.

    Returns
    -------
    LifeYield
    """
    if machine.drift is None:
        raise InputError(f"machine {machine.name!r} has no [drift] table: nothing changes "
                         f"with age")
    ages = checked_ages(ages)
    t = checks.one_allocation(machine, tolerances)
    machines = checks.positive_int(machines, "machines")
    model = model or YieldModel(machine, profile=profile, distribution=distribution,
                                points=points, k=k, memory=memory)
    experiment = deciding_experiment(model, machine.profile if profile is None else profile)
    error_rng, drift_rng = streams.spawn(rng, 2)
    size = max(1, chunk_size(8 * (model.dimension + len(ages) * machine.n_errors), memory))
    passed = np.zeros((len(ages), len(OUTPUTS)), dtype=np.int64)
    everything = np.zeros(len(ages), dtype=np.int64)
    for start in range(0, machines, size):
        count = min(size, machines - start)
        motion, assembly = model.errors(error_rng.standard_normal((count, model.dimension)),
                                        t)
        change = drift_draws(machine.drift, machine.correlation, ages, count, drift_rng)
        ratios = np.maximum.accumulate(
            drifted_ratios(experiment, machine, motion, assembly, change, memory), axis=1)
        within = passes(ratios, 1.0)  # (count, A, 6)
        passed += within.sum(axis=0)
        everything += within.all(axis=2).sum(axis=0)
    lower, upper = binomial_interval(everything, machines, confidence, "clopper-pearson")
    return LifeYield(ages, machines, everything, passed, np.asarray(lower),
                     np.asarray(upper), float(confidence))
