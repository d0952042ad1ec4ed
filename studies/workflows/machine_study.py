"""A machine's study: the same steps for any machine, as results (no text).

machine → FOSM of the initial allocation (Eqs. 19–23) → the certified cheapest allocation
meeting the targets over the continuous workspace (Eq. 34 with the poses the certificate
adds, :mod:`allocation.per_pose.continuous`; or at every grid pose, ``workspace="grid"``) →
Monte-Carlo verification of both
allocations (Sec. 5.3, :func:`reliability.sampling.verification.verify`). The report's sections are
made from the result by :mod:`studies.report.machine_sections`.

Defaults are the report's contract: the exact two-sided probability, the worst case over
the continuous workspace certified to 1e-3 in σ (starting from the 5-point grid), the
machine file's ``[bounds]`` box (else [0.5, 1.5] × the initial
allocation), limits and targets from the
machine file.
"""

from __future__ import annotations

from dataclasses import dataclass

import pandas as pd

from allocation import AllocationProblem, TargetUnreachableError
from allocation.per_pose.continuous import DEFAULT_RTOL, WORKSPACE_CHOICES, check_continuous, \
    solve_continuous
from allocation.per_pose.result_files import gap_bound, written_tolerances
from reliability.basics import checks as input_checks
from reliability.basics.errors import InputError
from reliability.basics.renamed import renamed
from reliability.basics.streams import integer_seed
from reliability.first_order.fosm import fosm
from reliability.model.poses import workspace_grid
from reliability.sampling.machine_yield import DEFAULT_MACHINES
from reliability.sampling.verification import verify

#: Relative change of a tolerance below which it counts as unchanged.
UNCHANGED = 0.01


@dataclass(frozen=True, repr=False)
class MachineStudy:
    """Everything a machine report is made from (see :func:`run`)."""

    machine: object
    points: int
    side: str
    bounds: tuple | None  # --bounds factors, or None: the machine file's box or the default
    seed: int
    problem: object
    initial_fosm: object
    optimum: object  # AllocationResult, or None when the targets are out of reach
    optimal_fosm: object
    checks: dict  # allocation name -> reliability.sampling.verification.Verification
    unreachable: object = None  # the TargetUnreachableError when out of reach
    machines: int = DEFAULT_MACHINES  # built machines per allocation's machine yield
    workspace: str = "grid"  # 'continuous' or 'grid'
    continuous: object = None  # the ContinuousAllocation under workspace 'continuous'
    given: str | None = None  # the given allocation's source in words, when one is given
    given_tolerances: object = None  # its tolerances (mm, rad), studied in the optimum's place
    given_fosm: object = None

    @property
    def reachable(self) -> bool:
        """Whether the study found an allocation inside the box that meets the targets
        (False when it was given an allocation instead of seeking one)."""
        return self.unreachable is None and self.given is None

    @property
    def allocated(self):
        """The optimal tolerances exactly as ``allocation.csv`` holds them (what every
        later step of the study verifies); None when the targets are out of reach."""
        return None if self.optimum is None else written_tolerances(self.optimum)

    @property
    def compared(self) -> tuple[str, object] | None:
        """The allocation set beside the initial one, as ``(name, tolerances)``: the optimum
        as written, or the given allocation; None when the targets are out of reach."""
        if self.given is not None:
            return "given", self.given_tolerances
        return ("optimum", self.allocated) if self.reachable else None

    def summary(self) -> str:
        """The study's choices and its headline numbers, one line each."""
        info = summary(self)
        return "\n".join([
            f"study of {self.machine.name}: {self.side.replace('_', '-')} targets "
            f"{self.workspace_text()}, box {self.problem.box_text()} "
            f"({self.problem.bounds_source}), seed {self.seed}",
            *(f"{name}: {check.machine_yield.summary().splitlines()[0]}"
              for name, check in self.checks.items()),
            f"initial allocation meets the targets: {info['initial_meets_targets']}",
            f"cheapest allocation: {info['relative_cost']:.4%} of the initial cost "
            f"({'certified' if info['certified'] else 'NOT certified'}, relative gap "
            f"≤ {info['relative_gap']:.0e})" if self.reachable else
            f"given allocation ({self.given}): {info['given_relative_cost']:.4%} of the "
            f"initial cost" if self.given is not None else
            f"targets out of reach in the box: {self.unreachable}",
            *(f"{name}: {check.summary()}" for name, check in self.checks.items())])

    def workspace_text(self) -> str:
        """Where the optimum's targets hold, in words (names the workspace)."""
        if self.workspace == "grid":
            return f"at every pose of the {self.points}-point grid (workspace 'grid')"
        if self.continuous is None:
            return "over the continuous workspace (workspace 'continuous')"
        return (f"over the continuous workspace (workspace 'continuous': "
                f"{self.continuous.statement})")

    def __repr__(self) -> str:
        return self.summary()


@renamed("seed", "rng")
def run(machine, *, points: int = 5, side: str = "two_sided", bounds=None,
        rng: int | None = 0, repeats: int = 20, samples: int = 20_000, progress=None,
        bar=None, machines: int = DEFAULT_MACHINES, workspace: str = "continuous",
        rtol: float = DEFAULT_RTOL, time_limit: float | None = None, given=None,
        given_text: str = "the given allocation") -> MachineStudy:
    """Run the study of ``machine``.

    Parameters
    ----------
    machine : Machine
    points : int
        Grid points per axis (the allocation constraint holds at every grid pose).
    side : {'two_sided', 'one_sided'}
    bounds : (float, float), optional
        Tolerance box as factors of the initial allocation; default the machine file's
        ``[bounds]`` table, else [0.5, 1.5] (``summary.json`` names the source).
    rng : int or None
        Seed of the Monte-Carlo verification of each allocation
        (:func:`reliability.basics.streams.verification_streams`), as ``precrel verify --seed``.
        The optimum is verified (and its FOSM computed) exactly as written to
        ``allocation.csv``, rounded down
        (:func:`allocation.per_pose.result_files.written_tolerances`), so
        ``precrel verify --tolerances allocation.csv --seed S`` prints the report's
        Monte-Carlo numbers (``--workspace grid`` under workspace 'grid'): each allocation is
        sampled at the worst poses of the study's workspace, certified over the continuous
        strokes by default (:func:`reliability.sampling.verification.verify`). None draws a
        fresh seed, recorded as the study's ``seed``; a Generator is refused
        (InputTypeError naming ``rng``): the report's named streams derive from an integer
        seed. ``seed=`` is the deprecated spelling (:mod:`reliability.basics.renamed`).
    repeats, samples : int
        Grid experiments, and random-pose / worst-pose samples, per allocation.
    progress : callable, optional
        ``progress(text)`` before each step.
    bar : callable, optional
        Progress-bar factory passed to :func:`reliability.sampling.verification.verify`.
    machines : int
        Built machines simulated for each allocation's machine yield, under
        ``machine.profile`` (:func:`reliability.sampling.machine_yield.machine_yield`).
    workspace : {'continuous', 'grid'}
        Where the optimum's targets hold: over the continuous strokes, certified to
        ``rtol`` in σ by cutting planes from the ``points``-point grid
        (:func:`allocation.per_pose.continuous.solve_continuous`), or at the grid poses only. The
        continuous workspace is refused (InputError) for correlated errors; nothing
        switches to the grid silently.
    rtol : float
        Relative tolerance in σ of the continuous workspace's certificate.
    time_limit : float, optional
        Seconds the continuous workspace's loop may take
        (:func:`allocation.per_pose.continuous.solve_continuous`'s ``time_limit``): past
        them, or at Ctrl-C, it stops with the best allocation so far, not certified, and
        the study goes on with it. None: no limit. Refused (InputError) with the grid.
    given : array_like (n_errors,), optional
        An allocation (mm, rad; e.g. ``precrel allocate --yield``'s, ``choose``'s or a
        supplier's, as ``--tolerances`` reads it) studied beside the initial one in place
        of the optimum: FOSM and the Monte-Carlo verification of it as given, and no
        allocation is sought (``optimum`` None, ``reachable`` False).
    given_text : str
        Where ``given`` comes from, in words (``given`` in the result).

    When no allocation inside the bounds meets the targets the study still runs for the
    initial allocation: ``optimum`` and ``optimal_fosm`` are None and ``unreachable``
    holds the :class:`allocation.TargetUnreachableError` (what blocks, where).
    """
    input_checks.choice(workspace, "workspace", WORKSPACE_CHOICES)
    if time_limit is not None and workspace != "continuous":
        raise InputError(f"time_limit: bounds the loop of the continuous workspace; "
                         f"workspace {workspace!r} has none (expected None)")
    seed = integer_seed(rng)
    if workspace == "continuous":
        check_continuous(machine, side)
    progress = progress or (lambda text: None)
    progress(f"FOSM of the initial allocation on the {points}-point grid")
    problem = AllocationProblem.build(machine, workspace_grid(machine, points), side=side,
                                      bounds=bounds)
    initial = fosm(machine, problem.reference, problem.poses, jacobian=problem.jacobian,
                   distribution=machine.distribution)
    verified = [("initial", problem.reference, initial)]
    optimum = optimal = unreachable = continuous = given_fosm = None
    if given is not None:
        given = machine.check_tolerances(given)
        given_fosm = fosm(machine, given, problem.poses, jacobian=problem.jacobian,
                          distribution=machine.distribution)
        verified.append(("given", given, given_fosm))
    else:
        optimum, continuous, unreachable = _optimum(problem, workspace, rtol, progress,
                                                    time_limit)
    if optimum is not None:
        written = written_tolerances(optimum)
        optimal = fosm(machine, written, problem.poses, jacobian=problem.jacobian,
                       distribution=machine.distribution)
        verified.append(("optimum", written, optimal))
    checks = {}
    for name, t, prediction in verified:
        progress(f"Monte-Carlo verification of the {name} allocation")
        checks[name] = verify(machine, t, points=points, repeats=repeats, samples=samples,
                              rng=seed, progress=lambda text: progress(f"  {text}"), bar=bar,
                              prediction=prediction, machines=machines,
                              workspace=workspace, rtol=rtol)
    return MachineStudy(machine=machine, points=points, side=side,
                        bounds=None if bounds is None else tuple(bounds),
                        seed=seed, problem=problem, initial_fosm=initial, optimum=optimum,
                        optimal_fosm=optimal, checks=checks, unreachable=unreachable,
                        machines=machines, workspace=workspace, continuous=continuous,
                        given=None if given is None else given_text,
                        given_tolerances=given, given_fosm=given_fosm)


def _optimum(problem, workspace: str, rtol: float, progress, time_limit=None) -> tuple:
    """The certified cheapest allocation of ``problem`` (Eq. 34) as ``(optimum,
    continuous, unreachable)``: the ContinuousAllocation under workspace 'continuous'
    (its loop stopped after ``time_limit`` seconds, if given), and the
    TargetUnreachableError (optimum None) when the box cannot meet the targets."""
    progress(f"certified cheapest allocation (convex solver, workspace '{workspace}')")
    optimum = unreachable = continuous = None
    try:
        if workspace == "continuous":
            limits = {} if time_limit is None else {"time_limit": time_limit}
            continuous = solve_continuous(problem, rtol=rtol,
                                          progress=lambda text: progress(f"  {text}"),
                                          **limits)
            optimum = continuous.result
        else:
            optimum = problem.solve_exact()
    except TargetUnreachableError as exc:
        unreachable = exc
        progress(f"targets out of reach in the box: {exc}")
    return optimum, continuous, unreachable


def summary(study: MachineStudy) -> dict:
    """The ``summary.json`` entries (the report's contract plus a few more), opening with
    the machine yield of each allocation (:func:`yield_summary`).

    ``reachable`` says whether an allocation inside the box meets the targets; when it is
    false, ``optimal_cost``, ``relative_cost``, ``relative_gap`` and
    ``optimal_meets_targets`` are None and ``reaching_factor`` is the largest lower-bound
    factor with which the targets can be reached. ``allocation`` says which allocation
    stands beside the initial one: ``"certified optimum"``, ``"given"`` (then
    ``reachable`` is None, not sought, and :func:`given_summary` adds its entries) or None
    when the targets are out of reach.
    """
    initial_cost = float(study.problem.cost.total(study.problem.reference))
    optimum = study.optimum
    checked = next(iter(study.checks.values()))  # every check uses the same counts
    return {
        **yield_summary(study),
        "machine": study.machine.name,
        "points_per_axis": study.points,  # the key summary.json has always had
        "side": study.side,
        "frame": study.machine.frame,
        "distribution": study.machine.distribution,
        "workspace": study.workspace,
        "bounds": None if study.bounds is None else list(study.bounds),
        "bounds_source": _bounds_source(study.problem),
        "reachable": None if study.given is not None else study.reachable,
        "reaching_factor": None if study.reachable or study.given is not None else
        study.problem.reaching_factor(),
        "allocation": "given" if study.given is not None else
        "certified optimum" if study.reachable else None,
        "initial_cost": initial_cost,
        "optimal_cost": None if optimum is None else optimum.cost,
        "relative_cost": None if optimum is None else optimum.cost / initial_cost,
        "certified": optimum is not None and bool(optimum.certificate["certified"]),
        "relative_gap": None if optimum is None else
        gap_bound(optimum.certificate["relative_gap"]),
        "initial_meets_targets": bool(study.initial_fosm.meets_targets(study.side).all()),
        "optimal_meets_targets": None if optimum is None else
        bool(study.optimal_fosm.meets_targets(study.side).all()),
        "seed": study.seed,
        "repeats": checked.grid.repeats,
        "samples": int(checked.worst_poses["samples"].iloc[0]),
        **given_summary(study),
    }


def given_summary(study: MachineStudy) -> dict:
    """The given allocation's entries (none without one): ``given_source`` (where it
    comes from), ``given_cost`` (Eq. 28), ``given_relative_cost`` (over the initial
    cost) and ``given_meets_targets`` (every target at every grid pose, FOSM)."""
    if study.given is None:
        return {}
    cost = float(study.problem.cost.total(study.given_tolerances))
    return {"given_source": study.given, "given_cost": cost,
            "given_relative_cost": cost / float(study.problem.cost.total(
                study.problem.reference)),
            "given_meets_targets": bool(study.given_fosm.meets_targets(study.side).all())}


def yield_summary(study: MachineStudy) -> dict:
    """``yield``, ``yield_interval`` (``optimal`` None when the targets are out of reach or
    an allocation is given; ``given``, that allocation's, only then),
    ``yield_profile``, ``yield_machines`` (built machines asked for per allocation; fewer
    when importance sampling reached its CoV), and ``yield_method`` and
    ``yield_first_order`` (first-order bounds of the linearised model) per allocation."""
    names = [("initial", "initial"), ("optimal", "optimum")] + \
        ([("given", "given")] if "given" in study.checks else [])
    estimates = {name: study.checks[check].machine_yield if check in study.checks else None
                 for name, check in names}

    def each(value):
        return {name: None if y is None else value(y) for name, y in estimates.items()}

    first = estimates["initial"]
    return {
        "yield": each(lambda y: y.estimate),
        "yield_interval": each(lambda y: [y.lower, y.upper]),
        "yield_profile": first.profile,
        "yield_machines": study.machines,
        "yield_method": each(lambda y: y.method),
        "yield_first_order": each(lambda y: [y.first_order_lower, y.first_order_upper]),
    }


def tolerance_changes(study: MachineStudy) -> tuple[pd.Series, pd.Series]:
    """The errors the optimum tightens and relaxes by more than :data:`UNCHANGED`, as
    relative changes (allocated / initial − 1), largest first (ties in error order)."""
    rate = pd.Series(study.optimum.tolerances / study.problem.reference - 1.0,
                     index=study.machine.error_names)
    tighten = rate[rate < -UNCHANGED].sort_values(kind="stable")
    relax = rate[rate > UNCHANGED].sort_values(ascending=False, kind="stable")
    return tighten, relax


def _bounds_source(problem) -> str:
    """``summary.json``'s ``bounds_source``: the problem's, bounds given to :func:`run`
    being those of ``--bounds`` on the command line."""
    return "command line" if problem.bounds_source == "given" else problem.bounds_source
