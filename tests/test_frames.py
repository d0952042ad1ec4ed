"""Outputs in the tool frame (Eq. 18) or in the workpiece frame: δ_w = R δ_t, ε_w = R ε_t."""

from __future__ import annotations

import dataclasses
import tomllib
from pathlib import Path

import numpy as np
import pytest

from reliability.basics.errors import MachineDescriptionError
from reliability.first_order.fosm import fosm
from reliability.model.kinematics import ideal_rotation, jacobian_and_derivative
from reliability.model.machine_file import load_machine, machine_from_dict
from reliability.model.poses import workspace_grid
from reliability.sampling.grid_experiment import GridExperiment

GANTRY = Path(__file__).parent.parent / "docs" / "examples" / "gantry5.toml"


@pytest.fixture(scope="module")
def gantry():
    return load_machine(GANTRY)


def _poses(machine, n, seed=0):
    rng = np.random.default_rng(seed)
    low = np.array([a.stroke[0] for a in machine.axis_specs])
    high = np.array([a.stroke[1] for a in machine.axis_specs])
    return low + rng.random((n, len(low))) * (high - low)


def test_a_vertical_error_of_a_vertical_axis_is_workpiece_dz_at_every_a_and_c(gantry):
    grid = workspace_grid(gantry, 5)
    x = np.zeros(gantry.n_errors)
    x[gantry.error_index("Z.dz")] = 0.01  # the ram's error along its own (vertical) axis
    work = gantry.comprehensive_error(grid, x, frame="workpiece")
    np.testing.assert_allclose(work[:, 2], 0.01, rtol=1e-9)
    np.testing.assert_allclose(work[:, [0, 1, 3, 4, 5]], 0.0, atol=1e-12)
    tool = gantry.comprehensive_error(grid, x, frame="tool")
    a = grid[:, gantry.axes.index("A")]
    tilted = np.abs(np.sin(a)) > 0.1
    assert np.all(np.abs(tool[tilted, 1]) > 1e-3)  # in the tool frame it leaks into dy


def test_workpiece_frame_is_the_tool_frame_turned_by_the_ideal_rotation(gantry, trunnion5):
    for machine in (gantry, trunnion5):
        q = _poses(machine, 20)
        x = np.random.default_rng(1).normal(scale=1e-4, size=(20, machine.n_errors))
        tool = machine.comprehensive_error(q, x, frame="tool")
        work = machine.comprehensive_error(q, x, frame="workpiece")
        rotation = ideal_rotation(machine, q)
        np.testing.assert_allclose(work[:, :3], np.einsum("pij,pj->pi", rotation, tool[:, :3]),
                                   atol=1e-15)
        np.testing.assert_allclose(work[:, 3:], np.einsum("pij,pj->pi", rotation, tool[:, 3:]),
                                   atol=1e-18)
        # lengths are the same in both frames
        np.testing.assert_allclose(np.linalg.norm(work[:, :3], axis=1),
                                   np.linalg.norm(tool[:, :3], axis=1), rtol=1e-12)


def test_workpiece_jacobian_matches_finite_differences_of_the_exact_model(gantry):
    q = _poses(gantry, 3, seed=2)
    jac = gantry.jacobian(q, frame="workpiece")
    h = 1e-7
    for i in range(0, gantry.n_errors, 5):
        x = np.zeros(gantry.n_errors)
        x[i] = h
        numeric = (gantry.comprehensive_error(q, x, frame="workpiece")
                   - gantry.comprehensive_error(q, -x, frame="workpiece")) / (2 * h)
        np.testing.assert_allclose(numeric, jac[:, :, i], atol=1e-6 * np.abs(jac).max())


def test_workpiece_jacobian_derivative_matches_finite_differences(gantry):
    q = _poses(gantry, 2, seed=3)[0]
    jac, derivative = jacobian_and_derivative(gantry, q, "workpiece")
    np.testing.assert_allclose(jac, gantry.jacobian(q, frame="workpiece"), atol=1e-14)
    for a in range(len(gantry.axes)):
        h = 1e-6 if gantry.axis_specs[a].kind == "rotary" else 1e-3
        step = np.zeros(len(gantry.axes))
        step[a] = h
        numeric = (gantry.jacobian(q + step, frame="workpiece")
                   - gantry.jacobian(q - step, frame="workpiece")) / (2 * h)
        np.testing.assert_allclose(derivative[a], numeric, atol=1e-6 * (1 + np.abs(numeric).max()))


def test_the_machine_files_frame_reaches_fosm_and_the_grid_experiment(gantry):
    tool = dataclasses.replace(gantry, frame="tool")
    grid = workspace_grid(gantry, 3)
    t = gantry.initial_allocation
    in_work, in_tool = fosm(gantry, t, grid), fosm(tool, t, grid)
    assert in_work.frame == "workpiece" and in_tool.frame == "tool"
    assert "workpiece frame" in in_work.summary()
    explicit = fosm(tool, t, grid, frame="workpiece")
    np.testing.assert_allclose(explicit.sigma, in_work.sigma, rtol=1e-12)
    # σ² = Σ J_w² var: the fast variance path agrees with the Jacobian
    variance = np.square(gantry.jacobian(grid, frame="workpiece")) @ np.square(t / 3)
    np.testing.assert_allclose(in_work.sigma, np.sqrt(variance), rtol=1e-10)
    # the grid experiment's fast product reads outputs in the same frame as the exact model
    experiment = GridExperiment(gantry, 3)
    rng = np.random.default_rng(4)
    motion = rng.normal(scale=1e-3, size=(2, len(gantry.axes), 3, 6))
    assembly = rng.normal(scale=1e-3, size=(2, len(gantry.axes) - 1, 6))
    np.testing.assert_allclose(experiment.evaluate(motion, assembly),
                               experiment.reference_evaluate(motion, assembly), atol=1e-12)


def test_frame_is_read_and_refused_by_name(tmp_path):
    text = GANTRY.read_text()
    path = tmp_path / "bad.toml"
    path.write_text(text.replace('frame = "workpiece"', 'frame = "world"'))
    with pytest.raises(MachineDescriptionError, match="requirements.frame"):
        load_machine(path)
    machine = load_machine(GANTRY)
    assert machine_from_dict(tomllib.loads(machine.to_toml())) == machine


def test_the_continuous_certificate_covers_the_workpiece_frame(gantry):
    from reliability.first_order.workspace_search import certified_worst

    assert certified_worst(gantry, gantry.initial_allocation, rtol=1e-2)["certified"].all()
