"""Sweeps: the same results.csv on every executor, resumable, changed tasks recomputed,
damaged store files detected, and the ``sweep`` command.

Tasks run on the 3-axis test mill with a 3-point grid and a few experiments, so a whole
sweep takes well under a second serially.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import shutil
import threading
from concurrent.futures import ProcessPoolExecutor, ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from allocation import AllocationProblem
from reliability.basics.errors import InputError, InputTypeError, SavedResultError
from reliability.model.machine_file import load_machine
from reliability.model.poses import workspace_grid
from reliability.sampling.verification import verify
from studies.cli import sweep as command
from studies.workflows.sweep import SweepSpec, SweepTask, run_sweep, run_task

MACHINES = Path(__file__).parent / "machines"


@pytest.fixture
def mill(tmp_path):
    """A private copy of the test mill, free to edit."""
    path = tmp_path / "mill3.toml"
    shutil.copy(MACHINES / "mill3.toml", path)
    return str(path)


def small_spec(machine, **changes):
    options = dict(machines=(machine,), sides=("one_sided", "two_sided"),
                   targets=(0.99, 0.999), seeds=(0, 1, 2), repeats=(3,), points=3)
    options.update(changes)
    return SweepSpec(**options)


class Counting:
    """Runs tasks and records which; raises after ``fail_after`` tasks when given."""

    def __init__(self, fail_after=None):
        self.fail_after = fail_after
        self.tasks = []
        self.lock = threading.Lock()

    def __call__(self, task, *allocated):
        with self.lock:
            if self.fail_after is not None and len(self.tasks) >= self.fail_after:
                raise KeyboardInterrupt("killed")
            self.tasks.append(task)
        return run_task(task, *allocated)


def test_serial_process_pool_and_dask_write_byte_identical_results(mill, tmp_path):
    spec = small_spec(mill)
    serial = run_sweep(spec, tmp_path / "serial")
    with ProcessPoolExecutor(2) as pool:
        pooled = run_sweep(spec, tmp_path / "processes", executor=pool)
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        dask = run_sweep(spec, tmp_path / "dask", executor=client)
    text = serial.path.read_bytes()
    assert pooled.path.read_bytes() == text
    assert dask.path.read_bytes() == text
    assert serial.computed == pooled.computed == dask.computed == 12
    assert len(serial.frame) == 12


def test_each_row_is_its_task_alone_and_the_allocation_is_the_exact_optimum(mill, tmp_path):
    spec = small_spec(mill)
    frame = run_sweep(spec, tmp_path / "store").frame
    task = spec.tasks()[7]
    alone = run_task(task)  # a fresh run of this task only: same stream, same numbers
    row = frame.iloc[7]
    assert row["seed"] == task.seed and row["side"] == task.side
    assert row["yield"] == alone["yield"]
    np.testing.assert_array_equal(row.filter(like="fraction_").to_numpy(dtype=float),
                                  alone["fraction"])
    machine = dataclasses.replace(load_machine(mill), targets=np.full(6, task.target))
    problem = AllocationProblem.build(machine, workspace_grid(machine, 3), side=task.side)
    best = problem.solve_exact()
    assert row["relative_cost"] == pytest.approx(best.cost / problem.cost.total(
        machine.initial_allocation), rel=1e-12)
    assert bool(row["certified"])
    checked = verify(machine, best.tolerances, points=3, repeats=task.repeats, samples=10,
                     rng=task.seed)  # same seed and allocation: the same grid experiments
    np.testing.assert_allclose(alone["fraction"], checked.grid.fractions.mean(axis=0),
                               rtol=1e-12)
    # a fraction is a mean of counts over 3 experiments of 27 poses
    counts = row.filter(like="fraction_").to_numpy(dtype=float) * 3 * 27
    np.testing.assert_allclose(counts, np.round(counts), atol=1e-9)


def test_different_seeds_give_different_streams(mill, tmp_path):
    frame = run_sweep(small_spec(mill, sides=("one_sided",), targets=(0.99,),
                                 seeds=tuple(range(6))), tmp_path / "store").frame
    fractions = frame.filter(like="fraction_").to_numpy()
    assert len({tuple(row) for row in fractions}) > 1


def test_results_csv_reads_back_as_the_result_table(mill, tmp_path):
    result = run_sweep(small_spec(mill, sides=("two_sided",), targets=(0.99,), seeds=(0,)),
                       tmp_path / "store")
    frame = result.to_frame()
    pd.testing.assert_frame_equal(frame, result.frame)
    assert frame is not result.frame and "1 task(s)" in result.summary()
    written = pd.read_csv(result.path, keep_default_na=False)
    assert list(written.columns) == list(frame.columns)
    numbers = frame.select_dtypes("number").columns
    np.testing.assert_allclose(written[numbers].to_numpy(float),
                               frame[numbers].to_numpy(float), rtol=5e-6, atol=0)


def test_killed_sweep_resumes_without_recomputing_finished_tasks(mill, tmp_path):
    spec = small_spec(mill)
    killed = Counting(fail_after=5)
    with pytest.raises(KeyboardInterrupt):
        run_sweep(spec, tmp_path / "store", task_function=killed)
    assert len(list((tmp_path / "store" / "tasks").glob("*.json"))) == 5
    resumed = Counting()
    messages = []
    result = run_sweep(spec, tmp_path / "store", task_function=resumed, log=messages.append)
    assert result.resumed == 5 and result.computed == 7
    assert messages == ["resumed: 5 of 12 tasks already done"]
    assert not set(killed.tasks) & set(resumed.tasks)  # no finished task computed again
    assert set(killed.tasks) | set(resumed.tasks) == set(spec.tasks())  # none lost
    reference = run_sweep(spec, tmp_path / "uninterrupted")
    assert result.path.read_bytes() == reference.path.read_bytes()
    again = Counting()
    assert run_sweep(spec, tmp_path / "store", task_function=again).computed == 0
    assert again.tasks == []


def test_interrupted_pool_sweep_loses_no_finished_task(mill, tmp_path):
    spec = small_spec(mill)
    store = tmp_path / "store"
    killed = Counting(fail_after=4)
    with ThreadPoolExecutor(2) as pool, pytest.raises(KeyboardInterrupt):
        run_sweep(spec, store, executor=pool, task_function=killed)
    stored = len(list((store / "tasks").glob("*.json")))
    assert 1 <= stored <= 4  # tasks finished before the interrupt was seen are stored
    resumed = Counting()
    result = run_sweep(spec, store, task_function=resumed)
    assert result.resumed == stored and result.computed == 12 - stored
    assert len(set(resumed.tasks)) == 12 - stored


def test_changed_tasks_are_recomputed(mill, tmp_path):
    store = tmp_path / "store"
    run_sweep(small_spec(mill), store)
    more = Counting()
    result = run_sweep(small_spec(mill, seeds=(0, 1, 2, 3)), store, task_function=more)
    assert result.computed == 4 and all(task.seed == 3 for task in more.tasks)
    text = Path(mill).read_text()
    assert "dx = { limit = 0.01," in text
    Path(mill).write_text(text.replace("dx = { limit = 0.01,", "dx = { limit = 0.012,"))
    edited = Counting()  # the machine changed: every task of it is a new task
    assert run_sweep(small_spec(mill), store, task_function=edited).computed == 12


def test_damaged_store_file_is_detected(mill, tmp_path):
    spec = small_spec(mill)
    store = tmp_path / "store"
    run_sweep(spec, store)
    stored = sorted((store / "tasks").glob("*.json"))
    record = json.loads(stored[0].read_text())
    record["result"]["yield"] = 1.0 - (record["result"]["yield"] or 0.0) + 0.5
    stored[0].write_text(json.dumps(record))
    with pytest.raises(SavedResultError, match="checksum"):
        run_sweep(spec, store)
    stored[0].write_text(stored[0].read_text()[:40])  # cut short
    with pytest.raises(SavedResultError, match="damaged"):
        run_sweep(spec, store)


def test_spec_from_toml_and_its_checks(mill, tmp_path):
    path = tmp_path / "spec.toml"
    path.write_text(f'machines = ["hobbing", "{Path(mill).name}"]\nsides = ["one_sided"]\n'
                    'targets = [0.99]\nseeds = [0, 1]\nrepeats = [2, 4]\n')
    spec = SweepSpec.from_toml(path)
    assert spec.machines == ("hobbing", str(tmp_path / "mill3.toml"))
    tasks = spec.tasks()
    assert len(tasks) == 2 * 1 * 1 * 1 * 2 * 2
    assert tasks[1] == SweepTask("hobbing", "one_sided", 0.99, "independent", 0, 4, 5)
    with pytest.raises(InputError, match="unknown key 'target'"):
        SweepSpec.from_dict({"machines": ["hobbing"], "target": [0.9]})
    with pytest.raises(InputError, match="side 'both'"):
        SweepSpec(machines=("hobbing",), sides=("both",))
    with pytest.raises(InputError, match="target 1.5"):
        SweepSpec(machines=("hobbing",), targets=(1.5,))
    with pytest.raises(InputError, match="does not exist"):
        SweepSpec(machines=(str(tmp_path / "missing.toml"),))
    with pytest.raises(InputError, match="repeats entry 0"):
        SweepSpec(machines=("hobbing",), repeats=(0,))
    with pytest.raises(InputTypeError, match="executor"):
        run_sweep(spec, tmp_path / "store", executor=object())


def test_unknown_profiles_are_refused_by_name(mill):
    with pytest.raises(InputError, match="profile 'ramp'"):
        small_spec(mill, profiles=("ramp",))


def parse(argv):
    parser = argparse.ArgumentParser(prog="precrel")
    command.add_parser(parser.add_subparsers(dest="command"))
    return parser.parse_args(argv)


def test_command_writes_results_and_reports_resumed_tasks(mill, tmp_path, capsys):
    spec = tmp_path / "spec.toml"
    spec.write_text(f'machines = ["{mill}"]\nsides = ["two_sided"]\ntargets = [0.99]\n'
                    'seeds = [0, 1]\nrepeats = [2]\npoints = 3\n')
    store = tmp_path / "out"
    assert command.run(parse(["sweep", str(spec), "--out", str(store)])) == 0
    first = capsys.readouterr()
    assert "2 task(s) computed" in first.out and "resumed" not in first.out
    assert "sweep" in first.err  # the progress bar
    lines = (store / "results.csv").read_text().splitlines()
    assert len(lines) == 3 and lines[0].startswith("machine,side,target,profile,seed")
    assert command.run(parse(["sweep", str(spec), "--out", str(store), "--executor",
                              "processes", "--workers", "2"])) == 0
    assert "resumed: 2 of 2 tasks already done" in capsys.readouterr().out
    with pytest.raises(InputError, match="--scheduler needs --executor dask"):
        command.run(parse(["sweep", str(spec), "--out", str(store), "--executor",
                           "processes", "--scheduler", "tcp://localhost:8786"]))
    with pytest.raises(InputError, match="--workers needs --executor processes or dask"):
        command.run(parse(["sweep", str(spec), "--out", str(store), "--workers", "2"]))
    with pytest.raises(SystemExit):
        parse(["sweep", str(spec), "--out", str(store), "--executor", "processes",
               "--workers", "0"])
    assert "--workers: expected an integer >= 1" in capsys.readouterr().err


def test_command_still_reads_the_old_store_spelling(mill, tmp_path, capsys):
    """``--store DIR``, the old spelling of ``--out DIR``, works with a warning."""
    spec = tmp_path / "spec.toml"
    spec.write_text(f'machines = ["{mill}"]\nsides = ["two_sided"]\ntargets = [0.99]\n'
                    'seeds = [0]\nrepeats = [2]\npoints = 3\n')
    assert command.run(parse(["sweep", str(spec), "--store", str(tmp_path / "s")])) == 0
    err = capsys.readouterr().err
    assert "precrel: warning: --store is deprecated; use --out" in err
    assert (tmp_path / "s" / "results.csv").exists()


def test_unreachable_target_is_recorded_not_raised(mill, tmp_path):
    # z = Φ⁻¹(1 − 1e-12) ≈ 7.0: more than twice the σ budget of z ≈ 2.6 at 0.99, beyond
    # what the tightest tolerances of the box (half the initial ones) can give
    spec = small_spec(mill, sides=("two_sided",), targets=(0.99, 1 - 1e-12), seeds=(0,))
    frame = run_sweep(spec, tmp_path / "store").frame
    assert frame["status"].tolist() == ["ok", "unreachable"]
    assert np.isnan(frame["relative_cost"].iloc[1]) and not frame["certified"].iloc[1]
    assert frame.filter(like="fraction_").iloc[1].isna().all()
    assert pd.isna(frame["reason"].iloc[0]) or frame["reason"].iloc[0] == ""
    assert "unreachable inside the bounds" in frame["reason"].iloc[1]
    assert " mm" in frame["reason"].iloc[1]  # the blocking σ with its unit


def test_spec_bounds_set_the_box_of_every_task(mill, tmp_path):
    spec = small_spec(mill, sides=("two_sided",), targets=(1 - 1e-12,), seeds=(0,),
                      bounds=[0.01, 1.5])
    frame = run_sweep(spec, tmp_path / "store").frame
    assert frame["status"].tolist() == ["ok"]  # unreachable in [0.5, 1.5], reached here
    assert (frame["bounds_low"].tolist(), frame["bounds_high"].tolist()) == ([0.01], [1.5])
    machine = dataclasses.replace(load_machine(mill), targets=np.full(6, 1 - 1e-12))
    problem = AllocationProblem.build(machine, workspace_grid(machine, 3), bounds=(0.01, 1.5))
    expected = problem.solve_exact().cost / problem.cost.total(machine.initial_allocation)
    written = pd.read_csv(tmp_path / "store" / "results.csv")
    assert written["relative_cost"].iloc[0] == float(f"{expected:.6g}")  # 6 digits, as stated
    for bad, words in (([1.5, 0.5], "LO exceeds HI"), ([0.5], "[LO, HI]"),
                       ([0, 1], "> 0"), ("wide", "[LO, HI]")):
        with pytest.raises(InputError, match=words.replace("[", r"\[").replace("]", r"\]")):
            small_spec(mill, bounds=bad)


def test_profiles_reach_the_grid_experiment(mill, tmp_path):
    """A constant profile's task equals a grid experiment with that profile, seeded alike."""
    spec = small_spec(mill, sides=("two_sided",), targets=(0.99,), seeds=(0,),
                      profiles=("independent", "constant"), repeats=(40,))
    frame = run_sweep(spec, tmp_path / "store").frame.set_index("profile")
    task = [t for t in spec.tasks() if t.profile == "constant"][0]
    alone = run_task(task)
    assert frame.loc["constant", "yield"] == alone["yield"]
    # one value per machine along travel: whole machines pass or fail together more often
    assert frame.loc["constant", "yield"] != frame.loc["independent", "yield"]


def test_a_task_yield_is_the_machine_yield_verify_prints(mill, tmp_path):
    """One engine, one stream: a task's yield is the machine yield that ``verify`` computes
    for the same allocation, seed, machine count (the task's repeats) and profile."""
    spec = small_spec(mill, sides=("two_sided",), targets=(0.99,), seeds=(3,),
                      profiles=("gp:300",), repeats=(40,))
    task = spec.tasks()[0]
    row = run_task(task)
    machine = dataclasses.replace(load_machine(mill), targets=np.full(6, task.target))
    problem = AllocationProblem.build(machine, workspace_grid(machine, 3), side="two_sided")
    checked = verify(machine, problem.solve_exact().tolerances, repeats=2, samples=10,
                     points=3, rng=3, profile="gp:300", machines=40,
                     distribution=machine.distribution)
    assert row["yield"] == checked.machine_yield.estimate
