"""Every printed number to the digits its computation fixes: the formatting helpers of
``reliability.basics.display`` by hand-computed cases, and the numbers ``precrel allocate``
prints."""

from __future__ import annotations

import contextlib
import io
import re
from pathlib import Path

import numpy as np
import pytest

from reliability.basics import display
from reliability.basics.errors import InputError
from reliability.basics.files import rounded_down, rounded_up
from studies import cli

MACHINES = Path(__file__).parent / "machines"


@pytest.mark.parametrize(("value", "unit", "text"), [
    (6.8178364e-3, "um", "6.817 µm"),      # rounded down, not to the nearest 6.818
    (0.0029, "um", "2.9 µm"),             # the file's 0.0029 mm, not 2.8999…
    (0.002, "mm", "0.002 mm"),
    (1.23456789e-3, "mm", "0.001234 mm"),  # 0.001 µm = 1e-6 mm
    (1e-5, "arcsec", "2.062 arcsec"),      # 1e-5 rad = 2.0626480… arcsec
    (1e-5, "rad", "0.00001 rad"),          # 8 decimals: 1e-8 rad = 0.0021 arcsec
    (0.0, "um", "0 µm"),
])
def test_a_tolerance_is_cut_to_a_thousandth_of_a_micrometre_or_arcsecond(value, unit, text):
    assert display.tolerance_text(value, unit) == text


@pytest.mark.parametrize(("fraction", "text"), [
    (2.2438941, "224.39 %"), (-0.5, "-50.00 %"), (0.0, "0 %"), (1e-6, "< 0.01 %"),
    (-1e-6, "> -0.01 %"), (0.000051, "0.01 %")])
def test_a_percentage_is_shown_to_a_hundredth_of_a_percent(fraction, text):
    assert display.percentage_text(fraction) == text


def test_a_percentage_that_bounds_is_rounded_to_its_safe_side():
    assert display.percentage_text(0.0012345, bound="upper") == "0.13 %"
    assert display.percentage_text(0.0012345, bound="lower") == "0.12 %"
    assert display.percentage_text(0.875, bound="lower") == "87.50 %"
    assert display.percentage_text(1e-9, bound="upper") == "0.01 %"     # never "0 %"


@pytest.mark.parametrize(("value", "text"), [
    (12.935616, "12.9"), (-1.204667, "-1.20"), (16.010119, "16.0"), (0.0, "0"),
    (1293.4, "1290"), (0.000123456, "0.000123"), (2.17304e11, "2.17e+11")])
def test_an_elasticity_has_three_significant_digits(value, text):
    assert display.significant_text(value) == text


def test_a_value_zero_to_rounding_is_shown_as_zero():
    assert display.resolved_text(-1.50314e-15, 1.0) == "0"          # 1e-12 of a σ of 1
    assert display.resolved_text(-1.50314e-15, 1.0, resolution=1e-16) == "-1.50314e-15"
    assert display.resolved_text(-1.50314e-9, 1e-3, digits=3) == "-1.50e-09"
    assert display.resolved_text(0.0, 0.0) == "0"


def test_a_bound_is_rounded_to_its_safe_side():
    assert display.upper_bound_text(2.04831e-05, 5) == "2.0484e-05"
    assert display.lower_bound_text(2.04831e-05, 5) == "2.0483e-05"
    assert display.upper_bound_text(-2.04831e-05, 5) == "-2.0483e-05"
    assert display.lower_bound_text(-2.04831e-05, 5) == "-2.0484e-05"
    assert display.upper_bound_text(0.0015, 2) == "0.0015"           # exact stays exact
    assert display.upper_bound_text(0.0, 3) == "0"
    assert display.quantity_bound_text(2.04831e-5, "mm", 5) == "2.0484e-05 mm"
    assert display.quantity_bound_text(2.04831e-5, "um", 5) == "0.020484 µm"


def test_the_ends_of_a_yield_interval_are_rounded_outward():
    # 1 - 0.99987654 = 1.2346e-4: two significant digits of it are five decimals
    assert display.probability_bound_text(0.99987654, upper=False, digits=2) == "0.99987"
    assert display.probability_bound_text(0.99987654, upper=True, digits=2) == "0.99988"
    assert display.probability_bound_text(0.25, upper=True) == "0.2500"
    assert display.probability_bound_text(0.83456, upper=False) == "0.8345"
    assert display.probability_bound_text(1.0, upper=True) == "1"
    assert display.interval_text(0.98123, 0.99501) == "[0.9812, 0.9951]"


def test_rounded_up_mirrors_rounded_down():
    np.testing.assert_array_equal(rounded_up([2.04831e-05, 0.0015, 9.9999], 3),
                                  [2.05e-05, 0.0015, 10.0])
    np.testing.assert_array_equal(rounded_down([2.04831e-05, 0.0015, 9.9999], 3),
                                  [2.04e-05, 0.0015, 9.99])
    with pytest.raises(InputError, match="values: entry 1"):
        rounded_up([1.0, -2.0])


#: A number in printed text: optional sign, digits, optional decimals and exponent.
NUMBER = re.compile(r"(?<![\w.])[-+]?\d+(?:\.(\d+))?(?:e[-+]?\d+)?")


def decimals_by_unit(text: str, unit: str) -> list[int]:
    """Decimals of every number printed just before ``unit``."""
    return [len(m.group(1) or "") for m in
            re.finditer(rf"[-+]?\d+(?:\.(\d+))?\s*{re.escape(unit)}(?!\w)", text)]


def allocate(folder: Path, machine: str) -> str:
    """What ``precrel allocate MACHINE --points 3 --workspace grid`` prints."""
    stdout = io.StringIO()
    with contextlib.redirect_stdout(stdout):
        assert cli.main(["allocate", machine, "--points", "3", "--workspace", "grid",
                         "--out", str(folder / "a.csv")]) == 0
    return stdout.getvalue()


#: Most decimals of a tolerance in each unit: 0.001 µm and 0.001 arcsec at most.
DECIMALS = {"mm": 6, "µm": 3, "rad": 8, "arcsec": 3}


def changes_rows(out: str) -> list[list[str]]:
    """The rows of the table of largest changes, split on blanks."""
    table = out.split("largest changes from the initial allocation")[1].split("\n\n")[0]
    return [line.split() for line in table.splitlines()[2:]]


@pytest.mark.parametrize("name", ["mill3", "swivel5"])
def test_allocate_prints_no_digit_past_its_rule(tmp_path, name):
    out = allocate(tmp_path, str(MACHINES / f"{name}.toml"))
    assert max(decimals_by_unit(out, "%")) <= 2                       # 0.01 %
    for unit, most in DECIMALS.items():
        assert max(decimals_by_unit(out, unit), default=0) <= most, unit
    rows = changes_rows(out)
    assert len(rows) == 10
    for row in rows:                  # ... unit initial allocated change %
        unit, initial, allocated, change = row[-5], row[-4], row[-3], row[-2]
        for value in (initial, allocated):
            assert len(value.partition(".")[2]) <= DECIMALS[unit], row
        assert re.fullmatch(r"[-+]?\d+\.\d\d", change) and row[-1] == "%", row
    table = out.split("requirements (elasticities")[1].split("\n\n")[0]
    for line in table.splitlines()[3:]:
        for number in NUMBER.finditer(" ".join(line.split()[3:])):
            digits = number.group(0).lstrip("-+").replace(".", "").lstrip("0")
            assert len(digits) <= 3, line                                  # 3 significant


def test_a_machine_in_micrometres_gets_its_changes_in_micrometres(tmp_path):
    units = {row[-5] for row in changes_rows(allocate(tmp_path, str(MACHINES /
                                                                      "swivel5.toml")))}
    assert units <= {"µm", "arcsec"} and units


def test_a_probability_that_bounds_from_below_is_rounded_down():
    assert display.percent_text(0.987656) == "98.7656 %"
    assert display.percent_text(0.98765649, lower=True) == "98.7656 %"
    assert display.percent_text(0.98765651, lower=True) == "98.7656 %"   # nearest: 98.7657
    # failure 2.0428e-14 rounded up to two digits: 2.1e-14, P never read above its bound
    assert display.percent_text(1 - 2.0428e-14, lower=True).endswith("(1 − 2.1e-14)")
    assert display.bound_text(0.1234567) == "0.123456"                  # Bonferroni, down
