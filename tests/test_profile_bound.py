"""allocation.machine_yield.profile_bound: the log-concave bound under the ``independent`` and
``gp`` profiles, against closed forms, an independent integral and repetition; and why an
item correlation stays refused."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from scipy.optimize import brentq, minimize, minimize_scalar
from scipy.stats import norm

from allocation import allocate_for_yield
from allocation.machine_yield.profile_bound import BlockRows, yield_and_gradient
from allocation.machine_yield.yield_dual import (log_concave_bound, tangent_bound,
                                                 tangent_step)
from allocation.per_pose.problem import AllocationProblem
from reliability.basics.errors import InputError
from reliability.model.poses import workspace_grid
from reliability.sampling.machine_yield import YieldModel

Z = 4.0  # standard errors allowed for an estimate against its exact value


# ----- independent: one row per error and grid point, a product over them ---------------
C, W = np.array([0.5, 0.8, 0.3]), np.array([1.0, 2.0, 0.5])
SIZES = np.array([3, 2, 1])  # grid points of each error (1: an assembly error)
LOWER, UPPER = np.full(3, 0.05), np.full(3, 2.0)


def product_rows(c=C, sizes=SIZES) -> BlockRows:
    """Each error drawn afresh at each of its points, one row per draw: the pass set is a
    box and the yield ``Π_i (2Φ(a_i) − 1)^{P_i}``, ``a_i = 1/(c_i t_i)``."""
    owner = np.repeat(np.arange(len(c)), sizes)
    return BlockRows(rows=np.diag(c[owner]), owner=owner)


def product_yield(t, c=C, sizes=SIZES):
    """The yield and ``∂Y/∂log t_i = −Y P_i 2 a_i φ(a_i) / (2Φ(a_i) − 1)``."""
    a = 1.0 / (c * t)
    single = 2.0 * norm.cdf(a) - 1.0
    value = float(np.prod(single ** sizes))
    return value, -value * sizes * 2.0 * a * norm.pdf(a) / single


def product_optimum(target):
    """The cheapest ``t`` in the box with yield ``target``: for a multiplier ``μ`` each
    ``u_i`` minimises ``w_i e^{−2u_i} − μ P_i log(2Φ(1/(c_i e^{u_i})) − 1)`` alone, and
    ``μ`` is the root at which the yield is the target."""
    def allocation(log_mu):
        return np.array([np.exp(minimize_scalar(
            lambda u, i=i: W[i] * np.exp(-2 * u) - np.exp(log_mu) * SIZES[i] * np.log(
                2 * norm.cdf(1 / (C[i] * np.exp(u))) - 1),
            bounds=(np.log(LOWER[i]), np.log(UPPER[i])), method="bounded",
            options={"xatol": 1e-12}).x) for i in range(3)])
    log_mu = brentq(lambda m: np.log(product_yield(allocation(m))[0]) - np.log(target),
                    -20.0, 20.0, xtol=1e-13)
    t = allocation(log_mu)
    return t, float(np.sum(W / t**2))


def test_gradient_of_the_independent_product_matches_the_closed_form():
    t = np.array([0.4, 0.5, 1.2])
    rows = product_rows()
    draws = np.random.default_rng(3).standard_normal((200_000, len(rows.owner)))
    passes, gradient, error = yield_and_gradient(rows, t, draws)
    exact, exact_gradient = product_yield(t)
    assert abs(passes / len(draws) - exact) <= Z * np.sqrt(exact * (1 - exact) / len(draws))
    assert np.all(np.abs(gradient - exact_gradient) <= Z * error)
    assert np.all(error < 0.05 * np.abs(exact_gradient))  # low variance, not only unbiased


# ----- gp: two poses along one axis, a bivariate normal -----------------------------------
RHO = 0.7  # the profile's correlation of the error between the two poses


def gp_rows(c0=0.6, c1=0.4) -> BlockRows:
    """Error 0 drawn at two points correlated ``ρ`` (its factor ``L``), one row per pose;
    error 1 an assembly error with a row of its own and a share in the second pose's row."""
    factor = np.linalg.cholesky([[1.0, RHO], [RHO, 1.0]])
    rows = np.array([[c0 * factor[0, 0], c0 * factor[0, 1], 0.0],
                     [c0 * factor[1, 0], c0 * factor[1, 1], 0.3],
                     [0.0, 0.0, c1]])
    return BlockRows(rows=rows, owner=np.array([0, 0, 1]))


def gp_yield(t, c0=0.6, c1=0.4):
    """``P(|c0 t0 x1| ≤ 1, |c0 t0 x2 + 0.3 t1 y| ≤ 1, |c1 t1 y| ≤ 1)`` with ``(x1, x2)``
    bivariate normal of correlation ρ and ``y`` standard normal: over ``y`` and ``x1``
    (Gauss–Legendre, 160 nodes each on their finite intervals: smooth integrands), the
    normal interval of ``x2`` given ``x1`` (independent of the estimator)."""
    nodes, weights = np.polynomial.legendre.leggauss(160)
    spread, x_edge, y_edge = np.sqrt(1 - RHO**2), 1 / (c0 * t[0]), 1 / (c1 * t[1])
    y, x1 = y_edge * nodes[:, None], x_edge * nodes[None, :]
    shift = 0.3 * t[1] * y / (c0 * t[0]) + RHO * x1
    inner = norm.cdf((x_edge - shift) / spread) - norm.cdf((-x_edge - shift) / spread)
    density = norm.pdf(y) * norm.pdf(x1) * weights[:, None] * weights[None, :]
    return float(np.sum(inner * density) * x_edge * y_edge)


def test_gradient_of_a_gp_pair_matches_finite_differences_of_its_integral():
    t = np.array([0.8, 1.1])
    rows = gp_rows()
    draws = np.random.default_rng(5).standard_normal((200_000, 3))
    passes, gradient, error = yield_and_gradient(rows, t, draws)
    step = 1e-4
    exact = [(gp_yield(t * np.exp(step * e)) - gp_yield(t * np.exp(-step * e))) / (2 * step)
             for e in np.eye(2)]
    assert np.all(np.abs(gradient - exact) <= Z * error)
    assert np.all(error < 0.05 * np.abs(exact))
    value = gp_yield(t)
    assert abs(passes / len(draws) - value) <= Z * np.sqrt(value * (1 - value) / len(draws))


def test_the_gp_yield_is_log_concave_along_lines_in_the_log_tolerances():
    """The midpoint test on the closed form along random lines in ``u = log t``:
    ``log Y(middle) ≥ (log Y(a) + log Y(b))/2`` (to the quadrature's 1e-9)."""
    rng = np.random.default_rng(8)
    for _ in range(12):
        a, b = rng.uniform(-1.5, 1.0, size=(2, 2))
        ends = np.log(gp_yield(np.exp(a))) + np.log(gp_yield(np.exp(b)))
        assert np.log(gp_yield(np.exp(0.5 * (a + b)))) >= 0.5 * ends - 1e-12


def correlated_slab(t, rho=-0.9):
    """Two errors of correlation ``ρ`` and one row through their sum: ``Y = 2Φ(1/σ) − 1``,
    ``σ² = t_1² + t_2² + 2ρ t_1 t_2``."""
    sigma = np.sqrt(t[0]**2 + t[1]**2 + 2 * rho * t[0] * t[1])
    return 2 * norm.cdf(1 / sigma) - 1


def test_an_item_correlation_can_break_log_concavity():
    """Why an item correlation stays refused: along ``u_2 = 0`` the yield of a negatively
    correlated pair is not log-concave in ``u_1`` (the midpoint test fails by far more
    than rounding)."""
    def log_yield(u1):
        return np.log(correlated_slab(np.exp([u1, 0.0])))
    a, b = -3.0, -0.5
    assert log_yield(0.5 * (a + b)) < 0.5 * (log_yield(a) + log_yield(b)) - 1e-3


# ----- the bound: tight at the optimum, and at its confidence by repetition --------------
def test_exact_tangent_bound_of_the_product_is_tight_at_the_optimum_and_below_elsewhere():
    optimum, cost = product_optimum(0.95)
    for factor, tight in ((1.0, True), (0.8, False), (np.array([1.2, 0.9, 1.0]), False)):
        point = optimum * factor
        value, gradient = product_yield(point)
        machines = 10**12
        bound = tangent_bound(W, LOWER, UPPER, point, round(value * machines), gradient,
                              np.zeros(3), machines, 0.95, robust=False)[0]
        assert bound == pytest.approx(cost, rel=1e-5) if tight else bound < cost


def repeated_bounds(rows, point, box, seed, repeats=40, machines=4000):
    """The 95 % bound at ``point`` on ``repeats`` independent samples of ``machines``."""
    rng = np.random.default_rng(seed)
    weights, lower, upper = box
    return np.array([tangent_bound(weights, lower, upper, point,
                                   *yield_and_gradient(rows, point, rng.standard_normal(
                                       (machines, rows.shape[1]))), machines, 0.95)[0]
                     for _ in range(repeats)])


def test_sampled_bound_of_the_product_holds_at_its_confidence_by_repetition():
    """40 independent samples of 4 000 machines at a point 10 % off the optimum: the 95 %
    bound exceeds the optimal cost no more often than 2 + 3 binomial standard errors of
    40 × 5 % allow, and its median is within 10 % of the optimum."""
    optimum, cost = product_optimum(0.95)
    point = optimum * 1.1
    bounds = repeated_bounds(product_rows(), point, (W, LOWER, UPPER), seed=11)
    assert np.sum(bounds > cost) <= 2 + 3 * np.sqrt(40 * 0.05 * 0.95)
    assert np.median(bounds) > 0.9 * cost


def test_a_tangent_step_on_blocks_lands_near_the_product_optimum():
    """From the optimum distorted by ±30 %, two steps on 20 000 machines end within 2 % of
    the optimal cost, at the target yield on a fresh sample."""
    optimum, cost = product_optimum(0.95)
    rows = product_rows()
    rng = np.random.default_rng(17)
    start = optimum * np.array([1.3, 0.7, 1.3])
    once = tangent_step(rows, W, LOWER, UPPER, start, rng.standard_normal((20_000, 6)), 0.95)
    twice = tangent_step(rows, W, LOWER, UPPER, once, rng.standard_normal((20_000, 6)), 0.95)
    assert np.sum(W / twice**2) == pytest.approx(cost, rel=0.02)
    value = product_yield(twice)[0]
    assert abs(value - 0.95) <= Z * np.sqrt(0.95 * 0.05 / 20_000)


W2, LOWER2, UPPER2 = np.array([1.0, 0.7]), np.full(2, 0.1), np.full(2, 3.0)


def gp_gradient(t, step=1e-5):
    """``∂Y/∂log t`` of :func:`gp_yield` by central differences."""
    return np.array([(gp_yield(t * np.exp(step * e)) - gp_yield(t * np.exp(-step * e)))
                     / (2 * step) for e in np.eye(2)])


def gp_optimum(target):
    """The cheapest ``t`` in the box with :func:`gp_yield` ≥ ``target``: a convex problem in
    ``log t`` (the yield is log-concave there), solved by SLSQP on the quadrature."""
    found = minimize(lambda u: float(np.sum(W2 * np.exp(-2 * u))), np.log([0.6, 0.6]),
                     method="SLSQP", bounds=list(zip(np.log(LOWER2), np.log(UPPER2))),
                     constraints=[{"type": "ineq", "fun": lambda u: np.log(
                         gp_yield(np.exp(u))) - np.log(target)}],
                     options={"ftol": 1e-14, "maxiter": 500})
    t = np.exp(found.x)
    return t, float(np.sum(W2 / t**2))


def test_sampled_bound_of_the_gp_pair_holds_at_its_confidence_by_repetition():
    """The gp pair: with the exact yield and gradient the tangent bound at the optimum is
    its cost (the optimum is right); 40 samples of 4 000 machines at a point 10 % off the
    optimum give a 95 % bound above the optimal cost no more often than 2 + 3 binomial
    standard errors of 40 × 5 % allow."""
    optimum, cost = gp_optimum(0.95)
    assert gp_yield(optimum) == pytest.approx(0.95, abs=1e-9)
    machines = 10**12
    exact = tangent_bound(W2, LOWER2, UPPER2, optimum, round(gp_yield(optimum) * machines),
                          gp_gradient(optimum), np.zeros(2), machines, 0.95, robust=False)[0]
    assert exact == pytest.approx(cost, rel=1e-4)
    point = optimum * 1.1
    bounds = repeated_bounds(gp_rows(), point, (W2, LOWER2, UPPER2), seed=13)
    assert np.sum(bounds > cost) <= 2 + 3 * np.sqrt(40 * 0.05 * 0.95)
    assert np.median(bounds) > 0.9 * cost


# ----- on a machine ----------------------------------------------------------------------
@pytest.mark.parametrize("profile", ["independent", "gp:300"])
def test_block_rows_are_the_engines_linearised_outputs(trunnion5, profile):
    """The rows times the coordinates of the model's own draws are the sums of the engine's
    first-order terms (``YieldModel.row_contributions``) at every (pose, output) asked."""
    model = YieldModel(trunnion5, profile=profile, distribution="normal", points=3)
    rows = BlockRows.of(model)
    u = model.draws(40, rng=1)
    t = np.asarray(trunnion5.initial_allocation, dtype=float)
    asked = np.random.default_rng(0).integers(0, 6 * model.experiment.n_poses, 40)
    expected = model.row_contributions(u, t, asked).sum(axis=1) \
        / np.asarray(trunnion5.limits)[asked % 6]
    jacobian = trunnion5.jacobian(model.experiment.poses).reshape(-1, len(t))
    kept = np.cumsum(np.abs(jacobian).sum(axis=1) > 0) - 1  # rows no error moves are left out
    got = (rows.standard(model, u) * rows.expanded(t)) @ rows.rows[kept[asked]].T
    np.testing.assert_allclose(np.diag(got), expected, rtol=1e-12, atol=1e-15)
    assert np.all(rows.sizes[:30] == 3) and np.all(rows.sizes[30:] == 1)


def result_of(machine, profile, distribution="normal"):
    """A yield allocation's fields that the bound reads, at the initial allocation in the
    default box."""
    problem = AllocationProblem.build(machine, workspace_grid(machine, 3))
    return SimpleNamespace(search_problem=problem, profile=profile,
                           distribution=distribution, points=3, yield_target=0.9,
                           tolerances=np.asarray(machine.initial_allocation, dtype=float))


@pytest.mark.parametrize("profile", ["independent", "gp:300"])
def test_log_concave_bound_under_a_profile_lies_below_the_point_it_is_taken_at(trunnion5,
                                                                               profile):
    """The bound after one step: below its estimate, below the cost of its point, whose
    yield on the bound's sample is the target's to sampling error."""
    bound = log_concave_bound(result_of(trunnion5, profile), machines=3000, steps=1, rng=2)
    assert bound.bound < bound.point_estimate < bound.point_cost
    assert abs(bound.point_yield - 0.9) <= Z * np.sqrt(2 * 0.09 / 3000)
    assert bound.rows == 6 * 3**5


def test_refused_for_the_truncated_reading_and_an_item_correlation(trunnion5):
    for distribution, correlation, words in (
            ("truncated", None, "'truncated', not 'normal'"),
            ("normal", np.eye(54), "item correlation .*different tolerances")):
        machine = SimpleNamespace(correlation=correlation)
        result = SimpleNamespace(distribution=distribution, profile="gp:300",
                                 search_problem=SimpleNamespace(machine=machine))
        with pytest.raises(InputError, match=words):
            log_concave_bound(result, machines=10)


def test_allocation_for_yield_takes_the_convex_step_under_independent(trunnion5):
    """The convex step runs under ``independent`` (its summary says so) and the result is
    the cheapest of the calibrated candidates."""
    result = allocate_for_yield(trunnion5, 0.9, profile="independent", points=3,
                                machines=300, rng=3, convex_steps=1, convex_machines=1000)
    assert result.convex_step_cost is not None
    assert result.cost == min(result.search_calibrated_cost, result.naive.cost,
                              result.convex_step_calibrated_cost)
    assert "convex steps: 1 step from the search's allocation" in result.summary()


def test_cli_prints_the_bound_under_gp(tmp_path, capsys):
    """``allocate --yield --profile gp:300 --bound-machines N`` runs to the bound (it was
    refused before the extension)."""
    from pathlib import Path

    from studies import cli
    machine = str(Path(__file__).parent / "machines" / "trunnion5.toml")
    assert cli.main(["allocate", machine, "--yield", "0.9", "--points", "3", "--machines",
                     "300", "--seed", "3", "--profile", "gp:300", "--bound-machines", "1000",
                     "--out", str(tmp_path / "a.csv")]) == 0
    assert "at 95% confidence" in capsys.readouterr().out
