"""The classical worst-case stack reading and the targets/limits overrides of the problem."""

from __future__ import annotations

import numpy as np
import pytest

from allocation import AllocationProblem, TargetUnreachableError, solve_convex_allocation
from allocation.solvers import convex
from reliability.basics.errors import InputError, InputTypeError
from reliability.first_order.fosm import required_index
from reliability.model.poses import workspace_grid

WIDE = (1e-3, 1.5)  # the default box [0.5, 1.5] cannot hold the stack of the paper's machine


def test_one_error_stack_closed_form():
    # min w/t² s.t. g t <= 1: t = 1/g, cost w g²
    sol = solve_convex_allocation([3.0], [[4.0]], 1e-6, 10.0, power=2)
    assert sol.t[0] == pytest.approx(0.25, rel=1e-9)
    assert sol.fun == pytest.approx(3.0 * 16.0, rel=1e-9)
    assert sol.success


def test_two_error_stack_closed_form():
    # min Σ w/t² s.t. Σ a t <= 1: t_i ∝ (w_i/a_i)^(1/3), cost (Σ a^(2/3) w^(1/3))³
    w, a = np.array([2.0, 5.0]), np.array([3.0, 0.5])
    sol = solve_convex_allocation(w, a[None, :], 1e-6, 10.0, power=2)
    shape = (w / a) ** (1 / 3)
    np.testing.assert_allclose(sol.t, shape / (a @ shape), rtol=1e-7)
    assert sol.fun == pytest.approx(np.sum(a ** (2 / 3) * w ** (1 / 3)) ** 3, rel=1e-9)
    # KKT: 2 w_i / t_i³ = λ a_i
    lam = sol.multipliers[0]
    np.testing.assert_allclose(2 * w / sol.t ** 3, lam * a, rtol=1e-6)


def test_power_two_primal_fallback_certifies(monkeypatch):
    rng = np.random.default_rng(3)
    w, G = rng.uniform(1, 3, 4), rng.uniform(0, 1, (30, 4))
    monkeypatch.setattr(convex, "_solve_dual",
                        lambda w_, G_, lo_, hi_, *rest: (lo_.copy(), np.zeros(G_.shape[0]), "x"))
    sol = solve_convex_allocation(w, G, 1e-3, 1.0, power=2)
    assert sol.message.startswith("SLSQP") and sol.success
    assert np.max(G @ sol.u) <= 1 + 1e-9


def test_bad_power_and_start_are_refused():
    with pytest.raises(ValueError, match="power"):
        solve_convex_allocation([1.0], [[1.0]], 0.1, 1.0, power=3)
    with pytest.raises(ValueError, match="start"):
        solve_convex_allocation([1.0], [[1.0]], 0.1, 1.0, start=[-1.0])


@pytest.fixture(scope="module")
def stack_solution(hobbing):
    problem = AllocationProblem.build(hobbing, workspace_grid(hobbing, 3), side="stack",
                                      bounds=WIDE)
    return problem, problem.solve_exact()


def test_stack_optimum_is_feasible_and_binding(hobbing, stack_solution):
    problem, result = stack_solution
    assert result.certificate["certified"] and result.feasible
    assert result.certificate["relative_gap"] <= 1e-6
    assert result.certificate["stationarity"] <= 1e-4
    # independent check: Σ|J| t against the limits at every pose
    stack = np.abs(hobbing.jacobian(problem.poses)) @ result.tolerances
    assert np.all(stack <= hobbing.limits * (1 + 1e-9))
    # the binding rows reach their limit
    for _, row in result.active.iterrows():
        output = list(hobbing.outputs).index(row["output"])
        assert stack[row["pose"], output] == pytest.approx(hobbing.limits[output], rel=1e-6)


def test_stack_allocation_is_at_least_three_sigma(hobbing, stack_solution):
    # σ_y = sqrt(Σ J² t²)/3 ≤ Σ|J| t / 3 ≤ I/3, so β ≥ 3 at every pose and output
    problem, result = stack_solution
    sigma = np.sqrt(np.square(hobbing.jacobian(problem.poses)) @ np.square(result.tolerances / 3))
    assert np.all(hobbing.limits / sigma >= 3 * (1 - 1e-9))


def test_stack_costs_more_than_the_reliability_optimum(hobbing, stack_solution):
    problem, result = stack_solution
    two_sided = AllocationProblem.build(hobbing, problem.poses, bounds=WIDE).solve_exact()
    assert result.cost > two_sided.cost


def test_stack_elasticity_counts_rows_linear_in_one_over_limit(hobbing, stack_solution):
    # Σλ/F per output: relaxing every limit by 1 % saves Σ_o elasticity_o % to first order
    problem, result = stack_solution
    relaxed = AllocationProblem.build(hobbing, problem.poses, side="stack", bounds=WIDE,
                                      limits={o: 1.001 * v for o, v in
                                              zip(hobbing.outputs, hobbing.limits)})
    saving = 1 - relaxed.solve_exact().cost / result.cost
    assert saving == pytest.approx(-1e-3 * result.requirements["elasticity"].sum(), rel=2e-3)


def test_default_box_cannot_hold_the_stack(hobbing):
    problem = AllocationProblem.build(hobbing, workspace_grid(hobbing, 3), side="stack")
    with pytest.raises(TargetUnreachableError, match="worst-case stack") as info:
        problem.solve_exact()
    blocking = info.value.blocking
    first = blocking.iloc[0]
    output = list(hobbing.outputs).index(first["output"])
    stack = np.abs(hobbing.jacobian(problem.poses[first["pose"]]))[output] @ problem.lower
    assert first["stack_at_lower"] == pytest.approx(stack, rel=1e-12)
    assert np.all(blocking["stack_at_lower"] > blocking["limit"])


def test_stack_needs_the_worst_case_workspace(hobbing):
    with pytest.raises(InputError, match="stack"):
        AllocationProblem.build(hobbing, side="stack", workspace="mean")


def test_target_and_limit_overrides(hobbing):
    poses = workspace_grid(hobbing, 2)
    base = AllocationProblem.build(hobbing, poses, workspace="mean")
    changed = AllocationProblem.build(hobbing, poses, workspace="mean",
                                      targets={"dx": 0.999}, limits={"ez": 2 * 4.8e-5})
    assert changed.machine.targets[0] == 0.999 and changed.machine.targets[1] == 0.99
    assert changed.required_index[0] == pytest.approx(required_index(0.999))
    rows, base_rows = changed.row_matrix(), base.row_matrix()
    ratio = (required_index(0.999) / required_index(0.99)) ** 2
    np.testing.assert_allclose(rows[:, 0], ratio * base_rows[:, 0], rtol=1e-12)
    np.testing.assert_allclose(rows[:, 5], base_rows[:, 5] / 4, rtol=1e-12)
    np.testing.assert_array_equal(hobbing.targets, np.full(6, 0.99))  # machine untouched


@pytest.mark.parametrize("options, error, match", [
    ({"targets": {"dw": 0.9}}, InputError, "unknown output 'dw'"),
    ({"targets": {"dx": 1.0}}, InputError, r"targets\['dx'\] must lie in \(0, 1\)"),
    ({"limits": {"ex": -1.0}}, InputError, r"limits\['ex'\] must be finite and > 0"),
    ({"limits": {"ex": "big"}}, InputTypeError, "must be a number"),
    ({"targets": [0.9] * 6}, InputTypeError, "must be a mapping"),
])
def test_bad_overrides_are_refused(hobbing, options, error, match):
    with pytest.raises(error, match=match):
        AllocationProblem.build(hobbing, workspace_grid(hobbing, 2), **options)


def test_evaluate_reports_the_stack(hobbing, stack_solution):
    problem, result = stack_solution
    frame = problem.evaluate(result.tolerances)
    assert frame["meets"].all()
    np.testing.assert_allclose(frame["worst_stack"],
                               problem.stack(result.tolerances).max(axis=0), rtol=1e-12)
    assert not problem.evaluate(hobbing.initial_allocation)["meets"].any()  # 4.3-7.5 × I


def test_gwo_on_the_stack_never_beats_the_certified_optimum(stack_solution):
    problem, result = stack_solution
    gwo = problem.solve_gwo(n_wolves=20, n_iterations=60, rng=1,
                            initial=result.tolerances[None, :])
    assert gwo.feasible
    assert gwo.cost >= result.certificate["dual_bound"] * (1 - 1e-9)
