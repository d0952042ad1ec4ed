"""Monte-Carlo verification on the exact model: the grid experiment of Sec. 5.3.

Grid experiment (docs/model.md). Each axis takes ``P`` equidistant points (P = 5 in the
paper); at every point of every axis its six motion errors are drawn once per experiment;
the assembly errors are drawn once per experiment; all ``P^n`` pose combinations are then
evaluated with the exact model (Eq. 18). All poses of one experiment share its assembly
errors, and each motion-error draw is shared by ``P^(n−1)`` poses, so the poses of one
experiment are *not* independent samples: the unit of replication is the experiment.

How it is computed. Split the chain into a head (the first ``h`` axes) and a tail, with
ideal transforms ``A``, ``B`` and actual ones ``A (I + D_h)``, ``B (I + D_t)``. Then exactly

    E − I = D_t + B⁻¹ D_h B (I + D_t),

which is linear in the twelve non-zero entries of ``D_h``. ``D_h`` has only ``P^h`` values
per experiment and ``D_t`` only ``P^(n−h)``, so the ``P^n`` poses come from one matrix
product ``(P^h × 12) · (12 × 6 P^(n−h))`` instead of a 17-matrix chain per pose.

On a machine with a work zone (:mod:`reliability.model.work_zone`) the experiment keeps the
grid poses inside the zone only: the whole grid is evaluated as above and the poses
outside are dropped before anything is counted.
"""

from __future__ import annotations

import numpy as np

from ..basics import checks, streams
from ..basics.chunks import chunk_size
from ..basics.errors import InputError
from ..basics.pass_rule import passes
from ..basics.renamed import renamed
from ..basics.result_store import ResultStore, machine_fingerprint
from ..model.error_draws import check_reading, draw_errors, draw_grid_errors
from ..model.kinematics import (deviation_from_transports, ideal_motion, ideal_rotation,
                                offset_transform, transports, vectors_in_frame)
from ..model.measured_profiles import grid_means
from ..model.poses import grid_axis_points, grid_inside_zone
from ..model.profiles import IndependentProfile, axis_profiles, draw_motion_errors, travel_factors
from ..model.transforms import read_pose_error, rigid_inverse
from .experiment_results import GridExperimentResult

# READ[o, r, s]: output o of a deviation matrix X is Σ READ[o, r, s] X[r, s]
# (translation column for δ, skew part of the rotation block for ε; see read_pose_error).
READ = np.zeros((6, 3, 4))
READ[0, 0, 3] = READ[1, 1, 3] = READ[2, 2, 3] = 1.0
READ[3, 2, 1], READ[3, 1, 2] = 0.5, -0.5
READ[4, 0, 2], READ[4, 2, 0] = 0.5, -0.5
READ[5, 1, 0], READ[5, 0, 1] = 0.5, -0.5


def _grid_shape(position: int, counts) -> tuple[int, ...]:
    """Broadcast shape of the axis at ``position`` among axes of ``counts`` points each."""
    return tuple(count if d == position else 1 for d, count in enumerate(counts))


class GridExperiment:
    """The Sec. 5.3 grid experiment for one machine and grid, ready to run many times.

    The pose-dependent part (transports of every error to the tool frame) is computed once
    here; :meth:`run` then costs one small matrix product per experiment.

    Parameters
    ----------
    machine : Machine
    points : int
        Grid points per axis (5 in the paper); ``points_per_axis=`` is its deprecated
        spelling (:mod:`reliability.basics.renamed`).
    profile : str, profile model or mapping
        How each axis' motion errors hang together along its travel
        (:mod:`reliability.model.profiles`): ``"independent"`` (the paper's, default),
        ``"constant"``, ``"gp:<length mm>"``, a model, or ``{axis name: model}``.
    systematic : SystematicErrors, optional
        Measured mean profiles (:mod:`reliability.model.measured_profiles`) added at every grid
        point.
    budget : int, optional
        Bytes one batch of experiments may take (default
        :data:`reliability.basics.checks.DEFAULT_BUDGET`); ``P^n`` is checked against it here,
        ``batch × P^n`` and the counts of all repeats in :meth:`run`.
    kept_points : sequence of array_like of int, optional
        Per axis, the indices of its ``P`` grid points the experiment evaluates (all by
        default): the poses are then the product of the kept points, in grid order, and
        errors are still given at all ``P`` points of every axis. Not with a work zone.

    Attributes
    ----------
    points : int
        Grid points per axis, ``P``.
    axis_points : list of ndarray
        The ``P`` grid points of every axis, in chain order.
    """

    @renamed("points_per_axis", "points")
    def __init__(self, machine, points: int = 5, profile="independent",
                 systematic=None, *, budget: int | None = None, kept_points=None):
        self.machine = machine
        self.axis_points = grid_axis_points(machine, points)
        self._kept = self._check_kept(kept_points, len(self.axis_points[0]))
        checks.require_size(len(self.axis_points[0]) ** len(self.axis_points), 6 * 8, budget,
                            f"one experiment on a {len(self.axis_points[0])}-point grid of "
                            f"{len(self.axis_points)} axes",
                            "use fewer points per axis, or sample random poses instead")
        self.budget = budget
        self.points = int(points)
        self.profiles = axis_profiles(machine, profile)
        self._travel = travel_factors(machine, self.profiles, self.axis_points)
        self._independent = all(isinstance(p, IndependentProfile) for p in self.profiles)
        self._motion_means = None if systematic is None else \
            grid_means(systematic, machine, self.axis_points)
        n = len(machine.axis_specs)
        self.n_head = n // 2  # empty head for a one-axis machine
        head_factors, self._head_gaps = self._segment(0, self.n_head)
        tail_factors, self._tail_gaps = self._segment(self.n_head, n)
        self._head_transports = transports(head_factors)
        self._tail_transports = transports(tail_factors)
        self._tail_ideal = self._product(tail_factors, self.counts[self.n_head:])
        self._tail_ideal_inverse = rigid_inverse(self._tail_ideal)
        self._zone_rows = self._rows_in_zone()
        self._rotation = ideal_rotation(machine, self.poses) \
            if machine.frame == "workpiece" else None  # outputs in the workpiece frame

    def _check_kept(self, kept_points, points: int) -> list[np.ndarray]:
        """Per axis, the indices of the grid points evaluated (all by default), checked."""
        n = len(self.machine.axis_specs)
        if kept_points is None:
            return [np.arange(points)] * n
        if self.machine.work_zone is not None:
            raise InputError("kept_points cannot be combined with a work zone")
        kept = [np.asarray(k, dtype=np.intp) for k in kept_points]
        if len(kept) != n:
            raise InputError(f"kept_points must give one index array per axis ({n}); "
                             f"got {len(kept)}")
        for axis, k in zip(self.machine.axes, kept):
            if k.ndim != 1 or len(k) == 0 or np.any(np.diff(k) <= 0) or k[0] < 0 \
                    or k[-1] >= points:
                raise InputError(f"kept_points of axis {axis} must be increasing indices in "
                                 f"[0, {points - 1}]; got {k.tolist()}")
        return kept

    @property
    def counts(self) -> tuple[int, ...]:
        """Points evaluated on each axis: ``P`` each, or the kept points' counts."""
        return tuple(len(k) for k in self._kept)

    @property
    def n_grid(self) -> int:
        """The grid's poses, ``P^n`` (15 625 for the paper's machine), or the product of
        the kept points' counts."""
        return int(np.prod(self.counts))

    @property
    def n_poses(self) -> int:
        """The poses evaluated: ``P^n``, or those inside the machine's work zone."""
        return self.n_grid if self._zone_rows is None else len(self._zone_rows)

    @property
    def poses(self) -> np.ndarray:
        """``(n_poses, n_axes)`` grid poses, first axis slowest (as ``workspace_grid``)."""
        grid = self._whole_grid()
        return grid if self._zone_rows is None else grid[self._zone_rows]

    def pose_rows(self) -> np.ndarray:
        """The row of each of :attr:`poses` in the whole grid, ``(n_poses,)``."""
        return np.arange(self.n_grid) if self._zone_rows is None else self._zone_rows

    def full_grid_rows(self) -> np.ndarray:
        """The row of each of :attr:`poses` in the grid of all ``P^n`` points (with kept
        points, their rows in it; otherwise :meth:`pose_rows`)."""
        full = (len(self.axis_points[0]),) * len(self._kept)
        index = np.meshgrid(*self._kept, indexing="ij")
        return np.ravel_multi_index([i.ravel() for i in index], full)[self.pose_rows()]

    def _whole_grid(self) -> np.ndarray:
        mesh = np.meshgrid(*[p[k] for p, k in zip(self.axis_points, self._kept)], indexing="ij")
        return np.stack([m.ravel() for m in mesh], axis=-1)

    def _rows_in_zone(self) -> np.ndarray | None:
        """Rows of the whole grid inside the work zone; None without a zone (all rows)."""
        if self.machine.work_zone is None:
            return None
        return np.flatnonzero(grid_inside_zone(self.machine, self._whole_grid(),
                                               self.points))

    # ----- set-up ------------------------------------------------------------------
    def _segment(self, first: int, stop: int):
        """Ideal factors and gap labels of axes ``first … stop−1`` on their own grid.

        A gap label is ``('motion', axis)`` or ``('joint', j)``. The tail starts with the
        assembly error of the joint into its first axis.
        """
        specs = self.machine.axis_specs
        counts = self.counts[first:stop]
        factors, gaps = [np.eye(4)], []
        if first > 0:
            gaps.append(("joint", first - 1))
            factors.append(np.eye(4))
        for i in range(first, stop):
            factors[-1] = factors[-1] @ offset_transform(specs[i].offset)
            gaps.append(("motion", i))
            position = self.axis_points[i][self._kept[i]].reshape(_grid_shape(i - first, counts))
            factors.append(ideal_motion(specs[i], position))
            if i < stop - 1:
                gaps.append(("joint", i))
                factors.append(np.eye(4))
        if stop == len(specs):
            factors[-1] = factors[-1] @ offset_transform(self.machine.tool_offset)
        return factors, gaps

    def _product(self, factors, counts) -> np.ndarray:
        out = factors[0]
        for factor in factors[1:]:
            out = out @ factor
        return np.broadcast_to(out, tuple(counts) + (4, 4)).reshape(-1, 4, 4)

    # ----- evaluation --------------------------------------------------------------
    def evaluate(self, motion_errors, assembly_errors) -> np.ndarray:
        """Exact comprehensive errors at every grid pose for given error draws.

        Parameters
        ----------
        motion_errors : array_like
            ``(R, n_axes, P, 6)``: each axis' six motion errors at each of its points.
        assembly_errors : array_like
            ``(R, n_axes − 1, 6)``.

        Returns
        -------
        numpy.ndarray
            ``(R, n_poses, 6)``, poses in the order of :attr:`poses`.
        """
        motion, assembly = self._check_draws(motion_errors, assembly_errors)
        repeats = motion.shape[0]
        head = self._deviation(self._head_transports, self._head_gaps, 0, motion, assembly)
        tail = self._deviation(self._tail_transports, self._tail_gaps, self.n_head, motion,
                               assembly)
        head = head.reshape(repeats, -1, 4, 4)
        tail = tail.reshape(repeats, -1, 4, 4)
        tail_actual = self._tail_ideal @ (np.eye(4) + tail)
        # E − I = D_t + B⁻¹ D_h B (I + D_t): linear in the 12 non-zero entries of D_h.
        coupling = np.einsum("ors,jra,Rjbs->Rabjo", READ, self._tail_ideal_inverse[:, :3, :3],
                             tail_actual, optimize=True)
        coupling = coupling.reshape(repeats, 12, -1)
        through_head = head[:, :, :3, :].reshape(repeats, -1, 12) @ coupling
        out = through_head.reshape(repeats, head.shape[1], tail.shape[1], 6)
        out += read_pose_error(tail)[:, None, :, :]
        out = out.reshape(repeats, -1, 6)
        if self._zone_rows is not None:
            out = out[:, self._zone_rows]
        return out if self._rotation is None else vectors_in_frame(out, self._rotation)

    def _deviation(self, adjoints, gaps, first: int, motion, assembly) -> np.ndarray:
        """Deviation of a segment for every repeat and every combination of its points."""
        counts = self.counts[first:first + len([g for g in gaps if g[0] == "motion"])]
        twists = []
        for kind, index in gaps:
            if kind == "motion":
                shape = _grid_shape(index - first, counts)
                kept = self._kept[index]
                at_points = motion[:, index] if len(kept) == motion.shape[2] \
                    else motion[:, index, kept]
                twists.append(at_points.reshape((-1,) + shape + (6,)))
            else:
                twists.append(assembly[:, index].reshape((-1,) + (1,) * len(counts) + (6,)))
        if not twists:
            return np.zeros((motion.shape[0], 1, 4, 4))
        return deviation_from_transports(adjoints, twists)

    def reference_evaluate(self, motion_errors, assembly_errors) -> np.ndarray:
        """Same as :meth:`evaluate`, by the straightforward per-pose exact model.

        Builds each pose's full error vector and calls ``machine.comprehensive_error`` on
        all the poses at once: the simple reference the benchmark compares against.
        """
        motion, assembly = self._check_draws(motion_errors, assembly_errors)
        index = np.stack(np.meshgrid(*self._kept, indexing="ij"),
                         axis=-1).reshape(-1, motion.shape[1])
        index = index[self.pose_rows()]
        per_pose = motion[:, np.arange(motion.shape[1]), index]  # (R, P^n, n_axes, 6)
        x = np.concatenate([per_pose.reshape(motion.shape[0], len(index), -1),
                            np.broadcast_to(assembly.reshape(motion.shape[0], 1, -1),
                                            (motion.shape[0], len(index),
                                             assembly[0].size))], axis=-1)
        return self.machine.comprehensive_error(self.poses, x)

    def _check_draws(self, motion, assembly):
        n = len(self.machine.axis_specs)
        motion = checks.numeric_array(motion, "motion errors")
        assembly = checks.numeric_array(assembly, "assembly errors")
        expected = (n, self.points, 6)
        if motion.ndim != 4 or motion.shape[1:] != expected:
            raise InputError(f"motion errors must have shape (R, {n}, {self.points}, 6);"
                             f" got {motion.shape}")
        if assembly.shape != (motion.shape[0], n - 1, 6):
            raise InputError(f"assembly errors must have shape ({motion.shape[0]}, {n - 1}, 6);"
                             f" got {assembly.shape}")
        return motion, assembly

    # ----- experiments -------------------------------------------------------------
    def run(self, tolerances, *, repeats: int = 20, rng=None, k: float = 3.0,
            distribution: str = "truncated", keep_values: str = "first",
            batch: int = 50, progress=None, memory: int | None = None,
            checkpoint=None) -> "GridExperimentResult":
        """Run ``repeats`` independent grid experiments (Tables 8 and 9).

        Parameters
        ----------
        tolerances : array_like
            ``(n_errors,)`` allocation, read as ±kσ.
        repeats : int
            Number of experiments (20 in the paper); each draws from its own generator
            spawned from ``rng``, so repeat r is the same whatever the batch size.
        rng : None, int or numpy.random.Generator
        k : float
            Coverage factor.
        distribution : {'truncated', 'normal'}
            Truncated at ±t as in Sec. 5.3 (default), or untruncated.
        keep_values : {'first', 'all', 'none'}
            Which experiments' per-pose values to keep (for Figs. 10–15).
        batch : int
            Experiments evaluated together at most (memory ≈ batch × P^n × 6 × 8 bytes);
            fewer when that exceeds ``memory``.
        progress : callable, optional
            Called as ``progress(done, total)`` after each batch.
        memory : int, optional
            Bytes of temporary arrays per batch (:data:`reliability.basics.chunks.MEMORY_BUDGET`
            by default); at least one experiment per batch.
        checkpoint : str or Path, optional
            Folder where each finished batch's counts are stored at once
            (:class:`reliability.basics.result_store.ResultStore`); a run with the same allocation,
            generator, options and batches reuses them instead of computing again. Batches
            whose per-pose values are kept (``keep_values``) are always computed.

        Returns
        -------
        GridExperimentResult
        """
        t = checks.one_allocation(self.machine, tolerances)
        repeats, batch = _check_run_options(repeats, keep_values, batch, distribution, k)
        checks.callback(progress, "progress")
        rng = streams.generator(rng)
        batch = min(batch, chunk_size(4 * 6 * 8 * self.n_grid, memory))
        values_kept = {"all": repeats, "first": 1, "none": 0}[keep_values]
        checks.require_size(min(batch, repeats) * self.n_grid, 6 * 8 * 4, self.budget,
                            f"a batch of {min(batch, repeats)} experiments",
                            "pass a smaller batch")
        checks.require_size(repeats * 6 + values_kept * self.n_poses * 6, 8, self.budget,
                            f"the results of {repeats:,} experiments",
                            "run fewer repeats per call, or keep_values='none'/'first'")
        store = None if checkpoint is None else ResultStore(checkpoint)
        inside, kept = [], []
        for start in range(0, repeats, batch):
            wanted = keep_values == "all" or (keep_values == "first" and start == 0)
            batch_children = rng.spawn(min(batch, repeats - start))  # same as one spawn
            key = self._checkpoint_key(t, batch_children, k, distribution)
            stored = None if store is None or wanted else store.load(key)
            if stored is not None:
                inside.append(np.asarray(stored, dtype=np.int64))
            else:
                draws = [self._draw(t, child, k, distribution) for child in batch_children]
                values = self.evaluate(np.stack([d[0] for d in draws]),
                                       np.stack([d[1] for d in draws]))
                inside.append(np.sum(passes(values, self.machine.limits), axis=1))  # Eq. (19)
                if store is not None:
                    store.save(key, inside[-1])
                if wanted:
                    kept.append(values if keep_values == "all" else values[:1])
            if progress is not None:
                progress(min(start + batch, repeats), repeats)
        return GridExperimentResult(
            limits=self.machine.limits.copy(), inside=np.concatenate(inside),
            n_poses=self.n_poses, distribution=distribution, k=float(k),
            points=self.points,
            values=np.concatenate(kept) if kept else None)

    def _checkpoint_key(self, t, children, k, distribution) -> dict:
        """Parameters that determine one batch's counts (its checkpoint key)."""
        seeds = [[child.bit_generator.seed_seq.entropy,
                  list(child.bit_generator.seed_seq.spawn_key)] for child in children]
        return {"kind": "grid_experiment", "machine": machine_fingerprint(self.machine),
                "points_per_axis": self.points,  # the key of checkpoints saved before 0.4
                "tolerances": t, "k": float(k), "distribution": distribution,
                "profiles": [str(p) for p in self.profiles],
                "systematic": None if self._motion_means is None else self._motion_means,
                "seeds": seeds}

    def _draw(self, t, rng, k, distribution):
        """One experiment's errors from its own generator: motion errors ``(n_axes, P, 6)``
        (one draw per axis point), then assembly errors ``(n_axes − 1, 6)``."""
        n = len(self.machine.axis_specs)
        if self.machine.correlation is not None:
            motion, assembly = draw_grid_errors(
                self.machine, t, self.points, k=k, distribution=distribution,
                rng=rng, travel=None if self._independent else self._travel)
        else:
            motion = self._draw_motion(t[:6 * n].reshape(n, 6), rng, k, distribution)
            assembly = draw_errors(t[6 * n:].reshape(n - 1, 6), (), k=k,
                                   distribution=distribution, rng=rng)
        if self._motion_means is not None:
            motion = motion + self._motion_means
        return motion, assembly

    def _draw_motion(self, motion_t, rng, k, distribution):
        """Uncorrelated items: each axis' motion errors at its P points, per its profile."""
        if self._independent:
            shape = (motion_t.shape[0], self.points, 6)
            return draw_errors(np.broadcast_to(motion_t[:, None, :], shape), (), k=k,
                               distribution=distribution, rng=rng)
        return draw_motion_errors(self._travel, motion_t, rng, k, distribution)


def _check_run_options(repeats, keep_values, batch, distribution, k) -> tuple[int, int]:
    counts = checks.positive_int(repeats, "repeats"), checks.positive_int(batch, "batch")
    checks.choice(keep_values, "keep_values", ("first", "all", "none"))
    check_reading(distribution, k)
    return counts
