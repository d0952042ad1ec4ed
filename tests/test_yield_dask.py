"""Built machines simulated on Dask (reliability.sampling.machine_blocks): the allocation for
a yield target gives the local run's bytes, and ``precrel allocate --yield --scheduler`` runs
it on that scheduler."""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
import pytest

from allocation import allocate_for_yield
from allocation.machine_yield.yield_search import SAMPLES
from reliability.basics import chunks
from reliability.basics.errors import InputError, InputTypeError
from reliability.sampling.machine_blocks import MachineBlocks
from studies import cli
from studies.cli import allocate as allocate_command

distributed = pytest.importorskip("distributed")

MACHINE = str(Path(__file__).parent / "machines" / "mill3.toml")
SMALL = {"points": 3, "machines": 100, "rng": 5, "rounds": 1, "naive_steps": 4,
         "restore_steps": 2, "shape_steps": 2, "profile": "independent"}
#: A memory budget that splits the 100 machines into several blocks: two of the whole grid
#: (every grid point decides under the independent profile), eight of the screened poses.
BUDGET = 500_000


@pytest.fixture(scope="module")
def client():
    with distributed.LocalCluster(processes=False, n_workers=2, threads_per_worker=1,
                                  dashboard_address=None) as cluster, \
            distributed.Client(cluster) as dask_client:
        yield dask_client


@pytest.fixture
def several_blocks(monkeypatch):
    monkeypatch.setattr(chunks, "MEMORY_BUDGET", BUDGET)


def share(estimate) -> tuple:
    """A proportion's numbers, to compare two of them."""
    return estimate.estimate, estimate.lower, estimate.upper, estimate.n


def test_allocation_on_dask_is_the_local_one(mill3, client, several_blocks, monkeypatch):
    """Every number of the result is the local run's, the blocks ran as tasks of the client,
    and the workers got the model and each sample of built machines, once each."""
    local = allocate_for_yield(mill3, 0.9, **SMALL)
    scattered = []

    def scatter(value, **options):
        scattered.append(value)
        return type(client).scatter(client, value, **options)
    monkeypatch.setattr(client, "scatter", scatter)
    with distributed.get_task_stream(client) as tasks:
        remote = allocate_for_yield(mill3, 0.9, executor=client, **SMALL)
    for name in ("tolerances", "output_targets", "lower_bound_tolerances"):
        assert np.array_equal(getattr(remote, name), getattr(local, name)), name
    for name in ("cost", "method", "evaluations", "lower_bound", "design_yield_target"):
        assert getattr(remote, name) == getattr(local, name), name
    assert np.array_equal(remote.naive.tolerances, local.naive.tolerances)
    assert (remote.naive.target, remote.naive.cost) == (local.naive.target, local.naive.cost)
    assert remote.summary() == local.summary()
    for mine, theirs in ((remote, local), (remote.naive, local.naive)):
        for sample in ("design_yield", "verified_yield"):
            assert share(getattr(mine, sample)) == share(getattr(theirs, sample)), sample
    ran = [task for task in tasks.data if task["key"].startswith("_block")]
    assert len(ran) > 3 * len(scattered)
    assert [type(value).__name__ for value in scattered] == \
        ["YieldModel", *["ndarray"] * len(SAMPLES)]


def test_cli_simulates_on_the_scheduler_it_is_given(client, tmp_path, monkeypatch):
    """``--scheduler ADDRESS`` hands allocate_for_yield a client of that scheduler, closed
    afterwards (the allocation itself is the local one: the test above)."""
    given = []

    def allocate(machine, yield_target, **options):
        given.append((options["executor"], options["executor"].scheduler.address))
        raise InputError("stopped before the search")
    monkeypatch.setattr(allocate_command, "allocate_for_yield", allocate)
    code = cli.main(["allocate", MACHINE, "--yield", "0.9", "--points", "3",
                     "--out", str(tmp_path / "a.csv"), "--scheduler", client.scheduler.address])
    assert code == 2
    assert [address for _, address in given] == [client.scheduler.address]
    assert given[0][0].status == "closed"


@pytest.mark.parametrize("extra, words", [
    (["--scheduler", "tcp://127.0.0.1:1"], "--scheduler is used with --yield only"),
    (["--executor", "dask"], "--executor is used with --yield only"),
    (["--workers", "2"], "--workers is used with --yield only"),
    (["--yield", "0.9", "--executor", "serial", "--scheduler", "tcp://127.0.0.1:1"],
     "--scheduler needs --executor dask"),
    (["--yield", "0.9", "--workers", "2"], "--workers needs --executor dask"),
    (["--yield", "0.9", "--workers", "2", "--scheduler", "tcp://127.0.0.1:1"],
     "--workers sizes a local Dask cluster"),
    (["--yield", "0.9", "--workers", "0", "--executor", "dask"], "--workers"),
    (["--yield", "0.9", "--scheduler", "nowhere:port"],
     "--scheduler nowhere:port: no Dask scheduler answers there"),
])
def test_cli_refuses_bad_dask_options_by_name(tmp_path, capsys, extra, words):
    code = cli.main(["allocate", MACHINE, "--points", "3", "--out", str(tmp_path / "a.csv"),
                     *extra])
    assert code == 2
    err = capsys.readouterr().err.strip()
    assert words in err
    assert len(err.splitlines()) == 1
    assert not (tmp_path / "a.csv").exists()


def test_cli_without_dask_names_the_extra(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)
    code = cli.main(["allocate", MACHINE, "--yield", "0.9", "--points", "3",
                     "--out", str(tmp_path / "a.csv"), "--scheduler", "tcp://127.0.0.1:1"])
    assert code == 2
    err = capsys.readouterr().err
    assert "--scheduler needs the dask extra" in err
    assert "precision-reliability[dask]" in err


def scaled_sums(scale, u, offset):
    """A per-machine function of the blocks: each row's sum times ``scale`` plus its
    offset."""
    return u.sum(axis=1) * scale[0] + offset


def test_blocks_ship_each_array_once_and_release_it_after_it(client, monkeypatch):
    """Blocks give the same rows here and on the client, in block order; each object goes
    to the workers once and is released there once the caller has dropped it."""
    scale, u, offset = np.array([2.0]), np.arange(12.0).reshape(6, 2), np.arange(6.0) / 10
    blocks = [slice(0, 4), slice(4, 6)]
    expected = 2 * u.sum(axis=1) + offset
    there = MachineBlocks(client)
    futures = []

    def scatter(value, **options):
        futures.append(type(client).scatter(client, value, **options))
        return futures[-1]
    monkeypatch.setattr(client, "scatter", scatter)
    for blocks_of in (MachineBlocks(), there, there):
        parts = blocks_of.map(scaled_sums, scale, u, blocks, per_machine=(offset,))
        assert [len(part) for part in parts] == [4, 2]
        assert np.array_equal(np.concatenate(parts), expected)
    assert len(futures) == 2  # scale and u, once each
    dropped = futures.pop().key
    del u
    there.map(scaled_sums, scale, np.ones((6, 2)), blocks, per_machine=(offset,))
    assert len(futures) == 2  # and the new draws
    waited = time.monotonic() + 5.0  # the client releases a key on its event loop
    while dropped in client.futures and time.monotonic() < waited:
        time.sleep(0.01)
    assert dropped not in client.futures


def test_an_executor_that_is_no_dask_client_is_refused_by_name():
    with pytest.raises(InputTypeError, match="executor"):
        MachineBlocks(object())
