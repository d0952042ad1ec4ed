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
  probability Y, :class:`~allocation.per_pose.common_target.CommonTargetSolver`) is a lower bound on its
  cost. The row probability is the FOSM one (the linearised output read as normal with
  σ of Eq. 20, the truncated σ under the truncated reading), so the bound holds for that
  model of a row, on the same grid; the yield itself is sampled on the exact model. The
  six rows of one pose must hold together, which gives a tighter bound
  (:mod:`allocation.machine_yield.yield_bound`); the larger of the two is the lower bound. A far
  tighter one, at a stated confidence, follows from the yield's log-concavity in the
  log-tolerances (:func:`allocation.machine_yield.yield_dual.log_concave_bound`, computed apart: it
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
  :func:`allocation.per_pose.system_target.system_allocation`).

The search. On the design sample every candidate must reach the design yield
``Y_d = Y + DESIGN_Z · √(Y (1 − Y) / N)`` (N machines), the margin that lets a fresh
sample of N machines confirm Y (below). At the cheapest allocation for a yield every output's
target buys yield at the same price (the KKT condition in the six targets). Each round
prices every binding output: the cost its target buys, by re-solving with the target
lowered (no sampling), over the yield it buys, from the design machines that fail through
that output alone (:meth:`~allocation.machine_yield.yield_search.YieldSearch._direction`). The targets of dear outputs go down and of
cheap ones up, in proportion to the logarithm of the price ratio, and a common shift of all
six, found by bisection, restores the design yield; the move is kept when it is cheaper,
otherwise the step is halved.

Then the error shape (:mod:`allocation.machine_yield.yield_shape`): starting from the per-output search's
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

Convex steps (``convex_steps``, one by default). Where the yield is log-concave in the
log-tolerances (normal reading, no item correlation, ``constant``) the problem is convex, and
a step towards the optimum of its tangent problem (:func:`allocation.machine_yield.yield_dual.tangent_step`)
from the search's allocation is one more candidate, calibrated like the others. There the
calibration and the verification use the radial control variate
(:mod:`allocation.machine_yield.yield_controlled`: the margin is ``DESIGN_Z`` of its far
smaller standard errors), and the lower bound is the log-concave one at 95 % confidence
(:func:`allocation.machine_yield.yield_dual.dual_bound`) when it is the largest; the
paragraph below is the calibration elsewhere (and with ``estimator='share'``).

Calibration. The search chooses among many candidates on its design samples, so the
yield of the allocation it ends at is biased upwards there (on the paper's machine at 4 000
machines the fresh samples saw about one standard error less). The allocation is therefore
multiplied by one factor, inside the box (:func:`allocation.machine_yield.yield_shape.scaled_to_yield`:
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

import numpy as np
import pandas as pd

from reliability.basics import checks, streams
from reliability.basics.errors import InputError
from reliability.basics.renamed import renamed
from reliability.basics.threads import one_blas_thread
from reliability.basics.saved_fields import (Array, Flag, Integer, Mapping, Nested, Number,
                                            Record, Text, Texts, read_fields, write_fields)
from reliability.basics.saved_results import load_payload, save_payload
from reliability.basics.statistics import ProportionEstimate, all_within_share
from reliability.model.machine import OUTPUTS
from reliability.sampling.radial_yield import CONTROLLED_METHOD

from ..per_pose.problem import DEFAULT_FACTORS
from ..solvers.convex import InfeasibleAllocationError
from .yield_bound import ChainBound, pose_chain_bound
from .log_concave_runs import bracket_defaults, log_concave_text, result_bound
from .yield_controlled import DESIGN_Z
from .yield_dual import YieldDualBound
from .yield_search import YieldSearch, YieldUnreachableError, two_sided_target
from .yield_words import finding_lines

#: Machines simulated by default (design and verification samples each).
DEFAULT_MACHINES = 2000
#: Rays of the convex steps, as a multiple of the design sample's machines, by default.
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
        (:func:`allocation.machine_yield.yield_dual.tangent_step`), before and after the calibration;
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
        Lower bound on the cost of any allocation with yield ≥ Y: the largest of the
        certified :attr:`row_bound` and pose-chain bound (:attr:`chain_bound`) and the
        log-concave bound at 95 % (:attr:`log_concave`, where it applies);
        :attr:`lower_bound_kind` says which, :attr:`lower_bound_confidence` at what
        confidence.
    row_bound : float
        The row relaxation's certified bound (every row at FOSM probability Y).
    chain_bound : allocation.machine_yield.yield_bound.ChainBound or None
        The pose-chain relaxation (:mod:`allocation.machine_yield.yield_bound`: the six outputs' joint
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
        Wall time of the build, the certified lower bounds, the two stages (summed over
        the searches), the convex step, the calibration, the verification and the
        log-concave bound.
    log_concave : allocation.machine_yield.yield_dual.YieldDualBound or None
        The lower bound at 95 % confidence from the yield's log-concavity in the
        log-tolerances (:func:`allocation.machine_yield.yield_dual.dual_bound`); None where
        the theorem does not hold or it was not asked for (:attr:`log_concave_text`).
    log_concave_text : str
        Why :attr:`log_concave` is None, in words (empty when it is not).
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
    log_concave: object = None
    log_concave_text: str = ""

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

    @property
    def certified_bound(self) -> float:
        """The larger of the row and pose-chain bounds (certified, no sampling)."""
        return max(self.row_bound, -np.inf if self.chain_bound is None else
                   self.chain_bound.bound)

    @property
    def lower_bound_kind(self) -> str:
        """Which bound :attr:`lower_bound` is: ``'log-concave'``, ``'pose chain'`` or
        ``'row'``."""
        if self.log_concave is not None and self.lower_bound == self.log_concave.bound:
            return "log-concave"
        if self.chain_bound is not None and self.lower_bound == self.chain_bound.bound:
            return "pose chain"
        return "row"

    @property
    def lower_bound_confidence(self) -> float:
        """The confidence :attr:`lower_bound` holds at: the log-concave bound's, 1 for a
        certified one."""
        return self.log_concave.confidence if self.lower_bound_kind == "log-concave" else 1.0

    @property
    def gap_of_cost(self) -> float:
        """:attr:`relative_gap`: the gap over the verified cost."""
        return self.relative_gap

    def summary(self, verbose: bool = True) -> str:
        """The model, the bracket, the verified yield and the naive method beside it, in
        words; with ``verbose`` also every bound and stage
        (:func:`allocation.machine_yield.yield_words.finding_lines`)."""
        return "\n".join([self.model_text(), *self.finding_lines(verbose)])

    def model_text(self) -> str:
        """What the yield is of: target, profile, reading, grid and box."""
        return (f"allocation for machine yield {self.yield_target:g} (profile {self.profile}, "
                f"distribution {self.distribution}, {self.points}-point grid of "
                f"{len(self.problem.poses):,} poses, {self.problem.box_text()})")

    def finding_lines(self, verbose: bool = False) -> list[str]:
        """One lower bound, the cost and its stage, one gap, the calibration, the verified
        yield and the naive method, one line each; ``verbose`` adds every bound and stage
        (:func:`allocation.machine_yield.yield_words.finding_lines`)."""
        return finding_lines(self, verbose)

    def __repr__(self) -> str:
        return self.summary()

    def to_frame(self) -> pd.DataFrame:
        """One row per error: the initial (reference) tolerance, the allocation, the
        search's allocation before calibration, the row relaxation's optimum and the naive
        method's allocation."""
        return pd.DataFrame({"reference": self.problem.reference,
                             "allocated": self.tolerances, "searched": self.search_tolerances,
                             "lower_bound": self.lower_bound_tolerances,
                             "naive": self.naive.tolerances},
                            index=pd.Index(self.problem.names, name="error"))

    def save(self, path, overwrite: bool = False):
        """Save as JSON (:data:`SAVED_FIELDS`, tag :data:`SAVED_FORMAT`, with
        ``from_narrower_box``, ``lower_bound_kind``, ``lower_bound_confidence`` and
        ``gap_of_cost``, derived keys that loading ignores); the problems are not saved. An existing file is kept
        unless ``overwrite``. Returns the path."""
        payload = write_fields(self, SAVED_FIELDS)
        payload["from_narrower_box"] = self.from_narrower_box
        payload.update(lower_bound_kind=self.lower_bound_kind,
                       lower_bound_confidence=self.lower_bound_confidence,
                       gap_of_cost=self.gap_of_cost)
        return save_payload(path, SAVED_FORMAT, payload, overwrite)

    @classmethod
    def load(cls, path, problem, search_problem=None) -> "YieldAllocation":
        """Reload an allocation written by :meth:`save` for ``problem`` (the one it was
        found for) and, when it came from the narrower box, its ``search_problem``; every
        field is checked: one tolerance per error of the problem, the bracket in order
        (lower bound at most the cost), so the verdicts (verified or not, the bracket, the
        yields and their intervals) are the saved ones; a file without
        :data:`LATER_FIELDS` loads without a log-concave bound. A damaged field raises
        :class:`~reliability.basics.errors.SavedResultError` naming the file and field."""
        data = load_payload(path, SAVED_FORMAT)
        for key in LATER_FIELDS:  # files written before the log-concave bound was saved
            data.data.setdefault(key, None)
        values = read_fields(data, SAVED_FIELDS)
        narrower = data.boolean("from_narrower_box")
        if narrower and search_problem is None:
            raise InputError(f"{path}: the allocation came from the narrower box; pass its "
                             f"search_problem")
        n = len(problem.names)
        for key in ("tolerances", "search_tolerances", "lower_bound_tolerances"):
            if len(values[key]) != n:
                raise data.error(key, f"expected one entry per error of the problem ({n})")
        if values["lower_bound"] > values["cost"] * (1 + 1e-9):
            raise data.error("lower_bound", "exceeds the cost")
        values["log_concave_text"] = values["log_concave_text"] or ""
        return cls(problem=problem, search_problem=search_problem if narrower else problem,
                   **values)


class SavedProportion:
    """The payload writer and reader of a one-number :class:`ProportionEstimate`."""

    FIELDS = (Number("estimate", low=0.0, high=1.0), Number("lower", low=0.0, high=1.0),
              Number("upper", low=0.0, high=1.0), Number("standard_error", low=0.0),
              Integer("n", low=1),
              Text("method", ("wilson", "clopper-pearson", CONTROLLED_METHOD)),
              Number("confidence", low=0.0, high=1.0), Texts("names", optional=True))

    @staticmethod
    def payload(estimate) -> dict:
        return write_fields(estimate, SavedProportion.FIELDS)

    @staticmethod
    def from_payload(data) -> ProportionEstimate:
        values = read_fields(data, SavedProportion.FIELDS)
        if not values["lower"] <= values["estimate"] <= values["upper"]:
            raise data.error("estimate", "lies outside its interval [lower, upper]")
        return ProportionEstimate(**values)


#: The fields of a :class:`~allocation.machine_yield.yield_bound.ChainBound` saved with a
#: yield allocation.
CHAIN_BOUND_FIELDS = (Number("bound", positive=True),
                      Array("tolerances", (None,), positive=True),
                      Array("poses", (None,), dtype=int, low=0), Integer("rows", low=0))
#: The fields of a :class:`~allocation.machine_yield.yield_dual.YieldDualBound` saved with a
#: yield allocation.
DUAL_BOUND_FIELDS = (Number("bound", positive=True), Number("confidence", low=0.0, high=1.0),
                     Number("yield_target", low=0.0, high=1.0),
                     Array("point", (None,), positive=True), Number("point_cost", positive=True),
                     Number("point_yield", low=0.0, high=1.0), Number("multiplier", low=0.0),
                     Number("point_estimate"), Integer("machines", low=1),
                     Integer("steps", low=0), Integer("rows", low=0), Number("seconds", low=0.0),
                     Text("sample", ("rays", "machines"), optional=True))
#: The fields of a :class:`NaiveAllocation` saved with a yield allocation.
NAIVE_FIELDS = (Number("target", low=0.0, high=1.0), Number("toward_lower", low=0.0, high=1.0),
                Array("tolerances", (None,), positive=True), Number("cost", positive=True),
                Number("search_cost", positive=True),
                *(Nested(key, SavedProportion)
                  for key in ("design_yield", "calibration_yield", "verified_yield")))


#: Fields a file written before the log-concave bound was part of the result lacks: they
#: load as None (no log-concave bound).
LATER_FIELDS = ("log_concave", "log_concave_text")
SAVED_FORMAT = "precrel.yield_allocation"
SAVED_FIELDS = (
    Number("yield_target", low=0.0, high=1.0), Number("design_yield_target", low=0.0, high=1.0),
    Array("tolerances", (None,), positive=True), Number("cost", positive=True),
    Array("search_tolerances", (None,), positive=True), Number("search_cost", positive=True),
    Number("search_calibrated_cost", positive=True), Text("search_stage"),
    Number("convex_step_cost", optional=True, positive=True),
    Number("convex_step_calibrated_cost", optional=True, positive=True),
    Text("convex_step_text"), Array("output_targets", (len(OUTPUTS),), low=0.0, high=1.0),
    Text("method", ("per-output targets", "error shape", "naive start", "convex step")),
    Nested("design_yield", SavedProportion), Flag("calibrated"),
    Nested("calibration_yield", SavedProportion), Nested("verified_yield", SavedProportion),
    Number("lower_bound", positive=True), Number("row_bound", positive=True),
    Record("chain_bound", CHAIN_BOUND_FIELDS, ChainBound, optional=True),
    Array("lower_bound_tolerances", (None,), positive=True), Record("naive", NAIVE_FIELDS, NaiveAllocation),
    Text("profile"), Text("distribution", ("normal", "truncated")), Integer("points", low=2),
    Integer("machines", low=1), Integer("seed"), Integer("evaluations", low=0),
    Mapping("seconds"), Record("log_concave", DUAL_BOUND_FIELDS, YieldDualBound, optional=True),
    Text("log_concave_text", optional=True))


@renamed("seed", "rng")
@one_blas_thread
def allocate_for_yield(machine, yield_target: float, *, profile=None, distribution=None,
                       points: int = 5, bounds=None, machines: int = DEFAULT_MACHINES,
                       rng: int | None = 0, rounds: int = 6, naive_steps: int = 8,
                       restore_steps: int = 4, shape_steps: int = 20,
                       convex_steps: int | None = None, convex_machines: int | None = None,
                       bound_machines: int | None = None, estimator: str = "radial",
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
    rng : int or None
        Seed of the samples: the design sample of the per-output stage, the verification
        sample, the design sample of the shape stage and the calibration sample draw from
        the first, second, third and fifth streams of
        :func:`reliability.basics.streams.yield_allocation_streams`, once each; None draws
        a fresh seed (recorded as the result's ``seed``). A Generator is refused
        (InputTypeError naming ``rng``): the named streams derive from an integer seed.
        ``seed=`` is the deprecated spelling (:mod:`reliability.basics.renamed`).
    rounds : int
        Rounds of the search over the six per-output targets (0: the naive method only).
    naive_steps, restore_steps : int
        Bisection steps on the naive common target and on each round's common shift.
    shape_steps : int
        Candidates of the shape search over every tolerance that follows the per-output
        search (:func:`allocation.machine_yield.yield_shape.shape_search`; 0: none).
    convex_steps : int, optional
        Steps of the convex problem from the search's allocation
        (:func:`allocation.machine_yield.yield_dual.tangent_step`) where the yield is
        log-concave in the log-tolerances (normal reading, no item correlation); by default
        one under the ``constant`` profile (on rays) and none under ``independent`` and
        ``gp`` (on crude machines of the profile, minutes: ask for them); 0: none. Their allocation is calibrated and verified
        like the others, and kept when cheapest.
    convex_machines : int, optional
        Rays the convex steps estimate the yield's gradient on (default
        ``CONVEX_MACHINES_FACTOR`` × ``machines``), drawn from the sixth stream: the
        step is only as good as its gradient, whose relative error falls as
        ``1/√convex_machines``.
    bound_machines : int, optional
        Rays of the lower bound at 95 % confidence from the yield's log-concavity
        (:func:`allocation.machine_yield.log_concave_runs.result_bound`: the tangent at the
        result rescaled to Y on a sample of its own, the bound on a fresh one), by default
        ``BOUND_MACHINES_FACTOR`` × ``machines`` under ``constant``; under the
        ``independent`` and ``gp`` profiles crude machines of the profile, only when given
        (they take minutes); 0: none.
    estimator : {'radial', 'share'}
        How the calibration and the verification estimate a yield: ``'radial'``, where the
        yield is log-concave (normal reading, no item correlation, ``constant``), the
        radial control variate (:mod:`allocation.machine_yield.yield_controlled`: its
        margin ``DESIGN_Z`` × its standard error, a normal interval), elsewhere and with
        ``'share'`` the share of machines passing (margin ``DESIGN_Z`` binomial standard
        errors, a Clopper–Pearson interval).
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
    seed = streams.integer_seed(rng)
    for value, name in ((rounds, "rounds"), (naive_steps, "naive_steps"),
                        (restore_steps, "restore_steps"), (shape_steps, "shape_steps"),
                        (convex_steps, "convex_steps")):
        if value is not None:
            checks.positive_int(value, name, minimum=0)
    convex_machines = CONVEX_MACHINES_FACTOR * machines if convex_machines is None else \
        checks.positive_int(convex_machines, "convex_machines")
    if bound_machines is not None:
        checks.positive_int(bound_machines, "bound_machines", minimum=0)
    controlled = checks.choice(estimator, "estimator", ("radial", "share")) == "radial"
    chosen = {name: value for name, value in (("profile", profile),
                                              ("distribution", distribution))
              if value is not None}
    machine = replace(machine, **chosen) if chosen else machine
    convex_steps, bound_machines = bracket_defaults(machine, machines, convex_steps,
                                                    bound_machines)
    design_target = min(yield_target + DESIGN_Z * np.sqrt(yield_target * (1 - yield_target)
                                                           / machines),
                        1.0 - 0.5 / machines)
    search = YieldSearch(machine, points, bounds, machines, seed, design_target, gap_tol,
                         executor=executor, yield_target=yield_target if controlled else None)
    searches = [search, *_narrower_searches(machine, points, search.problem, machines, seed,
                                            design_target, gap_tol, executor,
                                            search.yield_target)]
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
    finished = [_finished(outcome, convex_steps, convex_machines, design_target)
                for outcome in outcomes]
    kept = int(np.argmin([each.final.cost for each in finished]))
    found, done = outcomes[kept], finished[kept]
    chosen, naive = found.chosen, found.naive
    searched_final, naive_final, stepped, step_final = (
        done.searched, done.naive, done.stepped, done.step_final)
    method, final = done.method, done.final
    step_seconds = sum(each.step_seconds for each in finished)
    calibrated = time.perf_counter()
    verify = found.search.verification_sample()
    verified_yield, naive_verified = verify(final.t), verify(naive_final.t)
    verified = time.perf_counter()
    dual = result_bound(search.problem, points, yield_target, final.t, bound_machines, seed, machines)
    certified = max(float(lower.dual_bound), -np.inf if chain is None else chain.bound)
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
        calibrated=final.calibrated, calibration_yield=final.estimate,
        verified_yield=verified_yield,
        lower_bound=certified if dual is None else max(certified, dual.bound),
        row_bound=float(lower.dual_bound), chain_bound=chain,
        lower_bound_tolerances=np.asarray(lower.t),
        naive=NaiveAllocation(target=float(two_sided_target(naive.z[0])),
                              toward_lower=float(found.search.toward_lower),
                              tolerances=naive_final.t, cost=naive_final.cost,
                              search_cost=naive.cost,
                              design_yield=all_within_share(naive.passes),
                              calibration_yield=naive_final.estimate,
                              verified_yield=naive_verified),
        profile=machine.profile, distribution=machine.distribution, points=int(points),
        machines=machines, seed=seed, evaluations=sum(each.evaluations for each in searches),
        seconds={"build": built - started, "bound": bounded - built,
                 "targets": sum(outcome.seconds["targets"] for outcome in outcomes),
                 "shape": sum(outcome.seconds["shape"] for outcome in outcomes),
                 "convex step": step_seconds,
                 "calibration": calibrated - searched - step_seconds,
                 "verify": verified - calibrated,
                 "log-concave bound": time.perf_counter() - verified},
        log_concave=dual, log_concave_text=log_concave_text(machine, bound_machines))


@dataclass(frozen=True)
class _Finished:
    """One search's candidates, calibrated: its own allocation, its naive start and its
    convex step (None when not run), and the cheapest of them (``method``, ``final``)."""

    searched: object
    naive: object
    stepped: object
    step_final: object
    step_seconds: float
    method: str
    final: object


def _finished(outcome, convex_steps, convex_machines, design_target) -> _Finished:
    """Calibrate ``outcome``'s allocation and naive start, take the convex steps from its
    allocation and calibrate them; the cheapest of the three (first of equal costs). Every
    search (the box's and its intersection with the default box) is finished so, and the
    cheapest over all of them is the result: a box never costs more than its intersection
    with the default box."""
    search = outcome.search
    searched = search.calibrate(outcome.chosen)
    naive = search.calibrate(outcome.naive)
    started = time.perf_counter()
    level = searched.estimate.estimate if search.controlled else design_target
    stepped = search.convex_steps(outcome.chosen, convex_steps, convex_machines, level)
    step_seconds = time.perf_counter() - started
    step_final = None if stepped is None else search.calibrate(stepped)
    method, final = _cheapest({_stage(outcome): searched, "naive start": naive,
                               "convex step": step_final})
    return _Finished(searched, naive, stepped, step_final, step_seconds, method, final)


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
                       executor=None, yield_target=None):
    """The search in the default factor box intersected with ``problem``'s box, built as a
    search given that box would build it: none when the intersection is the box itself or
    empty."""
    reference = problem.reference
    lower = np.maximum(problem.lower, reference * DEFAULT_FACTORS[0])
    upper = np.minimum(problem.upper, reference * DEFAULT_FACTORS[1])
    same = np.array_equal(lower, problem.lower) and np.array_equal(upper, problem.upper)
    if same or np.any(lower > upper):
        return []
    return [YieldSearch(machine, points, None, machines, seed, design_target, gap_tol,
                    box={"lower": lower, "upper": upper}, executor=executor,
                    yield_target=yield_target)]


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
