"""The machine yield judged on each machine's own poses, and the search's check of it."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import reliability
from allocation.yield_target import _Search
from reliability.sampling.machine_yield import YieldModel, _largest_over_poses

MACHINE_DIR = Path(__file__).parent / "machines"


@pytest.fixture(scope="module")
def swivel_model():
    """A workpiece-frame machine whose motion errors differ at every grid point."""
    machine = reliability.load_machine(MACHINE_DIR / "swivel5.toml")
    return YieldModel(replace(machine, profile="independent"), points_per_axis=3)


def test_ratios_at_the_grid_worst_poses_are_the_grid_ratios(swivel_model):
    u = swivel_model.draws(40, 1)
    t = swivel_model.machine.initial_allocation
    full, where = swivel_model.output_ratios(u, t, with_poses=True)
    ratios, found = swivel_model.ratios_at(u, t, where)
    np.testing.assert_allclose(ratios, full, rtol=1e-12)
    np.testing.assert_array_equal(found, where)


def test_ratios_at_other_poses_never_exceed_the_grid(swivel_model):
    u = swivel_model.draws(40, 2)
    t = swivel_model.machine.initial_allocation
    full = swivel_model.output_ratios(u, t)
    poses = np.random.default_rng(3).integers(0, swivel_model.experiment.n_poses, (40, 4))
    ratios, found = swivel_model.ratios_at(u, t, poses)
    assert np.all(ratios <= full * (1 + 1e-12))
    assert all(np.isin(found[m], poses[m]).all() for m in range(40))


@pytest.mark.parametrize("count", [1, 2, 5, 15625])
def test_largest_over_poses_is_the_maximum(count):
    rows = np.random.default_rng(count).standard_normal((3, count, 6))
    np.testing.assert_array_equal(_largest_over_poses(rows.copy()), rows.max(axis=1))


def test_search_checks_its_screen_on_the_whole_grid(trunnion5):
    """A screen that misses the worst poses is caught, widened, and then agrees with the
    grid; every screened verdict is at least as lenient as the grid's."""
    search = _Search(trunnion5, 3, None, 60, 4, 0.0)
    t = trunnion5.initial_allocation
    grid = search.model.output_ratios(search.draws("design"), t) < 1.0
    np.testing.assert_array_equal(search.verdicts(t, "design"), grid)
    search._poses["design"] = np.zeros((60, 1), dtype=np.intp)
    screened = search.verdicts(t, "design")
    assert np.all(screened[grid])
    assert not np.array_equal(screened, grid)
    assert not search.confirm(t, "design")
    assert search._poses["design"].shape == (60, 7)
    assert search.confirm(t, "design")
    np.testing.assert_array_equal(search.verdicts(t, "design"), grid)


def test_ratios_at_skips_missing_poses(swivel_model):
    """A negative pose is no pose: each machine's ratios are those of its other poses, and a
    machine without any pose holds every output (ratio 0, pose -1)."""
    u = swivel_model.draws(30, 5)
    t = swivel_model.machine.initial_allocation
    poses = np.random.default_rng(4).integers(0, swivel_model.experiment.n_poses, (30, 3))
    holes = poses.copy()
    holes[::3, 1] = -1
    holes[1] = -1
    ratios, found = swivel_model.ratios_at(u, t, holes)
    for m in range(30):
        kept = holes[m][holes[m] >= 0]
        if len(kept) == 0:
            assert np.all(ratios[m] == 0) and np.all(found[m] == -1)
            continue
        alone, at = swivel_model.ratios_at(u[m:m + 1], t, kept[None, :])
        np.testing.assert_array_equal(ratios[m], alone[0])
        np.testing.assert_array_equal(found[m], at[0])


def test_a_failed_check_evaluates_the_grid_once(trunnion5, monkeypatch):
    """The check that catches a screen missing the worst poses takes the grid's verdicts and
    its worst poses from one evaluation of the whole grid."""
    search = _Search(trunnion5, 3, None, 60, 4, 0.0)
    t = trunnion5.initial_allocation
    search.verdicts(t, "design")
    search._poses["design"] = np.zeros((60, 1), dtype=np.intp)
    calls = []
    whole_grid = search.model.output_ratios

    def counted(*args, **kwargs):
        calls.append(kwargs)
        return whole_grid(*args, **kwargs)
    monkeypatch.setattr(search.model, "output_ratios", counted)
    assert not search.confirm(t, "design")
    assert len(calls) == 1
