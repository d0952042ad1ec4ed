"""Results that persist: machines pickle, copy, compare and write TOML; FOSM and allocation
results save to JSON and reload with every field verified; summaries print readably; every
saveable result has to_frame, summary, save and load under the same names."""

from __future__ import annotations

import copy
import json
import pickle
import tomllib
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from reliability import hobbing_machine, load_machine, machine_from_dict, machine_from_toml

MACHINE_DIR = Path(__file__).parent / "machines"
MACHINE_FILES = sorted(MACHINE_DIR.glob("*.toml"))


# ----- machines ----------------------------------------------------------------------------
def _every_machine():
    return [hobbing_machine()] + [load_machine(path) for path in MACHINE_FILES]


@pytest.mark.parametrize("machine", _every_machine(), ids=lambda m: m.name)
def test_machine_pickles_and_deep_copies_to_an_equal_machine(machine):
    for clone in (pickle.loads(pickle.dumps(machine)), copy.deepcopy(machine),
                  copy.copy(machine)):
        assert clone == machine and clone is not machine
        assert clone.error_index(machine.error_names[-1]) == machine.n_errors - 1
        q = np.array([np.mean(a.stroke) for a in machine.axis_specs])
        np.testing.assert_array_equal(clone.jacobian(q), machine.jacobian(q))


@pytest.mark.parametrize("machine", _every_machine(), ids=lambda m: m.name)
def test_to_toml_loads_back_to_an_equal_machine(machine, tmp_path):
    text = machine.to_toml()
    assert machine_from_dict(tomllib.loads(text)) == machine
    assert machine_from_toml(text, source="again") == machine
    path = tmp_path / "again.toml"
    path.write_text(text)
    assert load_machine(path) == machine


def test_machine_file_round_trip_keeps_every_given_item():
    for path in MACHINE_FILES:
        original = tomllib.loads(path.read_text())
        again = tomllib.loads(load_machine(path).to_toml())
        assert again["requirements"] == original["requirements"]
        assert again["cost"] == original["cost"]
        assert again["initial_allocation"] == original["initial_allocation"]


def test_machine_equality_sees_every_field(hobbing_dict):
    base = machine_from_dict(hobbing_dict)
    assert base == machine_from_dict(copy.deepcopy(hobbing_dict))
    edits = [lambda d: d["requirements"]["dz"].update(limit=0.021),
             lambda d: d["axes"][1].update(stroke=[0.0, 401.0]),
             lambda d: d["axes"][0].update(offset=[0.0, 0.0, 1.0]),
             lambda d: d["initial_allocation"].update(items={"X.dx": 0.004}),
             lambda d: d["cost"].update(a=2.0),
             lambda d: d.update(tool_offset=[0.0, 0.0, -1.0]),
             lambda d: d.update(name="another")]
    for edit in edits:
        changed = copy.deepcopy(hobbing_dict)
        edit(changed)
        assert machine_from_dict(changed) != base
    assert base != "not a machine"


def test_machine_with_items_differing_from_defaults_round_trips(hobbing_dict):
    hobbing_dict["initial_allocation"]["items"] = {"X.dx": 0.004, "Y-M.ez": 2e-5}
    machine = machine_from_dict(hobbing_dict)
    again = machine_from_dict(tomllib.loads(machine.to_toml()))
    assert again == machine
    assert again.initial_allocation[machine.error_index("X.dx")] == 0.004


# ----- FOSM results ------------------------------------------------------------------------
from allocation import AllocationProblem, AllocationResult  # noqa: E402
from reliability import FosmResult, fosm, workspace_grid  # noqa: E402
from reliability.basics.errors import SavedResultError

FOSM_ARRAYS = ("poses", "limits", "targets", "mean", "sigma", "beta", "one_sided",
               "two_sided", "worst_pose")


@pytest.fixture(scope="module")
def fosm_trunnion(trunnion5):
    return fosm(trunnion5, trunnion5.initial_allocation, workspace_grid(trunnion5, 3))


def _assert_same_fosm(a, b):
    for name in FOSM_ARRAYS:
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    pd.testing.assert_frame_equal(a.contributions, b.contributions, check_names=False)
    assert (a.axes, a.units, a.machine, a.k, a.distribution) == \
        (b.axes, b.units, b.machine, b.k, b.distribution)


def test_fosm_result_saves_and_reloads_bit_for_bit(fosm_trunnion, tmp_path):
    path = fosm_trunnion.save(tmp_path / "fosm.json")
    again = FosmResult.load(path)
    _assert_same_fosm(fosm_trunnion, again)
    assert again.summary() == fosm_trunnion.summary()
    document = json.loads(path.read_text())
    assert document["format"] == "precrel.fosm_result"
    assert document["format_version"] == 1 and isinstance(document["toolkit_version"], str)


def test_fosm_save_refuses_to_overwrite_unless_asked(fosm_trunnion, tmp_path):
    path = fosm_trunnion.save(tmp_path / "fosm.json")
    with pytest.raises(FileExistsError, match="overwrite=True"):
        fosm_trunnion.save(path)
    fosm_trunnion.save(path, overwrite=True)
    assert [p.name for p in tmp_path.iterdir()] == ["fosm.json"]  # no temporary left


def test_fosm_summary_shows_poses_as_axis_positions_with_units(fosm_trunnion, trunnion5):
    text = repr(fosm_trunnion)
    assert text == fosm_trunnion.summary()
    assert "C [deg]" in text and "A [deg]" in text and "X [mm]" in text
    assert "0.015 mm" in text and "5e-05 rad" in text
    worst = fosm_trunnion.worst_pose[0]
    row = next(line for line in text.splitlines()[text.splitlines().index(
        "Worst pose of each output (axis positions)"):] if line.startswith("dx"))
    rotary = [axis.kind == "rotary" for axis in trunnion5.axis_specs]
    shown = np.where(rotary, np.degrees(fosm_trunnion.poses[worst]), fosm_trunnion.poses[worst])
    assert [float(v) for v in row.split()[2:]] == pytest.approx(shown, rel=1e-5, abs=1e-6)
    meets = fosm_trunnion.meets_targets("two_sided")
    assert f"{int(meets.sum())} of 6 targets met" in text


def _edit_payload(path, edit):
    document = json.loads(path.read_text())
    edit(document["payload"])
    path.write_text(json.dumps(document))
    return path


FOSM_DAMAGE = {
    "poses shape": (lambda p: p["poses"].pop(), r"field 'payload.poses'|field 'payload.mean'"),
    "one axis too few": (lambda p: [row.pop() for row in p["poses"]], r"field 'payload.poses'"),
    "negative sigma": (lambda p: p["sigma"][0].__setitem__(0, -1.0), r"field 'payload.sigma'"),
    "probability above 1": (lambda p: p["two_sided"][0].__setitem__(0, 1.5),
                            r"field 'payload.two_sided'"),
    "beta tampered": (lambda p: p["beta"][3].__setitem__(2, p["beta"][3][2] * 1.01),
                      r"field 'payload.beta'.*does not follow"),
    "limit changed": (lambda p: p["limits"].__setitem__(0, 0.5), r"field 'payload.beta'"),
    "worst pose out of range": (lambda p: p["worst_pose"].__setitem__(0, 10**6),
                                r"field 'payload.worst_pose'"),
    "worst pose wrong": (lambda p: p["worst_pose"].__setitem__(
        0, (p["worst_pose"][0] + 1) % len(p["poses"])), r"field 'payload.worst_pose'"),
    "units": (lambda p: p["units"].__setitem__(0, "deg"), r"field 'payload.units'"),
    "missing field": (lambda p: p.pop("targets"), r"field 'payload.targets': missing"),
    "contributions": (lambda p: p["contributions"]["columns"].pop("ez"),
                      r"field 'payload.contributions.columns'.*'ez'"),
    "k text": (lambda p: p.update(k="3"), r"field 'payload.k'"),
    "distribution": (lambda p: p.update(distribution="uniform"),
                     r"field 'payload.distribution'"),
}


@pytest.mark.parametrize("damage", list(FOSM_DAMAGE))
def test_damaged_fosm_file_names_the_file_and_the_field(fosm_trunnion, tmp_path, damage):
    edit, match = FOSM_DAMAGE[damage]
    path = _edit_payload(fosm_trunnion.save(tmp_path / "damaged.json"), edit)
    with pytest.raises(SavedResultError, match=match) as caught:
        FosmResult.load(path)
    assert "damaged.json" in str(caught.value)


@pytest.mark.parametrize("content, match", [
    (b"", "not valid JSON"), (b"\xff\xfe\x00", "not a saved result"),
    (b"[1, 2]", "expected an object"), (b'{"format": "precrel.fosm_result"}',
                                        "'format_version': missing"),
    (b'{"format": "other", "format_version": 1}', "holds 'other'"),
    (b'{"format": "precrel.fosm_result", "format_version": 99, "toolkit_version": "x",'
     b' "payload": {}}', "not readable"),
])
def test_garbage_result_file_refused_with_its_name(tmp_path, content, match):
    path = tmp_path / "garbage.json"
    path.write_bytes(content)
    with pytest.raises(SavedResultError, match=match) as caught:
        FosmResult.load(path)
    assert "garbage.json" in str(caught.value)


def test_missing_result_file_names_it(tmp_path):
    with pytest.raises(SavedResultError, match="nothing.json: no such file"):
        FosmResult.load(tmp_path / "nothing.json")


def test_allocation_file_is_not_read_as_fosm(allocation_results, tmp_path):
    path = allocation_results[0].save(tmp_path / "allocation.json")
    with pytest.raises(SavedResultError, match="holds 'precrel.allocation_result'"):
        FosmResult.load(path)


# ----- allocation results ------------------------------------------------------------------
@pytest.fixture(scope="module")
def mill_problem(mill3):
    return AllocationProblem.build(mill3, workspace_grid(mill3, 3), locked=["Z.dz"])


@pytest.fixture(scope="module")
def allocation_results(mill_problem):
    return (mill_problem.solve_exact(),
            mill_problem.solve_gwo(n_wolves=12, n_iterations=20, rng=7))


def _assert_same_allocation(a, b):
    np.testing.assert_array_equal(a.tolerances, b.tolerances)
    assert (a.method, a.cost, a.feasible) == (b.method, b.cost, b.feasible)
    assert a.certificate == b.certificate
    pd.testing.assert_frame_equal(a.to_frame(), b.to_frame())
    pd.testing.assert_frame_equal(a.active, b.active, check_dtype=False)
    for name in ("history", "requirements"):
        x, y = getattr(a, name), getattr(b, name)
        assert (x is None) == (y is None)
        if x is not None:
            pd.testing.assert_frame_equal(x, y, check_dtype=False)


@pytest.mark.parametrize("which", [0, 1], ids=["exact", "gwo"])
def test_allocation_result_saves_and_reloads(allocation_results, mill_problem, tmp_path,
                                             which):
    result = allocation_results[which]
    path = result.save(tmp_path / "allocation.json")
    again = AllocationResult.load(path)
    _assert_same_allocation(result, again)
    assert again.summary() == result.summary()
    pd.testing.assert_frame_equal(again.breakdown(), result.breakdown())
    attached = AllocationResult.load(path, problem=mill_problem)
    assert attached.problem is mill_problem


def test_allocation_reload_refuses_another_problem(allocation_results, mill3, tmp_path):
    path = allocation_results[0].save(tmp_path / "allocation.json")
    other = AllocationProblem.build(mill3, workspace_grid(mill3, 3))
    with pytest.raises(SavedResultError, match=r"field 'payload.lower'|field 'upper'"):
        AllocationResult.load(path, problem=other)
    one_sided = AllocationProblem.build(mill3, workspace_grid(mill3, 3), locked=["Z.dz"],
                                        side="one_sided")
    with pytest.raises(SavedResultError, match=r"field 'payload.side'"):
        AllocationResult.load(path, problem=one_sided)


ALLOCATION_DAMAGE = {
    "cost tampered": (lambda p: p.update(cost=p["cost"] * 0.9), r"'payload.cost'.*not the cost"),
    "tolerance out of bounds": (lambda p: p["tolerances"].__setitem__(0, 1.0),
                                r"'payload.(tolerances|cost)'"),
    "negative tolerance": (lambda p: p["tolerances"].__setitem__(0, -1e-3),
                           r"'payload.tolerances'"),
    "lower above upper": (lambda p: p["lower"].__setitem__(1, 1.0), r"'payload.lower'"),
    "names repeat": (lambda p: p["names"].__setitem__(1, p["names"][0]),
                     r"'payload.names'.*more than once"),
    "method": (lambda p: p.update(method="annealing"), r"'payload.method'"),
    "feasible text": (lambda p: p.update(feasible="yes"), r"'payload.feasible'"),
    "side": (lambda p: p.update(side="both"), r"'payload.side'"),
    "weights short": (lambda p: p["cost_weights"].pop(), r"'payload.cost_weights'"),
    "pose out of range": (lambda p: p["active"]["columns"]["pose"].__setitem__(0, 10**6),
                          r"'payload.active'"),
    "requirements rows": (lambda p: p["requirements"]["index"].reverse(),
                          r"'payload.requirements.index'"),
    "certificate": (lambda p: p["certificate"].pop("certified"),
                    r"'payload.certificate.certified': missing"),
}


@pytest.mark.parametrize("damage", list(ALLOCATION_DAMAGE))
def test_damaged_allocation_file_names_the_field(allocation_results, tmp_path, damage):
    edit, match = ALLOCATION_DAMAGE[damage]
    path = _edit_payload(allocation_results[0].save(tmp_path / "bad.json"), edit)
    with pytest.raises(SavedResultError, match=match) as caught:
        AllocationResult.load(path)
    assert "bad.json" in str(caught.value)


def test_allocation_csv_has_exactly_the_contract_columns(allocation_results, mill3,
                                                         tmp_path):
    result = allocation_results[0]
    path = result.to_csv(tmp_path / "allocation.csv")
    frame = pd.read_csv(path)
    assert list(frame.columns) == ["error", "reference", "allocated"]
    assert tuple(frame["error"]) == mill3.error_names
    np.testing.assert_array_equal(frame["allocated"], result.tolerances)
    np.testing.assert_array_equal(frame["reference"], mill3.initial_allocation)
    with pytest.raises(FileExistsError):
        result.to_csv(path)


def test_allocation_summary_states_cost_ratio_and_what_binds(allocation_results,
                                                             mill_problem):
    exact = allocation_results[0]
    text = repr(exact)
    reference_cost = mill_problem.cost.total(mill_problem.reference)
    assert f"Cost {exact.cost / reference_cost:.4f} × the reference allocation" in text
    assert "certified" in text and "NOT FEASIBLE" not in text
    binding = exact.requirements.index[exact.requirements["binding_rows"] > 0]
    assert len(binding) > 0
    for output in binding:
        assert any(line.startswith(output) for line in text.splitlines())
    assert "Y [mm]" in text and "X [mm]" in text and "Z [mm]" in text
    assert "1 locked" in text


def test_infeasible_allocation_says_so_on_its_first_line(allocation_results, mill_problem):
    import dataclasses

    gwo = allocation_results[1]
    tight = mill_problem.lower.copy()
    bad = dataclasses.replace(gwo, tolerances=mill_problem.upper, feasible=False,
                              certificate={"violation": 0.25, "evaluations": 1})
    assert not mill_problem.meets_targets(mill_problem.upper)
    first = repr(bad).splitlines()[0]
    assert first.startswith("NOT FEASIBLE") and "0.25" in first
    assert repr(dataclasses.replace(gwo, tolerances=tight)).splitlines()[0] \
        .startswith("Allocation by the Grey Wolf")


# ----- bad arguments ---------------------------------------------------------------------
from reliability.basics.errors import InputError, InputTypeError


def test_bad_arguments_to_save_load_and_summary_are_refused(fosm_trunnion, allocation_results,
                                                            tmp_path):
    exact = allocation_results[0]
    cases = [
        (lambda: fosm_trunnion.save(3.5), InputTypeError, "path must be a file name"),
        (lambda: fosm_trunnion.save(tmp_path / "a.json", overwrite="yes"), InputTypeError,
         "overwrite must be True or False"),
        (lambda: exact.save("", overwrite=True), InputError, "path must not be empty"),
        (lambda: exact.to_csv(tmp_path / "a.csv", overwrite=1), InputTypeError, "overwrite"),
        (lambda: FosmResult.load(None), InputTypeError, "path must be a file name"),
        (lambda: fosm_trunnion.summary(top=0), InputError, "top must be >= 1"),
        (lambda: exact.summary(top="5"), InputTypeError, "top must be a whole number"),
    ]
    for call, kind, match in cases:
        with pytest.raises(kind, match=match):
            call()
    path = exact.save(tmp_path / "exact.json")
    with pytest.raises(InputTypeError, match="problem must be an AllocationProblem"):
        AllocationResult.load(path, problem="mill3")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["exact.json"]


# ----- one protocol ------------------------------------------------------------------------
def test_every_saveable_result_has_the_same_four_methods():
    import inspect

    from reliability import GridExperimentResult, RandomPoseResult

    for kind in (FosmResult, AllocationResult, GridExperimentResult, RandomPoseResult):
        for name in ("to_frame", "summary", "save"):
            assert callable(getattr(kind, name)), (kind.__name__, name)
        assert inspect.ismethod(kind.load) and kind.load.__self__ is kind, kind.__name__
        save = inspect.signature(kind.save).parameters
        assert list(save)[:3] == ["self", "path", "overwrite"], kind.__name__
        assert save["overwrite"].default is False, kind.__name__
        assert list(inspect.signature(kind.load).parameters)[0] == "path", kind.__name__
        assert not {"save_csv", "load_csv"} & set(dir(kind)), kind.__name__
