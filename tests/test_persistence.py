"""Results that persist: machines pickle, copy, compare and write TOML; FOSM and allocation
results save to JSON and reload with every field verified; summaries print readably."""

from __future__ import annotations

import copy
import json
import pickle
import tomllib
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import reliability
from reliability import hobbing_machine, load_machine, machine_from_dict

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
