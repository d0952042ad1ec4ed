"""The acceptance tests and the poses they visit on a machine.

- :class:`CircularTest` — ISO 230-4 circular test: the linear axes that move along the two
  directions of a plane of the workpiece frame trace a circle, 360 points per turn;
  result: the circular deviation ``G``, the radial range of the path about its
  least-squares circle centre (:func:`reliability.acceptance.iso_statistics.circular_deviation`);
- :class:`PositioningTest` — ISO 230-2 positioning of a linear axis: bidirectional runs to
  target positions along a measuring line; results: systematic positioning error ``E``,
  accuracy ``A``, repeatability ``R`` and reversal value ``B``
  (:func:`reliability.acceptance.iso_statistics.positioning_statistics`);
- :class:`RotaryTest` — the ISO 10791-6 idea for five-axis machines: one rotary axis turns
  through its stroke while the linear axes follow so that the ideal tool point stays put;
  results: the range of the tool point's deviation in x, y and z of the workpiece frame.

:func:`build_path` checks a test against a machine (axes, strokes, directions) and gives its
:class:`TestPath`: the poses, the directions its deviation is read along and the nominal path.

**The tool point in the workpiece frame.** Eq. (18) gives the error ``E = M⁻¹ M_e`` in the
tool frame; the tool point's actual position in the workpiece frame is ``M_e o = M E o``,
so its deviation there is ``R(q) δ`` with ``R(q)`` the ideal tool orientation and ``δ`` the
translation of ``E``. The first-order ``δ = J_δ(q) x`` (the analytic Jacobian,
:func:`deviation_weights`) is used: the neglected terms are of second order (``|ε| |δ|`` and
``|ε|²`` times a lever arm), below 10⁻⁶ mm for errors of micrometres and microradians on a
metre-size machine (checked against the exact product of Eq. 18 in the tests).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar, Mapping

import numpy as np

from ..basics.errors import InputError, InputTypeError
from ..model.kinematics import chain_factors
from .iso_statistics import default_targets

#: Points per turn of a circular test (ISO 230-4) and per degree of a rotary test.
POINTS_PER_TURN = 360
#: ISO 230-2: bidirectional runs of a positioning test unless the file says otherwise.
DEFAULT_RUNS = 5
PLANES = {"xy": (0, 1), "yz": (1, 2), "zx": (2, 0)}
DIRECTIONS = ("x", "y", "z")


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
        if not finite_number(value) or value <= 0:
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
    if not finite_number(test.radius) or test.radius <= 0:
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


def finite_number(value) -> bool:
    """Whether ``value`` is a finite int or float (not a bool)."""
    return not isinstance(value, bool) and isinstance(value, (int, float, np.floating)) \
        and math.isfinite(value)
