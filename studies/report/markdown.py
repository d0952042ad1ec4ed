"""The small markdown the reports use: pipe tables from DataFrames, and its HTML rendering.

:func:`markdown_table` writes a GitHub-flavoured table; :func:`markdown_to_html` renders the
subset the report sections use (paragraphs, ``-`` lists, pipe tables, ``###`` headings,
``**bold**``, ``code``, ``[links](#anchor)``, ``![figure](name.png)`` and the raw HTML
block lines of :data:`RAW_HTML`) for the self-contained ``report.html``. GitHub renders the
same raw blocks in ``report.md``, so a ``<details>`` block folds there too.
"""

from __future__ import annotations

import html
import re

import numpy as np
import pandas as pd

from reliability.basics.display import (lower_bound_text, percent_number,
                                        probability_bound_text, upper_bound_text)


#: Opening of the lines passed to HTML as they are: the folding blocks (``<details>``,
#: ``<summary>``) and the boxes (``<div class="...">``) the first screen lays out.
RAW_HTML = ("<details", "</details>", "<summary", "<div", "</div>")


def anchor(title: str) -> str:
    """The anchor of a section heading as GitHub makes it (and ``report.html`` sets it):
    lower case, punctuation dropped but for ``-`` and ``_``, spaces as ``-``."""
    kept = re.sub(r"[^\w\- ]", "", title.strip().lower())
    return kept.replace(" ", "-")


def details(summary: str, body: str) -> str:
    """``body`` (markdown) folded under ``summary`` in a ``<details>`` block: shut in
    ``report.html`` and on GitHub, opened with a click."""
    return f"<details><summary>{html.escape(summary)}</summary>\n\n{body.strip()}\n\n</details>"


def markdown_table(frame: pd.DataFrame, formats: dict | None = None,
                   index: bool = True) -> str:
    """A GitHub-flavoured markdown table; ``formats`` maps column -> formatter."""
    formats = formats or {}
    frame = frame.reset_index() if index else frame
    header = "| " + " | ".join(str(c) for c in frame.columns) + " |"
    rule = "| " + " | ".join("---" for _ in frame.columns) + " |"
    rows = []
    for _, row in frame.iterrows():
        cells = [formats.get(c, format_cell)(row[c]) for c in frame.columns]
        rows.append("| " + " | ".join(cells) + " |")
    return "\n".join([header, rule, *rows])


def interval_formats(show, lower=(), upper=()) -> dict:
    """Formats for :func:`markdown_table` that round each column of ``lower`` (lower bounds,
    an interval's lower ends) down and each of ``upper`` up, so a printed bound still
    bounds: ``show(value, bound)`` with ``bound`` ``"lower"`` or ``"upper"`` (one of
    :func:`significant_bound`, :func:`percent_bound`, :func:`probability_bound`); NaN as
    ``–``."""
    def cell(bound):
        return lambda value: "–" if np.isnan(value) else show(value, bound)
    return {column: cell("lower") for column in lower} | \
        {column: cell("upper") for column in upper}


def significant_bound(digits: int):
    """``show`` for :func:`interval_formats`: ``digits`` significant digits
    (:func:`~reliability.basics.display.upper_bound_text`, ``lower_bound_text``)."""
    return lambda value, bound: (upper_bound_text if bound == "upper" else
                                 lower_bound_text)(value, digits)


def percent_bound(decimals: int):
    """``show`` for :func:`interval_formats`: a probability in per cent to ``decimals``
    decimals, ``"98.930%"`` (:func:`~reliability.basics.display.percent_number`)."""
    return lambda value, bound: f"{percent_number(value, bound, decimals)}%"


def probability_bound(value: float, bound: str) -> str:
    """``show`` for :func:`interval_formats`: a yield's interval end as yields are shown
    (:func:`~reliability.basics.display.probability_bound_text`)."""
    return probability_bound_text(value, upper=bound == "upper")


def format_cell(value) -> str:
    """A table cell: yes/no for booleans, 5 significant digits for floats (– for NaN)."""
    if isinstance(value, (bool, np.bool_)):
        return "yes" if value else "no"
    if isinstance(value, (float, np.floating)):
        return "–" if np.isnan(value) else f"{value:.5g}"
    return str(value)


def markdown_to_html(text: str, images: dict | None = None) -> str:
    """The markdown the report sections use: paragraphs, ``-`` lists, pipe tables,
    ``###`` headings, ``**bold**``, ``code``, links, the raw lines of :data:`RAW_HTML`, and
    figures ``![alt](name)`` drawn from ``images`` (name -> ``src``, e.g. a data URI)."""
    blocks, out = re.split(r"\n\s*\n", text.strip()), []
    for block in blocks:
        lines = block.strip().splitlines()
        if all(line.lstrip().startswith(RAW_HTML) for line in lines):
            out.append("\n".join(lines))
        elif all(_FIGURE.fullmatch(line.strip()) for line in lines):
            out += [_figure(line.strip(), images or {}) for line in lines]
        elif all(line.lstrip().startswith("|") for line in lines):
            out.append(_table(lines))
        elif all(line.lstrip().startswith("- ") for line in lines):
            out.append("<ul>" + "".join(f"<li>{_inline(line.lstrip()[2:])}</li>"
                                        for line in lines) + "</ul>")
        elif lines[0].startswith("#"):
            level = min(6, len(lines[0]) - len(lines[0].lstrip("#")) + 2)
            out.append(f"<h{level}>{_inline(lines[0].lstrip('#').strip())}</h{level}>")
            if lines[1:]:
                out.append(f"<p>{_inline(' '.join(lines[1:]))}</p>")
        else:
            out.append(f"<p>{_inline(' '.join(lines))}</p>")
    return "\n".join(out)


_FIGURE = re.compile(r"!\[([^\]]*)\]\(([^)\s]+)\)")


def _figure(line: str, images: dict) -> str:
    alt, name = _FIGURE.fullmatch(line).groups()
    return f'<img alt="{html.escape(alt)}" src="{html.escape(images.get(name, name))}">'


def _table(lines) -> str:
    rows = [[cell.strip() for cell in line.strip().strip("|").split("|")] for line in lines
            if not re.fullmatch(r"\|?[\s:|-]+\|?", line.strip())]
    head = "".join(f"<th>{_inline(c)}</th>" for c in rows[0])
    body = "".join("<tr>" + "".join(_cell(c) for c in row) + "</tr>" for row in rows[1:])
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


#: A cell that reads as a number (a sign, digits, an exponent, a per cent, an interval's
#: brackets, or ``–`` for none): right-aligned; any other cell is text, left-aligned.
_NUMBER = re.compile(r"[-+−]?[\d.,]+(e[-+]?\d+)?\s*%?|–|\[[\d.,\s%e+-]+\]")


def _cell(text: str) -> str:
    if _NUMBER.fullmatch(text.replace("*", "").strip()):
        return f"<td>{_inline(text)}</td>"
    return f'<td class="text">{_inline(text)}</td>'


def _inline(text: str) -> str:
    text = html.escape(text)
    text = re.sub(r"\*\*(.+?)\*\*", r"<strong>\1</strong>", text)
    text = re.sub(r"\[([^\]]+)\]\((#[\w-]+)\)", r'<a href="\2">\1</a>', text)
    return re.sub(r"`(.+?)`", r"<code>\1</code>", text)
