"""Calibration and verification of an allocation for a machine yield with the radial
control variate, where the yield is log-concave.

Under the normal reading, without item correlation and with errors constant along travel,
the exact chain's yield of N built machines is estimated by (R3) of
:mod:`reliability.sampling.radial_yield`: the machines' exact verdicts minus their verdicts
on the linearised rows (the two almost always agree), plus the linearised yield by
directional sampling on M = :data:`RAYS_FACTOR` × N rays of a stream of its own. Its
standard error ``SE`` is a fraction of the binomial one, so the margin above Y that a fresh
sample needs to confirm Y shrinks with it:

* **calibration.** The allocation is multiplied by the largest factor (inside the box) at
  which ``Ŷ − DESIGN_Z · SE ≥ Y`` on the calibration sample (N machines and M rays), with
  ``DESIGN_Z = 1.96 (1 + √2)`` as for the crude estimate: 1.96 standard errors for the
  verification's interval and 1.96·√2 for the difference of two independent estimates of
  the same error. Along a factor the rays and the linearised verdicts scale exactly (the
  yield along a ray is homogeneous of degree one), the exact verdicts to first order; so
  the factor comes from the sample judged once, in a few fixed-point steps, and by
  bisection on the judged samples when tolerances held at their lower bounds stall them.
* **verification.** The estimate on a fresh sample (N machines, M rays), with the
  interval ``Ŷ ± 1.96 SE`` clipped to [0, 1]; the allocation is verified when its lower
  end is at least Y.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from reliability.basics import streams
from reliability.basics.statistics import ProportionEstimate
from reliability.sampling.radial_yield import (CONTROLLED_METHOD, Rays, controlled_yield,
                                               directions, rays, worst_rows)

from .yield_dual import RESCALES, SLACK, scaled_rows, unit_draws
from .yield_shape import bisected_scale

#: Standard errors of a yield estimate on N machines added to Y for the design and
#: calibration samples, so that a fresh sample of N machines confirms Y: 1.96 for the
#: verification's interval and 1.96·√2 for the difference of two independent samples
#: (calibration and verification) at 97.5 %.
DESIGN_Z = 1.96 * (1.0 + np.sqrt(2.0))
#: Rays of directional sampling per machine of a sample (calibration, verification).
RAYS_FACTOR = 10
#: The streams of the rays, after the six of
#: :func:`reliability.basics.streams.yield_allocation_streams`: ``spawn(seed, 9)``'s
#: seventh and eighth; the ninth is the log-concave bound's.
RAY_STREAMS = {"calibration": 6, "verification": 7}
BOUND_STREAM = 8


@dataclass(frozen=True, eq=False)
class Judged:
    """One allocation on a :class:`ControlledSample`: each machine's worst ratio on the
    exact chain and on the linearised rows, and the rays."""

    exact: np.ndarray
    linear: np.ndarray
    rays: Rays

    def estimate(self, scale: float = 1.0):
        """(R3) for the allocation times ``scale`` (a
        :class:`~reliability.sampling.radial_yield.ControlledYield`)."""
        return controlled_yield(scale * self.exact < 1.0, scale * self.linear < 1.0,
                                *self.rays.estimate(scale), len(self.rays.row))

    def margin(self, yield_target: float, z: float, scale: float = 1.0) -> float:
        """``Ŷ − z·SE − Y`` for the allocation times ``scale``."""
        found = self.estimate(scale)
        return found.estimate - z * found.standard_error - yield_target

    def largest_scale(self, yield_target: float, z: float) -> float:
        """The largest factor with :meth:`margin` ≥ 0 (bisection in its logarithm over
        [e^-3, e^3], 40 steps)."""
        low, high = -3.0, 3.0
        if self.margin(yield_target, z, np.exp(low)) < 0.0:
            return float(np.exp(low))
        for _ in range(40):
            middle = 0.5 * (low + high)
            if self.margin(yield_target, z, np.exp(middle)) >= 0.0:
                low = middle
            else:
                high = middle
        return float(np.exp(low))


class ControlledSample:
    """A sample of ``machines`` built machines (the draws ``u`` of a
    :class:`~reliability.sampling.machine_yield.YieldModel` under ``constant``) and rays
    ``theta`` on the linearised rows of the model's deciding poses."""

    def __init__(self, model, u, theta):
        self.model, self.u, self.theta = model, u, theta
        self.rows = scaled_rows(model.machine, model.deciding_poses)
        self.z = unit_draws(model, u)

    def judge(self, tolerances) -> Judged:
        """The allocation ``tolerances`` on the machines (exact chain, whole grid) and on
        the rays."""
        t = np.asarray(tolerances, dtype=float)
        return Judged(exact=self.model.output_ratios(self.u, t).max(axis=1),
                      linear=worst_rows(self.rows, t, self.z)[0],
                      rays=rays(self.rows, t, self.theta))

    def estimate(self, tolerances) -> ProportionEstimate:
        """:func:`proportion` of ``tolerances`` here."""
        return proportion(self.judge(tolerances).estimate())


def ray_sample(search, sample: str, seed: int) -> ControlledSample:
    """The ``sample`` (``'calibration'`` or ``'verification'``) of ``search`` (a
    :class:`~allocation.machine_yield.yield_search.YieldSearch`): its machines, and
    :data:`RAYS_FACTOR` times as many rays from the stream :data:`RAY_STREAMS` of
    ``seed``."""
    model = search.model
    rays_count = RAYS_FACTOR * search.machines
    stream = streams.spawn(seed, BOUND_STREAM + 1)[RAY_STREAMS[sample]]
    theta = directions(rays_count, len(model.machine.initial_allocation), stream)
    return ControlledSample(model, search.draws(sample), theta)


def proportion(found, confidence: float = 0.95) -> ProportionEstimate:
    """A :class:`~reliability.basics.statistics.ProportionEstimate` of the estimate
    ``found`` (:class:`~reliability.sampling.radial_yield.ControlledYield`): the estimate
    and its interval ``± z·SE``, each clipped to [0, 1]; ``n`` the machines."""
    lower, upper = found.interval(confidence)
    return ProportionEstimate(estimate=float(np.clip(found.estimate, 0.0, 1.0)), lower=lower,
                              upper=upper, standard_error=found.standard_error,
                              n=found.machines, method=CONTROLLED_METHOD,
                              confidence=confidence)


def calibrated(sample: ControlledSample, shape, lower, upper, yield_target: float,
               z: float):
    """``clip(s · shape, box)`` with the largest factor ``s`` at which ``Ŷ − z·SE ≥ Y`` on
    ``sample`` (module docstring).

    Returns
    -------
    (t, judged, reached) : ndarray, Judged, bool
        ``reached`` False when not even every tolerance at its lower bound meets it: then
        ``shape`` itself, judged.
    """
    shape = np.asarray(shape, dtype=float)

    def judged(scale):
        t = np.clip(scale * shape, lower, upper)
        found = sample.judge(t)
        return t, found, 0.0 if found.margin(yield_target, z) >= 0.0 else 1.0

    scale = 1.0
    for _ in range(RESCALES):
        t, found, failing = judged(scale)
        factor = found.largest_scale(yield_target, z)
        if not failing and factor < 1.0 + SLACK:
            return t, found, True
        following = scale * factor * (1.0 - 0.5 * SLACK)
        if np.array_equal(np.clip(following * shape, lower, upper), t):
            break
        scale = following
    t, found, failing = judged(scale)
    if not failing:
        return t, found, True
    bisected = bisected_scale(judged, scale, float(np.min(lower / shape)))
    if bisected is None:
        return shape, sample.judge(shape), False
    t, found, _ = bisected[1]
    return t, found, True
