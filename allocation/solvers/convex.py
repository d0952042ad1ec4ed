"""Exact, certified solution of the convex core of the allocation problem (Eq. 34).

With ``u_i = t_i**2`` the cost of Eq. 28 is ``f(u) = sum_i w_i / u_i`` (convex) and every
FOSM reliability constraint ``sum_i (dg/dX_i)**2 u_i / 9 <= (I / z)**2`` is linear in ``u``.
After dividing each constraint by its right-hand side the problem reads::

    minimise    f(u) = sum_i w_i / u_i
    subject to  G u <= 1          (G >= 0, one row per constraint)
                lo <= u <= hi     (lo > 0; lo == hi locks an item)

The classical worst-case stack ``sum_i |dg/dX_i| t_i <= I`` is linear in ``t`` itself,
so there the variable is ``u = t`` and the cost ``sum_i w_i / u_i**2``. Both are the
family ``f(u) = sum_i w_i / u_i**p`` with ``t**2 = u**p`` (``power`` p = 1 or 2); every
formula below is written for general ``p`` and reduces to the one shown for ``p = 1``.

This module solves it and certifies the answer on its own terms:

* **Primal.** In ``v = log u`` the problem is a geometric program in convex form,
  ``min log sum_i w_i exp(-v_i)`` s.t. ``log sum_j G_rj exp(v_j) <= 0``. Tolerances of
  lengths (~1e-3 mm) and angles (~1e-5 rad) give ``u`` spanning five orders of magnitude;
  in ``v`` every variable moves on the same scale and the objective and constraints are
  O(1), which is what SLSQP (analytic gradients and Jacobians) needs to converge tightly.
  Rows are brought in by constraint generation (start with the rows most loaded at ``hi``,
  add the most violated rows until none is violated), so thousands of (output, pose) rows
  are cheap. The SLSQP point is finally pulled back inside ``G u <= 1`` if it overshoots
  by rounding, so ``fun`` is the cost of a feasible allocation. The cost is flat at the
  optimum, so SLSQP pins ``u`` to about 1e-7 (relative) while ``fun`` is exact to about
  1e-12; the certificate below measures the latter.
* **Multipliers.** Not taken from the solver: they are fitted by non-negative least
  squares to the stationarity equations ``(G^T lam)_i - w_i / u_i**2 = mu_lo_i - mu_hi_i``
  (scaled by ``u_i**2 / w_i``) over the near-active rows, with bound multipliers
  ``mu >= 0`` only for the items at a bound. Lawson-Hanson NNLS returns a sparse ``lam``
  even when thousands of rows are active (many poses give the same row).
* **Certificate.** For any ``lam >= 0`` the Lagrangian dual
  ``g(lam) = sum_i min_{lo_i <= u_i <= hi_i} (w_i / u_i + c_i u_i) - sum_r lam_r``,
  ``c = G^T lam``, is a lower bound on the optimum (weak duality); the inner minimum is
  attained at ``clip(sqrt(w_i / c_i), lo_i, hi_i)``. So the optimum lies in
  ``[dual_bound, fun]``, and the KKT residuals say how well the pair satisfies the
  optimality conditions.

It is a pure numerical core that imports nothing else of the toolkit, so bad shapes or
entries raise the built-in ``ValueError`` rather than :class:`reliability.basics.errors.InputError`
(:class:`~allocation.per_pose.problem.AllocationProblem` checks its inputs before they reach it).
"""

import itertools
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy.optimize import minimize, nnls

from reliability.basics.saved_fields import (Array, Flag, Number, Record, Text, load_fields,
                                            save_fields)

__all__ = [
    "ConvexSolution",
    "InfeasibleAllocationError",
    "KktResiduals",
    "solve_convex_allocation",
]

#: A row outside the working set is added when its load exceeds 1 by more than this.
ROW_ADD_TOLERANCE = 1e-9
#: Rows added to the working set per round of constraint generation, per free item.
ROWS_PER_ROUND = 2
#: Loads are brought to at most 1 minus this, so that constraints evaluated from
#: ``t = sqrt(u)`` or in another summation order cannot exceed 1 by rounding.
FEASIBILITY_MARGIN = 1e-13
#: Relative duality gap below which the dual's answer is taken without the primal solve.
#: The cost is flat at the optimum, so a gap δ leaves the allocation loose by about √δ:
#: a dual answer certified at 4e-7 on the paper's machine with poses added between grid
#: points moved tolerances by 3e-5 (relative) between two BLAS kernels, where the primal
#: solve reaches a gap of 1e-13 and the same tolerances to their sixth digit.
PRECISE_GAP = 1e-9
#: L-BFGS-B memory for the dual; more than the default 10 pairs lets working sets of
#: hundreds of rows reach a 1e-6 duality gap without the slower primal fallback.
DUAL_MEMORY = 30


class InfeasibleAllocationError(ValueError):
    """No allocation in the box meets the constraints.

    Attributes
    ----------
    rows : tuple of int
        Indices of the constraint rows that exceed 1 even with every item at its lower
        bound (the tightest tolerances allowed).
    loads : numpy.ndarray
        ``(G @ lower)[rows]``.
    """

    def __init__(self, rows, loads):
        self.rows = tuple(int(row) for row in rows)
        self.loads = np.asarray(loads, dtype=float)
        shown = ", ".join(
            f"{row} (load {load:.6g})" for row, load in zip(self.rows[:10], self.loads[:10])
        )
        more = f" and {len(self.rows) - 10} more" if len(self.rows) > 10 else ""
        super().__init__(
            f"allocation is infeasible: constraint row(s) {shown}{more} exceed 1 even "
            "with every tolerance at its lower bound"
        )


@dataclass(frozen=True)
class KktResiduals:
    """Residuals of the Karush-Kuhn-Tucker conditions at (u, lam).

    Attributes
    ----------
    stationarity : float
        Largest relative violation of ``p w_i / u_i**(p+1) = (G^T lam)_i`` over the items:
        ``|(G^T lam)_i u_i**(p+1) / (p w_i) - 1|`` for free items, and only the
        wrong-signed part for items at a bound (locked items are exempt).
    primal_feasibility : float
        ``max(0, max_r (G u - 1)_r)``.
    complementary_slackness : float
        ``max_r |lam_r (G u - 1)_r|``, divided by ``fun`` to be comparable to the
        relative duality gap.
    """

    stationarity: float
    primal_feasibility: float
    complementary_slackness: float


KKT_FIELDS = (Number("stationarity", low=0.0), Number("primal_feasibility", low=0.0),
              Number("complementary_slackness", low=0.0))


@dataclass(frozen=True, eq=False)
class ConvexSolution:
    """Certified solution of ``min sum w/u**p s.t. G u <= 1, lo <= u <= hi``.

    Attributes
    ----------
    u : numpy.ndarray, shape (n,)
        Optimal ``u`` (``t**2`` for p = 1, ``t`` for p = 2).
    t : numpy.ndarray, shape (n,)
        Optimal tolerances ``u**(p/2)``: ``sqrt(u)`` for p = 1, ``u`` for p = 2.
    fun : float
        Cost ``sum w / u**p`` at ``u`` (an upper bound on the optimum when ``u`` is
        feasible).
    multipliers : numpy.ndarray, shape (m,)
        Lagrange multipliers ``lam >= 0`` of the rows of ``G``.
    dual_bound : float
        Lagrangian dual ``g(lam)``, a lower bound on the optimum (weak duality).
    duality_gap : float
        ``fun - dual_bound``.
    relative_gap : float
        ``duality_gap / fun``.
    kkt : KktResiduals
    active : numpy.ndarray of int
        Rows with ``G u >= 1 - tol``.
    at_lower, at_upper : numpy.ndarray of int
        Unlocked items within ``tol`` (relative) of their lower or upper bound.
    locked : numpy.ndarray of int
        Items with ``lo == hi``.
    success : bool
        True when the certificate holds: ``relative_gap <= gap_tol`` and
        ``kkt.primal_feasibility <= gap_tol``.
    message : str
        The primal solver's message and the certificate's verdict.
    """

    u: np.ndarray
    t: np.ndarray
    fun: float
    multipliers: np.ndarray
    dual_bound: float
    duality_gap: float
    relative_gap: float
    kkt: KktResiduals
    active: np.ndarray
    at_lower: np.ndarray
    at_upper: np.ndarray
    locked: np.ndarray
    success: bool
    message: str

    def to_frame(self):
        """One row per item: ``u``, ``t`` and ``status`` (free/lower/upper/locked).

        Returns
        -------
        pandas.DataFrame
            Indexed by item number; set the index to the error names as needed.
        """
        status = np.full(self.u.size, "free", dtype=object)
        status[self.at_lower] = "lower"
        status[self.at_upper] = "upper"
        status[self.locked] = "locked"
        frame = pd.DataFrame({"u": self.u, "t": self.t, "status": status})
        frame.index.name = "item"
        return frame

    def summary(self) -> str:
        """The cost, the certificate (gap and KKT residuals) and what binds."""
        verdict = "certified" if self.success else "NOT certified"
        return (f"Convex allocation: cost {self.fun:.6g}, dual bound {self.dual_bound:.6g} "
                f"(relative gap {self.relative_gap:.2e}), {verdict}; stationarity "
                f"{self.kkt.stationarity:.2e}, primal feasibility "
                f"{self.kkt.primal_feasibility:.2e}; {len(self.active)} active rows, "
                f"{len(self.at_lower)} items at their lower and {len(self.at_upper)} at their "
                f"upper bound, {len(self.locked)} locked\n{self.message}")

    def save(self, path, overwrite: bool = False):
        """Save as JSON (:data:`SAVED_FIELDS`, tag :data:`SAVED_FORMAT`); an existing file
        is kept unless ``overwrite``. Returns the path."""
        return save_fields(self, path, SAVED_FORMAT, SAVED_FIELDS, overwrite)

    @classmethod
    def load(cls, path) -> "ConvexSolution":
        """Reload a solution written by :meth:`save`, checked: ``t`` follows from ``u``
        (``√u`` or ``u``), the gap is ``fun − dual_bound`` and the item and row numbers are
        in range, so the certificate is the saved one. A damaged field raises
        :class:`~reliability.basics.errors.SavedResultError` naming the file and field."""
        data, values = load_fields(path, SAVED_FORMAT, SAVED_FIELDS)
        u, t = values["u"], values["t"]
        if not (np.allclose(t, np.sqrt(u), rtol=1e-12) or np.array_equal(t, u)):
            raise data.error("t", "is neither sqrt(u) nor u")
        if not np.isclose(values["duality_gap"], values["fun"] - values["dual_bound"],
                          rtol=1e-9, atol=1e-300):
            raise data.error("duality_gap", "is not fun - dual_bound")
        for key, size in (("active", len(values["multipliers"])), ("at_lower", len(u)),
                          ("at_upper", len(u)), ("locked", len(u))):
            if np.any(values[key] >= size):
                raise data.error(key, f"holds numbers beyond {size - 1}")
        return cls(**values)


SAVED_FORMAT = "precrel.convex_solution"
SAVED_FIELDS = (Array("u", ("n",), positive=True), Array("t", ("n",), positive=True),
                Number("fun"), Array("multipliers", (None,), low=0.0), Number("dual_bound"),
                Number("duality_gap"), Number("relative_gap"), Record("kkt", KKT_FIELDS, KktResiduals),
                *(Array(key, (None,), dtype=int, low=0)
                  for key in ("active", "at_lower", "at_upper", "locked")),
                Flag("success"), Text("message"))


def solve_convex_allocation(
    weights, constraints, lower, upper, *, tol=1e-7, gap_tol=1e-6, max_iter=1000,
    power=1, start=None
):
    """Minimise ``sum_i w_i / u_i**power`` subject to ``G u <= 1``, ``lower <= u <= upper``.

    Parameters
    ----------
    weights : array_like, shape (n,)
        Cost weights ``w_i`` (Eq. 28 with ``F = sum w_i / t_i**2``), finite and > 0.
    constraints : array_like, shape (m, n)
        ``G``, finite and >= 0, each row already divided by its right-hand side.
    lower, upper : array_like, shape (n,) or scalar
        Bounds on ``u = t**2``, finite, ``0 < lower <= upper``; equal bounds lock an item.
    tol : float, optional
        Relative closeness that counts as "active" for rows and "at a bound" for items.
    gap_tol : float, optional
        Relative duality gap and primal infeasibility accepted as ``success``.
    max_iter : int, optional
        Iteration limit of each SLSQP solve.
    power : {1, 2}, optional
        Exponent ``p`` of the cost: 1 for ``u = t**2`` (FOSM rows), 2 for ``u = t``
        (worst-case stack rows).
    start : array_like, shape (m,), optional
        Multipliers to start the dual from (e.g. those of a neighbouring problem, scaled);
        rows with a positive entry begin in the working set. Only the speed depends on it.

    Returns
    -------
    ConvexSolution

    Raises
    ------
    InfeasibleAllocationError
        If some row has ``G @ lower > 1``; its ``rows`` attribute lists them.
    ValueError
        On bad shapes or entries (the message names the item).
    """
    w, G, lo, hi = _check_inputs(weights, constraints, lower, upper)
    p = _check_power(power)
    start = _check_start(start, G.shape[0])
    _check_feasible(G, lo)
    u, lam, message = _solve_dual(w, G, lo, hi, max_iter, p, start)
    solution = _certify(w, G, lo, hi, u, lam, tol, gap_tol, message, p)
    if solution.success and solution.relative_gap <= PRECISE_GAP:
        return solution
    u, message = _solve_primal(w, G, lo, hi, max_iter, p)
    u = _restore_feasibility(G, u, lo)
    lam = _refine_multipliers(w, G, u, lo, hi, tol, p)
    primal = _certify(w, G, lo, hi, u, lam, tol, gap_tol, message, p)
    if solution.success and solution.relative_gap <= primal.relative_gap:
        return solution
    return primal


def _check_power(power):
    if power not in (1, 2) or isinstance(power, bool):
        raise ValueError(f"power must be 1 (u = t**2) or 2 (u = t); got {power!r}")
    return int(power)


def _check_start(start, m):
    if start is None:
        return None
    start = np.asarray(start, dtype=float)
    if start.shape != (m,):
        raise ValueError(f"start must have shape ({m},) to match the constraints; "
                         f"got {start.shape}")
    _require(np.isfinite(start) & (start >= 0), start, "start", "finite and >= 0")
    return start


def largest_fraction(holds, steps: int = 60) -> float:
    """Largest ``s`` in [0, 1] with ``holds(s)``, by bisection.

    ``holds(0)`` must be true and ``holds`` monotone (true up to some point, false after).
    """
    low, high = 0.0, 1.0
    for _ in range(steps):
        middle = 0.5 * (low + high)
        if holds(middle):
            low = middle
        else:
            high = middle
    return low


def _add_violated_rows(working, load, per_round):
    """The working set grown by the ``per_round`` most violated rows outside it, and
    whether any row outside it was violated."""
    violated = np.setdiff1d(np.flatnonzero(load > 1.0 + ROW_ADD_TOLERANCE), working)
    worst = violated[np.argsort(load[violated])[::-1][:per_round]]
    return np.union1d(working, worst), violated.size > 0


def _dual_minimiser(w, c, lo, hi, p=1):
    """``argmin_{lo <= u <= hi} w/u**p + c u`` item by item:
    ``clip((p w/c)**(1/(p+1)), lo, hi)``, i.e. ``clip(sqrt(w/c), lo, hi)`` for p = 1."""
    with np.errstate(divide="ignore"):
        return np.clip((p * w / c) ** (1.0 / (p + 1)), lo, hi)  # c = 0: inf, clipped to hi


def _solve_dual(w, G, lo, hi, max_iter, p=1, start=None):
    """Maximise the Lagrangian dual ``g(lam)`` over ``lam >= 0`` by L-BFGS-B.

    ``g`` is concave, and differentiable because the inner minimiser is unique:
    ``grad g = G u*(lam) - 1``. The primal point ``u*(lam)`` at the dual optimum is the
    primal optimum. Only a working set of rows gets a multiplier (most have none at the
    optimum): it starts with the rows most loaded at ``hi`` and grows by the rows that
    ``u*(lam)`` violates, as in :func:`_constraint_generation`. Rounding leaves the final
    point slightly infeasible, which :func:`_restore_feasibility` repairs. Costs are
    divided by ``f(hi)`` so that the multipliers are O(1) for the solver. Given ``start``
    multipliers, the working set begins with their positive rows (a warm start).
    """
    if G.shape[0] == 0 or np.max(G @ hi) <= 1.0:
        return hi.copy(), np.zeros(G.shape[0]), "every item at its upper bound is feasible"
    scale = np.sum(w / hi ** p)
    per_round = ROWS_PER_ROUND * int(np.sum(lo < hi))
    if start is None:
        working = np.argsort(G @ hi)[::-1][:per_round]
        lam = np.zeros(G.shape[0])
    else:
        lam = start.copy()
        working = np.flatnonzero(lam > 0)
        if working.size == 0:
            working = np.argsort(G @ hi)[::-1][:per_round]
    for round_ in itertools.count(1):
        lam[working] = scale * _maximise_dual(w / scale, G[working], lo, hi,
                                              lam[working] / scale, max_iter, p)
        load = G @ _dual_minimiser(w, G.T @ lam, lo, hi, p)
        working, grew = _add_violated_rows(working, load, per_round)
        if not grew:
            break
    lam = _polish_multipliers(w, G, lo, hi, lam, p=p)
    u = _restore_feasibility(G, _dual_minimiser(w, G.T @ lam, lo, hi, p), lo)
    return u, lam, (f"dual L-BFGS-B ({round_} round(s), {working.size} of {G.shape[0]} "
                    f"rows in the working set)")


def _polish_multipliers(w, G, lo, hi, lam, steps=8, p=1):
    """Newton steps on ``G_A u*(lam) = 1`` over the rows with ``lam > 0``.

    L-BFGS-B stops with the binding rows about 1e-8 short of 1; a few Newton steps make
    them binding to rounding. ``d u*_i / d c_i = -u*_i / ((p + 1) c_i)``
    (``-sqrt(w_i) c_i^(-3/2) / 2`` for p = 1) for the items not clipped to a bound, so
    the Jacobian is ``G_A diag(du/dc) G_A^T``; it may be singular (alike rows), hence
    least squares. A step that would make a multiplier negative is halved until it does
    not (and polishing stops if halving cannot keep it >= 0); the polished multipliers
    are kept only when they bring the rows closer to binding.
    """
    active = np.flatnonzero(lam > 0)
    if active.size == 0:
        return lam

    def residual(multipliers):
        return G[active] @ _dual_minimiser(w, G.T @ multipliers, lo, hi, p) - 1.0

    current = residual(lam)
    for _ in range(steps):
        c = G.T @ lam
        u = _dual_minimiser(w, c, lo, hi, p)
        unclipped = (u > lo) & (u < hi)
        slope = np.where(unclipped, -u / ((p + 1) * np.where(c > 0, c, 1.0)), 0.0)
        jacobian = (G[active] * slope) @ G[active].T
        step = np.linalg.lstsq(jacobian, -current, rcond=None)[0]
        trial = lam.copy()
        for _halving in range(30):
            trial[active] = lam[active] + step
            if np.all(trial[active] >= 0):
                break
            step = step / 2
        if np.any(trial[active] < 0):  # weak duality needs lam >= 0
            break
        candidate = residual(trial)
        if np.max(np.abs(candidate)) >= np.max(np.abs(current)):
            break
        lam, current = trial, candidate
    return lam


def _maximise_dual(w, G, lo, hi, start, max_iter, p=1):
    """``argmax_{lam >= 0} g(lam)`` for rows ``G`` (costs already scaled to O(1))."""

    def negative_dual(lam):
        u = _dual_minimiser(w, G.T @ lam, lo, hi, p)
        slack = G @ u - 1.0
        return -(np.sum(w / u ** p) + slack @ lam), -slack

    result = minimize(negative_dual, start, jac=True, method="L-BFGS-B",
                      bounds=[(0.0, None)] * G.shape[0],
                      options={"maxiter": max_iter * 10, "maxfun": max_iter * 20,
                               "ftol": 1e-15, "gtol": 1e-13, "maxcor": DUAL_MEMORY})
    return result.x


def _check_inputs(weights, constraints, lower, upper):
    w = np.asarray(weights, dtype=float)
    if w.ndim != 1 or w.size == 0:
        raise ValueError(f"weights must be a non-empty 1-D vector, got shape {w.shape}")
    _require(np.isfinite(w) & (w > 0), w, "weights", "finite and > 0")
    G = np.asarray(constraints, dtype=float)
    if G.ndim != 2 or G.shape[1] != w.size:
        raise ValueError(
            f"constraints must have shape (m, {w.size}) to match weights, got {G.shape}"
        )
    _require(np.isfinite(G) & (G >= 0), G, "constraints", "finite and >= 0")
    lo = _bound_vector(lower, w.size, "lower")
    hi = _bound_vector(upper, w.size, "upper")
    _require(lo > 0, lo, "lower", "> 0")
    bad = np.flatnonzero(lo > hi)
    if bad.size:
        i = bad[0]
        raise ValueError(f"lower[{i}] = {lo[i]} exceeds upper[{i}] = {hi[i]}")
    return w, G, lo, hi


def _bound_vector(bound, n, name):
    bound = np.asarray(bound, dtype=float)
    if bound.ndim > 1 or bound.size not in (1, n):
        raise ValueError(f"{name} must be a scalar or have shape ({n},), got {bound.shape}")
    bound = np.broadcast_to(bound, (n,)).copy()
    _require(np.isfinite(bound), bound, name, "finite")
    return bound


def _require(ok, values, name, condition):
    bad = np.argwhere(~ok)
    if bad.size:
        where = tuple(int(i) for i in bad[0])
        label = ", ".join(map(str, where))
        raise ValueError(f"{name}[{label}] = {values[where]} must be {condition}")


def _check_feasible(G, lo):
    loads = G @ lo
    rows = np.flatnonzero(loads > 1.0)
    if rows.size:
        raise InfeasibleAllocationError(rows, loads[rows])


def _solve_primal(w, G, lo, hi, max_iter, p=1):
    """Optimal ``u`` by SLSQP in ``v = log u``, locked items held at their value."""
    if G.shape[0] == 0 or np.max(G @ hi) <= 1.0:
        return hi.copy(), "every item at its upper bound meets all constraints"
    free = lo < hi
    program = _GeometricProgram.reduced(w, G, lo, free, p)
    v_lo, v_hi = np.log(lo[free]), np.log(hi[free])
    v, message = _constraint_generation(program, v_lo, v_hi, max_iter)
    u = lo.copy()
    # exp(log(lo)) may differ from lo in the last bit; keep u inside its bounds exactly
    u[free] = np.clip(np.exp(v), lo[free], hi[free])
    return u, message


def _constraint_generation(program, v_lo, v_hi, max_iter):
    """Solve on a working set of rows, adding the most violated rows until none is."""
    per_round = ROWS_PER_ROUND * v_lo.size
    working = np.sort(np.argsort(program.G @ np.exp(v_hi))[::-1][:per_round])
    v = _feasible_start(program.G, v_lo, v_hi)
    for round_ in itertools.count(1):
        v, message = program.solve(v, v_lo, v_hi, working, max_iter)
        load = program.G @ np.exp(v)
        grown, grew = _add_violated_rows(working, load, per_round)
        if not grew:
            rows = f"{working.size} of {load.size} rows"
            return v, f"SLSQP: {message} ({round_} round(s), {rows} in the working set)"
        working = grown


@dataclass(frozen=True)
class _GeometricProgram:
    """``min log(sum w e^(-p v) + fixed_cost)`` s.t. ``log(G_r e^v) <= 0`` for working rows.

    Only the free items are variables; ``G`` holds the rows that involve one, each
    divided by what the locked items leave of its budget of 1.
    """

    w: np.ndarray
    G: np.ndarray
    fixed_cost: float
    p: int = 1

    @classmethod
    def reduced(cls, w, G, lo, free, p=1):
        budget = 1.0 - G[:, ~free] @ lo[~free]  # > 0 on rows involving a free item
        rows = np.flatnonzero(np.any(G[:, free] > 0, axis=1))
        scaled = G[np.ix_(rows, free)] / budget[rows, None]
        return cls(w[free], scaled, np.sum(w[~free] / lo[~free] ** p), p)

    def objective(self, v):
        terms = self.w * np.exp(-self.p * v)
        total = terms.sum() + self.fixed_cost
        return np.log(total), -self.p * terms / total

    def constraint(self, v, rows):
        return -np.log(self.G[rows] @ np.exp(v))

    def jacobian(self, v, rows):
        terms = self.G[rows] * np.exp(v)
        return -terms / terms.sum(axis=1, keepdims=True)

    def solve(self, v0, v_lo, v_hi, rows, max_iter):
        result = minimize(
            self.objective,
            v0,
            jac=True,
            method="SLSQP",
            bounds=list(zip(v_lo, v_hi)),
            constraints=[{
                "type": "ineq",
                "fun": self.constraint,
                "jac": self.jacobian,
                "args": (rows,),
            }],
            options={"ftol": 1e-15, "maxiter": max_iter},
        )
        return result.x, result.message


def _feasible_start(G, v_lo, v_hi):
    """Furthest feasible point on the segment from ``log lo`` to ``log hi`` (bisection)."""
    s = largest_fraction(lambda s: np.max(G @ np.exp(v_lo + s * (v_hi - v_lo))) <= 1.0)
    return v_lo + s * (v_hi - v_lo)


def _restore_feasibility(G, u, lo):
    """Shrink ``u`` towards ``lo`` just enough that ``G u <= 1 - FEASIBILITY_MARGIN``
    holds (rounding repair).

    ``u(rho) = max(lo, rho u)`` is feasible at ``rho = 0`` (``G lo <= 1`` was checked)
    and the loads grow with ``rho``, so the largest feasible ``rho`` is found by bisection.
    Returns ``u`` unchanged when it is already within the margin.
    """
    limit = 1.0 - FEASIBILITY_MARGIN
    if G.shape[0] == 0 or np.max(G @ u) <= limit:
        return u
    rho = largest_fraction(lambda rho: np.max(G @ np.maximum(lo, rho * u)) <= limit)
    return np.maximum(lo, rho * u)


def _refine_multipliers(w, G, u, lo, hi, tol, p=1):
    """Multipliers by NNLS on the scaled stationarity equations.

    For every unlocked item ``i``:
    ``sum_r lam_r G_ri u_i**(p+1) / (p w_i) - mu_lo_i + mu_hi_i = 1`` with ``lam``, ``mu >= 0``,
    over the rows with ``G u >= 1 - tol`` and bound multipliers only for items at a bound.
    ``lam`` is scaled by ``f(u)`` so that the columns are O(1).
    """
    lam = np.zeros(G.shape[0])
    items = np.flatnonzero(lo < hi)
    rows = np.flatnonzero(G @ u >= 1.0 - tol)
    if rows.size == 0 or items.size == 0:
        return lam
    fun = np.sum(w / u ** p)
    scale = u[items] ** (p + 1) / (p * w[items])
    at_lower, at_upper = (mask[items] for mask in _at_bounds(u, lo, hi, tol))
    identity = np.eye(items.size)
    matrix = np.hstack([
        fun * G[np.ix_(rows, items)].T * scale[:, None],
        -identity[:, at_lower],
        identity[:, at_upper],
    ])
    solution, _ = nnls(matrix, np.ones(items.size), maxiter=50 * items.size)
    lam[rows] = fun * solution[: rows.size]
    return lam


def _at_bounds(u, lo, hi, tol):
    """Masks of the unlocked items at their lower and at their upper bound."""
    unlocked = lo < hi
    return unlocked & (u <= lo * (1.0 + tol)), unlocked & (u >= hi * (1.0 - tol))


def _dual_bound(w, G, lo, hi, lam, p=1):
    """Lagrangian dual ``g(lam)``, a lower bound on the optimum for any ``lam >= 0``."""
    c = G.T @ lam
    u_best = _dual_minimiser(w, c, lo, hi, p)
    return float(np.sum(w / u_best ** p + c * u_best) - lam.sum())


def _certify(w, G, lo, hi, u, lam, tol, gap_tol, message, p=1):
    fun = float(np.sum(w / u ** p))  # Eq. (28) with t**2 = u**p
    dual = _dual_bound(w, G, lo, hi, lam, p)
    slack = G @ u - 1.0
    at_lower, at_upper = _at_bounds(u, lo, hi, tol)
    kkt = KktResiduals(
        stationarity=_stationarity(w, G, u, lam, lo < hi, at_lower, at_upper, p),
        primal_feasibility=float(max(0.0, slack.max(initial=-np.inf))),
        complementary_slackness=float(np.max(np.abs(lam * slack), initial=0.0) / fun),
    )
    gap = fun - dual
    success = gap / fun <= gap_tol and kkt.primal_feasibility <= gap_tol
    verdict = "certified" if success else "NOT certified"
    return ConvexSolution(
        u=_read_only(u),
        t=_read_only(np.sqrt(u) if p == 1 else u),  # t**2 = u**p
        fun=fun,
        multipliers=_read_only(lam),
        dual_bound=dual,
        duality_gap=gap,
        relative_gap=gap / fun,
        kkt=kkt,
        active=np.flatnonzero(slack >= -tol),
        at_lower=np.flatnonzero(at_lower),
        at_upper=np.flatnonzero(at_upper),
        locked=np.flatnonzero(lo == hi),
        success=bool(success),
        message=f"{message}; {verdict}: relative duality gap {gap / fun:.3g}",
    )


def _read_only(array):
    array = np.array(array)
    array.setflags(write=False)
    return array


def _stationarity(w, G, u, lam, unlocked, at_lower, at_upper, p=1):
    """Largest relative stationarity residual; only the wrong sign counts at a bound."""
    residual = (G.T @ lam) * u ** (p + 1) / (p * w) - 1.0
    residual[at_lower] = np.maximum(0.0, -residual[at_lower])
    residual[at_upper] = np.maximum(0.0, residual[at_upper])
    return float(np.max(np.abs(residual[unlocked]), initial=0.0))
