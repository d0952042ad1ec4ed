"""Identification of a built machine's errors from its measurements (docs/measurements.md).

A linear-Gaussian Bayesian update. Readings ``y = A θ + B s + e`` with ``θ`` the errors as
standard-normal coefficients (:mod:`reliability.measured.travel_bases`: under ``constant``
``θ = x/σ``, σ = t/3 of the allocation in force; under ``gp:<ℓ>`` each motion error is a
Gaussian process along travel in its Karhunen–Loève basis), ``s`` the set-up unknowns of
the runs (flat prior: an instrument zero per quantity a run reads, a ballbar centre's offset
in its circle's plane) and ``e ~ N(0, diag u²)``. ``A`` is the first-order tool-point
deviation in the workpiece frame at zero errors (the analytic Jacobian), read along each
reading's quantity and carried to the coefficients; with ``iterate`` it is re-linearised at
the posterior mean on the exact chain (Gauss–Newton, :mod:`reliability.measured.relinearisation`).

Everything is formed in the information form, accumulated over chunks of readings:
``AᵀWA``, ``BᵀWA``, ``BᵀWB``, ``AᵀWy``, ``BᵀWy`` with ``W = diag(1/u²)``. The set-ups are
eliminated exactly by the Schur complement ``F = AᵀWA − (BᵀWA)ᵀ (BᵀWB)⁻¹ BᵀWA``, the
information about the errors once the set-ups are estimated; the posterior precision is
``I + F``, factored by Cholesky.

The check of fit is exact for the linear-Gaussian model: the minimum of
``Σ r_i² + θ̂ᵀθ̂`` (``r_i`` the normalised residuals at the posterior mean and the estimated
set-ups) equals ``yᵀ Q y`` with ``Q`` the prior-predictive precision with the set-ups
projected out, which is χ² with ``N − n_setup`` degrees of freedom.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy import stats

from ..acceptance.iso_tests import tool_point
from ..basics import streams
from ..basics.chunks import chunks, jacobian_bytes
from ..basics.display import ZERO_RESOLUTION
from ..basics.errors import InputError
from ..model.error_draws import psd_factor
from .measurement_files import QUANTITIES, Measurements
from .identification_files import read_identification_fields, write_identification
from .information import add_readings, eliminate_setups, empty_blocks, setup_effect, solve
from .plans import planned_readings
from .relinearisation import gauss_newton
from .travel_bases import Coefficients, travel_bases

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
#: Columns of the ``profiles.csv`` table.
PROFILE_COLUMNS = ("error", "position", "prior_sd", "posterior_mean", "posterior_sd",
                   "lower", "upper")


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
        ``'constant'`` or ``'gp:<ℓ>'``.
    prior_sd, mean : ndarray (n_errors,)
    covariance : ndarray (n_errors, n_errors)
        Prior σ, posterior mean and covariance of every error (mm, rad); under ``gp`` of a
        motion error's mean over its stroke.
    setup : DataFrame
        ``setup, estimate, sd`` of every set-up unknown.
    rank : int
        Rank of the information about the errors (their coefficients under ``gp``) once
        the set-ups are estimated.
    condition : float
        Condition number of that information (scaled by the prior σ) on its rank.
    combinations : tuple of str
        Directions of the errors, each motion error shifted by one amount along its whole
        travel, that change no reading.
    prior_like : tuple of str
        Rows of :attr:`errors` whose posterior σ is still above :data:`PRIOR_LIKE` of their
        prior σ.
    residuals : DataFrame
        ``row, run, quantity, value, fitted, normalised`` per reading.
    chi2 : float
    dof : int
    coefficients : Coefficients, optional
        How the errors are written as standard-normal coefficients; one per error (the
        ``constant`` profile) when not given.
    theta : ndarray (n_coefficients,), optional
    theta_covariance : ndarray (n_coefficients, n_coefficients), optional
        Posterior mean and covariance of the coefficients; from :attr:`mean` and
        :attr:`covariance` when not given.
    positions : tuple of ndarray
        The distinct positions (mm, rad) each axis is read at.
    iterations : int
        Gauss–Newton re-linearisations on the exact chain (0: first order at zero errors).
    change : float
        Largest change of a posterior mean (a row of :attr:`errors` or :attr:`profiles`)
        the re-linearisations made, in units of its posterior σ.
    settled : bool
        Whether the last re-linearisation moved no coefficient by more than
        :data:`reliability.measured.relinearisation.SETTLED` of its σ.
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
    coefficients: Coefficients | None = None
    theta: np.ndarray | None = None
    theta_covariance: np.ndarray | None = None
    positions: tuple = ()
    iterations: int = 0
    change: float = 0.0
    settled: bool = True

    def __post_init__(self):
        if self.coefficients is None:
            sigma = np.asarray(self.prior_sd, dtype=float)
            object.__setattr__(self, "coefficients", Coefficients(
                travel_bases(self.machine, "constant"), sigma))
            object.__setattr__(self, "theta", np.asarray(self.mean) / sigma)
            object.__setattr__(self, "theta_covariance",
                               np.asarray(self.covariance) / np.outer(sigma, sigma))

    @property
    def errors(self) -> pd.DataFrame:
        """The ``errors.csv`` table: ``error, prior_sd, posterior_mean, posterior_sd, lower,
        upper`` (mm, rad), the interval the 95 % posterior interval; under ``gp`` a motion
        error's row is its mean over the stroke."""
        sd = np.sqrt(np.diag(self.covariance))
        mean = _prior_where_uninformed(self.mean, self.prior_sd)
        return pd.DataFrame({"error": self.machine.error_names, "prior_sd": self.prior_sd,
                             "posterior_mean": mean, "posterior_sd": sd,
                             "lower": mean - Z95 * sd, "upper": mean + Z95 * sd})

    @property
    def profiles(self) -> pd.DataFrame:
        """The ``profiles.csv`` table: every motion error at every position its axis is
        read at (``position`` in mm, or degrees on a rotary axis): ``error, position,
        prior_sd, posterior_mean, posterior_sd, lower, upper`` (mm, rad). Empty under
        ``constant``."""
        if not self.coefficients.varies:
            return pd.DataFrame({name: [] for name in PROFILE_COLUMNS})
        parts = [self._axis_profiles(a) for a in range(len(self.positions))]
        return pd.concat(parts, ignore_index=True)

    def _axis_profiles(self, a: int) -> pd.DataFrame:
        positions = self.positions[a]
        prior, mean, sd = self.coefficients.profile_moments(a, positions, self.theta,
                                                            self.theta_covariance)
        mean = _prior_where_uninformed(mean, prior)
        axis = self.machine.axis_specs[a]
        shown = np.degrees(positions) if axis.kind == "rotary" else positions
        names = np.array(self.machine.error_names[6 * a:6 * a + 6])
        return pd.DataFrame({
            "error": np.repeat(names, len(positions)), "position": np.tile(shown, 6),
            "prior_sd": prior.ravel(), "posterior_mean": mean.ravel(),
            "posterior_sd": sd.ravel(), "lower": (mean - Z95 * sd).ravel(),
            "upper": (mean + Z95 * sd).ravel()})

    @property
    def chi2_p_value(self) -> float:
        """Upper-tail probability of ``chi2`` under χ²(``dof``)."""
        return float(stats.chi2.sf(self.chi2, self.dof)) if self.dof > 0 else 1.0

    def predict(self, poses, frame: str = "workpiece") -> tuple[np.ndarray, np.ndarray]:
        """Posterior mean and σ ``(..., 6)`` of the six outputs in ``frame`` (the workpiece
        frame, where readings are taken, by default) at ``poses`` ``(..., n_axes)``, first
        order, each error taken at the pose's position along its axis."""
        if not self.coefficients.varies:
            jac = self.machine.jacobian(poses, frame=frame)
            variance = np.einsum("...oi,ij,...oj->...o", jac, self.covariance, jac)
            return jac @ self.mean, np.sqrt(np.maximum(variance, 0.0))
        poses = self.machine.check_positions(poses)
        flat = poses.reshape(-1, poses.shape[-1])
        mean, sd = np.empty((len(flat), 6)), np.empty((len(flat), 6))
        width = 6 * 8 * (self.coefficients.size + 2 * self.machine.n_errors)
        for part in chunks(len(flat), width):
            rows = self.coefficients.rows(self.machine.jacobian(flat[part], frame=frame),
                                          flat[part])
            mean[part] = rows @ self.theta
            sd[part] = np.sqrt(np.maximum(np.sum((rows @ self.theta_covariance) * rows,
                                                 axis=-1), 0.0))
        shape = poses.shape[:-1] + (6,)
        return mean.reshape(shape), sd.reshape(shape)

    def sample(self, n: int, rng) -> np.ndarray:
        """``(n, n_errors)`` draws of the rows of :attr:`errors` from the posterior (the
        errors themselves under ``constant``)."""
        factor = psd_factor(self.covariance)
        normals = streams.generator(rng).standard_normal((n, len(self.mean)))
        return self.mean + normals @ factor.T

    def mean_at(self, poses) -> np.ndarray:
        """``(..., n_errors)``: the posterior mean of every error as it acts at each pose
        ``(..., n_axes)``, a motion error at the pose's position along its axis (under
        ``constant`` the same at every pose)."""
        poses = np.asarray(poses, dtype=float)
        if not self.coefficients.varies:
            return np.broadcast_to(self.mean, poses.shape[:-1] + self.mean.shape).copy()
        return self.coefficients.values(self.theta, poses)

    def sample_at(self, poses, n: int, rng) -> np.ndarray:
        """``(n, ..., n_errors)``: machines drawn from the posterior, each error's value as it
        acts at each pose ``(..., n_axes)`` (under ``constant`` the same at every pose)."""
        poses = np.asarray(poses, dtype=float)
        if not self.coefficients.varies:
            drawn = self.sample(n, rng)
            shape = (n,) + (1,) * (poses.ndim - 1) + drawn.shape[1:]
            return np.broadcast_to(drawn.reshape(shape),
                                   (n,) + poses.shape[:-1] + drawn.shape[1:]).copy()
        factor = psd_factor(self.theta_covariance)
        normals = streams.generator(rng).standard_normal((n, len(self.theta)))
        return self.coefficients.values(self.theta + normals @ factor.T, poses)

    def worst_residual(self) -> pd.Series:
        """The reading with the largest normalised residual."""
        return self.residuals.iloc[int(np.argmax(np.abs(self.residuals["normalised"])))]

    def summary_dict(self) -> dict:
        """The ``summary.json`` keys."""
        return {"readings": len(self.residuals), "parameters": int(self.machine.n_errors),
                "coefficients": int(self.coefficients.size),
                "rank": int(self.rank), "condition": float(self.condition),
                "chi2": float(self.chi2), "dof": int(self.dof), "profile": self.profile,
                "chi2_p_value": self.chi2_p_value, "setups": len(self.setup),
                "combinations": list(self.combinations), "prior_like": list(self.prior_like),
                "iterations": int(self.iterations), "change": float(self.change),
                "settled": bool(self.settled)}

    def to_frame(self) -> pd.DataFrame:
        """The errors' posterior, one row per error: :attr:`errors`."""
        return self.errors

    def save(self, folder, overwrite: bool = False) -> tuple:
        """Write the identification's folder
        (:func:`reliability.measured.identification_files.write_identification`): with
        ``overwrite`` an earlier identification's files this one does not write are
        removed. Returns the names of the files written."""
        return write_identification(self, folder, overwrite)

    @classmethod
    def load(cls, folder, machine) -> "Identification":
        """The identification saved in ``folder``, on ``machine`` (the one it was identified
        on, which the folder does not hold), checked
        (:func:`reliability.measured.identification_files.read_identification_fields`); a
        damaged file raises :class:`~reliability.basics.errors.SavedResultError` naming it.
        The posterior means and σ come back to the six digits of ``errors.csv`` under
        ``constant``, every digit under ``gp``."""
        return cls(**read_identification_fields(folder, machine))

    def summary(self) -> str:
        """The identification in words: rank, condition, combinations, χ² check."""
        lines = [f"{len(self.residuals)} readings, {self.machine.n_errors} errors, "
                 f"{len(self.setup)} set-up unknowns; profile {self.profile}"]
        if self.coefficients.varies:
            lines.append(f"the errors along travel as {self.coefficients.size} coefficients; "
                         f"rank of the information about them: {self.rank} of "
                         f"{self.coefficients.size}, condition {self.condition:.3g}")
        else:
            lines.append(f"rank of the information about the errors: {self.rank} of "
                         f"{self.machine.n_errors}, condition {self.condition:.3g}")
        if self.combinations:
            lines.append("moving the errors along these directions changes no reading"
                         + (" (motion errors shifted along their whole travel):"
                            if self.coefficients.varies else ":"))
            lines += [f"  {text}" for text in self.combinations]
        if self.prior_like:
            lines.append(f"still essentially their prior: {', '.join(self.prior_like)}")
        if self.iterations:
            lines.append(self._iteration_text())
        verdict = "consistent" if self.chi2_p_value >= CHI2_ALPHA else "NOT explained"
        lines.append(f"chi2 = {self.chi2:.4g} on {self.dof} degrees of freedom "
                     f"(p = {self.chi2_p_value:.3g}): readings {verdict} by the model")
        if verdict != "consistent":
            worst = self.worst_residual()
            lines.append(f"  worst: run {worst['run']!r}, row {int(worst['row'])} "
                         f"({worst['quantity']}), normalised residual "
                         f"{worst['normalised']:.3g}")
        return "\n".join(lines)

    def _iteration_text(self) -> str:
        settled = "settled" if self.settled else "NOT settled"
        return (f"re-linearised on the exact chain at the posterior mean: {self.iterations} "
                f"iteration{'s' if self.iterations > 1 else ''}, {settled}; the largest "
                f"change of a posterior mean is {self.change:.3g} of its posterior sigma")


def read_identification(folder, machine) -> Identification:
    """The identification saved in ``folder`` on ``machine``: :meth:`Identification.load`."""
    return Identification.load(folder, machine)


def identify(machine, measurements: Measurements, *, tolerances=None, profile="constant",
             iterate: bool = False, memory: int | None = None) -> Identification:
    """Identify a built machine's errors from its readings.

    Parameters
    ----------
    machine : Machine
    measurements : Measurements
        From :func:`reliability.read_measurements`.
    tolerances : array_like, optional
        Allocation in force; σ = t/3 is each error's prior σ. The machine file's initial
        allocation by default.
    profile : 'constant' or 'gp:<length mm>'
        One value of every motion error along the whole travel, or a Gaussian process
        along travel with the kernel of docs/profiles.md.
    iterate : bool
        Re-linearise at the posterior mean on the exact chain until it settles
        (Gauss–Newton).
    memory : int, optional
        Bytes of temporary arrays per chunk of readings.

    Returns
    -------
    Identification
    """
    if not isinstance(measurements, Measurements):
        raise InputError(f"measurements must be read by read_measurements; got "
                         f"{type(measurements).__name__}")
    t = machine.initial_allocation if tolerances is None else machine.check_tolerances(tolerances)
    coefficients = Coefficients(travel_bases(machine, profile), np.asarray(t, float) / 3.0)
    setups = setup_columns(machine, measurements)
    blocks, item_blocks = _first_order_blocks(machine, measurements, setups, coefficients,
                                              memory)
    fit = solve(blocks, setups.names)
    iterations, change, settled, fitted = 0, 0.0, True, None
    if iterate:
        first = fit
        fit, iterations, settled, fitted = gauss_newton(
            machine, measurements, setups, coefficients, fit, memory)
        change = _largest_change(coefficients, measurements, first, fit)
    if fitted is None:
        fitted = _first_order_fitted(machine, measurements, setups, coefficients, fit, memory)
    return _identification(machine, measurements, setups, coefficients, fit, fitted,
                           item_blocks, profile=str(profile), iterations=iterations,
                           change=change, settled=settled)


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
    """``AᵀWA, BᵀWA, BᵀWB, AᵀWy, BᵀWy`` of the errors (one value each along travel) at zero
    errors, accumulated over chunks of readings."""
    out = empty_blocks(machine.n_errors, len(setups.names))
    for part in chunks(len(measurements), jacobian_bytes(machine), memory):
        add_readings(out, setups, part, reading_rows(machine, measurements, part),
                     measurements.value[part], measurements.u[part])
    return out


def plan_information(machine, runs) -> np.ndarray:
    """``(n_errors, n_errors)``: what the plan's ``runs`` tell about the errors (one value
    each along travel) once each run's set-up is estimated, the Schur complement
    ``AᵀWA − (BᵀWA)ᵀ(BᵀWB)⁻¹BᵀWA``; it depends on the plan's poses, quantities and ``u``
    only, not on what is read."""
    readings = planned_readings(runs)
    setups = setup_columns(machine, readings)
    blocks = information_blocks(machine, readings, setups)
    return eliminate_setups(blocks, setups.names)[2]


def _first_order_blocks(machine, measurements, setups, coefficients, memory):
    """The blocks of the coefficients and, when the errors vary along travel, of the errors
    as constant shifts (for naming what cannot be told apart), in one pass."""
    blocks = empty_blocks(coefficients.size, len(setups.names))
    item = empty_blocks(machine.n_errors, len(setups.names)) if coefficients.varies else None
    width = jacobian_bytes(machine) + 16 * coefficients.size
    for part in chunks(len(measurements), width, memory):
        rows = reading_rows(machine, measurements, part)
        values, u = measurements.value[part], measurements.u[part]
        add_readings(blocks, setups, part, coefficients.rows(rows, measurements.poses[part]),
                     values, u)
        if item is not None:
            add_readings(item, setups, part, rows, values, u)
    return blocks, item


def _first_order_fitted(machine, measurements, setups, coefficients, fit, memory):
    fitted = np.empty(len(measurements))
    width = jacobian_bytes(machine) + 16 * coefficients.size
    for part in chunks(len(measurements), width, memory):
        rows = coefficients.rows(reading_rows(machine, measurements, part),
                                 measurements.poses[part])
        fitted[part] = rows @ fit.theta + setup_effect(setups, part, fit.setup_mean)
    return fitted


def distinct_positions(measurements) -> tuple:
    """The distinct positions (mm, rad) each axis is read at."""
    return tuple(np.unique(column) for column in measurements.poses.T)


def _reported(coefficients, positions, fit) -> tuple[np.ndarray, np.ndarray]:
    """Mean and σ of every reported quantity: the rows of ``errors.csv`` and, under ``gp``,
    of ``profiles.csv``."""
    rows = coefficients.mean_matrix()
    means = [rows @ fit.theta]
    sds = [np.sqrt(np.maximum(np.sum((rows @ fit.covariance) * rows, axis=1), 0.0))]
    if coefficients.varies:
        for a, where in enumerate(positions):
            _, mean, sd = coefficients.profile_moments(a, where, fit.theta, fit.covariance)
            means.append(mean.ravel())
            sds.append(sd.ravel())
    return np.concatenate(means), np.concatenate(sds)


def _largest_change(coefficients, measurements, first, last) -> float:
    positions = distinct_positions(measurements)
    before, _ = _reported(coefficients, positions, first)
    after, sd = _reported(coefficients, positions, last)
    seen = sd > 0
    return float(np.max(np.abs(after - before)[seen] / sd[seen], initial=0.0))


def _identification(machine, measurements, setups, coefficients, fit, fitted, item_blocks,
                    **status) -> Identification:
    residuals = pd.DataFrame({"row": np.arange(1, len(measurements) + 1),
                              "run": measurements.run, "quantity": measurements.quantity,
                              "value": measurements.value, "fitted": fitted,
                              "normalised": (measurements.value - fitted) / measurements.u})
    rank, condition, null = _seen_directions(fit.information)
    # no reading informs the null directions: there the posterior mean is the prior's, 0
    # exactly, not the rounding a solve leaves (which differs between computers)
    theta = fit.theta - null @ (null.T @ fit.theta)
    if item_blocks is None:
        combinations = combination_texts(machine.error_names,
                                         null * coefficients.prior_sd[:, None])
    else:
        item_information = eliminate_setups(item_blocks, setups.names)[2]
        scale = coefficients.prior_sd
        _, _, item_null = _seen_directions(item_information * np.outer(scale, scale))
        combinations = combination_texts(machine.error_names, item_null * scale[:, None])
    rows = coefficients.mean_matrix()
    covariance = rows @ fit.covariance @ rows.T
    prior, sd = np.sqrt(np.sum(rows ** 2, axis=1)), np.sqrt(np.diag(covariance))
    return Identification(
        machine=machine, prior_sd=prior, mean=rows @ theta, covariance=covariance,
        coefficients=coefficients, theta=theta, theta_covariance=fit.covariance,
        positions=distinct_positions(measurements),
        setup=pd.DataFrame({"setup": setups.names, "estimate": fit.setup_mean,
                            "sd": np.sqrt(np.diag(fit.setup_covariance))}),
        rank=rank, condition=condition, combinations=combinations,
        prior_like=tuple(np.array(machine.error_names)[sd > PRIOR_LIKE * prior]),
        residuals=residuals,
        chi2=float(np.sum(residuals["normalised"] ** 2) + np.sum(fit.theta ** 2)),
        dof=len(measurements) - len(setups.names), **status)


def _prior_where_uninformed(mean, prior_sd) -> np.ndarray:
    """Posterior means zero to rounding (within :data:`~reliability.basics.display.
    ZERO_RESOLUTION` of the prior σ) as the prior mean, 0: an error no reading informs
    has no other mean, and its rounding (1e-17 mm) would print as digits."""
    mean = np.asarray(mean, dtype=float)
    return np.where(np.abs(mean) <= ZERO_RESOLUTION * np.asarray(prior_sd), 0.0, mean)


def _seen_directions(information) -> tuple[int, float, np.ndarray]:
    """Rank and condition of an information matrix of unit-prior unknowns, and a basis
    ``(n, k)`` of its null space."""
    values, vectors = np.linalg.eigh(information)
    largest = max(values[-1], 0.0)
    seen = values > RANK_TOLERANCE * largest
    rank = int(np.sum(seen))
    condition = float(largest / values[seen][0]) if rank else float("inf")
    return rank, condition, vectors[:, ~seen]


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
