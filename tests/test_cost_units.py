"""[cost] units: the unit of t inside w / t², cost shares and nearly free items."""

from __future__ import annotations

import dataclasses
import tomllib
from pathlib import Path

import numpy as np
import pytest

from allocation import AllocationProblem, CostModel
from reliability.basics.errors import MachineDescriptionError
from reliability.model.machine_file import load_machine, machine_from_dict
from reliability.model.machine_checks import likely_mistakes

MILL = Path(__file__).parent / "machines" / "mill3.toml"
ARCSEC_PER_RAD = 180 * 3600 / np.pi


def _with_units(machine, units):
    costs = dataclasses.replace(machine.cost_coefficients, units=units)
    return dataclasses.replace(machine, cost_coefficients=costs)


def test_units_rescale_each_item_as_w_over_t_in_those_units(hobbing):
    plain = CostModel.from_machine(hobbing)  # the file states mm/rad
    micro = CostModel.from_machine(_with_units(hobbing, ("um", "arcsec")))
    t = hobbing.initial_allocation
    angular = np.array([n.split(".")[1].startswith("e") for n in hobbing.error_names])
    in_units = np.where(angular, t * ARCSEC_PER_RAD, t * 1000.0)  # t in µm and arcsec
    np.testing.assert_allclose(micro.item_costs(t), plain.weights / np.square(in_units),
                               rtol=1e-12)


def test_shares_sum_to_one_and_show_the_paper_machines_imbalance(hobbing):
    shares = CostModel.from_machine(hobbing).shares(hobbing.initial_allocation)
    assert shares.to_numpy().sum() == pytest.approx(1.0, abs=1e-12)
    assert shares["translational"].sum() == pytest.approx(2.12e-5, rel=0.01)
    micro = CostModel.from_machine(_with_units(hobbing, ("um", "arcsec")))
    assert micro.shares(hobbing.initial_allocation)["translational"].sum() == \
        pytest.approx(0.474, abs=0.001)


def test_nearly_free_items_are_at_a_bound_and_cheap(hobbing):
    result = AllocationProblem.build(hobbing).solve_exact()
    free = result.nearly_free()
    assert len(free) == 33 and all(".d" in name for name in free)
    frame = result.to_frame()
    costs = result.problem.cost.item_costs(result.tolerances)
    share = dict(zip(frame.index, costs / costs.sum()))
    assert all(frame.loc[name, "status"] in ("lower", "upper") and share[name] < 1e-3
               for name in free)
    micro = AllocationProblem.build(_with_units(hobbing, ("um", "arcsec"))).solve_exact()
    assert micro.nearly_free() == []


def test_units_are_read_written_back_and_refused_when_unknown(tmp_path):
    text = MILL.read_text().replace(
        "[cost]\n", '[cost]\nunits = { length = "um", angle = "arcsec" }\n')
    path = tmp_path / "units.toml"
    path.write_text(text)
    machine = load_machine(path)
    assert machine.cost_coefficients.units == ("um", "arcsec")
    assert "states no 'units'" not in " ".join(likely_mistakes(machine))
    assert "states no 'units'" in " ".join(likely_mistakes(load_machine(MILL)))
    assert machine_from_dict(tomllib.loads(machine.to_toml())) == machine
    for bad, words in (('{ length = "inch", angle = "rad" }', "units.length"),
                       ('{ length = "mm" }', "missing key 'angle'"),
                       ('"um"', "expected a table")):
        path.write_text(MILL.read_text().replace("[cost]\n", f"[cost]\nunits = {bad}\n"))
        with pytest.raises(MachineDescriptionError, match=words):
            load_machine(path)


def test_a_size_in_millimetres_is_refused_with_a_unit_hint(tmp_path):
    path = tmp_path / "mm.toml"
    path.write_text(MILL.read_text().replace("size = 1.2", "size = 2800.0", 1))  # 2800 mm
    with pytest.raises(MachineDescriptionError, match="in metres"):
        load_machine(path)
