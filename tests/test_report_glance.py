"""The report's first screen in headless Chromium: the summary table is seen without
scrolling at 1400 × 900, the figure stands beside it, nothing on it is cut, and the figures
keep their labels inside the picture; for the paper's machine with acceptance tests and for
swivel5 with acceptance tests and its measurements."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from matplotlib import image

import reliability
from studies import cli
from studies.benchmarks.screenshot import find_browser, first_screen_layout

ROOT = Path(__file__).resolve().parents[1]
SWIVEL = ROOT / "tests" / "machines" / "swivel5.toml"
#: Small reports: the layout, not the numbers, is under test.
SMALL = ["--repeats", "2", "--samples", "200", "--machines", "50", "--skip", "front",
         "system", "rare", "profiles", "--seed", "3"]
REPORTS = {
    "paper": [str(ROOT / "reliability" / "machines" / "hobbing.toml"), "--points", "2",
              "--tests", str(ROOT / "docs" / "examples" / "paper_tests.toml")],
    "swivel5": [str(SWIVEL), "--points", "3", "--tests",
                str(ROOT / "tests" / "acceptance_tests" / "swivel5.toml")],
}

#: CI sets PRECREL_REQUIRE_BROWSER=1, where tests/test_screenshot.py fails without a browser.
needs_browser = pytest.mark.skipif(find_browser() is None,
                                   reason="no headless Chromium installed")


@pytest.fixture(scope="module")
def reports(tmp_path_factory):
    """The two reports' folders; swivel5's measured by ``precrel measure`` first."""
    where = tmp_path_factory.mktemp("glance")
    readings = where / "meas.csv"
    assert cli.main(["measure", str(SWIVEL), "--plan",
                     str(ROOT / "docs" / "examples" / "swivel5_acceptance_plan.toml"),
                     "--out", str(readings), "--seed", "3"]) == 0
    extra = {"paper": [], "swivel5": ["--measurements", str(readings)]}
    folders = {}
    for name, arguments in REPORTS.items():
        folders[name] = where / name
        assert cli.main(["report", *arguments, *extra[name], *SMALL, "--out",
                         str(folders[name])]) == 0
    return folders


@needs_browser
@pytest.mark.parametrize("name", list(REPORTS))
def test_summary_table_is_on_the_first_screen_and_nothing_is_cut(reports, name):
    layout = first_screen_layout(reports[name] / "report.html", 1400, 900)
    width, height = layout["window"]
    left, top, right, bottom = layout["table"]
    assert bottom <= height and right <= width and left >= 0
    assert layout["cut"] == []
    # the figure stands beside the table, not under it
    figure = layout["figure"]
    assert figure[0] >= right and figure[1] < bottom and figure[2] <= width


@pytest.mark.parametrize("name, questions", [
    ("paper", ["Acceptance tests all passed, initial allocation",
               "Acceptance tests all passed, certified optimum"]),
    ("swivel5", ["This machine as measured: every limit at every pose",
                 "Acceptance runs as measured"])])
def test_first_screen_answers_in_numbers(reports, name, questions):
    markdown = (reports[name] / "report.md").read_text()
    first = markdown[markdown.index("## Answers"):markdown.index("**Tighten**")]
    rows = [line.split(" | ")[0].lstrip("| ") for line in first.splitlines()
            if line.startswith("| ") and not line.startswith("| ---")]
    assert rows[:5] == ["question", "Machine yield, initial allocation",
                        "Machine yield, certified optimum",
                        "Cost of the certified optimum against the initial",
                        "Does the initial allocation meet the targets?"]
    assert set(questions) <= set(rows)
    summary = json.loads((reports[name] / "summary.json").read_text())
    for key in ("yield", "relative_cost", "initial_meets_targets", "acceptance"):
        assert key in summary  # the keys stay; the table only reads them


@pytest.mark.parametrize("name", list(REPORTS))
@pytest.mark.parametrize("figure", ["answers_outputs.png", "failure_shares.png"])
def test_figure_labels_stay_inside_the_picture(reports, name, figure):
    """A label cut by the picture's edge leaves ink on its outermost pixels."""
    pixels = image.imread(reports[name] / figure)[..., :3]
    ring = np.concatenate([pixels[:2].reshape(-1, 3), pixels[-2:].reshape(-1, 3),
                           pixels[:, :2].reshape(-1, 3), pixels[:, -2:].reshape(-1, 3)])
    assert np.all(ring > 0.95)


def test_report_of_a_given_allocation(tmp_path):
    """``report --tolerances a.csv`` studies that allocation beside the initial one and
    seeks none: a supplier's list of the initial tolerances × 0.8 costs 1/0.8² of the
    initial allocation (Eq. 28, w/t²), and the summary says it is the given one."""
    mill = ROOT / "tests" / "machines" / "mill3.toml"
    machine = reliability.load_machine(mill)
    supplier = tmp_path / "supplier.csv"
    pd.DataFrame({"error": machine.error_names,
                  "allocated": 0.8 * machine.initial_allocation}).to_csv(supplier, index=False)
    out = tmp_path / "report"
    assert cli.main(["report", str(mill), "--points", "3", "--tolerances", str(supplier),
                     "--out", str(out), *SMALL]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["allocation"] == "given" and str(supplier) in summary["given_source"]
    assert summary["given_relative_cost"] == pytest.approx(1 / 0.8 ** 2, rel=1e-5)
    assert summary["reachable"] is None and summary["optimal_cost"] is None
    assert summary["yield"]["optimal"] is None and 0 < summary["yield"]["given"] <= 1
    assert not (out / "allocation.csv").exists()
    given = pd.read_csv(out / "given_allocation.csv")
    np.testing.assert_allclose(given["allocated"], 0.8 * machine.initial_allocation,
                               rtol=1e-5)
    markdown = (out / "report.md").read_text()
    assert "## Given allocation" in markdown and "## Cheapest certified allocation" not in \
        markdown
    assert "| Cost of the given allocation against the initial | **156.25%** |" in markdown


def test_output_ratios_figure_draws_each_output_in_its_colour():
    from matplotlib.colors import to_rgb
    from matplotlib.figure import Figure

    from reliability.basics.errors import InputError
    from studies.report.plots import OUTPUT_COLOURS, plot_output_ratios
    ratios = {"initial": [2.0, 1.0, 0.5, 0.1, 0.01, 1e-3], "optimum": [1.0] * 6}
    ax = plot_output_ratios(ratios, ax=Figure().subplots())
    bars = ax.patches
    assert len(bars) == 12
    np.testing.assert_allclose([bar.get_height() for bar in bars],
                               ratios["initial"] + ratios["optimum"])
    for index, colour in enumerate(OUTPUT_COLOURS.values()):
        for bar in (bars[index], bars[6 + index]):
            assert bar.get_facecolor()[:3] == pytest.approx(to_rgb(colour))
    low, high = ax.get_ylim()
    assert low < 1e-3 and high > 2.0  # every bar shows its length on the log axis
    with pytest.raises(InputError, match="ratios must hold"):
        plot_output_ratios({"a": [1.0] * 6, "b": [1.0] * 6, "c": [1.0] * 6})
