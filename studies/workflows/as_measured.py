"""This machine's reliability, as measured: its posterior pushed through the exact chain.

Given an :class:`~reliability.measured.identification.Identification` of a built machine,
machines are drawn from its posterior (:meth:`Identification.sample_at`, each error's value
as it acts at each pose) and evaluated

- on the exact chain (:meth:`GridExperiment.evaluate`) at every pose of the ``points``-point
  grid, and by :meth:`Machine.comprehensive_error` at any further poses (the certified worst
  poses of a verification): the probability that this machine holds every limit at every
  one of those poses, per output and all at once, and each output's worst pose for it;
- through the acceptance tests' own model (the first-order tool-point deviation in the
  workpiece frame, :func:`reliability.acceptance.prediction.results_of_deviations`): each
  test's predicted result for this machine.

Beside them stand the design-time numbers of the allocation in force (``t = 3 ×
coefficients.prior_sd``, the prior σ of every error at any position): FOSM at each output's worst pose of the same poses, the machine yield when the
caller has it, and the acceptance tests on machines built to that allocation.

A motion error of axis ``a`` depends on ``q_a`` only (a profile along travel), so the draws
at the grid are taken at ``P`` poses, the ``k``-th holding every axis at its ``k``-th grid
point, and laid out per axis as the grid experiment reads them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy.special import ndtr

from reliability.acceptance.acceptance_result import AcceptanceResult
from reliability.acceptance.iso_tests import build_path, deviation_weights
from reliability.acceptance.prediction import acceptance, results_of_deviations
from reliability.basics import checks, streams
from reliability.basics.chunks import chunks
from reliability.basics.display import (UNIT_SCALES, axis_units, output_people_units,
                                        percent_number, pose_text, resolved_text,
                                        unit_symbol)
from reliability.basics.pass_rule import passes
from reliability.basics.statistics import binomial_interval
from reliability.first_order.fosm import fosm
from reliability.model.machine import OUTPUTS
from reliability.sampling.grid_experiment import GridExperiment

#: Index of the as-measured stream among a seed's extra streams
#: (:func:`reliability.basics.streams.extra_stream`).
AS_MEASURED_STREAM = 6
#: Posterior machines drawn when not told otherwise.
DEFAULT_DRAWS = 2000
CONFIDENCE = 0.95


@dataclass(frozen=True, eq=False)
class AsMeasured:
    """This machine's reliability given what was measured, beside the design's.

    Attributes
    ----------
    machine : Machine
    tolerances : ndarray (n_errors,)
        The allocation in force: three times the identification's prior σ.
    draws : int
        Machines drawn from the posterior.
    workspace : str
        The poses judged, in words.
    holds : dict
        ``estimate, lower, upper``: the share of posterior machines within every limit at
        every pose (Clopper–Pearson interval at :data:`CONFIDENCE`).
    outputs : DataFrame
        Per output: ``limit``, this machine's ``holds`` share over all poses with
        ``holds_lower, holds_upper``; its worst pose (``worst_pose`` positions), the
        posterior ``mean`` and ``sd`` there and the share ``inside`` there; the design's
        FOSM worst pose (``design_pose``) and two-sided probability there.
    design_yield : YieldEstimate or None
        The design-time machine yield of the allocation, when the caller had it.
    acceptance : DataFrame or None
        Per test and quantity: ``limit``, this machine's ``mean, q05, q95`` and
        ``pass_probability, pass_low, pass_high``, and the design's ``design_pass,
        design_low, design_high``.
    """

    machine: object
    tolerances: np.ndarray
    draws: int
    workspace: str
    holds: dict
    outputs: pd.DataFrame
    design_yield: object = None
    acceptance: pd.DataFrame | None = None

    def summary(self) -> str:
        """What ``verify --identification`` prints."""
        lines = [f"This machine as measured: {self.draws} machines drawn from the posterior, "
                 f"exact chain at the {self.workspace}; outputs in the {self.machine.frame} "
                 f"frame.",
                 f"probability that it holds every limit at every pose: "
                 f"{holds_text(self.holds)}"]
        if self.design_yield is not None:
            lines.append(f"design-time machine yield of the allocation:     "
                         f"{holds_text(self.design_yield.to_dict())}")
        lines += ["", output_table(self).to_string(index=False)]
        if self.acceptance is not None:
            lines += ["", "acceptance tests, this machine beside machines built to the "
                          "allocation (pass probability, Wilson 95 %):",
                      acceptance_table(self.acceptance).to_string(index=False)]
        return "\n".join(lines)

    def summary_dict(self) -> dict:
        """The ``as_measured`` entry of ``summary.json``."""
        out = {"draws": self.draws, "workspace": self.workspace, "holds": self.holds,
               "outputs": {row.Index: {"holds": row.holds, "inside_at_worst": row.inside,
                                       "design_at_worst": row.design_two_sided}
                           for row in self.outputs.itertuples()}}
        if self.acceptance is not None:
            out["acceptance_pass"] = {f"{r.test}.{r.quantity}": r.pass_probability
                                      for r in self.acceptance.itertuples()
                                      if np.isfinite(r.limit)}
        return out


def as_measured(machine, identification, *, points: int = 5, poses=None,
                draws: int = DEFAULT_DRAWS, tests=None, design_yield=None,
                memory: int | None = None, rng=None) -> AsMeasured:
    """This machine's reliability from its identification, beside the design's.

    Parameters
    ----------
    machine : Machine
    identification : Identification
        Of this machine (:func:`reliability.identify` or
        :func:`reliability.read_identification`).
    points : int
        Grid points per axis.
    poses : array_like, optional
        ``(k, n_axes)`` further poses judged with the grid (e.g. certified worst poses).
    draws : int
        Machines drawn from the posterior.
    tests : sequence of acceptance tests, optional
    design_yield : YieldEstimate, optional
        The machine yield of the allocation in force, shown beside.
    memory : int, optional
        Bytes of temporary arrays per chunk of drawn machines.
    rng : None, int or Generator

    Returns
    -------
    AsMeasured
    """
    draws = checks.positive_int(draws, "draws")
    workspace_rng, tests_rng, design_rng = streams.spawn(rng, 3)
    tolerances = machine.check_tolerances(3.0 * identification.coefficients.prior_sd)
    experiment = GridExperiment(machine, points)
    extra = np.zeros((0, len(machine.axes))) if poses is None else \
        machine.check_positions(np.atleast_2d(poses))
    judged = _judge(machine, identification, experiment, extra, draws, memory, workspace_rng)
    all_poses = np.concatenate([experiment.poses, extra])
    outputs = _output_table(machine, tolerances, all_poses, judged, draws)
    workspace = f"{experiment.n_poses} poses of the {points}-point grid" + (
        f" and {len(extra)} further poses" if len(extra) else "")
    low, high = binomial_interval(judged["holds_all"], draws, CONFIDENCE,
                                  method="clopper-pearson")
    return AsMeasured(
        machine=machine, tolerances=tolerances, draws=draws, workspace=workspace,
        holds={"estimate": judged["holds_all"] / draws, "lower": float(low),
               "upper": float(high)},
        outputs=outputs, design_yield=design_yield,
        acceptance=None if tests is None else _acceptance_table(
            machine, identification, tuple(tests), tolerances, draws, tests_rng, design_rng))


def _diagonal_poses(experiment) -> np.ndarray:
    """``(P, n_axes)``: the ``k``-th pose holds every axis at its ``k``-th grid point."""
    return np.stack(experiment.axis_points, axis=-1)


def _judge(machine, identification, experiment, extra, draws, memory, rng) -> dict:
    """Counts over posterior machines: holding all limits everywhere, per output, and per
    pose and output; the outputs' sums and sums of squares per pose."""
    n_axes, n_poses = len(machine.axes), experiment.n_poses + len(extra)
    sampled = np.concatenate([_diagonal_poses(experiment), extra])
    count = len(experiment.axis_points[0])
    out = {"holds_all": 0, "holds": np.zeros(6, dtype=np.int64),
           "inside": np.zeros((n_poses, 6), dtype=np.int64),
           "sum": np.zeros((n_poses, 6)), "squares": np.zeros((n_poses, 6))}
    for part in chunks(draws, 96 * n_poses, memory):
        x = identification.sample_at(sampled, part.stop - part.start, rng)
        motion = np.stack([x[:, :count, 6 * a:6 * a + 6] for a in range(n_axes)], axis=1)
        assembly = x[:, 0, 6 * n_axes:].reshape(len(x), n_axes - 1, 6)
        y = experiment.evaluate(motion, assembly)
        if len(extra):
            y = np.concatenate([y, machine.comprehensive_error(extra, x[:, count:, :])], axis=1)
        inside = passes(y, machine.limits)
        out["holds_all"] += int(np.count_nonzero(inside.all(axis=(1, 2))))
        out["holds"] += inside.all(axis=1).sum(axis=0)
        out["inside"] += inside.sum(axis=0)
        out["sum"] += y.sum(axis=0)
        out["squares"] += np.square(y).sum(axis=0)
    return out


def _output_table(machine, tolerances, poses, judged, draws) -> pd.DataFrame:
    """Per output: this machine's share within the limit everywhere, its worst pose (the
    largest normal failure probability from the draws' mean and σ), and the design's FOSM
    worst pose of the same poses."""
    mean = judged["sum"] / draws
    sd = np.sqrt(np.maximum(judged["squares"] / draws - mean ** 2, 0.0))
    spread = np.maximum(sd, np.finfo(float).tiny)
    failure = ndtr((-machine.limits - mean) / spread) + ndtr((mean - machine.limits) / spread)
    worst = np.argmax(failure, axis=0)
    design = fosm(machine, tolerances, poses, distribution=machine.distribution).to_frame()
    rows = np.arange(6)
    low, high = binomial_interval(judged["holds"], draws, CONFIDENCE, method="clopper-pearson")
    inside = judged["inside"][worst, rows]
    in_low, in_high = binomial_interval(inside, draws, CONFIDENCE, method="clopper-pearson")
    return pd.DataFrame({
        "limit": machine.limits, "holds": judged["holds"] / draws, "holds_lower": low,
        "holds_upper": high, "worst_pose": list(poses[worst]), "mean": mean[worst, rows],
        "sd": sd[worst, rows], "inside": inside / draws, "inside_lower": in_low,
        "inside_upper": in_high,
        "design_pose": list(poses[design["worst_pose"].to_numpy()]),
        "design_two_sided": design["worst_two_sided"].to_numpy()},
        index=pd.Index(OUTPUTS, name="output"))


def _acceptance_table(machine, identification, tests, tolerances, draws, rng,
                      design_rng) -> pd.DataFrame:
    """Each test's predicted result for this machine beside machines built to the
    allocation (the identification's profile, the machine's reading of a tolerance)."""
    poses = np.concatenate([build_path(machine, test).poses for test in tests])
    weights = deviation_weights(machine, poses)
    values = []
    for part in chunks(draws, 8 * len(poses) * (3 + machine.n_errors)):
        x = identification.sample_at(poses, part.stop - part.start, rng)
        values.append(results_of_deviations(machine, tests, np.einsum("poi,mpi->mpo",
                                                                      weights, x), rng))
    values = pd.concat(values, ignore_index=True)
    q05 = values.quantile(0.05).to_numpy()
    measured = AcceptanceResult(tests=tests, values=values,
                                drivers=pd.DataFrame(columns=["test", "quantity", "item",
                                                              "share"]),
                                profile=identification.profile, distribution="normal",
                                confidence=CONFIDENCE).to_frame()
    design = acceptance(machine, tests, tolerances, machines=draws,
                        profile=identification.profile, distribution=machine.distribution,
                        confidence=CONFIDENCE, driver_machines=1, rng=design_rng).to_frame()
    measured = measured[measured["test"] != "all"].reset_index(drop=True)
    design = design[design["test"] != "all"].reset_index(drop=True)
    return pd.DataFrame({
        "test": measured["test"], "quantity": measured["quantity"],
        "limit": measured["limit"], "mean": measured["mean"], "q05": q05,
        "q95": measured["q95"], "pass_probability": measured["pass_probability"],
        "pass_low": measured["pass_low"], "pass_high": measured["pass_high"],
        "design_pass": design["pass_probability"], "design_low": design["pass_low"],
        "design_high": design["pass_high"]})


def holds_text(holds: dict) -> str:
    """``99.10 % [98.60, 99.50]``: an estimate with its interval, in per cent to 0.01 %,
    the interval's ends rounded outward."""
    return (f"{percent_number(holds['estimate'])} % "
            f"{_ends_text(holds['lower'], holds['upper'])}")


def output_table(result) -> pd.DataFrame:
    """The per-output table as printed: this machine beside the design, in the machine
    file's units (mm and rad when it states none)."""
    rows = []
    units = output_people_units(result.machine.cost_coefficients.units)
    for (output, row), unit in zip(result.outputs.iterrows(), units):
        scale, unit = UNIT_SCALES[unit], unit_symbol(unit)
        rows.append({
            "output": output, "limit": f"{scale * row['limit']:.4g} {unit}",
            "holds everywhere %": _interval_text(row["holds"], row["holds_lower"],
                                                 row["holds_upper"]),
            "its worst pose": _pose(result.machine, row["worst_pose"]),
            "mean ± sd there": f"{resolved_text(scale * row['mean'], scale * row['sd'], 3)} "
                               f"± {scale * row['sd']:.3g} {unit}",
            "inside there %": _interval_text(row["inside"], row["inside_lower"],
                                             row["inside_upper"]),
            "design worst pose": _pose(result.machine, row["design_pose"]),
            "design FOSM %": f"{100 * row['design_two_sided']:.3f}"})
    return pd.DataFrame(rows)


def acceptance_table(table) -> pd.DataFrame:
    """The acceptance comparison as printed (µm)."""
    return pd.DataFrame({
        "test": table["test"], "quantity": table["quantity"],
        "limit µm": [f"{1e3 * v:.3g}" if np.isfinite(v) else "-" for v in table["limit"]],
        "this machine µm (q05–q95)": [f"{1e3 * m:.3g} ({1e3 * lo:.3g}–{1e3 * hi:.3g})"
                                      for m, lo, hi in zip(table["mean"], table["q05"],
                                                           table["q95"])],
        "this machine passes": [_pass_text(p, lo, hi) for p, lo, hi in
                                zip(table["pass_probability"], table["pass_low"],
                                    table["pass_high"])],
        "built machines pass": [_pass_text(p, lo, hi) for p, lo, hi in
                                zip(table["design_pass"], table["design_low"],
                                    table["design_high"])]})


def _interval_text(value, low, high) -> str:
    return f"{percent_number(value)} {_ends_text(low, high)}"


def _ends_text(low, high) -> str:
    return f"[{percent_number(low, bound='lower')}, {percent_number(high, bound='upper')}]"


def _pass_text(value, low, high) -> str:
    return "-" if not np.isfinite(value) else f"{value:.3f} [{low:.3f}, {high:.3f}]"


def _pose(machine, pose) -> str:
    return pose_text(np.asarray(pose, dtype=float), machine.axes, axis_units(machine))
