"""studies.paper.reproduce (``python -m studies.reproduce_paper``): files, determinism,
refusal to overwrite, paper regressions."""

import numpy as np
import pytest

from studies.paper import reproduce as rp


@pytest.fixture
def small_study(small_paper_study):
    """A quick study (few wolves, iterations, repeats) to test the plumbing."""
    return small_paper_study


@pytest.mark.xdist_group("small_paper_study")
def test_required_tables_and_columns(small_study):
    tables = rp.tables(small_study)
    table6 = tables["table6_allocation.csv"]
    assert list(table6.index) == list(small_study.machine.error_names)
    assert {"initial", "paper", "gwo", "exact"} <= set(table6.columns)
    assert {"initial", "paper", "gwo", "exact"} <= set(tables["table7_cost.csv"].index)
    repeats = tables["table9_repeats.csv"].reset_index()
    assert {"allocation", "repeat", "dx", "dy", "dz", "ex", "ey", "ez"} <= set(repeats.columns)
    assert set(repeats["allocation"]) >= {"paper", "exact"}
    assert repeats.groupby("allocation").size().eq(3).all()


@pytest.mark.xdist_group("small_paper_study")
def test_fcem_reproduces_a(small_study):
    np.testing.assert_allclose(small_study.fcem.b, [0, 0.06, 0.24, 0.32, 0.38], atol=1e-12)
    assert small_study.fcem.value == pytest.approx(1.98, abs=1e-12)


@pytest.mark.xdist_group("small_paper_study")
def test_exact_optimum_beats_gwo_and_paper(small_study):
    costs = rp.tables(small_study)["table7_cost.csv"]["cost"]
    assert costs["exact"] <= costs["gwo"] * (1 + 1e-9)
    assert costs["exact_two_sided"] <= costs["gwo_two_sided"] * (1 + 1e-9)
    assert costs["exact"] < costs["paper"] < costs["initial"]


def test_the_committed_case_study_regenerates_byte_for_byte(tmp_path, capsys):
    """The README's first command (seed 2023) writes every file, refuses to replace them
    without --overwrite, and writes the files committed in figures/.

    Tables, markdown and JSON are compared byte for byte. Figures and report.html (which
    embeds them) also depend on the matplotlib and FreeType versions, so they are only
    checked to exist here.
    """
    from pathlib import Path

    committed = Path(__file__).parent.parent / "figures"
    assert rp.main(["--out", str(tmp_path), "--seed", "2023", "--quiet"]) == 0
    for name in rp.OUTPUT_FILES:
        assert (tmp_path / name).stat().st_size > 0, name
    def text_files(folder):
        return sorted(str(p.relative_to(folder)) for p in folder.rglob("*")
                      if p.suffix in (".csv", ".md", ".json"))

    text = text_files(tmp_path)
    assert set(rp.OUTPUT_FILES) & set(text) and text == text_files(committed)
    differing = [name for name in text
                 if (tmp_path / name).read_bytes() != (committed / name).read_bytes()]
    assert differing == [], f"regenerated files differ from figures/: {differing}"
    before = (tmp_path / "report.md").read_bytes()
    assert rp.main(["--out", str(tmp_path), "--quiet"]) == 2
    assert "--overwrite" in capsys.readouterr().err
    assert (tmp_path / "report.md").read_bytes() == before
