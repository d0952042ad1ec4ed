"""``precrel life`` and ``precrel predict --age`` (docs/cli.md, docs/over-time.md)."""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from studies.cli.program import main

HERE = Path(__file__).parent
DRIFTING = str(HERE / "machines" / "swivel5_drift.toml")
STILL = str(HERE / "machines" / "swivel5.toml")


def test_life_writes_its_files_and_refuses_a_second_run(tmp_path, capsys):
    out = tmp_path / "life"
    args = ["life", DRIFTING, "--until", "4", "--step", "1", "--machines", "100",
            "--points", "3", "--out", str(out), "--quiet"]
    assert main(args) == 0
    assert sorted(p.name for p in out.iterdir()) == ["life.csv", "life.png",
                                                    "life_summary.json"]
    table = pd.read_csv(out / "life.csv")
    assert list(table.columns) == ["age_years", "output", "probability"]
    assert list(table["output"].unique()) == ["dx", "dy", "dz", "ex", "ey", "ez", "machine"]
    assert sorted(table["age_years"].unique()) == [0, 1, 2, 3, 4]
    assert "ecalibration interval" in capsys.readouterr().out
    assert main(args) == 2
    assert "life.csv" in capsys.readouterr().err
    assert main(args + ["--overwrite"]) == 0


def test_life_refuses_a_machine_without_drift(tmp_path, capsys):
    assert main(["life", STILL, "--until", "4", "--out", str(tmp_path / "x")]) == 2
    assert "[drift]" in capsys.readouterr().err


def test_predict_age_zero_equals_predict(capsys):
    assert main(["predict", DRIFTING, "--points", "3"]) == 0
    plain = capsys.readouterr().out
    assert main(["predict", DRIFTING, "--points", "3", "--age", "0"]) == 0
    aged = capsys.readouterr().out
    assert aged.startswith(plain.rstrip("\n"))
    table = aged[len(plain):]
    assert "'linear'" in table and "age 0 years" in table
    for line in plain.splitlines():
        words = line.split()
        if words and words[0] in ("dx", "dy", "dz", "ex", "ey", "ez"):
            two_sided = [words[i - 1] for i, w in enumerate(words) if w == "%"][1]
            row = next(r for r in table.splitlines() if r.split() and r.split()[0] == words[0])
            shown = [w for i, w in enumerate(row.split()[:-1]) if row.split()[i + 1] == "%"]
            assert shown == [two_sided, two_sided]  # at the age and over [0, 0]


def test_predict_age_needs_drift(capsys):
    assert main(["predict", STILL, "--points", "3", "--age", "1"]) == 2
    assert "[drift]" in capsys.readouterr().err


def test_life_check_and_compensation_are_printed_and_saved(tmp_path, capsys):
    """With --compensation and --check the intervals between recalibrations and the
    Monte-Carlo check are printed, and the saved study reloads with them."""
    from studies.workflows.life_study import LifeStudy
    out = tmp_path / "life"
    plan = str(HERE.parent / "docs" / "examples" / "swivel5_plan.toml")
    assert main(["life", DRIFTING, "--until", "4", "--step", "1", "--machines", "100",
                 "--points", "3", "--compensation", plan, "--check", "200", "--yield",
                 "0.5", "--out", str(out), "--quiet"]) == 0
    printed = capsys.readouterr().out
    assert "With the compensation plan" in printed and "compensated Monte-Carlo" in printed
    study = LifeStudy.load(out / "life_summary.json")
    assert study.check.shape == (2, 6) and study.compensated_check.shape == (2, 6)
    assert study.recalibrations[0] == 0 and study.check_machines == 200
