"""The certified worst pose over the continuous workspace (reliability.certified,
docs/certified-workspace.md): enclosures, the bound against random poses, the gap, and
agreement with a dense grid plus local search."""

from __future__ import annotations

import numpy as np
import pytest

from reliability import OUTPUTS
from reliability.certified import _hessian_magnitude, interval_jacobian
from reliability.errors import InputError
from reliability.kinematics import jacobian_and_derivative, output_variance
from reliability.poses import workspace_grid
from reliability.worst_case import certified_worst, continuous_worst

RTOL = 1e-3


def strokes(machine):
    low = np.array([axis.stroke[0] for axis in machine.axis_specs])
    high = np.array([axis.stroke[1] for axis in machine.axis_specs])
    return low, high


@pytest.fixture(scope="module")
def trunnion_table(trunnion5):
    return certified_worst(trunnion5, trunnion5.initial_allocation, rtol=RTOL)


@pytest.mark.parametrize("name", ["hobbing", "trunnion5"])
def test_enclosures_hold_inside_their_boxes(name, request):
    """J, ∂J/∂q and |∂²σ²/∂q²| at random poses inside random boxes lie in the enclosures
    (the Hessian against central differences of the analytic gradient)."""
    machine = request.getfixturevalue(name)
    low, high = strokes(machine)
    rng = np.random.default_rng(5)
    centre = low + (high - low) * rng.random((60, len(low)))
    half = (high - low) * 0.05 * rng.random((60, len(low)))
    (j_mid, j_rad), (d_mid, d_rad) = interval_jacobian(machine, centre, half)
    variance = np.square(machine.initial_allocation / 3) * rng.uniform(0.5, 1.5,
                                                                       machine.n_errors)
    for _ in range(5):
        q = centre + half * rng.uniform(-1, 1, centre.shape)
        jac, derivative = jacobian_and_derivative(machine, q)
        assert np.all(np.abs(jac - j_mid) <= j_rad * (1 + 1e-9) + 1e-12)
        assert np.all(np.abs(derivative - d_mid) <= d_rad * (1 + 1e-9) + 1e-12)
    q = centre + half * rng.uniform(-1, 1, centre.shape)
    step = 1e-7 * (high - low)
    for o in (0, 1, 5):
        hessian = _hessian_magnitude(machine, (j_mid, j_rad), (d_mid, d_rad), o, variance)

        def gradient(p, o=o):
            jac, derivative = jacobian_and_derivative(machine, p)
            return 2 * np.einsum("bn,ban,n->ba", jac[:, o], derivative[:, :, o], variance)

        for b in range(len(low)):
            shift = np.zeros(len(low))
            shift[b] = step[b]
            central = (gradient(q + shift) - gradient(q - shift)) / (2 * step[b])
            # difference noise: rounding of the gradient over the step, truncation ~ step²
            noise = 1e-12 * np.abs(gradient(q)).max() / step[b] + 1e-6 * np.abs(central).max()
            assert np.all(np.abs(central) <= hessian[:, :, b] + noise)


def test_bound_is_never_below_sigma_and_meets_rtol(trunnion5, trunnion_table):
    """At 50 000 random poses of the strokes σ stays below the bound, and the gap between
    the bound and σ at the reported pose is at most rtol."""
    table = trunnion_table
    assert table["certified"].all()
    assert np.all(table["sigma_bound"] <= table["sigma"] * (1 + RTOL))
    assert np.all(table["sigma_bound"] >= table["sigma"])
    low, high = strokes(trunnion5)
    poses = low + (high - low) * np.random.default_rng(11).random((50_000, len(low)))
    variance = np.square(trunnion5.initial_allocation / 3)
    sigma = np.sqrt(output_variance(trunnion5, poses, variance))
    assert np.all(sigma.max(axis=0) <= table["sigma_bound"].to_numpy())
    pose_sigma = np.sqrt(output_variance(trunnion5, table[list(trunnion5.axes)].to_numpy(),
                                         variance))[np.arange(6), np.arange(6)]
    np.testing.assert_allclose(pose_sigma, table["sigma"], rtol=1e-12)


def test_agrees_with_dense_grid_and_local_search(trunnion5, trunnion_table):
    """The best of a 7-point grid and a local search from its worst poses lies between
    σ(1 + rtol)⁻¹... i.e. within [sigma_bound/(1 + rtol), sigma_bound]."""
    grid = workspace_grid(trunnion5, 7)
    searched = continuous_worst(trunnion5, trunnion5.initial_allocation, grid)
    found = trunnion5.limits / searched["beta"].to_numpy()  # σ of the search's best pose
    bound = trunnion_table["sigma_bound"].to_numpy()
    assert np.all(found <= bound * (1 + 1e-9))
    assert np.all(trunnion_table["sigma"].to_numpy() >= found / (1 + RTOL))


def test_all_linear_machine_and_reading(mill3):
    """An all-linear machine: σ² is a quadratic of the positions; the truncated reading
    scales every σ and bound by the truncated σ ratio."""
    normal = certified_worst(mill3, mill3.initial_allocation)
    truncated = certified_worst(mill3, mill3.initial_allocation, distribution="truncated")
    assert normal.attrs["distribution"] == "normal" and normal["certified"].all()
    np.testing.assert_allclose(truncated["sigma"] / normal["sigma"], 0.986578, rtol=1e-5)
    grid = workspace_grid(mill3, 9)
    sigma = np.sqrt(output_variance(mill3, grid, np.square(mill3.initial_allocation / 3)))
    assert np.all(sigma.max(axis=0) <= normal["sigma_bound"].to_numpy())
    assert list(normal.index) == list(OUTPUTS)


def test_bad_inputs(mill3):
    with pytest.raises(InputError, match="rtol"):
        certified_worst(mill3, mill3.initial_allocation, rtol=0.0)
    with pytest.raises(InputError, match="correlated"):
        certified_worst(mill3.with_correlation({("X.dx", "Y.dx"): 0.5}),
                        mill3.initial_allocation)


def test_verify_samples_at_the_certified_worst_poses(trunnion5, trunnion_table):
    """verify(worst_poses=...) samples each output at its certified worst pose under the
    study's reading and says whether the interval reaches the target; the exact linear
    probability there is the one FOSM gives at that pose."""
    from reliability.verification import verify

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
    from pathlib import Path

    from studies import cli

    mill = str(Path(__file__).parent / "machines" / "mill3.toml")
    assert cli.main(["predict", mill, "--points", "3", "--certify"]) == 0
    out = capsys.readouterr().out
    assert "certified to 0.001 in sigma" in out and "sigma bound" in out
    assert cli.main(["predict", mill, "--certify", "--rtol", "2"]) == 2
