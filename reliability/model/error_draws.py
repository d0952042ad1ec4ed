"""Drawing geometric errors: independent (normal or truncated at ±t, Sec. 5.3) or correlated
through a Gaussian copula.

Independent errors are zero-mean with σ = t/k, untruncated or truncated at ±t by rejection
(:func:`draw_errors`).

Correlated standard normals ``z = L ζ`` (``L Lᵀ = R``, a Cholesky factor)
are mapped to each error's own distribution by its quantile function (a Gaussian copula):
for the untruncated normal ``x = σ z``; for the normal truncated at ``±t`` (Sec. 5.3)
``x = σ Φ⁻¹(Φ(−k) + Φ(z)(2Φ(k) − 1))``, which keeps the marginal exactly truncated. The
correlation of the truncated draws differs from ``ρ`` by 10⁻³ or less at k = 3, which FOSM
neglects.

In the grid experiment every axis draws its motion errors at each of its points and the
assembly errors once per experiment, so only correlations *within one axis' motion errors*
(at the same point) and *among the assembly errors* have a meaning there; a machine with
other pairs is refused by :func:`grid_factors` (FOSM and random-pose sampling take any
pair).
"""

from __future__ import annotations

import numpy as np
from scipy.special import ndtr, ndtri

from ..basics import checks, streams
from ..basics.errors import InputError

#: The readings of a tolerance (one list for the whole toolkit): untruncated normal with
#: σ = t/k, or the normal truncated at ±t (Sec. 5.3).
DISTRIBUTIONS = ("normal", "truncated")


def check_reading(distribution, k) -> float:
    """Check the reading of a tolerance, ``distribution`` (one of :data:`DISTRIBUTIONS`)
    and the coverage factor ``k > 0`` (``t = ±kσ``); returns ``k`` as a float."""
    checks.choice(distribution, "distribution", DISTRIBUTIONS)
    return checks.finite_float(k, "coverage factor k", 0.0, low_open=True)


def draw_errors(tolerances, size, *, k: float = 3.0, distribution: str = "truncated",
                rng=None) -> np.ndarray:
    """Draw zero-mean errors with σ = t/k, optionally truncated at ±t (Sec. 5.3).

    Parameters
    ----------
    tolerances : array_like
        ``(n,)`` positive tolerances.
    size : tuple of int
        Leading shape; the result is ``size + (n,)``.
    k : float
        Coverage factor (t = ±kσ).
    distribution : {'truncated', 'normal'}
        'truncated': normal "within the allowable range", by rejection of |z| > k
        (exact; 0.27 % rejected at k = 3). 'normal': untruncated.
    rng : None, int or numpy.random.Generator
    """
    k = check_reading(distribution, k)
    t = checks.numeric_array(tolerances, "tolerances")
    if not np.all(np.isfinite(t) & (t > 0)):
        raise InputError("tolerances must be finite and > 0")
    rng = streams.generator(rng)
    z = rng.standard_normal(tuple(size) + t.shape)
    if distribution == "truncated":
        outside = np.abs(z) > k
        while np.any(outside):
            z[outside] = rng.standard_normal(int(outside.sum()))
            outside = np.abs(z) > k
    return z * (t / k)


def correlation_factor(correlation) -> np.ndarray:
    """A factor ``L`` with ``L Lᵀ = R``: the Cholesky factor, or (for a singular ``R``,
    e.g. a pair at ρ = ±1) the symmetric square root from the eigen-decomposition."""
    R = np.asarray(correlation, dtype=float)
    try:
        return np.linalg.cholesky(R)
    except np.linalg.LinAlgError:
        values, vectors = np.linalg.eigh(R)
        return (vectors * np.sqrt(np.maximum(values, 0.0))) @ vectors.T


def psd_factor(covariance) -> np.ndarray:
    """``L = V √Λ`` with ``L Lᵀ`` the covariance, from its eigen-decomposition: a singular
    covariance (a direction the readings pin down, a combination they cannot see) is
    allowed, its round-off negative eigenvalues taken as 0."""
    values, vectors = np.linalg.eigh(np.asarray(covariance, dtype=float))
    return vectors * np.sqrt(np.maximum(values, 0.0))


def correlate_items(z, cholesky) -> np.ndarray:
    """Correlated standard normals ``L z`` over the last axis of independent ones ``z``.

    Parameters
    ----------
    z : array_like
        ``(..., n)`` independent standard normals.
    cholesky : array_like
        ``(n, n)`` factor with ``L Lᵀ = R`` (:func:`correlation_factor`).
    """
    return np.asarray(z) @ np.asarray(cholesky).T


def normal_to_marginal(z, k: float = 3.0, distribution: str = "truncated") -> np.ndarray:
    """Map standard normals to the standardised error distribution (units of σ = t/k).

    'normal': unchanged. 'truncated': the quantile of N(0, 1) truncated at ±k at the
    probability ``Φ(z)``, so a standard normal becomes exactly a truncated one; computed on
    ``−|z|`` (the lower tail, where ``Φ`` is accurate) and given back its sign.
    """
    z = np.asarray(z, dtype=float)
    if distribution == "normal":
        return z
    if distribution != "truncated":
        raise InputError(f"distribution: unknown {distribution!r}; "
                         f"use 'truncated' or 'normal'")
    low = ndtr(-k)
    lower_tail = ndtri(low + ndtr(-np.abs(z)) * (1.0 - 2.0 * low))
    return np.where(z > 0, -lower_tail, lower_tail)


def draw_correlated(tolerances, size, cholesky, *, k: float = 3.0,
                    distribution: str = "truncated", rng=None) -> np.ndarray:
    """Errors ``size + (n,)`` with σ = t/k, the given correlation and the marginal
    ``distribution`` (Gaussian copula)."""
    t = np.asarray(tolerances, dtype=float)
    rng = streams.generator(rng)
    z = correlate_items(rng.standard_normal(tuple(size) + t.shape[-1:]), cholesky)
    return normal_to_marginal(z, k, distribution) * (t / k)


def grid_factors(machine) -> tuple[np.ndarray, np.ndarray]:
    """Factors of the correlation blocks the grid experiment can use.

    Returns
    -------
    motion : ndarray (n_axes, 6, 6)
        Factor of each axis' motion-error correlation (same point).
    assembly : ndarray (6 (n_axes − 1), 6 (n_axes − 1))
        Factor of the assembly-error correlation.

    Raises
    ------
    InputError
        When a pair links motion errors of two axes, or a motion and an assembly error:
        the grid experiment draws these at different points or once per experiment, so
        such a pair has no meaning there.
    """
    R = machine.correlation
    n = len(machine.axis_specs)
    owner = np.concatenate([np.repeat(np.arange(n), 6), np.full(6 * (n - 1), n)])
    across = (owner[:, None] != owner[None, :]) & (R != 0)
    if np.any(across):
        i, j = np.argwhere(across)[0]
        raise InputError(f"machine.correlation: the grid experiment draws "
                         f"{machine.error_names[i]!r} and {machine.error_names[j]!r} at "
                         f"different points; correlate errors of one axis, or assembly "
                         f"errors, or use sample_random_poses")
    motion = np.stack([correlation_factor(R[6 * a:6 * a + 6, 6 * a:6 * a + 6])
                       for a in range(n)])
    return motion, correlation_factor(R[6 * n:, 6 * n:])


def draw_grid_errors(machine, tolerances, points: int, *, k: float = 3.0,
                     distribution: str = "truncated", rng=None, travel=None):
    """One grid experiment's correlated errors: motion ``(n_axes, P, 6)`` (one draw per
    axis point) and assembly ``(n_axes − 1, 6)`` (:func:`grid_factors`).

    ``travel``, optional ``(n_axes, P, P)`` factors of an error profile along travel
    (:func:`reliability.model.profiles.travel_factors`), correlates each error along its axis
    as well; the two correlations act on different indices, so their order does not matter.
    """
    motion_factor, assembly_factor = grid_factors(machine)
    t = np.asarray(tolerances, dtype=float)
    n = len(machine.axis_specs)
    rng = streams.generator(rng)
    z = rng.standard_normal((n, points, 6))
    if travel is not None:
        z = np.einsum("apq,aqc->apc", travel, z)
    z = np.einsum("aij,apj->api", motion_factor, z)
    motion = normal_to_marginal(z, k, distribution) * (t[:6 * n].reshape(n, 1, 6) / k)
    assembly = draw_correlated(t[6 * n:], (), assembly_factor, k=k,
                               distribution=distribution, rng=rng)
    return motion, assembly.reshape(n - 1, 6)
