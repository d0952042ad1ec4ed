"""The machine yield's result: :class:`YieldEstimate`, its table and file, and the running
sums of sampled machines it is estimated from.

A yield estimated by crude sampling is the share of built machines that passed, with a
Clopper–Pearson interval; by importance sampling it is ``1 − p`` with ``p`` the mean of the
weighted failure indicators, its interval ``1 − (p ± z·se)`` (failure probability floored at
0) and its CoV ``se/p``. A saved estimate (:meth:`YieldEstimate.save`) is reloaded with these
verdicts checked against the counts they come from.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from scipy.stats import norm

from ..basics.saved_results import encode_frame, load_payload, save_payload
from ..basics.statistics import all_within_share
from .failure_regions import SHARE_COLUMNS

#: Rows of the failure-share table that :meth:`YieldEstimate.summary` prints.
SHOWN_SHARES = 12
SAVED_FORMAT = "precrel.yield_estimate"
#: The fields :meth:`YieldEstimate.save` writes besides the failure shares.
SAVED_FIELDS = ("estimate", "lower", "upper", "confidence", "cov", "machines", "method",
                "method_reason", "profile", "distribution", "workspace", "n_poses", "failures",
                "first_order_lower", "first_order_upper", "target_cov")


@dataclass(frozen=True, eq=False, repr=False)
class YieldEstimate:
    """A machine yield with its precision and what it rests on.

    Attributes
    ----------
    estimate : float
        Estimated yield: the probability that a built machine keeps all six outputs within
        their limits at every pose of the workspace.
    lower, upper : float
        Interval at ``confidence``: Clopper–Pearson (crude) or ``1 − (p ± z·se)``
        (importance sampling).
    confidence : float
    cov : float
        Coefficient of variation of the estimated *failure* probability ``1 − estimate``
        (NaN when no failing machine was seen).
    machines : int
        Built machines simulated; each is one evaluation of the exact chain at every pose.
    method : str
        ``'crude'`` or ``'importance'``.
    method_reason : str
        Why the method was used.
    profile : str
        The error-profile model (``'constant'``, ``'independent'``, ``'gp:300'``).
    distribution : str
        The reading of a tolerance (``'normal'`` or ``'truncated'``).
    workspace : str
        E.g. ``'5-point grid (15 625 poses)'``.
    n_poses : int
    failures : int
        Failing machines seen (under importance sampling, drawn from the proposal).
    first_order_lower, first_order_upper : float
        Bounds on the yield of the linearised model (union bound; best single row).
    failure_shares : DataFrame
        Columns ``output, region, share, lower, upper, failures``: which requirement fails
        first among failing machines, largest share first.
    target_cov : float or None
        The CoV importance sampling aimed at (None for crude).
    """

    estimate: float
    lower: float
    upper: float
    confidence: float
    cov: float
    machines: int
    method: str
    method_reason: str
    profile: str
    distribution: str
    workspace: str
    n_poses: int
    failures: int
    first_order_lower: float
    first_order_upper: float
    failure_shares: pd.DataFrame = field(repr=False)
    target_cov: float | None = None

    @property
    def failure_probability(self) -> float:
        """``1 − estimate``."""
        return 1.0 - self.estimate

    @property
    def machine_evaluations(self) -> int:
        """Evaluations of the exact chain at every grid pose: one per simulated machine,
        whichever the method (``machines``); ``machines × n_poses`` pose evaluations."""
        return self.machines

    @property
    def interval(self) -> tuple[float, float]:
        """``(lower, upper)``."""
        return self.lower, self.upper

    @property
    def crude_equivalent(self) -> float:
        """Machines crude sampling would need for the same CoV: ``(1 − p)/(p · CoV²)`` with
        ``p`` the failure probability (NaN without a CoV)."""
        p = self.failure_probability
        if not (p > 0 and np.isfinite(self.cov) and self.cov > 0):
            return math.nan
        return (1.0 - p) / (p * self.cov ** 2)

    def model_text(self) -> str:
        """The modelling choices the yield depends on, in words."""
        reading = ("normal, σ = t/3, truncated at ±t" if self.distribution == "truncated"
                   else "normal, σ = t/3")
        return (f"profile {self.profile}, tolerances read as {reading} "
                f"(distribution {self.distribution!r}), workspace {self.workspace}")

    def summary(self) -> str:
        """A few readable lines: the yield, how it was estimated, its first-order bounds
        and the failure shares."""
        level = f"{self.confidence:.0%}"
        how = (f"crude Monte-Carlo of {self.machines:,} built machines, {self.failures:,} "
               f"failing (Clopper–Pearson interval)" if self.method == "crude" else
               f"importance sampling (defensive ALOE mixture) of {self.machines:,} built "
               f"machines, {self.failures:,} failing; crude sampling would need about "
               f"{_count_text(self.crude_equivalent)} machines for the same CoV")
        lines = [
            f"machine yield {yield_text(self.estimate)} ({level} interval "
            f"[{yield_text(self.lower)}, {yield_text(self.upper)}]); "
            f"failure probability {self.failure_probability:.3g}, CoV {self.cov:.3g}",
            f"  share of built machines with all six outputs within their limits at every "
            f"pose; {self.model_text()}",
            f"  {how}; {self.method_reason}",
            f"  first-order bounds (linearised model, union bound and best single row): "
            f"{yield_text(self.first_order_lower)} ≤ yield ≤ "
            f"{yield_text(self.first_order_upper)}"]
        if len(self.failure_shares):
            shares = self.failure_shares.head(SHOWN_SHARES).copy()
            for column in ("share", "lower", "upper"):
                shares[column] = (100 * shares[column]).map("{:.1f}".format)
            shares = shares.rename(columns={"share": "share [%]", "lower": f"{level} low",
                                            "upper": f"{level} high"})
            lines += ["  what fails first in failing machines (largest |y|/I over the grid):",
                      _indent(shares.to_string(index=False))]
            rest = self.failure_shares.iloc[SHOWN_SHARES:]
            if len(rest):
                lines.append(f"    and {len(rest)} more regions holding "
                             f"{100 * rest['share'].sum():.1f} % of the failures")
        return "\n".join(lines)

    def __repr__(self) -> str:
        return f"YieldEstimate:\n{self.summary()}"

    def to_frame(self) -> pd.DataFrame:
        """One row: the yield, its interval, the failure probability and its CoV, the
        method, the machines simulated and failing, the first-order bounds, the profile, the
        reading and the workspace (the failure shares are :attr:`failure_shares`)."""
        return pd.DataFrame([{
            "yield": self.estimate, "lower": self.lower, "upper": self.upper,
            "confidence": self.confidence, "failure_probability": self.failure_probability,
            "cov": self.cov, "method": self.method, "machines": self.machines,
            "failing": self.failures, "first_order_lower": self.first_order_lower,
            "first_order_upper": self.first_order_upper, "profile": self.profile,
            "distribution": self.distribution, "workspace": self.workspace}])

    def payload(self) -> dict:
        """The JSON-ready fields of the estimate, as :meth:`save` writes them (also the
        payload of a yield saved inside another result)."""
        payload = {name: getattr(self, name) for name in SAVED_FIELDS}
        payload["cov"] = None if math.isnan(self.cov) else self.cov
        payload["failure_shares"] = encode_frame(self.failure_shares)
        return payload

    @classmethod
    def from_payload(cls, data) -> "YieldEstimate":
        """The estimate written by :meth:`payload`, read through ``data`` (a
        :class:`~reliability.basics.saved_results.PayloadReader`) and checked.

        The verdicts are checked against the counts they come from: a crude estimate and
        its interval must be the Clopper–Pearson share of the machines that passed
        (``machines − failures``), an importance-sampling interval ``1 − (p ± z·se)`` of its
        failure probability and CoV, and the failure shares must sum to one over the failing
        machines.
        """
        machines = data.integer("machines", low=1)
        values = {
            "estimate": data.number("estimate"), "lower": data.number("lower"),
            "upper": data.number("upper"), "confidence": data.number("confidence"),
            "cov": math.nan if data.raw("cov") is None else data.number("cov"),
            "machines": machines,
            "method": data.text("method", ("crude", "importance")),
            "method_reason": data.text("method_reason"), "profile": data.text("profile"),
            "distribution": data.text("distribution", ("normal", "truncated")),
            "workspace": data.text("workspace"), "n_poses": data.integer("n_poses", low=1),
            "failures": data.integer("failures", low=0),
            "first_order_lower": data.number("first_order_lower"),
            "first_order_upper": data.number("first_order_upper"),
            "target_cov": None if data.raw("target_cov") is None else
            data.number("target_cov", positive=True)}
        _check_interval(data, values)
        values["failure_shares"] = _saved_shares(data, values["failures"])
        return cls(**values)

    def save(self, path, overwrite: bool = False):
        """Save as JSON with its metadata (:mod:`reliability.basics.saved_results`); an
        existing file is kept unless ``overwrite``. Returns the path."""
        return save_payload(path, SAVED_FORMAT, self.payload(), overwrite)

    @classmethod
    def load(cls, path) -> "YieldEstimate":
        """Reload an estimate written by :meth:`save`, checked as :meth:`from_payload` says;
        a damaged or inconsistent field raises
        :class:`~reliability.basics.errors.SavedResultError` naming the file and the field."""
        return cls.from_payload(load_payload(path, SAVED_FORMAT))

    def to_dict(self) -> dict:
        """Plain JSON-ready values (the shares as a list of rows)."""
        return {
            "estimate": self.estimate, "lower": self.lower, "upper": self.upper,
            "confidence": self.confidence, "cov": None if math.isnan(self.cov) else self.cov,
            "machines": self.machines, "machine_evaluations": self.machine_evaluations,
            "method": self.method,
            "method_reason": self.method_reason, "profile": self.profile,
            "distribution": self.distribution, "workspace": self.workspace,
            "n_poses": self.n_poses, "failures": self.failures,
            "first_order_lower": self.first_order_lower,
            "first_order_upper": self.first_order_upper, "target_cov": self.target_cov,
            "failure_shares": self.failure_shares.to_dict(orient="records")}


def _check_interval(data, values) -> None:
    """The saved yield and interval are what the saved counts (crude) or failure
    probability and CoV (importance sampling) give, or a SavedResultError."""
    if not 0.0 < values["confidence"] < 1.0:
        raise data.error("confidence", f"expected a level in (0, 1), got "
                                       f"{values['confidence']!r}")
    if values["failures"] > values["machines"]:
        raise data.error("failures", f"{values['failures']} failing of {values['machines']} "
                                     f"machines")
    if values["cov"] < 0:
        raise data.error("cov", f"expected a number >= 0 or null, got {values['cov']!r}")
    for key in ("estimate", "lower", "upper", "first_order_lower", "first_order_upper"):
        if not 0.0 <= values[key] <= 1.0:
            raise data.error(key, f"expected a yield in [0, 1], got {values[key]!r}")
    if values["method"] == "crude":
        interval = all_within_share(values["machines"] - values["failures"],
                                    values["confidence"], trials=values["machines"])
        expected = (interval.estimate, interval.lower, interval.upper)
    else:
        p = 1.0 - values["estimate"]
        spread = norm.ppf(0.5 + values["confidence"] / 2) * values["cov"] * p if p > 0 else 0.0
        expected = (values["estimate"], 1.0 - min(1.0, p + spread), 1.0 - max(0.0, p - spread))
    for key, value in zip(("estimate", "lower", "upper"), expected):
        if not math.isclose(values[key], float(value), rel_tol=1e-9, abs_tol=1e-12):
            raise data.error(key, f"is {values[key]!r}, but the saved {values['method']} "
                                  f"sample gives {float(value)!r}")


def _saved_shares(data, failures: int) -> pd.DataFrame:
    """The failure-share table, its shares summing to one over ``failures`` machines."""
    shares = data.frame("failure_shares", columns=SHARE_COLUMNS)
    if shares is None:
        raise data.error("failure_shares", "missing table")
    if len(shares) == 0:
        if failures:
            raise data.error("failure_shares", f"empty, with {failures} failing machines")
        return pd.DataFrame(columns=list(SHARE_COLUMNS))
    shares = shares[list(SHARE_COLUMNS)].reset_index(drop=True)
    counts = shares["failures"].to_numpy()
    if counts.sum() != failures or not math.isclose(float(shares["share"].sum()), 1.0,
                                                    rel_tol=1e-9):
        raise data.error("failure_shares", f"shares sum to {float(shares['share'].sum())!r} "
                                           f"over {counts.sum()} machines; expected 1 over "
                                           f"{failures}")
    return shares


class SampleSums:
    """Running sums of the weighted failure indicator and the failing machines' worst rows."""

    def __init__(self):
        self.n = 0
        self.total = 0.0
        self.squares = 0.0
        self.rows, self.weights = [], []

    def add(self, failed, worst, weight):
        terms = weight * failed
        self.n += len(failed)
        self.total += float(terms.sum())
        self.squares += float(np.square(terms).sum())
        self.rows.append(worst[failed])
        self.weights.append(weight[failed])

    def mean(self) -> float:
        return self.total / self.n

    def standard_error(self) -> float:
        mean = self.mean()
        variance = max(self.squares / self.n - mean ** 2, 0.0) * self.n / max(self.n - 1, 1)
        return math.sqrt(variance / self.n)

    def cov(self) -> float:
        mean = self.mean()
        return self.standard_error() / mean if mean > 0 else math.inf

    def result(self, model, sigma, confidence, method, reason, lower, upper, target_cov):
        """The :class:`YieldEstimate` of the machines added: crude (Clopper–Pearson) or
        importance sampling (``1 − (p ± z·se)``), with ``model``'s description and failure
        shares (``sigma``: every row's FOSM σ), and the first-order bounds ``lower``,
        ``upper``."""
        rows, weights = np.concatenate(self.rows), np.concatenate(self.weights)
        if method == "crude":
            passed = self.n - len(rows)
            interval = all_within_share(passed, confidence, trials=self.n)
            estimate, low, high = float(interval.estimate), float(interval.lower), \
                float(interval.upper)
            p = 1.0 - estimate
            cov = math.sqrt((1.0 - p) / (self.n * p)) if p > 0 else math.nan
        else:
            p, se = self.mean(), self.standard_error()
            z = norm.ppf(0.5 + confidence / 2)
            estimate, low, high = 1.0 - p, 1.0 - min(1.0, p + z * se), 1.0 - max(0.0, p - z * se)
            cov = se / p if p > 0 else math.nan
        shares = model.regions.failure_shares(sigma, rows, weights, confidence)
        return YieldEstimate(
            estimate=estimate, lower=low, upper=high, confidence=confidence, cov=cov,
            machines=self.n, method=method, method_reason=reason, profile=model.profile,
            distribution=model.distribution, workspace=model.workspace,
            n_poses=model.experiment.n_poses, failures=len(rows), first_order_lower=lower,
            first_order_upper=upper, failure_shares=shares, target_cov=target_cov)


def yield_text(value: float) -> str:
    """A yield readable near 1: ``0.8350`` or ``0.999871`` (never a rounded 1): at least
    four decimals, and two significant digits of the failure probability."""
    failure = 1.0 - value
    if failure <= 0:
        return "1"
    digits = max(4, 1 - int(math.floor(math.log10(failure))))
    return f"{value:.{digits}f}"


def _count_text(value: float) -> str:
    """A count with thousands separators, ``?`` when unknown."""
    return "?" if not np.isfinite(value) else f"{value:,.0f}"


def _indent(text: str, by: str = "    ") -> str:
    """``text`` with every line indented ``by``."""
    return "\n".join(by + line for line in text.splitlines())
