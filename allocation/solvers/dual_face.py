"""What the optimal Lagrange multipliers of the allocation problem determine, and what not.

The optimum ``u*`` of ``min f(u) = sum_i w_i / u_i**p`` s.t. ``G u <= 1``,
``lo <= u <= hi`` (:mod:`allocation.solvers.convex`) is unique (``f`` is strictly
convex), but its multipliers need not be: every ``(lam, mu_lo, mu_hi) >= 0`` with

    (G_A^T lam)_i - mu_lo_i + mu_hi_i = p w_i / u_i**(p+1)    (each unlocked item i)   (F1)

over the active rows ``A`` (and bound multipliers only on items at that bound) is optimal.
Where active rows have equal gradients (two outputs binding at symmetric poses) or
linearly dependent ones, (F1) leaves the split of ``lam`` among them free, and a solver
returns whichever split its arithmetic reaches. The set (F1) is the optimal dual face.

What the face does determine: for a group ``S`` of rows, the range
``[min, max]`` of ``sum_{r in S} lam_r`` over (F1), two linear programs. By convex
duality (Rockafellar, Convex Analysis, Thm. 29.1; the optimal value ``v(b)`` of the problem
with right-hand sides ``b`` is convex and ``∂v = -face``) these are the one-sided
derivatives of the optimal cost when the right-hand sides of ``S`` move together:

    d v / d s (s -> 0+) = -min sum_S lam,   d v / d s (s -> 0-) = -max sum_S lam      (F2)

for ``b_S = 1 + s``. So the range is not an artefact: relaxing a requirement that binds
only together with another saves nothing (``min = 0``), while tightening it costs the
whole group's multiplier. A range of zero width is the unique derivative.

(F1) holds only to the accuracy of ``u*`` (about 1e-7 relative), so it is imposed with a
slack ``eps``: the smallest slack that admits a solution (an LP), times
:data:`SLACK_FACTOR`, and at least :data:`SLACK_FLOOR`. Ranges narrower than about
``eps`` times the conditioning are the same number
(:data:`allocation.per_pose.elasticity.UNIQUE_WIDTH`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import linprog

__all__ = ["DualFace", "dual_face", "stationarity_face"]

#: The slack of (F1) is this multiple of the smallest slack that admits a solution …
SLACK_FACTOR = 4.0
#: … and at least this (relative to the right-hand side of (F1), which is 1 after scaling):
#: ten times the feasibility tolerance of the LP solver (HiGHS, 1e-7), about what ``u*``
#: fixes (1e-7 relative).
SLACK_FLOOR = 1e-6
#: Times the slack is widened tenfold when the LP solver fails on the face.
SLACK_RETRIES = 2


@dataclass(frozen=True)
class DualFace:
    """The optimal dual face (F1) in scaled variables, ready for linear programs.

    Attributes
    ----------
    rows : numpy.ndarray of int
        Indices (into ``G``) of the active rows: the first ``len(rows)`` variables are
        their ``lam_r / f(u*)``; the rest are the scaled bound multipliers.
    matrix : numpy.ndarray, shape (n_unlocked, n_variables)
        Left-hand side of (F1), each item's equation divided by its right-hand side.
    slack : float
        ``eps``: every equation holds within ``1 ± eps``.
    fun : float
        ``f(u*)``, the scale of the multipliers.
    """

    rows: np.ndarray
    matrix: np.ndarray
    slack: float
    fun: float

    def sum_range(self, members) -> tuple[float, float]:
        """``[min, max]`` of ``sum_{r in members} lam_r`` over the face, (F2).

        Parameters
        ----------
        members : array_like of bool, shape (len(rows),)
            Which active rows belong to the group.

        Returns
        -------
        tuple of float
            The smallest and largest group total, in the units of ``lam``; the largest is
            ``inf`` when the group's rows involve only locked items or items at their
            lower bound (tightening them cannot be met at any cost); NaN when the LP
            solver fails even on a widened face.
        """
        return self.range(np.asarray(members, dtype=bool).astype(float))

    def range(self, coefficients) -> tuple[float, float]:
        """``[min, max]`` of ``sum_r c_r lam_r`` over the face (any linear form of the
        multipliers of the active rows, e.g. a derivative by the envelope theorem; for
        a parameter of the constraints the two ends are the derivatives of the optimal
        cost from below and from above).

        Parameters
        ----------
        coefficients : array_like, shape (len(rows),)
            ``c_r`` per active row.

        Returns
        -------
        tuple of float
            As :meth:`sum_range`.
        """
        c = np.zeros(self.matrix.shape[1])
        c[: len(self.rows)] = coefficients
        if not c.any():
            return 0.0, 0.0
        low = self._optimum(c)
        high = -self._optimum(-c)
        return self.fun * low, self.fun * (high if np.isnan(high) else max(high, low))

    def _optimum(self, c) -> float:
        """``min c·x`` over the face; should the LP solver fail on the thin slab (its
        tolerances are absolute), the slack is widened by 10 up to :data:`SLACK_RETRIES`
        times, and NaN (not computed) returned if it still fails."""
        n = self.matrix.shape[0]
        a_ub = np.vstack([self.matrix, -self.matrix])
        for retry in range(SLACK_RETRIES + 1):
            slack = self.slack * 10.0 ** retry
            b_ub = np.r_[np.full(n, 1.0 + slack), np.full(n, -(1.0 - slack))]
            result = linprog(c, A_ub=a_ub, b_ub=b_ub, bounds=(0, None), method="highs")
            if result.status == 3:  # a row on locked or lower-bound items only
                return -np.inf
            if result.status == 0:
                return float(result.fun)
        return np.nan


def dual_face(weights, constraints, u, lower, upper, active, *, power=1, tol=1e-7):
    """The optimal dual face (F1) at the optimum ``u`` of the convex allocation problem.

    Parameters
    ----------
    weights, constraints, lower, upper, power
        As given to :func:`allocation.solvers.convex.solve_convex_allocation`.
    u : array_like, shape (n,)
        Its optimum (:attr:`ConvexSolution.u`).
    active : array_like of int
        The active rows (:attr:`ConvexSolution.active`).
    tol : float, optional
        Relative closeness that counts as "at a bound" (the solver's ``tol``).

    Returns
    -------
    DualFace
    """
    w = np.asarray(weights, dtype=float)
    G = np.asarray(constraints, dtype=float)
    u, lo, hi = (np.broadcast_to(np.asarray(x, dtype=float), w.shape) for x in (u, lower, upper))
    rows = np.asarray(active, dtype=int)
    p = int(power)
    fun = float(np.sum(w / u ** p))
    items = np.flatnonzero(lo < hi)
    scale = u[items] ** (p + 1) / (p * w[items])
    identity = np.eye(items.size)
    at_lower = u[items] <= lo[items] * (1.0 + tol)
    at_upper = u[items] >= hi[items] * (1.0 - tol)
    matrix = np.hstack([fun * G[np.ix_(rows, items)].T * scale[:, None],
                        -identity[:, at_lower], identity[:, at_upper]])
    return stationarity_face(matrix, rows, fun)


def stationarity_face(matrix, rows, fun) -> DualFace:
    """The face of any problem whose scaled stationarity equations are ``matrix x = 1``,
    ``x >= 0``, the first ``len(rows)`` variables being ``lam_r / fun`` of the active
    ``rows`` (e.g. the correlated allocation's, :mod:`allocation.per_pose.correlated`).

    Parameters
    ----------
    matrix : array_like, shape (n_equations, n_variables)
    rows : array_like of int
    fun : float

    Returns
    -------
    DualFace
    """
    matrix = np.asarray(matrix, dtype=float)
    return DualFace(rows=np.asarray(rows, dtype=int), matrix=matrix, slack=_slack(matrix),
                    fun=float(fun))


def _slack(matrix) -> float:
    """:data:`SLACK_FACTOR` times the smallest ``eps`` with ``|matrix x - 1| <= eps``,
    ``x >= 0`` solvable (an LP in ``(x, eps)``), at least :data:`SLACK_FLOOR` (the floor
    alone when that LP fails: :meth:`DualFace.sum_range` then widens it)."""
    n, m = matrix.shape
    if n == 0:
        return SLACK_FLOOR
    column = -np.ones((n, 1))
    a_ub = np.vstack([np.hstack([matrix, column]), np.hstack([-matrix, column])])
    b_ub = np.r_[np.ones(n), -np.ones(n)]
    c = np.r_[np.zeros(m), 1.0]
    result = linprog(c, A_ub=a_ub, b_ub=b_ub, bounds=(0, None), method="highs")
    found = float(result.fun) if result.status == 0 else 0.0  # failed: the retries widen
    return max(SLACK_FLOOR, SLACK_FACTOR * found)
