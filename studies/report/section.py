"""One section of a machine report: its text, figures, tables and summary entries.

Every analysis that appears in ``precrel report`` (allocation, verification, the
cost–reliability front, system reliability, rare events, error profiles) returns a
:class:`Section`; the report writer lays the sections out in markdown and HTML, writes
their tables as CSV and their figures as PNG, and merges their summary entries into
``summary.json``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import pandas as pd


@dataclass
class Section:
    """A titled part of a report.

    Attributes
    ----------
    title : str
        Heading, e.g. ``"Cost against reliability"``.
    text : str
        Markdown body (paragraphs and tables), without the heading. Figures are referred to
        by their file names and placed by the writer after the text.
    figures : dict[str, matplotlib.figure.Figure]
        PNG file name -> figure, in the order they should appear.
    tables : dict[str, pandas.DataFrame]
        CSV file name -> table, written next to the report.
    summary : dict
        JSON-serialisable entries merged into ``summary.json``.
    """

    title: str
    text: str
    figures: dict = field(default_factory=dict)
    tables: dict[str, pd.DataFrame] = field(default_factory=dict)
    summary: dict = field(default_factory=dict)
