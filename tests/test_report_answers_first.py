"""Every section of ``precrel report`` opens with its answer: the first sentence carries, in
bold, the number the section's table or ``summary.json`` holds (read back from the written
files), and the method follows folded in a ``<details>`` block of ``report.html``; for the
paper's machine with every optional section, its work-zone variant, and swivel5 measured
against its acceptance tests."""

from __future__ import annotations

import html
import json
import math
import re
from pathlib import Path

import pandas as pd
import pytest

from studies import cli

ROOT = Path(__file__).resolve().parents[1]
MACHINES = ROOT / "tests" / "machines"
SMALL = ["--repeats", "2", "--samples", "300", "--machines", "100", "--seed", "3"]
SKIP = ["--skip", "front", "system", "rare", "profiles"]


@pytest.fixture(scope="module")
def reports(tmp_path_factory):
    """Three small reports' folders: ``paper`` (every optional section), ``zone`` and
    ``measured``."""
    where = tmp_path_factory.mktemp("answers")
    readings = where / "meas.csv"
    assert cli.main(["measure", str(MACHINES / "swivel5.toml"), "--plan",
                     str(ROOT / "docs" / "examples" / "swivel5_acceptance_plan.toml"),
                     "--out", str(readings), "--seed", "3"]) == 0
    runs = {
        "paper": [str(ROOT / "reliability" / "machines" / "hobbing.toml"), "--points", "2",
                  "--catalogue", str(ROOT / "docs" / "examples" / "paper_catalogue.toml"),
                  "--sensitivity", "--compensation",
                  str(ROOT / "docs" / "examples" / "paper_plan.toml")],
        "zone": [str(MACHINES / "hobbing_zone.toml"), "--points", "2", *SKIP],
        "measured": [str(MACHINES / "swivel5.toml"), "--points", "3", "--tests",
                     str(ROOT / "tests" / "acceptance_tests" / "swivel5.toml"),
                     "--measurements", str(readings), *SKIP]}
    folders = {}
    for name, arguments in runs.items():
        folders[name] = where / name
        assert cli.main(["report", *arguments, *SMALL, "--out", str(folders[name])]) == 0
    return folders


def opening(folder: Path, title: str) -> str:
    """The first paragraph of the section ``title`` of ``report.md``."""
    text = (folder / "report.md").read_text()
    start = text.index(f"\n## {title}\n") + len(title) + 5
    return text[start:].strip().split("\n\n")[0]


def folded(folder: Path, title: str, phrase: str) -> bool:
    """Whether ``phrase`` stands inside a ``<details>`` block of the section ``title`` in
    ``report.html`` (and nowhere else in it)."""
    page = (folder / "report.html").read_text()
    start = page.index(f">{html.escape(title)}</h2>")
    end = page.find("<h2", start)
    section = page[start:end if end > 0 else len(page)]
    blocks = re.findall(r"<details>.*?</details>", section, flags=re.S)
    outside = re.sub(r"<details>.*?</details>", "", section, flags=re.S)
    return any(phrase in b for b in blocks) and phrase not in outside


def summary(folder: Path) -> dict:
    return json.loads((folder / "summary.json").read_text())


def one_sentence(text: str) -> bool:
    """One sentence: a single full stop at its end (none inside but in numbers and
    abbreviations such as ``e.g.``)."""
    return text.endswith(".") and not re.search(r"[a-z)]\. [A-Z]", text[:-1])


def test_continuous_workspace_opens_with_the_cost_ratio(reports):
    first = opening(reports["paper"], "Continuous workspace")
    ratio = summary(reports["paper"])["workspace_cost_ratio"]
    assert first.startswith("The optimum over the continuous workspace costs")
    assert f"**{ratio:.6g} ×**" in first and one_sentence(first)
    assert folded(reports["paper"], "Continuous workspace", "convex solve(s)")


def test_front_opens_with_the_cost_of_the_target(reports):
    first = opening(reports["paper"], "Cost against reliability")
    front = pd.read_csv(reports["paper"] / "front.csv")
    cost = front.loc[front["target"].sub(0.99).abs().idxmin(), "relative_cost"]
    assert f"**{cost:.3g} ×**" in first and one_sentence(first)
    assert folded(reports["paper"], "Cost against reliability", "The front gives")


def test_system_reliability_opens_with_each_allocations_probability(reports):
    first = opening(reports["paper"], "System reliability")
    table = pd.read_csv(reports["paper"] / "system_reliability.csv")
    for label, value in zip(table["allocation"], table["system"]):
        assert f"**{value:.6f}** ({label})" in first
    assert one_sentence(first)
    assert folded(reports["paper"], "System reliability", "Bonferroni a weaker one")


def test_worst_poses_open_with_the_largest_failure_probability(reports):
    title = "Verification at the worst poses (optimum)"
    first = opening(reports["paper"], title)
    table = pd.read_csv(reports["paper"] / "optimum_worst_pose_mc.csv")
    assert f"**{table['mc_failure'].max():.3e}**" in first and one_sentence(first)
    assert folded(reports["paper"], title, "Wilson intervals on the failure")
    assert folded(reports["paper"], title, "by importance sampling on the exact model")


def test_profiles_open_with_the_yields_range(reports):
    title = "Errors along travel: independent, smooth or constant"
    first = opening(reports["paper"], title)
    table = pd.read_csv(reports["paper"] / "profiles_comparison.csv")
    rows = table[table["repeats"] == table["repeats"].max()]
    assert f"**{rows['yield'].min():.3f}**" in first
    assert f"**{rows['yield'].max():.3f}**" in first and one_sentence(first)
    assert folded(reports["paper"], title, "Gaussian-process profiles")


def test_catalogue_opens_with_the_price(reports):
    first = opening(reports["paper"], "Component choice")
    price = summary(reports["paper"])["catalogue"]["price"]
    assert f"**{price:.6g} " in first and one_sentence(first)
    assert folded(reports["paper"], "Component choice", "scipy.optimize.milp")


def test_sensitivity_opens_with_the_largest_yield_change(reports):
    first = opening(reports["paper"], "What each tolerance buys")
    table = pd.read_csv(reports["paper"] / "yield_sensitivity.csv")
    top = table.loc[table["dyield_dlnt"].abs().idxmax()]
    # tightening by 10 %: Δ ln t = ln 0.9, in percentage points (docs/sensitivity.md)
    change = 100 * math.log(0.9) * top["dyield_dlnt"]
    assert f"**{top['error']}**" in first and f"**{change:+.3f} %**" in first
    assert one_sentence(first)
    assert folded(reports["paper"], "What each tolerance buys", "first order in ln t")


def test_compensation_opens_with_the_cost_ratio(reports):
    first = opening(reports["paper"], "After compensation")
    ratio = summary(reports["paper"])["compensation_cost_ratio"]
    assert f"**{ratio:.4f} ×**" in first and one_sentence(first)
    assert folded(reports["paper"], "After compensation", "identified and compensated")


def test_work_zone_opens_with_its_poses_and_cost(reports):
    first = opening(reports["zone"], "The work zone")
    saved = summary(reports["zone"])
    table = pd.read_csv(reports["zone"] / "zone_allocations.csv").set_index("allocation")
    assert first.startswith(f"**{saved['zone_grid_poses']} of the {saved['grid_poses']} "
                            f"poses**")
    assert f"**{table.loc['optimum for the zone', 'cost']:.4g} ×**" in first
    assert one_sentence(first)
    assert folded(reports["zone"], "The work zone", "tool point and tilt")


def test_evaluation_opens_with_the_tests_passed(reports):
    first = opening(reports["measured"], "Acceptance as measured")
    verdicts = [v for v in summary(reports["measured"])["evaluation"].values()
                if v is not None]
    assert f"**{sum(verdicts)} of {len(verdicts)}**" in first and one_sentence(first)
    assert folded(reports["measured"], "Acceptance as measured", "The percentile is")


def test_verification_figures_colour_each_output_as_every_report_figure():
    from matplotlib.colors import to_rgba
    from matplotlib.figure import Figure

    from studies.report.plots import (OUTPUT_COLOURS, plot_comprehensive_error_scatter,
                                      plot_reliability_comparison, plot_repeats)
    outputs = list(OUTPUT_COLOURS)
    expected = [to_rgba(OUTPUT_COLOURS[o]) for o in outputs]
    repeats = pd.DataFrame({o: [0.98, 1.0] for o in outputs}).assign(allocation="a")
    ax = plot_repeats(repeats, by="allocation", ax=Figure().subplots(),
                      output_colours=OUTPUT_COLOURS)
    colours = ax.collections[-2].get_facecolors()[:, :3]  # the points (last: legend)
    assert [tuple(c) for c in colours[::2]] == [c[:3] for c in expected]
    assert [t.get_color() for t in ax.get_xticklabels()] == list(OUTPUT_COLOURS.values())
    frame = pd.DataFrame({"output": outputs, "fosm_one_sided": 0.995, "fosm_two_sided": 0.99,
                          "mc_estimate": 0.99, "mc_lower": 0.98, "mc_upper": 0.995})
    ax = plot_reliability_comparison(frame, ax=Figure().subplots(), interval="95 %",
                                     output_colours=OUTPUT_COLOURS)
    assert [tuple(c) for c in ax.collections[-1].get_facecolors()] == expected
    ax = plot_comprehensive_error_scatter([0.0, 0.5, 2.0], 1.0, output_label="ez",
                                          ax=Figure().subplots(),
                                          colour=OUTPUT_COLOURS["ez"])
    assert tuple(ax.collections[0].get_facecolors()[0]) == to_rgba(OUTPUT_COLOURS["ez"])
