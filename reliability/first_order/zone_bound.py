"""The work zone as constraints on poses: the constrained local search for the worst pose
in the zone, its Lagrange multipliers, and the Lagrangian bound of boxes across the zone's
boundary (docs/certified-workspace.md, "A work zone").

The zone is ``g_j(q) ≤ 0`` for every j, each ``g_j`` affine in one of the measures the
zone's enclosure expands (:class:`reliability.first_order.zone_enclosure.ZoneEnclosure`):
a box's faces ``x − x_max − ρ ≤ 0`` … on ``(x, y, z)``, a cylinder's
``(r² − (R + ρ)²)/R² ≤ 0`` and its bottom and top, and the tilt range on ``cos tilt``,
each with the zone's rounding ``ρ`` (:data:`reliability.model.work_zone.LENGTH_ROUNDING`,
:data:`reliability.first_order.zone_enclosure.COS_ROUNDING`), so that every pose the zone
holds satisfies them. For any ``λ ≥ 0``,

    max over (box ∩ zone) of f  ≤  max over box of  L = f − Σ_j λ_j g_j,

because ``−λ_j g_j ≥ 0`` on the zone. ``L`` is again of degree 2 in each axis (the
measures are of degree 1 or 2), so the certificate's second-order Taylor bound of boxes
applies to it, with its Hessian enclosed by ``f``'s minus ``Σ λ_j`` times the constraints'
(:meth:`ZoneConstraints.parts`, :func:`hessian_enclosure`). With λ the multipliers of the
worst pose q* on the boundary (``∇f(q*) = Σ λ_j ∇g_j(q*)`` over the constraints active
there, on the axes not at a stroke's end: :meth:`ZoneConstraints.multipliers`), ``L`` is
stationary at q* along the boundary's directions and ``L(q*) = f(q*)``, so the bound of a
box near q* exceeds ``f(q*)`` by O(h²) where the whole-box bound of ``f`` exceeds it by O(h).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import minimize, nnls

from ..model.work_zone import LENGTH_ROUNDING
from .pose_expansion import ROUNDING_RTOL, interval_tree, point_tree
from .zone_enclosure import COS_ROUNDING

#: Scaled amount by which the constrained local search keeps inside each constraint, so
#: that its result lies in the zone despite the solver's own tolerance on constraints.
SEARCH_MARGIN = 1e-9
#: Scaled value of ``g_j`` above which a constraint counts as active at a pose.
ACTIVE_TOLERANCE = 1e-6
#: Fraction of a stroke's span within which an axis counts as at the stroke's end.
END_TOLERANCE = 1e-9
#: Sets of multipliers a box's bound is taken over, at most (for the memory estimate).
BOUND_SETS = 8


class ZoneConstraints:
    """The work zone of a machine as scaled constraints ``g_j(q) = a_j · m(q) + b_j ≤ 0``
    on the enclosure's measures ``m`` (module docstring).

    Parameters
    ----------
    enclosure : ZoneEnclosure
    """

    def __init__(self, enclosure):
        self.expansion = enclosure.expansion
        rows = _zone_rows(enclosure.zone) + _tilt_rows(enclosure.zone)
        n_measures = self.expansion.coefficients.shape[-1]
        self.matrix = np.zeros((len(rows), n_measures))
        self.offset = np.zeros(len(rows))
        for j, (measure, sign, limit, scale) in enumerate(rows):
            self.matrix[j, measure] = sign / scale
            self.offset[j] = -sign * limit / scale

    @property
    def count(self) -> int:
        return len(self.offset)

    def values(self, x) -> tuple[np.ndarray, np.ndarray]:
        """``g`` ``(b, n_constraints)`` and its gradient ``(b, n_constraints, n_axes)`` at
        local points ``(b, n_axes)``."""
        tree = point_tree(self.expansion, np.atleast_2d(x), 1)
        measures = tree[()] @ self.matrix.T + self.offset
        gradient = np.stack([tree[(a,)] @ self.matrix.T
                             for a in range(self.expansion.n_axes)], axis=-1)
        return measures, gradient

    def search(self, objective, starts, low, high) -> np.ndarray:
        """Local maxima of ``objective`` (a local point ``(n_axes,)`` to its value and
        gradient) in the zone and the box ``[low, high]``, from each start (SLSQP);
        ``(n_starts, n_axes)``, each a pose kept :data:`SEARCH_MARGIN` inside the
        constraints."""
        starts = np.atleast_2d(starts)
        scale = max([abs(objective(x)[0]) for x in starts] + [0.0]) or 1.0

        def negative(x):
            value, gradient = objective(x)
            return -value / scale, -gradient / scale

        constraint = {"type": "ineq",
                      "fun": lambda x: -self.values(x)[0][0] - SEARCH_MARGIN,
                      "jac": lambda x: -self.values(x)[1][0]}
        return np.array([np.clip(minimize(negative, x, jac=True, method="SLSQP",
                                          bounds=list(zip(low, high)),
                                          constraints=[constraint],
                                          options={"maxiter": 200, "ftol": 1e-15}).x,
                                 low, high)
                         for x in starts]).reshape(len(starts), len(low))

    def multipliers(self, gradient, point, low, high) -> np.ndarray:
        """Multipliers ``λ ≥ 0`` of the constraints active at a local point where ``f``
        has the gradient ``gradient`` (``(n_axes,)``): the non-negative least-squares fit
        of ``∇f = Σ λ_j ∇g_j`` on the axes not at a stroke's end (zero for inactive
        constraints), ``(n_constraints,)``."""
        point = np.asarray(point, dtype=float)
        values, jacobian = self.values(point)
        active = values[0] > -ACTIVE_TOLERANCE
        span = high - low
        free = (point - low > END_TOLERANCE * span) & (high - point > END_TOLERANCE * span)
        multipliers = np.zeros(self.count)
        if active.any() and free.any():
            multipliers[active] = nnls(jacobian[0][np.ix_(active, free)].T, gradient[free])[0]
        return multipliers

    def parts(self, low, high) -> tuple[np.ndarray, ...]:
        """For boxes of local coordinates ``[low, high]`` (``(b, n_axes)``): ``g`` and its
        gradient at the centres, ``(b, n_constraints)`` and ``(b, n_constraints, n_axes)``,
        and the enclosure ``(mid, rad)`` of its Hessian over the boxes, each
        ``(b, n_constraints, n_axes, n_axes)``."""
        values, gradient = self.values((low + high) / 2)
        mid, rad = hessian_enclosure(self.expansion, low, high)
        return (values, gradient, np.einsum("bacm,jm->bjac", mid, self.matrix),
                np.einsum("bacm,jm->bjac", rad, np.abs(self.matrix)))

    @property
    def margins(self) -> np.ndarray:
        """What each ``g_j`` may differ from the chain's by, ``(n_constraints,)``: the
        measures' margins and the rounding of the combination."""
        size = np.abs(self.expansion.coefficients).reshape(-1, self.matrix.shape[1]).sum(0)
        return (np.abs(self.matrix) @ self.expansion.margin
                + ROUNDING_RTOL * (np.abs(self.matrix) @ size + np.abs(self.offset)))

    @property
    def bytes_per_box(self) -> int:
        """Temporary bytes per box of :meth:`parts` and of the bounds built on it: the
        Hessian enclosure's first contraction, and a few Hessians per constraint and per
        set of multipliers (:data:`BOUND_SETS`)."""
        n = self.expansion.n_axes
        return 8 * (4 * self.expansion.coefficients.size
                    + 4 * n * n * self.count * BOUND_SETS)


def hessian_enclosure(expansion, low, high) -> tuple[np.ndarray, np.ndarray]:
    """Enclosure ``(mid, rad)`` of an expansion's Hessian over boxes of local coordinates,
    each ``(b, n_axes, n_axes, *values)``
    (:func:`reliability.first_order.pose_expansion.interval_tree`)."""
    n = expansion.n_axes
    tree = interval_tree(expansion, low, high, 2)
    shape = (len(np.atleast_2d(low)), n, n) + expansion.coefficients.shape[n:]
    mid, rad = np.zeros(shape), np.zeros(shape)
    for (a, b), (m, r) in tree.items():
        mid[:, a, b] = mid[:, b, a] = m
        rad[:, a, b] = rad[:, b, a] = r
    return mid, rad


def _zone_rows(zone) -> list[tuple[int, float, float, float]]:
    """``(measure, sign, limit, scale)`` per constraint ``sign (m − limit)/scale ≤ 0`` of
    the solid, with its rounding."""
    if zone.shape == "box":
        rows = []
        for k in range(3):
            scale = zone.high[k] - zone.low[k]
            rows += [(k, -1.0, zone.low[k] - LENGTH_ROUNDING, scale),
                     (k, 1.0, zone.high[k] + LENGTH_ROUNDING, scale)]
        return rows
    height = zone.z[1] - zone.z[0]
    return [(0, 1.0, (zone.radius + LENGTH_ROUNDING) ** 2, zone.radius ** 2),
            (1, -1.0, zone.z[0] - LENGTH_ROUNDING, height),
            (1, 1.0, zone.z[1] + LENGTH_ROUNDING, height)]


def _tilt_rows(zone) -> list[tuple[int, float, float, float]]:
    """The tilt range on ``cos tilt`` (the last measure), the ends that can bind only."""
    if zone.tilt is None:
        return []
    measure = 3 if zone.shape == "box" else 2
    low, high = (math.radians(v) for v in zone.tilt)
    rows = []
    if low > 0:
        rows.append((measure, 1.0, math.cos(low) + COS_ROUNDING, 1.0))
    if high < math.pi:
        rows.append((measure, -1.0, math.cos(high) - COS_ROUNDING, 1.0))
    return rows
