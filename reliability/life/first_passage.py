"""The probability that an output stays within its limit over a service life, to first
order, under the linear drift of :mod:`reliability.model.drift`.

Under the linear model every error is ``e(t) = e(0) + r·t``, so an output read to first
order at a pose, ``y(t) = J·e(t)``, is linear in the age ``t``. A linear function stays in
the interval ``(−I, I)`` over ``[0, τ]`` exactly when it is inside at both ends, so the
first passage over the life is the two-dimensional event

    P(|y(0)| < I and |y(τ)| < I),   y(τ) = y(0) + d,   d = J·(e(τ) − e(0)),

with ``y(0) ~ N(m0, s0²)`` and the drift ``d ~ N(md, sd²)`` independent of ``y(0)``. One
of the two is integrated by Gauss–Legendre quadrature over ±12 of its standard deviations
and the other is a normal probability in closed form given it: given ``y(0)`` the drift
must land in ``(−I − y(0), I − y(0))``; given ``d``, ``y(0)`` must lie in
``(max(−I, −I − d), min(I, I − d))``, whose ends switch at ``d = 0`` (the integral is split
there). The variable with the smaller spread is integrated, so the closed form in the other
varies no faster than the nodes are spaced. With ``sd = 0`` the drift is a constant and
the event is one interval of ``y(0)``.
"""

from __future__ import annotations

import numpy as np
from scipy import special

#: Gauss–Legendre nodes of the one-dimensional integral (tested against the bivariate
#: normal's rectangle probability and Monte Carlo).
QUADRATURE_NODES = 96
#: Standard deviations either side of the mean that the integral covers.
SPAN = 12.0


def first_passage_within(limit, sigma0, drift_sd, mean0=0.0, drift_mean=0.0) -> np.ndarray:
    """``P(|y(0)| < I and |y(0) + d| < I)`` for independent normal ``y(0)`` and ``d``.

    Parameters
    ----------
    limit : array_like
        ``I > 0``, broadcast with the others.
    sigma0, drift_sd : array_like
        Standard deviations ``s0 > 0`` of the output at acceptance and ``sd ≥ 0`` of its
        drift over the life.
    mean0, drift_mean : array_like
        Their means.

    Returns
    -------
    ndarray
        The probability, broadcast shape; for the linear drift model the probability that
        the output stays within ``±I`` at every age of the life (module docstring).
    """
    limit, s0, sd, m0, md = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in
                                                  (limit, sigma0, drift_sd, mean0,
                                                   drift_mean)))
    over_start = _over_acceptance(limit, s0, sd, m0, md)
    over_drift = _over_drift(limit, s0, sd, m0, md)
    constant = _normal_between(np.maximum(-limit, -limit - md) - m0,
                               np.minimum(limit, limit - md) - m0, s0)
    result = np.where(sd == 0, constant, np.where(sd >= s0, over_start, over_drift))
    return np.clip(result, 0.0, 1.0)


def _over_acceptance(limit, s0, sd, m0, md):
    """The integral over ``y(0)`` in ``(−I, I)`` (within 12 ``s0`` of ``m0``) of its
    density times the drift's closed-form probability."""
    low = np.maximum(-limit, m0 - SPAN * s0)
    high = np.minimum(limit, m0 + SPAN * s0)
    y0, weights = _nodes(low, high)
    density = _density(y0, m0[..., None], s0[..., None])
    inside = _normal_between(-limit[..., None] - y0 - md[..., None],
                             limit[..., None] - y0 - md[..., None], sd[..., None])
    return np.sum(weights * density * inside, axis=-1)


def _over_drift(limit, s0, sd, m0, md):
    """The integral over the drift ``d`` (within 12 ``sd`` of ``md`` and ``|d| < 2I``,
    split at 0) of its density times the closed-form probability of ``y(0)``."""
    total = np.zeros(np.shape(limit))
    for low, high in ((-2 * limit, 0 * limit), (0 * limit, 2 * limit)):
        low = np.maximum(low, md - SPAN * sd)
        high = np.minimum(high, md + SPAN * sd)
        d, weights = _nodes(low, high)
        density = _density(d, md[..., None], sd[..., None])
        lim, mean, sigma = limit[..., None], m0[..., None], s0[..., None]
        inside = _normal_between(np.maximum(-lim, -lim - d) - mean,
                                 np.minimum(lim, lim - d) - mean, sigma)
        total = total + np.sum(weights * density * inside, axis=-1)
    return total


def _nodes(low, high):
    """Gauss–Legendre nodes and weights on ``[low, high]`` per element (weights 0 where
    the interval is empty)."""
    nodes, weights = np.polynomial.legendre.leggauss(QUADRATURE_NODES)
    half = np.maximum(high - low, 0.0)[..., None] / 2
    return (high + low)[..., None] / 2 + half * nodes, half * weights


def _density(x, mean, sd):
    """The normal density; 0 where ``sd`` is 0 (that case is taken in closed form)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        value = np.exp(-((x - mean) / sd) ** 2 / 2) / (np.sqrt(2 * np.pi) * sd)
    return np.where(sd > 0, value, 0.0)


def _normal_between(low, high, sd):
    """``P(low < x < high)`` for ``x ~ N(0, sd²)``; an indicator where ``sd`` is 0."""
    with np.errstate(divide="ignore", invalid="ignore"):
        upper = np.where(sd > 0, special.ndtr(high / sd), (high > 0).astype(float))
        lower = np.where(sd > 0, special.ndtr(low / sd), (low >= 0).astype(float))
    return np.maximum(upper - lower, 0.0)


#: Temporary bytes per probability :func:`first_passage_within` computes (its quadrature's
#: working arrays), for chunking callers' inputs within a memory budget.
FIRST_PASSAGE_BYTES = 16 * QUADRATURE_NODES * 8
