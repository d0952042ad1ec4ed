"""A measured machine's acceptance (``precrel evaluate``): the ISO 230-2, ISO 230-4 and
ISO 10791-6 values on hand-computed data and closed forms, the refusals of bad run files,
and the end-to-end ``measure`` → ``evaluate --machine`` on swivel5 with the percentile of a
machine drawn from the design uniform among the predicted machines."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest
from scipy import stats

import reliability
from reliability.acceptance.definitions import read_tests
from reliability.acceptance.evaluation import (circular_values, positioning_table,
                                               positioning_values, rotary_values)
from reliability.basics.errors import InputError
from reliability.basics.streams import acceptance_stream
from reliability.measured.acceptance_runs import acceptance_runs_from_frame
from reliability.measured.plans import read_plan
from reliability.measured.simulated_measurements import simulate_measurements
from studies.cli.program import main
from studies.report.extras import evaluation_builder, guarded
from studies.workflows.acceptance_evaluation import evaluate_against_design

ROOT = Path(__file__).resolve().parents[1]
SWIVEL = ROOT / "tests" / "machines" / "swivel5.toml"
SWIVEL_TESTS = ROOT / "tests" / "acceptance_tests" / "swivel5.toml"
SWIVEL_PLAN = ROOT / "docs" / "examples" / "swivel5_acceptance_plan.toml"
UM = 1e-3

# Two targets, three cycles (µm), worked by hand from ISO 230-2's definitions:
#   target 0:   ↑ 1, 2, 3 -> x̄↑ = 2, s↑ = 1;    ↓ -1, -1, -1 -> x̄↓ = -1, s↓ = 0
#   target 100: ↑ 4, 4, 4 -> x̄↑ = 4, s↑ = 0;    ↓ 0, 2, 4   -> x̄↓ = 2,  s↓ = 2
#   B_i = 3, 2 -> B = 3, B̄ = 2.5;   R_i↑ = 4, 0; R_i↓ = 0, 8; R_i = max(2+0+3, 4, 0) = 5,
#   max(0+4+2, 0, 8) = 8 -> R = 8, R↑ = 4, R↓ = 8;   E↑ = 4-2 = 2, E↓ = 2-(-1) = 3,
#   E = 4-(-1) = 5;   x̄_i = 0.5, 3 -> M = 2.5;   A↑ = max(4, 4) - min(0, 4) = 4,
#   A↓ = max(-1, 6) - min(-1, -2) = 8, A = max(4, 4, -1, 6) - min(0, 4, -1, -2) = 8.
HAND = np.array([[[1, 4], [-1, 0]], [[2, 4], [-1, 2]], [[3, 4], [-1, 4]]]) * UM
HAND_VALUES = {"E": 5, "E_up": 2, "E_down": 3, "M": 2.5, "R": 8, "R_up": 4, "R_down": 8,
               "B": 3, "B_mean": 2.5, "A": 8, "A_up": 4, "A_down": 8}


def test_positioning_values_are_the_hand_computed_ones():
    values = positioning_values(HAND)
    assert values == pytest.approx({k: v * UM for k, v in HAND_VALUES.items()}, abs=1e-15)
    table = positioning_table([0.0, 100.0], HAND)
    assert table["x_up"].to_numpy() == pytest.approx([2 * UM, 4 * UM])
    assert table["x_down"].to_numpy() == pytest.approx([-1 * UM, 2 * UM])
    assert table["s_down"].to_numpy() == pytest.approx([0.0, 2 * UM])
    assert table["B_i"].to_numpy() == pytest.approx([3 * UM, 2 * UM])
    assert table["R_i"].to_numpy() == pytest.approx([5 * UM, 8 * UM])


def test_the_mean_deviation_at_a_target_is_the_mean_over_cycles_not_positions():
    """Five targets, three cycles: dividing by the targets would scale x̄ by 3/5."""
    x = np.zeros((3, 2, 5))
    x[:, :, 2] = np.array([3.0, 6.0, 9.0])[:, None] * UM
    table = positioning_table(np.arange(5.0), x)
    assert table.loc[2, "x_up"] == pytest.approx(6 * UM)
    assert positioning_values(x)["E"] == pytest.approx(6 * UM)


def test_pure_reversal_and_pure_repeatability_in_closed_form():
    """±b/2 with no scatter: B = B̄ = E = R = A = b, E↑ = M = 0. Cycles −a, 0, a at every
    target and direction, no reversal: s = a, R = 4a, A = 4a, E = B = 0."""
    b, a = 2 * UM, 0.5 * UM
    reversal = np.broadcast_to(np.array([b / 2, -b / 2])[None, :, None], (4, 2, 6))
    values = positioning_values(reversal)
    for q in ("B", "B_mean", "E", "R", "A"):
        assert values[q] == pytest.approx(b, abs=1e-15)
    assert values["E_up"] == values["M"] == pytest.approx(0.0, abs=1e-15)
    scatter = np.broadcast_to(np.array([-a, 0.0, a])[:, None, None], (3, 2, 6))
    values = positioning_values(scatter)
    for q in ("R", "R_up", "A", "A_down"):
        assert values[q] == pytest.approx(4 * a, abs=1e-15)
    assert values["E"] == values["B"] == pytest.approx(0.0, abs=1e-15)


def _circle(radius, deviation, step_deg=5.0):
    theta = np.radians(np.arange(0.0, 360.0, step_deg))
    return theta, deviation(theta)


def test_a_pure_squareness_circle_has_g_alpha_r():
    """Out-of-squareness α between the axes: (x + α y, y) reads radially
    (α r / 2) sin 2θ to first order, so G = α r, F = ±α r / 2 and no hysteresis."""
    alpha, radius = 1e-5, 100.0
    theta = np.radians(np.arange(0.0, 360.0, 5.0))
    moved = np.stack([radius * np.cos(theta) + alpha * radius * np.sin(theta),
                      radius * np.sin(theta)], axis=-1)
    radial = np.linalg.norm(moved, axis=-1) - radius
    values = circular_values({"+": theta, "-": theta}, {"+": radial, "-": radial}, radius)
    second_order = alpha ** 2 * radius
    assert values["G"] == pytest.approx(alpha * radius, abs=second_order)
    assert values["G_plus"] == pytest.approx(alpha * radius, abs=second_order)
    assert values["F_max"] == pytest.approx(alpha * radius / 2, abs=second_order)
    assert values["F_min"] == pytest.approx(-alpha * radius / 2, abs=second_order)
    assert values["H"] == pytest.approx(0.0, abs=1e-12)


def test_hysteresis_of_two_concentric_paths_is_their_gap():
    """+ path at r + h/2, − path at r − h/2 (the − readings at other angles): H = G = h,
    G(+) = G(−) = 0, F = ±h/2."""
    h, radius = 3 * UM, 150.0
    plus, minus = np.radians(np.arange(0, 360, 10.0)), np.radians(np.arange(5, 360, 10.0))
    values = circular_values({"+": plus, "-": minus},
                             {"+": np.full(36, h / 2), "-": np.full(36, -h / 2)}, radius)
    assert values["H"] == pytest.approx(h, abs=1e-12)
    assert values["G"] == pytest.approx(h, abs=1e-12)
    assert values["G_plus"] == pytest.approx(0.0, abs=1e-12)
    assert (values["F_max"], values["F_min"]) == pytest.approx((h / 2, -h / 2), abs=1e-12)


def test_rotary_ranges_and_a_missing_direction_is_left_out():
    values = rotary_values({"dx": [0.001, -0.002, 0.0], "dz": [0.5, 0.5]})
    assert values == pytest.approx({"range_x": 0.003, "range_z": 0.0})
    with pytest.raises(InputError, match="deviations"):
        rotary_values({"ex": [1.0, 2.0]})


# ----------------------------------------------------------------------------- run files
def _positioning_rows(cycles=3, name="px"):
    rows = []
    for c in range(cycles):
        for d in range(2):
            for t, target in enumerate((0.0, 100.0)):
                rows.append({"run": name, "X_mm": target, "Y_mm": 5.0, "quantity": "dx",
                             "value": HAND[c % 3, d, t], "u": 1e-4, "cycle": c + 1,
                             "direction": "+-"[d]})
    return rows


def _read(rows):
    return acceptance_runs_from_frame(pd.DataFrame(rows).astype(object).fillna(""), "runs.csv")


def test_a_run_file_gives_the_hand_computed_values_and_a_warning_below_five_cycles():
    runs = _read(_positioning_rows())
    table = runs.evaluation_frame()
    assert list(table.columns) == ["run", "standard", "quantity", "value", "unit"]
    assert dict(zip(table["quantity"], table["value"])) == \
        pytest.approx({k: v * UM for k, v in HAND_VALUES.items()}, abs=1e-15)
    assert set(table["standard"]) == {"ISO 230-2"} and set(table["unit"]) == {"mm"}
    assert "3 cycles" in runs.warnings[0] and "ISO 230-2 asks for 5" in runs.warnings[0]


def test_a_line_run_without_cycles_is_left_out_and_named():
    rows = _positioning_rows() + [{"run": "laser", "X_mm": x, "Y_mm": 5.0, "quantity": "dy",
                                   "value": 0.0, "u": 1e-4, "cycle": "", "direction": ""}
                                  for x in (0.0, 50.0, 100.0)]
    runs = _read(rows)
    assert [run.name for run in runs.runs] == ["px"]
    assert "'laser'" in runs.left_out[0] and "not an acceptance run" in runs.left_out[0]


def _refused(rows, *, row, column, words):
    with pytest.raises(InputError) as caught:
        _read(rows)
    text = str(caught.value)
    assert f"row {row}, column {column!r}" in text and words in text, text


def test_bad_run_files_are_refused_naming_row_and_column():
    rows = _positioning_rows()
    missing = [dict(r) for r in rows]
    missing[4]["direction"] = ""
    _refused(missing, row=5, column="direction", words="missing direction")
    twice = [dict(r) for r in rows]
    twice[5]["cycle"] = 1                              # cycle 3's ↓ at 100 becomes cycle 1's
    _refused(twice, row=6, column="cycle", words="counted twice")
    fewer = [dict(r) for r in rows if not (r["cycle"] == 3 and r["X_mm"] == 100.0
                                           and r["direction"] == "-")]
    _refused(fewer, row=2, column="cycle", words="cycle 3 is missing")
    _refused(_positioning_rows(cycles=1), row=1, column="cycle",
             words="ISO 230-2 needs at least 2")
    angular = [dict(r) for r in rows]
    angular[2]["quantity"] = "ez"
    _refused(angular, row=3, column="quantity", words="mixed units")
    bad = [dict(r) for r in rows]
    bad[0]["direction"] = "up"
    _refused(bad, row=1, column="direction", words="expected + or -")


def test_an_axis_in_two_units_and_a_circle_that_is_no_circle_are_refused():
    frame = pd.DataFrame(_positioning_rows()).assign(X_deg="0")
    with pytest.raises(InputError, match="column 'X_deg': mixed units"):
        acceptance_runs_from_frame(frame.astype(str), "runs.csv")
    theta = np.radians(np.arange(0, 360, 30.0))
    circle = [{"run": "c", "X_mm": 100 * np.cos(a), "Y_mm": 50 * np.sin(a), "quantity": "radial",
               "value": 0.0, "u": 1e-4, "direction": "+"} for a in theta]
    with pytest.raises(InputError, match="do not lie on a circle"):
        _read(circle)
    round_ = [dict(r, Y_mm=100 * np.sin(a)) for r, a in zip(circle, theta)]
    partly = [dict(r, direction="" if i == 3 else "+") for i, r in enumerate(round_)]
    _refused(partly, row=4, column="direction", words="missing direction")
    unlabelled = [dict(r, direction="") for r in round_]
    with pytest.raises(InputError, match="no acceptance run"):
        _read(unlabelled)
    runs = _read(_positioning_rows() + unlabelled)
    assert "run 'c' reads radial without direction" in runs.left_out[0]


# ------------------------------------------------------------------------------ commands
def test_evaluate_writes_its_tables_and_figures_and_refuses_tests_without_a_machine(
        tmp_path, capsys):
    runs = tmp_path / "runs.csv"
    pd.DataFrame(_positioning_rows(cycles=5)).to_csv(runs, index=False)
    out = tmp_path / "ev"
    assert main(["evaluate", str(runs), "--out", str(out)]) == 0
    table = pd.read_csv(out / "evaluation.csv")
    assert list(table.columns) == ["run", "standard", "quantity", "value", "unit"]
    assert sorted(p.name for p in out.iterdir()) == \
        ["evaluation.csv", "evaluation_px.png", "positions.csv"]
    printed = capsys.readouterr().out
    assert "ISO 230-2" in printed and "B_mean" in printed
    assert main(["evaluate", str(runs), "--out", str(out)]) == 2
    assert "--overwrite" in capsys.readouterr().err
    assert main(["evaluate", str(runs), "--tests", str(SWIVEL_TESTS), "--out",
                 str(tmp_path / "other")]) == 2
    assert "--tests needs --machine" in capsys.readouterr().err


@pytest.fixture(scope="module")
def swivel():
    return reliability.load_machine(SWIVEL)


def test_measure_then_evaluate_against_the_design_end_to_end(tmp_path, capsys):
    readings = tmp_path / "meas.csv"
    assert main(["measure", str(SWIVEL), "--plan", str(SWIVEL_PLAN), "--out",
                 str(readings), "--seed", "3"]) == 0
    frame = pd.read_csv(readings, keep_default_na=False)
    positioning = frame[frame["run"] == "position_X"]
    assert set(positioning["direction"]) == {"+", "-"}
    assert sorted(set(positioning["cycle"].astype(str))) == ["1", "2", "3", "4", "5"]
    out = tmp_path / "ev"
    assert main(["evaluate", str(readings), "--machine", str(SWIVEL), "--tests",
                 str(SWIVEL_TESTS), "--machines", "200", "--out", str(out)]) == 0
    table = pd.read_csv(out / "evaluation.csv")
    assert list(table.columns) == ["run", "standard", "quantity", "value", "unit", "limit",
                                   "passes", "predicted_mean", "predicted_q95", "percentile"]
    compared = table.dropna(subset=["percentile"])
    assert set(zip(compared["run"], compared["quantity"])) == {
        ("circle_xy_r150", "G"), ("position_X", "E"), ("position_X", "A"),
        ("position_X", "R"), ("position_X", "B"), ("rotary_B", "range_x"),
        ("rotary_B", "range_y"), ("rotary_B", "range_z")}
    assert compared["percentile"].between(0, 1).all()
    assert (compared["passes"] == (compared["value"] < compared["limit"])).all()
    printed = capsys.readouterr().out
    assert "tests without a run of their name (not evaluated): position_Y, position_Z, " \
           "rotary_C" in printed


def test_the_percentile_of_a_machine_drawn_from_the_design_is_uniform(swivel):
    """200 machines drawn by ``measure``'s machinery, each evaluated against 2000 predicted
    machines: each quantity's 200 percentiles pass a Kolmogorov–Smirnov test against the
    uniform at α = 0.001 each (8 quantities, family-wise 0.008), and their mean lies within
    4 standard errors (z = 4, σ = 1/√12 /√200) of 1/2."""
    plan = read_plan(SWIVEL_PLAN, swivel)
    tests = read_tests(SWIVEL_TESTS, swivel)
    rng = np.random.default_rng(2026)
    percentiles = []
    result = None
    for _ in range(200):
        drawn = simulate_measurements(swivel, plan, profile=swivel.profile, rng=rng)
        runs = acceptance_runs_from_frame(drawn.measurements.to_frame(swivel).astype(str))
        if result is None:
            table, result, _ = evaluate_against_design(runs, swivel, tests, machines=2000,
                                                       rng=acceptance_stream(0))
            keys = list(zip(*table.dropna(subset=["percentile"])[["run", "quantity"]]
                            .to_numpy().T))
        values = runs.evaluation_frame().set_index(["run", "quantity"])["value"]
        percentiles.append([np.mean(result.values[key].to_numpy() <= values[key])
                            for key in keys])
    percentiles = np.array(percentiles)
    assert len(keys) == 8
    for key, column in zip(keys, percentiles.T):
        assert stats.kstest(column, "uniform").pvalue > 1e-3, key
        assert abs(column.mean() - 0.5) < 4 * np.sqrt(1 / 12 / 200), key


def test_with_a_machine_the_runs_are_checked_against_it(swivel):
    rows = [dict(r, Z_mm=250.0, C_deg=0.0, B_deg=0.0) for r in _positioning_rows(cycles=2)]
    assert acceptance_runs_from_frame(pd.DataFrame(rows).astype(str), "runs.csv", swivel).runs
    wrong = [dict(r, quantity="dy") for r in rows]
    with pytest.raises(InputError, match=r"row 1, column 'quantity'.*travels along dx"):
        acceptance_runs_from_frame(pd.DataFrame(wrong).astype(str), "runs.csv", swivel)
    outside = [dict(r, X_mm=r["X_mm"] * 5) for r in rows]
    with pytest.raises(InputError, match="column 'X_mm'.*outside the stroke"):
        acceptance_runs_from_frame(pd.DataFrame(outside).astype(str), "runs.csv", swivel)


def test_the_report_section_shows_the_evaluation_table(swivel, tmp_path):
    """``report --measurements meas.csv --tests`` adds "Acceptance as measured": the table
    ``evaluate --machine --tests`` writes, with the same numbers for the same machines,
    seed and profile."""
    readings = tmp_path / "meas.csv"
    assert main(["measure", str(SWIVEL), "--plan", str(SWIVEL_PLAN), "--out",
                 str(readings)]) == 0
    assert main(["evaluate", str(readings), "--machine", str(SWIVEL), "--tests",
                 str(SWIVEL_TESTS), "--machines", "100", "--seed", "4", "--out",
                 str(tmp_path / "ev")]) == 0
    check = SimpleNamespace(machine_yield=SimpleNamespace(profile=swivel.profile))
    study = SimpleNamespace(machine=swivel, machines=100, seed=4, checks={"initial": check})
    section = guarded("evaluation", evaluation_builder(readings, read_tests(SWIVEL_TESTS,
                                                                           swivel)))(study)
    assert section.title == "Acceptance as measured"
    written = pd.read_csv(tmp_path / "ev" / "evaluation.csv")
    shown = section.tables["evaluation.csv"]
    np.testing.assert_allclose(shown["percentile"].to_numpy(dtype=float),
                               written["percentile"].to_numpy(dtype=float), equal_nan=True)
    assert set(section.figures) == {"evaluation_circle_xy_r150.png",
                                    "evaluation_position_X.png"}
    assert section.summary["evaluation"]["position_X"] in (True, False)
