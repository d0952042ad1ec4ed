"""One reading of a tolerance per study: the machine file's [requirements] distribution,
--distribution on the commands, distribution= in Python, named in every output."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from scipy.stats import norm

from allocation import AllocationProblem
from reliability import load_machine, machine_from_dict
from reliability.basics.errors import InputError, MachineDescriptionError
from reliability.first_order.fosm import error_sigma
from reliability.model.machine import machine_to_dict
from reliability.model.poses import workspace_grid
from reliability.sampling.verification import verify
from studies import cli
from studies.workflows.sweep import SweepSpec

MILL = Path(__file__).parent / "machines" / "mill3.toml"
#: σ of N(0, 1) truncated at ±3, closed form.
TRUNCATED_RATIO = np.sqrt(1 - 2 * 3 * norm.pdf(3) / (2 * norm.cdf(3) - 1))


def truncated_file(tmp_path, value="truncated") -> Path:
    text = MILL.read_text(encoding="utf-8").replace(
        "[requirements]", f'[requirements]\ndistribution = "{value}"', 1)
    path = tmp_path / "mill_truncated.toml"
    path.write_text(text, encoding="utf-8")
    return path


def test_machine_file_reading_and_round_trip(tmp_path):
    assert load_machine(MILL).distribution == "normal"  # the default
    machine = load_machine(truncated_file(tmp_path))
    assert machine.distribution == "truncated"
    again = machine_from_dict(machine_to_dict(machine))
    assert again == machine and again.distribution == "truncated"
    assert "distribution" not in machine_to_dict(load_machine(MILL))["requirements"]
    with pytest.raises(MachineDescriptionError, match="requirements.distribution"):
        load_machine(truncated_file(tmp_path, "uniform"))
    with pytest.raises(InputError, match="distribution"):
        dataclasses.replace(machine, distribution="lognormal")


def test_allocation_constrains_the_truncated_sigma(mill3):
    """Under 'truncated' every row is the normal row times the truncated variance ratio,
    so the optimal tolerances are the normal ones divided by the σ ratio (0.98658)."""
    poses = workspace_grid(mill3, 3)
    normal = AllocationProblem.build(mill3, poses)
    truncated = AllocationProblem.build(mill3, poses, distribution="truncated")
    assert truncated.distribution == "truncated"
    assert truncated.spread == pytest.approx(TRUNCATED_RATIO, rel=1e-12)
    assert normal.spread == 1.0
    t = mill3.initial_allocation
    np.testing.assert_allclose(truncated.sigma(t), normal.sigma(t) * TRUNCATED_RATIO,
                               rtol=1e-12)
    np.testing.assert_allclose(error_sigma(t, 3, "truncated"), t / 3 * TRUNCATED_RATIO,
                               rtol=1e-12)
    frame = truncated.evaluate(t)
    assert (frame["exact_two_sided"] != frame["worst_two_sided"]).all()


def test_verification_draws_under_the_study_reading(tmp_path):
    machine = load_machine(truncated_file(tmp_path))
    check = verify(machine, machine.initial_allocation, points=3, repeats=2, samples=500,
                   rng=3)
    assert check.distribution == "truncated" and check.grid.distribution == "truncated"
    assert "truncated at ±t" in check.summary()
    normal = verify(machine, machine.initial_allocation, points=3, repeats=2, samples=500,
                    rng=3, distribution="normal")
    assert normal.grid.distribution == "normal"
    with pytest.raises(InputError, match="reading"):
        verify(machine, machine.initial_allocation, points=3, repeats=1, samples=10,
               prediction=normal.fosm)


def test_commands_name_the_reading(tmp_path, capsys):
    path = str(truncated_file(tmp_path))
    assert cli.main(["predict", path, "--points", "3"]) == 0
    out = capsys.readouterr().out
    assert "truncated at +-t" in out and "P exact linear" in out
    assert cli.main(["predict", path, "--points", "3", "--distribution", "normal"]) == 0
    out = capsys.readouterr().out
    assert "distribution 'normal'" in out and "P exact linear" not in out
    csv = tmp_path / "a.csv"
    assert cli.main(["allocate", path, "--points", "3", "--out", str(csv)]) == 0
    out = capsys.readouterr().out
    assert "truncated at +-t" in out and "exact linear" in out
    assert cli.main(["predict", path, "--distribution", "uniform"]) == 2


def test_sweep_spec_key():
    spec = SweepSpec.from_dict({"machines": [str(MILL)], "distribution": "truncated"})
    assert {task.distribution for task in spec.tasks()} == {"truncated"}
    plain = SweepSpec.from_dict({"machines": [str(MILL)]}).tasks()[0]
    assert "distribution" not in plain.parameters()  # old stores keep their hashes
    with pytest.raises(InputError, match="distribution"):
        SweepSpec.from_dict({"machines": [str(MILL)], "distribution": "uniform"})
