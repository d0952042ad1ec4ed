"""Certified optimal allocation when the geometric errors are correlated.

With a correlation matrix ``R = L Lᵀ`` between the errors (:mod:`reliability.model.correlation`)
an output's σ at a pose is ``σ = ‖Lᵀ D(t) j‖ / k`` with ``D(t) = diag(t)``: a norm of a
linear function of ``t``, hence convex in ``t``. The FOSM requirement ``σ ≤ I/z`` of every
(output, pose) is therefore a convex set, and the worst-case problem of Eq. (34)

    minimise    F(t) = Σ_i w_i / t_i²                                   (Eq. 28)
    subject to  h_r(t) = tᵀ Q_r t − 1 ≤ 0,   Q_r = diag(a_r) R diag(a_r)
                lower ≤ t ≤ upper,           a_r = j_r / (k I_o / z_o)

is convex in ``t`` (``Q_r`` is positive semi-definite, ``F`` convex for t > 0). Without
correlation ``tᵀ Q_r t = Σ a_ri² t_i²`` is the linear row of :mod:`allocation.solvers.convex` in
``u = t²``; with it the row is a quadratic form, no longer linear in ``u``, and a shrinking
tolerance can *raise* σ when it partly cancelled a correlated partner.

How it is solved and certified (the structure of :mod:`allocation.solvers.convex`):

* **Rows.** One per (output, pose) of the grid. Rows equal up to sign give the same form
  and are kept once; a row whose load stays ≤ 1 over the whole box even with ``|R|`` in
  place of ``R`` (an upper bound) can never bind and is dropped. Both are exact.
* **Primal.** SLSQP in ``v = log t`` on a working set of rows, grown by the most violated
  rows until none is violated (constraint generation); then Newton steps on the KKT
  equations of the active set found (SLSQP may stop with stationarity only ~1e-4 exact),
  and finally a pull inside the feasible set.
* **Multipliers.** Non-negative least squares on the stationarity equations
  ``2 w_i / t_i³ = Σ_r λ_r ∂h_r/∂t_i ± μ_i`` over the near-active rows.
* **Certificate.** For any ``λ ≥ 0`` the Lagrangian ``Λ(t) = F(t) + Σ λ_r h_r(t)`` is
  convex, so over the box ``Λ(t) ≥ Λ(t̂) + ∇Λ(t̂)·(t − t̂)``, and the smallest right-hand
  side is found item by item (each at a bound). Weak duality then gives the lower bound
  ``Λ(t̂) + Σ_i min(∇Λ_i (lower_i − t̂_i), ∇Λ_i (upper_i − t̂_i)) ≤ F*``; the optimum lies in
  ``[dual_bound, cost]``.

The derivative of the optimal cost with respect to one correlation coefficient follows
from the multipliers (envelope theorem): ``dF*/dρ_ab = Σ_r λ_r ∂h_r/∂ρ_ab
= Σ_r λ_r 2 a_ra a_rb t_a t_b`` (:meth:`CorrelatedAllocation.sensitivity`). Where binding
rows have linearly dependent gradients λ is not unique; the least and largest value of
that sum over all optimal λ are the derivatives from below and from above
(:meth:`CorrelatedAllocation.sensitivity_range`, :mod:`allocation.solvers.dual_face`).
"""

from __future__ import annotations

import dataclasses
import itertools
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy import sparse
from scipy.optimize import minimize, nnls
from threadpoolctl import threadpool_limits

from reliability.basics.display import axis_units, pose_text
from reliability.basics.errors import InputError, MachineDescriptionError
from reliability.basics.saved_fields import (Array, Flag, Frame, Mapping, Number, Text, Texts,
                                            read_fields, write_fields)
from reliability.basics.saved_results import load_payload, save_payload
from reliability.basics.display import (lower_bound_text, upper_bound_text)
from reliability.model.correlation import check_correlation_matrix
from reliability.model.iso_names import iso_names
from reliability.model.machine import OUTPUTS

from ..solvers.convex import ROW_ADD_TOLERANCE, ROWS_PER_ROUND, largest_fraction
from ..solvers.dual_face import stationarity_face
from .elasticity import UNIQUE_WIDTH
from .problem import AllocationProblem

ACTIVE_TOLERANCE = 1e-6  # a row with load ≥ 1 − this gets a multiplier
DUPLICATE_DIGITS = 12


@dataclass(frozen=True, eq=False)
class CorrelatedAllocation:
    """Certified optimum of the worst-case allocation with correlated errors.

    Attributes
    ----------
    names : tuple of str
        Error names.
    tolerances : ndarray (n_errors,)
    cost : float
        Eq. (28) at ``tolerances`` (feasible: an upper bound on the optimum).
    dual_bound : float
        Lower bound on the optimum (see the module docstring).
    relative_gap : float
        ``(cost − dual_bound) / cost``.
    stationarity : float
        Largest relative stationarity residual over the free items not at a bound.
    primal_feasibility : float
        ``max(0, max_r h_r(t))``.
    certified : bool
        ``relative_gap ≤ gap_tol`` and feasible.
    active : DataFrame
        Binding rows: output, pose index and positions, and the solver's multiplier λ
        (one optimal λ: where binding rows have dependent gradients the split is not
        unique, and :meth:`sensitivity_range` works on all of them).
    correlation : ndarray (n_errors, n_errors)
    rows : dict
        Row counts after each screening step.
    message : str
    """

    names: tuple
    tolerances: np.ndarray
    cost: float
    dual_bound: float
    relative_gap: float
    stationarity: float
    primal_feasibility: float
    certified: bool
    active: pd.DataFrame
    correlation: np.ndarray
    rows: dict
    message: str
    _forms: np.ndarray = dataclasses.field(repr=False)
    _face: np.ndarray | None = dataclasses.field(repr=False, default=None)

    def sensitivity(self, index_a: int, index_b: int) -> float:
        """``dF*/dρ_ab``: change of the optimal cost per unit of one correlation; NaN where
        the problem does not determine it (binding rows with dependent gradients, so that
        the cost has a kink in ρ_ab: :meth:`sensitivity_range` gives both sides)."""
        low, high = self.sensitivity_range(index_a, index_b)
        scale = UNIQUE_WIDTH * (self.cost + abs(high))
        return 0.5 * (low + high) if high - low <= scale else float("nan")

    def sensitivity_range(self, index_a: int, index_b: int) -> tuple[float, float]:
        """``dF*/dρ_ab`` from below and from above: the least and the largest
        ``Σ_r λ_r ∂h_r/∂ρ_ab`` over all optimal multipliers
        (:meth:`allocation.solvers.dual_face.DualFace.range`); equal where the derivative
        exists. A file saved before the face was kept gives the solver's multipliers'
        value twice."""
        a = self._forms * self.tolerances
        derivative = 2.0 * a[:, index_a] * a[:, index_b]  # ∂h_r/∂ρ_ab
        if self._face is None:
            value = float(np.sum(self.active["multiplier"].to_numpy() * derivative))
            return value, value
        if self._face.size == 0:
            return 0.0, 0.0
        face = stationarity_face(self._face, np.arange(len(derivative)), self.cost)
        return face.range(derivative)

    def to_frame(self) -> pd.DataFrame:
        """One row per error: its ISO 230-1 symbol and tolerance (mm or rad)."""
        return pd.DataFrame({"iso": iso_names(self.names), "tolerance": self.tolerances},
                            index=pd.Index(self.names, name="error"))

    def summary(self) -> str:
        verdict = "certified" if self.certified else "NOT certified"
        return (f"cost {self.cost:.6e} (dual bound {lower_bound_text(self.dual_bound, 7)}, "
                f"relative gap {upper_bound_text(self.relative_gap, 3)}, {verdict}); "
                f"{len(self.active)} binding row(s)")

    def save(self, path, overwrite: bool = False):
        """Save as JSON (:data:`SAVED_FIELDS`, ``forms``, the binding rows' linear forms,
        and ``face``, the stationarity equations :meth:`sensitivity_range` reads; tag
        :data:`SAVED_FORMAT`). An existing file is kept
        unless ``overwrite``. Returns the path."""
        payload = write_fields(self, SAVED_FIELDS)
        payload["forms"] = self._forms
        payload["face"] = self._face
        return save_payload(path, SAVED_FORMAT, payload, overwrite)

    @classmethod
    def load(cls, path) -> "CorrelatedAllocation":
        """Reload an allocation written by :meth:`save`, every field checked: the
        relative gap follows from cost and dual bound, the correlation is a correlation
        matrix and ``forms`` has one row per binding row; the certificate and the
        sensitivities are the saved ones. A damaged field raises
        :class:`~reliability.basics.errors.SavedResultError` naming the file and field."""
        data = load_payload(path, SAVED_FORMAT)
        values = read_fields(data, SAVED_FIELDS)
        try:
            check_correlation_matrix(values["correlation"], values["names"])
        except MachineDescriptionError as exc:
            raise data.error("correlation", str(exc)) from None
        gap = (values["cost"] - values["dual_bound"]) / values["cost"]
        if not np.isclose(values["relative_gap"], gap, rtol=1e-9, atol=1e-15):
            raise data.error("relative_gap", "is not (cost - dual_bound) / cost")
        forms = data.array("forms", (len(values["active"]), len(values["names"])))
        face = data.array("face", (None, None)) if data.data.get("face") is not None \
            else None
        if face is not None and face.size and face.shape[1] < len(forms):
            raise data.error("face", f"has {face.shape[1]} columns, fewer than the "
                                     f"{len(forms)} binding rows")
        return cls(**values, _forms=forms, _face=face)


SAVED_FORMAT = "precrel.correlated_allocation"
SAVED_FIELDS = (Texts("names", "n", unique=True), Array("tolerances", ("n",), positive=True),
                Number("cost", positive=True), Number("dual_bound"), Number("relative_gap"),
                Number("stationarity", low=0.0), Number("primal_feasibility", low=0.0),
                Flag("certified"), Frame("active", ("output", "multiplier")),
                Array("correlation", ("n", "n"), low=-1.0, high=1.0), Mapping("rows"),
                Text("message"))


def solve_correlated(machine, poses=None, *, correlation=None, side: str = "two_sided",
                     bounds=(0.5, 1.5), lower=None, upper=None, locked=(), reference=None,
                     k: float = 3.0, cost_factors=(1.0, 1.0, 1.0), gap_tol: float = 1e-6,
                     max_iter: int = 500) -> CorrelatedAllocation:
    """Certified optimum of Eq. (34) (worst case over the poses) with correlated errors.

    Parameters
    ----------
    machine : Machine
    poses : array_like, optional
        ``(n_poses, n_axes)``; default the 5-point workspace grid.
    correlation : array_like, optional
        ``(n_errors, n_errors)`` correlation matrix; default ``machine.correlation``
        (the identity when the machine has none).
    side, bounds, lower, upper, locked, reference, k, cost_factors
        As in :meth:`allocation.per_pose.problem.AllocationProblem.build` (locks and bounds by
        paper name or ISO 230-1 symbol).
    gap_tol : float
        Relative duality gap accepted as certified.
    max_iter : int
        Iteration limit of each SLSQP solve.

    Returns
    -------
    CorrelatedAllocation

    Raises
    ------
    InputError
        When the targets cannot be met inside the bounds (no feasible point found).
    """
    if correlation is None:
        correlation = machine.correlation
    if correlation is None:
        correlation = np.eye(machine.n_errors)
    R = check_correlation_matrix(correlation, machine.error_names)
    # the mean reading skips the linear rows that only independent errors have
    problem = AllocationProblem.build(dataclasses.replace(machine, correlation=None), poses,
                                      side=side, workspace="mean", bounds=bounds, lower=lower,
                                      upper=upper, locked=locked, reference=reference, k=k,
                                      cost_factors=cost_factors)
    forms = problem.jacobian / (k * problem.allowed_sigma[:, None])  # a_r, (P, 6, n)
    rows = _QuadraticRows.screen(forms, R, problem.upper)
    w, lo, hi = problem.cost.weights, problem.lower, problem.upper
    with threadpool_limits(limits=1, user_api="blas"):  # small matrices: one thread is fastest
        t, message = _solve_primal(w, rows, lo, hi, max_iter)
    t = _restore_feasibility(rows, _polish(w, rows, t, lo, hi), lo, hi)
    load = rows.load(t)
    if load.max(initial=0.0) > 1.0 + ROW_ADD_TOLERANCE:
        raise InputError(f"targets cannot be met inside the bounds with this correlation: "
                         f"{OUTPUTS[rows.output[np.argmax(load)]]} at "
                         f"{_pose_at(problem, rows.pose[np.argmax(load)])} has load "
                         f"{load.max():.6g} > 1")
    active = np.flatnonzero(load >= 1.0 - ACTIVE_TOLERANCE)
    lam = _multipliers(w, rows, t, lo, hi, active)
    face = _stationarity_matrix(w, rows, t, lo, hi, active)
    fun = float(np.sum(w / t ** 2))  # Eq. (28)
    bound, stationarity = _certificate(w, rows, t, lo, hi, active, lam, load)
    gap = (fun - bound) / fun
    feasibility = float(max(0.0, load.max(initial=0.0) - 1.0))
    certified = bool(gap <= gap_tol and feasibility <= gap_tol)
    frame = pd.DataFrame({"output": np.array(OUTPUTS)[rows.output[active]],
                          "pose": rows.pose[active]})
    for i, axis in enumerate(machine.axes):
        frame[axis] = problem.poses[rows.pose[active], i]
    frame["multiplier"] = lam
    verdict = "certified" if certified else "NOT certified"
    return CorrelatedAllocation(
        names=machine.error_names, tolerances=_read_only(t), cost=fun, dual_bound=bound,
        relative_gap=gap, stationarity=stationarity, primal_feasibility=feasibility,
        certified=certified, active=frame, correlation=R, rows=rows.counts,
        message=f"{message}; {verdict}: relative duality gap {gap:.3g}",
        _forms=rows.forms[active], _face=face)


@dataclass(frozen=True, eq=False)
class _QuadraticRows:
    """Constraint rows ``h_r(t) = (a_r∘t)ᵀ R (a_r∘t) − 1 ≤ 0`` with their origin."""

    forms: np.ndarray  # (m, n) a_r
    off_diagonal: sparse.csr_array  # R − I, a few pairs
    dense_R: np.ndarray
    pose: np.ndarray
    output: np.ndarray
    counts: dict

    @classmethod
    def screen(cls, forms, R, upper):
        """Keep one row per form up to sign, and only rows that can bind inside the box."""
        n_poses, n_outputs, n = forms.shape
        flat = forms.reshape(-1, n)
        pose = np.repeat(np.arange(n_poses), n_outputs)
        output = np.tile(np.arange(n_outputs), n_poses)
        counts = {"candidates": len(flat)}
        scaled = np.abs(flat) * upper
        can_bind = np.einsum("ri,ij,rj->r", scaled, np.abs(R), scaled) > 1.0  # upper bound
        flat, pose, output = flat[can_bind], pose[can_bind], output[can_bind]
        counts["box"] = len(flat)
        first = np.argmax(flat != 0, axis=1)
        signed = flat * np.sign(flat[np.arange(len(flat)), first])[:, None]
        scale = np.abs(signed).max(axis=1, keepdims=True)
        key = np.round(signed / np.where(scale > 0, scale, 1.0), DUPLICATE_DIGITS) * scale
        _, keep = np.unique(key, axis=0, return_index=True)
        keep = np.sort(keep)
        counts["duplicates"] = len(keep)
        off_diagonal = sparse.csr_array(R - np.eye(len(R)))
        return cls(flat[keep], off_diagonal, R, pose[keep], output[keep], counts)

    def _times_R(self, a) -> np.ndarray:
        """``a R`` row by row, as ``a + a (R − I)`` with the sparse off-diagonal part."""
        return a + (self.off_diagonal @ a.T).T  # R is symmetric

    def load(self, t, rows=slice(None)) -> np.ndarray:
        """``(a_r∘t)ᵀ R (a_r∘t)`` of the chosen rows."""
        a = self.forms[rows] * t
        return np.einsum("ri,ri->r", self._times_R(a), a)

    def gradient(self, t, rows) -> np.ndarray:
        """``∂ load_r / ∂t_i = 2 a_ri (R (a_r∘t))_i``, ``(len(rows), n)``."""
        a = self.forms[rows] * t
        return 2.0 * self.forms[rows] * self._times_R(a)


def _solve_primal(w, rows, lo, hi, max_iter):
    """SLSQP in ``v = log t`` over the free items with constraint generation."""
    free = lo < hi
    if rows.load(hi).max(initial=0.0) <= 1.0:
        return hi.copy(), "every item at its upper bound meets all constraints"

    def full(v):
        t = lo.copy()
        t[free] = np.exp(v)
        return t

    def objective(v):
        terms = w * full(v) ** -2.0
        total = terms.sum()
        return np.log(total), -2.0 * terms[free] / total

    def constraint(v, working):
        return -np.log(rows.load(full(v), working))

    def jacobian(v, working):
        t = full(v)
        return -(rows.gradient(t, working) * t)[:, free] / rows.load(t, working)[:, None]

    per_round = ROWS_PER_ROUND * int(free.sum())
    working = np.sort(np.argsort(rows.load(hi))[::-1][:per_round])
    v_lo, v_hi = np.log(lo[free]), np.log(hi[free])
    s = largest_fraction(  # furthest feasible point on the segment log lo -> log hi
        lambda s: rows.load(lo * (hi / lo) ** s).max() <= 1.0)
    v = v_lo + s * (v_hi - v_lo)
    for round_ in itertools.count(1):
        result = minimize(objective, v, jac=True, method="SLSQP",
                          bounds=list(zip(v_lo, v_hi)),
                          constraints=[{"type": "ineq", "fun": constraint, "jac": jacobian,
                                        "args": (working,)}],
                          options={"ftol": 1e-15, "maxiter": max_iter})
        v = result.x
        load = rows.load(full(v))
        violated = np.setdiff1d(np.flatnonzero(load > 1.0 + ROW_ADD_TOLERANCE), working)
        if violated.size == 0:
            return full(v), (f"SLSQP: {result.message} ({round_} round(s), {working.size} of "
                             f"{load.size} rows in the working set)")
        worst = violated[np.argsort(load[violated])[::-1][:per_round]]
        working = np.union1d(working, worst)


def _polish(w, rows, t, lo, hi, steps: int = 20):
    """Newton steps on the KKT equations of the active set found by SLSQP.

    SLSQP can stop with the free items' stationarity only ~1e-4 exact. With the rows near
    binding (``A``) and the items strictly inside their bounds (``F``) held as such, the
    optimum solves ``∇_F F + Σ_r λ_r ∇_F h_r = 0``, ``h_A(t) = 0``: a square system in
    ``(t_F, λ_A)`` whose Jacobian holds the Hessians ``6 w / t⁴`` and
    ``2 diag(a_r) R diag(a_r)``; it is solved in relative steps of ``t`` and ``λ / F``
    so that its columns are O(1). A step is kept only if it stays inside the box and lowers
    the residual (least squares, as alike rows make the system singular).
    """
    load = rows.load(t)
    active = np.flatnonzero(load >= 1.0 - 1e-4)
    at_lower, at_upper = _at_bounds(t, lo, hi, tol=1e-6)
    inside = np.flatnonzero((lo < hi) & ~at_lower & ~at_upper)
    if active.size == 0 or inside.size == 0:
        return t
    t = np.where(at_lower, lo, np.where(at_upper, hi, t))  # held at their bound
    lam = _multipliers(w, rows, t, lo, hi, active)

    def residual(t, lam):
        grad = -2.0 * w / t ** 3 + lam @ rows.gradient(t, active)
        scale = 2.0 * w[inside] / t[inside] ** 3
        return np.concatenate([grad[inside] / scale, rows.load(t, active) - 1.0])

    current = residual(t, lam)
    for _ in range(steps):
        G = rows.gradient(t, active)[:, inside]
        hessian = np.diag(6.0 * w[inside] / t[inside] ** 4)
        for r, weight in zip(active, lam):
            a = rows.forms[r, inside]
            hessian += weight * 2.0 * a[:, None] * rows.dense_R[np.ix_(inside, inside)] * a
        scale = 2.0 * w[inside] / t[inside] ** 3
        jacobian = np.block([[hessian / scale[:, None], G.T / scale[:, None]],
                             [G, np.zeros((active.size, active.size))]])
        columns = np.concatenate([t[inside], np.full(active.size, np.sum(w / t ** 2))])
        step = np.linalg.lstsq(jacobian * columns, -current, rcond=None)[0] * columns
        trial_t, trial_lam = t.copy(), np.maximum(lam + step[inside.size:], 0.0)
        trial_t[inside] += step[:inside.size]
        if np.any(trial_t < lo) or np.any(trial_t > hi):
            break
        candidate = residual(trial_t, trial_lam)
        if np.max(np.abs(candidate)) >= np.max(np.abs(current)):
            break
        t, lam, current = trial_t, trial_lam, candidate
    return t


def _restore_feasibility(rows, t, lo, hi):
    """Scale the free items towards zero just enough that every row holds.

    Scaling ``t`` by ``s`` scales every load by ``s²``; the bounds clip the result, so the
    largest feasible ``s ≤ 1`` is found by bisection (a no-op for a feasible ``t``).
    """
    if rows.load(t).max(initial=0.0) <= 1.0:
        return t
    s = largest_fraction(lambda s: rows.load(np.clip(s * t, lo, hi)).max() <= 1.0)
    return np.clip(s * t, lo, hi)


def _at_bounds(t, lo, hi, tol=1e-7):
    free = lo < hi
    return free & (t <= lo * (1 + tol)), free & (t >= hi * (1 - tol))


def _multipliers(w, rows, t, lo, hi, active) -> np.ndarray:
    """λ ≥ 0 of the active rows by NNLS on the scaled stationarity equations
    (:func:`_stationarity_matrix`); one optimal λ where alike rows let it split."""
    matrix = _stationarity_matrix(w, rows, t, lo, hi, active)
    if matrix.size == 0:
        return np.zeros(active.size)
    solution, _ = nnls(matrix, np.ones(len(matrix)), maxiter=50 * matrix.shape[1])
    return np.sum(w / t ** 2) * solution[:active.size]


def _stationarity_matrix(w, rows, t, lo, hi, active) -> np.ndarray:
    """The scaled stationarity equations ``matrix x = 1``, ``x ≥ 0``.

    For every free item ``i``: ``Σ_r λ_r g_ri t_i³ / (2 w_i) − μ_lo + μ_hi = 1`` with
    ``g_r = ∇ load_r``, bound multipliers only for items at a bound; the first
    ``len(active)`` unknowns are ``λ / F(t)`` so that the columns are O(1). Empty when
    no row is active or no item free.
    """
    items = np.flatnonzero(lo < hi)
    if active.size == 0 or items.size == 0:
        return np.zeros((0, 0))
    fun = np.sum(w / t ** 2)
    scale = t[items] ** 3 / (2.0 * w[items])
    at_lower, at_upper = (mask[items] for mask in _at_bounds(t, lo, hi))
    identity = np.eye(items.size)
    return np.hstack([fun * rows.gradient(t, active)[:, items].T * scale[:, None],
                      -identity[:, at_lower], identity[:, at_upper]])


def _certificate(w, rows, t, lo, hi, active, lam, load):
    """Lower bound ``Λ(t̂) + Σ_i min over the box of ∇Λ_i (t_i − t̂_i)`` and the
    largest relative stationarity residual of the free items strictly inside the box."""
    lagrangian = np.sum(w / t ** 2) + lam @ (load[active] - 1.0)
    grad = -2.0 * w / t ** 3 + lam @ rows.gradient(t, active)
    linear = np.minimum(grad * (lo - t), grad * (hi - t))
    bound = float(lagrangian + linear.sum())
    at_lower, at_upper = _at_bounds(t, lo, hi)
    inside = (lo < hi) & ~at_lower & ~at_upper
    residual = np.abs(grad * t ** 3 / (2.0 * w))[inside]
    return bound, float(residual.max(initial=0.0))


def _read_only(array):
    array = np.array(array, dtype=float)
    array.setflags(write=False)
    return array


def _pose_at(problem, index: int) -> str:
    """Grid pose ``index`` of ``problem`` by its axis positions."""
    machine = problem.machine
    return pose_text(problem.poses[index], machine.axes, axis_units(machine), digits=6)
