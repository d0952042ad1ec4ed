"""A picture of a report as a browser shows it: headless Chromium screenshots an HTML file.

    python -m studies.benchmarks.screenshot report/report.html report.png
    python -m studies.benchmarks.screenshot report/report.html first.png --first-screen

The whole page by default: a first run of the browser lays the page out at the picture's
width and measures its height, a second one takes a picture that tall. ``--first-screen``
keeps only the top of the page, as a reader first sees it.

Shows that ``report.html`` is self-contained: it is opened from a file, with networking
left to the page (which needs none), and the figures appear in the picture.
"""

from __future__ import annotations

import argparse
import html
import json
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from reliability.basics.errors import InputError

#: Browsers tried in order when none is given.
BROWSERS = ("/usr/bin/chromium", "chromium", "chromium-browser", "google-chrome")
#: Options of every browser run: no window, no sandbox (containers), one CSS pixel per pixel.
HEADLESS = ("--headless", "--disable-gpu", "--no-sandbox", "--hide-scrollbars",
            "--force-device-scale-factor=1")
#: Window height of the measuring run: small, so that the page, not the window, sets the
#: document's scroll height.
PROBE_HEIGHT = 100
#: Milliseconds of page time the measuring run grants the page to finish loading.
LOAD_BUDGET_MS = 10_000
#: Height of ``--first-screen`` pictures: a laptop screen's view of the page.
FIRST_SCREEN_HEIGHT = 800
#: Set on the page's root element by the measuring run, once the page has loaded.
HEIGHT_ATTRIBUTE = "data-page-height"
MEASURE_SCRIPT = (
    '<script>window.addEventListener("load", function () {'
    " var root = document.documentElement;"
    " var body = document.body ? document.body.scrollHeight : 0;"
    f' root.setAttribute("{HEIGHT_ATTRIBUTE}", Math.ceil(Math.max(root.scrollHeight, body)));'
    "});</script>")


#: Set on the page's root element by :func:`first_screen_layout`'s run: JSON of the layout.
LAYOUT_ATTRIBUTE = "data-first-screen"
#: Reads, once the page has loaded, where the first table ends and which elements of the
#: first screen show less than their text (clipped: wider content than box, or past the
#: window's right edge).
LAYOUT_SCRIPT = (
    '<script>window.addEventListener("load", function () {'
    " var table = document.querySelector('table');"
    " var box = table ? table.getBoundingClientRect() : null;"
    " var cut = [];"
    " document.querySelectorAll('h1,h2,p,li,th,td,summary,img').forEach(function (e) {"
    "  var r = e.getBoundingClientRect();"
    "  if (r.top >= window.innerHeight || r.height === 0) return;"
    "  if (e.scrollWidth > e.clientWidth + 1 || r.right > window.innerWidth + 0.5"
    "      || r.left < -0.5) cut.push(e.tagName + ': ' + e.textContent.slice(0, 60));"
    " });"
    " var img = document.querySelector('img');"
    " var pic = img ? img.getBoundingClientRect() : null;"
    " var out = {window: [window.innerWidth, window.innerHeight],"
    "  table: box ? [box.left, box.top, box.right, box.bottom] : null,"
    "  figure: pic ? [pic.left, pic.top, pic.right, pic.bottom] : null, cut: cut};"
    f' document.documentElement.setAttribute("{LAYOUT_ATTRIBUTE}", JSON.stringify(out));'
    "});</script>")


def find_browser() -> str | None:
    """Path of a Chromium-family browser, or None."""
    for name in BROWSERS:
        found = shutil.which(name)
        if found:
            return found
    return None


def _measuring_copy(html_path: Path, script: str = MEASURE_SCRIPT) -> str:
    """The page's text with a base address (its links resolve as from its own folder) and
    ``script``, which writes what it measures into the root element once loaded (by
    default the laid-out height)."""
    text = html_path.read_text(encoding="utf-8", errors="surrogateescape")
    base = f'<base href="{html_path.parent.as_uri()}/">'
    head = re.search(r"<head[^>]*>", text, flags=re.IGNORECASE)
    text = text[:head.end()] + base + text[head.end():] if head else base + text
    return text + script


def _run(command, browser, timeout) -> subprocess.CompletedProcess:
    """Run the browser with a fresh profile folder (no state shared between runs)."""
    with tempfile.TemporaryDirectory() as profile:
        return subprocess.run([browser, *HEADLESS, f"--user-data-dir={profile}", *command],
                              capture_output=True, text=True, timeout=timeout)


def page_height(html_path, width: int = 1200, *, browser: str | None = None,
                timeout: float = 120.0) -> int:
    """Height in pixels of the page ``html_path`` laid out ``width`` pixels wide.

    The browser opens a copy of the page (in a temporary folder, with a ``<base>`` pointing
    at the page's own folder) that records ``document.documentElement.scrollHeight`` after
    the load event, and prints the resulting document (``--dump-dom``).

    Raises
    ------
    InputError
        The HTML file does not exist or the width is not positive.
    FileNotFoundError
        No browser is installed.
    RuntimeError
        The browser did not report a height.
    """
    html_path = Path(html_path).resolve()
    browser = _checked(html_path, width, browser)
    return int(_probe(html_path, MEASURE_SCRIPT, HEIGHT_ATTRIBUTE, r"\d+", "page height",
                      (width, PROBE_HEIGHT), browser, timeout))


def first_screen_layout(html_path, width: int = 1400, height: int = 900, *,
                        browser: str | None = None, timeout: float = 120.0) -> dict:
    """How the first screen of ``html_path`` lays out in a ``width`` × ``height`` window:
    ``window`` (its inner size), ``table`` and ``figure`` (the page's first table and
    first image as [left, top, right, bottom] in pixels, None without one) and ``cut``
    (the elements on the first screen whose content is wider than their box or that pass
    the window's edges, each as ``"TAG: text"``), measured by :data:`LAYOUT_SCRIPT` in a
    copy of the page, as :func:`page_height` measures the height.

    Raises
    ------
    InputError, FileNotFoundError, RuntimeError
        As :func:`page_height`.
    """
    html_path = Path(html_path).resolve()
    browser = _checked(html_path, width, browser)
    found = _probe(html_path, LAYOUT_SCRIPT, LAYOUT_ATTRIBUTE, r'[^"]*', "layout",
                   (width, height), browser, timeout)
    return json.loads(html.unescape(found))


def _probe(html_path: Path, script: str, attribute: str, pattern: str, what: str, window,
           browser: str, timeout: float) -> str:
    """Load a copy of the page with ``script`` (:func:`_measuring_copy`) in a window of
    ``window`` (width, height) pixels and return the value ``script`` wrote into the root
    element's ``attribute`` (matching ``pattern``); RuntimeError naming ``what`` if none."""
    with tempfile.TemporaryDirectory() as folder:
        probe = Path(folder) / "probe.html"
        probe.write_text(_measuring_copy(html_path, script), encoding="utf-8",
                         errors="surrogateescape")
        done = _run([f"--window-size={window[0]},{window[1]}",
                     f"--virtual-time-budget={LOAD_BUDGET_MS}", "--dump-dom", probe.as_uri()],
                    browser, timeout)
    found = re.search(rf'{attribute}="({pattern})"', done.stdout)
    if found is None:
        raise RuntimeError(f"{browser} reported no {what} for {html_path} (exit "
                           f"{done.returncode}): {done.stderr.strip()[-500:]}")
    return found.group(1)


def _checked(html_path: Path, width: int, browser: str | None) -> str:
    """Refuse a missing page or a width below one pixel; return the browser to use."""
    if not html_path.is_file():
        raise InputError(f"html_path {html_path}: no such file")
    if width < 1:
        raise InputError(f"width must be >= 1 pixel; got {width}")
    browser = browser or find_browser()
    if browser is None:
        raise FileNotFoundError(f"no Chromium browser found (tried {', '.join(BROWSERS)})")
    return browser


def screenshot(html_path, png_path, width: int = 1200, height: int | None = None, *,
               browser: str | None = None, timeout: float = 120.0) -> Path:
    """Render ``html_path`` in headless Chromium and save a PNG ``width`` pixels wide.

    Parameters
    ----------
    html_path : str or Path
        HTML file to open (as a ``file://`` address).
    png_path : str or Path
        PNG to write (replaced if it exists).
    width : int
        Window width in pixels, which is the width of the picture.
    height : int, optional
        Height of the picture in pixels: the first screen of the page, that tall. None
        (default) for the whole page, as tall as :func:`page_height` measures it.
    browser : str, optional
        Browser executable; default the first of :data:`BROWSERS` found.
    timeout : float
        Seconds to wait for each run of the browser.

    Raises
    ------
    InputError
        The HTML file does not exist or the size is not positive.
    FileNotFoundError
        No browser is installed.
    RuntimeError
        The browser ran but wrote no picture or reported no page height.
    """
    html_path, png_path = Path(html_path).resolve(), Path(png_path).resolve()
    browser = _checked(html_path, width, browser)
    if height is not None and height < 1:
        raise InputError(f"height must be >= 1 pixel or None (the whole page); got {height}")
    if height is None:
        height = page_height(html_path, width, browser=browser, timeout=timeout)
    done = _run([f"--screenshot={png_path}", f"--window-size={width},{height}",
                 html_path.as_uri()], browser, timeout)
    if not png_path.is_file():
        raise RuntimeError(f"{browser} wrote no screenshot (exit {done.returncode}): "
                           f"{done.stderr.strip()[-500:]}")
    return png_path


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m studies.benchmarks.screenshot",
        description="A PNG of an HTML page in headless Chromium: the whole page, or its "
                    "first screen.")
    parser.add_argument("html", metavar="REPORT.html", help="the page to open")
    parser.add_argument("png", metavar="PICTURE.png", help="the picture to write")
    parser.add_argument("--width", type=int, default=1200, metavar="PX",
                        help="window and picture width in pixels (default 1200)")
    parser.add_argument("--first-screen", nargs="?", type=int, const=FIRST_SCREEN_HEIGHT,
                        default=None, metavar="PX",
                        help="only the top of the page, PX pixels tall (default "
                             f"{FIRST_SCREEN_HEIGHT}); without it, the whole page")
    return parser


def main(argv=None) -> int:
    args = _parser().parse_args(sys.argv[1:] if argv is None else argv)
    try:
        print(screenshot(args.html, args.png, width=args.width, height=args.first_screen))
    except (InputError, FileNotFoundError, RuntimeError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
