"""A command whose reader leaves (``precrel allocate ... | head``) still writes its files."""

from __future__ import annotations

import sys
from pathlib import Path

from studies import cli

MILL = str(Path(__file__).parent / "machines" / "mill3.toml")


class ClosedAfterOneLine:
    """Standard output whose reader leaves after the first write."""

    def __init__(self):
        self.writes = 0

    def write(self, text):
        self.writes += 1
        if self.writes > 1:
            raise BrokenPipeError(32, "Broken pipe")
        return len(text)

    def flush(self):
        pass


def test_allocate_writes_its_files_when_the_reader_leaves(tmp_path, monkeypatch):
    monkeypatch.setattr(sys, "stdout", ClosedAfterOneLine())
    out = tmp_path / "a.csv"
    assert cli.main(["allocate", MILL, "--workspace", "grid", "--points", "3", "--quiet",
                     "--out", str(out)]) == 0
    assert out.exists() and (tmp_path / "a.drawing.csv").exists()
