"""The error a compensated machine keeps (docs/compensation.md).

A compensated machine runs with ``r = x − c(q)``: its errors ``x`` less the table's values
``c(q)``, linear between table positions. With the table the posterior mean ``m`` of the
tabled items (``S`` the diagonal 0/1 mask of them), over the machines built to an allocation
(prior ``Σ = diag(σ²)``, ``σ = t/3`` as the identification reads it) and measured under a
plan whose information about the errors is ``F`` (set-ups eliminated), the residual has
covariance::

    Cov(r) = P + (I − S)(Σ − P)(I − S),      P = (Σ⁻¹ + F)⁻¹

(the posterior error ``x − m`` has covariance ``P`` and is uncorrelated with ``m``, whose
covariance is ``Σ − P``). A rule held fixed, ``c = S L y`` with the gain of the posterior at
``Σ₀``, leaves ``r = (I − S P₀ F) x − S (noise)``, whose covariance
``M Σ Mᵀ + S P₀ F P₀ S`` (``M = I − S P₀ F``) is linear in ``Σ``
(:func:`fixed_rule_terms`); at ``Σ = Σ₀`` it equals the formula above.

Not compensable: each linear axis' repeatability (σ of one approach) and reversal (a
``±B/2`` offset by the approach direction, variance ``B²/4``) act as its positioning error
``E<D><axis>`` does, pose by pose; they add ``J² (σ_R² + B²/4)`` to each output's variance
(:func:`positioning_variance`).
"""

from __future__ import annotations

import numpy as np
from scipy import linalg
from scipy.stats import norm

from ..model.kinematics import comprehensive_error


def posterior_covariance(prior_sd, information) -> np.ndarray:
    """``P = (Σ⁻¹ + F)⁻¹`` with ``Σ = diag(prior_sd²)``, formed as
    ``D (I + D F D)⁻¹ D`` (``D = diag(prior_sd)``) so that a zero σ is allowed."""
    scale = np.asarray(prior_sd, dtype=float)
    inner = np.eye(len(scale)) + information * np.outer(scale, scale)
    return linalg.solve(inner, np.diag(scale), assume_a="pos") * scale[:, None]


def residual_covariance(prior_sd, information, tabled) -> np.ndarray:
    """``Cov(r) = P + (I − S)(Σ − P)(I − S)`` of machines compensated with the posterior
    mean of the ``tabled`` items (boolean mask)."""
    posterior = posterior_covariance(prior_sd, information)
    untabled = ~np.asarray(tabled, dtype=bool)
    out = posterior.copy()
    block = np.ix_(untabled, untabled)
    out[block] = np.diag(np.square(np.asarray(prior_sd, dtype=float)[untabled]))
    return out


def fixed_rule_terms(prior_sd, information, tabled) -> tuple[np.ndarray, np.ndarray]:
    """``(M, N)`` with ``Cov(r) = M diag(σ²) Mᵀ + N`` for every prior σ, the table's rule
    (the posterior mean's gain at ``prior_sd``) held fixed: ``M = I − S P₀ F``,
    ``N = S P₀ F P₀ S``."""
    posterior = posterior_covariance(prior_sd, information)
    mask = np.asarray(tabled, dtype=float)
    gain = mask[:, None] * (posterior @ information)
    noise = mask[:, None] * (posterior @ information @ posterior) * mask[None, :]
    return np.eye(len(mask)) - gain, 0.5 * (noise + noise.T)


def positioning_variance(machine) -> np.ndarray:
    """``(n_errors,)``: ``σ_R² + B²/4`` of each linear axis on its positioning error, 0
    elsewhere: the part no table removes."""
    out = np.zeros(machine.n_errors)
    for axis in machine.axis_specs:
        if axis.kind == "linear":
            index = machine.error_index(f"{axis.name}.d{axis.direction}")
            out[index] = axis.repeatability ** 2 + 0.25 * axis.reversal ** 2
    return out


def output_sigma(machine, poses, covariance, extra_variance=None, frame=None) -> np.ndarray:
    """``(n_poses, 6)``: σ of the six outputs for errors of ``covariance`` plus independent
    ``extra_variance`` per error, first order, in ``frame`` (default the machine's)."""
    jac = machine.jacobian(poses, frame=frame or machine.frame)
    variance = np.einsum("...oi,ij,...oj->...o", jac, covariance, jac)
    if extra_variance is not None:
        variance = variance + np.square(jac) @ extra_variance
    return np.sqrt(np.maximum(variance, 0.0))


def two_sided(limits, sigma, mean=0.0) -> np.ndarray:
    """``P(|N(mean, σ²)| ≤ limit)`` per output."""
    sigma = np.maximum(sigma, 1e-300)
    return norm.cdf((limits - mean) / sigma) - norm.cdf((-limits - mean) / sigma)


def measured_residual(identification, tables, poses, frame=None
                      ) -> tuple[np.ndarray, np.ndarray]:
    """Mean and σ ``(n_poses, 6)`` of one measured machine's outputs once compensated by
    ``tables``: the mean is what the table leaves of the posterior mean (between its
    positions, beyond its range, items outside it), the σ the posterior's with the
    repeatability and reversal added."""
    machine = identification.machine
    poses = machine.check_positions(poses)
    jac = machine.jacobian(poses, frame=frame or machine.frame)
    left = identification.mean_at(poses) - tables.values_at(poses)
    mean = np.einsum("...oi,...i->...o", jac, left)
    posterior = identification.predict(poses, frame=frame or machine.frame)[1]
    variance = posterior ** 2 + np.square(jac) @ positioning_variance(machine)
    return mean, np.sqrt(variance)


def compensated_deviation(machine, poses, errors, tables, rng, frame=None) -> np.ndarray:
    """Exact outputs ``(..., n_poses, 6)`` of machines with ``errors`` ``(..., n_errors)``
    (or as they act at each pose, ``(..., n_poses, n_errors)``) compensated by ``tables``,
    each pose approached once: its repeatability drawn and its reversal's sign at random."""
    poses = machine.check_positions(poses)
    errors = np.asarray(errors, dtype=float)
    if errors.ndim == 1 or errors.shape[-2:-1] != poses.shape[:1]:
        errors = errors[..., None, :]
    residual = errors - tables.values_at(poses)
    residual = residual + positioning_draws(machine, residual.shape[:-1], rng)
    return comprehensive_error(machine, poses, residual, frame=frame or machine.frame)


def positioning_draws(machine, shape, rng) -> np.ndarray:
    """``shape + (n_errors,)``: one approach's repeatability ``N(0, σ_R²)`` plus
    ``±B/2`` on each linear axis' positioning error."""
    out = np.zeros(tuple(shape) + (machine.n_errors,))
    for axis in machine.axis_specs:
        if axis.kind == "linear" and (axis.repeatability or axis.reversal):
            index = machine.error_index(f"{axis.name}.d{axis.direction}")
            sign = rng.choice((-0.5, 0.5), size=shape)
            out[..., index] = axis.repeatability * rng.standard_normal(shape) + \
                axis.reversal * sign
    return out
