"""Tests of the machine description: loading, names, validation and input checks."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from reliability import (COMPONENTS, MachineDescriptionError, load_machine,
                         machine_from_dict)


# ----- the paper's machine ---------------------------------------------------------------
def test_hobbing_axes_and_names(hobbing):
    m = hobbing
    assert m.axes == ("C", "X", "Z", "A", "Y", "M")
    assert m.joints == ("C-X", "X-Z", "Z-A", "A-Y", "Y-M")
    names = m.error_names
    assert len(names) == m.n_errors == 66 and len(set(names)) == 66
    assert names[0] == "C.dx" and names[3] == "C.ex" and names[5] == "C.ez"
    assert names[6] == "X.dx" and names[35] == "M.ez"
    assert names[36] == "C-X.dx" and names[42] == "X-Z.dx"
    assert names[-1] == "Y-M.ez"
    # The documented order (docs/model.md), written out independently: motion axis by
    # axis, then joints.
    owners = ["C", "X", "Z", "A", "Y", "M", "C-X", "X-Z", "Z-A", "A-Y", "Y-M"]
    assert names == tuple(f"{o}.{c}" for o in owners for c in COMPONENTS)
    assert [m.error_index(n) for n in names] == list(range(66))


def test_hobbing_axes_kinds_strokes_sizes(hobbing):
    spec = {a.name: a for a in hobbing.axis_specs}
    assert [(a.kind, a.direction) for a in hobbing.axis_specs] == [
        ("rotary", "z"), ("linear", "x"), ("linear", "z"), ("rotary", "x"),
        ("linear", "y"), ("rotary", "y")]
    assert spec["C"].full_turn and spec["M"].full_turn and not spec["A"].full_turn
    assert spec["C"].stroke == (0.0, 2 * math.pi)
    assert spec["X"].stroke == (0.0, 400.0)  # Table 3
    assert spec["Y"].stroke == (0.0, 200.0)
    assert spec["Z"].stroke == (100.0, 500.0)
    assert spec["A"].stroke == (-math.pi / 4, math.pi / 4)  # Eq. 35
    assert [spec[n].size for n in "XYZACM"] == [4.0, 2.0, 5.0, 1.5, 3.0, 1.0]  # Table 3
    assert all(a.offset == (0.0, 0.0, 0.0) for a in hobbing.axis_specs)
    assert hobbing.tool_offset == (0.0, 0.0, 0.0)


def test_hobbing_requirements_allocation_cost(hobbing):
    m = hobbing
    np.testing.assert_array_equal(m.limits, [0.02, 0.02, 0.02, 4.8e-5, 4.8e-5, 4.8e-5])
    np.testing.assert_array_equal(m.targets, [0.99] * 6)
    expected = [1.45e-5 if n.split(".")[1].startswith("e") else 0.003 for n in m.error_names]
    np.testing.assert_array_equal(m.initial_allocation, expected)  # Table 4
    assert m.initial_allocation[m.error_index("A-Y.ey")] == 1.45e-5
    assert m.initial_allocation[m.error_index("A-Y.dy")] == 0.003
    cost = m.cost_coefficients
    assert (cost.a, cost.b, cost.c, cost.d) == (1.98, 1.5, 1.83, 1.4)  # Table 5
    assert dict(cost.assembly) == {"C-X": 1.3, "X-Z": 1.7, "Z-A": 1.1, "A-Y": 1.34,
                                   "Y-M": 1.07}
    with pytest.raises(ValueError):
        m.limits[0] = 1.0  # read-only


def test_test_machines_load(mill3, trunnion5):
    assert mill3.axes == ("Y", "X", "Z") and mill3.n_errors == 30
    assert mill3.tool_offset == (0.0, 0.0, -120.0)
    assert all(any(a.offset) for a in mill3.axis_specs)
    assert mill3.initial_allocation[mill3.error_index("Z.dz")] == 0.004  # items override
    assert mill3.initial_allocation[mill3.error_index("Z.dy")] == 0.002
    assert trunnion5.axes == ("C", "A", "Y", "X", "Z") and trunnion5.n_errors == 54
    assert trunnion5.joints == ("C-A", "A-Y", "Y-X", "X-Z")


# ----- error vectors ---------------------------------------------------------------------
def test_error_vector_from_dict_and_series(hobbing):
    m = hobbing
    v = m.error_vector({"X.dx": 1e-3, "Y-M.ez": -2e-6})
    assert v.shape == (66,)
    assert v[6] == 1e-3 and v[65] == -2e-6
    assert np.count_nonzero(v) == 2
    s = pd.Series({"Z-A.dy": 5e-3, "C.ex": 1e-5})
    w = m.error_vector(s, default=1.0)
    assert w[m.error_index("Z-A.dy")] == 5e-3 and w[3] == 1e-5
    assert np.sum(w == 1.0) == 64
    full = pd.Series(np.arange(66.0) + 1, index=list(m.error_names))
    np.testing.assert_array_equal(m.error_vector(full, default=None), np.arange(66.0) + 1)


def test_error_vector_refusals(hobbing):
    with pytest.raises(KeyError, match="Q.dx"):
        hobbing.error_vector({"Q.dx": 1.0})
    with pytest.raises(KeyError, match="X-C.dx"):  # joints have a direction
        hobbing.error_vector({"X-C.dx": 1.0})
    with pytest.raises(KeyError, match="missing"):
        hobbing.error_vector({"X.dx": 1.0}, default=None)
    with pytest.raises(KeyError):
        hobbing.error_index("C.dw")


# ----- input checks of the model ----------------------------------------------------------
@pytest.mark.parametrize("bad, shown", [(0.0, "0.0"), (-1e-3, "-0.001"), (np.nan, "nan"),
                                        (np.inf, "inf")])
def test_check_tolerances_refuses_and_names_the_error(hobbing, bad, shown):
    t = hobbing.initial_allocation.copy()
    t[hobbing.error_index("Z-A.ey")] = bad
    with pytest.raises(ValueError, match=r"'Z-A\.ey'.*" + shown):
        hobbing.check_tolerances(t)


def test_check_tolerances_accepts_and_checks_shape(hobbing):
    t = hobbing.check_tolerances(list(hobbing.initial_allocation))
    np.testing.assert_array_equal(t, hobbing.initial_allocation)
    with pytest.raises(ValueError, match="66"):
        hobbing.check_tolerances(np.ones(65))
    with pytest.raises(ValueError, match="66"):
        hobbing.check_tolerances(1.0)


@pytest.mark.parametrize("q", [np.zeros(5), np.zeros((3, 7)), np.float64(0.0),
                               np.array([0, 0, 100, 0, 0, np.nan])])
def test_wrong_positions_refused(hobbing, q):
    with pytest.raises(ValueError, match="positions"):
        hobbing.comprehensive_error(q, np.zeros(66))
    with pytest.raises(ValueError, match="positions"):
        hobbing.jacobian(q)


@pytest.mark.parametrize("x", [np.zeros(65), np.zeros((2, 67)), np.float64(0.0),
                               np.r_[np.zeros(65), np.inf]])
def test_wrong_errors_refused(hobbing, x):
    with pytest.raises(ValueError, match="errors"):
        hobbing.comprehensive_error(np.zeros(6), x)


# ----- description refusals ----------------------------------------------------------------
def _axis(d, name):
    return next(a for a in d["axes"] if a["name"] == name)


REFUSALS = {
    "unknown kind": (lambda d: _axis(d, "X").update(kind="prismatic"),
                     r"axis 'X'.*unknown kind 'prismatic'"),
    "unknown direction": (lambda d: _axis(d, "Y").update(direction="w"),
                          r"axis 'Y'.*unknown direction 'w'"),
    "missing stroke": (lambda d: _axis(d, "Z").pop("stroke"),
                       r"axis 'Z'.*missing key 'stroke'"),
    "min equals max": (lambda d: _axis(d, "X").update(stroke=[400.0, 400.0]),
                       r"axis 'X'.*stroke min 400.0 must be < max 400.0"),
    "min above max": (lambda d: _axis(d, "A").update(stroke=[1.0, -1.0]),
                      r"axis 'A'.*stroke min"),
    "zero size": (lambda d: _axis(d, "M").update(size=0.0), r"axis 'M'.*size.*> 0"),
    "negative size": (lambda d: _axis(d, "X").update(size=-4.0), r"axis 'X'.*size.*> 0"),
    "zero limit": (lambda d: d["requirements"]["dy"].update(limit=0.0),
                   r"requirements\.dy\.limit.*> 0"),
    "negative limit": (lambda d: d["requirements"]["ez"].update(limit=-4.8e-5),
                       r"requirements\.ez\.limit.*> 0"),
    "target 0": (lambda d: d["requirements"]["dx"].update(target=0),
                 r"requirements\.dx\.target.*\(0, 1\)"),
    "target 1": (lambda d: d["requirements"]["ex"].update(target=1),
                 r"requirements\.ex\.target.*\(0, 1\)"),
    "target 1.2": (lambda d: d["requirements"]["ey"].update(target=1.2),
                   r"requirements\.ey\.target.*\(0, 1\)"),
    "duplicate axis": (lambda d: _axis(d, "Y").update(name="X"), r"duplicate axis 'X'"),
    "unknown top key": (lambda d: d.update(colour="red"), r"unknown key 'colour'"),
    # Reported by position: the axis table's keys are checked before its name is read.
    "unknown axis key": (lambda d: _axis(d, "A").update(pitch=3),
                         r"axes\[3\]: unknown key 'pitch'"),
    "unknown requirement": (lambda d: d["requirements"].update(dw={"limit": 1, "target": 0.9}),
                            r"requirements: unknown key 'dw'"),
    "missing requirement": (lambda d: d["requirements"].pop("ez"),
                            r"requirements: missing key 'ez'"),
    "full_turn with stroke": (lambda d: _axis(d, "C").update(stroke=[0.0, 6.0]),
                              r"axis 'C'.*full_turn or a stroke"),
    "full_turn on linear": (lambda d: _axis(d, "X").update(full_turn=True),
                            r"axis 'X'.*full_turn applies to rotary axes only"),
    "missing assembly joint": (lambda d: d["cost"]["assembly"].pop("Z-A"),
                               r"cost\.assembly: missing key 'Z-A'"),
    "unknown assembly joint": (lambda d: d["cost"]["assembly"].update({"X-C": 1.0}),
                               r"cost\.assembly: unknown key 'X-C'"),
    "unknown initial item": (lambda d: d["initial_allocation"].update(items={"Q.dx": 1.0}),
                             r"initial_allocation\.items: unknown key 'Q.dx'"),
    "non-positive initial": (lambda d: d["initial_allocation"].update(rotation=0),
                             r"initial_allocation\.rotation.*> 0"),
    "missing axes": (lambda d: d.pop("axes"), r"missing key 'axes'"),
    "bad axis name": (lambda d: _axis(d, "A").update(name="A.1"), r"axis name"),
    "non-number size": (lambda d: _axis(d, "X").update(size="4"), r"size.*expected a number"),
    "bool size": (lambda d: _axis(d, "X").update(size=True), r"size.*expected a number"),
    "bad tool offset": (lambda d: d.update(tool_offset=[0.0, 1.0]), r"tool_offset"),
}


@pytest.mark.parametrize("case", list(REFUSALS))
def test_description_refusals(hobbing_dict, case):
    edit, match = REFUSALS[case]
    edit(hobbing_dict)
    with pytest.raises(MachineDescriptionError, match=match):
        machine_from_dict(hobbing_dict, source="edited")


def test_unedited_dict_is_accepted(hobbing_dict, hobbing):
    # Guards the refusal tests: each one differs from an accepted description by its edit.
    m = machine_from_dict(hobbing_dict)
    assert m.error_names == hobbing.error_names
    np.testing.assert_array_equal(m.initial_allocation, hobbing.initial_allocation)


def test_machine_description_error_is_a_value_error():
    assert issubclass(MachineDescriptionError, ValueError)


def test_malformed_toml_file_refused(tmp_path):
    path = tmp_path / "broken.toml"
    path.write_text('name = "broken"\n[[axes]]\nname = "X\nkind = "linear"\n')
    with pytest.raises(MachineDescriptionError, match=r"broken\.toml.*not valid TOML"):
        load_machine(path)


def test_load_machine_from_file_names_the_file(tmp_path, mill3):
    text = (Path(__file__).parent / "machines" / "mill3.toml").read_text()
    path = tmp_path / "mill_bad.toml"
    path.write_text(text.replace('direction = "y"', 'direction = "v"', 1))
    with pytest.raises(MachineDescriptionError, match=r"mill_bad\.toml.*axes\[0\].*'v'"):
        load_machine(path)
    good = tmp_path / "mill_ok.toml"
    good.write_text(text)
    assert load_machine(good).axes == mill3.axes


def test_non_broadcastable_positions_and_errors_refused_clearly(hobbing):
    # q (4, 6) and x (3, 66) have batch shapes (4,) and (3,) that do not broadcast. The
    # message should name both shapes; currently numpy's einsum error speaks of
    # "remapped shapes (4,6,6)->... (3,6)->..." instead.
    with pytest.raises(ValueError, match=r"\(4, 6\).*\(3, 66\)"):
        hobbing.comprehensive_error(np.zeros((4, 6)), np.zeros((3, 66)))


# ----- cost coefficients a machine does not need, and files that are not text ---------------
MILL3 = Path(__file__).parent / "machines" / "mill3.toml"


def _mill3_dict():
    import tomllib

    return tomllib.loads(MILL3.read_text())


def test_linear_machine_may_omit_rotary_cost_coefficients():
    data = _mill3_dict()
    del data["cost"]["c"], data["cost"]["d"]
    machine = machine_from_dict(data)
    assert machine.cost_coefficients.c is None and machine.cost_coefficients.d is None
    assert machine.cost_coefficients.a == 2.0
    assert "c =" not in machine.to_toml()
    assert machine_from_dict(_mill3_dict()).cost_coefficients.c == 1.8


def test_rotary_machine_may_omit_linear_cost_coefficients(hobbing_dict):
    hobbing_dict["axes"] = [a for a in hobbing_dict["axes"] if a["kind"] == "rotary"]
    hobbing_dict["cost"]["assembly"] = {"C-A": 1.0, "A-M": 1.2}
    del hobbing_dict["cost"]["a"], hobbing_dict["cost"]["b"]
    machine = machine_from_dict(hobbing_dict)
    assert (machine.cost_coefficients.a, machine.cost_coefficients.b) == (None, None)


@pytest.mark.parametrize("key", ["a", "b", "c", "d"])
def test_needed_cost_coefficient_still_required(hobbing_dict, key):
    del hobbing_dict["cost"][key]
    with pytest.raises(MachineDescriptionError, match=rf"cost: missing key '{key}'"):
        machine_from_dict(hobbing_dict)


def test_linear_machine_still_requires_linear_coefficients():
    data = _mill3_dict()
    del data["cost"]["c"], data["cost"]["b"]
    with pytest.raises(MachineDescriptionError, match=r"cost: missing key 'b'"):
        machine_from_dict(data)


def test_unneeded_coefficient_given_is_still_checked():
    data = _mill3_dict()
    data["cost"]["c"] = -1.0
    with pytest.raises(MachineDescriptionError, match=r"cost\.c: must be > 0"):
        machine_from_dict(data)


@pytest.mark.parametrize("content", [b"\x89PNG\r\n\x1a\n\x00\x00\xff\xfe",
                                     "name = 'caf\u00e9'".encode("latin-1")])
def test_binary_machine_file_names_the_file(tmp_path, content):
    path = tmp_path / "picture.toml"
    path.write_bytes(content)
    with pytest.raises(MachineDescriptionError, match=r"picture\.toml: not a text file"):
        load_machine(path)
