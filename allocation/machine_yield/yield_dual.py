"""A lower bound on the cost of any allocation of machine yield Y, at a stated confidence, from
the log-concavity of the yield in the log-tolerances.

Why the yield allocation is a convex problem. Read the six outputs to first order (Eq. 19,
the rows of every grid pose, ``y_o = J_o(q)·e``), every error normal with σ = t/3 and the
errors independent (no item correlation), constant along travel. A built machine is then
``e = t ∘ z / 3`` with ``z`` standard normal, and it passes when ``t ∘ z`` lies in the
symmetric convex polytope ``K = {v : |J_o(q)·v| ≤ 3 I_o at every pose}``. So its yield is
the Gaussian measure of ``e^{Δ(−u)} K`` with ``u = log t``, which is log-concave in ``u``
(the (B) theorem of Cordero-Erausquin, Fradelizi & Maurey, J. Funct. Anal. 214, 2004,
Theorem 1, for dilations by any diagonal matrix). So ``h(u) = −log Y(e^u)`` is convex, and
so is the cost ``Σ w_i e^{−2u_i}`` (Eq. 28): the allocation for a yield is a convex problem
in ``u``, with a single optimum.

The bound. At any point ``u0``, convexity gives ``h(u) ≥ h(u0) + g·(u − u0)`` with
``g = ∇h(u0)``, so every allocation of yield ≥ Y lies in the half-space
``g·(u − u0) ≤ −log Y − h(u0)``, and for every ``λ ≥ 0`` (weak duality)

    cost ≥ Σ_i min over [log lower_i, log upper_i] of (w_i e^{−2u_i} + λ g_i (u_i − u0_i))
           − λ (−log Y − h(u0)),

each term in closed form (the stationary point ``e^{−2u} = λ g_i / (2 w_i)``, clipped to the
box). The bound is the largest over ``λ`` (concave in ``λ``). ``h(u0)`` and ``g`` are
estimated on N sampled rays by directional sampling
(:func:`reliability.sampling.radial_yield.radial_gradient`: along each direction the
machine passes up to the radius ρ where the ray leaves the polytope, so the yield is the
mean of ``F_{χ²_n}(ρ²)`` and its gradient the mean of ``−2ρ² f_{χ²_n}(ρ²) s_i``, with
``s_i`` error i's share of the binding row, in closed form). On crude machines the gradient
is the conditional Monte Carlo of :func:`yield_and_gradient` (given the other errors of a
machine, the draws of error ``i`` that pass form an interval ``[l, r]``, so
``∂Y/∂log t_i`` is the mean of ``l φ(l) − r φ(r)``). For a bound that holds at the
confidence ``1 − α``, ``h(u0)`` is replaced by its lower confidence end and each ``g_i`` by
the worse end of its interval (Bonferroni: a two-sided interval of the yield at ``α/2``,
normal ``estimate ± z·SE`` on rays, Clopper–Pearson on crude machines, which the gradient's
ends also use, and a normal interval of each ``∂Y/∂log t_i`` at ``α/(2 n)``): the bound is
concave in each ``g_i``, so the worse end is one of the two.

The point. The bound is tight at the optimum, where the tangent half-space touches the
feasible set. Starting from an allocation (the search's), each step (:func:`tangent_step`)
estimates ``g`` there, takes the minimiser of the bound's Lagrangian (the optimum of the
tangent problem) and the points a half, a quarter and an eighth of the way to it, rescales
each to yield Y on the step's own sample and keeps the cheapest; the bound is then computed
at the last point on a fresh sample, so the point is independent of the sample that judges
it. The gradient's intervals are normal ones (the central limit theorem over the machines,
each machine's term bounded).

What it holds for: the linearised outputs on the grid's poses (the model of the certified
relaxations of :mod:`allocation.machine_yield.yield_target`), the normal reading, independent
errors, the ``constant`` profile here (on rays) and the ``independent`` and ``gp`` profiles
through :mod:`allocation.machine_yield.profile_bound` (the same theorem, each error's draws
along travel scaled by its tolerance alone; on crude machines); not the exact chain, on
which the yield is sampled. Under those assumptions the error of the first-order outputs is
second order in the errors.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize_scalar
from scipy.stats import beta, norm

from reliability.basics import checks, streams
from reliability.basics.display import percentage_text
from reliability.basics.errors import InputError
from reliability.basics.renamed import renamed
from reliability.basics.threads import one_blas_thread
from reliability.sampling.machine_yield import YieldModel
from reliability.sampling.radial_yield import as_directions, radial_gradient, rays, worst_rows

from . import profile_bound
from .yield_shape import bisected_scale

#: Coverage factor of the normal reading (σ = t/3).
K_SIGMA = 3.0
#: Floats of one block of machines × rows (memory bounded by chunking).
BLOCK_FLOATS = 2_000_000
#: Fixed-point steps of a factor rescaling an allocation to a yield (:func:`_at_yield` here,
#: the calibration of :mod:`allocation.machine_yield.yield_controlled`), and the relative
#: distance from the yield's factor within which it is accepted.
RESCALES, SLACK = 4, 1e-3
#: Shares of the way to the tangent problem's optimum a step tries (:func:`tangent_step`).
STEP_SHARES = (1.0, 0.5, 0.25, 0.125, 0.0)


@dataclass(frozen=True, eq=False)
class YieldDualBound:
    """A lower bound on the cost of any allocation whose machine yield is at least Y.

    Attributes
    ----------
    bound : float
        The bound (cost, Eq. 28), holding at :attr:`confidence` for the linearised model.
    confidence : float
    yield_target : float
    point : ndarray (n_errors,)
        The allocation the tangent was taken at.
    point_cost : float
    point_yield : float
        Its linearised yield on the bound's rays.
    multiplier : float
        The ``λ`` of the bound.
    point_estimate : float
        The bound with the estimates themselves in place of their confidence ends.
    machines : int
        Rays of each sample (every step and the bound's).
    steps : int
        Steps from the start to :attr:`point`.
    rows : int
        Rows ``(pose, output)`` of the linearised outputs (the poses that can decide).
    seconds : float
    sample : {'rays', 'machines'}
        What :attr:`machines` counts: rays (directional sampling, the ``constant``
        profile) or crude machines (the ``independent`` and ``gp`` profiles).
    """

    bound: float
    confidence: float
    yield_target: float
    point: np.ndarray
    point_cost: float
    point_yield: float
    multiplier: float
    point_estimate: float
    machines: int
    steps: int
    rows: int
    seconds: float
    sample: str = "rays"

    def text(self, reference_cost: float) -> str:
        """The bound relative to ``reference_cost``, in words."""
        lower = percentage_text(self.bound / reference_cost, bound="lower")
        return (f"lower bound {lower} of the initial cost at {self.confidence:.0%} "
                f"confidence (the yield is log-concave in the log-tolerances: linearised "
                f"outputs, normal reading, independent errors; tangent at an allocation of "
                f"{percentage_text(self.point_cost / reference_cost)} with yield "
                f"{self.point_yield:.4f} on {self.machines:,} {self.sample or 'rays'}, "
                f"{self.steps} "
                f"step{'' if self.steps == 1 else 's'} from the start; "
                f"{percentage_text(self.point_estimate / reference_cost)} with the estimates "
                f"themselves)")


def not_log_concave(machine, profile: str, distribution: str) -> str | None:
    """Why the theorem of the module docstring does not apply to ``machine`` under
    ``profile`` and ``distribution``; None when it does."""
    if distribution != "normal":
        return f"the reading is {distribution!r}, not 'normal'"
    if machine.correlation is not None:
        return ("the machine has an item correlation (it mixes errors of different "
                "tolerances, which no diagonal dilation of one convex set describes)")
    return None


def on_rays(machine, profile: str, distribution: str) -> bool:
    """Whether the yield's estimates here run on rays (directional sampling,
    :mod:`reliability.sampling.radial_yield`): the theorem applies and the profile is
    ``constant``, so a machine is one point of the errors' own space. Under the
    ``independent`` and ``gp`` profiles the estimates run on crude machines
    (:mod:`allocation.machine_yield.profile_bound`)."""
    return profile == "constant" and not_log_concave(machine, profile, distribution) is None


def linear_rows(model):
    """The linearised outputs' rows of ``model``'s machine: :func:`scaled_rows` at the
    deciding poses under the ``constant`` profile,
    :class:`allocation.machine_yield.profile_bound.BlockRows` under ``independent`` and
    ``gp``."""
    if model.profile == "constant":
        return scaled_rows(model.machine, model.deciding_poses)
    return profile_bound.BlockRows.of(model)


def linearised(model, u):
    """:func:`linear_rows` and the draws ``u`` of ``model``'s machines read for them
    (:func:`unit_draws`, or the blocks' coordinates)."""
    rows = linear_rows(model)
    if isinstance(rows, profile_bound.BlockRows):
        return rows, rows.standard(model, u)
    return rows, unit_draws(model, u)


def unit_draws(model, u) -> np.ndarray:
    """The standard normal of every error of each machine ``(N, n_errors)``, in the order
    of the tolerances, for a :class:`~reliability.sampling.machine_yield.YieldModel`'s
    draws ``u`` under the ``constant`` profile and the normal reading: the same machines
    the model judges, read for the linearised outputs."""
    motion, assembly = model.errors(u, np.full(len(model.machine.initial_allocation),
                                               model.k))
    return np.concatenate([motion[:, :, 0, :].reshape(len(u), -1),
                           assembly.reshape(len(u), -1)], axis=1)


def tangent_step(rows, weights, lower, upper, point, draws, yield_target) -> np.ndarray:
    """One step towards the optimum, on the rays of ``draws`` (standard normal, normalised to
    directions): the tangent problem's optimum at ``point`` (its yield and gradient estimated
    there by directional sampling,
    :func:`reliability.sampling.radial_yield.radial_gradient`), and the points a half, a
    quarter and an eighth of the way to it in ``log t`` and ``point`` itself, each rescaled to
    ``yield_target`` on the same rays; the cheapest of them. The tangent under-estimates
    ``−log Y`` (it is convex), so its optimum can overshoot; the shorter steps are the
    backtracking. With :class:`~allocation.machine_yield.profile_bound.BlockRows` (the
    ``independent`` and ``gp`` profiles) ``draws`` are crude machines
    (:func:`crude_tangent_step`)."""
    if isinstance(rows, profile_bound.BlockRows):
        return crude_tangent_step(rows, weights, lower, upper, point, draws, yield_target)
    theta = as_directions(draws)
    estimates = radial_gradient(rows, point, theta)
    _, _, moved = radial_tangent_bound(weights, lower, upper, point, *estimates,
                                       yield_target, robust=False)
    shift = np.log(moved / point)
    tried = [_at_yield(rows, point * np.exp(share * shift), theta, yield_target, lower,
                       upper) for share in STEP_SHARES]
    return min(tried, key=lambda t: float(np.sum(weights / t**2)))


def crude_tangent_step(rows, weights, lower, upper, point, draws, yield_target):
    """:func:`tangent_step` on crude machines ``draws``: the yield by the share passing,
    its gradient by :func:`yield_and_gradient`, each point rescaled by the quantile of the
    machines' worst row (:func:`_crude_at_yield`)."""
    estimates = yield_and_gradient(rows, point, draws)
    _, _, moved = tangent_bound(weights, lower, upper, point, *estimates, len(draws),
                                yield_target, robust=False)
    shift = np.log(moved / point)
    tried = [_crude_at_yield(rows, point * np.exp(share * shift), draws, yield_target,
                             lower, upper) for share in STEP_SHARES]
    return min(tried, key=lambda t: float(np.sum(weights / t**2)))


def scaled_rows(machine, poses) -> np.ndarray:
    """The linearised outputs' rows ``J_o(q) / (3 I_o)`` at ``poses``, one per (pose,
    output), rows that no error moves left out: a machine ``t ∘ z`` passes when every row
    times ``t ∘ z`` is within ±1."""
    jacobian = machine.jacobian(poses) / (K_SIGMA * np.asarray(machine.limits)[None, :, None])
    rows = jacobian.reshape(-1, jacobian.shape[-1])
    return rows[np.abs(rows).sum(axis=1) > 0]


def yield_and_gradient(rows, tolerances, draws):
    """Machines passing, and ``∂Y/∂log t_i`` with its standard error, on ``draws``.

    Parameters
    ----------
    rows : ndarray (R, n)
        :func:`scaled_rows`.
    tolerances : ndarray (n,)
    draws : ndarray (N, n)
        Standard normal draws, one row per machine.

    Returns
    -------
    passes : int
        Machines with every row within ±1.
    gradient, standard_error : ndarray (n,)
        Conditional Monte Carlo: for machine ``k`` and error ``i``, the values of ``z_i``
        with which the machine passes, its other draws held, form ``[l, r]`` (every row is
        affine in ``z_i``); ``P = Φ(r) − Φ(l)`` and, since ``l, r ∝ 1/t_i``,
        ``∂P/∂log t_i = l φ(l) − r φ(r)``; the gradient is their mean over machines.
    """
    if isinstance(rows, profile_bound.BlockRows):
        return profile_bound.yield_and_gradient(rows, tolerances, draws)
    draws = np.asarray(draws, dtype=float)
    machines, n = draws.shape
    block = max(1, BLOCK_FLOATS // len(rows))
    moves = rows != 0
    passes, total, squares = 0, np.zeros(n), np.zeros(n)
    for start in range(0, machines, block):
        z = draws[start:start + block]
        values = (z * tolerances) @ rows.T
        outside = np.abs(values) > 1.0
        passes += int(np.sum(~outside.any(axis=1)))
        # rows outside their band that error i does not move: the machine fails whatever z_i
        stuck = outside.sum(axis=1)[:, None] - outside.astype(float) @ moves
        with np.errstate(divide="ignore"):
            for i in range(n):
                slope = rows[:, i] * tolerances[i]
                centre = values * -np.divide(1.0, slope, where=moves[:, i],
                                             out=np.zeros(len(rows)))
                half = np.where(moves[:, i], 1.0 / np.abs(slope), np.inf)
                low = (centre - half).max(axis=1) + z[:, i]
                high = (centre + half).min(axis=1) + z[:, i]
                live = (stuck[:, i] == 0) & (high > low)
                low, high = np.where(live, low, 0.0), np.where(live, high, 0.0)
                change = low * norm.pdf(low) - high * norm.pdf(high)
                total[i] += change.sum()
                squares[i] += np.square(change).sum()
    mean = total / machines
    error = np.sqrt(np.maximum(squares / machines - mean**2, 0.0) / machines)
    return passes, mean, error


def _terms(weights, low, high, u0, slope):
    """Per error, ``min over [low, high] of w e^{−2u} + slope (u − u0)`` and its
    minimiser."""
    with np.errstate(divide="ignore"):
        stationary = -0.5 * np.log(np.maximum(slope, 1e-300) / (2.0 * weights))
    u = np.clip(np.where(slope > 0, stationary, high), low, high)
    return weights * np.exp(-2.0 * u) + slope * (u - u0), u


def tangent_bound(cost_weights, lower, upper, point, passes, gradient, error, machines,
                  yield_target, *, confidence=0.95, robust=True):
    """The bound of the module docstring at ``point`` from crude estimates there: ``passes``
    of ``machines`` and the gradient with its standard errors.

    Returns ``(bound, multiplier, minimiser)``: with ``robust`` the estimates are replaced
    by their ends at ``confidence`` (Clopper–Pearson for the yield, Bonferroni normal
    intervals for the gradient); the minimiser is the tangent problem's optimum at the
    point estimates (the next step's point).
    """
    alpha = 1.0 - confidence
    if passes == 0:
        raise InputError(f"tangent bound: no machine of {machines:,} passes at the point; "
                         f"start from an allocation whose yield is near the target")
    # α/2 for the yield's two-sided interval and α/(2n) for each gradient component's
    upper_yield = beta.ppf(1.0 - alpha / 4, passes + 1, machines - passes) \
        if passes < machines else 1.0
    lower_yield = beta.ppf(alpha / 4, passes, machines - passes + 1)
    return _bound(cost_weights, lower, upper, point, (passes / machines, lower_yield,
                                                      upper_yield),
                  gradient, error, yield_target, confidence, robust)


def radial_tangent_bound(cost_weights, lower, upper, point, value, value_error, gradient,
                         error, yield_target, *, confidence=0.95, robust=True):
    """:func:`tangent_bound` from the radial estimates
    (:func:`reliability.sampling.radial_yield.radial_gradient`): the yield's ends are
    ``value ± z·value_error`` (normal, at α/2 two-sided), clipped to (0, 1]."""
    if value <= 0.0:
        raise InputError(f"tangent bound: the yield estimate at the point is {value:g}; "
                         f"start from an allocation whose yield is near the target")
    z = norm.ppf(1.0 - (1.0 - confidence) / 4)
    ends = (max(value - z * value_error, 1e-300), min(value + z * value_error, 1.0))
    return _bound(cost_weights, lower, upper, point, (value, *ends), gradient, error,
                  yield_target, confidence, robust)


def _bound(cost_weights, lower, upper, point, yields, gradient, error, yield_target,
           confidence, robust):
    """The bound from the yield ``(estimate, lower end, upper end)`` and the gradient with
    its standard errors (module docstring; Bonferroni at α/(2n) per component)."""
    share, lower_yield, upper_yield = yields
    z = norm.ppf(1.0 - (1.0 - confidence) / (4.0 * len(point)))
    estimate = np.maximum(-gradient / share, 0.0)
    if robust:
        slopes = [np.maximum(-(gradient + z * error) / upper_yield, 0.0),
                  -(gradient - z * error) / lower_yield]
        h0 = -np.log(upper_yield)
    else:
        slopes, h0 = [estimate], -np.log(share)
    u0, low, high = np.log(point), np.log(lower), np.log(upper)
    margin = -np.log(yield_target) - h0

    def value(multiplier):
        terms = [_terms(cost_weights, low, high, u0, multiplier * g)[0] for g in slopes]
        return np.min(terms, axis=0).sum() - multiplier * margin

    scale = float(np.sum(cost_weights / point**2))
    found = minimize_scalar(lambda x: -value(np.exp(x)),
                            bounds=(np.log(scale * 1e-4), np.log(scale * 1e4)),
                            method="bounded", options={"xatol": 1e-6})
    multiplier = float(np.exp(found.x))
    _, minimiser = _terms(cost_weights, low, high, u0, multiplier * estimate)
    return float(value(multiplier)), multiplier, np.exp(minimiser)


@renamed("seed", "rng")
@one_blas_thread
def log_concave_bound(result, *, machines: int = 50_000, steps: int = 1,
                      confidence: float = 0.95, rng=0) -> YieldDualBound:
    """The lower bound of the module docstring for the yield of ``result``, with the
    tangent taken ``steps`` steps from ``result.tolerances``.

    Parameters
    ----------
    result : YieldAllocation
        :func:`allocation.allocate_for_yield`'s result: its problem (box, cost, grid),
        yield target and allocation (the start).
    machines : int
        Rays (directions, :mod:`reliability.sampling.radial_yield`) of each step's sample
        and of the bound's.
    steps : int
        Steps towards the tangent problem's optimum before the bound (0: at the start).
    confidence : float
        The bound holds with this probability over the bound's sample.
    rng : None, int or numpy.random.Generator
        Source of the samples (:func:`reliability.basics.streams.spawn`, one stream per step
        and the last for the bound). ``seed=`` is the deprecated spelling
        (:mod:`reliability.basics.renamed`).

    Raises
    ------
    InputError
        When the yield is not log-concave in the log-tolerances by the theorem used: a
        reading other than normal, or an item correlation (every profile along travel is
        taken: on rays under ``constant``, on crude machines under ``independent`` and
        ``gp`` through :mod:`allocation.machine_yield.profile_bound`).
    """
    started = time.perf_counter()
    machines = checks.positive_int(machines, "machines")
    steps = checks.positive_int(steps, "steps", minimum=0)
    confidence = checks.probability(confidence, "confidence")
    problem = result.search_problem
    machine = problem.machine
    why = not_log_concave(machine, result.profile, result.distribution)
    if why is not None:
        raise InputError(f"log_concave_bound: {why}; the yield is log-concave in the "
                         f"log-tolerances for independent normal errors, each one's draws "
                         f"along travel scaled by its tolerance alone")
    if result.profile != "constant":
        return crude_bound(problem, result.profile, result.points, result.yield_target,
                           result.tolerances, machines=machines, steps=steps,
                           confidence=confidence, rng=rng, started=started)
    return dual_bound(problem, result.points, result.yield_target, result.tolerances,
                      machines=machines, steps=steps, confidence=confidence, rng=rng,
                      started=started)


def dual_bound(problem, points, yield_target, start, *, machines, steps, confidence, rng,
               started=None, rescale_rays=0) -> YieldDualBound:
    """The bound of :func:`log_concave_bound` for ``problem`` (box, cost; its machine
    under ``constant`` and the normal reading) on the ``points``-point grid, the tangent
    ``steps`` steps from ``start``; the yield and its gradient by directional sampling
    (:func:`reliability.sampling.radial_yield.radial_gradient`) on ``machines`` rays of
    each stream of ``rng`` (one per step, the last for the bound). With ``rescale_rays``,
    the point is then rescaled to ``yield_target`` on that many rays of a stream of its own
    (the stream after the steps'; the bound's is the one after it): the bound is tight
    where the tangent is taken at the yield itself. The caller has checked that the
    theorem applies."""
    started = time.perf_counter() if started is None else started
    machine = problem.machine
    model = YieldModel(machine, profile="constant", points=points)
    rows = scaled_rows(machine, model.deciding_poses)
    weights = np.asarray(problem.cost.weights, dtype=float)
    lower, upper = np.asarray(problem.lower, float), np.asarray(problem.upper, float)
    samples = streams.spawn(rng, steps + 1 + bool(rescale_rays))
    point = np.asarray(start, dtype=float)
    for step in range(steps):
        draws = samples[step].standard_normal((machines, len(point)))
        point = tangent_step(rows, weights, lower, upper, point, draws, yield_target)
    if rescale_rays:
        draws = samples[steps].standard_normal((rescale_rays, len(point)))
        point = _at_yield(rows, point, draws, yield_target, lower, upper)
    theta = as_directions(samples[-1].standard_normal((machines, len(point))))
    estimates = radial_gradient(rows, point, theta)
    bound, multiplier, _ = radial_tangent_bound(weights, lower, upper, point, *estimates,
                                                yield_target, confidence=confidence)
    point_estimate, _, _ = radial_tangent_bound(weights, lower, upper, point, *estimates,
                                                yield_target, robust=False)
    return YieldDualBound(
        bound=bound, confidence=confidence, yield_target=yield_target, point=point,
        point_cost=float(problem.cost.total(point)), point_yield=estimates[0],
        multiplier=multiplier, point_estimate=point_estimate, machines=machines,
        steps=steps, rows=len(rows), seconds=time.perf_counter() - started)


def crude_bound(problem, profile, points, yield_target, start, *, machines, steps,
                confidence, rng, started=None) -> YieldDualBound:
    """:func:`dual_bound` on crude machines under ``profile`` (``independent`` or ``gp``:
    :class:`~allocation.machine_yield.profile_bound.BlockRows`), the yield by the share
    passing with its Clopper–Pearson ends and the gradient by conditional Monte Carlo along
    each error's block (:func:`allocation.machine_yield.profile_bound.yield_and_gradient`)."""
    started = time.perf_counter() if started is None else started
    model = YieldModel(problem.machine, profile=profile, distribution="normal", points=points)
    rows = linear_rows(model)
    weights = np.asarray(problem.cost.weights, dtype=float)
    lower, upper = np.asarray(problem.lower, float), np.asarray(problem.upper, float)
    samples = streams.spawn(rng, steps + 1)
    point = np.asarray(start, dtype=float)
    for step in range(steps):
        draws = samples[step].standard_normal((machines, rows.shape[1]))
        point = crude_tangent_step(rows, weights, lower, upper, point, draws, yield_target)
    draws = samples[steps].standard_normal((machines, rows.shape[1]))
    estimates = yield_and_gradient(rows, point, draws)
    bound, multiplier, _ = tangent_bound(weights, lower, upper, point, *estimates, machines,
                                         yield_target, confidence=confidence)
    point_estimate, _, _ = tangent_bound(weights, lower, upper, point, *estimates, machines,
                                         yield_target, robust=False)
    return YieldDualBound(
        bound=bound, confidence=confidence, yield_target=yield_target, point=point,
        point_cost=float(problem.cost.total(point)), point_yield=estimates[0] / machines,
        multiplier=multiplier, point_estimate=point_estimate, machines=machines,
        steps=steps, rows=len(rows), seconds=time.perf_counter() - started,
        sample="machines")


def _crude_at_yield(rows, tolerances, draws, yield_target, lower, upper) -> np.ndarray:
    """``tolerances`` times the factor at which the largest row ratio's ``yield_target``
    quantile on the crude machines ``draws`` is 1 (homogeneous of degree one), kept in the
    box; by bisection when tolerances held at their lower bounds keep that factor from
    reaching the yield (as :func:`_at_yield` does on rays)."""
    def judged(scale):
        worst = _worst_rows(rows, np.clip(scale * tolerances, lower, upper), draws)
        return None, worst, np.quantile(worst, yield_target)

    quantile = judged(1.0)[2]
    scaled = np.clip(tolerances / quantile, lower, upper)
    if np.mean(_worst_rows(rows, scaled, draws) <= 1.0) >= yield_target:
        return scaled
    found = bisected_scale(judged, 1.0 / quantile, float(np.min(lower / tolerances)))
    return np.asarray(lower, dtype=float) if found is None else \
        np.clip(found[0] * tolerances, lower, upper)


def _worst_rows(rows, tolerances, draws) -> np.ndarray:
    """Each crude machine's largest ``|row · (t ∘ z)|`` over the rows
    (:func:`reliability.sampling.radial_yield.worst_rows`)."""
    if isinstance(rows, profile_bound.BlockRows):
        rows, tolerances = rows.rows, rows.expanded(tolerances)
    return worst_rows(rows, tolerances, draws)[0]


def _at_yield(rows, tolerances, draws, yield_target, lower, upper) -> np.ndarray:
    """``tolerances`` times the factor at which their linearised yield on the rays of
    ``draws`` is ``yield_target`` (:meth:`~reliability.sampling.radial_yield.Rays.scale_at`,
    exact on the rays: the yield along a ray is homogeneous in the tolerances), kept in
    the box: fixed-point steps on the factor while tolerances held at a bound change the
    shape (:data:`RESCALES`, until within :data:`SLACK` below the yield's factor). When
    those held at their lower bounds stall the steps short of the yield, the largest factor
    that reaches it, by bisection (:func:`allocation.machine_yield.yield_shape.bisected_scale`,
    as :func:`~allocation.machine_yield.yield_shape.scaled_to_yield` does on the exact
    chain); the lower bounds themselves when not even they reach it."""
    theta = as_directions(draws)

    def judged(scale):
        t = np.clip(scale * tolerances, lower, upper)
        return t, None, 1.0 / rays(rows, t, theta).scale_at(yield_target)

    scale = 1.0
    for _ in range(RESCALES):
        t, _, quantile = judged(scale)
        if 1.0 - SLACK <= quantile <= 1.0 + 1e-9:
            return t
        following = scale * (1.0 - 0.5 * SLACK) / quantile
        if np.array_equal(np.clip(following * tolerances, lower, upper), t):
            break
        scale = following
    t, _, quantile = judged(scale)
    if quantile <= 1.0 + 1e-9:
        return t
    found = bisected_scale(judged, scale, float(np.min(lower / tolerances)))
    return np.asarray(lower, dtype=float) if found is None else found[1][0]
