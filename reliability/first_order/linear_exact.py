"""Exact probability of the linearised output under independent truncated-normal errors.

FOSM reads the output ``y = μ + Σ_i j_i x_i`` as normal. When each error ``x_i`` is
normal with σ_i = t_i/k truncated at ±t_i (the paper's "within the allowable range",
Sec. 5.3), every term ``y_i = j_i x_i`` is a truncated normal on ``±a_i`` (``a_i = |j_i| t_i``)
with scale ``s_i = |j_i| σ_i``, and their sum is not normal. This module computes

    P(|μ + Σ_i y_i| < I)

exactly up to a stated absolute error (:data:`TAIL_TOLERANCE`), so that the only difference
left between FOSM and a Monte-Carlo of the exact model is the linearisation.

Method: a Fourier series on the support (characteristic-function inversion without
quadrature error). The sum ``S = Σ y_i`` lies in ``[−A, A]``, ``A = Σ a_i``. Take a period
``L ≥ A + I + |μ|``: the L-periodic extension of the window ``w(x) = 1[|x + μ| < I]`` agrees
with ``w`` on ``[−A, A]`` (its copies start beyond A), and the density of S vanishes
outside, so ``P = ∫ w f_S`` equals the Fourier series of the periodic window paired with the
characteristic function ``φ_S(u) = Π_i φ_i(u)`` (real and even) at ``u_n = 2πn/L``:

    P = 2I/L + (4/L) Σ_{n ≥ 1} cos(u_n μ) sin(u_n I)/u_n · φ_S(u_n).

There is no discretisation error; the only error is the truncation of the series after N
terms. Integrating by parts, a symmetric unimodal density f_i on ``±a_i`` has
``|φ_i(u)| ≤ 2 f_i(0)/u = B_i/u``, ``B_i = 2/(s_i √(2π) (2Φ(k) − 1))``, and ``|φ_i| ≤ 1``, so
the terms beyond N are bounded (the series' terms decrease like the integral) by

    (2/π) ∫_{u_N}^∞ (1/u) Π_{i: B_i < u_N} (B_i/u) du = (2/π) Π_{i: B_i < u_N} (B_i/u_N) / m,

with m the number of factors. N is the smallest count that makes this bound at most
:data:`TAIL_TOLERANCE` (1e-10); the series' own rounding is below 1e-13 for the few dozen
terms needed, so the result is exact to 1e-9 absolute. (An output carried by one error
alone decays too slowly for the bound; it is computed in closed form, and a sum whose bound
cannot be met within :data:`MAX_TERMS` terms raises rather than returns a weaker number.)

Each factor is the characteristic function of the standard normal truncated at ±k, written
with the Faddeeva function ``w`` (:func:`scipy.special.wofz`) in a form free of overflow:

    φ(v) = [e^{−v²/2} − e^{−k²/2} Re(e^{ikv} w((v + ik)/√2))] / (2Φ(k) − 1),   v = s_i u,

read for speed from a clamped cubic spline of it for v ≤ 64 (error below 4e-14 per factor,
so below 1e-11 in the probability for up to a hundred factors and the few dozen terms of
the series).

The test suite checks the result against the truncated normal's CDF (one term), a
quadrature of two terms' convolution and a 10⁷-draw Monte-Carlo of the linear model.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.special import wofz
from scipy.stats import norm

from ..basics import checks
from ..basics.chunks import MEMORY_BUDGET
from ..basics.errors import InputError
from ..basics.pass_rule import passes

#: Bound on the truncation error of the series, absolute probability.
TAIL_TOLERANCE = 1e-10
#: Most series terms spent on one probability; a slower series raises.
MAX_TERMS = 200_000
#: The characteristic function is read from a clamped cubic spline on [0, CF_TABLE_END]
#: with knots CF_TABLE_STEP apart, and from the Faddeeva form beyond.
CF_TABLE_END = 64.0
CF_TABLE_STEP = 1.0 / 1024
#: Scales below this fraction of the largest scale of a sum are treated as exactly zero.
NEGLIGIBLE_SCALE = 1e-14


def truncated_normal_cf(v, k: float) -> np.ndarray:
    """Characteristic function of N(0, 1) truncated at ±k, at real ``v`` (Faddeeva form)."""
    v = np.asarray(v, dtype=float)
    mass = 2.0 * norm.cdf(k) - 1.0
    edge = np.exp(1j * k * v) * wofz((v + 1j * k) / np.sqrt(2.0))
    return (np.exp(-0.5 * v * v) - np.exp(-0.5 * k * k) * edge.real) / mass


def truncated_normal_cf_derivative(v, k: float) -> np.ndarray:
    """``dφ/dv`` of :func:`truncated_normal_cf`, from ``w'(z) = −2z w(z) + 2i/√π``."""
    v = np.asarray(v, dtype=float)
    mass = 2.0 * norm.cdf(k) - 1.0
    z = (v + 1j * k) / np.sqrt(2.0)
    w = wofz(z)
    slope = 1j * k * w + (-2.0 * z * w + 2j / np.sqrt(np.pi)) / np.sqrt(2.0)
    edge = np.exp(1j * k * v) * slope
    return (-v * np.exp(-0.5 * v * v) - np.exp(-0.5 * k * k) * edge.real) / mass


@lru_cache(maxsize=8)
def _cf_spline(k: float) -> CubicSpline:
    """Clamped cubic spline of φ on [0, :data:`CF_TABLE_END`], knots
    :data:`CF_TABLE_STEP` apart. Its error is at most ``(5/384) h⁴ max|φ⁽⁴⁾|`` (Hall and
    Meyer 1976) with ``|φ⁽⁴⁾| ≤ E[Z⁴ | |Z| < k] < 3``: below 4e-14 for h = 1/1024."""
    knots = np.arange(0.0, CF_TABLE_END + CF_TABLE_STEP / 2, CF_TABLE_STEP)
    ends = truncated_normal_cf_derivative(knots[[0, -1]], k)
    return CubicSpline(knots, truncated_normal_cf(knots, k),
                       bc_type=((1, float(ends[0])), (1, float(ends[1]))))


def fast_truncated_normal_cf(v, k: float) -> np.ndarray:
    """:func:`truncated_normal_cf` for ``v >= 0``: the spline of :func:`_cf_spline` up to
    :data:`CF_TABLE_END` (error < 4e-14), the Faddeeva form beyond."""
    v = np.asarray(v, dtype=float)
    near = v <= CF_TABLE_END
    if near.all():
        return _cf_spline(float(k))(v)
    out = np.empty_like(v)
    out[near] = _cf_spline(float(k))(v[near])
    out[~near] = truncated_normal_cf(v[~near], k)
    return out


def linear_two_sided(limit, scales, *, k: float = 3.0, mean=0.0,
                     memory: int | None = None) -> np.ndarray:
    """``P(|μ + Σ_i y_i| < I)`` for independent ``y_i`` ~ N(0, s_i²) truncated at ±k s_i.

    Parameters
    ----------
    limit : array_like
        Limits ``I > 0``, broadcast with ``scales[..., 0]``.
    scales : array_like (..., n_terms)
        Non-negative scales ``s_i = |j_i| σ_i`` (σ_i = t_i/k, the untruncated σ).
    k : float
        Truncation point in units of the scale (3: truncated at the tolerance ±t).
    mean : array_like
        Output mean μ, broadcast like ``limit``.
    memory : int, optional
        Bytes of temporary arrays per chunk (:data:`reliability.basics.chunks.MEMORY_BUDGET`).

    Returns
    -------
    numpy.ndarray
        The probabilities, shape ``scales.shape[:-1]``, exact to 1e-9 absolute.
    """
    k = checks.finite_float(k, "k", 0.0, low_open=True)
    scales = checks.numeric_array(scales, "scales")
    if scales.ndim < 1 or np.any(scales < 0):
        raise InputError("scales must be an array (..., n_terms) of values >= 0")
    shape = scales.shape[:-1]
    limit = np.broadcast_to(checks.numeric_array(limit, "limit"), shape).reshape(-1)
    if np.any(limit <= 0):
        raise InputError("limit must be > 0")
    mean = np.broadcast_to(checks.numeric_array(mean, "mean"), shape).reshape(-1)
    scales = scales.reshape(-1, scales.shape[-1])
    largest = scales.max(axis=-1, keepdims=True)
    scales = np.where(scales > NEGLIGIBLE_SCALE * largest, scales, 0.0)
    out = np.empty(len(scales))
    active = (scales > 0).sum(axis=-1)
    few = active <= 1
    out[few] = _single_term(limit[few], scales[few].max(axis=-1), k, mean[few])
    rows = np.flatnonzero(~few)
    if len(rows):
        width = int(active[rows].max())  # each row's non-zero scales first, largest first
        packed = -np.sort(-scales[rows], axis=-1)[:, :width]
        out[rows] = _series(limit[rows], packed, k, mean[rows], memory)
    return out.reshape(shape)


def _single_term(limit, scale, k, mean) -> np.ndarray:
    """Closed form for at most one term: the truncated normal's CDF (or a constant)."""
    safe = np.where(scale > 0, scale, 1.0)
    mass = 2.0 * norm.cdf(k) - 1.0

    def cdf(x):
        z = np.clip(x / safe, -k, k)
        return (norm.cdf(z) - norm.cdf(-k)) / mass

    spread = cdf(limit - mean) - cdf(-limit - mean)
    return np.where(scale > 0, spread, passes(mean, limit).astype(float))


def series_terms(limit, scales, k: float, mean) -> np.ndarray:
    """Terms N of the series that bound its truncation error by :data:`TAIL_TOLERANCE`,
    one per row of ``scales`` (n_rows, n_terms); :data:`MAX_TERMS` + 1 if none does.

    The bound of the module docstring is evaluated at about 150 geometrically spaced
    counts; the first count that meets it is used (so N is at most 10 % above the
    smallest sufficient count)."""
    mass = 2.0 * norm.cdf(k) - 1.0
    with np.errstate(divide="ignore"):
        bounds = np.where(scales > 0, 2.0 / (scales * np.sqrt(2.0 * np.pi) * mass), np.inf)
    log_b = np.log(np.sort(bounds, axis=-1))  # smallest B first; inf for zero scales
    cumulative = np.concatenate([np.zeros((len(log_b), 1)),
                                 np.cumsum(np.where(np.isfinite(log_b), log_b, 0.0), axis=-1)],
                                axis=-1)
    counts = np.unique(np.ceil(np.geomspace(1, MAX_TERMS, 150))).astype(int)
    log_u = np.log(2.0 * np.pi * counts[None, :] / _period(limit, scales, k, mean)[:, None])
    m = (log_b[:, None, :] < log_u[:, :, None]).sum(axis=-1)  # factors with B_i < u_N
    log_tail = (np.log(2.0 / np.pi) - np.log(np.maximum(m, 1))
                + np.take_along_axis(cumulative, m, axis=-1) - m * log_u)  # Π (B_i/u_N)/m
    good = (m > 0) & (log_tail <= np.log(TAIL_TOLERANCE))
    first = np.where(good.any(axis=-1), good.argmax(axis=-1), -1)
    return np.where(first >= 0, counts[first], MAX_TERMS + 1)


def _period(limit, scales, k, mean) -> np.ndarray:
    """``L = A + I + |μ|`` with the support half-width ``A = k Σ s_i``, widened by 1e-12
    so that the window's copies stay strictly outside the support."""
    return (k * scales.sum(axis=-1) + limit + np.abs(mean)) * (1.0 + 1e-12)


def _series(limit, scales, k, mean, memory) -> np.ndarray:
    """The Fourier series of the module docstring, rows grouped by their term count."""
    terms = series_terms(limit, scales, k, mean)
    if np.any(terms > MAX_TERMS):
        row = int(np.argmax(terms > MAX_TERMS))
        raise InputError(f"the exact linear probability needs more than {MAX_TERMS} series "
                         f"terms for scales {scales[row][scales[row] > 0].tolist()} (one "
                         f"term dominates the others by many orders of magnitude)")
    width = (scales > 0).sum(axis=-1)
    order = np.lexsort((width, terms))
    budget = MEMORY_BUDGET if memory is None else memory
    out = np.empty(len(limit))
    start = 0
    while start < len(order):
        n_terms = int(terms[order[start]])
        size = max(1, budget // (32 * scales.shape[-1] * max(n_terms, 1)))
        part = order[start:start + size]
        n_terms = int(terms[part].max())
        used = scales[part][:, :int(width[part].max())]  # non-zero scales come first
        out[part] = _series_sum(limit[part], used, k, mean[part], n_terms)
        start += len(part)
    return out


def _series_sum(limit, scales, k, mean, n_terms) -> np.ndarray:
    """``2I/L + (4/L) Σ_{n=1}^{N} cos(u_n μ) sin(u_n I)/u_n Π_i φ_i(u_n)``."""
    period = _period(limit, scales, k, mean)
    u = 2.0 * np.pi * np.arange(1, n_terms + 1)[None, :] / period[:, None]  # (rows, N)
    cf = np.prod(fast_truncated_normal_cf(u[:, :, None] * scales[:, None, :], k), axis=-1)
    window = np.cos(u * mean[:, None]) * np.sin(u * limit[:, None]) / u
    return 2.0 * limit / period + 4.0 / period * np.sum(window * cf, axis=-1)
