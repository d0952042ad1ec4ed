"""Sweeps: many allocate-and-verify tasks, serially, on a process pool or on a Dask cluster.

A sweep is the table of every combination of machine × reading (side) × target × error
profile × seed × repeats. Each task

1. builds the worst-case allocation problem on the machine's workspace grid, with every
   output's target replaced by the task's target, and solves it exactly (certified) on the
   grid, or over the continuous workspace when the spec says ``workspace = "continuous"``
   (:func:`allocation.per_pose.continuous.solve_continuous`) — or,
   when the spec names a ``catalogue``, chooses the certified cheapest catalogue classes
   (:func:`allocation.solve_catalogue`);
2. verifies the allocation by the grid experiment of Sec. 5.3 (``repeats`` experiments),
   recording the mean share of poses in tolerance per output and the machine-level yield
   (share of experiments in which every pose meets every limit).

Reproducible under any executor: a task's grid experiments draw from the grid stream of
:func:`reliability.basics.streams.verification_streams` of the task's seed, never from the worker
or the order of execution, so serial, process-pool and Dask runs write byte-identical
``results.csv``, and a task's numbers are those of ``precrel verify --seed S`` on its
allocation (the grid experiments, for the ``independent`` profile).

Resumable: each finished task is stored at once, one file per task
(:class:`reliability.basics.result_store.ResultStore`), keyed by its parameters and the toolkit
version. A sweep started again computes only the tasks without a stored result.
"""

from __future__ import annotations

import functools
import hashlib
import itertools
import tomllib
from concurrent.futures import Executor, as_completed
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np
import pandas as pd
from threadpoolctl import threadpool_limits

from allocation.catalogue.catalogue import load_catalogue
from allocation.per_pose.continuous import WORKSPACE_CHOICES, check_continuous, solve_continuous
from allocation.catalogue.discrete import CatalogueInfeasibleError, solve_catalogue
from allocation.per_pose.problem import AllocationProblem
from allocation.per_pose.solve import TargetUnreachableError
from reliability.basics.errors import InputError, InputTypeError
from reliability.basics.files import SIGNIFICANT, probability_text, write_csv
from reliability.basics.result_store import ResultStore, canonical_json, machine_fingerprint
from reliability.basics.renamed import renamed
from reliability.basics.streams import verification_streams
from reliability.model.error_draws import DISTRIBUTIONS
from reliability.model.machine import OUTPUTS
from reliability.model.machine_file import hobbing_machine, load_machine
from reliability.model.poses import workspace_grid
from reliability.model.profiles import profile_model
from reliability.sampling.grid_experiment import GridExperiment
from reliability.sampling.machine_yield import machine_yield

PAPER_MACHINE = "hobbing"
INDEPENDENT = "independent"
SIDES = ("one_sided", "two_sided")
#: The former name of the spec key ``points``, still read (with a DeprecationWarning).
OLD_POINTS_KEY = "points_per_axis"
SPEC_KEYS = {"machines", "sides", "targets", "profiles", "seeds", "repeats",
             "points", "bounds", "catalogue", "distribution", "workspace", OLD_POINTS_KEY}
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
        Seed of the verification (:func:`reliability.basics.streams.verification_streams`).
    repeats : int
        Grid experiments of the verification.
    points : int
        Grid of the allocation and of the verification (points per axis).
    bounds : (float, float) or None
        Search box of the allocation, as factors of the initial allocation; None: the
        machine file's ``[bounds]``, else [0.5, 1.5].
    catalogue : str or None
        A catalogue file: the allocation is then its certified cheapest choice of classes.
    distribution : {'normal', 'truncated'} or None
        The reading of a tolerance for the allocation and the verification; None: the
        machine file's (``[requirements] distribution``).
    workspace : {'continuous', 'grid'} or None
        Where the allocation's targets hold; None: the grid, as before the key existed.
    """

    machine: str
    side: str
    target: float
    profile: str
    seed: int
    repeats: int
    points: int
    bounds: tuple[float, float] | None = None
    catalogue: str | None = None
    distribution: str | None = None
    workspace: str | None = None

    def parameters(self, machine=None) -> dict:
        """The task's parameters as stored and hashed: the machine and the catalogue by
        their content (a task without a catalogue, a ``distribution`` of its own or a
        workspace other than the grid hashes as before those keys existed; the grid is
        stored under its former key ``points_per_axis``, so stored tasks still resume)."""
        machine = _load_machine(self.machine) if machine is None else machine
        parameters = dict(asdict(self), machine_fingerprint=machine_fingerprint(machine))
        parameters[OLD_POINTS_KEY] = parameters.pop("points")
        del parameters["catalogue"]
        if self.distribution is None:
            del parameters["distribution"]
        if self.workspace in (None, "grid"):
            del parameters["workspace"]
        if self.catalogue is not None:
            parameters.update(catalogue=self.catalogue,
                              catalogue_fingerprint=catalogue_fingerprint(self.catalogue))
        return parameters


@dataclass(frozen=True)
class SweepSpec:
    """The lists a sweep combines; :meth:`tasks` expands them in a fixed order.

    Build from a TOML file with :meth:`from_toml` (keys as the attributes). ``bounds`` is
    one box ``[LO, HI]`` (factors of the initial allocation) for every task; without it
    each machine's own ``[bounds]`` table, else [0.5, 1.5]. ``distribution``
    (``"normal"`` or ``"truncated"``) is one reading of a tolerance for every task, by
    default each machine file's own. ``workspace`` (``"continuous"`` or ``"grid"``) says
    where every task's allocation holds; the grid by default (as before the key existed).
    """

    machines: tuple[str, ...]
    sides: tuple[str, ...] = ("two_sided",)
    targets: tuple[float, ...] = (0.99,)
    profiles: tuple[str, ...] = (INDEPENDENT,)
    seeds: tuple[int, ...] = (0,)
    repeats: tuple[int, ...] = (20,)
    points: int = 5
    bounds: tuple[float, float] | None = None
    catalogue: str | None = None
    distribution: str | None = None
    workspace: str | None = None

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
        if self.workspace is not None and self.workspace not in WORKSPACE_CHOICES:
            raise InputError(f"sweep spec: workspace {self.workspace!r} must be "
                             f"'continuous' or 'grid'")
        if self.workspace == "continuous" and self.catalogue is not None:
            raise InputError("sweep spec: workspace 'continuous' does not apply with a "
                             "catalogue (a choice of classes holds on the grid poses); use "
                             "workspace 'grid'")
        _check_spec(self)
        if self.workspace == "continuous":
            for machine in self.machines:
                for side in self.sides:
                    check_continuous(_load_machine(machine), side)

    @classmethod
    def from_dict(cls, data, base: Path | None = None) -> "SweepSpec":
        """A spec from a parsed TOML table; machine paths are relative to ``base``. The
        former key ``points_per_axis`` is read as ``points`` with a DeprecationWarning (as
        the constructor's keyword; both given: InputTypeError)."""
        unknown = sorted(set(data) - SPEC_KEYS)
        if unknown:
            raise InputError(f"sweep spec: unknown key {unknown[0]!r}; expected some of "
                             f"{sorted(SPEC_KEYS - {OLD_POINTS_KEY})}")
        if "machines" not in data:
            raise InputError("sweep spec: 'machines' is missing (paths or \"hobbing\")")
        data = dict(data)
        machines = data.pop("machines")
        machines = (machines,) if isinstance(machines, str) else tuple(machines)
        if base is not None:
            machines = tuple(m if m == PAPER_MACHINE or Path(m).is_absolute()
                             else str(Path(base) / m) for m in machines)
            catalogue = data.get("catalogue")
            if isinstance(catalogue, str) and not Path(catalogue).is_absolute():
                data["catalogue"] = str(Path(base) / catalogue)
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
                          int(self.points), self.bounds, self.catalogue,
                          self.distribution, self.workspace)
                for machine, side, target, profile, seed, repeats in itertools.product(
                    self.machines, self.sides, self.targets, self.profiles, self.seeds,
                    self.repeats)]


SweepSpec.__init__ = renamed(OLD_POINTS_KEY, "points")(SweepSpec.__init__)


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

    def to_frame(self) -> pd.DataFrame:
        """One row per task, as written to ``results.csv`` (a copy of :attr:`frame`)."""
        return self.frame.copy()

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
        of poses in tolerance per output over the experiments), ``yield`` (the machine yield of
        :func:`reliability.sampling.machine_yield.machine_yield` from ``repeats`` built
        machines under the task's profile, on the verification's yield stream, so
        ``verify(..., rng=S, machines=R, profile=P)`` gives the same number for the same
        tolerances); with a catalogue also ``price`` and ``choice``
        (``"component=class; …"``).
    """
    with threadpool_limits(limits=1):
        machine = (task.machine, task.parameters()["machine_fingerprint"])
        if allocated is None:
            allocated = solve_allocation(*_allocation_key(task, machine[1]))
        chosen = {key: allocated.get(key) for key in ("price", "choice")} \
            if task.catalogue is not None else {}
        if allocated["status"] != "ok":
            return {"status": allocated["status"], "reason": allocated["reason"],
                    "bounds_source": allocated["bounds_source"],
                    "relative_cost": None, "certified": False,
                    "fraction": [None] * len(OUTPUTS), "yield": None, **chosen}
        experiment = _experiment(machine, task.target, task.points, task.profile,
                                 task.distribution)
        grid_rng, _, _, yield_rng = verification_streams(task.seed)
        verified = experiment.run(allocated["tolerances"], repeats=task.repeats, rng=grid_rng,
                                  keep_values="none",
                                  distribution=experiment.machine.distribution)
        built = machine_yield(experiment.machine, allocated["tolerances"],
                              profile=task.profile, points=task.points,
                              machines=task.repeats, rng=yield_rng)
    return {"status": "ok", "reason": "", "bounds_source": allocated["bounds_source"],
            "distribution": experiment.machine.distribution,
            "relative_cost": allocated["relative_cost"],
            "certified": allocated["certified"],
            "fraction": verified.fractions.mean(axis=0).tolist(),
            "yield": built.estimate, **chosen}


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
    written = frame.assign(target=[probability_text(r) for r in frame["target"]])
    path = write_csv(written, folder / RESULTS_FILE, overwrite=True, index=False,
                     float_format=f"%.{SIGNIFICANT}g")
    return SweepResult(frame=frame, computed=len(pending), resumed=resumed, path=path)


def results_frame(tasks, results) -> pd.DataFrame:
    """One row per task: its parameters (``bounds`` as ``bounds_low``, ``bounds_high``),
    status and ``reason`` (what blocks an unreachable target; empty otherwise), relative
    cost, certified, the mean fraction in tolerance per output (``fraction_<output>``) and
    the machine-level yield; with a catalogue also the catalogue file, the total ``price``
    and the ``choice``."""
    rows = []
    for task, result in zip(tasks, results):
        row = asdict(task)
        if task.catalogue is None:
            del row["catalogue"]
        row["bounds_low"], row["bounds_high"] = row.pop("bounds") or (None, None)
        row["bounds_source"] = result.get("bounds_source", "")
        row["distribution"] = result.get("distribution", task.distribution)
        row["workspace"] = task.workspace or "grid"
        row["status"] = result["status"]
        row["reason"] = result.get("reason", "")
        row["relative_cost"] = result["relative_cost"]
        row["certified"] = result["certified"]
        row.update({f"fraction_{name}": value
                    for name, value in zip(OUTPUTS, result["fraction"])})
        row["yield"] = result["yield"]
        if task.catalogue is not None:
            row.update(price=result["price"], choice=result["choice"])
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
    """``bounds = [LO, HI]``: two numbers, 0 < LO <= HI (None: each machine's own box)."""
    if bounds is None:
        return None
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
    points = spec.points
    if isinstance(points, bool) or not isinstance(points, int) or points < 2:
        raise InputError(f"sweep spec: points {points!r} must be an integer >= 2")
    if spec.catalogue is not None:
        if not isinstance(spec.catalogue, str):
            raise InputTypeError(f"sweep spec: catalogue {spec.catalogue!r} must be a path")
        catalogue = load_catalogue(spec.catalogue)
        for machine in spec.machines:
            catalogue.for_machine(_load_machine(machine))


def clear_caches() -> None:
    """Forget the allocations and experiments this process has set up (for timing)."""
    for cached in (_task_machine, solve_allocation, _experiment, _catalogue):
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
    key = (task.machine, fingerprint, task.side, task.target, task.points,
           task.bounds, task.distribution, task.workspace)
    if task.catalogue is None:
        return key
    return key + (task.catalogue, catalogue_fingerprint(task.catalogue))


@functools.lru_cache(maxsize=64)
def solve_allocation(name: str, fingerprint: str, side: str, target: float,
                     points: int, bounds: tuple[float, float] | None = None,
                     distribution: str | None = None, workspace: str | None = None,
                     catalogue: str | None = None,
                     catalogue_content: str | None = None) -> dict:
    """Certified optimum of one machine (file ``name`` with content ``fingerprint``) and
    reading in the box ``bounds`` (None: the machine file's, else the default factors):
    ``status`` ('ok' or 'unreachable', with ``reason``), ``bounds_source``,
    ``tolerances``, ``relative_cost`` and ``certified``; with a ``catalogue`` (file, with
    content ``catalogue_content``) the certified cheapest choice of classes, with its
    ``price`` and ``choice`` (``bounds_source`` is then ``"catalogue classes"``).
    Under ``workspace='continuous'`` the optimum is certified over the continuous strokes
    (``certified`` then also requires the workspace certificate).
    Deterministic, so solving it anywhere, once or many times, gives the same numbers."""
    with threadpool_limits(limits=1):
        machine = _task_machine((name, fingerprint), target, distribution)
        problem = AllocationProblem.build(machine, workspace_grid(machine, points),
                                          side=side, bounds=bounds)
        try:
            if catalogue is not None:
                return dict(_choose(problem, _catalogue(catalogue, catalogue_content)),
                            bounds_source="catalogue classes")
            if workspace == "continuous":
                continuous = solve_continuous(problem)
                best, covered = continuous.result, continuous.certified
            else:
                best, covered = problem.solve_exact(), True
        except (TargetUnreachableError, CatalogueInfeasibleError) as exc:
            return {"status": "unreachable", "reason": str(exc),
                    "bounds_source": problem.bounds_source}
    return {"status": "ok", "tolerances": best.tolerances,
            "bounds_source": problem.bounds_source,
            "relative_cost": float(best.cost / problem.cost.total(problem.reference)),
            "certified": bool(best.certificate["certified"]) and covered}


def _choose(problem, catalogue) -> dict:
    """The certified cheapest catalogue choice as a task's allocation."""
    best = solve_catalogue(problem, catalogue)
    return {"status": "ok", "tolerances": best.tolerances,
            "relative_cost": float(problem.cost.total(best.tolerances)
                                   / problem.cost.total(problem.reference)),
            "certified": best.certified, "price": best.price,
            "choice": "; ".join(f"{name}={chosen}" for name, chosen in best.choice.items())}


def catalogue_fingerprint(path: str) -> str:
    """Hex SHA-256 of a catalogue's content as read (components, classes, prices,
    tolerances), so an edited catalogue is a new one and a moved one is not."""
    catalogue = load_catalogue(path)
    description = {"currency": catalogue.currency, "components": [
        {"name": c.name, "items": list(c.items),
         "classes": [{"name": k.name, "price": k.price, "tolerances": dict(k.tolerances)}
                     for k in c.classes]} for c in catalogue.components]}
    return hashlib.sha256(canonical_json(description).encode("utf-8")).hexdigest()


@functools.lru_cache(maxsize=16)
def _catalogue(path: str, content: str):
    """The catalogue file ``path`` (``content``: its fingerprint, so an edit misses)."""
    return load_catalogue(path)


@functools.lru_cache(maxsize=64)
def _experiment(machine: tuple[str, str], target: float, points: int,
                profile: str, distribution: str | None = None) -> GridExperiment:
    return GridExperiment(_task_machine(machine, target, distribution), points,
                          profile=profile)
