"""Accuracy over time (docs/over-time.md): the first-order life reliability against
Monte-Carlo on the exact chain, the wear increments against their moments, the yield
curve's intervals by repetition, bad [drift] tables, the life study's file, and
``predict --age 0`` against ``predict``.

Tolerances are z standard errors of the Monte-Carlo estimate, the z stated at each test."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from reliability import load_machine, machine_from_toml
from reliability.basics.errors import InputError, MachineDescriptionError, SavedResultError
from reliability.first_order.fosm import fosm
from reliability.life.life_fosm import age_grid, life_reliability, undominated
from reliability.life.life_yield import life_yield
from reliability.life.recalibration import crossing_age
from reliability.life.wear_paths import wear_paths
from reliability.model.drift import Drift
from reliability.model.poses import workspace_grid
from studies.workflows.life_study import LifeStudy, life_study

HERE = Path(__file__).parent
MILL = HERE / "machines" / "mill3.toml"


def drifting(machine, kind="linear", rate_mm=0.0008, rate_rad=3e-6, spread=None):
    """``machine`` with a drift of ``rate_mm`` per year on every translation and
    ``rate_rad`` on every angle (and, for wear, the spread as a share of the rate)."""
    angular = np.array([name.split(".")[1].startswith("e") for name in machine.error_names])
    rate = np.where(angular, rate_rad, rate_mm)
    drift = Drift(kind, rate, None if kind == "linear" else rate * spread)
    return dataclasses.replace(machine, drift=drift)


def test_linear_life_matches_monte_carlo_on_the_exact_chain():
    """Built machines with drawn errors and rates, judged on the exact chain at the worst
    pose over a fine age grid (41 ages: the output is linear in age to first order, so
    the grid sees every crossing but second-order ones); z = 4."""
    machine = drifting(load_machine(MILL))
    t = machine.initial_allocation
    poses = workspace_grid(machine, 3)
    found = life_reliability(machine, t, poses, [0.0, 8.0])
    rng = np.random.default_rng(11)
    n = 20_000
    e0 = rng.standard_normal((n, machine.n_errors)) * t / 3
    rate = rng.standard_normal((n, machine.n_errors)) * machine.drift.rate
    ages = np.linspace(0.0, 8.0, 41)
    for output in range(6):
        pose = poses[found.worst_pose[-1, output]]
        errors = e0[:, None, :] + ages[None, :, None] * rate[:, None, :]
        y = machine.comprehensive_error(pose, errors.reshape(-1, machine.n_errors))
        within = np.abs(y[:, output].reshape(n, len(ages))) < machine.limits[output]
        share = within.all(axis=1).mean()
        se = np.sqrt(found.life[-1, output] * (1 - found.life[-1, output]) / n)
        assert abs(share - found.life[-1, output]) < 4 * se + 1e-4, output
        assert found.life[-1, output] <= found.at_age[-1, output] + 1e-12


def test_life_at_age_zero_is_the_fosm_two_sided_probability():
    """At age 0 nothing has drifted: the life and the at-age probability are FOSM's
    worst-pose two-sided probability, at its worst pose."""
    machine = drifting(load_machine(MILL))
    poses = workspace_grid(machine, 4)
    found = life_reliability(machine, machine.initial_allocation, poses, [0.0, 3.0])
    result = fosm(machine, machine.initial_allocation, poses)
    np.testing.assert_allclose(found.life[0], result.worst("two_sided"), rtol=1e-9)
    np.testing.assert_allclose(found.at_age[0], result.worst("two_sided"), rtol=1e-9)
    assert np.all(np.diff(found.life, axis=0) <= 1e-12)


def test_pruning_keeps_the_worst_pose():
    """The poses left out by Anderson's inequality are never worse: every pose's
    quadrature gives the same worst life probability."""
    from reliability.life.first_passage import first_passage_within
    from reliability.life.life_fosm import output_moments
    machine = drifting(load_machine(MILL))
    poses = workspace_grid(machine, 4)
    s0, _, unit = output_moments(machine, poses, machine.initial_allocation)
    full = first_passage_within(machine.limits, s0, 5.0 * unit).min(axis=0)
    found = life_reliability(machine, machine.initial_allocation, poses, [0.0, 5.0])
    np.testing.assert_allclose(found.life[-1], full, rtol=1e-12)
    assert undominated(s0, unit).sum() < s0.size


def test_wear_increments_have_their_moments():
    """W(2 years) has mean 2μ and variance 2v; z = 4 on 200 000 paths."""
    drift = Drift("wear", np.array([0.001, 2e-6, 0.0]), np.array([0.0005, 3e-6, 0.0]))
    paths = wear_paths(drift, np.array([0.0, 0.5, 2.0]), 200_000, np.random.default_rng(5))
    wear = paths[:, -1]
    assert np.all(paths[:, 0] == 0) and np.all(np.diff(paths, axis=1) >= 0)
    mean, variance = 2 * drift.rate, 2 * drift.spread ** 2
    n = len(wear)
    se_mean = np.sqrt(variance / n)
    np.testing.assert_array_less(np.abs(wear.mean(axis=0) - mean), 4 * se_mean + 1e-15)
    centred = wear - wear.mean(axis=0)
    se_var = np.sqrt(np.maximum((centred ** 4).mean(axis=0) - variance ** 2, 0) / n)
    np.testing.assert_array_less(np.abs(wear.var(axis=0) - variance), 4 * se_var + 1e-15)


def test_wear_life_agrees_with_rice_when_the_mean_dominates():
    """Sampled wear life against the out-crossing approximation: within z = 4 standard
    errors plus 0.01 (the approximation's own error) on a drift whose spread is a tenth
    of its mean."""
    machine = drifting(load_machine(MILL), "wear", spread=0.1)
    found = life_reliability(machine, machine.initial_allocation, workspace_grid(machine, 3),
                             age_grid(6, 0.5), rng=3, paths=20_000)
    assert np.all(np.abs(found.life - found.rice) < 4 * found.life_se + 0.01)


def test_yield_intervals_cover_by_repetition():
    """30 repetitions of 150 machines: the Clopper–Pearson interval at each age covers a
    reference yield of 6 000 machines at least 25 times (P(fewer) < 0.3 % for a 95 %
    interval); the reference's own standard error is small against the intervals."""
    machine = drifting(load_machine(MILL))
    t = machine.initial_allocation
    ages = [0.0, 4.0, 8.0]
    reference = life_yield(machine, t, ages, points=3, machines=6000, rng=100).estimate
    covered = np.zeros(len(ages), dtype=int)
    for seed in range(30):
        one = life_yield(machine, t, ages, points=3, machines=150, rng=seed)
        covered += (one.lower <= reference) & (reference <= one.upper)
    assert np.all(covered >= 25), covered
    assert np.all(np.diff(reference) <= 0)


def test_life_yield_needs_drift():
    machine = load_machine(MILL)
    with pytest.raises(InputError, match="drift"):
        life_yield(machine, machine.initial_allocation, [0.0, 1.0])


@pytest.mark.parametrize("table, words", [
    ('translation = -0.001\nrotation = 1e-6', "≥ 0"),
    ('kind = "creep"\ntranslation = 0.001\nrotation = 1e-6', "kind"),
    ('kind = "wear"\ntranslation = 0.001\nrotation = 1e-6', "mean, sd"),
    ('translation = 0.001\nrotation = 1e-6\nitems = { "Q.dx" = 0.001 }', "Q.dx"),
])
def test_bad_drift_tables_are_refused_by_name(table, words):
    text = MILL.read_text() + "\n[drift]\n" + table + "\n"
    with pytest.raises(MachineDescriptionError, match="drift") as caught:
        machine_from_toml(text, source="mill")
    assert words in str(caught.value)


def test_crossing_age_interpolates_and_says_beyond():
    ages = np.array([0.0, 1.0, 2.0])
    assert crossing_age(ages, [1.0, 0.98, 0.94], 0.96) == pytest.approx(1.5)
    assert crossing_age(ages, [0.9, 0.8, 0.7], 0.95) == 0.0
    assert np.isnan(crossing_age(ages, [1.0, 0.99, 0.98], 0.95))


def test_life_study_saves_and_refuses_a_changed_field(tmp_path):
    machine = drifting(load_machine(MILL))
    study = life_study(machine, machine.initial_allocation, until=4, step=1, points=3,
                       machines=200, seed=1)
    path = study.save(tmp_path / "life_summary.json")
    back = LifeStudy.load(path)
    assert back.to_frame().equals(study.to_frame())
    data = json.loads(path.read_text())
    data["payload" if "payload" in data else "data"]["interval"][1] = 0.123
    path.write_text(json.dumps(data))
    with pytest.raises(SavedResultError, match="interval"):
        LifeStudy.load(path)


def _swivel_plan():
    from reliability.compensation.compensation_plans import read_compensation_plan
    machine = load_machine(HERE / "machines" / "swivel5_drift.toml")
    plan = read_compensation_plan(HERE.parent / "docs" / "examples" / "swivel5_plan.toml",
                                  machine)
    return machine, plan


def test_compensated_first_cycle_matches_monte_carlo_on_the_exact_chain():
    """Compensated at acceptance, the residual ``M e0 − ν`` then drifts with the rates:
    the first-order life probability at the worst pose against built machines on the exact
    chain (15 000 machines, 41 ages; z = 4)."""
    from reliability.compensation.residual import fixed_rule_terms
    from reliability.life.compensated_life import first_cycle_covariance
    machine, plan = _swivel_plan()
    t = machine.initial_allocation / 2
    poses = workspace_grid(machine, 3)
    found = life_reliability(machine, t, poses, [0.0, 10.0],
                             start_covariance=first_cycle_covariance(machine, plan, t))
    rule, noise = fixed_rule_terms(t / 3, plan.information, plan.tabled)
    rng = np.random.default_rng(4)
    n, ages = 15_000, np.linspace(0.0, 10.0, 41)
    values, vectors = np.linalg.eigh(noise)
    start = (rng.standard_normal((n, machine.n_errors)) * t / 3) @ rule.T \
        - rng.standard_normal((n, machine.n_errors)) @ (vectors * np.sqrt(np.maximum(values, 0))).T
    rate = rng.standard_normal((n, machine.n_errors)) * machine.drift.rate
    for output in range(6):
        pose = poses[found.worst_pose[-1, output]]
        errors = start[:, None, :] + ages[None, :, None] * rate[:, None, :]
        y = machine.comprehensive_error(pose, errors.reshape(-1, machine.n_errors))
        share = (np.abs(y[:, output].reshape(n, -1)) < machine.limits[output]).all(axis=1).mean()
        p = found.life[-1, output]
        assert abs(share - p) < 4 * np.sqrt(p * (1 - p) / n) + 1e-4, output


def test_nothing_compensated_is_the_machine_without_compensation():
    """A plan that tables nothing leaves ``M = I`` and no noise: its first cycle is the
    life yield under the constant profile (independent draws of 3 000 machines each;
    z = 4 on the difference)."""
    from reliability.life.compensated_life import compensated_life
    machine, plan = _swivel_plan()
    idle = dataclasses.replace(plan, tabled=np.zeros(machine.n_errors, dtype=bool))
    t = machine.initial_allocation / 2
    ages = [0.0, 2.0, 4.0]
    cycles = compensated_life(machine, idle, t, ages, 0.5, points=3, machines=3000, rng=2)
    plain = life_yield(dataclasses.replace(machine, profile="constant"), t, ages, points=3,
                       machines=3000, rng=3).estimate
    se = np.sqrt(plain * (1 - plain) / 3000 + cycles.first_yield * (1 - cycles.first_yield)
                 / 3000)
    assert np.all(np.abs(cycles.first_yield - plain) < 4 * se + 1e-9)
    assert cycles.starts[0] == 0


def test_compensation_resets_what_the_plan_sees():
    """With the plan, right after compensation at acceptance the yield is higher than
    without, and each later cycle starts at a recalibration age of the grid."""
    from reliability.life.compensated_life import compensated_life
    machine, plan = _swivel_plan()
    t = machine.initial_allocation / 2
    ages = age_grid(6, 0.5)
    cycles = compensated_life(machine, plan, t, ages, 0.8, points=3, machines=1000, rng=5)
    plain = life_yield(machine, t, ages, points=3, machines=1000, rng=6)
    assert cycles.first_lower[0] > plain.upper[0]
    assert np.all(np.isin(cycles.starts, ages)) and np.all(np.diff(cycles.starts) > 0)


def test_over_time_section_opens_with_its_answer(tmp_path):
    """The report's section: one sentence with the recalibration interval in bold, read
    back from its summary entry and its life.csv."""
    import re
    from studies.report.life_section import life_section
    from studies.report.writer import write_section
    machine = load_machine(HERE / "machines" / "swivel5_drift.toml")
    section = life_section(machine, machine.initial_allocation / 2, points=3, seed=1)
    first = section.text.split("\n\n")[0]
    years = section.summary["recalibration_years"]
    assert first.startswith("**Recalibrate after") or first.startswith("**The machine yield")
    if first.startswith("**Recalibrate after"):
        assert f"**Recalibrate after {years:.1f} years**" in first
    assert first.endswith(".") and not re.search(r"[a-z)]\. [A-Z]", first[:-1])
    written = write_section(tmp_path / "s", section)
    table = pd.read_csv(tmp_path / "s" / "life.csv")
    last = table[(table["output"] == "machine")]["probability"].iloc[-1]
    assert f"{last:.3f}" in first
    assert section.summary["life_yield_at_horizon"] == pytest.approx(last, rel=1e-5)
    assert any(Path(p).name == "over_time.png" for p in written)
