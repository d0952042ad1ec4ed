"""A report is one study: one profile, machine count and seed for every simulated number,
each reproduced by the command (or function) that computes it alone, and a report whose
optional section cannot be computed is still written, saying why."""

import contextlib
import dataclasses
import io
import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from allocation import load_catalogue
from reliability.acceptance.definitions import read_tests
from reliability.acceptance.prediction import acceptance
from reliability.basics.streams import acceptance_stream, machine_yield_stream
from reliability.model.machine_file import load_machine
from reliability.sampling.machine_yield import machine_yield
from studies import cli
from studies.report.extras import acceptance_builder, catalogue_builder, profiles
from studies.workflows import machine_study

ROOT = Path(__file__).resolve().parent
SWIVEL = str(ROOT / "machines" / "swivel5.toml")
SWIVEL_TESTS = ROOT / "acceptance_tests" / "swivel5.toml"
MILL = str(ROOT / "machines" / "mill3.toml")
MILL_CIRCLE = ('[[tests]]\nname = "c"\nkind = "circular"\nplane = "xy"\n'
               'centre = { Y = 200.0, X = 0.0, Z = -175.0 }\nradius = 100.0\nlimit = 0.004\n')
LOOSE_SCREW = ('[[components]]\nname = "X ball screw"\nitems = ["X.dx"]\n'
               '[[components.classes]]\nname = "coarse"\nprice = 1.0\n'
               'tolerances = { "X.dx" = 0.5 }\n')
SEED, MACHINES, POINTS = 3, 60, 3
SMALL = ["--points", str(POINTS), "--workspace", "grid", "--machines", str(MACHINES),
         "--repeats", "2", "--samples", "200", "--seed", str(SEED)]
ONE_COMPONENT = """
[[components]]
name = "X ball screw"
items = ["X.dx"]
[[components.classes]]
name = "normal"
price = 100.0
tolerances = { "X.dx" = 0.008 }
[[components.classes]]
name = "precision"
price = 260.0
tolerances = { "X.dx" = 0.001 }
"""


@pytest.fixture(scope="module")
def swivel_gp():
    """The swivel-head machine with the profile gp:300 (none of the compared profiles)."""
    return dataclasses.replace(load_machine(SWIVEL), profile="gp:300")


@pytest.fixture(scope="module")
def study(swivel_gp):
    return machine_study.run(swivel_gp, points=POINTS, rng=SEED, repeats=2, samples=200,
                             machines=MACHINES, workspace="grid")


@pytest.fixture(scope="module")
def two_tests(tmp_path_factory, swivel_gp):
    """A circle and a positioning test of the swivel-head machine's test file."""
    text = SWIVEL_TESTS.read_text()
    path = tmp_path_factory.mktemp("tests") / "two.toml"
    path.write_text(text[:text.index('[[tests]]\nname = "position_Y"')])
    assert [t.name for t in read_tests(path, swivel_gp)] == ["circle_xy_r150", "position_X"]
    return path


def test_the_yield_is_machine_yield_on_its_named_stream(study, swivel_gp):
    for name, tolerances in (("initial", swivel_gp.initial_allocation),
                             ("optimum", study.allocated)):
        alone = machine_yield(swivel_gp, tolerances, machines=MACHINES, points=POINTS,
                              rng=machine_yield_stream(SEED))
        reported = study.checks[name].machine_yield
        assert (alone.estimate, alone.lower, alone.upper) == \
            (reported.estimate, reported.lower, reported.upper)
    summary = machine_study.summary(study)
    assert summary["yield_profile"] == "gp:300" and summary["yield_machines"] == MACHINES


def test_acceptance_section_is_the_acceptance_command(study, swivel_gp, two_tests, tmp_path,
                                                      capsys):
    section = acceptance_builder(read_tests(two_tests, swivel_gp))(study)
    assert section.summary["acceptance_profile"] == "gp:300"
    assert section.summary["acceptance_machines"] == MACHINES
    assert "profile gp:300" in section.text
    machine_file = tmp_path / "swivel_gp.toml"
    machine_file.write_text(Path(SWIVEL).read_text().replace(
        "[requirements]\n", '[requirements]\nprofile = "gp:300"\n'))
    assert cli.main(["acceptance", str(machine_file), "--tests", str(two_tests),
                     "--machines", str(MACHINES), "--seed", str(SEED),
                     "--out", str(tmp_path)]) == 0
    assert "gp:300" in capsys.readouterr().out
    command = pd.read_csv(tmp_path / "acceptance.csv")
    reported = section.tables["acceptance_initial.csv"]
    numbers = ["mean", "q95", "pass_probability", "pass_low", "pass_high"]
    np.testing.assert_allclose(command[numbers].to_numpy(float),
                               reported[numbers].to_numpy(float), rtol=5e-6)
    optimum = acceptance(swivel_gp, read_tests(two_tests, swivel_gp), study.allocated,
                         machines=MACHINES, profile="gp:300", rng=acceptance_stream(SEED))
    pd.testing.assert_frame_equal(optimum.to_frame(), section.tables["acceptance_optimum.csv"])


def test_profiles_row_of_the_study_profile_is_the_study_yield(study):
    section = profiles(study, repeats=20)
    table = section.tables["profiles_comparison.csv"]
    assert list(table["profile"].unique()) == ["independent", "gp:100", "gp:300", "gp:1000",
                                               "constant"]
    own = table[table["profile"] == "gp:300"].set_index("allocation")
    for name, check in study.checks.items():
        y = check.machine_yield
        assert tuple(own.loc[name, ["yield", "yield_lower", "yield_upper", "machines"]]) == \
            (y.estimate, y.lower, y.upper, y.machines)
        assert section.summary["profiles_yield"][f"{name}/gp:300"] == y.estimate
    others = table[table["profile"] != "gp:300"]
    assert (others["machines"] == 20).all()
    assert "**gp:300**, the study's profile" in section.text


def test_report_tolerances_mean_what_allocate_tolerances_mean(study, swivel_gp, tmp_path,
                                                              capsys):
    catalogue = tmp_path / "one.toml"
    catalogue.write_text(ONE_COMPONENT)
    start = np.where([n.split(".")[-1].startswith("d") for n in swivel_gp.error_names],
                     0.0015, 8e-6)
    start_csv = tmp_path / "start.csv"
    pd.DataFrame({"error": swivel_gp.error_names, "allocated": start}).to_csv(start_csv,
                                                                              index=False)
    assert cli.main(["allocate", SWIVEL, "--catalogue", str(catalogue), "--tolerances",
                     str(start_csv), "--points", str(POINTS), "--workspace", "grid",
                     "--out", str(tmp_path / "choice.csv"),
                     "--tolerances-out", str(tmp_path / "t.csv")]) == 0
    capsys.readouterr()
    build = catalogue_builder(load_catalogue(catalogue, swivel_gp), start,
                              start_text="start.csv", samples=200)
    section = build(study)
    chosen = section.tables["choice_tolerances.csv"]
    allocated = pd.read_csv(tmp_path / "t.csv")
    np.testing.assert_allclose(chosen["allocated"], allocated["allocated"], rtol=1e-12)
    outside = chosen["error"] != "X.dx"
    np.testing.assert_array_equal(chosen.loc[outside, "allocated"], start[outside])
    assert "keep start.csv" in section.text


@pytest.fixture(scope="module")
def failing_report(tmp_path_factory):
    """A report whose two asked-for sections cannot be computed: a catalogue that cannot
    meet the targets, and acceptance tests under the independent profile."""
    folder = tmp_path_factory.mktemp("failing")
    (folder / "loose.toml").write_text(LOOSE_SCREW)
    (folder / "circle.toml").write_text(MILL_CIRCLE)
    out = folder / "report"
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        code = cli.main(["report", MILL, "--out", str(out), *SMALL, "--profile",
                         "independent", "--skip", "front", "system", "rare", "profiles",
                         "--tests", str(folder / "circle.toml"),
                         "--catalogue", str(folder / "loose.toml")])
    return code, out, printed.getvalue()


def test_a_report_whose_optional_sections_fail_is_written_and_says_why(failing_report):
    code, out, printed = failing_report
    assert code == 0
    summary = json.loads((out / "summary.json").read_text())
    assert set(summary["not_computed"]) == {"catalogue", "tests"}
    assert "no choice of classes meets" in summary["not_computed"]["catalogue"]
    assert "'independent'" in summary["not_computed"]["tests"]
    markdown = (out / "report.md").read_text()
    for heading in ("## Component choice\n\n**Not computed** (asked for by --catalogue)",
                    "## Acceptance tests\n\n**Not computed** (asked for by --tests)"):
        assert heading in markdown
    assert "Not computed</strong>" in (out / "report.html").read_text()
    assert (out / "catalogue_blocking.csv").exists() and (out / "allocation.csv").exists()
    assert "(listed in catalogue_blocking.csv)" in summary["not_computed"]["catalogue"]
    blocking = pd.read_csv(out / "catalogue_blocking.csv")  # poses where they are, mm
    assert list(blocking.columns) == ["output", "Y_mm", "X_mm", "Z_mm", "load"]
    assert (blocking["load"] > 1).all()
    assert "section 'Component choice' not computed" in printed
    assert "section 'Acceptance tests' not computed" in printed
