"""Grey Wolf Optimiser (Mirjalili, Mirjalili & Lewis 2014; the paper's ref. 63, Sec. 4.4).

The paper solves its allocation model (Eq. 34) with GWO, 100 wolves and 500 iterations.
This module implements GWO as published:

* the pack is led by the three best positions found so far in the run, alpha, beta and
  delta (distinct positions; a new best demotes alpha to beta and beta to delta, as the
  article describes; commonly circulated code skips this demotion);
* the control parameter ``a`` decreases linearly from 2 towards 0: the ``l``-th move of
  ``n_iterations`` uses ``a = 2 (1 - l / n_iterations)``, ``l = 0, 1, ...``, as in the
  authors' reference code;
* for every wolf, dimension and leader ``k`` independent ``r1, r2 ~ U(0, 1)`` give
  ``A = 2 a r1 - a``, ``C = 2 r2``, ``D = |C X_k - X|``, ``X'_k = X_k - A D``, and the
  wolf moves to ``(X'_alpha + X'_beta + X'_delta) / 3``;
* a coordinate that leaves the search box is put back on the bound it crossed (clipping).
  This repair is part of the published algorithm, not a silent correction of user input.

Hu et al. do not say how their GWO handled the reliability constraints. Here they are
handled by Deb's feasibility rules (K. Deb, Comput. Methods Appl. Mech. Eng. 186 (2000)
311-338), which need no penalty factor: a feasible position beats an infeasible one, two
feasible ones compare by objective, two infeasible ones by total violation (ties broken
by objective, then by who came first). The search runs in normalised coordinates ``z`` in
``[0, 1]^d``, mapped to ``x = lower (1 - z) + upper z``, so that dimensions of very
different scale (tolerances in mm and rad) move alike.

:func:`grey_wolf` is vectorised over the pack. :func:`grey_wolf_reference` is the same
algorithm written as a plain loop over wolves, dimensions and leaders; it draws the random
numbers in the same order (initial pack row by row, then per move wolf by wolf, dimension
by dimension, leader alpha, beta, delta, ``r1`` before ``r2``), so with the same seed both
follow the same trajectory. It is the yardstick of the benchmark.

A note on precision. ``C`` is random around 1, so ``D = |C X_k - X|`` does not vanish
when the pack has gathered at a leader unless that leader sits at the origin of the search
coordinates (``z = 0``, the box's lower corner). Near the end of a run only the shrinking
``a`` (``2 / n_iterations`` at the last move) reduces the steps, and the attainable
resolution is about that times the normalised coordinate of the optimum. GWO therefore
ends close to, but not at, an interior optimum; the allocation problem's exact optimum is
computed by :mod:`allocation.solvers.convex` and GWO is measured against it.
"""

from dataclasses import dataclass
from operator import index
from typing import NamedTuple

import numpy as np
import pandas as pd

from reliability.basics import streams
from reliability.basics.errors import InputError
from reliability.basics.saved_fields import (Array, Flag, Frame, Integer, Number, load_fields,
                                            save_fields)

__all__ = ["GwoResult", "grey_wolf", "grey_wolf_reference"]

N_LEADERS = 3


@dataclass(frozen=True, eq=False)
class GwoResult:
    """Outcome of a Grey Wolf Optimiser run.

    Attributes
    ----------
    x : numpy.ndarray, shape (d,)
        Best position found (alpha), under Deb's feasibility rules.
    fun : float
        Objective at ``x``.
    violation : float
        Total constraint violation at ``x`` (0 when feasible).
    feasible : bool
        Whether ``x`` satisfies the constraints (``violation == 0``).
    history : pandas.DataFrame
        One row per iteration (0 = the initial pack): columns ``fun``, ``violation`` and
        ``feasible`` of the alpha wolf after that iteration.
    n_evaluations : int
        Number of positions evaluated, ``n_wolves * (n_iterations + 1)``.
    """

    x: np.ndarray
    fun: float
    violation: float
    feasible: bool
    history: pd.DataFrame
    n_evaluations: int

    def to_frame(self):
        """One-row summary (``fun``, ``violation``, ``feasible``, ``n_evaluations``).

        Concatenate the frames of several runs (seeds) to compare them; the trajectory
        is in :attr:`history`.
        """
        return pd.DataFrame(
            {
                "fun": [self.fun],
                "violation": [self.violation],
                "feasible": [self.feasible],
                "n_evaluations": [self.n_evaluations],
            }
        )

    def summary(self) -> str:
        """The best objective, its feasibility and the run's length."""
        verdict = "feasible" if self.feasible else f"NOT feasible (violation {self.violation:.3g})"
        return (f"Grey Wolf Optimiser: best objective {self.fun:.6g}, {verdict}; "
                f"{self.n_evaluations} evaluations over {len(self.history) - 1} iterations")

    def save(self, path, overwrite: bool = False):
        """Save as JSON (:data:`SAVED_FIELDS`, tag :data:`SAVED_FORMAT`); an existing file
        is kept unless ``overwrite``. Returns the path."""
        return save_fields(self, path, SAVED_FORMAT, SAVED_FIELDS, overwrite)

    @classmethod
    def load(cls, path) -> "GwoResult":
        """Reload a run written by :meth:`save`, checked: feasible exactly when the
        violation is 0. A damaged field raises
        :class:`~reliability.basics.errors.SavedResultError` naming the file and field."""
        data, values = load_fields(path, SAVED_FORMAT, SAVED_FIELDS)
        if values["feasible"] != (values["violation"] == 0):
            raise data.error("feasible", "must be true exactly when 'violation' is 0")
        return cls(**values)


SAVED_FORMAT = "precrel.gwo_result"
SAVED_FIELDS = (Array("x", (None,)), Number("fun"), Number("violation", low=0.0),
                Flag("feasible"), Frame("history", ("fun", "violation", "feasible")),
                Integer("n_evaluations", low=1))


def grey_wolf(
    objective,
    lower,
    upper,
    *,
    violation=None,
    n_wolves=100,
    n_iterations=500,
    rng=None,
    initial=None,
    progress=None,
):
    """Minimise ``objective`` over a box with the Grey Wolf Optimiser.

    Parameters
    ----------
    objective : callable
        ``objective(X)`` with ``X`` of shape (n_wolves, d) returns shape (n_wolves,).
        ``+inf`` is allowed, NaN is an error.
    lower, upper : array_like, shape (d,)
        Search box, finite, ``lower < upper`` elementwise.
    violation : callable, optional
        ``violation(X)`` returns the total constraint violation, shape (n_wolves,),
        ``>= 0`` with 0 meaning feasible. Default: unconstrained.
    n_wolves : int, optional
        Pack size, at least 3 (default 100, as in the paper).
    n_iterations : int, optional
        Number of moves of the pack, at least 1 (default 500, as in the paper).
    rng : None, int or numpy.random.Generator, optional
        Passed to :func:`reliability.basics.streams.generator`.
    initial : array_like, shape (m, d) or (d,), optional
        Starting positions inside the box, placed as the first ``m <= n_wolves`` wolves;
        the others start uniformly at random.
    progress : callable, optional
        Called after every iteration as ``progress(iteration, fun, violation)`` with the
        alpha wolf's objective and violation.

    Returns
    -------
    GwoResult

    Raises
    ------
    InputError
        On a bad box, pack size, iteration count or initial position (named in the
        message), or when ``objective``/``violation`` return a bad shape, NaN or a
        negative violation.
    """
    problem = _Problem.build(
        objective, lower, upper, violation, n_wolves, n_iterations, initial
    )
    rng = streams.generator(rng)
    z = _initial_pack(problem, rng)
    leaders = _select_leaders(_Wolves(z, *problem.evaluate(z)))
    history = [leaders.summary()]
    for move in range(problem.n_iterations):
        a = _control_parameter(move, problem.n_iterations)
        z = _move_pack(z, _guides(leaders.z), a, rng)
        pack = _Wolves(z, *problem.evaluate(z))
        leaders = _select_leaders(_Wolves(*map(_stack, leaders, pack)))
        history.append(leaders.summary())
        _report(progress, move + 1, history[-1])
    return problem.result(leaders.z[0], history)


def grey_wolf_reference(
    objective,
    lower,
    upper,
    *,
    violation=None,
    n_wolves=100,
    n_iterations=500,
    rng=None,
    initial=None,
    progress=None,
):
    """Grey Wolf Optimiser written as a plain loop over wolves; a reference for testing.

    Same parameters, result and random-number order as :func:`grey_wolf`, so the same
    ``rng`` seed gives the same trajectory. ``objective`` and ``violation`` are called
    on one wolf at a time (``X`` of shape (1, d)). The leaders are kept as a short list
    into which every newly evaluated wolf is inserted in turn (strictly better than a
    leader: goes before it; same position as a leader: ignored; list cut to three).
    """
    problem = _Problem.build(
        objective, lower, upper, violation, n_wolves, n_iterations, initial
    )
    rng = streams.generator(rng)
    n, d = problem.n_wolves, problem.dimension
    pack = [list(row) for row in problem.initial]
    for _ in range(n - len(pack)):
        pack.append([rng.random() for _ in range(d)])
    leaders = []
    for position in pack:
        _insert_leader(leaders, position, problem)
    history = [_reference_summary(leaders)]
    for move in range(problem.n_iterations):
        a = _control_parameter(move, problem.n_iterations)
        guides = [leader[1] for leader in leaders]
        guides += [guides[-1]] * (N_LEADERS - len(guides))
        for i in range(n):
            for j in range(d):
                moved = []
                for guide in guides:
                    r1 = rng.random()
                    r2 = rng.random()
                    big_a = 2 * a * r1 - a
                    big_c = 2 * r2
                    distance = abs(big_c * guide[j] - pack[i][j])
                    moved.append(guide[j] - big_a * distance)
                new = (moved[0] + moved[1] + moved[2]) / 3
                pack[i][j] = min(max(new, 0.0), 1.0)
        for position in pack:
            _insert_leader(leaders, position, problem)
        history.append(_reference_summary(leaders))
        _report(progress, move + 1, history[-1])
    return problem.result(np.array(leaders[0][1]), history)


@dataclass(frozen=True, eq=False)
class _Problem:
    """Validated inputs shared by both implementations."""

    objective: object
    violation: object
    lower: np.ndarray
    upper: np.ndarray
    n_wolves: int
    n_iterations: int
    initial: np.ndarray

    @classmethod
    def build(cls, objective, lower, upper, violation, n_wolves, n_iterations, initial):
        lower, upper = _check_box(lower, upper)
        n_wolves = _check_count(n_wolves, "n_wolves", N_LEADERS)
        n_iterations = _check_count(n_iterations, "n_iterations", 1)
        initial = _check_initial(initial, lower, upper, n_wolves)
        return cls(objective, violation, lower, upper, n_wolves, n_iterations, initial)

    @property
    def dimension(self):
        return self.lower.size

    def to_x(self, z):
        """Map normalised positions to the box."""
        return self.lower * (1.0 - z) + self.upper * z

    def evaluate(self, z):
        """Objective and total violation of the positions ``z`` (n, d)."""
        x = self.to_x(z)
        fun = _checked_output(self.objective(x), x.shape[0], "objective")
        if self.violation is None:
            return fun, np.zeros_like(fun)
        vio = _checked_output(self.violation(x), x.shape[0], "violation")
        negative = np.flatnonzero(vio < 0)
        if negative.size:
            raise InputError(
                f"violation returned {vio[negative[0]]} < 0 for row {negative[0]}; "
                "it must be >= 0 (0 = feasible)"
            )
        return fun, vio

    def result(self, best_z, history):
        frame = pd.DataFrame(history, columns=["fun", "violation", "feasible"])
        frame.index.name = "iteration"
        best = frame.iloc[-1]
        return GwoResult(
            x=self.to_x(np.asarray(best_z, dtype=float)),
            fun=float(best["fun"]),
            violation=float(best["violation"]),
            feasible=bool(best["feasible"]),
            history=frame,
            n_evaluations=self.n_wolves * (self.n_iterations + 1),
        )


class _Wolves(NamedTuple):
    """Positions (normalised) of some wolves with their objectives and violations."""

    z: np.ndarray
    fun: np.ndarray
    violation: np.ndarray

    def summary(self):
        """``(fun, violation, feasible)`` of the first wolf, a history row."""
        return float(self.fun[0]), float(self.violation[0]), bool(self.violation[0] == 0)


def _stack(first, second):
    return np.concatenate([first, second])


def _control_parameter(move, n_iterations):
    """``a`` of the ``move``-th move: 2 at the first, decreasing linearly towards 0."""
    return 2.0 * (1.0 - move / n_iterations)


def _initial_pack(problem, rng):
    """Given starting positions first, then uniform random rows."""
    n_random = problem.n_wolves - problem.initial.shape[0]
    return np.vstack([problem.initial, rng.random((n_random, problem.dimension))])


def _move_pack(z, guides, a, rng):
    """One GWO move of the whole pack towards the three guides (3, d)."""
    r = rng.random((z.shape[0], z.shape[1], N_LEADERS, 2))
    big_a = 2 * a * r[..., 0] - a
    big_c = 2 * r[..., 1]
    leader = guides.T  # (d, 3)
    distance = np.abs(big_c * leader - z[..., None])
    moved = leader - big_a * distance
    new = (moved[..., 0] + moved[..., 1] + moved[..., 2]) / 3
    return np.clip(new, 0.0, 1.0)  # the algorithm's bound repair


def _select_leaders(wolves):
    """The three best distinct positions under Deb's rules, best first.

    The sort is stable, so of two equally good wolves the earlier row wins (the old
    leaders come first in the pool). Fewer than three are returned when the pool holds
    fewer distinct positions.
    """
    z, fun, vio = wolves
    # Deb's rules: feasible first, then by violation, then by objective
    candidates = np.lexsort((fun, vio, vio > 0))
    chosen = []
    while candidates.size and len(chosen) < N_LEADERS:
        best = candidates[0]
        chosen.append(best)
        candidates = candidates[np.any(z[candidates] != z[best], axis=1)]
    return _Wolves(*(values[chosen] for values in wolves))


def _guides(positions):
    """Alpha, beta and delta positions; missing leaders repeat the last one."""
    missing = N_LEADERS - positions.shape[0]
    return np.vstack([positions] + [positions[-1:]] * missing)


def _insert_leader(leaders, position, problem):
    """Insert one evaluated wolf into the leader list (reference implementation)."""
    fun, vio = problem.evaluate(np.array([position]))
    deb_key = (bool(vio[0] > 0), float(vio[0]), float(fun[0]))  # as in _select_leaders
    candidate = (deb_key, list(position))
    if any(leader[1] == position for leader in leaders):
        return
    rank = next(
        (k for k, leader in enumerate(leaders) if candidate[0] < leader[0]), len(leaders)
    )
    leaders.insert(rank, candidate)
    del leaders[N_LEADERS:]


def _reference_summary(leaders):
    (infeasible, vio, fun), _ = leaders[0]
    return fun, vio, not infeasible


def _report(progress, iteration, row):
    if progress is not None:
        progress(iteration, row[0], row[1])


def _checked_output(values, n_rows, what):
    values = np.asarray(values, dtype=float)
    if values.shape != (n_rows,):
        raise InputError(
            f"{what} must return shape ({n_rows},) for X of {n_rows} rows, "
            f"got shape {values.shape}"
        )
    nan = np.flatnonzero(np.isnan(values))
    if nan.size:
        raise InputError(f"{what} returned NaN for row {nan[0]}")
    return values


def _check_box(lower, upper):
    lower = np.asarray(lower, dtype=float)
    upper = np.asarray(upper, dtype=float)
    if lower.ndim != 1 or lower.size == 0 or lower.shape != upper.shape:
        raise InputError(
            "lower and upper must be non-empty 1-D vectors of one shape, got shapes "
            f"{lower.shape} and {upper.shape}"
        )
    for name, bound in (("lower", lower), ("upper", upper)):
        bad = np.flatnonzero(~np.isfinite(bound))
        if bad.size:
            raise InputError(f"{name}[{bad[0]}] = {bound[bad[0]]} is not finite")
    bad = np.flatnonzero(~(lower < upper))
    if bad.size:
        i = bad[0]
        raise InputError(f"lower[{i}] = {lower[i]} must be < upper[{i}] = {upper[i]}")
    return lower, upper


def _check_count(value, name, minimum):
    try:
        value = index(value)
    except TypeError:
        raise InputError(f"{name} must be an integer, got {value!r}") from None
    if value < minimum:
        raise InputError(f"{name} must be >= {minimum}, got {value}")
    return value


def _check_initial(initial, lower, upper, n_wolves):
    """Starting positions as normalised coordinates (m, d); empty when none given."""
    if initial is None:
        return np.empty((0, lower.size))
    initial = np.atleast_2d(np.asarray(initial, dtype=float))
    if initial.ndim != 2 or initial.shape[1] != lower.size or initial.shape[0] > n_wolves:
        raise InputError(
            f"initial must have shape (m, {lower.size}) with m <= n_wolves = {n_wolves}, "
            f"got shape {initial.shape}"
        )
    outside = np.argwhere(~((initial >= lower) & (initial <= upper)))
    if outside.size:
        row, col = outside[0]
        raise InputError(
            f"initial[{row}, {col}] = {initial[row, col]} is outside the box "
            f"[{lower[col]}, {upper[col]}] (or not finite)"
        )
    return (initial - lower) / (upper - lower)
