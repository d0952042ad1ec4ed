"""The chain's Jacobian and σ² as exact per-axis expansions over the poses.

For a serial chain every Jacobian entry ``J_oi(q)`` is, in each axis separately, of
degree 1 in ``(1, u_a)`` for a linear axis and in ``(1, cos θ_a, sin θ_a)`` for a rotary
one, with the outputs read in the tool frame (Eq. 18) or in the workpiece frame
(docs/certified-workspace.md, "The expansion"), so

    J_oi(q) = Σ_k C_k,oi Π_a φ_{a,k_a}(q_a)                      (degree 1)
    σ_o²(q) = Σ_i σ_i² J_oi(q)² = Σ_k S_k,o Π_a φ_{a,k_a}(q_a)   (degree 2, Eq. 20)

with per-axis bases ``(1, u, u²)`` (linear, ``u = (x − mid)/half`` of the stroke, so
``|u| ≤ 1`` on it) and ``(1, cos θ, sin θ, cos 2θ, sin 2θ)`` (rotary, whatever its stroke).
The coefficients follow exactly from the values at a tensor grid of nodes (``degree + 1``
equally spaced values of ``u`` in [−1, 1], ``2 degree + 1`` equally spaced angles over a
full turn) by one small linear solve per axis. :class:`PoseExpansion` evaluates an
expansion, its gradient and its Hessian at points and encloses them over boxes of poses
(each basis function's range on an interval is exact); the certificate of
:mod:`reliability.first_order.certificate` is built on it.

Every expansion is checked against the chain at :data:`CHECK_POSES` poses spread over the
strokes (a Halton sequence, no randomness); a machine whose expansion differs from the
chain by more than :data:`CHECK_RTOL` of the function's size is refused.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.stats import qmc

from ..basics.errors import InputError
from ..model.kinematics import jacobian, output_variance

#: Relative agreement an expansion must reach with the chain at the check poses.
CHECK_RTOL = 1e-10
#: Poses of the strokes (a Halton sequence) at which every expansion is checked.
CHECK_POSES = 256
#: Coefficients below this fraction of the largest are set to zero; their absolute sum is
#: added to the expansion's :attr:`PoseExpansion.margin` (every basis function is at most 1
#: in magnitude on the strokes), so exact zeros stay exact (directions the function does
#: not depend on cost nothing) and the bound stays rigorous.
DROP_RTOL = 1e-12
#: Relative size, against the sum of absolute coefficients, of the margin that covers the
#: rounding of the node values, of the per-axis solves and of the evaluations (all of order
#: 1e-15; the margin is far above them).
ROUNDING_RTOL = 1e-11
#: Widening of every basis function's range on an interval (relative to 1 + its size):
#: above the rounding of cos and sin at angles of a few turns (a few 1e-15).
RANGE_WIDENING = 1e-14


def basis_size(kind: str, degree: int) -> int:
    """Basis functions of one axis: ``degree + 1`` (linear), ``2 degree + 1`` (rotary)."""
    return degree + 1 if kind == "linear" else 2 * degree + 1


def basis_nodes(kind: str, degree: int) -> np.ndarray:
    """Nodes of one axis in local coordinates: ``u`` in [−1, 1] or angles over a turn."""
    n = basis_size(kind, degree)
    if kind == "linear":
        return np.linspace(-1.0, 1.0, n)
    return 2 * np.pi * np.arange(n) / n


def basis_values(kind: str, degree: int, x, derivative: int = 0) -> np.ndarray:
    """The axis' basis functions (or their ``derivative``-th derivative) at local
    positions ``x``, ``(..., n)``: ``u^k`` (linear) or ``1, cos θ, sin θ, cos 2θ, …``."""
    x = np.asarray(x, dtype=float)[..., None]
    if kind == "linear":
        power = np.arange(degree + 1)
        factor = np.ones(degree + 1)
        for step in range(derivative):
            factor = factor * (power - step)
        return factor * np.where(power >= derivative, x, 1.0) ** np.maximum(
            power - derivative, 0)
    m = np.arange(1, degree + 1)
    phase = m * x + derivative * np.pi / 2  # d/dθ cos(mθ) = m cos(mθ + π/2)
    scale = m.astype(float) ** derivative
    constant = np.full(x.shape, 1.0 if derivative == 0 else 0.0)
    return np.concatenate([constant, scale * np.cos(phase), scale * np.sin(phase)],
                          axis=-1)[..., _rotary_order(degree)]


def basis_ranges(kind: str, degree: int, low, high, derivative: int = 0):
    """Midpoint and radius of every basis function's ``derivative`` over ``[low, high]``.

    The ranges are exact (extrema of ``u^k`` and of ``cos``/``sin`` located in closed
    form), widened by :data:`RANGE_WIDENING` for rounding.

    Returns
    -------
    mid, rad : ndarray (..., n)
    """
    low = np.asarray(low, dtype=float)
    high = np.asarray(high, dtype=float)
    if kind == "linear":
        lo, hi = _power_ranges(degree, low, high, derivative)
    else:
        m = np.arange(1, degree + 1)
        shift = derivative * np.pi / 2
        scale = m.astype(float) ** derivative
        c_lo, c_hi = _cos_range(m * low[..., None] + shift, m * high[..., None] + shift)
        s_lo, s_hi = _cos_range(m * low[..., None] + shift - np.pi / 2,
                                m * high[..., None] + shift - np.pi / 2)
        one = np.full(low.shape + (1,), 1.0 if derivative == 0 else 0.0)
        lo = np.concatenate([one, scale * c_lo, scale * s_lo], axis=-1)[..., _rotary_order(degree)]
        hi = np.concatenate([one, scale * c_hi, scale * s_hi], axis=-1)[..., _rotary_order(degree)]
    # covers the rounding of the end values and of their arguments (angles of a few turns)
    widen = RANGE_WIDENING * (1 + np.maximum(np.abs(lo), np.abs(hi)))
    return (lo + hi) / 2, (hi - lo) / 2 + widen


def _rotary_order(degree: int) -> np.ndarray:
    """Reorder ``[1, cos θ … cos dθ, sin θ … sin dθ]`` to ``[1, cos θ, sin θ, cos 2θ, …]``."""
    order = [0]
    for m in range(1, degree + 1):
        order += [m, degree + m]
    return np.array(order)


def _power_ranges(degree, low, high, derivative):
    """Exact ranges of ``d^j/du^j u^k`` over ``[low, high]`` for k = 0…degree."""
    lows, highs = [], []
    for k in range(degree + 1):
        power = k - derivative
        factor = float(np.prod(np.arange(power + 1, k + 1))) if power >= 0 else 0.0
        if power < 0:
            lo = hi = np.zeros(low.shape)
        elif power == 0:
            lo = hi = np.full(low.shape, factor)
        else:
            ends = np.stack([low ** power, high ** power])
            lo, hi = ends.min(axis=0), ends.max(axis=0)
            if power % 2 == 0:  # an even power reaches 0 inside an interval around 0
                lo = np.where((low < 0) & (high > 0), 0.0, lo)
            lo, hi = factor * lo, factor * hi
        lows.append(lo)
        highs.append(hi)
    return np.stack(lows, axis=-1), np.stack(highs, axis=-1)


def _cos_range(low, high):
    """Exact range of cos over ``[low, high]`` (elementwise)."""
    ends = np.stack([np.cos(low), np.cos(high)])
    lo, hi = ends.min(axis=0), ends.max(axis=0)
    turn = 2 * np.pi
    has_max = np.floor(high / turn) >= np.ceil(low / turn)  # 2πk inside
    has_min = np.floor((high - np.pi) / turn) >= np.ceil((low - np.pi) / turn)
    return np.where(has_min, -1.0, lo), np.where(has_max, 1.0, hi)


@dataclass(frozen=True)
class PoseExpansion:
    """``f(q) = Σ_k coefficients[k] Π_a φ_{a,k_a}(x_a)`` over the axes (module docstring).

    Attributes
    ----------
    kinds : tuple of str
        ``'linear'`` or ``'rotary'`` per axis.
    degree : int
        1 (the Jacobian) or 2 (σ²).
    origin, scale : ndarray (n_axes,)
        Local coordinate ``x_a = (q_a − origin_a)/scale_a``: the stroke's middle and half
        length for a linear axis, 0 and 1 (the angle itself) for a rotary one.
    coefficients : ndarray (n_1, …, n_axes, *values)
        One coefficient per product of basis functions and per value (e.g. per output),
        over the basis functions :attr:`basis_index` keeps.
    margin : ndarray (*values)
        Absolute bound of what the expansion may differ from the chain by on the strokes
        beyond its coefficients: dropped coefficients and rounding (:data:`DROP_RTOL`,
        :data:`ROUNDING_RTOL`).
    basis_index : tuple of ndarray
        Per axis, the basis functions the coefficients use (all of them when fitted; a
        restriction keeps only those with a non-zero coefficient).
    """

    kinds: tuple
    degree: int
    origin: np.ndarray
    scale: np.ndarray
    coefficients: np.ndarray
    margin: np.ndarray
    basis_index: tuple

    @property
    def n_axes(self) -> int:
        return len(self.kinds)

    def local(self, q) -> np.ndarray:
        """Local coordinates of poses ``(..., n_axes)``."""
        return (np.asarray(q, dtype=float) - self.origin) / self.scale

    def pose(self, x) -> np.ndarray:
        """Poses (mm, rad) of local coordinates."""
        return self.origin + self.scale * np.asarray(x, dtype=float)

    def values(self, x) -> np.ndarray:
        """``f`` at local points ``(b, n_axes)``: ``(b, *values)``."""
        return point_tree(self, x, 0)[()]

    def restricted(self, index) -> "PoseExpansion":
        """The expansion of the values ``index`` selects (e.g. one output's row), keeping
        per axis only the basis functions with a non-zero coefficient."""
        index = index if isinstance(index, tuple) else (index,)
        coefficients = self.coefficients[(slice(None),) * self.n_axes + index]
        used = coefficients != 0
        keep = []
        for a in range(self.n_axes):
            others = tuple(b for b in range(coefficients.ndim) if b != a)
            kept = np.flatnonzero(used.any(axis=others))
            keep.append(kept if len(kept) else np.array([0]))  # the constant, all zero
        trailing = (np.arange(n) for n in coefficients.shape[self.n_axes:])
        coefficients = coefficients[np.ix_(*keep, *trailing)]
        index_kept = tuple(self.basis_index[a][k] for a, k in enumerate(keep))
        return PoseExpansion(self.kinds, self.degree, self.origin, self.scale, coefficients,
                             self.margin[index], index_kept)


def point_tree(expansion: PoseExpansion, x, order: int) -> dict:
    """Every partial derivative of order at most ``order`` at local points.

    Contracts the coefficients axis by axis with the basis values (and their derivatives)
    of each point. Returns a mapping from the sorted tuple of differentiated axes (``()``
    for the value, ``(a,)``, ``(a, b)``) to ``(b, *values)`` arrays.
    """
    x = np.atleast_2d(np.asarray(x, dtype=float))
    factors = [[basis_values(kind, expansion.degree, x[:, a], d)[:, index]
                for d in range(order + 1)]
               for a, (kind, index) in enumerate(zip(expansion.kinds, expansion.basis_index))]
    return _tree(expansion.coefficients, factors, order, None)


def interval_tree(expansion: PoseExpansion, low, high, order: int) -> dict:
    """Enclosures (midpoint, radius) of every partial derivative of order ``order`` over
    boxes ``[low, high]`` of local coordinates ``(b, n_axes)``.

    The same contraction as :func:`point_tree` with every basis function replaced by its
    exact range on the box's interval, in midpoint–radius arithmetic:
    ``Σ_j [c_j ± r_j][m_j ± s_j] ⊆ Σ_j c_j m_j ± Σ_j (|c_j| s_j + r_j (|m_j| + s_j))``.
    Returns a mapping like :func:`point_tree`'s, to ``(mid, rad)`` pairs, for the
    derivatives of exactly ``order``.
    """
    low = np.atleast_2d(low)
    high = np.atleast_2d(high)
    factors = [[tuple(part[:, index] for part in
                      basis_ranges(kind, expansion.degree, low[:, a], high[:, a], d))
                for d in range(order + 1)]
               for a, (kind, index) in enumerate(zip(expansion.kinds, expansion.basis_index))]
    tree = _tree(expansion.coefficients, factors, order, order)
    return {key: value for key, value in tree.items() if len(key) == order}


def _tree(coefficients, factors, order, exact_order):
    """Axis-by-axis contraction of ``coefficients`` with per-axis factors.

    ``factors[a][d]`` is axis a's ``d``-th derivative of the basis, ``(b, n_a)`` points or a
    ``(mid, rad)`` pair of them. States are keyed by the differentiated axes; a state that
    can no longer reach ``exact_order`` (if given) is dropped.
    """
    n_axes = len(factors)
    interval = isinstance(factors[0][0], tuple)
    states = {(): None}
    for a in range(n_axes):
        remaining = n_axes - a - 1
        new = {}
        for key, state in states.items():
            for d in range(order + 1 - len(key)):
                new_key = key + (a,) * d
                if exact_order is not None and len(new_key) + remaining * order < exact_order:
                    continue
                if exact_order is not None and len(new_key) > exact_order:
                    continue
                new[new_key] = _contract(coefficients if state is None else state,
                                         factors[a][d], state is None, interval)
        states = new
    return states


def _contract(tensor, factor, shared, interval):
    """Contract the leading axis of ``tensor`` (shared coefficients or a per-box state)
    with one factor per box."""
    if not interval:
        if shared:
            head = tensor.shape[0]
            flat = factor @ tensor.reshape(head, -1)
            return flat.reshape((len(factor),) + tensor.shape[1:])
        return _weighted_sum(tensor, factor)
    mid, rad = factor
    if shared:
        head = tensor.shape[0]
        flat = tensor.reshape(head, -1)
        shape = (len(mid),) + tensor.shape[1:]
        return (mid @ flat).reshape(shape), (rad @ np.abs(flat)).reshape(shape)
    t_mid, t_rad = tensor
    return (_weighted_sum(t_mid, mid),
            _weighted_sum(np.abs(t_mid), rad) + _weighted_sum(t_rad, np.abs(mid) + rad))


def _weighted_sum(tensor, factor):
    """``Σ_j tensor[b, j, …] factor[b, j]`` as one batched matrix product."""
    flat = tensor.reshape(tensor.shape[:2] + (-1,))
    return np.matmul(factor[:, None, :], flat)[:, 0].reshape(
        (len(tensor),) + tensor.shape[2:])


def fit_expansion(machine, evaluate, degree: int, what: str, pooled: int = 0
                  ) -> PoseExpansion:
    """The expansion of ``evaluate(poses) -> (n_poses, *values)`` of the given per-axis
    degree, from its values at the node grid, checked at :data:`CHECK_POSES` poses.

    Parameters
    ----------
    machine : Machine
    evaluate : callable
        Values at poses ``(n_poses, n_axes)`` (mm, rad).
    degree : int
    what : str
        Name of the function, for the error message.
    pooled : int
        Trailing value axes over which a function's size is pooled (the terms of one sum,
        e.g. one output's weighted Jacobian row): coefficients are dropped and the check is
        judged relative to the largest of the group.

    Raises
    ------
    InputError
        If the expansion differs from ``evaluate`` at a check pose by more than
        :data:`CHECK_RTOL` of the largest value of its group: the machine's chain is not of
        the per-axis degree the certificate relies on.
    """
    kinds = tuple(axis.kind for axis in machine.axis_specs)
    low = np.array([axis.stroke[0] for axis in machine.axis_specs], dtype=float)
    high = np.array([axis.stroke[1] for axis in machine.axis_specs], dtype=float)
    linear = np.array([kind == "linear" for kind in kinds])
    origin = np.where(linear, (low + high) / 2, 0.0)
    scale = np.where(linear, (high - low) / 2, 1.0)
    nodes = [basis_nodes(kind, degree) for kind in kinds]
    grid = np.stack(np.meshgrid(*nodes, indexing="ij"), axis=-1)
    node_values = np.asarray(evaluate(origin + scale * grid.reshape(-1, len(kinds))))
    values_shape = node_values.shape[1:]
    coefficients = node_values.reshape(grid.shape[:-1] + values_shape)
    for a, (kind, points) in enumerate(zip(kinds, nodes)):
        inverse = np.linalg.inv(basis_values(kind, degree, points))  # rows: nodes
        coefficients = np.moveaxis(np.tensordot(inverse, coefficients, axes=([1], [a])), 0, a)
    size = np.abs(coefficients).reshape(-1, *values_shape)
    largest = _pool(size.max(axis=0), pooled)
    dropped = np.abs(coefficients) < DROP_RTOL * largest
    margin = (np.where(dropped, np.abs(coefficients), 0.0).reshape(size.shape).sum(axis=0)
              + ROUNDING_RTOL * size.sum(axis=0))
    expansion = PoseExpansion(kinds, degree, origin, scale,
                              np.where(dropped, 0.0, coefficients), margin,
                              tuple(np.arange(len(points)) for points in nodes))
    _check(expansion, evaluate, low, high, what, pooled)
    return expansion


def _pool(size, pooled: int) -> np.ndarray:
    """The largest of ``size`` over its last ``pooled`` axes, broadcast back."""
    if pooled == 0:
        return size
    axes = tuple(range(size.ndim - pooled, size.ndim))
    return np.broadcast_to(size.max(axis=axes, keepdims=True), size.shape)


def _check(expansion, evaluate, low, high, what, pooled) -> None:
    """Refuse an expansion that differs from the chain at the check poses."""
    unit = qmc.Halton(d=len(low), scramble=False).random(CHECK_POSES + 1)[1:]
    poses = low + (high - low) * unit
    direct = np.asarray(evaluate(poses))
    expanded = expansion.values(expansion.local(poses))
    size = _pool(np.abs(direct).max(axis=0), pooled)
    error = np.abs(expanded - direct).max(axis=0)
    if np.any(error > CHECK_RTOL * size + expansion.margin):
        worst = np.unravel_index(np.argmax(error / np.maximum(size, 1e-300)), error.shape)
        raise InputError(
            f"machine: the per-axis expansion of {what} differs from the chain by "
            f"{float(error[worst] / max(size[worst], 1e-300)):.1e} (relative, item {worst}) "
            f"at the check poses, more than {CHECK_RTOL:g}; the certificate needs a serial "
            f"chain whose Jacobian is of degree 1 in each axis (docs/certified-workspace.md)")


def variance_expansion(machine, variance, frame: str = "tool") -> PoseExpansion:
    """σ_o² (Eq. 20) of all six outputs, per-axis degree 2, values ``(6,)``.

    Parameters
    ----------
    machine : Machine
    variance : ndarray (n_errors,)
        Error variances σ_i² (independent errors).
    frame : {'tool', 'workpiece'}
        The frame the outputs are read in (Eq. 18, or rotated into the workpiece's axes).
    """
    return fit_expansion(machine, lambda q: output_variance(machine, q, variance, frame),
                         2, f"sigma^2 ({frame} frame)")


def jacobian_expansion(machine, weights, frame: str = "tool") -> PoseExpansion:
    """The Jacobian (Eq. 18's first-order sensitivities, in ``frame``) times a weight per
    error, ``J_oi w_i`` (e.g. ``w = t`` for the worst-case stack ``Σ_i |J_oi| t_i``),
    per-axis degree 1, values ``(6, n_errors)``; sizes pooled per output."""
    weights = np.asarray(weights, dtype=float)
    return fit_expansion(machine, lambda q: jacobian(machine, q, frame) * weights, 1,
                         f"the Jacobian ({frame} frame)", pooled=1)
