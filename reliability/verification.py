"""Monte-Carlo verification of one allocation, FOSM beside it (Sec. 5.3 generalised).

:func:`verify` runs three independent checks of the FOSM prediction, each with its interval:

- repeated grid experiments (one error draw per experiment shared by all grid poses):
  the mean share in tolerance against the grid mean of the FOSM probability, a Wilson
  interval on Kish's effective sample size from the spread between experiments;
- random poses (fresh pose and errors per sample): Wilson interval;
- Monte-Carlo at each output's FOSM worst pose: Wilson interval, against FOSM there.

Errors are drawn normal with σ = t/3 truncated at ±t as in the paper, so the Monte-Carlo
is slightly more reliable than the untruncated FOSM; the worst-pose FOSM here uses the σ of
the truncated draws so that the two compare like with like.

Beyond the grid, at each output's worst grid pose: :func:`reachable_events` says which
failure probabilities crude sampling can resolve, and :func:`rare_event_table` estimates
each output's and the system's failure probability by importance sampling (or subset
simulation) on the exact model.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy.stats import norm

from .comparison import fosm_versus_monte_carlo
from .errors import InputError
from .fosm import fosm
from .machine import OUTPUTS
from .pose_sampling import EVENTS, sample_at_poses
from .poses import workspace_grid
from .rare import failure_probability, worst_grid_poses
from .sampling import GridExperiment, sample_random_poses
from .streams import spawn, verification_streams


@dataclass(frozen=True, repr=False)
class Verification:
    """Monte-Carlo checks of one allocation.

    Attributes
    ----------
    fosm : FosmResult
        FOSM on the grid poses.
    grid : GridExperimentResult
    grid_comparison : DataFrame
        :func:`reliability.comparison.fosm_versus_monte_carlo`.
    random_poses : DataFrame
        :meth:`RandomPoseResult.to_frame` (Wilson 95 %).
    worst_poses : DataFrame
        Per output: the worst pose's axis positions, FOSM two-sided probability (σ of the
        truncated draws) and the Monte-Carlo estimate with its Wilson 95 % interval.
    """

    fosm: object
    grid: object
    grid_comparison: pd.DataFrame
    random_poses: pd.DataFrame
    worst_poses: pd.DataFrame

    def to_frame(self) -> pd.DataFrame:
        """Per output, the three Monte-Carlo estimates with their 95 % intervals beside
        the FOSM predictions they check (two-sided probabilities)."""
        grid = self.grid_comparison.set_index("output")
        random = self.random_poses.set_index("output")
        worst = self.worst_poses.set_index("output")
        return pd.DataFrame({
            "grid_mc": grid["mc_estimate"], "grid_low": grid["mc_lower"],
            "grid_high": grid["mc_upper"], "grid_fosm_normal": grid["fosm_two_sided"],
            "random_mc": random["estimate"], "random_low": random["lower"],
            "random_high": random["upper"], "random_fosm_normal": random["fosm_two_sided"],
            "worst_mc": worst["mc_estimate"], "worst_low": worst["mc_lower"],
            "worst_high": worst["mc_upper"], "worst_fosm_truncated": worst["fosm_two_sided"],
        })

    def summary(self) -> str:
        """What was sampled, then :meth:`to_frame` in per cent."""
        head = (f"Monte-Carlo verification: {self.grid.repeats} grid experiments of "
                f"{self.grid.n_poses} poses (Wilson interval on Kish's effective size), "
                f"{int(self.random_poses['n'].iloc[0])} random poses and "
                f"{int(self.worst_poses['samples'].iloc[0])} samples at each output's worst "
                f"pose (Wilson); errors drawn normal, σ = t/3, truncated at ±t; FOSM with "
                f"normal errors, and with the truncated σ at the worst pose; two-sided "
                f"probabilities in %")
        return f"{head}\n{(100 * self.to_frame()).to_string(float_format='{:.3f}'.format)}"

    def __repr__(self) -> str:
        return self.summary()


def verify(machine, tolerances, *, points: int = 5, repeats: int = 20,
           samples: int = 20_000, rng=None, progress=None, bar=None,
           prediction=None) -> Verification:
    """Run the three Monte-Carlo checks of ``tolerances``.

    Parameters
    ----------
    machine : Machine
    tolerances : ndarray (n_errors,)
    points : int
        Grid points per axis.
    repeats : int
        Grid experiments.
    samples : int
        Random-pose samples, and samples at each worst pose.
    rng : None, int or numpy.random.Generator
        Split by :func:`reliability.streams.verification_streams` into the grid,
        random-pose and worst-pose streams, in that order (the same seed gives the same
        numbers here, in ``precrel verify``, ``precrel report`` and a sweep).
    progress : callable, optional
        ``progress(step)`` with a short description before each step.
    bar : callable, optional
        ``bar(total, description)`` returning a progress bar (a context manager with
        ``update(n)``, e.g. ``tqdm``) for the grid experiments and random poses.
    prediction : FosmResult, optional
        FOSM of ``tolerances`` on the ``points``-point workspace grid, when the caller has
        it already; computed otherwise.
    """
    progress = progress or (lambda step: None)
    bar = bar or _NoBar
    grid_rng, random_rng, worst_rng = verification_streams(rng)
    experiment = GridExperiment(machine, points)
    result = fosm(machine, tolerances, experiment.poses) if prediction is None else prediction
    if not np.array_equal(result.poses, experiment.poses):
        raise InputError("prediction must be FOSM on the same workspace grid as the "
                         "grid experiments")
    progress(f"{repeats} grid experiments of {experiment.n_poses} poses")
    with bar(repeats, "grid experiments") as counter:
        grid = experiment.run(tolerances, repeats=repeats, rng=grid_rng,
                              progress=_advance(counter))
    progress(f"{samples} random poses")
    with bar(samples, "random poses") as counter:
        random = sample_random_poses(machine, tolerances, samples, rng=random_rng,
                                     progress=_advance(counter))
    progress(f"{samples} samples at each output's worst pose")
    worst = worst_pose_monte_carlo(machine, tolerances, result, samples, worst_rng)
    return Verification(fosm=result, grid=grid,
                        grid_comparison=fosm_versus_monte_carlo(result, grid),
                        random_poses=random.to_frame().reset_index(), worst_poses=worst)


def worst_pose_monte_carlo(machine, tolerances, fosm_result, samples: int, rng
                           ) -> pd.DataFrame:
    """Monte-Carlo of each output at its own FOSM worst pose (truncated normal errors), by
    :func:`reliability.pose_sampling.sample_at_poses`; Wilson intervals."""
    poses = fosm_result.poses[fosm_result.worst_pose]  # (6, n_axes)
    sampled = sample_at_poses(machine, tolerances, poses, samples=samples, rng=rng,
                              distribution="truncated", events=OUTPUTS, fosm=False)
    rows = np.arange(len(OUTPUTS))
    failure = sampled.estimate  # the complement of a Wilson interval is a Wilson interval
    truncated = fosm(machine, tolerances, poses, distribution="truncated")
    frame = pd.DataFrame({"output": list(OUTPUTS)})
    for i, axis in enumerate(machine.axes):
        frame[axis] = poses[:, i]
    frame["fosm_two_sided"] = truncated.two_sided[rows, rows]
    frame["mc_estimate"] = 1.0 - np.asarray(failure.estimate)[rows, rows]
    frame["mc_lower"] = 1.0 - np.asarray(failure.upper)[rows, rows]
    frame["mc_upper"] = 1.0 - np.asarray(failure.lower)[rows, rows]
    frame["samples"] = samples
    return frame


def reachable_events(machine, tolerances, precision: float, max_samples: int, *,
                     k: float = 3.0, confidence: float = 0.95) -> tuple[str, ...]:
    """Events whose worst-pose failure probability crude Monte-Carlo can resolve to
    ``precision`` within ``max_samples``.

    A Wilson interval's relative half-width on a failure probability p after n samples is
    about z √((1 − p)/(n p)), so n ≤ max_samples reaches ``precision`` only if
    p ≳ (z/precision)² / max_samples. FOSM's two-sided failure probability at each output's
    worst grid pose decides; the system event (which fails at least as often as any output)
    is kept when any output is.
    """
    z = norm.ppf(0.5 + confidence / 2)
    threshold = (z / precision) ** 2 / max_samples
    grid = fosm(machine, tolerances, workspace_grid(machine), k=k)
    failure = 1.0 - grid.two_sided.min(axis=0)
    kept = tuple(o for o, p in zip(machine.outputs, failure) if p >= threshold)
    return kept + ("system",) if kept else ()


def rare_event_table(machine, tolerances, *, events=EVENTS, method: str = "importance",
                     target_cov: float = 0.1, max_evaluations: int = 20_000, k: float = 3.0,
                     distribution: str = "normal", rng=None) -> pd.DataFrame:
    """Failure probability of each event at its worst grid pose, one row per event.

    Each event draws from its own stream (``spawn(rng, len(events))``). Columns: the pose
    (axis positions with units), the estimate, its CoV and interval, the exact-model
    evaluations, whether the target CoV was reached and the linear FOSM answer
    (:class:`reliability.rare.RareEventResult`).
    """
    events = tuple(events)
    streams = spawn(rng, len(events))
    poses = worst_grid_poses(machine, tolerances, events, k=k)
    frames = []
    for event, stream, pose in zip(events, streams, poses):
        result = failure_probability(machine, tolerances, pose, event=event, method=method,
                                     target_cov=target_cov, max_evaluations=max_evaluations,
                                     k=k, distribution=distribution, rng=stream)
        frames.append(result.to_frame())
    return pd.concat(frames, ignore_index=True).set_index("event")


def _advance(counter):
    """A ``progress(done, total)`` callback moving ``counter`` to ``done``."""
    def update(done, total):
        counter.update(done - counter.n)
    return update


class _NoBar:
    """A silent stand-in for a progress bar."""

    def __init__(self, total, description):
        self.n = 0

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False

    def update(self, n):
        self.n += n
