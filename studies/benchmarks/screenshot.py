"""A picture of a report as a browser shows it: headless Chromium screenshots an HTML file.

    python -m studies.benchmarks.screenshot report/report.html report.png

Shows that ``report.html`` is self-contained: it is opened from a file, with networking
left to the page (which needs none), and the figures appear in the picture.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from reliability.errors import InputError

#: Browsers tried in order when none is given.
BROWSERS = ("/usr/bin/chromium", "chromium", "chromium-browser", "google-chrome")


def find_browser() -> str | None:
    """Path of a Chromium-family browser, or None."""
    for name in BROWSERS:
        found = shutil.which(name)
        if found:
            return found
    return None


def screenshot(html_path, png_path, width: int = 1200, height: int = 2400, *,
               browser: str | None = None, timeout: float = 120.0) -> Path:
    """Render ``html_path`` in headless Chromium and save a ``width`` × ``height`` PNG.

    Parameters
    ----------
    html_path : str or Path
        HTML file to open (as a ``file://`` address).
    png_path : str or Path
        PNG to write (replaced if it exists).
    width, height : int
        Window size in pixels, which is the size of the picture.
    browser : str, optional
        Browser executable; default the first of :data:`BROWSERS` found.
    timeout : float
        Seconds to wait for the browser.

    Raises
    ------
    InputError
        The HTML file does not exist or the size is not positive.
    FileNotFoundError
        No browser is installed.
    RuntimeError
        The browser ran but wrote no picture.
    """
    html_path, png_path = Path(html_path).resolve(), Path(png_path).resolve()
    if not html_path.is_file():
        raise InputError(f"html_path {html_path}: no such file")
    if width < 1 or height < 1:
        raise InputError(f"width and height must be >= 1 pixel; got {width} x {height}")
    browser = browser or find_browser()
    if browser is None:
        raise FileNotFoundError(f"no Chromium browser found (tried {', '.join(BROWSERS)})")
    with tempfile.TemporaryDirectory() as profile:
        command = [browser, "--headless", "--disable-gpu", "--no-sandbox",
                   "--hide-scrollbars", f"--user-data-dir={profile}",
                   f"--screenshot={png_path}", f"--window-size={width},{height}",
                   html_path.as_uri()]
        done = subprocess.run(command, capture_output=True, text=True, timeout=timeout)
    if not png_path.is_file():
        raise RuntimeError(f"{browser} wrote no screenshot (exit {done.returncode}): "
                           f"{done.stderr.strip()[-500:]}")
    return png_path


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) != 2:
        print("usage: python -m studies.benchmarks.screenshot REPORT.html PICTURE.png",
              file=sys.stderr)
        return 2
    print(screenshot(argv[0], argv[1]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
