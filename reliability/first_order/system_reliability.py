"""System precision reliability: all six comprehensive errors inside their limits at once.

FOSM (Eqs. 19–23) treats each output alone. A workpiece is good only when every output is
inside its limit, so the machine's reliability at a pose is the probability of the
rectangle ``|y_o| < I_o`` for all six outputs at once. For the linearised model with
normal errors (σ_i = t_i/k, correlation R, the identity unless ``machine.correlation`` is
set) the outputs are jointly normal with mean 0 and covariance ``C = J D R D Jᵀ``,
``D = diag(σ)`` (Eq. 20 is its diagonal for R = I), so that probability is a
six-dimensional normal rectangle probability.

It is computed here by Genz's separation-of-variables transform (Genz 1992, "Numerical
computation of multivariate normal probabilities", J. Comput. Graph. Stat. 1, 141–149):
after a Cholesky factorisation the rectangle probability is the mean of a product of
one-dimensional interval probabilities over the unit cube, which is integrated with
scrambled Sobol' points, independently scrambled in several batches; the spread of the
batch means gives the numerical standard error. Everything is vectorised over poses.

Two bounds come for free from the marginals ``P_o`` (the two-sided FOSM probabilities):

* Šidák's inequality (Šidák 1967, J. Am. Stat. Assoc. 62, 626–633): for a centred normal
  vector, ``P(all |y_o| < I_o) ≥ Π_o P_o``, so the product of the marginals is a lower bound
  (it is exact when the outputs are independent);
* Bonferroni: ``P ≥ 1 − Σ_o (1 − P_o)``, weaker than the product;

and the system can be no more reliable than its least reliable output: ``P ≤ min_o P_o``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy.special import ndtr, ndtri
from scipy.stats import qmc

from ..basics import streams
from ..basics.display import axis_units, bound_text, decimals_text, pose_text
from ..basics.errors import InputError
from ..basics.saved_fields import Array, Integer, Texts, load_fields, save_fields
from ..basics.ties import worst_rows
from ..model.machine import OUTPUTS
from .fosm import two_sided_probability
from .output_covariance import output_covariance

#: Poses × points evaluated at once (bounds memory to a few arrays of this many floats).
CHUNK_SIZE = 2 ** 21


@dataclass(frozen=True, eq=False)
class SystemReliability:
    """Probability that all six outputs are inside their limits, pose by pose.

    Attributes
    ----------
    poses : ndarray (n_poses, n_axes)
    index : ndarray (n_poses,) of int
        Position of each pose in the pose set it came from.
    axes : tuple of str
    probability : ndarray (n_poses,)
        The six-dimensional normal rectangle probability (exact for the linear model, up
        to ``error``).
    error : ndarray (n_poses,)
        Standard error of ``probability`` from the spread of the scrambled batches.
    product : ndarray (n_poses,)
        Product of the six two-sided marginals (Šidák's lower bound).
    bonferroni : ndarray (n_poses,)
        ``max(0, 1 − Σ (1 − P_o))``, the Bonferroni lower bound, clipped at 0 (a bound of
        0 says nothing: printed as trivial).
    marginal : ndarray (n_poses, 6)
        Two-sided FOSM probability of each output.
    n_points : int
        Sobol' points per batch; ``n_batches`` batches.
    n_batches : int
    units : tuple of str
        Unit of each axis' position (``mm`` or ``rad``).
    """

    poses: np.ndarray
    index: np.ndarray
    axes: tuple
    probability: np.ndarray
    error: np.ndarray
    product: np.ndarray
    bonferroni: np.ndarray
    marginal: np.ndarray
    n_points: int
    n_batches: int
    units: tuple = ()

    def save(self, path, overwrite: bool = False):
        """Save as JSON (:data:`SAVED_FIELDS`, tag :data:`SAVED_FORMAT`); an existing file
        is kept unless ``overwrite``. Returns the path."""
        return save_fields(self, path, SAVED_FORMAT, SAVED_FIELDS, overwrite)

    @classmethod
    def load(cls, path) -> "SystemReliability":
        """Reload a result written by :meth:`save`, every field checked; the bounds must
        follow from the saved marginals, so the worst pose and its verdicts are the saved
        ones. A damaged field raises
        :class:`~reliability.basics.errors.SavedResultError` naming the file and field."""
        data, values = load_fields(path, SAVED_FORMAT, SAVED_FIELDS)
        marginal = values["marginal"]
        for key, expected in (("product", marginal.prod(axis=1)),
                              ("bonferroni", np.maximum(0.0, 1.0 - (1.0 - marginal).sum(1)))):
            if not np.allclose(values[key], expected, rtol=1e-12, atol=1e-15):
                raise data.error(key, "does not follow from the saved marginals")
        return cls(**values)

    @property
    def worst(self) -> int:
        """Row (in this result) of the pose with the lowest system probability (ties by the
        first pose, :func:`reliability.basics.ties.worst_rows`)."""
        return worst_rows(self.probability, self.poses, largest=False)

    @property
    def worst_pose(self) -> np.ndarray:
        """Axis positions of the worst pose, ``(n_axes,)``."""
        return self.poses[self.worst]

    @property
    def worst_probability(self) -> float:
        """The lowest system probability over the poses."""
        return float(self.probability[self.worst])

    @property
    def min_marginal(self) -> np.ndarray:
        """Upper bound: the least reliable output at each pose."""
        return self.marginal.min(axis=1)

    def to_frame(self) -> pd.DataFrame:
        """One row per pose: positions, probability, error, product, Bonferroni, least
        marginal (probabilities as fractions)."""
        frame = pd.DataFrame(self.poses, columns=list(self.axes),
                             index=pd.Index(self.index, name="pose"))
        frame["probability"] = self.probability
        frame["error"] = self.error
        frame["product"] = self.product
        frame["bonferroni"] = self.bonferroni
        frame["min_marginal"] = self.min_marginal
        return frame

    def summary(self) -> str:
        """Worst pose and the bounds beside it, one line each."""
        w = self.worst
        positions = pose_text(self.poses[w], self.axes, self.units, digits=6)
        return "\n".join([
            f"system reliability over {len(self.probability)} pose(s) "
            f"({self.n_batches} × {self.n_points} scrambled Sobol' points per pose)",
            f"worst pose {positions}",
            f"  all six inside  {self.probability[w]:.8f} ± {self.error[w]:.2g} (std. error)",
            f"  product         {decimals_text(self.product[w], 8, 'lower')} (Šidák lower "
            f"bound)",
            f"  Bonferroni      {bound_text(self.bonferroni[w], 8)}",
            f"  least output    {decimals_text(self.min_marginal[w], 8, 'upper')} "
            f"({OUTPUTS[int(np.argmin(self.marginal[w]))]})",
        ])

    def __repr__(self) -> str:
        positions = pose_text(self.worst_pose, self.axes, self.units)
        return (f"SystemReliability(n_poses={len(self.probability)}, worst pose "
                f"{positions}: {self.worst_probability:.6g} ± "
                f"{self.error[self.worst]:.2g})")


SAVED_FORMAT = "precrel.system_reliability"
SAVED_FIELDS = (Array("poses", ("n", None)), Array("index", ("n",), dtype=int, low=0),
                Texts("axes", unique=True),
                Array("probability", ("n",), low=0.0, high=1.0),
                Array("error", ("n",), low=0.0),
                Array("product", ("n",), low=0.0, high=1.0),
                Array("bonferroni", ("n",), low=0.0, high=1.0),
                Array("marginal", ("n", len(OUTPUTS)), low=0.0, high=1.0),
                Integer("n_points", low=1), Integer("n_batches", low=1),
                Texts("units"))


def system_reliability(machine, tolerances, poses, *, k: float = 3.0, n_points: int = 1024,
                       n_batches: int = 8, rng=None, jacobian=None) -> SystemReliability:
    """Probability that all six outputs are inside their limits at once, at every pose.

    Parameters
    ----------
    machine : Machine
    tolerances : array_like (n_errors,)
        Allocated tolerances, read as ±kσ, zero mean.
    poses : array_like (n_poses, n_axes)
    k : float
        Coverage factor of the tolerances.
    n_points : int
        Scrambled Sobol' points per batch, a power of 2.
    n_batches : int
        Independent scramblings (≥ 2); their spread gives the standard error.
    rng : None, int or numpy.random.Generator
    jacobian : ndarray, optional
        Precomputed ``machine.jacobian(poses)``.

    Returns
    -------
    SystemReliability
    """
    t, poses, jacobian = _check(machine, tolerances, poses, k, n_points, n_batches, jacobian)
    covariance = output_covariance(jacobian, t, machine.correlation, k)
    return _evaluate(machine, poses, np.arange(len(poses)), covariance, n_points, n_batches,
                     rng)


def worst_system_reliability(machine, tolerances, poses, *, k: float = 3.0,
                             n_points: int = 1024, n_batches: int = 8, rng=None,
                             batch: int = 64, jacobian=None) -> SystemReliability:
    """The system probability at the poses that can be the worst of a large pose set.

    The product of the marginals (vectorised over all poses) is a lower bound at every
    pose (Šidák). Poses are evaluated exactly in order of increasing product, ``batch`` at
    a time, until the next pose's product exceeds the lowest upper confidence limit
    (probability + 4 standard errors) found so far: no pose left out can then be worse.

    Returns
    -------
    SystemReliability
        Over the evaluated poses only (``index`` gives their positions in ``poses``);
        its :attr:`~SystemReliability.worst` is the worst pose of the whole set.
    """
    t, poses, jacobian = _check(machine, tolerances, poses, k, n_points, n_batches, jacobian)
    if batch < 1:
        raise InputError(f"batch must be >= 1; got {batch!r}")
    covariance = output_covariance(jacobian, t, machine.correlation, k)
    sigma = np.sqrt(np.einsum("pii->pi", covariance))  # Eq. (20)
    product = np.prod(two_sided_probability(machine.limits, sigma), axis=1)
    order = np.argsort(product, kind="stable")
    generator = streams.generator(rng)
    parts, best = [], np.inf
    for start in range(0, len(order), batch):
        chosen = order[start:start + batch]
        if product[chosen[0]] > best:
            break
        part = _evaluate(machine, poses[chosen], chosen, covariance[chosen], n_points, n_batches,
                         generator.spawn(1)[0])
        parts.append(part)
        best = min(best, float(np.min(part.probability + 4.0 * part.error)))  # z = 4
    return _concatenate(parts)


def _check(machine, tolerances, poses, k, n_points, n_batches, jacobian):
    t = machine.check_tolerances(tolerances)
    if t.ndim != 1:
        raise InputError(f"tolerances must be one allocation of shape ({machine.n_errors},); "
                         f"got {t.shape}")
    poses = np.atleast_2d(machine.check_positions(poses))
    if poses.ndim != 2:
        raise InputError(f"poses must have shape (n_poses, {len(machine.axes)}); "
                         f"got {poses.shape}")
    if not (np.isfinite(k) and k > 0):
        raise InputError(f"k must be finite and > 0; got {k!r}")
    if not (isinstance(n_points, (int, np.integer)) and n_points >= 2
            and n_points & (n_points - 1) == 0):
        raise InputError(f"n_points must be a power of 2 (>= 2); got {n_points!r}")
    if not (isinstance(n_batches, (int, np.integer)) and n_batches >= 2):
        raise InputError(f"n_batches must be an integer >= 2; got {n_batches!r}")
    jacobian = machine.jacobian(poses) if jacobian is None else np.asarray(jacobian, float)
    if jacobian.shape != (len(poses), 6, machine.n_errors):
        raise InputError(f"jacobian must have shape {(len(poses), 6, machine.n_errors)}; "
                         f"got {jacobian.shape}")
    return t, poses, jacobian


def _evaluate(machine, poses, index, covariance, n_points, n_batches, rng):
    """Rectangle probabilities for covariances ``(n_poses, 6, 6)``."""
    limits = machine.limits
    sd = np.sqrt(np.einsum("pii->pi", covariance))
    with np.errstate(divide="ignore"):
        marginal = np.where(sd > 0, two_sided_probability(limits, sd), 1.0)
    estimates = rectangle_probability(covariance, limits, n_points=n_points,
                                      n_batches=n_batches, rng=rng)
    probability = estimates.mean(axis=0)
    error = estimates.std(axis=0, ddof=1) / np.sqrt(n_batches)
    return SystemReliability(
        poses=poses, index=np.asarray(index), axes=tuple(machine.axes),
        units=axis_units(machine),
        probability=probability, error=error, product=np.prod(marginal, axis=1),
        bonferroni=np.maximum(0.0, 1.0 - np.sum(1.0 - marginal, axis=1)), marginal=marginal,
        n_points=n_points, n_batches=n_batches)


def rectangle_probability(covariance, limits, *, n_points: int = 1024, n_batches: int = 8,
                          rng=None) -> np.ndarray:
    """``P(|y_o| < limits_o for all o)`` for ``y ~ N(0, covariance)``, batch by batch.

    Parameters
    ----------
    covariance : ndarray (n_poses, d, d)
        Positive semi-definite covariances.
    limits : ndarray (d,)
    n_points, n_batches : int
        Scrambled Sobol' points per batch and independent scramblings.
    rng : None, int or numpy.random.Generator

    Returns
    -------
    ndarray (n_batches, n_poses)
        One unbiased estimate per batch; their mean is the estimate, their spread its error.
    """
    covariance = np.asarray(covariance, dtype=float)
    d = covariance.shape[-1]
    sd = np.sqrt(np.einsum("pii->pi", covariance))
    with np.errstate(divide="ignore", invalid="ignore"):
        bound = np.where(sd > 0, limits / sd, np.inf)  # standardised half-widths
        correlation = covariance / (sd[:, :, None] * sd[:, None, :])
    correlation = np.where(np.isfinite(correlation), correlation, 0.0)
    # most restrictive outputs first (Genz's advice); any order gives the same integral
    order = np.argsort(bound, axis=1, kind="stable")
    bound = np.take_along_axis(bound, order, axis=1)
    correlation = np.take_along_axis(np.take_along_axis(correlation, order[:, :, None], 1),
                                     order[:, None, :], 2)
    factor = _cholesky(correlation)
    children = streams.spawn(rng, n_batches)
    chunk = max(1, CHUNK_SIZE // n_points)
    estimates = np.empty((n_batches, len(covariance)))
    for b, child in enumerate(children):
        points = qmc.Sobol(d=max(d - 1, 1), scramble=True, seed=child).random(n_points)
        for start in range(0, len(covariance), chunk):
            part = slice(start, start + chunk)
            estimates[b, part] = _genz(factor[part], bound[part], points).mean(axis=1)
    return estimates


def _cholesky(matrix, tiny: float = 1e-12) -> np.ndarray:
    """Lower Cholesky factors of ``(n, d, d)`` semi-definite matrices (zero columns where a
    variable is a combination of the earlier ones)."""
    n, d, _ = matrix.shape
    factor = np.zeros_like(matrix)
    for j in range(d):
        pivot = matrix[:, j, j] - np.sum(factor[:, j, :j] ** 2, axis=1)
        diagonal = np.sqrt(np.maximum(pivot, 0.0))
        diagonal[diagonal <= tiny] = 0.0
        factor[:, j, j] = diagonal
        safe = np.where(diagonal > 0, diagonal, 1.0)
        for i in range(j + 1, d):
            value = (matrix[:, i, j] - np.sum(factor[:, i, :j] * factor[:, j, :j], axis=1))
            factor[:, i, j] = np.where(diagonal > 0, value / safe, 0.0)
    return factor


def _genz(factor, bound, points) -> np.ndarray:
    """Integrand of Genz's transform at ``points`` (n_points, d − 1): ``(n_poses, n_points)``.

    With ``y = L z``, ``z`` standard normal, variable ``i`` must lie in
    ``(−b_i − s_i, b_i − s_i) / L_ii`` with ``s_i = Σ_{j<i} L_ij z_j``; its probability
    multiplies the integrand and ``z_i`` is drawn inside it by the inverse CDF.
    """
    n, d = bound.shape
    value = np.ones((n, len(points)))
    z = np.zeros((n, len(points), d))
    for i in range(d):
        shift = np.einsum("pj,pkj->pk", factor[:, i, :i], z[:, :, :i])
        diagonal = factor[:, i, i][:, None]
        b = bound[:, i][:, None]
        with np.errstate(divide="ignore", invalid="ignore"):
            low = ndtr(np.where(diagonal > 0, (-b - shift) / diagonal, -np.inf))
            high = ndtr(np.where(diagonal > 0, (b - shift) / diagonal, np.inf))
        degenerate = (diagonal == 0) & np.isfinite(b)
        inside = np.where(degenerate, (np.abs(shift) < b).astype(float), high - low)
        value *= inside
        if i < d - 1:
            uniform = low + points[:, i][None, :] * (high - low)
            uniform = np.clip(uniform, 1e-300, np.nextafter(1.0, 0.0))
            z[:, :, i] = np.where(diagonal > 0, ndtri(uniform), 0.0)
    return value


def _concatenate(parts) -> SystemReliability:
    """One result from the results of several pose batches."""
    first = parts[0]
    joined = {name: np.concatenate([getattr(p, name) for p in parts])
              for name in ("poses", "index", "probability", "error", "product", "bonferroni",
                           "marginal")}
    return SystemReliability(axes=first.axes, units=first.units, n_points=first.n_points,
                             n_batches=first.n_batches, **joined)
