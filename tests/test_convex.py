"""Tests of the certified convex allocation solver."""

import numpy as np
import pytest
from scipy.optimize import Bounds, LinearConstraint, minimize

from allocation.solvers import convex
from allocation.solvers.convex import (
    ConvexSolution,
    InfeasibleAllocationError,
    solve_convex_allocation,
)


def random_problem(rng, m, n=66):
    """A feasible problem scaled like the paper's: u of lengths ~1e-5, of angles ~1e-10.

    Each row loads the initial allocation ``u0`` to between 0.6 and 1.6; the box is
    t in [0.5, 1.5] t0, i.e. u in [0.25, 2.25] u0, so ``G lo <= 0.4``.
    """
    t0 = np.where(rng.random(n) < 0.45, 3e-3, 1.45e-5)
    u0 = t0**2
    w = rng.uniform(1.0, 8.0, n)
    support = rng.random((m, n)) < 0.6
    support[np.arange(m), rng.integers(n, size=m)] = True  # no empty row
    G = rng.random((m, n)) * support / u0
    G *= (rng.uniform(0.6, 1.6, m) / (G @ u0))[:, None]
    return w, G, 0.25 * u0, 2.25 * u0


def dual_maximum(w, G, lo, hi):
    """max_{lam >= 0} g(lam) by L-BFGS-B: an independent route to the optimal cost."""
    scale = np.sum(w / hi)

    def negative_dual(mu):
        lam = scale * mu
        c = G.T @ lam
        with np.errstate(divide="ignore"):
            u = np.clip(np.sqrt(w / c), lo, hi)
        value = np.sum(w / u + c * u) - lam.sum()
        return -value / scale, -(G @ u - 1.0)

    result = minimize(
        negative_dual, np.ones(G.shape[0]), jac=True, method="L-BFGS-B",
        bounds=[(0.0, None)] * G.shape[0],
        options={"ftol": 1e-15, "gtol": 1e-13, "maxiter": 20000, "maxcor": 50},
    )
    return -result.fun * scale


def assert_certified(solution, G, lo, hi, gap=1e-6):
    assert isinstance(solution, ConvexSolution)
    assert solution.success, solution.message
    assert -1e-12 <= solution.relative_gap <= gap
    assert solution.dual_bound <= solution.fun * (1 + 1e-12)
    assert np.all(solution.multipliers >= 0)
    assert np.all(G @ solution.u <= 1.0 + 1e-12)
    assert np.all((solution.u >= lo) & (solution.u <= hi))
    np.testing.assert_allclose(solution.t, np.sqrt(solution.u))
    assert solution.kkt.primal_feasibility <= 1e-12
    assert solution.kkt.stationarity <= 1e-5
    assert solution.kkt.complementary_slackness <= 1e-6


def test_single_constraint_matches_the_lagrange_closed_form():
    # min sum c_i / t_i^2 s.t. sum (a_i t_i / 3)^2 <= L^2 with no active bound:
    # t_i proportional to (c_i / a_i^2)^(1/4), scaled so the constraint is active.
    c = np.array([1.98, 6.0, 1.83, 4.2, 1.3, 1.7])
    a = np.array([1.0, 250.0, 0.5, 400.0, 1.0, 120.0])
    limit = 0.02
    g = a**2 / 9 / limit**2
    sol = solve_convex_allocation(c, g[None, :], 1e-16, 1.0)
    shape = (c / a**2) ** 0.25
    t_expected = shape * limit * 3 / np.sqrt(np.sum((a * shape) ** 2))
    # the cost is flat at the optimum, so SLSQP pins u only to ~1e-7 (cost to ~1e-15)
    np.testing.assert_allclose(sol.t, t_expected, rtol=1e-6)
    f_star = np.sum(np.sqrt(c * g)) ** 2
    assert sol.fun == pytest.approx(f_star, rel=1e-12)
    assert sol.multipliers[0] == pytest.approx(f_star, rel=1e-6)  # lam = f for one row
    np.testing.assert_array_equal(sol.active, [0])
    assert sol.at_lower.size == 0 and sol.at_upper.size == 0
    assert_certified(sol, g[None, :], 1e-16, 1.0, gap=1e-10)


@pytest.mark.parametrize("seed, m", [(0, 20), (1, 35), (2, 50), (3, 60)])
def test_random_problems_are_certified_and_match_the_dual(seed, m):
    w, G, lo, hi = random_problem(np.random.default_rng(seed), m)
    sol = solve_convex_allocation(w, G, lo, hi)
    assert_certified(sol, G, lo, hi)
    # independent computation: maximise the dual by L-BFGS-B over lam >= 0
    assert dual_maximum(w, G, lo, hi) == pytest.approx(sol.fun, rel=1e-6)
    # at least one constraint binds, so the solution is not the trivial u = hi
    assert sol.active.size > 0


def test_agrees_with_trust_constr_in_scaled_variables():
    w, G, lo, hi = random_problem(np.random.default_rng(10), 30, n=20)
    sol = solve_convex_allocation(w, G, lo, hi)
    u0 = np.sqrt(lo * hi)  # scale u = u0 y so that y = O(1)
    cost0 = np.sum(w / u0)
    other = minimize(
        lambda y: np.sum(w / (u0 * y)) / cost0,
        np.full(w.size, 1.0),
        jac=lambda y: -w / (u0 * y**2) / cost0,
        hess=lambda y: np.diag(2 * w / (u0 * y**3)) / cost0,
        method="trust-constr",
        constraints=[LinearConstraint(G * u0, -np.inf, 1.0)],
        bounds=Bounds(lo / u0, hi / u0),
        options={"gtol": 1e-12, "xtol": 1e-14, "maxiter": 5000},
    )
    assert other.fun * cost0 == pytest.approx(sol.fun, rel=1e-6)
    np.testing.assert_allclose(u0 * other.x, sol.u, rtol=1e-3)


def test_two_variables_against_brute_force_grid():
    w = np.array([1.0, 3.0])
    G = np.array([[1.0, 0.5], [0.25, 1.5]])
    lo, hi = np.array([0.05, 0.05]), np.array([0.9, 0.5])
    sol = solve_convex_allocation(w, G, lo, hi)
    u1, u2 = np.meshgrid(np.linspace(lo[0], hi[0], 3001), np.linspace(lo[1], hi[1], 3001))
    feasible = (G[0, 0] * u1 + G[0, 1] * u2 <= 1) & (G[1, 0] * u1 + G[1, 1] * u2 <= 1)
    cost = np.where(feasible, w[0] / u1 + w[1] / u2, np.inf)
    best = np.unravel_index(np.argmin(cost), cost.shape)
    # the grid minimum can only be above the true one, by O(grid step)
    assert sol.fun <= cost[best]
    assert cost[best] - sol.fun < 1e-3 * sol.fun
    np.testing.assert_allclose(sol.u, [u1[best], u2[best]], atol=2e-3)
    assert_certified(sol, G, lo, hi)


def test_locked_items_keep_their_value():
    rng = np.random.default_rng(4)
    w, G, lo, hi = random_problem(rng, 25, n=12)
    locked = [0, 5, 7]
    lo[locked] = hi[locked] = 1.2 * lo[locked]
    sol = solve_convex_allocation(w, G, lo, hi)
    np.testing.assert_array_equal(sol.u[locked], lo[locked])
    np.testing.assert_array_equal(sol.locked, locked)
    assert not set(locked) & (set(sol.at_lower) | set(sol.at_upper))
    assert_certified(sol, G, lo, hi)
    assert (sol.to_frame().loc[locked, "status"] == "locked").all()


def test_lower_bounds_bind_with_the_right_sign():
    # item 0 is cheap to tighten but pushed hard by the constraint: it sits at its bound
    w = np.array([0.01, 1.0, 1.0])
    G = np.array([[10.0, 1.0, 1.0]])
    sol = solve_convex_allocation(w, G, [0.05, 0.01, 0.01], [1.0, 1.0, 1.0])
    np.testing.assert_array_equal(sol.at_lower, [0])
    assert sol.to_frame().loc[0, "status"] == "lower"
    # at the lower bound the constraint price exceeds the marginal cost saving
    assert (G.T @ sol.multipliers)[0] >= w[0] / sol.u[0] ** 2
    assert_certified(sol, G, np.array([0.05, 0.01, 0.01]), 1.0)


def test_no_binding_constraint_gives_the_upper_bounds():
    G = np.array([[0.1, 0.2], [0.0, 0.0]])
    sol = solve_convex_allocation([1.0, 2.0], G, 0.1, [2.0, 3.0])
    np.testing.assert_array_equal(sol.u, [2.0, 3.0])
    np.testing.assert_array_equal(sol.multipliers, [0.0, 0.0])
    np.testing.assert_array_equal(sol.at_upper, [0, 1])
    assert sol.duality_gap == pytest.approx(0.0, abs=1e-15)
    assert sol.success and sol.active.size == 0


def test_constraint_generation_over_many_rows(monkeypatch):
    # 2000 rows and 5 free items: 10 rows per round, so several rounds are needed
    w, G, lo, hi = random_problem(np.random.default_rng(5), 2000, n=5)
    solves = []
    original = convex._maximise_dual

    def counting_solve(w_, G_, *args):
        solves.append(G_.shape[0])
        return original(w_, G_, *args)

    monkeypatch.setattr(convex, "_maximise_dual", counting_solve)
    sol = solve_convex_allocation(w, G, lo, hi)
    assert len(solves) > 1 and solves[-1] < 2000
    assert "dual" in sol.message
    assert_certified(sol, G, lo, hi)  # the certificate covers all 2000 rows
    assert dual_maximum(w, G, lo, hi) == pytest.approx(sol.fun, rel=1e-6)


def test_primal_fallback_when_the_dual_is_not_certified(monkeypatch):
    # A dual answer that cannot be certified (lam = 0 gives the weak bound sum w/hi)
    # must hand over to the primal SLSQP path, which then certifies on its own.
    w, G, lo, hi = random_problem(np.random.default_rng(6), 60)
    monkeypatch.setattr(convex, "_solve_dual",
                        lambda w_, G_, lo_, hi_, *rest: (lo_.copy(), np.zeros(G_.shape[0]), "x"))
    sol = solve_convex_allocation(w, G, lo, hi)
    assert sol.message.startswith("SLSQP")
    assert_certified(sol, G, lo, hi)


def test_infeasible_rows_are_reported():
    G = np.array([[0.1, 0.1], [5.0, 1.0], [0.2, 0.2], [1.0, 6.0]])
    with pytest.raises(
        InfeasibleAllocationError, match=r"row\(s\) 1 \(load 1\.2\), 3 \(load 1\.4\)"
    ) as info:
        solve_convex_allocation([1.0, 1.0], G, 0.2, 1.0)
    assert info.value.rows == (1, 3)
    np.testing.assert_allclose(info.value.loads, [1.2, 1.4])
    assert isinstance(info.value, ValueError)


@pytest.mark.parametrize(
    "changes, match",
    [
        (dict(weights=[1.0, 0.0]), r"weights\[1\] = 0.0 must be finite and > 0"),
        (dict(weights=[[1.0, 1.0]]), r"weights must be a non-empty 1-D vector"),
        (dict(constraints=[[1.0, -1.0]]),
         r"constraints\[0, 1\] = -1.0 must be finite and >= 0"),
        (dict(constraints=[[1.0, np.nan]]), r"constraints\[0, 1\] = nan"),
        (dict(constraints=[1.0, 1.0]),
         r"constraints must have shape \(m, 2\) to match weights, got \(2,\)"),
        (dict(constraints=[[1.0, 1.0, 1.0]]), r"got \(1, 3\)"),
        (dict(lower=[0.1, 0.0]), r"lower\[1\] = 0.0 must be > 0"),
        (dict(lower=[0.1, 0.1, 0.1]),
         r"lower must be a scalar or have shape \(2,\), got \(3,\)"),
        (dict(upper=[1.0, np.inf]), r"upper\[1\] = inf must be finite"),
        (dict(upper=[1.0, 0.05]), r"lower\[1\] = 0.1 exceeds upper\[1\] = 0.05"),
    ],
)
def test_refusals(changes, match):
    kwargs = dict(weights=[1.0, 1.0], constraints=[[1.0, 1.0]], lower=0.1, upper=1.0)
    kwargs.update(changes)
    with pytest.raises(ValueError, match=match):
        solve_convex_allocation(**kwargs)
