"""The machine as an OpenTURNS and a SALib model (reliability.interop)."""

from __future__ import annotations

import dataclasses
import sys

import numpy as np
import pytest

from reliability.basics.errors import InputError
from reliability.first_order.fosm import fosm
from reliability.first_order.worst_grid_pose import worst_grid_poses
from reliability.interop import exact_gradient, openturns_model, salib_evaluate, salib_problem
from reliability.sampling.sobol import fosm_shares

ot = pytest.importorskip("openturns")


def test_the_gradient_is_the_exact_chains_away_from_zero_error(trunnion5):
    pose = np.array([0.4, -0.3, 50.0, -20.0, 60.0])  # C, A in rad; Y, X, Z in mm
    x = np.random.default_rng(2).normal(size=trunnion5.n_errors) \
        * trunnion5.initial_allocation * 30
    step = 1e-7
    for frame in ("tool", "workpiece"):
        columns = [(trunnion5.comprehensive_error(pose, x + step * e, frame)
                    - trunnion5.comprehensive_error(pose, x - step * e, frame)) / (2 * step)
                   for e in np.eye(trunnion5.n_errors)]
        difference = np.stack(columns, axis=1)
        ours = exact_gradient(trunnion5, pose, x, frame)
        assert np.allclose(ours, difference, rtol=1e-6, atol=1e-9 * np.abs(ours).max())
        assert not np.allclose(ours, trunnion5.jacobian(pose, frame), rtol=1e-9, atol=0)


def test_openturns_function_and_distribution(mill3):
    pose = worst_grid_poses(mill3, mill3.initial_allocation, points=3)[1]
    function, distribution = openturns_model(mill3, "dy", pose)
    sample = distribution.getSample(50)
    values = np.asarray(function(sample))[:, 0]
    assert np.allclose(values, mill3.comprehensive_error(pose, np.asarray(sample))[:, 1])
    assert list(function.getInputDescription()) == list(mill3.error_names)
    assert np.allclose(np.sqrt(np.diag(np.asarray(distribution.getCovariance()))),
                       mill3.initial_allocation / 3)
    _, truncated = openturns_model(mill3, 1, pose, distribution="truncated")
    assert np.allclose(np.asarray(truncated.getRange().getUpperBound()),
                       mill3.initial_allocation)
    correlated = mill3.with_correlation({("X.dx", "Y.dx"): 0.5})
    _, joint = openturns_model(correlated, 1, pose)
    assert not joint.hasIndependentCopula()


def test_openturns_form_matches_fosm_at_the_worst_pose(mill3):
    t = mill3.initial_allocation
    poses = worst_grid_poses(mill3, t, points=3)
    reference = fosm(mill3, t, poses)
    for o in (0, 4):
        function, distribution = openturns_model(mill3, o, poses[o])
        event = ot.ThresholdEvent(ot.CompositeRandomVector(function,
                                                           ot.RandomVector(distribution)),
                                  ot.Greater(), float(mill3.limits[o]))
        algorithm = ot.FORM(ot.AbdoRackwitz(), event, distribution.getMean())
        algorithm.run()
        beta = algorithm.getResult().getHasoferReliabilityIndex()
        # the chain is linear to ~1e-5 in the errors: beta agrees far beyond sampling
        assert beta == pytest.approx(reference.beta[o, o], rel=1e-4)


def test_salib_problem_and_evaluate_give_the_fosm_shares(mill3):
    salib_sobol = pytest.importorskip("SALib.sample.sobol")
    from SALib.analyze import sobol as analyze
    t = mill3.initial_allocation
    problem = salib_problem(mill3)
    assert problem["num_vars"] == mill3.n_errors and problem["dists"][0] == "norm"
    assert np.allclose([b[1] for b in problem["bounds"]], t / 3)
    pose = worst_grid_poses(mill3, t, points=3)[0]
    samples = salib_sobol.sample(problem, 256, calc_second_order=False, seed=4)
    values = salib_evaluate(mill3, samples, "dx", pose)
    assert np.allclose(values, mill3.comprehensive_error(pose, samples)[:, 0])
    result = analyze.analyze(problem, values, calc_second_order=False, seed=4)
    shares = fosm_shares(mill3, t, np.tile(pose, (6, 1)))[0]
    se = np.asarray(result["S1_conf"]) / 1.96  # SALib's half-width at 95 %
    assert np.all(np.abs(np.asarray(result["S1"]) - shares) <= 3.9 * se + 1e-9)
    truncated = salib_problem(dataclasses.replace(mill3, distribution="truncated"))
    assert truncated["dists"][0] == "truncnorm" and truncated["bounds"][0][1] == t[0]


def test_salib_refuses_correlated_errors(mill3):
    with pytest.raises(InputError, match="independent errors"):
        salib_problem(mill3.with_correlation({("X.dx", "Y.dx"): 0.5}))


def test_without_openturns_the_message_names_the_extra(mill3, monkeypatch):
    monkeypatch.setitem(sys.modules, "openturns", None)
    pose = worst_grid_poses(mill3, mill3.initial_allocation, points=2)[0]
    with pytest.raises(ImportError, match=r"interop.*\[interop\]"):
        openturns_model(mill3, "dx", pose)
