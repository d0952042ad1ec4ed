"""The certified worst pose over the continuous workspace (reliability.first_order.certificate and
reliability.first_order.pose_expansion, docs/certified-workspace.md): the expansion against the
chain, the enclosures, the box bounds against the chain inside random boxes, the certificate
against random poses, grids and closed forms, the stack reading, bad input."""

from __future__ import annotations

import dataclasses
import itertools
from pathlib import Path

import numpy as np
import pytest

import reliability
from reliability import OUTPUTS
from reliability.basics.errors import InputError
from reliability.first_order.box_models import SigmaModel, StackModel
from reliability.first_order.certificate import certified_worst
from reliability.first_order.pose_expansion import (CHECK_RTOL, basis_ranges, fit_expansion,
                                                    interval_tree, jacobian_expansion, point_tree,
                                                    variance_expansion)
from reliability.first_order.workspace_search import continuous_worst
from reliability.model.kinematics import jacobian, jacobian_and_derivative, output_variance
from reliability.model.poses import workspace_grid

RTOL = 1e-3


def strokes(machine):
    low = np.array([axis.stroke[0] for axis in machine.axis_specs])
    high = np.array([axis.stroke[1] for axis in machine.axis_specs])
    return low, high


def random_poses(machine, count, seed):
    low, high = strokes(machine)
    return low + (high - low) * np.random.default_rng(seed).random((count, len(low)))


def perturbed(machine, seed):
    """An allocation 0.5–1.5 × the initial one, so no symmetry makes σ flat by accident."""
    rng = np.random.default_rng(seed)
    return machine.initial_allocation * rng.uniform(0.5, 1.5, machine.n_errors)


def stack(machine, poses, t):
    return np.abs(jacobian(machine, poses, "tool")) @ t


@pytest.fixture(scope="module")
def trunnion_table(trunnion5):
    return certified_worst(trunnion5, trunnion5.initial_allocation, rtol=RTOL)


@pytest.fixture(scope="module")
def swivel5():
    """C table and B swivel head: the tool frame turns with both, so the frames differ."""
    path = Path(__file__).parent / "machines" / "swivel5.toml"
    return dataclasses.replace(reliability.load_machine(path), frame="workpiece")


# ----- the expansion -----------------------------------------------------------------------
@pytest.mark.parametrize("name", ["hobbing", "trunnion5", "mill3"])
def test_expansions_equal_the_chain_at_random_poses(name, request):
    """σ² (degree 2 per axis) and the weighted Jacobian (degree 1) from their node values
    agree with the chain at 500 random poses to 1e-10 relative."""
    machine = request.getfixturevalue(name)
    t = perturbed(machine, 1)
    variance = np.square(t / 3)
    poses = random_poses(machine, 500, 2)
    sigma_sq = variance_expansion(machine, variance)
    direct = output_variance(machine, poses, variance)
    np.testing.assert_allclose(sigma_sq.values(sigma_sq.local(poses)), direct, rtol=1e-10)
    weighted = jacobian_expansion(machine, t)
    direct = jacobian(machine, poses) * t
    scale = np.abs(direct).max(axis=(0, 2))  # per output
    error = np.abs(weighted.values(weighted.local(poses)) - direct).max(axis=(0, 2))
    assert np.all(error <= 1e-10 * scale)


@pytest.mark.parametrize("name", ["trunnion5", "swivel5"])
def test_workpiece_frame_expansions_equal_the_chain(name, request):
    """In the workpiece frame a link's error is R_0k (ε × p + δ), R_0k ε with R_0k of the
    axes before it and p of those after it, so the degrees per axis are kept: both
    expansions agree with the rotated chain at 300 random poses to 1e-10 relative, and
    they differ from the tool frame's."""
    machine = dataclasses.replace(request.getfixturevalue(name), frame="workpiece")
    t = perturbed(machine, 21)
    variance = np.square(t / 3)
    poses = random_poses(machine, 300, 22)
    sigma_sq = variance_expansion(machine, variance, "workpiece")
    direct = output_variance(machine, poses, variance, "workpiece")
    np.testing.assert_allclose(sigma_sq.values(sigma_sq.local(poses)), direct, rtol=1e-10)
    tool = output_variance(machine, poses, variance, "tool")
    assert np.abs(direct - tool).max() > 0.01 * np.abs(tool).max()
    weighted = jacobian_expansion(machine, t, "workpiece")
    direct = jacobian(machine, poses, "workpiece") * t
    scale = np.abs(direct).max(axis=(0, 2))
    error = np.abs(weighted.values(weighted.local(poses)) - direct).max(axis=(0, 2))
    assert np.all(error <= 1e-10 * scale)


def test_expansion_derivatives_are_the_chain_derivatives(trunnion5):
    """The expansion's gradient equals 2 Σ σ_i² J ∂J/∂q from the analytic chain
    derivative, and its Hessian central differences of that gradient."""
    machine = trunnion5
    variance = np.square(perturbed(machine, 3) / 3)
    expansion = variance_expansion(machine, variance)
    poses = random_poses(machine, 20, 4)
    tree = point_tree(expansion, expansion.local(poses), 2)

    def gradient(q):
        jac, derivative = jacobian_and_derivative(machine, q)
        return 2 * np.einsum("bon,baon,n->bao", jac, derivative, variance)

    analytic = gradient(poses)
    for a in range(len(machine.axes)):
        np.testing.assert_allclose(tree[(a,)] / expansion.scale[a], analytic[:, a],
                                   rtol=1e-8, atol=1e-10 * np.abs(analytic).max())
    low, high = strokes(machine)
    for a, b in itertools.combinations_with_replacement(range(len(low)), 2):
        step = np.zeros(len(low))
        step[b] = 1e-6 * (high[b] - low[b])
        central = (gradient(poses + step) - gradient(poses - step))[:, a] / (2 * step[b])
        hessian = tree[(a, b)] / (expansion.scale[a] * expansion.scale[b])
        np.testing.assert_allclose(hessian, central, rtol=1e-5,
                                   atol=1e-6 * np.abs(central).max() + 1e-300)


def test_a_function_of_higher_degree_is_refused(trunnion5):
    """σ² is of degree 2 in each axis: an expansion of degree 1 fails its check and is
    refused with an error naming the function; degree 2 passes."""
    variance = np.square(trunnion5.initial_allocation / 3)

    def sigma_sq(q):
        return output_variance(trunnion5, q, variance)

    with pytest.raises(InputError, match="per-axis expansion of sigma"):
        fit_expansion(trunnion5, sigma_sq, 1, "sigma^2")
    fit_expansion(trunnion5, sigma_sq, 2, "sigma^2")
    assert CHECK_RTOL <= 1e-10


@pytest.mark.parametrize("kind", ["linear", "rotary"])
def test_basis_ranges_contain_and_reach_the_sampled_range(kind):
    """The range of every basis function and derivative on an interval contains 2001
    samples and is reached by them (to the sampling resolution)."""
    from reliability.first_order.pose_expansion import basis_values

    rng = np.random.default_rng(7)
    span = 1.0 if kind == "linear" else 7.0
    low = rng.uniform(-span, span, 40)
    high = low + rng.uniform(0, span, 40)
    if kind == "linear":
        low, high = np.clip(low, -1, 1), np.clip(high, -1, 1)
    samples = low[:, None] + (high - low)[:, None] * np.linspace(0, 1, 2001)
    for derivative in range(3):
        mid, rad = basis_ranges(kind, 2, low, high, derivative)
        values = basis_values(kind, 2, samples, derivative)  # (40, 2001, n)
        assert np.all(values <= (mid + rad)[:, None] + 1e-15)
        assert np.all(values >= (mid - rad)[:, None] - 1e-15)
        resolution = 4 * 2 * (high - low)[:, None] / 2000 + 1e-12
        assert np.all(values.max(axis=1) >= mid + rad - resolution)
        assert np.all(values.min(axis=1) <= mid - rad + resolution)


@pytest.mark.parametrize("name", ["hobbing", "trunnion5"])
def test_interval_tree_encloses_the_derivatives_inside_boxes(name, request):
    machine = request.getfixturevalue(name)
    expansion = variance_expansion(machine, np.square(perturbed(machine, 5) / 3))
    low, high = (expansion.local(end) for end in strokes(machine))
    rng = np.random.default_rng(8)
    centre = low + (high - low) * rng.random((50, len(low)))
    half = (high - low) * 0.2 * rng.random((50, len(low)))
    enclosure = interval_tree(expansion, centre - half, centre + half, 2)
    assert len(enclosure) == len(low) * (len(low) + 1) // 2
    for _ in range(10):
        tree = point_tree(expansion, centre + half * rng.uniform(-1, 1, centre.shape), 2)
        for key, (mid, rad) in enclosure.items():
            assert np.all(np.abs(tree[key] - mid) <= rad * (1 + 1e-9) + 1e-300)


# ----- the box bounds ----------------------------------------------------------------------
@pytest.mark.parametrize("name", ["hobbing", "trunnion5"])
@pytest.mark.parametrize("reading", ["sigma", "stack"])
def test_box_bounds_are_never_below_the_chain_inside_their_box(name, reading, request):
    """For 200 random boxes of every size, each output's bound is at least σ² (or the
    stack) computed from the chain at 20 random poses inside the box and 20 corners."""
    machine = request.getfixturevalue(name)
    t = perturbed(machine, 9)
    variance = np.square(t / 3)
    rng = np.random.default_rng(10)
    if reading == "sigma":
        expansion = variance_expansion(machine, variance)
        models = [SigmaModel(expansion.restricted(o)) for o in range(len(OUTPUTS))]
    else:
        expansion = jacobian_expansion(machine, t)
        models = [StackModel(expansion.restricted(o)) for o in range(len(OUTPUTS))]
    low, high = models[0].local_strokes(machine)
    size = (high - low) * np.exp(rng.uniform(np.log(1e-4), 0, (200, len(low))))
    box_low = low + (high - low - size) * rng.random((200, len(low)))
    box_high = box_low + size
    inside = box_low[:, None] + size[:, None] * rng.random((200, 20, len(low)))
    corners = box_low[:, None] + size[:, None] * rng.integers(0, 2, (200, 20, len(low)))
    points = expansion.pose(np.concatenate([inside, corners], axis=1))
    if reading == "sigma":
        values = output_variance(machine, points, variance)
    else:
        values = stack(machine, points, t)
    for o, model in enumerate(models):
        bound = model.boxes(box_low, box_high)[0]
        assert np.all(values[..., o].max(axis=1) <= bound), OUTPUTS[o]


# ----- the certificate ---------------------------------------------------------------------
def test_bound_is_never_below_sigma_and_meets_rtol(trunnion5, trunnion_table):
    """At 50 000 random poses and on the 9-point grid σ stays below the bound; the gap
    between the bound and σ at the reported pose is at most rtol."""
    table = trunnion_table
    assert table["certified"].all() and list(table.index) == list(OUTPUTS)
    assert np.all(table["sigma_bound"] <= table["sigma"] * (1 + RTOL))
    assert np.all(table["sigma_bound"] >= table["sigma"])
    variance = np.square(trunnion5.initial_allocation / 3)
    for poses in (random_poses(trunnion5, 50_000, 11), workspace_grid(trunnion5, 9)):
        sigma = np.sqrt(output_variance(trunnion5, poses, variance))
        assert np.all(sigma.max(axis=0) <= table["sigma_bound"].to_numpy())
    pose_sigma = np.sqrt(output_variance(trunnion5, table[list(trunnion5.axes)].to_numpy(),
                                         variance))[np.arange(6), np.arange(6)]
    np.testing.assert_allclose(pose_sigma, table["sigma"], rtol=1e-12)
    assert table.attrs == {"rtol": RTOL, "distribution": "normal", "reading": "sigma"}


def test_paper_machine_is_certified_and_bounds_random_poses(hobbing):
    """The paper's machine, an allocation without symmetries: all six outputs certified
    (to 1e-2 here, to keep the test short; the benchmark runs 1e-3) and σ below the bound
    at 20 000 random poses and on the 5-point grid."""
    t = perturbed(hobbing, 12)
    table = certified_worst(hobbing, t, rtol=1e-2)
    assert table["certified"].all() and np.all(table["gap"] <= 1e-2)
    variance = np.square(t / 3)
    for poses in (random_poses(hobbing, 20_000, 13), workspace_grid(hobbing, 5)):
        sigma = np.sqrt(output_variance(hobbing, poses, variance))
        assert np.all(sigma.max(axis=0) <= table["sigma_bound"].to_numpy())


def test_agrees_with_dense_grid_and_local_search(trunnion5, trunnion_table):
    """The best of a 7-point grid and a local search from its worst poses (an independent
    computation on the chain) lies within [sigma_bound/(1 + rtol), sigma_bound]."""
    grid = workspace_grid(trunnion5, 7)
    searched = continuous_worst(trunnion5, trunnion5.initial_allocation, grid)
    found = trunnion5.limits / searched["beta"].to_numpy()  # σ of the search's best pose
    bound = trunnion_table["sigma_bound"].to_numpy()
    assert np.all(found <= bound * (1 + 1e-9))
    assert np.all(trunnion_table["sigma"].to_numpy() >= found / (1 + RTOL))


def test_workpiece_frame_certificate_against_a_dense_search(swivel5):
    """Workpiece frame of a C-table, B-head machine: the best of a 7-point grid and a
    local search from its worst poses, and σ at 20 000 random poses (computations on the
    rotated chain, independent of the expansion), stay below the certified bound, and the
    certified σ is within the stated gap (≤ rtol) of the search's best."""
    t = perturbed(swivel5, 23)
    table = certified_worst(swivel5, t, rtol=RTOL)
    assert table["certified"].all() and np.all(table["gap"] <= RTOL)
    bound, sigma = table["sigma_bound"].to_numpy(), table["sigma"].to_numpy()
    searched = continuous_worst(swivel5, t, workspace_grid(swivel5, 7))
    found = swivel5.limits / searched["beta"].to_numpy()
    assert np.all(found <= bound * (1 + 1e-9))
    assert np.all(sigma * (1 + table["gap"].to_numpy()) >= found * (1 - 1e-9))
    variance = np.square(t / 3)
    poses = random_poses(swivel5, 20_000, 24)
    assert np.all(np.sqrt(output_variance(swivel5, poses, variance, "workpiece")).max(axis=0)
                  <= bound)
    at_pose = output_variance(swivel5, table[list(swivel5.axes)].to_numpy(), variance,
                              "workpiece")
    np.testing.assert_allclose(np.sqrt(at_pose[np.arange(6), np.arange(6)]), sigma,
                               rtol=1e-12)


def test_workpiece_frame_stack_bounds_random_poses(swivel5):
    """The worst-case stack in the workpiece frame: certified, below its bound at 20 000
    random poses of the rotated chain."""
    t = perturbed(swivel5, 25)
    table = certified_worst(swivel5, t, reading="stack", rtol=RTOL)
    assert table["certified"].all()
    poses = random_poses(swivel5, 20_000, 26)
    values = np.abs(jacobian(swivel5, poses, "workpiece")) @ t
    assert np.all(values.max(axis=0) <= table["stack_bound"].to_numpy())


@pytest.mark.parametrize("reading", ["sigma", "stack"])
def test_all_linear_machine_against_its_corners(mill3, reading):
    """On an all-linear machine every J_oi is affine in each position, so σ² and the stack
    are convex in each position and their maximum over the strokes is at one of the 2³
    corners: the certificate lies between that maximum and (1 + rtol) times it."""
    t = perturbed(mill3, 14)
    table = certified_worst(mill3, t, reading=reading)
    low, high = strokes(mill3)
    corners = np.array(list(itertools.product(*zip(low, high))))
    if reading == "sigma":
        exact = np.sqrt(output_variance(mill3, corners, np.square(t / 3))).max(axis=0)
    else:
        exact = stack(mill3, corners, t).max(axis=0)
    assert table["certified"].all()
    assert np.all(table[f"{reading}_bound"].to_numpy() >= exact)
    assert np.all(table[reading].to_numpy() >= exact / (1 + RTOL))
    assert np.all(table[reading].to_numpy() <= exact * (1 + 1e-12))


def test_truncated_reading_scales_sigma(mill3):
    """Truncated at ±3σ every error's σ shrinks by sqrt(1 − 6φ(3)/(2Φ(3) − 1)) = 0.986578,
    so do every σ and bound."""
    normal = certified_worst(mill3, mill3.initial_allocation)
    truncated = certified_worst(mill3, mill3.initial_allocation, distribution="truncated")
    assert truncated.attrs["distribution"] == "truncated"
    np.testing.assert_allclose(truncated["sigma"] / normal["sigma"], 0.986578, rtol=1e-5)


def test_stack_reading_bounds_random_poses(trunnion5):
    """The stack Σ|J_oi| t_i from the chain at 50 000 random poses and on the 9-point grid
    stays below the certified bound, within rtol of the value at the reported pose."""
    t = perturbed(trunnion5, 15)
    table = certified_worst(trunnion5, t, reading="stack", rtol=RTOL)
    assert {"stack", "stack_bound", "gap", "certified", "calls", "seconds"} <= set(table)
    assert "sigma" not in table and table.attrs["reading"] == "stack"
    assert table["certified"].all()
    for poses in (random_poses(trunnion5, 50_000, 16), workspace_grid(trunnion5, 9)):
        assert np.all(stack(trunnion5, poses, t).max(axis=0)
                      <= table["stack_bound"].to_numpy())
    at_pose = stack(trunnion5, table[list(trunnion5.axes)].to_numpy(), t)
    np.testing.assert_allclose(at_pose[np.arange(6), np.arange(6)], table["stack"],
                               rtol=1e-12)


def test_a_search_stopped_early_still_bounds_every_pose(trunnion5):
    """Out of box evaluations the search says so (certified False) and its bound still
    holds over the whole workspace."""
    t = perturbed(trunnion5, 17)
    table = certified_worst(trunnion5, t, reading="stack", max_calls=3)
    assert not table["certified"].all()
    assert np.all(table["gap"] >= 0)
    poses = random_poses(trunnion5, 20_000, 18)
    assert np.all(stack(trunnion5, poses, t).max(axis=0)
                  <= table["stack_bound"].to_numpy())


def test_bad_inputs(mill3):
    t = mill3.initial_allocation
    with pytest.raises(InputError, match="rtol"):
        certified_worst(mill3, t, rtol=0.0)
    with pytest.raises(InputError, match="reading"):
        certified_worst(mill3, t, reading="worst")
    with pytest.raises(InputError, match="max_calls"):
        certified_worst(mill3, t, max_calls=0)
    with pytest.raises(InputError, match="distribution"):
        certified_worst(mill3, t, reading="stack", distribution="uniform")
    with pytest.raises(InputError, match="^k must"):
        certified_worst(mill3, t, k=-1.0)
    with pytest.raises(InputError, match="tolerances"):
        certified_worst(mill3, np.stack([t, t]))
    with pytest.raises(InputError, match="correlated"):
        certified_worst(mill3.with_correlation({("X.dx", "Y.dx"): 0.5}), t)


def test_verify_samples_at_the_certified_worst_poses(trunnion5, trunnion_table):
    """verify(worst_poses=...) samples each output at its certified worst pose under the
    study's reading and says whether the interval reaches the target."""
    from reliability.sampling.verification import verify

    poses = trunnion_table[list(trunnion5.axes)].to_numpy()
    check = verify(trunnion5, trunnion5.initial_allocation, points=3, repeats=2,
                   samples=2000, rng=4, worst_poses=poses, distribution="truncated")
    worst = check.worst_poses
    np.testing.assert_array_equal(worst[list(trunnion5.axes)].to_numpy(), poses)
    assert check.distribution == "truncated"
    np.testing.assert_array_equal(worst["reaches_target"],
                                  worst["mc_upper"] >= trunnion5.targets)
    with pytest.raises(InputError, match="worst_poses"):
        verify(trunnion5, trunnion5.initial_allocation, points=3, repeats=1, samples=10,
               worst_poses=poses[:2])


def test_cli_certify(capsys):
    from studies import cli

    mill = str(Path(__file__).parent / "machines" / "mill3.toml")
    assert cli.main(["predict", mill, "--points", "3", "--certify"]) == 0
    out = capsys.readouterr().out
    assert "certified to 0.001 in sigma" in out and "sigma bound" in out
    assert cli.main(["predict", mill, "--certify", "--rtol", "2"]) == 2


def test_cli_certify_in_the_workpiece_frame(capsys):
    from studies import cli

    swivel = str(Path(__file__).parent / "machines" / "swivel5.toml")
    assert cli.main(["predict", swivel, "--points", "3", "--certify"]) == 0
    out = capsys.readouterr().out
    assert "outputs in the workpiece frame" in out and "certified to 0.001 in sigma" in out
