"""Every result a user can get has the protocol of docs/results.md: ``summary()``,
``to_frame()``, ``save(path, overwrite=False)`` and a checked ``load``.

The result classes are found by walking the modules of ``reliability`` and ``allocation``
(every class that defines ``summary`` or ``to_frame``); each must be in :data:`ROUND_TRIPS`
(or, with a reason, in :data:`NOT_RESULTS`), so a new result without a round trip fails
here. Each round trip saves a small instance, loads it back, and compares ``to_frame()``
and the verdicts a reader decides from it; an existing file is refused without
``overwrite``; a file with one field changed to a wrong type raises SavedResultError.
"""

from __future__ import annotations

import importlib
import inspect
import json
import pkgutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import allocation
import reliability
from allocation import AllocationProblem, load_catalogue, solve_catalogue
from allocation.per_pose.compensated import allocate_compensated
from allocation.per_pose.continuous import solve_continuous
from allocation.solvers.convex import solve_convex_allocation
from allocation.per_pose.correlated import solve_correlated
from allocation.cost.fuzzy_evaluation import fcem_coefficient
from allocation.solvers.gwo import grey_wolf
from allocation.machine_yield.yield_target import allocate_for_yield
from reliability.acceptance.prediction import PositioningTest, acceptance
from reliability.acceptance.suggested_limits import suggest_limits
from reliability.basics.errors import SavedResultError
from reliability.basics.saved_results import SavedResult
from reliability.compensation.compensation_plans import parse_compensation_plan
from reliability.compensation.tables import compensation_tables
from reliability.first_order.system_reliability import system_reliability
from reliability.measured.planning import parse_candidates, plan_measurements
from reliability.measured.simulated_measurements import simulate_measurements
from reliability.model.poses import workspace_grid
from reliability.sampling.machine_yield import YieldModel, machine_yield
from reliability.sampling.pose_sampling import sample_at_poses, sample_random_poses
from reliability.sampling.rare_events import failure_probability
from reliability.sampling.sobol import sobol_indices
from reliability.sampling.verification import verify
from reliability.sampling.yield_sensitivity import yield_sensitivity

HERE = Path(__file__).parent

#: Classes with ``summary`` or ``to_frame`` that are not results, and why.
NOT_RESULTS = {
    "reliability.basics.saved_results.SavedResult": "the protocol itself",
    "reliability.basics.statistics._FrameMixin": "private base of the two estimates",
    "reliability.basics.statistics.ProportionEstimate": "an interval inside other results",
    "reliability.basics.statistics.ReplicateEstimate": "an interval inside other results",
    "reliability.measured.measurement_files.Measurements": "an input (a measurement file)",
    "reliability.model.measured_profiles.MeasuredProfile": "an input (a measured profile)",
    "reliability.model.measured_profiles.SystematicErrors": "an input (measured errors)",
    "allocation.cost.cost.CostModel": "an input (the cost weights)",
    "allocation.solvers.gwo._Wolves": "private state of the optimiser",
}


def found_classes() -> set[str]:
    """Every class defined in a module of reliability or allocation with ``summary`` or
    ``to_frame``, plus every class that passes as a :class:`SavedResult`."""
    names = set()
    for package in (reliability, allocation):
        for info in pkgutil.walk_packages(package.__path__, package.__name__ + "."):
            module = importlib.import_module(info.name)
            for name, value in vars(module).items():
                if inspect.isclass(value) and value.__module__ == module.__name__ and (
                        hasattr(value, "summary") or hasattr(value, "to_frame")):
                    names.add(f"{module.__name__}.{name}")
    return names


# ----- small instances, built once --------------------------------------------------------
def _line(axis, line):
    return {"name": f"laser_{axis}", "kind": "line", "axis": axis, "line": line,
            "quantities": ["dx", "dy", "dz", "ex", "ey", "ez"], "u": 0.0005,
            "u_angle": 1e-6, "cost": 1.0}


LINES = [_line("X", {"Y": 200.0, "Z": -100.0}), _line("Y", {"X": 0.0, "Z": -100.0}),
         _line("Z", {"X": 0.0, "Y": 200.0})]


@pytest.fixture(scope="module")
def grid(mill3):
    return workspace_grid(mill3, 3)


@pytest.fixture(scope="module")
def problem(mill3, grid):
    return AllocationProblem.build(mill3, grid)


@pytest.fixture(scope="module")
def comp_plan(mill3):
    return parse_compensation_plan({"tests": LINES, "compensation": {"spacing_mm": 100.0}},
                                   mill3)


@pytest.fixture(scope="module")
def identification(mill3, comp_plan):
    built = simulate_measurements(mill3, comp_plan.runs, rng=7)
    return reliability.identify(mill3, built.measurements)


@pytest.fixture(scope="module")
def interior(mill3, grid):
    low, high = grid.min(axis=0), grid.max(axis=0)
    poses = 0.5 * (low + high) + 0.5 * (grid - 0.5 * (low + high))
    return AllocationProblem.build(mill3, poses, bounds=(0.05, 1.5))


@pytest.fixture(scope="module")
def verification(mill3):
    return verify(mill3, mill3.initial_allocation, points=2, repeats=2, samples=300,
                  machines=100, rng=1)


@pytest.fixture(scope="module")
def acceptance_setup(mill3):
    test = PositioningTest("position_X", "X", {"Y": 200.0, "Z": -175.0},
                           {"E": 0.01, "A": 0.02, "R": 0.01, "B": 0.01})
    return acceptance(mill3, [test], machines=60, driver_machines=1, rng=2)


def build(name, request):
    """The instance of result class ``name`` and the keyword arguments its ``load`` takes
    besides the path."""
    get = request.getfixturevalue
    mill3 = get("mill3")
    t = mill3.initial_allocation
    builders = {
        "FosmResult": lambda: (reliability.fosm(mill3, t, get("grid")), {}),
        "SystemReliability": lambda: (system_reliability(mill3, t, get("grid")[:4],
                                                         n_points=64, n_batches=2, rng=1), {}),
        "GridExperimentResult": lambda: (get("verification").grid, {}),
        "RandomPoseResult": lambda: (sample_random_poses(mill3, t, 500, rng=1), {}),
        "PoseSamplingResult": lambda: (sample_at_poses(mill3, t, get("grid")[:2],
                                                       samples=500, rng=1), {}),
        "RareEventResult": lambda: (failure_probability(mill3, 3 * t, get("grid")[0],
                                                        event="dx", rng=1), {}),
        "SobolIndices": lambda: (sobol_indices(mill3, samples=64, resamples=20,
                                               points=2, rng=1), {}),
        "YieldSensitivity": lambda: (yield_sensitivity(
            YieldModel(mill3, points=2), t, machines=300, rng=1), {}),
        "Verification": lambda: (get("verification"), {}),
        "YieldEstimate": lambda: (machine_yield(mill3, t, points=2, machines=200,
                                                rng=1), {}),
        "Identification": lambda: (get("identification"), {"machine": mill3}),
        "CompensationTables": lambda: (compensation_tables(get("identification"),
                                                           spacing_mm=100.0),
                                       {"machine": mill3}),
        "MeasurementPlan": lambda: (plan_measurements(
            mill3, parse_candidates({"tests": LINES}, mill3), 2.0, points=2),
            {"machine": mill3}),
        "AcceptanceResult": lambda: (get("acceptance_setup"), {}),
        "SuggestedLimits": lambda: (suggest_limits(get("acceptance_setup"), 0.9), {}),
        "AllocationResult": lambda: (get("problem").solve_exact(),
                                     {"problem": get("problem")}),
        "ContinuousAllocation": lambda: _continuous(get("interior")),
        "CatalogueResult": lambda: _catalogue(mill3, get("problem")),
        "CorrelatedAllocation": lambda: (solve_correlated(
            mill3.with_correlation({("X.ey", "X.dz"): 0.5}), get("grid")), {}),
        "CompensatedAllocation": lambda: _compensated(mill3, get("comp_plan")),
        "YieldAllocation": lambda: _yield_allocation(mill3),
        "GwoResult": lambda: (grey_wolf(lambda x: np.sum((x - 0.3) ** 2, axis=1), [0.0] * 2,
                                        [1.0] * 2, n_wolves=6, n_iterations=5, rng=1), {}),
        "ConvexSolution": lambda: (solve_convex_allocation(
            [1.0, 2.0, 0.5], np.array([[1.0, 0.5, 0.2], [0.3, 1.0, 0.8]]), 0.01, 1.0), {}),
        "FcemResult": lambda: (fcem_coefficient([0.5, 0.5], [[0.2, 0.3, 0.5, 0.0, 0.0],
                                                             [0.1, 0.1, 0.2, 0.3, 0.3]]), {}),
    }
    return builders[name]()


def _continuous(interior):
    result = solve_continuous(interior, rtol=1e-2)
    return result, {"problem": result.result.problem, "grid_problem": result.grid.problem}


def _catalogue(mill3, problem):
    catalogue = load_catalogue(str(HERE / "catalogues" / "mill3.toml"), mill3)
    return solve_catalogue(problem, catalogue), {"problem": problem, "catalogue": catalogue}


def _compensated(mill3, plan):
    problem = AllocationProblem.build(mill3, workspace_grid(mill3, 2), side="two_sided")
    return allocate_compensated(problem, plan), {"problem": problem, "plan": plan}


def _yield_allocation(mill3):
    result = allocate_for_yield(mill3, 0.9, profile="constant", points=2, machines=300,
                                rng=1, rounds=2, naive_steps=3, restore_steps=1,
                                shape_steps=2)
    extra = {"search_problem": result.search_problem} if result.from_narrower_box else {}
    return result, {"problem": result.problem, **extra}


# ----- what a reader decides --------------------------------------------------------------
def _proportion(p):
    return (p.estimate, p.lower, p.upper)


VERDICTS = {
    "FosmResult": lambda r: (r.meets_targets(), r.worst()),
    "SystemReliability": lambda r: (r.worst, r.worst_probability),
    "GridExperimentResult": lambda r: (r.all_inside, r.fractions),
    "RandomPoseResult": lambda r: r.to_frame(),
    "PoseSamplingResult": lambda r: (r.estimate.lower, r.estimate.upper),
    "RareEventResult": lambda r: (r.interval, r.reached),
    "SobolIndices": lambda r: r.interaction_flags(),
    "YieldSensitivity": lambda r: r.ranked(),
    "Verification": lambda r: (r.fosm.meets_targets(), r.grid.all_inside,
                               None if r.machine_yield is None else r.machine_yield.interval),
    "YieldEstimate": lambda r: r.interval,
    "Identification": lambda r: (r.errors[["lower", "upper"]], r.rank, r.combinations),
    "CompensationTables": lambda r: (r.items, r.values_at(r.machine.check_positions(
        workspace_grid(r.machine, 2)))),
    "MeasurementPlan": lambda r: (r.chosen, r.cost),
    "AcceptanceResult": lambda r: r.to_frame(),
    "SuggestedLimits": lambda r: r.to_frame(),
    "AllocationResult": lambda r: (r.feasible, r.certificate, r.cost),
    "ContinuousAllocation": lambda r: (r.certified, r.statement, r.cost_ratio),
    "CatalogueResult": lambda r: (r.choice, r.certified, r.feasible, r.binding()),
    "CorrelatedAllocation": lambda r: (r.certified, r.sensitivity(0, 1)),
    "CompensatedAllocation": lambda r: (r.feasible, r.lower_bound, r.tight()),
    "YieldAllocation": lambda r: (r.verified, r.relative_gap, _proportion(r.verified_yield)),
    "GwoResult": lambda r: (r.feasible, r.fun),
    "ConvexSolution": lambda r: (r.success, r.relative_gap),
    "FcemResult": lambda r: r.value,
}

#: Result classes, the field a corrupted file changes, and marks.
ROUND_TRIPS = {
    "reliability.first_order.fosm.FosmResult": "limits",
    "reliability.first_order.system_reliability.SystemReliability": "probability",
    "reliability.sampling.experiment_results.GridExperimentResult": "inside",
    "reliability.sampling.experiment_results.RandomPoseResult": "inside",
    "reliability.sampling.pose_sampling.PoseSamplingResult": "failures",
    "reliability.sampling.rare_events.RareEventResult": "probability",
    "reliability.sampling.sobol.SobolIndices": "samples",
    "reliability.sampling.yield_sensitivity.YieldSensitivity": "dyield_dlnt",
    "reliability.sampling.verification.Verification": "distribution",
    "reliability.sampling.yield_estimate.YieldEstimate": "estimate",
    "reliability.measured.identification.Identification": "summary.json:rank",
    "reliability.compensation.tables.CompensationTables": "X.csv",
    "reliability.measured.planning.MeasurementPlan": "budget",
    "reliability.acceptance.acceptance_result.AcceptanceResult": "k",
    "reliability.acceptance.suggested_limits.SuggestedLimits": "probability",
    "allocation.per_pose.solve.AllocationResult": "tolerances",
    "allocation.per_pose.continuous.ContinuousAllocation": "certified",
    "allocation.catalogue.discrete.CatalogueResult": "price",
    "allocation.per_pose.correlated.CorrelatedAllocation": "cost",
    "allocation.per_pose.compensated.CompensatedAllocation": "lower_bound",
    "allocation.machine_yield.yield_target.YieldAllocation": "cost",
    "allocation.solvers.gwo.GwoResult": "fun",
    "allocation.cost.fuzzy_evaluation.FcemResult": "value",
    "allocation.solvers.convex.ConvexSolution": "u",
}


def test_every_result_class_found_has_a_round_trip():
    found = found_classes()
    assert found - set(NOT_RESULTS) == set(ROUND_TRIPS), \
        "result classes without a round trip here (or gone)"


def test_the_walk_finds_the_results_the_package_exports():
    exported = {f"{c.__module__}.{c.__qualname__}" for c in
                (reliability.FosmResult, reliability.SystemReliability,
                 reliability.CompensationTables, reliability.Identification,
                 allocation.YieldAllocation, allocation.ConvexSolution)}
    assert exported <= found_classes()


def _short(path):
    return path.rsplit(".", 1)[1]


def _cases():
    for path, field in ROUND_TRIPS.items():
        yield pytest.param(path, field, id=_short(path))


@pytest.mark.parametrize(("path", "field"), list(_cases()))
def test_round_trip_keeps_the_frame_and_the_verdicts(path, field, request, tmp_path):
    result, attach = build(_short(path), request)
    assert isinstance(result, SavedResult)
    assert f"{type(result).__module__}.{type(result).__qualname__}" == path
    where = tmp_path / ("saved" if _short(path) in FOLDERS else
                        "saved.csv" if _short(path) in CSV_FILES else "saved.json")
    result.save(where)
    back = type(result).load(where, **attach)
    assert type(back) is type(result)
    assert isinstance(back.summary(), str) and back.summary()
    rtol = 1e-5 if _short(path) == "Identification" else 0  # errors.csv: six digits
    _same(back.to_frame(), result.to_frame(), rtol)
    _same(VERDICTS[_short(path)](back), VERDICTS[_short(path)](result), rtol)
    with pytest.raises(FileExistsError):
        result.save(where)
    result.save(where, overwrite=True)
    _corrupt(where, field)
    with pytest.raises(SavedResultError, match=str(where.name)):
        type(result).load(where, **attach)


#: Results saved as a folder of files, and as one CSV table.
FOLDERS = {"Identification", "CompensationTables"}
CSV_FILES = {"GridExperimentResult", "RandomPoseResult"}


def _corrupt(where: Path, field: str) -> None:
    """One field of a saved result changed to a wrong type (a text for a number)."""
    if where.is_dir():
        name, _, key = field.partition(":")
        path = where / name
        if key:
            data = json.loads(path.read_text())
            data[key] = "many"
            path.write_text(json.dumps(data))
        else:
            lines = path.read_text().splitlines()
            last = lines[-1].split(",")
            last[-1] = "many"
            path.write_text("\n".join(lines[:-1] + [",".join(last)]) + "\n")
        return
    if where.suffix == ".json":
        document = json.loads(where.read_text())
        document["payload"][field] = "many"
        where.write_text(json.dumps(document))
        return
    table = pd.read_csv(where, dtype=str)
    table.loc[0, field] = "many"
    table.to_csv(where, index=False)


def _same(back, memory, rtol) -> None:
    """Equal, numbers to ``rtol`` (0: exactly), through tuples, dicts, arrays and frames."""
    if isinstance(memory, pd.DataFrame):
        tolerance = {"check_exact": True} if rtol == 0 else {"rtol": rtol}
        pd.testing.assert_frame_equal(back, memory, check_dtype=False, check_index_type=False,
                                      check_column_type=False, **tolerance)
    elif isinstance(memory, (tuple, list)) and not isinstance(back, str):
        assert len(back) == len(memory)
        for b, m in zip(back, memory):
            _same(b, m, rtol)
    elif isinstance(memory, dict):
        assert back.keys() == memory.keys()
        for key in memory:
            _same(back[key], memory[key], rtol)
    elif isinstance(memory, (np.ndarray, float, np.floating)) and not isinstance(memory, bool):
        np.testing.assert_allclose(back, memory, rtol=rtol, atol=0)
    else:
        assert back == memory


# ----- folders rewritten hold only the new run -------------------------------------------
def test_an_identification_rewritten_under_constant_drops_the_gp_files(
        mill3, comp_plan, identification, tmp_path):
    built = simulate_measurements(mill3, comp_plan.runs, rng=7)
    along = reliability.identify(mill3, built.measurements, profile="gp:300")
    folder = tmp_path / "id"
    assert "coefficients.npz" in along.save(folder)
    (folder / "notes.txt").write_text("kept\n")
    with pytest.raises(FileExistsError):
        identification.save(folder)
    written = identification.save(folder, overwrite=True)
    assert "profiles.csv" not in written and "coefficients.npz" not in written
    assert sorted(p.name for p in folder.iterdir()) == sorted(written + ("notes.txt",))
    back = reliability.Identification.load(folder, mill3)
    assert back.profile == "constant" and not back.coefficients.varies


def test_compensation_tables_rewritten_drop_an_earlier_machines_tables(
        mill3, identification, tmp_path):
    tables = compensation_tables(identification, spacing_mm=100.0)
    folder = tmp_path / "tables"
    tables.save(folder)
    (folder / "W.csv").write_text("# compensation table of 'another', axis W (linear)\n")
    (folder / "notes.txt").write_text("kept\n")
    with pytest.raises(FileExistsError):
        tables.save(folder)
    tables.save(folder, overwrite=True)
    assert sorted(p.name for p in folder.iterdir()) == \
        ["X.csv", "Y.csv", "Z.csv", "assembly.csv", "notes.txt"]
    _same(reliability.CompensationTables.load(folder, mill3).to_frame(), tables.to_frame(), 0)


def test_a_folder_of_another_machines_tables_is_refused_without_overwrite(
        mill3, identification, tmp_path):
    folder = tmp_path / "tables"
    folder.mkdir()
    (folder / "W.csv").write_text("# compensation table of 'another', axis W (linear)\n")
    with pytest.raises(FileExistsError, match="W.csv"):
        compensation_tables(identification, spacing_mm=100.0).save(folder)
