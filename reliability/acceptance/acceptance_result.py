"""The predicted acceptance-test results of machines built to one allocation, as a table,
as text and as a file.

A built machine passes a test when every limited quantity is within its limit, decided by
:func:`reliability.basics.pass_rule.passes`: a test value ``v >= 0`` passes when
``v < limit``, so a value exactly on its limit fails, as everywhere in the toolkit. The
pass probabilities carry Wilson score intervals. A saved result
(:meth:`AcceptanceResult.save`) reloads with its verdicts checked against the saved results.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from ..basics.errors import InputError
from ..basics.pass_rule import passes
from ..basics.saved_results import encode_frame, load_payload, save_payload
from ..basics.statistics import binomial_interval
from ..model.profiles import ConstantProfile, profile_model
from .definitions import parse_test, table_of_test

SAVED_FORMAT = "precrel.acceptance_result"
DISTRIBUTIONS = ("normal", "truncated")
DRIVER_COLUMNS = ("test", "quantity", "item", "share")


@dataclass(frozen=True, eq=False)
class AcceptanceResult:
    """Predicted acceptance-test results of machines built to one allocation.

    Attributes
    ----------
    tests : tuple
        The test definitions.
    values : pandas.DataFrame
        One row per built machine, columns ``(test, quantity)``: each result (mm).
    drivers : pandas.DataFrame
        Columns ``test, quantity, item, share``: each error item's share of the result's
        mean square, the item drawn alone on the first
        :data:`~reliability.acceptance.prediction.DRIVER_MACHINES` machines
        (shares of a quantity sum to 1; for a result linear in the items the single-item
        mean squares add up to the result's own).
    profile : str
        The error profile along travel (e.g. ``gp:300``).
    distribution : str
        The reading of a tolerance: ``normal`` or ``truncated`` at ±t, σ = t/k.
    k : float
    confidence : float
        Level of the Wilson score intervals on the pass probabilities.
    """

    tests: tuple
    values: pd.DataFrame
    drivers: pd.DataFrame
    profile: str
    distribution: str
    k: float = 3.0
    confidence: float = 0.95

    @property
    def n_machines(self) -> int:
        """Built machines simulated."""
        return len(self.values)

    def passed(self) -> pd.DataFrame:
        """Boolean frame, one column per test and ``all``: every limited quantity within its
        limit (:func:`~reliability.basics.pass_rule.passes`, ``value < limit``: a value
        exactly on its limit fails)."""
        out = {}
        for test in self.tests:
            ok = np.ones(self.n_machines, dtype=bool)
            for quantity, limit in test.limits.items():
                ok &= passes(self.values[(test.name, quantity)].to_numpy(), limit)
            out[test.name] = ok
        frame = pd.DataFrame(out)
        frame["all"] = frame.all(axis=1)
        return frame

    def to_frame(self) -> pd.DataFrame:
        """The ``acceptance.csv`` table: ``test, quantity, limit, mean, q95, pass_probability,
        pass_low, pass_high``; one row per test and quantity, then ``all, pass``.

        ``pass_*`` are empty for a quantity without a limit; the interval is the Wilson
        score interval at :attr:`confidence`.
        """
        rows = []
        for test in self.tests:
            for quantity in test.quantities:
                values = self.values[(test.name, quantity)].to_numpy()
                limit = test.limits.get(quantity, np.nan)
                row = {"test": test.name, "quantity": quantity, "limit": limit,
                       "mean": values.mean(), "q95": np.quantile(values, 0.95)}
                row.update(self._pass(passes(values, limit)) if quantity in test.limits else
                           dict.fromkeys(("pass_probability", "pass_low", "pass_high"),
                                         np.nan))
                rows.append(row)
        everything = self.passed()["all"].to_numpy()
        rows.append({"test": "all", "quantity": "pass", "limit": np.nan, "mean": np.nan,
                     "q95": np.nan, **self._pass(everything)})
        return pd.DataFrame(rows)

    def test_pass(self) -> pd.DataFrame:
        """Pass probability of each test (every limited quantity) and of all, with interval."""
        passed = self.passed()
        return pd.DataFrame([{"test": name, **self._pass(passed[name].to_numpy())}
                             for name in passed.columns])

    def top_drivers(self, test: str, quantity: str, n: int = 3) -> str:
        """The ``n`` items with the largest shares, e.g. ``"X.dx 61 %, Y-X.ez 22 %"``."""
        rows = self.drivers[(self.drivers["test"] == test)
                            & (self.drivers["quantity"] == quantity)]
        rows = rows.sort_values("share", ascending=False, kind="stable").head(n)
        return ", ".join(f"{r.item} {100 * r.share:.0f} %" for r in rows.itertuples()
                         if r.share >= 0.005)

    def summary(self) -> str:
        """The set-up (built machines, error profile, reading of a tolerance), then
        :meth:`results_text`."""
        return (f"{self.n_machines} built machines through {len(self.tests)} acceptance "
                f"tests; {profile_note(self.profile)}; tolerances read as "
                f"{self.distribution} with σ = t/{self.k:g}\n\n{self.results_text()}")

    def results_text(self) -> str:
        """Each result's limit, mean and 95 % quantile in µm, its pass probability with
        its interval and the items that drive it, then each test's pass probability: what
        ``precrel acceptance`` prints below its heading."""
        lines = [self._printed_table().to_string(index=False), "",
                 f"pass probability of each test (every limited quantity), Wilson "
                 f"{100 * self.confidence:g} %:"]
        lines += [f"  {row.test}: {row.pass_probability:.4f} "
                  f"[{row.pass_low:.4f}, {row.pass_high:.4f}]"
                  for row in self.test_pass().itertuples()]
        return "\n".join(lines)

    def _printed_table(self) -> pd.DataFrame:
        """:meth:`to_frame` with limits, means and quantiles in µm and the drivers."""
        rows = []
        for row in self.to_frame().itertuples():
            if row.test == "all":
                continue
            limited = pd.notna(row.limit)
            rows.append({
                "test": row.test, "quantity": row.quantity,
                "limit µm": f"{1000 * row.limit:.3g}" if limited else "-",
                "mean µm": f"{1000 * row.mean:.3g}", "q95 µm": f"{1000 * row.q95:.3g}",
                "pass": f"{row.pass_probability:.4f} [{row.pass_low:.4f}, "
                        f"{row.pass_high:.4f}]" if limited else "-",
                "driven by (share of mean square)":
                    self.top_drivers(row.test, row.quantity) or "-"})
        return pd.DataFrame(rows)

    def payload(self) -> dict:
        """The JSON-ready fields :meth:`save` writes: the tests in the test file's layout,
        every result of every machine, the drivers, the set-up and each test's count of
        passing machines (also the payload of a result saved inside another)."""
        return {"tests": [table_of_test(test) for test in self.tests],
                "values": self.values.to_numpy(), "drivers": encode_frame(self.drivers),
                "profile": self.profile, "distribution": self.distribution, "k": self.k,
                "confidence": self.confidence, "passing": self._passing()}

    def save(self, path, overwrite: bool = False):
        """Save as JSON with its metadata (:mod:`reliability.basics.saved_results`); an
        existing file is kept unless ``overwrite``. Returns the path."""
        return save_payload(path, SAVED_FORMAT, self.payload(), overwrite)

    @classmethod
    def load(cls, path) -> "AcceptanceResult":
        """Reload a result written by :meth:`save`, checked as :meth:`from_payload` says; a
        damaged or inconsistent field raises
        :class:`~reliability.basics.errors.SavedResultError` naming the file and the field."""
        return cls.from_payload(load_payload(path, SAVED_FORMAT))

    @classmethod
    def from_payload(cls, data) -> "AcceptanceResult":
        """The result written by :meth:`payload`, read through ``data`` (a
        :class:`~reliability.basics.saved_results.PayloadReader`).

        The tests are read as a test file's tables; the verdicts are kept: each test's count
        of passing machines, decided again from the saved results and limits, must be the
        saved count.
        """
        tests = _saved_tests(data)
        columns = result_columns(tests)
        values = data.array("values", (None, len(columns)), low=0.0)
        if len(values) < 1:
            raise data.error("values", "expected at least one built machine")
        drivers = data.frame("drivers", columns=DRIVER_COLUMNS)
        if drivers is None:
            raise data.error("drivers", "missing table")
        result = cls(tests=tests, values=pd.DataFrame(values, columns=columns),
                     drivers=drivers[list(DRIVER_COLUMNS)].reset_index(drop=True),
                     profile=data.text("profile"),
                     distribution=data.text("distribution", DISTRIBUTIONS),
                     k=data.number("k", positive=True),
                     confidence=data.number("confidence", positive=True))
        if not result.confidence < 1:
            raise data.error("confidence", f"expected a level in (0, 1), got "
                                           f"{result.confidence!r}")
        saved = data.table("passing")
        for name, count in result._passing().items():
            if saved.integer(name, low=0) != count:
                raise saved.error(name, f"{saved.data[name]} machines pass, but the saved "
                                        f"results pass {count} against the limits")
        return result

    def _passing(self) -> dict[str, int]:
        """Machines passing each test and all of them."""
        return {name: int(count) for name, count in self.passed().sum().items()}

    def _pass(self, ok) -> dict[str, float]:
        k, n = int(np.count_nonzero(ok)), len(ok)
        low, high = binomial_interval(k, n, self.confidence, method="wilson")
        return {"pass_probability": k / n, "pass_low": float(low), "pass_high": float(high)}


def profile_note(profile) -> str:
    """The error profile named with what it means for the tests, to print beside results."""
    model = profile_model(profile)
    if isinstance(model, ConstantProfile):
        return ("error profile constant (one value of every error per built machine along "
                "the whole travel: an axis' own positioning error is one offset, so "
                "positioning tests show only reversal and repeatability, and a circle is an "
                "exact ellipse with G proportional to its radius)")
    return (f"error profile {model} (Gaussian process along travel, correlation length "
            f"{model.length:g} mm)")


def result_columns(tests) -> pd.MultiIndex:
    """The ``(test, quantity)`` columns of :attr:`AcceptanceResult.values` for ``tests``."""
    return pd.MultiIndex.from_tuples([(test.name, q) for test in tests
                                      for q in test.quantities], names=["test", "quantity"])


def _saved_tests(data) -> tuple:
    """The saved tests, each read as a test file's table, names unique."""
    entries = data.raw("tests")
    if not isinstance(entries, list) or not entries:
        raise data.error("tests", "expected one or more test tables")
    tests = []
    for position, entry in enumerate(entries):
        if not isinstance(entry, dict):
            raise data.error("tests", f"entry {position} is not a table")
        try:
            tests.append(parse_test(entry, "tests", position))
        except InputError as exc:
            raise data.error("tests", str(exc)) from None
    names = [test.name for test in tests]
    if len(set(names)) != len(names):
        duplicate = next(n for n in names if names.count(n) > 1)
        raise data.error("tests", f"test name {duplicate!r} is used twice")
    return tuple(tests)
