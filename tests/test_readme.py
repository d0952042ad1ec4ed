"""The README's example runs as written (docs kept in step with the code)."""

import re
from pathlib import Path

README = Path(__file__).resolve().parents[1] / "README.md"


def python_blocks(text: str) -> list[str]:
    return re.findall(r"```python\n(.*?)```", text, flags=re.S)


def test_readme_example_runs(tmp_path, monkeypatch, capsys):
    blocks = python_blocks(README.read_text())
    assert blocks, "README has no python example"
    monkeypatch.chdir(tmp_path)
    for block in blocks:
        exec(compile(block, "README.md", "exec"), {})
    assert (tmp_path / "runs.csv").exists()
    assert "dx" in capsys.readouterr().out


def test_readme_starts_with_the_two_commands():
    lines = [line for line in README.read_text().splitlines() if line.strip()]
    fence = lines.index("```")
    main, tests = lines[fence + 1], lines[fence + 2]
    assert "studies.reproduce_paper" in main and "--out figures" in main
    assert "pytest" in tests
    ci = (README.parent / ".ci" / "run").read_text()
    assert tests in ci, "CI must run the README's test command verbatim"
