"""report.html opens in a real (headless) browser, figures included; the helper pictures the
whole page, or its first screen."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from matplotlib import image

from reliability.basics.errors import InputError
from studies import cli
from studies.benchmarks.screenshot import find_browser, main, page_height, screenshot

MILL = str(Path(__file__).parent / "machines" / "mill3.toml")

#: CI sets this (.ci/run installs Chromium): there a missing browser is a failure, not a skip.
REQUIRED = os.environ.get("PRECREL_REQUIRE_BROWSER") == "1"

pytestmark = pytest.mark.skipif(find_browser() is None and not REQUIRED,
                                reason="no headless Chromium installed")


def test_a_browser_is_found_where_one_is_required():
    assert find_browser() is not None, "PRECREL_REQUIRE_BROWSER=1 but no Chromium found"

#: A page 3000 px tall at any width: white, with a red band as its last 40 px.
TALL_PAGE = ('<!DOCTYPE html><html><head><style>body{margin:0}div{width:100%}</style>'
             '</head><body><div style="height:2960px;background:#fff"></div>'
             '<div style="height:40px;background:#f00"></div></body></html>')


@pytest.fixture
def tall_page(tmp_path):
    page = tmp_path / "tall.html"
    page.write_text(TALL_PAGE)
    return page


def _red(pixels):
    """Rows of the picture that are pure red."""
    return np.flatnonzero(np.all(np.abs(pixels - [1.0, 0.0, 0.0]) < 0.02, axis=-1).all(axis=1))


def test_whole_page_is_captured_to_its_last_pixel(tall_page, tmp_path):
    assert page_height(tall_page, 600) == 3000
    pixels = image.imread(screenshot(tall_page, tmp_path / "all.png", width=600))[..., :3]
    assert pixels.shape[:2] == (3000, 600)
    np.testing.assert_array_equal(_red(pixels), np.arange(2960, 3000))


def test_first_screen_is_the_top_of_the_page(tall_page, tmp_path):
    picture = screenshot(tall_page, tmp_path / "top.png", width=500, height=300)
    pixels = image.imread(picture)[..., :3]
    assert pixels.shape[:2] == (300, 500)
    assert _red(pixels).size == 0


def test_command_line_first_screen_and_whole_page(tall_page, tmp_path, capsys):
    assert main([str(tall_page), str(tmp_path / "top.png"), "--first-screen"]) == 0
    assert image.imread(tmp_path / "top.png").shape[:2] == (800, 1200)
    assert main([str(tall_page), str(tmp_path / "all.png"), "--width", "400"]) == 0
    assert image.imread(tmp_path / "all.png").shape[:2] == (3000, 400)
    assert main([str(tmp_path / "missing.html"), str(tmp_path / "x.png")]) == 2
    assert capsys.readouterr().err.startswith("error: html_path")


@pytest.mark.parametrize("options, match", [({"width": 0}, "width must be >= 1"),
                                            ({"height": 0}, "height must be >= 1")])
def test_bad_sizes_are_refused(tall_page, tmp_path, options, match):
    with pytest.raises(InputError, match=match):
        screenshot(tall_page, tmp_path / "x.png", **options)
    assert not (tmp_path / "x.png").exists()


def test_report_html_screenshot_is_not_blank(tmp_path):
    out = tmp_path / "report"
    assert cli.main(["report", MILL, "--out", str(out), "--points", "3", "--repeats", "2",
                     "--samples", "500"]) == 0
    picture = screenshot(out / "report.html", tmp_path / "report.png", width=1000)
    pixels = image.imread(picture)[..., :3]
    # The whole report, far taller than a screen, down to its last line of text.
    assert pixels.shape[:2] == (page_height(out / "report.html", 1000), 1000)
    assert pixels.shape[0] > 2400
    grey = pixels.mean(axis=-1)
    written = np.flatnonzero((grey < 0.5).any(axis=1))
    assert written.max() > pixels.shape[0] - 100
    # A blank page is one colour; text, tables and figures spread the grey levels.
    assert grey.std() > 0.05
    # Colour appears only with the embedded figures (the page's text is black on white).
    saturation = pixels.max(axis=-1) - pixels.min(axis=-1)
    assert (saturation > 0.3).mean() > 1e-3
