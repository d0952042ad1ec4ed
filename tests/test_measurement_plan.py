"""Planning the measurements: the chosen runs are the best affordable ones by the posterior an
identification of their readings gives, and the chosen plan is a plan file."""

import itertools
import tomllib
from pathlib import Path

import numpy as np
import pytest
import tomli_w

import reliability
from reliability.basics.errors import InputError
from reliability.measured.planning import parse_candidates, plan_measurements
from reliability.measured.plans import read_plan
from reliability.measured.simulated_measurements import simulate_measurements
from studies.cli.program import main

MILL = Path(__file__).parent / "machines" / "mill3.toml"
SIX = ["dx", "dy", "dz", "ex", "ey", "ez"]


def laser(name, axis, line, targets, quantities, cost):
    return {"name": name, "kind": "line", "axis": axis, "line": line, "targets": targets,
            "quantities": quantities, "u": 0.0005, "u_angle": 1e-6, "cost": cost}


CANDIDATES = {"tests": [
    laser("laser_X", "X", {"Y": 200.0, "Z": -100.0}, [-300.0, 0.0, 300.0], SIX, 2.0),
    laser("straight_X", "X", {"Y": 0.0, "Z": -300.0}, [-300.0, 0.0, 300.0], ["dy", "dz"], 1.0),
    laser("laser_Y", "Y", {"X": 0.0, "Z": -100.0}, [0.0, 200.0, 400.0], SIX, 2.0),
    laser("laser_Z", "Z", {"Y": 200.0, "X": 0.0}, [-350.0, -175.0, 0.0], ["dx", "dy", "ez"],
          1.0),
    {"name": "circle_xy", "kind": "circular", "plane": "xy", "radius": 100.0,
     "centre": {"Y": 200.0, "X": 0.0, "Z": -100.0}, "limit": 0.01, "u": 0.0005, "cost": 1.5}]}


@pytest.fixture(scope="module")
def mill():
    return reliability.load_machine(MILL)


@pytest.fixture(scope="module")
def candidates(mill):
    return parse_candidates(CANDIDATES, mill)


def direct_sd(machine, candidates, subset, worst_poses):
    """Each output's posterior sd at its worst pose, from identifying the subset's readings
    together (no readings: the prior's)."""
    if not subset:
        covariance = np.diag((machine.initial_allocation / 3.0) ** 2)
    else:
        readings = simulate_measurements(machine, tuple(candidates[i].run for i in subset),
                                         rng=2).measurements
        covariance = reliability.identify(machine, readings).covariance
    rows = machine.jacobian(np.stack(worst_poses))[np.arange(6), np.arange(6)]
    return np.sqrt(np.einsum("oi,ij,oj->o", rows, covariance, rows))


def test_the_chosen_runs_are_the_best_affordable_by_their_identification(mill, candidates):
    budget = 2.5
    plan = plan_measurements(mill, candidates, budget, points=3)
    worst = list(plan.outputs["worst_pose"])
    assert plan.cost <= budget
    scores = {}
    for size in range(len(candidates) + 1):
        for subset in itertools.combinations(range(len(candidates)), size):
            if sum(candidates[i].cost for i in subset) <= budget:
                sd = direct_sd(mill, candidates, subset, worst)
                scores[subset] = np.sum((sd / mill.limits) ** 2)
    chosen = tuple(sorted(plan.chosen))
    assert scores[chosen] <= min(scores.values()) * (1 + 1e-9)
    assert plan.objective["greedy"] == pytest.approx(scores[chosen], rel=1e-6)
    assert plan.objective["chosen"] == pytest.approx(scores[chosen], rel=1e-6)
    np.testing.assert_allclose(plan.outputs["chosen_sd"], direct_sd(mill, candidates, chosen,
                                                                    worst), rtol=1e-6)
    np.testing.assert_allclose(plan.outputs["all_sd"], direct_sd(
        mill, candidates, tuple(range(len(candidates))), worst), rtol=1e-6)


@pytest.mark.parametrize("cost", [0, -1.0, "two", True])
def test_a_bad_cost_is_refused_naming_the_run(mill, cost):
    data = {"tests": [dict(CANDIDATES["tests"][0], cost=cost)]}
    with pytest.raises(InputError, match="test 'laser_X', key 'cost'"):
        parse_candidates(data, mill)


def test_plan_writes_the_chosen_runs_as_a_plan(mill, tmp_path, capsys):
    candidates = tmp_path / "candidates.toml"
    candidates.write_text(tomli_w.dumps(CANDIDATES))
    chosen = tmp_path / "chosen.toml"
    assert main(["plan", str(MILL), "--candidates", str(candidates), "--budget", "2",
                 "--points", "2", "--out", str(chosen)]) == 0
    printed = capsys.readouterr().out
    runs = read_plan(chosen, mill)
    costs = {test["name"]: test["cost"] for test in CANDIDATES["tests"]}
    assert runs and sum(costs[run.name] for run in runs) <= 2
    assert all(f"  {run.name} (cost" in printed for run in runs)
    assert "what each chosen run adds" in printed


def test_exchanges_take_the_greedy_plan_to_the_best_subset(tmp_path):
    """On these four runs of the swivel machine's example plan, adding by gain per cost
    takes circle_yz where circle_zx is better; the exchange finds the best of all subsets."""
    swivel = reliability.load_machine(MILL.parent / "swivel5.toml")
    example = tomllib.loads((MILL.parents[2] / "docs" / "examples" /
                             "swivel5_plan.toml").read_text())
    kept = ("laser_Z", "circle_yz", "circle_zx", "rotary_C")
    candidates = parse_candidates({"tests": [t for t in example["tests"]
                                             if t["name"] in kept]}, swivel)
    plan = plan_measurements(swivel, candidates, 3, points=3)
    assert sorted(candidates[i].run.name for i in plan.chosen) == ["circle_zx", "laser_Z",
                                                                   "rotary_C"]
    assert plan.objective["greedy"] == pytest.approx(plan.objective["chosen"], rel=1e-12)
