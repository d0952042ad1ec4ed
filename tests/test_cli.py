"""The precrel command line on the test mill: outputs, exit codes, one-line errors, the
report's file contract."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from allocation import AllocationProblem
from reliability import workspace_grid
from studies import cli
from studies.cli import program
from studies.report.markdown import markdown_to_html
from studies.report.writer import rounded

MILL = str(Path(__file__).parent / "machines" / "mill3.toml")
QUICK = ["--repeats", "3", "--samples", "1000", "--points", "3", "--machines", "400"]


def run(capsys, *argv):
    code = cli.main(list(argv))
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def assert_one_line_error(code, err, *words):
    assert code == 2
    lines = err.strip().splitlines()  # progress lines may come before the error
    errors = [line for line in lines if line.startswith("precrel:")]
    assert len(errors) == 1 and lines[-1] == errors[0], err
    assert errors[0].startswith("precrel: error: "), err
    for word in words:
        assert word in errors[0]


@pytest.fixture(scope="module")
def allocation_csv(tmp_path_factory):
    path = tmp_path_factory.mktemp("alloc") / "allocation.csv"
    assert cli.main(["allocate", MILL, "--out", str(path), "--points", "3"]) == 0
    return path


@pytest.fixture(scope="module")
def report_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("report") / "mill"
    assert cli.main(["report", MILL, "--out", str(out), "--seed", "5", *QUICK]) == 0
    return out


def test_check_summarises_and_warns(capsys):
    code, out, _ = run(capsys, "check", MILL)
    assert code == 0
    assert "300 mm" in out                         # X stroke with its unit
    assert "30" in out and "errors" in out         # 3 axes x 6 + 2 joints x 6
    assert "0.015 mm" in out and "3e-05 rad" in out
    assert "initial allocation cost" in out and "2.47506e+11" in out
    assert "warnings (2)" in out  # mill3's first axis has an offset; its cost has no units
    assert "offset" in out.split("warnings (2)")[1] and "'units'" in out.split("warnings (2)")[1]


def test_predict_gives_worst_pose_as_axis_positions(capsys, mill3):
    code, out, _ = run(capsys, "predict", MILL, "--points", "3")
    assert code == 0
    # dx's worst pose of the initial allocation, found independently of the command:
    problem = AllocationProblem.build(mill3, workspace_grid(mill3, 3))
    sigma = problem.sigma(mill3.initial_allocation)[:, 0]
    pose = problem.poses[np.argmax(sigma)]
    dx_line = next(line for line in out.splitlines() if line.startswith("dx"))
    assert f"Y={pose[0]:.6g} mm, X={pose[1]:.6g} mm, Z={pose[2]:.6g} mm" in dx_line
    assert "NOT met by: dx" in out


def test_allocate_writes_the_csv_contract(allocation_csv, mill3, capsys):
    frame = pd.read_csv(allocation_csv)
    assert list(frame.columns) == ["error", "reference", "allocated"]
    assert list(frame["error"]) == list(mill3.error_names)
    np.testing.assert_allclose(frame["reference"], mill3.initial_allocation, rtol=1e-5)
    # The written allocation meets every target at every grid pose (6 significant
    # digits of rounding can only move it by ~1e-6 relative).
    problem = AllocationProblem.build(mill3, workspace_grid(mill3, 3))
    assert problem.violation(frame["allocated"].to_numpy() * (1 - 1e-5)) == 0


def test_allocate_elasticities_and_refusal(allocation_csv, capsys):
    code, out, err = run(capsys, "allocate", MILL, "--out", str(allocation_csv),
                         "--points", "3")
    assert_one_line_error(code, err, "exists", "--overwrite")
    code, out, _ = run(capsys, "allocate", MILL, "--out", str(allocation_csv),
                       "--points", "3", "--overwrite", "--lock", "Y.ex")
    assert code == 0 and "certified optimum: yes" in out and "1 locked" in out
    assert "dlncost/dln_limit" in out


def test_predict_reads_the_allocation_back(allocation_csv, capsys):
    code, out, _ = run(capsys, "predict", MILL, "--points", "3",
                       "--tolerances", str(allocation_csv))
    assert code == 0 and "every output meets its target" in out


def test_verify_prints_fosm_beside_monte_carlo(allocation_csv, capsys):
    code, out, _ = run(capsys, "verify", MILL, "--tolerances", str(allocation_csv), *QUICK)
    assert code == 0
    assert "grid experiments (3 x 27 poses)" in out
    assert "95% Wilson" in out and "worst pose" in out


def test_tolerance_file_names_are_checked(tmp_path, allocation_csv, capsys):
    frame = pd.read_csv(allocation_csv)
    renamed = frame.replace({"error": {"Y.dx": "Q.dx"}})
    renamed.to_csv(tmp_path / "unknown.csv", index=False)
    code, _, err = run(capsys, "predict", MILL, "--tolerances", str(tmp_path / "unknown.csv"))
    assert_one_line_error(code, err, "Q.dx")
    frame.iloc[1:].to_csv(tmp_path / "short.csv", index=False)
    code, _, err = run(capsys, "predict", MILL, "--tolerances", str(tmp_path / "short.csv"))
    assert_one_line_error(code, err, "missing", "Y.dx")
    # Rows in another order are aligned by name, not position.
    frame.iloc[::-1].to_csv(tmp_path / "reversed.csv", index=False)
    first = run(capsys, "predict", MILL, "--points", "3", "--tolerances", str(allocation_csv))
    second = run(capsys, "predict", MILL, "--points", "3",
                 "--tolerances", str(tmp_path / "reversed.csv"))
    assert first[1].splitlines()[1:] == second[1].splitlines()[1:]


@pytest.mark.parametrize("argv, words", [
    (["verify", MILL, "--tolerances", "x.csv", "--repeats", "0"], ["--repeats"]),
    (["verify", MILL, "--tolerances", "x.csv", "--seed", "-1"], ["--seed"]),
    (["predict", MILL, "--points", "1"], ["--points"]),
    (["allocate", MILL, "--out", "x.csv", "--bounds", "1.5", "0.5"], ["--bounds"]),
    (["allocate", MILL, "--out", "x.csv", "--target", "1.2"], ["--target"]),
    (["allocate", MILL, "--out", "x.csv", "--lock", "Q.dx"], ["Q.dx"]),
    (["check", "no-such-machine.toml"], ["no-such-machine.toml"]),
    (["predict", MILL, "--tolerances", "no-such.csv"], ["--tolerances no-such.csv", "No such file"]),
    (["frobnicate"], ["frobnicate"]),
])
def test_bad_input_is_one_line_and_exit_2(argv, words, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, out, err = run(capsys, *argv)
    assert_one_line_error(code, err, *words)
    assert out == ""  # refused before any work


def test_unreachable_target_is_one_line(tmp_path, capsys):
    code, _, err = run(capsys, "allocate", MILL, "--out", str(tmp_path / "a.csv"),
                       "--points", "3", "--bounds", "0.99", "1.0", "--target", "0.9999")
    assert_one_line_error(code, err, "unreachable")
    assert not (tmp_path / "a.csv").exists()


def test_report_contract(report_dir, mill3):
    summary = json.loads((report_dir / "summary.json").read_text())
    for key in ("machine", "points_per_axis", "side", "initial_cost", "optimal_cost",
                "relative_cost", "certified", "initial_meets_targets", "seed"):
        assert key in summary
    assert summary["machine"] == mill3.name and summary["seed"] == 5
    assert summary["points_per_axis"] == 3 and summary["side"] == "two_sided"
    assert summary["certified"] is True
    assert summary["initial_meets_targets"] is False  # dx falls short (see predict)
    assert summary["relative_cost"] == pytest.approx(
        summary["optimal_cost"] / summary["initial_cost"], rel=1e-5)
    frame = pd.read_csv(report_dir / "allocation.csv")
    assert list(frame.columns) == ["error", "reference", "allocated"]
    assert list(frame["error"]) == list(mill3.error_names)


def test_report_html_is_self_contained(report_dir):
    html = (report_dir / "report.html").read_text()
    assert html.count("data:image/png;base64,") >= 8
    assert "http://" not in html and "https://" not in html
    assert "Table 4" not in html and "Table 4" not in (report_dir / "report.md").read_text()
    markdown = (report_dir / "report.md").read_text()
    assert markdown.index("## Answers") < markdown.index("## Machine and requirements")
    for name in ("Y.dx", "X-Z.ex"):
        assert name in markdown


def test_report_refuses_an_earlier_report(report_dir, tmp_path, capsys):
    code, _, err = run(capsys, "report", MILL, "--out", str(report_dir), *QUICK)
    assert_one_line_error(code, err, "earlier report", "--overwrite")
    (tmp_path / "file").write_text("x")
    code, _, err = run(capsys, "report", MILL, "--out", str(tmp_path / "file"), *QUICK)
    assert_one_line_error(code, err, "is a file")


def test_report_overwrite_keeps_unrelated_files_and_numbers(report_dir, capsys):
    (report_dir / "notes.txt").write_text("mine")
    before = {p.name: p.read_bytes() for p in report_dir.glob("*.csv")}
    before["summary.json"] = (report_dir / "summary.json").read_bytes()
    code, _, _ = run(capsys, "report", MILL, "--out", str(report_dir), "--seed", "5",
                     "--overwrite", *QUICK)
    assert code == 0
    assert (report_dir / "notes.txt").read_text() == "mine"
    for name, data in before.items():  # same seed, same files
        assert (report_dir / name).read_bytes() == data, name


def test_a_report_rewritten_holds_one_report_and_the_user_s_files(tmp_path):
    """--overwrite removes what the earlier report wrote (its summary.json's ``files``) and
    this one does not; a file the report never wrote stays, and so do an earlier report's
    files when its summary.json lists none (0.3.0) or lists a path instead of a name."""
    from studies.report.section import Section
    from studies.report.writer import write_report
    table = pd.DataFrame({"a": [1.0]})
    first = [Section("One", "t", tables={"one.csv": table}),
             Section("Two", "t", tables={"two.csv": table})]
    write_report(tmp_path, first, {}, title="T")
    (tmp_path / "notes.txt").write_text("mine")
    write_report(tmp_path, first[:1], {}, title="T", overwrite=True)
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "notes.txt", "one.csv", "report.html", "report.md", "summary.json"]
    summary = json.loads((tmp_path / "summary.json").read_text())
    summary["files"] = ["../notes.txt", "notes.txt/"]
    (tmp_path / "summary.json").write_text(json.dumps(summary))
    (tmp_path / "old.csv").write_text("a\n1\n")  # a 0.3.0 report's table, unlisted
    write_report(tmp_path, first[:1], {}, title="T", overwrite=True)
    assert (tmp_path / "notes.txt").read_text() == "mine" and (tmp_path / "old.csv").exists()


def test_rounded_keeps_six_significant_digits():
    assert rounded({"a": 0.1234567891, "b": [2.0e-5 / 3], "c": np.float64(1e12 / 7),
                    "d": np.bool_(True), "e": np.int64(3)}) == {
        "a": 0.123457, "b": [6.66667e-06], "c": 142857000000.0, "d": True, "e": 3}


def test_markdown_to_html_tables_and_lists():
    html = markdown_to_html("Intro **bold** `x<y`\n\n| a | b |\n| --- | --- |\n| 1 | 2 |"
                            "\n\n- one\n- two")
    assert "<strong>bold</strong>" in html and "<code>x&lt;y</code>" in html
    assert "<th>a</th>" in html and "<td>2</td>" in html
    assert "<li>two</li>" in html


def test_python_m_studies_help():
    done = subprocess.run([sys.executable, "-m", "studies", "--help"], capture_output=True,
                          text=True, cwd=Path(__file__).parent.parent, timeout=120)
    assert done.returncode == 0
    for command in program.COMMANDS:
        assert command in done.stdout


def test_writer_takes_extra_sections(tmp_path):
    from studies.report.writer import write_report
    from studies.report.section import Section
    extra = Section("Extra", "| a |\n| --- |\n| 1 |", tables={"extra.csv": pd.DataFrame(
        {"a": [1.0 / 3]})}, summary={"extra_key": 2.0 / 3})
    written = write_report(tmp_path, [Section("First", "text"), extra], {"machine": "m"},
                           title="T")
    assert {p.name for p in written} == {"extra.csv", "report.md", "report.html",
                                         "summary.json"}
    assert (tmp_path / "extra.csv").read_text() == "a\n0.333333\n"
    assert json.loads((tmp_path / "summary.json").read_text()) == {
        "machine": "m", "extra_key": 0.666667,
        "files": ["extra.csv", "report.md", "report.html", "summary.json"]}
    assert "## Extra" in (tmp_path / "report.md").read_text()


def test_every_section_of_a_report_copes_with_targets_out_of_reach(tmp_path, capsys):
    out = tmp_path / "unreachable"
    tight = tmp_path / "tight.toml"
    tight.write_text(Path(MILL).read_text().replace("limit = 0.01,", "limit = 0.0001,"))
    code, printed, _ = run(capsys, "report", str(tight), "--out", str(out), *QUICK)
    assert code == 0 and "No allocation inside the box" in printed
    summary = json.loads((out / "summary.json").read_text())
    assert summary["reachable"] is False and summary["front_reached"] == 0
    assert (out / "initial_rare_events.csv").is_file()  # rare events of what exists
    assert "Targets out of reach" in (out / "report.md").read_text()


OPTIONAL_FILES = ("front.csv", "system_reliability.csv", "optimum_rare_events.csv",
                  "optimum_worst_pose_mc.csv", "profiles_comparison.csv")


def test_report_has_the_optional_sections(report_dir):
    for name in OPTIONAL_FILES:
        assert (report_dir / name).exists(), name
    summary = json.loads((report_dir / "summary.json").read_text())
    system = pd.read_csv(report_dir / "system_reliability.csv", index_col="allocation")
    # all six inside at once is no more likely than the least reliable output alone
    assert (system["system"] <= system["least_output"] + 4 * system["error"]).all()
    assert summary["front_points"] > 0 and summary["front_certified"] is True
    text = (report_dir / "report.md").read_text()
    for title in ("Cost against reliability", "System reliability", "worst poses"):
        assert title in text


@pytest.mark.xdist_group("lean_mill_report")
def test_report_skip_leaves_sections_out(lean_mill_report, tmp_path, capsys):
    out = lean_mill_report.folder  # --skip front system rare profiles
    assert (out / "report.html").is_file()
    assert not any((out / name).exists() for name in OPTIONAL_FILES)
    code, _, err = run(capsys, "report", MILL, "--out", str(tmp_path / "x"), "--skip", "tea")
    assert code == 2 and "tea" in err


def test_verify_precision_and_rare(allocation_csv, capsys):
    code, out, _ = run(capsys, "verify", MILL, "--tolerances", str(allocation_csv), *QUICK,
                       "--precision", "0.5", "--max-samples", "20000", "--rare",
                       "--max-evaluations", "3000")
    assert code == 0
    assert "Relative half-width target 0.5" in out
    assert "importance" in out and "system" in out


def test_front_command_writes_its_table(tmp_path, capsys):
    path = tmp_path / "front.csv"
    code, out, _ = run(capsys, "front", MILL, "--target", "0.9", "0.99", "0.999",
                       "--points", "3", "--out", str(path))
    assert code == 0
    frame = pd.read_csv(path)
    assert list(frame["target"]) == [0.9, 0.99, 0.999]
    assert frame["cost"].is_monotonic_increasing and frame["certified"].all()
    assert (frame["relative_gap"] == 1e-8).all()  # written as the bound "< 1e-8"


def test_front_on_an_unreachable_box_refuses_with_the_blocking_pose(capsys):
    code, out, err = run(capsys, "front", MILL, "--target", "0.99999999", "--points", "3")
    assert_one_line_error(code, err, "unreachable", "--bounds", " mm")
    assert out == ""


def test_front_prints_high_targets_with_their_failure_probability(capsys):
    code, out, _ = run(capsys, "front", MILL, "--target", "0.9", "0.999999999",
                       "--points", "3", "--bounds", "0.001", "1.5")
    assert code == 0
    assert "0.999999999 " in out and "1e-09" in out


def test_report_on_an_unreachable_box_is_written_and_says_how_to_proceed(tmp_path, capsys):
    out = tmp_path / "tight"
    code, printed, _ = run(capsys, "report", MILL, "--out", str(out), *QUICK, "--bounds", "1",
                           "1.01")
    assert code == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["reachable"] is False
    assert summary["optimal_cost"] is None and summary["relative_cost"] is None
    factor = summary["reaching_factor"]
    assert 0 < factor < 1 and "--bounds LO HI" in printed
    assert (out / "fosm_initial.csv").is_file() and (out / "blocking.csv").is_file()
    assert not (out / "allocation.csv").exists()
    # the factor is the largest that reaches the targets: just above it, no box does
    reached = run(capsys, "allocate", MILL, "--out", str(tmp_path / "a.csv"), "--points", "3",
                  "--bounds", f"{0.999 * factor:.6g}", "1.01")
    missed = run(capsys, "allocate", MILL, "--out", str(tmp_path / "b.csv"), "--points", "3",
                 "--bounds", f"{1.001 * factor:.6g}", "1.01")
    assert reached[0] == 0 and missed[0] == 2


def test_tolerances_may_name_errors_by_iso_symbol(allocation_csv, mill3, tmp_path, capsys):
    frame = pd.read_csv(allocation_csv)
    frame["error"] = [mill3.iso_names[mill3.error_index(n)] for n in frame["error"]]
    iso = tmp_path / "iso.csv"
    frame.to_csv(iso, index=False)
    by_name = run(capsys, "predict", MILL, "--points", "3", "--tolerances", str(allocation_csv))
    by_iso = run(capsys, "predict", MILL, "--points", "3", "--tolerances", str(iso))
    assert by_iso[0] == 0 and by_iso[1].replace(str(iso), "") == \
        by_name[1].replace(str(allocation_csv), "")
