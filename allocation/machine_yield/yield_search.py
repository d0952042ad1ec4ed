"""The search of :func:`~allocation.machine_yield.yield_target.allocate_for_yield`: the
family of allocations along six per-output targets, solved certified and judged on built
machines.

:class:`YieldSearch` solves the per-pose problem of Eq. (34) at six per-output required
indices (:meth:`YieldSearch.solve`), judges each allocation on fixed samples of built
machines with common random numbers (:meth:`YieldSearch.verdicts`, screened to each
machine's worst poses and confirmed on the whole grid), and runs the stages the module
:mod:`allocation.machine_yield.yield_target` describes: the naive method, the per-output
search, the error shape, the convex steps and the calibration.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import NamedTuple

import numpy as np
from scipy.stats import norm

from reliability.basics import streams
from reliability.basics.statistics import all_within_share
from reliability.first_order.fosm import required_index
from reliability.model.machine import OUTPUTS
from reliability.model.poses import workspace_grid
from reliability.sampling.machine_yield import YieldModel

from ..per_pose.common_target import CommonTargetSolver
from ..per_pose.problem import AllocationProblem
from ..solvers.convex import InfeasibleAllocationError, solve_convex_allocation
from .yield_controlled import DESIGN_Z, calibrated, proportion, ray_sample
from .yield_dual import linearised, not_log_concave, on_rays, scaled_rows, tangent_step
from .yield_shape import scaled_to_yield, shape_search

#: Two-sided per-pose target the constraint rows are built and screened at: every target
#: the search uses lies at or below it, so no screened-out row can bind.
BUILD_TARGET = 1.0 - 1e-9
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
#: The samples of built machines and their streams
#: (:func:`reliability.basics.streams.yield_allocation_streams`; the fourth stream is the
#: bootstrap's of :func:`~allocation.machine_yield.yield_margin.equal_yield_margin`).
SAMPLE_STREAMS = {"design": 0, "verification": 1, "shape": 2, "calibration": 4}
SAMPLES = tuple(SAMPLE_STREAMS)
#: The stream of the convex steps' machines.
CONVEX_STREAM = 5


class YieldUnreachableError(InfeasibleAllocationError):
    """Even the most precise common per-pose target inside the box misses the yield."""

    def __init__(self, message: str):
        ValueError.__init__(self, message)
        self.rows, self.loads = (), np.empty(0)


def two_sided_target(z):
    """Two-sided per-pose target ``2Φ(z) − 1`` of a required index ``z``."""
    return 2.0 * norm.cdf(z) - 1.0


@dataclass(frozen=True, eq=False)
class SearchPoint:
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
    """An allocation after :meth:`YieldSearch.calibrate`: its tolerances, cost, per-machine
    verdicts on the calibration sample, whether a factor was found, and its yield there
    (a ProportionEstimate)."""

    t: np.ndarray
    cost: float
    passes: np.ndarray
    calibrated: bool
    estimate: object


class YieldSearch:
    """The per-output-target family of allocations, solved and simulated with CRN.

    Every sample of built machines is one draw of standard normals ``u`` from its stream of
    :func:`~reliability.basics.streams.yield_allocation_streams` (design, verification,
    shape design), made when first needed and kept, and judged by :attr:`model`'s
    :meth:`~reliability.sampling.machine_yield.YieldModel.output_ratios`. Given a
    ``yield_target`` where the yield is log-concave, the calibration and the verification
    use the radial control variate on those samples and rays of their own
    (:attr:`controlled`)."""

    def __init__(self, machine, points, bounds, machines, seed, design_target,
                 gap_tol=1e-6, problem=None, box=None, executor=None, yield_target=None):
        self.problem = problem if problem is not None else AllocationProblem.build(
            machine, workspace_grid(machine, points), side="two_sided", workspace="worst",
            bounds=bounds, targets=dict.fromkeys(OUTPUTS, BUILD_TARGET), **(box or {}))
        machine = self.problem.machine
        self.solver = CommonTargetSolver(self.problem, gap_tol)
        self.gap_tol = gap_tol
        self.z_build = float(self.problem.required_index[0])
        self.model = YieldModel(machine, points=points, executor=executor)
        self.streams = streams.yield_allocation_streams(seed)
        self.seed = seed
        self.yield_target = yield_target
        self._ray_samples = {}
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

    def solve(self, z) -> SearchPoint:
        """The certified per-pose optimum at required indices ``z`` (no sampling)."""
        z = np.clip(np.asarray(z, dtype=float), self.floor, self.cap)
        scale = np.square(z / self.z_build)[self.problem.rows.output]
        start = None if self._start is None else self._start[0] * scale / self._start[1]
        solution = solve_convex_allocation(
            self.problem.cost.weights, self.problem.rows.matrix * scale[:, None],
            np.square(self.problem.lower), np.square(self.problem.upper),
            gap_tol=self.gap_tol, start=start)
        self._start = (np.array(solution.multipliers), scale)
        return SearchPoint(z=z, t=np.asarray(solution.t), cost=float(solution.fun))

    def evaluate(self, z) -> SearchPoint:
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

    @property
    def controlled(self) -> bool:
        """The calibration and the verification use the radial control variate
        (:mod:`allocation.machine_yield.yield_controlled`): a yield target was given and
        the yield is log-concave here (normal reading, no item correlation, ``constant``)."""
        machine = self.problem.machine
        return self.yield_target is not None and \
            on_rays(machine, machine.profile, machine.distribution)

    def ray_sample(self, sample: str):
        """The :class:`~allocation.machine_yield.yield_controlled.ControlledSample` of
        ``sample`` (``'calibration'`` or ``'verification'``), made once."""
        if sample not in self._ray_samples:
            self._ray_samples[sample] = ray_sample(self, sample, self.seed)
        return self._ray_samples[sample]

    def calibrate(self, point) -> _Calibrated:
        """``point``'s allocation times one factor (inside the box) at which its yield on
        the calibration sample is the design yield
        (:func:`allocation.machine_yield.yield_shape.scaled_to_yield`, the whole grid), or,
        :attr:`controlled`, at which ``Ŷ − DESIGN_Z·SE ≥ Y`` there
        (:func:`allocation.machine_yield.yield_controlled.calibrated`); ``point``'s own,
        judged there, when no factor inside the box reaches it."""
        lower, upper = np.asarray(self.problem.lower), np.asarray(self.problem.upper)
        if self.controlled:
            t, judged, reached = calibrated(self.ray_sample("calibration"), point.t, lower,
                                            upper, self.yield_target, DESIGN_Z)
            return _Calibrated(t, float(self.problem.cost.total(t)), judged.exact < 1.0,
                               reached, proportion(judged.estimate()))
        u = self.draws("calibration")
        found = scaled_to_yield(self.model, lower, upper, point.t, self.design_target, u)
        if found is None:
            passes = (self.model.output_ratios(u, point.t) < 1.0).all(axis=1)
            return _Calibrated(point.t, point.cost, passes, False, all_within_share(passes))
        return _Calibrated(found["t"], float(self.problem.cost.total(found["t"])),
                           found["passes"], True, all_within_share(found["passes"]))

    def convex_steps(self, point, steps: int, machines: int, level: float):
        """``steps`` steps of the convex problem from ``point``
        (:func:`allocation.machine_yield.yield_dual.tangent_step` on the linearised outputs,
        ``machines`` rays of the convex-step stream, each step rescaled to the yield
        ``level`` there), or None when ``steps`` is 0 or the yield is not log-concave in the
        log-tolerances here."""
        machine = self.problem.machine
        if steps == 0 or not_log_concave(machine, machine.profile, machine.distribution):
            return None
        if machine.profile == "constant":
            rows = scaled_rows(machine, self.model.deciding_poses)
            draws = self.streams[CONVEX_STREAM].standard_normal((machines, len(point.t)))
        else:  # crude machines of the profile (allocation.machine_yield.profile_bound)
            rows, draws = linearised(self.model, self.model.draws(machines,
                                                                  self.streams[CONVEX_STREAM]))
        lower, upper = np.asarray(self.problem.lower), np.asarray(self.problem.upper)
        t = point.t
        for _ in range(steps):
            t = tangent_step(rows, self.problem.cost.weights, lower, upper, t, draws, level)
        return SearchPoint(z=point.z, t=t, cost=float(self.problem.cost.total(t)))

    def convex_step_text(self, steps: int, machines: int) -> str:
        """Whether the convex steps run here, and why not, in words."""
        machine = self.problem.machine
        why = not_log_concave(machine, machine.profile, machine.distribution)
        if steps == 0:
            return "none asked for"
        if why is not None:
            return (f"not run: {why} (the yield is log-concave in the log-tolerances for "
                    f"independent normal errors, each scaled by its own tolerance)")
        plural = "s" if steps > 1 else ""
        sample = (f"{machines:,} rays" if machine.profile == "constant" else
                  f"{machines:,} machines under the profile {machine.profile!r}")
        return (f"{steps} step{plural} from the search's allocation, the yield's gradient "
                f"on the linearised outputs of {sample} of their own (the yield is "
                f"log-concave in the log-tolerances: a convex problem)")

    def verification_sample(self):
        """``t ->`` the yield (a ProportionEstimate) of an allocation on the fresh sample,
        on the whole grid (same draws for all): the share of its machines passing, or,
        :attr:`controlled`, the radial control variate on its machines and rays."""
        if self.controlled:
            return self.ray_sample("verification").estimate
        verdicts = self.verification_verdicts()
        return lambda t: all_within_share(verdicts(t))

    def verification_verdicts(self):
        """``t ->`` per-machine verdicts of an allocation on the fresh sample, on the whole
        grid (same draws for all)."""
        u = self.draws("verification")
        return lambda t: (self.model.output_ratios(u, t) < 1.0).all(axis=1)

    def naive(self, steps, yield_target) -> SearchPoint:
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

    def _toward_lower_bounds(self, high, steps) -> SearchPoint | None:
        """``high``'s allocation moved the smallest share ``λ`` (bisected ``steps`` times)
        of the way to the box's lower bounds at which it meets the design yield; None
        when the lower bounds themselves miss it."""
        def point(share):
            t = high.t + share * (np.asarray(self.problem.lower) - high.t)
            return SearchPoint(z=high.z, t=t, cost=float(self.problem.cost.total(t)),
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

    def _smallest_shift(self, base, low, high, best, steps) -> SearchPoint:
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

    def improve(self, start, rounds, restore_steps) -> SearchPoint:
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

    def shape(self, start, steps) -> SearchPoint | None:
        """The shape search over every tolerance from ``start``
        (:func:`allocation.machine_yield.yield_shape.shape_search`) on a design sample of its
        own of the same size (its verdicts are that sample's); None when ``steps`` is 0 or the
        box cannot hold it."""
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
        return SearchPoint(z=start.z, t=found.tolerances, cost=found.cost,
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

    def _restore(self, z, step, steps) -> SearchPoint | None:
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
