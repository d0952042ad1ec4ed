"""Simulated measurements of a plan: one machine drawn, its readings on the exact chain.

The machine's errors are drawn under the study's profile along travel and reading of a
tolerance (σ = t/3, normal or truncated at ±t), at every position of every axis the plan
visits; every run gets its own set-up (an instrument zero per quantity, a ballbar centre
off its nominal place); each reading is the exact workpiece-frame deviation (or the
ballbar's length change) plus its zero and noise of standard deviation ``u``. A positioning
run's readings also carry its axis' reversal and repeatability, as the acceptance prediction
draws them (:mod:`reliability.acceptance.prediction`): ``+B/2`` approaching in the ``+``
direction, ``−B/2`` in the ``−`` direction, and a fresh ``σ_R`` normal per approach, along
the axis' travel (drawn last, so plans without positioning runs read as before).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import pandas as pd

from ..acceptance.iso_tests import tool_point
from ..basics import streams
from ..model.kinematics import comprehensive_error
from ..model.profiles import axis_profiles, to_marginal
from .measurement_files import QUANTITIES, Measurements
from .plans import planned_readings

#: Set-ups are drawn with this many times each reading's ``u`` as standard deviation.
SETUP_SPREAD = 10.0


@dataclass(frozen=True, eq=False)
class SimulatedMachine:
    """A drawn machine's readings and the truth behind them.

    Attributes
    ----------
    measurements : Measurements
    truth : DataFrame
        ``item, position, value``: each error (with the axis position, in the file's unit,
        of a motion error that varies along travel), then each run's set-up.
    errors : ndarray (N, n_errors)
        The errors in force at each reading.
    """

    measurements: Measurements
    truth: pd.DataFrame
    errors: np.ndarray


def simulate_measurements(machine, plan, tolerances=None, *, profile="constant",
                          rng=None) -> SimulatedMachine:
    """Draw one machine and what the plan's runs would read on it.

    Parameters
    ----------
    machine : Machine
    plan : tuple of PlannedRun
        From :func:`reliability.measured.plans.read_plan`.
    tolerances : array_like, optional
        Allocation the machine is built to; the initial allocation by default.
    profile : str or profile model
        Motion errors along travel (docs/profiles.md).
    rng : None, int or numpy.random.Generator
    """
    rng = streams.generator(rng)
    t = machine.initial_allocation if tolerances is None else machine.check_tolerances(tolerances)
    layout = planned_readings(plan)
    errors, truth = _draw_errors(machine, layout.poses, t, profile, rng)
    exact = comprehensive_error(machine, layout.poses, errors, frame="workpiece")
    value = _exact_readings(machine, layout, exact)
    setup, setup_truth = _draw_setups(machine, layout, rng)
    value = value + setup + layout.u * rng.standard_normal(len(value))
    value = value + _approach_effects(plan, layout, rng)
    measurements = replace(layout, value=value)
    return SimulatedMachine(measurements, pd.concat([truth, setup_truth], ignore_index=True),
                            errors)


def _approach_effects(plan, layout, rng) -> np.ndarray:
    """``(N,)`` each positioning run's reversal (±B/2 by direction) and repeatability (σ_R
    per approach) along its axis' travel; zero on other readings."""
    effect = np.zeros(len(layout.u))
    for run in plan:
        if run.approach is None:
            continue
        chosen = np.flatnonzero(layout.run == run.name)   # run names are unique in a plan
        sigma, reversal, sign = run.approach
        half = np.where(layout.direction[chosen] == "+", 0.5, -0.5) * reversal
        effect[chosen] = sign * (half + sigma * rng.standard_normal(len(chosen)))
    return effect


def _draw_errors(machine, poses, tolerances, profile, rng) -> tuple[np.ndarray, pd.DataFrame]:
    n_axes = len(machine.axis_specs)
    errors = np.empty((len(poses), machine.n_errors))
    rows = []
    for a, (model, axis) in enumerate(zip(axis_profiles(machine, profile), machine.axis_specs)):
        points, where = np.unique(poses[:, a], return_inverse=True)
        z = model.factor(axis, points) @ rng.standard_normal((len(points), 6))
        block = slice(6 * a, 6 * a + 6)
        values = to_marginal(z, tolerances[block], 3.0, machine.distribution)
        errors[:, block] = values[where]
        varies = not np.allclose(values, values[:1])
        shown = np.degrees(points) if axis.kind == "rotary" else points
        for c, name in enumerate(machine.error_names[block]):
            if varies:
                rows += [(name, p, v) for p, v in zip(shown, values[:, c])]
            else:
                rows.append((name, np.nan, values[0, c]))
    assembly = slice(6 * n_axes, machine.n_errors)
    drawn = to_marginal(rng.standard_normal(machine.n_errors - 6 * n_axes),
                        tolerances[assembly], 3.0, machine.distribution)
    errors[:, assembly] = drawn
    rows += [(name, np.nan, v) for name, v in zip(machine.error_names[assembly], drawn)]
    return errors, pd.DataFrame(rows, columns=["item", "position", "value"])


def _exact_readings(machine, layout, exact) -> np.ndarray:
    quantity = layout.quantity
    radial = quantity == "radial"
    index = np.array([QUANTITIES.index(q) if q != "radial" else 0 for q in quantity])
    value = exact[np.arange(len(index)), index]
    if radial.any():
        nominal = tool_point(machine, layout.poses[radial])
        arm = nominal - layout.centre[radial]
        moved = arm + exact[radial, :3]
        value[radial] = np.linalg.norm(moved, axis=1) - np.linalg.norm(arm, axis=1)
    return value


def _draw_setups(machine, layout, rng) -> tuple[np.ndarray, pd.DataFrame]:
    """Each run's zeros (and ballbar centre offsets) and their effect on every reading."""
    effect = np.zeros(len(layout.u))
    rows = []
    keys = pd.DataFrame({"run": layout.run, "quantity": layout.quantity})
    for (run, quantity), group in keys.groupby(["run", "quantity"], sort=False):
        chosen = group.index.to_numpy()
        spread = SETUP_SPREAD * layout.u[chosen[0]]
        if quantity != "radial":
            zero = spread * rng.standard_normal()
            effect[chosen] = zero
            rows.append((f"{run}:{quantity}", np.nan, zero))
            continue
        offset = spread * rng.standard_normal(3)
        arm = tool_point(machine, layout.poses[chosen]) - layout.centre[chosen]
        length = np.linalg.norm(arm, axis=1)
        effect[chosen] = np.linalg.norm(arm - offset, axis=1) - length
        rows += [(f"{run}:centre_{axis}", np.nan, v) for axis, v in zip("xyz", offset)]
    return effect, pd.DataFrame(rows, columns=["item", "position", "value"])
