"""A machine yield is a probability: every estimate, interval end and failure probability
lies in [0, 1] with an interval holding the estimate, whatever the sample size, profile,
seed or method; the estimator is chosen for its regime and named; the intervals cover.

Coverage checks count how often repeated 95 % intervals hold a reference yield (a crude
run of 40 000 machines, its own standard error below 0.003) and allow ``z = 4`` binomial
standard errors below 95 %.
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest
from scipy.stats import beta

from reliability import load_machine
from reliability.basics.errors import SavedResultError
from reliability.sampling.machine_yield import YieldModel
from reliability.sampling.yield_estimate import YieldEstimate
from studies import cli

MILL = Path(__file__).parent / "machines" / "mill3.toml"
Z = 4.0
#: A moderate yield (about 0.5 under gp:300 on the 3-point grid): importance sampling was
#: chosen here for small samples and left [0, 1].
SCALE = 1.5


@pytest.fixture(scope="module")
def mill():
    return load_machine(MILL)


@pytest.fixture(scope="module", params=["constant", "independent", "gp:300"])
def model(request, mill):
    return YieldModel(mill, profile=request.param, points=3)


def assert_probability_with_interval(result):
    """Estimate, interval ends and failure probability in [0, 1], the interval holding
    the estimate and of positive width, the crude-sampling equivalent a count or NaN."""
    assert 0.0 <= result.lower <= result.estimate <= result.upper <= 1.0, result
    assert result.lower < result.upper, result
    assert 0.0 <= result.failure_probability <= 1.0
    assert math.isnan(result.crude_equivalent) or result.crude_equivalent >= 1.0
    assert math.isnan(result.cov) or result.cov >= 0.0


@pytest.mark.parametrize("method", ["auto", "importance"])
def test_small_samples_give_probabilities_with_intervals_holding_them(mill, model, method):
    t = SCALE * mill.initial_allocation
    for machines in (1, 2, 5, 10, 50):
        for seed in range(4):
            result = model.estimate(t, machines=machines, rng=seed, method=method)
            assert_probability_with_interval(result)
            expected = "crude" if method == "auto" else "importance"
            assert result.method == expected
            assert result.interval_method in (
                ("clopper-pearson",) if expected == "crude"
                else ("clipped-wald", "defensive-bound"))


def test_auto_samples_crudely_unless_failures_are_rare_and_the_sample_large(mill):
    model = YieldModel(mill, profile="constant", points=3)
    few = model.estimate(0.5 * mill.initial_allocation, machines=999, rng=1)
    assert few.method == "crude" and "999 machines < 1,000" in few.method_reason
    # linearised failure probability about 0.036: under 50 failing of 1000, but not rare
    common = model.estimate(mill.initial_allocation, machines=1000, rng=1)
    assert common.method == "crude" and "not rare" in common.method_reason
    assert "1 − 0." not in common.summary()


def test_an_importance_sample_without_spread_is_bounded_through_the_defensive_share(mill):
    """One machine, or no failing machine: ``[0, min(1, U/α)]`` for the failure
    probability, ``U`` the Clopper–Pearson upper end of the failing share (computed here
    from the beta quantile), α = 0.1."""
    model = YieldModel(mill, profile="gp:300", points=3)
    one = model.estimate(SCALE * mill.initial_allocation, machines=1, rng=3,
                         method="importance")
    assert one.interval_method == "defensive-bound" and math.isnan(one.cov)
    assert (one.lower, one.upper) == (0.0, 1.0)
    none = model.estimate(0.05 * mill.initial_allocation, machines=30, rng=3,
                          method="importance")
    assert none.failures == 0 and none.interval_method == "defensive-bound"
    upper = beta.ppf(0.975, 1, 30)
    assert none.estimate == 1.0 and none.upper == 1.0
    assert math.isclose(none.lower, 1.0 - min(1.0, upper / 0.1), rel_tol=1e-9)
    assert "crude sampling would need" not in none.summary()


@pytest.fixture(scope="module")
def reference(mill):
    """The gp:300 model and the yield at SCALE from 40 000 crude machines."""
    model = YieldModel(mill, profile="gp:300", points=3)
    truth = model.estimate(SCALE * mill.initial_allocation, machines=40_000, rng=99,
                           method="crude")
    assert 0.3 < truth.estimate < 0.7
    return model, truth.estimate


@pytest.mark.parametrize("machines, method, runs", [(10, "auto", 200),
                                                    (1000, "importance", 60)])
def test_intervals_cover_a_reference_yield(mill, reference, machines, method, runs):
    """Clopper–Pearson of 10 machines (chosen by auto) and the clipped normal interval of
    1000 importance-sampled machines hold the reference in at least 95 % − 4 binomial
    standard errors of the runs."""
    model, truth = reference
    covered = 0
    for seed in range(runs):
        result = model.estimate(SCALE * mill.initial_allocation, machines=machines,
                                rng=1000 + seed, method=method, target_cov=1e-3)
        assert result.method == ("crude" if method == "auto" else "importance")
        covered += result.lower <= truth <= result.upper
    assert covered >= runs * (0.95 - Z * math.sqrt(0.95 * 0.05 / runs))


def test_a_file_saved_before_interval_method_loads_and_one_outside_0_1_is_refused(
        mill, tmp_path):
    model = YieldModel(mill, profile="constant", points=3)
    for method, named in (("crude", "clopper-pearson"), ("importance", "clipped-wald")):
        result = model.estimate(mill.initial_allocation, machines=1000, rng=5,
                                method=method, target_cov=1.0)
        assert result.interval_method == named
        path = result.save(tmp_path / f"{method}.json")
        document = json.loads(path.read_text())
        del document["payload"]["interval_method"]
        path.write_text(json.dumps(document))
        assert YieldEstimate.load(path).to_dict() == result.to_dict()
    bound = model.estimate(SCALE * mill.initial_allocation, machines=1, rng=3,
                           method="importance")
    path = bound.save(tmp_path / "bound.json")
    assert YieldEstimate.load(path).to_dict() == bound.to_dict()
    document = json.loads(path.read_text())
    document["payload"]["lower"] = 0.5
    path.write_text(json.dumps(document))
    with pytest.raises(SavedResultError, match=r"payload\.lower.*defensive-bound"):
        YieldEstimate.load(path)
    document["payload"].update(estimate=-1.0268, lower=0.0, upper=0.6641)
    path.write_text(json.dumps(document))
    with pytest.raises(SavedResultError, match=r"payload\.estimate.*in \[0, 1\]"):
        YieldEstimate.load(path)


def numbers(line: str) -> list[float]:
    """The decimal numbers of a printed line, in order."""
    return [float(text) for text in
            re.findall(r"-?\d+(?:\.\d+)?(?:e-?\d+)?", line)]


@pytest.mark.parametrize("machines", ["1", "10"])
def test_the_command_prints_a_yield_within_its_interval(tmp_path, capsys, machines):
    csv = tmp_path / "a.csv"
    assert cli.main(["allocate", str(MILL), "--out", str(csv), "--points", "3"]) == 0
    rows = csv.read_text().splitlines()
    scaled = [rows[0]] + [",".join(cells[:-1] + [repr(SCALE * float(cells[-1]))])
                          for cells in (row.split(",") for row in rows[1:])]
    csv.write_text("\n".join(scaled) + "\n")
    capsys.readouterr()
    assert cli.main(["verify", str(MILL), "--tolerances", str(csv), "--points", "3",
                     "--repeats", "2", "--samples", "200", "--workspace", "grid",
                     "--machines", machines, "--profile", "gp:300", "--seed", "1"]) == 0
    printed = capsys.readouterr().out
    line = next(line for line in printed.splitlines() if line.startswith("machine yield"))
    estimate, _, lower, upper, failure, *_ = numbers(line)
    assert 0 <= lower <= estimate <= upper <= 1 and lower < upper
    assert 0 <= failure <= 1
    assert f"crude Monte-Carlo of {machines} built machines" in printed
    assert "Clopper–Pearson interval" in printed
    assert "would need about -" not in printed and "would need about ?" not in printed
    assert "CoV nan" not in printed and "CoV 0," not in printed


def test_a_sweep_of_small_repeats_writes_yields_within_0_1(tmp_path):
    """results.csv keeps its columns, and every task's yield (1 to 10 built machines, three
    profiles, three seeds) is a probability."""
    from studies.workflows.sweep import SweepSpec, run_sweep
    spec = SweepSpec(machines=(str(MILL),), targets=(0.9,),
                     profiles=("constant", "independent", "gp:300"), seeds=(0, 1, 2),
                     repeats=(1, 2, 5, 10), points=3)
    result = run_sweep(spec, tmp_path / "store")
    written = result.path.read_text().splitlines()
    assert written[0].split(",") == [
        "machine", "side", "target", "profile", "seed", "repeats", "points", "distribution",
        "workspace", "bounds_low", "bounds_high", "bounds_source", "status", "reason",
        "relative_cost", "certified", "fraction_dx", "fraction_dy", "fraction_dz",
        "fraction_ex", "fraction_ey", "fraction_ez", "yield"]
    yields = np.array([float(row.split(",")[-1]) for row in written[1:]])
    assert len(yields) == 36 and np.all((0.0 <= yields) & (yields <= 1.0))
    assert len(np.unique(yields)) > 2  # not all 0 or 1: the samples see failures
