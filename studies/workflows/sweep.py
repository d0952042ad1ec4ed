"""Sweeps: many allocate-and-verify tasks, serially, on a process pool or on a Dask cluster.

A sweep is the table of every combination of machine × reading (side) × target × error
profile × seed × repeats. Each task

1. builds the worst-case allocation problem on the machine's workspace grid, with every
   output's target replaced by the task's target, and solves it exactly (certified);
2. verifies the allocation by the grid experiment of Sec. 5.3 (``repeats`` experiments),
   recording the mean share of poses in tolerance per output and the machine-level yield
   (share of experiments in which every pose meets every limit).

Reproducible under any executor: a task's grid experiments draw from the grid stream of
:func:`reliability.streams.verification_streams` of the task's seed, never from the worker
or the order of execution, so serial, process-pool and Dask runs write byte-identical
``results.csv``, and a task's numbers are those of ``precrel verify --seed S`` on its
allocation (the grid experiments, for the ``independent`` profile).

Resumable: each finished task is stored at once, one file per task
(:class:`reliability.checkpoint.ResultStore`), keyed by its parameters and the toolkit
version. A sweep started again computes only the tasks without a stored result.
"""

from __future__ import annotations

import functools
import itertools
import tomllib
from concurrent.futures import Executor, as_completed
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np
import pandas as pd
from threadpoolctl import threadpool_limits

from allocation.problem import AllocationProblem
from allocation.solve import TargetUnreachableError
from reliability.checkpoint import ResultStore, machine_fingerprint
from reliability.errors import InputError, InputTypeError
from reliability.files import SIGNIFICANT, write_csv
from reliability.machine import OUTPUTS, hobbing_machine, load_machine
from reliability.poses import workspace_grid
from reliability.profiles import profile_model
from reliability.sampling import GridExperiment
from reliability.streams import verification_streams

PAPER_MACHINE = "hobbing"
INDEPENDENT = "independent"
SIDES = ("one_sided", "two_sided")
SPEC_KEYS = {"machines", "sides", "targets", "profiles", "seeds", "repeats",
             "points_per_axis", "bounds", "distribution"}
DISTRIBUTIONS = ("normal", "truncated")
#: The search box of every task when the spec gives none (factors of the initial allocation).
DEFAULT_BOUNDS = (0.5, 1.5)
RESULTS_FILE = "results.csv"
TASKS_FOLDER = "tasks"


@dataclass(frozen=True)
class SweepTask:
    """One allocate-and-verify task.

    Attributes
    ----------
    machine : str
        ``"hobbing"`` (the paper's machine) or a machine TOML file.
    side : {'one_sided', 'two_sided'}
    target : float
        Reliability target of every output, in (0, 1).
    profile : str
        Error profile along travel of the verification (``"independent"``: the paper's).
    seed : int
        Seed of the verification (:func:`reliability.streams.verification_streams`).
    repeats : int
        Grid experiments of the verification.
    points_per_axis : int
        Grid of the allocation and of the verification.
    bounds : (float, float)
        Search box of the allocation, as factors of the initial allocation.
    distribution : {'normal', 'truncated'} or None
        The reading of a tolerance for the allocation and the verification; None: the
        machine file's (``[requirements] distribution``).
    """

    machine: str
    side: str
    target: float
    profile: str
    seed: int
    repeats: int
    points_per_axis: int
    bounds: tuple[float, float] = DEFAULT_BOUNDS
    distribution: str | None = None

    def parameters(self, machine=None) -> dict:
        """The task's parameters as stored and hashed: the machine by its content (a task
        without a ``distribution`` of its own hashes as before the key existed)."""
        machine = _load_machine(self.machine) if machine is None else machine
        parameters = asdict(self)
        if self.distribution is None:
            del parameters["distribution"]
        return dict(parameters, machine_fingerprint=machine_fingerprint(machine))


@dataclass(frozen=True)
class SweepSpec:
    """The lists a sweep combines; :meth:`tasks` expands them in a fixed order.

    Build from a TOML file with :meth:`from_toml` (keys as the attributes). ``bounds`` is
    one box ``[LO, HI]`` (factors of the initial allocation) for every task;
    ``distribution`` (``"normal"`` or ``"truncated"``) one reading of a tolerance for every
    task, by default each machine file's own.
    """

    machines: tuple[str, ...]
    sides: tuple[str, ...] = ("two_sided",)
    targets: tuple[float, ...] = (0.99,)
    profiles: tuple[str, ...] = (INDEPENDENT,)
    seeds: tuple[int, ...] = (0,)
    repeats: tuple[int, ...] = (20,)
    points_per_axis: int = 5
    bounds: tuple[float, float] = DEFAULT_BOUNDS
    distribution: str | None = None

    def __post_init__(self):
        for name in ("machines", "sides", "targets", "profiles", "seeds", "repeats"):
            value = getattr(self, name)
            if isinstance(value, (str, int, float)):
                value = (value,)
            value = tuple(value)
            if not value:
                raise InputError(f"sweep spec: {name!r} is empty; give at least one entry")
            object.__setattr__(self, name, value)
        object.__setattr__(self, "bounds", _check_bounds(self.bounds))
        if self.distribution is not None and self.distribution not in DISTRIBUTIONS:
            raise InputError(f"sweep spec: distribution {self.distribution!r} must be "
                             f"'normal' or 'truncated'")
        _check_spec(self)

    @classmethod
    def from_dict(cls, data, base: Path | None = None) -> "SweepSpec":
        """A spec from a parsed TOML table; machine paths are relative to ``base``."""
        unknown = sorted(set(data) - SPEC_KEYS)
        if unknown:
            raise InputError(f"sweep spec: unknown key {unknown[0]!r}; expected some of "
                             f"{sorted(SPEC_KEYS)}")
        if "machines" not in data:
            raise InputError("sweep spec: 'machines' is missing (paths or \"hobbing\")")
        data = dict(data)
        machines = data.pop("machines")
        machines = (machines,) if isinstance(machines, str) else tuple(machines)
        if base is not None:
            machines = tuple(m if m == PAPER_MACHINE or Path(m).is_absolute()
                             else str(Path(base) / m) for m in machines)
        return cls(machines=machines, **data)

    @classmethod
    def from_toml(cls, path) -> "SweepSpec":
        """Read a spec file (see docs/sweeps.md)."""
        path = Path(path)
        try:
            data = tomllib.loads(path.read_text(encoding="utf-8"))
        except FileNotFoundError:
            raise InputError(f"sweep spec {str(path)!r} does not exist") from None
        except tomllib.TOMLDecodeError as exc:
            raise InputError(f"sweep spec {str(path)!r} is not valid TOML: {exc}") from None
        return cls.from_dict(data, base=path.parent)

    def tasks(self) -> list[SweepTask]:
        """Every combination, machines slowest and repeats fastest."""
        return [SweepTask(machine, side, float(target), profile, int(seed), int(repeats),
                          int(self.points_per_axis), self.bounds, self.distribution)
                for machine, side, target, profile, seed, repeats in itertools.product(
                    self.machines, self.sides, self.targets, self.profiles, self.seeds,
                    self.repeats)]


@dataclass(frozen=True, eq=False, repr=False)
class SweepResult:
    """What a sweep run did.

    Attributes
    ----------
    frame : DataFrame
        One row per task (as written to ``results.csv``).
    computed : int
        Tasks computed by this run.
    resumed : int
        Tasks found already finished in the store.
    path : Path
        The ``results.csv`` written.
    """

    frame: pd.DataFrame
    computed: int
    resumed: int
    path: Path

    def summary(self) -> str:
        """How many tasks, how each ended, and where the table is."""
        status = self.frame["status"].value_counts()
        return (f"sweep of {len(self.frame)} task(s): {self.computed} computed, "
                f"{self.resumed} resumed; "
                + ", ".join(f"{count} {name}" for name, count in status.items())
                + f"; results in {self.path}")

    def __repr__(self) -> str:
        return self.summary()


def run_task(task: SweepTask, allocated: dict | None = None) -> dict:
    """Allocate and verify one task; returns plain numbers (stored as JSON).

    Parameters
    ----------
    task : SweepTask
    allocated : dict, optional
        The task's allocation from :func:`solve_allocation`, when already solved (a sweep
        solves each distinct allocation once, then verifies every task that uses it).

    Returns
    -------
    dict
        ``status`` (``"ok"``, or ``"unreachable"`` when no allocation inside the bounds
        meets the target: ``reason`` then says what blocks, and the other entries are
        empty), ``relative_cost`` (optimum
        over the cost of the reference allocation), ``certified``, ``fraction`` (mean share
        of poses in tolerance per output over the experiments), ``yield`` (share of
        experiments entirely in tolerance).
    """
    with threadpool_limits(limits=1):
        machine = (task.machine, task.parameters()["machine_fingerprint"])
        if allocated is None:
            allocated = solve_allocation(*_allocation_key(task, machine[1]))
        if allocated["status"] != "ok":
            return {"status": allocated["status"], "reason": allocated["reason"],
                    "relative_cost": None, "certified": False,
                    "fraction": [None] * len(OUTPUTS), "yield": None}
        experiment = _experiment(machine, task.target, task.points_per_axis, task.profile,
                                 task.distribution)
        rng = verification_streams(task.seed)[0]
        verified = experiment.run(allocated["tolerances"], repeats=task.repeats, rng=rng,
                                  keep_values="none",
                                  distribution=experiment.machine.distribution)
    return {"status": "ok", "reason": "", "distribution": experiment.machine.distribution,
            "relative_cost": allocated["relative_cost"],
            "certified": allocated["certified"],
            "fraction": verified.fractions.mean(axis=0).tolist(),
            "yield": float(np.mean(verified.all_inside))}


def run_sweep(spec: SweepSpec, store, *, executor=None, progress=None, log=None,
              task_function=run_task) -> SweepResult:
    """Run every task of ``spec`` not yet in ``store``, then write ``store/results.csv``.

    Parameters
    ----------
    spec : SweepSpec
    store : str or Path
        Folder of finished tasks (``tasks/``) and of ``results.csv``; created if missing.
    executor : concurrent.futures.Executor or dask.distributed.Client, optional
        Where tasks run; serially in this process by default. Results are stored by this
        process as each task finishes, whatever the executor.
    progress : callable, optional
        ``progress(done, total)`` after each finished task (resumed ones included).
    log : callable, optional
        Called with ``"resumed: N of M tasks already done"`` when some are.
    task_function : callable
        ``task_function(task) -> dict``; :func:`run_task` unless testing.

    Returns
    -------
    SweepResult
    """
    if not isinstance(spec, SweepSpec):
        raise InputTypeError(f"spec must be a SweepSpec; got {type(spec).__name__}")
    _check_executor(executor)
    folder = Path(store)
    tasks = spec.tasks()
    machines = {name: _load_machine(name) for name in spec.machines}
    parameters = [task.parameters(machines[task.machine]) for task in tasks]
    results = ResultStore(folder / TASKS_FOLDER)
    finished = [results.load(p) for p in parameters]
    pending = [i for i, result in enumerate(finished) if result is None]
    resumed = len(tasks) - len(pending)
    if resumed and log is not None:
        log(f"resumed: {resumed} of {len(tasks)} tasks already done")
    done = resumed
    if progress is not None:
        progress(done, len(tasks))
    keys = {i: _allocation_key(tasks[i], parameters[i]["machine_fingerprint"])
            for i in pending}
    distinct = sorted(set(keys.values()))
    solved = {distinct[i]: allocated
              for i, allocated in _execute(solve_allocation, distinct, executor)}
    calls = [(tasks[i], solved[keys[i]]) for i in pending]
    for position, result in _execute(task_function, calls, executor):
        index = pending[position]
        results.save(parameters[index], result)
        finished[index] = result
        done += 1
        if progress is not None:
            progress(done, len(tasks))
    frame = results_frame(tasks, finished)
    path = write_csv(frame, folder / RESULTS_FILE, overwrite=True, index=False,
                     float_format=f"%.{SIGNIFICANT}g")
    return SweepResult(frame=frame, computed=len(pending), resumed=resumed, path=path)


def results_frame(tasks, results) -> pd.DataFrame:
    """One row per task: its parameters (``bounds`` as ``bounds_low``, ``bounds_high``),
    status and ``reason`` (what blocks an unreachable target; empty otherwise), relative
    cost, certified, the mean fraction in tolerance per output (``fraction_<output>``) and
    the machine-level yield."""
    rows = []
    for task, result in zip(tasks, results):
        row = asdict(task)
        row["bounds_low"], row["bounds_high"] = row.pop("bounds")
        row["distribution"] = result.get("distribution", task.distribution)
        row["status"] = result["status"]
        row["reason"] = result.get("reason", "")
        row["relative_cost"] = result["relative_cost"]
        row["certified"] = result["certified"]
        row.update({f"fraction_{name}": value
                    for name, value in zip(OUTPUTS, result["fraction"])})
        row["yield"] = result["yield"]
        rows.append(row)
    return pd.DataFrame(rows)


def _execute(function, calls, executor):
    """``(position, function(*calls[position]))`` as the calls finish."""
    if executor is None:
        for position, arguments in enumerate(calls):
            yield position, function(*arguments)
        return
    if isinstance(executor, Executor):
        futures = {executor.submit(function, *arguments): position
                   for position, arguments in enumerate(calls)}
        finished = as_completed(futures)
    else:
        from distributed import as_completed as dask_completed

        futures = {executor.submit(function, *arguments, pure=False): position
                   for position, arguments in enumerate(calls)}
        finished = dask_completed(list(futures))
    try:
        for future in finished:
            yield futures[future], future.result()
    finally:  # interrupted or failed: drop the tasks not started (finished ones are stored)
        for future in futures:
            future.cancel()


def _check_executor(executor) -> None:
    if executor is None or isinstance(executor, Executor):
        return
    if type(executor).__module__.split(".")[0] == "distributed" and hasattr(executor,
                                                                            "submit"):
        return
    raise InputTypeError(f"executor must be None, a concurrent.futures.Executor or a "
                         f"dask.distributed.Client; got {type(executor).__name__}")


def _check_bounds(bounds) -> tuple[float, float]:
    """``bounds = [LO, HI]``: two numbers, 0 < LO <= HI."""
    if isinstance(bounds, (str, bytes)) or not hasattr(bounds, "__len__") or len(bounds) != 2:
        raise InputError(f"sweep spec: bounds {bounds!r} must be [LO, HI], factors of the "
                         f"initial allocation")
    low, high = bounds
    for value in (low, high):
        if isinstance(value, bool) or not isinstance(value, (int, float)) \
                or not np.isfinite(value) or value <= 0:
            raise InputError(f"sweep spec: bounds entry {value!r} must be a number > 0")
    if low > high:
        raise InputError(f"sweep spec: bounds [{low}, {high}]: LO exceeds HI")
    return float(low), float(high)


def _check_spec(spec: SweepSpec) -> None:
    for machine in spec.machines:
        if not isinstance(machine, str):
            raise InputTypeError(f"sweep spec: machine {machine!r} must be a path or "
                                 f"{PAPER_MACHINE!r}")
        if machine != PAPER_MACHINE and not Path(machine).is_file():
            raise InputError(f"sweep spec: machine file {machine!r} does not exist")
    for side in spec.sides:
        if side not in SIDES:
            raise InputError(f"sweep spec: unknown side {side!r}; use one of {SIDES}")
    for target in spec.targets:
        if isinstance(target, bool) or not isinstance(target, (int, float)) \
                or not 0 < target < 1:
            raise InputError(f"sweep spec: target {target!r} must be a number in (0, 1)")
    for profile in spec.profiles:
        if not isinstance(profile, str):
            raise InputTypeError(f"sweep spec: profile {profile!r} must be a name")
        try:
            profile_model(profile)
        except (InputError, InputTypeError) as error:
            raise InputError(f"sweep spec: profile {profile!r}: {error}") from None
    for name in ("seeds", "repeats"):
        for value in getattr(spec, name):
            if isinstance(value, bool) or not isinstance(value, int) or value < 0 \
                    or (name == "repeats" and value < 1):
                raise InputError(f"sweep spec: {name} entry {value!r} must be a "
                                 f"{'positive' if name == 'repeats' else 'non-negative'} "
                                 f"integer")
    points = spec.points_per_axis
    if isinstance(points, bool) or not isinstance(points, int) or points < 2:
        raise InputError(f"sweep spec: points_per_axis {points!r} must be an integer >= 2")


def clear_caches() -> None:
    """Forget the allocations and experiments this process has set up (for timing)."""
    for cached in (_task_machine, solve_allocation, _experiment):
        cached.cache_clear()


def _load_machine(name: str):
    return hobbing_machine() if name == PAPER_MACHINE else load_machine(name)


# The caches below are keyed by (file name, fingerprint of its content): a machine file
# edited during a session is a new machine.
@functools.lru_cache(maxsize=64)
def _task_machine(machine: tuple[str, str], target: float, distribution: str | None = None):
    """The machine with every output's target set to ``target`` and, when given, the
    reading ``distribution``."""
    loaded = _load_machine(machine[0])
    return replace(loaded, targets=np.full(len(OUTPUTS), float(target)),
                   distribution=distribution or loaded.distribution)


def _allocation_key(task: SweepTask, fingerprint: str) -> tuple:
    """What a task's allocation depends on (tasks differing only in profile, seed or
    repeats share it)."""
    return (task.machine, fingerprint, task.side, task.target, task.points_per_axis,
            task.bounds, task.distribution)


@functools.lru_cache(maxsize=64)
def solve_allocation(name: str, fingerprint: str, side: str, target: float,
                     points: int, bounds: tuple[float, float] = DEFAULT_BOUNDS,
                     distribution: str | None = None) -> dict:
    """Certified optimum of one machine (file ``name`` with content ``fingerprint``) and
    reading in the box ``bounds``: ``status`` ('ok' or 'unreachable', with ``reason``),
    ``tolerances``, ``relative_cost`` and ``certified``. Deterministic, so solving it
    anywhere, once or many times, gives the same numbers."""
    with threadpool_limits(limits=1):
        machine = _task_machine((name, fingerprint), target, distribution)
        problem = AllocationProblem.build(machine, workspace_grid(machine, points),
                                          side=side, bounds=bounds)
        try:
            best = problem.solve_exact()
        except TargetUnreachableError as exc:
            return {"status": "unreachable", "reason": str(exc)}
    return {"status": "ok", "tolerances": best.tolerances,
            "relative_cost": float(best.cost / problem.cost.total(problem.reference)),
            "certified": bool(best.certificate["certified"])}


@functools.lru_cache(maxsize=64)
def _experiment(machine: tuple[str, str], target: float, points: int,
                profile: str, distribution: str | None = None) -> GridExperiment:
    return GridExperiment(_task_machine(machine, target, distribution), points,
                          profile=profile)
