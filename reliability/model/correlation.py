"""Correlated geometric errors: the correlation matrix of a machine description.

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

FOSM with the matrix is :mod:`reliability.first_order.output_covariance`; drawing
correlated errors through a Gaussian copula is :mod:`reliability.model.error_draws`.
"""

from __future__ import annotations

import dataclasses
from typing import Mapping

import numpy as np
import pandas as pd

from ..basics.errors import InputError, MachineDescriptionError

#: Largest asymmetry or negative eigenvalue accepted as rounding.
ROUNDING = 1e-10


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
                                      f"not finite: {float(R[i, j])!r}")
    off = np.flatnonzero(np.abs(np.diag(R) - 1.0) > ROUNDING)
    if off.size:
        raise MachineDescriptionError(f"correlation of {names[off[0]]!r} with itself must be "
                                      f"1; got {float(R[off[0], off[0]])!r}")
    for test, what in ((np.abs(R - R.T) > ROUNDING, "is not symmetric"),
                       (np.abs(R) > 1.0, "must lie in [-1, 1]")):
        if np.any(test):
            i, j = np.argwhere(test)[0]
            raise MachineDescriptionError(f"correlation of {names[i]!r} and {names[j]!r} "
                                          f"{what}: {float(R[i, j])!r}")
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
