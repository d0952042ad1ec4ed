"""The unknowns of an identification: every error as standard-normal coefficients.

Under ``constant`` a motion error is one value along its axis' whole travel, ``x = σ θ``
with one coefficient ``θ ~ N(0, 1)``. Under ``gp:<ℓ>`` it is the Gaussian process of
docs/profiles.md (:class:`reliability.model.profiles.GaussianProfile`, the same kernel the
simulated machines are drawn with), written in its Karhunen–Loève basis on a grid ``S``
over the stroke with spacing ``ℓ/GRID_PER_LENGTH`` (arc length on a rotary axis): with the
correlation on the grid ``C_S = V Λ Vᵀ``,

    x(p) = σ ψ(p)ᵀ θ,    ψ(p) = Λ^(-1/2) Vᵀ c(S, p),    θ ~ N(0, I),

the process' kriging predictor from its values on the grid, which at the grid's points is
the process itself. The part of the process the grid does not fix has variance
``1 − ‖ψ(p)‖²``, below :data:`RESIDUAL_FLOOR` of the prior variance at every position of
the stroke at this spacing (checked when a basis is built), so the representation is the
process itself to that precision. Eigenvalues below :data:`EIGEN_FLOOR` of the largest are
dropped. Assembly errors (squareness, location) are one coefficient each.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..basics.errors import InputError, SizeBudgetError
from ..model.profiles import ConstantProfile, GaussianProfile, profile_model

#: Grid points per correlation length along the stroke.
GRID_PER_LENGTH = 6
#: Eigenvalues of the grid's correlation below this fraction of the largest are dropped.
EIGEN_FLOOR = 1e-12
#: Largest variance, as a fraction of the prior's, the grid may leave unexplained.
RESIDUAL_FLOOR = 1e-9
#: Fewest and most grid intervals along one axis.
MIN_GRID = 8
MAX_GRID = 2000
#: Most coefficients of one identification.
MAX_COEFFICIENTS = 4000
#: Positions per chunk when the kernel is evaluated between positions and the grid.
KERNEL_CHUNK = 512
#: Quadrature nodes per grid interval of the mean over the stroke.
MEAN_NODES = 8


def arc_length(axis) -> float:
    """The stroke's length in mm: arc length at the rotation radius on a rotary axis."""
    low, high = (0.0, 2 * math.pi) if axis.full_turn else axis.stroke
    radius = 500.0 * axis.size if axis.kind == "rotary" else 1.0
    return radius * (high - low)


@dataclass(frozen=True, eq=False)
class ConstantBasis:
    """One value along the whole travel: one coefficient."""

    axis: object
    size: int = 1

    def at(self, positions) -> np.ndarray:
        """``(k, 1)`` ones: every position takes the coefficient."""
        return np.ones((np.size(positions), 1))

    def mean_row(self) -> np.ndarray:
        """The mean over the stroke as a row of the coefficients: the value itself."""
        return np.ones(1)


@dataclass(frozen=True, eq=False)
class GaussianBasis:
    """A Gaussian process along travel in its Karhunen–Loève basis on a grid (module
    docstring).

    Attributes
    ----------
    axis : Axis
    model : GaussianProfile
    points : ndarray (m,)
        The grid over the stroke (mm or rad).
    loadings : ndarray (m, r)
        ``V Λ^(-1/2)``: ``ψ(p) = c(p, S) @ loadings``.
    """

    axis: object
    model: GaussianProfile
    points: np.ndarray
    loadings: np.ndarray

    @property
    def size(self) -> int:
        """Number of coefficients ``r``."""
        return self.loadings.shape[1]

    def at(self, positions) -> np.ndarray:
        """``(k, r)``: ``ψ`` at each position (mm or rad), formed once per distinct one."""
        positions = np.ravel(np.asarray(positions, dtype=float))
        distinct, where = np.unique(positions, return_inverse=True)
        return (cross_correlation(self.model, self.axis, distinct, self.points)
                @ self.loadings)[where.ravel()]

    def residual_variance(self, positions) -> np.ndarray:
        """``1 − ‖ψ(p)‖²``: the share of the prior variance the grid leaves unexplained."""
        return 1.0 - np.sum(self.at(positions) ** 2, axis=-1)

    def mean_row(self) -> np.ndarray:
        """``(r,)``: the mean of the profile over the stroke as a row of the coefficients
        (Gauss–Legendre nodes on every grid interval; equal weights around a full turn)."""
        nodes, weights = mean_nodes(self.axis, self.points)
        return weights @ self.at(nodes)


def mean_nodes(axis, points) -> tuple[np.ndarray, np.ndarray]:
    """Quadrature nodes and weights (summing to 1) of the mean over the stroke."""
    if axis.full_turn:
        count = MEAN_NODES * len(points)
        return np.arange(count) * (2 * math.pi / count), np.full(count, 1.0 / count)
    unit, unit_weights = np.polynomial.legendre.leggauss(MEAN_NODES)
    low, high = points[:-1, None], points[1:, None]
    nodes = 0.5 * (low + high) + 0.5 * (high - low) * unit
    weights = 0.5 * (high - low) * unit_weights
    return nodes.ravel(), (weights / weights.sum()).ravel()


def cross_correlation(model, axis, positions, points) -> np.ndarray:
    """``(k, m)`` correlation of the profile between ``positions`` and grid ``points``,
    from the model's own kernel, over chunks of positions."""
    parts = [model.correlation(axis, np.concatenate([positions[start:start + KERNEL_CHUNK],
                                                     points]))
             [:len(positions[start:start + KERNEL_CHUNK]), -len(points):]
             for start in range(0, len(positions), KERNEL_CHUNK)]
    return np.concatenate(parts) if parts else np.zeros((0, len(points)))


def grid_points(axis, length: float) -> np.ndarray:
    """The grid over the stroke at spacing ``length/GRID_PER_LENGTH`` (at least
    :data:`MIN_GRID` intervals)."""
    count = max(MIN_GRID, math.ceil(arc_length(axis) * GRID_PER_LENGTH / length))
    if count > MAX_GRID:
        raise SizeBudgetError(f"profile gp:{length:g}: axis {axis.name!r} would need a grid "
                              f"of {count} intervals (at most {MAX_GRID}); identify with a "
                              f"longer correlation length")
    if axis.full_turn:
        return np.arange(count) * (2 * math.pi / count)
    return np.linspace(*axis.stroke, count + 1)


def gaussian_basis(axis, model: GaussianProfile) -> GaussianBasis:
    """The basis of one axis, checked to leave at most :data:`RESIDUAL_FLOOR` unexplained."""
    points = grid_points(axis, model.length)
    values, vectors = np.linalg.eigh(model.correlation(axis, points))
    kept = values > EIGEN_FLOOR * values[-1]
    basis = GaussianBasis(axis, model, points, vectors[:, kept] / np.sqrt(values[kept]))
    between = 0.5 * (points[:-1] + points[1:])
    left = float(np.max(basis.residual_variance(np.concatenate([points, between]))))
    if left > RESIDUAL_FLOOR:
        raise InputError(f"profile gp:{model.length:g}: the grid along axis {axis.name!r} "
                         f"leaves {left:.2g} of the prior variance unexplained (at most "
                         f"{RESIDUAL_FLOOR:g})")
    return basis


def travel_bases(machine, profile) -> tuple:
    """One basis per axis of ``machine`` under ``profile`` ('constant' or 'gp:<mm>')."""
    model = profile_model(profile)
    if isinstance(model, ConstantProfile):
        return tuple(ConstantBasis(axis) for axis in machine.axis_specs)
    if isinstance(model, GaussianProfile):
        return tuple(gaussian_basis(axis, model) for axis in machine.axis_specs)
    raise InputError(f"profile: identification takes 'constant' or 'gp:<length mm>'; got "
                     f"{profile!r} (a fresh value at every position cannot be identified)")


@dataclass(frozen=True, eq=False)
class Coefficients:
    """Every error of a machine as standard-normal coefficients.

    Motion error ``c`` of axis ``a`` at position ``p`` is ``σ_c ψ_a(p)ᵀ θ_(a,c)``; an
    assembly error is ``σ θ``. Coefficients are ordered axis by axis, error by error, then
    the assembly errors.

    Attributes
    ----------
    bases : tuple
        One basis per axis.
    prior_sd : ndarray (n_errors,)
        σ = t/3 of every error.
    """

    bases: tuple
    prior_sd: np.ndarray

    def __post_init__(self):
        if self.size > MAX_COEFFICIENTS:
            raise SizeBudgetError(f"profile: the errors along travel need {self.size} "
                                  f"coefficients (at most {MAX_COEFFICIENTS}); identify "
                                  f"with a longer correlation length")

    @property
    def size(self) -> int:
        """Number of coefficients."""
        motion = 6 * sum(basis.size for basis in self.bases)
        return motion + len(self.prior_sd) - 6 * len(self.bases)

    @property
    def varies(self) -> bool:
        """Whether any motion error varies along travel."""
        return not all(isinstance(basis, ConstantBasis) for basis in self.bases)

    def motion_slices(self) -> list[slice]:
        """The coefficients of each axis' six motion errors, ``6 r`` each."""
        out, start = [], 0
        for basis in self.bases:
            out.append(slice(start, start + 6 * basis.size))
            start += 6 * basis.size
        return out

    def rows(self, item_rows, poses) -> np.ndarray:
        """Sensitivity rows ``(..., [k,] n_errors)`` to the errors at ``poses``
        ``(..., n_axes)`` as rows ``(..., [k,] size)`` to the coefficients."""
        item_rows = np.asarray(item_rows)
        poses = np.asarray(poses, dtype=float)
        extra = (1,) * (item_rows.ndim - poses.ndim)
        parts = []
        for a, (basis, block) in enumerate(zip(self.bases, self.motion_slices())):
            psi = basis.at(poses[..., a]).reshape(poses.shape[:-1] + extra + (basis.size,))
            scaled = item_rows[..., 6 * a:6 * a + 6] * self.prior_sd[6 * a:6 * a + 6]
            parts.append((scaled[..., :, None] * psi[..., None, :]).reshape(
                scaled.shape[:-1] + (block.stop - block.start,)))
        assembly = slice(6 * len(self.bases), len(self.prior_sd))
        parts.append(item_rows[..., assembly] * self.prior_sd[assembly])
        return np.concatenate(parts, axis=-1)

    def values(self, theta, poses) -> np.ndarray:
        """Errors ``(*theta.shape[:-1], *poses.shape[:-1], n_errors)`` at ``poses`` for
        coefficients ``theta`` ``(..., size)``."""
        theta = np.asarray(theta, dtype=float)
        poses = np.asarray(poses, dtype=float)
        lead, count = theta.shape[:-1], int(np.prod(poses.shape[:-1], dtype=int))
        flat = theta.reshape(-1, theta.shape[-1])
        out = np.empty((len(flat), count, len(self.prior_sd)))
        for a, (basis, block) in enumerate(zip(self.bases, self.motion_slices())):
            psi = basis.at(poses[..., a])
            coefficients = flat[:, block].reshape(len(flat), 6, basis.size)
            out[:, :, 6 * a:6 * a + 6] = np.einsum("qr,ncr->nqc", psi, coefficients) * \
                self.prior_sd[6 * a:6 * a + 6]
        assembly = slice(6 * len(self.bases), len(self.prior_sd))
        out[:, :, assembly] = (flat[:, self.motion_slices()[-1].stop:] *
                               self.prior_sd[assembly])[:, None, :]
        return out.reshape(lead + poses.shape[:-1] + (len(self.prior_sd),))

    def mean_matrix(self) -> np.ndarray:
        """``(n_errors, size)``: each error's mean over its stroke (the error itself for
        an assembly error or a constant profile) as a row of the coefficients."""
        out = np.zeros((len(self.prior_sd), self.size))
        for a, (basis, block) in enumerate(zip(self.bases, self.motion_slices())):
            row = basis.mean_row()
            for c in range(6):
                out[6 * a + c, block.start + c * basis.size:
                    block.start + (c + 1) * basis.size] = self.prior_sd[6 * a + c] * row
        assembly = np.arange(6 * len(self.bases), len(self.prior_sd))
        out[assembly, self.motion_slices()[-1].stop + np.arange(len(assembly))] = \
            self.prior_sd[assembly]
        return out

    def profile_moments(self, a: int, positions, theta, covariance) -> tuple[np.ndarray, ...]:
        """Axis ``a``'s six motion errors at ``positions``: prior σ, posterior mean and σ
        ``(6, k)`` under coefficients of mean ``theta`` and ``covariance``."""
        basis, block = self.bases[a], self.motion_slices()[a]
        psi = basis.at(positions)
        sigma = self.prior_sd[6 * a:6 * a + 6, None]
        out = np.empty((3, 6, len(psi)))
        for c in range(6):
            own = slice(block.start + c * basis.size, block.start + (c + 1) * basis.size)
            out[0, c] = np.sqrt(np.sum(psi ** 2, axis=1))
            out[1, c] = psi @ theta[own]
            out[2, c] = np.sqrt(np.maximum(np.sum((psi @ covariance[own, own]) * psi,
                                                  axis=1), 0.0))
        return tuple(sigma * out)
