"""Numbers a user can trust: one tie rule, one stream per seed, files others can read, no
partial reports, bounds that are probabilities, digits the computation fixes."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from allocation.per_pose.result_files import (GAP_SHOWN, allocation_to_csv, gap_bound, gap_text,
                                     read_allocation_csv)
from reliability.basics.display import bound_text, pose_text, target_text
from reliability.basics.files import as_written, atomic_write_text
from reliability.basics.ties import lexicographic_rank, worst_rows
from reliability.first_order.fosm import fosm
from reliability.model.poses import workspace_grid
from reliability.sampling.verification import verify
from studies import cli
from studies.cli.options import percent
from studies.report import writer

MACHINES = Path(__file__).parent / "machines"
MILL = str(MACHINES / "mill3.toml")
TRUNNION = str(MACHINES / "trunnion5.toml")
QUICK = ["--repeats", "3", "--samples", "1000", "--points", "3", "--machines", "400"]
SKIP_EXTRAS = ["--skip", "front", "system", "rare", "profiles"]


# ----- the tie rule ---------------------------------------------------------------------
def test_ties_go_to_the_lexicographically_first_pose():
    poses = np.array([[2.0, 0.0], [1.0, 5.0], [1.0, 3.0], [0.0, 9.0]])
    # rows 0, 1, 2 tie within 1e-9; row 3 is clearly smaller
    values = np.array([1.0, 1.0 + 4e-10, 1.0 - 4e-10, 0.5])
    assert worst_rows(values, poses) == 2  # (1, 3) comes first among the tied
    assert worst_rows(values, poses, rtol=1e-12) == 1  # no tie: the largest
    assert worst_rows(-values, poses, largest=False) == 2
    columns = np.column_stack([values, values[::-1]])
    np.testing.assert_array_equal(worst_rows(columns, poses), [2, 3])
    np.testing.assert_array_equal(lexicographic_rank(poses), [3, 2, 1, 0])


def test_fosm_worst_pose_of_a_symmetric_machine_is_the_same_whatever_the_rounding(
        trunnion5):
    poses = workspace_grid(trunnion5, 5)
    t = trunnion5.initial_allocation
    result = fosm(trunnion5, t, poses)
    # perturb σ by summation-sized noise: the chosen worst poses must not move
    noisy = result.sigma * (1 + 1e-13 * np.random.default_rng(3).standard_normal(
        result.sigma.shape))
    again = type(result).worst_rows(trunnion5.limits, noisy, result.mean, poses)
    np.testing.assert_array_equal(again, result.worst_pose)
    # and each is the first of its ties in lexicographic order
    rank = lexicographic_rank(poses)
    for o, row in enumerate(result.worst_pose):
        tied = np.flatnonzero(result.sigma[:, o] >= result.sigma[row, o] * (1 - 1e-9))
        assert rank[row] == rank[tied].min()


# ----- one number per question -----------------------------------------------------------
@pytest.mark.xdist_group("lean_mill_report")
def test_report_and_verify_print_the_same_monte_carlo_numbers(lean_mill_report, capsys):
    out = lean_mill_report.folder
    assert cli.main(["verify", MILL, "--tolerances", str(out / "allocation.csv"),
                     "--seed", "4", *QUICK]) == 0
    printed = capsys.readouterr().out
    table = pd.read_csv(out / "worst_pose_mc.csv").query("allocation == 'optimum'")
    for row in table.itertuples():
        line = next(line for line in printed.splitlines()
                    if line.startswith(row.output) and "deg" not in line and "mm" in line)
        assert f"{100 * row.mc_estimate:.3f}" in line
    grid = pd.read_csv(out / "fosm_vs_mc.csv").query("allocation == 'optimum'")
    for row in grid.itertuples():
        assert f"{100 * row.mc_estimate:.3f}" in printed


def test_the_report_verifies_the_allocation_as_written(tmp_path, mill3):
    from studies.workflows import machine_study

    study = machine_study.run(mill3, points=3, repeats=2, samples=500, rng=9)
    written = read_allocation_csv(_written_allocation(tmp_path, study), mill3)
    np.testing.assert_array_equal(study.allocated, written)
    check = verify(mill3, written, points=3, repeats=2, samples=500, rng=9)
    pd.testing.assert_frame_equal(check.worst_poses, study.checks["optimum"].worst_poses)
    pd.testing.assert_frame_equal(check.grid_comparison,
                                  study.checks["optimum"].grid_comparison)


def _written_allocation(folder, study) -> Path:
    """The report's allocation.csv (its allocation section written alone), checked to be
    byte for byte the allocation CSV's one writer at the report's digits."""
    from studies.report.machine_sections import allocation_section

    writer.write_section(folder / "report", allocation_section(study))
    path = folder / "report" / "allocation.csv"
    same = allocation_to_csv(study.optimum, folder / "allocation.csv",
                             significant=writer.SIGNIFICANT)
    assert path.read_bytes() == same.read_bytes()
    return path


def test_as_written_is_what_a_file_reads_back():
    values = np.array([1.2345678e-5, 0.0123456789, 3.0])
    np.testing.assert_array_equal(as_written(values), [1.23457e-5, 0.0123457, 3.0])


# ----- files -----------------------------------------------------------------------------
@pytest.mark.xdist_group("lean_mill_report")
def test_files_and_report_folders_follow_the_umask(tmp_path, lean_mill_report):
    folder = lean_mill_report.folder  # written under the umask 022
    assert stat.S_IMODE(folder.stat().st_mode) == 0o755
    assert {stat.S_IMODE(p.stat().st_mode) for p in folder.iterdir()} == {0o644}
    previous = os.umask(0o022)
    try:
        path = atomic_write_text(tmp_path / "a.txt", "x")
        assert stat.S_IMODE(path.stat().st_mode) == 0o644
        os.umask(0o077)
        private = atomic_write_text(tmp_path / "b.txt", "x")
        assert stat.S_IMODE(private.stat().st_mode) == 0o600
    finally:
        os.umask(previous)


def test_an_interrupted_report_leaves_nothing_and_a_rerun_works(tmp_path, capsys,
                                                                monkeypatch):
    out = tmp_path / "report"
    drawn = []
    real_png = writer.png_bytes

    def interrupt_late(figure):
        drawn.append(figure)
        if len(drawn) == 5:  # figures are drawn after every table is written
            raise KeyboardInterrupt
        return real_png(figure)

    monkeypatch.setattr(writer, "png_bytes", interrupt_late)
    assert cli.main(["report", MILL, "--out", str(out), *QUICK, *SKIP_EXTRAS]) == 130
    assert not out.exists()
    assert list(tmp_path.iterdir()) == []  # no staging folder left behind
    monkeypatch.setattr(writer, "png_bytes", real_png)
    assert cli.main(["report", MILL, "--out", str(out), *QUICK, *SKIP_EXTRAS]) == 0
    assert (out / "report.html").is_file()
    capsys.readouterr()


def test_a_report_never_replaces_a_file_it_did_not_write_without_overwrite(tmp_path):
    from studies.report.section import Section

    out = tmp_path / "folder"
    out.mkdir()
    (out / "table.csv").write_text("mine\n")
    section = Section("S", "text", tables={"table.csv": pd.DataFrame({"a": [1.0]})})
    with pytest.raises(FileExistsError, match="table.csv"):
        writer.write_report(out, [section], {}, title="T")
    assert (out / "table.csv").read_text() == "mine\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["folder"]


# ----- readable numbers -----------------------------------------------------------------
def test_probability_bounds_are_clipped_and_marked_trivial():
    assert bound_text(-0.419062) == "0.000000 (trivial)"
    assert bound_text(0.25) == "0.250000"
    assert bound_text(1.2, 3) == "1.000 (trivial)"


def test_bonferroni_bound_is_never_negative(trunnion5):
    from reliability.first_order.system_reliability import system_reliability

    poses = workspace_grid(trunnion5, 3)[:4]
    result = system_reliability(trunnion5, 20 * trunnion5.initial_allocation, poses,
                                rng=0)
    assert (result.bonferroni == 0).all()  # 1 − Σ(1 − P) < 0 here: clipped
    assert "(trivial)" in result.summary()


def test_gaps_are_written_as_bounds():
    assert gap_bound(1.05e-13) == gap_bound(9.7e-14) == GAP_SHOWN
    assert gap_text(1.3e-9) == "< 1e-08"
    assert gap_bound(2.31e-5) == pytest.approx(2.4e-5) and gap_text(2.31e-5) == "≤ 2.4e-05"
    assert np.isnan(gap_bound(np.nan))


def test_targets_near_one_stay_readable():
    assert target_text(0.99) == "0.99"
    assert target_text(1 - 1e-9) == "0.999999999"
    assert target_text(1 - 2.5e-8) == "0.999999975"
    assert percent(1 - 1e-9) == "> 99.9999999 % (1 − 1.0e-09)"
    assert percent(0.99) == "99.0000 %"


def test_poses_are_printed_in_degrees_with_units():
    text = pose_text([np.pi / 2, 400.0], ("A", "X"), ("rad", "mm"))
    assert text == "A=90 deg, X=400 mm"


def test_result_objects_print_readable_summaries(mill3):
    from reliability.basics.statistics import all_within_share

    estimate = all_within_share(np.r_[np.ones(1987, bool), np.zeros(13, bool)])
    text = repr(estimate)
    assert "ProportionEstimate(" not in text
    assert "0.9935" in text and "clopper-pearson" in text and "2000 trials" in text
    check = verify(mill3, mill3.initial_allocation, points=3, repeats=2, samples=200, rng=1)
    assert "worst_exact_linear" in repr(check) and "grid_fosm" in repr(check)
    assert "σ = t/3 (not truncated)" in repr(check)  # the reading of the study, named


def test_reproduce_paper_refuses_bad_options_in_one_line(tmp_path, capsys):
    from studies.paper import reproduce

    existing = tmp_path / "file"
    existing.write_text("")
    for argv, words in ((["--out", str(existing)], "is a file"),
                        (["--seed", "-1"], "seed >= 0"),
                        (["--repeats", "0"], "integer >= 1")):
        assert reproduce.main([*argv, "--quiet"]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("reproduce_paper: error: ")
        assert words in err[0]



def test_rows_equal_but_for_rounding_form_one_set_whichever_side_of_a_step_they_fall():
    """first_of_equal_rows: rows a last bit apart around a rounding step (where rounding
    alone splits them) are one set; rows a whole step apart are two; the first row of each
    set is returned, in order."""
    from reliability.basics.ties import first_of_equal_rows

    step_edge = 7.5  # floor() changes here on the half-shifted grid, 8 on the plain one
    keys = np.array([[3.0, 8.0], [3.0, np.nextafter(8.0, 0.0)], [3.0, step_edge],
                     [3.0, np.nextafter(step_edge, 0.0)], [1.0, 2.0], [1.0, 3.2]])
    assert first_of_equal_rows(keys).tolist() == [0, 4, 5]
    assert first_of_equal_rows(keys[[4, 1, 0]]).tolist() == [0, 1]


def test_the_largest_contributors_keep_the_error_order_on_shares_equal_but_for_rounding():
    import pandas as pd

    from reliability.basics.display import top_contributors

    shares = pd.DataFrame({"dz": [61.0, 10.0, 10.0 * (1 + 1e-15), 19.0 - 1e-15]},
                          index=["Y.ex", "X.ey", "Y-X.ey", "Z.ez"])
    assert top_contributors(shares, "dz") == "Y.ex 61%, Z.ez 19%, X.ey 10%"


def test_decreasing_order_keeps_the_given_order_among_values_equal_but_for_rounding():
    from reliability.basics.ties import decreasing_order

    values = np.array([0.3, 0.7, 0.3 * (1 + 2e-16), 0.7 * (1 - 1e-15), 0.3 * (1 + 1e-6)])
    assert decreasing_order(values).tolist() == [1, 3, 4, 0, 2]
    assert decreasing_order(np.zeros(0)).tolist() == []
