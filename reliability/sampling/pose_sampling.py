"""Crude Monte-Carlo on the exact model at given poses, with optional adaptive stopping.

The allocation promises a reliability at every pose; this module checks the promise where
it is tightest. At each pose, independent error vectors are drawn (normal with σ = t/k, or
truncated at ±t as in Sec. 5.3) and the exact comprehensive error (Eq. 18) is evaluated.
Every draw is an independent Bernoulli trial of each event, so the failure counts are
binomial and a binomial interval applies (:func:`reliability.basics.statistics.proportion`): the
Wilson score interval by default, Clopper–Pearson on request.

Events: each output failing, ``|y_o| ≥ I_o`` (the complement of Eq. 19), and the system
event, some output failing (the complement of "all six inside").

By default the poses are each output's worst pose on the 5-point workspace grid (FOSM,
largest σ); output ``o`` is then tracked at its own worst pose and the system event at all
of them. With explicit poses every event is tracked at every pose; ``events`` narrows the
selection.

Adaptive stopping (``precision`` given): samples are drawn in batches until every tracked
event's interval has a relative half-width ``(upper − lower)/(2 p̂)`` on the failure
probability at most ``precision``, or ``max_samples`` is reached. Checking after every batch
is a sequential procedure, so the coverage of the final interval is not exactly the fixed-n
Wilson coverage; it is measured by repetition in the tests (close to nominal).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy.stats import multivariate_normal

from ..basics import checks, streams
from ..basics.display import lower_bound_text, shown_positions, upper_bound_text
from ..basics.errors import InputError, InputTypeError
from ..basics.pass_rule import passes
from ..basics.saved_fields import (Array, Flag, Integer, Number, Text, Texts, load_fields,
                                   save_fields)
from ..basics.statistics import proportion
from ..first_order.fosm import (error_sigma, one_sided_probability, output_sigma,
                                two_sided_probability)
from ..first_order.worst_grid_pose import EVENTS, worst_grid_poses
from ..model.error_draws import check_reading, correlation_factor, draw_correlated, draw_errors
from ..model.machine import OUTPUTS
from ..model.poses import random_poses
from .experiment_results import RandomPoseResult

_INTERVAL_NAMES = {"wilson": "Wilson", "clopper-pearson": "Clopper–Pearson"}
INTERVALS = ("wilson", "clopper-pearson")


@dataclass(frozen=True)
class PoseSamplingResult:
    """Failure counts at a set of poses, with binomial intervals and the FOSM answer.

    Attributes
    ----------
    axes : tuple of str
        Axis names with the units positions are shown in, e.g. ``'X (mm)'``, ``'A (deg)'``.
    poses : ndarray (n_poses, n_axes)
        Positions in the model's units (mm, rad); :meth:`to_frame` shows rotary ones in
        degrees.
    labels : tuple of str
        One label per pose (``'worst dx'`` … or ``'pose 0'`` …).
    tracked : ndarray (n_poses, 7) of bool
        Which (pose, event) pairs are reported and drive adaptive stopping; events are
        ``dx dy dz ex ey ez system``.
    failures : ndarray (n_poses, 7) of int
    n_samples : int
        Samples drawn at every pose.
    fosm_failure : ndarray (n_poses, 7)
        Linear-Gaussian failure probability: two-sided FOSM per output, and for the system
        event ``1 − P(all six inside)`` from the six-dimensional normal rectangle. σ is that
        of the drawn distribution.
    confidence : float
    precision : float or None
        Requested relative half-width, or None for a fixed sample count.
    reached : bool or None
        Whether every tracked event reached ``precision`` (None without one).
    distribution : str
    k : float
    interval : {'wilson', 'clopper-pearson'}
        The binomial interval used.
    """

    axes: tuple
    poses: np.ndarray
    labels: tuple
    tracked: np.ndarray
    failures: np.ndarray
    n_samples: int
    fosm_failure: np.ndarray
    confidence: float
    precision: float | None
    reached: bool | None
    distribution: str
    k: float
    interval: str = "wilson"

    @property
    def estimate(self):
        """Failure-probability estimates with the chosen binomial intervals, ``(n_poses, 7)``."""
        return proportion(self.failures, self.n_samples, self.confidence, self.interval)

    def relative_half_width(self) -> np.ndarray:
        """``(upper − lower)/(2 p̂)`` per (pose, event); inf where no failure was seen."""
        est = self.estimate
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(self.failures > 0,
                            (est.upper - est.lower) / (2 * np.asarray(est.estimate)), np.inf)

    def to_frame(self) -> pd.DataFrame:
        """One row per tracked (pose, event): pose positions, MC failure probability and
        interval, FOSM failure probability, reliability."""
        est = self.estimate
        pose_index, event_index = np.nonzero(self.tracked)
        frame = pd.DataFrame({"pose": np.asarray(self.labels)[pose_index],
                              "event": np.asarray(EVENTS)[event_index]})
        shown, _ = shown_positions(self.poses[pose_index],
                                   ["rad" if a.endswith("(deg)") else "mm" for a in self.axes])
        for a, axis in enumerate(self.axes):
            frame[axis] = shown[:, a]
        frame["samples"] = self.n_samples
        frame["failures"] = self.failures[pose_index, event_index]
        frame["mc_failure"] = np.asarray(est.estimate)[pose_index, event_index]
        frame["lower"] = np.asarray(est.lower)[pose_index, event_index]
        frame["upper"] = np.asarray(est.upper)[pose_index, event_index]
        frame["fosm_failure"] = self.fosm_failure[pose_index, event_index]
        frame["relative_half_width"] = self.relative_half_width()[pose_index, event_index]
        frame["mc_reliability"] = 1.0 - frame["mc_failure"]
        frame["fosm_reliability"] = 1.0 - frame["fosm_failure"]
        return frame

    def summary(self) -> str:
        """A readable table with the stopping outcome."""
        head = (f"Monte-Carlo at {len(self.poses)} poses, {self.n_samples} exact-model samples "
                f"per pose, {self.distribution} errors (t = ±{self.k:g}σ); "
                f"{100 * self.confidence:.0f} % {_INTERVAL_NAMES[self.interval]} intervals on the "
                f"failure probability.")
        if self.precision is not None:
            head += (f" Relative half-width target {self.precision:g}: "
                     f"{'reached' if self.reached else 'NOT reached (sample cap)'}.")
        columns = ["pose", "event", *self.axes, "failures",
                   "mc_failure", "lower", "upper", "fosm_failure"]
        frame = self.to_frame()[columns]
        frame = frame.assign(lower=[lower_bound_text(v, 4) for v in frame["lower"]],
                             upper=[upper_bound_text(v, 4) for v in frame["upper"]])
        return head + "\n" + frame.to_string(index=False, float_format="{:.4g}".format)

    def __str__(self) -> str:
        return self.summary()

    def save(self, path, overwrite: bool = False):
        """Save the counts and the FOSM answer as JSON (:data:`SAVED_FIELDS`, tag
        :data:`SAVED_FORMAT`); an existing file is kept unless ``overwrite``. Returns the
        path."""
        return save_fields(self, path, SAVED_FORMAT, SAVED_FIELDS, overwrite)

    @classmethod
    def load(cls, path) -> "PoseSamplingResult":
        """Reload a result written by :meth:`save`, every field checked (counts within
        the sample count); the intervals are computed again from the saved counts, so they
        are the saved result's. A damaged field raises
        :class:`~reliability.basics.errors.SavedResultError` naming the file and field."""
        data, values = load_fields(path, SAVED_FORMAT, SAVED_FIELDS)
        if np.any(values["failures"] > values["n_samples"]):
            raise data.error("failures", "counts exceed 'n_samples'")
        if (values["precision"] is None) != (values["reached"] is None):
            raise data.error("reached", "must be null exactly when 'precision' is")
        return cls(**values)


SAVED_FORMAT = "precrel.pose_sampling"
SAVED_FIELDS = (Texts("axes", "axes"), Array("poses", ("n", "axes")),
                Texts("labels", "n"), Array("tracked", ("n", len(EVENTS)), dtype=bool),
                Array("failures", ("n", len(EVENTS)), dtype=int, low=0),
                Integer("n_samples", low=1),
                Array("fosm_failure", ("n", len(EVENTS)), low=0.0, high=1.0, nan=True),
                Number("confidence", low=0.0, high=1.0),
                Number("precision", optional=True, positive=True),
                Flag("reached", optional=True), Text("distribution"),
                Number("k", positive=True), Text("interval", INTERVALS))


def axis_labels(machine) -> tuple:
    """Axis names with the units positions are shown in, ``'X (mm)'`` or ``'A (deg)'``."""
    return tuple(f"{a.name} ({'mm' if a.kind == 'linear' else 'deg'})"
                 for a in machine.axis_specs)


def linear_failure(machine, tolerances, poses, *, k: float = 3.0,
                   distribution: str = "normal") -> np.ndarray:
    """Linear-Gaussian failure probability of each output and the system, ``(n_poses, 7)``.

    Outputs: ``1 − [Φ(I/σ) − Φ(−I/σ)]`` (two-sided FOSM). System: one minus the normal
    probability of the rectangle ``|y| < I`` with covariance ``J diag(σ_x²) Jᵀ``
    (scipy's ``multivariate_normal.cdf``; absolute accuracy about 1e−8, so only meaningful
    above that).
    """
    sigma_x = error_sigma(machine.check_tolerances(tolerances), k, distribution)
    poses = np.atleast_2d(poses)
    jacobian = machine.jacobian(poses) * sigma_x  # (P, 6, n)
    covariance = jacobian @ np.swapaxes(jacobian, -1, -2)
    sd = np.sqrt(np.diagonal(covariance, axis1=-2, axis2=-1))
    out = np.empty((len(poses), len(EVENTS)))
    out[:, :6] = 1.0 - two_sided_probability(machine.limits, sd)
    for p in range(len(poses)):  # one 6-D rectangle per pose
        correlation = covariance[p] / np.outer(sd[p], sd[p])
        bound = machine.limits / sd[p]
        inside = multivariate_normal(np.zeros(6), correlation, abseps=1e-10, releps=1e-8,
                                     maxpts=200_000, seed=0).cdf(bound, lower_limit=-bound)
        out[p, 6] = 1.0 - inside
    return out


def sample_at_poses(machine, tolerances, poses=None, *, samples: int = 100_000, rng=None,
                    k: float = 3.0, distribution: str = "normal", precision=None,
                    max_samples: int = 2_000_000, batch: int = 10_000,
                    confidence: float = 0.95, interval: str = "wilson", events=None,
                    fosm: bool = True, progress=None) -> PoseSamplingResult:
    """Monte-Carlo failure probabilities at given poses on the exact model.

    Parameters
    ----------
    machine : Machine
    tolerances : array_like
        ``(n_errors,)`` allocation, read as ±kσ.
    poses : array_like, optional
        ``(n_poses, n_axes)``. Default: each output's worst pose on the 5-point grid under
        the reading ``distribution``
        (:func:`reliability.first_order.worst_grid_pose.worst_grid_poses`).
    samples : int
        Samples per pose when ``precision`` is None.
    rng : None, int or numpy.random.Generator
    k : float
        Coverage factor (σ = t/k).
    distribution : {'normal', 'truncated'}
        Untruncated, or truncated at ±t (Sec. 5.3).
    precision : float, optional
        Target relative half-width of every tracked failure-probability interval; sampling
        continues in batches until it is reached or ``max_samples`` is drawn.
    max_samples : int
        Sample cap per pose with ``precision``.
    batch : int
        Samples per pose evaluated together (memory ≈ batch × n_poses × n_errors × 8 bytes).
    confidence : float
        Level of the intervals.
    interval : {'wilson', 'clopper-pearson'}
        Wilson score (coverage close to nominal on average) or Clopper–Pearson (never below
        nominal, conservative).
    events : sequence of str, optional
        Events to report and to drive adaptive stopping (names from ``dx … ez``,
        ``'system'``). Default: all of them (with default poses, each output at its own
        worst pose and the system event at every pose; when outputs are selected, the
        system event only at their worst poses).
    fosm : bool
        Compute the linear-Gaussian comparison (:func:`linear_failure`); NaN when False.
    progress : callable, optional
        ``progress(done, total)`` after each batch.

    Returns
    -------
    PoseSamplingResult
    """
    checks.independent_errors(machine, "sample_at_poses")
    t = machine.check_tolerances(tolerances)
    _check_options(t, samples, precision, max_samples, batch, confidence, distribution, k)
    if interval not in INTERVALS:
        raise InputError(f"interval must be one of {INTERVALS}; got {interval!r}")
    selected = np.ones(len(EVENTS), bool) if events is None else _event_mask(events)
    if poses is None:
        poses = worst_grid_poses(machine, t, k=k, distribution=distribution)
        labels = tuple(f"worst {o}" for o in OUTPUTS)
        outputs = selected[:6] if selected[:6].any() else np.ones(6, bool)
        tracked = np.hstack([np.eye(6, dtype=bool), outputs[:, None]])
    else:
        poses = _check_poses(machine, poses)
        labels = tuple(f"pose {i}" for i in range(len(poses)))
        tracked = np.ones((len(poses), len(EVENTS)), bool)
    tracked = tracked & selected
    rng = streams.generator(rng)
    total = samples if precision is None else max_samples
    failures = np.zeros((len(poses), len(EVENTS)), dtype=np.int64)
    done, reached = 0, None
    while done < total:
        size = min(batch, total - done)
        x = draw_errors(t, (size, len(poses)), k=k, distribution=distribution, rng=rng)
        outside = ~passes(machine.comprehensive_error(poses, x), machine.limits)  # Eq. (19)
        failures[:, :6] += outside.sum(axis=0)
        failures[:, 6] += outside.any(axis=-1).sum(axis=0)
        done += size
        if progress is not None:
            progress(done, total)
        if precision is not None:
            reached = _precise_enough(failures, done, tracked, precision, confidence,
                                      interval)
            if reached:
                break
    return PoseSamplingResult(
        axes=axis_labels(machine), poses=poses, labels=labels, tracked=tracked, failures=failures,
        n_samples=int(done),
        fosm_failure=linear_failure(machine, t, poses, k=k, distribution=distribution)
        if fosm else np.full(failures.shape, np.nan),
        confidence=float(confidence), precision=None if precision is None else float(precision),
        reached=reached, distribution=distribution, k=float(k), interval=interval)


def _precise_enough(failures, n, tracked, precision, confidence, interval) -> bool:
    """Whether every tracked event's interval is within ``precision`` of p̂."""
    counts = failures[tracked]
    if np.any(counts == 0):
        return False
    est = proportion(counts, n, confidence, interval)
    half = (np.asarray(est.upper) - np.asarray(est.lower)) / 2
    return bool(np.all(half <= precision * np.asarray(est.estimate)))


def _event_mask(events) -> np.ndarray:
    events = (events,) if isinstance(events, str) else tuple(events)
    unknown = [e for e in events if e not in EVENTS]
    if unknown or not events:
        raise InputError(f"events must be a non-empty selection of {EVENTS}; "
                         f"got {unknown[0] if unknown else 'none'!r}")
    return np.isin(np.asarray(EVENTS), events)


def _check_poses(machine, poses) -> np.ndarray:
    poses = np.atleast_2d(machine.check_positions(poses))
    if poses.ndim != 2:
        raise InputError(f"poses must have shape (n_poses, {len(machine.axes)}) for axes "
                         f"{machine.axes}; got {poses.shape}")
    return poses


def _check_options(t, samples, precision, max_samples, batch, confidence, distribution, k):
    if t.ndim != 1:
        raise InputError(f"tolerances must be one allocation; got shape {t.shape}")
    for name, value in (("samples", samples), ("max_samples", max_samples),
                        ("batch", batch)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
            raise InputError(f"{name} must be a positive integer; got {value!r}")
    if precision is not None:
        if isinstance(precision, bool) or not isinstance(precision,
                                                         (int, float, np.floating)):
            raise InputTypeError(f"precision must be a number; got {precision!r}")
        if not (np.isfinite(precision) and precision > 0):
            raise InputError(f"precision must be finite and > 0; got {precision!r}")
    if not 0 < confidence < 1:
        raise InputError(f"confidence must lie in (0, 1); got {confidence!r}")
    if distribution not in ("normal", "truncated"):
        raise InputError(f"distribution must be 'normal' or 'truncated'; "
                         f"got {distribution!r}")
    if not (np.isfinite(k) and k > 0):
        raise InputError(f"k must be finite and > 0; got {k!r}")


def sample_random_poses(machine, tolerances, n_samples: int, *, rng=None, k: float = 3.0,
                        distribution: str = "truncated", chunk: int = 50_000,
                        progress=None, budget: int | None = None) -> RandomPoseResult:
    """Pose-level reliability from independent samples (docs/model.md).

    Every sample draws a pose uniformly over the workspace and a fresh set of all errors,
    so samples are independent and a binomial interval applies. The FOSM prediction for
    the same poses, with the σ of the drawn distribution (truncated or not), is averaged
    alongside: where the model is linear-normal the two agree.

    Parameters
    ----------
    machine : Machine
    tolerances : array_like
        ``(n_errors,)`` allocation, read as ±kσ.
    n_samples : int
    rng : None, int or numpy.random.Generator
    k : float
        Coverage factor.
    distribution : {'truncated', 'normal'}
    chunk : int
        Samples evaluated together (memory ≈ chunk × 3 kB).
    progress : callable, optional
        ``progress(done, total)`` after each chunk.
    budget : int, optional
        Bytes one chunk may take (default :data:`reliability.basics.checks.DEFAULT_BUDGET`).

    Returns
    -------
    RandomPoseResult
    """
    t = checks.one_allocation(machine, tolerances)
    n_samples = checks.positive_int(n_samples, "n_samples")
    chunk = checks.positive_int(chunk, "chunk")
    check_reading(distribution, k)
    checks.callback(progress, "progress")
    rng = streams.generator(rng)
    checks.require_size(min(chunk, n_samples), 8 * (3 * 6 * machine.n_errors + 32), budget,
                        f"a chunk of {min(chunk, n_samples):,} samples", "pass a smaller chunk")
    sigma_x = error_sigma(t, k, distribution)  # the spread actually drawn
    factor = None if machine.correlation is None else correlation_factor(machine.correlation)
    inside = np.zeros(6, dtype=np.int64)
    one_sided, two_sided = np.zeros(6), np.zeros(6)
    for start in range(0, n_samples, chunk):
        size = min(chunk, n_samples - start)
        poses = random_poses(machine, size, rng)
        errors = draw_errors(t, (size,), k=k, distribution=distribution, rng=rng) \
            if factor is None else draw_correlated(t, (size,), factor, k=k,
                                                   distribution=distribution, rng=rng)
        inside += np.sum(passes(machine.comprehensive_error(poses, errors), machine.limits),
                         axis=0)  # Eq. (19)
        sigma = output_sigma(machine.jacobian(poses), sigma_x, machine.correlation)  # Eq. (20)
        one_sided += one_sided_probability(machine.limits, sigma).sum(axis=0)
        two_sided += two_sided_probability(machine.limits, sigma).sum(axis=0)
        if progress is not None:
            progress(start + size, n_samples)
    return RandomPoseResult(limits=machine.limits.copy(), inside=inside,
                            n_samples=int(n_samples), fosm_one_sided=one_sided / n_samples,
                            fosm_two_sided=two_sided / n_samples, distribution=distribution,
                            k=float(k))
