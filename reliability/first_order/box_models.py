"""Upper bounds of one output's spread over boxes of poses, for the certificate's branch and
bound (:mod:`reliability.first_order.certificate`, docs/certified-workspace.md).

Two readings of the spread, each a model over the local coordinates of the expansion of
:mod:`reliability.first_order.pose_expansion`:

* :class:`SigmaModel`, σ² of Eq. (20): on a box of centre c and half-widths h, the lower
  of the second-order Taylor bound with the Lagrange remainder

      σ²(c + d) ≤ σ²(c) + Σ_a h_a |g_a(c)| + ½ Σ_a h_a² max(H_aa, 0) + Σ_{a<b} h_a h_b |H_ab|

  (g exact at the centre, H enclosed over the box) and the first-order mean-value bound on
  the gradient's enclosure;
* :class:`StackModel`, the worst-case stack ``Σ_i |J_oi t_i|``: the largest value of its
  linear model at a vertex of the box plus the second-order remainder
  (:func:`curvature_bound`).

Each model also gives each axis' contribution to the bound (what the box is halved by), a
candidate point per box and its value, and the first candidates (a coarse grid, improved
for σ by a bounded local search).
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import minimize

from ..basics.chunks import chunks
from ..basics.errors import InputError
from ..basics.ties import TIE_RTOL
from .canonical_maxima import POLISH_OPTIONS
from .pose_expansion import interval_tree, point_tree
from .zone_bound import hessian_enclosure

#: Default bytes of temporary arrays per chunk of boxes: small enough to stay in cache,
#: which the per-box contractions (a few passes over each box's states) need to be fast.
BOX_MEMORY = 8 * 2 ** 20
#: Points per axis of the grid that gives the first candidate (σ reading; the stack's
#: vertex candidates need less, and its grid costs a whole Jacobian row per point).
START_POINTS = {"sigma": 5, "stack": 3}
#: Local searches (σ reading) from the best points of that grid.
START_SEARCHES = 3


class _Model:
    """What both readings share: the expansion, the local stroke box, the start."""

    def __init__(self, expansion):
        self.expansion = expansion
        #: Axes the function does not depend on (only the constant basis function left):
        #: never split, and reported at the low end of their stroke.
        self.fixed = np.array([len(index) == 1 and index[0] == 0
                               for index in expansion.basis_index])
        # the first contraction's six states (three derivatives, midpoint and radius)
        # and their temporaries dominate
        values = int(np.prod(expansion.coefficients.shape[expansion.n_axes:]))
        self.bytes_per_box = 8 * (4 * expansion.coefficients.size
                                  + 4 * expansion.n_axes ** 2 * values)

    def local_strokes(self, machine):
        low = np.array([axis.stroke[0] for axis in machine.axis_specs], dtype=float)
        high = np.array([axis.stroke[1] for axis in machine.axis_specs], dtype=float)
        return self.expansion.local(low), self.expansion.local(high)

    def start(self, low, high, inside, search):
        """The best points of the :data:`START_POINTS` grid inside the work zone (``inside``
        of points) and their value (``search``, a local search, is not used)."""
        grid = _start_grid(low, high, START_POINTS[self.reading], inside)
        values = self.grid_values(grid)
        return grid[values >= values.max() * (1 - TIE_RTOL)], float(values.max())

    def grid_values(self, points):
        """:meth:`values` at many points, in chunks within :data:`BOX_MEMORY`."""
        per_point = 8 * 2 * self.expansion.coefficients.size
        return np.concatenate([self.values(points[part])
                               for part in chunks(len(points), per_point, BOX_MEMORY)])


def _start_grid(low, high, points, inside) -> np.ndarray:
    """The ``points``-point grid's points inside the work zone, or an InputError."""
    grid = _grid(low, high, points)
    grid = grid[inside(grid)]
    if not len(grid):
        raise InputError(f"machine: no pose of the {points}-point grid of the strokes lies in "
                         f"its work zone, so the certificate has no pose to start from")
    return grid


def _grid(low, high, points) -> np.ndarray:
    """The ``points``-point grid of a box, ``(points^n_axes, n_axes)``."""
    axes = [np.linspace(lo, hi, points) for lo, hi in zip(low, high)]
    return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, len(low))


class SigmaModel(_Model):
    """σ² of one output: second-order Taylor bound on boxes (module docstring)."""

    reading = "sigma"

    def values(self, x):
        return self.expansion.values(x) if len(x) else np.empty(0)

    def spread(self, value):
        return float(np.sqrt(max(value, 0.0)))

    def function_of(self, spread):
        """The model's function (σ²) at a spread (σ); the inverse of :meth:`spread`."""
        return float(spread) ** 2

    def closing_factor(self, rtol):
        return (1 + rtol) ** 2

    def start(self, low, high, inside, search):
        """The grid's best points (inside the work zone: ``inside`` of points) improved by
        the local search ``search`` of points (:meth:`polish`, or the search constrained to
        the work zone) from the best few, where it stays in the zone."""
        grid = _start_grid(low, high, START_POINTS[self.reading], inside)
        values = self.grid_values(grid)
        found = search(grid[np.argsort(-values, kind="stable")[:START_SEARCHES]])
        found = found[inside(found)]
        candidates = np.vstack([grid, found])
        values = np.concatenate([values, self.values(found)])
        best = float(values.max())
        return candidates[values >= best * (1 - TIE_RTOL)], best

    def polish(self, starts, low, high):
        """Local maxima of σ² from a few starting points (bounded L-BFGS-B with the
        expansion's gradient, σ² scaled to about 1 so that the search's absolute
        tolerances mean the same for every machine and unit)."""
        scale = float(np.abs(self.values(starts)).max()) if len(starts) else 1.0
        scale = scale if scale > 0 else 1.0

        def negative(x):
            tree = point_tree(self.expansion, x[None, :], 1)
            gradient = np.array([tree[(a,)][0] for a in range(len(x))])
            return -tree[()][0] / scale, -gradient / scale

        return np.array([np.clip(minimize(negative, x, jac=True, method="L-BFGS-B",
                                          bounds=list(zip(low, high)),
                                          options=POLISH_OPTIONS).x, low, high)
                         for x in starts])

    def boxes(self, low, high, parts: bool = False):
        """Bound, contributions, candidate points, their values and slopes for boxes:
        the tighter of the second-order Taylor bound and the first-order mean-value
        bound on the gradient's enclosure, per box. With ``parts``, also σ² and its
        gradient at the centres and the enclosure ``(mid, rad)`` of its Hessian over the
        boxes, ``(b, n_axes, n_axes)`` each, for the bounds that build on them (the
        Lagrangian bound of a work zone's boundary)."""
        e = self.expansion
        centre, half = (low + high) / 2, (high - low) / 2
        point = point_tree(e, centre, 1)
        value = point[()]
        gradient = np.stack([point[(a,)] for a in range(e.n_axes)], axis=1)
        hessian = hessian_enclosure(e, low, high)
        second, step = self._second_order(half, gradient, *hessian)
        slope_mid, slope_rad = _stacked(interval_tree(e, low, high, 1), e.n_axes)
        first = half * (np.abs(slope_mid) + slope_rad)
        use_first = first.sum(axis=1) < second.sum(axis=1)
        contribution = np.where(use_first[:, None], first, second)
        bound = value + contribution.sum(axis=1) + e.margin
        vertex = _stepped(low, high, step, np.sign(gradient))
        vertex_value = e.values(vertex)
        better = vertex_value > value
        points = np.where(better[:, None], vertex, centre)
        away = (np.abs(slope_mid) > slope_rad + e.margin) & (high > low)
        found = (bound, contribution, points, np.where(better, vertex_value, value),
                 np.where(away, np.sign(slope_mid), 0.0))
        return found + (value, gradient) + hessian if parts else found

    def _second_order(self, half, gradient, h_mid, h_rad):
        """Each axis' share of the second-order Taylor bound's rise above the centre
        value, and the step towards the largest value of its quadratic model, from the
        Hessian's enclosure ``(h_mid, h_rad)`` over the boxes."""
        diagonal = np.arange(self.expansion.n_axes)
        curvature = (h_mid + h_rad)[:, diagonal, diagonal]
        cross = np.abs(h_mid) + h_rad
        cross[:, diagonal, diagonal] = 0.0
        step = rising_step(np.abs(gradient), curvature, half)
        return (np.abs(gradient) * step + 0.5 * curvature * step ** 2
                + 0.5 * half * np.einsum("bac,bc->ba", cross, half)), step


def _stepped(low, high, step, direction):
    """The centre of each box moved by ``step`` along ``direction`` per axis, exactly on
    the box's face where the step reaches it."""
    centre, half = (low + high) / 2, (high - low) / 2
    face = np.where(direction > 0, high, low)
    return np.where((step >= half) & (direction != 0), face,
                    np.clip(centre + step * direction, low, high))


def _stacked(tree, n_axes):
    """The first derivatives of an interval tree as ``(mid, rad)``, each ``(b, n_axes)``."""
    return (np.stack([tree[(a,)][0] for a in range(n_axes)], axis=1),
            np.stack([tree[(a,)][1] for a in range(n_axes)], axis=1))


def rising_step(slope, curvature, half):
    """The step ``0 ≤ d ≤ h`` that maximises ``slope·d + ½ curvature·d²``: ``h`` unless
    the curvature is negative and the maximum of the parabola lies inside."""
    concave = curvature < 0
    inside = np.divide(slope, -curvature, out=np.array(half, dtype=float), where=concave)
    return np.where(concave, np.minimum(half, inside), half)


class StackModel(_Model):
    """The weighted Jacobian row ``w_i = J_oi t_i`` of one output: the worst-case stack
    bounded by the vertices of its linear model plus the second-order remainder (module
    docstring)."""

    reading = "stack"

    def __init__(self, expansion):
        super().__init__(expansion)
        n = expansion.n_axes
        # the linear model's vertices over the axes the row depends on (others: 0)
        moving = [[0.0] if fixed else [-1.0, 1.0] for fixed in self.fixed]
        self.vertices = np.array(np.meshgrid(*moving, indexing="ij")).reshape(n, -1).T
        self.curvature = curvature_bound(expansion)
        values = expansion.coefficients.shape[-1]
        self.bytes_per_box = 8 * (3 * len(self.vertices) * values + 4 * (n + 1) * values
                                  + 2 * expansion.coefficients.size)

    def values(self, x):
        return np.abs(self.expansion.values(x)).sum(axis=-1) if len(x) else np.empty(0)

    def polish(self, starts, low, high):
        """No local search: the stack is not smooth, its boxes' vertex candidates serve."""
        return starts[:0]

    def spread(self, value):
        return float(value)

    def function_of(self, spread):
        return float(spread)

    def closing_factor(self, rtol):
        return 1 + rtol

    def boxes(self, low, high, parts: bool = False):
        """As :meth:`SigmaModel.boxes`; the stack's Lagrangian bound needs no parts."""
        e = self.expansion
        centre, half = (low + high) / 2, (high - low) / 2
        n = e.n_axes
        point = point_tree(e, centre, 1)
        value = point[()]  # (b, n_errors)
        gradient = np.stack([point[(a,)] for a in range(n)], axis=1)  # (b, a, n_errors)
        remainder = 0.5 * half * (half @ self.curvature)  # (b, a): Σ_i over the errors
        steps = half[:, None, :] * self.vertices[None]  # (b, v, a)
        linear = np.abs(value[:, None, :] + np.matmul(steps, gradient))  # (b, v, i)
        totals = linear.sum(axis=-1)  # (b, v)
        best_vertex = np.argmax(totals, axis=1)
        rows = np.arange(len(low))
        bound = totals[rows, best_vertex] + remainder.sum(axis=1) + e.margin.sum()
        contribution = half * np.abs(gradient).sum(axis=-1) + remainder
        vertex = np.clip(centre + steps[rows, best_vertex], low, high)
        vertex_value = self.values(vertex)
        centre_value = np.abs(value).sum(axis=-1)
        better = vertex_value > centre_value
        points = np.where(better[:, None], vertex, centre)
        return (bound, contribution, points, np.where(better, vertex_value, centre_value),
                np.zeros_like(half))


def curvature_bound(expansion) -> np.ndarray:
    """``K_ab ≥ Σ_i max |∂²w_i/∂x_a∂x_b|`` over the whole stroke box, ``(n_axes, n_axes)``.

    ``w_i`` is of degree 1 in each axis, so ``∂_a ∂_b w_i`` (a ≠ b) keeps the terms whose
    basis functions on axes a and b are not the constant, each differentiated once, and
    ``∂_a² w_i`` keeps the rotary terms in cos θ_a, sin θ_a (a linear axis enters
    affinely). Every basis function and its derivatives are at most 1 in magnitude on the
    strokes (``|u| ≤ 1``), so ``Σ_k |C_k,i|`` over those terms bounds each entry.
    """
    magnitude = np.abs(expansion.coefficients)
    magnitude = magnitude.reshape(magnitude.shape[:expansion.n_axes] + (-1,)).sum(axis=-1)
    n = expansion.n_axes
    moving = [np.asarray(index) != 0 for index in expansion.basis_index]
    out = np.zeros((n, n))
    for a in range(n):
        for b in range(a, n):
            if a == b and expansion.kinds[a] == "linear":
                continue
            weight = magnitude
            for axis in {a, b}:
                shape = [1] * n
                shape[axis] = -1
                weight = weight * moving[axis].reshape(shape)
            out[a, b] = out[b, a] = weight.sum()
    return out
