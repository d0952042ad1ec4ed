"""Allocation for a machine-yield target (allocation.machine_yield, precrel allocate --yield)."""

from __future__ import annotations

import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy.stats import norm

from allocation import YieldUnreachableError, allocate_for_yield, read_allocation_csv
from allocation.machine_yield.yield_shape import scaled_to_yield
from allocation.machine_yield.yield_margin import _cost_at_yield, equal_yield_margin
from allocation.machine_yield.yield_search import (SAMPLE_STREAMS, SAMPLES, YieldSearch,
                                                   two_sided_target)
from allocation.machine_yield.yield_target import DESIGN_Z
import reliability
from reliability.basics import streams
from reliability.basics.errors import InputError, InputTypeError
from reliability.basics.statistics import all_within_share
from reliability.sampling.grid_experiment import GridExperiment
from reliability.sampling.machine_yield import YieldModel
from studies import cli

MACHINE_DIR = Path(__file__).parent / "machines"

Y = 0.9
MACHINES = 300
Z = 4.0  # standard errors allowed between two independent yield estimates
# On 300 design machines the search fits its draws, so its allocation often loses more on the
# calibration sample than the naive start does: on seed 7 the naive start, calibrated, is the
# cheaper and is the result. On SEED the search's error-shape allocation stays the cheaper
# after the calibration, so the tests of the stages see the search's result.
SEED = 3
NAIVE_KEPT_SEED = 7
# The tests of the binomial path: the share of machines passing, the design margin of
# binomial standard errors, no convex step and no log-concave bound (the defaults before the
# radial control variate; that path is tested in tests/test_yield_radial.py).
SHARE = dict(estimator="share", convex_steps=0, bound_machines=0)


@pytest.fixture(scope="module")
def result(trunnion5):
    return allocate_for_yield(trunnion5, Y, profile="constant", points=3, machines=MACHINES,
                              rng=SEED, **SHARE)


def fosm_two_sided(machine, poses, t):
    """Two-sided FOSM probability of every (pose, output), straight from the Jacobian:
    σ_o = sqrt(Σ_i J_oi² (t_i/3)²), P = 2Φ(I/σ) − 1 (Eqs. 20–23)."""
    sigma = np.sqrt(np.einsum("pon,n->po", np.square(machine.jacobian(poses)),
                              np.square(t / 3.0)))
    return 2.0 * norm.cdf(machine.limits / sigma) - 1.0


def test_lower_bound_is_below_both_feasible_costs(result):
    assert result.lower_bound <= result.cost
    assert result.lower_bound <= result.naive.cost
    assert result.gap == pytest.approx(result.cost - result.lower_bound)


def test_relaxation_rows_sit_at_the_yield_target(result):
    """The bound's allocation meets every row at probability Y and the active rows at
    exactly Y (an independent FOSM computation on the same grid)."""
    problem = result.problem
    p = fosm_two_sided(problem.machine, problem.poses, result.lower_bound_tolerances)
    assert p.min() >= Y - 1e-7
    assert p.min() == pytest.approx(Y, abs=1e-6)
    assert problem.cost.total(result.lower_bound_tolerances) >= result.row_bound


def test_lower_bound_holds_for_allocations_meeting_every_row(result):
    """Weak duality: any allocation in the box with every row at probability >= Y costs at
    least the row bound (random allocations in the box, scaled down until they meet Y)."""
    problem = result.problem
    rng = np.random.default_rng(3)
    low, high = problem.lower, problem.upper
    tried = low + rng.random((40, len(low))) * (high - low)
    met = 0
    for t in tried:
        while fosm_two_sided(problem.machine, problem.poses, t).min() < Y and \
                np.any(t > low):
            t = np.maximum(low, 0.9 * t)
        if fosm_two_sided(problem.machine, problem.poses, t).min() >= Y:
            met += 1
            assert problem.cost.total(t) >= result.row_bound
    assert met > 0


def test_machine_yield_stays_below_every_row(result):
    """The relaxation's premise, measured: the machine yield's interval starts below the
    smallest row probability of the allocation found."""
    problem = result.problem
    worst_row = fosm_two_sided(problem.machine, problem.poses, result.tolerances).min()
    assert result.verified_yield.lower <= worst_row


def test_verdict_says_what_the_fresh_machines_show(result):
    assert result.verified == (result.verified_yield.lower >= Y)
    assert result.verified_yield.upper >= Y  # the fresh machines do not refute the target
    assert result.verified_yield.n == MACHINES
    assert result.design_yield.estimate >= result.design_yield_target
    assert result.naive.design_yield.estimate >= result.design_yield_target


def test_verified_yield_agrees_with_an_independent_simulation(result, trunnion5):
    """A separate grid experiment with its own seed: the two yields differ by less than
    Z = 4 standard errors of their difference."""
    experiment = GridExperiment(result.problem.machine, 3, profile="constant")
    other = experiment.run(result.tolerances, repeats=MACHINES, rng=12345,
                           keep_values="none", distribution="normal").all_inside_share()
    a, b = result.verified_yield.estimate, other.estimate
    pooled = 0.5 * (a + b)
    error = np.sqrt(2 * pooled * (1 - pooled) / MACHINES)
    assert abs(a - b) <= Z * max(error, 1.0 / MACHINES)


def test_beats_or_equals_the_naive_method(result):
    """Same design sample and target for both: the search never ends dearer; on this
    machine it is strictly cheaper."""
    assert result.search_cost < result.naive.search_cost
    assert result.output_targets.min() >= 0.5


def test_calibration_scales_the_search_allocation_to_the_design_yield(result, trunnion5):
    """The result is the search's allocation times one factor (inside the box), whose yield
    on the calibration sample, simulated here from the fifth stream, reaches the design
    yield; the naive allocation is calibrated the same way."""
    problem = result.search_problem
    final, found = result.tolerances, result.search_tolerances
    inside = (final > problem.lower) & (final < problem.upper)
    scale = final[inside][0] / found[inside][0]
    np.testing.assert_allclose(final, np.clip(scale * found, problem.lower, problem.upper),
                               rtol=1e-12)
    assert result.calibrated
    model = YieldModel(trunnion5, profile="constant", points=3)
    u = model.draws(MACHINES, streams.yield_allocation_streams(SEED)[4])
    for final, share in ((result.tolerances, result.calibration_yield),
                         (result.naive.tolerances, result.naive.calibration_yield)):
        passes = (model.output_ratios(u, final) < 1.0).all(axis=1)
        assert share.estimate == passes.mean() >= result.design_yield_target


def test_a_calibrated_allocation_is_verified_in_at_least_97_5_percent_of_runs(trunnion5):
    """The design yield's margin, by repetition: an allocation scaled to Y_d on one sample
    of N machines and judged on another independent one has a Clopper-Pearson interval
    above Y in at least 97.5 % of 40 pairs of samples (the failures at most their
    expectation 1 plus 3 binomial standard errors). Scaled to Y itself it fails in
    every one of these 40 pairs."""
    model = YieldModel(trunnion5, profile="constant", points=3)
    problem = YieldSearch(trunnion5, 3, None, MACHINES, 0, 0.0).problem
    design = Y + DESIGN_Z * np.sqrt(Y * (1 - Y) / MACHINES)
    shape = 1.2 * problem.reference
    rng = np.random.default_rng(2026)
    failures = 0
    for _ in range(40):
        u, fresh = model.draws(MACHINES, rng), model.draws(MACHINES, rng)
        found = scaled_to_yield(model, problem.lower, problem.upper, shape, design, u)
        passes = (model.output_ratios(fresh, found["t"]) < 1.0).all(axis=1)
        failures += all_within_share(passes).lower < Y
    assert failures <= 1 + 3 * np.sqrt(40 * 0.025 * 0.975)


def test_shape_stage_meets_the_design_yield_on_its_sample(result):
    """Whichever stage gave the result, its design yield reaches the design target, and the
    shape stage (when it won) is cheaper than the per-output stage alone."""
    assert result.design_yield.estimate >= result.design_yield_target
    targets_only = allocate_for_yield(result.problem.machine, Y, points=3,
                                      machines=MACHINES, rng=SEED, shape_steps=0, **SHARE)
    assert result.search_cost <= targets_only.search_cost
    if result.method == "error shape":
        assert result.cost < targets_only.cost


def test_naive_target_is_one_common_target(result):
    """rounds=0 without the shape stage is the naive method alone, and the same seed gives
    the same naive point."""
    naive = allocate_for_yield(result.problem.machine, Y, points=3, machines=MACHINES,
                               rng=SEED, rounds=0, shape_steps=0, **SHARE)
    assert naive.method == "per-output targets"
    assert np.array_equal(naive.tolerances, result.naive.tolerances)
    assert naive.cost == pytest.approx(result.naive.cost, rel=1e-9)
    assert np.allclose(naive.output_targets, naive.naive.target)
    assert naive.naive.target == pytest.approx(result.naive.target)


def test_common_random_numbers(result):
    """Same seed, same draws: a uniformly tighter allocation keeps every machine that passed
    (the outputs are nearly linear in the errors) and the same allocation gives the same
    verdicts, from a search built anew with the same seed."""
    search = YieldSearch(result.problem.machine, 3, None, 200, 5, 0.0, problem=result.problem)
    again = YieldSearch(result.problem.machine, 3, None, 200, 5, 0.0, problem=result.problem)
    t = result.problem.machine.initial_allocation * 1.5
    loose = search.verdicts(t, "design")
    assert loose.shape == (200, 6)
    assert np.array_equal(loose, again.verdicts(t, "design"))
    tight = search.verdicts(0.7 * t, "design")
    assert np.all(tight[loose])
    assert tight.all(axis=1).sum() > loose.all(axis=1).sum()
    fresh = search.verdicts(t, "verification")  # another sample: other draws
    assert not np.array_equal(search.draws("design"), search.draws("verification"))
    assert fresh.shape == (200, 6)


def test_both_stages_and_verify_judge_machines_by_one_engine(result):
    """The yields the allocation reports are shares of machines judged by
    YieldModel.output_ratios on one draw per sample from the seed's streams; and verify's
    crude yield (YieldModel.estimate) on the same draws gives the same verdicts."""
    machine = result.problem.machine
    model = YieldModel(machine, points=result.points)
    search = YieldSearch(machine, result.points, None, MACHINES, result.seed, 0.0,
                     problem=result.problem)
    every = streams.yield_allocation_streams(result.seed)
    for name in SAMPLES:
        stream = every[SAMPLE_STREAMS[name]]
        np.testing.assert_array_equal(search.draws(name), model.draws(MACHINES, stream))
        np.testing.assert_array_equal(search.verdicts(result.tolerances, name),
                                      model.output_ratios(search.draws(name),
                                                          result.tolerances) < 1.0)
    design, verification, shape, _, calibration, _ = streams.yield_allocation_streams(
        result.seed)
    sample = {"per-output targets": design, "error shape": shape}[result.search_stage]
    passes = (model.output_ratios(model.draws(MACHINES, sample), result.search_tolerances)
              < 1.0).all(axis=1)
    assert result.design_yield.estimate == passes.mean()
    calibrated = (model.output_ratios(model.draws(MACHINES, calibration), result.tolerances)
                  < 1.0).all(axis=1)
    assert result.calibration_yield.estimate == calibrated.mean()
    u = model.draws(MACHINES, verification)
    assert result.verified_yield.estimate == \
        (model.output_ratios(u, result.tolerances) < 1.0).all(axis=1).mean()
    naive = (model.output_ratios(u, result.naive.tolerances) < 1.0).all(axis=1)
    assert result.naive.verified_yield.estimate == naive.mean()
    # verify's yield: YieldModel.estimate draws its crude machines from the second child
    # of its seed; on those same draws the allocation's verdicts give the same yield.
    estimate = model.estimate(result.tolerances, machines=MACHINES, rng=21, method="crude")
    same = model.draws(MACHINES, streams.spawn(21, 2)[1])
    verdicts = model.output_ratios(same, result.tolerances) < 1.0
    assert verdicts.all(axis=1).mean() == estimate.estimate
    assert estimate.failures == int((~verdicts.all(axis=1)).sum())


def test_cost_at_yield_interpolates_linearly():
    """Yields 0.8, 0.9, 1.0 at costs 1, 2, 3: yield 0.85 costs 1.5 and 0.95 costs 2.5."""
    costs = np.array([1.0, 2.0, 3.0])
    passes = np.zeros((3, 10), dtype=bool)
    for row, count in enumerate((8, 9, 10)):
        passes[row, :count] = True
    weights = np.ones((1, 10))
    assert _cost_at_yield(costs, passes, 0.85, weights)[0] == pytest.approx(1.5)
    assert _cost_at_yield(costs, passes, 0.95, weights)[0] == pytest.approx(2.5)
    assert np.isnan(_cost_at_yield(costs, passes, 0.75, weights)[0])


def test_equal_yield_margin_takes_seed_and_refuses_a_generator(result):
    """``seed=`` is the deprecated spelling of ``rng=`` (the same margin, with a warning);
    a Generator is refused by name, the named streams deriving from an integer seed."""
    with pytest.warns(DeprecationWarning, match="seed is deprecated; use rng"):
        old = equal_yield_margin(result, seed=SEED + 4, resamples=20)
    new = equal_yield_margin(result, rng=SEED + 4, resamples=20)
    assert (old["naive"], old["result"], old["margin_error"]) == \
        (new["naive"], new["result"], new["margin_error"])
    with pytest.raises(InputTypeError, match="rng must be None or a non-negative integer"):
        equal_yield_margin(result, rng=np.random.default_rng(SEED))


def test_equal_yield_margin_is_paired_and_finite(result):
    margin = equal_yield_margin(result, level=Y, resamples=300)
    assert margin["level"] == Y
    assert np.isfinite([margin["naive"], margin["result"], margin["margin"]]).all()
    assert margin["margin_error"] > 0
    assert margin["margin"] == pytest.approx(margin["naive"] - margin["result"])
    for name in ("naive", "result"):
        yields = margin["yields"][name]
        assert yields.min() < Y <= yields.max()


def test_two_sided_target_inverts_the_required_index():
    assert two_sided_target(norm.ppf(0.995)) == pytest.approx(0.99)


@pytest.mark.parametrize("kwargs, named", [
    ({"yield_target": 0.0}, "yield_target"), ({"yield_target": 1.0}, "yield_target"),
    ({"yield_target": 1.5}, "yield_target"), ({"yield_target": True}, "yield_target"),
    ({"yield_target": 0.9, "machines": 0}, "machines"),
    ({"yield_target": 0.9, "rng": -1}, "rng"),
    ({"yield_target": 0.9, "rounds": -1}, "rounds"),
    ({"yield_target": 0.9, "convex_steps": -1}, "convex_steps"),
    ({"yield_target": 0.9, "convex_machines": 0}, "convex_machines"),
    ({"yield_target": 0.9, "profile": "bogus"}, "profile"),
])
def test_bad_input_is_refused_by_name(mill3, kwargs, named):
    """A bad value is an InputError, a wrong type (a bool) an InputTypeError; both name it."""
    with pytest.raises((InputError, InputTypeError), match=named):
        allocate_for_yield(mill3, points=3, **kwargs)


def test_unreachable_yield_says_so(mill3):
    with pytest.raises(YieldUnreachableError, match="unreachable"):
        allocate_for_yield(mill3, 0.9, points=3, machines=50, bounds=(1.0, 1.5))


def test_cli_allocates_for_yield(result, tmp_path, capsys):
    out = tmp_path / "yield.csv"
    machine = str(MACHINE_DIR / "trunnion5.toml")
    code = cli.main(["allocate", machine, "--yield", str(Y), "--points", "3",
                     "--machines", str(MACHINES), "--seed", str(SEED), "--profile", "constant",
                     "--out", str(out)])
    assert code == 0
    text = capsys.readouterr().out
    for words in ("lower bound", "of the initial cost", "gap", "verified yield",
                  f"from {MACHINES} fresh built machines", "naive method", "profile constant",
                  "3-point grid", "box [0.5, 1.5]", "distribution 'normal'",
                  "the cheapest found by this search; not certified: see the lower bound"):
        assert words in text
    written = read_allocation_csv(out, reliability.load_machine(machine))
    problem = result.problem
    share = problem.cost.total(written) / problem.cost.total(problem.reference)
    printed = re.search(r"cost \S+ = ([0-9.]+) % of the initial allocation", text)
    # CSV = printed: to the printed 0.01 % (half a step), beside 1e-5 of the CSV's rounding
    assert float(printed.group(1)) == pytest.approx(100 * share, rel=1e-5, abs=0.005)


@pytest.mark.parametrize("extra, words", [
    (["--yield", "0"], "--yield"), (["--yield", "1"], "--yield"),
    (["--yield", "abc"], "--yield"),
    (["--yield", "0.9", "--profile", "gp:-3"], "--profile"),
    (["--yield", "0.9", "--target", "0.99"], "--target does not apply with --yield"),
    (["--yield", "0.9", "--method", "gwo"], "--method gwo does not apply with --yield"),
    (["--yield", "0.9", "--side", "one_sided"], "--side one_sided"),
    (["--yield", "0.9", "--tolerances-out", "x.csv"], "--tolerances-out does not apply"),
    (["--profile", "constant"], "--profile is used with --yield only"),
])
def test_cli_bad_yield_input_is_one_line_exit_2(tmp_path, capsys, extra, words):
    code = cli.main(["allocate", str(MACHINE_DIR / "mill3.toml"), "--points", "3",
                     "--out", str(tmp_path / "a.csv"), *extra])
    assert code == 2
    err = capsys.readouterr().err.strip()
    assert words in err
    assert len(err.splitlines()) == 1
    assert not (tmp_path / "a.csv").exists()


@pytest.fixture(scope="module")
def gantry5_tool():
    """The gantry example in the tool frame: its [bounds] box lets output dy reach the
    largest common target only with every tolerance at its lower bound."""
    machine = reliability.load_machine(Path(__file__).parents[1] / "docs/examples/gantry5.toml")
    return replace(machine, frame="tool")


def test_solve_at_the_cap_is_feasible(gantry5_tool):
    """At the largest common target the box holds, the solve gives an allocation meeting it
    at every pose (an independent FOSM computation), not an infeasible point."""
    search = YieldSearch(gantry5_tool, 3, None, 20, 0, 0.5)
    cap = search.cap.min()
    point = search.evaluate(np.full(6, cap))
    assert np.isfinite(point.cost) and point.verdicts is not None
    p = fosm_two_sided(search.problem.machine, search.problem.poses, point.t)
    assert p.min() >= two_sided_target(cap) - 1e-9


def test_unreachable_yield_names_yield_box_and_outputs(gantry5_tool):
    with pytest.raises(YieldUnreachableError) as raised:
        allocate_for_yield(gantry5_tool, 0.95, points=3, machines=200, rounds=0,
                           shape_steps=0)
    message = str(raised.value)
    for words in ("machine yield 0.95 unreachable", "the machine file's [bounds]",
                  "output dy's rows reach their limits", "on 200 machines", "fails most"):
        assert words in message
    tightest = re.search(r"every tolerance at its lower bound gives ([\d.]+)", message)
    lowest = YieldSearch(gantry5_tool, 3, None, 200, 0, 0.0)
    u = lowest.draws("design")
    passes = (lowest.model.output_ratios(u, lowest.problem.lower) < 1.0).all(axis=1)
    assert float(tightest.group(1)) == pytest.approx(passes.mean(), abs=5e-5)
    design = min(0.95 + DESIGN_Z * np.sqrt(0.95 * 0.05 / 200), 1.0 - 0.5 / 200)
    assert ("unreachable inside the box" in message) == (passes.mean() < design)


@pytest.fixture(scope="module")
def nested_boxes(mill3):
    """One search in the default box and one in a box containing it (same seed, machines,
    grid); on these draws the wider box's own search ends dearer than the default box's once
    both are calibrated (cheaper before)."""
    options = dict(points=3, machines=100, rng=1, rounds=2, shape_steps=6, **SHARE)
    return {box: allocate_for_yield(mill3, Y, bounds=box, **options)
            for box in ((0.5, 1.5), (0.375, 3.0))}


def test_wider_box_costs_no_more(nested_boxes):
    narrow, wide = nested_boxes[(0.5, 1.5)], nested_boxes[(0.375, 3.0)]
    assert wide.cost <= narrow.cost
    assert not narrow.from_narrower_box and wide.from_narrower_box
    np.testing.assert_array_equal(wide.tolerances, narrow.tolerances)  # the same run
    assert np.all(wide.tolerances >= narrow.problem.lower)
    assert np.all(wide.tolerances <= narrow.problem.upper)


def test_result_is_not_called_the_cheapest_without_qualification(result, nested_boxes):
    standing = "the cheapest found by this search; not certified: see the lower bound"
    assert standing in result.summary()
    assert "of the search in" not in result.summary()
    wide = nested_boxes[(0.375, 3.0)]
    assert standing in wide.summary()
    assert ("of the search in this box intersected with the default factor box [0.5, 1.5] × "
            "the initial allocation ([0.5, 1.5] × the initial allocation), cheaper than this "
            "box's own search") in wide.summary()


def test_naive_start_moves_towards_the_lower_bounds_when_its_target_cannot():
    """In swivel5's [bounds] box the most precise common target misses the design yield on
    300 machines while every tolerance at its lower bound meets it: the naive start is that
    target's allocation moved part of the way to the lower bounds, the search goes on from
    there, and the summary says so."""
    swivel5 = reliability.load_machine(MACHINE_DIR / "swivel5.toml")
    result = allocate_for_yield(swivel5, Y, points=3, machines=MACHINES, rng=0, rounds=2,
                                shape_steps=6, **SHARE)
    share = result.naive.toward_lower
    assert 0.0 < share < 1.0
    search = YieldSearch(swivel5, 3, None, MACHINES, 0, result.design_yield_target)
    cap = search.solve(np.full(6, search.cap.min()))
    assert not search.evaluate(cap.z).meets(result.design_yield_target)
    moved = cap.t + share * (search.problem.lower - cap.t)
    assert result.naive.search_cost == pytest.approx(search.problem.cost.total(moved))
    assert result.naive.design_yield.estimate >= result.design_yield_target
    assert f"moved {share:.1%} of the way to the box's lower bounds" in result.summary()
    assert result.search_cost <= result.naive.search_cost
    assert np.isfinite(equal_yield_margin(result)["naive"])  # its family passes through it


def test_the_naive_start_is_the_result_when_it_is_cheaper_once_calibrated(trunnion5):
    """Seed 7: the search ends far cheaper than the naive start on its design sample
    (164.5 % against 202.1 % of the initial cost) but dearer once both are scaled to the
    design yield on the calibration sample, so the result is the calibrated naive start,
    named as such, and the search's own costs stay on record."""
    result = allocate_for_yield(trunnion5, Y, profile="constant", points=3,
                                machines=MACHINES, rng=NAIVE_KEPT_SEED, **SHARE)
    assert result.method == "naive start"
    assert result.search_cost < result.naive.search_cost
    assert result.search_calibrated_cost > result.cost == result.naive.cost
    np.testing.assert_array_equal(result.tolerances, result.naive.tolerances)
    assert result.verified_yield.estimate == result.naive.verified_yield.estimate
    assert result.calibration_yield.estimate == result.naive.calibration_yield.estimate
    model = YieldModel(trunnion5, profile="constant", points=3)
    u = model.draws(MACHINES, streams.yield_allocation_streams(NAIVE_KEPT_SEED)[4])
    problem = result.search_problem
    scaled = scaled_to_yield(model, problem.lower, problem.upper, result.search_tolerances,
                             result.design_yield_target, u)
    assert problem.cost.total(scaled["t"]) == pytest.approx(result.search_calibrated_cost,
                                                            rel=1e-12)
    summary = result.summary()
    assert "found by the naive start stage" in summary
    assert "dearer than the naive start scaled the same way, which is the result" in summary
    margin = equal_yield_margin(result, resamples=50)
    assert margin["margin"] == pytest.approx(0.0, abs=1e-12)  # one family for both


def test_the_search_runs_blas_on_one_thread_whatever_the_caller_set(trunnion5, monkeypatch):
    """The search decides on sampled verdicts whose last bits depend on BLAS's thread
    count, so it pins one thread itself (the paper's machine at 4 000 machines, seed 2023:
    124.41 % of the initial cost on one thread, 124.77 % on two), and gives the caller's
    setting back."""
    from threadpoolctl import threadpool_info, threadpool_limits

    import allocation.machine_yield.yield_target as yield_target

    def blas_threads():
        return [info["num_threads"] for info in threadpool_info()
                if info["user_api"] == "blas"]

    seen = []

    def spy(*args, **kwargs):
        seen.append(blas_threads())
        raise RuntimeError("stopped at the lower bound")

    monkeypatch.setattr(yield_target, "pose_chain_bound", spy)
    with threadpool_limits(limits=2, user_api="blas"):
        callers = blas_threads()
        with pytest.raises(RuntimeError, match="stopped"):
            allocate_for_yield(trunnion5, Y, points=3, machines=50)
        assert blas_threads() == callers
    assert seen[0] and set(seen[0]) == {1}
