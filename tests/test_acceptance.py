"""Acceptance tests at design time (reliability.acceptance.prediction,
reliability.acceptance.definitions, precrel acceptance): closed forms, an independent simulation,
bad test files, the CSV.

Statistical checks use z = 4 on the estimator's standard error, with fixed seeds."""

from __future__ import annotations

import copy
import inspect
import json
import math
import tomllib
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy.stats import norm

from reliability import load_machine, machine_from_dict
from reliability.acceptance.acceptance_result import AcceptanceResult
from reliability.acceptance.definitions import read_tests, parse_tests
from reliability.acceptance.iso_statistics import (circular_deviation, default_targets,
                                                   positioning_statistics)
from reliability.acceptance.iso_tests import (CircularTest, PositioningTest, RotaryTest,
                                              build_path, deviation_weights, ideal_chain)
from reliability.acceptance.prediction import acceptance
from reliability.basics.errors import InputError, MachineDescriptionError, SavedResultError
from reliability.model.measured_profiles import SystematicErrors, measured_profile
from studies import cli

MACHINES = Path(__file__).parent / "machines"
EXAMPLES = Path(__file__).parent.parent / "docs" / "examples"
Z = 4.0
TINY = 1e-12  # a tolerance that makes an error item vanish beside the others
CENTRE = {"Y": 200.0, "X": 0.0, "Z": -175.0}  # mill3, inside every stroke


def _mill_dict():
    return tomllib.loads((MACHINES / "mill3.toml").read_text())


def _mill(**x_axis):
    """mill3 with extra keys on its X axis (repeatability, reversal)."""
    data = _mill_dict()
    data["axes"][1].update(x_axis)
    return machine_from_dict(data)


def _only(machine, **tolerances):
    """Every tolerance TINY except the named ones."""
    t = np.full(machine.n_errors, TINY)
    for name, value in tolerances.items():
        t[machine.error_index(name.replace("_", "-"))] = value
    return t


def _x_test(targets=None, limits=None, runs=5):
    return PositioningTest("position_X", "X", {"Y": 200.0, "Z": -175.0},
                           limits or {"E": 0.01}, targets, runs)


# ----- ISO statistics against closed forms ---------------------------------------------
def test_ellipse_of_a_squareness_has_g_equal_to_radius_times_squareness():
    radius, squareness = 100.0, 2e-5
    theta = 2 * np.pi * np.arange(360) / 360
    points = np.stack([radius * np.cos(theta),
                       radius * np.sin(theta) + squareness * radius * np.cos(theta)], -1)
    # first order: G = r |S|; the rest is O(r S²) = 4e-8 mm
    assert circular_deviation(points + [3.0, -2.0]) == pytest.approx(radius * squareness,
                                                                       rel=1e-3)


def test_least_squares_centre_is_found_for_an_offset_circle_with_a_lobe():
    theta = np.linspace(0, 2 * np.pi, 360, endpoint=False)
    radial = 50.0 + 0.001 * np.cos(3 * theta)  # three lobes: G = 0.002 about the true centre
    points = np.stack([radial * np.cos(theta), radial * np.sin(theta)], -1) + [0.01, -0.02]
    assert circular_deviation(points) == pytest.approx(0.002, rel=1e-6)


def test_fast_circle_fit_agrees_with_the_least_squares_circle(mill3):
    from reliability.acceptance import prediction as module
    path = build_path(mill3, CircularTest("c", "xy", CENTRE, 80.0, 1.0))
    rng = np.random.default_rng(12)
    theta = np.linspace(0, 2 * np.pi, 360, endpoint=False)
    along = (0.01 * rng.standard_normal((50, 1, 2))       # centre offsets up to ~30 µm
             + 0.002 * rng.standard_normal((50, 1, 1)) * np.cos(2 * theta)[:, None]
             + 0.001 * rng.standard_normal((50, 1, 1)) * np.sin(5 * theta)[:, None])
    fast = module._circle_g(path, along)
    assert np.allclose(fast, circular_deviation(path.nominal + along, iterations=4),
                       rtol=0, atol=1e-7)


def test_reversal_and_systematic_errors_by_iso_230_2():
    systematic = np.array([0.0, 0.001, 0.003])  # mm
    b = 0.002
    runs = np.broadcast_to(systematic + np.array([[b / 2], [-b / 2]]), (5, 2, 3))
    stats = positioning_statistics(runs)
    assert stats["B"] == pytest.approx(b)
    assert stats["E"] == pytest.approx(0.003 + b)        # max x̄↑ − min x̄↓
    assert stats["E_up"] == pytest.approx(0.003)
    assert stats["M"] == pytest.approx(0.003)
    assert stats["R"] == pytest.approx(b)                 # 2 s↑ + 2 s↓ + |B_i|, s = 0
    assert stats["R_up"] == 0.0 and stats["A"] == pytest.approx(stats["E"])


def test_unidirectional_repeatability_is_four_sigma():
    sigma, runs, n = 0.0007, 5, 20_000
    x = sigma * np.random.default_rng(3).standard_normal((n, runs, 2, 7))
    stats = positioning_statistics(x)
    s = x.std(axis=1, ddof=1)
    assert np.allclose(stats["R_up"], 4 * s[:, 0, :].max(axis=-1), rtol=1e-12)
    # at one target R↑ = 4 s↑, and (R↑/4)² = s² estimates σ² with Var(s²) = 2σ⁴/(n−1)
    one = positioning_statistics(x[..., :1])["R_up"]
    standard_error = sigma ** 2 * math.sqrt(2 / (runs - 1) / n)
    assert abs(np.mean((one / 4) ** 2) - sigma ** 2) < Z * standard_error
    assert np.mean(one) == pytest.approx(4 * sigma, rel=0.07)  # E[s] = c4 σ, c4(5) = 0.94


def test_default_targets_follow_the_spacing_rule():
    short = default_targets((0.0, 400.0))
    assert len(short) == 5 and short[0] == 0.0 and short[-1] == 400.0
    long = default_targets((-1000.0, 1500.0))
    assert len(long) == math.ceil(5 * 2.5)
    spacing = 2500.0 / (len(long) - 1)
    uniform = -1000.0 + spacing * np.arange(len(long))
    assert np.all(np.diff(long) > 0) and np.all(np.abs(long - uniform) <= 0.2 * spacing)
    assert len(np.unique(np.round(np.diff(long), 6))) > 2  # not uniform


# ----- the path model against the exact model ------------------------------------------
def test_workpiece_frame_deviation_agrees_with_the_exact_model(trunnion5):
    rng = np.random.default_rng(5)
    low = np.array([0.0, -2.0, -250.0, -400.0, 0.0])
    high = np.array([6.28, 0.5, 250.0, 400.0, 500.0])
    q = low + (high - low) * rng.random((40, 5))
    x = 3e-3 / 3 * rng.standard_normal((40, trunnion5.n_errors))
    x[:, [i for i, n in enumerate(trunnion5.error_names) if ".e" in n]] *= 5e-3
    weights = deviation_weights(trunnion5, q)

    def neglected(errors):
        exact = (ideal_chain(trunnion5, q)[:, :3, :3] @
                 trunnion5.comprehensive_error(q, errors)[:, :3, None])[..., 0]
        return np.max(np.abs(np.einsum("poi,pi->po", weights, errors) - exact))

    # what the first order leaves out is of second order: a tenth of the errors, a hundredth
    assert neglected(x) < 1e-6
    assert 80 < neglected(x) / neglected(x / 10) < 120


def test_circle_path_keeps_the_tool_point_on_the_circle(trunnion5):
    test = CircularTest("c", "xy", {"C": 0.0, "A": 0.0, "Y": 0.0, "X": 0.0, "Z": 250.0},
                        150.0, 0.01)
    path = build_path(trunnion5, test)
    points = ideal_chain(trunnion5, path.poses)[:, :3, 3]
    centre = ideal_chain(trunnion5, path.poses[:1] * [1, 1, 0, 0, 1])[0, :3, 3]
    assert np.allclose(np.linalg.norm(points[:, :2] - centre[:2], axis=1), 150.0)
    assert np.allclose(points[:, 2], centre[2])


def test_rotary_path_holds_the_ideal_tool_point(trunnion5):
    centre = {"C": 0.0, "A": 0.0, "Y": 0.0, "X": 0.0, "Z": 250.0}
    for axis, sweep in (("C", None), ("A", (-1.0, 0.5))):
        path = build_path(trunnion5, RotaryTest("r", axis, centre, {"range_x": 0.01}, sweep))
        points = ideal_chain(trunnion5, path.poses)[:, :3, 3]
        assert np.allclose(points, points[0], atol=1e-9)
        assert np.ptp(path.poses[:, trunnion5.axes.index(axis)]) > 1.0


# ----- closed forms through the whole computation -------------------------------------
def test_pure_squareness_gives_g_equal_to_r_times_the_squareness(mill3):
    sigma, radius, n = 2e-5 / 3, 100.0, 4000
    t = _only(mill3, **{"Y_X.ez": 3 * sigma})
    result = acceptance(mill3, [CircularTest("c", "xy", CENTRE, radius, radius * sigma)], t,
                        machines=n, profile="constant", rng=1)
    g = result.values[("c", "G")].to_numpy()
    # G = r |S| with S ~ N(0, σ²): (G / rσ)² is χ²(1), mean 1, variance 2
    ratio = np.square(g / (radius * sigma))
    assert abs(ratio.mean() - 1.0) < Z * math.sqrt(2.0 / n)
    # limit rσ: P(|S| < σ) = 2Φ(1) − 1
    p = result.to_frame().iloc[0]["pass_probability"]
    expected = 2 * norm.cdf(1.0) - 1
    assert abs(p - expected) < Z * math.sqrt(expected * (1 - expected) / n)
    assert set(result.drivers["item"]) == {"Y-X.ez"}


def test_constant_profile_makes_g_proportional_to_the_radius(mill3):
    tests = [CircularTest("r50", "xy", CENTRE, 50.0, 1.0),
             CircularTest("r100", "xy", CENTRE, 100.0, 1.0)]
    result = acceptance(mill3, tests, machines=300, profile="constant", rng=2)
    g50, g100 = (result.values[(name, "G")].to_numpy() for name in ("r50", "r100"))
    # exactly proportional to first order; second order is |Δ|²/r < (2 µm)²/50 mm < 1e-7 mm
    assert np.allclose(g100, 2 * g50, rtol=0, atol=1e-7)
    assert np.median(g100) > 1e-4


def test_linear_measured_profile_gives_e_equal_to_slope_times_length(mill3):
    slope = 2e-5  # mm per mm
    stroke = np.array([-300.0, 300.0])
    bow = measured_profile(mill3, "X.dx", stroke, slope * stroke)
    result = acceptance(mill3, [_x_test(targets=(-300.0, -120.0, 10.0, 150.0, 300.0))],
                        _only(mill3), machines=20, systematic=SystematicErrors(mill3, [bow]),
                        rng=3)
    e = result.values[("position_X", "E")].to_numpy()
    assert np.allclose(e, slope * 600.0, rtol=1e-9)
    assert set(result.drivers["item"]) == {"X.dx"}


def test_constant_profile_leaves_positioning_with_reversal_and_repeatability_only():
    machine = _mill(reversal=0.001)
    result = acceptance(machine, [_x_test()], machines=200, profile="constant", rng=4)
    assert np.allclose(result.values[("position_X", "E")], 0.001, atol=1e-12)
    assert np.allclose(result.values[("position_X", "B")], 0.001, atol=1e-12)


def test_reversal_b_gives_b_on_every_machine():
    machine = _mill(reversal=0.0025)
    result = acceptance(machine, [_x_test(limits={"B": 0.003})], machines=300, rng=5)
    assert np.allclose(result.values[("position_X", "B")], 0.0025, rtol=0, atol=1e-12)
    share = result.drivers.query("quantity == 'B'").set_index("item")["share"]
    assert share.to_dict() == {"X.reversal": 1.0}


def _bidirectional_r(sigma, runs, targets, n, rng):
    """An independent simulation of ISO 230-2's bidirectional R from pure repeatability."""
    x = sigma * rng.standard_normal((n, runs, 2, targets))
    s = x.std(axis=1, ddof=1)
    b = np.abs(x.mean(axis=1)[:, 0] - x.mean(axis=1)[:, 1])
    r = np.maximum(2 * s[:, 0] + 2 * s[:, 1] + b, 4 * np.maximum(s[:, 0], s[:, 1]))
    return r.max(axis=1)


def test_repeatability_against_an_independent_simulation():
    sigma, n = 0.0005, 3000
    machine = _mill(repeatability=sigma)
    result = acceptance(machine, [_x_test(limits={"R": 4.5 * sigma})], _only(machine),
                        machines=n, rng=6)
    ours = result.values[("position_X", "R")].to_numpy()
    theirs = _bidirectional_r(sigma, 5, 5, n, np.random.default_rng(60))
    se = math.sqrt(ours.var() / n + theirs.var() / n)
    assert abs(ours.mean() - theirs.mean()) < Z * se
    p, q = np.mean(ours <= 4.5 * sigma), np.mean(theirs <= 4.5 * sigma)
    assert abs(p - q) < Z * math.sqrt(p * (1 - p) / n + q * (1 - q) / n)


def _independent_circle(machine, t, radius, length, n, rng):
    """A circle on mill3 simulated independently: own Gaussian-process draws along the
    visited positions, the exact model of Eq. 18, an algebraic (Kåsa) circle fit."""
    theta = 2 * np.pi * np.arange(360) / 360
    q = np.tile([CENTRE["Y"], CENTRE["X"], CENTRE["Z"]], (360, 1))
    q[:, 1] += radius * np.cos(theta)  # X along x
    q[:, 0] += radius * np.sin(theta)  # Y along y
    x = np.zeros((n, 360, machine.n_errors))
    for a in range(3):
        d = q[:, a, None] - q[None, :, a]
        c = np.exp(-0.5 * (d / length) ** 2) + 1e-8 * np.eye(360)
        factor = np.linalg.cholesky(c) / math.sqrt(1 + 1e-8)
        z = rng.standard_normal((n, 360, 6))
        x[:, :, 6 * a:6 * a + 6] = np.einsum("pr,nrc->npc", factor, z) * t[6 * a:6 * a + 6] / 3
    x[:, :, 18:] = (rng.standard_normal((n, 12)) * t[18:] / 3)[:, None, :]
    delta = machine.comprehensive_error(q, x)[..., :3]  # no rotary axis: R(q) = I
    px = radius * np.cos(theta) + delta[..., 0]
    py = radius * np.sin(theta) + delta[..., 1]
    design = np.stack([px, py, np.ones_like(px)], -1)
    coef = np.linalg.solve(np.einsum("npi,npj->nij", design, design),
                           np.einsum("npi,np->ni", design, px ** 2 + py ** 2)[..., None])[..., 0]
    cx, cy = coef[:, 0] / 2, coef[:, 1] / 2
    r = np.hypot(px - cx[:, None], py - cy[:, None])
    return r.max(axis=1) - r.min(axis=1)


def test_circle_pass_probability_against_an_independent_simulation(mill3):
    # the independent simulation runs the exact chain at 360 poses per machine: fewer of
    # its machines, each sample's own size in the standard errors
    n, m, radius, length = 2000, 800, 100.0, 200.0
    t = mill3.initial_allocation
    theirs = _independent_circle(mill3, t, radius, length, m, np.random.default_rng(70))
    limit = float(np.median(theirs))
    result = acceptance(mill3, [CircularTest("c", "xy", CENTRE, radius, limit)], t,
                        machines=n, profile=f"gp:{length:g}", rng=7)
    ours = result.values[("c", "G")].to_numpy()
    assert abs(ours.mean() - theirs.mean()) < Z * math.sqrt(ours.var() / n + theirs.var() / m)
    p, q = result.to_frame().iloc[0]["pass_probability"], np.mean(theirs <= limit)
    assert abs(p - q) < Z * math.sqrt(p * (1 - p) / n + q * (1 - q) / m)


# ----- the computation's own promises --------------------------------------------------
def _paper_tests(hobbing):
    return read_tests(EXAMPLES / "paper_tests.toml", hobbing)


def test_chunks_and_the_two_products_give_the_same_numbers(hobbing):
    tests = _paper_tests(hobbing)
    whole = acceptance(hobbing, tests, machines=60, driver_machines=10, rng=8)
    chunked = acceptance(hobbing, tests, machines=60, driver_machines=10, memory=200_000,
                         rng=8)
    # the same draws whatever the chunks; the matrix products may round differently
    assert np.allclose(whole.values, chunked.values, rtol=1e-12, atol=1e-15)
    # the normal errors as one matrix product against the general path (any marginal)
    from reliability.acceptance import prediction as module
    plan = module._plan(hobbing, tests, module.profile_model("gp:300"),
                        hobbing.initial_allocation / 3, None)
    draws = module._draw(hobbing, plan, 30, 9)
    fast = module._quantities(plan, draws, hobbing, 3.0, "normal",
                              module._latent_map(plan, len(hobbing.axes)))
    general = module._quantities(plan, draws, hobbing, 3.0, "normal")
    assert np.allclose(fast, general, rtol=1e-9, atol=1e-15)


def test_truncated_reading_narrows_the_results(hobbing):
    tests = _paper_tests(hobbing)[:1]
    normal = acceptance(hobbing, tests, machines=400, driver_machines=10, rng=10)
    truncated = acceptance(hobbing, tests, machines=400, driver_machines=10, rng=10,
                           distribution="truncated")
    assert truncated.distribution == "truncated"
    assert truncated.values.mean().iloc[0] < normal.values.mean().iloc[0]


def test_csv_table_rows_and_columns(hobbing):
    tests = _paper_tests(hobbing)
    frame = acceptance(hobbing, tests, machines=50, driver_machines=5, rng=11).to_frame()
    assert list(frame.columns) == ["test", "quantity", "limit", "mean", "q95",
                                   "pass_probability", "pass_low", "pass_high"]
    expected = [(t.name, q) for t in tests for q in t.quantities] + [("all", "pass")]
    assert list(zip(frame["test"], frame["quantity"])) == expected
    limited = frame["limit"].notna()
    assert np.all(frame.loc[limited, "pass_low"] <= frame.loc[limited, "pass_probability"])
    assert np.all(frame.loc[limited, "pass_probability"] <= frame.loc[limited, "pass_high"])


def test_summary_gives_the_set_up_the_table_and_each_tests_pass_probability(hobbing):
    tests = _paper_tests(hobbing)
    result = acceptance(hobbing, tests, machines=50, driver_machines=5, rng=11)
    text = result.summary()
    first, rest = text.split("\n\n", 1)
    assert first.startswith(f"50 built machines through {len(tests)} acceptance tests; ")
    assert "gp:300" in first and "σ = t/3" in first
    assert rest == result.results_text()
    lines = text.splitlines()
    assert "Wilson 95 %:" in lines[-len(tests) - 2]
    for row, line in zip(result.test_pass().itertuples(), lines[-len(tests) - 1:]):
        assert line == (f"  {row.test}: {row.pass_probability:.4f} [{row.pass_low:.4f}, "
                        f"{row.pass_high:.4f}]")


def test_independent_profile_is_refused_naming_it(mill3):
    with pytest.raises(InputError, match="independent.*test 'c'"):
        acceptance(mill3, [CircularTest("c", "xy", CENTRE, 50.0, 0.01)],
                   profile="independent")


# ----- bad files ---------------------------------------------------------------------
GOOD = {"name": "c", "kind": "circular", "plane": "xy", "centre": dict(CENTRE),
        "radius": 100.0, "limit": 0.005}
POSITIONING = {"name": "p", "kind": "positioning", "axis": "X",
               "line": {"Y": 200.0, "Z": -175.0}, "limit": {"E": 0.005}}


@pytest.mark.parametrize("change, words", [
    ({"kind": "spiral"}, ["'c'", "'kind'", "spiral"]),
    ({"plane": "xz"}, ["'c'", "'plane'", "xz"]),
    ({"colour": "red"}, ["'c'", "'colour'"]),
    ({"radius": 250.0}, ["'c'", "'radius'", "stroke"]),
    ({"limit": 0.0}, ["'c'", "'limit'", "> 0"]),
    ({"limit": -1e-3}, ["'c'", "'limit'"]),
    ({"centre": {"Y": 200.0, "X": 0.0}}, ["'c'", "'centre'", "'Z'"]),
    ({"centre": {**CENTRE, "W": 1.0}}, ["'c'", "'centre'", "'W'"]),
    ({"radius": True}, ["'c'", "'radius'"]),
])
def test_bad_circular_tests_are_refused(mill3, change, words):
    with pytest.raises(InputError) as info:
        parse_tests({"tests": [{**GOOD, **change}]}, mill3)
    for word in words:
        assert word in str(info.value)


@pytest.mark.parametrize("change, words", [
    ({"axis": "W"}, ["'p'", "'axis'", "'W'"]),
    ({"limit": {"E": 0.0}}, ["'p'", "'limit.E'"]),
    ({"limit": {"G": 0.01}}, ["'p'", "'limit'", "'G'"]),
    ({"limit": 0.01}, ["'p'", "'limit'"]),
    ({"targets": [-400.0, 0.0, 100.0]}, ["'p'", "'targets'", "stroke"]),
    ({"targets": [100.0, 0.0]}, ["'p'", "'targets'", "increasing"]),
    ({"runs": 1}, ["'p'", "'runs'"]),
    ({"radius": 3.0}, ["'p'", "'radius'"]),
    ({"line": {"Y": 200.0, "Z": -175.0, "X": 0.0}}, ["'p'", "'line'", "'X'"]),
])
def test_bad_positioning_tests_are_refused(mill3, change, words):
    with pytest.raises(InputError) as info:
        parse_tests({"tests": [{**POSITIONING, **change}]}, mill3)
    for word in words:
        assert word in str(info.value)


def test_bad_rotary_and_file_level_mistakes_are_refused(trunnion5, mill3):
    centre = {"C": 0.0, "A": 0.0, "Y": 0.0, "X": 0.0, "Z": 250.0}
    rotary = {"name": "r", "kind": "rotary", "axis": "A", "centre": centre,
              "limit": {"range_x": 0.01}}
    cases = [({**rotary, "axis": "X"}, "linear"),
             ({**rotary, "sweep": [-1.5707963, 0.5]}, "'centre'"),  # Z leaves its stroke
             ({**rotary, "limit": {"range_w": 0.01}}, "'range_w'")]
    for entry, word in cases:
        with pytest.raises(InputError, match=word):
            parse_tests({"tests": [entry]}, trunnion5)
    with pytest.raises(InputError, match="used twice"):
        parse_tests({"tests": [GOOD, GOOD]}, mill3)
    with pytest.raises(InputError, match="unknown top-level key 'test'"):
        parse_tests({"test": [GOOD]}, mill3)
    with pytest.raises(InputError, match="missing key 'radius'"):
        parse_tests({"tests": [{k: v for k, v in GOOD.items() if k != "radius"}]}, mill3)


def test_tests_built_in_python_are_checked_too(mill3):
    bad = [CircularTest("c", "xy", CENTRE, 100.0, -0.001),
           CircularTest("c", "xy", CENTRE, 0.0, 0.001),
           PositioningTest("p", "X", {"Y": 200.0, "Z": -175.0}, {"G": 0.01}),
           PositioningTest("p", "X", {"Y": 200.0, "Z": -175.0}, {})]
    for test, key in zip(bad, ("limit", "radius", "limit", "limit")):
        with pytest.raises(InputError, match=f"key '{key}'"):
            acceptance(mill3, [test], machines=10)
    with pytest.raises(InputError, match="confidence"):
        acceptance(mill3, [bad[1]], confidence=1.0)


def test_machine_file_positioning_keys_are_checked():
    data = _mill_dict()
    data["axes"][1]["reversal"] = -0.001
    with pytest.raises(MachineDescriptionError, match="reversal must be >= 0"):
        machine_from_dict(data)
    hobbing_like = copy.deepcopy(tomllib.loads((MACHINES / "trunnion5.toml").read_text()))
    hobbing_like["axes"][0]["repeatability"] = 0.001
    with pytest.raises(MachineDescriptionError, match="linear axes only"):
        machine_from_dict(hobbing_like)
    machine = _mill(repeatability=0.0004, reversal=0.001)
    again = machine_from_dict(tomllib.loads(machine.to_toml()))
    assert again == machine and again.axis_specs[1].reversal == 0.001
    from reliability.model.machine_checks import describe
    assert "reversal [mm]" in describe(machine) and "reversal" not in describe(_mill())


@pytest.mark.parametrize("machine_file, tests_file", [
    (None, "paper_tests.toml"), ("trunnion5.toml", "trunnion5_tests.toml")])
def test_example_test_files_load(hobbing, machine_file, tests_file):
    machine = hobbing if machine_file is None else \
        machine_from_dict(tomllib.loads((MACHINES / machine_file).read_text()))
    tests = read_tests(EXAMPLES / tests_file, machine)
    assert len(tests) == 6 and {t.kind for t in tests} == {"circular", "positioning", "rotary"}


def test_report_section_has_a_figure_and_both_allocations(mill3):
    from studies.report.acceptance_section import FIGURE, acceptance_section
    tests = [CircularTest("c", "xy", CENTRE, 100.0, 0.004), _x_test()]
    section = acceptance_section(mill3, tests, {"initial": mill3.initial_allocation,
                                                "tight": mill3.initial_allocation / 2},
                                 machines=100, seed=13)
    assert section.title == "Acceptance tests" and FIGURE in section.figures
    assert set(section.tables) == {"acceptance_initial.csv", "acceptance_tight.csv"}
    tight = section.summary["acceptance"]["tight"]["c/G"]
    assert tight >= section.summary["acceptance"]["initial"]["c/G"]
    assert "gp:300" in section.text


# ----- the command line ----------------------------------------------------------------
def test_command_writes_the_csv_and_refuses_bad_files(tmp_path, capsys):
    machine = str(MACHINES / "trunnion5.toml")
    tests = str(EXAMPLES / "trunnion5_tests.toml")
    code = cli.main(["acceptance", machine, "--tests", tests, "--machines", "40",
                     "--out", str(tmp_path / "acc.csv")])
    out = capsys.readouterr().out
    assert code == 0 and "error profile constant" in out and "rotary_C" in out
    frame = pd.read_csv(tmp_path / "acc.csv")
    assert list(frame.columns) == ["test", "quantity", "limit", "mean", "q95",
                                   "pass_probability", "pass_low", "pass_high"]
    assert tuple(frame.iloc[-1][["test", "quantity"]]) == ("all", "pass")
    assert cli.main(["acceptance", machine, "--tests", tests, "--machines", "40",
                     "--out", str(tmp_path / "acc.csv")]) == 2
    assert "--overwrite" in capsys.readouterr().err
    bad = tmp_path / "bad.toml"
    bad.write_text(Path(tests).read_text().replace("limit = 0.004", "limit = 0.0", 1))
    assert cli.main(["acceptance", machine, "--tests", str(bad)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "'circle_xy_r150'" in err and "'limit'" in err
    assert cli.main(["acceptance", machine, "--tests", tests, "--profile",
                     "independent"]) == 2
    assert "independent" in capsys.readouterr().err


def test_command_csv_reads_back_as_the_results_table(tmp_path, capsys):
    """Also the old spelling: a folder as --out gets its acceptance.csv, with a warning."""
    machine = str(MACHINES / "trunnion5.toml")
    tests = str(EXAMPLES / "trunnion5_tests.toml")
    assert cli.main(["acceptance", machine, "--tests", tests, "--machines", "40", "--seed",
                     "3", "--out", str(tmp_path)]) == 0
    captured = capsys.readouterr()
    printed = captured.out
    assert (f"precrel: warning: --out DIR (a folder) in acceptance is deprecated; use --out "
            f"{tmp_path / 'acceptance.csv'}") in captured.err
    loaded = load_machine(machine)
    result = acceptance(loaded, read_tests(tests, loaded), machines=40, profile=loaded.profile,
                        rng=3)
    assert result.results_text() in printed
    written = pd.read_csv(tmp_path / "acceptance.csv")
    expected = result.to_frame()
    assert written[["test", "quantity"]].equals(expected[["test", "quantity"]])
    numbers = [c for c in expected.columns if c not in ("test", "quantity")]
    np.testing.assert_allclose(written[numbers].to_numpy(float),
                               expected[numbers].to_numpy(float), rtol=5e-6, atol=0)


def test_report_with_tests_adds_the_section(tmp_path, capsys):
    tests = tmp_path / "mill_tests.toml"
    tests.write_text('[[tests]]\nname = "c"\nkind = "circular"\nplane = "xy"\n'
                     'centre = { Y = 200.0, X = 0.0, Z = -175.0 }\nradius = 100.0\n'
                     'limit = 0.004\n')
    code = cli.main(["report", str(MACHINES / "mill3.toml"), "--out", str(tmp_path / "r"),
                     "--tests", str(tests), "--skip", "front", "system", "rare", "profiles",
                     "--repeats", "2", "--samples", "500", "--points", "3", "--machines", "400",
                     "--suggest", "0.95"])
    capsys.readouterr()
    assert code == 0
    assert "## Acceptance tests" in (tmp_path / "r" / "report.md").read_text()
    assert "suggested_limit" in (tmp_path / "r" / "acceptance_optimum.csv").read_text()
    for name in ("acceptance.png", "acceptance_initial.csv", "acceptance_optimum.csv"):
        assert (tmp_path / "r" / name).exists()
    tests.write_text(tests.read_text().replace("radius = 100.0", "radius = 500.0"))
    assert cli.main(["report", str(MACHINES / "mill3.toml"), "--out", str(tmp_path / "s"),
                     "--tests", str(tests)]) == 2
    assert "'radius'" in capsys.readouterr().err and not (tmp_path / "s").exists()


def test_constant_profile_is_explained_where_chosen(capsys):
    code = cli.main(["acceptance", str(MACHINES / "trunnion5.toml"), "--tests",
                     str(EXAMPLES / "trunnion5_tests.toml"), "--machines", "20",
                     "--profile", "constant"])
    out = capsys.readouterr().out
    assert code == 0 and "only reversal and repeatability" in out and "ellipse" in out


def test_a_value_exactly_on_its_limit_fails():
    """The toolkit's one rule, |y| < I: a result equal to its limit does not pass."""
    test = CircularTest("c", "xy", CENTRE, 80.0, 0.001)
    values = pd.DataFrame([[0.001], [0.0005], [0.0015]],
                          columns=pd.MultiIndex.from_tuples([("c", "G")],
                                                            names=["test", "quantity"]))
    result = AcceptanceResult(tests=(test,), values=values,
                              drivers=pd.DataFrame(columns=["test", "quantity", "item",
                                                            "share"]),
                              profile="gp:300", distribution="normal")
    assert result.passed()["c"].tolist() == [False, True, False]
    assert result.to_frame()["pass_probability"].iloc[0] == pytest.approx(1 / 3)


def test_a_saved_acceptance_result_reloads_with_its_verdicts(hobbing, tmp_path):
    tests = _paper_tests(hobbing)
    result = acceptance(hobbing, tests, machines=300, driver_machines=10, rng=4)
    assert inspect.signature(result.save).parameters["overwrite"].default is False
    path = result.save(tmp_path / "acceptance.json")
    again = AcceptanceResult.load(path)
    assert inspect.ismethod(AcceptanceResult.load) and again.tests == result.tests
    assert (again.profile, again.distribution, again.k, again.confidence) == \
        (result.profile, result.distribution, result.k, result.confidence)
    pd.testing.assert_frame_equal(again.values, result.values)
    pd.testing.assert_frame_equal(again.drivers, result.drivers, check_dtype=False)
    pd.testing.assert_frame_equal(again.passed(), result.passed())
    pd.testing.assert_frame_equal(again.to_frame(), result.to_frame())
    assert again.summary() == result.summary()
    with pytest.raises(FileExistsError, match="overwrite=True"):
        result.save(path)
    document = json.loads(path.read_text())
    document["payload"]["passing"]["all"] += 1
    path.write_text(json.dumps(document))
    with pytest.raises(SavedResultError, match="passing.all"):
        AcceptanceResult.load(path)
    document["payload"]["passing"]["all"] -= 1
    document["payload"]["tests"][0]["kind"] = "spiral"
    path.write_text(json.dumps(document))
    with pytest.raises(SavedResultError, match="tests.*unknown kind 'spiral'"):
        AcceptanceResult.load(path)
