"""Compensation tables, their files, the residual model of compensated machines and the
allocation for them (docs/compensation.md)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from allocation import AllocationProblem
from allocation.per_pose.compensated import allocate_compensated
from studies import cli
from reliability import compensation_tables, identify, read_compensation, write_compensation
from reliability.basics.errors import InputError
from reliability.basics.files import SIGNIFICANT
from reliability.compensation.compensation_plans import (parse_compensation_plan,
                                                         read_compensation_plan)
from reliability.compensation.residual import (compensated_deviation, fixed_rule_terms,
                                               positioning_draws, posterior_covariance,
                                               residual_covariance)
from reliability.compensation.tables import CompensationTables, table_positions
from reliability.measured.measurement_files import write_measurements
from reliability.measured.simulated_measurements import simulate_measurements
from reliability.model.poses import random_poses, workspace_grid

ROOT = Path(__file__).resolve().parent.parent


def _line(axis, line):
    return {"name": f"laser_{axis}", "kind": "line", "axis": axis, "line": line,
            "quantities": ["dx", "dy", "dz", "ex", "ey", "ez"], "u": 0.0005,
            "u_angle": 1e-6}


def mill3_plan(**compensation):
    """Laser runs along each axis of the test mill."""
    return {"tests": [_line("X", {"Y": 200.0, "Z": -100.0}),
                      _line("Y", {"X": 0.0, "Z": -100.0}),
                      _line("Z", {"X": 0.0, "Y": 200.0})],
            "compensation": {"spacing_mm": 100.0, **compensation}}


@pytest.fixture(scope="module")
def measured_mill3(mill3):
    plan = parse_compensation_plan(mill3_plan(), mill3)
    built = simulate_measurements(mill3, plan.runs, rng=7)
    return plan, built, identify(mill3, built.measurements)


# ----- tables and their files ----------------------------------------------------------
def test_table_positions_step_from_the_stroke_start_and_end_on_its_end(mill3):
    x = mill3.axis_specs[mill3.axes.index("X")]
    assert table_positions(x, 250.0, 1.0).tolist() == [-300.0, -50.0, 200.0, 300.0]


def test_tables_round_trip_to_the_same_values(measured_mill3, tmp_path, mill3):
    _, _, identification = measured_mill3
    tables = compensation_tables(identification, spacing_mm=100.0, items=["X.dy", "EB0X"],
                                 max_correction_mm=1e-3)
    write_compensation(tables, tmp_path / "tables")
    back = read_compensation(tmp_path / "tables", mill3)
    poses = random_poses(mill3, 50, rng=3)
    assert np.array_equal(back.values_at(poses), tables.values_at(poses))
    assert back.items == ("X.dy", "Y-X.ey") and back.spacing_mm == 100.0
    header = (tmp_path / "tables" / "X.csv").read_text().splitlines()[:4]
    assert "test 3-axis mill" in header[0] and "EYX in mm" in header[1]
    assert header[2] == "# spacing_mm: 100.0"


def test_a_table_holds_the_identified_mean_within_its_range(measured_mill3):
    _, _, identification = measured_mill3
    tables = compensation_tables(identification, max_correction_mm=2e-4)
    machine = identification.machine
    expected = np.clip(identification.mean, -2e-4, 2e-4)
    lengths = np.array([n[-2] == "d" for n in machine.error_names])
    got = tables.values_at(workspace_grid(machine, 2))
    assert np.allclose(got[:, lengths], expected[lengths], rtol=0, atol=1e-18)
    assert np.allclose(got[:, ~lengths], identification.mean[~lengths], rtol=0, atol=1e-18)


def test_values_between_table_positions_are_linear(mill3):
    tables = CompensationTables(
        mill3, 300.0, 1.0,
        {"X": _frame({"position_mm": [-300.0, 0.0, 300.0], "EYX": [0.0, 0.003, 0.001]})},
        _frame({"error": [], "iso": [], "value": []}))
    pose = np.array([[100.0, -150.0, -10.0], [100.0, 150.0, -10.0]])
    got = tables.values_at(pose)[:, mill3.error_index("X.dy")]
    assert got == pytest.approx([0.0015, 0.002], rel=1e-12)


@pytest.mark.parametrize("name, text, match", [
    ("X.csv", "position_mm,EYY\n-300,0\n", "'EYY': not a motion error of axis X"),
    ("X.csv", "position_mm,EYX\n-300,0\n400,1e-3\n", "row 2, column 'position_mm'.*outside"),
    ("X.csv", "position_mm,EYX\n-300,a\n", "row 1, column 'EYX': expected a finite number"),
    ("X.csv", "position_deg,EYX\n0,0\n", "is 'position_mm'"),
    ("assembly.csv", "error,iso,value\nY-X.ey,EB0Z,0\n", "row 1, column 'iso'"),
])
def test_a_bad_table_is_refused_naming_row_and_column(tmp_path, mill3, name, text, match):
    folder = tmp_path / "tables"
    folder.mkdir()
    spacing = "# spacing_mm: 100\n# spacing_deg: 1\n"
    (folder / "assembly.csv").write_text(spacing + "error,iso,value\n")
    (folder / name).write_text((spacing if name == "assembly.csv" else "") + text)
    with pytest.raises(InputError, match=match):
        read_compensation(folder, mill3)


# ----- the residual model ----------------------------------------------------------------
def test_posterior_of_one_error_is_the_scalar_update():
    sigma, information = 2e-3, 4e6
    expected = sigma ** 2 / (1 + information * sigma ** 2)
    got = posterior_covariance(np.array([sigma]), np.array([[information]]))
    assert got[0, 0] == pytest.approx(expected, rel=1e-12)


def test_fixed_rule_touches_the_residual_and_bounds_it_elsewhere(measured_mill3, mill3):
    plan = measured_mill3[0]
    rng = np.random.default_rng(5)
    here = mill3.initial_allocation / 3
    gain, noise = fixed_rule_terms(here, plan.information, plan.tabled)
    exact = residual_covariance(here, plan.information, plan.tabled)
    assert np.allclose(gain * here ** 2 @ gain.T + noise, exact, rtol=0,
                       atol=1e-12 * exact.max())
    for _ in range(5):
        there = here * rng.uniform(0.3, 3.0, size=here.shape)
        bound = gain * there ** 2 @ gain.T + noise
        gap = np.linalg.eigvalsh(bound - residual_covariance(there, plan.information,
                                                             plan.tabled))
        assert gap.min() >= -1e-9 * bound.max()


def test_an_untabled_error_keeps_its_prior(measured_mill3, mill3):
    plan = measured_mill3[0]
    sd = mill3.initial_allocation / 3
    tabled = np.ones(mill3.n_errors, dtype=bool)
    tabled[mill3.error_index("Y.ez")] = False
    covariance = residual_covariance(sd, plan.information, tabled)
    index = mill3.error_index("Y.ez")
    assert covariance[index, index] == pytest.approx(sd[index] ** 2, rel=1e-12)
    assert covariance[index, index] > 4 * residual_covariance(
        sd, plan.information, np.ones(mill3.n_errors, dtype=bool))[index, index]


def test_a_machine_compensated_by_its_own_errors_keeps_only_repeatability(swivel5_machine):
    machine = swivel5_machine
    x = machine.initial_allocation * np.random.default_rng(2).uniform(-1, 1, machine.n_errors)
    own = CompensationTables(machine, 10.0, 1.0, {}, _frame(
        {"error": machine.error_names[6 * len(machine.axes):],
         "iso": machine.iso_names[6 * len(machine.axes):],
         "value": x[6 * len(machine.axes):]}))
    poses = workspace_grid(machine, 2)
    motion = x.copy()
    motion[6 * len(machine.axes):] = 0.0
    residual = compensated_deviation(machine, poses, x, own, np.random.default_rng(1))
    alone = machine.comprehensive_error(poses, motion + positioning_draws(
        machine, (len(poses),), np.random.default_rng(1)), frame=machine.frame)
    assert np.allclose(residual, alone, rtol=0, atol=1e-15)


def test_repeatability_and_reversal_draws_have_their_variance(swivel5_machine):
    machine = swivel5_machine
    y = machine.axis_specs[machine.axes.index("Y")]
    n = 20_000
    draws = positioning_draws(machine, (n,), np.random.default_rng(11))
    values = draws[:, machine.error_index("Y.dy")]
    variance = y.repeatability ** 2 + y.reversal ** 2 / 4
    # z = 4 on the sample variance (its standard error ≈ variance · sqrt(2/n) for a
    # near-normal sum; the ±B/2 part has kurtosis below the normal's)
    assert abs(values.var() - variance) <= 4 * variance * math.sqrt(2 / n)
    assert np.count_nonzero(draws.any(axis=0)) == 3  # Y, X, Z positioning


# ----- the allocation --------------------------------------------------------------------
def test_compensated_allocation_is_feasible_cheaper_and_bracketed(swivel5_machine):
    machine = swivel5_machine
    plan = read_compensation_plan(ROOT / "docs" / "examples" / "swivel5_plan.toml", machine)
    problem = AllocationProblem.build(machine, workspace_grid(machine, 2), side="two_sided")
    found = allocate_compensated(problem, plan)
    sigma = plan.sigma(found.tolerances, problem.poses)
    assert np.all(sigma <= problem.allowed_sigma * (1 + 1e-9))
    assert found.lower_bound <= found.cost * (1 + 1e-9) < found.cost_without
    assert np.all(np.diff(found.rounds["cost"]) <= 1e-12 * found.rounds["cost"].iloc[0])


def test_when_no_row_can_bind_after_compensation_every_item_is_at_its_upper_bound(hobbing):
    plan = read_compensation_plan(ROOT / "docs" / "examples" / "paper_plan.toml", hobbing)
    problem = AllocationProblem.build(hobbing, workspace_grid(hobbing, 2), side="two_sided")
    upper_loads = plan.sigma(problem.upper, problem.poses) / problem.allowed_sigma
    assert upper_loads.max() < 1.0  # the whole box meets the targets after compensation
    found = allocate_compensated(problem, plan)
    assert np.array_equal(found.tolerances, problem.upper)
    assert found.cost == pytest.approx(found.lower_bound, rel=1e-12)


def test_table_range_caps_a_tabled_tolerance(mill3):
    plan = parse_compensation_plan(mill3_plan(max_correction_rad=8e-6), mill3)
    problem = AllocationProblem.build(mill3, workspace_grid(mill3, 2), side="two_sided")
    found = allocate_compensated(problem, plan)
    angles = np.array([n[-2] == "e" for n in mill3.error_names]) & plan.tabled
    assert angles.sum() >= 10
    assert found.tolerances[angles].max() <= 8e-6 * (1 + 1e-12)
    assert np.all(found.upper[angles] == 8e-6)


# ----- the command line ------------------------------------------------------------------
def test_compensate_writes_the_tables_of_an_identification_folder(tmp_path, mill3,
                                                                    measured_mill3):
    _, built, identification = measured_mill3
    machine_file = str(ROOT / "tests" / "machines" / "mill3.toml")
    write_measurements(built.measurements, mill3, tmp_path / "m.csv")
    assert cli.main(["identify", machine_file, "--measurements", str(tmp_path / "m.csv"),
                     "--out", str(tmp_path / "id")]) == 0
    assert cli.main(["compensate", machine_file, "--identification", str(tmp_path / "id"),
                     "--out", str(tmp_path / "tables"), "--spacing-mm", "200"]) == 0
    back = read_compensation(tmp_path / "tables", mill3)
    # errors.csv holds the posterior means to SIGNIFICANT digits; unseen items are 0 but
    # for rounding (~1e-17)
    scale = np.abs(identification.mean).max()
    assert np.allclose(back.values_at(workspace_grid(mill3, 2)), identification.mean,
                       rtol=10.0 ** (1 - SIGNIFICANT), atol=1e-9 * scale)


def test_verify_text_sets_results_after_compensation_beside_before(mill3, tmp_path):
    from argparse import Namespace
    from studies.cli.compensate import verification_text
    lines = "".join(
        f'[[tests]]\nname = "laser_{axis}"\nkind = "line"\naxis = "{axis}"\n'
        f'line = {{ {line} }}\nquantities = ["dx", "dy", "dz", "ex", "ey", "ez"]\n'
        f'u = 0.0005\nu_angle = 1e-6\n\n'
        for axis, line in (("X", "Y = 200.0, Z = -100.0"), ("Y", "X = 0.0, Z = -100.0"),
                           ("Z", "X = 0.0, Y = 200.0")))
    path = tmp_path / "plan.toml"
    path.write_text(lines + "[compensation]\nspacing_mm = 100.0\n")
    args = Namespace(compensation=str(path), points=2, seed=0, compensated_machines=2)
    text = verification_text(mill3, mill3.initial_allocation, args)
    rows = {line.split()[0]: line.split()[1:] for line in text.splitlines()[2:9]}
    # no repeatability or reversal on this machine: the posterior is never wider than the prior
    assert all(float(rows[o][2]) >= float(rows[o][1]) for o in mill3.outputs)
    assert any(float(rows[o][2]) > float(rows[o][1]) + 1e-3 for o in mill3.outputs)
    assert "predicted by the residual model" in text and "(2 machines)" in text


def test_verified_compensation_counts_passes_by_the_pass_rule(mill3):
    from reliability.compensation.compensated_machines import simulate_compensated
    from studies.workflows.compensation_verification import verify_compensation
    plan = parse_compensation_plan(mill3_plan(), mill3)
    poses = workspace_grid(mill3, 2)
    t = mill3.initial_allocation * 4  # loose enough that some machines fail
    check = verify_compensation(plan, t, poses, 12, 50, rng=3)
    outputs = simulate_compensated(plan, t, poses, 12, np.random.default_rng(3))
    inside = np.abs(outputs) < mill3.limits
    np.testing.assert_array_equal(check.simulated, inside.all(axis=(1, 2)))
    after = plan.probability(t, poses)
    worst = after.argmin(axis=0)
    np.testing.assert_allclose(check.table["simulated after"],
                               [inside[:, worst[o], o].mean() for o in range(6)])
    assert check.predicted.shape == (50,) and check.predicted.dtype == bool
    with pytest.raises(InputError, match="model_machines"):
        verify_compensation(plan, t, poses, 2, 0)


def test_report_section_names_what_stays_tight_and_why(swivel5_machine):
    from types import SimpleNamespace
    from studies.report.compensation_section import compensation_section
    machine = swivel5_machine
    plan = read_compensation_plan(ROOT / "docs" / "examples" / "swivel5_plan.toml", machine)
    study = SimpleNamespace(problem=AllocationProblem.build(
        machine, workspace_grid(machine, 2), side="two_sided"), optimum=None)
    section = compensation_section(study, plan, "swivel5_plan.toml")
    table = section.tables["compensation.csv"]
    assert len(table) == machine.n_errors
    assert 0 < section.summary["compensation_lower_bound_ratio"] <= \
        section.summary["compensation_cost_ratio"] < 1
    tight = table[table["limited_by"] == "targets"]
    assert len(tight) and not tight["seen"].any()  # what no run's zeros let the plan see
    assert f"{len(tight)} of them are not seen by the plan" in section.text


def _swivel5():
    from reliability import load_machine
    return load_machine(ROOT / "tests" / "machines" / "swivel5.toml")


def _frame(columns):
    import pandas as pd
    return pd.DataFrame(columns)


@pytest.fixture(scope="module")
def swivel5_machine():
    return _swivel5()


@pytest.mark.parametrize("option, words", [
    (["--yield", "0.9"], ["--yield does not apply with --compensation",
                          "verify MACHINE.toml --tolerances CSV --compensation PLAN.toml"]),
    (["--method", "gwo"], ["--method gwo does not apply with --compensation"]),
])
def test_allocate_compensation_refuses_options_saying_why(option, words, tmp_path, capsys):
    """Refused before any work, in one line; --yield is pointed to where an allocation's
    yield after compensation is found."""
    out = tmp_path / "a.csv"
    code = cli.main(["allocate", str(ROOT / "tests" / "machines" / "swivel5.toml"),
                     "--compensation", str(ROOT / "docs" / "examples" / "swivel5_plan.toml"),
                     "--out", str(out), *option])
    error = capsys.readouterr().err
    assert code == 2 and not out.exists()
    assert len(error.strip().splitlines()) == 1
    for text in words:
        assert text in error
    assert ("verify MACHINE.toml" in error) == (option[0] == "--yield")
