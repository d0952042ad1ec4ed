"""The machine yield: the share of built machines that hold every limit at every pose.

A built machine is one draw of all its errors (:mod:`reliability.model.profiles` says how an
axis' motion errors hang together along its travel). It *passes* when all six outputs stay
strictly within their limits, ``|y_o| < I_o`` (Eq. 19), at every pose of the workspace
grid (the ``P``-point grid of Sec. 5.3, 15 625 poses for the paper's machine). The machine
yield is the probability that a built machine passes, under a stated error-profile model
and reading of a tolerance.

The API (stable)::

    machine_yield(machine, tolerances, *, profile=None, distribution=None,
                  points=5, machines=DEFAULT_MACHINES, rng=None, method="auto",
                  confidence=0.95, k=3.0, target_cov=0.1, memory=None) -> YieldEstimate

    model = YieldModel(machine, profile=None, distribution=None, points=5, k=3.0,
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
(Eq. 19 at every pose, read by :func:`reliability.basics.pass_rule.passes`).
:meth:`YieldModel.estimate` (``precrel verify``, both allocations of ``precrel report``,
:func:`reliability.sampling.verification.verify`), both stages of
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
* **importance** — the defensive ALOE mixture over the linearised rows' events
  (:mod:`reliability.sampling.row_events`): the estimate of the failure probability is the
  mean of ``w(u) 1[the exact chain fails at some pose]``, unbiased for the *true*
  (non-linear, truncated) failure probability whatever the linearisation's error, because
  ``q > 0`` wherever ``φ > 0`` and the weight ``w = φ/q`` is exact; the linearisation only
  sets the efficiency. Its CoV is the sample standard deviation of those terms over ``√n``
  and the mean; sampling runs in batches until the CoV is at most ``target_cov`` (after at
  least :data:`MIN_IMPORTANCE_MACHINES`) or ``machines`` are spent. The mean is clipped to
  1 and its interval ``p ± z·se`` to [0, 1] (or, without a spread to estimate, bounded
  through the proposal's plain-normal share: :mod:`reliability.sampling.yield_estimate`),
  so the yield and its interval are probabilities whatever the sample.
* **auto** — importance sampling only where failures are rare and crude sampling would
  see few of them: at least :data:`MIN_IMPORTANCE_MACHINES` machines, and the linearised
  model's failure probability below :data:`RARE_FAILURE` and below
  :data:`MIN_FAILURES` failing machines among ``machines``; crude otherwise. That
  probability is the worst row's when it alone decides, else estimated cheaply by ALOE
  without the chain (``P_S · mean 1/N_S`` over 2 000 draws of the mixture, a precision
  that does not depend on ``machines``) plus the rows left out of ``S``.

The first-order bounds on the yield come from the linearised rows
(:mod:`reliability.sampling.linear_rows`), the failure shares from
:mod:`reliability.sampling.failure_regions`; the result and its file are
:mod:`reliability.sampling.yield_estimate`.
"""

from __future__ import annotations

import numpy as np

from ..basics import checks, streams
from ..basics.chunks import chunk_size, chunks
from ..basics.pass_rule import passes
from ..basics.renamed import renamed
from ..basics.ties import TIE_RTOL
from ..first_order.fosm import two_sided_failure
from ..model.error_draws import check_reading, grid_factors, normal_to_marginal
from ..model.kinematics import (chain_factors, deviation_from_transports, ideal_rotation,
                                transports, vectors_in_frame)
from ..model.machine import OUTPUTS
from ..model.profiles import ConstantProfile, axis_profiles, travel_factors
from ..model.transforms import read_pose_error
from .failure_regions import FailureRegions
from .grid_experiment import GridExperiment
from .linear_rows import LinearRows, bounds_from_rows
from .machine_blocks import MachineBlocks
from .row_events import RowEvents
from .yield_estimate import SampleSums, YieldEstimate

#: Built machines simulated when not told otherwise (the command line's ``--machines``).
DEFAULT_MACHINES = 4000
METHODS = ("auto", "crude", "importance")
#: ``auto`` samples crudely only when it expects at least this many failing machines.
MIN_FAILURES = 50
#: Importance sampling stops at the target CoV only after this many machines, and ``auto``
#: uses it only when it may draw that many.
MIN_IMPORTANCE_MACHINES = 1000
#: ``auto`` calls failures rare below this linearised failure probability: fewer than
#: :data:`MIN_FAILURES` failing among :data:`DEFAULT_MACHINES`, whatever the sample size.
RARE_FAILURE = MIN_FAILURES / DEFAULT_MACHINES
#: Machines per importance-sampling batch at most (the CoV is checked between batches).
IMPORTANCE_BATCH = 500


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
    points : int
        Grid points per axis (5: the 15 625-pose grid of Sec. 5.3 on six axes);
        ``points_per_axis=`` is its deprecated spelling (:mod:`reliability.basics.renamed`).
    k : float
        Coverage factor, t = ±kσ.
    memory : int, optional
        Bytes of temporary arrays per batch of machines
        (:data:`reliability.basics.chunks.MEMORY_BUDGET` by default).
    executor : distributed.Client, optional
        Evaluate the batches of machines of :meth:`output_ratios` and :meth:`ratios_at` as
        tasks of this Dask client (:mod:`reliability.sampling.machine_blocks`: the same
        batches and the same bytes as without it); None evaluates them here.

    Attributes
    ----------
    linear : LinearRows
        The grid's rows linearised in the draws: their σ, vectors and the first-order
        bounds (:mod:`reliability.sampling.linear_rows`).
    regions : FailureRegions
        The pose regions of the grid's rows and the failure shares
        (:mod:`reliability.sampling.failure_regions`).
    """

    @renamed("points_per_axis", "points")
    def __init__(self, machine, *, profile=None, distribution=None, points: int = 5,
                 k: float = 3.0, memory: int | None = None, executor=None):
        distribution = machine.distribution if distribution is None else distribution
        self.k = check_reading(distribution, k)
        profile = machine.profile if profile is None else profile
        self.profiles = axis_profiles(machine, profile)
        self.machine = machine
        self.distribution = distribution
        self.experiment = GridExperiment(machine, points, profile)
        self.memory = memory
        self.blocks = MachineBlocks(executor)
        self._last_block = None
        kept = deciding_points(machine, self.profiles, self.experiment.points)
        self._deciding = self.experiment if kept is None else GridExperiment(
            machine, points, profile, kept_points=kept)
        # each evaluated pose's index into experiment.poses (the whole grid when kept)
        self._deciding_rows = np.arange(self.experiment.n_poses) if kept is None \
            else self._deciding.full_grid_rows()
        self.batch = chunk_size(4 * 6 * 8 * self._deciding.n_grid, memory)
        n, points = len(machine.axis_specs), self.experiment.points
        self.travel = travel_factors(machine, self.profiles, self.experiment.axis_points)
        if machine.correlation is None:
            self.item_factors = np.broadcast_to(np.eye(6), (n, 6, 6))
            self.assembly_factor = np.eye(6 * (n - 1))
        else:
            self.item_factors, self.assembly_factor = grid_factors(machine)
        self._motion_size = n * points * 6
        self.dimension = self._motion_size + 6 * (n - 1)
        self.grid_index = np.stack(np.unravel_index(
            self.experiment.pose_rows(), (points,) * n), axis=-1)
        self.linear = LinearRows(self)
        self.regions = FailureRegions(machine, self.experiment, self.grid_index)

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
            return f"{self.experiment.points}-point grid ({count} poses)"
        return (f"{self.experiment.points}-point grid, {count} of its {whole} poses "
                f"in the work zone")

    # ----- the machine as drawn -----------------------------------------------------
    def errors(self, u, tolerances):
        """Motion ``(R, n, P, 6)`` and assembly ``(R, n − 1, 6)`` errors of standard
        normal draws ``u (R, dimension)``: correlated by the profile (and the machine's
        item correlation), then mapped to each error's marginal."""
        n, points = len(self.machine.axis_specs), self.experiment.points
        motion_u = u[:, :self._motion_size].reshape(-1, n, points, 6)
        z_motion = np.einsum("apq,aij,Raqj->Rapi", self.travel, self.item_factors, motion_u,
                             optimize=True)
        z_assembly = u[:, self._motion_size:] @ self.assembly_factor.T
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
        top = by_output.max(axis=2, keepdims=True)
        # the first pose (grid order is lexicographic) within the tie tolerance of the
        # largest, not the one the rounding of symmetric poses happens to favour
        where = np.argmax(by_output >= top * (1 - TIE_RTOL), axis=2)
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
        x = self._pair_errors(motion, assembly, machine, self.grid_index[pose])
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
        return ~passes(ratio, 1.0), worst

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
        index = self.grid_index[pose]  # (R, n)
        at_pose = motion[np.arange(len(u))[:, None], np.arange(n), index]  # (R, n, 6)
        x = np.concatenate([at_pose.reshape(len(u), -1), assembly.reshape(len(u), -1)],
                           axis=1)
        distinct, where = np.unique(pose, return_inverse=True)
        jacobian = self.machine.jacobian(self.experiment.poses[distinct])[where.ravel()]
        return jacobian[np.arange(len(u)), output] * x

    # ----- the linearised model -----------------------------------------------------
    def first_order_bounds(self, tolerances) -> tuple[float, float]:
        """Bounds on the yield of the linearised model
        (:meth:`reliability.sampling.linear_rows.LinearRows.first_order_bounds`)."""
        return self.linear.first_order_bounds(tolerances)

    def linear_failure(self, tolerances, rng=None) -> float:
        """The linearised model's failure probability (all rows at once), estimated without
        the chain by ALOE (``P_S · mean 1/N_S`` over :data:`LINEAR_SAMPLES` draws of the
        pure mixture) plus the ``p_r`` of the rows left out of ``S`` (an upper estimate
        for them)."""
        t = checks.one_allocation(self.machine, tolerances)
        events = RowEvents.dominant(self.linear, t)
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
        sigma = self.linear.row_sigma(t)
        failure = two_sided_failure(self.machine.limits, sigma).ravel()
        lower, upper = bounds_from_rows(failure)
        method, reason, events = self._choose(method, machines, t, failure, pilot_rng)
        sampled = self._sample(t, machines, main_rng, events, target_cov)
        return sampled.result(self, sigma, confidence, method, reason, lower, upper,
                              None if method == "crude" else target_cov)

    def _choose(self, method, machines, t, failure, rng):
        """The method, why, and the proposal's events (None for crude sampling)."""
        if method == "crude":
            return method, "method 'crude' asked for", None
        if method == "importance":
            events = RowEvents.dominant(self.linear, t)
            return method, "method 'importance' asked for", events
        if machines < MIN_IMPORTANCE_MACHINES:
            return "crude", (f"{machines:,} machines < {MIN_IMPORTANCE_MACHINES:,}, too few "
                             f"for importance sampling's standard error"), None
        common = _common_failure(machines, failure.max())
        if common:
            return "crude", f"the worst row alone gives {common}", None
        events = RowEvents.dominant(self.linear, t)
        if events.size == 0:
            return "crude", "no row of the linearised model can fail in double precision", None
        linear = min(1.0, events.linear_failure(rng) + events.left_out)
        common = _common_failure(machines, linear)
        if common:
            return "crude", f"the linearised model gives {common}", None
        return "importance", (f"crude sampling of {machines:,} machines would expect "
                              f"{machines * linear:.3g} failing (linearised model) < "
                              f"{MIN_FAILURES}, failure probability {linear:.3g} < "
                              f"{RARE_FAILURE:.3g}"), events

    def _sample(self, t, machines, rng, events, target_cov) -> SampleSums:
        """Machines drawn plainly (``events`` None) or from the proposal, in batches, until
        ``machines`` are spent or importance sampling reaches ``target_cov``."""
        samples = SampleSums()
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


@renamed("points_per_axis", "points")
def machine_yield(machine, tolerances, *, profile=None, distribution=None,
                  points: int = 5, machines: int = DEFAULT_MACHINES, rng=None,
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
    points : int
        Grid points per axis (5 in the paper: 15 625 poses on six axes);
        ``points_per_axis=`` is its deprecated spelling (:mod:`reliability.basics.renamed`).
    machines : int
        Built machines simulated (crude), or at most (importance sampling).
    rng : None, int or numpy.random.Generator
        Split by :func:`reliability.basics.streams.spawn` into the stream of the ``auto`` decision
        and the stream of the machines.
    method : {'auto', 'crude', 'importance'}
        See the module's docstring; ``auto`` samples by importance only with at least
        :data:`MIN_IMPORTANCE_MACHINES` machines, a linearised failure probability below
        :data:`RARE_FAILURE` and fewer than :data:`MIN_FAILURES` failing machines
        expected, crudely otherwise.
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
                       points=points, k=k, memory=memory)
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


def _common_failure(machines: int, probability: float) -> str:
    """Why failures of ``probability`` are not rare enough for importance sampling of
    ``machines`` (at least :data:`RARE_FAILURE`, or :data:`MIN_FAILURES` expected failing
    machines), else the empty text."""
    expected = machines * probability
    if expected >= MIN_FAILURES:
        return f"{expected:,.0f} expected failing machines ≥ {MIN_FAILURES}"
    if probability >= RARE_FAILURE:
        return (f"failure probability {probability:.3g} ≥ {RARE_FAILURE:.3g}: failures are "
                f"not rare")
    return ""


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
    """The largest of each machine's output ratios and its row ``pose · 6 + output``: among
    the rows within :data:`reliability.basics.ties.TIE_RTOL` of the largest, the one that
    comes first."""
    ratio = ratios.max(axis=1)
    rows = poses * len(OUTPUTS) + np.arange(len(OUTPUTS))
    tied = ratios >= ratio[:, None] * (1 - TIE_RTOL)
    worst = np.where(tied, rows, np.iinfo(np.intp).max).min(axis=1)
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
