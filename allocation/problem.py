"""The precision-allocation problem of Eq. (34), built from a machine and a pose set.

    minimise    F(t) = Σ_i w_i / t_i²                                  (Eq. 28)
    subject to  P_o(pose, t) ≥ R_o for every output o and pose          (Eqs. 24, 35)
                lower_i ≤ t_i ≤ upper_i

With FOSM (Eqs. 19–23) at zero error mean, ``P ≥ R`` at a pose is ``σ_o ≤ I_o / z_o`` with
``z = Φ⁻¹(R)`` (the paper's one-sided reading) or ``z = Φ⁻¹((1 + R)/2)`` (exact two-sided);
in ``u = t²`` it is the linear row ``Σ_i J_oi² u_i / k² ≤ (I_o / z_o)²``. The workspace
constraint of Eq. (35) is read as "at every pose of the grid" (DESIGN §2); a
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
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import pandas as pd

from reliability import checks
from reliability.errors import InputError, InputTypeError
from reliability.fosm import error_sigma, fosm, probability, required_index
from reliability.machine import OUTPUTS
from reliability.poses import workspace_grid

from .cost import CostModel

SIDES = ("one_sided", "two_sided", "stack")
WORKSPACES = ("worst", "mean")
DUPLICATE_DIGITS = 10  # rows equal to 10 significant digits count as one


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
    jacobian : ndarray (n_poses, 6, n_errors)
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

    @classmethod
    def build(cls, machine, poses=None, *, side: str = "two_sided", workspace: str = "worst",
              bounds=(0.5, 1.5), lower=None, upper=None, locked=(), reference=None,
              k: float = 3.0, cost_factors=(1.0, 1.0, 1.0), targets=None, limits=None,
              allow_outside_stroke: bool = False,
              budget: int | None = None) -> "AllocationProblem":
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
            Target at every pose (Eq. 35 as read in DESIGN §2) or on the workspace mean.
        bounds : (float, float)
            Default box as multiples of ``reference`` ([0.5, 1.5]: Table 6 moves no item by
            more than +50 %).
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
            Bytes the grid and the Jacobian may take (default
            :data:`reliability.checks.DEFAULT_BUDGET`).
        """
        _check_choice(side, SIDES, "side")
        _check_choice(workspace, WORKSPACES, "workspace")
        if getattr(machine, "correlation", None) is not None:
            raise InputError("machine: its errors are correlated (machine.correlation) but "
                             "these constraint rows assume independent errors; use "
                             "allocation.correlated.solve_correlated")
        if side == "stack" and workspace != "worst":
            raise InputError("side='stack' is a worst-case reading; use workspace='worst'")
        machine = with_requirements(machine, targets=targets, limits=limits)
        k = checks.finite_float(k, "coverage factor k", 0.0, low_open=True)
        poses = workspace_grid(machine, budget=budget) if poses is None else \
            _checked_poses(machine, poses, allow_outside_stroke)
        checks.require_size(len(poses), 2 * 6 * machine.n_errors * 8, budget,
                            "the Jacobian and rows of the allocation problem",
                            "pass fewer poses (a coarser grid)")
        reference = _reference(machine, reference)
        low, high = _bounds(machine, reference, bounds, lower, upper, locked)
        jacobian = machine.jacobian(poses)
        problem = cls(machine=machine, poses=poses, jacobian=jacobian, side=side,
                      workspace=workspace, k=float(k), lower=low, upper=high,
                      reference=reference, cost=CostModel.from_machine(machine, *cost_factors),
                      rows=None)
        if workspace == "worst":
            object.__setattr__(problem, "rows", screen_rows(problem.row_matrix(),
                                                            problem.variable(high)))
        return problem

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
    def required_index(self) -> np.ndarray:
        """β each output needs at zero mean: ``z_o`` for the chosen side."""
        return required_index(self.machine.targets, self.side)

    @property
    def allowed_sigma(self) -> np.ndarray:
        """Largest σ of each output that meets its target, ``I_o / z_o``."""
        return self.machine.limits / self.required_index

    def row_matrix(self, jacobian=None) -> np.ndarray:
        """Rows ``J_oi² / (k² (I_o/z_o)²)`` (or ``|J_oi| / I_o`` for the stack) as
        ``(n_poses, 6, n_errors)``, of the problem's poses or of the given sensitivities."""
        jacobian = self.jacobian if jacobian is None else jacobian
        if self.side == "stack":
            return np.abs(jacobian) / self.machine.limits[:, None]
        return np.square(jacobian / self.k) / np.square(self.allowed_sigma)[:, None]

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
        return replace(self, poses=np.vstack([self.poses, extra]),
                       jacobian=np.concatenate([self.jacobian, jacobian]), rows=rows)

    # ----- evaluation ----------------------------------------------------------------
    def sigma(self, t) -> np.ndarray:
        """σ of every output at every pose, ``(..., n_poses, 6)`` for ``t (..., n)``."""
        sigma_x = error_sigma(t, self.k)
        return np.sqrt(np.einsum("pon,...n->...po", np.square(self.jacobian),
                                 np.square(sigma_x)))  # Eq. (20)

    def probability(self, t) -> np.ndarray:
        """FOSM probability of the chosen side (two-sided for the stack),
        ``(..., n_poses, 6)``."""
        side = "two_sided" if self.side == "stack" else self.side
        return probability(self.machine.limits, self.sigma(t), side)

    def stack(self, t) -> np.ndarray:
        """Worst-case stack ``Σ_i |J_oi| t_i`` of every output at every pose,
        ``(..., n_poses, 6)``."""
        return np.einsum("pon,...n->...po", np.abs(self.jacobian), np.asarray(t, float))

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
        result = fosm(self.machine, t, self.poses, k=self.k, jacobian=self.jacobian)
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
        probability = self.probability(np.asarray(t, dtype=float))
        value = probability.min(axis=0) if self.workspace == "worst" else \
            probability.mean(axis=0)
        return bool(np.all(value >= self.machine.targets * (1 - 1e-12)))

    # ----- solvers -------------------------------------------------------------------
    def solve_exact(self, **options):
        """Certified optimum; see :func:`allocation.solve.solve_exact`."""
        from .solve import solve_exact

        return solve_exact(self, **options)

    def solve_gwo(self, **options):
        """Grey Wolf Optimiser as in the paper; see :func:`allocation.solve.solve_gwo`."""
        from .solve import solve_gwo

        return solve_gwo(self, **options)


def screen_rows(rows, upper_u) -> ScreenedRows:
    """Remove rows that can never bind inside the box (box, duplicate, dominance).

    Parameters
    ----------
    rows : ndarray (n_poses, 6, n)
        Normalised rows; the constraint is ``row @ u ≤ 1``.
    upper_u : ndarray (n,)
        Upper bounds of ``u = t²``.
    """
    n_poses, n_outputs, n = rows.shape
    counts = {"candidates": n_poses * n_outputs, "box": 0, "duplicates": 0, "dominance": 0}
    kept_rows, kept_pose, kept_output = [], [], []
    for output in range(n_outputs):
        matrix = rows[:, output, :]
        pose = np.flatnonzero(matrix @ upper_u > 1.0)
        counts["box"] += len(pose)
        pose = pose[_unique_rows(matrix[pose])]
        counts["duplicates"] += len(pose)
        pose = pose[_undominated(matrix[pose])]
        counts["dominance"] += len(pose)
        kept_rows.append(matrix[pose])
        kept_pose.append(pose)
        kept_output.append(np.full(len(pose), output))
    return ScreenedRows(matrix=np.concatenate(kept_rows), pose=np.concatenate(kept_pose),
                        output=np.concatenate(kept_output), counts=counts)


def _unique_rows(matrix) -> np.ndarray:
    """Indices of the first occurrence of each distinct row (to DUPLICATE_DIGITS)."""
    if len(matrix) == 0:
        return np.arange(0)
    scale = matrix.max(axis=1, keepdims=True)
    scale[scale == 0] = 1.0
    key = np.round(matrix / scale, DUPLICATE_DIGITS) * scale
    _, first = np.unique(key, axis=0, return_index=True)
    return np.sort(first)


def _undominated(matrix, block: int = 256) -> np.ndarray:
    """Indices of rows not dominated entrywise by another row (duplicates already gone).

    Rows are compared in order of decreasing sum: only a row with a larger sum can
    dominate, so each block is tested against the rows before it and itself.
    """
    order = np.argsort(-matrix.sum(axis=1), kind="stable")
    sorted_rows = matrix[order]
    dominated = np.zeros(len(order), dtype=bool)
    for start in range(0, len(order), block):
        stop = min(start + block, len(order))
        candidates = sorted_rows[:stop]
        covers = np.all(candidates[None, :, :] >= sorted_rows[start:stop, None, :], axis=-1)
        covers[np.arange(stop - start), np.arange(start, stop)] = False
        dominated[start:stop] = covers.any(axis=1)
    return np.sort(order[~dominated])


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
        raise ValueError(f"lower bound exceeds upper bound for {machine.error_names[bad[0]]!r}")
    if not isinstance(locked, str) and not hasattr(locked, "__iter__"):
        raise InputTypeError(f"locked must be an error name or names; got {locked!r}")
    for name in (locked,) if isinstance(locked, str) else locked:
        index = machine.error_index(name)
        low[index] = high[index] = reference[index]
    return low, high
