"""Where files may be written (one check for the library and the command line), the
allocation CSV's one writer and one reader, and the result store's records."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from allocation import AllocationProblem
from allocation.per_pose.result_files import allocation_to_csv, read_allocation_csv
from reliability.basics.errors import InputError, InputTypeError, SavedResultError
from reliability.basics.files import check_destination
from reliability.basics.result_store import ResultStore
from reliability.model.poses import workspace_grid
from studies.cli.options import destination


def test_a_new_file_in_an_existing_folder_is_accepted(tmp_path):
    assert check_destination(tmp_path / "new.csv") == tmp_path / "new.csv"
    assert check_destination(str(tmp_path / "new"), folder=True) == tmp_path / "new"


@pytest.mark.parametrize("case, error, words", [
    ("existing file", FileExistsError, ["taken.csv", "overwrite=True"]),
    ("folder for a file", IsADirectoryError, ["is a folder"]),
    ("missing parent", FileNotFoundError, ["does not exist"]),
    ("file for a folder", NotADirectoryError, ["expected a folder"]),
    ("earlier report", FileExistsError, ["report.md", "overwrite=True"]),
    ("overwrite not a bool", InputTypeError, ["overwrite", "1"]),
    ("path not a path", InputTypeError, ["path", "int"]),
    ("empty path", InputError, ["empty"]),
])
def test_refusals_name_the_path_and_what_was_expected(tmp_path, case, error, words):
    (tmp_path / "taken.csv").write_text("x")
    (tmp_path / "old").mkdir()
    (tmp_path / "old" / "report.md").write_text("x")
    calls = {
        "existing file": lambda: check_destination(tmp_path / "taken.csv"),
        "folder for a file": lambda: check_destination(tmp_path),
        "missing parent": lambda: check_destination(tmp_path / "no" / "file.csv"),
        "file for a folder": lambda: check_destination(tmp_path / "taken.csv", folder=True),
        "earlier report": lambda: check_destination(tmp_path / "old", folder=True,
                                                    markers=("summary.json", "report.md")),
        "overwrite not a bool": lambda: check_destination(tmp_path / "a.csv", 1),
        "path not a path": lambda: check_destination(3),
        "empty path": lambda: check_destination(""),
    }
    with pytest.raises(error) as caught:
        calls[case]()
    assert all(word in str(caught.value) for word in words)


def test_overwrite_and_unrelated_files_in_a_report_folder_are_accepted(tmp_path):
    (tmp_path / "taken.csv").write_text("x")
    (tmp_path / "old").mkdir()
    (tmp_path / "old" / "notes.txt").write_text("x")
    assert check_destination(tmp_path / "taken.csv", True) == tmp_path / "taken.csv"
    assert check_destination(tmp_path / "old", folder=True, markers=("report.md",))


def test_the_command_line_rewords_refusals_with_its_options(tmp_path):
    (tmp_path / "taken.csv").write_text("x")
    (tmp_path / "old").mkdir()
    (tmp_path / "old" / "summary.json").write_text("{}")
    with pytest.raises(InputError, match=r"--out .*taken.csv: exists; pass --overwrite"):
        destination(tmp_path / "taken.csv", False)
    with pytest.raises(InputError, match=r"holds an earlier report \(summary.json\); pass "
                                         r"--overwrite"):
        destination(tmp_path / "old", False, folder=True, markers=("summary.json",))
    with pytest.raises(InputError, match="--store .*is a folder"):
        destination(tmp_path, False, "--store")


@pytest.fixture(scope="module")
def mill_result(mill3):
    problem = AllocationProblem.build(mill3, workspace_grid(mill3, 3), side="two_sided")
    return problem.solve_exact()


def test_allocation_csv_round_trip_all_digits_and_six(mill_result, mill3, tmp_path):
    exact = read_allocation_csv(allocation_to_csv(mill_result, tmp_path / "a.csv"), mill3)
    np.testing.assert_array_equal(exact, mill_result.tolerances)
    six = read_allocation_csv(allocation_to_csv(mill_result, tmp_path / "b.csv",
                                                significant=6), mill3)
    np.testing.assert_allclose(six, mill_result.tolerances, rtol=1e-5, atol=0)
    assert not np.array_equal(six, mill_result.tolerances)  # digits really were cut
    text = (tmp_path / "b.csv").read_text().splitlines()
    assert text[0] == "error,reference,allocated"
    cells = [float(cell) for line in text[1:] for cell in line.split(",")[1:]]
    assert all(value == float(f"{value:.6g}") for value in cells)


def test_allocation_csv_reader_refuses_a_damaged_file_naming_it(mill3, tmp_path):
    frame = pd.DataFrame({"error": list(mill3.error_names),
                          "allocated": mill3.initial_allocation})
    frame.iloc[1:].to_csv(tmp_path / "short.csv", index=False)
    with pytest.raises(InputError, match=r"short.csv: 1 error\(s\) missing"):
        read_allocation_csv(tmp_path / "short.csv", mill3)
    reordered = frame.iloc[::-1]
    reordered.to_csv(tmp_path / "reversed.csv", index=False)
    np.testing.assert_array_equal(read_allocation_csv(tmp_path / "reversed.csv", mill3),
                                  mill3.initial_allocation)


def test_result_store_round_trip_keeps_values_and_refuses_other_types(tmp_path):
    store = ResultStore(tmp_path / "tasks", version="1.0")
    parameters = {"machine": "mill3", "seed": np.int64(3), "target": 0.99}
    result = {"inside": np.array([[5, 6], [7, 8]]), "cost": np.float64(0.8), "ok": True}
    assert parameters not in store and store.load(parameters) is None
    path = store.save(parameters, result)
    assert path.parent == tmp_path / "tasks" and parameters in store
    assert store.load(parameters) == {"inside": [[5, 6], [7, 8]], "cost": 0.8, "ok": True}
    assert ResultStore(tmp_path / "tasks", version="1.1").load(parameters) is None
    path.write_text(path.read_text().replace("0.8", "0.9"))
    with pytest.raises(SavedResultError, match="checksum"):
        store.load(parameters)
    with pytest.raises(InputTypeError, match="cannot save a set"):
        store.save(parameters, {"names": {"a"}})
