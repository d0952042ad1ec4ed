"""Tolerances for drawings: rounded down to the resolution in µm and arcsec, written with
ISO 230-1 symbols and plain names, read back as they are, and still meeting the targets."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from allocation import AllocationProblem
from allocation.per_pose.result_files import (DRAWING_COLUMNS, DRAWING_FILE, drawing_frame,
                                     drawing_to_csv, drawing_tolerances, read_allocation_csv)
from reliability.basics.errors import InputError
from reliability.model.machine_file import machine_from_toml
from reliability.model.poses import workspace_grid
from studies import cli

MACHINES = Path(__file__).parent / "machines"
ARCSEC = math.pi / 648000.0


@pytest.fixture(scope="module")
def mill():
    return machine_from_toml((MACHINES / "mill3.toml").read_text())


@pytest.fixture(scope="module")
def optimum(mill):
    problem = AllocationProblem.build(mill, workspace_grid(mill, 3))
    return problem.solve_exact()


def test_each_tolerance_is_the_largest_multiple_of_the_resolution_not_above_it():
    texts, values = drawing_tolerances(
        ["X.dx", "X.dy", "X.ex", "X.ey"],
        [0.0034, np.nextafter(0.0034, 0.0), 2.96 * ARCSEC, 0.0021],
        resolution=(0.1, 0.5))
    assert texts == ["3.4", "3.3", "2.5", "433.0"]
    assert values[:2] == pytest.approx([0.0034, 0.0033], rel=1e-15)
    assert values[2] == pytest.approx(2.5 * ARCSEC, rel=1e-15)
    assert values[1] <= np.nextafter(0.0034, 0.0)


def test_a_tolerance_below_the_resolution_is_refused_by_name():
    with pytest.raises(InputError, match=r"'X\.ex'.*below the drawing resolution 0\.1 "
                                         r"arcsec"):
        drawing_tolerances(["X.dx", "X.ex"], [0.003, 0.05 * ARCSEC])


def test_the_drawing_reads_back_below_the_optimum_and_meets_the_targets(mill, optimum,
                                                                        tmp_path):
    path = drawing_to_csv(mill, optimum.tolerances, tmp_path / DRAWING_FILE)
    frame = pd.read_csv(path)
    assert tuple(frame.columns) == DRAWING_COLUMNS
    assert frame.loc[frame["error"] == "Y-X.ez", ["iso", "name", "unit"]].values.tolist() \
        == [["EC0X", "squareness between X and Y", "arcsec"]]
    read = read_allocation_csv(path, mill)
    assert np.all(read <= optimum.tolerances)
    shown = np.where(frame["unit"] == "um", read * 1e3, read / ARCSEC)
    assert np.all(optimum.tolerances - read < np.where(frame["unit"] == "um", 1e-4,
                                                       0.1 * ARCSEC))
    assert np.allclose(shown * 10, np.round(shown * 10), rtol=0, atol=1e-9)
    assert optimum.problem.meets_targets(read)


def test_the_reader_takes_other_units_and_refuses_one_that_does_not_fit(mill, tmp_path):
    frame = drawing_frame(mill, mill.initial_allocation)
    frame.loc[0, ["tolerance", "unit"]] = [str(mill.initial_allocation[0]), "mm"]
    frame.loc[3, ["tolerance", "unit"]] = [str(mill.initial_allocation[3] * 1e6), "µrad"]
    frame.to_csv(tmp_path / "edited.csv", index=False)
    read = read_allocation_csv(tmp_path / "edited.csv", mill)
    assert read[[0, 3]] == pytest.approx(mill.initial_allocation[[0, 3]], rel=1e-12)
    frame.loc[1, "unit"] = "arcsec"
    frame.to_csv(tmp_path / "bad.csv", index=False)
    with pytest.raises(InputError, match=r"bad\.csv: unit of 'Y\.dy' is 'arcsec'; "
                                         r"expected one of \('mm', 'um'\) for a length"):
        read_allocation_csv(tmp_path / "bad.csv", mill)


def test_allocate_writes_the_drawing_beside_out_and_predict_reads_it(tmp_path, capsys):
    machine = str(MACHINES / "mill3.toml")
    out = tmp_path / "alloc.csv"
    assert cli.main(["allocate", machine, "--out", str(out), "--workspace", "grid",
                     "--points", "3", "--drawing-resolution", "0.5", "1"]) == 0
    printed = capsys.readouterr().out
    drawing = tmp_path / "alloc.drawing.csv"
    assert f"drawing tolerances written to {drawing}" in printed
    assert not (tmp_path / DRAWING_FILE).exists()  # named from --out, never a fixed name
    assert "rounded down to 0.5 µm and 1 arcsec" in printed
    assert "meets the targets at the 27 poses of the problem: yes" in printed
    drawn = pd.read_csv(drawing)
    assert np.allclose(drawn["tolerance"] % np.where(drawn["unit"] == "um", 0.5, 1.0), 0)
    assert cli.main(["predict", machine, "--points", "3", "--tolerances",
                     str(drawing)]) == 0
    assert "every output meets its target" in capsys.readouterr().out
    assert cli.main(["allocate", machine, "--out", str(out), "--drawing", str(out),
                     "--overwrite"]) == 2
    assert f"--drawing {out} is also --out" in capsys.readouterr().err
