"""Tables for people in the machine file's units with ISO 230-1 symbols and plain names,
and advice ranked by what each change buys."""

from __future__ import annotations

import math
import re
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest
from scipy.stats import norm

from allocation import AllocationProblem
from reliability.basics.display import in_units, quantity_text
from reliability.first_order.fosm import fosm
from reliability.model.identifiability import indistinguishable_groups
from reliability.model.iso_names import plain_names
from reliability.model.machine_file import machine_from_toml
from reliability.model.poses import workspace_grid
from studies import cli
from studies.report.machine_sections import advice, buy_ratios, in_people_units, \
    tolerance_table

MACHINES = Path(__file__).parent / "machines"
ARCSEC = math.pi / 648000.0


@pytest.fixture(scope="module")
def swivel():
    return machine_from_toml((MACHINES / "swivel5.toml").read_text())


@pytest.fixture(scope="module")
def mill():
    return machine_from_toml((MACHINES / "mill3.toml").read_text())


def test_plain_names_follow_each_axis_direction(swivel):
    names = dict(zip(swivel.error_names, plain_names(swivel)))
    assert [names[n] for n in ("X.dx", "X.dy", "X.ex", "X.ey", "X.ez", "Z.ex", "Z.ez")] == [
        "X positioning", "X straightness in y", "X roll", "X pitch", "X yaw",
        "Z tilt about x", "Z roll"]
    assert [names[n] for n in ("C.dx", "C.dz", "C.ey", "C.ez", "B.ey")] == [
        "C radial motion in x", "C axial motion", "C tilt about y", "C angular positioning",
        "B angular positioning"]
    assert [names[n] for n in ("Y-X.ez", "C-Y.ez", "X-Z.ey", "Z-B.ey", "Z-B.dx")] == [
        "squareness between X and Y", "squareness between Y and X",
        "squareness between Z and X", "zero position of B",
        "position of the B axis line in x"]
    assert len(set(names.values())) == swivel.n_errors


def test_lengths_and_angles_are_shown_in_the_stated_units():
    assert quantity_text(0.0034, "um") == "3.4 µm"
    assert quantity_text(8e-5, "arcsec", 6) == "16.5012 arcsec"
    assert in_units([0.0025, ARCSEC, 1e-6], ["um", "arcsec", "urad"]) == \
        pytest.approx([2.5, 1.0, 1.0], rel=1e-12)


def test_report_tables_show_the_files_units_with_symbols_and_names(swivel, mill):
    table = tolerance_table(swivel, swivel.initial_allocation, swivel.initial_allocation / 2)
    row = table.set_index("error").loc["Y-X.ez"]
    assert (row.iso, row["name"], row.unit) == ("EC0X", "squareness between X and Y",
                                                 "arcsec")
    assert (row.initial, row.allocated, row.change) == pytest.approx(
        (2e-5 / ARCSEC, 1e-5 / ARCSEC, -0.5), rel=1e-12)
    for machine, shown in ((swivel, (25.0, 8e-5 / ARCSEC, "µm", "arcsec")),
                           (mill, (mill.limits[0], mill.limits[3], "mm", "rad"))):
        limits = pd.DataFrame({"output": ["dx", "dy", "dz", "ex", "ey", "ez"],
                               "limit": machine.limits, "unit": ["mm"] * 3 + ["rad"] * 3})
        people = in_people_units(machine, limits, "limit")
        assert (people["limit"][0], people["limit"][3]) == pytest.approx(shown[:2], rel=1e-12)
        assert (people["unit"][0], people["unit"][3]) == shown[2:]


def test_predict_prints_limits_in_the_files_units(capsys):
    assert cli.main(["predict", str(MACHINES / "swivel5.toml"), "--points", "3"]) == 0
    rows = capsys.readouterr().out.splitlines()
    assert re.match(r"dx\s+25 µm\s", next(r for r in rows if r.startswith("dx")))
    assert re.match(r"ez\s+16\.5012 arcsec\s", next(r for r in rows if r.startswith("ez")))


def _failures(machine, poses, t) -> float:
    """Σ over outputs of the two-sided failure probability at the given pose of each."""
    sigma = np.sqrt(np.einsum("on,n->o", machine.jacobian(poses)[np.arange(6), np.arange(6)]
                              ** 2, (t / 3.0) ** 2))
    return float(np.sum(2.0 * norm.sf(machine.limits / sigma)))


@pytest.fixture(scope="module")
def mill_study(mill):
    """What the ranking reads of a study, on the mill's 3-point grid; the optimum tightens
    every item by 30 %."""
    grid = workspace_grid(mill, 3)
    start = mill.initial_allocation
    return SimpleNamespace(
        machine=mill, side="two_sided", problem=AllocationProblem.build(mill, grid),
        initial_fosm=fosm(mill, start, grid), optimum=SimpleNamespace(tolerances=0.7 * start))


def _entries(mill_study):
    """Each single error and each group of errors that cannot be told apart, as members."""
    groups = indistinguishable_groups(mill_study.machine, mill_study.problem.poses)
    grouped = {name for group in groups for name in group}
    return {**{name: [name] for name in mill_study.machine.error_names if name not in grouped},
            **{tuple(group): list(group) for group in groups}}


def _difference_ratio(study, members, h=1e-4) -> float:
    """Failure probability removed per 1 % of the initial cost, by central differences."""
    machine, t = study.machine, study.problem.reference
    poses = study.initial_fosm.poses[study.initial_fosm.worst_pose]
    index = [machine.error_index(name) for name in members]
    up, down = t.copy(), t.copy()
    up[index] *= math.exp(h)
    down[index] *= math.exp(-h)
    cost = study.problem.cost
    removed = _failures(machine, poses, up) - _failures(machine, poses, down)
    spent = (cost.total(down) - cost.total(up)) / (cost.total(t) / 100.0)
    return removed / spent


def test_the_buy_ratio_is_the_failure_probability_removed_per_percent_of_cost(mill_study):
    entries = _entries(mill_study)
    group = next(members for key, members in entries.items() if isinstance(key, tuple))
    ratios = buy_ratios(mill_study, {"g": group})
    for name in ("X.dx", "Y.ez", "g"):
        members = group if name == "g" else [name]
        assert ratios[name] == pytest.approx(_difference_ratio(mill_study, members), rel=1e-6)


def test_tighten_lists_the_ten_that_buy_most_first(mill_study):
    tighten, relax = advice(mill_study)
    assert relax == ""
    shown = re.findall(r"(?:^|\); )([^();]+?) \(", tighten)
    assert len(shown) == 10
    ratios = {key: _difference_ratio(mill_study, members)
              for key, members in _entries(mill_study).items()}
    assert tighten.endswith(f" and {len(ratios) - 10} more")
    ranked = sorted(ratios.values(), reverse=True)
    listed = []
    for name in shown:
        key = name if name in ratios else next(
            k for k in ratios if isinstance(k, tuple) and re.search(
                rf"{re.escape(name)} \(\d+ items: {re.escape(k[0])},", tighten))
        listed.append(ratios[key])
    assert listed == pytest.approx(ranked[:10], rel=1e-5)


def test_with_positions_shows_a_pose_by_where_it_is_not_by_its_row():
    from reliability.basics.display import with_positions
    frame = pd.DataFrame({"output": ["dx", "ez"], "pose": [7, 3], "X": [-300.0, 0.0],
                          "A": [math.pi / 4, -math.pi / 2], "load": [1.5, 1.2]})
    shown = with_positions(frame, ("X", "A"), ("mm", "rad"))
    assert list(shown.columns) == ["output", "X_mm", "A_deg", "load"]
    np.testing.assert_allclose(shown["A_deg"], [45.0, -90.0])
    np.testing.assert_array_equal(shown["X_mm"], [-300.0, 0.0])
    assert list(frame.columns) == ["output", "pose", "X", "A", "load"]  # left as it was
