"""The bad-input contract: a catalogue of bad inputs, one row each, grouped by entry point.

Every row names the entry point (the id's prefix), the bad input, the exception expected
and substrings its message must contain (the argument, the offending item, what was
expected). The policy behind the rows is in docs/inputs.md. Below the catalogue: the
inputs that are accepted on purpose, the labelled-input alignment, lazy child generators,
same seed → same bytes, and atomic saves.
"""

from __future__ import annotations

import copy
import subprocess
import sys
import tomllib
from collections import Counter
from importlib import resources
from pathlib import Path

import matplotlib
import numpy as np
import pandas as pd
import pytest

matplotlib.use("Agg")

import allocation
import reliability
from allocation import AllocationProblem, grey_wolf, solve_gwo, solve_over_workspace
from reliability import (GridExperiment, GridExperimentResult, MachineDescriptionError,
                         RandomPoseResult, fosm, load_machine, machine_from_dict, random_poses,
                         sample_random_poses, workspace_grid)
from reliability.basics.checks import require_size
from reliability.basics.errors import InputError, InputTypeError, SavedResultError, SizeBudgetError
from reliability.basics.statistics import binomial_interval, proportion
from reliability.first_order.fosm import error_sigma
from reliability.first_order.workspace_search import continuous_worst, searched_worst
from reliability.model.error_draws import draw_errors
from reliability.sampling.fosm_comparison import fosm_versus_monte_carlo
from studies.report.plots import plot_comprehensive_error_scatter

ROOT = Path(__file__).resolve().parent.parent
HOB = reliability.hobbing_machine()
MILL = load_machine(Path(__file__).parent / "machines" / "mill3.toml")
T0 = HOB.initial_allocation
TM = MILL.initial_allocation
Q0 = np.zeros((1, 6)) + [0.0, 100.0, 200.0, 0.1, 50.0, 1.0]  # inside every stroke
QM = np.array([[100.0, 0.0, -100.0]])
NAMES = HOB.error_names
SERIES = pd.Series(T0, index=NAMES)
TEXT = (resources.files("reliability") / "machines" / "hobbing.toml").read_text()
GRID_CSV_HEADER = "repeat,output,limit,inside,outside,fraction,distribution,k,points"


def _dict():
    return copy.deepcopy(tomllib.loads(TEXT))


def _axis(data, name):
    return next(a for a in data["axes"] if a["name"] == name)


def _edited(edit):
    """machine_from_dict on the hobbing description after ``edit(data)``."""
    def run(tmp):
        data = _dict()
        edit(data)
        return machine_from_dict(data, source="edited.toml")
    return run


def _set(name, key, value):
    return _edited(lambda d: _axis(d, name).__setitem__(key, value))


def _file(data: bytes, load):
    def run(tmp):
        path = tmp / "saved.csv"
        path.write_bytes(data)
        return load(path)
    return run


def _grid_result():
    inside = np.array([[100, 99, 98, 97, 96, 95], [90, 91, 92, 93, 94, 95]])
    return GridExperimentResult(limits=HOB.limits, inside=inside, n_poses=125,
                                distribution="truncated", k=3.0, points=5)


def _grid_lines():
    return _grid_result().to_frame().to_csv(index=False).splitlines()


def _grid_file(edit):
    """A saved grid-results CSV whose lines (header first) were changed by ``edit``."""
    def run(tmp):
        lines = _grid_lines()
        edit(lines)
        path = tmp / "table9.csv"
        path.write_text("\n".join(lines) + "\n")
        return GridExperimentResult.load(path)
    return run


def _cell(row, column, value):
    """Set one cell (row 1 = first data line) of the saved grid CSV."""
    def edit(lines):
        header = lines[0].split(",")
        cells = lines[row].split(",")
        cells[header.index(column)] = value
        lines[row] = ",".join(cells)
    return _grid_file(edit)


def _random_result():
    return RandomPoseResult(limits=HOB.limits, inside=np.array([990, 1000, 975, 900, 999, 950]),
                            n_samples=1000, fosm_one_sided=np.full(6, 0.99),
                            fosm_two_sided=np.full(6, 0.98))


def _random_file(edit):
    def run(tmp):
        lines = _random_result().saved_frame().to_csv(index=False).splitlines()
        edit(lines)
        path = tmp / "random.csv"
        path.write_text("\n".join(lines) + "\n")
        return RandomPoseResult.load(path)
    return run


def _random_cell(row, column, value):
    def edit(lines):
        header = lines[0].split(",")
        cells = lines[row].split(",")
        cells[header.index(column)] = value
        lines[row] = ",".join(cells)
    return _random_file(edit)


def _small_problem(**options):
    return AllocationProblem.build(MILL, QM, **options)


def _all_locked(tmp):
    problem = _small_problem(locked=MILL.error_names)
    return solve_gwo(problem, n_wolves=5, n_iterations=2)


def _shuffled(series, seed=0):
    return series.sample(frac=1.0, random_state=seed)


E, T, S, F, M = InputError, InputTypeError, SizeBudgetError, SavedResultError, \
    MachineDescriptionError

# (id, call taking a tmp folder, exception, substrings the message must contain)
CATALOGUE = [
    # ----- machine files and descriptions ------------------------------------------
    ("machine_file-binary", _file(b"\xff\xfe\x00\x81binary", load_machine), M,
     ["saved.csv", "not a text"]),
    ("machine_file-size-400-digits", _set("X", "size", 10**400), M, ["size", "401 digits"]),
    ("machine_file-stroke-1e300", _set("X", "stroke", [0.0, 1e300]), M,
     ["axis 'X'", "stroke", "at most"]),
    ("machine_file-size-1e300", _set("Z", "size", 1e300), M, ["axis 'Z'", "size"]),
    ("machine_file-offset-1e300", _set("Y", "offset", [0.0, 1e300, 0.0]), M,
     ["axis 'Y'", "offset"]),
    ("machine_file-rotary-stroke-in-degrees", _set("A", "stroke", [-45.0, 45.0]), M,
     ["axis 'A'", "turn", "degrees", "full_turn"]),
    ("machine_file-axis-name-newline", _set("X", "name", "X\nY"), M, ["axis name", "'X\\nY'"]),
    ("machine_file-axis-name-tab", _set("X", "name", "X\t"), M, ["axis name", "whitespace"]),
    ("machine_file-axis-name-control", _set("X", "name", "X\x00"), M, ["axis name", "control"]),
    ("machine_file-axis-name-nbsp", _set("X", "name", "X\u00a0Y"), M, ["axis name"]),
    ("machine_file-cost-overflow", _edited(lambda d: d["cost"].__setitem__("a", 10**400)), M,
     ["cost.a", "digits"]),
    ("machine_file-limit-infinite",
     _edited(lambda d: d["requirements"]["dx"].__setitem__("limit", float("inf"))), M,
     ["requirements.dx.limit", "finite"]),
    # ----- Machine.error_vector ----------------------------------------------------
    ("error_vector-list", lambda tmp: HOB.error_vector([0.001] * HOB.n_errors), T,
     ["mapping", "list"]),
    ("error_vector-array", lambda tmp: HOB.error_vector(T0), T, ["mapping", "ndarray"]),
    ("error_vector-string", lambda tmp: HOB.error_vector("C.dx=1"), T, ["mapping", "str"]),
    ("error_vector-string-value", lambda tmp: HOB.error_vector({"C.dx": "0.01"}), T,
     ["values['C.dx']", "real number"]),
    ("error_vector-nan-value", lambda tmp: HOB.error_vector({"X.ey": float("nan")}), E,
     ["values['X.ey']", "finite"]),
    ("error_vector-unknown-name", lambda tmp: HOB.error_vector({"Q.dx": 1e-3}), KeyError,
     ["unknown error name", "Q.dx"]),
    # ----- fosm ----------------------------------------------------------------------
    ("fosm-tolerances-strings", lambda tmp: fosm(HOB, [str(v) for v in T0], Q0), T,
     ["tolerances", "dtype"]),
    ("fosm-tolerances-string", lambda tmp: fosm(HOB, "0.01", Q0), T, ["tolerances", "str"]),
    ("fosm-tolerances-dict-missing", lambda tmp: fosm(HOB, dict(list(SERIES.items())[1:]), Q0),
     E, ["tolerances", "missing", "C.dx"]),
    ("fosm-tolerances-dict-string-value",
     lambda tmp: fosm(HOB, {**SERIES.to_dict(), "X.dy": "0.01"}, Q0), T,
     ["tolerances['X.dy']", "number"]),
    ("fosm-tolerances-series-extra",
     lambda tmp: fosm(HOB, pd.concat([SERIES, pd.Series({"W.dx": 0.01})]), Q0), E,
     ["tolerances", "unknown name", "W.dx"]),
    ("fosm-tolerances-series-missing", lambda tmp: fosm(HOB, SERIES.drop("A.ez"), Q0), E,
     ["tolerances", "missing", "A.ez"]),
    ("fosm-tolerances-series-duplicate",
     lambda tmp: fosm(HOB, pd.concat([SERIES, SERIES.iloc[:1]]), Q0), E,
     ["tolerances", "more than once", "C.dx"]),
    ("fosm-tolerances-series-unlabelled",
     lambda tmp: fosm(HOB, pd.Series(T0), Q0), E, ["tolerances", "unknown name", "0"]),
    ("fosm-tolerances-wrong-length", lambda tmp: fosm(HOB, T0[:-1], Q0), E,
     ["tolerances", "shape", "66"]),
    ("fosm-tolerances-negative", lambda tmp: fosm(HOB, np.where(np.arange(66) == 7, -1, T0), Q0),
     E, ["tolerance of 'X.dy'", "> 0"]),
    ("fosm-tolerances-nan", lambda tmp: fosm(HOB, np.where(np.arange(66) == 0, np.nan, T0), Q0),
     E, ["tolerance of 'C.dx'", "finite"]),
    ("fosm-tolerances-400-digits", lambda tmp: fosm(HOB, [10**400] + list(T0[1:]), Q0), T,
     ["tolerances", "dtype object"]),
    ("fosm-tolerances-two-allocations", lambda tmp: fosm(HOB, np.vstack([T0, T0]), Q0), ValueError,
     ["one allocation"]),
    ("fosm-k-string", lambda tmp: fosm(HOB, T0, Q0, k="3"), T, ["coverage factor k", "'3'"]),
    ("fosm-k-zero", lambda tmp: fosm(HOB, T0, Q0, k=0), E, ["coverage factor k", "0"]),
    ("fosm-k-nan", lambda tmp: fosm(HOB, T0, Q0, k=float("nan")), E, ["coverage factor k",
                                                                       "finite"]),
    ("fosm-zero-poses", lambda tmp: fosm(HOB, T0, np.empty((0, 6))), E,
     ["poses", "at least one pose", "(0, 6)"]),
    ("fosm-pose-outside-stroke", lambda tmp: fosm(HOB, T0, Q0 + [0, 500, 0, 0, 0, 0]), E,
     ["axis 'X'", "position 600.0", "stroke [0.0, 400.0]", "allow_outside_stroke"]),
    ("fosm-pose-rotary-in-degrees", lambda tmp: fosm(HOB, T0, Q0 + [0, 0, 0, 30, 0, 0]), E,
     ["axis 'A'", "30.1", "outside its stroke"]),
    ("fosm-pose-nan", lambda tmp: fosm(HOB, T0, Q0 + [0, 0, np.nan, 0, 0, 0]), E,
     ["positions", "'Z'", "finite"]),
    ("fosm-poses-strings", lambda tmp: fosm(HOB, T0, [["0", "1", "2", "0", "1", "0"]]), T,
     ["positions", "dtype"]),
    ("fosm-poses-wrong-width", lambda tmp: fosm(HOB, T0, np.zeros((2, 5))), E,
     ["positions", "shape", "'C', 'X'"]),
    ("fosm-poses-frame-missing-axis",
     lambda tmp: fosm(HOB, T0, pd.DataFrame(Q0, columns=HOB.axes).drop(columns="A")), E,
     ["positions", "missing", "'A'"]),
    ("fosm-distribution", lambda tmp: fosm(HOB, T0, Q0, distribution="uniform"), E,
     ["distribution", "uniform", "truncated"]),
    ("fosm-means-wrong-length", lambda tmp: fosm(HOB, T0, Q0, means=np.zeros(5)), E,
     ["errors", "shape", "66"]),
    ("fosm-means-series-missing",
     lambda tmp: fosm(HOB, T0, Q0, means=pd.Series(0.0, index=NAMES[:-1])), E,
     ["errors", "missing", NAMES[-1]]),
    ("fosm-results-over-budget", lambda tmp: fosm(HOB, T0, Q0, budget=100), S,
     ["FOSM results", "budget", "chunks"]),
    ("fosm-error_sigma-k-string", lambda tmp: error_sigma(T0, k="3"), T, ["k", "'3'"]),
    # ----- workspace_grid ------------------------------------------------------------
    ("workspace_grid-points-string", lambda tmp: workspace_grid(HOB, "5"), T,
     ["points must be", "'5'"]),
    ("workspace_grid-points-one", lambda tmp: workspace_grid(HOB, 1), E,
     ["points must be", ">= 2"]),
    ("workspace_grid-points-float", lambda tmp: workspace_grid(HOB, 2.5), E,
     ["points must be", "2.5"]),
    ("workspace_grid-P^n-over-budget", lambda tmp: workspace_grid(HOB, 200), S,
     ["200-point grid on 6 axes", "budget", "fewer points", "pose set"]),
    ("workspace_grid-small-budget", lambda tmp: workspace_grid(HOB, 5, budget=1000), S,
     ["15,625", "budget"]),
    # ----- random_poses --------------------------------------------------------------
    ("random_poses-zero", lambda tmp: random_poses(HOB, 0), E, ["number of poses", "0"]),
    ("random_poses-negative", lambda tmp: random_poses(HOB, -1), E, ["number of poses", "-1"]),
    ("random_poses-string", lambda tmp: random_poses(HOB, "10"), T, ["number of poses"]),
    ("random_poses-rng-negative", lambda tmp: random_poses(HOB, 3, rng=-1), E,
     ["rng", "non-negative", "-1"]),
    ("random_poses-rng-float", lambda tmp: random_poses(HOB, 3, rng=1.5), T, ["rng", "1.5"]),
    ("random_poses-rng-string", lambda tmp: random_poses(HOB, 3, rng="seed"), T,
     ["rng", "'seed'"]),
    ("random_poses-over-budget", lambda tmp: random_poses(HOB, 10**12), S,
     ["random poses", "budget", "fewer"]),
    # ----- GridExperiment ------------------------------------------------------------
    ("GridExperiment-P^n-over-budget", lambda tmp: GridExperiment(HOB, 100), S,
     ["100-point grid of 6 axes", "budget", "fewer points"]),
    ("GridExperiment-points-one", lambda tmp: GridExperiment(HOB, 1), E, ["points must be"]),
    ("GridExperiment-run-repeats-zero", lambda tmp: GridExperiment(MILL, 3).run(TM, repeats=0),
     E, ["repeats", ">= 1", "0"]),
    ("GridExperiment-run-repeats-negative",
     lambda tmp: GridExperiment(MILL, 3).run(TM, repeats=-1), E, ["repeats", "-1"]),
    ("GridExperiment-run-repeats-string",
     lambda tmp: GridExperiment(MILL, 3).run(TM, repeats="20"), T, ["repeats", "'20'"]),
    ("GridExperiment-run-batch-zero", lambda tmp: GridExperiment(MILL, 3).run(TM, batch=0), E,
     ["batch", "0"]),
    ("GridExperiment-run-rng-negative", lambda tmp: GridExperiment(MILL, 3).run(TM, rng=-1),
     E, ["rng", "-1"]),
    ("GridExperiment-run-keep-values",
     lambda tmp: GridExperiment(MILL, 3).run(TM, keep_values="some"), E,
     ["keep_values", "some"]),
    ("GridExperiment-run-k-string", lambda tmp: GridExperiment(MILL, 3).run(TM, k="3"), T,
     ["coverage factor k"]),
    ("GridExperiment-run-results-over-budget",
     lambda tmp: GridExperiment(MILL, 3).run(TM, repeats=10**12, keep_values="none"), S,
     ["1,000,000,000,000 experiments", "budget", "fewer repeats"]),
    ("GridExperiment-run-all-values-over-budget",
     lambda tmp: GridExperiment(MILL, 3, budget=10**6).run(TM, repeats=10**4,
                                                          keep_values="all"), S,
     ["experiments", "keep_values"]),
    ("GridExperiment-run-batch-over-budget",
     lambda tmp: GridExperiment(MILL, 3, budget=10**5).run(TM, repeats=100, batch=100), S,
     ["batch of 100", "smaller batch"]),
    ("GridExperiment-run-tolerances-series-wrong-names",
     lambda tmp: GridExperiment(MILL, 3).run(pd.Series(TM), repeats=2), E,
     ["tolerances", "unknown name"]),
    # ----- sample_random_poses ---------------------------------------------------------
    ("sample_random_poses-negative", lambda tmp: sample_random_poses(MILL, TM, -1), E,
     ["n_samples", "-1"]),
    ("sample_random_poses-chunk-zero", lambda tmp: sample_random_poses(MILL, TM, 10, chunk=0),
     E, ["chunk", "0"]),
    ("sample_random_poses-rng-negative",
     lambda tmp: sample_random_poses(MILL, TM, 10, rng=-1), E, ["rng", "-1"]),
    ("sample_random_poses-chunk-over-budget",
     lambda tmp: sample_random_poses(MILL, TM, 10**9, chunk=10**9), S,
     ["chunk of 1,000,000,000", "smaller chunk"]),
    ("sample_random_poses-k-nan",
     lambda tmp: sample_random_poses(MILL, TM, 10, k=float("nan")), E, ["k", "finite"]),
    ("sample_random_poses-tolerances-dict",
     lambda tmp: sample_random_poses(MILL, {"Y.dx": 0.01}, 10), E, ["tolerances", "missing"]),
    ("draw_errors-rng-negative", lambda tmp: draw_errors(TM, (2,), rng=-1), E, ["rng", "-1"]),
    ("draw_errors-tolerances-string", lambda tmp: draw_errors("abc", (2,)), T, ["tolerances"]),
    # ----- AllocationProblem.build -------------------------------------------------------
    ("AllocationProblem-side", lambda tmp: _small_problem(side="both"), E, ["side", "both"]),
    ("AllocationProblem-workspace", lambda tmp: _small_problem(workspace="all"), E,
     ["workspace", "all"]),
    ("AllocationProblem-k-string", lambda tmp: _small_problem(k="3"), T, ["coverage factor k"]),
    ("AllocationProblem-bounds-reversed", lambda tmp: _small_problem(bounds=(1.5, 0.5)), E,
     ["bounds", "low <= high"]),
    ("AllocationProblem-bounds-string", lambda tmp: _small_problem(bounds="0.5,1.5"), T,
     ["bounds", "two factors"]),
    ("AllocationProblem-bounds-nan", lambda tmp: _small_problem(bounds=(np.nan, 1.5)), E,
     ["bounds", "finite"]),
    ("AllocationProblem-zero-poses", lambda tmp: AllocationProblem.build(MILL, np.empty((0, 3))),
     E, ["poses", "at least one pose"]),
    ("AllocationProblem-pose-outside-stroke",
     lambda tmp: AllocationProblem.build(MILL, [[100.0, 0.0, 50.0]]), E,
     ["axis 'Z'", "50.0", "allow_outside_stroke"]),
    ("AllocationProblem-reference-series-wrong-names",
     lambda tmp: _small_problem(reference=pd.Series(TM)), KeyError,
     ["unknown error name 0", "Y.dx"]),
    ("AllocationProblem-locked-unknown", lambda tmp: _small_problem(locked=["Q.dx"]), KeyError,
     ["Q.dx"]),
    ("AllocationProblem-grid-over-budget",
     lambda tmp: AllocationProblem.build(HOB, budget=10**6), S,
     ["5-point grid on 6 axes", "budget", "fewer points"]),
    ("AllocationProblem-rows-over-budget",
     lambda tmp: AllocationProblem.build(HOB, budget=3 * 10**6), S,
     ["screened rows", "budget", "fewer poses"]),
    ("AllocationProblem-with_poses-outside",
     lambda tmp: _small_problem().with_poses([[100.0, 0.0, 10.0]]), E,
     ["extra", "axis 'Z'", "outside"]),
    # ----- solvers -----------------------------------------------------------------------
    ("solve_gwo-every-item-locked", _all_locked, E, ["every item", "locked"]),
    ("solve_gwo-rng-negative", lambda tmp: solve_gwo(_small_problem(), n_wolves=5,
                                                      n_iterations=2, rng=-1), E, ["rng", "-1"]),
    ("solve_gwo-wolves-too-few", lambda tmp: solve_gwo(_small_problem(), n_wolves=2), ValueError,
     ["n_wolves", ">= 3"]),
    ("grey_wolf-rng-string", lambda tmp: grey_wolf(lambda x: x.sum(1), [0.0], [1.0],
                                                   n_wolves=3, n_iterations=1, rng="x"), T,
     ["rng", "'x'"]),
    ("solve_over_workspace-max-rounds-zero",
     lambda tmp: solve_over_workspace(_small_problem(), max_rounds=0), E,
     ["max_rounds", ">= 1", "0"]),
    ("solve_over_workspace-max-rounds-negative",
     lambda tmp: solve_over_workspace(_small_problem(), max_rounds=-1), E, ["max_rounds"]),
    ("solve_over_workspace-max-rounds-string",
     lambda tmp: solve_over_workspace(_small_problem(), max_rounds="3"), T, ["max_rounds"]),
    ("solve_over_workspace-tolerance-nan",
     lambda tmp: solve_over_workspace(_small_problem(), tolerance=np.nan), E,
     ["tolerance", "finite"]),
    # ----- continuous_worst ---------------------------------------------------------------
    ("continuous_worst-starts-negative", lambda tmp: continuous_worst(MILL, TM, QM, starts=-1), E,
     ["starts", "-1"]),
    ("continuous_worst-starts-zero", lambda tmp: continuous_worst(MILL, TM, QM, starts=0), E,
     ["starts", ">= 1"]),
    ("continuous_worst-starts-string", lambda tmp: continuous_worst(MILL, TM, QM, starts="3"), T,
     ["starts"]),
    ("continuous_worst-empty-grid", lambda tmp: continuous_worst(MILL, TM, np.empty((0, 3))), E,
     ["grid", "at least one pose"]),
    ("continuous_worst-grid-outside", lambda tmp: continuous_worst(MILL, TM, QM * 10), E,
     ["grid", "axis 'Y'", "outside"]),
    ("continuous_worst-two-allocations",
     lambda tmp: continuous_worst(MILL, np.vstack([TM, TM]), QM), E, ["one allocation"]),
    ("searched_worst-scale-short",
     lambda tmp: searched_worst(MILL, TM, QM, scale=[1.0, 1.0]), E, ["scale", "one per output"]),
    ("searched_worst-scale-zero",
     lambda tmp: searched_worst(MILL, TM, QM, scale=np.zeros(6)), E, ["scale", "positive"]),
    ("searched_worst-scale-nan",
     lambda tmp: searched_worst(MILL, TM, QM, scale=np.full(6, np.nan)), E, ["scale", "finite"]),
    ("searched_worst-distribution",
     lambda tmp: searched_worst(MILL, TM, QM, distribution="uniform"), E,
     ["distribution", "uniform"]),
    # ----- statistics -------------------------------------------------------------------
    ("statistics-proportion-more-successes", lambda tmp: proportion(11, 10), ValueError,
     ["successes"]),
    ("statistics-confidence-above-one", lambda tmp: binomial_interval(5, 10, 1.5), ValueError,
     ["confidence", "1.5"]),
    ("statistics-method", lambda tmp: binomial_interval(5, 10, method="exactish"), ValueError,
     ["method", "exactish"]),
    ("plots-scatter-rng-negative",
     lambda tmp: plot_comprehensive_error_scatter(np.r_[0.0, 0.03, 0.0, 0.0], 0.02,
                                                  output_label="dx", max_points=2, rng=-1),
     E, ["rng", "-1"]),
    ("CostModel-k1-string", lambda tmp: allocation.CostModel.from_machine(MILL, "1"), T,
     ["k1"]),
    ("CostModel-total-string", lambda tmp: allocation.CostModel.from_machine(MILL).total("abc"),
     T, ["tolerances", "str"]),
    ("CostModel-total-series-missing",
     lambda tmp: allocation.CostModel.from_machine(MILL).total(
         pd.Series(TM, index=MILL.error_names).iloc[1:]), E, ["tolerances", "missing", "Y.dx"]),
    ("fcem-weights-strings",
     lambda tmp: allocation.fcem_coefficient(["0.5", "0.5"], np.eye(2, 5)), T,
     ["weights", "dtype"]),
    ("statistics-confidence-string", lambda tmp: binomial_interval(5, 10, "0.95"), T,
     ["confidence", "'0.95'"]),
    ("statistics-fractions-strings",
     lambda tmp: reliability.basics.statistics.between_experiment_interval([["a"], ["b"]]), T,
     ["fractions", "dtype"]),
    ("GridExperimentResult-inside-above-poses",
     lambda tmp: GridExperimentResult(limits=HOB.limits, inside=np.full((2, 6), 200),
                                      n_poses=125), E, ["inside[0, 0]", "n_poses = 125"]),
    ("GridExperimentResult-inside-negative",
     lambda tmp: GridExperimentResult(limits=HOB.limits, inside=-np.ones((1, 6)), n_poses=9),
     E, ["inside[0, 0]", "whole count"]),
    ("GridExperimentResult-table8-string", lambda tmp: _grid_result().table8("0"), T,
     ["repeat", "'0'"]),
    ("GridExperiment-evaluate-strings", lambda tmp: GridExperiment(MILL, 3).evaluate("a", "b"),
     T, ["motion errors"]),
    ("solve_gwo-initial-wrong-length",
     lambda tmp: solve_gwo(_small_problem(), n_wolves=4, n_iterations=1, initial=np.ones(3)),
     E, ["tolerances", "shape", "30"]),
    ("solve_exact-gap-tol-string", lambda tmp: _small_problem().solve_exact(gap_tol="x"), T,
     ["gap_tol", "'x'"]),
    ("AllocationProblem-locked-number", lambda tmp: _small_problem(locked=5), T,
     ["locked", "5"]),
    ("RandomPoseResult-inside-above-samples",
     lambda tmp: RandomPoseResult(limits=HOB.limits, inside=np.full(6, 11), n_samples=10,
                                  fosm_one_sided=np.ones(6), fosm_two_sided=np.ones(6)), E,
     ["inside", "n_samples = 10"]),
    ("comparison-not-a-fosm-result",
     lambda tmp: fosm_versus_monte_carlo("fosm", _grid_result()), T, ["fosm_result", "str"]),
    ("comparison-not-a-grid-result",
     lambda tmp: fosm_versus_monte_carlo(fosm(HOB, T0, Q0), _random_result()), T,
     ["grid_result", "RandomPoseResult"]),
    ("GridExperiment-run-progress-not-callable",
     lambda tmp: GridExperiment(MILL, 3).run(TM, progress=True), T, ["progress"]),
    ("sample_random_poses-progress-not-callable",
     lambda tmp: sample_random_poses(MILL, TM, 10, progress="bar"), T, ["progress", "'bar'"]),
    ("solve_over_workspace-log-not-callable",
     lambda tmp: solve_over_workspace(_small_problem(), log=print.__name__), T, ["log"]),
    # ----- require_size -----------------------------------------------------------------
    ("require_size-over", lambda tmp: require_size(10**20, 8, None, "a thing", "do less"), S,
     ["a thing", "budget", "do less"]),
    # ----- saved grid results (GridExperimentResult.load) -------------------------
    ("saved_grid_csv-empty-file", _file(b"", GridExperimentResult.load), F, ["saved.csv"]),
    ("saved_grid_csv-garbage", _file(b"\x00\xff\xfe garbage \x81\n\x00", GridExperimentResult.load),
     F, ["saved.csv"]),
    ("saved_grid_csv-header-only", _file((GRID_CSV_HEADER + "\n").encode(),
                                   GridExperimentResult.load), F, ["saved.csv", "no rows"]),
    ("saved_grid_csv-other-table", _file(b"a,b\n1,2\n", GridExperimentResult.load), F,
     ["saved.csv", "'repeat'"]),
    ("saved_grid_csv-truncated", _grid_file(lambda ls: ls.__setitem__(-1, ls[-1][:12])), F,
     ["table9.csv", "row 12"]),
    ("saved_grid_csv-missing-row", _grid_file(lambda ls: ls.pop(8)), F,
     ["table9.csv", "repeat 2", "'dy'", "missing"]),
    ("saved_grid_csv-duplicated-row", _grid_file(lambda ls: ls.append(ls[3])), F,
     ["table9.csv", "row 13", "more than once"]),
    ("saved_grid_csv-inside-above-poses", _cell(1, "inside", "200"), F,
     ["table9.csv", "row 1", "pose counts"]),
    ("saved_grid_csv-negative-inside", _cell(2, "inside", "-1"), F,
     ["row 2", "'inside'", ">= 0"]),
    ("saved_grid_csv-negative-outside", _cell(5, "outside", "-5"), F, ["row 5", "'outside'"]),
    ("saved_grid_csv-count-overflow", _cell(4, "inside", "9223372036854775808"), F,
     ["row 4", "'inside'", "whole number"]),
    ("saved_grid_csv-count-fractional", _cell(4, "inside", "96.5"), F, ["row 4", "'inside'"]),
    ("saved_grid_csv-count-text", _cell(3, "inside", "many"), F, ["row 3", "'inside'", "'many'"]),
    ("saved_grid_csv-changed-limit", _cell(7, "limit", "0.5"), F,
     ["row 7", "'limit'", "limit of output 'dx'"]),
    ("saved_grid_csv-limit-nan", _cell(2, "limit", "nan"), F, ["row 2", "'limit'", "finite"]),
    ("saved_grid_csv-fraction-above-one", _cell(1, "fraction", "1.5"), F,
     ["row 1", "'fraction'", "inside / poses"]),
    ("saved_grid_csv-unknown-output", _cell(6, "output", "ew"), F, ["row 6", "'output'", "'ew'"]),
    ("saved_grid_csv-repeat-zero", _cell(1, "repeat", "0"), F, ["row 1", "'repeat'"]),
    ("saved_grid_csv-mixed-distribution", _cell(9, "distribution", "normal"), F,
     ["row 9", "'distribution'", "more than one"]),
    ("saved_grid_csv-unknown-distribution", _cell(1, "distribution", "uniform"), F,
     ["row 1", "'distribution'"]),
    ("saved_grid_csv-mixed-k", _cell(10, "k", "2.5"), F, ["row 10", "'k'"]),
    ("saved_grid_csv-k-text", _cell(1, "k", "three"), F, ["row 1", "'k'"]),
    ("saved_grid_csv-points-one", _cell(1, "points", "1"), F, ["'points'"]),
    ("saved_grid_csv-extra-column", _grid_file(lambda ls: ls.__setitem__(
        slice(None), [line + ",x" for line in ls])), F, ["unexpected column"]),
    ("saved_grid_csv-missing-column", _grid_file(lambda ls: ls.__setitem__(
        slice(None), [line.rsplit(",", 1)[0] for line in ls])), F,
     ["lacks column", "'points'"]),
    ("saved_grid_csv-from_frame-not-a-table",
     lambda tmp: GridExperimentResult.from_frame({"repeat": [1]}), F, ["expected a table"]),
    # ----- saved random-pose results (RandomPoseResult.load) ----------------------
    ("saved_random_csv-empty-file", _file(b"", RandomPoseResult.load), F, ["saved.csv"]),
    ("saved_random_csv-duplicated-output", _random_file(lambda ls: ls.__setitem__(2, ls[1])), F,
     ["random.csv", "row 2", "more than once"]),
    ("saved_random_csv-missing-output", _random_file(lambda ls: ls.pop(3)), F,
     ["output 'dz' is missing"]),
    ("saved_random_csv-inside-above-samples", _random_cell(1, "inside", "1001"), F,
     ["row 1", "sample counts"]),
    ("saved_random_csv-probability-above-one", _random_cell(2, "fosm_two_sided", "1.5"), F,
     ["row 2", "'fosm_two_sided'"]),
    ("saved_random_csv-negative-count", _random_cell(6, "outside", "-1"), F, ["row 6", "'outside'"]),
    ("sample_at_poses-correlated-machine",
     lambda tmp: reliability.sample_at_poses(MILL.with_correlation({("X.ey", "X.dz"): 0.5}),
                                             TM, QM, samples=10),
     InputError, ["sample_at_poses", "correlated"]),
    ("failure_probability-correlated-machine",
     lambda tmp: reliability.sampling.rare_events.failure_probability(
         MILL.with_correlation({("X.ey", "X.dz"): 0.5}), TM, QM[0]),
     InputError, ["failure_probability", "correlated"]),
    ("saved_random_csv-mixed-k", _random_cell(3, "k", "2"), F, ["row 3", "'k'"]),
    ("saved_random_csv-truncated", _random_file(lambda ls: ls.__setitem__(-1, ls[-1][:8])), F,
     ["random.csv", "row 6"]),
]


def test_catalogue_is_large_and_ids_unique():
    ids = [case[0] for case in CATALOGUE]
    assert len(set(ids)) == len(ids)
    assert len(ids) >= 80


@pytest.mark.parametrize("call, exception, fragments",
                         [case[1:] for case in CATALOGUE], ids=[case[0] for case in CATALOGUE])
def test_bad_input_is_refused_with_its_cause_named(call, exception, fragments, tmp_path):
    with pytest.raises(exception) as caught:
        call(tmp_path)
    message = str(caught.value)
    for fragment in fragments:
        assert fragment in message, f"{fragment!r} not in {message!r}"


# ----- the command line: exit 2 with one line naming the cause, before any work --------
MILL_FILE = str(Path(__file__).parent / "machines" / "mill3.toml")


def _file(name, content):
    """A file written into the test's folder; returns its path as text."""
    def make(tmp):
        path = tmp / name
        path.write_bytes(content if isinstance(content, bytes) else content.encode())
        return str(path)
    return make


def _tolerances(rows):
    return _file("t.csv", "error,allocated\n" + "".join(f"{n},{v}\n" for n, v in rows))


def _all_mill(**changes):
    values = dict(zip(MILL.error_names, TM))
    values.update(changes)
    return _tolerances(values.items())


CLI_CATALOGUE = [
    ("precrel-check-missing-file", lambda tmp: ["check", str(tmp / "nope.toml")],
     ["nope.toml"]),
    ("precrel-check-binary-file",
     lambda tmp: ["check", _file("m.toml", b"\x89PNG\r\n\x00\xff")(tmp)],
     ["m.toml", "not a text file"]),
    ("precrel-check-bad-toml", lambda tmp: ["check", _file("m.toml", "name = ")(tmp)],
     ["m.toml", "not valid TOML"]),
    ("precrel-predict-points-one", lambda tmp: ["predict", MILL_FILE, "--points", "1"],
     ["--points"]),
    ("precrel-predict-side-unknown", lambda tmp: ["predict", MILL_FILE, "--side", "left"],
     ["--side", "left"]),
    ("precrel-predict-tolerances-unknown-name",
     lambda tmp: ["predict", MILL_FILE, "--tolerances", _all_mill(**{"Q.dx": 0.002})(tmp)],
     ["Q.dx"]),
    ("precrel-predict-tolerances-missing-name",
     lambda tmp: ["predict", MILL_FILE, "--tolerances",
                  _tolerances(list(zip(MILL.error_names, TM))[:-1])(tmp)],
     [MILL.error_names[-1]]),
    ("precrel-predict-tolerances-negative",
     lambda tmp: ["predict", MILL_FILE, "--tolerances", _all_mill(**{"X.dx": -0.002})(tmp)],
     ["X.dx"]),
    ("precrel-predict-tolerances-no-allocated-column",
     lambda tmp: ["predict", MILL_FILE, "--tolerances", _file("t.csv", "error,t\nX.dx,1\n")(tmp)],
     ["allocated"]),
    ("precrel-allocate-out-exists",
     lambda tmp: ["allocate", MILL_FILE, "--out", _file("a.csv", "keep me")(tmp)],
     ["a.csv", "--overwrite"]),
    ("precrel-allocate-out-is-a-folder",
     lambda tmp: ["allocate", MILL_FILE, "--out", str(tmp), "--overwrite"], ["--out"]),
    ("precrel-allocate-bounds-reversed",
     lambda tmp: ["allocate", MILL_FILE, "--out", str(tmp / "a.csv"), "--bounds", "2", "1"],
     ["--bounds"]),
    ("precrel-allocate-target-one",
     lambda tmp: ["allocate", MILL_FILE, "--out", str(tmp / "a.csv"), "--target", "1"],
     ["--target"]),
    ("precrel-allocate-lock-unknown",
     lambda tmp: ["allocate", MILL_FILE, "--out", str(tmp / "a.csv"), "--lock", "Q.dx"],
     ["Q.dx"]),
    ("precrel-allocate-method-unknown",
     lambda tmp: ["allocate", MILL_FILE, "--out", str(tmp / "a.csv"), "--method", "magic"],
     ["--method", "magic"]),
    ("precrel-verify-repeats-zero",
     lambda tmp: ["verify", MILL_FILE, "--tolerances", "x.csv", "--repeats", "0"],
     ["--repeats"]),
    ("precrel-verify-seed-negative",
     lambda tmp: ["verify", MILL_FILE, "--tolerances", "x.csv", "--seed", "-1"], ["--seed"]),
    ("precrel-verify-samples-text",
     lambda tmp: ["verify", MILL_FILE, "--tolerances", "x.csv", "--samples", "many"],
     ["--samples", "many"]),
    ("precrel-verify-precision-one",
     lambda tmp: ["verify", MILL_FILE, "--tolerances", "x.csv", "--precision", "1"],
     ["--precision"]),
    ("precrel-report-out-is-a-file",
     lambda tmp: ["report", MILL_FILE, "--out", _file("r", "a file")(tmp)], ["r"]),
    ("precrel-report-skip-unknown",
     lambda tmp: ["report", MILL_FILE, "--out", str(tmp / "r"), "--skip", "tea"], ["tea"]),
    ("precrel-front-target-above-one",
     lambda tmp: ["front", MILL_FILE, "--targets", "0.9", "1.5"], ["--targets"]),
    ("precrel-front-target-probability-above-one",
     lambda tmp: ["front", MILL_FILE, "--target", "0.9", "1.5"], ["--target", "'1.5'"]),
    ("precrel-front-count-not-an-integer",
     lambda tmp: ["front", MILL_FILE, "--count", "0.9"], ["--count", "'0.9'"]),
    ("precrel-sweep-missing-spec",
     lambda tmp: ["sweep", str(tmp / "spec.toml"), "--out", str(tmp / "s")], ["spec.toml"]),
    ("precrel-sweep-workers-zero",
     lambda tmp: ["sweep", _file("spec.toml", 'machines = ["hobbing"]\n')(tmp), "--out",
                  str(tmp / "s"), "--workers", "0"], ["--workers"]),
    ("precrel-unknown-command", lambda tmp: ["plot", MILL_FILE], ["plot"]),
]


@pytest.mark.parametrize("argv", [case[1] for case in CLI_CATALOGUE],
                         ids=[case[0] for case in CLI_CATALOGUE])
def test_command_line_refuses_with_one_line(argv, tmp_path, capsys):
    from studies import cli

    fragments = dict((case[0], case[2]) for case in CLI_CATALOGUE)
    case = next(c for c in CLI_CATALOGUE if c[1] is argv)
    code = cli.main(argv(tmp_path))
    captured = capsys.readouterr()
    assert code == 2 and captured.out == ""
    last = captured.err.strip().splitlines()[-1]
    assert last.startswith("precrel"), captured.err
    for fragment in fragments[case[0]]:
        assert fragment in last, f"{fragment!r} not in {last!r}"


def catalogue_size_by_entry_point() -> Counter:
    """Rows per entry point (the id up to the first '-'), library and command line."""
    return Counter(case[0].split("-")[0] for case in CATALOGUE + CLI_CATALOGUE)


if __name__ == "__main__":
    sizes = catalogue_size_by_entry_point()
    for entry, count in sorted(sizes.items()):
        print(f"{entry:24s} {count:4d}")
    print(f"{'total':24s} {sum(sizes.values()):4d}")


# ----- labelled inputs are aligned by name, never used by position ----------------------
def test_series_in_another_order_gives_the_same_reliability_as_the_array():
    grid = workspace_grid(HOB, 3)
    tolerances = SERIES * np.linspace(0.5, 1.5, HOB.n_errors)  # items differ from each other
    shuffled = _shuffled(tolerances)
    by_name = fosm(HOB, shuffled, grid)
    by_array = fosm(HOB, tolerances.to_numpy(), grid)
    np.testing.assert_array_equal(by_name.two_sided, by_array.two_sided)
    by_position = fosm(HOB, shuffled.to_numpy(), grid)  # what a positional reading gives
    assert not np.allclose(by_position.worst(), by_array.worst())


def test_mapping_and_frame_inputs_are_aligned_by_name():
    q = pd.DataFrame(Q0, columns=HOB.axes)[list(reversed(HOB.axes))]
    np.testing.assert_array_equal(HOB.check_positions(q), Q0)
    assert np.array_equal(HOB.check_tolerances(dict(_shuffled(SERIES).items())), T0)
    errors = pd.Series(np.arange(HOB.n_errors) * 1e-6, index=NAMES)
    np.testing.assert_array_equal(HOB.check_errors(_shuffled(errors)), errors.to_numpy())


# ----- inputs accepted on purpose (docs/inputs.md) ------------------------------------------
def test_full_turn_axes_accept_any_angle():
    outside_one_turn = Q0 + [10.0, 0, 0, 0, 0, -7.0]  # C and M are full-turn axes
    fosm(HOB, T0, outside_one_turn)


def test_outside_stroke_on_request():
    beyond = Q0 + [0, 500.0, 0, 0, 0, 0]
    result = fosm(HOB, T0, beyond, allow_outside_stroke=True)
    assert np.all(np.isfinite(result.sigma))


def test_stroke_ends_are_inside():
    ends = np.array([[0.0, 0.0, 100.0, -np.pi / 4, 0.0, 0.0],
                     [0.0, 400.0, 500.0, np.pi / 4, 200.0, 0.0]])
    fosm(HOB, T0, ends)


@pytest.mark.parametrize("seed", [None, 0, np.int64(7), np.random.SeedSequence(3),
                                  np.random.default_rng(4)])
def test_seed_forms_accepted(seed):
    assert random_poses(MILL, 2, rng=seed).shape == (2, 3)


def test_rotary_stroke_of_exactly_one_turn_is_accepted():
    data = _dict()
    _axis(data, "A")["stroke"] = [-np.pi, np.pi]
    machine_from_dict(data)


# ----- child generators are spawned per batch ------------------------------------------------
def test_run_spawns_children_per_batch_not_all_up_front():
    seeds = np.random.SeedSequence(11)

    class Stop(Exception):
        pass

    def stop(done, total):
        raise Stop

    with pytest.raises(Stop):
        GridExperiment(MILL, 3).run(TM, repeats=10**7, batch=4, rng=seeds,
                                    keep_values="none", progress=stop)
    assert seeds.n_children_spawned == 4


def test_per_batch_spawning_gives_the_streams_of_one_spawn():
    experiment = GridExperiment(MILL, 3)
    children = np.random.default_rng(5).spawn(7)  # every repeat's stream, spawned at once
    draws = [experiment._draw(TM, child, 3.0, "truncated") for child in children]
    values = experiment.evaluate(np.stack([d[0] for d in draws]), np.stack([d[1] for d in draws]))
    expected = np.sum(np.abs(values) < MILL.limits, axis=1)
    for batch in (1, 3, 7, 50):
        result = experiment.run(TM, repeats=7, batch=batch, rng=5)
        np.testing.assert_array_equal(result.inside, expected)


# ----- same seed, same bytes -------------------------------------------------------------------
SAVE_SCRIPT = """
import sys
import reliability
from reliability import GridExperiment
machine = reliability.load_machine(sys.argv[1])
result = GridExperiment(machine, 3).run(machine.initial_allocation * 3, repeats=9,
                                        batch=int(sys.argv[3]), rng=2024)
result.save(sys.argv[2])
"""


def test_same_seed_same_bytes_across_batches_and_processes(tmp_path):
    machine_file = Path(__file__).parent / "machines" / "mill3.toml"
    result = GridExperiment(MILL, 3).run(TM * 3, repeats=9, batch=9, rng=2024)
    assert 0 < result.inside.min() < result.n_poses  # counts that a change would move
    here = result.save(tmp_path / "here.csv").read_bytes()
    for batch in (1, 4):
        out = tmp_path / f"process-{batch}.csv"
        subprocess.run([sys.executable, "-c", SAVE_SCRIPT, str(machine_file), str(out),
                        str(batch)], check=True, cwd=ROOT)
        assert out.read_bytes() == here


def test_random_pose_results_round_trip_exactly(tmp_path):
    result = sample_random_poses(MILL, TM, 500, rng=1, chunk=200)
    path = result.save(tmp_path / "random.csv")
    back = RandomPoseResult.load(path)
    np.testing.assert_array_equal(back.inside, result.inside)
    np.testing.assert_array_equal(back.fosm_two_sided, result.fosm_two_sided)
    assert back.n_samples == 500 and back.save(tmp_path / "again.csv").read_bytes() == \
        path.read_bytes()


# ----- saves are atomic ----------------------------------------------------------------------
def test_interrupted_save_keeps_the_old_file_and_leaves_no_temporary(tmp_path, monkeypatch):
    path = _grid_result().save(tmp_path / "table9.csv")
    before = path.read_bytes()

    def broken_replace(source, target):
        raise KeyboardInterrupt

    monkeypatch.setattr("reliability.basics.files.os.replace", broken_replace)
    other = GridExperimentResult(limits=HOB.limits, inside=np.full((1, 6), 3), n_poses=125)
    with pytest.raises(KeyboardInterrupt):
        other.save(path, overwrite=True)
    assert path.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["table9.csv"]


RANDOM_SCRIPT = """
import sys
import reliability
machine = reliability.load_machine(sys.argv[1])
reliability.sample_random_poses(machine, machine.initial_allocation * 3, 700, rng=99,
                                chunk=300).save(sys.argv[2])
"""


def test_random_pose_results_same_bytes_across_processes(tmp_path):
    machine_file = Path(__file__).parent / "machines" / "mill3.toml"
    here = sample_random_poses(MILL, TM * 3, 700, rng=99, chunk=300)
    assert 0 < here.inside.min() < 700
    expected = here.save(tmp_path / "here.csv").read_bytes()
    out = tmp_path / "process.csv"
    subprocess.run([sys.executable, "-c", RANDOM_SCRIPT, str(machine_file), str(out)],
                   check=True, cwd=ROOT)
    assert out.read_bytes() == expected
