"""A lower bound on the cost of any allocation with machine yield ≥ Y from the joint event
of the six outputs at a pose.

A built machine passes only if all six outputs hold at every pose, so its yield is at most
the probability that the six rows of any one pose hold together. Under the bound's model
(the linearised outputs ``y_o = Σ_i J_oi x_i`` with independent normal errors of standard
deviation ``σ_i``, Eq. 20's model of a row, the truncated σ under the truncated reading)
that joint probability is bounded by a product. Order the six rows of a pose; let ``E_k``
be the errors row ``k`` depends on and no earlier row does (its *fresh* errors). Given
every other error, row ``k`` is a fixed shift plus the centred normal ``Σ_{i∈E_k} J_ki x_i``,
independent of the earlier rows, and a centred normal is most likely inside a symmetric
interval when unshifted (Anderson's theorem). So

    yield ≤ P(all six rows hold) ≤ Π_k p(v_k),   v_k = Σ_{i∈E_k} J_ki² σ_i² / I_k²,

with ``p(v) = 2Φ(1/√v) − 1`` (the first row's fresh errors are all of its errors). Each
``v_k`` is linear in ``s = t²``, and ``h(v) = log p(v)`` is concave for ``v ≤ 1/β_c²``
(``β_c ≈ 1.61``) and convex beyond. Every row of a feasible allocation has probability
≥ Y, so ``v_k ≤ 1/z_Y²`` (``z_Y = Φ⁻¹((1 + Y)/2)``), and ``ĥ``, the concave envelope of
``h`` on ``[0, 1/z_Y²]`` (``h`` itself when ``z_Y ≥ β_c``), turns every pose's constraint
``Σ_k ĥ(v_k(s)) ≥ log Y`` into a convex one. Together with the rows' own constraints
``v_r(s) ≤ 1/z_Y²`` and the box this is a convex relaxation of the yield target.

The relaxation is solved by cutting planes (rows and poses most violated at the current
point join, a few rounds, every pose ordered greedily: at each step the row whose fresh
errors leave the smallest probability) and certified by weak duality: for multipliers
``λ ≥ 0`` the Lagrangian ``L(s) = c(s) − Σ_j λ_j g_j(s)`` (constraints ``g_j ≥ 0``) is
convex, below the cost at every feasible allocation, and its minimum over the box is at
least ``L(s*) + min_box ∇L(s*)·(s − s*)`` at any ``s*``. Coefficients ``|J_oi|`` below
:data:`ZERO` times the row's largest are read as the chain's exact zeros (their rounding).
The bound needs independent errors: with an item correlation there is none
(:func:`pose_chain_bound` returns None).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq, minimize, nnls
from scipy.special import ndtr
from scipy.stats import norm

from reliability.basics.chunks import chunks, jacobian_bytes
from reliability.first_order.fosm import error_sigma, required_index

#: Relative size below which a Jacobian coefficient is the rounding of an exact zero.
ZERO = 1e-12
#: Largest index of a row whose ``h`` is convex (``β² + 2βφ(β)/p(β) = 3``).
CONVEX_BELOW = 1.6108
#: Poses and rows joining the relaxation per round, and rounds.
POSES_PER_ROUND = 12
ROWS_PER_ROUND = 40
ROUNDS = 8


@dataclass(frozen=True)
class ChainBound:
    """The pose-chain relaxation's certified bound.

    Attributes
    ----------
    bound : float
        Lower bound on the cost of any allocation in the box with yield ≥ Y (the bound's
        model, the grid of the problem).
    tolerances : ndarray (n_errors,)
        The relaxation's solution.
    poses : ndarray of int
        Poses (indices into the problem's poses) whose chains the relaxation holds.
    rows : int
        Single rows it holds.
    """

    bound: float
    tolerances: np.ndarray
    poses: np.ndarray
    rows: int


class ChainLog:
    """``ĥ``: the concave envelope of ``h(v) = log(2Φ(1/√v) − 1)`` on ``[0, v_max]``,
    continued linearly beyond."""

    def __init__(self, v_max: float):
        self.v_max = float(v_max)
        v_convex = 1.0 / CONVEX_BELOW ** 2
        if self.v_max <= v_convex:
            self.v_touch = self.v_max
        else:
            def tangent_gap(v):
                return self._h(v) + self._slope(v) * (self.v_max - v) - self._h(self.v_max)
            self.v_touch = brentq(tangent_gap, 1e-4 * v_convex, v_convex, xtol=1e-14)
        self.line_slope = self._slope(self.v_touch)

    @staticmethod
    def _h(v):
        beta = 1.0 / np.sqrt(np.maximum(v, 1e-4))  # beyond 100 sigma, h is 0 in doubles
        return np.log(np.maximum(2.0 * ndtr(beta) - 1.0, 1e-300))

    @staticmethod
    def _slope(v):
        beta = 1.0 / np.sqrt(np.maximum(v, 1e-4))
        return -norm.pdf(beta) * beta ** 3 / np.maximum(2.0 * ndtr(beta) - 1.0, 1e-300)

    def __call__(self, v):
        v = np.asarray(v, dtype=float)
        line = self._h(self.v_touch) + self.line_slope * (v - self.v_touch)
        return np.where(v <= self.v_touch, self._h(v), line)

    def slope(self, v):
        v = np.asarray(v, dtype=float)
        return np.where(v <= self.v_touch, self._slope(v), self.line_slope)


def pose_chain_bound(problem, yield_target: float, start, *, k: float = 3.0):
    """The certified pose-chain bound (module docstring) of ``problem``'s grid and box.

    Parameters
    ----------
    problem : AllocationProblem
        Two-sided, every pose of the grid: its machine, poses, cost and box.
    yield_target : float
    start : ndarray (n_errors,)
        A starting allocation (the row relaxation's optimum).
    k : float
        Coverage factor of a tolerance.

    Returns
    -------
    ChainBound or None
        None for a machine with an item correlation, or when ``start`` meets every pose's
        chain (the row bound is then as tight).
    """
    machine = problem.machine
    if machine.correlation is not None:
        return None
    relaxation = _Relaxation(problem, yield_target, k)
    s = np.square(np.asarray(start, dtype=float)) / relaxation.scale
    for _ in range(ROUNDS):
        if not relaxation.add_violated(s):
            break
        s = relaxation.solve(s)
    if not relaxation.chains:
        return None
    return ChainBound(bound=relaxation.certified(s), tolerances=np.sqrt(s * relaxation.scale),
                      poses=np.array(sorted({p for p, _ in relaxation.chain_poses})),
                      rows=len(relaxation.rows))


class _Relaxation:
    """The rows and pose chains held so far, in ``s = t²`` scaled by the reference's."""

    def __init__(self, problem, yield_target, k):
        self.problem = problem
        machine = problem.machine
        self.scale = np.square(np.asarray(problem.reference, dtype=float))
        self.lower = np.square(np.asarray(problem.lower)) / self.scale
        self.upper = np.square(np.asarray(problem.upper)) / self.scale
        self.weights = np.asarray(problem.cost.weights) / self.scale
        unit = error_sigma(np.sqrt(self.scale), k, machine.distribution)
        self.unit_variance = np.square(unit) / np.square(machine.limits)[:, None]  # (6, n)
        self.v_max = float(required_index(yield_target, "two_sided")) ** -2
        self.log_y = float(np.log(yield_target))
        self.h = ChainLog(self.v_max)
        self.rows, self.chains, self.chain_poses = [], [], set()

    # ----- what the grid says at s ------------------------------------------------
    def _coefficients(self, poses):
        """Variance terms ``J_oi² σ_i² / I_o²`` per unit ``s`` at ``poses`` ``(P, 6, n)``
        and the chain's support (terms above :data:`ZERO`² of the row's largest)."""
        coefficient = np.square(self.problem.machine.jacobian(poses)) * self.unit_variance
        return coefficient, coefficient > ZERO ** 2 * coefficient.max(axis=2, keepdims=True)

    def _scan(self, s):
        """Per pose of the grid: the rows' loads ``v_r/v_max`` ``(P, 6)`` and the greedy
        chain's ``Σ h`` ``(P,)``, in chunks of poses."""
        poses = self.problem.poses
        loads, chain_logs = np.empty((len(poses), 6)), np.empty(len(poses))
        for part in chunks(len(poses), 3 * jacobian_bytes(self.problem.machine)):
            coefficient, support = self._coefficients(poses[part])
            loads[part] = coefficient @ s / self.v_max
            chain_logs[part] = _greedy_chain(coefficient, support, s, self.h)[0]
        return loads, chain_logs

    def add_violated(self, s) -> bool:
        """Add the most violated rows and chains at ``s``; whether any was."""
        loads, chain_logs = self._scan(s)
        flat = loads.ravel()
        rows = np.argsort(-flat, kind="stable")[:ROWS_PER_ROUND]
        rows = rows[flat[rows] > 1.0 + 1e-9]
        poses = np.argsort(chain_logs, kind="stable")[:POSES_PER_ROUND]
        poses = poses[chain_logs[poses] < self.log_y - 1e-9]
        added = len(rows)
        if len(rows):
            coefficient, _ = self._coefficients(self.problem.poses[rows // 6])
            self.rows.extend(coefficient[np.arange(len(rows)), rows % 6] / self.v_max)
        if len(poses):
            coefficient, support = self._coefficients(self.problem.poses[poses])
            _, fresh, orders = _greedy_chain(coefficient, support, s, self.h)
            for pose, chain, order in zip(poses, fresh, orders):
                if (int(pose), tuple(order)) not in self.chain_poses:
                    self.chain_poses.add((int(pose), tuple(order)))
                    self.chains.append(chain)
                    added += 1
        return added > 0

    # ----- the convex problem ------------------------------------------------------
    def _constraints(self, s):
        """Values ``g ≥ 0`` and gradients of every held constraint at ``s``."""
        values, gradients = [], []
        if self.rows:
            rows = np.array(self.rows)
            values.append(1.0 - rows @ s)
            gradients.append(-rows)
        if self.chains:
            chains = np.array(self.chains)  # (C, 6, n)
            v = chains @ s
            values.append(self.h(v).sum(axis=1) - self.log_y)
            gradients.append(np.einsum("ck,ckn->cn", self.h.slope(v), chains))
        return np.concatenate(values), np.concatenate(gradients)

    def solve(self, s):
        """The relaxation's optimum from ``s`` (SLSQP in ``log s``)."""
        unit = self.weights.sum()  # the reference's cost: SLSQP works on a cost near 1

        def cost(x):
            value = np.exp(-x) * self.weights / unit
            return value.sum(), -value

        def constraint(x):
            return self._constraints(np.exp(x))[0]

        def jacobian(x):
            return self._constraints(np.exp(x))[1] * np.exp(x)

        found = minimize(cost, np.log(s), jac=True, method="SLSQP",
                         bounds=list(zip(np.log(self.lower), np.log(self.upper))),
                         constraints=[{"type": "ineq", "fun": constraint, "jac": jacobian}],
                         options={"maxiter": 500, "ftol": 1e-12})
        return np.clip(np.exp(found.x), self.lower, self.upper)

    def certified(self, s) -> float:
        """Weak duality at ``s``: multipliers from the KKT conditions (non-negative least
        squares on the items inside the box), the Lagrangian minimised over the box from
        ``s``, and its linear lower bound there."""
        values, gradients = self._constraints(s)
        cost_gradient = -self.weights / np.square(s)
        free = (s > self.lower * (1 + 1e-6)) & (s < self.upper * (1 - 1e-6))
        near = values <= 1e-6 * np.maximum(1.0, np.abs(values).max())
        multipliers = np.zeros(len(values))
        if near.any() and free.any():
            multipliers[near] = nnls(gradients[near][:, free].T, cost_gradient[free])[0]

        def lagrangian(x):
            value, gradient = self._constraints(x)
            return (float(np.sum(self.weights / x) - multipliers @ value),
                    -self.weights / np.square(x) - multipliers @ gradient)

        found = minimize(lagrangian, s, jac=True, method="L-BFGS-B",
                         bounds=list(zip(self.lower, self.upper)),
                         options={"maxiter": 2000, "ftol": 1e-15, "gtol": 1e-14})
        point = np.clip(found.x, self.lower, self.upper)
        value, gradient = lagrangian(point)
        corner = np.where(gradient > 0, self.lower, self.upper)
        return value + float(gradient @ (corner - point))


def _greedy_chain(coefficient, support, s, h):
    """Per pose of ``coefficient (P, 6, n)``: the six rows ordered greedily (each step the
    row whose fresh errors leave the least probability), ``Σ_k h(v_k)`` and the fresh
    coefficients ``(P, 6, n)`` in that order."""
    count = coefficient.shape[0]
    used = np.zeros((count, coefficient.shape[2]), dtype=bool)
    left = np.ones((count, 6), dtype=bool)
    total = np.zeros(count)
    fresh_rows = np.zeros_like(coefficient)
    orders = np.zeros((count, 6), dtype=int)
    every = np.arange(count)
    for step in range(6):
        fresh = coefficient * (support & ~used[:, None, :])
        logs = np.where(left, h(fresh @ s), np.inf)
        chosen = np.argmin(logs, axis=1)
        total += logs[every, chosen]
        fresh_rows[:, step] = fresh[every, chosen]
        orders[:, step] = chosen
        used |= support[every, chosen]
        left[every, chosen] = False
    return total, fresh_rows, orders
