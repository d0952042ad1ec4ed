"""The zone benchmark's own parts: it reads what ``allocate`` prints, and a run past its
time limit is stopped and shown as such (studies/benchmarks/zone_allocation.py)."""

from __future__ import annotations

from pathlib import Path

from studies import cli
from studies.benchmarks import zone_allocation as bench

ROOT = Path(__file__).resolve().parents[1]
MILL = str(ROOT / "tests" / "machines" / "mill3.toml")


def test_loop_counts_reads_the_work_line():
    text = ("workspace: continuous — NOT certified over the continuous workspace (x)\n"
            "3 convex solve(s), 2 pose(s) added, 3 local search(es), 2 certificate call(s), "
            "1.0 s; cost 1.000001 × the 27-pose grid optimum's\n")
    assert bench.loop_counts(text) == {"solves": "3", "calls": "2", "certified": "no"}
    assert bench.loop_counts("") == {"solves": "", "calls": "", "certified": ""}


def test_the_counts_are_found_in_what_allocate_prints(tmp_path, capsys):
    assert cli.main(["allocate", MILL, "--points", "3", "--out", str(tmp_path / "c.csv"),
                     "--quiet"]) == 0
    counts = bench.loop_counts(capsys.readouterr().out)
    assert counts["solves"].isdigit() and counts["calls"].isdigit()
    assert counts["certified"] == "yes"
    assert cli.main(["allocate", MILL, "--points", "3", "--out", str(tmp_path / "g.csv"),
                     "--workspace", "grid", "--quiet"]) == 0
    assert bench.grid_poses(capsys.readouterr().out) == "27"  # 3 points on 3 axes


def test_a_run_past_its_limit_is_stopped_and_shown_so():
    run = bench.run_command(["check", MILL], ROOT, time_limit=0.01)
    assert run["stopped"] and run["code"] is None
    assert bench.seconds_text(run, 0.01) == "> 0.01 s, stopped"
    done = bench.run_command(["check", MILL], ROOT, time_limit=120.0)
    assert not done["stopped"] and done["code"] == 0 and done["peak_mb"] > 0
    assert "Workspace" in done["stdout"]
