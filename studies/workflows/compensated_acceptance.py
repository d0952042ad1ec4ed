"""Acceptance tests after compensation: each test's result on machines built to an
allocation, measured under a plan and compensated, beside the results before compensation
(docs/compensation.md, docs/acceptance.md).

A compensated machine keeps the residual errors of the residual model
(:meth:`reliability.compensation.compensation_plans.CompensationPlan.residual_covariance`,
``Cov(r) = P + (I − S)(Σ − P)(I − S)``), each one value per machine along the whole travel
(the constant profile, the one an identification holds). The residual errors are drawn
correlated from that covariance, carried to the tool point in the workpiece frame
(:func:`reliability.acceptance.iso_tests.deviation_weights`) and put through the same test
simulation as machines before compensation
(:func:`reliability.acceptance.prediction.results_of_deviations`): that simulation draws each
linear axis' repeatability (σ_R per approach) and reversal (±B/2 by the direction of
approach) in every run of a positioning test, as the residual model has them, and leaves
them out of circular and rotary tests, as before compensation.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from reliability.acceptance.acceptance_result import AcceptanceResult
from reliability.acceptance.iso_tests import build_path, deviation_weights
from reliability.acceptance.prediction import results_of_deviations
from reliability.acceptance.suggested_limits import suggest_limits
from reliability.basics import checks, streams
from reliability.basics.chunks import chunks
from reliability.basics.display import decimals_text
from reliability.compensation.compensation_plans import K
from reliability.model.error_draws import psd_factor

#: The suffix of the columns after compensation in ``acceptance.csv``.
SUFFIX = "_compensated"
#: Columns of one result taken from each side: its distribution and pass probability.
RESULT_COLUMNS = ("mean", "q05", "q95", "pass_probability", "pass_low", "pass_high")
#: Columns added with suggested limits.
SUGGESTED_COLUMNS = ("suggested_limit", "suggested_low", "suggested_high")
#: The residual model's profile along travel.
RESIDUAL_PROFILE = "constant"


def compensated_acceptance(plan, tests, tolerances=None, *, machines: int = 2000,
                           confidence: float = 0.95, rng=None) -> AcceptanceResult:
    """Acceptance-test results of machines built to ``tolerances``, measured under ``plan``
    and compensated.

    Parameters
    ----------
    plan : CompensationPlan
        :func:`reliability.compensation.compensation_plans.read_compensation_plan`.
    tests : sequence of CircularTest, PositioningTest, RotaryTest
    tolerances : array_like, optional
        ``(n_errors,)`` allocation (mm, rad); the machine's initial allocation by default.
    machines : int
        Compensated machines drawn.
    confidence : float
        Level of the Wilson intervals on the pass probabilities.
    rng : None, int or Generator
        ``precrel acceptance --compensation`` draws from
        :func:`reliability.basics.streams.compensated_acceptance_stream`.

    Returns
    -------
    AcceptanceResult
        Its ``drivers`` are empty; its profile is ``constant``, the residual model's.
    """
    machine = plan.machine
    machines = checks.positive_int(machines, "machines")
    t = machine.initial_allocation if tolerances is None else \
        machine.check_tolerances(tolerances)
    tests = tuple(tests)
    poses = np.concatenate([build_path(machine, test).poses for test in tests])
    weights = deviation_weights(machine, poses)
    factor = psd_factor(plan.residual_covariance(t))
    rng = streams.generator(rng)
    values = []
    for part in chunks(machines, 8 * len(poses) * (3 + machine.n_errors)):
        residual = rng.standard_normal((part.stop - part.start, len(factor))) @ factor.T
        values.append(results_of_deviations(
            machine, tests, np.einsum("poi,mi->mpo", weights, residual), rng))
    return AcceptanceResult(tests=tests, values=pd.concat(values, ignore_index=True),
                            drivers=pd.DataFrame(columns=["test", "quantity", "item",
                                                          "share"]),
                            profile=RESIDUAL_PROFILE, distribution="normal", k=K,
                            confidence=confidence)



def comparison_frame(before: AcceptanceResult, after: AcceptanceResult,
                     suggest: float | None = None) -> pd.DataFrame:
    """The ``acceptance.csv`` table with the results after compensation beside.

    The columns of :meth:`AcceptanceResult.to_frame` (and of suggested limits with
    ``suggest``) stay as they are; then ``q05`` before compensation, and every one of
    :data:`RESULT_COLUMNS` (and :data:`SUGGESTED_COLUMNS`) after it, with the suffix
    :data:`SUFFIX`.
    """
    frame = _side(before, suggest)
    shown = _side(after, suggest)
    names = RESULT_COLUMNS + (SUGGESTED_COLUMNS if suggest is not None else ())
    for name in names:
        frame[name + SUFFIX] = shown[name].to_numpy()
    return frame


def _side(result, suggest) -> pd.DataFrame:
    """One side's table: :meth:`to_frame` (with suggested limits) and its 5 % quantile."""
    frame = result.to_frame() if suggest is None else suggest_limits(result, suggest).to_frame()
    frame["q05"] = [result.values[(row.test, row.quantity)].quantile(0.05)
                    if row.test != "all" else np.nan for row in frame.itertuples()]
    return frame


def comparison_text(frame: pd.DataFrame) -> str:
    """The table of :func:`comparison_frame` as printed: each result before and after
    compensation, mean (5–95 %) in µm, pass probability with its interval, suggested limit
    when there is one; then each test's and all tests' pass probability."""
    results = frame[frame["quantity"] != "pass"]
    table = pd.DataFrame({
        "test": results["test"], "quantity": results["quantity"],
        "limit µm": [_micrometres(v) for v in results["limit"]]})
    for label, suffix in (("before", ""), ("after", SUFFIX)):
        table[f"{label} µm (q05–q95)"] = [
            f"{_micrometres(m)} ({_micrometres(lo)}–{_micrometres(hi)})" for m, lo, hi in
            zip(results["mean" + suffix], results["q05" + suffix], results["q95" + suffix])]
        table[f"{label}: pass"] = _passes(results, suffix)
        if "suggested_limit" in frame:
            table[f"{label}: suggested µm"] = [_micrometres(v) for v in
                                               results["suggested_limit" + suffix]]
    everything = frame[frame["quantity"] == "pass"].iloc[0]
    return (table.to_string(index=False) + "\n\npass probability of all tests, Wilson "
            f"intervals: before {_interval(everything, '')}, after compensation "
            f"{_interval(everything, SUFFIX)}")


def _passes(rows, suffix) -> list[str]:
    return ["-" if pd.isna(row["pass_probability" + suffix]) else _interval(row, suffix)
            for _, row in rows.iterrows()]


def _interval(row, suffix) -> str:
    """A pass probability to four decimals, its interval's ends rounded outward."""
    return (f"{row['pass_probability' + suffix]:.4f} "
            f"[{decimals_text(row['pass_low' + suffix], 4, 'lower')}, "
            f"{decimals_text(row['pass_high' + suffix], 4, 'upper')}]")


def _micrometres(value) -> str:
    return "-" if pd.isna(value) else f"{1000 * value:.3g}"
