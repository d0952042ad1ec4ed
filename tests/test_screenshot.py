"""report.html opens in a real (headless) browser, figures included."""

from __future__ import annotations

from pathlib import Path

import pytest
from matplotlib import image

from studies import cli
from studies.benchmarks.screenshot import find_browser, screenshot

MILL = str(Path(__file__).parent / "machines" / "mill3.toml")

pytestmark = pytest.mark.skipif(find_browser() is None,
                                reason="no headless Chromium installed")


def test_report_html_screenshot_is_not_blank(tmp_path):
    out = tmp_path / "report"
    assert cli.main(["report", MILL, "--out", str(out), "--points", "3", "--repeats", "2",
                     "--samples", "500"]) == 0
    picture = screenshot(out / "report.html", tmp_path / "report.png", width=1000,
                         height=8000)
    pixels = image.imread(picture)[..., :3]
    assert pixels.shape[:2] == (8000, 1000)
    # A blank page is one colour; text, tables and figures spread the grey levels.
    grey = pixels.mean(axis=-1)
    assert grey.std() > 0.05
    # Colour appears only with the embedded figures (the page's text is black on white).
    saturation = pixels.max(axis=-1) - pixels.min(axis=-1)
    assert (saturation > 0.3).mean() > 1e-3
