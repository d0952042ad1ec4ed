"""A measured machine's acceptance against its tests and against the machines the design
predicted (``precrel evaluate --machine --tests``, docs/acceptance.md).

Each acceptance run is matched to the test of the same name. For each of the test's
quantities the measured value gets the test's ``limit`` and whether it ``passes``
(``value < limit``, :func:`reliability.basics.pass_rule.passes`), and, from the machines
built to the allocation as the acceptance prediction draws them
(:func:`reliability.acceptance.prediction.acceptance`: the same tests, profile, stream and
machines as ``precrel acceptance``), ``predicted_mean``, ``predicted_q95`` and the
``percentile``: the share of predicted machines whose value is ≤ the measured one. A machine
drawn from the predicted distribution has a percentile uniform on [0, 1] (discrete on
``k/N``), which the tests check on simulated machines.

A circular test's ``G`` is compared with the bidirectional ``G`` (the prediction's two
directions coincide); a run read in one direction gives that direction's ``G`` instead.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from reliability.acceptance.iso_tests import TEST_TYPES
from reliability.acceptance.prediction import acceptance
from reliability.basics.errors import InputError
from reliability.basics.pass_rule import passes

#: Columns ``evaluate --machine`` adds to ``evaluation.csv``.
DESIGN_COLUMNS = ("limit", "passes", "predicted_mean", "predicted_q95", "percentile")
#: A measured value at or above this percentile of the predicted machines is among the
#: worst 10 %: its drivers are named.
WORST_SHARE = 0.9
#: The measured quantity a test's quantity is compared with, in order of preference.
MEASURED_AS = {"G": ("G", "G_plus", "G_minus")}


def matched_tests(runs, tests) -> tuple:
    """The tests that have a run of their name, in the tests' order, kinds checked.

    Raises
    ------
    InputError
        Naming the test and the run when a run of a test's name is of another kind, or when
        no test has a run.
    """
    by_name = {run.name: run for run in runs.runs}
    matched = []
    for test in tests:
        if not isinstance(test, TEST_TYPES):
            raise InputError(f"tests: expected acceptance tests; got {type(test).__name__}")
        run = by_name.get(test.name)
        if run is None:
            continue
        if run.kind != test.kind:
            raise InputError(f"test {test.name!r} is a {test.kind} test, but the run of that "
                             f"name is a {run.kind} run")
        matched.append(test)
    if not matched:
        raise InputError(f"no run has the name of a test; the runs are "
                         f"{', '.join(by_name)}, the tests {', '.join(t.name for t in tests)}")
    return tuple(matched)


def evaluate_against_design(runs, machine, tests, tolerances=None, *, machines: int = 2000,
                            profile=None, rng=None):
    """The measured values beside the tests' limits and the predicted machines.

    Parameters
    ----------
    runs : AcceptanceRuns
        :func:`reliability.measured.acceptance_runs.read_acceptance_runs`.
    machine : Machine
    tests : sequence of CircularTest, PositioningTest, RotaryTest
        Matched to runs by name (:func:`matched_tests`).
    tolerances : array_like, optional
        The allocation the machine was built to; its initial allocation by default.
    machines : int
        Predicted machines.
    profile : str, optional
        Error profile along travel; the machine's by default.
    rng : seed or Generator
        ``precrel evaluate`` passes ``acceptance_stream(seed)``, as ``precrel acceptance``.

    Returns
    -------
    table : pandas.DataFrame
        ``evaluation.csv``: the runs' values with :data:`DESIGN_COLUMNS` (empty where the
        run or quantity has no test).
    result : AcceptanceResult
        The prediction.
    tests : tuple
        The matched tests.
    """
    tests = matched_tests(runs, tests)
    result = acceptance(machine, tests, tolerances, machines=machines,
                        profile=machine.profile if profile is None else profile, rng=rng)
    table = runs.evaluation_frame()
    for column in DESIGN_COLUMNS:
        table[column] = pd.Series(np.nan, index=table.index, dtype=object if
                                  column == "passes" else float)
    for test in tests:
        for quantity in test.quantities:
            row = _measured_row(table, test.name, quantity)
            if row is None:
                continue
            value = table.at[row, "value"]
            predicted = result.values[(test.name, quantity)].to_numpy()
            table.at[row, "predicted_mean"] = predicted.mean()
            table.at[row, "predicted_q95"] = np.quantile(predicted, 0.95)
            table.at[row, "percentile"] = np.mean(predicted <= value)
            if quantity in test.limits:
                table.at[row, "limit"] = test.limits[quantity]
                table.at[row, "passes"] = bool(passes(value, test.limits[quantity]))
    return table, result, tests


def _measured_row(table, run, quantity):
    """The row of ``table`` holding the measured value the test's ``quantity`` is compared
    with, or None."""
    for name in MEASURED_AS.get(quantity, (quantity,)):
        rows = table.index[(table["run"] == run) & (table["quantity"] == name)]
        if len(rows):
            return rows[0]
    return None


def verdicts_by_test(table, tests) -> pd.DataFrame:
    """``test, passes``: a test passes when every limited quantity passes."""
    rows = []
    for test in tests:
        verdicts = table.loc[(table["run"] == test.name) & table["passes"].notna(), "passes"]
        rows.append({"test": test.name, "passes": bool(verdicts.all()) if len(verdicts)
                     else np.nan})
    return pd.DataFrame(rows, columns=["test", "passes"])


def worst_sentences(table, result, tests) -> list[str]:
    """One sentence per test with a quantity among the worst :data:`WORST_SHARE` of the
    predicted machines, naming what drives that quantity at design time."""
    sentences = []
    for test in tests:
        rows = table[(table["run"] == test.name) & (table["percentile"] >= WORST_SHARE)]
        if rows.empty:
            continue
        parts = []
        for row in rows.itertuples():
            quantity = next(q for q in test.quantities
                            if row.quantity in MEASURED_AS.get(q, (q,)))
            drivers = result.top_drivers(test.name, quantity) or "no single item"
            parts.append(f"{row.quantity} = {1000 * row.value:.3g} µm is at or above "
                         f"{100 * row.percentile:.1f} % of the predicted machines (driven at "
                         f"design time by {drivers})")
        sentences.append(f"{test.name}: among the worst {100 * (1 - WORST_SHARE):.0f} % of "
                         f"the predicted machines: {'; '.join(parts)}.")
    return sentences


def printed_table(table) -> pd.DataFrame:
    """``evaluation.csv`` for people: values, limits and predictions in µm to three
    significant digits, verdicts as yes/NO, percentiles in % to 0.1 %."""
    shown = table[["run", "standard", "quantity"]].copy()
    shown["value µm"] = [f"{1000 * v:.3g}" for v in table["value"]]
    if "limit" in table:
        shown["limit µm"] = [_um(v) for v in table["limit"]]
        shown["passes"] = ["-" if pd.isna(v) else "yes" if v else "NO"
                           for v in table["passes"]]
        shown["predicted mean µm"] = [_um(v) for v in table["predicted_mean"]]
        shown["predicted q95 µm"] = [_um(v) for v in table["predicted_q95"]]
        shown["percentile"] = ["-" if pd.isna(v) else f"{100 * v:.1f} %"
                               for v in table["percentile"]]
    return shown


def _um(value) -> str:
    return "-" if pd.isna(value) else f"{1000 * value:.3g}"
