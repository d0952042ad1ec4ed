"""The machine yield: crude and importance-sampling estimates against independent
computations, the exact proposal weights, first-order bounds, failure shares, the summary
keys and bad inputs.

Statistical checks compare two independent estimates with ``|a − b| ≤ z √(se_a² + se_b²)``
at z = 4 (fixed seeds), unless said otherwise.
"""

from __future__ import annotations

import inspect
import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy.stats import norm

from reliability import load_machine
from reliability.basics.errors import InputError, SavedResultError
from reliability.first_order.fosm import fosm
from reliability.model.error_draws import draw_errors
from reliability.sampling.grid_experiment import GridExperiment
from reliability.model.profiles import axis_profiles
from reliability.sampling.machine_yield import YieldModel, deciding_points, machine_yield
from reliability.sampling.row_events import RowEvents
from reliability.sampling.yield_estimate import YieldEstimate
from studies import cli
from studies.workflows import machine_study

ROOT = Path(__file__).resolve().parents[1]
MILL = Path(__file__).parent / "machines" / "mill3.toml"
Z = 4.0


@pytest.fixture(scope="module")
def mill():
    return load_machine(MILL)


def reference_yield(machine, tolerances, points, n, profile, distribution, seed):
    """Yield by the straightforward per-pose exact model (``machine.comprehensive_error``
    through :meth:`GridExperiment.reference_evaluate`), errors drawn directly: one value per
    machine for ``constant``, one per grid point for ``independent``."""
    experiment = GridExperiment(machine, points)
    rng = np.random.default_rng(seed)
    axes = len(machine.axes)
    motion_t = tolerances[:6 * axes].reshape(axes, 6)
    passed = 0
    for start in range(0, n, 500):
        size = min(500, n - start)
        if profile == "constant":
            motion = draw_errors(motion_t, (size,), distribution=distribution, rng=rng)
            motion = np.broadcast_to(motion[:, :, None, :], (size, axes, points, 6))
        else:
            motion = draw_errors(np.broadcast_to(motion_t[:, None, :], (axes, points, 6)),
                                 (size,), distribution=distribution, rng=rng)
        assembly = draw_errors(tolerances[6 * axes:].reshape(axes - 1, 6), (size,),
                               distribution=distribution, rng=rng)
        values = experiment.reference_evaluate(motion, assembly)
        passed += int(np.all(np.abs(values) < machine.limits, axis=(1, 2)).sum())
    return passed / n


def binomial_se(p, n):
    return np.sqrt(p * (1 - p) / n)


@pytest.mark.parametrize("profile, distribution", [("constant", "normal"),
                                                   ("independent", "truncated")])
def test_crude_yield_matches_a_direct_monte_carlo(mill, profile, distribution):
    t = 1.15 * mill.initial_allocation
    estimate = machine_yield(mill, t, profile=profile, distribution=distribution,
                             points=3, machines=6000, rng=1, method="crude")
    reference = reference_yield(mill, t, 3, 12_000, profile, distribution, seed=2)
    assert 0.2 < reference < 0.95  # a yield both estimators see well
    se = np.hypot(binomial_se(estimate.estimate, 6000), binomial_se(reference, 12_000))
    assert abs(estimate.estimate - reference) <= Z * se
    assert estimate.method == "crude" and estimate.machines == 6000
    assert estimate.lower <= estimate.estimate <= estimate.upper
    assert estimate.profile == profile and estimate.distribution == distribution
    assert estimate.workspace == "3-point grid (27 poses)"


@pytest.mark.parametrize("profile", ["independent", "gp:300", "constant"])
def test_row_vectors_are_the_linearised_chain_and_have_fosm_sigma(mill, profile):
    model = YieldModel(mill, profile=profile, distribution="normal", points=3)
    t = mill.initial_allocation
    rows = np.array([0, 7, 50, 100, 161])
    vectors = model.linear.row_vectors(rows, t)
    sigma = fosm(mill, t, model.experiment.poses, distribution="normal").sigma
    np.testing.assert_allclose(np.linalg.norm(vectors, axis=1),
                               sigma.reshape(-1)[rows], rtol=1e-10)
    u = np.random.default_rng(3).standard_normal((4, model.dimension))
    eps = 1e-4  # the exact chain at small errors is its linearisation
    exact = model.experiment.evaluate(*model.errors(eps * u, t)).reshape(4, -1)[:, rows] / eps
    np.testing.assert_allclose(exact, u @ vectors.T, rtol=1e-3,
                               atol=1e-6 * np.abs(exact).max())


def chain_ratios(model, u, t):
    """Per machine and output, max over the grid poses of |y_o|/I_o straight from the exact
    chain: each machine's errors (:meth:`YieldModel.errors`) put together per pose and
    ``machine.comprehensive_error`` called on the grid poses, one machine at a time."""
    machine, poses = model.machine, model.experiment.poses
    motion, assembly = model.errors(u, t)
    n, points = len(machine.axes), model.experiment.points
    index = np.stack(np.unravel_index(np.arange(len(poses)), (points,) * n), axis=-1)
    out = np.empty((len(u), 6))
    for m in range(len(u)):
        x = np.concatenate([motion[m][np.arange(n), index].reshape(len(poses), -1),
                            np.broadcast_to(assembly[m].ravel(),
                                            (len(poses), assembly[m].size))], axis=1)
        y = machine.comprehensive_error(poses, x)
        out[m] = np.max(np.abs(y) / machine.limits, axis=0)
    return out


@pytest.mark.parametrize("machine_name, profile, distribution", [
    ("mill3", "constant", "normal"), ("trunnion5", "gp:300", "truncated"),
    ("trunnion5", "independent", "normal")])
def test_output_ratios_are_the_exact_chain_per_machine(machine_name, profile, distribution,
                                                       request):
    """The engine's per-output worst ratios (batched, here in batches of 2 machines) are
    those of the exact chain evaluated pose by pose, and worst_ratios is their largest,
    with a row at which the chain reaches it."""
    machine = request.getfixturevalue(machine_name)
    kept = deciding_points(machine, axis_profiles(machine, profile), 3)
    poses = 3 ** len(machine.axes) if kept is None else np.prod([len(k) for k in kept])
    model = YieldModel(machine, profile=profile, distribution=distribution,
                       points=3, memory=2 * 4 * 6 * 8 * int(poses))
    assert model.batch == 2
    t = 1.3 * machine.initial_allocation
    u = model.draws(5, rng=11)
    ratios, poses = model.output_ratios(u, t, with_poses=True)
    assert ratios.shape == poses.shape == (5, 6)
    np.testing.assert_allclose(ratios, chain_ratios(model, u, t), rtol=1e-9)
    np.testing.assert_array_equal(model.output_ratios(u, t), ratios)
    ratio, worst = model.worst_ratios(u, t)
    np.testing.assert_array_equal(ratio, ratios.max(axis=1))
    pose, output = np.divmod(worst, 6)
    np.testing.assert_array_equal(ratios[np.arange(5), output], ratio)
    np.testing.assert_array_equal(poses[np.arange(5), output], pose)
    failed, rows = model.worst_rows(u, t)
    np.testing.assert_array_equal(failed, ~(ratios < 1.0).all(axis=1))
    np.testing.assert_array_equal(rows, worst)


@pytest.mark.parametrize("path, distribution", [
    ("tests/machines/swivel5.toml", "normal"), ("tests/machines/trunnion5.toml", "truncated")])
def test_the_deciding_poses_give_the_whole_grids_largest_ratios(path, distribution):
    """Under a constant profile only the ends of each linear axis are evaluated (2 of 3
    points on each of three linear axes here), and every machine's largest ratio per output
    is the exact chain's over the whole grid, reached at the pose returned (swivel5 reads
    its outputs in the workpiece frame)."""
    machine = load_machine(ROOT / path)
    kept = deciding_points(machine, axis_profiles(machine, "constant"), 3)
    linear = [spec.kind == "linear" for spec in machine.axis_specs]
    assert [len(k) for k in kept] == [2 if lin else 3 for lin in linear]
    model = YieldModel(machine, profile="constant", distribution=distribution,
                       points=3)
    t = 4.0 * machine.initial_allocation
    u = model.draws(6, rng=5)
    ratios, poses = model.output_ratios(u, t, with_poses=True)
    np.testing.assert_allclose(ratios, chain_ratios(model, u, t), rtol=1e-12)
    full = np.abs(model.experiment.evaluate(*model.errors(u, t))) / machine.limits
    reached = np.take_along_axis(full, poses[:, None, :], axis=1)[:, 0]
    np.testing.assert_allclose(reached, ratios, rtol=1e-12)
    # the poses evaluated are the grid poses whose linear axes sit at a stroke end
    ends = np.ones(model.experiment.n_poses, dtype=bool)
    for axis, is_linear in enumerate(linear):
        if is_linear:
            column = model.experiment.poses[:, axis]
            ends &= (column == column.min()) | (column == column.max())
    np.testing.assert_array_equal(model.deciding_poses, model.experiment.poses[ends])


def test_the_ends_of_a_linear_axis_do_not_decide_when_its_errors_vary_along_it():
    """The reduction rests on errors constant along travel: under the independent profile
    the grid of the linear axes' ends misses larger ratios inside, and none is made."""
    machine = load_machine(ROOT / "tests/machines/trunnion5.toml")
    assert deciding_points(machine, axis_profiles(machine, "independent"), 3) is None
    kept = [np.array([0, 2]) if spec.kind == "linear" else np.arange(3)
            for spec in machine.axis_specs]
    ends = GridExperiment(machine, 3, "independent", kept_points=kept)
    model = YieldModel(machine, profile="independent", points=3)
    u = model.draws(20, rng=5)
    errors = model.errors(u, 4.0 * machine.initial_allocation)
    at_ends = np.max(np.abs(ends.evaluate(*errors)), axis=1)
    whole = np.max(np.abs(model.experiment.evaluate(*errors)), axis=1)
    assert np.all(at_ends <= whole * (1 + 1e-12)) and np.any(at_ends < 0.99 * whole)


def test_draws_come_from_the_seed_through_the_stream_door(mill):
    model = YieldModel(mill, points=3)
    u = model.draws(7, rng=3)
    assert u.shape == (7, model.dimension)
    np.testing.assert_array_equal(u, model.draws(7, rng=np.random.default_rng(3)))
    with pytest.raises(InputError, match="machines"):
        model.draws(0, rng=3)


def test_proposal_weights_are_the_exact_density_ratio(mill):
    """Under the proposal, E_q[w] = 1 and E_q[w 1(F_r)] = p_r for every row (because
    w = φ/q exactly), checked at z = 4."""
    model = YieldModel(mill, profile="constant", distribution="normal", points=3)
    t = 0.8 * mill.initial_allocation
    events = RowEvents.dominant(model.linear, t)
    u = events.draw(np.random.default_rng(4), 40_000)
    w = events.weight(u)
    assert w.max() <= 1 / 0.1 + 1e-12
    assert abs(w.mean() - 1) <= Z * w.std() / np.sqrt(len(w))
    inside = np.abs(u @ events.vectors.T) >= events.thresholds
    for r in range(min(events.size, 5)):
        terms = w * inside[:, r]
        assert abs(terms.mean() - events.probabilities[r]) <= \
            Z * terms.std() / np.sqrt(len(w)) + 1e-15


@pytest.mark.parametrize("profile, distribution, scale", [("constant", "normal", 0.8),
                                                          ("gp:300", "truncated", 0.85)])
def test_importance_sampling_agrees_with_crude_on_a_moderate_yield(mill, profile,
                                                                   distribution, scale):
    """Unbiased for the true failure indicator: non-linear chain, and under 'truncated'
    the copula map of the draws."""
    t = scale * mill.initial_allocation
    options = {"profile": profile, "distribution": distribution, "points": 3}
    crude = machine_yield(mill, t, machines=40_000, rng=5, method="crude", **options)
    weighted = machine_yield(mill, t, machines=4000, rng=6, method="importance",
                             target_cov=0.01, **options)
    p_crude, p_is = crude.failure_probability, weighted.failure_probability
    assert 50 < crude.failures  # a failure probability crude sampling resolves
    se = np.hypot(binomial_se(p_crude, 40_000), weighted.cov * p_is)
    assert abs(p_crude - p_is) <= Z * se
    assert weighted.method == "importance" and weighted.cov < crude.cov


def test_importance_intervals_cover_a_small_failure_probability(mill):
    """A yield near 1 − 1e-4: 40 short importance-sampling runs against one long one;
    95 % intervals should cover about 38 times; at least 32 (P < 1e-4 for correct
    intervals)."""
    t = 0.5 * mill.initial_allocation
    model = YieldModel(mill, points=3)
    truth = model.estimate(t, machines=30_000, rng=7, method="importance", target_cov=0.005)
    assert 1e-6 < truth.failure_probability < 1e-3
    covered = 0
    for seed in range(40):
        run = model.estimate(t, machines=1000, rng=100 + seed, method="importance",
                             target_cov=1.0)
        covered += run.lower <= truth.estimate <= run.upper
    assert covered >= 32


def test_auto_switches_to_importance_and_beats_crude(mill):
    t = 0.5 * mill.initial_allocation
    result = machine_yield(mill, t, points=3, machines=4000, rng=8, target_cov=0.1)
    assert result.method == "importance" and "< 50" in result.method_reason
    assert result.cov <= 0.1
    assert result.crude_equivalent > 20 * result.machines
    assert "1 − " not in f"{result.estimate}"  # a number, not a rounded 1
    assert result.estimate < 1.0
    moderate = machine_yield(mill, mill.initial_allocation, points=3, machines=4000,
                             rng=8)
    assert moderate.method == "crude"


def test_first_order_bounds_bracket_the_yield_and_are_the_row_formulas(mill):
    t = 0.7 * mill.initial_allocation
    model = YieldModel(mill, profile="constant", distribution="normal", points=3)
    lower, upper = model.first_order_bounds(t)
    prediction = fosm(mill, t, model.experiment.poses, distribution="normal")
    failure = 2 * norm.sf(mill.limits / prediction.sigma)
    assert lower == pytest.approx(1 - failure.sum(), rel=1e-12)
    assert upper == pytest.approx(1 - failure.max(), rel=1e-12)
    precise = model.estimate(t, machines=20_000, rng=9, method="importance",
                             target_cov=0.01)
    assert lower <= precise.lower and precise.upper <= upper


def test_failure_shares_sum_to_one_and_name_readable_regions(mill):
    result = machine_yield(mill, mill.initial_allocation, profile="constant",
                           points=3, machines=3000, rng=10, method="crude")
    shares = result.failure_shares
    assert shares["share"].sum() == pytest.approx(1.0)
    assert shares["failures"].sum() == result.failures
    assert (shares["lower"] <= shares["share"]).all() and (shares["share"] <= shares["upper"]).all()
    assert set(shares["output"]) <= set(mill.outputs)
    assert shares["region"].str.contains(
        r"(?:low|middle|high) \(.* mm\)|poses?, all with |sharing no axis position").all()
    text = result.summary()
    assert "profile constant" in text and "first-order bounds" in text
    assert json.loads(json.dumps(result.to_dict()))["method"] == "crude"


@pytest.mark.parametrize("kwargs, words", [
    ({"machines": 0}, "machines"), ({"profile": "wavy"}, "unknown profile"),
    ({"method": "fast"}, "method"), ({"distribution": "uniform"}, "distribution"),
    ({"confidence": 1.5}, "confidence"), ({"target_cov": 0.0}, "target_cov"),
    ({"points": 1}, "points must be")])
def test_bad_inputs_are_refused_naming_the_argument(mill, kwargs, words):
    with pytest.raises(InputError, match=words):
        machine_yield(mill, mill.initial_allocation, **kwargs)


def test_bad_tolerances_are_refused(mill):
    bad = mill.initial_allocation.copy()
    bad[3] = -1.0
    with pytest.raises(InputError, match=mill.error_names[3]):
        machine_yield(mill, bad)


@pytest.mark.parametrize("argv, words", [(["--machines", "0"], "--machines"),
                                         (["--profile", "wavy"], "--profile")])
def test_command_line_refuses_bad_yield_options(tmp_path, capsys, argv, words):
    csv = tmp_path / "a.csv"
    assert cli.main(["allocate", str(MILL), "--out", str(csv), "--points", "3"]) == 0
    capsys.readouterr()
    code = cli.main(["verify", str(MILL), "--tolerances", str(csv), *argv])
    err = capsys.readouterr().err
    assert code == 2 and words in err and err.strip().splitlines()[-1].startswith("precrel")


def test_summary_opens_with_the_yield_of_both_allocations(mill):
    study = machine_study.run(mill, points=3, repeats=2, samples=200, rng=1, machines=400)
    info = machine_study.summary(study)
    assert list(info)[:4] == ["yield", "yield_interval", "yield_profile", "yield_machines"]
    assert set(info["yield"]) == {"initial", "optimal"}
    for name, check in (("initial", "initial"), ("optimal", "optimum")):
        estimate = study.checks[check].machine_yield
        assert info["yield"][name] == estimate.estimate
        assert info["yield_interval"][name] == [estimate.lower, estimate.upper]
    assert info["yield_profile"] == "constant" and info["yield_machines"] == 400
    blocked = machine_study.run(mill, points=3, repeats=2, samples=200, rng=1,
                                machines=200, bounds=(1.0, 1.0))
    info = machine_study.summary(blocked)
    assert not info["reachable"]
    assert info["yield"]["optimal"] is None and info["yield_interval"]["optimal"] is None


def test_yields_near_one_are_printed_with_their_failure_probability():
    from reliability.sampling.yield_estimate import yield_text
    assert yield_text(0.835) == "0.8350"
    assert yield_text(1 - 2.5e-7) == "0.99999975"
    assert yield_text(1 - 1e-12) != "1" and yield_text(1.0) == "1"


def test_kept_points_are_checked_by_axis_before_any_work():
    machine = load_machine(ROOT / "tests/machines/trunnion5.toml")
    with pytest.raises(InputError, match=r"one index array per axis \(5\); got 1"):
        GridExperiment(machine, 3, "constant", kept_points=[[0, 2]])
    bad = [np.arange(3)] * 4 + [np.array([2, 0])]
    with pytest.raises(InputError, match=rf"kept_points of axis {machine.axes[4]} must be "
                                         r"increasing indices in \[0, 2\]; got \[2, 0\]"):
        GridExperiment(machine, 3, "constant", kept_points=bad)


@pytest.mark.parametrize("scale, method", [(1.0, "crude"), (0.5, "importance")])
def test_a_saved_yield_reloads_with_its_verdicts_and_refuses_a_changed_count(
        mill, tmp_path, scale, method):
    """save/load keeps every field and the failure shares; a file whose counts no longer
    give its yield (or whose file exists) is refused."""
    result = machine_yield(mill, scale * mill.initial_allocation, points=3,
                           machines=1500, rng=12, method=method, target_cov=0.2)
    assert inspect.signature(result.save).parameters["overwrite"].default is False
    path = result.save(tmp_path / "yield.json")
    again = YieldEstimate.load(path)
    assert inspect.ismethod(YieldEstimate.load) and again.to_dict() == result.to_dict()
    assert again.summary() == result.summary()
    pd.testing.assert_frame_equal(again.to_frame(), result.to_frame())
    pd.testing.assert_frame_equal(again.failure_shares, result.failure_shares,
                                  check_dtype=False)
    frame = again.to_frame()
    assert frame.shape[0] == 1 and frame["machines"].iloc[0] == result.machines
    with pytest.raises(FileExistsError, match="overwrite=True"):
        result.save(path)
    document = json.loads(path.read_text())
    document["payload"]["estimate"] = 0.5 * result.estimate
    path.write_text(json.dumps(document))
    with pytest.raises(SavedResultError, match=r"field 'payload\.(estimate|lower|upper)'"):
        YieldEstimate.load(path)


def test_a_saved_crude_yield_must_match_its_passing_machines(mill, tmp_path):
    result = machine_yield(mill, mill.initial_allocation, points=3, machines=1000,
                           rng=13, method="crude")
    assert result.failures > 0
    path = result.save(tmp_path / "yield.json")
    document = json.loads(path.read_text())
    document["payload"]["failures"] -= 1
    path.write_text(json.dumps(document))
    with pytest.raises(SavedResultError, match="estimate|lower|upper|failure_shares"):
        YieldEstimate.load(path)
