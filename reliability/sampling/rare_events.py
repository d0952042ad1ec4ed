"""Rare failure probabilities at one pose: importance sampling and subset simulation.

Crude Monte-Carlo needs about ``(1 − p)/(p · CoV²)`` exact-model evaluations to estimate a
failure probability ``p`` to a coefficient of variation CoV: 10⁸ for p = 1e−6 at 10 %. The
two estimators here reach the same precision in thousands of evaluations by working in the
standard normal space of the errors, ``x_i = σ_i u_i`` with ``σ_i = t_i/k``.

* **Importance sampling** (``method='importance'``). For an output ``y_o`` with linear
  sensitivities ``a_o = J_o σ`` (the analytic Jacobian, scaled), the failure ``|y_o| ≥ I_o``
  has two design points ``u* = ±β_o a_o/|a_o|``, ``β_o = I_o/|a_o|`` (Eq. 21): the most
  likely failing errors of each tail. They are refined on the exact model by a Newton line
  search along ``a_o`` (the model's non-linearity is far below the limits, so the direction
  is kept). Samples come from a mixture of unit normals centred on the design points of the
  event (two for an output, twelve for the system event), weighted by each tail's linear
  probability Φ(−β); each sample carries the likelihood ratio ``φ(u)/h(u)``. The estimate is
  the mean of ``w · 1{failure}``, its CoV comes from the sample variance of those terms, and
  sampling continues in batches until the CoV reaches ``target_cov`` or the evaluation
  budget is spent. The estimator is unbiased whatever the centres; they only set its
  efficiency.
* **Subset simulation** (``method='subset'``, Au & Beck 2001). The failure event is reached
  through nested events ``r(u) > b_1 > … `` with conditional probability ``p0 = 0.1`` each;
  the conditional samples come from Markov chains (conditional sampling in standard normal
  space, ``u' = ρu + √(1 − ρ²) ξ``, accepted when it stays in the current event). The
  per-level CoV is ``δ_l² = (1 − p_l)/(p_l N) (1 + γ_l)`` with ``γ_l`` from the chains'
  estimated autocorrelation (Au & Beck 2001, Eqs. 27–29), so it accounts for the chains'
  correlation; the total CoV² is ``Σ δ_l²`` (levels treated as uncorrelated, as there).
* **Truncated inputs** (``distribution='truncated'``, normal truncated at ±t as in Sec. 5.3).
  The errors then live in a box, and the outputs are bounded. If the worst case over the box,
  ``Σ_i |∂y/∂x_i| t_i`` plus a rigorous bound on the model's non-linear remainder, stays
  inside every limit of the event, the probability is exactly 0 and the result says so
  (no sampling). Otherwise importance sampling runs with the truncated density as the
  target: design points are found inside the box and samples outside it carry weight 0.

``event`` is an output name (``'dx'`` … ``'ez'``, failure ``|y_o| ≥ I_o``) or ``'system'``
(some output outside its limit, the complement of "all six inside").
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from scipy.special import logsumexp
from scipy.stats import norm

from ..basics import checks, streams
from ..basics.display import lower_bound_text, pose_text, shown_positions, upper_bound_text
from ..basics.errors import InputError, InputTypeError
from ..basics.pass_rule import passes
from ..basics.saved_fields import (Array, Flag, Integer, Number, Records, Text, load_fields,
                                   save_fields)
from ..first_order.fosm import two_sided_probability
from ..first_order.worst_grid_pose import EVENTS, worst_grid_poses
from ..model.error_draws import DISTRIBUTIONS
from ..model.kinematics import chain_factors, transports
from ..model.machine import OUTPUTS, Axis

METHODS = ("importance", "subset")
P0 = 0.1  # conditional probability of each subset level (Au & Beck 2001)
CHAIN_CORRELATION = 0.8  # ρ of conditional sampling; a common heuristic choice
MIN_SUBSET_LEVEL = 500  # samples per subset level below which the CoV estimate is unreliable


@dataclass(frozen=True)
class RareEventResult:
    """A failure probability at one pose with its own precision.

    Attributes
    ----------
    event : str
        Output name or ``'system'``.
    method : str
        ``'importance'``, ``'subset'`` or ``'exact-zero'`` (truncated inputs that cannot
        reach the limit).
    distribution : str
    axes : tuple of Axis
        The machine's axes (names and kinds, for units).
    pose : ndarray (n_axes,)
    probability : float
        Estimated failure probability.
    cov : float
        Estimated coefficient of variation of ``probability`` (0 for an exact zero, NaN when
        no failure was sampled).
    interval : (float, float)
        Confidence interval at ``confidence``: ``p ± z·p·cov`` (lower bound floored at 0)
        for importance sampling, ``p·exp(±z·cov)`` for subset simulation; (0, 0) for an
        exact zero.
    confidence : float
    n_evaluations : int
        Exact-model evaluations made (design-point search included).
    target_cov : float
    reached : bool
        Whether ``cov <= target_cov``.
    fosm_probability : float
        The linear-Gaussian answer for comparison: two-sided FOSM failure probability of the
        output, for ``'system'`` the union bound Σ_o (an upper bound). For truncated inputs
        it uses the untruncated σ = t/k and is only indicative.
    note : str
        What the estimate rests on (e.g. the worst-case stack for an exact zero).
    """

    event: str
    method: str
    distribution: str
    axes: tuple = field(repr=False)
    pose: np.ndarray
    probability: float
    cov: float
    interval: tuple
    confidence: float
    n_evaluations: int
    target_cov: float
    reached: bool
    fosm_probability: float
    note: str = ""

    @property
    def reliability(self) -> float:
        """``1 − probability``."""
        return 1.0 - self.probability

    def to_frame(self) -> pd.DataFrame:
        """One row: the pose as axis positions (``X (mm)``, ``A (deg)``), the estimate, its
        CoV and interval."""
        units = ["mm" if axis.kind == "linear" else "rad" for axis in self.axes]
        shown, shown_units = shown_positions(self.pose, units)
        row = {f"{axis.name} ({unit})": value
               for axis, value, unit in zip(self.axes, shown, shown_units)}
        row.update(event=self.event, method=self.method, distribution=self.distribution,
                   probability=self.probability, cov=self.cov, lower=self.interval[0],
                   upper=self.interval[1], n_evaluations=self.n_evaluations,
                   reached=self.reached, fosm_probability=self.fosm_probability)
        return pd.DataFrame([row])

    def summary(self) -> str:
        """A few readable lines."""
        pose = pose_text(self.pose, [a.name for a in self.axes],
                         ["mm" if a.kind == "linear" else "rad" for a in self.axes])
        level = f"{100 * self.confidence:.0f} %"
        if self.method == "exact-zero":
            body = f"failure probability exactly 0 ({self.note})"
        else:
            body = (f"failure probability {self.probability:.3e} (CoV {self.cov:.3f}, "
                    f"{level} interval [{lower_bound_text(self.interval[0], 4)}, "
                    f"{upper_bound_text(self.interval[1], 4)}]), "
                    f"{self.n_evaluations} exact-model evaluations, target CoV "
                    f"{self.target_cov:g} {'reached' if self.reached else 'NOT reached'}")
        return (f"{self.event} at pose ({pose}), {self.distribution} inputs, {self.method}: "
                f"{body}; linear FOSM {self.fosm_probability:.3e}")

    def __str__(self) -> str:
        return self.summary()

    def save(self, path, overwrite: bool = False):
        """Save as JSON (:data:`SAVED_FIELDS`, tag :data:`SAVED_FORMAT`; the axes with all
        their fields); an existing file is kept unless ``overwrite``. Returns the path."""
        return save_fields(self, path, SAVED_FORMAT, SAVED_FIELDS, overwrite)

    @classmethod
    def load(cls, path) -> "RareEventResult":
        """Reload a result written by :meth:`save`, every field checked: the interval
        holds the probability and ``reached`` is ``cov <= target_cov``, so the verdicts are
        the saved ones. A damaged field raises
        :class:`~reliability.basics.errors.SavedResultError` naming the file and field."""
        data, values = load_fields(path, SAVED_FORMAT, SAVED_FIELDS)
        if len(values["pose"]) != len(values["axes"]):
            raise data.error("pose", "expected one position per axis")
        low, high = values["interval"]
        if not low <= values["probability"] <= high:
            raise data.error("interval", "does not hold the probability")
        values["interval"] = (float(low), float(high))
        return cls(**values)


def saved_axis(stroke, offset, **fields) -> Axis:
    """An axis from its saved fields (stroke and offset saved as lists)."""
    return Axis(stroke=tuple(float(v) for v in stroke), offset=tuple(float(v) for v in offset),
                **fields)


AXIS_FIELDS = (Text("name"), Text("kind", ("linear", "rotary")),
               Text("direction", ("x", "y", "z")), Array("stroke", (2,)),
               Number("size", positive=True), Flag("full_turn"), Array("offset", (3,)),
               Number("repeatability", low=0.0), Number("reversal", low=0.0))
SAVED_FORMAT = "precrel.rare_event"
SAVED_FIELDS = (Text("event", EVENTS), Text("method", ("importance", "subset", "exact-zero")),
                Text("distribution", ("normal", "truncated")),
                Records("axes", AXIS_FIELDS, saved_axis),
                Array("pose", (None,)), Number("probability", low=0.0, high=1.0),
                Number("cov", finite=False), Array("interval", (2,), low=0.0),
                Number("confidence", low=0.0, high=1.0), Integer("n_evaluations", low=0),
                Number("target_cov", positive=True), Flag("reached"),
                Number("fosm_probability", low=0.0, high=1.0), Text("note"))


def linear_model(jacobian):
    """The linearised model ``x ↦ J x`` at one pose, as a ``model=`` for the estimators.

    Parameters
    ----------
    jacobian : array_like
        ``(6, n_errors)`` sensitivities, e.g. ``machine.jacobian(pose)``.
    """
    jacobian = np.asarray(jacobian, dtype=float)
    return lambda x: x @ jacobian.T


def failure_probability(machine, tolerances, pose=None, *, event: str = "dx",
                        method: str = "importance", target_cov: float = 0.1,
                        max_evaluations: int = 20_000, k: float = 3.0,
                        distribution: str = "normal", rng=None, confidence: float = 0.95,
                        batch: int = 500, model=None, jacobian=None) -> RareEventResult:
    """Probability that ``event`` fails at ``pose``, estimated on the exact model.

    Parameters
    ----------
    machine : Machine
    tolerances : array_like
        ``(n_errors,)`` allocation, read as ±kσ.
    pose : array_like, optional
        ``(n_axes,)`` positions. Default: the event's worst pose on the 5-point workspace
        grid under the reading ``distribution`` (:func:`worst_grid_pose`).
    event : str
        Output name or ``'system'``.
    method : {'importance', 'subset'}
    target_cov : float
        Stop once the estimated CoV is at most this (importance sampling), or size the
        subset levels to reach it within the budget.
    max_evaluations : int
        Budget of exact-model evaluations.
    k : float
        Coverage factor: σ = t/k.
    distribution : {'normal', 'truncated'}
        Untruncated normal errors, or normal truncated at ±t (importance sampling only; the
        exact-zero check bounds the machine's own chain, see :func:`worst_case_bound`).
    rng : None, int or numpy.random.Generator
    confidence : float
        Level of the reported interval.
    batch : int
        Importance samples drawn per step.
    model : callable, optional
        ``x (m, n_errors) -> y (m, 6)`` replacing the exact model at the pose, e.g.
        :func:`linear_model` for checks against closed forms.
    jacobian : array_like, optional
        ``(6, n_errors)`` sensitivities used for the design points instead of
        ``machine.jacobian(pose)`` (to pair with a ``model`` of other sensitivities).

    Returns
    -------
    RareEventResult
    """
    checks.independent_errors(machine, "failure_probability")
    t = machine.check_tolerances(tolerances)
    _check_options(event, method, target_cov, max_evaluations, k, distribution, confidence,
                   batch, model, t)
    rng = streams.generator(rng)
    pose = worst_grid_pose(machine, t, event, k=k, distribution=distribution) if pose is None \
        else _check_pose(machine, pose)
    jacobian = machine.jacobian(pose) if jacobian is None else _check_jacobian(machine,
                                                                               jacobian)
    counter = _CountingModel(model or (lambda x: machine.comprehensive_error(pose, x)))
    problem = _Problem(t / k, jacobian, machine.limits, _event_outputs(event), counter)
    common = dict(event=event, distribution=distribution, axes=machine.axis_specs, pose=pose,
                  confidence=confidence, target_cov=float(target_cov),
                  fosm_probability=problem.fosm_probability())
    if distribution == "truncated":
        stack = worst_case_bound(machine, t, pose, jacobian)
        outputs = problem.outputs
        if np.all(passes(stack[outputs], machine.limits[outputs])):
            note = ("worst-case stack Σ|∂y/∂x|·t plus the non-linear remainder bound "
                    f"{_ratio_text(stack, machine.limits, outputs)} of the limit")
            return RareEventResult(method="exact-zero", probability=0.0, cov=0.0,
                                   interval=(0.0, 0.0), n_evaluations=0, reached=True,
                                   note=note, **common)
        problem.drop_outputs(passes(stack, machine.limits))
        p, cov = _importance(problem, rng, target_cov, max_evaluations, batch, k)
    elif method == "importance":
        p, cov = _importance(problem, rng, target_cov, max_evaluations, batch, None)
    else:
        p, cov = _subset(problem, rng, target_cov, max_evaluations)
    z = norm.ppf(0.5 + confidence / 2)
    if method == "subset" and distribution == "normal":
        interval = (p * np.exp(-z * cov), p * np.exp(z * cov))
    else:
        interval = (max(p - z * p * cov, 0.0), p + z * p * cov)
    note = "" if p > 0 else "no failing sample: the estimate does not bound the probability"
    return RareEventResult(method=method, probability=float(p), cov=float(cov),
                           interval=tuple(float(b) for b in interval),
                           n_evaluations=counter.count,
                           reached=bool(np.isfinite(cov) and cov <= target_cov), note=note,
                           **common)


# ----- the problem in standard normal space ----------------------------------------------
class _CountingModel:
    """Wraps a model ``x -> y`` and counts the rows it evaluates."""

    def __init__(self, model):
        self.model, self.count = model, 0

    def __call__(self, x):
        self.count += len(x)
        return np.asarray(self.model(x), dtype=float)


class _Problem:
    """The event in standard normal space: ``x = σ ⊙ u``, response ``r(u) = max |y_o|/I_o``
    over the event's outputs; failure is ``r ≥ 1``, where some output misses its limit
    (``passes(r, 1)`` reads the pass rule on the scaled outputs)."""

    def __init__(self, sigma, jacobian, limits, outputs, model):
        self.sigma, self.limits, self.model = sigma, np.asarray(limits), model
        self.outputs = np.asarray(outputs)
        self.a = jacobian * sigma  # ∂y/∂u, (6, n)
        self.beta = self.limits / np.linalg.norm(self.a, axis=1)  # Eq. (21) at zero mean

    @property
    def dimension(self) -> int:
        return self.a.shape[1]

    def drop_outputs(self, impossible) -> None:
        """Forget outputs that provably cannot fail (their tails get no design points)."""
        self.outputs = self.outputs[~np.asarray(impossible)[self.outputs]]

    def response(self, u) -> np.ndarray:
        y = self.model(u * self.sigma)
        return np.max(np.abs(y[:, self.outputs]) / self.limits[self.outputs], axis=1)

    def fosm_probability(self) -> float:
        tails = two_sided_probability(self.limits, self.limits / self.beta)
        return float(np.sum(1.0 - tails[self.outputs]))

    def design_points(self, k=None):
        """Design points ``(m, n)`` of both tails of every output and their log Φ(−β).

        Normal inputs: ``±β a/|a|`` refined on the model by Newton steps along ``a``.
        Truncated (``k`` given): the point of least ``|u|`` on ``a·u = I`` inside the box
        ``|u_i| ≤ k`` (linear model; the box corner when the plane lies beyond it).
        """
        signs = np.tile([1.0, -1.0], len(self.outputs))
        a = np.repeat(self.a[self.outputs], 2, axis=0) * signs[:, None]
        limits = np.repeat(self.limits[self.outputs], 2)
        rows = np.repeat(self.outputs, 2)
        if k is not None:
            points = _box_design_points(a, limits, k)
            beta = np.linalg.norm(points, axis=1)
            return points, norm.logcdf(-beta)
        direction = a / np.linalg.norm(a, axis=1, keepdims=True)
        length = limits / np.linalg.norm(a, axis=1)
        slope = np.linalg.norm(a, axis=1)  # d(a·u)/dλ along the direction
        for _ in range(2):  # Newton on s·y_o(λ d) = I_o
            y = self.model(length[:, None] * direction * self.sigma)[np.arange(len(rows)), rows]
            length = length - (signs * y - limits) / slope
        return length[:, None] * direction, norm.logcdf(-length)


def _box_design_points(a, limits, k, steps: int = 80) -> np.ndarray:
    """Least-norm ``u`` with ``a·u = I`` and ``|u_i| ≤ k``: ``u = clip(λa, −k, k)`` (KKT of
    the separable problem), ``λ`` by bisection; the corner ``k·sign(a)`` if out of reach."""
    low = np.zeros(len(a))
    high = np.full(len(a), 1.0)
    reach = lambda lam: np.sum(a * np.clip(lam[:, None] * a, -k, k), axis=1)  # noqa: E731
    corner = k * np.sum(np.abs(a), axis=1)
    for _ in range(200):  # doubling until the plane is reached (λ up to 2^200)
        short = (reach(high) < limits) & (corner >= limits)
        if not np.any(short):
            break
        high = np.where(short, 2 * high, high)
    for _ in range(steps):
        middle = 0.5 * (low + high)
        below = reach(middle) < limits
        low, high = np.where(below, middle, low), np.where(below, high, middle)
    points = np.clip(high[:, None] * a, -k, k)
    return np.where((corner < limits)[:, None], k * np.sign(a), points)


# ----- importance sampling ----------------------------------------------------------------
def _importance(problem, rng, target_cov, budget, batch, k):
    """Mixture importance sampling; returns (estimate, CoV). ``k`` truncates the target."""
    centres, log_mass = problem.design_points(k)
    log_mix = log_mass - logsumexp(log_mass)
    n_dim = problem.dimension
    log_box = 0.0 if k is None else -n_dim * np.log(2 * norm.cdf(k) - 1)
    count, mean, m2 = 0, 0.0, 0.0
    while problem.model.count < budget:
        size = min(batch, budget - problem.model.count)
        pick = rng.choice(len(centres), size=size, p=np.exp(log_mix))
        u = centres[pick] + rng.standard_normal((size, n_dim))
        log_h = logsumexp(log_mix + u @ centres.T - 0.5 * np.sum(centres ** 2, axis=1),
                          axis=1)  # log h(u) − log φ(u)
        log_w = log_box - log_h
        inside = np.ones(size, bool) if k is None else np.all(np.abs(u) <= k, axis=1)
        values = np.zeros(size)
        fails = np.zeros(size, bool)
        fails[inside] = ~passes(problem.response(u[inside]), 1.0)
        values[fails] = np.exp(log_w[fails])
        count, mean, m2 = _merge(count, mean, m2, values)
        cov = np.sqrt(m2 / (count - 1) / count) / mean if mean > 0 else np.inf
        if cov <= target_cov:
            break
    if count < 2:
        return np.nan, np.nan
    return mean, (np.sqrt(m2 / (count - 1) / count) / mean if mean > 0 else np.nan)


def _merge(count, mean, m2, values):
    """Chan et al.'s parallel update of a running mean and sum of squared deviations."""
    n = len(values)
    batch_mean = values.mean()
    batch_m2 = np.sum((values - batch_mean) ** 2)
    total = count + n
    delta = batch_mean - mean
    return total, mean + delta * n / total, m2 + batch_m2 + delta ** 2 * count * n / total


# ----- subset simulation ------------------------------------------------------------------
def _subset(problem, rng, target_cov, budget):
    """Subset simulation with conditional sampling; returns (estimate, CoV)."""
    per_level = _level_size(problem, target_cov, budget)
    seeds_per_level = int(round(per_level * P0))
    chain_length = per_level // seeds_per_level
    u = rng.standard_normal((per_level, problem.dimension))
    r = problem.response(u)
    chains = None  # level 0 samples are independent
    probability, cov2 = 1.0, 0.0
    while True:
        order = np.argsort(r)[::-1]
        threshold = 0.5 * (r[order[seeds_per_level - 1]] + r[order[seeds_per_level]])
        next_cost = per_level - seeds_per_level
        if threshold >= 1.0 or problem.model.count + next_cost > budget:
            hit = ~passes(r, 1.0)
            p_level = hit.mean()
            probability *= p_level
            if p_level == 0:
                return 0.0, np.nan
            cov2 += _level_cov2(p_level, hit, chains, per_level)
            return probability, np.sqrt(cov2)
        probability *= P0
        cov2 += _level_cov2(P0, r > threshold, chains, per_level)
        seeds = order[:seeds_per_level]
        u, r = _run_chains(problem, u[seeds], r[seeds], threshold, chain_length, rng)
        chains = (chain_length, seeds_per_level)


def _level_size(problem, target_cov, budget) -> int:
    """Samples per level: enough for ``target_cov`` with γ ≈ 3, within the budget.

    The number of levels is predicted from the linear answer; samples per level are a
    multiple of ``1/p0``.
    """
    levels = max(1, int(np.ceil(np.log(max(problem.fosm_probability(), 1e-300))
                                / np.log(P0))))
    wanted = levels * (1 - P0) / P0 * (1 + 3.0) / target_cov ** 2
    affordable = budget / (1 + (levels - 1) * (1 - P0) + 1)
    size = int(min(wanted, affordable) // (1 / P0) * (1 / P0))
    return max(size, MIN_SUBSET_LEVEL)


def _run_chains(problem, u, r, threshold, length, rng):
    """Advance all chains ``length − 1`` steps; return states in order (step, chain).

    Conditional sampling: ``u' = ρu + √(1 − ρ²) ξ`` leaves the standard normal invariant,
    and a candidate is accepted when it stays above the current threshold.
    """
    rho = CHAIN_CORRELATION
    states_u, states_r = [u], [r]
    for _ in range(length - 1):
        candidate = rho * u + np.sqrt(1 - rho ** 2) * rng.standard_normal(u.shape)
        candidate_r = problem.response(candidate)
        accept = candidate_r > threshold
        u = np.where(accept[:, None], candidate, u)
        r = np.where(accept, candidate_r, r)
        states_u.append(u)
        states_r.append(r)
    return np.concatenate(states_u), np.concatenate(states_r)


def _level_cov2(p, indicator, chains, n) -> float:
    """δ_l² = (1 − p)/(p N) (1 + γ) (Au & Beck 2001, Eqs. 27–29); γ = 0 for level 0."""
    gamma = 0.0 if chains is None else _gamma(indicator.reshape(chains), p)
    return (1 - p) / (p * n) * (1 + gamma)


def _gamma(indicator, p) -> float:
    """γ = 2 Σ_k (1 − k/N_s) ρ(k) from the chains' indicator autocovariance.

    ``indicator`` is ``(N_s, N_c)``: chain step by chain.
    """
    steps, chains = indicator.shape
    x = indicator.astype(float)
    variance = p * (1 - p)
    if variance <= 0:
        return 0.0
    gamma = 0.0
    for lag in range(1, steps):  # Au & Beck 2001, Eq. (29)
        covariance = np.sum(x[:-lag] * x[lag:]) / ((steps - lag) * chains) - p ** 2
        gamma += 2 * (1 - lag / steps) * covariance / variance
    return gamma


# ----- truncated inputs: the worst case over the box --------------------------------------
def worst_case_bound(machine, tolerances, pose, jacobian=None) -> np.ndarray:
    """Largest ``|y_o|`` any errors with ``|x_i| ≤ t_i`` can give at ``pose``, bounded above.

    The first-order stack ``Σ_i |∂y_o/∂x_i| t_i`` plus a rigorous bound on the remainder
    of the exact chain product. With every error moved to the tool frame, the chain is
    ``Π_k [[I + ω_k×, v_k], [0, 1]]`` (see :mod:`reliability.model.kinematics`); its translation
    is ``Σ_k Π_{j<k}(I + ω_j×) v_k`` and its rotation ``Π_k (I + ω_k×)``, so beyond first
    order the translation moves by at most ``Σ_k (Π_{j<k}(1 + |ω_j|) − 1)|v_k|`` and each
    angle by at most ``Π_k(1 + |ω_k|) − 1 − Σ_k|ω_k|``, with ``|ω_k|``, ``|v_k|`` bounded
    over the box through the transports.

    Returns
    -------
    numpy.ndarray
        ``(6,)`` upper bounds on ``|δx| … |εz|`` over the tolerance box.
    """
    t = np.asarray(tolerances, dtype=float)
    pose = np.asarray(pose, dtype=float)
    jacobian = machine.jacobian(pose) if jacobian is None else jacobian
    stack = np.abs(jacobian) @ t
    factors, blocks = chain_factors(machine, pose)
    bounds = np.array([np.abs(adjoint) @ t[6 * b: 6 * b + 6]
                       for b, adjoint in zip(blocks, transports(factors))])
    v = np.linalg.norm(bounds[:, :3], axis=1)
    w = np.linalg.norm(bounds[:, 3:], axis=1)
    before = np.concatenate([[1.0], np.cumprod(1 + w)[:-1]])  # Π_{j<k}(1 + |ω_j|)
    translation = np.sum((before - 1) * v)
    rotation = np.prod(1 + w) - 1 - np.sum(w)
    return stack + np.repeat([translation, rotation], 3)


def worst_grid_pose(machine, tolerances, event: str = "dx", *, points: int = 5,
                    k: float = 3.0, distribution: str | None = None) -> np.ndarray:
    """The workspace-grid pose where ``event`` is most likely to fail, ``(n_axes,)``: the
    one row of :func:`reliability.first_order.worst_grid_pose.worst_grid_poses` for
    ``(event,)`` (``distribution`` None reads the tolerances as the machine does)."""
    return worst_grid_poses(machine, tolerances, (event,), points=points, k=k,
                            distribution=distribution)[0]


# ----- input checks -----------------------------------------------------------------------
def _event_outputs(event):
    return np.arange(len(OUTPUTS)) if event == "system" else np.array([OUTPUTS.index(event)])


def _ratio_text(stack, limits, outputs) -> str:
    worst = max(outputs, key=lambda o: stack[o] / limits[o])
    return f"reach at most {100 * stack[worst] / limits[worst]:.1f} % ({OUTPUTS[worst]})"


def _check_options(event, method, target_cov, max_evaluations, k, distribution, confidence,
                   batch, model, t):
    if t.ndim != 1:
        raise InputError(f"tolerances must be one allocation of shape ({t.shape[-1]},); "
                         f"got {t.shape}")
    if event not in EVENTS:
        raise InputError(f"event must be one of {EVENTS}; got {event!r}")
    if method not in METHODS:
        raise InputError(f"method must be one of {METHODS}; got {method!r}")
    if distribution not in DISTRIBUTIONS:
        raise InputError(f"distribution must be one of {DISTRIBUTIONS}; got {distribution!r}")
    if distribution == "truncated" and method != "importance":
        raise InputError("method: subset simulation is offered for distribution='normal'; "
                         "use method='importance' for truncated inputs")
    for name, value in (("target_cov", target_cov), ("k", k)):
        if isinstance(value, bool) or not isinstance(value, (int, float, np.floating)):
            raise InputTypeError(f"{name} must be a number; got {value!r}")
        if not (np.isfinite(value) and value > 0):
            raise InputError(f"{name} must be finite and > 0; got {value!r}")
    if not 0 < confidence < 1:
        raise InputError(f"confidence must lie in (0, 1); got {confidence!r}")
    for name, value in (("max_evaluations", max_evaluations), ("batch", batch)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
            raise InputError(f"{name} must be a positive integer; got {value!r}")
    if model is not None and not callable(model):
        raise InputTypeError(f"model must be callable x -> y; got {type(model).__name__}")


def _check_pose(machine, pose) -> np.ndarray:
    pose = np.asarray(machine.check_positions(pose), dtype=float)
    if pose.shape != (len(machine.axes),):
        raise InputError(f"pose must be one pose of shape ({len(machine.axes)},) for axes "
                         f"{machine.axes}; got {pose.shape}")
    return pose


def _check_jacobian(machine, jacobian) -> np.ndarray:
    jacobian = np.asarray(jacobian, dtype=float)
    if jacobian.shape != (len(OUTPUTS), machine.n_errors):
        raise InputError(f"jacobian must have shape (6, {machine.n_errors}); "
                         f"got {jacobian.shape}")
    return jacobian
