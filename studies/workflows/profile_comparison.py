"""Error profiles along travel compared: the machine-level yield and the spread between
experiments, for any machine, allocations and profiles.

:func:`profile_comparison` runs the grid experiment (Sec. 5.3) of each allocation under each
profile (:func:`reliability.model.profiles.profile_model`: ``independent``, ``gp:<length>``,
``constant``); :func:`systematic_effect` shows how a measured (systematic) error profile uses
up the reliability budget. The report section is :mod:`studies.report.profiles_section`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from reliability.basics.renamed import renamed
from reliability.basics.streams import integer_seed, profiles_stream
from reliability.first_order.fosm import fosm
from reliability.model.machine import OUTPUTS
from reliability.model.poses import workspace_grid
from reliability.model.profiles import profile_model
from reliability.sampling.grid_experiment import GridExperiment

#: Profiles compared by default, from independent to constant (lengths in mm).
PROFILES = ("independent", "gp:30", "gp:100", "gp:300", "gp:1000", "gp:3000", "constant")
#: Table 9's spread is shown for these outputs.
SPREAD_OUTPUTS = ("dx", "ex", "ey")


@dataclass
class ProfilesStudy:
    """Tables the profile study is made of (see :func:`run_profiles_study`)."""

    comparison: pd.DataFrame
    paper_check: pd.DataFrame | None = None
    systematic: pd.DataFrame | None = None
    timings: dict = field(default_factory=dict)
    study_profile: str | None = None  # a report's profile, whose rows hold its machine yield


def profile_length(spec) -> float:
    """Correlation length of a profile for plotting: 0 independent, ∞ constant, else ℓ."""
    model = profile_model(spec)
    if str(model) == "independent":
        return 0.0
    if str(model) == "constant":
        return np.inf
    return model.length


@renamed("points_per_axis", "points")
@renamed("seed", "rng")
def profile_comparison(machine, allocations: dict, profiles=PROFILES, repeats=(20, 2000),
                       rng: int | None = 2023, keep=None, log=lambda message: None, *,
                       points: int = 5, distribution: str = "truncated") -> pd.DataFrame:
    """Yield, Table 9's spread and mean fractions for every allocation, profile and count.

    Parameters
    ----------
    machine : Machine
    allocations : dict[str, array_like]
        Label → tolerances.
    profiles : sequence
        Profile specifications (:func:`reliability.model.profiles.profile_model`).
    repeats : sequence of int
        Numbers of experiments; each count is its own run from the same seed.
    rng : int or None
        Every run draws from a fresh :func:`reliability.basics.streams.profiles_stream` of
        this integer seed (common random numbers across allocations, profiles and counts);
        None draws a fresh seed. A Generator is refused (InputTypeError naming ``rng``):
        the named stream derives from an integer seed. ``seed=`` is the deprecated
        spelling (:mod:`reliability.basics.renamed`).
    keep : dict, optional
        Filled with ``(label, profile, repeats) → GridExperimentResult``.
    log : callable
    points : int
        Grid points per axis (``points_per_axis=`` is the deprecated spelling).
    distribution : {'truncated', 'normal'}
        The reading of a tolerance the experiments draw under.

    Returns
    -------
    pandas.DataFrame
        One row per (allocation, profile, repeats).
    """
    seed = integer_seed(rng)
    rows = []
    for spec in profiles:
        experiment = GridExperiment(machine, points, profile=spec)
        for label, t in allocations.items():
            for count in repeats:
                start = time.perf_counter()
                result = experiment.run(t, repeats=int(count), rng=profiles_stream(seed),
                                        keep_values="none", distribution=distribution)
                seconds = time.perf_counter() - start
                log(f"  {label:>10} {str(spec):>11} x {count}: {seconds:.2f} s")
                if keep is not None:
                    keep[(label, str(spec), int(count))] = result
                rows.append(_row(label, spec, result, seconds))
    return pd.DataFrame(rows)


def _row(label, spec, result, seconds) -> dict:
    fit = result.all_inside_share()
    spread = result.reliability()
    row = {"allocation": label, "profile": str(spec), "length_mm": profile_length(spec),
           "repeats": result.repeats, "yield": fit.estimate, "yield_lower": fit.lower,
           "yield_upper": fit.upper}
    columns = list(OUTPUTS)
    for output in SPREAD_OUTPUTS:
        row[f"std_{output}"] = spread.std[columns.index(output)]
    for output in SPREAD_OUTPUTS:
        row[f"mean_{output}"] = spread.estimate[columns.index(output)]
        row[f"se_{output}"] = spread.standard_error[columns.index(output)]
    row["seconds"] = seconds
    return row


@renamed("points_per_axis", "points")
@renamed("seed", "rng")
def systematic_effect(machine, tolerances, systematic, *, repeats: int = 2000,
                      rng=2023, points: int = 5) -> pd.DataFrame:
    """FOSM and Monte-Carlo reliability without and with a systematic error profile.

    Returns one row per output: the worst-pose and workspace-mean two-sided FOSM
    probability without and with the measured means over the grid, the largest output
    mean, and the grid experiment's mean fraction with its standard error, with the means
    added. ``rng`` (None, an int or a Generator) drives the grid experiment, on the
    ``points``-point grid; ``seed=`` and ``points_per_axis=`` are their deprecated
    spellings (:mod:`reliability.basics.renamed`).
    """
    poses = workspace_grid(machine, points)
    jacobian = machine.jacobian(poses)
    plain = fosm(machine, tolerances, poses, jacobian=jacobian, distribution="truncated")
    shifted = fosm(machine, tolerances, poses, jacobian=jacobian, distribution="truncated",
                   means=systematic.means(poses))
    mc = GridExperiment(machine, points, systematic=systematic).run(
        tolerances, repeats=repeats, rng=rng, keep_values="none").reliability()
    return pd.DataFrame({
        "limit": machine.limits,
        "worst_without": plain.worst("two_sided"), "worst_with": shifted.worst("two_sided"),
        "mean_without": plain.workspace_mean("two_sided"),
        "mean_with": shifted.workspace_mean("two_sided"),
        "largest_output_mean": np.abs(shifted.mean).max(axis=0),
        "mc_mean_with": mc.estimate, "mc_se_with": mc.standard_error,
    }, index=pd.Index(OUTPUTS, name="output"))
