"""Numbers the problem does not determine are reported in a form it does determine.

Where constraint rows of the allocation problem have equal or linearly dependent gradients
at the optimum, the split of their Lagrange multipliers is free; each output's summed
multiplier is then reported as its range over all optimal multipliers (docs/non-unique.md).
Expected values here come from closed forms worked out by hand, not from the code.
"""

from dataclasses import fields, replace

import numpy as np
import pytest

from allocation.per_pose.elasticity import UNIQUE_WIDTH, requirement_table, requirement_text
from allocation.per_pose.problem import AllocationProblem, ScreenedRows
from allocation.solvers.convex import solve_convex_allocation
from allocation.solvers.dual_face import dual_face

RTOL = 1e-5  # the dual face is imposed to 1e-6 (dual_face.SLACK_FLOOR)


def face_of(w, G, lo, hi):
    solution = solve_convex_allocation(w, G, lo, hi)
    return solution, dual_face(w, G, solution.u, lo, hi, solution.active)


def test_two_identical_rows_closed_form():
    # min w/u s.t. a u <= 1 (twice): u* = 1/a, w/u*² = a (λ1 + λ2), so λ1 + λ2 = w a = F;
    # each λ alone can be anything in [0, w a]
    w, a = np.array([3.0]), 2.0
    G = np.array([[a], [a]])
    solution, face = face_of(w, G, 0.01, 100.0)
    assert solution.fun == pytest.approx(w[0] * a, rel=1e-12)
    for members in ([True, False], [False, True]):
        low, high = face.sum_range(members)
        assert low == pytest.approx(0.0, abs=RTOL * w[0] * a)
        assert high == pytest.approx(w[0] * a, rel=RTOL)
    low, high = face.sum_range([True, True])
    assert low == pytest.approx(w[0] * a, rel=RTOL)
    assert high == pytest.approx(w[0] * a, rel=RTOL)


def test_dependent_rows_closed_form():
    # rows (0.6, 0.4), (0.4, 0.6) and their mean (0.5, 0.5), all binding at u* = (1, 1)
    # with w = (1, 1): λ1 = λ2 = 1 − λ3/2, λ3 in [0, 2]; Σλ = 2 = F whatever the split
    w = np.ones(2)
    G = np.array([[0.6, 0.4], [0.4, 0.6], [0.5, 0.5]])
    solution, face = face_of(w, G, 0.01, 100.0)
    np.testing.assert_allclose(solution.u, [1.0, 1.0], rtol=1e-7)
    low, high = face.sum_range([True, True, False])
    assert (low, high) == pytest.approx((0.0, 2.0), abs=2 * RTOL)
    low, high = face.sum_range([False, False, True])
    assert (low, high) == pytest.approx((0.0, 2.0), abs=2 * RTOL)
    assert face.sum_range([True, True, True]) == pytest.approx((2.0, 2.0), rel=RTOL)


@pytest.mark.parametrize("order", [(0, 1, 2), (2, 0, 1), (1, 2, 0)])
def test_ranges_do_not_depend_on_the_row_order(order):
    w = np.ones(2)
    G = np.array([[0.6, 0.4], [0.4, 0.6], [0.5, 0.5]])
    base = face_of(w, G, 0.01, 100.0)[1]
    permuted = face_of(w, G[list(order)], 0.01, 100.0)[1]
    for members in ([True, True, False], [False, False, True], [True, False, True]):
        moved = np.asarray(members)[list(order)]  # row j of G[order] is row order[j] of G
        assert permuted.sum_range(moved) == pytest.approx(base.sum_range(members), abs=2 * RTOL)


def test_a_tiny_perturbation_flips_the_solver_but_not_the_range():
    # three identical rows a u <= 1 (one variable): λ1 + λ2 + λ3 = w a, any split. Row 0
    # (group A) 1e-13 lighter or heavier changes which rows the solver loads, so the
    # solver's A total jumps; the ranges do not: A and B = rows 1, 2 each in [0, w a],
    # together w a
    w, a = np.array([3.0]), 2.0
    G = np.full((3, 1), a)
    group_a = np.array([True, False, False])
    totals, ranges = [], []
    for factor in (1 - 1e-13, 1 + 1e-13):
        perturbed = G * np.array([[factor], [1.0], [1.0]])
        solution, face = face_of(w, perturbed, 0.01, 100.0)
        totals.append(solution.multipliers[group_a].sum())
        ranges.append([face.sum_range(group_a), face.sum_range(~group_a),
                       face.sum_range(np.ones(3, dtype=bool))])
    assert abs(totals[0] - totals[1]) > 0.1 * w[0] * a  # the solver's split flipped
    np.testing.assert_allclose(ranges[0], ranges[1], rtol=RTOL, atol=RTOL * w[0] * a)
    expected = [(0.0, w[0] * a), (0.0, w[0] * a), (w[0] * a, w[0] * a)]
    np.testing.assert_allclose(ranges[0], expected, rtol=RTOL, atol=RTOL * w[0] * a)


def test_a_row_on_items_at_their_lower_bound_cannot_be_tightened():
    # row 0 loads only item 0, which it holds within 1e-9 of its lower bound: tightening
    # it by more than that is infeasible at any cost, so its largest multiplier is inf;
    # relaxing it frees u0, at the rate w0/u0² / G00 = 1 (its smallest multiplier)
    w = np.array([1.0, 1.0])
    G = np.array([[1.0 - 1e-9, 0.0], [0.0, 0.5]])
    _, face = face_of(w, G, np.array([1.0, 0.01]), np.array([10.0, 100.0]))
    low, high = face.sum_range([True, False])
    assert low == pytest.approx(1.0, rel=1e-5) and high == np.inf


# ----- the case study ------------------------------------------------------------------
@pytest.fixture(scope="module")
def hobbing_problem(hobbing):
    return AllocationProblem.build(hobbing, side="one_sided")


def _permuted(problem, order):
    rows = problem.rows
    return replace(problem, rows=ScreenedRows(matrix=rows.matrix[order], pose=rows.pose[order],
                                              output=rows.output[order], counts=rows.counts))


def test_case_study_table_does_not_depend_on_the_row_order(hobbing_problem):
    """The hobbing machine's ex and ez bind at equal rows (the grid poses with A = 0):
    their sums are not determined, their ranges and joint elasticity are, in any row
    order."""
    base = hobbing_problem.solve_exact()
    order = np.random.default_rng(2023).permutation(len(hobbing_problem.rows.pose))
    again = _permuted(hobbing_problem, order).solve_exact()
    one, two = requirement_table(base), requirement_table(again)
    numbers = one.columns[one.dtypes.map(lambda d: d.kind) == "f"]
    np.testing.assert_allclose(one[numbers].to_numpy(), two[numbers].to_numpy(),
                               rtol=1e-5, atol=1e-6)  # the dual face holds to ~1e-7
    assert one["bound_with"].tolist() == two["bound_with"].tolist()
    assert requirement_text(base).equals(requirement_text(again))


def test_case_study_groups_and_one_sided_values(hobbing_problem):
    result = hobbing_problem.solve_exact()
    frame = result.requirements
    grouped = frame[frame["bound_with"] != ""]
    assert set(grouped.index) == {"ex", "ez"} and set(grouped["bound_with"]) == {"ex+ez"}
    assert grouped["multiplier"].isna().all() and grouped["elasticity"].isna().all()
    # relaxing ex alone saves nothing: ez holds the same rows (one-sided derivative)
    np.testing.assert_allclose(grouped["elasticity_relax"], 0.0, atol=1e-6)
    # tightening one alone costs what tightening the pair does (the group's elasticity)
    np.testing.assert_allclose(grouped["elasticity_tighten"], grouped["group_elasticity"],
                               rtol=RTOL)
    # the joint elasticity is the cost's finite-difference change when both limits move
    step = 1e-4
    machine = hobbing_problem.machine
    limits = machine.limits.copy()
    for output in ("ex", "ez"):
        limits[machine.outputs.index(output)] *= 1 + step
    relaxed = AllocationProblem.build(machine, side="one_sided",
                                      limits=dict(zip(machine.outputs, limits)))
    change = np.log(relaxed.solve_exact().cost / result.cost) / np.log1p(step)
    assert change == pytest.approx(grouped["group_elasticity"].iloc[0], rel=1e-2)
    # relaxing ex alone: the cost does not move (Eq. F2 with min Σλ = 0)
    alone = machine.limits.copy()
    alone[machine.outputs.index("ex")] *= 1 + step
    relaxed = AllocationProblem.build(machine, side="one_sided",
                                      limits=dict(zip(machine.outputs, alone)))
    change = np.log(relaxed.solve_exact().cost / result.cost) / np.log1p(step)
    assert change == pytest.approx(0.0, abs=1e-3)
    unique = frame[frame["bound_with"] == ""]
    np.testing.assert_allclose(unique["elasticity_relax"], unique["elasticity_tighten"],
                               atol=1e-5)


# ----- identification: directions no reading informs -----------------------------------
def _reordered(measurements, order):
    columns = {f.name: getattr(measurements, f.name) for f in fields(measurements)}
    return replace(measurements, **{k: v[order] for k, v in columns.items()
                                    if isinstance(v, np.ndarray) and len(v) == len(order)})


def test_uninformed_errors_keep_the_prior_mean_in_any_reading_order(mill3):
    """Two laser runs on the mill inform 4 of its 30 error directions; the others keep
    the prior, mean 0 exactly (not the 1e-17 mm a solve leaves), whatever the order."""
    from test_measured_machine import mill_plan

    import reliability
    from reliability.measured.simulated_measurements import simulate_measurements

    measurements = simulate_measurements(mill3, mill_plan(mill3), rng=0).measurements
    first = reliability.identify(mill3, measurements).errors
    order = np.random.default_rng(5).permutation(len(measurements.value))
    again = reliability.identify(mill3, _reordered(measurements, order)).errors
    uninformed = np.isclose(first["posterior_sd"], first["prior_sd"], rtol=1e-9)
    assert uninformed.sum() > 0
    assert (first["posterior_mean"][uninformed] == 0.0).all()
    assert (again["posterior_mean"][uninformed] == 0.0).all()
    np.testing.assert_allclose(first["posterior_mean"], again["posterior_mean"], rtol=1e-9,
                               atol=1e-12 * first["prior_sd"].max())


@pytest.fixture(scope="module")
def hobbing_continuous(hobbing):
    """The machine report's optimum: two-sided, the grid refined until the targets hold
    over the continuous workspace, where the row of dx at one pose equals that of dz at
    the pose with M turned by 90°."""
    from allocation.per_pose.continuous import solve_continuous
    from reliability.model.poses import workspace_grid

    problem = AllocationProblem.build(hobbing, workspace_grid(hobbing, 5), side="two_sided")
    return solve_continuous(problem, rtol=1e-3).result


def test_case_study_dx_dz_table_does_not_depend_on_the_row_order(hobbing_continuous):
    result = hobbing_continuous
    frame = result.requirements
    assert frame.loc["dx", "bound_with"] == frame.loc["dz", "bound_with"] == "dx+dz"
    # relaxing dx alone saves nothing (dz holds the alike rows); the pair has one value
    assert frame.loc["dx", "elasticity_relax"] == pytest.approx(0.0, abs=1e-5)
    assert np.isfinite(frame.loc["dx", "group_elasticity"])
    order = np.random.default_rng(7).permutation(len(result.problem.rows.pose))
    again = _permuted(result.problem, order).solve_exact()
    one, two = requirement_table(result), requirement_table(again)
    numbers = one.columns[one.dtypes.map(lambda d: d.kind) == "f"]
    # the face is held to the optimum's accuracy, so a determined value is fixed to
    # UNIQUE_WIDTH (relative), far finer than the three digits it is printed with
    np.testing.assert_allclose(one[numbers].to_numpy(), two[numbers].to_numpy(),
                               rtol=UNIQUE_WIDTH, atol=1e-6)
    assert one["bound_with"].tolist() == two["bound_with"].tolist()
    assert requirement_text(result).equals(requirement_text(again))
