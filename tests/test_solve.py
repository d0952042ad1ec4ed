"""Tests of the problem-level solvers: the certified exact optimum and GWO.

The exact optimum is checked on its own terms (a dual bound recomputed here from the
reported multipliers, KKT signs, the meaning of a binding row) and against GWO, the
Lagrange closed form of a single constraint, locked items, bounds and infeasible targets.
The workspace-mean variant is checked for feasibility, for being no dearer than the
worst case, and for stationarity.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd
import pytest
from scipy.optimize import nnls
from scipy.stats import norm

from allocation import (AllocationProblem, AllocationResult, InfeasibleAllocationError,
                        TargetUnreachableError)
from reliability.first_order.fosm import fosm
from reliability.model.machine import OUTPUTS
from reliability.model.poses import workspace_grid

#: The convex solver certifies a relative duality gap of at most this (its default).
GAP = 1e-6
#: GWO costs are compared with the certified optimum allowing for rounding only.
ROUNDING = 1e-9
#: Reduced GWO settings for the tests; the paper's are 100 wolves × 500 iterations.
REDUCED = {"n_wolves": 40, "n_iterations": 150}


@pytest.fixture(scope="module")
def grid3(hobbing):
    return workspace_grid(hobbing, 3)


@pytest.fixture(scope="module")
def grid2(hobbing):
    return workspace_grid(hobbing, 2)


@pytest.fixture(scope="module")
def paper_problem(hobbing):
    """The paper's problem: 5^6 grid, one-sided Φ(β) ≥ 0.99, worst case."""
    return AllocationProblem.build(hobbing, side="one_sided")


@pytest.fixture(scope="module")
def paper_exact(paper_problem):
    return paper_problem.solve_exact()


@pytest.fixture(scope="module")
def small(hobbing, grid3):
    return {side: AllocationProblem.build(hobbing, grid3, side=side)
            for side in ("one_sided", "two_sided")}


@pytest.fixture(scope="module")
def small_exact(small):
    return {side: problem.solve_exact() for side, problem in small.items()}


@pytest.fixture(scope="module")
def exact_cases(paper_problem, paper_exact, small, small_exact):
    """(problem, exact result): the paper's grid one-sided, the 3-point grid both sides."""
    return [(paper_problem, paper_exact), (small["two_sided"], small_exact["two_sided"]),
            (small["one_sided"], small_exact["one_sided"])]


def output_index(frame):
    return np.array([OUTPUTS.index(o) for o in frame["output"]])


def active_rows(problem, active):
    """The unscreened rows ``G_r`` of an ``active`` frame, ``(n_active, n_errors)``."""
    return problem.row_matrix()[active["pose"].to_numpy(), output_index(active)]


# ----- the exact optimum -----------------------------------------------------------------
def test_exact_is_certified_feasible_and_meets_targets(exact_cases, hobbing):
    for problem, result in exact_cases:
        assert isinstance(result, AllocationResult) and result.method == "exact"
        cert = result.certificate
        assert cert["certified"]
        # primal and dual values agree to rounding at the optimum: a gap of -1e-16 is 0
        assert -1e-12 <= cert["relative_gap"] <= GAP
        assert cert["dual_bound"] <= result.cost * (1 + 1e-12)
        assert cert["primal_feasibility"] == 0
        assert result.feasible and problem.meets_targets(result.tolerances)
        assert problem.violation(result.tolerances) == 0
        worst = problem.probability(result.tolerances).min(axis=0)
        assert np.all(worst >= hobbing.targets * (1 - 1e-12))
        assert result.cost == pytest.approx(problem.cost.total(result.tolerances), rel=1e-15)
        assert np.all(result.tolerances >= problem.lower)
        assert np.all(result.tolerances <= problem.upper)
        # cheaper than the reference (which is feasible one-sided, so this is a must there)
        assert result.cost < problem.cost.total(problem.reference)


def test_exact_dual_bound_recomputed_from_the_reported_multipliers(exact_cases):
    # Weak duality with the multipliers of the active frame, computed independently:
    # g(λ) = Σ_i min_{lo ≤ u ≤ hi} (w_i/u + c_i u) − Σ λ,  c = Gᵀλ  ≤  optimum ≤ F(t).
    for problem, result in exact_cases:
        lam = result.active["multiplier"].to_numpy()
        assert np.all(lam >= 0) and lam.sum() > 0
        c = lam @ active_rows(problem, result.active)
        w, lo2, hi2 = problem.cost.weights, problem.lower ** 2, problem.upper ** 2
        with np.errstate(divide="ignore"):
            u = np.clip(np.sqrt(w / c), lo2, hi2)
        dual = np.sum(w / u + c * u) - lam.sum()
        assert dual <= result.cost * (1 + 1e-12)
        assert (result.cost - dual) / result.cost <= GAP
        assert dual == pytest.approx(result.certificate["dual_bound"], rel=1e-9)


def test_exact_kkt_signs_at_the_bounds(exact_cases):
    # d/du of Σ w/u is −w/u²; stationarity: Gᵀλ − w/u² = μ_lo − μ_hi with μ ≥ 0.
    for problem, result in exact_cases:
        frame = result.to_frame()
        u = result.tolerances ** 2
        lam = result.active["multiplier"].to_numpy()
        pull = lam @ active_rows(problem, result.active)
        push = problem.cost.weights / u
        scaled = pull * u / push  # 1 for free items
        status = frame["status"].to_numpy()
        np.testing.assert_allclose(scaled[status == "free"], 1.0, atol=1e-5)
        assert np.all(scaled[status == "lower"] >= 1 - 1e-5)
        assert np.all(scaled[status == "upper"] <= 1 + 1e-5)


def test_active_frame(exact_cases):
    for problem, result in exact_cases:
        active = result.active
        assert {"output", "pose", "multiplier", "elasticity",
                *problem.machine.axes} <= set(active.columns)
        np.testing.assert_array_equal(active[list(problem.machine.axes)].to_numpy(),
                                      problem.poses[active["pose"].to_numpy()])
        load = active_rows(problem, active) @ result.tolerances ** 2
        assert np.all(load >= 1 - 1e-7) and np.all(load <= 1)
        np.testing.assert_allclose(active["elasticity"], -2 * active["multiplier"] / result.cost,
                                   rtol=1e-12)
        # complementary slackness, relative to the cost as the duality gap is
        slack = active["multiplier"].to_numpy() * (1 - load) / result.cost
        assert active["multiplier"].gt(0).any() and np.all(slack <= GAP)


def test_requirements_bracket_the_per_output_totals(exact_cases):
    # the solver's multipliers are one optimal split: each output's total lies in the
    # range over all optimal multipliers, and equals it where that range is one number
    # (the face is imposed to 1e-6 of the cost, dual_face.SLACK_FLOOR)
    for problem, result in exact_cases:
        frame = result.requirements
        assert tuple(frame.index) == OUTPUTS
        grouped = result.active.groupby("output")["multiplier"]
        totals = grouped.sum().reindex(OUTPUTS, fill_value=0.0)
        slack = 1e-5 * result.cost
        assert np.all(frame["multiplier_min"] <= totals + slack)
        assert np.all(totals <= frame["multiplier_max"] + slack)
        determined = frame["multiplier"].notna()
        np.testing.assert_allclose(frame["multiplier"][determined], totals[determined],
                                   rtol=1e-5, atol=slack)
        np.testing.assert_array_equal(frame["binding_rows"],
                                      grouped.size().reindex(OUTPUTS, fill_value=0))
        np.testing.assert_allclose(frame["elasticity"][determined],
                                   -2 * frame["multiplier"][determined] / result.cost,
                                   rtol=1e-9)
        np.testing.assert_allclose(frame["elasticity_relax"],
                                   -2 * frame["multiplier_min"] / result.cost, rtol=1e-9)
        np.testing.assert_allclose(frame["elasticity_tighten"],
                                   -2 * frame["multiplier_max"] / result.cost, rtol=1e-9)


@pytest.mark.parametrize("side", ["one_sided", "two_sided"])
def test_a_binding_row_means_sigma_equals_the_allowed_sigma(small, small_exact, hobbing, side):
    # A row load is σ²/(I/z)², so a binding row (λ > 0, load 1) is σ = I/z. 1e-9 is what
    # an exactly binding row gives in double precision (observed 1e-16 with the primal
    # SLSQP path of convex.py); the dual L-BFGS-B path leaves binding rows at load
    # 1 − 2.4e-8, i.e. σ = (I/z)(1 − 1.3e-8), which this would catch.
    problem, result = small[side], small_exact[side]
    active = result.active[result.active["multiplier"] > 0]
    assert len(active) >= 3
    outputs = output_index(active)
    poses = active["pose"].to_numpy()
    sigma = problem.sigma(result.tolerances)[poses, outputs]
    np.testing.assert_allclose(sigma, problem.allowed_sigma[outputs], rtol=1e-9)
    # and the FOSM probability there is the target, from the reliability package
    probability = fosm(hobbing, result.tolerances, problem.poses[poses])
    p = getattr(probability, side)[np.arange(len(poses)), outputs]
    np.testing.assert_allclose(p, 0.99, atol=1e-9)
    z = norm.ppf(0.99) if side == "one_sided" else norm.ppf(0.995)
    np.testing.assert_allclose(probability.beta[np.arange(len(poses)), outputs], z,
                               rtol=1e-9)


def test_a_binding_row_on_the_paper_grid(paper_problem, paper_exact):
    # (σ to 1e-9 is asserted on the 3-point grid above; here the probabilities)
    active = paper_exact.active[paper_exact.active["multiplier"] > 0]
    outputs = output_index(active)
    sigma = paper_problem.sigma(paper_exact.tolerances)[active["pose"].to_numpy(), outputs]
    np.testing.assert_allclose(sigma, paper_problem.allowed_sigma[outputs], rtol=1e-7)
    # the worst one-sided probability of every binding output is exactly the target
    worst = paper_problem.probability(paper_exact.tolerances).min(axis=0)
    np.testing.assert_allclose(worst[np.unique(outputs)], 0.99, atol=1e-9)


def test_single_constraint_matches_the_lagrange_closed_form(hobbing):
    # One pose; only δx constrains (the other limits are 10^6 larger); a box of 10^±3
    # around Table 4 keeps every item free. min Σ c_i/t_i² s.t. Σ (a_i t_i/k)² ≤ (I/z)²
    # gives t_i ∝ (c_i / a_i²)^(1/4); items with a_i = 0 go to their upper bound.
    limits = hobbing.limits * np.r_[1.0, np.full(5, 1e6)]
    machine = dataclasses.replace(hobbing, limits=limits)
    pose = np.array([[0.7, 150.0, 300.0, 0.3, 80.0, 1.1]])
    problem = AllocationProblem.build(machine, pose, side="one_sided", bounds=(1e-3, 1e3))
    assert problem.rows.counts["dominance"] == 1
    result = problem.solve_exact()

    a = hobbing.jacobian(pose)[0, 0]
    c = problem.cost.weights
    sensitive = a != 0
    assert 40 < sensitive.sum() < 66
    budget = (3.0 * 0.02 / norm.ppf(0.99)) ** 2            # (k I / z)²
    shape = (c[sensitive] / a[sensitive] ** 2) ** 0.25
    kappa2 = budget / np.sum(a[sensitive] ** 2 * shape ** 2)
    expected = problem.upper.copy()
    expected[sensitive] = np.sqrt(kappa2) * shape
    assert np.all((expected[sensitive] > 2 * problem.lower[sensitive])
                  & (expected[sensitive] < problem.upper[sensitive] / 2))
    # the cost is flat at the optimum, so the solver pins t only to ~1e-7 (relative)
    np.testing.assert_allclose(result.tolerances, expected, rtol=1e-6)
    assert result.cost == pytest.approx(problem.cost.total(expected), rel=1e-10)
    ratio = result.tolerances[sensitive] / shape
    assert np.ptp(ratio) / ratio.mean() < 1e-6
    # one multiplier: λ = Σ_free c/u (sum of the stationarity equations weighted by u)
    assert len(result.active) == 1
    lam = np.sum(c[sensitive] / expected[sensitive] ** 2)
    assert result.active["multiplier"].iloc[0] == pytest.approx(lam, rel=1e-6)
    # F_free ∝ I⁻² (homogeneous of degree −1 in u): the elasticity is 2 × its share of F
    share = lam / result.cost
    assert result.active["elasticity"].iloc[0] == pytest.approx(-2 * share, rel=1e-6)
    status = result.to_frame()["status"]
    assert set(status[sensitive]) == {"free"} and set(status[~sensitive]) == {"upper"}


# ----- GWO against the exact optimum -----------------------------------------------------
def test_exact_beats_every_reduced_gwo_run(paper_problem, paper_exact):
    feasible = 0
    for seed in range(3):
        gwo = paper_problem.solve_gwo(rng=seed, **REDUCED)
        assert gwo.method == "gwo"
        assert gwo.feasible == paper_problem.meets_targets(gwo.tolerances)
        if gwo.feasible:
            feasible += 1
            assert paper_exact.cost <= gwo.cost * (1 + ROUNDING)
    assert feasible >= 1


@pytest.mark.parametrize("side", ["one_sided", "two_sided"])
def test_exact_beats_reduced_gwo_on_the_small_grid(small, small_exact, side):
    problem, exact = small[side], small_exact[side]
    costs = []
    for seed in range(3):
        gwo = problem.solve_gwo(rng=10 + seed, **REDUCED)
        if gwo.feasible:
            costs.append(gwo.cost)
    assert costs and exact.cost <= min(costs) * (1 + ROUNDING)


def test_exact_beats_gwo_with_the_papers_settings(small, small_exact):
    problem, exact = small["one_sided"], small_exact["one_sided"]
    gwo = problem.solve_gwo(n_wolves=100, n_iterations=500, rng=2023)
    assert gwo.feasible
    assert exact.cost <= gwo.cost * (1 + ROUNDING)
    assert gwo.certificate["evaluations"] == 100 * 501
    assert len(gwo.history) == 501


def test_gwo_seeded_with_the_reference_never_costs_more(paper_problem):
    # Table 4 is feasible one-sided; under Deb's rules the alpha can only improve on it.
    gwo = paper_problem.solve_gwo(rng=0, initial=paper_problem.reference, n_wolves=20,
                                  n_iterations=30)
    assert gwo.feasible
    assert gwo.cost <= paper_problem.cost.total(paper_problem.reference)


def test_gwo_history_and_violation(small):
    problem = small["two_sided"]
    gwo = problem.solve_gwo(rng=3, n_wolves=20, n_iterations=40)
    history = gwo.history
    assert list(history.columns) == ["cost", "violation", "feasible"]
    assert history.index.name == "iteration" and len(history) == 41
    feasible = history[history["feasible"]]
    assert np.all(np.diff(feasible["cost"].to_numpy()) <= 0)
    assert gwo.cost == pytest.approx(problem.cost.total(gwo.tolerances), rel=1e-15)
    assert gwo.certificate["violation"] == pytest.approx(problem.violation(gwo.tolerances))


def test_with_poses_solves_like_a_problem_built_on_all_poses(small, hobbing, grid3):
    extra = workspace_grid(hobbing, 4)[::97]
    grown = small["two_sided"].with_poses(extra).solve_exact()
    built = AllocationProblem.build(hobbing, np.vstack([grid3, extra]), side="two_sided")
    direct = built.solve_exact()
    assert grown.feasible and built.meets_targets(grown.tolerances)
    assert grown.cost == pytest.approx(direct.cost, rel=2 * GAP)


# ----- locked items, bounds --------------------------------------------------------------
LOCKED = ["X.dx", "A.ey", "C-X.ez", "Y-M.dy"]


@pytest.fixture(scope="module")
def locked_problem(hobbing, grid3):
    return AllocationProblem.build(hobbing, grid3, side="one_sided", locked=LOCKED,
                                   bounds=(0.6, 1.8))


@pytest.mark.parametrize("solver", ["exact", "gwo"])
def test_locked_items_stay_at_their_reference(locked_problem, hobbing, solver):
    problem = locked_problem
    result = problem.solve_exact() if solver == "exact" else problem.solve_gwo(rng=1, **REDUCED)
    index = [hobbing.error_index(name) for name in LOCKED]
    assert result.tolerances[index].tolist() == problem.reference[index].tolist()
    assert np.all(result.tolerances >= problem.lower)
    assert np.all(result.tolerances <= problem.upper)
    frame = result.to_frame()
    assert (frame.loc[LOCKED, "status"] == "locked").all()
    assert (frame.drop(index=LOCKED)["status"] != "locked").all()
    np.testing.assert_array_equal(frame.loc[LOCKED, "rate"], 0.0)
    if solver == "exact":
        assert result.feasible and result.certificate["certified"]


def test_locking_never_makes_the_optimum_cheaper(hobbing, grid3, locked_problem):
    free = AllocationProblem.build(hobbing, grid3, side="one_sided", bounds=(0.6, 1.8))
    assert free.solve_exact().cost <= locked_problem.solve_exact().cost * (1 + ROUNDING)


def test_wider_box_never_costs_more(small, small_exact, hobbing, grid3):
    wide = AllocationProblem.build(hobbing, grid3, side="two_sided", bounds=(0.4, 2.0))
    assert wide.solve_exact().cost <= small_exact["two_sided"].cost * (1 + ROUNDING)


# ----- infeasible targets ----------------------------------------------------------------
@pytest.fixture(scope="module")
def blocked(hobbing, grid3):
    """δx limit 0.004 mm: unreachable at many poses even with every item at 0.5 × Table 4."""
    limits = hobbing.limits.copy()
    limits[0] = 0.004
    machine = dataclasses.replace(hobbing, limits=limits)
    problem = AllocationProblem.build(machine, grid3, side="one_sided")
    with pytest.raises(TargetUnreachableError) as info:
        problem.solve_exact()
    return problem, info.value


def test_unreachable_target_names_the_output_and_the_pose(blocked, hobbing):
    problem, error = blocked
    assert isinstance(error, InfeasibleAllocationError) and isinstance(error, ValueError)
    message = str(error)
    assert "dx" in message
    first = error.blocking.iloc[0]
    for axis in hobbing.axis_specs:  # rotary positions in degrees, every position with its unit
        shown, unit = (np.degrees(first[axis.name]), "deg") if axis.kind == "rotary" else \
            (first[axis.name], "mm")
        assert f"{axis.name}={shown:.6g} {unit}" in message
    assert f"pose {int(first['pose'])}" not in message  # named by positions, not by row
    assert ".blocking" not in message  # refusals name no Python attribute


def test_blocking_frame_lists_truly_blocked_rows(blocked):
    problem, error = blocked
    frame = error.blocking
    assert isinstance(frame, pd.DataFrame) and len(frame) > 0
    assert {"output", "pose", "allowed_sigma", "sigma_at_lower"} <= set(frame.columns)
    outputs = output_index(frame)
    poses = frame["pose"].to_numpy()
    sigma = problem.sigma(problem.lower)[poses, outputs]
    np.testing.assert_allclose(frame["sigma_at_lower"], sigma, rtol=1e-12)
    np.testing.assert_allclose(frame["allowed_sigma"], problem.allowed_sigma[outputs],
                               rtol=1e-15)
    assert np.all(frame["sigma_at_lower"] > frame["allowed_sigma"])
    # exactly the outputs that are blocked somewhere, found without the screening
    truly = problem.sigma(problem.lower) > problem.allowed_sigma
    assert set(frame["output"]) == {OUTPUTS[o] for o in np.flatnonzero(truly.any(axis=0))}


def test_blocking_frame_counts_every_blocked_pose_worst_first(blocked):
    # The message says "N constraint(s) blocked in all" and names the first row of
    # .blocking; the docstring promises "the (output, pose) rows that no allocation inside
    # the bounds can satisfy". Today the frame lists only the screened (undominated,
    # deduplicated) rows, in screening order, so N undercounts and the pose named in the
    # message need not be the worst one.
    problem, error = blocked
    ratio = problem.sigma(problem.lower) / problem.allowed_sigma
    truly = ratio > 1
    listed = set(zip(error.blocking["output"], error.blocking["pose"]))
    every = {(OUTPUTS[o], p) for p, o in zip(*np.nonzero(truly))}
    assert listed <= every
    first = error.blocking.iloc[0]
    first_ratio = first["sigma_at_lower"] / first["allowed_sigma"]
    problems = []
    if len(listed) != len(every):
        problems.append(f"{len(every)} (output, pose) constraints are unreachable, "
                        f".blocking lists {len(listed)}")
    if first_ratio < ratio.max() * (1 - 1e-12):
        problems.append(f"the message names a pose at σ/σ_allowed = {first_ratio:.4g}, the "
                        f"worst is {ratio.max():.4g}")
    assert not problems, "; ".join(problems)


def test_gwo_on_an_unreachable_target_reports_infeasible(blocked):
    problem, _ = blocked
    gwo = problem.solve_gwo(rng=0, n_wolves=10, n_iterations=5)
    assert not gwo.feasible and gwo.certificate["violation"] > 0


# ----- workspace-mean variant --------------------------------------------------------------
def mean_probability_gradient(problem, u):
    """``∂/∂u_i`` of the mean over poses of P_o, ``(6, n)``, written out independently:
    σ² = Σ_i (J_oi/k)² u_i, β = I/σ, dP/dβ = φ(β) (one-sided) or 2φ(β) (two-sided),
    dβ/du_i = −β (J_oi/k)² / (2σ²)."""
    a = np.square(problem.jacobian / problem.k)
    sigma2 = a @ u
    beta = problem.machine.limits / np.sqrt(sigma2)
    density = norm.pdf(beta) * (2.0 if problem.side == "two_sided" else 1.0)
    return np.einsum("po,pon->on", -density * beta / (2 * sigma2), a) / len(problem.poses)


def mean_kkt(problem, result):
    """Relative stationarity over the free items and the bound-sign violations, with
    multipliers of the active mean constraints fitted by NNLS (min F s.t. mean P ≥ R)."""
    t = result.tolerances
    u = t ** 2
    slack = problem.probability(t).mean(axis=0) - problem.machine.targets
    active = np.flatnonzero(slack <= 1e-7)
    pull = -mean_probability_gradient(problem, u)[active]      # ≥ 0: P falls as u grows
    scaled = pull * u ** 2 / problem.cost.weights               # 1 = balance for free items
    status = result.to_frame()["status"].to_numpy()
    free = status == "free"
    lam = nnls(scaled[:, free].T, np.ones(free.sum()))[0] if len(active) else np.zeros(0)
    balance = lam @ scaled
    return {"active": active, "multipliers": lam,
            "stationarity": float(np.max(np.abs(balance[free] - 1), initial=0.0)),
            "lower": float(np.max(1 - balance[status == "lower"], initial=0.0)),
            "upper": float(np.max(balance[status == "upper"] - 1, initial=0.0))}


@pytest.fixture(scope="module", params=["one_sided", "two_sided"])
def mean_case(request, hobbing, grid2):
    side = request.param
    problem = AllocationProblem.build(hobbing, grid2, side=side, workspace="mean")
    worst = AllocationProblem.build(hobbing, grid2, side=side)
    return problem, problem.solve_exact(), worst.solve_exact()


def test_mean_gradient_of_the_test_matches_finite_differences(mean_case):
    problem = mean_case[0]
    u = problem.reference ** 2
    grad = mean_probability_gradient(problem, u)
    for i in (0, 9, 44):  # C.dx, X.ex, X-Z.dz
        step = 1e-5 * u[i]
        up, down = u.copy(), u.copy()
        up[i] += step
        down[i] -= step
        diff = (problem.probability(np.sqrt(up)).mean(axis=0)
                - problem.probability(np.sqrt(down)).mean(axis=0)) / (2 * step)
        np.testing.assert_allclose(diff, grad[:, i], rtol=1e-5, atol=1e-9 * np.abs(grad).max())


def test_mean_optimum_is_feasible_and_no_dearer_than_the_worst_case(mean_case, hobbing):
    problem, mean, worst = mean_case
    assert mean.feasible
    shortfall = hobbing.targets - problem.probability(mean.tolerances).mean(axis=0)
    assert np.all(shortfall <= 1e-9)
    assert np.all(mean.tolerances >= problem.lower) and np.all(mean.tolerances <= problem.upper)
    # the worst-case optimum is feasible for the weaker mean constraint
    assert problem.meets_targets(worst.tolerances)
    assert mean.cost <= worst.cost * (1 + ROUNDING)
    assert mean.cost < 0.95 * worst.cost  # and the mean reading is clearly weaker here
    assert mean.certificate["primal_feasibility"] <= 1e-9


def test_mean_optimum_is_stationary(mean_case):
    # Observed with the cutting-plane solver: stationarity ≈ 1e-6 or better. (The earlier
    # SLSQP solver left it at 1.0: translational items stayed inside their box with no
    # active constraint involving them.)
    problem, mean, _ = mean_case
    kkt = mean_kkt(problem, mean)
    assert len(kkt["active"]) >= 1
    assert kkt["stationarity"] <= 1e-4, kkt
    assert kkt["lower"] <= 1e-4 and kkt["upper"] <= 1e-4, kkt


def test_mean_dual_bound_is_below_the_cost(mean_case):
    _, mean, _ = mean_case
    cert = mean.certificate
    if "dual_bound" in cert:
        assert cert["dual_bound"] <= mean.cost * (1 + 1e-12)


def test_mean_reading_is_solved_when_only_the_worst_case_is_unreachable(hobbing, grid2):
    # δx limit at twice the largest δx σ the lower bounds allow: Φ(2) = 0.977 < 0.99 at
    # the worst pose, so the worst-case problem is infeasible, but the mean of Φ over the
    # 64 poses at the lower bounds is 0.995 ≥ 0.99: the mean problem is feasible
    # (t = lower meets it), and solve_exact must not declare it unreachable.
    base = AllocationProblem.build(hobbing, grid2, side="one_sided", workspace="mean")
    limits = hobbing.limits.copy()
    limits[0] = 2.0 * base.sigma(base.lower)[:, 0].max()
    machine = dataclasses.replace(hobbing, limits=limits)
    problem = AllocationProblem.build(machine, grid2, side="one_sided", workspace="mean")
    assert problem.meets_targets(problem.lower)
    with pytest.raises(TargetUnreachableError):
        AllocationProblem.build(machine, grid2, side="one_sided").solve_exact()
    result = problem.solve_exact()
    assert result.feasible
    assert result.cost <= problem.cost.total(problem.lower)


def test_mean_reading_unreachable_names_the_output(hobbing, grid2):
    # δx limit so small that even the lower bounds miss the mean target
    base = AllocationProblem.build(hobbing, grid2, side="two_sided", workspace="mean")
    limits = hobbing.limits.copy()
    limits[0] = 1.0 * base.sigma(base.lower)[:, 0].min()
    machine = dataclasses.replace(hobbing, limits=limits)
    problem = AllocationProblem.build(machine, grid2, side="two_sided", workspace="mean")
    assert not problem.meets_targets(problem.lower)
    with pytest.raises(TargetUnreachableError, match="dx"):
        problem.solve_exact()


# ----- results ---------------------------------------------------------------------------------
def test_gwo_is_deterministic(small):
    problem = small["one_sided"]
    first = problem.solve_gwo(rng=7, n_wolves=20, n_iterations=50)
    again = problem.solve_gwo(rng=np.random.default_rng(7), n_wolves=20, n_iterations=50)
    other = problem.solve_gwo(rng=8, n_wolves=20, n_iterations=50)
    np.testing.assert_array_equal(first.tolerances, again.tolerances)
    assert first.cost == again.cost
    pd.testing.assert_frame_equal(first.history, again.history)
    assert not np.array_equal(first.tolerances, other.tolerances)


def test_exact_is_deterministic(small, small_exact):
    again = small["two_sided"].solve_exact()
    np.testing.assert_array_equal(again.tolerances, small_exact["two_sided"].tolerances)


@pytest.mark.parametrize("which", ["exact", "gwo"])
def test_to_frame_statuses_agree_with_the_bounds(paper_problem, paper_exact, which):
    result = paper_exact if which == "exact" else paper_problem.solve_gwo(rng=4, **REDUCED)
    frame = result.to_frame()
    assert list(frame.columns) == ["reference", "allocated", "rate", "status"]
    assert tuple(frame.index) == paper_problem.names and frame.index.name == "error"
    np.testing.assert_array_equal(frame["allocated"], result.tolerances)
    np.testing.assert_allclose(frame["rate"], result.tolerances / paper_problem.reference - 1,
                               rtol=1e-12, atol=1e-15)
    status = frame["status"].to_numpy()
    assert set(status) <= {"free", "lower", "upper", "locked"}
    t, lo, hi, ref = result.tolerances, paper_problem.lower, paper_problem.upper, \
        paper_problem.reference
    near = 1e-6 * ref
    np.testing.assert_array_less(np.abs(t - lo)[status == "lower"], near[status == "lower"]
                                 * (1 + 1e-12))
    np.testing.assert_array_less(np.abs(t - hi)[status == "upper"], near[status == "upper"]
                                 * (1 + 1e-12))
    inner = status == "free"
    assert np.all((t[inner] > lo[inner] + near[inner]) & (t[inner] < hi[inner] - near[inner]))
    assert not (status == "locked").any()
    if which == "exact":  # the exact optimum leans on both kinds of bound here
        assert {"free", "lower", "upper"} <= set(status)


@pytest.mark.parametrize("which", ["exact", "gwo"])
def test_breakdown_sums_to_the_cost(small, small_exact, which):
    problem = small["two_sided"]
    result = small_exact["two_sided"] if which == "exact" else problem.solve_gwo(
        rng=5, n_wolves=10, n_iterations=10)
    breakdown = result.breakdown()
    assert tuple(breakdown.index) == problem.names
    assert breakdown["cost"].sum() == pytest.approx(result.cost, rel=1e-12)
    assert breakdown["share"].sum() == pytest.approx(1.0, rel=1e-12)
    np.testing.assert_array_equal(breakdown["tolerance"], result.tolerances)
