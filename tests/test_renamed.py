"""One name per idea: ``points`` for the grid size, ``rng`` for randomness; the former
keywords ``points_per_axis`` and ``seed`` still work for one release, with a warning, and a
grid-experiment table saved by 0.3.0 (column ``points_per_axis``) still loads."""

from __future__ import annotations

import json

import numpy as np
import pytest

from allocation import allocate_for_yield
from reliability import GridExperiment, GridExperimentResult, workspace_grid
from reliability.basics.errors import InputError, InputTypeError, SavedResultError
from reliability.basics.renamed import renamed
from reliability.basics.streams import integer_seed
from reliability.sampling.machine_yield import YieldModel, machine_yield
from reliability.sampling.sobol import sobol_indices
from reliability.sampling.verification import Verification, verify
from studies.workflows import machine_study
from studies.workflows.profile_comparison import profile_comparison
from studies.workflows.sweep import SweepSpec

POINTS_WARNING = "points_per_axis is deprecated; use points"
SEED_WARNING = "seed is deprecated; use rng"

#: A grid-experiment table as 0.3.0 saved it: two experiments of 27 poses on a 3-point grid.
SAVED_0_3_0 = "\n".join(
    ["repeat,output,limit,inside,outside,fraction,distribution,k,points_per_axis"]
    + [f"{r},{o},0.01,{n},{27 - n},{n / 27!r},normal,3.0,3"
       for r, counts in ((1, (27, 26, 25, 24, 23, 22)), (2, (20, 21, 22, 23, 24, 25)))
       for o, n in zip(("dx", "dy", "dz", "ex", "ey", "ez"), counts)]) + "\n"


@renamed("old", "new")
def _echo(*, new=None):
    return new


def test_the_old_keyword_works_with_a_warning_naming_both():
    with pytest.warns(DeprecationWarning, match="old is deprecated; use new"):
        assert _echo(old=4) == 4


def test_the_new_keyword_alone_does_not_warn(recwarn):
    assert _echo(new=5) == 5
    assert not [w for w in recwarn if issubclass(w.category, DeprecationWarning)]


def test_both_keywords_are_refused_naming_them():
    with pytest.raises(InputTypeError, match="old and new were both given"):
        _echo(old=1, new=2)


def test_the_warning_points_at_the_caller():
    with pytest.warns(DeprecationWarning) as caught:
        _echo(old=1)
    assert caught[0].filename == __file__


def test_workspace_grid_takes_points_per_axis(mill3):
    with pytest.warns(DeprecationWarning, match=POINTS_WARNING):
        grid = workspace_grid(mill3, points_per_axis=3)
    np.testing.assert_array_equal(grid, workspace_grid(mill3, points=3))
    assert grid.shape == (27, 3)


def test_grid_experiment_takes_points_per_axis(mill3):
    with pytest.warns(DeprecationWarning, match=POINTS_WARNING):
        experiment = GridExperiment(mill3, points_per_axis=2)
    assert experiment.points == 2 and experiment.n_poses == 8
    assert [len(axis) for axis in experiment.axis_points] == [2, 2, 2]
    with pytest.raises(InputTypeError, match="points_per_axis and points"):
        GridExperiment(mill3, points=2, points_per_axis=2)


def test_grid_experiment_result_takes_points_per_axis():
    with pytest.warns(DeprecationWarning, match=POINTS_WARNING):
        result = GridExperimentResult(limits=np.full(6, 0.01), inside=np.zeros((1, 6)),
                                      n_poses=8, points_per_axis=2)
    assert result.points == 2


def test_machine_yield_and_its_model_take_points_per_axis(mill3):
    with pytest.warns(DeprecationWarning, match=POINTS_WARNING):
        model = YieldModel(mill3, points_per_axis=2)
    assert model.experiment.points == 2
    with pytest.warns(DeprecationWarning, match=POINTS_WARNING):
        old = machine_yield(mill3, mill3.initial_allocation, points_per_axis=2, machines=200,
                            rng=4, method="crude")
    new = machine_yield(mill3, mill3.initial_allocation, points=2, machines=200, rng=4,
                        method="crude")
    assert old.estimate == new.estimate and old.workspace == "2-point grid (8 poses)"


def test_sobol_indices_take_points_per_axis(mill3):
    with pytest.warns(DeprecationWarning, match=POINTS_WARNING):
        old = sobol_indices(mill3, samples=50, resamples=5, points_per_axis=2, rng=1)
    new = sobol_indices(mill3, samples=50, resamples=5, points=2, rng=1)
    np.testing.assert_array_equal(old.poses, new.poses)
    np.testing.assert_array_equal(old.S1, new.S1)


def test_profile_comparison_takes_seed_and_points_per_axis(mill3):
    t = {"initial": mill3.initial_allocation}
    with pytest.warns(DeprecationWarning) as caught:
        old = profile_comparison(mill3, t, ("independent",), (3,), seed=7, points_per_axis=2)
    assert {str(w.message) for w in caught} >= {SEED_WARNING, POINTS_WARNING}
    new = profile_comparison(mill3, t, ("independent",), (3,), rng=7, points=2)
    assert old.drop(columns="seconds").equals(new.drop(columns="seconds"))


def test_allocate_for_yield_takes_seed_and_refuses_a_generator(mill3):
    with pytest.warns(DeprecationWarning, match=SEED_WARNING), \
            pytest.raises(InputError, match="rng seed must be a non-negative integer; got -1"):
        allocate_for_yield(mill3, 0.9, seed=-1)
    with pytest.raises(InputTypeError, match="rng must be None or a non-negative integer"):
        allocate_for_yield(mill3, 0.9, rng=np.random.default_rng(0))


def test_machine_study_takes_seed(mill3):
    with pytest.warns(DeprecationWarning, match=SEED_WARNING), \
            pytest.raises(InputError, match="rng seed must be a non-negative integer; got -2"):
        machine_study.run(mill3, seed=-2)


def test_integer_seed():
    assert integer_seed(12) == 12 and integer_seed(np.int64(3)) == 3
    fresh = integer_seed(None)
    assert isinstance(fresh, int) and 0 <= fresh < 2**63
    for bad in (np.random.default_rng(0), 1.5, True, "1"):
        with pytest.raises(InputTypeError, match="rng"):
            integer_seed(bad)
    with pytest.raises(InputError, match="rng"):
        integer_seed(-1)


def test_a_grid_experiment_table_saved_by_0_3_0_still_loads(tmp_path):
    path = tmp_path / "grid.csv"
    path.write_text(SAVED_0_3_0)
    result = GridExperimentResult.load(path)
    assert result.points == 3 and result.n_poses == 27 and result.repeats == 2
    np.testing.assert_array_equal(result.inside, [[27, 26, 25, 24, 23, 22],
                                                  [20, 21, 22, 23, 24, 25]])
    assert (result.distribution, result.k) == ("normal", 3.0)
    saved = result.save(tmp_path / "again.csv")
    assert saved.read_text().splitlines()[0].endswith(",distribution,k,points")


def test_a_table_with_both_grid_columns_is_refused(tmp_path):
    lines = SAVED_0_3_0.splitlines()
    path = tmp_path / "both.csv"
    path.write_text("\n".join([lines[0] + ",points"] + [line + ",3" for line in lines[1:]]))
    with pytest.raises(SavedResultError, match="both columns 'points' and 'points_per_axis'"):
        GridExperimentResult.load(path)


def test_the_sweep_spec_reads_points_per_axis(tmp_path):
    with pytest.warns(DeprecationWarning, match=POINTS_WARNING):
        spec = SweepSpec.from_dict({"machines": ["hobbing"], "points_per_axis": 4})
    assert spec.points == 4 and spec.tasks()[0].points == 4
    assert SweepSpec.from_dict({"machines": ["hobbing"], "points": 4}).points == 4
    with pytest.raises(InputTypeError, match="points_per_axis and points"):
        SweepSpec.from_dict({"machines": ["hobbing"], "points": 4, "points_per_axis": 4})


def test_a_verification_saved_by_0_3_0_still_loads(mill3, tmp_path):
    """A saved verification holds its grid table, whose grid column 0.3.0 named
    ``points_per_axis``: the file still loads, with the grid read as ``points``."""
    result = verify(mill3, mill3.initial_allocation, points=2, repeats=2, samples=50,
                    machines=50, workspace="grid", rng=1)
    path = result.save(tmp_path / "verification.json")
    data = json.loads(path.read_text())
    columns = data["payload"]["grid"]["table"]["columns"]
    columns["points_per_axis"] = columns.pop("points")
    path.write_text(json.dumps(data))
    back = Verification.load(path)
    assert back.grid.points == 2
    np.testing.assert_array_equal(back.grid.inside, result.grid.inside)
