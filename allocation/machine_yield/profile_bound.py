"""The log-concave lower bound of :mod:`allocation.machine_yield.yield_dual` under the
``independent`` and ``gp:<length>`` profiles along travel.

Why the yield is still log-concave in ``u = log t``. Under these profiles a built machine
draws each motion error of an axis at every grid point of the axis, and each assembly error
once. Its standardised draws ``w`` (one standard normal per item and column of the item's
factor, :attr:`BlockRows.owner`) give the errors

    e = D(t ⊗ 1) L w / 3,                                                          (P1)

with ``D(t ⊗ 1)`` the diagonal matrix repeating ``t_i`` over item ``i``'s block of
coordinates and ``L`` block diagonal: item ``i``'s block is its axis' factor of the
profile's correlation along travel (:func:`reliability.model.profiles.travel_factors`:
the identity for ``independent``, the Cholesky factor of the squared-exponential
correlation for ``gp``), one 1 × 1 block of 1 for an assembly error. Every block of ``L``
sits inside a block of ``D(t ⊗ 1)`` on which ``D`` is a multiple of the identity, so the
two commute, ``e = L D(t ⊗ 1) w / 3``, and the machine passes (Eq. 19 to first order at
every pose) when

    D(t ⊗ 1) w ∈ K' = {v : |J_o(q)·L v| ≤ 3 I_o at every grid pose q and output o},   (P2)

a symmetric convex polytope in ``w``-space that does not depend on ``t``. So the yield is
``γ(D(e^{−u} ⊗ 1) K')``, the standard Gaussian measure of a diagonal dilation of one
symmetric convex set. By the (B) theorem (Cordero-Erausquin, Fradelizi & Maurey, J. Funct.
Anal. 214, 2004, Theorem 1) ``s ↦ γ(e^{Δ(s)} K')`` is log-concave on the whole ``R^d``
(``K'`` is unbounded along the directions no row sees: it is the increasing union of the
symmetric convex bodies ``K' ∩ [−m, m]^d``, and a pointwise limit of log-concave functions
is log-concave); the yield is its restriction to the linear subspace of coordinates
repeated within each block, ``s = −(u ⊗ 1)``, and a log-concave function composed with a
linear map is log-concave. The bound and the tangent steps of
:mod:`~allocation.machine_yield.yield_dual` therefore hold unchanged, with the estimates of
:func:`yield_and_gradient` here.

Where it does not extend. An *item correlation* mixes the blocks of different items, so
``L`` no longer commutes with ``D``: the pass set in ``w`` is ``L⁻¹ D(t)⁻¹ K``, a dilation
along axes that are not orthogonal for the standard Gaussian, which the theorem does not
cover, and the yield can indeed fail to be log-concave (two errors of correlation −0.9 and
one row through their sum: ``tests/test_profile_bound.py``). The *truncated* reading maps
each correlated normal through the truncated-normal quantile, a non-linear map, so the pass
set in ``w`` is neither convex nor a dilation of a fixed set and the errors are not
Gaussian; the theorem is for the Gaussian measure.

The gradient (conditional Monte Carlo along the block's line). For a machine ``w`` and item
``i`` with block ``B`` of ``P_i`` coordinates, write ``w_B = s θ`` with ``θ = w_B/|w_B|``.
Given the other coordinates and the line ``{s θ}``, ``s`` has the two-sided chi density
``f_P(s) = |s|^{P−1} e^{−s²/2} / (2^{P/2} Γ(P/2))`` (the radius of a standard normal in
``R^P``, with either sign), every row is affine in ``s``, so the machine passes for ``s``
in an interval ``[l, r]`` and with probability ``F_P(r) − F_P(l)``. Scaling ``t_i`` scales
``s``, so

    ∂Y/∂log t_i = E[l f_P(l) − r f_P(r)],                                          (P3)

a mean of bounded terms (``|s f_P(s)|`` is bounded): unbiased, with a normal interval from
the central limit theorem over the machines, and for ``P_i = 1`` the estimator of the
``constant`` profile.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import gammaln

from reliability.sampling.machine_yield import YieldModel

#: Floats of one block of machines × rows: small enough (2 MB) that a block's temporaries stay
#: in cache through the items' passes (about twice as fast as 16 MB blocks on trunnion5).
BLOCK_FLOATS = 250_000
#: Beyond this ``|s|`` the line's density ``f_P`` is below 1e-300 for every block size used.
FAR = 40.0


@dataclass(frozen=True, eq=False)
class BlockRows:
    """The linearised outputs in the standardised draws of one built machine, (P1)–(P2).

    Attributes
    ----------
    rows : ndarray (R, d)
        ``J_o(q) L / (3 I_o)`` for every (grid pose, output) that some error moves: a
        machine with draws ``w`` passes when ``|rows · (t[owner] ∘ w)| ≤ 1`` everywhere.
    owner : ndarray (d,) of int
        The item (tolerance) each coordinate belongs to; each item's coordinates are
        contiguous, in the order of the tolerances.
    """

    rows: np.ndarray
    owner: np.ndarray

    @classmethod
    def of(cls, model: YieldModel) -> "BlockRows":
        """The rows of ``model``'s machine on its whole grid under its profiles (no item
        correlation: each motion error correlated along its own axis only)."""
        machine, experiment = model.machine, model.experiment
        n, points = len(machine.axis_specs), experiment.points
        jacobian = machine.jacobian(experiment.poses) \
            / (model.k * np.asarray(machine.limits)[None, :, None])
        poses = len(experiment.poses)
        motion = jacobian[:, :, :6 * n].reshape(poses, 6, n, 6)
        travel = model.travel[np.arange(n), model.grid_index]  # (poses, n, P): row of each axis
        rows = np.concatenate([
            np.einsum("qoai,qap->qoaip", motion, travel).reshape(6 * poses, -1),
            jacobian[:, :, 6 * n:].reshape(6 * poses, -1)], axis=1)
        used = cls.used_columns(model)
        rows = rows[:, used]
        owner = np.concatenate([np.repeat(np.arange(6 * n), points),
                                np.arange(6 * n, jacobian.shape[-1])])[used]
        return cls(rows=rows[np.abs(rows).sum(axis=1) > 0], owner=owner)

    @staticmethod
    def used_columns(model: YieldModel) -> np.ndarray:
        """Columns (item-major) of the draws the profile's factors use: every column of a
        ``gp`` or ``independent`` factor, the first of a ``constant`` one."""
        n = len(model.machine.axis_specs)
        live = np.abs(model.travel).sum(axis=1) > 0  # (n, P): columns of each axis' factor
        motion = np.broadcast_to(live[:, None, :], (n, 6, live.shape[1])).ravel()
        return np.concatenate([motion, np.ones(model.dimension - motion.size, bool)])

    @property
    def shape(self) -> tuple[int, int]:
        """``(R, d)``, as for the array of rows of the ``constant`` profile."""
        return self.rows.shape

    def __len__(self) -> int:
        return len(self.rows)

    def expanded(self, tolerances) -> np.ndarray:
        """``(d,)`` each coordinate's tolerance, ``t[owner]``: ``rows · (expanded ∘ w)``
        are the linearised outputs over their limits (the rows of an array of the
        ``constant`` profile times ``t ∘ z``)."""
        return np.asarray(tolerances, dtype=float)[self.owner]

    @property
    def sizes(self) -> np.ndarray:
        """Coordinates of each item's block, ``P_i``."""
        return np.bincount(self.owner, minlength=self.owner.max() + 1)

    def standard(self, model: YieldModel, u) -> np.ndarray:
        """``(N, d)`` coordinates of the model's draws ``u (N, dimension)``
        (:meth:`~reliability.sampling.machine_yield.YieldModel.draws`): the same machines
        the model judges, read for the linearised outputs."""
        u = np.asarray(u, dtype=float)
        n, points = len(model.machine.axis_specs), model.experiment.points
        size = 6 * n * points  # the motion errors' draws come first, (n, P, 6)
        motion = u[:, :size].reshape(len(u), n, points, 6)
        ordered = np.concatenate([motion.transpose(0, 1, 3, 2).reshape(len(u), -1),
                                  u[:, size:]], axis=1)
        return ordered[:, self.used_columns(model)]


def line_moment(s, size) -> np.ndarray:
    """``s f_P(s)`` of (P3), the two-sided chi density of ``size`` degrees of freedom
    times ``s`` (``s φ(s)`` for one), 0 at ``±∞``."""
    s = np.clip(s, -FAR, FAR)
    log_scale = 0.5 * size * np.log(2.0) + gammaln(0.5 * size)
    with np.errstate(divide="ignore"):
        return np.sign(s) * np.exp(size * np.log(np.abs(s)) - 0.5 * s * s - log_scale)


def yield_and_gradient(block_rows: BlockRows, tolerances, draws):
    """Machines passing, and ``∂Y/∂log t_i`` of (P3) with its standard error, on ``draws``.

    Parameters
    ----------
    block_rows : BlockRows
    tolerances : ndarray (n,)
    draws : ndarray (N, d)
        Standard normal draws of the coordinates, one row per machine.

    Returns
    -------
    passes : int
    gradient, standard_error : ndarray (n,)
        The mean over machines of ``l f_P(l) − r f_P(r)`` per item, and its standard error.
    """
    rows, sizes = block_rows.rows, block_rows.sizes
    blocks = [slice(a, b) for a, b in zip(np.r_[0, np.cumsum(sizes)[:-1]], np.cumsum(sizes))]
    moves = np.stack([np.abs(rows[:, cols]).sum(axis=1) > 0 for cols in blocks])  # (n, R)
    moved = [np.flatnonzero(row) for row in moves]
    item_rows = [rows[kept, cols] for kept, cols in zip(moved, blocks)]
    scale = block_rows.expanded(tolerances)
    draws = np.asarray(draws, dtype=float)
    machines, n = len(draws), len(sizes)
    block = max(1, BLOCK_FLOATS // len(rows))
    passes, total, squares = 0, np.zeros(n), np.zeros(n)
    for start in range(0, machines, block):
        w = draws[start:start + block]
        scaled = w * scale
        values = scaled @ rows.T
        outside = np.abs(values) > 1.0
        passes += int(np.sum(~outside.any(axis=1)))
        # rows outside their band that item i does not move: the machine fails whatever w_B
        stuck = outside.sum(axis=1)[:, None] - outside.astype(float) @ moves.T
        for i, (cols, kept) in enumerate(zip(blocks, moved)):
            change = np.where(stuck[:, i] == 0,
                              _line_change(item_rows[i], values[:, kept], scaled[:, cols],
                                           w[:, cols], sizes[i]), 0.0)
            total[i] += change.sum()
            squares[i] += np.square(change).sum()
    mean = total / machines
    error = np.sqrt(np.maximum(squares / machines - mean**2, 0.0) / machines)
    return passes, mean, error


def _line_change(rows, values, scaled, w, size) -> np.ndarray:
    """Per machine, ``l f_P(l) − r f_P(r)`` for the pass interval ``[l, r]`` of ``s`` on the
    line ``w_B = s θ`` of one item's block (0 where it is empty), from the rows the block
    moves and their ``values`` at ``s = |w_B|``. A row whose slope is 0 (probability 0) gives
    no finite end and is skipped by ``fmax``/``fmin``."""
    part = scaled @ rows.T  # the block's share of every row, at s = |w_B|
    radius = np.sqrt(np.sum(w * w, axis=1))[:, None]
    with np.errstate(divide="ignore", invalid="ignore"):
        inverse = radius / part  # 1 / slope
        centre = (part - values) * inverse  # where the row's value crosses 0
        half = np.abs(inverse, out=inverse)
        low = np.fmax.reduce(centre - half, axis=1)
        high = np.fmin.reduce(np.add(centre, half, out=centre), axis=1)
    live = high > low
    return np.where(live, line_moment(np.where(live, low, 0.0), size)
                    - line_moment(np.where(live, high, 0.0), size), 0.0)
