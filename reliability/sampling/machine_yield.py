"""The machine yield: the share of built machines that hold every limit at every pose.

A built machine is one draw of all its errors (:mod:`reliability.model.profiles` says how an
axis' motion errors hang together along its travel). It *passes* when all six outputs stay
strictly within their limits, ``|y_o| < I_o`` (Eq. 19), at every pose of the workspace
grid (the ``P``-point grid of Sec. 5.3, 15 625 poses for the paper's machine). The machine
yield is the probability that a built machine passes, under a stated error-profile model
and reading of a tolerance.

The API (stable)::

    machine_yield(machine, tolerances, *, profile=None, distribution=None,
                  points_per_axis=5, machines=DEFAULT_MACHINES, rng=None, method="auto",
                  confidence=0.95, k=3.0, target_cov=0.1, memory=None) -> YieldEstimate

    model = YieldModel(machine, profile=None, distribution=None, points_per_axis=5, k=3.0,
                       memory=None, executor=None)
    model.estimate(tolerances, machines=..., rng=..., method=..., ...) -> YieldEstimate
    model.first_order_bounds(tolerances) -> (lower, upper)
    model.linear_failure(tolerances, rng=None) -> float   # the linearised model's, no chain
    model.draws(machines, rng=None) -> u                   # (machines, model.dimension)
    model.output_ratios(u, tolerances) -> (R, 6)           # max over poses of |y_o|/I_o
    model.worst_ratios(u, tolerances) -> (ratio, row)      # max over outputs, and its row

:class:`YieldModel` holds what does not depend on the tolerances (the grid, the profile's
factors, the chain's transports), so a caller that estimates many allocations of one
machine (an allocation for a yield target) builds it once. :func:`machine_yield` is the
one-call form. The result, :class:`YieldEstimate`, carries the estimate, its interval and
coefficient of variation, the machines simulated, the method, the profile, the reading,
the workspace, the first-order bounds and the failure shares.

One engine
----------
Every verdict on a built machine comes from :meth:`YieldModel.output_ratios`: for given
standard normal draws ``u`` it evaluates the exact chain at every grid pose and keeps, per
machine and output, the largest ``|y_o|/I_o``; the machine passes when all six are below 1
(Eq. 19 at every pose). :meth:`YieldModel.estimate` (``precrel verify``, both allocations
of ``precrel report``, :func:`reliability.sampling.verification.verify`), both stages of
:func:`allocation.allocate_for_yield` (per-output targets and error shape, on fixed draws:
common random numbers), its naive method and its verification sample all use it, so the
same draws give the same verdicts wherever they are judged. Machines are independent, so
it evaluates them in fixed batches, here or, with ``executor=client``, as tasks of a Dask
client (:mod:`reliability.sampling.machine_blocks`), with the same bytes either way.

Estimators
----------
Every draw of one machine lives in a standard normal space ``u`` of dimension
``6 n P + 6 (n − 1)`` (each axis' six motion errors at its ``P`` grid points, then the
assembly errors). The profile's factor ``L`` (and the machine's item correlation, if any)
makes correlated normals ``z = L u``; the reading maps each to its error,
``x = (t/k) g(z)`` with ``g`` the identity (``normal``) or the truncated-normal quantile of
``Φ(z)`` (``truncated``, :func:`reliability.model.profiles.to_marginal`). The exact chain
(:meth:`GridExperiment.evaluate`) then gives every pose's outputs.

* **crude** — ``N`` machines with ``u ~ N(0, I)``; the yield is the share that pass, with a
  Clopper–Pearson interval.
* **importance** — the failure set is the union over rows ``r = (pose, output)`` of
  ``{|y_r(u)| ≥ I_r}``. Linearised at ``u = 0``, ``y_r ≈ a_r·u`` with ``a_r = J_r s L`` (the
  analytic Jacobian at the row's pose; ``s = ∂x/∂z`` at 0: ``t/k``, times ``1 − 2Φ(−k)`` under the
  truncated reading) and each row event is a pair of half-spaces ``F_r = {|a_r·u| ≥ I_r}`` of
  probability ``p_r = 2Φ(−I_r/|a_r|)`` (``|a_r|`` is Eq. 20's σ with ``s``: FOSM's σ of the row
  under the normal reading). Following the ALOE construction of Owen, Maximov & Chertkov (2019,
  "Importance sampling for the union of rare events in reliability"), the proposal is the defensive
  mixture

      q(u) = α φ(u) + (1 − α) Σ_{r∈S} (p_r / P_S) φ(u) 1[u ∈ F_r] / p_r,

  over the dominant rows ``S`` (``P_S = Σ_{r∈S} p_r``): with probability ``α`` a plain
  draw, otherwise a row chosen with probability ``p_r/P_S`` and ``u`` drawn from ``φ``
  conditioned exactly on that row's event (its component along ``a_r`` from the normal
  tail beyond ``I_r/|a_r|``, either sign, the rest unchanged). Its density ratio is

      w(u) = φ(u)/q(u) = 1 / (α + (1 − α) N_S(u)/P_S),   N_S(u) = #{r ∈ S: u ∈ F_r},

  known exactly and at most ``1/α``. The estimate of the failure probability is the mean
  of ``w(u) 1[the exact chain fails at some pose]``: unbiased for the *true* (non-linear,
  truncated) failure probability whatever the linearisation's error, because ``q > 0``
  wherever ``φ > 0`` and ``w`` is the exact ratio; the linearisation only sets the
  efficiency. Its CoV is the sample standard deviation of those terms over ``√n`` and the
  mean; sampling runs in batches until the CoV is at most ``target_cov`` (after at least
  :data:`MIN_IMPORTANCE_MACHINES`) or ``machines`` are spent. The interval is
  ``p ± z·se`` (failure probability, lower end floored at 0).
* **auto** — crude unless crude sampling of ``machines`` would expect fewer than
  :data:`MIN_FAILURES` failing machines; the expectation is ``machines`` times the
  linearised model's failure probability, itself estimated cheaply by ALOE without the
  chain (``P_S · mean 1/N_S`` over 2 000 draws of the mixture) plus the rows left out of
  ``S``.

First-order bounds
------------------
For the linearised model, whatever the profile (every row's marginal is FOSM's), the union
(Bonferroni) bound gives ``yield ≥ 1 − Σ_rows P(|y_r| ≥ I_r)`` (floored at 0) and the best
single row ``yield ≤ min_rows P(|y_r| < I_r)``. Row probabilities are normal: exact for the
``normal`` reading, the normal approximation with the truncated σ for ``truncated``.

Failure shares
--------------
Among failing machines, the requirement that fails first is the row with the largest ``|y_r|/I_r``
over the grid: its output and its pose region. A region bins the worst pose per axis into the low,
middle or high third of the axis' stroke, showing only the axes along which that output's mean σ²
changes most (at most :data:`MAX_REGION_AXES`, each by more than :data:`REGION_SPREAD`; the others
hardly decide where it fails); an output no axis decides has one region, the axis positions
all its failing rows' worst poses share. Shares are weighted by ``w`` under importance sampling; their
intervals are Wilson intervals on Kish's effective number of failing machines ``(Σw)²/Σw²``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from scipy.special import ndtr, ndtri
from scipy.stats import norm

from ..basics import checks, streams
from ..basics.chunks import chunk_size, chunks, jacobian_bytes
from ..basics.statistics import all_within_share, share_interval
from ..first_order.fosm import error_sigma, pose_sigma, two_sided_failure
from ..model.error_draws import check_reading, grid_factors, normal_to_marginal
from ..model.kinematics import (chain_factors, deviation_from_transports, ideal_rotation,
                                transports, vectors_in_frame)
from ..model.machine import OUTPUTS
from ..model.profiles import ConstantProfile, axis_profiles, travel_factors
from ..model.transforms import read_pose_error
from .grid_experiment import GridExperiment
from .machine_blocks import MachineBlocks

#: Built machines simulated when not told otherwise (the command line's ``--machines``).
DEFAULT_MACHINES = 4000
METHODS = ("auto", "crude", "importance")
#: ``auto`` samples crudely only when it expects at least this many failing machines.
MIN_FAILURES = 50
#: α, the plain-normal share of the importance proposal; weights are at most 1/α.
DEFENSIVE = 0.1
#: The proposal's rows: the fewest, by decreasing p_r, that hold this share of Σ p_r ...
EVENT_MASS = 1.0 - 1e-3
#: ... and at most this many.
MAX_EVENTS = 20_000
#: Draws of the mixture in the chain-free ALOE estimate of the linearised failure probability.
LINEAR_SAMPLES = 2000
#: Importance sampling stops at the target CoV only after this many machines.
MIN_IMPORTANCE_MACHINES = 1000
#: Machines per importance-sampling batch at most (the CoV is checked between batches).
IMPORTANCE_BATCH = 500
#: An axis is shown in a failure region when an output's mean σ² over the grid points of
#: the axis changes by more than this share between its least and its largest ...
REGION_SPREAD = 0.25
#: ... and it is one of the output's this many axes of largest change.
MAX_REGION_AXES = 2
#: Rows of the failure-share table that :meth:`YieldEstimate.summary` prints.
SHOWN_SHARES = 12
THIRDS = ("low", "middle", "high")
SHARE_COLUMNS = ("output", "region", "share", "lower", "upper", "failures")


@dataclass(frozen=True, eq=False, repr=False)
class YieldEstimate:
    """A machine yield with its precision and what it rests on.

    Attributes
    ----------
    estimate : float
        Estimated yield: the probability that a built machine keeps all six outputs within
        their limits at every pose of the workspace.
    lower, upper : float
        Interval at ``confidence``: Clopper–Pearson (crude) or ``1 − (p ± z·se)``
        (importance sampling).
    confidence : float
    cov : float
        Coefficient of variation of the estimated *failure* probability ``1 − estimate``
        (NaN when no failing machine was seen).
    machines : int
        Built machines simulated; each is one evaluation of the exact chain at every pose.
    method : str
        ``'crude'`` or ``'importance'``.
    method_reason : str
        Why the method was used.
    profile : str
        The error-profile model (``'constant'``, ``'independent'``, ``'gp:300'``).
    distribution : str
        The reading of a tolerance (``'normal'`` or ``'truncated'``).
    workspace : str
        E.g. ``'5-point grid (15 625 poses)'``.
    n_poses : int
    failures : int
        Failing machines seen (under importance sampling, drawn from the proposal).
    first_order_lower, first_order_upper : float
        Bounds on the yield of the linearised model (union bound; best single row).
    failure_shares : DataFrame
        Columns ``output, region, share, lower, upper, failures``: which requirement fails
        first among failing machines, largest share first.
    target_cov : float or None
        The CoV importance sampling aimed at (None for crude).
    """

    estimate: float
    lower: float
    upper: float
    confidence: float
    cov: float
    machines: int
    method: str
    method_reason: str
    profile: str
    distribution: str
    workspace: str
    n_poses: int
    failures: int
    first_order_lower: float
    first_order_upper: float
    failure_shares: pd.DataFrame = field(repr=False)
    target_cov: float | None = None

    @property
    def failure_probability(self) -> float:
        """``1 − estimate``."""
        return 1.0 - self.estimate

    @property
    def machine_evaluations(self) -> int:
        """Evaluations of the exact chain at every grid pose: one per simulated machine,
        whichever the method (``machines``); ``machines × n_poses`` pose evaluations."""
        return self.machines

    @property
    def interval(self) -> tuple[float, float]:
        """``(lower, upper)``."""
        return self.lower, self.upper

    @property
    def crude_equivalent(self) -> float:
        """Machines crude sampling would need for the same CoV: ``(1 − p)/(p · CoV²)`` with
        ``p`` the failure probability (NaN without a CoV)."""
        p = self.failure_probability
        if not (p > 0 and np.isfinite(self.cov) and self.cov > 0):
            return math.nan
        return (1.0 - p) / (p * self.cov ** 2)

    def model_text(self) -> str:
        """The modelling choices the yield depends on, in words."""
        reading = ("normal, σ = t/3, truncated at ±t" if self.distribution == "truncated"
                   else "normal, σ = t/3")
        return (f"profile {self.profile}, tolerances read as {reading} "
                f"(distribution {self.distribution!r}), workspace {self.workspace}")

    def summary(self) -> str:
        """A few readable lines: the yield, how it was estimated, its first-order bounds
        and the failure shares."""
        level = f"{self.confidence:.0%}"
        how = (f"crude Monte-Carlo of {self.machines:,} built machines, {self.failures:,} "
               f"failing (Clopper–Pearson interval)" if self.method == "crude" else
               f"importance sampling (defensive ALOE mixture) of {self.machines:,} built "
               f"machines, {self.failures:,} failing; crude sampling would need about "
               f"{_count_text(self.crude_equivalent)} machines for the same CoV")
        lines = [
            f"machine yield {yield_text(self.estimate)} ({level} interval "
            f"[{yield_text(self.lower)}, {yield_text(self.upper)}]); "
            f"failure probability {self.failure_probability:.3g}, CoV {self.cov:.3g}",
            f"  share of built machines with all six outputs within their limits at every "
            f"pose; {self.model_text()}",
            f"  {how}; {self.method_reason}",
            f"  first-order bounds (linearised model, union bound and best single row): "
            f"{yield_text(self.first_order_lower)} ≤ yield ≤ "
            f"{yield_text(self.first_order_upper)}"]
        if len(self.failure_shares):
            shares = self.failure_shares.head(SHOWN_SHARES).copy()
            for column in ("share", "lower", "upper"):
                shares[column] = (100 * shares[column]).map("{:.1f}".format)
            shares = shares.rename(columns={"share": "share [%]", "lower": f"{level} low",
                                            "upper": f"{level} high"})
            lines += ["  what fails first in failing machines (largest |y|/I over the grid):",
                      _indent(shares.to_string(index=False))]
            rest = self.failure_shares.iloc[SHOWN_SHARES:]
            if len(rest):
                lines.append(f"    and {len(rest)} more regions holding "
                             f"{100 * rest['share'].sum():.1f} % of the failures")
        return "\n".join(lines)

    def __repr__(self) -> str:
        return f"YieldEstimate:\n{self.summary()}"

    def to_dict(self) -> dict:
        """Plain JSON-ready values (the shares as a list of rows)."""
        return {
            "estimate": self.estimate, "lower": self.lower, "upper": self.upper,
            "confidence": self.confidence, "cov": None if math.isnan(self.cov) else self.cov,
            "machines": self.machines, "machine_evaluations": self.machine_evaluations,
            "method": self.method,
            "method_reason": self.method_reason, "profile": self.profile,
            "distribution": self.distribution, "workspace": self.workspace,
            "n_poses": self.n_poses, "failures": self.failures,
            "first_order_lower": self.first_order_lower,
            "first_order_upper": self.first_order_upper, "target_cov": self.target_cov,
            "failure_shares": self.failure_shares.to_dict(orient="records")}


class YieldModel:
    """What a machine yield depends on besides the tolerances, built once.

    Parameters
    ----------
    machine : Machine
    profile : str, profile model or mapping, optional
        The error-profile model (:func:`reliability.model.profiles.axis_profiles`);
        ``machine.profile`` by default.
    distribution : {'normal', 'truncated'}, optional
        The reading of a tolerance; ``machine.distribution`` by default.
    points_per_axis : int
        Grid points per axis (5: the 15 625-pose grid of Sec. 5.3 on six axes).
    k : float
        Coverage factor, t = ±kσ.
    memory : int, optional
        Bytes of temporary arrays per batch of machines
        (:data:`reliability.basics.chunks.MEMORY_BUDGET` by default).
    executor : distributed.Client, optional
        Evaluate the batches of machines of :meth:`output_ratios` and :meth:`ratios_at` as
        tasks of this Dask client (:mod:`reliability.sampling.machine_blocks`: the same
        batches and the same bytes as without it); None evaluates them here.
    """

    def __init__(self, machine, *, profile=None, distribution=None, points_per_axis: int = 5,
                 k: float = 3.0, memory: int | None = None, executor=None):
        distribution = machine.distribution if distribution is None else distribution
        self.k = check_reading(distribution, k)
        profile = machine.profile if profile is None else profile
        self.profiles = axis_profiles(machine, profile)
        self.machine = machine
        self.distribution = distribution
        self.experiment = GridExperiment(machine, points_per_axis, profile)
        self.memory = memory
        self.blocks = MachineBlocks(executor)
        self._last_block = None
        kept = deciding_points(machine, self.profiles, self.experiment.points_per_axis)
        self._deciding = self.experiment if kept is None else GridExperiment(
            machine, points_per_axis, profile, kept_points=kept)
        # each evaluated pose's index into experiment.poses (the whole grid when kept)
        self._deciding_rows = np.arange(self.experiment.n_poses) if kept is None \
            else self._deciding.full_grid_rows()
        self.batch = chunk_size(4 * 6 * 8 * self._deciding.n_grid, memory)
        n, points = len(machine.axis_specs), self.experiment.points_per_axis
        self._travel = travel_factors(machine, self.profiles, self.experiment.points)
        if machine.correlation is None:
            self._items = np.broadcast_to(np.eye(6), (n, 6, 6))
            self._assembly = np.eye(6 * (n - 1))
        else:
            self._items, self._assembly = grid_factors(machine)
        self._motion_size = n * points * 6
        self.dimension = self._motion_size + 6 * (n - 1)
        self._grid_index = np.stack(np.unravel_index(
            self.experiment.pose_rows(), (points,) * n), axis=-1)

    # ----- descriptions -------------------------------------------------------------
    @property
    def profile(self) -> str:
        """The profile's name (one model for every axis), else ``axis=model`` pairs."""
        names = [str(p) for p in self.profiles]
        if len(set(names)) == 1:
            return names[0]
        return ", ".join(f"{axis}={name}" for axis, name in zip(self.machine.axes, names))

    @property
    def workspace(self) -> str:
        """E.g. ``'5-point grid (15 625 poses)'``, or with a work zone
        ``'5-point grid, 105 of its 3 125 poses in the work zone'``."""
        count, whole = (f"{n:,}".replace(",", " ") for n in (self.experiment.n_poses,
                                                               self.experiment.n_grid))
        if self.machine.work_zone is None:
            return f"{self.experiment.points_per_axis}-point grid ({count} poses)"
        return (f"{self.experiment.points_per_axis}-point grid, {count} of its {whole} poses "
                f"in the work zone")

    # ----- the machine as drawn -----------------------------------------------------
    def errors(self, u, tolerances):
        """Motion ``(R, n, P, 6)`` and assembly ``(R, n − 1, 6)`` errors of standard
        normal draws ``u (R, dimension)``: correlated by the profile (and the machine's
        item correlation), then mapped to each error's marginal."""
        n, points = len(self.machine.axis_specs), self.experiment.points_per_axis
        motion_u = u[:, :self._motion_size].reshape(-1, n, points, 6)
        z_motion = np.einsum("apq,aij,Raqj->Rapi", self._travel, self._items, motion_u,
                             optimize=True)
        z_assembly = u[:, self._motion_size:] @ self._assembly.T
        scale = tolerances / self.k
        motion = normal_to_marginal(z_motion, self.k, self.distribution) \
            * scale[:6 * n].reshape(n, 1, 6)
        assembly = normal_to_marginal(z_assembly, self.k, self.distribution) * scale[6 * n:]
        return motion, assembly.reshape(-1, n - 1, 6)

    def draws(self, machines: int, rng=None) -> np.ndarray:
        """The standard normal draws ``u`` of ``machines`` built machines,
        ``(machines, dimension)``, from ``rng`` (through
        :func:`reliability.basics.streams.generator`).

        Evaluating several allocations on the same draws gives common random numbers: two
        allocations then differ only through their tolerances (every error is ``(t_i/k)``
        times a function of ``u``, :meth:`errors`).
        """
        machines = checks.positive_int(machines, "machines")
        return streams.generator(rng).standard_normal((machines, self.dimension))

    def output_ratios(self, u, tolerances, *, with_poses: bool = False):
        """Each built machine's worst ratio per output: ``max over grid poses |y_o|/I_o``
        of the exact chain (Eq. 18) for draws ``u (R, dimension)``.

        Output ``o`` of a machine holds its limit at every pose (Eq. 19 everywhere) when its
        ratio is below 1, and the machine passes when all six are. This is the one
        evaluation of built machines behind the yield: :meth:`worst_ratios`,
        :meth:`worst_rows` and :meth:`estimate` derive from it, and so do both stages of
        :func:`allocation.allocate_for_yield`.

        Parameters
        ----------
        u : ndarray (R, dimension)
            Standard normal draws (:meth:`draws`, or importance-sampling draws).
        tolerances : ndarray (n_errors,)
            The allocation, read as ±kσ under the model's reading.
        with_poses : bool
            Also return, per machine and output, the grid pose (index into
            ``experiment.poses``) where the ratio is reached (the first such pose).

        Returns
        -------
        ratios : ndarray (R, 6)
        poses : ndarray (R, 6) of int
            Only with ``with_poses``.

        Notes
        -----
        Machines are evaluated in batches of :attr:`batch` (temporary arrays within the
        model's memory budget), here or on the model's Dask client, with the same bytes;
        nothing loops over machines or poses in Python. Only the grid poses that can hold a
        maximum are evaluated (:func:`deciding_points`).
        """
        u = np.asarray(u, dtype=float)
        blocks = [slice(start, min(start + self.batch, len(u)))
                  for start in range(0, len(u), self.batch)]
        parts = self.blocks.map(YieldModel._output_block, self, u, blocks,
                                (tolerances, with_poses))
        self._last_block = None
        ratios = _joined([ratios for ratios, _ in parts], (0, len(OUTPUTS)), float)
        if not with_poses:
            return ratios
        return ratios, _joined([where for _, where in parts], (0, len(OUTPUTS)), np.intp)

    @property
    def deciding_poses(self) -> np.ndarray:
        """``(poses, n_axes)`` the grid poses the model evaluates: those at which a built
        machine's largest ratio can be reached (:func:`deciding_points`), else every grid
        pose (inside the work zone, when the machine has one)."""
        return self._deciding.poses

    def _output_block(self, u, tolerances, with_poses):
        """:meth:`output_ratios` of one block of machines (``where`` is None without
        ``with_poses``).

        Its largest array is kept until the next block has been evaluated: freed at every
        block, the allocator hands that memory back to the system and faults it in again
        for the next block, about a third slower over the whole grid."""
        values = self._deciding.evaluate(*self.errors(u, tolerances))
        self._last_block = values
        rows = np.abs(values, out=values)
        rows /= self.machine.limits  # (batch, deciding poses, 6)
        if not with_poses:
            return _largest_over_poses(rows), None
        by_output = np.ascontiguousarray(rows.transpose(0, 2, 1))  # reduced along memory
        where = np.argmax(by_output, axis=2)
        ratios = np.take_along_axis(by_output, where[..., None], axis=2)[..., 0]
        return ratios, self._deciding_rows[where]

    def ratios_at(self, u, tolerances, poses):
        """Each built machine's worst ratio per output over its own grid poses: ``max over
        poses[m] |y_o|/I_o`` of the exact chain (Eq. 18, each pose evaluated on its own)
        for draws ``u (R, dimension)``.

        The same chain and errors as :meth:`output_ratios` on a subset of the grid, so each
        ratio is at most the full grid's, and equal to it (to rounding) when ``poses[m]``
        holds the pose where the full grid reaches it.

        Parameters
        ----------
        u : ndarray (R, dimension)
        tolerances : ndarray (n_errors,)
        poses : ndarray (R, W) of int
            Grid pose indices (into ``experiment.poses``) of each machine; a negative entry
            is no pose (a machine may have fewer than ``W``).

        Returns
        -------
        ratios : ndarray (R, 6)
            0 where a machine has no pose.
        where : ndarray (R, 6) of int
            The pose (grid index) of each ratio, the first of ``poses[m]`` on a tie; -1
            where a machine has no pose.
        """
        u = np.asarray(u, dtype=float)
        poses = np.asarray(poses, dtype=np.intp)
        distinct = np.unique(poses[poses >= 0])
        chain = _PoseChains(self.machine, self.experiment.poses[distinct])
        blocks = chunks(len(u), 4 * 8 * 36 * poses.shape[1] * len(chain.adjoints),
                        self.memory)
        parts = self.blocks.map(YieldModel._ratios_block, self, u, blocks,
                                (tolerances, chain, distinct), (poses,))
        return (_joined([ratios for ratios, _ in parts], (0, len(OUTPUTS)), float),
                _joined([where for _, where in parts], (0, len(OUTPUTS)), np.intp))

    def _ratios_block(self, u, tolerances, chain, distinct, poses):
        """:meth:`ratios_at` of one block of machines, with the chain at the ``distinct``
        poses of all of them."""
        ratios = np.zeros((len(u), len(OUTPUTS)))
        where = np.full((len(u), len(OUTPUTS)), -1, dtype=np.intp)
        machine, column = np.nonzero(poses >= 0)  # pairs, machine by machine
        if len(machine) == 0:
            return ratios, where
        pose = poses[machine, column]
        motion, assembly = self.errors(u, tolerances)
        x = self._pair_errors(motion, assembly, machine, self._grid_index[pose])
        rows = np.abs(chain.evaluate(np.searchsorted(distinct, pose), x))
        rows /= self.machine.limits  # (pairs, 6)
        first = np.flatnonzero(np.diff(machine, prepend=-1))  # each machine's first pair
        owner = machine[first]
        ratios[owner] = np.maximum.reduceat(rows, first, axis=0)
        attained = rows == ratios[machine]
        pair = np.where(attained, np.arange(len(pose))[:, None], len(pose))
        where[owner] = pose[np.minimum.reduceat(pair, first, axis=0)]
        return ratios, where

    @staticmethod
    def _pair_errors(motion, assembly, machine, index) -> np.ndarray:
        """``(pairs, n_errors)`` error vectors of (machine, pose) pairs: every axis' motion
        errors at the pose's grid point ``index (pairs, n)``, then the assembly errors."""
        n = index.shape[1]
        at_pose = [motion[machine, a, index[:, a]] for a in range(n)]  # (pairs, 6) each
        return np.concatenate(at_pose + [assembly[machine].reshape(len(machine), -1)],
                              axis=-1)

    def worst_rows(self, u, tolerances):
        """For each draw: whether the machine fails (``|y| ≥ I`` at some pose and output,
        the complement of Eq. 19 everywhere) and its worst row ``pose · 6 + output``
        (largest ``|y|/I``)."""
        ratio, worst = self.worst_ratios(u, tolerances)
        return ratio >= 1.0, worst

    def worst_ratios(self, u, tolerances):
        """For each draw ``u (R, dimension)``: the largest ``|y|/I`` over every pose and
        output of the exact chain (the machine passes when it is below 1) and its row
        ``pose · 6 + output``; the largest of :meth:`output_ratios` (on a tie, the row
        that comes first)."""
        return _worst_of(*self.output_ratios(u, tolerances, with_poses=True))

    def worst_ratios_at(self, u, tolerances, poses):
        """:meth:`worst_ratios` over each machine's own grid poses ``poses (R, W)``
        (:meth:`ratios_at`)."""
        return _worst_of(*self.ratios_at(u, tolerances, poses))

    def row_contributions(self, u, tolerances, rows) -> np.ndarray:
        """``(R, n_errors)``: each error's term ``J_ri x_i`` of the linearised output of
        row ``rows[m]`` (``pose · 6 + output``) of draw ``u[m]``, with ``x_i`` the error's
        value at that pose's grid points (Eq. 18 to first order; the terms sum to the
        linearised output)."""
        motion, assembly = self.errors(u, tolerances)
        pose, output = np.divmod(np.asarray(rows), len(OUTPUTS))
        n = len(self.machine.axis_specs)
        index = self._grid_index[pose]  # (R, n)
        at_pose = motion[np.arange(len(u))[:, None], np.arange(n), index]  # (R, n, 6)
        x = np.concatenate([at_pose.reshape(len(u), -1), assembly.reshape(len(u), -1)],
                           axis=1)
        distinct, where = np.unique(pose, return_inverse=True)
        jacobian = self.machine.jacobian(self.experiment.poses[distinct])[where.ravel()]
        return jacobian[np.arange(len(u)), output] * x

    # ----- the linearised model -----------------------------------------------------
    def row_sigma(self, tolerances) -> np.ndarray:
        """FOSM σ (Eq. 20) of every output at every grid pose under the reading,
        ``(n_poses, 6)``."""
        spread = error_sigma(tolerances, self.k, self.distribution)
        return pose_sigma(self.machine, self.experiment.poses, spread, memory=self.memory)

    def slope_spread(self, tolerances) -> np.ndarray:
        """``∂x/∂z`` at ``z = 0`` of each error: ``t/k`` for the normal reading and
        ``(t/k)(1 − 2Φ(−k))`` for the truncated one (the slope of its copula map at 0, a
        closer linearisation in ``u`` than the truncated σ, ``0.9866 t/k``)."""
        slope = 1.0 if self.distribution == "normal" else 1.0 - 2.0 * float(ndtr(-self.k))
        return np.asarray(tolerances, dtype=float) / self.k * slope

    def event_sigma(self, tolerances) -> np.ndarray:
        """``|a_r|`` of every row, ``(n_poses, 6)``: Eq. (20) with :meth:`slope_spread`
        (FOSM's σ under the normal reading)."""
        return pose_sigma(self.machine, self.experiment.poses,
                          self.slope_spread(tolerances), memory=self.memory)

    def row_vectors(self, rows, tolerances) -> np.ndarray:
        """``a_r`` of rows ``pose · 6 + output``: the linearised output in ``u`` (the
        Jacobian times :meth:`slope_spread` times the profile's factor),
        ``(len(rows), dimension)``, with ``|a_r|`` from :meth:`event_sigma` (in chunks of
        rows)."""
        rows = np.asarray(rows)
        spread = self.slope_spread(tolerances)
        out = np.empty((len(rows), self.dimension))
        for part in chunks(len(rows), jacobian_bytes(self.machine), self.memory):
            out[part] = self._row_vectors(rows[part], spread)
        return out

    def row_signatures(self, rows, tolerances) -> np.ndarray:
        """``(len(rows), 3)``: the projections of ``a_r/I_r`` on three fixed directions,
        rounded to 1e-10; rows with the same event ``{|a_r·u| ≥ I_r}`` have the same
        signature (in chunks of rows)."""
        rows = np.asarray(rows)
        spread = self.slope_spread(tolerances)
        limits = np.tile(self.machine.limits, self.experiment.n_poses)
        index = np.arange(self.dimension)[:, None] * np.array([0.7, 1.3, 2.9])
        directions = np.cos(index + np.array([0.0, 1.0, 2.0]))  # fixed, not random
        out = np.empty((len(rows), 3))
        for part in chunks(len(rows), jacobian_bytes(self.machine), self.memory):
            scaled = self._row_vectors(rows[part], spread) / limits[rows[part], None]
            out[part] = np.round(scaled @ directions, 10)
        return out

    def _row_vectors(self, rows, spread) -> np.ndarray:
        pose, output = np.divmod(rows, len(OUTPUTS))
        n = len(self.machine.axis_specs)
        distinct, where = np.unique(pose, return_inverse=True)  # one Jacobian per pose
        jacobian = self.machine.jacobian(self.experiment.poses[distinct])[where.ravel()]
        c = jacobian[np.arange(len(rows)), output] * spread
        travel = self._travel[np.arange(n), self._grid_index[pose]]  # (rows, n, P)
        motion = np.einsum("Kac,Kaq,acj->Kaqj", c[:, :6 * n].reshape(-1, n, 6), travel,
                           self._items, optimize=True)
        assembly = c[:, 6 * n:] @ self._assembly
        return np.concatenate([motion.reshape(len(rows), -1), assembly], axis=1)

    def first_order_bounds(self, tolerances) -> tuple[float, float]:
        """Bounds on the yield of the linearised model: ``1 − Σ_rows p_r`` (floored at 0)
        and ``min_rows (1 − p_r)``, ``p_r = 2Φ(−I/σ_r)``."""
        t = checks.one_allocation(self.machine, tolerances)
        failure = two_sided_failure(self.machine.limits, self.row_sigma(t))
        return _bounds_from_rows(failure)

    def linear_failure(self, tolerances, rng=None) -> float:
        """The linearised model's failure probability (all rows at once), estimated without
        the chain by ALOE (``P_S · mean 1/N_S`` over :data:`LINEAR_SAMPLES` draws of the
        pure mixture) plus the ``p_r`` of the rows left out of ``S`` (an upper estimate
        for them)."""
        t = checks.one_allocation(self.machine, tolerances)
        events = RowEvents.dominant(self, t)
        return min(1.0, events.linear_failure(streams.generator(rng)) + events.left_out)

    # ----- the estimate -------------------------------------------------------------
    def estimate(self, tolerances, *, machines: int = DEFAULT_MACHINES, rng=None,
                 method: str = "auto", confidence: float = 0.95,
                 target_cov: float = 0.1) -> YieldEstimate:
        """The machine yield of ``tolerances`` (see :func:`machine_yield`)."""
        t = checks.one_allocation(self.machine, tolerances)
        machines = checks.positive_int(machines, "machines")
        checks.choice(method, "method", METHODS)
        confidence = checks.finite_float(confidence, "confidence", 0.0, 1.0, low_open=True,
                                         high_open=True)
        target_cov = checks.finite_float(target_cov, "target_cov", 0.0, low_open=True)
        pilot_rng, main_rng = streams.spawn(rng, 2)
        sigma = self.row_sigma(t)
        failure = two_sided_failure(self.machine.limits, sigma).ravel()
        lower, upper = _bounds_from_rows(failure)
        method, reason, events = self._choose(method, machines, t, failure, pilot_rng)
        sampled = self._sample(t, machines, main_rng, events, target_cov)
        return sampled.result(self, sigma, confidence, method, reason, lower, upper,
                              None if method == "crude" else target_cov)

    def _choose(self, method, machines, t, failure, rng):
        """The method, why, and the proposal's events (None for crude sampling)."""
        if method == "crude":
            return method, "method 'crude' asked for", None
        if method == "importance":
            events = RowEvents.dominant(self, t)
            return method, "method 'importance' asked for", events
        if machines * failure.max() >= MIN_FAILURES:
            return "crude", (f"the worst row alone gives {machines * failure.max():,.0f} "
                             f"expected failing machines ≥ {MIN_FAILURES}"), None
        events = RowEvents.dominant(self, t)
        if events.size == 0:
            return "crude", "no row of the linearised model can fail in double precision", None
        expected = machines * min(1.0, events.linear_failure(rng) + events.left_out)
        if expected >= MIN_FAILURES:
            return "crude", (f"{expected:,.0f} expected failing machines (linearised model) "
                             f"≥ {MIN_FAILURES}"), None
        return "importance", (f"crude sampling of {machines:,} machines would expect "
                              f"{expected:.3g} failing (linearised model) < "
                              f"{MIN_FAILURES}"), events

    def _sample(self, t, machines, rng, events, target_cov) -> "_Samples":
        samples = _Samples()
        batch = self.batch if events is None else min(self.batch, IMPORTANCE_BATCH)
        while samples.n < machines:
            size = min(batch, machines - samples.n)
            if events is None:
                u, weight = rng.standard_normal((size, self.dimension)), np.ones(size)
            else:
                u = events.draw(rng, size)
                weight = events.weight(u)
            failed, worst = self.worst_rows(u, t)
            samples.add(failed, worst, weight)
            if events is not None and samples.n >= MIN_IMPORTANCE_MACHINES \
                    and samples.cov() <= target_cov:
                break
        return samples

    # ----- failure regions ----------------------------------------------------------
    def deciding_axes(self, sigma) -> np.ndarray:
        """``(6, n_axes)`` bool: for each output, the (at most :data:`MAX_REGION_AXES`)
        axes along which its mean σ² over the grid changes most, by more than
        :data:`REGION_SPREAD`."""
        n = len(self.machine.axis_specs)
        variance = np.square(sigma)
        spread = np.zeros((len(OUTPUTS), n))
        for a in range(n):
            profile = self._mean_along(a, variance)  # (points of axis a in use, 6)
            with np.errstate(divide="ignore", invalid="ignore"):
                spread[:, a] = np.where(profile.min(axis=0) > 0,
                                        profile.max(axis=0) / profile.min(axis=0) - 1.0, 0.0)
        rank = np.argsort(np.argsort(-spread, axis=1, kind="stable"), axis=1, kind="stable")
        return (spread > REGION_SPREAD) & (rank < MAX_REGION_AXES)

    def _mean_along(self, a: int, values) -> np.ndarray:
        """Mean of per-pose ``values (n_poses, 6)`` at each grid point of axis ``a`` that
        some pose uses, ``(used points, 6)``."""
        points = self.experiment.points_per_axis
        index = self._grid_index[:, a]
        counts = np.bincount(index, minlength=points)
        sums = np.stack([np.bincount(index, weights=column, minlength=points)
                         for column in values.T], axis=-1)
        used = counts > 0
        return sums[used] / counts[used, None]

    def region_texts(self, rows, deciding) -> list[str]:
        """The worst pose of each row as its stroke thirds along the deciding axes; for an
        output no axis decides, the axis positions all its rows' worst poses share."""
        pose, output = np.divmod(np.asarray(rows), len(OUTPUTS))
        position = self.experiment.poses[pose]
        shared = {o: self._shared_text(position[output == o])
                  for o in np.unique(output) if not deciding[o].any()}
        return [shared[o] if o in shared else
                ", ".join(self._third_text(a, q[a]) for a in np.flatnonzero(deciding[o]))
                for q, o in zip(position, output)]

    def _shared_text(self, positions) -> str:
        """What a set of grid poses shares, e.g. ``48 poses, all with Y = ±300 mm,
        Z = 0 or 500 mm (C, X any)``."""
        poses = np.unique(positions, axis=0)
        shared, free = [], []
        for a, axis in enumerate(self.machine.axis_specs):
            values = np.unique(poses[:, a])
            if len(values) == len(self.experiment.points[a]):
                free.append(axis.name)
                continue
            unit = "deg" if axis.kind == "rotary" else "mm"
            shown = np.degrees(values) if axis.kind == "rotary" else values
            words = (f"±{shown[1]:.4g}" if len(shown) == 2 and np.isclose(shown[0], -shown[1])
                     else " or ".join(f"{v:.4g}" for v in shown))
            shared.append(f"{axis.name} = {words} {unit}")
        if not shared:
            return f"{len(poses)} poses sharing no axis position"
        rest = f" ({', '.join(free)} any)" if free else ""
        return f"{len(poses)} pose{'s' if len(poses) > 1 else ''}, all with " \
               f"{', '.join(shared)}{rest}"

    def _third_text(self, a, position) -> str:
        axis = self.machine.axis_specs[a]
        low, high = axis.stroke
        third = min(2, int(3 * (position - low) / (high - low)))
        edges = low + (high - low) * np.array([third, third + 1]) / 3
        if axis.kind == "rotary":
            edges, unit = np.degrees(edges), "deg"
        else:
            unit = "mm"
        return f"{axis.name} {THIRDS[third]} ({edges[0]:.4g} to {edges[1]:.4g} {unit})"


def machine_yield(machine, tolerances, *, profile=None, distribution=None,
                  points_per_axis: int = 5, machines: int = DEFAULT_MACHINES, rng=None,
                  method: str = "auto", confidence: float = 0.95, k: float = 3.0,
                  target_cov: float = 0.1, memory: int | None = None) -> YieldEstimate:
    """The probability that one built machine keeps all six outputs within their limits at
    every pose of the workspace grid.

    Parameters
    ----------
    machine : Machine
    tolerances : array_like
        ``(n_errors,)`` allocation, read as ±kσ.
    profile : str, profile model or mapping, optional
        ``'constant'``, ``'independent'``, ``'gp:<length mm>'``; ``machine.profile`` by
        default.
    distribution : {'normal', 'truncated'}, optional
        The reading of a tolerance; ``machine.distribution`` by default.
    points_per_axis : int
        Grid points per axis (5 in the paper: 15 625 poses on six axes).
    machines : int
        Built machines simulated (crude), or at most (importance sampling).
    rng : None, int or numpy.random.Generator
        Split by :func:`reliability.basics.streams.spawn` into the stream of the ``auto`` decision
        and the stream of the machines.
    method : {'auto', 'crude', 'importance'}
        See the module's docstring; ``auto`` samples crudely unless fewer than
        :data:`MIN_FAILURES` failing machines are expected.
    confidence : float
        Level of the interval.
    k : float
        Coverage factor.
    target_cov : float
        Importance sampling stops once the failure probability's CoV is at most this.
    memory : int, optional
        Bytes of temporary arrays per batch of machines.

    Returns
    -------
    YieldEstimate
    """
    model = YieldModel(machine, profile=profile, distribution=distribution,
                       points_per_axis=points_per_axis, k=k, memory=memory)
    return model.estimate(tolerances, machines=machines, rng=rng, method=method,
                          confidence=confidence, target_cov=target_cov)


def deciding_points(machine, profiles, points: int) -> list[np.ndarray] | None:
    """Per axis, the grid points at which a machine's largest ``|y_o|/I_o`` over the grid
    can be reached: the two ends of the stroke on a linear axis whose errors are constant
    along its travel, every point on the others; None when that is every point.

    Why. Hold the errors fixed (a built machine under a constant profile on that axis: none
    of the machine's errors then changes along it) and move one linear axis, every other
    axis fixed. The axis enters the chain as one translation ``Trans(q d)``, so the actual
    and the ideal tool poses are ``A Trans(q d) C`` with ``A``, ``C`` free of ``q``: their
    positions are affine in ``q`` and their orientations do not depend on it. The exact
    deviation (Eq. 18; its translation is the ideal orientation's transpose times the
    difference of the positions, its rotation ``R_idealᵀ R_actual``) is therefore affine in
    ``q``, in the workpiece frame as well (the ideal orientation does not change along a
    linear axis). ``|y_o|`` is then convex in ``q``, and its largest value over points
    ``q_1 < … < q_P`` of the line is at ``q_1`` or ``q_P``; on a tie the first in grid order
    is ``q_1``. So the largest ratio over the whole grid, and the first pose reaching it,
    are those over the grid of kept points (to rounding). Not with a work zone (its lines
    are cut by the zone).
    """
    if machine.work_zone is not None or points <= 2:
        return None
    kept = [np.array([0, points - 1]) if spec.kind == "linear"
            and isinstance(profile, ConstantProfile) else np.arange(points)
            for spec, profile in zip(machine.axis_specs, profiles)]
    return None if all(len(k) == points for k in kept) else kept


def _largest_over_poses(rows) -> np.ndarray:
    """``rows.max(axis=1)`` of ``(batch, n_poses, 6)``, by halving the poses in place: each
    step takes the larger of two contiguous blocks, which runs at memory speed where a
    reduction along the middle axis does not (``rows`` is overwritten)."""
    count = rows.shape[1]
    while count > 1:
        half = count // 2
        np.maximum(rows[:, :half], rows[:, count - half:count], out=rows[:, :half])
        count -= half
    return rows[:, 0].copy()


def _joined(parts, empty_shape, dtype) -> np.ndarray:
    """The blocks' arrays one after the other (an empty array of ``empty_shape`` for no
    block)."""
    return np.concatenate(parts) if parts else np.empty(empty_shape, dtype=dtype)


def _worst_of(ratios, poses):
    """The largest of each machine's output ratios and its row ``pose · 6 + output`` (on a
    tie, the row that comes first)."""
    ratio = ratios.max(axis=1)
    rows = poses * len(OUTPUTS) + np.arange(len(OUTPUTS))
    worst = np.where(ratios == ratio[:, None], rows, np.iinfo(np.intp).max).min(axis=1)
    return ratio, worst


class _PoseChains:
    """The exact chain at a set of poses, with each pose's transports computed once, for
    error vectors given per (machine, pose)."""

    def __init__(self, machine, positions):
        factors, self.blocks = chain_factors(machine, positions)
        self.adjoints = transports(factors)  # per gap: (n_poses, 6, 6)
        self.rotation = ideal_rotation(machine, positions) \
            if machine.frame == "workpiece" else None

    def evaluate(self, pose, x) -> np.ndarray:
        """Outputs ``(R, W, 6)`` for errors ``x (R, W, n_errors)`` at poses ``pose (R, W)``
        (indices into the positions)."""
        twists = [x[..., 6 * b: 6 * b + 6] for b in self.blocks]
        deviation = deviation_from_transports([adjoint[pose] for adjoint in self.adjoints],
                                              twists)
        out = read_pose_error(deviation)
        return out if self.rotation is None else vectors_in_frame(out, self.rotation[pose])


# ----- the importance proposal ------------------------------------------------------------
class RowEvents:
    """The dominant linearised row events ``S = {|a_r·u| ≥ I_r}`` and the ALOE mixture
    over them (:meth:`draw`, :meth:`weight`); built by :meth:`dominant`."""

    def __init__(self, vectors, thresholds, probabilities, left_out):
        self.vectors = vectors  # (K, D) a_r
        self.norms = np.linalg.norm(vectors, axis=1)
        self.thresholds = thresholds  # (K,) I_r
        self.probabilities = probabilities  # (K,) p_r
        self.total = float(probabilities.sum())  # P_S
        self.left_out = left_out  # Σ p_r over rows not in S

    @property
    def size(self) -> int:
        return len(self.thresholds)

    @classmethod
    def dominant(cls, model, tolerances):
        """The distinct row events (rows with the same event, e.g. poses that differ only
        along an axis the output does not depend on under the ``constant`` profile, count
        once: :meth:`YieldModel.row_signatures`), the fewest by decreasing ``p_r`` holding
        :data:`EVENT_MASS` of their ``Σ p_r``, at most :data:`MAX_EVENTS`, without rows
        whose ``p_r = 2Φ(−I_r/|a_r|)`` is 0 in double precision. Any subset keeps the
        weights exact; a larger one makes them more efficient."""
        limits = np.tile(model.machine.limits, model.experiment.n_poses)
        failure = two_sided_failure(limits, model.event_sigma(tolerances).ravel())
        candidates = np.flatnonzero(failure > 0)
        if len(candidates) == 0:
            return cls(np.zeros((0, model.dimension)), np.zeros(0), np.zeros(0), 0.0)
        _, first = np.unique(model.row_signatures(candidates, tolerances), axis=0,
                             return_index=True)
        distinct = candidates[np.sort(first)]
        distinct = distinct[np.argsort(-failure[distinct], kind="stable")]
        cumulative = np.cumsum(failure[distinct])
        total = cumulative[-1]
        count = min(MAX_EVENTS, int(np.searchsorted(cumulative, EVENT_MASS * total)) + 1)
        rows = distinct[:count]
        return cls(model.row_vectors(rows, tolerances), limits[rows], failure[rows],
                   float(total - cumulative[count - 1]))

    def counts(self, u) -> np.ndarray:
        """``N_S(u)``: the events of ``S`` that contain each draw (in chunks of draws)."""
        out = np.empty(len(u), dtype=np.int64)
        for part in chunks(len(u), 2 * 8 * self.size):
            out[part] = np.count_nonzero(np.abs(u[part] @ self.vectors.T) >= self.thresholds,
                                         axis=1)
        return out

    def weight(self, u) -> np.ndarray:
        """``w(u) = 1/(α + (1 − α) N_S(u)/P_S)``, the exact ``φ/q`` (1 without events:
        the proposal is then ``φ``)."""
        if self.size == 0:
            return np.ones(len(u))
        return 1.0 / (DEFENSIVE + (1.0 - DEFENSIVE) * self.counts(u) / self.total)

    def draw(self, rng, size, defensive: float = DEFENSIVE) -> np.ndarray:
        """``size`` draws of the mixture: plain normals with probability ``defensive``,
        else ``φ`` conditioned on one event chosen with probability ``p_r/P_S``."""
        u = rng.standard_normal((size, self.vectors.shape[1]))
        if self.size == 0:
            return u
        conditioned = np.flatnonzero(rng.random(size) >= defensive)
        row = rng.choice(self.size, size=len(conditioned), p=self.probabilities / self.total)
        direction = self.vectors[row] / self.norms[row, None]
        beta = self.thresholds[row] / self.norms[row]
        tail = -ndtri(rng.random(len(conditioned)) * ndtr(-beta))  # beyond β, exactly
        sign = np.where(rng.random(len(conditioned)) < 0.5, -1.0, 1.0)
        along = np.einsum("kd,kd->k", u[conditioned], direction)
        u[conditioned] += (sign * tail - along)[:, None] * direction
        return u

    def linear_failure(self, rng) -> float:
        """ALOE's estimate of ``P(∪_S F_r)`` for the linearised model, without the chain:
        ``P_S · mean(1/N_S)`` over draws of the pure mixture."""
        if self.size == 0:
            return 0.0
        counts = self.counts(self.draw(rng, LINEAR_SAMPLES, defensive=0.0))
        return self.total * float(np.mean(1.0 / np.maximum(counts, 1)))


class _Samples:
    """Running sums of the weighted failure indicator and the failing machines' worst rows."""

    def __init__(self):
        self.n = 0
        self.total = 0.0
        self.squares = 0.0
        self.rows, self.weights = [], []

    def add(self, failed, worst, weight):
        terms = weight * failed
        self.n += len(failed)
        self.total += float(terms.sum())
        self.squares += float(np.square(terms).sum())
        self.rows.append(worst[failed])
        self.weights.append(weight[failed])

    def mean(self) -> float:
        return self.total / self.n

    def standard_error(self) -> float:
        mean = self.mean()
        variance = max(self.squares / self.n - mean ** 2, 0.0) * self.n / max(self.n - 1, 1)
        return math.sqrt(variance / self.n)

    def cov(self) -> float:
        mean = self.mean()
        return self.standard_error() / mean if mean > 0 else math.inf

    def result(self, model, sigma, confidence, method, reason, lower, upper, target_cov):
        rows, weights = np.concatenate(self.rows), np.concatenate(self.weights)
        if method == "crude":
            passed = self.n - len(rows)
            interval = all_within_share(passed, confidence, trials=self.n)
            estimate, low, high = float(interval.estimate), float(interval.lower), \
                float(interval.upper)
            p = 1.0 - estimate
            cov = math.sqrt((1.0 - p) / (self.n * p)) if p > 0 else math.nan
        else:
            p, se = self.mean(), self.standard_error()
            z = norm.ppf(0.5 + confidence / 2)
            estimate, low, high = 1.0 - p, 1.0 - min(1.0, p + z * se), 1.0 - max(0.0, p - z * se)
            cov = se / p if p > 0 else math.nan
        shares = _failure_shares(model, sigma, rows, weights, confidence)
        return YieldEstimate(
            estimate=estimate, lower=low, upper=high, confidence=confidence, cov=cov,
            machines=self.n, method=method, method_reason=reason, profile=model.profile,
            distribution=model.distribution, workspace=model.workspace,
            n_poses=model.experiment.n_poses, failures=len(rows), first_order_lower=lower,
            first_order_upper=upper, failure_shares=shares, target_cov=target_cov)


def _failure_shares(model, sigma, rows, weights, confidence) -> pd.DataFrame:
    """Weighted shares of (output, region) among the failing machines' worst rows."""
    if len(rows) == 0:
        return pd.DataFrame(columns=list(SHARE_COLUMNS))
    frame = pd.DataFrame({
        "output": np.asarray(OUTPUTS)[rows % len(OUTPUTS)],
        "region": model.region_texts(rows, model.deciding_axes(sigma)),
        "weight": weights, "square": np.square(weights), "failures": 1})
    groups = frame.groupby(["output", "region"], sort=False).sum().reset_index()
    total, squares = frame["weight"].sum(), frame["square"].sum()
    share = groups["weight"].to_numpy() / total
    effective = total ** 2 / squares  # Kish's effective number of failing machines
    lower, upper = share_interval(share, effective, confidence)
    out = pd.DataFrame({"output": groups["output"], "region": groups["region"],
                        "share": share, "lower": np.asarray(lower, dtype=float),
                        "upper": np.asarray(upper, dtype=float),
                        "failures": groups["failures"].astype(int)})
    return out.sort_values(["share", "output", "region"], ascending=[False, True, True],
                           kind="stable").reset_index(drop=True)


def _bounds_from_rows(failure) -> tuple[float, float]:
    """Union bound and best single row from row failure probabilities."""
    failure = np.asarray(failure, dtype=float).ravel()
    return max(0.0, 1.0 - float(failure.sum())), 1.0 - float(failure.max())


def yield_text(value: float) -> str:
    """A yield readable near 1: ``0.8350`` or ``0.999871`` (never a rounded 1): at least
    four decimals, and two significant digits of the failure probability."""
    failure = 1.0 - value
    if failure <= 0:
        return "1"
    digits = max(4, 1 - int(math.floor(math.log10(failure))))
    return f"{value:.{digits}f}"


def _count_text(value: float) -> str:
    return "?" if not np.isfinite(value) else f"{value:,.0f}"


def _indent(text: str, by: str = "    ") -> str:
    return "\n".join(by + line for line in text.splitlines())
