"""Correlated geometric errors: the correlation matrix, FOSM with it, and a Gaussian copula.

The paper treats the geometric errors as independent (Eq. 20 sums squared sensitivities).
Errors with a common cause are not: a carriage riding over a bump of its guideway both
rises (straightness) and pitches, so the two errors move together. A machine description
may list such pairs::

    [[correlation]]
    errors = ["X.ey", "X.dz"]      # paper names or ISO 230-1 symbols ("EBX", "EZX")
    coefficient = 0.6

The pairs are assembled into a correlation matrix ``R`` (unit diagonal, symmetric,
``|ρ| ≤ 1``, positive semi-definite; anything else is refused naming the pair or the
eigenvalue) stored as ``machine.correlation`` (``None`` when no pair is given).

FOSM. With ``σ_i = t_i/k`` and ``D = diag(σ)`` the error covariance is ``Σ = D R D`` and
the output variance ``σ_y² = jᵀ Σ j`` (Eq. 20 with the cross terms the paper drops;
``R = I`` gives Eq. 20 back). The share of error ``i`` in ``σ_y²`` is its Euler
allocation ``a_i (R a)_i / σ_y²`` with ``a = D j``: the shares add up to 100 %, reduce to
Eq. 20's terms without correlation, and one of them can be negative when an error partly
cancels a correlated partner.

Monte-Carlo. Correlated standard normals ``z = L ζ`` (``L Lᵀ = R``, a Cholesky factor)
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

import dataclasses
from typing import Mapping

import numpy as np
import pandas as pd
from scipy.special import ndtr, ndtri

from . import streams
from .errors import InputError, MachineDescriptionError

#: Largest asymmetry or negative eigenvalue accepted as rounding.
ROUNDING = 1e-10


# ----- the matrix ------------------------------------------------------------------------
def check_correlation_matrix(matrix, names) -> np.ndarray:
    """Return ``matrix`` as a read-only correlation matrix over ``names`` or raise.

    Raises
    ------
    MachineDescriptionError
        Wrong shape, non-finite entry, diagonal ≠ 1, asymmetric pair, ``|ρ| > 1``, or a
        negative eigenvalue (naming it and the errors that carry its eigenvector).
    """
    names = tuple(names)
    n = len(names)
    R = np.array(matrix, dtype=float)
    if R.shape != (n, n):
        raise MachineDescriptionError(f"correlation matrix must have shape ({n}, {n}); "
                                      f"got {R.shape}")
    if not np.all(np.isfinite(R)):
        i, j = np.argwhere(~np.isfinite(R))[0]
        raise MachineDescriptionError(f"correlation of {names[i]!r} and {names[j]!r} is "
                                      f"not finite: {R[i, j]!r}")
    off = np.flatnonzero(np.abs(np.diag(R) - 1.0) > ROUNDING)
    if off.size:
        raise MachineDescriptionError(f"correlation of {names[off[0]]!r} with itself must be "
                                      f"1; got {R[off[0], off[0]]!r}")
    for test, what in ((np.abs(R - R.T) > ROUNDING, "is not symmetric"),
                       (np.abs(R) > 1.0, "must lie in [-1, 1]")):
        if np.any(test):
            i, j = np.argwhere(test)[0]
            raise MachineDescriptionError(f"correlation of {names[i]!r} and {names[j]!r} "
                                          f"{what}: {R[i, j]!r}")
    R = 0.5 * (R + R.T)
    values, vectors = np.linalg.eigh(R)
    if values[0] < -ROUNDING:
        carriers = np.argsort(-np.abs(vectors[:, 0]))[:4]
        shown = ", ".join(repr(names[i]) for i in carriers if abs(vectors[i, 0]) > 1e-3)
        raise MachineDescriptionError(
            f"correlations are not positive semi-definite: eigenvalue {values[0]:.4g} < 0, "
            f"its eigenvector lies mostly on {shown}; no joint distribution has these "
            f"pairwise correlations")
    R.setflags(write=False)
    return R


def parse_correlation(machine, entries, source: str = "machine"):
    """``machine`` with the correlations of a ``[[correlation]]`` array of tables.

    Each table has ``errors = [name, name]`` (paper names or ISO 230-1 symbols) and
    ``coefficient`` in [-1, 1]. A pair given twice, an error paired with itself and an
    unknown name are refused.
    """
    where = f"{source}: correlation"
    if not isinstance(entries, list):
        raise MachineDescriptionError(f"{where}: expected an array of tables [[correlation]]")
    pairs = []
    for position, entry in enumerate(entries):
        at = f"{where}[{position}]"
        if not isinstance(entry, Mapping):
            raise MachineDescriptionError(f"{at}: expected a table")
        unknown = sorted(set(entry) - {"errors", "coefficient"})
        if unknown or "errors" not in entry or "coefficient" not in entry:
            raise MachineDescriptionError(f"{at}: needs exactly the keys 'errors' and "
                                          f"'coefficient'; got {sorted(entry)}")
        errors, value = entry["errors"], entry["coefficient"]
        if not isinstance(errors, list) or len(errors) != 2 or \
                not all(isinstance(e, str) for e in errors):
            raise MachineDescriptionError(f"{at}.errors: expected two error names; got "
                                          f"{errors!r}")
        pairs.append((errors[0], errors[1], value, at))
    return dataclasses.replace(machine, correlation=_assemble(machine, pairs))


def with_correlation(machine, pairs):
    """A copy of ``machine`` with correlated errors.

    Parameters
    ----------
    machine : Machine
    pairs : mapping, iterable or array
        ``{(name_a, name_b): ρ}``, an iterable of ``(name_a, name_b, ρ)`` (names as paper
        names or ISO 230-1 symbols), or a full ``(n_errors, n_errors)`` correlation matrix.
        Pairs are set on top of the machine's existing correlations; a pair named twice is
        refused.

    Returns
    -------
    Machine
    """
    if isinstance(pairs, np.ndarray):
        return dataclasses.replace(machine, correlation=pairs)
    if isinstance(pairs, Mapping):
        items = [(a, b, rho) for (a, b), rho in pairs.items()]
    else:
        items = [tuple(p) for p in pairs]
        bad = [p for p in items if len(p) != 3]
        if bad:
            raise InputError(f"pairs: expected (name_a, name_b, coefficient); got {bad[0]!r}")
    labelled = [(a, b, rho, f"pairs[{a!r}, {b!r}]") for a, b, rho in items]
    return dataclasses.replace(machine, correlation=_assemble(machine, labelled))


def _assemble(machine, pairs) -> np.ndarray:
    R = np.eye(machine.n_errors) if machine.correlation is None else \
        np.array(machine.correlation)
    given = {}
    for a, b, value, at in pairs:
        i, j = (_index(machine, name, at) for name in (a, b))
        if i == j:
            raise MachineDescriptionError(f"{at}: {a!r} and {b!r} are the same error")
        key = (min(i, j), max(i, j))
        if key in given:
            raise MachineDescriptionError(f"{at}: the pair {a!r}, {b!r} is already given at "
                                          f"{given[key]}")
        given[key] = at
        if isinstance(value, bool) or not isinstance(value, (int, float, np.floating)) or \
                not np.isfinite(value) or abs(value) > 1:
            raise MachineDescriptionError(f"{at}.coefficient: expected a number in [-1, 1]; "
                                          f"got {value!r}")
        R[i, j] = R[j, i] = float(value)
    return check_correlation_matrix(R, machine.error_names)


def _index(machine, name, at) -> int:
    try:
        return machine.error_index(name)
    except KeyError as exc:
        raise MachineDescriptionError(f"{at}: {exc.args[0]}") from None


def correlation_pairs(machine) -> pd.DataFrame:
    """The correlated pairs of a machine: ``error_a, error_b, iso_a, iso_b, coefficient``."""
    columns = ["error_a", "error_b", "iso_a", "iso_b", "coefficient"]
    if machine.correlation is None:
        return pd.DataFrame(columns=columns)
    i, j = np.nonzero(np.triu(machine.correlation, 1))
    names, iso = np.array(machine.error_names), np.array(machine.iso_names)
    return pd.DataFrame({"error_a": names[i], "error_b": names[j], "iso_a": iso[i],
                         "iso_b": iso[j], "coefficient": machine.correlation[i, j]},
                        columns=columns)


def correlation_to_toml(machine) -> list[dict]:
    """The ``[[correlation]]`` tables that describe ``machine.correlation`` (empty when
    none), for writing a machine back to TOML; :func:`parse_correlation` reads them."""
    frame = correlation_pairs(machine)
    return [{"errors": [a, b], "coefficient": float(rho)}
            for a, b, rho in zip(frame["error_a"], frame["error_b"], frame["coefficient"])]


# ----- FOSM --------------------------------------------------------------------------------
def output_covariance(jacobian, tolerances, correlation=None, k: float = 3.0) -> np.ndarray:
    """Covariance of the six outputs, ``J D R D Jᵀ`` with ``D = diag(t/k)``.

    Parameters
    ----------
    jacobian : array_like
        ``(..., 6, n)`` sensitivities.
    tolerances : array_like
        ``(n,)`` tolerances read as ±kσ.
    correlation : array_like, optional
        ``(n, n)`` correlation matrix; ``None`` for independent errors.
    k : float

    Returns
    -------
    numpy.ndarray
        ``(..., 6, 6)``; its diagonal is ``σ_y²`` (Eq. 20 with cross terms).
    """
    a = np.asarray(jacobian, dtype=float) * (np.asarray(tolerances, dtype=float) / k)
    if correlation is None:
        return a @ np.swapaxes(a, -1, -2)
    return a @ np.asarray(correlation) @ np.swapaxes(a, -1, -2)


def euler_terms(jacobian, sigma, correlation=None) -> np.ndarray:
    """Each error's share of ``σ_y²``: ``a_i (R a)_i`` with ``a = j σ``, ``(..., 6, n)``.

    The terms sum to ``σ_y²``; without correlation they are Eq. (20)'s ``(∂y/∂x_i)² σ_i²``.
    """
    a = np.asarray(jacobian, dtype=float) * np.asarray(sigma)[..., None, :]
    return a * a if correlation is None else a * (a @ np.asarray(correlation))


def correlated_sigma(jacobian, sigma, correlation) -> np.ndarray:
    """σ of each output, ``sqrt(jᵀ D R D j)``: ``(..., 6, n), (n,), (n, n) -> (..., 6)``."""
    return np.sqrt(np.maximum(euler_terms(jacobian, sigma, correlation).sum(axis=-1), 0.0))


# ----- the copula --------------------------------------------------------------------------
def correlation_factor(correlation) -> np.ndarray:
    """A factor ``L`` with ``L Lᵀ = R``: the Cholesky factor, or (for a singular ``R``,
    e.g. a pair at ρ = ±1) the symmetric square root from the eigen-decomposition."""
    R = np.asarray(correlation, dtype=float)
    try:
        return np.linalg.cholesky(R)
    except np.linalg.LinAlgError:
        values, vectors = np.linalg.eigh(R)
        return (vectors * np.sqrt(np.maximum(values, 0.0))) @ vectors.T


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
    (:func:`reliability.profiles.travel_factors`), correlates each error along its axis
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
