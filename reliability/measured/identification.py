"""Identification of a built machine's errors from its measurements (docs/measurements.md).

A linear-Gaussian Bayesian update. Readings ``y = A x + B s + e`` with ``x`` the geometric
errors (prior N(0, diag σ²), σ = t/3 of the allocation in force), ``s`` the set-up unknowns
of the runs (flat prior: an instrument zero per quantity a run reads, a ballbar centre's
offset in its circle's plane) and ``e ~ N(0, diag u²)``. ``A`` is the first-order tool-point
deviation in the workpiece frame at zero errors (the analytic Jacobian), read along each
reading's quantity.

Everything is formed in the information form, accumulated over chunks of readings:
``AᵀWA``, ``BᵀWA``, ``BᵀWB``, ``AᵀWy``, ``BᵀWy`` with ``W = diag(1/u²)``. The set-ups are
eliminated exactly by the Schur complement ``F = AᵀWA − (BᵀWA)ᵀ (BᵀWB)⁻¹ BᵀWA``, the
information about the errors once the set-ups are estimated; the posterior precision is
``diag(1/σ²) + F``, factored by Cholesky.

The check of fit is exact for the linear-Gaussian model: the minimum of
``Σ r_i² + x̂ᵀ diag(1/σ²) x̂`` (``r_i`` the normalised residuals at the posterior mean and
the estimated set-ups) equals ``yᵀ Q y`` with ``Q`` the prior-predictive precision with the
set-ups projected out, which is χ² with ``N − n_setup`` degrees of freedom.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy import linalg, stats

from ..acceptance.prediction import tool_point
from ..basics.chunks import chunks, jacobian_bytes
from ..basics.errors import InputError
from ..model.profiles import ConstantProfile, profile_model
from .measurement_files import QUANTITIES, Measurements

#: Two-sided 95 % normal quantile of the posterior intervals.
Z95 = stats.norm.ppf(0.975)
#: Eigenvalues of the prior-scaled information below this fraction of the largest are
#: counted as directions the readings do not see.
RANK_TOLERANCE = 1e-9
#: An error whose posterior σ is above this fraction of its prior σ is still essentially
#: its prior.
PRIOR_LIKE = 0.95
#: The χ² check fails below this upper-tail probability.
CHI2_ALPHA = 1e-3
#: Coefficients of a combination below this fraction of its largest are dropped.
COEFFICIENT_FLOOR = 1e-8


@dataclass(frozen=True)
class SetupColumns:
    """The set-up unknowns: names and, per reading, up to two columns and coefficients."""

    names: tuple[str, ...]
    columns: np.ndarray
    coefficients: np.ndarray


@dataclass(frozen=True, eq=False)
class Identification:
    """A built machine's errors as measured: the posterior and its checks.

    Attributes
    ----------
    machine : Machine
    profile : str
    prior_sd, mean : ndarray (n_errors,)
    covariance : ndarray (n_errors, n_errors)
        Posterior covariance of the errors (mm, rad).
    setup : DataFrame
        ``setup, estimate, sd`` of every set-up unknown.
    rank : int
        Rank of the information about the errors once the set-ups are estimated.
    condition : float
        Condition number of that information (scaled by the prior σ) on its rank.
    combinations : tuple of str
        Directions of the errors that change no reading.
    prior_like : tuple of str
        Errors whose posterior σ is still above :data:`PRIOR_LIKE` of their prior σ.
    residuals : DataFrame
        ``row, run, quantity, value, fitted, normalised`` per reading.
    chi2 : float
    dof : int
    """

    machine: object
    profile: str
    prior_sd: np.ndarray
    mean: np.ndarray
    covariance: np.ndarray
    setup: pd.DataFrame
    rank: int
    condition: float
    combinations: tuple[str, ...]
    prior_like: tuple[str, ...]
    residuals: pd.DataFrame
    chi2: float
    dof: int

    @property
    def errors(self) -> pd.DataFrame:
        """The ``errors.csv`` table: ``error, prior_sd, posterior_mean, posterior_sd, lower,
        upper`` (mm, rad), the interval the 95 % posterior interval."""
        sd = np.sqrt(np.diag(self.covariance))
        return pd.DataFrame({"error": self.machine.error_names, "prior_sd": self.prior_sd,
                             "posterior_mean": self.mean, "posterior_sd": sd,
                             "lower": self.mean - Z95 * sd, "upper": self.mean + Z95 * sd})

    @property
    def chi2_p_value(self) -> float:
        """Upper-tail probability of ``chi2`` under χ²(``dof``)."""
        return float(stats.chi2.sf(self.chi2, self.dof)) if self.dof > 0 else 1.0

    def predict(self, poses) -> tuple[np.ndarray, np.ndarray]:
        """Posterior mean and σ ``(..., 6)`` of the six outputs in the workpiece frame at
        ``poses`` ``(..., n_axes)``, first order."""
        jac = self.machine.jacobian(poses, frame="workpiece")
        mean = jac @ self.mean
        variance = np.einsum("...oi,ij,...oj->...o", jac, self.covariance, jac)
        return mean, np.sqrt(np.maximum(variance, 0.0))

    def sample(self, n: int, rng) -> np.ndarray:
        """``(n, n_errors)`` machines drawn from the posterior."""
        factor = _psd_factor(self.covariance)
        return self.mean + rng.standard_normal((n, len(self.mean))) @ factor.T

    def mean_at(self, poses) -> np.ndarray:
        """``(..., n_errors)``: the posterior mean of every error as it acts at each pose
        ``(..., n_axes)`` (under ``constant`` the same at every pose)."""
        poses = np.asarray(poses, dtype=float)
        return np.broadcast_to(self.mean, poses.shape[:-1] + self.mean.shape).copy()

    def sample_at(self, poses, n: int, rng) -> np.ndarray:
        """``(n, ..., n_errors)``: machines drawn from the posterior, each error's value as it
        acts at each pose ``(..., n_axes)`` (under ``constant`` the same at every pose)."""
        poses = np.asarray(poses, dtype=float)
        drawn = self.sample(n, rng)
        shape = (n,) + (1,) * (poses.ndim - 1) + drawn.shape[1:]
        return np.broadcast_to(drawn.reshape(shape),
                               (n,) + poses.shape[:-1] + drawn.shape[1:]).copy()

    def worst_residual(self) -> pd.Series:
        """The reading with the largest normalised residual."""
        return self.residuals.iloc[int(np.argmax(np.abs(self.residuals["normalised"])))]

    def summary_dict(self) -> dict:
        """The ``summary.json`` keys."""
        return {"readings": len(self.residuals), "parameters": int(len(self.mean)),
                "rank": int(self.rank), "condition": float(self.condition),
                "chi2": float(self.chi2), "dof": int(self.dof), "profile": self.profile,
                "chi2_p_value": self.chi2_p_value, "setups": len(self.setup),
                "combinations": list(self.combinations), "prior_like": list(self.prior_like)}

    def summary(self) -> str:
        """The identification in words: rank, condition, combinations, χ² check."""
        lines = [f"{len(self.residuals)} readings, {len(self.mean)} errors, "
                 f"{len(self.setup)} set-up unknowns; profile {self.profile}",
                 f"rank of the information about the errors: {self.rank} of {len(self.mean)}, "
                 f"condition {self.condition:.3g}"]
        if self.combinations:
            lines.append("moving the errors along these directions changes no reading:")
            lines += [f"  {text}" for text in self.combinations]
        if self.prior_like:
            lines.append(f"still essentially their prior: {', '.join(self.prior_like)}")
        verdict = "consistent" if self.chi2_p_value >= CHI2_ALPHA else "NOT explained"
        lines.append(f"chi2 = {self.chi2:.4g} on {self.dof} degrees of freedom "
                     f"(p = {self.chi2_p_value:.3g}): readings {verdict} by the model")
        if verdict != "consistent":
            worst = self.worst_residual()
            lines.append(f"  worst: run {worst['run']!r}, row {int(worst['row'])} "
                         f"({worst['quantity']}), normalised residual "
                         f"{worst['normalised']:.3g}")
        return "\n".join(lines)


def identify(machine, measurements: Measurements, *, tolerances=None, profile="constant",
             memory: int | None = None) -> Identification:
    """Identify a built machine's errors from its readings.

    Parameters
    ----------
    machine : Machine
    measurements : Measurements
        From :func:`reliability.read_measurements`.
    tolerances : array_like, optional
        Allocation in force; σ = t/3 is each error's prior σ. The machine file's initial
        allocation by default.
    profile : 'constant'
        One value of every motion error along the whole travel.
    memory : int, optional
        Bytes of temporary arrays per chunk of readings.

    Returns
    -------
    Identification
    """
    if not isinstance(measurements, Measurements):
        raise InputError(f"measurements must be read by read_measurements; got "
                         f"{type(measurements).__name__}")
    if not isinstance(profile_model(profile), ConstantProfile):
        raise InputError(f"profile: only 'constant' is identified; got {profile!r}")
    t = machine.initial_allocation if tolerances is None else machine.check_tolerances(tolerances)
    prior_sd = np.asarray(t, dtype=float) / 3.0
    setups = setup_columns(machine, measurements)
    blocks = information_blocks(machine, measurements, setups, memory)
    return _posterior(machine, measurements, setups, blocks, prior_sd, memory)


def reading_rows(machine, measurements, part) -> np.ndarray:
    """``(n, n_errors)``: each reading's first-order sensitivity to every error (the
    Jacobian formed once per distinct pose: a pose is often read for several quantities)."""
    poses = measurements.poses[part]
    distinct, where = np.unique(poses, axis=0, return_inverse=True)
    jac = machine.jacobian(distinct, frame="workpiece")[where.ravel()]
    quantity = measurements.quantity[part]
    radial = quantity == "radial"
    index = np.array([QUANTITIES.index(q) if q != "radial" else 0 for q in quantity])
    rows = jac[np.arange(len(index)), index, :]
    if radial.any():
        direction = radial_directions(machine, poses[radial], measurements.centre[part][radial])
        rows[radial] = np.einsum("nk,nki->ni", direction, jac[radial, :3, :])
    return rows


def radial_directions(machine, poses, centres) -> np.ndarray:
    """Unit vectors from each ballbar centre to the nominal tool point (workpiece frame)."""
    arm = tool_point(machine, poses) - centres
    length = np.linalg.norm(arm, axis=-1, keepdims=True)
    if np.any(length <= 0):
        raise InputError("a radial reading sits at its ballbar's centre")
    return arm / length


def setup_columns(machine, measurements) -> SetupColumns:
    """The set-up unknowns of every run and each reading's columns among them."""
    n = len(measurements)
    columns = np.zeros((n, 2), dtype=np.int64)
    coefficients = np.zeros((n, 2))
    names = []
    for run in measurements.runs:
        rows = np.flatnonzero(measurements.run == run)
        if measurements.quantity[rows[0]] == "radial":
            basis = _circle_plane(machine, measurements, rows, run)
            direction = radial_directions(machine, measurements.poses[rows],
                                          measurements.centre[rows])
            columns[rows] = [len(names), len(names) + 1]
            coefficients[rows] = -direction @ basis.T
            names += [f"{run}:centre_{k}" for k in ("u", "v")]
            continue
        for quantity in pd.unique(measurements.quantity[rows]):
            chosen = rows[measurements.quantity[rows] == quantity]
            columns[chosen, 0] = len(names)
            coefficients[chosen, 0] = 1.0
            names.append(f"{run}:{quantity}")
    return SetupColumns(tuple(names), columns, coefficients)


def _circle_plane(machine, measurements, rows, run) -> np.ndarray:
    """``(2, 3)`` orthonormal directions of a ballbar run's circle plane."""
    arm = tool_point(machine, measurements.poses[rows]) - measurements.centre[rows]
    _, singular, vectors = np.linalg.svd(arm, full_matrices=False)
    if len(singular) < 2 or singular[1] <= 1e-9 * singular[0]:
        raise InputError(f"run {run!r}: its radial readings do not span a plane, so its "
                         f"centre's offset cannot be estimated")
    return vectors[:2]


def information_blocks(machine, measurements, setups, memory=None) -> dict:
    """``AᵀWA, BᵀWA, BᵀWB, AᵀWy, BᵀWy``, accumulated over chunks of readings; ``B`` is
    never formed: each reading touches at most two set-up columns, summed into place."""
    p, s = machine.n_errors, len(setups.names)
    out = {"AA": np.zeros((p, p)), "BA": np.zeros((s, p)), "BB": np.zeros((s, s)),
           "Ay": np.zeros(p), "By": np.zeros(s)}
    for part in chunks(len(measurements), jacobian_bytes(machine), memory):
        weight = 1.0 / measurements.u[part]
        a = reading_rows(machine, measurements, part) * weight[:, None]
        columns = setups.columns[part]
        b = setups.coefficients[part] * weight[:, None]
        y = measurements.value[part] * weight
        out["AA"] += a.T @ a
        out["Ay"] += a.T @ y
        for k in range(columns.shape[1]):
            np.add.at(out["BA"], columns[:, k], b[:, k, None] * a)
            np.add.at(out["By"], columns[:, k], b[:, k] * y)
            for j in range(columns.shape[1]):
                np.add.at(out["BB"], (columns[:, k], columns[:, j]), b[:, k] * b[:, j])
    return out


def _posterior(machine, measurements, setups, blocks, prior_sd, memory) -> Identification:
    setup_factor = _setup_cholesky(blocks["BB"], setups.names)
    gain = linalg.cho_solve(setup_factor, blocks["BA"])
    information = blocks["AA"] - blocks["BA"].T @ gain
    information = 0.5 * (information + information.T)
    drive = blocks["Ay"] - gain.T @ blocks["By"]
    factor = linalg.cho_factor(information + np.diag(1.0 / prior_sd ** 2), lower=True)
    mean = linalg.cho_solve(factor, drive)
    covariance = linalg.cho_solve(factor, np.eye(len(mean)))
    setup_mean = linalg.cho_solve(setup_factor, blocks["By"] - blocks["BA"] @ mean)
    setup_cov = linalg.cho_solve(setup_factor, np.eye(len(setup_mean))) + \
        gain @ covariance @ gain.T
    residuals = _residuals(machine, measurements, setups, mean, setup_mean, memory)
    rank, condition, combinations = _seen_directions(machine, information, prior_sd)
    sd = np.sqrt(np.diag(covariance))
    return Identification(
        machine=machine, profile="constant", prior_sd=prior_sd, mean=mean,
        covariance=covariance,
        setup=pd.DataFrame({"setup": setups.names, "estimate": setup_mean,
                            "sd": np.sqrt(np.diag(setup_cov))}),
        rank=rank, condition=condition, combinations=combinations,
        prior_like=tuple(np.array(machine.error_names)[sd > PRIOR_LIKE * prior_sd]),
        residuals=residuals,
        chi2=float(np.sum(residuals["normalised"] ** 2) + np.sum((mean / prior_sd) ** 2)),
        dof=len(measurements) - len(setups.names))


def _setup_cholesky(matrix, names):
    try:
        return linalg.cho_factor(matrix, lower=True)
    except linalg.LinAlgError:
        diagonal = np.diag(matrix)
        weakest = names[int(np.argmin(diagonal))] if len(names) else "?"
        raise InputError(f"the set-up unknowns cannot be estimated from the readings (first "
                         f"suspect: {weakest!r}); give each run readings that move it") from None


def _residuals(machine, measurements, setups, mean, setup_mean, memory) -> pd.DataFrame:
    fitted = np.empty(len(measurements))
    for part in chunks(len(measurements), jacobian_bytes(machine), memory):
        fitted[part] = reading_rows(machine, measurements, part) @ mean + np.sum(
            setups.coefficients[part] * setup_mean[setups.columns[part]], axis=1)
    return pd.DataFrame({"row": np.arange(1, len(measurements) + 1), "run": measurements.run,
                         "quantity": measurements.quantity, "value": measurements.value,
                         "fitted": fitted,
                         "normalised": (measurements.value - fitted) / measurements.u})


def _seen_directions(machine, information, prior_sd) -> tuple[int, float, tuple[str, ...]]:
    """Rank and condition of the prior-scaled information, and its null space named."""
    scaled = information * np.outer(prior_sd, prior_sd)
    values, vectors = np.linalg.eigh(scaled)
    largest = max(values[-1], 0.0)
    seen = values > RANK_TOLERANCE * largest
    rank = int(np.sum(seen))
    condition = float(largest / values[seen][0]) if rank else float("inf")
    null = vectors[:, ~seen] * prior_sd[:, None]
    return rank, condition, combination_texts(machine.error_names, null)


def combination_texts(names, null) -> tuple[str, ...]:
    """Each direction of a null-space basis ``(n, k)`` as a combination of named errors,
    the basis brought to reduced row-echelon form so that each direction is short."""
    if null.shape[1] == 0:
        return ()
    rows = _row_echelon(null.T)
    return tuple(_combination(names, row) for row in rows)


def _row_echelon(matrix) -> np.ndarray:
    matrix = matrix.copy()
    pivot_row = 0
    for column in range(matrix.shape[1]):
        if pivot_row == matrix.shape[0]:
            break
        candidate = pivot_row + int(np.argmax(np.abs(matrix[pivot_row:, column])))
        if abs(matrix[candidate, column]) <= 1e-9 * np.abs(matrix).max():
            continue
        matrix[[pivot_row, candidate]] = matrix[[candidate, pivot_row]]
        matrix[pivot_row] /= matrix[pivot_row, column]
        others = np.arange(matrix.shape[0]) != pivot_row
        matrix[others] -= np.outer(matrix[others, column], matrix[pivot_row])
        pivot_row += 1
    return matrix[:pivot_row]


def _combination(names, row) -> str:
    keep = np.abs(row) > COEFFICIENT_FLOOR * np.abs(row).max()
    terms = []
    for name, value in zip(np.array(names)[keep], row[keep]):
        sign = "-" if value < 0 else "+"
        size = "" if np.isclose(abs(value), 1.0) else f"{abs(value):.4g}·"
        terms.append(f"{sign} {size}{name}")
    text = " ".join(terms)
    return text[2:] if text.startswith("+ ") else text


def _psd_factor(covariance) -> np.ndarray:
    values, vectors = np.linalg.eigh(covariance)
    return vectors * np.sqrt(np.maximum(values, 0.0))
