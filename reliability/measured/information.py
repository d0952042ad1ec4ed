"""The information form of a linear-Gaussian identification (docs/measurements.md).

Readings ``y = A θ + B s + e``: ``θ`` unknowns with prior N(0, I), ``s`` set-up unknowns with
a flat prior, ``e ~ N(0, diag u²)``. ``AᵀWA``, ``BᵀWA``, ``BᵀWB``, ``AᵀWy``, ``BᵀWy`` with
``W = diag(1/u²)`` are accumulated over chunks of readings; the set-ups are eliminated by
the Schur complement ``F = AᵀWA − (BᵀWA)ᵀ (BᵀWB)⁻¹ BᵀWA`` and the posterior precision
``I + F`` is factored by Cholesky.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import linalg

from ..basics.errors import InputError


@dataclass(frozen=True, eq=False)
class Fit:
    """One linear-Gaussian solution: the coefficients' posterior and the set-ups'."""

    theta: np.ndarray
    covariance: np.ndarray
    information: np.ndarray
    setup_mean: np.ndarray
    setup_covariance: np.ndarray


def empty_blocks(n_parameters: int, n_setups: int) -> dict:
    """Zero ``AᵀWA, BᵀWA, BᵀWB, AᵀWy, BᵀWy`` for ``n_parameters`` columns of ``A``."""
    p, s = n_parameters, n_setups
    return {"AA": np.zeros((p, p)), "BA": np.zeros((s, p)), "BB": np.zeros((s, s)),
            "Ay": np.zeros(p), "By": np.zeros(s)}


def add_readings(blocks, setups, part, rows, values, u, *, setup_terms=True) -> None:
    """Add the readings ``part`` (sensitivity ``rows``, ``values``, uncertainties ``u``) to
    ``blocks`` in place; ``B`` is never formed: each reading touches at most two set-up
    columns, summed into place (``setup_terms=False`` leaves ``BᵀWB`` alone)."""
    weight = 1.0 / u
    a = rows * weight[:, None]
    columns = setups.columns[part]
    b = setups.coefficients[part] * weight[:, None]
    y = values * weight
    blocks["AA"] += a.T @ a
    blocks["Ay"] += a.T @ y
    for k in range(columns.shape[1]):
        np.add.at(blocks["BA"], columns[:, k], b[:, k, None] * a)
        np.add.at(blocks["By"], columns[:, k], b[:, k] * y)
        if setup_terms:
            for j in range(columns.shape[1]):
                np.add.at(blocks["BB"], (columns[:, k], columns[:, j]), b[:, k] * b[:, j])


def solve(blocks, setup_names) -> Fit:
    """The posterior of the coefficients (prior N(0, I)) and of the set-ups (flat prior)
    from the information blocks."""
    setup_factor, gain, information = eliminate_setups(blocks, setup_names)
    drive = blocks["Ay"] - gain.T @ blocks["By"]
    factor = linalg.cho_factor(information + np.eye(len(drive)), lower=True)
    theta = linalg.cho_solve(factor, drive)
    covariance = linalg.cho_solve(factor, np.eye(len(theta)))
    setup_mean = linalg.cho_solve(setup_factor, blocks["By"] - blocks["BA"] @ theta)
    setup_covariance = linalg.cho_solve(setup_factor, np.eye(len(setup_mean))) + \
        gain @ covariance @ gain.T
    return Fit(theta, covariance, information, setup_mean, setup_covariance)


def eliminate_setups(blocks, setup_names) -> tuple:
    """The set-ups' Cholesky factor, the gain ``(BᵀWB)⁻¹BᵀWA`` and the Schur complement
    ``F``, the information about the unknowns once the set-ups are estimated."""
    setup_factor = _setup_cholesky(blocks["BB"], setup_names)
    gain = linalg.cho_solve(setup_factor, blocks["BA"])
    information = blocks["AA"] - blocks["BA"].T @ gain
    return setup_factor, gain, 0.5 * (information + information.T)


def _setup_cholesky(matrix, names):
    try:
        return linalg.cho_factor(matrix, lower=True)
    except linalg.LinAlgError:
        diagonal = np.diag(matrix)
        weakest = names[int(np.argmin(diagonal))] if len(names) else "?"
        raise InputError(f"the set-up unknowns cannot be estimated from the readings (first "
                         f"suspect: {weakest!r}); give each run readings that move it") from None


def setup_effect(setups, part, setup_mean) -> np.ndarray:
    """Each reading's share of the estimated set-ups."""
    return np.sum(setups.coefficients[part] * setup_mean[setups.columns[part]], axis=1)
