"""``allocate`` and ``report`` with ``--time-limit`` and ``--quiet``: a certification stopped
by the time limit (or Ctrl-C) still writes its outputs, marked not certified with the reason,
and exits 3; ``--time-limit`` is passed to the continuous loop and refused where there is no
loop to stop; ``--quiet`` silences the progress lines."""

from __future__ import annotations

import dataclasses
import inspect
import json
from pathlib import Path

import pandas as pd
import pytest

from allocation.per_pose import continuous as continuous_module
from reliability.basics.errors import InputError
from studies import cli
from studies.cli import allocate, options
from studies.workflows import machine_study

ROOT = Path(__file__).resolve().parents[1]
MILL = str(ROOT / "tests" / "machines" / "mill3.toml")
ZONED = str(ROOT / "tests" / "machines" / "trunnion5_zone.toml")
REAL_LOOP = continuous_module.solve_continuous
HAS_TIME_LIMIT = "time_limit" in inspect.signature(REAL_LOOP).parameters
#: The reasons the loop gives when stopped (docs/continuous-allocation.md).
BY_TIME = "not certified to rtol: stopped by the time limit after 0.5 s"
BY_CTRL_C = "not certified to rtol: interrupted after 0.5 s"
#: A small report: no optional section, few samples.
SMALL_REPORT = ["--points", "3", "--repeats", "2", "--samples", "200", "--machines", "100",
                "--skip", "front", "system", "rare", "profiles"]


def stopping_loop(reason, calls):
    """A stand-in for ``solve_continuous`` taking ``time_limit`` (recorded in ``calls``)
    and returning the real loop's result as the loop stopped by ``reason`` returns it:
    the allocation so far, not certified."""
    def loop(problem, *, time_limit=None, **kwargs):
        calls.append(time_limit)
        result = REAL_LOOP(problem, **kwargs)
        return dataclasses.replace(result, certified=False, reason=reason)
    return loop


def run_allocate(folder, *extra):
    return cli.main(["allocate", MILL, "--points", "3", "--out", str(folder / "a.csv"),
                     *extra])


@pytest.mark.parametrize("reason", [BY_TIME, BY_CTRL_C])
def test_a_stopped_allocation_is_written_marked_and_exits_3(tmp_path, monkeypatch, capsys,
                                                            reason):
    calls = []
    monkeypatch.setattr(allocate, "solve_continuous", stopping_loop(reason, calls))
    assert run_allocate(tmp_path, "--time-limit", "2.5") == options.STOPPED == 3
    assert calls == [2.5]
    out, err = capsys.readouterr()
    assert f"NOT certified over the continuous workspace ({reason})" in out
    assert "certification stopped" in err and "exit code 3" in err
    frame = pd.read_csv(tmp_path / "a.csv")
    assert list(frame.columns) == ["error", "reference", "allocated", "certified", "reason"]
    assert not frame["certified"].any() and set(frame["reason"]) == {reason}
    assert (tmp_path / "a.drawing.csv").exists()


def test_without_time_limit_the_loop_gets_none_and_the_file_is_as_before(
        tmp_path, monkeypatch, capsys):
    """No --time-limit: the loop keeps its default (no keyword passed) and a certified
    allocation's CSV has the three columns of the format."""
    received = []

    def loop(problem, **kwargs):
        received.append(kwargs)
        return REAL_LOOP(problem, **kwargs)

    monkeypatch.setattr(allocate, "solve_continuous", loop)
    assert run_allocate(tmp_path) == 0
    assert "time_limit" not in received[0]
    assert list(pd.read_csv(tmp_path / "a.csv").columns) == ["error", "reference",
                                                             "allocated"]


def test_an_uncertified_result_not_stopped_is_marked_and_exits_0(tmp_path, monkeypatch):
    """Not certified for another reason (the loop's cap on solves): marked, exit 0."""
    reason = "stopped after 30 solves with output(s) dx still short"
    monkeypatch.setattr(allocate, "solve_continuous", stopping_loop(reason, []))
    assert run_allocate(tmp_path) == 0
    assert set(pd.read_csv(tmp_path / "a.csv")["reason"]) == {reason}


@pytest.mark.parametrize("extra, words", [
    (["--workspace", "grid"], "--workspace grid has none to stop"),
    (["--yield", "0.9"], "--time-limit does not apply with --yield"),
])
def test_time_limit_is_refused_where_no_loop_runs(tmp_path, capsys, extra, words):
    assert run_allocate(tmp_path, "--time-limit", "5", *extra) == 2
    assert words in capsys.readouterr().err
    assert not any(tmp_path.iterdir())


@pytest.mark.parametrize("value", ["0", "-1", "nan", "soon"])
def test_time_limit_must_be_positive_seconds(tmp_path, capsys, value):
    assert run_allocate(tmp_path, "--time-limit", value) == 2
    assert "--time-limit" in capsys.readouterr().err


def test_quiet_silences_the_progress_lines(tmp_path, capsys):
    assert run_allocate(tmp_path, "--workspace", "grid") == 0
    assert "building the problem" in capsys.readouterr().err
    assert run_allocate(tmp_path, "--workspace", "grid", "--overwrite", "--quiet") == 0
    out, err = capsys.readouterr()
    assert err == "" and "allocation written to" in out


def test_the_loop_prints_progress_lines_unless_quiet(tmp_path, capsys):
    assert run_allocate(tmp_path) == 0
    assert any(line.startswith("  solve 1:") for line in capsys.readouterr().err.splitlines())
    assert run_allocate(tmp_path, "--overwrite", "--quiet") == 0
    assert capsys.readouterr().err == ""


def test_a_stopped_report_is_written_not_certified_and_exits_3(tmp_path, monkeypatch,
                                                               capsys):
    calls = []
    monkeypatch.setattr(machine_study, "solve_continuous", stopping_loop(BY_TIME, calls))
    folder = tmp_path / "report"
    assert cli.main(["report", MILL, "--out", str(folder), "--time-limit", "7",
                     *SMALL_REPORT, "--quiet"]) == 3
    assert calls == [7.0]
    summary = json.loads((folder / "summary.json").read_text())
    assert summary["workspace"] == "continuous" and summary["workspace_certified"] is False
    assert BY_TIME in (folder / "report.md").read_text()
    assert capsys.readouterr().err.startswith("precrel: certification stopped")


def test_report_refuses_time_limit_on_the_grid(tmp_path, capsys):
    assert cli.main(["report", MILL, "--out", str(tmp_path / "r"), "--workspace", "grid",
                     "--time-limit", "5"]) == 2
    assert "--time-limit" in capsys.readouterr().err
    assert not (tmp_path / "r").exists()


def test_the_study_refuses_a_time_limit_on_the_grid(mill3):
    with pytest.raises(InputError, match="time_limit: .*workspace 'grid'"):
        machine_study.run(mill3, workspace="grid", time_limit=5.0)


@pytest.mark.skipif(not HAS_TIME_LIMIT,
                    reason="allocation.per_pose.continuous.solve_continuous has no "
                           "time_limit parameter yet")
def test_end_to_end_a_tiny_time_limit_stops_the_zone_machine(tmp_path, capsys):
    """The real loop on the trunnion with its zone, stopped after a millisecond."""
    code = cli.main(["allocate", ZONED, "--out", str(tmp_path / "a.csv"), "--time-limit",
                     "0.001", "--quiet"])
    assert code == 3
    frame = pd.read_csv(tmp_path / "a.csv")
    assert not frame["certified"].any()
    assert frame["reason"].str.contains("stopped by the time limit").all()
