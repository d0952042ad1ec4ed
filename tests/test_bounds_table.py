"""The machine file's [bounds] table: the achievable tolerances as the default search box."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from allocation import AllocationProblem
from reliability.basics.errors import MachineDescriptionError
from reliability.model.machine_file import load_machine, machine_from_dict
from reliability.model.poses import workspace_grid
from studies import cli

MILL = Path(__file__).parent / "machines" / "mill3.toml"
BOUNDS = '''
[bounds]
translation = [0.0012, 0.004]
rotation = [6e-6, 2e-5]
items = { "Z.dz" = [0.002, 0.006] }
'''


@pytest.fixture
def bounded(tmp_path):
    path = tmp_path / "bounded.toml"
    path.write_text(MILL.read_text() + BOUNDS)
    return path


def test_bounds_table_is_read_and_written_back(bounded):
    machine = load_machine(bounded)
    low, high = machine.tolerance_bounds
    z = machine.error_index("Z.dz")
    x = machine.error_index("X.dx")
    ex = machine.error_index("X.ex")
    assert (low[z], high[z]) == (0.002, 0.006) and (low[x], high[x]) == (0.0012, 0.004)
    assert (low[ex], high[ex]) == (6e-6, 2e-5)
    import tomllib
    again = machine_from_dict(tomllib.loads(machine.to_toml()))
    assert again == machine


@pytest.mark.parametrize("table, words", [
    ('translation = [0.004, 0.001]\nrotation = [1e-6, 2e-6]', "bounds.translation: lo"),
    ('translation = [0.001]\nrotation = [1e-6, 2e-6]', "expected [lo, hi]"),
    ('translation = [0, 0.001]\nrotation = [1e-6, 2e-6]', "bounds.translation"),
    ('rotation = [1e-6, 2e-6]', "missing key 'translation'"),
    ('translation = [0.001, 0.002]\nrotation = [1e-6, 2e-6]\nitems = { "Q.dx" = [1, 2] }',
     "bounds.items"),
    ('translation = [0.001, 0.002]\nrotation = [1e-6, 2e-6]\nwidth = 3', "width"),
])
def test_bad_bounds_tables_are_refused_naming_the_key(tmp_path, table, words):
    path = tmp_path / "bad.toml"
    path.write_text(MILL.read_text() + "\n[bounds]\n" + table + "\n")
    with pytest.raises(MachineDescriptionError, match=words.replace("[", r"\[")):
        load_machine(path)


def test_the_file_box_is_the_default_box_and_certified(bounded):
    machine = load_machine(bounded)
    poses = workspace_grid(machine, 3)
    problem = AllocationProblem.build(machine, poses)
    assert problem.bounds_source == "machine file"
    np.testing.assert_array_equal(problem.lower, machine.tolerance_bounds[0])
    np.testing.assert_array_equal(problem.upper, machine.tolerance_bounds[1])
    best = problem.solve_exact()
    assert best.certificate["certified"]
    assert np.all(best.tolerances >= problem.lower * (1 - 1e-12))
    assert np.all(best.tolerances <= problem.upper * (1 + 1e-12))
    factors = AllocationProblem.build(machine, poses, bounds=(0.5, 1.5))
    assert factors.bounds_source == "given"
    np.testing.assert_allclose(factors.lower, 0.5 * machine.initial_allocation)
    plain = AllocationProblem.build(load_machine(MILL), poses)
    assert plain.bounds_source == "factors of the initial allocation"


def test_report_names_the_box_and_its_source(bounded, tmp_path, capsys):
    out = tmp_path / "report"
    assert cli.main(["report", str(bounded), "--out", str(out), "--repeats", "2",
                     "--samples", "500", "--points", "3", "--machines", "400", "--skip", "front", "system",
                     "rare", "profiles"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["bounds_source"] == "machine file" and summary["bounds"] is None
    assert "machine file's [bounds]" in (out / "report.md").read_text()
    again = tmp_path / "again"
    assert cli.main(["report", str(bounded), "--out", str(again), "--repeats", "2",
                     "--samples", "500", "--points", "3", "--machines", "400", "--bounds", "0.5", "1.5",
                     "--workspace", "grid",
                     "--skip", "front", "system", "rare", "profiles"]) == 0
    assert json.loads((again / "summary.json").read_text())["bounds_source"] == "command line"
    capsys.readouterr()
