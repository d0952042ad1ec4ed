"""allocation.machine_yield.yield_dual: the conditional Monte Carlo gradient of the yield, and
the tangent bound, against closed forms, an independent integral and repetition."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from scipy import integrate
from scipy.optimize import brentq, minimize_scalar
from scipy.stats import norm

from allocation import allocate_for_yield
from allocation.machine_yield.yield_dual import (log_concave_bound, tangent_bound, tangent_step,
                                   yield_and_gradient)
from reliability.basics.errors import InputError

Z = 4.0  # standard errors allowed for an estimate against its exact value


def box_yield(c, t):
    """One row per error, ``|c_i t_i z_i| ≤ 1``: ``Y = Π (2Φ(a_i) − 1)`` with
    ``a_i = 1/(c_i t_i)``, and ``∂Y/∂log t_i = −Y · 2 a_i φ(a_i) / (2Φ(a_i) − 1)``."""
    a = 1.0 / (c * t)
    single = 2.0 * norm.cdf(a) - 1.0
    value = np.prod(single)
    return value, -value * 2.0 * a * norm.pdf(a) / single


def test_gradient_of_a_box_matches_the_closed_form():
    c, t = np.array([0.5, 0.8, 0.3]), np.array([0.4, 0.5, 1.2])
    draws = np.random.default_rng(3).standard_normal((200_000, 3))
    passes, gradient, error = yield_and_gradient(np.diag(c), t, draws)
    exact, exact_gradient = box_yield(c, t)
    share = passes / len(draws)
    assert abs(share - exact) <= Z * np.sqrt(exact * (1 - exact) / len(draws))
    assert np.all(np.abs(gradient - exact_gradient) <= Z * error)
    assert np.all(error < 0.05 * np.abs(exact_gradient))  # low variance, not only unbiased


def polygon_yield(rows, t):
    """Gaussian measure of ``{z ∈ R² : |rows · (t ∘ z)| ≤ 1}`` by quadrature over ``z_1``
    of the interval of ``z_2`` (an independent computation)."""
    def inner(z1):
        low, high = -np.inf, np.inf
        for a, b in rows * t:
            if b == 0:
                if abs(a * z1) > 1:
                    return 0.0
                continue
            ends = sorted(((-1 - a * z1) / b, (1 - a * z1) / b))
            low, high = max(low, ends[0]), min(high, ends[1])
        return max(norm.cdf(high) - norm.cdf(low), 0.0) * norm.pdf(z1)
    return integrate.quad(inner, -9, 9, limit=200, epsabs=1e-8, epsrel=1e-8)[0]


def test_gradient_of_a_polygon_matches_finite_differences_of_its_integral():
    rows = np.array([[1.0, 0.5], [0.3, -1.0], [0.8, 0.8]])
    t = np.array([0.45, 0.5])
    draws = np.random.default_rng(5).standard_normal((200_000, 2))
    passes, gradient, error = yield_and_gradient(rows, t, draws)
    step = 1e-3
    exact = [(polygon_yield(rows, t * np.exp(step * e)) -
              polygon_yield(rows, t * np.exp(-step * e))) / (2 * step) for e in np.eye(2)]
    assert np.all(np.abs(gradient - exact) <= Z * error)
    value = polygon_yield(rows, t)
    assert abs(passes / len(draws) - value) <= Z * np.sqrt(value * (1 - value) / len(draws))


def box_optimum(c, w, lower, upper, target):
    """The cheapest ``t`` in the box with ``Π (2Φ(1/(c_i t_i)) − 1) ≥ target``, from the
    Lagrange conditions of the convex problem in ``u = log t``: for a multiplier ``μ`` each
    ``u_i`` minimises ``w_i e^{−2u_i} − μ log(2Φ(1/(c_i e^{u_i})) − 1)`` alone (a 1-D
    convex problem), and ``μ`` is found by root finding so that the yield is the target."""
    def allocation(log_mu):
        return np.array([np.exp(minimize_scalar(
            lambda u, i=i: w[i] * np.exp(-2 * u) - np.exp(log_mu) * np.log(
                2 * norm.cdf(1 / (c[i] * np.exp(u))) - 1),
            bounds=(np.log(lower[i]), np.log(upper[i])), method="bounded",
            options={"xatol": 1e-12}).x) for i in range(len(c))])
    log_mu = brentq(lambda m: np.log(box_yield(c, allocation(m))[0]) - np.log(target),
                    -20.0, 20.0, xtol=1e-13)
    t = allocation(log_mu)
    return t, float(np.sum(w / t**2))


C, W = np.array([0.5, 0.8, 0.3]), np.array([1.0, 2.0, 0.5])
LOWER, UPPER = np.full(3, 0.05), np.full(3, 2.0)


def exact_bound(point, target, **options):
    """The bound at ``point`` with the exact yield and gradient (no sampling)."""
    value, gradient = box_yield(C, point)
    machines = 10**12
    return tangent_bound(W, LOWER, UPPER, point, round(value * machines), gradient,
                         np.zeros(3), machines, target, robust=False, **options)


def test_tangent_bound_is_below_the_optimum_and_tight_at_it():
    """With the exact yield and gradient: at the optimum the bound equals the optimal cost
    (the tangent touches the feasible set there); anywhere else it is below it."""
    optimum, cost = box_optimum(C, W, LOWER, UPPER, 0.95)
    assert exact_bound(optimum, 0.95)[0] == pytest.approx(cost, rel=1e-5)
    for factor in (0.7, 1.3, np.array([0.8, 1.2, 1.0])):
        assert exact_bound(optimum * factor, 0.95)[0] < cost
    # at the optimum, the tangent problem's minimiser is the optimum itself
    np.testing.assert_allclose(exact_bound(optimum, 0.95)[2], optimum, rtol=1e-3)


def test_sampled_bound_holds_at_its_confidence_by_repetition():
    """40 independent samples of 4 000 machines at a point 10 % off the optimum: the bound
    at 95 % exceeds the optimal cost at most 2 + 3 binomial standard errors times (it is
    conservative: Bonferroni over the gradient), and it is within 10 % of the optimum."""
    optimum, cost = box_optimum(C, W, LOWER, UPPER, 0.95)
    point = optimum * 1.1
    rng = np.random.default_rng(11)
    bounds = []
    for _ in range(40):
        estimates = yield_and_gradient(np.diag(C), point, rng.standard_normal((4000, 3)))
        bounds.append(tangent_bound(W, LOWER, UPPER, point, *estimates, 4000, 0.95)[0])
    bounds = np.array(bounds)
    assert np.sum(bounds > cost) <= 2 + 3 * np.sqrt(40 * 0.05 * 0.95)
    assert np.median(bounds) > 0.9 * cost


def test_refused_where_the_yield_is_not_log_concave_by_the_theorem():
    machine = SimpleNamespace(correlation=None)
    for distribution, profile, correlation, words in (
            ("truncated", "constant", None, "'truncated', not 'normal'"),
            ("truncated", "independent", None, "'truncated', not 'normal'"),
            ("normal", "constant", np.eye(6), "item correlation")):
        machine.correlation = correlation
        result = SimpleNamespace(distribution=distribution, profile=profile,
                                 search_problem=SimpleNamespace(machine=machine))
        with pytest.raises(InputError, match=words):
            log_concave_bound(result, machines=10)


def test_a_tangent_step_from_a_poor_shape_lands_near_the_optimum():
    """From the optimum distorted by ±30 % per error (rescaled to the yield: 74 % dearer),
    one step on 20 000 machines ends within 10 % of the optimal cost (the tangent's own
    optimum overshoots; the backtracking keeps a quarter of the way), a second within 2 %;
    the yield, on a fresh sample, is the target's to sampling error."""
    optimum, cost = box_optimum(C, W, LOWER, UPPER, 0.95)
    rng = np.random.default_rng(17)
    start = optimum * np.array([1.3, 0.7, 1.3])
    start = start / box_yield_scale(start, 0.95)
    once = tangent_step(np.diag(C), W, LOWER, UPPER, start,
                        rng.standard_normal((20_000, 3)), 0.95)
    assert np.sum(W / once**2) < 1.1 * cost < np.sum(W / start**2)
    stepped = tangent_step(np.diag(C), W, LOWER, UPPER, once,
                           rng.standard_normal((20_000, 3)), 0.95)
    assert np.sum(W / stepped**2) == pytest.approx(cost, rel=0.02)
    fresh = rng.standard_normal((20_000, 3))
    share = np.mean(np.all(np.abs(fresh * stepped * C) <= 1.0, axis=1))
    assert abs(share - 0.95) <= Z * np.sqrt(0.95 * 0.05 / 20_000) * np.sqrt(2)


def box_yield_scale(t, target):
    """The factor ``s`` with ``Y(t/s) = target`` for the box rows (bisection in log s)."""
    low, high = -5.0, 5.0
    for _ in range(100):
        middle = 0.5 * (low + high)
        low, high = (middle, high) if box_yield(C, t / np.exp(middle))[0] < target else \
            (low, middle)
    return np.exp(0.5 * (low + high))


@pytest.fixture(scope="module")
def stepped(trunnion5):
    """trunnion5 (3-point grid, 300 machines) with one convex step on 2 000 machines."""
    return allocate_for_yield(trunnion5, 0.9, profile="constant", points=3, machines=300,
                              rng=3, convex_steps=1, convex_machines=2000)


def test_allocation_for_yield_takes_the_convex_step_where_the_theorem_holds(stepped,
                                                                            trunnion5):
    """One convex step runs, is calibrated like the search's allocation, and the result is
    the cheapest of them; under the truncated reading it does not run and the summary says
    why."""
    assert stepped.convex_step_cost is not None
    assert stepped.cost == min(stepped.search_calibrated_cost, stepped.naive.cost,
                               stepped.convex_step_calibrated_cost)
    assert (stepped.method == "convex step") == \
        (stepped.cost == stepped.convex_step_calibrated_cost)
    assert "convex steps: 1 step from the search's allocation" in stepped.summary()
    assert "2,000 rays of their own" in stepped.summary()
    truncated = allocate_for_yield(trunnion5, 0.9, profile="constant", points=3,
                                   machines=300, rng=3, convex_steps=1,
                                   distribution="truncated")
    assert truncated.convex_step_cost is None and truncated.method != "convex step"
    assert "convex steps: not run: the reading is 'truncated'" in truncated.summary()


def test_log_concave_bound_takes_seed_and_a_generator(stepped):
    """``seed=`` is the deprecated spelling of ``rng=`` (the same bound, with a warning);
    a Generator of the same seed gives the same samples (one spawn of it)."""
    with pytest.warns(DeprecationWarning, match="seed is deprecated; use rng"):
        old = log_concave_bound(stepped, machines=2000, steps=0, seed=2)
    new = log_concave_bound(stepped, machines=2000, steps=0, rng=2)
    drawn = log_concave_bound(stepped, machines=2000, steps=0, rng=np.random.default_rng(2))
    assert old.bound == new.bound == drawn.bound


def test_bound_of_an_allocation_for_yield_lies_below_its_cost(stepped):
    """The bound at the result itself (no step) is below the result's cost and its point is
    the result; a step moves it to a cheaper point at yield near Y on its sample."""
    at_start = log_concave_bound(stepped, machines=4000, steps=0, rng=1)
    np.testing.assert_array_equal(at_start.point, stepped.tolerances)
    assert at_start.bound < at_start.point_estimate < stepped.cost
    moved = log_concave_bound(stepped, machines=4000, steps=1, rng=1)
    assert moved.point_cost < stepped.cost
    assert abs(moved.point_yield - 0.9) <= Z * np.sqrt(0.09 / 4000)
    assert "at 95% confidence" in moved.text(stepped.initial_cost)


def test_cli_prints_the_bound_after_writing_the_allocation(tmp_path, capsys):
    """``allocate --yield --convex-steps 1 --bound-machines N``: the convex steps' line
    (``--verbose``), the bound and its gap, the files written; options refused where they
    cannot apply, before any work."""
    from pathlib import Path

    from studies import cli
    machine = str(Path(__file__).parent / "machines" / "trunnion5.toml")
    out = tmp_path / "a.csv"
    common = ["allocate", machine, "--yield", "0.9", "--points", "3", "--machines", "300",
              "--seed", "3", "--profile", "constant"]
    assert cli.main([*common, "--convex-steps", "1", "--convex-machines", "1000",
                     "--bound-machines", "1000", "--verbose", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "convex steps: 1 step from the search's allocation" in text
    assert text.index("at 95% confidence (log-concave bound") < text.index("gap") \
        < text.index("allocation written to")
    assert out.exists()
    for extra, words in ((["--distribution", "truncated", "--bound-machines", "10"],
                          "--bound-machines: the reading is 'truncated'"),
                         (["--convex-steps", "0", "--convex-machines", "10"],
                          "not with --convex-steps 0")):
        fresh = tmp_path / "refused"
        fresh.mkdir(exist_ok=True)
        assert cli.main([*common, *extra, "--out", str(fresh / "b.csv")]) == 2
        assert words in capsys.readouterr().err and not any(fresh.iterdir())
    assert cli.main(["allocate", machine, "--bound-machines", "10",
                     "--out", str(tmp_path / "c.csv")]) == 2
    assert "--bound-machines is used with --yield only" in capsys.readouterr().err


def test_rescaling_to_the_yield_bisects_when_lower_bounds_hold_items():
    """One row per error; the second tolerance sits at its lower bound, so the single
    homogeneous factor that puts the sample's quantile at 1 cannot lower it and misses the
    yield: the factor is bisected until the yield is reached (the second item stays at its
    bound), and when not even the lower bounds reach it, those are returned."""
    from allocation.machine_yield.yield_dual import _at_yield

    rows = np.diag([1.0, 1.0, 1.0])
    lower, upper = np.array([0.05, 0.45, 0.05]), np.full(3, 2.0)
    t = np.array([1.0, 0.45, 1.0])
    draws = np.random.default_rng(4).standard_normal((20_000, 3))
    single = np.clip(t / np.quantile(np.abs(draws * t).max(axis=1), 0.95), lower, upper)
    assert np.mean(np.all(np.abs(draws * single) <= 1, axis=1)) < 0.95  # the stall
    found = _at_yield(rows, t, draws, 0.95, lower, upper)
    assert np.mean(np.all(np.abs(draws * found) <= 1, axis=1)) >= 0.95
    assert found[1] == lower[1] and np.all(found >= lower) and np.all(found <= upper)
    assert np.all(found[[0, 2]] > lower[[0, 2]])
    unreachable = _at_yield(rows, t, draws, 0.95, np.full(3, 0.6), upper)
    np.testing.assert_array_equal(unreachable, np.full(3, 0.6))
