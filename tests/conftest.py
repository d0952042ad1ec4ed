"""Shared fixtures: the paper's hobbing machine and two test machines (tests/machines)."""

from __future__ import annotations

import copy
import tomllib
from importlib import resources
from pathlib import Path

import pytest
from threadpoolctl import threadpool_limits

import reliability

MACHINE_DIR = Path(__file__).parent / "machines"


#: Modules whose tests take longest, longest first. They run first, so that the two
#: workers share them from the start and no long test is left for one worker at the end.
LONG_MODULES = ("test_other_computers", "test_reproduce", "test_cli", "test_trust",
                "test_continuous", "test_rare",
                "test_plots", "test_sampling", "test_acceptance", "test_system",
                "test_combinations", "test_bounds_table", "test_report_study",
                "test_correlation", "test_pose_sampling", "test_yield_target",
                "test_yield_dual", "test_sweep", "test_one_answer", "test_bad_inputs",
                "test_chunking", "test_layout", "test_catalogue", "test_report_tables",
                "test_rare_section", "test_compensation", "test_profiles_study",
                "test_yield_bracket", "test_gp_identification", "test_as_measured",
                "test_zone_certificate")


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(items):
    """Run the tests of :data:`LONG_MODULES` first, each module's tests kept together and in
    their order, and give every test not already in an xdist group its module's: with
    ``--dist loadgroup`` a module runs on one worker, so its module-scoped fixtures are built
    once."""
    def name(item):
        return item.module.__name__.rsplit(".", 1)[-1]

    def rank(item):
        return LONG_MODULES.index(name(item)) if name(item) in LONG_MODULES else \
            len(LONG_MODULES)
    items.sort(key=rank)
    for item in items:
        if item.get_closest_marker("xdist_group") is None:
            item.add_marker(pytest.mark.xdist_group(name(item)))


@pytest.fixture(scope="session", autouse=True)
def one_blas_thread():
    """BLAS pinned to one thread: threads fight on a busy 2-core machine."""
    with threadpool_limits(limits=1):
        yield


@pytest.fixture(scope="session")
def hobbing():
    """The paper's CNC-LGHM, C X Z A Y M (Tables 2-5)."""
    return reliability.hobbing_machine()


@pytest.fixture(scope="session")
def mill3():
    """A 3-axis mill, Y X Z, all linear, with axis offsets and a tool offset."""
    return reliability.load_machine(MACHINE_DIR / "mill3.toml")


@pytest.fixture(scope="session")
def trunnion5():
    """A 5-axis trunnion machine, C A Y X Z, with offsets and a tool offset."""
    return reliability.load_machine(MACHINE_DIR / "trunnion5.toml")


@pytest.fixture(scope="session")
def small_paper_study():
    """The paper's case study, quick (few wolves, iterations and repeats): for tests of its
    plumbing and figures, not its numbers. Its tests share the xdist group
    ``small_paper_study``, so that it is computed once."""
    from studies.paper import reproduce
    return reproduce.run_study(seed=7, repeats=3, wolves=8, iterations=10,
                               random_samples=2000)


@pytest.fixture(scope="session")
def lean_mill_report(tmp_path_factory):
    """A report of mill3 without its optional sections (seed 4, small samples), written
    under the umask 022: its folder and what the command printed. Its tests share the xdist
    group ``lean_mill_report``, so that it is written once."""
    import contextlib
    import io
    import os
    from types import SimpleNamespace

    from studies import cli

    folder = tmp_path_factory.mktemp("lean") / "report"
    printed, previous = io.StringIO(), os.umask(0o022)
    try:
        with contextlib.redirect_stdout(printed):
            assert cli.main(["report", str(MACHINE_DIR / "mill3.toml"), "--out", str(folder),
                             "--seed", "4", *LEAN_REPORT]) == 0
    finally:
        os.umask(previous)
    return SimpleNamespace(folder=folder, printed=printed.getvalue())


#: The options of :func:`lean_mill_report`.
LEAN_REPORT = ("--repeats", "3", "--samples", "1000", "--points", "3", "--machines", "400",
               "--skip", "front", "system", "rare", "profiles")


@pytest.fixture(scope="session", params=["hobbing", "mill3", "trunnion5"])
def any_machine(request):
    """Each of the three machines in turn."""
    return request.getfixturevalue(request.param)


@pytest.fixture(scope="session")
def _hobbing_table():
    text = resources.files("reliability").joinpath("machines/hobbing.toml").read_text()
    return tomllib.loads(text)


@pytest.fixture
def hobbing_dict(_hobbing_table):
    """A fresh, freely editable copy of the parsed hobbing.toml (the TOML layout)."""
    return copy.deepcopy(_hobbing_table)
