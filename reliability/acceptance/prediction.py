"""Acceptance tests at design time: ISO 230 test results of machines built to an allocation.

A machine is accepted against standard tests rather than against a reliability at every
pose. This module predicts, for an allocation of the geometric errors, the distribution of
each test's result over the machines built to it and the probability that a built machine
passes:

- :class:`CircularTest` — ISO 230-4 circular test: the linear axes that move along the two
  directions of a plane of the workpiece frame trace a circle, 360 points per turn;
  result: the circular deviation ``G``, the radial range of the path about its
  least-squares circle centre (:func:`circular_deviation`);
- :class:`PositioningTest` — ISO 230-2 positioning of a linear axis: bidirectional runs to
  target positions along a measuring line; results: systematic positioning error ``E``,
  accuracy ``A``, repeatability ``R`` and reversal value ``B``
  (:func:`positioning_statistics`);
- :class:`RotaryTest` — the ISO 10791-6 idea for five-axis machines: one rotary axis turns
  through its stroke while the linear axes follow so that the ideal tool point stays put;
  results: the range of the tool point's deviation in x, y and z of the workpiece frame.

**What is modelled.** Geometric errors only (the machine file's motion and assembly
errors, Eqs. 2 and 14), plus, for positioning tests only, each linear axis' ``repeatability``
and ``reversal`` from the machine file: no servo, dynamic, thermal or load effects. On a
circle both directions of travel pass through the same poses with the same geometric
errors, so the two directions give the same path and it is evaluated once; ISO 230-4's
``G(a)``, ``G(b)`` and the bidirectional ``G`` coincide.

**The tool point in the workpiece frame.** Eq. (18) gives the error ``E = M⁻¹ M_e`` in the
tool frame; the tool point's actual position in the workpiece frame is ``M_e o = M E o``,
so its deviation there is ``R(q) δ`` with ``R(q)`` the ideal tool orientation and ``δ`` the
translation of ``E``. The first-order ``δ = J_δ(q) x`` (the analytic Jacobian) is used:
the neglected terms are of second order (``|ε| |δ|`` and ``|ε|²`` times a lever arm), below
10⁻⁶ mm for errors of micrometres and microradians on a metre-size machine (checked against
the exact product of Eq. 18 in the tests).

**Built machines.** Each machine draws every motion error as a function of its axis'
position (an error profile along travel, :mod:`reliability.model.profiles`: ``gp:<length>`` or
``constant``; the ``independent`` profile has no continuous path and is refused), every assembly
error once, and the repeatability of every approach of every positioning run. A tolerance ``t`` is
read as ``σ = t/k`` (``k = 3``), normal by default (``distribution``). Measured profiles
(:class:`reliability.model.measured_profiles.SystematicErrors`) add their means along the path. All
tests of a file are evaluated on the same built machines, so the probability of passing them all is
estimated as well.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar, Mapping

import numpy as np
import pandas as pd

from ..basics.chunks import chunks
from ..basics.errors import InputError, InputTypeError
from ..basics.statistics import binomial_interval
from ..basics.streams import generator
from ..model.error_draws import normal_to_marginal
from ..model.kinematics import chain_factors
from ..model.measured_profiles import SystematicErrors
from ..model.profiles import ConstantProfile, GaussianProfile, profile_model

#: Profile used when none is given: a Gaussian process with a 300 mm correlation length.
DEFAULT_PROFILE = "gp:300"
#: Points per turn of a circular test (ISO 230-4) and per degree of a rotary test.
POINTS_PER_TURN = 360
#: ISO 230-2: bidirectional runs of a positioning test unless the file says otherwise.
DEFAULT_RUNS = 5
#: ISO 230-2 target spacing: at least this many targets per metre of travel, and at least
#: :data:`MIN_TARGETS` in all.
TARGETS_PER_METRE = 5
MIN_TARGETS = 5
#: Relative size of the deterministic irregular shift of interior default targets (ISO
#: 230-2 shifts targets off a uniform spacing so that periodic errors are sampled).
TARGET_SHIFT = 0.2
#: Eigenvalues of an along-travel correlation below this share of the largest are dropped.
RANK_TOLERANCE = 1e-10
#: Machines on which each error item's share of a result is estimated (drivers).
DRIVER_MACHINES = 200
#: A result below this (mm) is rounding, not an effect (drivers).
NEGLIGIBLE = 1e-9
PLANES = {"xy": (0, 1), "yz": (1, 2), "zx": (2, 0)}
DIRECTIONS = ("x", "y", "z")
DISTRIBUTIONS = ("normal", "truncated")


# ----- test definitions ----------------------------------------------------------------
@dataclass(frozen=True)
class CircularTest:
    """ISO 230-4 circular test in a plane of the workpiece frame.

    Attributes
    ----------
    name : str
    plane : {'xy', 'yz', 'zx'}
    centre : Mapping[str, float]
        Every axis' position at the circle's centre (mm, rad).
    radius : float
        mm.
    limit : float
        Limit on the circular deviation ``G`` (mm).
    """

    kind: ClassVar[str] = "circular"
    quantities: ClassVar[tuple[str, ...]] = ("G",)
    name: str
    plane: str
    centre: Mapping[str, float]
    radius: float
    limit: float

    @property
    def limits(self) -> dict[str, float]:
        return {"G": self.limit}


@dataclass(frozen=True)
class PositioningTest:
    """ISO 230-2 positioning test of one linear axis.

    Attributes
    ----------
    name : str
    axis : str
        A linear axis.
    line : Mapping[str, float]
        Positions of every other axis (mm, rad): the measuring line.
    limits : Mapping[str, float]
        Limits (mm) on any of ``E``, ``A``, ``R``, ``B``.
    targets : tuple of float or None
        Target positions (mm); None: ISO 230-2's spacing rule (:func:`default_targets`).
    runs : int
        Bidirectional runs (ISO 230-2: 5).
    """

    kind: ClassVar[str] = "positioning"
    quantities: ClassVar[tuple[str, ...]] = ("E", "A", "R", "B")
    name: str
    axis: str
    line: Mapping[str, float]
    limits: Mapping[str, float]
    targets: tuple[float, ...] | None = None
    runs: int = DEFAULT_RUNS


@dataclass(frozen=True)
class RotaryTest:
    """A rotary axis turning with the ideal tool point held (the ISO 10791-6 idea).

    Attributes
    ----------
    name : str
    axis : str
        A rotary axis.
    centre : Mapping[str, float]
        Every axis' position (mm, rad) at which the held tool point is defined; the other
        rotary axes stay there, the linear axes follow.
    limits : Mapping[str, float]
        Limits (mm) on any of ``range_x``, ``range_y``, ``range_z``.
    sweep : tuple of float or None
        ``(start, end)`` of the turning axis (rad); None: its stroke (a whole turn for a
        full-turn axis).
    """

    kind: ClassVar[str] = "rotary"
    quantities: ClassVar[tuple[str, ...]] = ("range_x", "range_y", "range_z")
    name: str
    axis: str
    centre: Mapping[str, float]
    limits: Mapping[str, float]
    sweep: tuple[float, float] | None = None


TEST_TYPES = (CircularTest, PositioningTest, RotaryTest)
KINDS = {test.kind: test for test in TEST_TYPES}


# ----- ISO statistics ------------------------------------------------------------------
def circular_deviation(points, iterations: int = 2) -> np.ndarray:
    """ISO 230-4 circular deviation ``G``: radial range about the least-squares circle centre.

    The centre and radius minimise ``Σ (|p_j − c| − ρ)²`` (ISO 230-4, the least-squares
    circle); found by Gauss–Newton steps from the centroid, which converge in one or two
    steps for a path within micrometres of a circle.

    Parameters
    ----------
    points : array_like
        ``(..., P, 2)`` actual path in the plane of the test (mm).
    iterations : int
        Gauss–Newton steps.

    Returns
    -------
    numpy.ndarray
        ``(...)`` G = max_j |p_j − c| − min_j |p_j − c| (mm).
    """
    p = np.asarray(points, dtype=float)
    centre = p.mean(axis=-2, keepdims=True)
    for _ in range(iterations):
        offset = p - centre
        distance = np.linalg.norm(offset, axis=-1)
        unit = offset / distance[..., None]
        # residual_j = |p_j − c| − ρ; its gradient is (−u_j, −1): the normal equations
        basis = np.concatenate([unit, np.ones(distance.shape + (1,))], axis=-1)
        normal = np.einsum("...pi,...pj->...ij", basis, basis)
        right = np.einsum("...pi,...p->...i", basis, distance)
        step = np.linalg.solve(normal, right[..., None])[..., 0]
        # distance ≈ ρ + u·Δc  →  the centre moves by Δc, ρ is step[..., 2]
        centre = centre + step[..., None, :2]
    radial = np.linalg.norm(p - centre, axis=-1)
    return radial.max(axis=-1) - radial.min(axis=-1)


def positioning_statistics(deviations) -> dict[str, np.ndarray]:
    """ISO 230-2 (2014, clause 3) statistics of bidirectional positioning runs.

    Parameters
    ----------
    deviations : array_like
        ``(..., runs, 2, targets)`` positioning deviations ``x_ij = P_ij − P_i`` (mm);
        direction 0 approaches every target from below (↑), 1 from above (↓). At least two
        runs.

    Returns
    -------
    dict of ndarray
        ``E``, ``A``, ``R``, ``B`` (bidirectional systematic positioning error, accuracy,
        repeatability and reversal value of the axis) and ``E_up``, ``E_down``, ``R_up``,
        ``R_down``, ``A_up``, ``A_down``, ``M`` (unidirectional values and the range of the
        mean bidirectional positional deviation), each ``(...)``.
    """
    x = np.asarray(deviations, dtype=float)
    if x.ndim < 3 or x.shape[-2] != 2 or x.shape[-3] < 2:
        raise InputError(f"deviations must have shape (..., runs >= 2, 2, targets); "
                         f"got {x.shape}")
    first = x[..., :1, :, :]             # runs taken from the first, so equal runs give s = 0
    mean = first[..., 0, :, :] + (x - first).mean(axis=-3)  # x̄_i↑, x̄_i↓
    s = (x - first).std(axis=-3, ddof=1)  # s_i↑, s_i↓: estimators of the standard uncertainty
    up, down = mean[..., 0, :], mean[..., 1, :]
    s_up, s_down = s[..., 0, :], s[..., 1, :]
    reversal_i = up - down               # B_i = x̄_i↑ − x̄_i↓
    r_up, r_down = 4.0 * s_up, 4.0 * s_down   # R_i↑ = 4 s_i↑, R_i↓ = 4 s_i↓
    r_i = np.maximum(2.0 * s_up + 2.0 * s_down + np.abs(reversal_i),
                     np.maximum(r_up, r_down))  # bidirectional R_i
    bidirectional = (up + down) / 2.0    # x̄_i
    return {
        "E": _range(mean, axis=(-2, -1)),                       # max(x̄↑, x̄↓) − min(x̄↑, x̄↓)
        "A": (mean + 2.0 * s).max(axis=(-2, -1)) - (mean - 2.0 * s).min(axis=(-2, -1)),
        "R": r_i.max(axis=-1),
        "B": np.abs(reversal_i).max(axis=-1),
        "E_up": _range(up), "E_down": _range(down),
        "R_up": r_up.max(axis=-1), "R_down": r_down.max(axis=-1),
        "A_up": (up + 2.0 * s_up).max(axis=-1) - (up - 2.0 * s_up).min(axis=-1),
        "A_down": (down + 2.0 * s_down).max(axis=-1) - (down - 2.0 * s_down).min(axis=-1),
        "M": _range(bidirectional),
    }


def _range(values, axis=-1) -> np.ndarray:
    return values.max(axis=axis) - values.min(axis=axis)


def default_targets(stroke, per_metre: int = TARGETS_PER_METRE,
                    minimum: int = MIN_TARGETS) -> np.ndarray:
    """Target positions by ISO 230-2's spacing rule (its test conditions, target positions).

    At least ``per_metre`` targets per metre of travel and at least ``minimum`` in all,
    ``P_i = (i − 1) p + r_i`` over the stroke with ``p`` the uniform spacing and ``r_i`` a
    shift that differs from target to target so that periodic errors are sampled. The
    standard draws ``r_i`` at random; here it is the deterministic
    ``r_i = TARGET_SHIFT · p · (2 frac(i φ) − 1)`` (φ the golden ratio), so that the same
    file gives the same targets, and the two end targets sit at the stroke ends.

    Parameters
    ----------
    stroke : (float, float)
        mm.

    Returns
    -------
    numpy.ndarray
        Increasing targets (mm).
    """
    low, high = (float(v) for v in stroke)
    count = max(minimum, math.ceil(per_metre * (high - low) / 1000.0))
    spacing = (high - low) / (count - 1)
    index = np.arange(count)
    golden = (1.0 + math.sqrt(5.0)) / 2.0
    shift = TARGET_SHIFT * spacing * (2.0 * np.mod(index * golden, 1.0) - 1.0)
    shift[[0, -1]] = 0.0
    return low + index * spacing + shift


# ----- paths: the poses each test visits ----------------------------------------------
@dataclass(frozen=True, eq=False)
class TestPath:
    """The poses a test visits on a machine, and how its result is read from them.

    Attributes
    ----------
    test : CircularTest, PositioningTest or RotaryTest
    poses : ndarray
        ``(P, n_axes)`` positions (mm, rad).
    directions : ndarray
        ``(d, 3)`` unit vectors of the workpiece frame onto which the deviation is read:
        the plane's two directions (circular), the axis' direction of travel (positioning),
        x, y, z (rotary).
    nominal : ndarray
        ``(P, d)`` ideal path in those directions relative to its centre (circular), or the
        targets (positioning), or zeros (rotary).
    """

    __test__ = False  # not a pytest class
    test: object
    poses: np.ndarray
    directions: np.ndarray
    nominal: np.ndarray


def ideal_chain(machine, q) -> np.ndarray:
    """``(..., 4, 4)`` ideal transform ``M`` of the chain (tool frame to workpiece frame)."""
    q = machine.check_positions(q)
    factors, _ = chain_factors(machine, q)
    out = np.broadcast_to(np.eye(4), q.shape[:-1] + (4, 4))
    for factor in factors:
        out = out @ factor
    return out


def tool_point(machine, q) -> np.ndarray:
    """``(..., 3)`` ideal tool point in the workpiece frame (mm)."""
    return ideal_chain(machine, q)[..., :3, 3]


def deviation_weights(machine, poses) -> np.ndarray:
    """``(P, 3, n_errors)``: the tool point's deviation in the workpiece frame per unit of
    each error, ``R(q) J_δ(q)`` (first order of ``R(q) δ`` with ``δ`` the translation of
    Eq. 18's ``E``)."""
    return machine.jacobian(poses, frame="workpiece")[..., :3, :]


def build_path(machine, test) -> TestPath:
    """The poses of ``test`` on ``machine``, checked: axes, strokes, directions.

    Raises
    ------
    InputError
        Naming the test and the key at fault.
    """
    builders = {CircularTest: _circular_path, PositioningTest: _positioning_path,
                RotaryTest: _rotary_path}
    if type(test) not in builders:
        raise InputTypeError(f"tests must be CircularTest, PositioningTest or RotaryTest; "
                             f"got {type(test).__name__}")
    _check_limits(test)
    return builders[type(test)](machine, test)


def _check_limits(test) -> None:
    """Limits on the test's own quantities only, at least one, each finite and > 0 (mm)."""
    if not isinstance(test.limits, Mapping) or not test.limits:
        _refuse(test, "limit", f"give a limit on any of {test.quantities} (mm)")
    for quantity, value in test.limits.items():
        if quantity not in test.quantities:
            _refuse(test, "limit", f"unknown quantity {quantity!r}; use any of "
                                   f"{test.quantities}")
        if not _finite_number(value) or value <= 0:
            _refuse(test, "limit", f"the limit on {quantity} must be a finite number > 0 mm; "
                                   f"got {value!r}")


def _refuse(test, key: str, text: str):
    raise InputError(f"test {test.name!r}, key {key!r}: {text}")


def _positions(machine, test, key: str, given: Mapping, leave_out=()) -> np.ndarray:
    """Every axis' position from ``given`` (every axis except ``leave_out``), in strokes."""
    needed = [a for a in machine.axes if a not in leave_out]
    unknown = [a for a in given if a not in needed]
    if unknown:
        what = "is the axis under test" if unknown[0] in leave_out else "is not an axis"
        _refuse(test, key, f"{unknown[0]!r} {what}; give the positions of {needed}")
    missing = [a for a in needed if a not in given]
    if missing:
        _refuse(test, key, f"missing the position of axis {missing[0]!r}; give every one of "
                           f"{needed}")
    q = np.zeros(len(machine.axes))
    for i, axis in enumerate(machine.axis_specs):
        if axis.name in given:
            q[i] = _within_stroke(test, key, axis, float(given[axis.name]))
    return q


def _within_stroke(test, key, axis, value, what="position") -> float:
    if not math.isfinite(value):
        _refuse(test, key, f"{what} of {axis.name!r} must be finite; got {value!r}")
    if axis.full_turn:
        return value
    low, high = axis.stroke
    slack = 1e-9 * (high - low)
    if value < low - slack or value > high + slack:
        _refuse(test, key, f"{what} {_shown(axis, value)} of axis {axis.name!r} lies outside "
                           f"its stroke [{_shown(axis, low)}, {_shown(axis, high)}]")
    return value


def _shown(axis, value) -> str:
    """A position with its unit, rotary ones in rad and degrees."""
    if axis.kind == "linear":
        return f"{value:g} mm"
    return f"{value:g} rad ({math.degrees(value):.4g}°)"


def _axis_index(machine, test, kind: str) -> int:
    if test.axis not in machine.axes:
        _refuse(test, "axis", f"unknown axis {test.axis!r}; the machine's axes are "
                              f"{machine.axes}")
    index = machine.axes.index(test.axis)
    if machine.axis_specs[index].kind != kind:
        _refuse(test, "axis", f"axis {test.axis!r} is {machine.axis_specs[index].kind}; a "
                              f"{test.kind} test needs a {kind} axis")
    return index


def _travel_directions(machine, q) -> np.ndarray:
    """``(n_axes, 3)``: the tool point's displacement per mm of each axis at ``q`` (exact for
    linear axes, whose motion is a translation; rows of rotary axes are zero)."""
    linear = [i for i, a in enumerate(machine.axis_specs) if a.kind == "linear"]
    out = np.zeros((len(machine.axes), 3))
    steps = q + np.eye(len(machine.axes))[linear]
    out[linear] = tool_point(machine, steps) - tool_point(machine, q)
    return out


def _circular_path(machine, test) -> TestPath:
    if not _finite_number(test.radius) or test.radius <= 0:
        _refuse(test, "radius", f"expected a finite number > 0 mm; got {test.radius!r}")
    if test.plane not in PLANES:
        _refuse(test, "plane", f"unknown plane {test.plane!r}; use one of {tuple(PLANES)}")
    centre = _positions(machine, test, "centre", test.centre)
    directions = _travel_directions(machine, centre)
    angles = 2.0 * np.pi * np.arange(POINTS_PER_TURN) / POINTS_PER_TURN
    poses = np.repeat(centre[None, :], POINTS_PER_TURN, axis=0)
    units = np.eye(3)[list(PLANES[test.plane])]
    for unit, wave in zip(units, (np.cos(angles), np.sin(angles))):
        axis, sign = _axis_along(machine, test, directions, unit)
        poses[:, axis] += sign * test.radius * wave
        spec = machine.axis_specs[axis]
        for end in (-1.0, 1.0):
            _within_stroke(test, "radius", spec, centre[axis] + end * test.radius,
                           what=f"with radius {test.radius:g} mm, the position")
    nominal = test.radius * np.stack([np.cos(angles), np.sin(angles)], axis=-1)
    return TestPath(test, poses, units, nominal)


def _axis_along(machine, test, directions, unit) -> tuple[int, float]:
    """The one linear axis whose travel is along ±``unit`` at the test's pose."""
    along = np.flatnonzero(np.abs(directions @ unit) > 1.0 - 1e-9)
    name = DIRECTIONS[int(np.argmax(unit))]
    if len(along) != 1:
        found = "no linear axis moves" if len(along) == 0 else \
            f"axes {[machine.axes[i] for i in along]} all move"
        _refuse(test, "plane", f"{found} along {name} of the workpiece frame at this centre; "
                               f"a circle needs exactly one axis per direction of its plane")
    return int(along[0]), float(np.sign(directions[along[0]] @ unit))


def _positioning_path(machine, test) -> TestPath:
    axis = _axis_index(machine, test, "linear")
    spec = machine.axis_specs[axis]
    line = _positions(machine, test, "line", test.line, leave_out=(test.axis,))
    targets = default_targets(spec.stroke) if test.targets is None else \
        np.array([_within_stroke(test, "targets", spec, float(v), what="target")
                  for v in test.targets])
    if len(targets) < 2 or np.any(np.diff(targets) <= 0):
        _refuse(test, "targets", "give at least two increasing target positions")
    if isinstance(test.runs, bool) or not isinstance(test.runs, (int, np.integer)) \
            or test.runs < 2:
        _refuse(test, "runs", f"expected an integer >= 2 (ISO 230-2: 5); got {test.runs!r}")
    poses = np.repeat(line[None, :], len(targets), axis=0)
    poses[:, axis] = targets
    direction = _travel_directions(machine, line)[axis]
    return TestPath(test, poses, direction[None, :], targets[:, None])


def _rotary_path(machine, test) -> TestPath:
    axis = _axis_index(machine, test, "rotary")
    spec = machine.axis_specs[axis]
    centre = _positions(machine, test, "centre", test.centre)
    angles = _sweep_angles(test, spec)
    poses = np.repeat(centre[None, :], len(angles), axis=0)
    poses[:, axis] = angles
    linear = [i for i, a in enumerate(machine.axis_specs) if a.kind == "linear"]
    held = tool_point(machine, centre)
    # the tool point is affine in the linear positions: p = p(q with them at 0) + B q_lin
    start = poses.copy()
    start[:, linear] = 0.0
    base = tool_point(machine, start)
    columns = np.stack([tool_point(machine, start + np.eye(len(machine.axes))[i]) - base
                        for i in linear], axis=-1)  # (P, 3, n_linear)
    solution = np.einsum("pij,pj->pi", np.linalg.pinv(columns), held - base)
    poses[:, linear] = solution
    miss = np.abs(tool_point(machine, poses) - held).max()
    if miss > 1e-6:
        _refuse(test, "axis", f"the linear axes cannot hold the tool point while "
                              f"{test.axis!r} turns (off by {miss:.3g} mm)")
    for i in linear:
        for value in (poses[:, i].min(), poses[:, i].max()):
            _within_stroke(test, "centre", machine.axis_specs[i], float(value),
                           what=f"to hold the tool point while {test.axis!r} turns, the "
                                f"position")
    return TestPath(test, poses, np.eye(3), np.zeros((len(angles), 3)))


def _sweep_angles(test, spec) -> np.ndarray:
    if test.sweep is None and spec.full_turn:
        return 2.0 * np.pi * np.arange(POINTS_PER_TURN) / POINTS_PER_TURN
    low, high = spec.stroke if test.sweep is None else (float(v) for v in test.sweep)
    if not high > low:
        _refuse(test, "sweep", f"expected [start, end] with start < end (rad); got "
                               f"[{low:g}, {high:g}]")
    for value in (low, high):
        _within_stroke(test, "sweep", spec, value)
    count = max(2, math.ceil(math.degrees(high - low) * POINTS_PER_TURN / 360.0)) + 1
    return np.linspace(low, high, count)


# ----- the result ----------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class AcceptanceResult:
    """Predicted acceptance-test results of machines built to one allocation.

    Attributes
    ----------
    tests : tuple
        The test definitions.
    values : pandas.DataFrame
        One row per built machine, columns ``(test, quantity)``: each result (mm).
    drivers : pandas.DataFrame
        Columns ``test, quantity, item, share``: each error item's share of the result's
        mean square, the item drawn alone on the first :data:`DRIVER_MACHINES` machines
        (shares of a quantity sum to 1; for a result linear in the items the single-item
        mean squares add up to the result's own).
    profile : str
        The error profile along travel (e.g. ``gp:300``).
    distribution : str
        The reading of a tolerance: ``normal`` or ``truncated`` at ±t, σ = t/k.
    k : float
    confidence : float
        Level of the Wilson score intervals on the pass probabilities.
    """

    tests: tuple
    values: pd.DataFrame
    drivers: pd.DataFrame
    profile: str
    distribution: str
    k: float = 3.0
    confidence: float = 0.95

    @property
    def n_machines(self) -> int:
        return len(self.values)

    def passed(self) -> pd.DataFrame:
        """Boolean frame, one column per test and ``all``: every limited quantity within its
        limit (``value <= limit``)."""
        out = {}
        for test in self.tests:
            ok = np.ones(self.n_machines, dtype=bool)
            for quantity, limit in test.limits.items():
                ok &= self.values[(test.name, quantity)].to_numpy() <= limit
            out[test.name] = ok
        frame = pd.DataFrame(out)
        frame["all"] = frame.all(axis=1)
        return frame

    def to_frame(self) -> pd.DataFrame:
        """The ``acceptance.csv`` table: ``test, quantity, limit, mean, q95, pass_probability,
        pass_low, pass_high``; one row per test and quantity, then ``all, pass``.

        ``pass_*`` are empty for a quantity without a limit; the interval is the Wilson
        score interval at :attr:`confidence`.
        """
        rows = []
        for test in self.tests:
            for quantity in test.quantities:
                values = self.values[(test.name, quantity)].to_numpy()
                limit = test.limits.get(quantity, np.nan)
                row = {"test": test.name, "quantity": quantity, "limit": limit,
                       "mean": values.mean(), "q95": np.quantile(values, 0.95)}
                row.update(self._pass(values <= limit) if quantity in test.limits else
                           dict.fromkeys(("pass_probability", "pass_low", "pass_high"),
                                         np.nan))
                rows.append(row)
        everything = self.passed()["all"].to_numpy()
        rows.append({"test": "all", "quantity": "pass", "limit": np.nan, "mean": np.nan,
                     "q95": np.nan, **self._pass(everything)})
        return pd.DataFrame(rows)

    def test_pass(self) -> pd.DataFrame:
        """Pass probability of each test (every limited quantity) and of all, with interval."""
        passed = self.passed()
        return pd.DataFrame([{"test": name, **self._pass(passed[name].to_numpy())}
                             for name in passed.columns])

    def top_drivers(self, test: str, quantity: str, n: int = 3) -> str:
        """The ``n`` items with the largest shares, e.g. ``"X.dx 61 %, Y-X.ez 22 %"``."""
        rows = self.drivers[(self.drivers["test"] == test)
                            & (self.drivers["quantity"] == quantity)]
        rows = rows.sort_values("share", ascending=False, kind="stable").head(n)
        return ", ".join(f"{r.item} {100 * r.share:.0f} %" for r in rows.itertuples()
                         if r.share >= 0.005)

    def summary(self) -> str:
        """The set-up (built machines, error profile, reading of a tolerance), then
        :meth:`results_text`."""
        return (f"{self.n_machines} built machines through {len(self.tests)} acceptance "
                f"tests; {profile_note(self.profile)}; tolerances read as "
                f"{self.distribution} with σ = t/{self.k:g}\n\n{self.results_text()}")

    def results_text(self) -> str:
        """Each result's limit, mean and 95 % quantile in µm, its pass probability with
        its interval and the items that drive it, then each test's pass probability: what
        ``precrel acceptance`` prints below its heading."""
        lines = [self._printed_table().to_string(index=False), "",
                 f"pass probability of each test (every limited quantity), Wilson "
                 f"{100 * self.confidence:g} %:"]
        lines += [f"  {row.test}: {row.pass_probability:.4f} "
                  f"[{row.pass_low:.4f}, {row.pass_high:.4f}]"
                  for row in self.test_pass().itertuples()]
        return "\n".join(lines)

    def _printed_table(self) -> pd.DataFrame:
        """:meth:`to_frame` with limits, means and quantiles in µm and the drivers."""
        rows = []
        for row in self.to_frame().itertuples():
            if row.test == "all":
                continue
            limited = pd.notna(row.limit)
            rows.append({
                "test": row.test, "quantity": row.quantity,
                "limit µm": f"{1000 * row.limit:.3g}" if limited else "-",
                "mean µm": f"{1000 * row.mean:.3g}", "q95 µm": f"{1000 * row.q95:.3g}",
                "pass": f"{row.pass_probability:.4f} [{row.pass_low:.4f}, "
                        f"{row.pass_high:.4f}]" if limited else "-",
                "driven by (share of mean square)":
                    self.top_drivers(row.test, row.quantity) or "-"})
        return pd.DataFrame(rows)

    def _pass(self, ok) -> dict[str, float]:
        k, n = int(np.count_nonzero(ok)), len(ok)
        low, high = binomial_interval(k, n, self.confidence, method="wilson")
        return {"pass_probability": k / n, "pass_low": float(low), "pass_high": float(high)}


def profile_note(profile) -> str:
    """The error profile named with what it means for the tests, to print beside results."""
    model = profile_model(profile)
    if isinstance(model, ConstantProfile):
        return ("error profile constant (one value of every error per built machine along "
                "the whole travel: an axis' own positioning error is one offset, so "
                "positioning tests show only reversal and repeatability, and a circle is an "
                "exact ellipse with G proportional to its radius)")
    return (f"error profile {model} (Gaussian process along travel, correlation length "
            f"{model.length:g} mm)")


# ----- the computation -----------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class _Plan:
    """Everything about the tests that does not depend on a built machine."""

    paths: tuple
    offsets: tuple          # start of each path's poses in the stacked poses
    weights: np.ndarray     # (P, 3, n_errors): workpiece-frame tool-point deviation per error
    index: tuple            # per axis: (P,) index of each pose's position among the axis'
    factors: tuple          # per axis: (U_a, r_a) along-travel factor at its positions
    mean_deviation: np.ndarray  # (P, 3) from measured means
    item_means: np.ndarray  # (P, n_errors) measured means at the poses
    sigma: np.ndarray       # (n_errors,) t/k
    positioning: dict       # positioning test name: (repeatability σ, reversal) of its axis


def acceptance(machine, tests, tolerances=None, *, machines: int = 2000,
               profile=DEFAULT_PROFILE, distribution: str = "normal", k: float = 3.0,
               systematic=None, confidence: float = 0.95,
               driver_machines: int = DRIVER_MACHINES, memory: int | None = None,
               rng=None) -> AcceptanceResult:
    """Predicted ISO 230 acceptance-test results of machines built to an allocation.

    Parameters
    ----------
    machine : Machine
    tests : sequence of CircularTest, PositioningTest, RotaryTest
        Evaluated on the same built machines (names unique).
    tolerances : array_like, optional
        ``(n_errors,)`` allocation (mm, rad); the machine's initial allocation by default.
    machines : int
        Built machines drawn.
    profile : str or profile model
        Error profile along travel of every axis' motion errors: ``gp:<length mm>``
        (default :data:`DEFAULT_PROFILE`) or ``constant``. Under ``constant`` an axis'
        own positioning error is one offset along its whole travel, so positioning tests
        show only reversal and repeatability, and a circle is an exact ellipse with ``G``
        proportional to its radius. ``independent`` is refused: a fresh value at every
        point does not describe a continuous path.
    distribution : {'normal', 'truncated'}
        Reading of a tolerance: ``σ = t/k``, normal or truncated at ``±t``.
    k : float
    systematic : SystematicErrors, optional
        Measured profiles whose means are added along the paths.
    confidence : float
        Level of the Wilson intervals on the pass probabilities.
    driver_machines : int
        Machines (the first ones drawn) on which each item's share is estimated.
    memory : int, optional
        Bytes of temporary arrays per chunk of machines (:mod:`reliability.basics.chunks`).
    rng : seed or Generator

    Returns
    -------
    AcceptanceResult
    """
    tests = _check_tests(tests)
    model = path_profile(profile, tests)
    _check_options(distribution, k, confidence, machines, driver_machines)
    if machine.correlation is not None:
        raise InputError("acceptance tests do not take the machine's [[correlation]] "
                         "between error items into account yet; remove it to predict them")
    t = machine.initial_allocation if tolerances is None else \
        machine.check_tolerances(tolerances)
    if t.shape != (machine.n_errors,):
        raise InputError(f"tolerances must have shape ({machine.n_errors},); got {t.shape}")
    plan = _plan(machine, tests, model, t / k, systematic)
    draws = _draw(machine, plan, machines, rng)
    latent_map = _latent_map(plan, len(machine.axes)) if distribution == "normal" else None
    values = np.concatenate([_quantities(plan, _slice(draws, part), machine, k, distribution,
                                         latent_map)
                             for part in chunks(machines, _bytes_per_machine(plan), memory)])
    columns = pd.MultiIndex.from_tuples([(p.test.name, q) for p in plan.paths
                                         for q in p.test.quantities],
                                        names=["test", "quantity"])
    first = _slice(draws, slice(0, min(driver_machines, machines)))
    drivers = _drivers(plan, first, machine, k, distribution)
    return AcceptanceResult(tests=tests, values=pd.DataFrame(values, columns=columns),
                            drivers=drivers, profile=str(model), distribution=distribution,
                            k=float(k), confidence=float(confidence))


def results_of_deviations(machine, tests, deviations, rng=None) -> pd.DataFrame:
    """Each test's results on given machines, columns ``(test, quantity)`` as
    :attr:`AcceptanceResult.values`.

    ``deviations`` ``(m, P, 3)`` is each machine's tool-point deviation in the workpiece
    frame at the poses of the tests' paths (:func:`build_path`), stacked in test order; the
    repeatability and reversal of positioning runs are drawn from ``rng`` as in
    :func:`acceptance`.
    """
    tests = _check_tests(tests)
    plan = _plan(machine, tests, ConstantProfile(), np.zeros(machine.n_errors), None)
    deviations = np.asarray(deviations, dtype=float)
    if deviations.ndim != 3 or deviations.shape[1:] != (len(plan.weights), 3):
        raise InputError(f"deviations must have shape (machines, {len(plan.weights)}, 3); "
                         f"got {deviations.shape}")
    rng = generator(rng)
    repeat = [rng.standard_normal((len(deviations), p.test.runs, 2, len(p.poses)))
              for p in plan.paths if isinstance(p.test, PositioningTest)]
    columns = pd.MultiIndex.from_tuples([(p.test.name, q) for p in plan.paths
                                         for q in p.test.quantities],
                                        names=["test", "quantity"])
    return pd.DataFrame(_results(plan, deviations, repeat, scale=(1.0, 1.0)), columns=columns)


def _check_options(distribution, k, confidence, machines, driver_machines) -> None:
    if distribution not in DISTRIBUTIONS:
        raise InputError(f"distribution must be one of {DISTRIBUTIONS}; got {distribution!r}")
    if not _finite_number(k) or k <= 0:
        raise InputError(f"k must be a finite number > 0; got {k!r}")
    if not _finite_number(confidence) or not 0 < confidence < 1:
        raise InputError(f"confidence must be a number in (0, 1); got {confidence!r}")
    for name, value in (("machines", machines), ("driver_machines", driver_machines)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
            raise InputError(f"{name} must be an integer >= 1; got {value!r}")


def _finite_number(value) -> bool:
    return not isinstance(value, bool) and isinstance(value, (int, float, np.floating)) \
        and math.isfinite(value)


def _check_tests(tests) -> tuple:
    tests = tuple(tests)
    if not tests:
        raise InputError("tests: give at least one test")
    names = set()
    for test in tests:
        if not isinstance(test, TEST_TYPES):
            raise InputTypeError(f"tests must be CircularTest, PositioningTest or RotaryTest; "
                                 f"got {type(test).__name__}")
        if test.name in names:
            raise InputError(f"test name {test.name!r} is used twice")
        names.add(test.name)
    return tests


def path_profile(profile, tests):
    """The profile model for ``tests``, or a refusal of ``independent`` naming the first test."""
    model = profile_model(profile)
    if not isinstance(model, (GaussianProfile, ConstantProfile)):
        raise InputError(f"profile {str(model)!r} draws a fresh error at every point and does "
                         f"not describe a continuous path; test {tests[0].name!r} "
                         f"({tests[0].kind}) needs 'gp:<length mm>' or 'constant'")
    return model


def _plan(machine, tests, model, sigma, systematic) -> _Plan:
    paths = tuple(build_path(machine, test) for test in tests)
    poses = np.concatenate([p.poses for p in paths])
    offsets = tuple(np.cumsum([0] + [len(p.poses) for p in paths])[:-1])
    weights = deviation_weights(machine, poses)
    index, factors = [], []
    for a, axis in enumerate(machine.axis_specs):
        where = np.mod(poses[:, a], 2.0 * np.pi) if axis.full_turn else poses[:, a]
        # positions equal to 1e-9 (mm, rad) are one position of the profile
        unique, inverse = np.unique(np.round(where, 9), return_inverse=True)
        index.append(inverse.reshape(-1))
        factors.append(travel_factor(model, axis, unique))
    if systematic is None:
        item_means = np.zeros((len(poses), machine.n_errors))
    elif not isinstance(systematic, SystematicErrors):
        raise InputTypeError(f"systematic must be a SystematicErrors; got {systematic!r}")
    else:
        item_means = systematic.means(poses)
    specs = {a.name: a for a in machine.axis_specs}
    positioning = {p.test.name: (specs[p.test.axis].repeatability, specs[p.test.axis].reversal)
                   for p in paths if isinstance(p.test, PositioningTest)}
    return _Plan(paths=paths, offsets=offsets, weights=weights, index=tuple(index),
                 factors=tuple(factors),
                 mean_deviation=np.einsum("poi,pi->po", weights, item_means),
                 item_means=item_means, sigma=np.asarray(sigma, dtype=float),
                 positioning=positioning)


def travel_factor(model, axis, positions) -> np.ndarray:
    """``(U, r)`` factor ``F`` with ``F Fᵀ`` the profile's correlation at ``positions``.

    The eigenvectors of the correlation whose eigenvalues exceed :data:`RANK_TOLERANCE`
    times the largest, scaled by their roots, and each row renormalised to unit length so
    that every position keeps its marginal exactly. A smooth profile at many close positions
    has a low numerical rank ``r``, so a built machine's profile is ``F z`` with only ``r``
    standard normals per error (rank one for ``constant``).
    """
    correlation = model.correlation(axis, positions)
    values, vectors = np.linalg.eigh(correlation)
    keep = values > RANK_TOLERANCE * values[-1]
    factor = vectors[:, keep] * np.sqrt(values[keep])
    return factor / np.linalg.norm(factor, axis=1, keepdims=True)


def _draw(machine, plan, n, rng) -> dict:
    """Every random number of ``n`` built machines, drawn once in a fixed order (so the
    numbers do not depend on the memory budget's chunks)."""
    rng = generator(rng)
    n_axes = len(machine.axes)
    draws = {"motion": [rng.standard_normal((n, f.shape[1], 6)) for f in plan.factors],
             "assembly": rng.standard_normal((n, 6 * (n_axes - 1)))}
    draws["repeat"] = [rng.standard_normal((n, p.test.runs, 2, len(p.poses)))
                       for p in plan.paths if isinstance(p.test, PositioningTest)]
    return draws


def _slice(draws, part) -> dict:
    return {"motion": [z[part] for z in draws["motion"]], "assembly": draws["assembly"][part],
            "repeat": [z[part] for z in draws["repeat"]]}


def _bytes_per_machine(plan) -> int:
    return 8 * len(plan.weights) * (3 + 2 * 6) * 2


def _item_values(plan, draws, machine, k, distribution):
    """Per axis ``(m, U_a, 6)`` motion errors at its positions, and ``(m, n_joint_errors)``
    assembly errors, each ``σ × marginal(z)`` (means are added along the paths)."""
    n_axes = len(machine.axes)
    motion = [normal_to_marginal(np.matmul(f, z), k, distribution)
              * plan.sigma[6 * a:6 * a + 6]
              for a, (f, z) in enumerate(zip(plan.factors, draws["motion"]))]
    assembly = normal_to_marginal(draws["assembly"], k, distribution) * plan.sigma[6 * n_axes:]
    return motion, assembly


def _deviations(plan, motion, assembly, n_axes) -> np.ndarray:
    """``(m, P, 3)`` tool-point deviation in the workpiece frame at every pose, from the
    errors' values (any marginal distribution)."""
    w = plan.weights
    out = assembly @ w[:, :, 6 * n_axes:].reshape(-1, assembly.shape[-1]).T
    out = out.reshape(len(assembly), len(w), 3) + plan.mean_deviation
    for a, values in enumerate(motion):
        at_poses = values[:, plan.index[a], :]                 # (m, P, 6)
        for c in range(6):
            out += at_poses[:, :, c, None] * w[:, :, 6 * a + c]
    return out


def _latent_map(plan, n_axes) -> np.ndarray:
    """``(L, P·3)``: the deviations as a linear map of every standard normal of a machine
    (normal errors only): ``F_a`` along travel, ``σ`` and the weights folded together."""
    blocks = []
    for a, factor in enumerate(plan.factors):
        w = plan.weights[:, :, 6 * a:6 * a + 6] * plan.sigma[6 * a:6 * a + 6]
        blocks.append(np.einsum("pr,poc->rcpo", factor[plan.index[a]], w)
                      .reshape(-1, 3 * len(w)))
    w = plan.weights[:, :, 6 * n_axes:] * plan.sigma[6 * n_axes:]
    blocks.append(np.moveaxis(w, 2, 0).reshape(-1, 3 * len(w)))
    return np.concatenate(blocks)


def _latent(draws) -> np.ndarray:
    """``(m, L)`` a machine's standard normals in the order of :func:`_latent_map`."""
    motion = [z.reshape(len(z), -1) for z in draws["motion"]]
    return np.concatenate(motion + [draws["assembly"]], axis=1)


def _quantities(plan, draws, machine, k, distribution, latent_map=None) -> np.ndarray:
    """``(m, quantities)``: the results of a chunk of machines."""
    if latent_map is not None:   # normal errors: one matrix product
        deviations = (_latent(draws) @ latent_map).reshape(-1, len(plan.weights), 3) \
            + plan.mean_deviation
    else:
        motion, assembly = _item_values(plan, draws, machine, k, distribution)
        deviations = _deviations(plan, motion, assembly, len(machine.axes))
    return _results(plan, deviations, draws["repeat"], scale=(1.0, 1.0))


def _results(plan, deviations, repeat, scale) -> np.ndarray:
    """``(m, quantities)`` every test's results from the deviations along the paths.

    ``scale`` multiplies the repeatability and the reversal of positioning tests (0 to leave
    them out when one geometric item is drawn alone)."""
    noise = iter(repeat)
    columns = []
    for path, start in zip(plan.paths, plan.offsets):
        part = deviations[:, start:start + len(path.poses), :]
        columns.append(_path_results(plan, path, part, next(noise) if isinstance(
            path.test, PositioningTest) else None, scale))
    return np.concatenate(columns, axis=1)


def _path_results(plan, path, deviations, noise, scale) -> np.ndarray:
    """``(m, quantities of the test)`` from the deviations ``(m, P_test, 3)`` of one path."""
    along = deviations @ path.directions.T
    if isinstance(path.test, CircularTest):
        return _circle_g(path, along)[:, None]
    if isinstance(path.test, PositioningTest):
        sigma, reversal = plan.positioning[path.test.name]
        return _positioning_results(along[..., 0], sigma * scale[0], reversal * scale[1],
                                    noise)
    return along.max(axis=1) - along.min(axis=1)


def _circle_g(path, along, iterations: int = 2) -> np.ndarray:
    """``(m,)`` G of circles traced with deviations ``along`` ``(m, P, 2)`` from the nominal.

    The least-squares centre by linear least squares of the radial deviations on
    ``1, cos θ_j, sin θ_j`` at the nominal angles, repeated about the new centre (each pass
    leaves a centre error smaller by about |Δ|/r, and an error e of the centre changes G by
    up to 2e), then the radial range about that centre, exactly. Agrees with
    :func:`circular_deviation` (whose normal equations use the actual directions) to
    10⁻⁷ mm on paths within 30 µm of the circle (tests)."""
    x = path.nominal[:, 0] + along[..., 0]
    y = path.nominal[:, 1] + along[..., 1]
    radius = np.hypot(path.nominal[0, 0], path.nominal[0, 1])
    angles = np.arctan2(path.nominal[:, 1], path.nominal[:, 0])
    basis = np.stack([np.ones_like(angles), np.cos(angles), np.sin(angles)], axis=-1)
    fit = np.linalg.pinv(basis).T                                 # (P, 3): ρ − r, Δcx, Δcy
    cx = cy = np.zeros((len(x), 1))
    for _ in range(iterations):
        step = (np.hypot(x - cx, y - cy) - radius) @ fit
        cx, cy = cx + step[:, 1:2], cy + step[:, 2:3]
    radial = np.hypot(x - cx, y - cy)
    return radial.max(axis=1) - radial.min(axis=1)


def _positioning_results(systematic, sigma, reversal, noise) -> np.ndarray:
    """``(m, 4)`` E, A, R, B of runs whose deviations are the geometric ``systematic``
    ``(m, T)``, ``±reversal/2`` for approaches from below/above and ``σ`` noise."""
    sign = np.array([0.5, -0.5])[:, None]
    deviations = systematic[:, None, None, :] + reversal * sign + sigma * noise
    stats = positioning_statistics(deviations)
    return np.stack([stats[q] for q in PositioningTest.quantities], axis=-1)


def _drivers(plan, draws, machine, k, distribution) -> pd.DataFrame:
    """Each error item's share of each result's mean square, the item drawn alone.

    Items: the machine's errors, and the repeatability and reversal of the axis of each
    positioning test. Mean squares below ``NEGLIGIBLE²`` (rounding) count as zero."""
    n_axes = len(machine.axes)
    motion, assembly = _item_values(plan, draws, machine, k, distribution)
    noise = dict(zip([p.test.name for p in plan.paths if isinstance(p.test, PositioningTest)],
                     draws["repeat"]))
    rows = []
    for path, start in zip(plan.paths, plan.offsets):
        poses = slice(start, start + len(path.poses))
        weights, repeat = plan.weights[poses], noise.get(path.test.name)
        squares = {}
        for i, item in enumerate(machine.error_names):
            if not np.any(weights[:, :, i] @ path.directions.T):
                continue
            if i < 6 * n_axes:
                a, c = divmod(i, 6)
                values = motion[a][:, plan.index[a][poses], c]              # (m, P)
            else:
                values = assembly[:, i - 6 * n_axes, None]
            deviations = (values + plan.item_means[poses, i])[..., None] * weights[:, :, i]
            squares[item] = _mean_square(_path_results(plan, path, deviations, repeat,
                                                       (0.0, 0.0)))
        if isinstance(path.test, PositioningTest):
            zero = np.zeros((len(assembly), len(path.poses), 3))
            for key, scale in (("repeatability", (1.0, 0.0)), ("reversal", (0.0, 1.0))):
                squares[f"{path.test.axis}.{key}"] = _mean_square(
                    _path_results(plan, path, zero, repeat, scale))
        table = pd.DataFrame(squares, index=list(path.test.quantities))
        total = table.sum(axis=1)
        for quantity, row in table.iterrows():
            if total[quantity] > 0:
                rows += [{"test": path.test.name, "quantity": quantity, "item": item,
                          "share": value / total[quantity]}
                         for item, value in row.items() if value > 0]
    return pd.DataFrame(rows, columns=["test", "quantity", "item", "share"])


def _mean_square(results) -> np.ndarray:
    square = np.mean(np.square(results), axis=0)
    return np.where(square > NEGLIGIBLE ** 2, square, 0.0)
