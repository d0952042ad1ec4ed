"""Honest uncertainty for Monte-Carlo precision-reliability estimates.

The paper (Sec. 5.3, Tables 8 and 9) reads the fraction of grid poses whose comprehensive
error stays inside its limit as the "precision reliability" and reports it without an error
bar. This module supplies the error bars, and is explicit about what counts as an
independent sample:

* :func:`binomial_interval` and :func:`proportion` -- for *independent* Bernoulli trials
  (Wilson score or Clopper-Pearson exact interval).
* :func:`between_experiment_interval` -- for per-experiment fractions whose poses share
  their random errors; the spread between experiments gives the design effect, and a
  Wilson score interval on Kish's effective sample size keeps the bounds inside [0, 1].
* :func:`all_within_share` -- the share of experiments (simulated machines) in which every
  entry (pose, output) meets its limit; experiments are independent, so a binomial interval
  applies. (The machine yield of an allocation, with its choice of estimator, is
  :func:`reliability.sampling.machine_yield.machine_yield`; this is the interval of a count.)

Every function is vectorised over trailing "output" axes (e.g. the six comprehensive
errors ``dx dy dz ex ey ez``) and returns a frozen result that carries its own standard
error and interval and turns into a :class:`pandas.DataFrame` with ``.to_frame()``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy import stats

from . import checks
from .display import lower_bound_text, upper_bound_text
from .errors import InputError, InputTypeError

__all__ = [
    "METHODS",
    "ProportionEstimate",
    "ReplicateEstimate",
    "all_within_share",
    "between_experiment_interval",
    "binomial_interval",
    "proportion",
]

METHODS = ("wilson", "clopper-pearson")


# --------------------------------------------------------------------------- input checks
def _index_text(name, bad, values):
    """Describe the first offending element of ``values`` where ``bad`` is true."""
    idx = tuple(int(i) for i in np.argwhere(bad)[0])
    where = f"{name}[{', '.join(map(str, idx))}]" if idx else name
    return f"{where} = {values[idx].item()!r}"


def _check_confidence(confidence):
    """Return ``confidence`` as a float in the open interval (0, 1)."""
    return checks.probability(confidence, "confidence")


def _check_method(method):
    """Refuse interval methods other than those in :data:`METHODS`."""
    if method not in METHODS:
        raise InputError(f"unknown interval method {method!r}; choose one of {METHODS}")


def _integer_array(name, values):
    """Return ``values`` as an int64 array, refusing non-finite or non-integral entries."""
    x = np.asarray(values)
    if x.dtype.kind not in "biuf":
        raise InputTypeError(f"{name} must be numeric; got dtype {x.dtype}")
    x = x.astype(float)
    bad = ~np.isfinite(x) | (x != np.round(x))
    if bad.any():
        raise InputError(f"{name} must be whole numbers; {_index_text(name, bad, x)}")
    return x.astype(np.int64)


def _check_counts(successes, trials):
    """Validate and broadcast success and trial counts; return int64 arrays."""
    k = _integer_array("successes", successes)
    n = _integer_array("trials", trials)
    if (n <= 0).any():
        raise InputError(f"trials must be positive; {_index_text('trials', n <= 0, n)}")
    try:
        k, n = np.broadcast_arrays(k, n)
    except ValueError:
        raise InputError(
            f"successes of shape {k.shape} and trials of shape {n.shape} do not broadcast"
        ) from None
    bad = (k < 0) | (k > n)
    if bad.any():
        raise InputError(
            "successes must lie in [0, trials]; "
            f"{_index_text('successes', bad, k)} with {_index_text('trials', bad, n)}"
        )
    return k, n


def _check_names(names, shape):
    """Return ``names`` as a tuple matching a 0-d or 1-d result ``shape`` (or None)."""
    if names is None:
        return None
    names = (names,) if isinstance(names, str) else tuple(names)
    if len(shape) > 1:
        raise InputError(f"names label a 1-d result; this result has shape {shape}")
    size = shape[0] if shape else 1
    if len(names) != size:
        raise InputError(f"got {len(names)} names for {size} outputs: {names!r}")
    return names


def _frozen(x, dtype=float):
    """Return a read-only copy of ``x``, or a Python scalar for a 0-d value."""
    x = np.array(x, dtype=dtype)
    if x.ndim == 0:
        return x.item()
    x.setflags(write=False)
    return x


# --------------------------------------------------------------------------- intervals
def _wilson(k, n, z):
    """Wilson score interval (no continuity correction)."""
    return _wilson_share(k / n, n, z)


def _wilson_share(p, n, z):
    """Wilson score interval for a share ``p`` observed on ``n`` (possibly effective,
    non-integral) trials; always inside [0, 1]."""
    denom = 1.0 + z**2 / n
    centre = (p + z**2 / (2 * n)) / denom
    half = z / denom * np.sqrt(p * (1 - p) / n + z**2 / (4 * n**2))
    # At p = 0 and p = 1 the bounds are exactly 0 and 1; rounding would leave +-1e-17.
    return np.where(p == 0, 0.0, centre - half), np.where(p == 1, 1.0, centre + half)


def _clopper_pearson(k, n, alpha):
    """Clopper-Pearson interval from beta quantiles; bounds 0 at k = 0 and 1 at k = n."""
    lower = stats.beta.ppf(alpha / 2, np.maximum(k, 1), n - k + 1)
    upper = stats.beta.ppf(1 - alpha / 2, k + 1, np.maximum(n - k, 1))
    return np.where(k == 0, 0.0, lower), np.where(k == n, 1.0, upper)


def _bounds(k, n, confidence, method):
    """Interval bounds for validated counts, as read-only arrays or floats."""
    alpha = 1.0 - confidence
    if method == "wilson":
        lower, upper = _wilson(k, n, stats.norm.ppf(1 - alpha / 2))
    else:
        lower, upper = _clopper_pearson(k, n, alpha)
    return _frozen(lower), _frozen(upper)


def share_interval(share, effective_n, confidence=0.95):
    """Wilson score interval for a share observed on ``effective_n`` (possibly weighted,
    non-integral) trials, e.g. Kish's ``(Σw)²/Σw²`` of weighted samples; inside [0, 1].

    Parameters
    ----------
    share : array_like
        Observed shares in [0, 1].
    effective_n : array_like
        Effective number of trials, > 0.
    confidence : float, default 0.95

    Returns
    -------
    (lower, upper) : ndarrays
    """
    confidence = _check_confidence(confidence)
    p = checks.numeric_array(share, "share")
    n = checks.numeric_array(effective_n, "effective_n")
    if np.any(~np.isfinite(p) | (p < 0) | (p > 1)):
        raise InputError(f"share must lie in [0, 1]; got {p!r}")
    if np.any(~np.isfinite(n) | (n <= 0)):
        raise InputError(f"effective_n must be finite and > 0; got {n!r}")
    return _wilson_share(p, n, stats.norm.ppf(0.5 + confidence / 2))


def binomial_interval(successes, trials, confidence=0.95, method="wilson"):
    """Two-sided confidence interval for a binomial proportion.

    Parameters
    ----------
    successes : array_like of int
        Number of successes ``k``, ``0 <= k <= trials``.
    trials : array_like of int
        Number of independent trials ``n > 0``; broadcast against `successes`.
    confidence : float, default 0.95
        Two-sided confidence level in (0, 1).
    method : {"wilson", "clopper-pearson"}
        ``"wilson"``: score interval, coverage close to nominal on average.
        ``"clopper-pearson"``: exact interval from beta quantiles, coverage never below
        nominal (conservative); lower bound 0 at ``k = 0``, upper bound 1 at ``k = n``.

    Returns
    -------
    lower, upper : float or ndarray
        Interval bounds, with the broadcast shape of the inputs.

    Raises
    ------
    InputError
        If a count is negative, non-integral or exceeds its trials, if `confidence` is
        outside (0, 1), or if `method` is unknown.
    InputTypeError
        If a count is not numeric.

    Notes
    -----
    Both intervals assume independent trials. Poses of one grid experiment are not
    independent (they share the experiment's errors); use
    :func:`between_experiment_interval` for them.
    """
    confidence = _check_confidence(confidence)
    _check_method(method)
    k, n = _check_counts(successes, trials)
    return _bounds(k, n, confidence, method)


# --------------------------------------------------------------------------- results
class _FrameMixin:
    """``as_dict``, ``to_frame`` and a readable ``summary`` (also the ``repr``) for the
    frozen estimate dataclasses."""

    def summary(self) -> str:
        """The estimate with its interval, one line per output, and how it was made."""
        n = np.unique(np.asarray(self.n)).tolist()
        trials = "experiments" if self.method == "wilson-kish" else "trials"
        head = (f"{type(self).__name__}: {self.confidence:.0%} {self.method} interval, "
                f"{n[0] if len(n) == 1 else n} {trials}")
        frame = pd.DataFrame({
            "estimate": np.atleast_1d(self.estimate),
            "lower": [lower_bound_text(v) for v in np.atleast_1d(self.lower)],
            "upper": [upper_bound_text(v) for v in np.atleast_1d(self.upper)],
            "standard_error": np.atleast_1d(self.standard_error)},
            index=pd.Index(self.names if self.names else
                           range(np.size(np.atleast_1d(self.estimate))), name="output"))
        if np.ndim(self.estimate) == 0:
            return (f"{head}: {float(self.estimate):.6g} [{lower_bound_text(self.lower)}, "
                    f"{upper_bound_text(self.upper)}], standard error "
                    f"{float(self.standard_error):.3g}")
        return f"{head}\n{frame.to_string(float_format='{:.6g}'.format)}"

    def __repr__(self) -> str:
        return self.summary()

    def as_dict(self):
        """Return the fields as a plain dict (arrays stay arrays)."""
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}

    def to_frame(self):
        """Return one row per output, indexed by ``names`` when they were given.

        Raises
        ------
        InputError
            If the estimate has more than one dimension.
        """
        shape = np.shape(self.estimate)
        if len(shape) > 1:
            raise InputError(f"to_frame needs a 0-d or 1-d estimate; got shape {shape}")
        size = shape[0] if shape else 1
        columns = {
            f.name: np.broadcast_to(getattr(self, f.name), (size,))
            for f in dataclasses.fields(self)
            if f.name != "names"
        }
        index = pd.Index(self.names if self.names else range(size), name="output")
        return pd.DataFrame(columns, index=index)


@dataclass(frozen=True, eq=False, repr=False)
class ProportionEstimate(_FrameMixin):
    """A proportion from independent trials, with its interval.

    Attributes
    ----------
    estimate : float or ndarray
        ``successes / trials``.
    lower, upper : float or ndarray
        Confidence bounds from `method`.
    standard_error : float or ndarray
        Plug-in binomial standard error ``sqrt(p (1 - p) / n)``; it is 0 at ``p = 0`` or 1,
        where only the interval is informative.
    n : int or ndarray
        Number of trials.
    method : str
        ``"wilson"`` or ``"clopper-pearson"``.
    confidence : float
        Two-sided confidence level.
    names : tuple of str or None
        Output names, used as the index of :meth:`to_frame`.
    """

    estimate: float | np.ndarray
    lower: float | np.ndarray
    upper: float | np.ndarray
    standard_error: float | np.ndarray
    n: int | np.ndarray
    method: str
    confidence: float
    names: tuple[str, ...] | None = None


@dataclass(frozen=True, eq=False, repr=False)
class ReplicateEstimate(_FrameMixin):
    """A mean over independent experiments, with a Wilson score interval on Kish's
    effective sample size.

    Attributes
    ----------
    estimate : float or ndarray
        Mean of the per-experiment fractions.
    lower, upper : float or ndarray
        Wilson score bounds for ``estimate`` observed on ``effective_n`` trials; always
        inside [0, 1].
    standard_error : float or ndarray
        ``std / sqrt(n)``, from the spread between experiments.
    n : int
        Number of experiments.
    method : str
        Always ``"wilson-kish"``.
    confidence : float
        Two-sided confidence level.
    std : float or ndarray
        Sample standard deviation across experiments (``ddof=1``).
    minimum, maximum : float or ndarray
        Smallest and largest per-experiment fraction (Table 9's "Min" and "Max" rows).
    names : tuple of str or None
        Output names, used as the index of :meth:`to_frame`.
    effective_n : float or ndarray or None
        Kish's effective sample size ``p (1 − p) / standard_error²``, at most the number
        of poses evaluated when it is known.
    """

    estimate: float | np.ndarray
    lower: float | np.ndarray
    upper: float | np.ndarray
    standard_error: float | np.ndarray
    n: int
    method: str
    confidence: float
    std: float | np.ndarray
    minimum: float | np.ndarray
    maximum: float | np.ndarray
    names: tuple[str, ...] | None = None
    effective_n: float | np.ndarray | None = None


# --------------------------------------------------------------------------- estimators
def proportion(successes, trials, confidence=0.95, method="wilson", *, names=None):
    """Estimate a proportion from independent trials.

    Parameters
    ----------
    successes, trials, confidence, method
        As in :func:`binomial_interval`.
    names : sequence of str, optional
        One name per output (last axis of a 1-d result), e.g. ``("dx", ..., "ez")``.

    Returns
    -------
    ProportionEstimate
    """
    confidence = _check_confidence(confidence)
    _check_method(method)
    k, n = _check_counts(successes, trials)
    lower, upper = _bounds(k, n, confidence, method)
    p = k / n
    return ProportionEstimate(
        estimate=_frozen(p),
        lower=lower,
        upper=upper,
        standard_error=_frozen(np.sqrt(p * (1 - p) / n)),
        n=_frozen(n, dtype=np.int64),
        method=method,
        confidence=confidence,
        names=_check_names(names, p.shape),
    )


def _check_fractions(fractions):
    """Return per-experiment fractions as a float array of shape (n >= 2, ...)."""
    f = checks.numeric_array(fractions, "fractions")
    if f.ndim == 0 or f.shape[0] < 2:
        n = 0 if f.ndim == 0 else f.shape[0]
        raise InputError(
            f"need at least 2 experiments along axis 0 to estimate a spread; got {n}"
        )
    bad = ~np.isfinite(f) | (f < 0) | (f > 1)
    if bad.any():
        raise InputError(
            f"fractions must be finite and in [0, 1]; {_index_text('fractions', bad, f)}"
        )
    return f


def between_experiment_interval(fractions, confidence=0.95, *, names=None, poses=None):
    """Mean in-tolerance fraction over repeated experiments, with a Wilson score interval
    on Kish's effective sample size.

    One grid experiment (Sec. 5.3) of the paper's machine evaluates 15 625 poses, but draws the 30
    assembly errors once and each axis' six motion errors only at its five grid points, so every
    pose shares its assembly errors with all others and its motion errors with thousands of others.
    Out-of-tolerance poses therefore come in clusters: one unlucky draw pushes hundreds of poses
    out at once (Table 9, experiment 8, εz: 99.14 %). The poses are not independent trials, and the
    unit of replication is the experiment.

    A binomial interval on the 20 x 15 625 = 312 500 pooled poses treats them as
    independent and is far too narrow. For the εz column of Table 9 the pooled binomial
    standard error is 7.4e-5, while the spread between experiments gives 5.9e-4: a design
    effect of about 60, so the pooled interval is about 8 times too narrow and would
    claim a precision the 20 experiments do not have. This function uses the experiments'
    own spread instead: the design effect ``deff = se² / (p (1 − p) / N)`` turns the ``N``
    pooled poses into Kish's effective sample size ``n_eff = N / deff = p (1 − p) / se²``,
    and the Wilson score interval for ``p`` on ``n_eff`` trials is the interval. Unlike a
    Student-t interval it never leaves [0, 1], and it keeps a width when every experiment
    gives the same fraction (then ``n_eff`` is the number of poses, ``N``).

    Parameters
    ----------
    fractions : array_like, shape (n_experiments, ...)
        Per-experiment fraction of poses within the limit, each in [0, 1]; trailing axes
        are outputs (e.g. shape (20, 6) for Table 9).
    confidence : float, default 0.95
        Two-sided confidence level in (0, 1).
    names : sequence of str, optional
        One name per output for :meth:`ReplicateEstimate.to_frame`.
    poses : int, optional
        Poses per experiment. ``n_eff`` never exceeds the ``n * poses`` poses evaluated;
        without it, experiments that all agree give ``n_eff = n``.

    Returns
    -------
    ReplicateEstimate
        Mean, ``std(ddof=1) / sqrt(n)`` standard error, Wilson score interval on the
        effective sample size, minimum and maximum, per output.

    Raises
    ------
    InputError
        If there are fewer than 2 experiments, or a fraction is non-finite or outside
        [0, 1] (the offending element is named).

    Notes
    -----
    The interval is approximate: the effective sample size is itself estimated from the
    experiments, and fractions near 1 are skewed (many experiments at exactly 1, a few
    well below), so with 20 experiments the coverage is only near nominal.
    :func:`all_within_share` answers the complementary question "how often is a
    machine entirely within its limits" with an exact binomial interval.

    Examples
    --------
    Three experiments, two outputs:

    >>> est = between_experiment_interval([[0.999, 1.0], [0.997, 1.0], [0.998, 0.999]],
    ...                                   names=("dx", "ez"))
    >>> est.n, round(float(est.standard_error[0]), 6)
    (3, 0.000577)
    """
    confidence = _check_confidence(confidence)
    f = _check_fractions(fractions)
    n = f.shape[0]
    mean = f.mean(axis=0)
    std = f.std(axis=0, ddof=1)
    se = std / np.sqrt(n)
    n_eff = _kish_effective_size(mean, se, n, poses)
    lower, upper = _wilson_share(mean, n_eff, stats.norm.ppf(0.5 + confidence / 2))
    return ReplicateEstimate(
        estimate=_frozen(mean),
        lower=_frozen(lower),
        upper=_frozen(upper),
        standard_error=_frozen(se),
        n=n,
        method="wilson-kish",
        confidence=confidence,
        std=_frozen(std),
        minimum=_frozen(f.min(axis=0)),
        maximum=_frozen(f.max(axis=0)),
        names=_check_names(names, mean.shape),
        effective_n=_frozen(n_eff),
    )


def _kish_effective_size(mean, se, n, poses):
    """``p (1 − p) / se²`` (Kish: pooled size over design effect), capped at the poses
    evaluated; where the experiments all agree (se = 0), the poses evaluated (or ``n``)."""
    if poses is not None:
        poses = _integer_array("poses", poses)
        if np.any(poses < 1):
            raise InputError(f"poses must be >= 1; got {poses!r}")
    cap = float(n) if poses is None else float(n) * poses
    with np.errstate(divide="ignore", invalid="ignore"):
        n_eff = np.where(se > 0, mean * (1.0 - mean) / np.square(se), cap)
    return n_eff if poses is None else np.minimum(n_eff, cap)


def all_within_share(all_within, confidence=0.95, method="clopper-pearson", *, trials=None):
    """Share of experiments entirely within their limits, with a binomial interval.

    Each experiment (a grid experiment, one simulated machine: one draw of all its errors)
    counts when every entry of it (every pose, every output) is within its limit;
    experiments are independent, so the share is a binomial proportion over experiments,
    with a Clopper–Pearson interval by default. Given the verdicts of crude samples of built
    machines it is the crude machine yield's interval; the machine yield itself, with its
    estimator, is :func:`reliability.sampling.machine_yield.machine_yield`.

    Parameters
    ----------
    all_within : array_like of bool, shape (n_experiments, ...), or int
        Without `trials`: a boolean array whose first axis is the experiment; any trailing
        axes (poses, outputs) are reduced with ``all``, so an experiment counts only if
        every entry is True. With `trials`: the number of experiments that were entirely
        within their limits.
    confidence : float, default 0.95
        Two-sided confidence level in (0, 1).
    method : {"clopper-pearson", "wilson"}
        Interval method; the exact interval is the default because the number of
        experiments is small and the yield is often 0 or 1.
    trials : int, optional
        Number of experiments, when `all_within` is a count.

    Returns
    -------
    ProportionEstimate

    Raises
    ------
    InputTypeError
        If `all_within` is not boolean and no `trials` is given.
    InputError
        If there is no experiment, or as in :func:`binomial_interval`.
    """
    if trials is not None:
        return proportion(all_within, trials, confidence, method)
    ok = np.asarray(all_within)
    if ok.dtype != bool:
        raise InputTypeError(
            f"all_within must be a boolean array (n_experiments, ...); got dtype "
            f"{ok.dtype}. To pass a count of all-within experiments, also give trials="
        )
    if ok.ndim == 0:
        raise InputError("all_within needs a leading experiment axis; got a scalar")
    per_machine = ok.all(axis=tuple(range(1, ok.ndim)))
    return proportion(int(per_machine.sum()), per_machine.size, confidence, method)
