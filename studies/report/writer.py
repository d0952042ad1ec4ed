"""Write a report: a list of :class:`~studies.report.section.Section` into a folder.

The folder receives every section's tables as CSV and figures as PNG, ``report.md``,
``report.html`` (self-contained: figures embedded as base64 PNG, no network access
needed) and ``summary.json`` (the sections' summary entries merged,
:func:`merged_summary`, and under ``files`` the names of every file the report wrote, so
that a report rewritten in the same folder removes what the earlier one wrote and this one
does not). Numbers in the CSV,
markdown and JSON files are written to :data:`SIGNIFICANT` significant digits, so that a
rerun with the same seed, on this or another computer, gives the same files.
"""

from __future__ import annotations

import base64
import html
import io
import json
import math
import shutil
from pathlib import Path

import numpy as np

from reliability.basics.files import (SIGNIFICANT, atomic_write_bytes, atomic_write_text,
                                      check_destination, make_temporary_folder, write_csv)

from .markdown import anchor, markdown_to_html
from .plots import fit_titles

#: Files whose presence marks a folder as holding an earlier report.
REPORT_MARKERS = ("summary.json", "report.md", "report.html")
FIGURE_DPI = 100


def check_output_folder(out, overwrite: bool) -> Path:
    """The report folder, checked before any work by
    :func:`reliability.basics.files.check_destination`: refused if it is a file, if its parent
    does not exist, or if it holds an earlier report (:data:`REPORT_MARKERS`) and
    ``overwrite`` is false. :func:`write_report` creates it."""
    return check_destination(out, overwrite, folder=True, markers=REPORT_MARKERS)


def write_report(out, sections, summary: dict, *, title: str, overwrite: bool = False
                 ) -> list[Path]:
    """Write ``sections`` into ``out``; return the paths written.

    The report is assembled in a temporary folder beside ``out`` and moved into place only
    when every file is written, so an interrupted run leaves no partial report (and a rerun
    works without replacing anything).

    Parameters
    ----------
    out : str or Path
        Folder, created if absent (check it first with :func:`check_output_folder`).
    sections : list of Section
        In report order; their tables, figures and summary entries are written too.
    summary : dict
        Entries of ``summary.json`` (the sections' entries are merged into it).
    title : str
        Heading of the report.
    overwrite : bool
        Replace an earlier report: its files are replaced, and those it wrote (its
        ``summary.json`` lists them under ``files``) that this report does not write are
        removed, so the folder holds one report. Other files are never touched.

    Raises
    ------
    FileExistsError
        ``out`` already holds a file the report writes and ``overwrite`` is false (checked
        before anything is moved; the assembled report is removed).
    """
    out = check_output_folder(out, overwrite)
    staging = make_temporary_folder(out)
    try:
        names = _assemble(staging, sections, summary, title)
        clashes = [name for name in names if (out / name).exists()]
        if clashes and not overwrite:
            raise FileExistsError(f"{out / clashes[0]} exists; allow overwriting to "
                                  f"replace it")
        if not out.exists():
            staging.rename(out)
        else:
            stale = earlier_report_files(out) - set(names)
            for name in names:
                (staging / name).replace(out / name)
            staging.rmdir()
            for name in sorted(stale):
                (out / name).unlink(missing_ok=True)
    finally:
        if staging.exists():
            shutil.rmtree(staging)
    return [out / name for name in names]


def earlier_report_files(out: Path) -> set[str]:
    """The files an earlier report in ``out`` wrote, as its ``summary.json`` lists them
    (``files``); empty when there is none, or it lists none (a report of 0.3.0 or earlier),
    or it is not a report's summary. Only plain file names count, never a path."""
    try:
        listed = json.loads((out / "summary.json").read_text()).get("files", [])
    except (OSError, ValueError, AttributeError):
        return set()
    if not isinstance(listed, list):
        return set()
    return {name for name in listed if isinstance(name, str) and name == Path(name).name
            and name not in ("", ".", "..")}


def _assemble(folder: Path, sections, summary: dict, title: str) -> list[str]:
    """Write every file of the report into the empty ``folder``; return their names."""
    names, merged, images = [], merged_summary(summary, sections), {}
    for section in sections:
        for name, frame in section.tables.items():
            index = frame.index.name is not None or any(frame.index.names)
            write_csv(frame, folder / name, index=index, float_format=f"%.{SIGNIFICANT}g")
            names.append(name)
    for section in sections:
        for name, figure in section.figures.items():
            images[name] = png_bytes(figure)
            atomic_write_bytes(folder / name, images[name])
            names.append(name)
    names += ["report.md", "report.html", "summary.json"]
    merged["files"] = names
    atomic_write_text(folder / "report.md", render_markdown(title, sections))
    atomic_write_text(folder / "report.html", render_html(title, sections, images))
    atomic_write_text(folder / "summary.json", json.dumps(rounded(merged), indent=2) + "\n")
    return names


def merged_summary(summary: dict, sections) -> dict:
    """``summary`` with every section's entries added in report order; an entry that is a
    dict in both (e.g. ``not_computed``) holds the keys of both."""
    merged = dict(summary)
    for section in sections:
        for key, value in section.summary.items():
            both = isinstance(value, dict) and isinstance(merged.get(key), dict)
            merged[key] = {**merged[key], **value} if both else value
    return merged


def write_section(out, section, *, overwrite: bool = False) -> list[Path]:
    """One section as a report of its own in ``out`` (titled by the section; its summary
    entries make ``summary.json``); see :func:`write_report`."""
    return write_report(out, [section], {}, title=section.title, overwrite=overwrite)


def rounded(value):
    """``value`` with every float rounded to :data:`SIGNIFICANT` significant digits and
    numpy scalars made plain Python (for JSON)."""
    if isinstance(value, dict):
        return {str(k): rounded(v) for k, v in value.items()}
    if isinstance(value, (list, tuple, np.ndarray)):
        return [rounded(v) for v in value]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        value = float(value)
        return value if not math.isfinite(value) or value == 0 else \
            float(f"{value:.{SIGNIFICANT}g}")
    return value


def png_bytes(figure, dpi: int = FIGURE_DPI) -> bytes:
    """The figure as PNG bytes at ``dpi``, without a creation-software stamp (stable bytes),
    and closed: how every figure of a report or of the paper's reproduction is written."""
    import matplotlib.pyplot as plt
    buffer = io.BytesIO()
    fit_titles(figure)
    figure.savefig(buffer, format="png", dpi=dpi, metadata={"Software": None})
    plt.close(figure)
    return buffer.getvalue()


# ----- markdown ------------------------------------------------------------------------
def render_markdown(title: str, sections) -> str:
    """``report.md``: the title, then each section's text and the figures its text does
    not place itself (``![name](name)``)."""
    parts = [f"# {title}"]
    for section in sections:
        parts.append(f"## {section.title}\n\n{section.text.strip()}")
        parts += [f"![{name}]({name})" for name in trailing_figures(section)]
    return "\n\n".join(parts) + "\n"


def trailing_figures(section) -> list[str]:
    """The section's figures its text does not place, in order: they follow the text."""
    return [name for name in section.figures if f"]({name})" not in section.text]


# ----- HTML ----------------------------------------------------------------------------
STYLE = ("body{font-family:sans-serif;max-width:1300px;margin:1em auto;padding:0 1em;"
         "line-height:1.45;color:#222}h1{font-size:1.6em;margin:.3em 0}"
         "table{border-collapse:collapse;margin:1em 0;"
         "font-size:90%}td,th{border:1px solid #bbb;padding:3px 8px;text-align:right}"
         "td:first-child,th:first-child,td.text{text-align:left}"
         "th{background:#eee}img{max-width:100%;display:block;margin:1em 0}"
         "code{background:#f3f3f3;padding:0 3px}details{margin:.6em 0}"
         "summary{cursor:pointer;color:#245}"
         ".glance{display:flex;flex-wrap:wrap;gap:0 1.5em;align-items:flex-start}"
         ".glance table{margin-top:0;max-width:720px}.glance td,.glance th{text-align:left}"
         ".glance td:first-child{white-space:nowrap}"
         ".glance img{max-width:500px;margin-top:0}")


def render_html(title: str, sections, images: dict[str, bytes]) -> str:
    """``report.html``: the sections' markdown as HTML, figures inline as data URIs."""
    body = [f"<h1>{html.escape(title)}</h1>"]
    sources = {name: "data:image/png;base64," + base64.b64encode(data).decode("ascii")
               for name, data in images.items()}
    for section in sections:
        body.append(f'<h2 id="{anchor(section.title)}">{html.escape(section.title)}</h2>')
        body.append(markdown_to_html(section.text, sources))
        for name in trailing_figures(section):
            body.append(f'<img alt="{html.escape(name)}" src="{sources[name]}">')
    return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<title>{html.escape(title)}</title><style>{STYLE}</style></head>\n<body>\n"
            + "\n".join(body) + "\n</body></html>\n")
