"""Acceptance limits from the design: the limit each test result meets with probability P.

The reverse of :func:`reliability.acceptance.prediction.acceptance`: instead of the
probability that a built machine meets a given limit, the limit that machines built to the
allocation meet with a given probability ``P``, to write in the machine's specification.

**The suggested limit** of a result is its ``P``-quantile over the built machines: the
order statistic ``x₍ₖ₎`` with ``k = ⌈n P⌉`` (the inverse of the empirical distribution
function), moved up to the next floating-point number, so that at least a share ``P`` of
the simulated machines pass it by the toolkit's one rule ``value < limit``
(:mod:`reliability.basics.pass_rule`; the machine at ``x₍ₖ₎`` itself passes). The ends of
its interval are moved up alike, so they read as limits too.

**Its interval** is distribution-free: with ``K`` the number of built machines whose result
lies below the true ``P``-quantile, ``K`` is binomial ``(n, P)`` whatever the result's
distribution, so ``[x₍ₗ₎, x₍ᵤ₎]`` covers the quantile with probability at least
``F(u − 1) − F(l − 1)`` (``F`` the binomial distribution function). The ranks are the
equal-tailed choice: ``l`` the largest rank with ``F(l − 1) <= α/2`` and ``u`` the smallest
with ``1 − F(u − 1) <= α/2``, ``α = 1 − confidence``; the coverage is at least the
confidence, exactly ``F(u − 1) − F(l − 1)`` for a continuous result.

**Several limits at once.** A test with several limited quantities (a positioning test's
``E``, ``A``, ``R``, ``B``) gets one suggested limit per quantity; a machine passes the test
only when every quantity is within its limit, so the probability of passing with every
suggested limit at once is lower than ``P`` (unless the quantities move together):
:class:`SuggestedLimits` gives it for each test and for all tests.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy.stats import binom

from ..basics.display import interval_text, lower_bound_text, upper_bound_text
from ..basics.errors import InputError
from ..basics.pass_rule import passes
from ..basics.saved_fields import Frame, Nested, Number, load_fields, save_fields
from ..basics.statistics import binomial_interval
from .acceptance_result import AcceptanceResult

#: Columns :meth:`SuggestedLimits.to_frame` adds to the ``acceptance.csv`` table (mm).
COLUMNS = ("suggested_limit", "suggested_low", "suggested_high")
SAVED_FORMAT = "precrel.suggested_limits"


def _check_probability(name: str, value) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating)) \
            or not 0.0 < value < 1.0:
        raise InputError(f"{name} must be a number in (0, 1); got {value!r}")
    return float(value)


def minimum_machines(probability: float, confidence: float = 0.95) -> int:
    """The fewest built machines whose order statistics bound the ``probability``-quantile
    on both sides at ``confidence``.

    The interval needs ``P(K = n) = Pⁿ <= α/2`` and ``P(K = 0) = (1 − P)ⁿ <= α/2``.

    Parameters
    ----------
    probability : float
        In (0, 1).
    confidence : float
        In (0, 1).

    Returns
    -------
    int
    """
    p = _check_probability("probability", probability)
    tail = (1.0 - _check_probability("confidence", confidence)) / 2.0
    n = max(1, math.floor(math.log(tail) / math.log(max(p, 1.0 - p))))
    while not _bounded(n, p, tail):
        n += 1
    return n


def _bounded(n: int, probability: float, tail: float) -> bool:
    """Whether neither ``K = 0`` nor ``K = n`` has probability above ``tail``."""
    return binom.cdf(0, n, probability) <= tail and binom.sf(n - 1, n, probability) <= tail


def check_machines(machines: int, probability: float, confidence: float = 0.95,
                   name: str = "machines") -> None:
    """Refuse too few built machines for the ``probability``-quantile's interval.

    Parameters
    ----------
    machines : int
    probability, confidence : float
        In (0, 1).
    name : str
        The argument's name in the message, e.g. ``--machines``.

    Raises
    ------
    InputError
        Naming the argument, the quantile and the fewest machines needed.
    """
    needed = minimum_machines(probability, confidence)
    if machines < needed:
        raise InputError(f"{name} must be at least {needed} to bound the "
                         f"{probability:g}-quantile of a result on both sides at "
                         f"{100 * confidence:g} % confidence; got {machines}")


def quantile_ranks(n: int, probability: float, confidence: float = 0.95) -> tuple[int, int, float]:
    """Ranks ``l < u`` (1-based) of the order statistics that bound the
    ``probability``-quantile of ``n`` independent draws, and their coverage.

    Parameters
    ----------
    n : int
        Draws; at least :func:`minimum_machines`.
    probability, confidence : float
        In (0, 1).

    Returns
    -------
    lower, upper : int
        ``l`` the largest rank with ``F(l − 1) <= α/2``, ``u`` the smallest with
        ``1 − F(u − 1) <= α/2`` (``F`` binomial ``(n, probability)``, ``α = 1 − confidence``).
    coverage : float
        ``F(u − 1) − F(l − 1)``: the probability that ``[x₍ₗ₎, x₍ᵤ₎]`` covers the quantile of a
        continuous distribution (at least that for any distribution).
    """
    check_machines(n, probability, confidence)
    tail = (1.0 - confidence) / 2.0
    counts = np.arange(n + 1)
    below = binom.cdf(counts, n, probability)          # F(j)
    above = binom.sf(counts, n, probability)           # 1 − F(j)
    lower = int(np.flatnonzero(below <= tail)[-1]) + 1
    upper = int(np.flatnonzero(above <= tail)[0]) + 1
    return lower, upper, float(above[lower - 1] - above[upper - 1])


def quantile_interval(values, probability: float, confidence: float = 0.95):
    """The ``probability``-quantile of independent draws and its order-statistic interval.

    Parameters
    ----------
    values : array_like
        ``(n, ...)`` independent draws along the first axis, e.g. one column per result.
    probability, confidence : float
        In (0, 1).

    Returns
    -------
    estimate, low, high : ndarray
        Each ``(...)``: ``x₍⌈n P⌉₎`` and ``[x₍ₗ₎, x₍ᵤ₎]`` from :func:`quantile_ranks`.
    """
    ordered = np.sort(np.asarray(values, dtype=float), axis=0)
    p = _check_probability("probability", probability)
    lower, upper, _ = quantile_ranks(len(ordered), p, confidence)
    return ordered[math.ceil(len(ordered) * p) - 1], ordered[lower - 1], ordered[upper - 1]


@dataclass(frozen=True, eq=False)
class SuggestedLimits:
    """Suggested acceptance limits for the results of :class:`AcceptanceResult`.

    Attributes
    ----------
    result : AcceptanceResult
        The built machines' test results.
    probability : float
        ``P``: the share of built machines meant to meet each limit.
    confidence : float
        Level of the order-statistic intervals and of the Wilson intervals.
    limits : pandas.DataFrame
        Columns ``test, quantity`` and :data:`COLUMNS` (mm), one row per test and quantity.
    coverage : float
        The order-statistic interval's coverage (:func:`quantile_ranks`).
    """

    result: object
    probability: float
    confidence: float
    limits: pd.DataFrame
    coverage: float

    def _suggested(self, test: str, quantity: str) -> float:
        rows = self.limits[(self.limits["test"] == test) & (self.limits["quantity"] == quantity)]
        return float(rows["suggested_limit"].iloc[0])

    def passed(self) -> pd.DataFrame:
        """Boolean frame, one column per test and ``all``: every quantity the test file
        limits within its suggested limit."""
        values, out = self.result.values, {}
        for test in self.result.tests:
            ok = np.ones(self.result.n_machines, dtype=bool)
            for quantity in test.limits:
                ok &= passes(values[(test.name, quantity)].to_numpy(),
                             self._suggested(test.name, quantity))
            out[test.name] = ok
        frame = pd.DataFrame(out)
        frame["all"] = frame.all(axis=1)
        return frame

    def joint_pass(self) -> pd.DataFrame:
        """Columns ``test, quantities, pass_probability, pass_low, pass_high``: the share of
        the built machines that pass each test (and ``all``) with every limited quantity at
        its suggested limit, with its Wilson interval; estimated on the machines that gave
        the limits."""
        passed = self.passed()
        limited = {t.name: ", ".join(t.limits) for t in self.result.tests}
        rows = []
        for name in passed.columns:
            ok = passed[name].to_numpy()
            low, high = binomial_interval(int(ok.sum()), len(ok), self.confidence)
            rows.append({"test": name, "quantities": limited.get(name, "every test"),
                         "pass_probability": ok.mean(), "pass_low": float(low),
                         "pass_high": float(high)})
        return pd.DataFrame(rows)

    def to_frame(self) -> pd.DataFrame:
        """The ``acceptance.csv`` table (:meth:`AcceptanceResult.to_frame`) with the columns
        :data:`COLUMNS` added (mm); empty on the last row ``all, pass``."""
        return self.result.to_frame().merge(self.limits, on=["test", "quantity"], how="left")

    def summary(self) -> str:
        """Each result's suggested limit and interval in µm beside its limit, then the
        probability of passing each test with its suggested limits at once."""
        heading = (f"suggested limits: the {self.probability:g}-quantile of each result over "
                   f"the {self.result.n_machines} built machines (a limit that a share "
                   f"{self.probability:g} of them meet), with its distribution-free "
                   f"order-statistic interval (coverage {self.coverage:.4f} >= "
                   f"{self.confidence:g}):")
        joint = (f"pass probability of each test with every limited quantity at its "
                 f"suggested limit (below {self.probability:g} when a test limits "
                 f"quantities that do not move together: a machine must meet them all), "
                 f"Wilson {100 * self.confidence:g} %:")
        lines = [heading, self._printed_table().to_string(index=False), "", joint]
        lines += [f"  {row.test} ({row.quantities}): {row.pass_probability:.4f} "
                  f"{interval_text(row.pass_low, row.pass_high)}"
                  for row in self.joint_pass().itertuples()]
        return "\n".join(lines)

    def save(self, path, overwrite: bool = False):
        """Save as JSON (:mod:`reliability.basics.saved_fields`): the acceptance result, the
        probability, the confidence, the limits and their coverage; an existing file is kept
        unless ``overwrite``. Returns the path."""
        return save_fields(self, path, SAVED_FORMAT, SAVED_FIELDS, overwrite)

    @classmethod
    def load(cls, path) -> "SuggestedLimits":
        """Reload limits written by :meth:`save`, the acceptance result checked as
        :meth:`AcceptanceResult.from_payload` says. The verdicts are kept: the suggested
        limits and their intervals must be the quantiles of the saved results, and the
        coverage their ranks' coverage; anything else raises
        :class:`~reliability.basics.errors.SavedResultError` naming the file and the field."""
        data, values = load_fields(path, SAVED_FORMAT, SAVED_FIELDS)
        for name in ("probability", "confidence"):
            if not 0.0 < values[name] < 1.0:
                raise data.error(name, f"expected a number in (0, 1), got {values[name]!r}")
        again = suggest_limits(values["result"], values["probability"], values["confidence"])
        saved = values["limits"]
        if list(saved.columns) != list(again.limits.columns) or len(saved) != len(again.limits) \
                or not np.array_equal(saved[list(COLUMNS)].to_numpy(float),
                                      again.limits[list(COLUMNS)].to_numpy(float)):
            raise data.error("limits", "are not the quantiles of the saved results")
        if values["coverage"] != again.coverage:
            raise data.error("coverage", f"is {values['coverage']!r}; the ranks give "
                                         f"{again.coverage!r}")
        return again

    def _printed_table(self) -> pd.DataFrame:
        """Limits, suggested limits and their intervals in µm, one row per result."""
        frame = self.to_frame().iloc[:-1]
        return pd.DataFrame({
            "test": frame["test"], "quantity": frame["quantity"],
            "limit µm": [f"{1000 * v:.3g}" if pd.notna(v) else "-" for v in frame["limit"]],
            "suggested µm": [f"{1000 * v:.4g}" for v in frame["suggested_limit"]],
            f"{100 * self.confidence:g} % interval µm": [
                f"[{lower_bound_text(1000 * low, 4)}, {upper_bound_text(1000 * high, 4)}]"
                for low, high in zip(frame["suggested_low"], frame["suggested_high"])]})


def suggest_limits(result, probability: float,
                   confidence: float | None = None) -> SuggestedLimits:
    """The limit each test result meets with ``probability`` on machines built to the
    allocation: its quantile, with a distribution-free interval.

    Parameters
    ----------
    result : AcceptanceResult
        :func:`reliability.acceptance.prediction.acceptance`.
    probability : float
        ``P`` in (0, 1), e.g. 0.95.
    confidence : float, optional
        Level of the intervals; the result's (95 % by default).

    Returns
    -------
    SuggestedLimits

    Raises
    ------
    InputError
        If ``probability`` or ``confidence`` is not in (0, 1), or the result has fewer
        built machines than :func:`minimum_machines`.
    """
    p = _check_probability("probability", probability)
    level = _check_probability("confidence", result.confidence if confidence is None
                               else confidence)
    _, _, coverage = quantile_ranks(result.n_machines, p, level)
    limits = result.values.columns.to_frame(index=False)
    estimate, low, high = quantile_interval(result.values, p, level)
    for column, values in zip(COLUMNS, (estimate, low, high)):
        limits[column] = np.nextafter(values, np.inf)  # passed by |v| < limit
    return SuggestedLimits(result=result, probability=p, confidence=level, limits=limits,
                           coverage=coverage)


#: The fields :meth:`SuggestedLimits.save` writes.
SAVED_FIELDS = (Nested("result", AcceptanceResult), Number("probability"),
                Number("confidence"), Frame("limits", ("test", "quantity", *COLUMNS)),
                Number("coverage", low=0.0, high=1.0))
