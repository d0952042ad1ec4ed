"""The precision-allocation problem of Eq. (34), built from a machine and a pose set.

    minimise    F(t) = Σ_i w_i / t_i²                                  (Eq. 28)
    subject to  P_o(pose, t) ≥ R_o for every output o and pose          (Eqs. 24, 35)
                lower_i ≤ t_i ≤ upper_i

With FOSM (Eqs. 19–23) at zero error mean, ``P ≥ R`` at a pose is ``σ_o ≤ I_o / z_o`` with
``z = Φ⁻¹(R)`` (the paper's one-sided reading) or ``z = Φ⁻¹((1 + R)/2)`` (exact two-sided);
in ``u = t²`` it is the linear row ``Σ_i J_oi² u_i / k² ≤ (I_o / z_o)²``. The workspace
constraint of Eq. (35) is read as "at every pose of the grid" (docs/model.md); a
workspace-mean variant asks the mean of P over the poses to reach R instead.

The classical worst-case reading ``side='stack'`` ("completely within the allowable
range") asks every error anywhere in ±t_i to keep each output inside its limit:
``Σ_i |J_oi| t_i ≤ I_o`` at every pose, linear in ``t`` itself (the solver's variable is
then ``u = t`` and the cost ``Σ w_i / u_i²``). It involves neither k nor the targets.

Rows that can never bind are removed before any solver sees them:

1. *box*: a row whose load stays ≤ 1 even with every tolerance at its upper bound;
2. *duplicates*: poses that give the same row (e.g. εx does not depend on X, Y, Z);
3. *dominance*: a row that is ≤ another row of the same output in every entry.

All three are exact: the screened problem has the same feasible set inside the box.
Screening runs over chunks of poses (the Jacobian of all poses is never held when it
exceeds the memory budget), and the dominance test compares each row only with the rows
kept so far, in order of decreasing row sum, which is exact by transitivity.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import pandas as pd

from reliability.basics import checks
from reliability.basics.chunks import MEMORY_BUDGET, chunks, jacobian_bytes
from reliability.basics.errors import InputError, InputTypeError
from reliability.basics.ties import first_of_equal_rows
from reliability.first_order.fosm import error_sigma, fosm, probability, required_index
from reliability.model.kinematics import check_frame
from reliability.model.machine import OUTPUTS
from reliability.model.poses import workspace_grid

from ..cost.cost import CostModel
from . import solve

SIDES = ("one_sided", "two_sided", "stack")
WORKSPACES = ("worst", "mean")
DUPLICATE_DIGITS = 10  # rows equal to 10 significant digits count as one
#: Entries of a column within this relative distance count as equal in the dominance
#: screening (the rounding of equal entries differs between computers).
ENTRY_RTOL = 1e-13


@dataclass(frozen=True, eq=False)
class ScreenedRows:
    """Constraint rows ``matrix @ u ≤ 1`` that survive screening, with their origin.

    Attributes
    ----------
    matrix : ndarray (n_rows, n_errors)
        Normalised rows over all items (locked ones included).
    pose, output : ndarray (n_rows,) of int
        Pose index and output index of each row.
    counts : dict
        Rows remaining after each screening step.
    """

    matrix: np.ndarray
    pose: np.ndarray
    output: np.ndarray
    counts: dict


@dataclass(frozen=True, eq=False)
class AllocationProblem:
    """Eq. (34) for one machine, pose set and reliability reading; build with :meth:`build`.

    Attributes
    ----------
    machine : Machine
    poses : ndarray (n_poses, n_axes)
    jacobian : ndarray (n_poses, 6, n_errors) or None
        Kept when it fits the memory budget (or for the mean reading); otherwise None and
        recomputed chunk by chunk where needed (:meth:`jacobian_chunks`).
    side : {'one_sided', 'two_sided', 'stack'}
    workspace : {'worst', 'mean'}
    k : float
        Tolerances are ±kσ.
    lower, upper : ndarray (n_errors,)
        Tolerance bounds; equal bounds lock an item.
    reference : ndarray (n_errors,)
        Allocation the bounds and optimisation rates refer to (the machine's initial
        allocation by default).
    cost : CostModel
    rows : ScreenedRows or None
        The linear rows of the worst-case reading (None for the mean reading), in the
        solver's variable (:attr:`variable_power`).
    memory : int or None
        Bytes of temporary arrays per chunk of poses (None: the default budget).
    bounds_source : str
        Where the box comes from: ``"machine file"`` (its ``[bounds]`` table),
        ``"factors of the initial allocation"`` (the default [0.5, 1.5]) or ``"given"``
        (``bounds``, ``lower`` or ``upper`` passed to :meth:`build`).
    life : LifeRequirement or None
        The life target of :mod:`allocation.per_pose.life` (:meth:`with_life`): each row
        is then divided by its own largest σ0² instead of the output's ``(I/z)²``.
    """

    machine: object
    poses: np.ndarray
    jacobian: np.ndarray
    side: str
    workspace: str
    k: float
    lower: np.ndarray
    upper: np.ndarray
    reference: np.ndarray
    cost: CostModel
    rows: ScreenedRows | None
    memory: int | None = None
    bounds_source: str = "given"
    life: object = None

    @classmethod
    def build(cls, machine, poses=None, *, side: str = "two_sided", workspace: str = "worst",
              bounds=None, lower=None, upper=None, locked=(), reference=None,
              k: float = 3.0, cost_factors=(1.0, 1.0, 1.0), targets=None, limits=None,
              allow_outside_stroke: bool = False, budget: int | None = None,
              memory: int | None = None, frame: str | None = None,
              distribution: str | None = None) -> "AllocationProblem":
        """Set up the problem.

        Parameters
        ----------
        machine : Machine
        poses : array_like, optional
            ``(n_poses, n_axes)``; default the 5-point workspace grid (5^n poses for n
            axes).
        side : {'one_sided', 'two_sided', 'stack'}
            The paper's Φ(β), the exact two-sided probability, or the classical
            worst-case stack ``Σ|J| t ≤ I`` (worst-case workspace only).
        workspace : {'worst', 'mean'}
            Target at every pose (Eq. 35 as read in docs/model.md) or on the workspace mean.
        bounds : (float, float), optional
            Box as multiples of ``reference``. Default: the machine file's ``[bounds]``
            table when it has one, else :data:`DEFAULT_FACTORS` ([0.5, 1.5]: Table 6 moves
            no item by more than +50 %); :attr:`bounds_source` says which.
        lower, upper : array_like, optional
            Explicit tolerance bounds, overriding ``bounds``.
        locked : str or iterable of str
            Error names held at their reference value.
        reference : array_like or mapping, optional
            Reference allocation, default ``machine.initial_allocation``.
        k : float
            Coverage factor of the tolerances.
        cost_factors : (k1, k2, k3)
            Group weights of Eq. (28).
        targets, limits : mapping, optional
            ``{output name: value}`` overriding the machine's reliability targets (in
            (0, 1)) or limits (> 0, mm or rad) for the named outputs; the others keep
            the machine's. The problem's ``machine`` carries the overridden values.
        allow_outside_stroke : bool
            Accept poses outside an axis' stroke (extrapolation); refused by default.
        budget : int, optional
            Bytes the grid and the screened rows may take (default
            :data:`reliability.basics.checks.DEFAULT_BUDGET`), checked before any work.
        memory : int, optional
            Bytes of temporary arrays (default :data:`reliability.basics.chunks.MEMORY_BUDGET`):
            poses are screened in chunks, and the Jacobian of all poses is kept only when it
            fits (always for the mean reading, which needs it whole).
        frame : {'tool', 'workpiece'}, optional
            Frame the requirements hold in; default ``machine.frame`` (the machine file's
            ``[requirements] frame``, else ``"tool"``, Eq. 18). The problem's ``machine``
            carries it.
        distribution : {'normal', 'truncated'}, optional
            How a tolerance is read (default ``machine.distribution``): under 'truncated' every σ
            constraint uses the truncated normal's standard deviation
            (:func:`reliability.first_order.fosm.error_sigma`). The problem's ``machine`` carries
            it.
        """
        _check_choice(side, SIDES, "side")
        if distribution is not None:
            _check_choice(distribution, ("normal", "truncated"), "distribution")
            machine = replace(machine, distribution=distribution)
        _check_choice(workspace, WORKSPACES, "workspace")
        if getattr(machine, "correlation", None) is not None:
            raise InputError("machine: its errors are correlated (machine.correlation) but "
                             "these constraint rows assume independent errors; use "
                             "allocation.per_pose.correlated.solve_correlated")
        if side == "stack" and workspace != "worst":
            raise InputError("side='stack' is a worst-case reading; use workspace='worst'")
        machine = with_requirements(machine, targets=targets, limits=limits)
        if frame is not None:
            machine = replace(machine, frame=check_frame(frame))
        k = checks.finite_float(k, "coverage factor k", 0.0, low_open=True)
        poses = workspace_grid(machine, budget=budget) if poses is None else \
            _checked_poses(machine, poses, allow_outside_stroke)
        checks.require_size(len(poses), 6 * 8 * 8, budget,
                            "the per-pose results and screened rows of the allocation problem",
                            "pass fewer poses (a coarser grid)")
        reference = _reference(machine, reference)
        source = bounds_source(machine, bounds, lower, upper)
        if source == "machine file":
            lower, upper = machine.tolerance_bounds
        low, high = _bounds(machine, reference, DEFAULT_FACTORS if bounds is None else bounds,
                            lower, upper, locked)
        memory_budget = MEMORY_BUDGET if memory is None else memory
        keep = workspace == "mean" or len(poses) * 6 * machine.n_errors * 8 <= memory_budget
        jacobian = machine.jacobian(poses) if keep else None
        problem = cls(machine=machine, poses=poses, jacobian=jacobian, side=side,
                      workspace=workspace, k=float(k), lower=low, upper=high,
                      reference=reference, cost=CostModel.from_machine(machine, *cost_factors),
                      rows=None, memory=memory, bounds_source=source)
        return replace(problem, rows=problem._screen()) if workspace == "worst" else problem

    def box_text(self) -> str:
        """The box in words, for a report: ``[0.5, 1.5] × the initial allocation`` when it is
        made of factors of the reference, else its extent and where it comes from."""
        free = ~self.locked
        low, high = self.lower[free] / self.reference[free], self.upper[free] / self.reference[free]
        where = {"machine file": "the machine file's [bounds]"}.get(self.bounds_source,
                                                                    "the given bounds")
        if low.size and np.ptp(low) <= 1e-12 * low.max() and np.ptp(high) <= 1e-12 * high.max():
            factors = f"[{low[0]:.6g}, {high[0]:.6g}] × the initial allocation"
            return factors if self.bounds_source != "machine file" else f"{where} ({factors})"
        return (f"{where} (translations {_span(self.lower, self.upper, self.machine, False)} "
                f"mm, rotations {_span(self.lower, self.upper, self.machine, True)} rad)")

    def with_reading(self, side: str) -> "AllocationProblem":
        """The same poses, bounds and costs under another reliability reading.

        The Jacobian is shared. When the new reading allows every output at least the σ
        of this one (e.g. one-sided from two-sided at the same targets), its rows are this
        problem's screened rows rescaled and box-screened again: exact, because a row
        dominated under one scaling is dominated under any per-output scaling and its
        dominator is at least as loaded. Otherwise the poses are screened afresh.
        """
        _check_choice(side, SIDES, "side")
        if self.life is not None:
            raise InputError("with_reading: a life problem is two-sided by construction; "
                             "build the problem under the other reading and add the life")
        problem = replace(self, side=side, rows=None)
        if self.workspace != "worst":
            return problem
        if "stack" in (side, self.side):  # rows of another kind: screen afresh
            return replace(problem, rows=problem._screen())
        ratio = np.square(self.allowed_sigma / problem.allowed_sigma)  # new row / old row
        if np.all(ratio <= 1.0):
            scaled = self.rows.matrix * ratio[self.rows.output][:, None]
            keep = scaled @ np.square(self.upper) > 1.0
            counts = {"candidates": self.rows.counts["candidates"],
                      "shared": len(self.rows.matrix), "box": int(keep.sum()),
                      "dominance": int(keep.sum())}
            rows = ScreenedRows(matrix=scaled[keep], pose=self.rows.pose[keep],
                                output=self.rows.output[keep], counts=counts)
        else:
            rows = problem._screen()
        return replace(problem, rows=rows)

    def _screen(self) -> ScreenedRows:
        """Screened rows of all poses, built chunk by chunk (:func:`screen_rows`)."""
        upper_u = self.variable(self.upper)
        parts = ((part.start, self.row_matrix(block)) for part, block in self.jacobian_chunks())
        return _screen_parts(parts, upper_u, len(self.poses))

    def rows_up_to(self, upper) -> ScreenedRows:
        """Screened rows of all poses for tolerances anywhere up to ``upper`` instead of the
        problem's box (e.g. a catalogue's loosest classes). Only the box step depends on
        the bound; duplicates and dominance hold for any tolerances."""
        upper = self.machine.check_tolerances(upper).astype(float)
        return replace(self, upper=upper, rows=None)._screen()

    def jacobian_chunks(self):
        """``(slice, jacobian)`` over chunks of the poses, within the memory budget."""
        for part in chunks(len(self.poses), jacobian_bytes(self.machine), self.memory):
            yield part, (self.machine.jacobian(self.poses[part]) if self.jacobian is None
                         else self.jacobian[part])

    # ----- description ---------------------------------------------------------------
    @property
    def names(self) -> tuple[str, ...]:
        """Error names (the decision variables)."""
        return self.machine.error_names

    @property
    def locked(self) -> np.ndarray:
        """Boolean mask of items held fixed (lower == upper)."""
        return self.lower == self.upper

    @property
    def variable_power(self) -> int:
        """``p`` with ``t² = u^p`` for the solver's variable ``u``: 2 for the stack
        (``u = t``), 1 for the reliability readings (``u = t²``)."""
        return 2 if self.side == "stack" else 1

    def variable(self, t) -> np.ndarray:
        """The solver's variable of tolerances ``t``: ``t`` (stack) or ``t²``."""
        t = np.asarray(t, dtype=float)
        return t if self.side == "stack" else np.square(t)

    @property
    def distribution(self) -> str:
        """How a tolerance is read: ``'normal'`` or ``'truncated'`` (the machine's)."""
        return self.machine.distribution

    @property
    def spread(self) -> float:
        """σ of an error per unit of its tolerance over ``1/k``: 1 under the normal reading,
        the truncated normal's 0.9866 (k = 3) under the truncated one."""
        return float(error_sigma(1.0, self.k, self.distribution)) * self.k

    @property
    def required_index(self) -> np.ndarray:
        """β each output needs at zero mean: ``z_o`` for the chosen side."""
        return required_index(self.machine.targets, self.side)

    @property
    def allowed_sigma(self) -> np.ndarray:
        """Largest σ of each output that meets its target, ``I_o / z_o``."""
        return self.machine.limits / self.required_index

    def row_matrix(self, jacobian=None) -> np.ndarray:
        """Rows ``(J_oi s/k)² / (I_o/z_o)²`` with ``s`` = :attr:`spread` (1 under the
        normal reading), or ``|J_oi| / I_o`` for the stack, as
        ``(n_poses, 6, n_errors)``, of the problem's poses or of the given sensitivities;
        with a life target, ``(J_oi s/k)² / A`` with ``A`` the row's own largest σ0²
        (:meth:`allocation.per_pose.life.LifeRequirement.allowed_variance`)."""
        if jacobian is None:
            jacobian = self.machine.jacobian(self.poses) if self.jacobian is None \
                else self.jacobian
        if self.side == "stack":
            return np.abs(jacobian) / self.machine.limits[:, None]
        rows = np.square(jacobian / self.k * self.spread)
        if self.life is not None:  # the row's own largest σ0² (allocation.per_pose.life)
            with np.errstate(divide="ignore"):
                return rows / self.life.allowed_variance(jacobian)[..., None]
        return rows / np.square(self.allowed_sigma)[:, None]

    def with_life(self, life) -> "AllocationProblem":
        """The same poses, box and costs with the life target ``life``
        (:class:`allocation.per_pose.life.LifeRequirement`) in every row, screened
        again."""
        problem = replace(self, life=life, rows=None)
        return replace(problem, rows=problem._screen())

    def loads(self, u) -> np.ndarray:
        """Row loads ``row @ u`` of every output at every pose, ``(n_poses, 6)``, in
        chunks (σ² over the allowed σ², for ``u = t²``)."""
        out = np.empty((len(self.poses), len(OUTPUTS)))
        for part, block in self.jacobian_chunks():
            out[part] = self.row_matrix(block) @ u
        return out

    def reaching_factor(self) -> float:
        """The largest ``f`` with which ``f ×`` the reference allocation meets every row:
        the largest lower-bound factor (``--bounds f HI``) that can reach the targets.

        A row's load at ``f t`` is ``f^(2/p)`` times its load at ``t`` (``p`` =
        :attr:`variable_power`), so ``f = (max load at the reference)^(−p/2)``.
        """
        worst = float(self.loads(self.variable(self.reference)).max())
        return worst ** (-self.variable_power / 2.0)

    def with_poses(self, extra) -> "AllocationProblem":
        """The same problem with more poses; their rows are added unscreened."""
        extra = _checked_poses(self.machine, extra, False, "extra")
        jacobian = self.machine.jacobian(extra)
        rows = self.rows
        if rows is not None:
            added = self.row_matrix(jacobian)
            counts = dict(rows.counts, added=rows.counts.get("added", 0) + added[:, :, 0].size)
            rows = ScreenedRows(
                matrix=np.vstack([rows.matrix, added.reshape(-1, added.shape[-1])]),
                pose=np.concatenate([rows.pose, len(self.poses) + np.repeat(
                    np.arange(len(extra)), len(OUTPUTS))]),
                output=np.concatenate([rows.output, np.tile(np.arange(len(OUTPUTS)),
                                                            len(extra))]),
                counts=counts)
        joined = None if self.jacobian is None else np.concatenate([self.jacobian, jacobian])
        return replace(self, poses=np.vstack([self.poses, extra]), jacobian=joined, rows=rows)

    # ----- evaluation ----------------------------------------------------------------
    def sigma(self, t) -> np.ndarray:
        """σ of every output at every pose, ``(..., n_poses, 6)`` for ``t (..., n)``."""
        variance_x = np.square(error_sigma(t, self.k, self.distribution))
        out = np.empty(variance_x.shape[:-1] + (len(self.poses), len(OUTPUTS)))
        for part, block in self.jacobian_chunks():
            out[..., part, :] = np.sqrt(np.einsum("pon,...n->...po", np.square(block),
                                                  variance_x))  # Eq. (20)
        return out

    def probability(self, t) -> np.ndarray:
        """FOSM probability of the chosen side (two-sided for the stack),
        ``(..., n_poses, 6)``."""
        side = "two_sided" if self.side == "stack" else self.side
        return probability(self.machine.limits, self.sigma(t), side)

    def stack(self, t) -> np.ndarray:
        """Worst-case stack ``Σ_i |J_oi| t_i`` of every output at every pose,
        ``(..., n_poses, 6)``."""
        t = np.asarray(t, dtype=float)
        out = np.empty(t.shape[:-1] + (len(self.poses), len(OUTPUTS)))
        for part, block in self.jacobian_chunks():
            out[..., part, :] = np.einsum("pon,...n->...po", np.abs(block), t)
        return out

    def violation(self, t) -> np.ndarray:
        """Total constraint violation ``(...,)``, 0 when ``t`` meets every target.

        Worst case: Σ over the screened rows of ``max(0, load − 1)``, in units of the
        allowed variance. Mean: Σ over outputs of ``max(0, R_o − mean_p P)``.
        """
        t = np.asarray(t, dtype=float)
        if self.workspace == "worst":
            load = self.variable(t) @ self.rows.matrix.T
            return np.maximum(load - 1.0, 0.0).sum(axis=-1)
        shortfall = self.machine.targets - self.probability(t).mean(axis=-2)
        return np.maximum(shortfall, 0.0).sum(axis=-1)

    def evaluate(self, t) -> pd.DataFrame:
        """Per output: worst-pose and mean probability (both sides) and the verdict."""
        result = fosm(self.machine, t, self.poses, k=self.k, jacobian=self.jacobian,
                      distribution=self.distribution)
        frame = result.to_frame()
        if self.side == "stack":
            frame["worst_stack"] = self.stack(t).max(axis=0)
            frame["meets"] = frame["worst_stack"].to_numpy() <= self.machine.limits
            return frame
        frame["required"] = self.machine.targets
        frame["meets"] = result.meets_targets(self.side, self.workspace)
        return frame

    def meets_targets(self, t) -> bool:
        """True when ``t`` satisfies every constraint of this problem (all poses)."""
        if self.side == "stack":
            return bool(np.all(self.stack(t) <= self.machine.limits * (1 + 1e-12)))
        if self.life is not None:  # σ0² within its row's own largest value (1e-9: the roots')
            return bool(np.all(self.loads(self.variable(t)) <= 1.0 + 1e-9))
        probability = self.probability(np.asarray(t, dtype=float))
        value = probability.min(axis=0) if self.workspace == "worst" else \
            probability.mean(axis=0)
        return bool(np.all(value >= self.machine.targets * (1 - 1e-12)))

    # ----- solvers -------------------------------------------------------------------
    def solve_exact(self, **options):
        """Certified optimum; see :func:`allocation.per_pose.solve.solve_exact`."""
        return solve.solve_exact(self, **options)

    def solve_gwo(self, **options):
        """Grey Wolf Optimiser as in the paper; see :func:`allocation.per_pose.solve.solve_gwo`."""
        return solve.solve_gwo(self, **options)


def screen_rows(rows, upper_u) -> ScreenedRows:
    """Remove rows that can never bind inside the box (box, duplicate, dominance).

    Parameters
    ----------
    rows : ndarray (n_poses, 6, n)
        Normalised rows; the constraint is ``row @ u ≤ 1``.
    upper_u : ndarray (n,)
        Upper bounds of ``u = t²``.
    """
    rows = np.asarray(rows, dtype=float)
    return _screen_parts([(0, rows)], np.asarray(upper_u, dtype=float), rows.shape[0],
                         rows.shape[1])


def _screen_parts(parts, upper_u, n_poses, n_outputs=len(OUTPUTS)) -> ScreenedRows:
    """:func:`screen_rows` over ``(first_pose, rows)`` chunks in pose order.

    Each chunk is box-screened and deduplicated on its own; the survivors of all chunks
    are then deduplicated together (keeping each row's first pose, as over all rows at
    once) and screened for dominance.
    """
    pooled = [([], []) for _ in range(n_outputs)]
    counts = {"candidates": n_poses * n_outputs, "box": 0, "duplicates": 0, "dominance": 0}
    for first, rows in parts:
        for output in range(n_outputs):
            matrix = rows[:, output, :]
            pose = np.flatnonzero(matrix @ upper_u > 1.0)
            counts["box"] += len(pose)
            pose = pose[_unique_rows(matrix[pose])]
            pooled[output][0].append(matrix[pose])
            pooled[output][1].append(first + pose)
    kept_rows, kept_pose, kept_output = [], [], []
    for output, (matrices, poses) in enumerate(pooled):
        matrix = np.concatenate(matrices) if matrices else np.zeros((0, len(upper_u)))
        pose = np.concatenate(poses) if poses else np.zeros(0, dtype=int)
        unique = _unique_rows(matrix)
        matrix, pose = matrix[unique], pose[unique]
        counts["duplicates"] += len(pose)
        keep = _undominated(matrix)
        counts["dominance"] += len(keep)
        kept_rows.append(matrix[keep])
        kept_pose.append(pose[keep])
        kept_output.append(np.full(len(keep), output))
    return ScreenedRows(matrix=np.concatenate(kept_rows), pose=np.concatenate(kept_pose),
                        output=np.concatenate(kept_output), counts=counts)


def _unique_rows(matrix) -> np.ndarray:
    """Indices of the first row of each set of rows equal to :data:`DUPLICATE_DIGITS`
    significant digits (their shape and their size), found on two rounding grids so that
    rows equal but for rounding count once on every computer
    (:func:`reliability.basics.ties.first_of_equal_rows`)."""
    if len(matrix) == 0:
        return np.arange(0)
    scale = matrix.max(axis=1, keepdims=True)
    scale[scale == 0] = 1.0
    keyed = np.hstack([matrix / scale, np.log(scale)]) / 10.0 ** -DUPLICATE_DIGITS
    return first_of_equal_rows(keyed)


def _undominated(matrix, block: int = 512) -> np.ndarray:
    """Indices of rows not dominated entrywise by another row (duplicates already gone).

    Rows are visited in order of decreasing sum: only a row with a larger sum can dominate
    (a row with an equal sum that dominates is equal, and duplicates are gone). Each block
    is compared with the rows kept so far and with itself. Comparing with kept rows only is
    exact: a row dominated by a discarded row is dominated by whatever row discarded it
    (dominance is transitive), and that chain ends at a kept row. Columns equal in every
    row never decide dominance and are left out of the comparisons.
    """
    if len(matrix) == 0:
        return np.arange(0)
    # entries equal but for rounding made equal; rows then equal count once (the first)
    canonical = _equal_entries_equal(matrix)
    distinct = np.sort(np.unique(canonical, axis=0, return_index=True)[1])
    return distinct[_undominated_distinct(canonical[distinct], block)]


def _undominated_distinct(matrix, block: int) -> np.ndarray:
    """:func:`_undominated` of rows no two of which are equal."""
    varying = np.flatnonzero(np.ptp(matrix, axis=0) > 0)
    order = np.argsort(-matrix.sum(axis=1), kind="stable")
    sorted_rows = np.ascontiguousarray(matrix[order][:, varying])
    kept = np.zeros((0, len(varying)))
    keep = np.zeros(len(order), dtype=bool)
    for start in range(0, len(order), block):
        index = np.arange(start, min(start + block, len(order)))
        for first in range(0, len(kept), block):  # most rows fall to the first kept rows
            index = index[~_covered(sorted_rows[index], kept[first:first + block])]
        index = index[~_covered(sorted_rows[index], sorted_rows[index], skip_self=True)]
        keep[index] = True
        kept = np.concatenate([kept, sorted_rows[index]])
    return np.sort(order[keep])


def _equal_entries_equal(matrix) -> np.ndarray:
    """``matrix`` with the entries of each column that are equal but for rounding (apart by
    at most :data:`ENTRY_RTOL` of the larger, consecutively in sorted order) replaced by
    the smallest of them, so that dominance, an exact comparison, does not depend on which
    way the rounding of equal entries went on this computer."""
    order = np.argsort(matrix, axis=0, kind="stable")
    ordered = np.take_along_axis(matrix, order, axis=0)
    new_group = np.diff(ordered, axis=0) > ENTRY_RTOL * np.abs(ordered[1:])
    group = np.vstack([np.zeros((1, matrix.shape[1]), dtype=int),
                       np.cumsum(new_group, axis=0)])
    columns = np.arange(matrix.shape[1])
    first = np.full((group.max() + 1 if group.size else 0, matrix.shape[1]), np.inf)
    np.minimum.at(first, (group, np.broadcast_to(columns, group.shape)), ordered)
    canonical = np.empty_like(matrix)
    np.put_along_axis(canonical, order, first[group, columns], axis=0)
    return canonical


def _covered(rows, dominators, skip_self: bool = False) -> np.ndarray:
    """Which ``rows`` are ≤ some row of ``dominators`` in every entry.

    Candidate pairs are filtered one column at a time, so the work shrinks with the pairs
    still standing instead of comparing every pair in every column.
    """
    if len(rows) == 0 or len(dominators) == 0:
        return np.zeros(len(rows), dtype=bool)
    if rows.shape[1] == 0:  # every row equal: only another row can cover
        return np.full(len(rows), len(dominators) > 1 or not skip_self)
    row, other = np.nonzero(dominators[None, :, 0] >= rows[:, None, 0])
    if skip_self:
        row, other = row[row != other], other[row != other]
    for column in range(1, rows.shape[1]):
        if len(row) == 0:
            break
        standing = dominators[other, column] >= rows[row, column]
        row, other = row[standing], other[standing]
    covered = np.zeros(len(rows), dtype=bool)
    covered[row] = True
    return covered


def with_requirements(machine, *, targets=None, limits=None):
    """``machine`` with some outputs' targets or limits replaced.

    Parameters
    ----------
    machine : Machine
    targets, limits : mapping, optional
        ``{output name: value}``; targets in (0, 1), limits finite and > 0.

    Raises
    ------
    InputError, InputTypeError
        Naming the argument and the offending output or value.
    """
    changes = {}
    for what, values in (("targets", targets), ("limits", limits)):
        if values is None:
            continue
        if not hasattr(values, "items"):
            raise InputTypeError(f"{what} must be a mapping {{output name: value}}; "
                                 f"got {type(values).__name__}")
        vector = np.array(getattr(machine, what), dtype=float)
        for name, value in values.items():
            if name not in OUTPUTS:
                raise InputError(f"{what}: unknown output {name!r}; use one of {OUTPUTS}")
            vector[OUTPUTS.index(name)] = _requirement(what, name, value)
        changes[what] = vector
    return replace(machine, **changes) if changes else machine


def _requirement(what, name, value) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.number)):
        raise InputTypeError(f"{what}[{name!r}] must be a number; got {value!r}")
    value = float(value)
    if what == "targets" and not 0.0 < value < 1.0:
        raise InputError(f"targets[{name!r}] must lie in (0, 1); got {value!r}")
    if what == "limits" and not (np.isfinite(value) and value > 0):
        raise InputError(f"limits[{name!r}] must be finite and > 0; got {value!r}")
    return value


def _check_choice(value, allowed, what) -> None:
    checks.choice(value, what, allowed)


def _checked_poses(machine, poses, allow_outside_stroke, name="poses") -> np.ndarray:
    poses = np.atleast_2d(machine.check_positions(poses))
    if poses.ndim != 2 or len(poses) == 0:
        raise InputError(f"{name} must have shape (n_poses, {len(machine.axes)}) with at "
                         f"least one pose; got {poses.shape}")
    return checks.poses_in_strokes(machine, poses, name, allow_outside_stroke)


def _reference(machine, reference) -> np.ndarray:
    if reference is None:
        return machine.initial_allocation.copy()
    if hasattr(reference, "items"):
        reference = machine.error_vector(reference, default=None)
    return machine.check_tolerances(reference).astype(float)


#: The box when neither the caller nor the machine file gives one: factors of the reference.
DEFAULT_FACTORS = (0.5, 1.5)


def bounds_source(machine, bounds, lower=None, upper=None) -> str:
    """Which box :meth:`AllocationProblem.build` uses for these arguments."""
    if bounds is not None or lower is not None or upper is not None:
        return "given"
    if getattr(machine, "tolerance_bounds", None) is not None:
        return "machine file"
    return "factors of the initial allocation"


def _span(lower, upper, machine, angular: bool) -> str:
    mask = np.array([n.split(".")[1].startswith("e") == angular for n in machine.error_names])
    return f"{lower[mask].min():g}–{upper[mask].max():g}"


def _bounds(machine, reference, bounds, lower, upper, locked):
    """Tolerance bounds from factors of the reference or explicit arrays, with locks."""
    if isinstance(bounds, (str, bytes)) or not hasattr(bounds, "__len__") or len(bounds) != 2:
        raise InputTypeError(f"bounds must be two factors (low, high); got {bounds!r}")
    low_factor, high_factor = (checks.finite_float(b, "bounds", 0.0, low_open=True)
                               for b in bounds)
    if low_factor > high_factor:
        raise InputError(f"bounds must be finite factors 0 < low <= high; got {bounds!r}")
    low = reference * low_factor if lower is None else machine.check_tolerances(lower)
    high = reference * high_factor if upper is None else machine.check_tolerances(upper)
    low, high = np.array(low, dtype=float), np.array(high, dtype=float)
    bad = np.flatnonzero(low > high)
    if len(bad):
        raise InputError(f"lower bound exceeds upper bound for {machine.error_names[bad[0]]!r}")
    if not isinstance(locked, str) and not hasattr(locked, "__iter__"):
        raise InputTypeError(f"locked must be an error name or names; got {locked!r}")
    for name in (locked,) if isinstance(locked, str) else locked:
        index = machine.error_index(name)
        low[index] = high[index] = reference[index]
    return low, high
