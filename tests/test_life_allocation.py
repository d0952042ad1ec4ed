"""The life allocation (allocation.per_pose.life, precrel allocate --life): its roots against
an independent quadrature, T → 0 against the acceptance allocation, a one-error machine
solved by hand, Monte Carlo of the exact chain at the binding poses, the certificate's
bound against a dense search, and the refusals."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy import integrate, optimize, stats

import reliability
from allocation import AllocationProblem, read_allocation_csv
from allocation.per_pose.continuous import solve_continuous
from allocation.per_pose.life import LifeRequirement, RootCurve, life_loads, life_problem
from reliability.basics.errors import InputError
from reliability.life.first_passage import first_passage_within
from reliability.model.drift import Drift
from reliability.model.machine import OUTPUTS
from reliability.model.poses import workspace_grid
from studies import cli

MACHINES = Path(__file__).parent / "machines"
MILL_LIFE = str(MACHINES / "mill3_life.toml")
MILL = str(MACHINES / "mill3.toml")


def quadrature_within(s0, sd, limit=1.0) -> float:
    """P(|y0| < I and |y0 + d| < I) by adaptive quadrature over y0 (independent of the
    module's Gauss–Legendre rule)."""
    if sd == 0:
        return float(stats.norm.cdf(limit / s0) - stats.norm.cdf(-limit / s0))

    def integrand(u):  # y0 = s0·u, u standard normal
        y0 = s0 * u
        inside = stats.norm.cdf((limit - y0) / sd) - stats.norm.cdf((-limit - y0) / sd)
        return stats.norm.pdf(u) * inside
    span = min(limit / s0, 40.0)
    return integrate.quad(integrand, -span, span, epsabs=1e-15, epsrel=1e-13, limit=400,
                          points=[0.0])[0]


def quadrature_root(target, rho) -> float:
    """The largest (σ0/I)² with P ≥ target at drift σ ρ·I, by brentq on the quadrature."""
    z = stats.norm.ppf((1 + target) / 2)
    if rho == 0:  # no drift: P(|y0| < I) = R in closed form
        return 1 / z ** 2
    root = optimize.brentq(lambda s: quadrature_within(s, rho) - target, 1e-4, 1 / z,
                           xtol=1e-15, rtol=1e-14)
    return root ** 2


@pytest.fixture(scope="module")
def mill_life():
    return reliability.load_machine(MILL_LIFE)


@pytest.fixture(scope="module")
def grid_problem(mill_life):
    return AllocationProblem.build(mill_life, workspace_grid(mill_life, 3))


# ----- the roots --------------------------------------------------------------------------
def test_the_first_passage_decreases_in_both_spreads_where_the_roots_are_taken():
    s0 = np.linspace(0.02, 0.45, 60)
    for rho in (0.0, 0.1, 0.25, 0.38):
        values = first_passage_within(1.0, s0, rho)
        assert np.all(np.diff(values) <= 1e-13)
    sd = np.linspace(0.0, 0.39, 60)
    for sigma0 in (0.1, 0.2, 0.35):
        values = first_passage_within(1.0, sigma0, sd)
        assert np.all(np.diff(values) <= 1e-13)


@pytest.mark.parametrize("target", [0.99, 0.95])
def test_the_root_curve_matches_an_independent_quadrature(target):
    curve = RootCurve.of(target)
    rng = np.random.default_rng(11)
    rho = np.concatenate([[0.0], rng.uniform(0, curve.rho_max * 0.97, 7)])
    expected = np.array([quadrature_root(target, r) for r in rho])
    assert np.allclose(curve.allowed(rho), expected, rtol=1e-8, atol=0)
    z = stats.norm.ppf((1 + target) / 2)
    assert curve.allowed(0.0) == pytest.approx(1 / z ** 2, rel=1e-10)
    assert curve.allowed(curve.rho_max * 1.01) == 0.0


def test_the_support_line_lies_below_the_quadrature_roots():
    curve = RootCurve.of(0.99)
    high = 0.6 * curve.rho_max
    rng = np.random.default_rng(5)
    for w_star in (0.0, 0.2 * high ** 2, 0.9 * high ** 2):
        b, c = curve.support_line(w_star, high)
        rho = np.concatenate([[0.0, high], rng.uniform(0, high, 6)])
        exact = np.array([quadrature_root(0.99, r) for r in rho])
        assert np.all(b - c * rho ** 2 <= exact * (1 + 1e-9))
    # tight where the curve is convex: at w_star the line is within 1e-4 of the curve
    w_star = (0.3 * curve.rho_max) ** 2
    b, c = curve.support_line(w_star, high)
    assert b - c * w_star == pytest.approx(float(curve.allowed(np.sqrt(w_star))), rel=1e-4)


# ----- the allocation on the grid -----------------------------------------------------------
def test_a_vanishing_life_gives_the_acceptance_allocation(grid_problem):
    acceptance = grid_problem.solve_exact()
    short = life_problem(grid_problem, 1e-9, bound_drift=False).solve_exact()
    assert np.allclose(short.tolerances, acceptance.tolerances, rtol=1e-6)
    assert short.cost == pytest.approx(acceptance.cost, rel=1e-6)


def test_one_free_error_is_the_root_by_hand(mill_life):
    """All errors locked but Y.dx: its largest tolerance is the smallest over the rows of
    3·√((A − Σ_others J² σ²)/J²), A from the quadrature root at the row's drift."""
    poses = workspace_grid(mill_life, 2)
    free = mill_life.error_index("Y.dx")
    locked = [name for name in mill_life.error_names if name != "Y.dx"]
    reference = mill_life.initial_allocation * 0.3
    problem = AllocationProblem.build(mill_life, poses, locked=locked, bounds=(0.05, 50.0),
                                      reference=reference)
    years = 4.0
    result = life_problem(problem, years, bound_drift=False).solve_exact()
    jacobian = mill_life.jacobian(poses)
    sigma = reference / 3
    drift_sd = mill_life.drift.rate * years
    largest = np.inf
    for p in range(len(poses)):
        for o in range(6):
            if abs(jacobian[p, o, free]) < 1e-12:
                continue
            limit, target = mill_life.limits[o], mill_life.targets[o]
            s_d = np.sqrt(np.sum(jacobian[p, o] ** 2 * drift_sd ** 2))
            allowed = limit ** 2 * quadrature_root(target, s_d / limit)
            others = np.sum(np.delete(jacobian[p, o] ** 2 * sigma ** 2, free))
            largest = min(largest, 3 * np.sqrt((allowed - others)) / abs(jacobian[p, o, free]))
    assert result.tolerances[free] == pytest.approx(min(largest, problem.upper[free]),
                                                    rel=1e-6)


# ----- over the continuous workspace --------------------------------------------------------
@pytest.fixture(scope="module")
def certified(grid_problem):
    return solve_continuous(life_problem(grid_problem, 5.0), rtol=1e-3)


def test_the_life_allocation_is_certified_and_costs_more_than_acceptance(certified,
                                                                          grid_problem):
    acceptance = solve_continuous(grid_problem, rtol=1e-3)
    assert certified.certified, certified.reason
    assert certified.cost > acceptance.cost
    assert certified.scaled is None
    assert np.all(life_loads(certified.result.problem, certified.tolerances)
                  <= 1 + 1e-6)


def test_the_certificate_holds_on_a_dense_search(certified, mill_life):
    """At 4000 random poses and the corners, the first passage with the limits widened by
    rtol (what the certificate claims) reaches every target (quadrature of the module,
    itself checked against the bivariate normal)."""
    rng = np.random.default_rng(3)
    low = np.array([a.stroke[0] for a in mill_life.axis_specs])
    high = np.array([a.stroke[1] for a in mill_life.axis_specs])
    poses = np.vstack([low + (high - low) * rng.random((4000, 3)),
                       workspace_grid(mill_life, 2)])
    jacobian = mill_life.jacobian(poses)
    sigma0 = np.sqrt(np.square(jacobian) @ np.square(certified.tolerances / 3))
    drift = np.sqrt(np.square(jacobian) @ np.square(mill_life.drift.rate * 5.0))
    within = first_passage_within(mill_life.limits * (1 + certified.rtol), sigma0, drift)
    assert np.all(within >= mill_life.targets - 1e-10)


def test_monte_carlo_of_the_exact_chain_at_the_binding_poses(certified, mill_life):
    """Built machines with the allocation's tolerances (normal, σ = t/3) and drawn rates;
    the share that keeps the output within ±I at 21 ages of [0, 5] years reaches the
    target within z = 3 standard errors; the acceptance allocation falls short by more
    than z = 3."""
    table = certified.certificate
    rng = np.random.default_rng(2024)
    n = 40000
    ages = np.linspace(0.0, 5.0, 21)
    acceptance = solve_continuous(AllocationProblem.build(
        mill_life, workspace_grid(mill_life, 3)), rtol=1e-3).tolerances
    shares = {}
    for name in ("dx", "dy"):
        o = OUTPUTS.index(name)
        pose = table.loc[name, list(mill_life.axes)].to_numpy(dtype=float)
        for label, t in (("life", certified.tolerances), ("acceptance", acceptance)):
            e0 = rng.normal(size=(n, mill_life.n_errors)) * t / 3
            rate = rng.normal(size=(n, mill_life.n_errors)) * mill_life.drift.rate
            inside = np.ones(n, dtype=bool)
            for age in ages:
                y = mill_life.comprehensive_error(pose, e0 + rate * age)[:, o]
                inside &= np.abs(y) < mill_life.limits[o]
            shares[name, label] = inside.mean()
        target = mill_life.targets[o]
        se = np.sqrt(target * (1 - target) / n)
        assert shares[name, "life"] >= target - 3 * se, shares
    assert min(shares["dx", "acceptance"], shares["dy", "acceptance"]) < \
        mill_life.targets[0] - 3 * np.sqrt(0.99 * 0.01 / n), shares


# ----- refusals and the command ---------------------------------------------------------------
def test_the_requirement_refuses_bad_input_by_name(mill_life):
    plain = reliability.load_machine(MILL)
    with pytest.raises(InputError, match=r"no \[drift\] table"):
        LifeRequirement.of(plain, 5)
    wear = dataclasses.replace(mill_life, drift=Drift(
        "wear", mill_life.drift.rate, mill_life.drift.rate))
    with pytest.raises(InputError, match="kind 'wear' is refused"):
        LifeRequirement.of(wear, 5)
    with pytest.raises(InputError, match="must be > 0 years"):
        LifeRequirement.of(mill_life, 0)
    with pytest.raises(InputError, match="age must be a finite number"):
        LifeRequirement.of(mill_life, -1)
    one_sided = AllocationProblem.build(mill_life, workspace_grid(mill_life, 2),
                                        side="one_sided")
    with pytest.raises(InputError, match="two-sided"):
        life_problem(one_sided, 5)


def test_a_drift_that_alone_misses_the_target_is_refused_naming_the_pose(grid_problem):
    with pytest.raises(InputError, match=r"output \w+ at pose .*no tolerances meet it"):
        life_problem(grid_problem, 60.0)


def run(capsys, *argv):
    code = cli.main(list(argv))
    captured = capsys.readouterr()
    return code, captured.out, captured.err


@pytest.mark.parametrize("argv, words", [
    ([MILL, "--life", "5"], ["--life 5", "no [drift] table"]),
    ([MILL_LIFE, "--life", "5", "--yield", "0.9"], ["--life", "--yield"]),
    ([MILL_LIFE, "--life", "5", "--side", "one_sided"], ["--life", "one_sided"]),
    ([MILL_LIFE, "--life", "5", "--method", "gwo"], ["--life", "gwo"]),
    ([MILL_LIFE, "--life", "0"], ["--life", "> 0"]),
])
def test_the_command_refuses_before_any_work(tmp_path, capsys, argv, words):
    code, out, err = run(capsys, "allocate", argv[0], "--out", str(tmp_path / "a.csv"),
                         *argv[1:])
    assert code == 2
    for word in words:
        assert word in err
    assert not list(tmp_path.iterdir())


def test_the_command_writes_the_life_allocation_beside_the_acceptance_cost(tmp_path, capsys,
                                                                           mill_life):
    out = tmp_path / "a.csv"
    argv = ["allocate", MILL_LIFE, "--out", str(out), "--life", "5", "--points", "3"]
    code, text, err = run(capsys, *argv)
    assert code == 0, err
    assert "life_years 5" in text and "drift model: linear" in text
    assert "certified over the continuous workspace" in text
    assert "life: solve 1" in err and "acceptance: solve 1" in err
    summary = pd.read_csv(tmp_path / "a.life.csv")
    assert summary.loc[0, "life_years"] == 5
    assert summary.loc[0, "life_over_acceptance_cost"] > 1
    assert bool(summary.loc[0, "certified"])
    tolerances = read_allocation_csv(out, mill_life)
    assert pd.read_csv(out).columns.tolist() == ["error", "reference", "allocated"]
    problem = life_problem(AllocationProblem.build(mill_life, workspace_grid(mill_life, 3)),
                           5, bound_drift=False)
    assert np.all(life_loads(problem, tolerances) <= 1 + 1e-9)
    code, _, err = run(capsys, *argv)
    assert code == 2 and "--overwrite" in err


def test_the_certificate_of_one_output_is_its_row_of_all_six(mill_life):
    from reliability.first_order.workspace_search import certified_worst
    t = mill_life.initial_allocation
    full = certified_worst(mill_life, t, rtol=1e-3)
    one = certified_worst(mill_life, t, rtol=1e-3, outputs=["dy"])
    assert one.index.tolist() == ["dy"]
    columns = list(mill_life.axes) + ["sigma", "sigma_bound", "calls"]
    assert one.loc["dy", columns].tolist() == full.loc["dy", columns].tolist()
    with pytest.raises(InputError, match="outputs must name"):
        certified_worst(mill_life, t, outputs=["dq"])


def test_feasibility_of_a_life_problem_is_the_life_target(grid_problem):
    problem = life_problem(grid_problem, 5.0, bound_drift=False)
    result = problem.solve_exact()
    assert result.feasible
    acceptance = grid_problem.solve_exact().tolerances
    assert grid_problem.meets_targets(acceptance)
    assert not problem.meets_targets(acceptance)  # acceptance tolerances miss the life
    assert not problem.meets_targets(result.tolerances * 1.001)
