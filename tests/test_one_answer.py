"""One answer per question across commands: where the worst poses are sampled, refusals
before any work, and advice that fits the box the study uses."""

import re
from pathlib import Path

import pandas as pd
import pytest

from studies.cli import main

ROOT = Path(__file__).resolve().parents[1]
MILL3 = ROOT / "tests" / "machines" / "mill3.toml"
TRUNNION5 = ROOT / "tests" / "machines" / "trunnion5.toml"
SWIVEL5 = ROOT / "tests" / "machines" / "swivel5.toml"
OUTPUT_ROWS = ("dx", "dy", "dz", "ex", "ey", "ez")
SMALL = ["--points", "3", "--repeats", "2", "--samples", "500", "--machines", "50"]


def _correlated(tmp_path) -> Path:
    """mill3 with one correlated pair: the continuous certificate does not cover it."""
    path = tmp_path / "correlated.toml"
    path.write_text(MILL3.read_text() + '\n[[correlation]]\nerrors = ["X.ey", "X.dz"]\n'
                                        'coefficient = 0.6\n')
    return path


def test_verify_samples_each_output_where_the_report_does(tmp_path, capsys):
    """The report's worst-pose Monte-Carlo of its optimum is what ``verify`` prints for the
    written allocation with the same seed and sizes: same poses, same estimates."""
    out = tmp_path / "report"
    assert main(["report", str(TRUNNION5), "--out", str(out), *SMALL, "--seed", "4",
                 "--skip", "front", "system", "rare", "profiles"]) == 0
    capsys.readouterr()
    assert main(["verify", str(TRUNNION5), "--tolerances", str(out / "allocation.csv"), *SMALL,
                 "--seed", "4"]) == 0
    printed = capsys.readouterr().out
    table = printed.split("worst pose (500 samples):")[1]
    rows = {line.split()[0]: line for line in table.splitlines() if line[:2] in OUTPUT_ROWS}
    reported = pd.read_csv(out / "worst_pose_mc.csv").query("allocation == 'optimum'")
    for row in reported.itertuples():
        line = rows[row.output]
        assert f"Y={row.Y_mm:g} mm, X={row.X_mm:g} mm, Z={row.Z_mm:g} mm" in line
        assert f"{100 * row.mc_estimate:.3f}" in line.split(" mm")[-1].split()


def test_verify_grid_workspace_samples_the_worst_grid_pose(tmp_path, capsys):
    """``--workspace grid`` samples the FOSM worst pose of the grid, as before; the
    default certifies over the strokes and says so."""
    written = tmp_path / "initial.csv"
    assert main(["allocate", str(MILL3), "--workspace", "grid", "--points", "3",
                 "--out", str(written)]) == 0
    capsys.readouterr()
    assert main(["verify", str(MILL3), "--tolerances", str(written), *SMALL,
                 "--workspace", "grid"]) == 0
    assert "at each output's grid worst pose" in capsys.readouterr().out
    code = main(["verify", str(MILL3), "--tolerances", str(written), *SMALL,
                 "--workspace", "grid", "--certify"])
    assert code == 2 and "--certify" in capsys.readouterr().err


@pytest.mark.parametrize("command", [["predict", "--certify"], ["verify"]])
def test_certificate_refusal_comes_before_any_work(tmp_path, capsys, command):
    """A study the certificate cannot cover is refused before anything is printed, in one
    line naming the option and what to pass instead."""
    machine = _correlated(tmp_path)
    tolerances = tmp_path / "t.csv"
    extra = ["--tolerances", str(tolerances)] if command[0] == "verify" else []
    if extra:
        tolerances.write_text("error,allocated\n")
    code = main([command[0], str(machine), *command[1:], *extra])
    captured = capsys.readouterr()
    assert code == 2 and captured.out == ""
    assert "correlated" in captured.err and len(captured.err.strip().splitlines()) == 1
    assert ("--certify" in captured.err) if command[0] == "predict" else \
        ("--workspace grid" in captured.err)


def test_unreachable_advice_names_the_files_bounds_table(tmp_path, capsys):
    """With the box from the file's [bounds], the advice is to widen that table, not to pass
    factors that would silently replace it."""
    strict = tmp_path / "strict.toml"
    text = SWIVEL5.read_text().replace("dx = { limit = 0.025", "dx = { limit = 0.002")
    strict.write_text(text)
    code = main(["allocate", str(strict), "--workspace", "grid", "--points", "3",
                 "--out", str(tmp_path / "a.csv")])
    err = capsys.readouterr().err
    assert code == 2 and "[bounds] table" in err and "would replace it" in err
    assert re.search(r"pose \d", err) is None and re.search(r"at C=-?[\d.]+ deg, Y=", err)
    code = main(["allocate", str(strict), "--workspace", "grid", "--points", "3",
                 "--bounds", "0.5", "1.5", "--out", str(tmp_path / "b.csv")])
    assert code == 2 and "a wider box (--bounds LO HI" in capsys.readouterr().err


def test_report_sensitivity_is_the_sensitivity_command(tmp_path):
    """The report's "What each tolerance buys" table of an allocation is what ``precrel
    sensitivity --yield`` writes for it at the same seed, grid and machine count."""
    from reliability import load_machine
    from reliability.basics.streams import sensitivity_stream
    from studies.report.sensitivity_section import sensitivity_section

    machine = load_machine(MILL3)
    section = sensitivity_section(machine, machine.initial_allocation, label="initial",
                                  points=3, machines=200, rng=sensitivity_stream(5))
    assert main(["sensitivity", str(MILL3), "--yield", "--points", "3", "--machines", "200",
                 "--samples", "64", "--seed", "5", "--out", str(tmp_path / "s")]) == 0
    written = pd.read_csv(tmp_path / "s" / "yield_sensitivity.csv")
    shown = section.tables["yield_sensitivity.csv"].reset_index(drop=True)
    pd.testing.assert_frame_equal(written, shown, check_exact=False, rtol=1e-5)
