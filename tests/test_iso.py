"""ISO 230-1 symbols beside the paper's error names, accepted wherever a name is."""

from __future__ import annotations

import numpy as np
import pytest

from allocation import AllocationProblem
from reliability.basics.errors import InputError, MachineDescriptionError
from reliability.model.iso_names import iso_names, iso_symbol, name_table
from reliability.model.machine import error_names
from reliability.model.machine_file import machine_from_dict


def test_the_standards_symbols_for_a_linear_and_a_rotary_axis(hobbing):
    iso = dict(zip(hobbing.error_names, hobbing.iso_names))
    # ISO 230-1: linear X — EXX positioning, EYX EZX straightness, EAX roll, EBX ECX
    assert [iso[f"X.{c}"] for c in ("dx", "dy", "dz", "ex", "ey", "ez")] == \
        ["EXX", "EYX", "EZX", "EAX", "EBX", "ECX"]
    # rotary C — EXC EYC radial, EZC axial, EAC EBC tilt, ECC angular positioning
    assert [iso[f"C.{c}"] for c in ("dx", "dy", "dz", "ex", "ey", "ez")] == \
        ["EXC", "EYC", "EZC", "EAC", "EBC", "ECC"]


def test_each_axis_positioning_error_is_e_direction_axis(any_machine):
    iso = dict(zip(any_machine.error_names, any_machine.iso_names))
    for axis in any_machine.axis_specs:
        comp = ("d" if axis.kind == "linear" else "e") + axis.direction
        letter = {"dx": "X", "dy": "Y", "dz": "Z", "ex": "A", "ey": "B", "ez": "C"}[comp]
        assert iso[f"{axis.name}.{comp}"] == f"E{letter}{axis.name}"


def test_joint_errors_are_location_errors_of_the_following_axis(hobbing):
    iso = dict(zip(hobbing.error_names, hobbing.iso_names))
    assert iso["C-X.ey"] == "EB0X"  # squareness of X about y
    assert iso["Z-A.dy"] == "EY0A" and iso["Z-A.ez"] == "EC0A"
    assert iso["Y-M.dx"] == "EX0M"


def test_names_are_aligned_unique_and_indexed_both_ways(any_machine):
    names, iso = any_machine.error_names, any_machine.iso_names
    assert len(iso) == len(names) == len(set(iso))
    assert not set(iso) & set(names)
    for i, (name, symbol) in enumerate(zip(names, iso)):
        assert any_machine.error_index(name) == any_machine.error_index(symbol) == i


def test_unknown_name_still_raises(hobbing):
    with pytest.raises(KeyError, match="EQX"):
        hobbing.error_index("EQX")


def test_error_vector_takes_iso_names_and_refuses_one_error_twice(hobbing):
    v = hobbing.error_vector({"EBX": 2e-5, "Z.dz": 0.004})
    assert v[hobbing.error_index("X.ey")] == 2e-5
    assert v[hobbing.error_index("EZZ")] == 0.004
    with pytest.raises(KeyError, match="same error"):
        hobbing.error_vector({"EBX": 2e-5, "X.ey": 3e-5})
    full = dict(zip(hobbing.iso_names, hobbing.initial_allocation))
    assert np.array_equal(hobbing.error_vector(full, default=None), hobbing.initial_allocation)


def test_machine_file_items_by_iso_name(hobbing_dict):
    hobbing_dict["initial_allocation"]["items"] = {"EXX": 0.002, "C-X.ey": 1e-5}
    machine = machine_from_dict(hobbing_dict)
    assert machine.initial_allocation[machine.error_index("X.dx")] == 0.002
    assert machine.initial_allocation[machine.error_index("EB0X")] == 1e-5
    hobbing_dict["initial_allocation"]["items"] = {"EXX": 0.002, "X.dx": 0.001}
    with pytest.raises(MachineDescriptionError, match="same error"):
        machine_from_dict(hobbing_dict)


def test_locks_by_iso_name(mill3):
    problem = AllocationProblem.build(mill3, locked=["EXX", "Z.ey"])
    assert problem.locked[mill3.error_index("X.dx")]
    assert problem.locked[mill3.error_index("EBZ")]
    assert problem.locked.sum() == 2


def test_symbols_of_single_names():
    assert iso_symbol("X2.dx") == "EXX2"
    assert iso_symbol("A-B.ez") == "EC0B"
    with pytest.raises(InputError, match="X.qq"):
        iso_symbol("X.qq")


def test_clashing_symbols_are_refused():
    # an axis named "0C" has motion error EX0C, the location error of C on it too
    with pytest.raises(InputError, match="EX0C"):
        iso_names(error_names(("0C", "C")))


def test_name_table(hobbing):
    table = name_table(hobbing)
    assert list(table.index) == list(hobbing.error_names)
    assert table.loc["C-X.ey", "iso"] == "EB0X" and table.loc["C-X.ey", "kind"] == "assembly"
    assert table.loc["M.ey", "iso"] == "EBM" and table.loc["M.ey", "owner"] == "M"
