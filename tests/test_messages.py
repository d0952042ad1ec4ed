"""Messages and printed numbers: plain numbers, sentences, close names instead of every
name, the micro sign in cost units, unit warnings on every input, poses by their axis
positions and only the digits the computation fixes."""

from __future__ import annotations

import copy
import re
import tomllib
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from allocation import AllocationProblem, load_catalogue, solve_catalogue
from allocation.catalogue.catalogue import Catalogue, unit_warnings
from allocation.machine_yield.yield_words import gap_line
from allocation.catalogue.discrete import neighbour_table
from allocation.per_pose.result_files import read_allocation_csv
from reliability import MachineDescriptionError, load_machine, machine_from_dict, workspace_grid
from reliability.acceptance import definitions
from reliability.basics.display import pose_text
from reliability.basics.errors import InputError
from reliability.model.machine_checks import likely_mistakes, tolerance_warnings
from studies import cli
from studies.cli.options import percent

HERE = Path(__file__).parent
MILL_FILE = HERE / "machines" / "mill3.toml"
SWIVEL_FILE = HERE / "machines" / "swivel5.toml"
MILL = load_machine(MILL_FILE)
SWIVEL = load_machine(SWIVEL_FILE)
CATALOGUE = tomllib.loads((HERE / "catalogues" / "mill3.toml").read_text(encoding="utf-8"))


def _allocation_csv(path, values):
    rows = [f"{name},{value},{value}" for name, value in zip(MILL.error_names, values)]
    path.write_text("error,reference,allocated\n" + "\n".join(rows) + "\n", encoding="utf-8")
    return path


def _swivel_dict():
    return tomllib.loads(SWIVEL_FILE.read_text(encoding="utf-8"))


def test_a_bad_tolerance_is_quoted_as_a_plain_number(tmp_path):
    values = MILL.initial_allocation.copy()
    values[0] = -1e-5
    with pytest.raises(InputError) as caught:
        read_allocation_csv(_allocation_csv(tmp_path / "t.csv", values), MILL)
    assert "allocated value of 'Y.dx' is -1e-05;" in str(caught.value)
    assert "np." not in str(caught.value)


def test_a_circle_leaving_the_stroke_is_one_sentence():
    data = {"tests": [{"name": "circle", "kind": "circular", "plane": "xy", "limit": 0.01,
                       "centre": {"C": 0.0, "Y": 260.0, "X": 0.0, "Z": 250.0, "B": 0.0},
                       "radius": 300.0}]}
    with pytest.raises(InputError) as caught:
        definitions.parse_tests(data, SWIVEL)
    assert "with radius 300 mm, the position 560 mm of axis 'Y' lies outside its stroke" \
        in str(caught.value)


def test_a_typo_in_a_components_items_is_named_with_its_close_names():
    data = copy.deepcopy(CATALOGUE)
    data["components"][0]["items"] = ["X.dxx"]
    with pytest.raises(InputError) as caught:
        Catalogue.from_dict(data, machine=MILL)
    message = str(caught.value)
    assert "component 'X ball screw': unknown item 'X.dxx' (did you mean 'X.dx'" in message
    assert "class" not in message


def test_a_typo_in_the_machine_file_suggests_names_instead_of_listing_all():
    data = _swivel_dict()
    data["initial_allocation"]["items"] = {"X.dxx": 0.003}
    with pytest.raises(MachineDescriptionError) as caught:
        machine_from_dict(data)
    message = str(caught.value)
    assert "unknown key 'X.dxx' (did you mean 'X.dx'" in message
    assert "the 54 errors are named" in message and "EXC" not in message


@pytest.mark.parametrize("length, angle", [("µm", "µrad"), ("μm", "μrad")])
def test_micro_sign_and_greek_mu_are_read_as_um(length, angle):
    data = _swivel_dict()
    data["cost"]["units"] = {"length": length, "angle": angle}
    assert machine_from_dict(data).cost_coefficients.units == ("um", "urad")


def test_tolerances_in_um_are_flagged_by_item_value_and_unit():
    t = MILL.initial_allocation.copy()
    t[MILL.error_index("X.dx")] = 3.0  # 3 µm written as mm
    t[MILL.error_index("Z.ex")] = 2.5  # 2.5 arcsec written as rad
    warnings = tolerance_warnings(MILL, t, "alloc.csv")
    assert len(warnings) == 2
    assert "alloc.csv: the tolerance of X.dx is 3 mm" in warnings[0] and "µm" in warnings[0]
    assert "the tolerance of Z.ex is 2.5 rad" in warnings[1] and "arc" in warnings[1]
    assert tolerance_warnings(MILL, MILL.initial_allocation) == []


def test_bounds_limits_and_catalogue_tolerances_in_um_are_flagged():
    data = _swivel_dict()
    data["bounds"]["translation"] = [1.5, 12.0]
    assert any("bounds: the upper bound of C.dx is 12 mm" in w
               for w in likely_mistakes(machine_from_dict(data)))
    catalogue = copy.deepcopy(CATALOGUE)
    catalogue["components"][0]["classes"][0]["tolerances"]["X.dx"] = 8.7
    (warning,) = unit_warnings(Catalogue.from_dict(catalogue, source="cat.toml"))
    assert "class 'C7': the tolerance of X.dx is 8.7 mm" in warning
    tests = definitions.read_tests(HERE.parent / "docs" / "examples" / "trunnion5_tests.toml",
                                   load_machine(HERE / "machines" / "trunnion5.toml"))
    assert definitions.unit_warnings(tests) == []
    tests = (SimpleNamespace(name="circle", limits={"G": 8.0}),)
    (warning,) = definitions.unit_warnings(tests, "t.toml")
    assert "t.toml: test 'circle': the limit on G is 8 mm" in warning


def test_commands_warn_on_stderr_once_and_go_on(tmp_path, capsys):
    t = MILL.initial_allocation.copy()
    t[MILL.error_index("X.dx")] = 3.0
    path = _allocation_csv(tmp_path / "um.csv", t)
    assert cli.main(["predict", str(MILL_FILE), "--tolerances", str(path),
                     "--points", "2"]) == 0
    err = capsys.readouterr().err
    assert err.count("warning: ") == 1 and "the tolerance of X.dx is 3 mm" in err


def test_poses_are_shown_to_the_resolution_the_search_fixes():
    text = pose_text(np.radians([-3.60682e-05, 89.9994, 144.0]) , ("B", "C", "A"),
                     ("rad", "rad", "rad"), digits=6)
    assert text == "B=0 deg, C=89.999 deg, A=144 deg"


def test_a_probability_near_one_shows_only_the_digits_it_has():
    text = percent(1 - 2.02e-14)
    assert text == "> 99.99999999999 % (1 − 2.0e-14)"
    assert percent(0.95) == "95.0000 %"


def test_a_gap_is_shown_rounded_up_to_a_hundredth_of_a_percent():
    """79.41686 % and 192.1888 % are printed as 79.42 % and 192.19 %: a gap is never shown
    smaller than it is."""
    result = SimpleNamespace(initial_cost=1.0, gap=1.921888, gap_of_cost=0.7941686)
    assert gap_line(result).startswith(
        "gap 79.42 % of the verified cost (192.19 % of the initial cost)")


def test_catalogue_poses_are_named_by_their_positions():
    problem = AllocationProblem.build(MILL, workspace_grid(MILL, 3))
    result = solve_catalogue(problem, load_catalogue(HERE / "catalogues" / "mill3.toml"))
    position = r"Y=-?[\d.]+ mm, X=-?[\d.]+ mm, Z=-?[\d.]+ mm"
    looser = neighbour_table(result)["looser"]
    broken = looser[looser.str.contains("breaks")]
    assert len(broken) and broken.str.fullmatch(rf"\S+: breaks d[xyz] at {position}").all()
    assert result.binding()["worst_pose"].str.fullmatch(position).all()
    moved = result.neighbours[~result.neighbours["meets"].astype(bool)]
    assert moved[["Y_mm", "X_mm", "Z_mm"]].notna().all().all()
    assert re.search(r"\(pose \d+\)", result.summary()) is None
