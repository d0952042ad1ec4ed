"""Monte-Carlo verification of one allocation, FOSM beside it (Sec. 5.3 generalised).

:func:`verify` first answers the manufacturer's question, the machine yield: the share of
built machines that keep all six outputs within their limits at every grid pose, under the study's
error-profile model (``machine.profile``) and reading
(:func:`reliability.sampling.machine_yield.machine_yield`). Below it, three independent checks of
the per-output, per-pose FOSM prediction, each with its interval:

- repeated grid experiments (one error draw per experiment shared by all grid poses):
  the mean share in tolerance against the grid mean of the FOSM probability, a Wilson
  interval on Kish's effective sample size from the spread between experiments;
- random poses (fresh pose and errors per sample): Wilson interval;
- Monte-Carlo at each output's FOSM worst pose: Wilson interval, against FOSM there.

Every check draws the errors under the study's reading of a tolerance
(``machine.distribution`` unless ``distribution=`` says otherwise): normal with σ = t/3, or
that normal truncated at ±t as in the paper's Sec. 5.3; FOSM beside it uses the same
reading, and at the worst poses the exact probability of the linearised output
(:mod:`reliability.first_order.linear_exact`) stands beside the Monte-Carlo, so that what is left
between them is the linearisation. The worst poses are the grid's FOSM worst poses, or any
poses the caller gives (e.g. the certified worst poses of the continuous workspace,
:func:`reliability.first_order.workspace_search.certified_worst`).

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

from ..basics import checks
from ..basics.errors import InputError
from ..basics.saved_fields import Frame, Nested, Text, load_fields, save_fields
from ..basics.streams import spawn, verification_streams
from ..first_order.certificate import DEFAULT_RTOL, WORKSPACES, certified_worst
from ..first_order.fosm import FosmResult, fosm
from ..first_order.worst_grid_pose import worst_grid_poses
from ..model.machine import OUTPUTS
from ..model.poses import workspace_grid
from .experiment_results import GridExperimentResult
from .fosm_comparison import fosm_versus_monte_carlo
from .grid_experiment import GridExperiment
from .machine_yield import DEFAULT_MACHINES, YieldModel
from .pose_sampling import EVENTS, sample_at_poses, sample_random_poses
from .rare_events import failure_probability
from .yield_estimate import YieldEstimate


@dataclass(frozen=True, repr=False)
class Verification:
    """Monte-Carlo checks of one allocation.

    Attributes
    ----------
    fosm : FosmResult
        FOSM on the grid poses.
    grid : GridExperimentResult
    grid_comparison : DataFrame
        :func:`reliability.sampling.fosm_comparison.fosm_versus_monte_carlo`.
    random_poses : DataFrame
        :meth:`RandomPoseResult.to_frame` (Wilson 95 %).
    worst_poses : DataFrame
        Per output: the worst pose's axis positions, the FOSM two-sided probability
        (normal approximation), the exact linear probability (``exact_linear``) and the
        Monte-Carlo estimate with its Wilson 95 % interval, and whether the interval
        reaches the target (``reaches_target``: its upper end is at least the target).
    distribution : str
        The reading every check drew its errors under.
    machine_yield : YieldEstimate or None
        The share of built machines within every limit at every grid pose
        (:func:`reliability.sampling.machine_yield.machine_yield`), under the profile it names.
    """

    fosm: object
    grid: object
    grid_comparison: pd.DataFrame
    random_poses: pd.DataFrame
    worst_poses: pd.DataFrame
    distribution: str = "normal"
    machine_yield: object = None

    def to_frame(self) -> pd.DataFrame:
        """Per output, the three Monte-Carlo estimates with their 95 % intervals beside
        the FOSM predictions they check (two-sided probabilities)."""
        grid = self.grid_comparison.set_index("output")
        random = self.random_poses.set_index("output")
        worst = self.worst_poses.set_index("output")
        return pd.DataFrame({
            "grid_mc": grid["mc_estimate"], "grid_low": grid["mc_lower"],
            "grid_high": grid["mc_upper"], "grid_fosm": grid["fosm_two_sided"],
            "random_mc": random["estimate"], "random_low": random["lower"],
            "random_high": random["upper"], "random_fosm": random["fosm_two_sided"],
            "worst_mc": worst["mc_estimate"], "worst_low": worst["mc_lower"],
            "worst_high": worst["mc_upper"], "worst_fosm": worst["fosm_two_sided"],
            "worst_exact_linear": worst["exact_linear"],
        })

    def summary(self) -> str:
        """The machine yield, what was sampled, then :meth:`to_frame` in per cent."""
        first = "" if self.machine_yield is None else self.machine_yield.summary() + "\n\n"
        head = first + (f"Monte-Carlo verification: {self.grid.repeats} grid experiments of "
                f"{self.grid.n_poses} poses (Wilson interval on Kish's effective size), "
                f"{int(self.random_poses['n'].iloc[0])} random poses and "
                f"{int(self.worst_poses['samples'].iloc[0])} samples at each output's worst "
                f"pose (Wilson); errors drawn {reading_text(self.distribution)}, and FOSM "
                f"with the same reading; two-sided probabilities in %")
        return f"{head}\n{(100 * self.to_frame()).to_string(float_format='{:.3f}'.format)}"

    def __repr__(self) -> str:
        return self.summary()

    def save(self, path, overwrite: bool = False):
        """Save as JSON (:data:`SAVED_FIELDS`, tag :data:`SAVED_FORMAT`): the FOSM result,
        the grid experiments' counts (not their per-pose values), the three tables of
        estimates and the machine yield. An existing file is kept unless ``overwrite``.
        Returns the path."""
        return save_fields(self, path, SAVED_FORMAT, SAVED_FIELDS, overwrite)

    @classmethod
    def load(cls, path) -> "Verification":
        """Reload a verification written by :meth:`save`, every field checked (the FOSM
        result and the grid counts as their own ``load`` checks them); the estimates,
        intervals and verdicts are the saved ones. A damaged field raises
        :class:`~reliability.basics.errors.SavedResultError` naming the file and field."""
        return cls(**load_fields(path, SAVED_FORMAT, SAVED_FIELDS)[1])


SAVED_FORMAT = "precrel.verification"
SAVED_FIELDS = (
    Nested("fosm", FosmResult), Nested("grid", GridExperimentResult),
    Frame("grid_comparison", ("output", "mc_estimate", "mc_lower", "mc_upper",
                              "fosm_two_sided")),
    Frame("random_poses", ("output", "estimate", "lower", "upper", "fosm_two_sided", "n")),
    Frame("worst_poses", ("output", "mc_estimate", "mc_lower", "mc_upper", "fosm_two_sided",
                          "exact_linear", "samples")),
    Text("distribution", ("normal", "truncated")),
    Nested("machine_yield", YieldEstimate, optional=True))


def reading_text(distribution: str) -> str:
    """The reading of a tolerance t in words."""
    return ("normal, σ = t/3, truncated at ±t" if distribution == "truncated"
            else "normal, σ = t/3 (not truncated)")


def verify(machine, tolerances, *, points: int = 5, repeats: int = 20,
           samples: int = 20_000, rng=None, progress=None, bar=None,
           prediction=None, distribution: str | None = None,
           worst_poses=None, profile=None,
           machines: int = DEFAULT_MACHINES, workspace: str = "continuous",
           rtol: float = DEFAULT_RTOL) -> Verification:
    """The machine yield of ``tolerances``, then the three Monte-Carlo checks.

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
        Split by :func:`reliability.basics.streams.verification_streams` into the grid,
        random-pose, worst-pose and machine-yield streams, in that order (the same seed
        gives the same numbers here, in ``precrel verify``, ``precrel report`` and a sweep).
    progress : callable, optional
        ``progress(step)`` with a short description before each step.
    bar : callable, optional
        ``bar(total, description)`` returning a progress bar (a context manager with
        ``update(n)``, e.g. ``tqdm``) for the grid experiments and random poses.
    prediction : FosmResult, optional
        FOSM of ``tolerances`` on the ``points``-point workspace grid under the same
        reading, when the caller has it already; computed otherwise.
    distribution : {'normal', 'truncated'}, optional
        The reading of a tolerance every check draws under; ``machine.distribution`` by
        default.
    worst_poses : array_like (6, n_axes), optional
        The pose at which to sample each output; by default each output's worst pose of
        ``workspace``.
    profile : str, optional
        Error profile of the machine yield; ``machine.profile`` by default.
    machines : int
        Built machines simulated for the machine yield.
    workspace : {'continuous', 'grid'}
        Where each output's worst pose is sought when ``worst_poses`` is not given: its
        certified worst pose over the continuous strokes
        (:func:`reliability.first_order.certificate.certified_worst`, to ``rtol`` in σ;
        the default, as ``precrel verify`` and ``precrel report``), or its FOSM worst
        pose of the ``points``-point grid.
    rtol : float
        Relative tolerance in σ of the continuous workspace's certificate.
    """
    progress = progress or (lambda step: None)
    bar = bar or _NoBar
    distribution = machine.distribution if distribution is None else distribution
    checks.choice(distribution, "distribution", ("normal", "truncated"))
    if worst_poses is not None:
        worst_poses = np.asarray(machine.check_positions(worst_poses), dtype=float)
        if worst_poses.shape != (len(OUTPUTS), len(machine.axes)):
            raise InputError(f"worst_poses must have shape ({len(OUTPUTS)}, "
                             f"{len(machine.axes)}), one pose per output; got "
                             f"{worst_poses.shape}")
        checks.poses_in_strokes(machine, worst_poses, "worst_poses")
    machines = checks.positive_int(machines, "machines")
    checks.choice(workspace, "workspace", WORKSPACES)
    if worst_poses is None and workspace == "continuous":
        progress(f"certified worst poses over the continuous workspace (rtol {rtol:g})")
        worst_poses = certified_worst(machine, tolerances, rtol=rtol,
                                      distribution=distribution)[list(machine.axes)]
        worst_poses = worst_poses.to_numpy(dtype=float)
    grid_rng, random_rng, worst_rng, yield_rng = verification_streams(rng)
    yield_model = YieldModel(machine, profile=profile, distribution=distribution,
                             points=points)
    experiment = GridExperiment(machine, points)
    result = fosm(machine, tolerances, experiment.poses, distribution=distribution) \
        if prediction is None else prediction
    if not np.array_equal(result.poses, experiment.poses):
        raise InputError("prediction must be FOSM on the same workspace grid as the "
                         "grid experiments")
    if result.distribution != distribution:
        raise InputError(f"prediction was computed under the {result.distribution!r} "
                         f"reading; the verification draws under {distribution!r}")
    progress(f"machine yield from up to {machines} built machines (profile "
             f"{yield_model.profile})")
    built = yield_model.estimate(tolerances, machines=machines, rng=yield_rng)
    progress(f"{repeats} grid experiments of {experiment.n_poses} poses")
    with bar(repeats, "grid experiments") as counter:
        grid = experiment.run(tolerances, repeats=repeats, rng=grid_rng,
                              progress=_advance(counter), distribution=distribution)
    progress(f"{samples} random poses")
    with bar(samples, "random poses") as counter:
        random = sample_random_poses(machine, tolerances, samples, rng=random_rng,
                                     progress=_advance(counter), distribution=distribution)
    progress(f"{samples} samples at each output's worst pose")
    poses = result.poses[result.worst_pose] if worst_poses is None else worst_poses
    worst = worst_pose_monte_carlo(machine, tolerances, poses, samples, worst_rng,
                                   distribution=distribution)
    return Verification(fosm=result, grid=grid,
                        grid_comparison=fosm_versus_monte_carlo(result, grid),
                        random_poses=random.to_frame().reset_index(), worst_poses=worst,
                        distribution=distribution, machine_yield=built)


def worst_pose_monte_carlo(machine, tolerances, poses, samples: int, rng, *,
                           distribution: str = "normal") -> pd.DataFrame:
    """Monte-Carlo of each output at its own pose (``poses`` (6, n_axes), row o for
    output o) under the reading ``distribution``, by
    :func:`reliability.sampling.pose_sampling.sample_at_poses`; Wilson intervals, beside FOSM and
    the exact linear probability, and whether each interval reaches the target."""
    poses = np.asarray(poses, dtype=float)
    sampled = sample_at_poses(machine, tolerances, poses, samples=samples, rng=rng,
                              distribution=distribution, events=OUTPUTS, fosm=False)
    rows = np.arange(len(OUTPUTS))
    failure = sampled.estimate  # the complement of a Wilson interval is a Wilson interval
    linear = fosm(machine, tolerances, poses, distribution=distribution)
    frame = pd.DataFrame({"output": list(OUTPUTS)})
    for i, axis in enumerate(machine.axes):
        frame[axis] = poses[:, i]
    frame["fosm_two_sided"] = linear.two_sided[rows, rows]
    frame["exact_linear"] = linear.exact_two_sided[rows, rows]
    frame["mc_estimate"] = 1.0 - np.asarray(failure.estimate)[rows, rows]
    frame["mc_lower"] = 1.0 - np.asarray(failure.upper)[rows, rows]
    frame["mc_upper"] = 1.0 - np.asarray(failure.lower)[rows, rows]
    frame["samples"] = samples
    frame["target"] = machine.targets
    frame["reaches_target"] = frame["mc_upper"] >= machine.targets
    return frame


def reachable_events(machine, tolerances, precision: float, max_samples: int, *,
                     k: float = 3.0, confidence: float = 0.95,
                     distribution: str | None = None) -> tuple[str, ...]:
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
    distribution = machine.distribution if distribution is None else distribution
    grid = fosm(machine, tolerances, workspace_grid(machine), k=k, distribution=distribution)
    failure = 1.0 - grid.two_sided.min(axis=0)
    kept = tuple(o for o, p in zip(machine.outputs, failure) if p >= threshold)
    return kept + ("system",) if kept else ()


def rare_event_table(machine, tolerances, *, events=EVENTS, method: str = "importance",
                     target_cov: float = 0.1, max_evaluations: int = 20_000, k: float = 3.0,
                     distribution: str | None = None, rng=None) -> pd.DataFrame:
    """Failure probability of each event at its worst grid pose, one row per event.

    Each event draws from its own stream (``spawn(rng, len(events))``). Columns: the pose (axis
    positions with units), the estimate, its CoV and interval, the exact-model evaluations, whether
    the target CoV was reached and the linear FOSM answer
    (:class:`reliability.sampling.rare_events.RareEventResult`). ``distribution`` is the reading of
    the tolerances, ``machine.distribution`` by default.
    """
    distribution = machine.distribution if distribution is None else distribution
    events = tuple(events)
    streams = spawn(rng, len(events))
    poses = worst_grid_poses(machine, tolerances, events, k=k, distribution=distribution)
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
