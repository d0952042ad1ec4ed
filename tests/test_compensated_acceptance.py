"""Acceptance tests after compensation: machines built to an allocation, measured under a
plan and compensated, through the same test simulation as before compensation
(docs/compensation.md, docs/acceptance.md)."""

from __future__ import annotations

import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd
from scipy.stats import norm

from reliability.acceptance.iso_statistics import circular_deviation
from reliability.acceptance.iso_tests import CircularTest, build_path, deviation_weights
from reliability.compensation.compensation_plans import (CompensationPlan,
                                                         parse_compensation_plan)
from reliability.compensation.residual import posterior_covariance
from studies import cli
from studies.report.extras import acceptance_builder
from studies.workflows.compensated_acceptance import (SUFFIX, comparison_frame,
                                                      compensated_acceptance)

#: Standard errors allowed in statistical checks.
Z = 4.0
TINY = 1e-9
ROOT = Path(__file__).resolve().parent.parent
CENTRE = {"Y": 200.0, "X": 0.0, "Z": -175.0}  # mill3, inside every stroke
RADIUS = 100.0


def _only(machine, **tolerances):
    """Every tolerance TINY except the named ones."""
    t = np.full(machine.n_errors, TINY)
    for name, value in tolerances.items():
        t[machine.error_index(name.replace("_", "-"))] = value
    return t


def _exact_plan(machine, name):
    """A plan that pins down the error ``name`` exactly and tables it alone."""
    index = machine.error_index(name)
    information = np.zeros((machine.n_errors, machine.n_errors))
    information[index, index] = 1e18
    tabled = np.zeros(machine.n_errors, dtype=bool)
    tabled[index] = True
    return CompensationPlan(machine, (), information, tabled, 10.0, 1.0)


def _mill3_plan(machine):
    """Laser runs along X and Y and a ballbar circle in xy, every informed item tabled."""
    def line(axis, at):
        return {"name": f"laser_{axis}", "kind": "line", "axis": axis, "line": at,
                "quantities": ["dx", "dy", "dz", "ex", "ey", "ez"], "u": 0.0005,
                "u_angle": 1e-6}
    ballbar = {"name": "ballbar", "kind": "circular", "plane": "xy", "centre": CENTRE,
               "radius": RADIUS, "limit": 1.0, "u": 0.0005}
    return parse_compensation_plan(
        {"tests": [line("X", {"Y": 200.0, "Z": -100.0}), line("Y", {"X": 0.0, "Z": -100.0}),
                   ballbar], "compensation": {"spacing_mm": 100.0}}, machine)


def test_a_squareness_identified_exactly_leaves_the_circle_to_the_other_error(mill3):
    # X.ez (constant) and the squareness Y-X.ez each turn X's travel about z, so the xy
    # circle is an ellipse with G = r |S ± e|; with S identified exactly and tabled, what
    # stays is G = r |e|: (G / rσ)² is χ²(1), mean 1, variance 2
    sigma, n = 2e-5 / 3, 2000
    t = _only(mill3, **{"Y_X.ez": 3 * sigma, "X.ez": 3 * sigma})
    circle = CircularTest("c", "xy", CENTRE, RADIUS, RADIUS * sigma)
    after = compensated_acceptance(_exact_plan(mill3, "Y-X.ez"), [circle], t, machines=n,
                                   rng=3)
    ratio = np.square(after.values[("c", "G")].to_numpy() / (RADIUS * sigma))
    assert abs(ratio.mean() - 1.0) < Z * math.sqrt(2.0 / n)
    # limit rσ: P(|e| < σ) = 2Φ(1) − 1
    expected = 2 * norm.cdf(1.0) - 1
    passed = after.to_frame().iloc[0]["pass_probability"]
    assert abs(passed - expected) < Z * math.sqrt(expected * (1 - expected) / n)
    # untabled, the squareness stays: G = r |S ± e|, (G / rσ)² has mean 2
    kept = compensated_acceptance(_exact_plan(mill3, "X.dx"), [circle], t, machines=n, rng=3)
    ratio = np.square(kept.values[("c", "G")].to_numpy() / (RADIUS * sigma))
    assert abs(ratio.mean() - 2.0) < Z * 2.0 * math.sqrt(2.0 / n)


def test_pass_probability_after_compensation_matches_independent_draws(mill3):
    # independent draws: each machine's errors x from the prior, the table's posterior mean
    # given x, m = P F x + η with η ~ N(0, P F P), r = x − S m; G by the ISO least-squares
    # circle of the points themselves
    plan, t, n = _mill3_plan(mill3), mill3.initial_allocation, 3000
    circle = CircularTest("c", "xy", CENTRE, RADIUS, 5e-5)
    predicted = compensated_acceptance(plan, [circle], t, machines=n, rng=11)
    p_model = predicted.to_frame().iloc[0]["pass_probability"]
    rng = np.random.default_rng(12)
    sd = t / 3.0
    posterior = posterior_covariance(sd, plan.information)
    gain = posterior @ plan.information
    noise = posterior @ plan.information @ posterior
    values, vectors = np.linalg.eigh(0.5 * (noise + noise.T))
    x = rng.standard_normal((n, mill3.n_errors)) * sd
    eta = rng.standard_normal((n, mill3.n_errors)) @ (vectors * np.sqrt(np.maximum(values,
                                                                                0))).T
    residual = x - plan.tabled * (x @ gain.T + eta)
    path = build_path(mill3, circle)
    along = np.einsum("poi,ni->npo", deviation_weights(mill3, path.poses), residual)
    points = path.nominal + along @ path.directions.T
    p_independent = np.mean(circular_deviation(points) <= circle.limit)
    se = math.sqrt(p_independent * (1 - p_independent) * 2 / n)
    assert 0.2 < p_independent < 0.8  # a probability the check can tell apart
    assert abs(p_model - p_independent) < Z * se


def test_comparison_keeps_the_columns_before_and_adds_the_compensated_ones(mill3):
    circle = CircularTest("c", "xy", CENTRE, RADIUS, 1e-3)
    plan, t = _exact_plan(mill3, "Y-X.ez"), _only(mill3, **{"Y_X.ez": 2e-5})
    before = compensated_acceptance(_exact_plan(mill3, "X.dx"), [circle], t, machines=300,
                                    rng=1)
    after = compensated_acceptance(plan, [circle], t, machines=300, rng=1)
    frame = comparison_frame(before, after, suggest=0.9)
    kept = list(before.to_frame().columns) + ["suggested_limit", "suggested_low",
                                              "suggested_high"]
    assert list(frame.columns[:len(kept)]) == kept
    assert "pass_probability" + SUFFIX in frame and "suggested_limit" + SUFFIX in frame
    row = frame.iloc[0]
    assert row["q05"] <= row["mean"] and row["mean" + SUFFIX] < 1e-3 * row["mean"]


def test_acceptance_command_prints_and_writes_results_after_compensation(tmp_path, capsys):
    plan = tmp_path / "plan.toml"
    plan.write_text('[[tests]]\nname = "ballbar"\nkind = "circular"\nplane = "xy"\n'
                    'centre = { Y = 200.0, X = 0.0, Z = -175.0 }\nradius = 100.0\n'
                    'limit = 1.0\nu = 0.0005\n\n[compensation]\nspacing_mm = 100.0\n')
    out = tmp_path / "acc.csv"
    cli.main(["acceptance", str(ROOT / "tests" / "machines" / "mill3.toml"), "--tests",
              str(ROOT / "tests" / "acceptance_tests" / "mill3.toml"), "--machines", "60",
              "--compensation", str(plan), "--out", str(out)])
    text = capsys.readouterr().out
    assert f"after compensation ({plan}: 1 runs" in text and "after: pass" in text
    frame = pd.read_csv(out)
    before = ["test", "quantity", "limit", "mean", "q95", "pass_probability", "pass_low",
              "pass_high"]
    assert list(frame.columns[:len(before)]) == before
    assert {"mean" + SUFFIX, "q95" + SUFFIX, "pass_probability" + SUFFIX} <= set(frame)


def test_report_section_shows_the_compensated_column_and_survives_a_failure(mill3,
                                                                           trunnion5):
    circle = CircularTest("c", "xy", CENTRE, RADIUS, 1e-3)
    study = SimpleNamespace(machine=mill3, reachable=False, compared=None, machines=50, seed=0,
                            checks={"initial": SimpleNamespace(
                                machine_yield=SimpleNamespace(profile="constant"))})
    section = acceptance_builder([circle], suggest=0.9, plan=_mill3_plan(mill3),
                                 plan_name="plan.toml")(study)
    assert "compensated pass" in section.text and "compensated suggested µm" in section.text
    assert "pass_probability" + SUFFIX in section.tables["acceptance_initial.csv"]
    assert "c/G" in section.summary["acceptance_compensated"]["initial"]
    # a plan of another machine: its tests' axes are refused, the section stays
    section = acceptance_builder([circle], plan=_exact_plan(trunnion5, "X.dx"),
                                 plan_name="plan.toml")(study)
    assert "not computed" in section.text
    assert "pass_probability" + SUFFIX not in section.tables["acceptance_initial.csv"]
