"""Allocation for a machine-yield target: a cheap allocation whose built machines pass.

The machine yield of an allocation is the share of built machines that keep all six
outputs within their limits at every pose of the workspace grid, under the study's error
profile along travel (``constant``, ``independent`` or ``gp:<length>``) and reading of a
tolerance. :func:`allocate_for_yield` looks for the cheapest allocation in the study's box
whose yield is at least Y and returns it inside a bracket:

* **lower bound (a relaxation).** A built machine passes only if every output is inside at
  every pose, so its yield cannot exceed the probability of any one (output, pose) row.
  Any allocation with yield ≥ Y therefore has every row's probability ≥ Y, and the
  certified dual bound of the two-sided per-pose problem at target Y (every row at
  probability Y, :class:`~allocation.front.CommonTargetSolver`) is a lower bound on its
  cost. The row probability is the FOSM one (the linearised output read as normal with
  σ of Eq. 20, the truncated σ under the truncated reading), so the bound holds for that
  model of a row, on the same grid; the yield itself is sampled on the exact model. The
  six rows of one pose must hold together, which gives a tighter bound
  (:mod:`allocation.yield_bound`); the larger of the two is the lower bound. A far
  tighter one, at a stated confidence, follows from the yield's log-concavity in the
  log-tolerances (:func:`allocation.yield_dual.log_concave_bound`, computed apart: it
  needs tens of thousands of machines).
* **feasible side.** Every candidate is the certified optimum of the per-pose problem for
  six per-output two-sided targets (one per output, stated as required indices
  ``z_o = Φ⁻¹((1 + R_o)/2)``); its yield is estimated by simulating built machines with
  common random numbers (the same draws for every candidate). The search starts from the
  naive method and moves the six targets (below); the allocation chosen is then rescaled
  on a fresh calibration sample (below) and verified on another fresh, independent sample
  of built machines, and counts as verified when the Clopper–Pearson interval's lower end
  is at least Y.
* **naive method.** One common two-sided per-pose target for all outputs, raised by
  bisection until the estimated yield reaches the design yield (the pattern of
  :func:`allocation.system_target.system_allocation`).

The search. On the design sample every candidate must reach the design yield
``Y_d = Y + DESIGN_Z · √(Y (1 − Y) / N)`` (N machines), the margin that lets a fresh
sample of N machines confirm Y (below). At the cheapest allocation for a yield every output's
target buys yield at the same price (the KKT condition in the six targets). Each round
prices every binding output: the cost its target buys, by re-solving with the target
lowered (no sampling), over the yield it buys, from the design machines that fail through
that output alone (:meth:`_Search._direction`). The targets of dear outputs go down and of
cheap ones up, in proportion to the logarithm of the price ratio, and a common shift of all
six, found by bisection, restores the design yield; the move is kept when it is cheaper,
otherwise the step is halved.

Then the error shape (:mod:`allocation.yield_shape`): starting from the per-output search's
allocation, every tolerance moves towards equal shares of the cost and of the failures at the
yield's margin, rescaled on the exact chain so that the design yield holds on a design sample
of its own; the cheaper of the two stages is the result (:attr:`YieldAllocation.method`).
The per-output stage cannot trade one error against another inside an output; on the paper's
machine, whose failing machines fail several outputs at once, that is where the saving is.

A wider box. The search is local, and the per-pose optimum it moves along is a poorer guide
to the machine yield in a wider box: at the same targets it is cheaper, but it loosens
items further, so more outputs come near their limits at more poses at once; its machine
yield is lower, and the search starts from higher targets and ends elsewhere. So the stages also run in the default factor box
([0.5, 1.5] × the initial allocation) intersected with the box asked for, when that is a
different, non-empty box, exactly as a search asked for that box would run, each result is
calibrated in its own box (below), and the cheaper calibrated one is kept: the result never
costs more than the result for that
intersection (a box containing the default one never costs more than the default one). It
is the cheapest allocation this search found, not a certified optimum: only the lower bound
is certified.

Convex steps (``convex_steps``, none by default). Where the yield is log-concave in the
log-tolerances (normal reading, no item correlation, ``constant``) the problem is convex, and
a step towards the optimum of its tangent problem (:func:`allocation.yield_dual.tangent_step`)
from the search's allocation is one more candidate, calibrated like the others.

Calibration. The search chooses among many candidates on its design samples, so the
yield of the allocation it ends at is biased upwards there (on the paper's machine at 4 000
machines the fresh samples saw about one standard error less). The allocation is therefore
multiplied by one factor, inside the box (:func:`allocation.yield_shape.scaled_to_yield`:
the worst ratios are homogeneous of degree one in the tolerances, so the factor comes from
their quantile, bisected when tolerances held at their bounds stall that), until its yield
on a *calibration* sample of N fresh machines is ``Y_d``. That sample is used for
nothing else, so the calibrated yield is an honest estimate, and the verification sample
then differs from it by sampling noise alone: the difference of two independent samples
of N (standard deviation ``√2`` standard errors). ``DESIGN_Z`` = 1.96 + 1.96·√2 ≈ 4.73
standard errors, so the verification's 95 % Clopper–Pearson interval clears Y in about
97.5 % of runs. When no factor reaches ``Y_d`` on the calibration sample, not even every
tolerance at its lower bound, the search's allocation is kept as it is
(:attr:`YieldAllocation.calibrated` is False). The naive allocation is calibrated the same
way, and when it is then cheaper than the search's calibrated allocation, the naive start
is the result (:attr:`YieldAllocation.method` ``'naive start'``): on small samples the
search fits its design draws and its allocation can lose more on the calibration sample.

One engine. Every yield of both stages, of the verification and of the naive method is a
share of built machines judged by
:meth:`reliability.sampling.machine_yield.YieldModel.output_ratios` (per machine and output,
the largest ``|y_o|/I_o`` over the grid of the exact chain) on fixed standard normal draws,
one draw per sample from the seed (:func:`reliability.basics.streams.yield_allocation_streams`):
the engine of :func:`reliability.sampling.machine_yield.machine_yield`, which ``precrel
verify`` and ``report`` print.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from typing import NamedTuple

import numpy as np
from scipy.stats import norm

from reliability.basics import checks, streams
from reliability.basics.threads import one_blas_thread
from reliability.basics.display import interval_text, percentage_text
from reliability.basics.statistics import all_within_share
from reliability.first_order.fosm import required_index
from reliability.model.machine import OUTPUTS
from reliability.model.poses import workspace_grid
from reliability.sampling.machine_yield import YieldModel

from .convex import InfeasibleAllocationError, solve_convex_allocation
from .front import CommonTargetSolver
from .problem import DEFAULT_FACTORS, AllocationProblem
from .yield_bound import pose_chain_bound
from .yield_dual import not_log_concave, scaled_rows, tangent_step, unit_draws
from .yield_shape import scaled_to_yield, shape_search

#: Two-sided per-pose target the constraint rows are built and screened at: every target
#: the search uses lies at or below it, so no screened-out row can bind.
BUILD_TARGET = 1.0 - 1e-9
#: Standard errors of a yield on N machines added to Y for the design and calibration
#: samples, so that a fresh sample of N machines confirms Y: 1.96 for the verification's
#: interval and 1.96·√2 for the difference of two independent samples (calibration and
#: verification) at 97.5 %.
DESIGN_Z = 1.96 * (1.0 + np.sqrt(2.0))
#: Relative margin of every output's largest required index below the one the box holds
#: exactly (all items at their lower bounds), so that no solve at a cap is infeasible by
#: rounding: the loads at the lower bounds stay below 1 by about twice this.
CAP_MARGIN = 1e-9
#: Required-index step of the finite differences and the first move of the search.
FD_STEP = 0.15
FIRST_STEP = 0.3
#: A price ratio of this factor moves a target by one whole step.
PRICE_SCALE = 4.0
#: A machine's output is screened at its worst pose only when its ratio there is at least
#: this share of the design quantile of the machines' worst ratios (or is the machine's
#: worst): outputs far inside their limits do not decide a verdict near the yield's margin.
SCREEN_FLOOR = 0.5
#: Machines simulated by default (design and verification samples each).
DEFAULT_MACHINES = 2000
#: The samples of built machines and their streams
#: (:func:`reliability.basics.streams.yield_allocation_streams`; the fourth stream is the
#: bootstrap's of :func:`equal_yield_margin`).
SAMPLE_STREAMS = {"design": 0, "verification": 1, "shape": 2, "calibration": 4}
SAMPLES = tuple(SAMPLE_STREAMS)
#: The stream of the convex steps' machines.
CONVEX_STREAM = 5
#: Machines of the convex steps, as a multiple of the design sample's, by default.
CONVEX_MACHINES_FACTOR = 5


@dataclass(frozen=True, eq=False)
class NaiveAllocation:
    """The naive method's allocation: one common per-pose target for all outputs, calibrated
    as the result is.

    Attributes
    ----------
    target : float
        The common two-sided per-pose target R.
    toward_lower : float
        0, or, when even the largest R the box holds misses the design yield, the share of
        the way from that R's allocation to the box's lower bounds it was moved.
    tolerances : ndarray (n_errors,)
        The allocation of that target (moved), calibrated.
    cost : float
    search_cost : float
        The cost of the allocation of the target, before the calibration.
    design_yield : ProportionEstimate
        The allocation of the target on the design sample.
    calibration_yield, verified_yield : ProportionEstimate
        :attr:`tolerances` on the calibration sample and on the fresh verification sample.
    """

    target: float
    toward_lower: float
    tolerances: np.ndarray
    cost: float
    search_cost: float
    design_yield: object
    calibration_yield: object
    verified_yield: object


    def text(self) -> str:
        """The target, and how far it was moved, in words."""
        common = f"one common per-pose target {self.target:.6g}"
        if self.toward_lower == 0.0:
            return common
        return (f"{common}, the most precise the box holds, moved {self.toward_lower:.1%} of "
                f"the way to the box's lower bounds: the target alone misses the design "
                f"yield")


@dataclass(frozen=True, eq=False)
class YieldAllocation:
    """An allocation for a machine-yield target, with its cost bracket.

    Attributes
    ----------
    problem : AllocationProblem
        The per-pose problem (two-sided, every pose of the grid) in the box asked for: the
        lower bound's; its ``reference`` is the initial allocation.
    search_problem : AllocationProblem
        The per-pose problem the search that gave the allocation solved every candidate
        with: :attr:`problem`, or the same problem in the default factor box
        ([0.5, 1.5] × the initial allocation) intersected with its box, when the search
        there found a cheaper allocation (:attr:`from_narrower_box`). The naive method and
        :attr:`output_targets` are that search's.
    yield_target : float
        Y.
    design_yield_target : float
        ``Y_d``, the yield every candidate had to reach on the design sample.
    tolerances : ndarray (n_errors,)
        The allocation found: the search's, calibrated (:attr:`calibrated`), or the naive
        start's, calibrated, when that is cheaper (:attr:`method` ``'naive start'``).
    cost : float
        Its cost (Eq. 28).
    search_tolerances : ndarray (n_errors,)
        The allocation the search ended at, before the calibration.
    search_cost : float
    search_calibrated_cost : float
        The cost of :attr:`search_tolerances` calibrated: :attr:`cost`, unless the naive
        start or the convex step was kept.
    search_stage : str
        The stage the search's allocation comes from: ``'per-output targets'`` or
        ``'error shape'``.
    convex_step_cost, convex_step_calibrated_cost : float or None
        The allocation the convex steps from the search's allocation ended at
        (:func:`allocation.yield_dual.tangent_step`), before and after the calibration;
        None when they did not run (:attr:`convex_step_text` says why).
    convex_step_text : str
        Whether and how the convex steps ran, in words.
    output_targets : ndarray (6,)
        The per-output two-sided per-pose targets the per-output search ended at.
    method : str
        Which stage gave the allocation: ``'per-output targets'`` (the certified per-pose
        optimum of :attr:`output_targets`), ``'error shape'`` (the shape search over
        every tolerance, which started there and found a cheaper allocation) or
        ``'naive start'`` (the search's allocation, once calibrated, costs more than the
        naive start calibrated the same way, :attr:`naive`, which is then the result) or
        ``'convex step'`` (the convex steps' allocation, calibrated, is the cheapest).
    design_yield : ProportionEstimate
        The search's allocation's yield on its design sample (the design sample of the
        stage it ended in).
    calibrated : bool
        The result was scaled to the design yield on the calibration sample (False when
        no scale inside the box reaches it: the allocation is kept as it is).
    calibration_yield : ProportionEstimate
        The result's yield on the calibration sample.
    verified_yield : ProportionEstimate
        Its yield on the fresh verification sample.
    lower_bound : float
        Certified lower bound on the cost of any allocation with yield ≥ Y: the larger of
        :attr:`row_bound` and the pose-chain bound (:attr:`chain_bound`).
    row_bound : float
        The row relaxation's certified bound (every row at FOSM probability Y).
    chain_bound : allocation.yield_bound.ChainBound or None
        The pose-chain relaxation (:mod:`allocation.yield_bound`: the six outputs' joint
        event at each pose); None for a machine with an item correlation.
    lower_bound_tolerances : ndarray (n_errors,)
        The row relaxation's optimum (every row at probability ≥ Y).
    naive : NaiveAllocation
    profile, distribution : str
        The error profile along travel and the reading of a tolerance.
    points : int
        Grid points per axis (the workspace of the yield and of the rows).
    machines : int
        Built machines in each sample (design and verification).
    seed : int
    evaluations : int
        Candidates solved and simulated on the design sample, by both searches when the
        default factor box was searched too.
    seconds : dict
        Wall time of the build, the lower bounds, the two stages (summed over the
        searches), the calibration and the verification.
    """

    problem: object = field(repr=False)
    search_problem: object = field(repr=False)
    yield_target: float
    design_yield_target: float
    tolerances: np.ndarray
    cost: float
    search_tolerances: np.ndarray
    search_cost: float
    search_calibrated_cost: float
    search_stage: str
    convex_step_cost: float | None
    convex_step_calibrated_cost: float | None
    convex_step_text: str
    output_targets: np.ndarray
    method: str
    design_yield: object
    calibrated: bool
    calibration_yield: object
    verified_yield: object
    lower_bound: float
    row_bound: float
    chain_bound: object
    lower_bound_tolerances: np.ndarray
    naive: NaiveAllocation
    profile: str
    distribution: str
    points: int
    machines: int
    seed: int
    evaluations: int
    seconds: dict

    @property
    def initial_cost(self) -> float:
        """Cost of the initial (reference) allocation."""
        return float(self.problem.cost.total(self.problem.reference))

    @property
    def from_narrower_box(self) -> bool:
        """The allocation comes from the search in the default factor box intersected with
        the box asked for (:attr:`search_problem`)."""
        return self.search_problem is not self.problem

    @property
    def verified(self) -> bool:
        """The fresh sample's interval lies at or above Y."""
        return bool(self.verified_yield.lower >= self.yield_target)

    @property
    def gap(self) -> float:
        """Feasible cost minus the lower bound."""
        return self.cost - self.lower_bound

    @property
    def relative_gap(self) -> float:
        """:attr:`gap` over the feasible cost."""
        return self.gap / self.cost

    def summary(self) -> str:
        """The model, the bracket, the verified yield and the naive method beside it, in
        words."""
        return "\n".join([self.model_text(), *self.finding_lines()])

    def model_text(self) -> str:
        """What the yield is of: target, profile, reading, grid and box."""
        return (f"allocation for machine yield {self.yield_target:g} (profile {self.profile}, "
                f"distribution {self.distribution}, {self.points}-point grid of "
                f"{len(self.problem.poses):,} poses, {self.problem.box_text()})")

    def finding_lines(self) -> list[str]:
        """The bracket, how the result was found and calibrated, its verified yield and
        the naive method's, one line each."""
        initial = self.initial_cost
        v, n = self.verified_yield, self.naive.verified_yield
        verdict = "verified" if self.verified else \
            "NOT verified: the interval reaches below the target"
        targets = ", ".join(f"{name} {target:.6g}" for name, target
                            in zip(OUTPUTS, self.output_targets))
        return [
            f"lower bound {percentage_text(self.lower_bound / initial, bound='lower')} of "
            f"the initial cost "
            f"({self.bound_text()})",
            f"cost {self.cost:.6g} = {percentage_text(self.cost / initial)} of the initial "
            f"allocation "
            f"({initial:.6g}): the cheapest found by this search; not certified: see the "
            f"lower bound",
            f"gap {percentage_text(self.gap / initial, bound='upper')} of the initial cost "
            f"({percentage_text(self.relative_gap, bound='upper')} of the cost)",
            self.calibration_text(),
            self.convex_step_line(),
            f"verified yield {v.estimate:.4f}, 95% Clopper-Pearson "
            f"{interval_text(v.lower, v.upper)} from {v.n:,} fresh built machines: {verdict}",
            f"found by the {self.method} stage{self.narrower_box_text()}; per-output "
            f"per-pose targets of the first stage: {targets}",
            f"naive method ({self.naive.text()}, calibrated the same way): cost "
            f"{percentage_text(self.naive.cost / initial)} of the initial allocation, "
            f"verified yield {n.estimate:.4f} {interval_text(n.lower, n.upper)} from "
            f"{n.n:,} machines"]

    def calibration_text(self) -> str:
        """How the search's allocation (or the naive start's) became the result, in
        words."""
        initial = self.initial_cost
        c = self.calibration_yield
        search = (f"the search ended at {percentage_text(self.search_cost / initial)} of the "
                  f"initial cost (yield {self.design_yield.estimate:.4f} on its "
                  f"{self.design_yield.n:,} design machines)")
        if self.method == "convex step":
            return (f"{search}; the convex steps from it ended at "
                    f"{percentage_text(self.convex_step_cost / initial)}, scaled to the "
                    f"design yield {self.design_yield_target:.4f} on {c.n:,} fresh "
                    f"calibration machines: "
                    f"the result (yield {c.estimate:.4f} there)")
        if self.method == "naive start":
            scaled = percentage_text(self.search_calibrated_cost / initial)
            return (f"{search}, {scaled} once scaled to the design yield "
                    f"{self.design_yield_target:.4f} on {c.n:,} fresh "
                    f"calibration machines: dearer than the naive start scaled the same "
                    f"way, which is the result (yield {c.estimate:.4f} there)")
        if not self.calibrated:
            return (f"{search}; no scale inside the box reaches the design yield "
                    f"{self.design_yield_target:.4f} on the {c.n:,} calibration machines "
                    f"(yield {c.estimate:.4f} there): kept as it is")
        return (f"{search}, scaled to the design yield {self.design_yield_target:.4f} on "
                f"{c.n:,} fresh calibration machines (yield {c.estimate:.4f} there)")

    def convex_step_line(self) -> str:
        """The convex steps: what they are, and what they gave when not kept."""
        if self.convex_step_cost is None or self.method == "convex step":
            return f"convex steps: {self.convex_step_text}"
        initial = self.initial_cost
        return (f"convex steps: {self.convex_step_text}; they ended at "
                f"{percentage_text(self.convex_step_cost / initial)}, "
                f"{percentage_text(self.convex_step_calibrated_cost / initial)} calibrated: "
                f"not the cheapest")

    def bound_text(self) -> str:
        """What the lower bound rests on, in words."""
        rows = (f"every (output, pose) row at probability {self.yield_target:g} alone: "
                f"{percentage_text(self.row_bound / self.initial_cost, bound='lower')}")
        if self.lower_bound == self.row_bound:
            return f"{rows}; FOSM two-sided, certified"
        return (f"the six outputs' joint event at each pose, bounded through their fresh "
                f"errors; {rows}; FOSM two-sided, certified")

    def narrower_box_text(self) -> str:
        """Where the search that gave the allocation ran, when not in the box asked for."""
        if not self.from_narrower_box:
            return ""
        low, high = DEFAULT_FACTORS
        return (f" of the search in this box intersected with the default factor box "
                f"[{low:g}, {high:g}] × the initial allocation "
                f"({self.search_problem.box_text()}), cheaper than this box's own search")

    def __repr__(self) -> str:
        return self.summary()


@one_blas_thread
def allocate_for_yield(machine, yield_target: float, *, profile=None, distribution=None,
                       points: int = 5, bounds=None, machines: int = DEFAULT_MACHINES,
                       seed: int = 0, rounds: int = 6, naive_steps: int = 8,
                       restore_steps: int = 4, shape_steps: int = 20,
                       convex_steps: int = 0, convex_machines: int | None = None,
                       gap_tol: float = 1e-6, executor=None) -> YieldAllocation:
    """The cheapest allocation found whose machine yield reaches ``yield_target``.

    Parameters
    ----------
    machine : Machine
    yield_target : float
        Y in (0, 1): the share of built machines that must hold every limit at every pose.
    profile : str, optional
        Error profile along travel of a built machine (``'constant'``, ``'independent'``,
        ``'gp:<length mm>'``); default ``machine.profile``.
    distribution : {'normal', 'truncated'}, optional
        Reading of a tolerance; default ``machine.distribution``.
    points : int
        Grid points per axis: the poses of the rows and of the simulated machines.
    bounds : (float, float), optional
        Box as factors of the initial allocation (default as
        :meth:`AllocationProblem.build`). When it differs from its intersection with the
        default factor box, the search also runs in that intersection and the cheaper
        result is kept (module docstring), which doubles the time of the search.
    machines : int
        Built machines in each sample: the design samples of the two stages and,
        independently, the calibration and the verification samples.
    seed : int
        Seed of the samples: the design sample of the per-output stage, the verification
        sample, the design sample of the shape stage and the calibration sample draw from
        the first, second, third and fifth streams of
        :func:`reliability.basics.streams.yield_allocation_streams`, once each.
    rounds : int
        Rounds of the search over the six per-output targets (0: the naive method only).
    naive_steps, restore_steps : int
        Bisection steps on the naive common target and on each round's common shift.
    shape_steps : int
        Candidates of the shape search over every tolerance that follows the per-output
        search (:func:`allocation.yield_shape.shape_search`; 0: none).
    convex_steps : int
        Steps of the convex problem from the search's allocation
        (:func:`allocation.yield_dual.tangent_step`) where the yield is log-concave in the
        log-tolerances (normal reading, no item correlation, ``constant``); 0: none. Their
        allocation is calibrated and verified like the others, and kept when cheapest.
    convex_machines : int, optional
        Machines the convex steps estimate the yield's gradient on (default
        ``CONVEX_MACHINES_FACTOR`` × ``machines``), drawn from the sixth stream: the
        step is only as good as its gradient, whose relative error falls as
        ``1/√convex_machines``.
    gap_tol : float
        Relative duality gap accepted by the convex solves.
    executor : distributed.Client, optional
        Simulate the built machines as tasks of this Dask client (each sample sent to its
        workers once), with the same result as without it
        (:mod:`reliability.sampling.machine_blocks`); None simulates them here.

    BLAS runs on one thread meanwhile (:mod:`reliability.basics.threads`): the search
    decides on sampled verdicts, which would otherwise depend on the thread count.

    Returns
    -------
    YieldAllocation

    Raises
    ------
    InputError
        A bad argument (named), before any work.
    TargetUnreachableError
        (from the solver) or :class:`YieldUnreachableError` when even the most precise
        common target the box allows misses the design yield.
    """
    started = time.perf_counter()
    yield_target = checks.probability(yield_target, "yield_target")
    machines = checks.positive_int(machines, "machines")
    seed = checks.positive_int(seed, "seed", minimum=0)
    for value, name in ((rounds, "rounds"), (naive_steps, "naive_steps"),
                        (restore_steps, "restore_steps"), (shape_steps, "shape_steps"),
                        (convex_steps, "convex_steps")):
        checks.positive_int(value, name, minimum=0)
    convex_machines = CONVEX_MACHINES_FACTOR * machines if convex_machines is None else \
        checks.positive_int(convex_machines, "convex_machines")
    chosen = {name: value for name, value in (("profile", profile),
                                              ("distribution", distribution))
              if value is not None}
    machine = replace(machine, **chosen) if chosen else machine
    design_target = min(yield_target + DESIGN_Z * np.sqrt(yield_target * (1 - yield_target)
                                                           / machines),
                        1.0 - 0.5 / machines)
    search = _Search(machine, points, bounds, machines, seed, design_target, gap_tol,
                     executor=executor)
    searches = [search, *_narrower_searches(machine, points, search.problem, machines, seed,
                                            design_target, gap_tol, executor)]
    built = time.perf_counter()
    lower = _lower_bound(search, yield_target)
    chain = pose_chain_bound(search.problem, yield_target, lower.t)
    bounded = time.perf_counter()
    outcomes, unreachable = [], []
    for each in searches:
        try:
            outcomes.append(_stages(each, yield_target, naive_steps, rounds, restore_steps,
                                    shape_steps))
        except YieldUnreachableError as error:
            unreachable.append(error)
    if not outcomes:
        raise unreachable[0]
    searched = time.perf_counter()
    finals = [outcome.search.calibrate(outcome.chosen) for outcome in outcomes]
    cheapest = int(np.argmin([final.cost for final in finals]))
    found, searched_final = outcomes[cheapest], finals[cheapest]
    chosen, naive = found.chosen, found.naive
    naive_final = found.search.calibrate(naive)
    step_started = time.perf_counter()
    stepped = found.search.convex_steps(chosen, convex_steps, convex_machines)
    step_seconds = time.perf_counter() - step_started
    step_final = None if stepped is None else found.search.calibrate(stepped)
    method, final = _cheapest({_stage(found): searched_final, "naive start": naive_final,
                               "convex step": step_final})
    calibrated = time.perf_counter()
    verify = found.search.verification_sample()
    return YieldAllocation(
        problem=search.problem, search_problem=found.search.problem,
        yield_target=yield_target,
        design_yield_target=float(design_target), tolerances=final.t, cost=final.cost,
        search_tolerances=chosen.t, search_cost=chosen.cost,
        search_calibrated_cost=searched_final.cost, search_stage=_stage(found),
        convex_step_cost=None if stepped is None else stepped.cost,
        convex_step_calibrated_cost=None if step_final is None else step_final.cost,
        convex_step_text=found.search.convex_step_text(convex_steps, convex_machines),
        output_targets=two_sided_target(found.best.z),
        method=method,
        design_yield=all_within_share(chosen.passes),
        calibrated=final.calibrated, calibration_yield=all_within_share(final.passes),
        verified_yield=all_within_share(verify(final.t)),
        lower_bound=max(float(lower.dual_bound), -np.inf if chain is None else chain.bound),
        row_bound=float(lower.dual_bound), chain_bound=chain,
        lower_bound_tolerances=np.asarray(lower.t),
        naive=NaiveAllocation(target=float(two_sided_target(naive.z[0])),
                              toward_lower=float(found.search.toward_lower),
                              tolerances=naive_final.t, cost=naive_final.cost,
                              search_cost=naive.cost,
                              design_yield=all_within_share(naive.passes),
                              calibration_yield=all_within_share(naive_final.passes),
                              verified_yield=all_within_share(verify(naive_final.t))),
        profile=machine.profile, distribution=machine.distribution, points=int(points),
        machines=machines, seed=seed, evaluations=sum(each.evaluations for each in searches),
        seconds={"build": built - started, "bound": bounded - built,
                 "targets": sum(outcome.seconds["targets"] for outcome in outcomes),
                 "shape": sum(outcome.seconds["shape"] for outcome in outcomes),
                 "convex step": step_seconds,
                 "calibration": calibrated - searched - step_seconds,
                 "verify": time.perf_counter() - calibrated})


def _stage(found) -> str:
    """The search's stage its allocation comes from."""
    return "per-output targets" if found.chosen is found.best else "error shape"


def _cheapest(calibrated: dict):
    """The name and the calibrated allocation of the cheapest of ``calibrated`` (None
    values skipped; the first of equal costs)."""
    name = min((name for name, each in calibrated.items() if each is not None),
               key=lambda name: calibrated[name].cost)
    return name, calibrated[name]


def _lower_bound(search, yield_target):
    """The relaxation's certified solve (every row at probability ``yield_target``);
    :class:`YieldUnreachableError` naming the outputs whose rows the box cannot hold."""
    try:
        return search.solver(yield_target)
    except InfeasibleAllocationError as infeasible:
        blocking = sorted({OUTPUTS[o] for o in search.problem.rows.output[list(infeasible.rows)]})
        raise YieldUnreachableError(
            f"machine yield {yield_target:g} unreachable inside the box "
            f"{search.problem.box_text()}: not even every (output, pose) row can reach "
            f"probability {yield_target:g} (rows of {', '.join(blocking)} miss it with every "
            f"tolerance at its lower bound); widen the box (bounds)") from None


def _narrower_searches(machine, points, problem, machines, seed, design_target, gap_tol,
                       executor=None):
    """The search in the default factor box intersected with ``problem``'s box, built as a
    search given that box would build it: none when the intersection is the box itself or
    empty."""
    reference = problem.reference
    lower = np.maximum(problem.lower, reference * DEFAULT_FACTORS[0])
    upper = np.minimum(problem.upper, reference * DEFAULT_FACTORS[1])
    same = np.array_equal(lower, problem.lower) and np.array_equal(upper, problem.upper)
    if same or np.any(lower > upper):
        return []
    return [_Search(machine, points, None, machines, seed, design_target, gap_tol,
                    box={"lower": lower, "upper": upper}, executor=executor)]


@dataclass(frozen=True, eq=False)
class _Outcome:
    """One search's stages: the naive start, the per-output search's best, the allocation
    chosen of the two stages, and the seconds of each stage."""

    search: object
    naive: object
    best: object
    chosen: object
    seconds: dict


def _stages(search, yield_target, naive_steps, rounds, restore_steps, shape_steps):
    """The naive start, the per-output search and the shape search in ``search``'s box."""
    started = time.perf_counter()
    naive = _confirmed(lambda: search.naive(naive_steps, yield_target), search, "design")
    best = search.improve(naive, rounds, restore_steps)
    targets_found = time.perf_counter()
    shaped = search.shape(best, shape_steps)
    while shaped is not None and not search.confirm(shaped.t, "shape"):
        shaped = search.shape(shaped, 1)  # its end point rescaled on the widened screen
    if shaped is None or shaped.cost >= best.cost:
        best = _confirmed(lambda: search.improve(naive, rounds, restore_steps), search,
                          "design", best)
    chosen = best if shaped is None or shaped.cost >= best.cost else shaped
    return _Outcome(search=search, naive=naive, best=best, chosen=chosen,
                    seconds={"targets": targets_found - started,
                             "shape": time.perf_counter() - targets_found})


def _confirmed(stage, search, sample, point=None):
    """The point ``stage()`` ends at (``point`` when it has run already), run again until
    its screened verdicts on ``sample`` are the whole grid's (each failed check widens the
    screen, so this ends)."""
    point = stage() if point is None else point
    while point is not None and not search.confirm(point.t, sample):
        point = stage()
    return point


class YieldUnreachableError(InfeasibleAllocationError):
    """Even the most precise common per-pose target inside the box misses the yield."""

    def __init__(self, message: str):
        ValueError.__init__(self, message)
        self.rows, self.loads = (), np.empty(0)


def two_sided_target(z):
    """Two-sided per-pose target ``2Φ(z) − 1`` of a required index ``z``."""
    return 2.0 * norm.cdf(z) - 1.0


def equal_yield_margin(result: YieldAllocation, *, level: float | None = None,
                       spacing: float = 0.04,
                       machines: int | None = None, seed: int | None = None,
                       resamples: int = 2000) -> dict:
    """Cost of the naive method and of the result at one yield, and their difference with
    its error bar, measured on one fresh sample shared by both (paired).

    ``level`` is the yield compared at: by default the design yield ``Y_d`` both methods
    were tuned to (their allocations' yields); ``yield_target`` gives the comparison at Y.

    Each method is a family of allocations along a common shift of its required indices
    (naive: the common target, or the share of the way to the lower bounds when its start
    was moved there; the result: its six targets, or, when the error-shape stage
    gave it, its tolerances scaled by ``z/(z + shift)`` inside the box with ``z`` the naive
    required index). On a fresh sample (common
    random numbers for every allocation) each family is moved from shift 0 outwards in
    doubling steps of ``spacing`` until its yields bracket the level, the bracket is bisected
    four times, one shift is added beyond each end, and its cost at the level is
    interpolated linearly between the shifts whose yields bracket it.
    The error bar is the bootstrap standard error over the sample's machines (Poisson
    weights, the same resample for both families, so the difference is paired). The shared
    sample and the weights draw from the second and the fourth stream of
    :func:`reliability.basics.streams.yield_allocation_streams` of ``seed`` (by default
    ``result.seed + 1``), and the machines are judged by the engine of the search.

    Returns
    -------
    dict
        ``level``: the yield compared at; ``naive`` and ``result``: cost there relative
        to the initial cost; ``margin``: their difference (naive − result, relative to
        the initial cost); ``*_error``: the bootstrap standard errors; ``saving``: the
        margin over the naive cost; ``machines``; ``shifts``, ``yields`` and ``costs`` of
        each family; ``evaluations``.
    """
    spacing = checks.finite_float(spacing, "spacing", 0.0, low_open=True)
    machines = result.machines if machines is None else checks.positive_int(machines,
                                                                            "machines")
    seed = result.seed + 1 if seed is None else checks.positive_int(seed, "seed", minimum=0)
    resamples = checks.positive_int(resamples, "resamples")
    target = result.design_yield_target if level is None else checks.probability(level, "level")
    search = _Search(result.problem.machine, result.points, None, machines, seed, 0.0,
                     problem=result.search_problem)
    sample = search.verification_sample()
    z_naive = np.full(6, required_index(result.naive.target, "two_sided"))
    families = {"naive": _naive_family(result, search, z_naive),
                "result": _result_family(result, search, float(z_naive[0]))}
    shifts, costs, passes = {}, {}, {}
    for name, allocate in families.items():
        shifts[name], costs[name], passes[name] = _family(allocate, sample, spacing, target)
        costs[name] = costs[name] / result.initial_cost
    weights = search.streams[3].poisson(1.0, (resamples, machines))
    at_y = {name: _cost_at_yield(costs[name], passes[name], target, weights)
            for name in families}
    point = {name: float(_cost_at_yield(costs[name], passes[name], target,
                                        np.ones((1, machines)))[0]) for name in families}
    margin = at_y["naive"] - at_y["result"]
    return {"level": target, "naive": point["naive"], "result": point["result"],
            "margin": point["naive"] - point["result"],
            "naive_error": float(np.nanstd(at_y["naive"], ddof=1)),
            "result_error": float(np.nanstd(at_y["result"], ddof=1)),
            "margin_error": float(np.nanstd(margin, ddof=1)),
            "saving": (point["naive"] - point["result"]) / point["naive"],
            "machines": machines, "shifts": shifts, "costs": costs,
            "yields": {name: passes[name].mean(axis=1) for name in families},
            "evaluations": sum(len(s) for s in shifts.values())}


def _naive_family(result, search, z):
    """The naive allocation at a shift: its common target shifted, or, when it was moved
    towards the box's lower bounds, that share shifted: past the most precise target (share
    0) the common target falls, past the lower bounds (share 1) nothing moves."""
    if result.naive.toward_lower == 0.0:
        return lambda shift: search.solve(z + shift)
    cap, lower = search.solve(z), np.asarray(result.search_problem.lower)

    def moved(shift):
        share = result.naive.toward_lower + shift
        if share <= 0.0:
            return search.solve(z + share)
        t = cap.t + min(share, 1.0) * (lower - cap.t)
        return _Point(z=z, t=t, cost=float(result.search_problem.cost.total(t)))
    return moved


def _result_family(result, search, z):
    """The result's allocation at a shift: its six targets shifted (the per-output stage),
    its tolerances scaled by ``z/(z + shift)`` inside the box (the error-shape stage), or the
    naive family (the naive start kept: no margin)."""
    if result.method == "naive start":
        return _naive_family(result, search, z)
    if result.method == "per-output targets":
        z_result = required_index(result.output_targets, "two_sided")
        return lambda shift: search.solve(z_result + shift)
    problem = result.search_problem

    def scaled(shift):
        t = np.clip(result.tolerances * z / (z + shift), problem.lower, problem.upper)
        return _Point(z=np.full(6, z + shift), t=t, cost=float(problem.cost.total(t)))
    return scaled


def _family(allocate, sample, spacing, target, doublings: int = 10, steps: int = 4):
    """Shifts, costs and per-machine verdicts on ``sample`` around yield ``target`` of the
    allocations ``allocate(shift)``: from shift 0 outwards in doubling steps until the
    yields bracket it, then ``steps`` bisections of the bracket, and one shift beyond each
    end of it."""
    found = {}

    def meets(shift):
        if shift not in found:
            point = allocate(shift)
            found[shift] = (point.cost, sample(point.t))
        return found[shift][1].mean() >= target

    low = high = 0.0
    outward = -1.0 if meets(0.0) else 1.0
    for i in range(doublings):
        shift = outward * spacing * 2 ** i
        if meets(shift) != (outward < 0):
            break
    low, high = sorted((shift, shift / 2 if i else 0.0))
    for _ in range(steps):
        middle = 0.5 * (low + high)
        low, high = (low, middle) if meets(middle) else (middle, high)
    meets(low - spacing)
    meets(high + spacing)
    order = sorted(found)
    return (np.array(order), np.array([found[s][0] for s in order]),
            np.stack([found[s][1] for s in order]))


def _cost_at_yield(costs, passes, target, weights) -> np.ndarray:
    """Cost at yield ``target`` for each row of machine weights, linear in the yield
    between the first offset reaching it and the one before (NaN when not bracketed)."""
    yields = weights @ passes.T / weights.sum(axis=1, keepdims=True)  # (B, offsets)
    yields = np.maximum.accumulate(yields, axis=1)  # a more precise family never loses
    reach = yields >= target
    first = np.argmax(reach, axis=1)
    ok = reach.any(axis=1) & (first > 0)
    k = np.where(ok, first, 1)
    rows = np.arange(len(yields))
    y0, y1 = yields[rows, k - 1], yields[rows, k]
    share = np.where(y1 > y0, (target - y0) / np.where(y1 > y0, y1 - y0, 1.0), 1.0)
    out = costs[k - 1] + share * (costs[k] - costs[k - 1])
    return np.where(ok, out, np.nan)


@dataclass(frozen=True, eq=False)
class _Point:
    """A candidate: required indices, its allocation, cost and the design sample's
    per-machine verdicts."""

    z: np.ndarray
    t: np.ndarray
    cost: float
    verdicts: np.ndarray | None = None  # (machines, 6): output inside at every pose

    @property
    def passes(self) -> np.ndarray:
        """Per machine: every output inside at every pose."""
        return self.verdicts.all(axis=1)

    def meets(self, target) -> bool:
        return self.passes.mean() >= target


class _Calibrated(NamedTuple):
    """An allocation after :meth:`_Search.calibrate`: its tolerances, cost, per-machine
    verdicts on the calibration sample, and whether a factor was found."""

    t: np.ndarray
    cost: float
    passes: np.ndarray
    calibrated: bool


class _Search:
    """The per-output-target family of allocations, solved and simulated with CRN.

    Every sample of built machines is one draw of standard normals ``u`` from its stream of
    :func:`~reliability.basics.streams.yield_allocation_streams` (design, verification,
    shape design), made when first needed and kept, and judged by :attr:`model`'s
    :meth:`~reliability.sampling.machine_yield.YieldModel.output_ratios`."""

    def __init__(self, machine, points, bounds, machines, seed, design_target,
                 gap_tol=1e-6, problem=None, box=None, executor=None):
        self.problem = problem if problem is not None else AllocationProblem.build(
            machine, workspace_grid(machine, points), side="two_sided", workspace="worst",
            bounds=bounds, targets=dict.fromkeys(OUTPUTS, BUILD_TARGET), **(box or {}))
        machine = self.problem.machine
        self.solver = CommonTargetSolver(self.problem, gap_tol)
        self.gap_tol = gap_tol
        self.z_build = float(self.problem.required_index[0])
        self.model = YieldModel(machine, points_per_axis=points, executor=executor)
        self.streams = streams.yield_allocation_streams(seed)
        self._draws = {}
        self.machines = machines
        self.design_target = design_target
        self.floor = float(required_index(0.5, "two_sided"))
        self.cap = self._caps()
        self.evaluations = 0
        self.toward_lower = 0.0
        self._start = None
        self._cache = {}
        self._poses = {}
        self._grid = {}

    def _caps(self) -> np.ndarray:
        """Largest required index of each output the box can hold (all items at their
        lower bounds), at most the build's, less :data:`CAP_MARGIN`."""
        rows = self.problem.rows
        load = rows.matrix @ np.square(self.problem.lower)
        worst = np.zeros(len(OUTPUTS))
        np.maximum.at(worst, rows.output, load)
        with np.errstate(divide="ignore"):
            held = np.minimum(self.z_build, self.z_build / np.sqrt(worst))
        return held * (1.0 - CAP_MARGIN)

    def solve(self, z) -> _Point:
        """The certified per-pose optimum at required indices ``z`` (no sampling)."""
        z = np.clip(np.asarray(z, dtype=float), self.floor, self.cap)
        scale = np.square(z / self.z_build)[self.problem.rows.output]
        start = None if self._start is None else self._start[0] * scale / self._start[1]
        solution = solve_convex_allocation(
            self.problem.cost.weights, self.problem.rows.matrix * scale[:, None],
            np.square(self.problem.lower), np.square(self.problem.upper),
            gap_tol=self.gap_tol, start=start)
        self._start = (np.array(solution.multipliers), scale)
        return _Point(z=z, t=np.asarray(solution.t), cost=float(solution.fun))

    def evaluate(self, z) -> _Point:
        """:meth:`solve` and the design sample's verdicts (cached by ``z``)."""
        z = np.clip(np.asarray(z, dtype=float), self.floor, self.cap)
        key = tuple(np.round(z, 12))
        if key not in self._cache:
            point = self.solve(z)
            self.evaluations += 1
            self._cache[key] = replace(point, verdicts=self.verdicts(point.t, "design"))
        return self._cache[key]

    def draws(self, sample: str) -> np.ndarray:
        """The standard normal draws ``(machines, dimension)`` of ``sample``
        (``'design'``, ``'verification'`` or ``'shape'``): one draw from its stream, the
        same array for every allocation (common random numbers)."""
        if sample not in self._draws:
            stream = self.streams[SAMPLE_STREAMS[sample]]
            self._draws[sample] = self.model.draws(self.machines, stream)
        return self._draws[sample]

    def verdicts(self, t, sample: str) -> np.ndarray:
        """Per-machine, per-output verdicts ``(machines, 6)`` of allocation ``t`` on
        ``sample``: the output holds its limit at every screened pose of the machine (its
        worst ratio ``|y_o|/I_o`` there below 1, Eq. 19); the machine passes when all six
        do. Screened verdicts are never stricter than the full grid's (:meth:`confirm`)."""
        return self.ratios(t, sample) < 1.0

    def ratios(self, t, sample: str) -> np.ndarray:
        """Per machine and output, the worst ratio of ``t`` over the machine's screened
        poses: the first allocation judged on a sample is judged on the whole grid, and its
        worst pose of every machine and output starts that machine's screened poses."""
        u = self.draws(sample)
        if sample not in self._poses:
            ratios, where = self.model.output_ratios(u, t, with_poses=True)
            self._poses[sample] = self._screen(ratios, where)
            return ratios
        return self.model.ratios_at(u, t, self._poses[sample])[0]

    def _screen(self, ratios, where) -> np.ndarray:
        """The worst poses ``where (machines, 6)`` worth screening: a machine's pose of an
        output whose ratio is below :data:`SCREEN_FLOOR` times the design quantile of the
        machines' worst ratios becomes -1 (no pose), unless it is the machine's worst."""
        level = max(self.design_target, 0.5)
        floor = SCREEN_FLOOR * np.quantile(ratios.max(axis=1), level)
        kept = (ratios >= floor) | (ratios == ratios.max(axis=1, keepdims=True))
        return np.where(kept, where, -1)

    def worst_ratios(self, sample: str):
        """``t -> (ratio, row)``: each machine's worst ratio of ``t`` over its screened
        poses of ``sample`` and its row (the shape search's evaluation)."""
        u = self.draws(sample)
        return lambda t: self.model.worst_ratios_at(u, t, self._poses[sample])

    def confirm(self, t, sample: str) -> bool:
        """Whether the screened verdicts of ``t`` on ``sample`` are the whole grid's; when
        not, the grid's worst poses of ``t`` join every machine's screened poses and every
        cached verdict is dropped. The grid's verdicts of each ``t`` are kept, so a stage
        that ends again at the same allocation is checked without the grid."""
        key = (sample, np.asarray(t, dtype=float).tobytes())
        if key not in self._grid:
            ratios, where = self.model.output_ratios(self.draws(sample), t, with_poses=True)
            self._grid[key] = (ratios < 1.0, self._screen(ratios, where))
        grid, worst = self._grid[key]
        if np.array_equal(grid, self.verdicts(t, sample)):
            return True
        self._poses[sample] = np.concatenate([self._poses[sample], worst], axis=1)
        self._cache.clear()
        return False

    def calibrate(self, point) -> _Calibrated:
        """``point``'s allocation times one factor (inside the box) at which its yield on
        the calibration sample is the design yield
        (:func:`allocation.yield_shape.scaled_to_yield`, the whole grid); ``point``'s own,
        judged there, when no factor inside the box reaches it."""
        u = self.draws("calibration")
        found = scaled_to_yield(self.model, np.asarray(self.problem.lower),
                                np.asarray(self.problem.upper), point.t, self.design_target,
                                u)
        if found is None:
            passes = (self.model.output_ratios(u, point.t) < 1.0).all(axis=1)
            return _Calibrated(point.t, point.cost, passes, calibrated=False)
        return _Calibrated(found["t"], float(self.problem.cost.total(found["t"])),
                           found["passes"], calibrated=True)

    def convex_steps(self, point, steps: int, machines: int):
        """``steps`` steps of the convex problem from ``point``
        (:func:`allocation.yield_dual.tangent_step` on the linearised outputs of
        ``machines`` machines of the convex-step stream, each step rescaled to the design
        yield there), or None when ``steps`` is 0 or the yield is not log-concave in the
        log-tolerances here."""
        machine = self.problem.machine
        if steps == 0 or not_log_concave(machine, machine.profile, machine.distribution):
            return None
        rows = scaled_rows(machine, self.model.deciding_poses)
        draws = unit_draws(self.model, self.model.draws(machines,
                                                        self.streams[CONVEX_STREAM]))
        lower, upper = np.asarray(self.problem.lower), np.asarray(self.problem.upper)
        t = point.t
        for _ in range(steps):
            t = tangent_step(rows, self.problem.cost.weights, lower, upper, t, draws,
                             self.design_target)
        return _Point(z=point.z, t=t, cost=float(self.problem.cost.total(t)))

    def convex_step_text(self, steps: int, machines: int) -> str:
        """Whether the convex steps run here, and why not, in words."""
        machine = self.problem.machine
        why = not_log_concave(machine, machine.profile, machine.distribution)
        if steps == 0:
            return "none asked for"
        if why is not None:
            return (f"not run: {why} (the yield is log-concave in the log-tolerances for "
                    f"independent normal errors constant along travel)")
        plural = "s" if steps > 1 else ""
        return (f"{steps} step{plural} from the search's allocation, the yield's gradient "
                f"on the linearised outputs of {machines:,} machines of their own (the yield "
                f"is log-concave in the log-tolerances: a convex problem)")

    def verification_sample(self):
        """Per-machine verdicts of an allocation on the fresh sample, on the whole grid
        (same draws for all)."""
        u = self.draws("verification")
        return lambda t: (self.model.output_ratios(u, t) < 1.0).all(axis=1)

    def naive(self, steps, yield_target) -> _Point:
        """One common required index, bisected to the smallest meeting the design yield.

        When even the largest the box holds misses it, that index's allocation is moved
        towards the box's lower bounds, ``t + λ (lower − t)``, with ``λ`` bisected to the
        smallest share meeting it (:attr:`toward_lower`); :class:`YieldUnreachableError`
        for ``yield_target`` when not even every tolerance at its lower bound does."""
        self.toward_lower = 0.0
        high = self.evaluate(np.full(6, self.cap.min()))
        if high.meets(self.design_target):
            return self._smallest_shift(np.zeros(6), self.floor, self.cap.min(), high, steps)
        lowered = self._toward_lower_bounds(high, steps)
        if lowered is None:
            raise YieldUnreachableError(self._unreachable(high, yield_target))
        return lowered

    def _toward_lower_bounds(self, high, steps) -> _Point | None:
        """``high``'s allocation moved the smallest share ``λ`` (bisected ``steps`` times)
        of the way to the box's lower bounds at which it meets the design yield; None
        when the lower bounds themselves miss it."""
        def point(share):
            t = high.t + share * (np.asarray(self.problem.lower) - high.t)
            return _Point(z=high.z, t=t, cost=float(self.problem.cost.total(t)),
                          verdicts=self.verdicts(t, "design"))
        best = point(1.0)
        if not best.meets(self.design_target):
            return None
        low, high_share = 0.0, 1.0
        for _ in range(steps):
            middle = 0.5 * (low + high_share)
            trial = point(middle)
            if trial.meets(self.design_target):
                high_share, best = middle, trial
            else:
                low = middle
        self.toward_lower = high_share
        return best

    def _unreachable(self, high, yield_target) -> str:
        """Why ``yield_target`` is out of reach: the yield, the box, the output whose rows
        cap the common target and the output most machines fail at that target."""
        capping = OUTPUTS[int(np.argmin(self.cap))]
        failures = (~high.verdicts).sum(axis=0)
        failing = OUTPUTS[int(np.argmax(failures))]
        tightest = (self.model.output_ratios(self.draws("design"), self.problem.lower)
                    < 1.0).all(axis=1).mean()
        return (f"machine yield {yield_target:g} unreachable inside the box "
                f"{self.problem.box_text()}: the most precise common per-pose target it "
                f"holds, {two_sided_target(self.cap.min()):.6g} (output {capping}'s rows reach "
                f"their limits with every tolerance at its lower bound), gives a yield of "
                f"{high.passes.mean():.4f} on {self.machines} machines, short of the design "
                f"yield {self.design_target:.4f} every candidate must reach there; output "
                f"{failing} fails most of them ({failures.max()} of {self.machines}), and "
                f"every tolerance at its lower bound gives {tightest:.4f}; widen the box "
                f"(bounds) or simulate more machines (a smaller margin above Y)")

    def _smallest_shift(self, base, low, high, best, steps) -> _Point:
        """Bisection on the shift ``s`` of ``base + s`` between a failing ``low`` and a
        passing ``high`` (whose point is ``best``)."""
        for _ in range(steps):
            middle = 0.5 * (low + high)
            point = self.evaluate(base + middle)
            if point.meets(self.design_target):
                high, best = middle, point
            else:
                low = middle
        return best

    def improve(self, start, rounds, restore_steps) -> _Point:
        """Move the six targets towards equal prices of yield (module docstring)."""
        current, step = start, FIRST_STEP
        for _ in range(rounds):
            direction = self._direction(current)
            if not direction.any():
                break
            moved = self._restore(current.z + step * direction, step, restore_steps)
            if moved is not None and moved.cost < current.cost:
                current = moved
            else:
                step *= 0.5
        return current

    def shape(self, start, steps) -> _Point | None:
        """The shape search over every tolerance from ``start``
        (:func:`allocation.yield_shape.shape_search`) on a design sample of its own of the
        same size (its verdicts are that sample's); None when ``steps`` is 0 or the box
        cannot hold it."""
        if steps == 0:
            return None
        self.ratios(start.t, "shape")
        found = shape_search(self.model, self.problem.cost, np.asarray(self.problem.lower),
                             np.asarray(self.problem.upper), start.t,
                             self.design_target, self.draws("shape"), iterations=steps,
                             worst_ratios=self.worst_ratios("shape"))
        if found is None:
            return None
        self.evaluations += found.evaluations
        return _Point(z=start.z, t=found.tolerances, cost=found.cost,
                      verdicts=self.verdicts(found.tolerances, "shape"))

    def _direction(self, current) -> np.ndarray:
        """Per output: −1 (lower its target) … +1 (raise it), from its price of yield.

        The cost a target buys is measured by solving with it lowered by :data:`FD_STEP`
        (no sampling). The yield it buys is what the machines failing through that output
        alone would regain: raising ``z_o`` by ``dz`` shrinks the failures of output ``o``
        by the factor ``1 − h(z_o) dz`` (``h = φ/Φ(−z)``, the normal tail's hazard), so the
        yield gains ``U_o h(z_o) dz / N`` where ``U_o`` is the count of design machines
        failing output ``o`` and no other (machines failing several outputs are not saved
        by one). The price is cost over yield; half a machine stands in for ``U_o = 0``.
        """
        saved = np.zeros(6)
        for o in np.flatnonzero((current.z > self.floor + 1e-9) & self._binds(current)):
            lowered = current.z.copy()
            lowered[o] -= FD_STEP
            saved[o] = current.cost - self.solve(lowered).cost
        binding = saved > 1e-9 * current.cost
        if binding.sum() < 2:
            return np.zeros(6)
        failing = ~current.verdicts
        alone = (failing & (failing.sum(axis=1) == 1)[:, None]).sum(axis=0)
        hazard = norm.pdf(current.z) / norm.sf(current.z)
        gained = np.maximum(alone, 0.5) * hazard * FD_STEP / self.machines
        price = saved / gained
        log_price = np.log(np.where(binding, price, 1.0))
        log_ratio = log_price - log_price[binding].mean()
        return np.where(binding, -np.clip(log_ratio / np.log(PRICE_SCALE), -1.0, 1.0), 0.0)

    def _binds(self, point) -> np.ndarray:
        """Per output: some row of it is active at ``point`` (lowering its target can save)."""
        rows = self.problem.rows
        scale = np.square(point.z / self.z_build)[rows.output]
        load = scale * (rows.matrix @ np.square(point.t))
        worst = np.zeros(len(OUTPUTS))
        np.maximum.at(worst, rows.output, load)
        return worst >= 1.0 - 1e-6

    def _restore(self, z, step, steps) -> _Point | None:
        """The smallest common shift of ``z`` meeting the design yield (None when the box
        cannot): bracketed in steps of ``step``, then bisected."""
        point = self.evaluate(z)
        low, high = 0.0, 0.0
        if point.meets(self.design_target):
            best = point
            for _ in range(8):
                low -= step
                trial = self.evaluate(z + low)
                if not trial.meets(self.design_target):
                    break
                high, best = low, trial
            else:
                return best
        else:
            best = None
            for _ in range(8):
                high += step
                trial = self.evaluate(z + high)
                if trial.meets(self.design_target):
                    best = trial
                    break
                low = high
                if np.all(z + high >= self.cap):
                    return None
            if best is None:
                return None
        return self._smallest_shift(z, low, high, best, steps)
