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
