"""studies.benchmarks.yield_scenario_bound: the linear programme behind each machine's cost
is a lower bound on the convex optimum, close to it, against closed forms."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from studies.benchmarks.yield_scenario_bound import TangentProgram


def box_problem(weights, reference, factors=(0.5, 1.5)):
    """A problem with cost Σ w_i/t_i² (Eq. 28) in a factor box of ``reference``."""
    weights, reference = np.asarray(weights, float), np.asarray(reference, float)
    cost = SimpleNamespace(weights=weights, total=lambda t: float(np.sum(weights / t**2)))
    return SimpleNamespace(reference=reference, lower=factors[0] * reference,
                           upper=factors[1] * reference, cost=cost)


def test_one_row_per_tolerance_matches_the_closed_form():
    """Rows ``|a_i t_i| ≤ 1`` cap each tolerance at ``min(upper_i, 1/a_i)``; the convex
    optimum is then ``Σ w_i / cap_i²`` (relative to the reference's cost). The programme's
    optimum is below it (tangents lie under a convex function) by less than 0.5 %."""
    weights, reference = [2.0, 1.0, 4.0], [1e-3, 2e-3, 5e-6]
    problem = box_problem(weights, reference)
    a = 1.0 / (np.array([0.8, 1.2, 2.0]) * np.array(reference))  # the third cannot bind
    cap = np.minimum(problem.upper, 1.0 / a)
    exact = np.sum(np.array(weights) / cap**2) / problem.cost.total(problem.reference)
    found = TangentProgram(problem).lowest_cost(np.diag(a))
    assert found <= exact * (1 + 1e-9)
    assert found == pytest.approx(exact, rel=5e-3)


def test_rows_that_cannot_bind_leave_the_box_corner():
    """No row can bind: every tolerance at its upper bound, exactly."""
    problem = box_problem([1.0, 3.0], [1e-3, 1e-3])
    rows = np.array([[10.0, 10.0]])  # |10 t_1 + 10 t_2| ≤ 0.03 < 1 in the whole box
    expected = np.sum(problem.cost.weights / problem.upper**2) / \
        problem.cost.total(problem.reference)
    assert TangentProgram(problem).lowest_cost(rows) == pytest.approx(expected, rel=1e-12)


def test_a_machine_no_allocation_in_the_box_passes_costs_infinity():
    """A row that needs the first tolerance below its lower bound: infeasible."""
    problem = box_problem([1.0, 1.0], [1e-3, 1e-3])
    rows = np.array([[1.0 / (0.25e-3), 0.0]])  # t_1 ≤ 0.25e-3 < lower 0.5e-3
    assert TangentProgram(problem).lowest_cost(rows) == np.inf
