"""The certified cheapest choice of catalogue classes against brute-force enumeration.

The reference enumerates every choice, builds its tolerances, and evaluates every
(pose, output) row of the problem's poses from the Jacobian (no screening), so it shares
neither the MILP nor the row screening with :func:`allocation.solve_catalogue`.
"""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest

import allocation
from allocation import AllocationProblem, Catalogue, solve_catalogue
from allocation.catalogue import discrete
from reliability import hobbing_machine, load_machine, workspace_grid
from reliability.basics.errors import InputError, InputTypeError
from reliability.model.machine import OUTPUTS

MILL = Path(__file__).parent / "machines" / "mill3.toml"


def random_catalogue(machine, components, factors, seed, skip=0):
    """Components of consecutive items (``skip`` items left out between components),
    classes at the given multiples of the initial allocation with random spread, prices
    falling with the factor."""
    rng = np.random.default_rng(seed)
    names, start, entries = machine.error_names, 0, []
    for c, size in enumerate(components):
        items = list(names[start:start + size])
        start += size + skip
        classes = []
        for j, factor in enumerate(factors):
            spread = 0.8 + 0.4 * rng.random(size)
            classes.append({
                "name": f"class{j}", "price": float(100.0 / factor * (0.9 + 0.2 * rng.random())),
                "tolerances": {item: float(machine.initial_allocation[machine.error_index(item)]
                                           * factor * s) for item, s in zip(items, spread)}})
        entries.append({"name": f"component {c}", "items": items, "classes": classes})
    return Catalogue.from_dict({"components": entries})


def enumerate_choices(problem, catalogue, threshold=1.0 + discrete.LOAD_TOLERANCE):
    """Every choice: class indices, total price, largest load over all rows, feasible."""
    index = [[problem.names.index(i) for i in c.items] for c in catalogue.components]
    choices = np.array(list(itertools.product(*(range(len(c.classes))
                                                for c in catalogue.components))))
    t = np.tile(problem.reference, (len(choices), 1))
    price = np.zeros(len(choices))
    for c, component in enumerate(catalogue.components):
        t[:, index[c]] = component.tolerance_matrix()[choices[:, c]]
        price += component.prices()[choices[:, c]]
    rows = problem.row_matrix().reshape(-1, len(problem.names))  # every pose, every output
    load = (rows @ problem.variable(t).T).max(axis=0)
    return choices, price, load, load <= threshold


def brute_force(problem, catalogue, threshold=1.0 + discrete.LOAD_TOLERANCE):
    choices, price, load, feasible = enumerate_choices(problem, catalogue, threshold)
    best = np.flatnonzero(feasible)[np.argmin(price[feasible])]
    choice = {c.name: c.classes[j].name for c, j in zip(catalogue.components, choices[best])}
    return choice, price[best], (choices, price, load, feasible)


def cases():
    hobbing = hobbing_machine()
    mill = load_machine(MILL)
    grid = workspace_grid(hobbing, 3)
    return {
        # five 6-item components over the motion errors of C..A, four classes, 1024 choices
        "two_sided": (AllocationProblem.build(hobbing, grid, side="two_sided"),
                      random_catalogue(hobbing, [6] * 5, (0.5, 1.0, 2.0, 4.0), seed=3)),
        # three components with items left between them (kept at the start), five classes
        "one_sided": (AllocationProblem.build(hobbing, grid, side="one_sided"),
                      random_catalogue(hobbing, [4, 3, 5], (0.25, 0.5, 1.0, 2.0, 4.0),
                                       seed=11, skip=2)),
        # the worst-case stack on the 3-axis mill (limits x 3), four components of three
        # classes
        "stack": (AllocationProblem.build(mill, workspace_grid(mill, 4), side="stack",
                                          limits=dict(zip(OUTPUTS, 3 * mill.limits))),
                  random_catalogue(mill, [4, 4, 4, 4], (0.2, 0.5, 1.0), seed=5, skip=1)),
    }


CASES = cases()


@pytest.fixture(scope="module", params=sorted(CASES))
def case(request):
    problem, catalogue = CASES[request.param]
    return problem, catalogue, solve_catalogue(problem, catalogue)


def test_equals_brute_force(case):
    problem, catalogue, result = case
    choice, price, (_, prices, _, feasible) = brute_force(problem, catalogue)
    # the instance is not trivial: some choices fail, and the cheapest choice is one of them
    assert 0 < feasible.sum() < len(feasible)
    assert not feasible[np.argmin(prices)]
    assert result.choice == choice
    assert result.price == pytest.approx(price, rel=1e-12)
    assert result.gap <= discrete.MIP_REL_GAP
    assert result.certified and result.feasible


def test_row_generation_needs_only_some_rows(case):
    _, _, result = case
    details = result.details
    assert details["rounds"] >= 2  # the first answer, without rows, is the cheapest
    assert 0 < details["active_rows"] <= details["rows"]["dominance"]


def test_choice_rechecked_on_every_row(case):
    problem, catalogue, result = case
    rows = problem.row_matrix().reshape(-1, len(problem.names))
    assert (rows @ problem.variable(result.tolerances)).max() <= 1 + discrete.LOAD_TOLERANCE
    assert result.details["max_load"] == pytest.approx(
        (rows @ problem.variable(result.tolerances)).max(), rel=1e-12)
    assert problem.meets_targets(result.tolerances)  # by the probabilities themselves
    # items in no component stay at the problem's reference
    fixed = set(catalogue.items)
    rest = [i for i, name in enumerate(problem.names) if name not in fixed]
    np.testing.assert_array_equal(result.tolerances[rest], problem.reference[rest])


def test_neighbour_prices_by_enumeration(case):
    problem, catalogue, result = case
    choices, prices, _, feasible = enumerate_choices(problem, catalogue)
    position = {tuple(row): k for k, row in enumerate(choices)}
    chosen = [component.class_names.index(result.choice[component.name])
              for component in catalogue.components]
    assert len(result.neighbours) > 0
    for move in result.neighbours.itertuples():
        c = next(i for i, comp in enumerate(catalogue.components)
                 if comp.name == move.component)
        moved = list(chosen)
        moved[c] = catalogue.components[c].class_names.index(move._3)  # 'class'
        k = position[tuple(moved)]
        assert move.price == pytest.approx(prices[k], rel=1e-12)
        assert move.price_change == pytest.approx(prices[k] - result.price, rel=1e-9,
                                                  abs=1e-9)
        assert bool(move.meets) == bool(feasible[k])
        # a cheaper neighbour that still met every requirement would beat the optimum
        assert not (move.meets and move.price_change < 0)


def test_neighbour_directions_follow_the_tolerances(case):
    _, catalogue, result = case
    for move in result.neighbours.itertuples():
        component = next(c for c in catalogue.components if c.name == move.component)
        here = component.tolerance_matrix()[component.class_names.index(
            result.choice[move.component])]
        there = component.tolerance_matrix()[component.class_names.index(move._3)]
        size = np.log(there).mean() - np.log(here).mean()
        assert size > 0 if move.direction == "looser" else size < 0


def test_the_search_box_does_not_apply_and_rows_allow_the_loosest_class():
    """A catalogue whose classes lie far outside the problem's box: the box-screened rows of
    the problem would miss rows that a loose class loads above 1."""
    machine = hobbing_machine()
    problem = AllocationProblem.build(machine, workspace_grid(machine, 3), bounds=(0.9, 1.0))
    catalogue = random_catalogue(machine, [6] * 5, (0.3, 1.6, 3.0), seed=2)
    result = solve_catalogue(problem, catalogue)
    choice, price, _ = brute_force(problem, catalogue)
    assert result.choice == choice and result.price == pytest.approx(price, rel=1e-12)
    assert (result.tolerances > problem.upper).any()
    assert result.details["rows"]["box"] > problem.rows.counts["box"]


def test_extra_poses_plug_in_as_rows():
    machine = hobbing_machine()
    problem = AllocationProblem.build(machine, workspace_grid(machine, 3))
    catalogue = random_catalogue(machine, [6] * 5, (0.5, 1.0, 2.0, 4.0), seed=3)
    extended = problem.with_poses(workspace_grid(machine, 4))
    result = solve_catalogue(extended, catalogue)
    choice, price, _ = brute_force(extended, catalogue)
    assert result.choice == choice and result.price == pytest.approx(price, rel=1e-12)
    assert result.details["poses"] == 3 ** 6 + 4 ** 6
    assert result.details["active_rows"] < result.details["rows"]["dominance"] / 2


def test_cut_off_choices_keep_the_certificate(monkeypatch):
    """With a negative load tolerance HiGHS's answers fail the re-check until a choice
    with every load below 1 − 0.06 is found (the five cheapest feasible choices load some
    row between 0.94 and 1): the no-good cuts give the optimum of that
    stricter problem, as enumeration does."""
    problem, catalogue = CASES["two_sided"]
    monkeypatch.setattr(discrete, "LOAD_TOLERANCE", -0.06)
    result = solve_catalogue(problem, catalogue)
    choice, price, _ = brute_force(problem, catalogue, threshold=0.94)
    assert result.details["cuts"] == 5
    assert result.choice == choice and result.price == pytest.approx(price, rel=1e-12)


def test_unreachable_names_output_and_pose():
    machine = hobbing_machine()
    problem = AllocationProblem.build(machine, workspace_grid(machine, 3))
    catalogue = random_catalogue(machine, [6, 6], (20.0, 40.0), seed=1)
    with pytest.raises(allocation.CatalogueInfeasibleError, match=r"meets \w+ at C=-?[\d.]+ deg, X=") as info:
        solve_catalogue(problem, catalogue)
    assert len(info.value.blocking) > 0
    assert (info.value.blocking["load"] > 1).all()


def test_choice_csv_and_tolerances(case, tmp_path):
    problem, catalogue, result = case
    frame = result.to_frame()
    assert list(frame.columns) == ["component", "class", "price"]
    assert len(frame) == len(catalogue.components)
    assert frame["price"].sum() == pytest.approx(result.price, rel=1e-12)
    path = result.to_csv(tmp_path / "choice.csv")
    assert path.read_text().splitlines()[0] == "component,class,price"
    written = allocation.read_allocation_csv(
        allocation.per_pose.result_files.allocation_to_csv(result, tmp_path / "t.csv"),
        problem.machine)
    np.testing.assert_array_equal(written, result.tolerances)


def test_bad_arguments():
    problem, catalogue = CASES["two_sided"]
    with pytest.raises(InputTypeError, match="AllocationProblem"):
        solve_catalogue("problem", catalogue)
    with pytest.raises(InputTypeError, match="Catalogue"):
        solve_catalogue(problem, {"components": []})
    machine = hobbing_machine()
    mean = AllocationProblem.build(machine, workspace_grid(machine, 2), workspace="mean")
    with pytest.raises(InputError, match="workspace='worst'"):
        solve_catalogue(mean, catalogue)
    unknown = Catalogue.from_dict({"components": [{"name": "screw", "items": ["Q.dx"],
                                                   "classes": [{"name": "C5", "price": 1.0,
                                                                "tolerances": {"Q.dx": 0.01}}]}]})
    with pytest.raises(InputError, match=r"component 'screw': unknown item 'Q.dx'"):
        solve_catalogue(problem, unknown)
