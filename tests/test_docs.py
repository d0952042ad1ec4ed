"""The documentation stands on its own: examples load, tutorial code runs, links resolve."""

import re
from pathlib import Path

import pytest

import reliability

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
PAGES = sorted(DOCS.glob("*.md"))
LINK = re.compile(r"\]\(([^)#\s]+)(?:#[^)]*)?\)")


def python_blocks(page: Path) -> list[str]:
    """The ```python code blocks of a markdown page, in order."""
    return re.findall(r"```python\n(.*?)```", page.read_text(), flags=re.S)


MACHINE_FILES = sorted(p for p in (DOCS / "examples").glob("*.toml")
                       if "[[axes]]" in p.read_text())


def test_the_examples_include_a_machine():
    assert MACHINE_FILES


@pytest.mark.parametrize("path", MACHINE_FILES, ids=lambda p: p.name)
def test_example_machines_load(path):
    machine = reliability.load_machine(path)
    assert machine.n_errors == 6 * (2 * len(machine.axes) - 1)


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.name)
def test_relative_links_resolve(page):
    targets = [t for t in LINK.findall(page.read_text()) if "://" not in t]
    missing = [t for t in targets if not (page.parent / t).exists()]
    assert not missing, f"{page.name} links to missing files {missing}"


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.name)
def test_pages_point_only_inside_the_repository(page):
    """Links and quoted paths that climb out of docs/ must still land in the repository."""
    text = page.read_text()
    climbing = LINK.findall(text) + re.findall(r"`(\.\./[^`\s]+)`", text)
    outside = [t for t in climbing if t.startswith("..")
               and ROOT not in (page.parent / t).resolve().parents]
    assert not outside, f"{page.name} points outside the repository: {outside}"


def test_tutorial_python_runs(monkeypatch):
    monkeypatch.chdir(ROOT)
    namespace = {}
    blocks = python_blocks(DOCS / "tutorial.md")
    assert len(blocks) >= 4
    for block in blocks:
        exec(compile(block, "docs/tutorial.md", "exec"), namespace)
    assert namespace["relative"] < 1.0
    assert namespace["result"].repeats == 20


CODE_NAME = re.compile(r"`[^`]*?\b((?:reliability|allocation|studies)(?:\.[A-Za-z_]\w*)+)[^`]*`")
FILE_SUFFIXES = (".csv", ".md", ".json", ".toml", ".png", ".html", ".py")


def resolves(dotted: str) -> bool:
    """Whether ``dotted`` names an importable module or an attribute reached from one."""
    import importlib
    parts = dotted.split(".")
    for cut in range(len(parts), 0, -1):
        try:
            found = importlib.import_module(".".join(parts[:cut]))
        except ImportError:
            continue
        for name in parts[cut:]:
            if not hasattr(found, name):
                return False
            found = getattr(found, name)
        return True
    return False


def test_the_resolver_tells_a_module_from_a_missing_one():
    assert resolves("reliability.first_order.fosm.error_sigma")
    assert not resolves("reliability.fosm_that_never_was")


@pytest.mark.parametrize("page", PAGES + [ROOT / "README.md"], ids=lambda p: p.name)
def test_code_names_in_the_docs_resolve(page):
    names = {m for m in CODE_NAME.findall(page.read_text()) if not m.endswith(FILE_SUFFIXES)
             and not any(f"{m}{s}" in page.read_text() for s in FILE_SUFFIXES)}
    missing = sorted(name for name in names if not resolves(name))
    assert not missing, f"{page.name} names modules or objects that do not exist: {missing}"
